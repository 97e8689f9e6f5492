"""USD → Mitsuba 3: infrared band radiance and EO spectral renders of a composed stage.

The per-frame orchestration with ground truth and the manifest is
:func:`humv_usd.pipeline.render.render_stage`; this package does not import ``groundtruth``.
"""

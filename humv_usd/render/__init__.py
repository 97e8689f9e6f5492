"""USD → Mitsuba 3: infrared band radiance and EO spectral renders of a composed stage.

Modules, one job each (top to bottom):

- :mod:`~humv_usd.render.scene_export`: the stage's rendered meshes in numpy (traversal,
  UsdSkel posing, one part per bound material, double-sided back copies, topology checks);
- :mod:`~humv_usd.render.frame`: :class:`~humv_usd.render.frame.FrameState` (one frame's
  points, face temperatures, cameras, sky temperature) and the temperature and path-table reads;
- :mod:`~humv_usd.render.export`: :class:`~humv_usd.render.export.StageExport`, the stage read
  for rendering (meshes + sensors) that fills a FrameState per frame;
- :mod:`~humv_usd.render.radiometry` (sub-bands, sky, sun, atmospheric path; pure numpy),
  :mod:`~humv_usd.render.cie` (frozen CIE tables);
- :mod:`~humv_usd.render.ir` (Mitsuba IR scene and band render), :mod:`~humv_usd.render.eo`
  (Mitsuba spectral EO render).

Atmosphere and environment data are read directly through :mod:`humv_usd.usd.atmosphere` and
:mod:`humv_usd.usd.environment`. The per-frame orchestration with ground truth and the manifest
is :func:`humv_usd.pipeline.render.render_stage`; this package does not import ``groundtruth``.
"""

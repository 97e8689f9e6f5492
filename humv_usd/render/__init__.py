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
- :mod:`~humv_usd.render.light`: the frame's light (spectra, sun, DNI), read once per frame for
  every sensor pass; :mod:`~humv_usd.render.bands`: a material's band quantities per sensor,
  cached, and its Kirchhoff closure (one authority per band);
- :mod:`~humv_usd.render.elements`: scene elements, each its Mitsuba dict and the parameter keys
  it updates per frame; :mod:`~humv_usd.render.ir` (Mitsuba IR scene, the frame's one scene for
  every sensor, and the path tracer's band render), :mod:`~humv_usd.render.estimator` (the fast
  estimator), :mod:`~humv_usd.render.renderer` (the interface: one implementation per estimator,
  one rule that picks it), :mod:`~humv_usd.render.quality` (sample batching, stopping rules,
  error summaries, IR and EO), :mod:`~humv_usd.render.eo` and :mod:`~humv_usd.render.eo_fast`
  (visible: reflectance to CIE XYZ and sRGB).

Atmosphere and environment data are read directly through :mod:`humv_usd.usd.atmosphere` and
:mod:`humv_usd.usd.environment`. The per-frame orchestration with ground truth and the manifest
is :func:`humv_usd.pipeline.render.render_stage` (the IR pass of one sensor:
:mod:`humv_usd.pipeline.ir_pass`); this package does not import ``groundtruth``.
"""

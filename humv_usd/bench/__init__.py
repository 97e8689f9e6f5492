"""Benchmarks behind ``humv-usd bench`` (every bench lives here; each CLI command only parses and
prints): render estimators (:mod:`~humv_usd.bench.render`, :mod:`~humv_usd.bench.render_eo`), the
sub-band model's spectral error (:mod:`~humv_usd.bench.subbands`), one frame's cost
(:mod:`~humv_usd.bench.frame`), compose and render wall times (:mod:`~humv_usd.bench.pipeline`),
thermal q_rad and time steps (:mod:`~humv_usd.bench.thermal`, :mod:`~humv_usd.bench.thermal_steps`),
avatar, clothing, labels, memory, sweep throughput. They may import any tool: the package sits
above the tools, the pipeline and the sweep."""

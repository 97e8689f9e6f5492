"""``humv-usd sweep``: a base scenario and axes (a grid and random draws) expanded into variants,
composed and rendered as stateless tasks (one per variant and frame chunk) on Dask, resumable,
assembled into one dataset folder.

Modules: :mod:`~humv_usd.sweep.spec` (the sweep file, variants, validation),
:mod:`~humv_usd.sweep.plan` (layer cache keys, tasks, cost estimate),
:mod:`~humv_usd.sweep.store` (lock, staging, done records, shared layer store),
:mod:`~humv_usd.sweep.tasks` (what a worker runs), :mod:`~humv_usd.sweep.run` (the client loop:
Dask, retries, progress events), :mod:`~humv_usd.sweep.dataset` (merged COCO, index, card, YOLO),
:mod:`humv_usd.bench.sweep` (throughput, scaling, memory, scheduler cost).
"""

"""Clothing tool: garments fitted from MakeHuman's helper geometry, skinned to the avatar's
skeleton, kept off the skin frame by frame, with per-vertex air gaps (layers/clothing_<id>.usda).

Modules: :mod:`~humv_usd.catalog.garments` (catalogue), :mod:`~humv_usd.clothing.fit`
(rest shape + weight transfer, refinement over the neck/pelvis), :mod:`~humv_usd.clothing.collide`
(per-frame intersection fix, layering, air gap), :mod:`~humv_usd.clothing.drape` (loose parts:
position-based dynamics), :mod:`~humv_usd.geometry.mesh` (closest point, signed distance, rays),
:mod:`~humv_usd.clothing.layer` (USD), :mod:`~humv_usd.bench.clothing` (counts and timings).
"""

"""The one ray caster (humv_usd.geometry.raycast) against closed forms on a box."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from numpy.testing import assert_allclose, assert_array_equal

from humv_usd.geometry.raycast import (
    RayCaster,
    first_faces,
    ray_caster,
    unblocked,
    unblocked_local,
)


def box(lo=(1.0, 2.0, 3.0), hi=(3.0, 5.0, 4.0)):
    """Axis-aligned box (points, triangles, lo, hi) with outward normals."""
    lo, hi = np.asarray(lo), np.asarray(hi)
    m = trimesh.creation.box(bounds=[lo, hi])
    return np.asarray(m.vertices), np.asarray(m.faces), lo, hi


def random_rays(n, seed=0):
    """Origins around the box (some inside), aimed at points near it: about half hit."""
    rng = np.random.default_rng(seed)
    o = rng.uniform(-2.0, 8.0, (n, 3))
    d = rng.uniform([0.0, 1.0, 2.0], [4.0, 6.0, 5.0], (n, 3)) - o
    return o, d / np.linalg.norm(d, axis=1, keepdims=True)


def slab_distance(o, d, lo, hi):
    """Closed form (slab method): distance to the box along each ray, inf on a miss."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - o) / d, (hi - o) / d
    tn = np.max(np.minimum(t1, t2), axis=1)
    tf = np.min(np.maximum(t1, t2), axis=1)
    t = np.where(tn > 0, tn, tf)
    return np.where((tf >= tn) & (tf > 0), t, np.inf)


@pytest.mark.parametrize("normalize", [True, False])
def test_hit_distance_and_points_match_the_slab_method(normalize):
    p, t, lo, hi = box()
    o, d = random_rays(4000)
    ref = slab_distance(o, d, lo, hi)
    caster = RayCaster(p, t, normalize=normalize)
    dist = caster.hit_distance(o, d)
    hit = np.isfinite(ref)
    assert hit.sum() > 300 and (~hit).sum() > 300
    assert_array_equal(np.isfinite(dist), hit)
    assert_allclose(dist[hit], ref[hit], rtol=1e-5, atol=1e-5)
    face, points = caster.first_points(o, d)
    assert_array_equal(face >= 0, hit)
    # the float64 plane intersection is exact to rounding, unlike the float32 distance
    assert_allclose(points[hit], o[hit] + ref[hit, None] * d[hit], atol=1e-12)
    assert np.isnan(points[~hit]).all()
    # the face hit contains the hit point
    tri = p[t[face[hit]]]
    assert (points[hit] >= tri.min(axis=1) - 1e-9).all() and (points[hit] <= tri.max(axis=1) + 1e-9).all()


def test_any_hit_and_chunks_agree_with_first_hit():
    p, t, lo, hi = box()
    o, d = random_rays(3000, seed=1)
    caster = ray_caster(p, t)
    first = caster.intersects_first(o, d)
    assert_array_equal(caster.intersects_any(o, d), first >= 0)
    assert_array_equal(first_faces(caster, o, d, chunk=7), first)
    assert_array_equal(unblocked(caster, o, d, chunk=7), first < 0)
    local = caster.local(o)
    assert_array_equal(caster.first_hit_local(local, np.ascontiguousarray(d, dtype=np.float32)), first)
    # origins converted once to the caster's frame (the thermal shadow rays): the same answer
    assert_array_equal(unblocked_local(caster, local, d.astype(np.float32), chunk=7), first < 0)
    assert_array_equal(ray_caster(p, t).any_hit_local(local, d.astype(np.float32)), first >= 0)


def test_inside_by_parity():
    p, t, lo, hi = box()
    q = np.random.default_rng(2).uniform([0.5, 1.5, 2.5], [3.5, 5.5, 4.5], (2000, 3))
    ref = np.all((q > lo) & (q < hi), axis=1)
    assert 300 < ref.sum() < 1700
    for normalize in (True, False):
        assert_array_equal(RayCaster(p, t, normalize=normalize).inside(q), ref)


def test_mitsuba_backend_finds_the_same_faces():
    pytest.importorskip("mitsuba")
    p, t, lo, hi = box()
    o, d = random_rays(2000, seed=3)
    ref = slab_distance(o, d, lo, hi)
    mi = ray_caster(p, t, backend="mitsuba")
    first = mi.intersects_first(o, d)
    assert_array_equal(first >= 0, np.isfinite(ref))
    assert_array_equal(unblocked_local(mi, mi.local(o), d.astype(np.float32)), ~np.isfinite(ref))
    # same face as embree except for rays through a shared edge
    assert np.mean(first == ray_caster(p, t).intersects_first(o, d)) > 0.99


def test_unknown_backend_is_refused():
    p, t, _, _ = box()
    with pytest.raises(ValueError, match="invalid ray backend 'optix'"):
        ray_caster(p, t, backend="optix")

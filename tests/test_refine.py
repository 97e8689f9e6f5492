"""Finer garment mesh where garments overlap (neck, pelvis): one midpoint subdivision."""

from __future__ import annotations

import numpy as np
import pytest

from humv_usd.clothing.fit import REFINE_REGIONS, fit_garment, prepare
from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.human import labels as L
from humv_usd.human.body import build_body


@pytest.fixture(scope="module")
def rig():
    return prepare(build_body("female", 30, 1.65, 60.0))


def _edges(counts, flat):
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    out = []
    for s, c in zip(starts, counts):
        ring = flat[s : s + c]
        out += [tuple(sorted((int(ring[k]), int(ring[(k + 1) % c])))) for k in range(c)]
    return out


@pytest.mark.parametrize("name", ["trousers", "jacket"])
def test_refined_garment_is_crack_free_and_interpolates(rig, name):
    coarse = fit_garment(rig, name, refined=False)
    fine = fit_garment(rig, name, refined=True)
    n = coarse.vertex_count
    assert np.array_equal(fine.points[:n], coarse.points)  # old vertices kept
    assert np.array_equal(fine.joint_indices[:n], coarse.joint_indices)
    split = np.isin(coarse.face_regions, [L.REGION_ID[r] for r in REFINE_REGIONS])
    loose = [k for k, p in enumerate(coarse.garment.parts) if p.loose]
    quads = coarse.face_indices.reshape(-1, 4)
    split &= ~np.isin(coarse.part_of[quads[:, 0]], loose)
    assert split.sum() > 20
    # counts: + one vertex per split edge and per split face; 3 more faces per split face
    split_edges = {tuple(sorted((int(q[k]), int(q[(k + 1) % 4])))) for q in quads[split] for k in range(4)}
    assert fine.vertex_count == n + len(split_edges) + split.sum()
    assert len(fine.face_counts) == len(coarse.face_counts) + 3 * split.sum()
    # no T-junction: no face still uses a split edge; every edge in at most two faces
    edges = _edges(fine.face_counts, fine.face_indices)
    assert not split_edges & set(edges)
    _, uses = np.unique(np.array(edges), axis=0, return_counts=True)
    assert uses.max() <= 2
    # boundary length preserved: boundary edges of the fine mesh = coarse boundary edges,
    # the split ones counted twice (halves)
    c_edges = _edges(coarse.face_counts, coarse.face_indices)
    ce, cu = np.unique(np.array(c_edges), axis=0, return_counts=True)
    c_boundary = {tuple(e) for e in ce[cu == 1]}
    fe, fu = np.unique(np.array(edges), axis=0, return_counts=True)
    assert (fu == 1).sum() == len(c_boundary) + len(c_boundary & split_edges)
    # the fan triangles are not degenerate (fans start at an inserted midpoint)
    tri = fine.points[fan_triangulate(fine.face_counts, fine.face_indices)[0]]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert area.min() > 1e-7
    # same surface (fans of planar-ish quads): area within 1 %
    tri_c = coarse.points[coarse.triangles]
    area_c = 0.5 * np.linalg.norm(np.cross(tri_c[:, 1] - tri_c[:, 0], tri_c[:, 2] - tri_c[:, 0]), axis=1)
    assert area.sum() == pytest.approx(area_c.sum(), rel=0.01)
    # weights: rows sum to 1; a midpoint's dominant joint is one of its parents' joints
    assert np.allclose(fine.joint_weights.sum(axis=1), 1.0, atol=1e-6)
    assert set(np.unique(fine.face_regions)) <= set(np.unique(coarse.face_regions))
    print(f"\n{name}: {n} -> {fine.vertex_count} vertices, {split.sum()} faces split")


def test_dress_refines_only_where_garments_overlap(rig):
    from humv_usd.clothing.collide import dress

    alone = dress(rig, ["trousers"]).garments[0]
    assert alone.vertex_count == fit_garment(rig, "trousers").vertex_count  # nothing over it
    both = {g.name: g for g in dress(rig, ["trousers", "tshirt_white"]).garments}
    full = fit_garment(rig, "trousers", refined=True)
    assert alone.vertex_count < both["trousers"].vertex_count <= full.vertex_count
    assert both["tshirt_white"].vertex_count > fit_garment(rig, "tshirt_white").vertex_count

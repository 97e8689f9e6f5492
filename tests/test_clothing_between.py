"""Garment points between the vertices (edge midpoints, triangle centroids): the fix resolves
those inside the body or an inner garment (issue 4, intersections), not only the vertices."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from humv_usd.clothing.collide import between_samples, push_between, push_out
from humv_usd.geometry.mesh import Surface
from humv_usd.geometry.raycast import RayCaster

GAP = 0.002


def _fix(body: Surface, tri: np.ndarray, faces: np.ndarray, shells=()):
    required = np.full(len(tri), GAP)
    fixed, d, vertex_counts = push_out(body, tri, required, GAP)
    fixed, d, before, after = push_between(body, fixed, d, between_samples(faces), GAP, required, shells)
    return fixed, d, vertex_counts, before, after


def test_triangle_over_a_sphere_cap_with_its_centre_inside_is_fixed():
    """Closed form: the sphere |p| = r; a triangle in the plane z = 0.095 with its corners
    6 cm off the axis has them 12 mm outside (sqrt(0.095^2 + 0.06^2) - 0.1) and its centre
    5 mm inside: the vertex fix sees nothing, the between pass must lift it."""
    r = 0.1
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=r)
    body = Surface(np.asarray(sphere.vertices), np.asarray(sphere.faces))
    angle = np.radians([90.0, 210.0, 330.0])
    tri = np.column_stack([0.06 * np.cos(angle), 0.06 * np.sin(angle), np.full(3, 0.095)])
    faces = np.array([[0, 1, 2]])
    assert np.all(np.linalg.norm(tri, axis=1) - r > GAP)  # corners outside
    assert np.linalg.norm(tri.mean(axis=0)) - r < -0.004  # centre inside
    fixed, d, vertex_counts, before, after = _fix(body, tri, faces)
    assert vertex_counts.inside_before == 0 and vertex_counts.close_before == 0
    assert before[0] == 4  # the centre and the 3 edge midpoints
    assert after == (0, 0, 0)
    ids, w = between_samples(faces)
    samples = np.einsum("sk,ski->si", w, fixed[ids])
    # exact sphere (the mesh is inside it: its chords lie within ~0.1 mm)
    assert np.all(np.linalg.norm(samples, axis=1) - r >= GAP - 2e-4)
    assert np.all(np.linalg.norm(fixed, axis=1) - r >= GAP - 2e-4)
    assert body.closest(samples).signed.min() >= GAP
    assert d.min() >= GAP
    # lifted about along the axis, by about the centre's depth + gap (not thrown away)
    lift = fixed.mean(axis=0) - tri.mean(axis=0)
    assert lift[2] == pytest.approx(r - 0.095 + GAP, abs=1.5e-3)
    assert np.linalg.norm(lift[:2]) < 1e-3


def test_triangle_straddling_a_box_edge_is_fixed():
    """A face whose corners are outside two faces of a box (3 mm off each) while its centre
    and edge midpoints cut through the box's edge: after the fix no sample and no vertex is
    inside the box (ray-parity test, independent of the closest-point sign) or closer than
    the gap (exact box distance)."""
    v, f = trimesh.creation.box(extents=(0.2, 0.2, 0.2)).vertices, trimesh.creation.box().faces
    for _ in range(3):  # 768 faces: interpolated normals bend only along the edges
        v, f = trimesh.remesh.subdivide(np.asarray(v), np.asarray(f))
    body = Surface(v, f)
    tri = np.array([[-0.02, 0.103, 0.07], [0.02, 0.103, 0.07], [0.0, 0.07, 0.103]])
    faces = np.array([[0, 1, 2]])
    caster = RayCaster(v, f)
    ids, w = between_samples(faces)
    assert not caster.inside(tri).any()
    assert caster.inside(np.einsum("sk,ski->si", w, tri[ids])).sum() >= 2
    fixed, d, vertex_counts, before, after = _fix(body, tri, faces)
    assert vertex_counts.inside_before == 0 and before[0] >= 2
    assert after == (0, 0, 0)
    samples = np.einsum("sk,ski->si", w, fixed[ids])
    assert not caster.inside(np.concatenate([samples, fixed])).any()

    def box_distance(p):  # exact distance outside an axis-aligned box
        return np.linalg.norm(np.maximum(np.abs(p) - 0.1, 0.0), axis=1)

    assert box_distance(samples).min() >= GAP - 1e-6
    assert box_distance(fixed).min() >= GAP - 1e-6


def test_between_layers_pushes_an_outer_face_off_an_inner_garment():
    """An outer face over a flat inner garment (a sheet at z = 0, thickness 1 mm): two
    corners 4 mm above it, one 3 mm below it (through the fabric): the pass (with the inner garment
    as a shell) lifts the vertex and the samples to thickness + gap above the sheet."""
    r = 1.0  # body far away: a sphere of 1 m, 0.5 m below the sheet
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=r)
    body = Surface(np.asarray(sphere.vertices) - [0, 0, 1.6], np.asarray(sphere.faces))
    xs = np.linspace(-0.02, 0.02, 5)
    gx, gy = np.meshgrid(xs, xs)
    sheet_pts = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(25)])
    quads = [
        (i * 5 + j, i * 5 + j + 1, (i + 1) * 5 + j + 1, (i + 1) * 5 + j) for i in range(4) for j in range(4)
    ]
    sheet_tris = np.array([t for a, b, c, e in quads for t in ((a, b, c), (a, c, e))])
    from humv_usd.clothing.collide import _flat_normals

    shell = (Surface(sheet_pts, sheet_tris), _flat_normals(sheet_pts, sheet_tris), 0.001)
    # outer triangle: corners 4 mm above the sheet, one 3 mm below it (through the fabric)
    tri = np.array([[-0.01, -0.01, 0.004], [0.01, -0.01, 0.004], [0.0, 0.01, -0.003]])
    faces = np.array([[0, 1, 2]])
    fixed, d, _, before, after = _fix(body, tri, faces, shells=[shell])
    assert before[2] >= 1 and after[2] == 0
    ids, w = between_samples(faces)
    samples = np.einsum("sk,ski->si", w, fixed[ids])
    assert samples[:, 2].min() >= 0.001 + GAP - 1e-6  # the sheet is z = 0 here
    assert fixed[:, 2].min() >= 0.001 + GAP - 1e-6

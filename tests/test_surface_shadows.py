"""Scene surfaces without artefacts (issue 14 deliverable 5): adaptive tessellation at shadow
and footprint edges, a person's cool ground patch, interior air behind walls."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from numpy.testing import assert_allclose
from pxr import Usd, UsdGeom
from scipy.optimize import brentq
from scipy.spatial import ConvexHull
from test_thermal_surfaces import ISOTROPIC_SKY, stage_material

from humv_usd.atmosphere import model as M
from humv_usd.constants import STEFAN_BOLTZMANN as SIGMA
from humv_usd.geometry.camera import Camera, CameraPose
from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.physics.slab import INTERIOR_SURFACE_COEFFICIENT
from humv_usd.pipeline.compose import compose
from humv_usd.scenario import validate
from humv_usd.scene.geometry import box, ground_grid
from humv_usd.thermal import surfaces as SF
from humv_usd.thermal.human import longwave_emissivity
from humv_usd.usd.mesh import triangle_areas

#: afternoon sun from the south-south-west, 37 deg up (humvvex at 14:05)
SUN = np.array(
    [
        -np.sin(np.radians(25)) * np.cos(np.radians(37)),
        -np.cos(np.radians(25)) * np.cos(np.radians(37)),
        np.sin(np.radians(37)),
    ]
)


def _mesh(path, points, counts, indices, material, ground=False, held=None, interior=None):
    tris, tri_face = fan_triangulate(counts, indices)
    return SF.SceneMesh(
        path,
        np.asarray(points, float),
        tris,
        tri_face,
        len(counts),
        stage_material(material),
        held,
        ground,
        stage_material("soil") if ground else None,
        interior,
        np.asarray(counts),
        np.asarray(indices),
        np.eye(4),
        held is None,
    )


def _ground(size=60.0, cells=8):
    return _mesh("/World/Scene/Ground", *ground_grid([size, size], cells), "concrete", ground=True)


def _forcing(times, sun=SUN, up=True, dni=750.0):
    n = len(times)
    one = np.ones(n)
    return SF.SurfaceForcing(
        np.asarray(times, float),
        289.0 * one,
        0.45 * one,
        3.0 * one,
        np.tile(sun, (n, 1)),
        np.full(n, up),
        dni * one,
        100.0 * one,
        550.0 * one,
        sky_shape=ISOTROPIC_SKY,
    )


def _centroids(m):
    starts = np.r_[0, np.cumsum(m.counts)[:-1]]
    return np.array([m.points[m.indices[s : s + c]].mean(axis=0) for s, c in zip(starts, m.counts)])


def _lit_samples(m, scene_meshes, sun):
    """(F, 16) whether 16 points of each face see the sun: trimesh's own ray test, independent
    of the thermal tool's caster."""
    pts = np.concatenate([x.points for x in scene_meshes])
    off = np.cumsum([0] + [len(x.points) for x in scene_meshes])
    tris = np.concatenate([x.triangles + o for x, o in zip(scene_meshes, off)])
    scene = trimesh.Trimesh(pts, tris, process=False)
    starts = np.r_[0, np.cumsum(m.counts)[:-1]]
    cells = np.array([m.points[m.indices[s : s + 4]] for s in starts])
    samples = SF._samples(cells).reshape(-1, 3) + [0.0, 0.0, 1e-3]
    hit = scene.ray.intersects_any(samples, np.tile(sun, (len(samples), 1)))
    return ~hit.reshape(len(cells), -1)


def test_no_face_straddles_the_wall_foot_and_the_sunlit_strip_is_open_pad():
    """A building on a 7.5 m ground grid in the afternoon sun: the faces along its south wall
    were half under the building and came out as a cold strip (humvvex: 288.3 K instead of
    297.7 K); refined, every face is lit or shaded as a whole and the strip is open pad."""
    ground = _ground()
    building = _mesh(
        "/World/Scene/warehouse", *box([0.0, 13.75, 0.0], [20.0, 7.5 + 0.5, 8.0]), "painted_metal"
    )
    # wall face at y = 9.75: inside a ground cell (7.5-15 m), as in humvvex
    times = np.arange(-3 * 3600.0, 0.1, 600.0)
    f = _forcing(times)
    # the tessellation under the open-sky model (exchange=False): with the exchange the wall
    # foot sees the sunlit wall and is warmer than open pad (test_surface_views.py)
    coarse, _ = SF.surface_temperatures(None, [ground, building], [0.0], 3 * 3600.0, f, exchange=False)
    refined, report = SF.refine_meshes([ground, building], f)
    assert report["/World/Scene/Ground"]["refinedFaces"] > ground.n_faces
    assert "/World/Scene/warehouse" not in report  # its faces see the sun whole
    fine, _ = SF.surface_temperatures(None, refined, [0.0], 3 * 3600.0, f, exchange=False)
    g = refined[0]
    lit = _lit_samples(g, refined, SUN)
    straddling = lit.any(axis=1) & ~lit.all(axis=1)
    size = np.array([np.ptp(g.points[g.indices[4 * k : 4 * k + 4]][:, 0]) for k in range(g.n_faces)])
    assert np.all(size[straddling] <= SF.MIN_CELL_M + 1e-9)  # only the smallest cells, on the edge
    t_fine = fine["/World/Scene/Ground"][0]
    c = _centroids(g)
    pad = np.median(t_fine[c[:, 1] < -10.0])
    strip = (np.abs(c[:, 0]) < 8.0) & (c[:, 1] > 7.5) & (c[:, 1] < 9.75 - SF.MIN_CELL_M)
    assert strip.sum() > 10
    assert np.all(np.abs(t_fine[strip] - pad) < 0.05)
    # before: the coarse cell straddling the wall foot (7.5-15 m) was several kelvin colder
    c0 = _centroids(ground)
    foot = (np.abs(c0[:, 0]) < 8.0) & (np.abs(c0[:, 1] - 11.25) < 0.1)
    assert np.all(coarse["/World/Scene/Ground"][0][foot] < pad - 2.0)
    # refined faces tile the same ground: total area kept, parents point at the coarse faces
    area = lambda m: m.face_geometry()[2]  # noqa: E731
    assert area(g).sum() == pytest.approx(area(ground).sum(), rel=1e-9)
    np.testing.assert_allclose(np.bincount(g.parent_face, area(g), ground.n_faces), area(ground), rtol=1e-9)


def _patch(stood_s, after_s=(0.0,), leave_s=np.inf):
    """(pad temperature, ground temperatures (len(after_s), F), refined ground, occluder) for
    a pillar (a standing person's size) at the origin that stood there ``stood_s`` before frame 0."""
    ground = _ground(30.0, 4)
    p_pts, p_counts, p_idx = box([0.0, 0.0, 0.0], [0.45, 0.3, 1.78])
    p_tris, _ = fan_triangulate(p_counts, p_idx)
    spin = 4 * 3600.0
    times = np.r_[np.arange(-spin, 0.0, 600.0), np.asarray(after_s, float)]
    f = _forcing(times)
    occ = SF.standing_occluder(p_pts, p_tris, times, -stood_s, leave_s)
    meshes, _ = SF.refine_meshes([ground], f, occ)
    out, _ = SF.surface_temperatures(None, meshes, np.asarray(after_s, float), spin, f, occ)
    t = out["/World/Scene/Ground"]
    c = _centroids(meshes[0])
    pad = np.median(t[0][np.hypot(c[:, 0], c[:, 1]) > 8.0])
    return pad, t, meshes[0], c


def test_presence_share_of_the_steps():
    t = np.array([-1200.0, -600.0, 0.0, 1.0, 2.0])
    assert_allclose(SF.presence_share(t, -900.0), [0.0, 0.5, 1.0, 1.0, 1.0])
    assert_allclose(SF.presence_share(t, -np.inf, 0.5), [1.0, 1.0, 1.0, 0.5, 0.0])


def test_a_person_who_stood_longer_leaves_a_colder_larger_patch():
    rows = []
    for stood in (0.0, 600.0, 1800.0, 3600.0):
        pad, t, g, c = _patch(stood)
        area = g.face_geometry()[2]
        cool = t[0] < pad - 0.5
        rows.append((stood, float(t[0].min() - pad), float(area[cool].sum())))
    assert abs(rows[0][1]) < 0.01 and rows[0][2] == 0.0  # just arrived: nothing yet
    deficits = [r[1] for r in rows[1:]]
    areas = [r[2] for r in rows[1:]]
    assert deficits[0] < -1.0 and np.all(np.diff(deficits) < 0)  # colder with time stood
    assert np.all(np.diff(areas) >= 0)  # and the patch does not shrink
    # the shadow lies away from the sun: the patch's centre is north-north-east of the pillar
    centre = np.average(c[cool], weights=area[cool], axis=0)
    assert centre[1] > 0.3 and centre[0] > 0.0


def test_the_patch_persists_after_the_person_walks_away():
    after = np.array([0.0, 60.0, 300.0, 600.0])
    pad, t, g, c = _patch(1800.0, after, leave_s=0.0)
    patch = np.argmin(t[0])
    deficit = t[:, patch] - pad
    assert deficit[0] < -2.0
    assert np.all(np.diff(deficit) > 0)  # recovering in the sun ...
    assert deficit[-1] < -0.5  # ... but still there 10 min later


def test_interior_air_warms_the_back_of_a_wall_as_the_closed_form_says():
    """A south wall at night, steady state: eps (E_lw - sigma T^4) + h (T_air - T) +
    (T_in - T) / (d / k + 1 / h_i) = 0 (the wall's conduction in series with ISO 6946's
    inside coefficient)."""
    ground = _mesh("/World/Scene/Ground", *ground_grid([60.0, 60.0], 2), "concrete", ground=True, held=285.0)
    wall_pts = [[-5, 10, 0], [5, 10, 0], [5, 10, 8], [-5, 10, 8]]
    warm = _mesh("/World/Scene/w", wall_pts, [4], [0, 1, 2, 3], "painted_metal", interior=293.0)
    cold = _mesh("/World/Scene/c", np.asarray(wall_pts) + [20, 0, 0], [4], [0, 1, 2, 3], "painted_metal")
    times = np.arange(-3600.0, 0.1, 600.0)
    f = _forcing(times, up=False, dni=0.0)
    f.dhi_w_m2[:] = 0.0
    f.ghi_w_m2[:] = 0.0
    # the closed form's ground reflects the sky only (exchange=False): with the exchange it
    # also reflects the walls' own long wave back to them (+4 mK here)
    out, _ = SF.surface_temperatures(None, [ground, warm, cold], [0.0], 3600.0, f, exchange=False)
    m = stage_material("painted_metal")
    eps, eps_g = longwave_emissivity(m), longwave_emissivity(stage_material("concrete"))
    e_sky = float(f.sky_longwave[0])
    e_lw = 0.5 * e_sky + 0.5 * (eps_g * SIGMA * 285.0**4 + (1 - eps_g) * e_sky)
    h = 2.8 + 3.0 * 3.0
    r_back = m.thickness / m.conductivity + 1.0 / INTERIOR_SURFACE_COEFFICIENT

    def balance(t, t_in):
        back = 0.0 if t_in is None else (t_in - t) / r_back
        return eps * (e_lw - SIGMA * t**4) + h * (289.0 - t) + back

    assert out["/World/Scene/w"][0, 0] == pytest.approx(brentq(balance, 200, 400, args=(293.0,)), abs=1e-3)
    assert out["/World/Scene/c"][0, 0] == pytest.approx(brentq(balance, 200, 400, args=(None,)), abs=1e-3)
    assert out["/World/Scene/w"][0, 0] > out["/World/Scene/c"][0, 0] + 0.1


def _ground_faces(stage):
    g = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Scene/Ground"))
    counts = np.asarray(g.GetFaceVertexCountsAttr().Get())
    indices = np.asarray(g.GetFaceVertexIndicesAttr().Get())
    pts = np.asarray(g.GetPointsAttr().Get(), dtype=float)
    temps = np.asarray(g.GetPrim().GetAttribute("primvars:humv:thermal:temperature").Get(0))
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    cen = np.array([pts[indices[s : s + c]].mean(axis=0) for s, c in zip(starts, counts)])
    return cen, temps, triangle_areas(pts, counts, indices)


@pytest.mark.slow
def test_humvvex_person_shadow_patch_and_wall_foot(raw, tmp_path, monkeypatch):
    """humvvex composed: the person (avatar and clothes posed by UsdSkel) stood 30 min: a cool
    patch north-north-east of their feet; the pad at the warehouse's wall foot is not colder than
    open pad (the old 7.5 m faces made a 2.5 m strip 9 K colder). The refined faces are on the stage."""
    monkeypatch.setenv(M.CACHE_ENV, str(tmp_path / "cache"))
    raw["placement"][0]["standing_before_s"] = 1800.0
    raw["sensor"] = [s for s in raw["sensor"] if s["id"] == "lwir640"]
    compose(validate(raw), tmp_path / "out")
    stage = Usd.Stage.Open(str(tmp_path / "out" / "stage.usda"))
    cen, temps, area = _ground_faces(stage)
    assert len(temps) > 1000  # re-tessellated from 16 x 16
    pad = np.median(temps[(cen[:, 1] < -5.0) & (np.abs(cen[:, 0]) < 30.0)])
    near = np.hypot(cen[:, 0], cen[:, 1]) < 3.0
    cool = near & (temps < pad - 1.0)
    assert area[cool].sum() > 0.3 and temps[near].min() < pad - 3.0
    assert np.average(cen[cool, 1], weights=area[cool]) > 0.0  # in the shadow, away from the sun
    foot = (np.abs(cen[:, 0]) < 15.0) & (cen[:, 1] > 7.5) & (cen[:, 1] < 10.0 - SF.MIN_CELL_M)
    # the old defect was a cold strip; the foot now also sees the sunlit wall (its long wave and
    # reflected sun, issue 25), so it is open pad or warmer, never colder
    assert foot.sum() > 10 and np.all(temps[foot] > pad - 0.1)


def _shadow_polygon(box_lo, box_hi, sun):
    """(hull vertices (V, 2)) of a box's shadow on z = 0: the convex hull of its base corners and
    its top corners projected along the sun (Duffie & Beckman 2013, section 1.9 shading)."""
    xs, ys = (box_lo[0], box_hi[0]), (box_lo[1], box_hi[1])
    base = np.array([[x, y] for x in xs for y in ys])
    top = base - box_hi[2] / sun[2] * sun[:2]
    pts = np.concatenate([base, top])
    return pts[ConvexHull(pts).vertices]


def _distance_to_boundary(points, poly):
    """(n,) distance [m] of 2-D points to a closed polygon's edges."""
    a, b = poly, np.roll(poly, -1, axis=0)
    ab = b - a
    t = np.clip(
        np.einsum("nkx,kx->nk", points[:, None, :] - a[None], ab) / np.einsum("kx,kx->k", ab, ab), 0, 1
    )
    near = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - near, axis=2).min(axis=1)


def test_ground_shadow_edges_are_resolved_to_the_closest_cameras_pixel_footprint():
    """A 2 x 2 x 3 m box on a 2.5 m ground grid in the afternoon sun, seen from its shadow side
    by a 160 x 120 camera with a 40 deg field of view (a pixel spans 4.5 mrad, about 5 cm at
    the shadow): every face the shadow edge crosses is no larger than the pixel footprint there,
    and every face wholly lit or wholly shaded lies on its side of the analytic shadow polygon
    or within one footprint of its edge: the edge is placed within one pixel. Without the
    camera the edge stops at 7.8 cm cells (2.5 m / 2^5, the first size below MIN_CELL_M), larger
    than the footprint."""
    ground = _ground(20.0, 8)
    lo, hi = np.array([-1.0, -1.0, 0.0]), np.array([1.0, 1.0, 3.0])
    box_mesh = _mesh("/World/Scene/box", *box([0.0, 0.0, 0.0], [2.0, 2.0, 3.0]), "painted_metal")
    # on the shadow side (the shadow runs north-north-east), looking down at the box's foot
    origin = np.array([2.0, 9.0, 6.0])
    forward = np.array([0.0, 1.8, 0.0]) - origin
    pose = CameraPose(origin, forward / np.linalg.norm(forward), np.array([0.0, 0.0, 1.0]), 40.0)
    cam = Camera.from_pose(pose, 160, 120)
    ifov = 2.0 * np.tan(np.radians(20.0)) / 160  # pixel pitch / focal length [rad]
    f = _forcing(np.array([-600.0, 0.0]))
    plain, rep0 = SF.refine_meshes([ground, box_mesh], f)
    meshes, rep = SF.refine_meshes([ground, box_mesh], f, cameras=[cam])
    assert rep["/World/Scene/Ground"]["refinedFaces"] > rep0["/World/Scene/Ground"]["refinedFaces"]
    poly = _shadow_polygon(lo, hi, SUN)
    for m, finer in ((plain[0], False), (meshes[0], True)):
        lit = _lit_samples(m, [m, box_mesh], SUN)
        c = _centroids(m)
        size = np.array([np.ptp(m.points[m.indices[4 * k : 4 * k + 4]][:, 0]) for k in range(m.n_faces)])
        depth = (c - origin) @ (forward / np.linalg.norm(forward))
        footprint = depth * ifov
        uv, _ = cam.project(c)
        seen = (uv[:, 0] > 0) & (uv[:, 0] < 160) & (uv[:, 1] > 0) & (uv[:, 1] < 120)
        # faces under the box are inside the polygon too; leave out the box's own footprint
        outside_box = ~np.all((c[:, :2] > lo[:2]) & (c[:, :2] < hi[:2]), axis=1)
        edge = seen & outside_box & lit.any(axis=1) & ~lit.all(axis=1)
        assert edge.sum() > 20
        if finer:
            assert np.all(size[edge] <= footprint[edge] * (1 + 1e-9))
        else:
            assert np.any(size[edge] > footprint[edge])  # the staircase a camera would see
        # where a face is wholly lit or shaded, the analytic edge is at most a footprint away
        # (plus half the face) or on the same side
        d = _distance_to_boundary(c[:, :2], poly)
        inside = np.array([np.all(np.cross(np.roll(poly, -1, 0) - poly, p - poly) >= 0) for p in c[:, :2]])
        whole = seen & outside_box & (lit.all(axis=1) | ~lit.any(axis=1))
        wrong_side = whole & (inside == lit.all(axis=1))
        slack = footprint + 0.71 * size
        if finer:
            assert np.all(d[wrong_side] <= slack[wrong_side])
            # the edge faces straddle the analytic edge: within a footprint of it
            assert np.all(d[edge] <= footprint[edge] + 0.71 * size[edge])

"""Scene surfaces that see their surroundings (issue 25 deliverable 6): sky view factors and
view factors against closed forms, and the long-wave exchange in the slab balance."""

from __future__ import annotations

import numpy as np
import pytest
from test_surface_shadows import _forcing, _mesh

from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.scene.geometry import box, ground_grid
from humv_usd.thermal import surfaces as SF
from humv_usd.thermal.views import face_views

HW = [0.5, 1.0, 2.0, 4.0]


def _canyon(h, w, length=1000.0, patch=0.02):
    """Faces: 0 a small patch at the floor centre, 1 a small patch at the foot of the west wall,
    2 the whole floor, 3 the west wall (normal +x), 4 the east wall (normal -x); a canyon
    ``length`` long along y (long against h and w: the 2-D closed forms hold at its middle)."""
    s, L = patch / 2, length / 2
    quads = [
        [[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]],
        [[-w / 2, -s, 0], [-w / 2 + patch, -s, 0], [-w / 2 + patch, s, 0], [-w / 2, s, 0]],
        [[-w / 2, -L, 0], [w / 2, -L, 0], [w / 2, L, 0], [-w / 2, L, 0]],
        [[-w / 2, -L, 0], [-w / 2, L, 0], [-w / 2, L, h], [-w / 2, -L, h]],
        [[w / 2, L, 0], [w / 2, -L, 0], [w / 2, -L, h], [w / 2, L, h]],
    ]
    pts = np.asarray(quads, float).reshape(-1, 3)
    tris, face = fan_triangulate(np.full(5, 4), np.arange(20))
    return pts, tris, face


@pytest.mark.parametrize("hw", HW)
def test_canyon_sky_view_factors_match_the_closed_forms(hw):
    w = 10.0
    h = hw * w
    pts, tris, face = _canyon(h, w)
    # only the patches and the walls cast: the floor itself is coplanar with the patches
    v = face_views(pts, tris, face, 5, rays=4096)
    svf = v.sky_view_factor
    # floor centre: the walls rise to beta = atan(2H/W) on both sides, svf = cos(beta) (Oke 1981)
    assert svf[0] == pytest.approx(np.cos(np.arctan(2 * hw)), abs=0.01)
    # at the foot of a wall: half the hemisphere is wall, the other side rises to atan(H/W)
    assert svf[1] == pytest.approx(0.5 * np.cos(np.arctan(hw)), abs=0.01)
    # the whole floor (area mean): sqrt(1 + (H/W)^2) - H/W (Johnson & Watson 1984, Hottel's
    # crossed strings); a wall: (1 + W/H - sqrt(1 + (W/H)^2)) / 2
    assert svf[2] == pytest.approx(np.sqrt(1 + hw**2) - hw, abs=0.01)
    assert svf[3] == pytest.approx(0.5 * (1 + 1 / hw - np.sqrt(1 + hw**-2)), abs=0.01)
    # the rest of the floor's hemisphere is the two walls, equally; reciprocity A_f F_fw = A_w F_wf
    f = v.to_faces.toarray()
    assert f[2, 3] == pytest.approx(f[2, 4], abs=0.01)
    assert svf[2] + f[2, 3] + f[2, 4] == pytest.approx(1.0, abs=1e-9)
    assert w * f[2, 3] == pytest.approx(h * f[3, 2], rel=0.03)
    assert v.open_sky_view[0] == 1.0 and v.open_sky_view[3] == pytest.approx(0.5, abs=0.01)


def test_an_open_face_sees_the_whole_sky_and_is_unchanged():
    ground = _mesh("/World/Scene/Ground", *ground_grid([60.0, 60.0], 4), "concrete", ground=True)
    f = _forcing(np.arange(-6 * 3600.0, 0.1, 600.0))
    on, d = SF.surface_temperatures(None, [ground], [0.0], 6 * 3600.0, f)
    off, _ = SF.surface_temperatures(None, [ground], [0.0], 6 * 3600.0, f, exchange=False)
    assert d["meanSkyViewFactor"]["/World/Scene/Ground"] == 1.0
    np.testing.assert_array_equal(on["/World/Scene/Ground"], off["/World/Scene/Ground"])


def _canyon_meshes(hw, w=8.0, length=1000.0):
    h = hw * w
    ground = _mesh(
        "/World/Scene/Ground",
        [[-w / 2, -length / 2, 0], [w / 2, -length / 2, 0], [w / 2, length / 2, 0], [-w / 2, length / 2, 0]],
        [4],
        [0, 1, 2, 3],
        "concrete",
        ground=True,
    )
    if hw == 0:
        return [ground]
    west = [
        [-w / 2, -length / 2, 0],
        [-w / 2, length / 2, 0],
        [-w / 2, length / 2, h],
        [-w / 2, -length / 2, h],
    ]
    east = [[w / 2, length / 2, 0], [w / 2, -length / 2, 0], [w / 2, -length / 2, h], [w / 2, length / 2, h]]
    return [
        ground,
        _mesh("/World/Scene/w", west, [4], [0, 1, 2, 3], "concrete"),
        _mesh("/World/Scene/e", east, [4], [0, 1, 2, 3], "concrete"),
    ]


def test_a_deeper_canyon_floor_stays_closer_to_the_air_on_a_clear_night():
    """A clear night: an open floor radiates to the cold sky and ends well below the air; in a
    canyon it sees the walls instead, so it stays closer to the air and to the walls' own
    temperature as H/W grows (Oke 1981: the canyon floor's nocturnal cooling falls with the
    sky view factor)."""
    times = np.arange(-12 * 3600.0, 0.1, 600.0)
    f = _forcing(times, up=False, dni=0.0)
    f.dhi_w_m2[:] = 0.0
    f.ghi_w_m2[:] = 0.0
    below, gap = [], []
    for hw in [0.0, *HW]:
        out, d = SF.surface_temperatures(None, _canyon_meshes(hw), [0.0], 12 * 3600.0, f, view_rays=2048)
        floor = float(out["/World/Scene/Ground"][0, 0])
        below.append(289.0 - floor)
        if hw:
            gap.append(abs(float(out["/World/Scene/w"][0, 0]) - floor))
            assert d["meanSkyViewFactor"]["/World/Scene/Ground"] == pytest.approx(
                np.sqrt(1 + hw**2) - hw, abs=0.02
            )
    assert below[0] > 4.0  # open floor: several kelvin under the air
    assert np.all(np.diff(below) < 0.0) and below[-1] < 0.35 * below[0]
    assert np.all(np.diff(gap) < 0.0) and gap[-1] < 1.0


def test_a_sunlit_wall_warms_the_ground_at_its_foot():
    """The long wave and reflected sun of a sunlit wall reach the ground at its foot: warmer
    than open pad, the more the closer (the sky-only model had them equal)."""

    ground = _mesh("/World/Scene/Ground", *ground_grid([60.0, 60.0], 8), "concrete", ground=True)
    building = _mesh("/World/Scene/warehouse", *box([0.0, 13.75, 0.0], [20.0, 8.0, 8.0]), "painted_metal")
    times = np.arange(-3 * 3600.0, 0.1, 600.0)
    f = _forcing(times)
    meshes, _ = SF.refine_meshes([ground, building], f)
    out, d = SF.surface_temperatures(None, meshes, [0.0], 3 * 3600.0, f)
    g = meshes[0]
    c = g.face_geometry()[1]
    t = out["/World/Scene/Ground"][0]
    pad = np.median(t[c[:, 1] < -10.0])
    at = [t[np.argmin(np.hypot(c[:, 0] - 1.0, c[:, 1] - y))] for y in (9.7, 9.0, 7.0, 3.0)]  # wall at 9.75
    assert np.all(np.diff(at) < 0.0) and at[-1] > pad and at[0] > pad + 3.0
    assert d["exchangeLastChange_K"] < SF.EXCHANGE_TOLERANCE_K
    # the faces get smaller where the sky view changes (refine_meshes' view_spread), so the
    # warm band at the foot has no staircase: along a line towards the wall, neighbouring faces
    # differ by about 1 K at most (7.5 m faces: 5 K)
    steps = []
    for spread in (np.inf, SF.VIEW_SPREAD):
        ms, _ = SF.refine_meshes([ground, building], f, view_spread=spread)
        t_line = SF.surface_temperatures(None, ms, [0.0], 3 * 3600.0, f)[0]["/World/Scene/Ground"][0]
        g = ms[0]
        starts = np.r_[0, np.cumsum(g.counts)[:-1]]
        lo = np.array([g.points[g.indices[s : s + c]].min(0) for s, c in zip(starts, g.counts)])
        hi = np.array([g.points[g.indices[s : s + c]].max(0) for s, c in zip(starts, g.counts)])
        on = (lo[:, 0] <= 1.0) & (hi[:, 0] > 1.0) & (lo[:, 1] >= -15.0) & (hi[:, 1] <= 9.75)
        steps.append(np.abs(np.diff(t_line[on][np.argsort(lo[on, 1])])).max())
    assert steps[0] > 3.0 and steps[1] < 1.5

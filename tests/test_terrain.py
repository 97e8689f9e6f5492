"""Terrain and the ground to the horizon (issue 30.1): humv_usd.geometry.terrain against closed
forms, the scene tool's ground meshes, and the thermal tool treating zones as ground."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from numpy.testing import assert_allclose
from pxr import Usd, UsdGeom

from humv_usd.avatar.layer import _avatar_rotation_deg, avatar_ground
from humv_usd.errors import InputError
from humv_usd.geometry.terrain import TAPER_SHARE, polyline_distance, terrain_from_section
from humv_usd.scenario import validate
from humv_usd.scene.geometry import ground_grid, horizon_rings, terrain_grid
from humv_usd.scene.ground import FLAT_CELLS, ground_pieces, zone_path
from humv_usd.scene.layer import build
from humv_usd.thermal.surfaces import _refinable
from humv_usd.usd.paths import GROUND


def _scene(terrain=None, horizon=20000.0, size=(100.0, 100.0), material="grass"):
    return {"ground": {"material": material, "size_m": list(size), "horizon_m": horizon}, "terrain": terrain}


def test_flat_default_is_zero_everywhere():
    t = terrain_from_section(None)
    x, y = np.meshgrid(np.linspace(-1e4, 1e4, 7), np.linspace(-1e4, 1e4, 7))
    assert np.all(t.height(x, y) == 0.0)
    assert_allclose(t.normal(x, y), np.broadcast_to([0, 0, 1], x.shape + (3,)))
    assert not t.has_relief


def test_slope_plane_and_its_normal():
    t = terrain_from_section({"slope_deg": [10.0, -5.0]}, (50, 50))
    x, y = np.array([3.0, -400.0]), np.array([7.0, 900.0])  # inside and far beyond the rectangle
    gx, gy = np.tan(np.radians(10.0)), np.tan(np.radians(-5.0))
    assert_allclose(t.height(x, y), gx * x + gy * y)
    n = np.array([-gx, -gy, 1.0]) / np.linalg.norm([-gx, -gy, 1.0])
    assert_allclose(t.normal(x, y), np.broadcast_to(n, (2, 3)), atol=1e-9)


def test_ditch_and_embankment_profiles():
    t = terrain_from_section(
        {
            "cut": [
                {"kind": "ditch", "path_m": [[-40, 0], [40, 0]], "width_m": 4.0, "depth_m": 1.0},
                {"kind": "embankment", "path_m": [[0, 20]], "width_m": 10.0, "depth_m": 2.0},
            ]
        },
        (100, 100),
    )
    # raised cosine: full depth on the line, half at a quarter width, zero at the edge
    assert_allclose(
        t.height(np.array([0.0, 0.0, 0.0, 0.0]), np.array([0.0, 1.0, 2.0, 3.0])), [-1, -0.5, 0, 0], atol=1e-12
    )
    assert t.height(0.0, 20.0) == pytest.approx(2.0)
    # the relief fades to the plane at the rectangle's edge
    assert t.height(50.0, 0.0) == pytest.approx(0.0, abs=1e-12)
    assert t.taper(50.0 - TAPER_SHARE * 100 - 1e-9, 0.0) == pytest.approx(1.0)


def test_hills_have_the_asked_rms_and_follow_the_seed():
    t = terrain_from_section({"hills_m": 2.0, "hill_size_m": 20.0, "seed": 5}, (2000, 2000))
    x, y = np.meshgrid(np.linspace(-800, 800, 300), np.linspace(-800, 800, 300))
    z = t.height(x, y)
    assert np.sqrt(np.mean(z**2)) == pytest.approx(2.0, rel=0.15)  # sum of independent waves
    same = terrain_from_section({"hills_m": 2.0, "hill_size_m": 20.0, "seed": 5}, (2000, 2000))
    other = terrain_from_section({"hills_m": 2.0, "hill_size_m": 20.0, "seed": 6}, (2000, 2000))
    assert np.array_equal(same.height(x, y), z) and not np.allclose(other.height(x, y), z)
    # the normal is the gradient's: compare with the analytic derivative of the waves
    kx, ky, amp, phase = t._waves
    px, py = 13.0, -7.0
    s = -np.sin(kx * px + ky * py + phase) * amp
    n = np.array([-(s @ kx), -(s @ ky), 1.0])
    assert_allclose(t.normal(px, py), n / np.linalg.norm(n), atol=1e-4)


def test_dem_png_is_read_north_up_and_scaled(tmp_path):
    # a 16-bit ramp: black in the west, white in the east; a bright pixel row in the north
    w, h = 5, 4
    img = np.tile(np.linspace(0, 65535, w, dtype=np.uint16), (h, 1))
    img[0, :] = 65535
    path = tmp_path / "dem.png"
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(w, h, 1, oiio.UINT16))
    out.write_image(img[:, :, None].copy())
    out.close()
    t = terrain_from_section(
        {"dem_file": str(path), "dem_size_m": [40.0, 30.0], "dem_height_m": [10.0, 20.0]}, (400, 400)
    )
    # west edge, middle row, east edge at the southern row; northern row white
    assert t.height(-20.0, -15.0) == pytest.approx(10.0)
    assert t.height(20.0, -15.0) == pytest.approx(20.0)
    assert t.height(0.0, -15.0) == pytest.approx(15.0, abs=1e-3)  # 32767.5 rounds to a uint16
    assert t.height(-20.0, 15.0) == pytest.approx(20.0)
    with pytest.raises(InputError, match="dem_file"):
        terrain_from_section({"dem_file": str(tmp_path / "missing.png")}, (10, 10))


def test_zones_strips_and_polyline_distance():
    assert_allclose(polyline_distance([0.0, 5.0, -3.0], [2.0, 0.0, -4.0], [[0, 0], [4, 0]]), [2.0, 1.0, 5.0])
    t = terrain_from_section(
        {
            "zone": [
                {"material": "asphalt", "path_m": [[-50, 0], [50, 0]], "width_m": 6.0},
                {"material": "soil", "path_m": [[0, -50], [0, 50]], "width_m": 2.0},
            ]
        },
        (100, 100),
    )
    names = t.material_at(np.array([0.0, 10.0, 0.0, 0.5]), np.array([20.0, 2.9, 3.1, 0.0]), "grass")
    assert list(names) == ["soil", "asphalt", "soil", "soil"]  # the later zone wins at the crossing
    assert t.material_at(10.0, 3.1, "grass") == "grass"


def test_horizon_rings_cover_the_annulus_with_planar_ccw_faces():
    t = terrain_from_section({"slope_deg": [3.0, 0.0]}, (100, 60))
    p, c, i = horizon_rings(t, (100, 60), 5000.0)
    v = p[i.reshape(-1, 4)]
    n = np.cross(v[:, 2] - v[:, 0], v[:, 3] - v[:, 1])
    assert np.all(n[:, 2] > 0)  # counter-clockwise from above
    # planar on the tilted plane: every corner at the plane's height
    assert_allclose(v[..., 2], t.plane(v[..., 0], v[..., 1]), atol=1e-9)
    # the projected areas add up to the outer rectangle minus the inner one
    area = 0.5 * np.abs(np.cross(v[:, 2, :2] - v[:, 0, :2], v[:, 3, :2] - v[:, 1, :2]))
    scale = 5000.0 / 50.0
    assert area.sum() == pytest.approx(100 * 60 * scale**2 - 100 * 60, rel=1e-9)
    assert len(c) < 1000  # coarse: a few hundred faces to 5 km
    assert horizon_rings(t, (100, 60), 40.0)[0].shape == (0, 3)


def test_horizon_is_capped_at_what_the_path_tables_cover(tmp_path):
    """The farthest ground, the rings' corners at sqrt(2) horizon_m, stays within the slant-path
    tables' last range; a horizon beyond is refused in one line naming the key and the range."""
    from humv_usd.atmosphere.model import PATH_RANGES_M
    from humv_usd.scenario.spec import GROUND

    hi = GROUND.keys["horizon_m"].hi
    assert np.sqrt(2.0) * hi <= PATH_RANGES_M[-1]
    raw = {
        "general": {"name": "t", "start": "2024-06-21T13:00:00", "latitude_deg": 48.1, "longitude_deg": 11.6},
        "scene": {"ground": {"material": "grass", "size_m": [40.0, 40.0], "horizon_m": 50000.0}},
    }
    with pytest.raises(InputError, match=r"horizon_m = 50000.0: allowed range 0.0..21000.0"):
        validate(raw, tmp_path / "t.toml")


def test_flat_ground_keeps_its_grid_and_adds_the_rings():
    pieces = ground_pieces(_scene())
    assert len(pieces) == 1
    path, material, points, counts, indices = pieces[0]
    assert path == GROUND and material == "grass"
    p0, c0, i0 = ground_grid((100.0, 100.0), FLAT_CELLS)
    assert np.array_equal(points[: len(p0)], p0) and np.array_equal(indices[: len(i0)], i0)
    assert points[:, 0].max() == pytest.approx(20000.0)
    none = ground_pieces(_scene(horizon=0.0))
    assert np.array_equal(none[0][2], p0)


def test_terrain_ground_splits_into_zone_meshes_on_the_surface():
    section = {
        "hills_m": 1.0,
        "cell_m": 2.0,
        "zone": [{"material": "asphalt", "path_m": [[-50, 0], [50, 0]], "width_m": 6.0}],
    }
    scene = _scene(section, horizon=1000.0)
    t = terrain_from_section(section, (100, 100))
    pieces = ground_pieces(scene)
    assert [p[0] for p in pieces] == [GROUND, zone_path(0)] and pieces[1][1] == "asphalt"
    _, _, idx, _ = terrain_grid(t, (100, 100), 2.0)
    inner = sum(len(c) for _, _, _, c, _ in pieces) - len(horizon_rings(t, (100, 100), 1000.0)[1])
    assert inner == len(idx) // 3  # every terrain triangle in exactly one piece
    road = pieces[1][2]
    assert np.all(np.abs(road[:, 1]) <= 3.0 + 2.0 + 1e-9)  # the strip, to a cell
    for _, _, points, _, _ in pieces:  # every vertex on the terrain
        assert_allclose(points[:, 2], t.height(points[:, 0], points[:, 1]), atol=1e-5)


@pytest.mark.parametrize(
    ("path", "expect"),
    [([[-50, 0], [50, 0]], 6.0 * 100.0), ([[-30, -30], [30, 30]], 6.0 * 60 * 2**0.5 + np.pi * 3.0**2)],
)
def test_zone_edges_run_along_triangle_edges(path, expect):
    # a 6 m road on a 2 m grid: its edges (y = +-3, mid-cell) become straight mesh edges
    section = {
        "hills_m": 0.5,
        "cell_m": 2.0,
        "zone": [{"material": "asphalt", "path_m": path, "width_m": 6.0}],
    }
    t = terrain_from_section(section, (100, 100))
    _, _, points, counts, indices = ground_pieces(_scene(section, horizon=0.0))[1]
    v = points[indices.reshape(-1, 3)]
    area = 0.5 * np.abs(np.cross(v[:, 1, :2] - v[:, 0, :2], v[:, 2, :2] - v[:, 0, :2])).sum()
    d = polyline_distance(points[:, 0], points[:, 1], np.asarray(path, float))
    assert np.all(d <= 3.0 + 1e-6)  # no vertex outside the strip
    # the strip's area: width x length, plus its two round caps where it ends inside the ground
    assert area == pytest.approx(expect, rel=0.01)
    assert_allclose(points[:, 2], t.height(points[:, 0], points[:, 1]), atol=1e-5)


def test_scene_layer_puts_objects_and_plants_on_the_terrain(tmp_path):
    raw = tomllib.loads(
        """
[general]
name = "t"
start = 2024-06-21T13:00:00
utc_offset_h = 2.0
latitude_deg = 48.1
longitude_deg = 11.6
fps = 1.0
duration_s = 0.0
[scene.ground]
material = "grass"
size_m = [40.0, 40.0]
horizon_m = 500.0
[scene.terrain]
slope_deg = [0.0, 5.0]
hills_m = 0.5
cell_m = 4.0
[[scene.terrain.zone]]
material = "asphalt"
path_m = [[-20.0, 0.0], [20.0, 0.0]]
width_m = 5.0
[[scene.object]]
id = "hut"
material = "wood"
center_m = [5.0, 10.0, 0.0]
size_m = [3.0, 3.0, 2.5]
[[scene.object]]
id = "oak"
kind = "tree"
class = "vegetation"
material = "leaf"
center_m = [-6.0, 8.0, 0.0]
size_m = [4.0, 4.0, 7.0]
"""
    )
    scenario = validate(raw, tmp_path / "t.toml")
    stage = Usd.Stage.Open(build(scenario))
    t = terrain_from_section(scenario["scene"]["terrain"], (40.0, 40.0))

    def world(path):
        prim = stage.GetPrimAtPath(path)
        pts = np.asarray(UsdGeom.Mesh(prim).GetPointsAttr().Get(), dtype=float)
        return pts

    hut = world("/World/Scene/hut")
    base = hut[:, 2].min()
    corners = hut[np.isclose(hut[:, 2], base)]
    ground = t.height(corners[:, 0], corners[:, 1])
    assert np.all(ground >= base - 1e-4) and np.min(ground - base) < 1e-4  # on its lowest corner
    trunk = world("/World/Scene/oak/Trunk")
    assert trunk[:, 2].min() < t.height(-6.0, 8.0) < trunk[:, 2].min() + 0.2  # rooted
    ids = {
        p.GetPath().name: p.GetAttribute("humv:label:instanceId").Get()
        for p in stage.Traverse()
        if p.HasAttribute("humv:label:instanceId")
    }
    assert len(set(ids.values())) == len(ids)  # the zone has its own id
    assert stage.GetPrimAtPath("/World/Scene/GroundZone0").GetCustomDataByKey("humv:groundZone")
    # the thermal tool refines the ground and boxes, not a plant's faces
    for path, refinable in (
        ("/World/Scene/oak/Trunk", False),
        ("/World/Scene/oak/Crown", False),
        ("/World/Scene/hut", True),
    ):
        prim = stage.GetPrimAtPath(path)
        counts = np.asarray(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get())
        assert _refinable(prim, counts) is refinable


def test_avatar_ground_is_the_terrain_in_the_avatar_frame(tmp_path):
    section = {"slope_deg": [3.0, 8.0], "hills_m": 0.4, "cell_m": 4.0}
    scenario = {"scene": {"ground": {"size_m": [40.0, 40.0]}, "terrain": section}}
    place = {"position_m": [2.0, -3.0, 0.25], "heading_deg": 60.0}
    h = avatar_ground(scenario, place)
    t = terrain_from_section(section, (40.0, 40.0))
    phi = np.radians(_avatar_rotation_deg(place))
    local = np.array([[0.0, 0.0], [1.0, 0.0], [0.3, -2.0]])
    world = local @ np.array([[np.cos(phi), np.sin(phi)], [-np.sin(phi), np.cos(phi)]]) + [2.0, -3.0]
    assert_allclose(h(local[:, 0], local[:, 1]), t.height(world[:, 0], world[:, 1]) - 0.25, atol=1e-12)
    flat = {"scene": {"ground": {"size_m": [40.0, 40.0]}, "terrain": None}}
    assert avatar_ground(flat, place) is None  # flat: the motion model's own z = 0


SLOPE_WALK = Path(__file__).resolve().parents[1] / "examples" / "terrain" / "slope_walk.toml"


def test_slope_walk_example_walks_uphill_over_the_terrain():
    """examples/terrain/slope_walk.toml (issue 30.1: people walking over terrain) validates and
    its person's straight walk climbs the terrain: the closed-form rise of the tilted plane along
    the heading, d (cos h tan a_x + sin h tan a_y), within the hills' amplitude."""
    scenario = validate(tomllib.loads(SLOPE_WALK.read_text()), SLOPE_WALK)
    section = scenario["scene"]["terrain"]
    t = terrain_from_section(section, tuple(scenario["scene"]["ground"]["size_m"]))
    place = scenario["placement"][0]
    d = scenario["human"][0]["speed_m_s"] * scenario["general"]["duration_s"]
    h = np.radians(place["heading_deg"])
    x0, y0 = place["position_m"][:2]
    rise = float(t.height(x0 + d * np.cos(h), y0 + d * np.sin(h)) - t.height(x0, y0))
    plane = d * (
        np.cos(h) * np.tan(np.radians(section["slope_deg"][0]))
        + np.sin(h) * np.tan(np.radians(section["slope_deg"][1]))
    )
    assert plane > 0.4 and abs(rise - plane) < 2 * section["hills_m"] + 1e-9


@pytest.mark.extended
def test_slope_walk_example_keeps_the_feet_on_the_terrain(tmp_path):
    """End to end (about a minute here): the example composed without clothing; the avatar
    layer's contact report (humv:contact) over the clip: feet within 5 mm of the terrain, no
    deeper than 5 mm into it (3a6b39a measured 0.000 m on a plain 8 deg slope)."""
    from humv_usd.pipeline.compose import compose

    raw = tomllib.loads(SLOPE_WALK.read_text())
    raw["human"][0]["clothing"] = []
    raw["sensor"][0].update(resolution=[40, 32], pixel_pitch_um=96.0)
    compose(validate(raw, SLOPE_WALK), tmp_path / "walk")
    stage = Usd.Stage.Open(str(tmp_path / "walk" / "stage.usda"))
    report = dict(stage.GetPrimAtPath("/World/Humans/p1").GetCustomDataByKey("humv:contact"))
    assert report["max_gap_m"] < 0.005 and report["max_penetration_m"] < 0.005, report

"""Clothing: catalogue, fabrics, fitting on three bodies, intersection fix, skinning, layer."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import quat_x, ramp_pose
from pxr import Sdf, Usd, UsdGeom, UsdShade

from humv_usd.avatar import layer as avatar_layer
from humv_usd.catalog.garments import GARMENTS, OUTFITS, fabrics, garment
from humv_usd.catalog.materials import FABRICS, LIBRARY, WAVELENGTHS_UM
from humv_usd.clothing import layer as clothing_layer
from humv_usd.clothing.collide import apply, blend_transforms, dress, simulate
from humv_usd.clothing.fit import prepare
from humv_usd.geometry.mesh import Surface, closest_on_triangles
from humv_usd.geometry.raycast import RayCaster
from humv_usd.human.body import build_body
from humv_usd.human.skeleton import forward_kinematics, skinning_matrices
from humv_usd.human.usdskel import skinned_points
from humv_usd.materials import layer as materials_layer
from humv_usd.pipeline.compose import compose_in_memory
from humv_usd.scenario.load import validate
from humv_usd.usd import schemas as S

BODIES = {
    "female_160_55": ("female", 1.60, 55.0),
    "male_178_80": ("male", 1.78, 80.0),
    "male_190_105": ("male", 1.90, 105.0),
}
TOL = 1e-6  # [m] float round-off allowance in distance checks
#: garments added by issue 29, fitted on varied bodies in tests/test_wardrobe.py (one by one on
#: these three bodies in the extended tier: test_issue29_garments_fit_three_bodies)
ISSUE29 = (
    "hair_long",
    "hair_tied",
    "beard",
    "dress",
    "skirt",
    "hoodie",
    "gloves",
    "scarf",
    "beanie",
    "helmet",
    "socks",
)


@pytest.fixture(scope="module")
def rigs():
    return {k: prepare(build_body(sex, 30, h, m)) for k, (sex, h, m) in BODIES.items()}


def _pose(skeleton, bends: dict[str, float], frames: int = 1) -> np.ndarray:
    """Skinning matrices (frames + 1, J, 4, 4): frame 0 rest, then the joints of ``bends``
    rotated about X by the given angles [deg] (ramped over ``frames``)."""
    q = np.zeros((frames + 1, len(skeleton.names), 4))
    q[..., 0] = 1.0
    for f in range(1, frames + 1):
        for joint, deg in bends.items():
            q[f, skeleton.index(joint)] = quat_x(deg * f / frames)
    root = np.repeat(skeleton.rest_positions[:1], frames + 1, axis=0)
    return skinning_matrices(skeleton, forward_kinematics(skeleton, q, root))


# ---------------------------------------------------------------------------- catalogue
def test_catalogue_names_fabrics_and_seed_outfits():
    assert {
        "tshirt_white",
        "tshirt_black",
        "longsleeve",
        "shorts",
        "leggings",
        "trousers",
        "jacket",
        "robe",
        "cap",
    } <= set(GARMENTS)
    assert garment("tshirt").name == "tshirt_white"
    with pytest.raises(ValueError, match="unknown garment 'toga'.*tshirt_white"):
        garment("toga")
    for g in GARMENTS.values():
        assert g.fabric in LIBRARY and 0 < g.thickness <= 0.05 and 0 <= g.ease <= 0.3  # schema: 0-0.05 m
    assert garment("tshirt_white").parts == garment("tshirt_black").parts
    assert garment("tshirt_white").fabric != garment("tshirt_black").fabric
    assert garment("jacket").fabric == "camouflage_nyco"
    assert {n for names in OUTFITS.values() for n in names} <= set(GARMENTS)
    assert fabrics(["jacket", "uniform_trousers", "tshirt"]) == ["camouflage_nyco", "cotton_white"]


def test_fabrics_have_sources_and_plausible_spectra():
    lwir = [i for i, w in enumerate(WAVELENGTHS_UM) if 8.0 <= w <= 14.0]
    vis = WAVELENGTHS_UM.index(0.55)
    for name, m in FABRICS.items():
        assert LIBRARY[name] is m
        assert len(m.reflectance) == len(WAVELENGTHS_UM)
        assert "Belliveau" in m.source or "Bauer" in m.source, name
        assert "Morton & Hearle" in m.source and len(m.source) > 200
        eps = np.array(m.emissivity)[lwir]
        assert np.all((eps >= 0.85) & (eps <= 0.92)), (name, eps)  # measured 0.87-0.90
        assert 0.02 < m.conductivity < 0.1 and 100 < m.density < 700
        assert 1000 <= m.specific_heat <= 1500 and 0 < m.thickness <= 0.003
    assert FABRICS["cotton_white"].reflectance[vis] > 0.7 > 0.1 > FABRICS["cotton_black"].reflectance[vis]
    assert FABRICS["cotton_black"].solar_absorptivity > 2 * FABRICS["cotton_white"].solar_absorptivity


# ---------------------------------------------------------------------------- geometry
def test_closest_point_matches_brute_force():
    rng = np.random.default_rng(1)
    a, b, c = rng.normal(size=(3, 200, 3))
    p = rng.normal(size=(200, 3)) * 2
    bary = closest_on_triangles(p, a, b, c)
    assert np.all(bary >= -1e-12) and np.allclose(bary.sum(axis=1), 1.0)
    got = np.linalg.norm(np.einsum("nj,jni->ni", bary, np.stack([a, b, c])) - p, axis=1)
    # dense barycentric sampling never gets closer than the exact answer
    u, v = np.meshgrid(np.linspace(0, 1, 81), np.linspace(0, 1, 81))
    keep = u + v <= 1
    u, v = u[keep], v[keep]
    samples = (
        a[:, None] * (1 - u - v)[None, :, None]
        + b[:, None] * u[None, :, None]
        + c[:, None] * v[None, :, None]
    )
    brute = np.linalg.norm(samples - p[:, None], axis=2).min(axis=1)
    assert np.all(got <= brute + 1e-12)
    assert np.all(brute - got < 0.02 * np.linalg.norm(b - a, axis=1) + 1e-9)


def test_body_closest_point_matches_brute_force(rigs):
    """The KD-tree candidate search finds the exact closest body point (all triangles)."""
    rig = rigs["male_190_105"]
    rng = np.random.default_rng(2)
    pick = rng.choice(len(rig.mesh.points), 40, replace=False)
    q = rig.mesh.points[pick] + rng.normal(0.0, 0.02, (40, 3))
    got = rig.surface.closest(q)
    tri = rig.mesh.points[rig.triangles]
    for i in range(len(q)):
        bary = closest_on_triangles(q[i], tri[:, 0], tri[:, 1], tri[:, 2])
        best = np.linalg.norm(np.einsum("tj,tji->ti", bary, tri) - q[i], axis=1).min()
        assert abs(got.signed[i]) == pytest.approx(best, abs=1e-5)


# ---------------------------------------------------------------------------- fitting
@pytest.mark.slow
def test_every_garment_fits_three_bodies(rigs):
    """Rest pose: after the fix no vertex is inside the skin (closest-point sign AND an
    independent ray-parity test) and the air gap never drops below the minimum gap."""
    report = {}
    for key, rig in rigs.items():
        caster = RayCaster(rig.mesh.points, rig.triangles)
        skin = _pose(rig.skeleton, {}, frames=0)
        for name in GARMENTS:
            if GARMENTS[name].is_prop or name in ISSUE29:
                continue  # props: tests/test_carry.py; the issue-29 wardrobe: tests/test_wardrobe.py
            sim = simulate(dress(rig, [name]), skin)
            anim = sim.garments[0]
            c = anim.counts[0]
            gap = anim.fitted.garment.minimum_gap
            fixed = anim.posed[0]
            assert c.inside_after == 0 and c.close_after == 0, (key, name, c)
            assert not caster.inside(fixed).any(), (key, name)
            assert rig.surface.closest(fixed).signed.min() >= gap - TOL, (key, name)
            assert anim.air_gap.min() >= gap - TOL, (key, name)
            assert anim.fitted.face_regions.min() >= 1
            report[key, name] = (
                c.inside_before + c.close_before,
                anim.air_gap.min(),
                float(np.median(anim.air_gap)),
            )
    # the garments differ in what they cover and how loose they are, on every body
    for key in rigs:
        assert (
            report[key, "leggings"][2]
            < report[key, "tshirt_white"][2]
            < report[key, "jacket"][2]
            < report[key, "robe"][2]
        )
        assert 0.004 < report[key, "leggings"][2] < 0.012
    print("\n(before fix: inside + closer than the gap, min / median air gap [mm])")
    for (key, name), (before, lo, med) in report.items():
        print(f"{key:14s} {name:16s} {before:4d}  {lo * 1e3:5.2f} / {med * 1e3:5.1f}")


@pytest.mark.extended
@pytest.mark.parametrize("name", ISSUE29)
def test_issue29_garments_fit_three_bodies(rigs, name):
    """As test_every_garment_fits_three_bodies, for each issue-29 garment alone."""
    for key, rig in rigs.items():
        caster = RayCaster(rig.mesh.points, rig.triangles)
        sim = simulate(dress(rig, [name]), _pose(rig.skeleton, {}, frames=0))
        anim = sim.garments[0]
        c, gap = anim.counts[0], anim.fitted.garment.minimum_gap
        assert c.inside_after == 0 and c.close_after == 0, (key, name, c)
        assert not caster.inside(anim.posed[0]).any(), (key, name)
        assert rig.surface.closest(anim.posed[0]).signed.min() >= gap - TOL, (key, name)
        assert anim.air_gap.min() >= gap - TOL, (key, name)


def test_coverage_follows_the_catalogue(rigs):
    rig = rigs["male_178_80"]
    from humv_usd.clothing.fit import fit_garment
    from humv_usd.human.labels import BODY_REGION_NAMES

    def regions(name):
        return {BODY_REGION_NAMES[r] for r in np.unique(fit_garment(rig, name).face_regions)}

    assert {"chest", "back", "leftUpperArm"} <= regions("tshirt_white")
    assert "leftLowerArm" not in regions("tshirt_white")
    assert "leftLowerArm" in regions("longsleeve")
    assert regions("leggings") >= {"pelvis", "leftUpperLeg", "leftLowerLeg"}
    assert "leftLowerLeg" not in regions("shorts") and "chest" not in regions("shorts")
    assert regions("cap") == {"head"}
    with pytest.raises(ValueError, match="listed twice"):
        dress(rig, ["tshirt", "tshirt_white"])
    z = fit_garment(rig, "robe").points[:, 2]
    assert z.min() < 0.2 * rig.body.stature_m  # the skirt reaches the shins


def test_garments_follow_a_bent_knee(rigs):
    """Leggings on a flexed hip and knee: the shin part moves with the shin and keeps its
    rest offset from the skin; around the knee it stays within a few mm of it."""
    rig = rigs["male_178_80"]
    sk = rig.skeleton
    skin = _pose(sk, {"LeftUpLeg": -40.0, "LeftLeg": 70.0})
    anim = simulate(dress(rig, ["leggings"]), skin).garments[0]
    body = apply(blend_transforms(rig.joint_indices, rig.joint_weights, skin[1]), rig.mesh.points)
    d0 = rig.surface.closest(anim.posed[0]).signed
    d1 = Surface(body, rig.triangles).closest(anim.posed[1]).signed
    j = sk.index("LeftLeg")
    head, tail = sk.rest_positions[j], sk.tail_positions[j]
    t = (anim.fitted.points - head) @ (tail - head) / np.dot(tail - head, tail - head)
    left = anim.fitted.points[:, 0] > 0.03
    shin = left & (t > 0.2) & (t < 0.9)
    knee = left & (t >= -0.1) & (t <= 0.2)
    moved = np.linalg.norm(anim.posed[1][shin] - anim.posed[0][shin], axis=1)
    assert shin.sum() > 50 and np.median(moved) > 0.1
    assert np.abs(d1 - d0)[shin].max() < 0.001
    assert np.median(np.abs(d1 - d0)[knee]) < 0.002 and np.abs(d1 - d0)[knee].max() < 0.01
    assert d1.min() >= anim.fitted.garment.minimum_gap - TOL
    assert anim.counts[1].inside_after == 0


def test_fix_detects_and_removes_intersections_in_a_stride(rigs):
    """A deep stride drives garments into the body (the check must see it, and an
    independent parity test must agree); after the fix none is inside, for a full outfit."""
    rig = rigs["female_160_55"]
    skin = _pose(
        rig.skeleton,
        {"LeftUpLeg": -50.0, "LeftLeg": 60.0, "RightUpLeg": 25.0, "LeftArm": 40.0, "RightArm": -40.0},
        frames=2,
    )
    outfit = dress(rig, ["trousers", "tshirt_black", "jacket", "robe", "cap"])
    sim = simulate(outfit, skin)
    body = apply(blend_transforms(rig.joint_indices, rig.joint_weights, skin[-1]), rig.mesh.points)
    caster, surface = RayCaster(body, rig.triangles), Surface(body, rig.triangles)
    before = 0
    for anim in sim.garments:
        g = anim.fitted
        unfixed = apply(blend_transforms(g.joint_indices, g.joint_weights, skin[-1]), g.points)
        before += int(caster.inside(unfixed).sum())
        assert caster.inside(unfixed).sum() <= anim.counts[-1].inside_before + 2
        for c in anim.counts:
            assert c.inside_after == 0 and c.close_after == 0, (anim.name, c)
        assert not caster.inside(anim.posed[-1]).any(), anim.name
        assert surface.closest(anim.posed[-1]).signed.min() >= g.garment.minimum_gap - TOL
    assert before > 20
    # layering: the jacket stays outside the T-shirt where both are
    order = [a.name for a in sim.garments]
    assert order.index("tshirt_black") < order.index("jacket")


# ---------------------------------------------------------------------------- layer
@pytest.fixture(scope="module")
def clothed_stage(humvvex_raw):
    raw = dict(humvvex_raw)
    raw["general"] = dict(raw["general"], duration_s=0.1)  # 3 frames at 30 fps
    scenario = validate(raw)
    human = scenario["human"][0]
    frames = scenario.frame_count
    _, pose = ramp_pose(scenario, human, {"RightUpLeg": -30.0, "RightLeg": 60.0})  # a knee bend
    garments = ["tshirt_white", "leggings", "cap"]
    avatar = avatar_layer.build_one(scenario, human, motion=pose)
    upstream = compose_in_memory([avatar], scenario["general"]["fps"])
    clothing = clothing_layer.build_one(scenario, human, upstream, garments=garments)
    original = materials_layer.used_materials
    try:  # these garments differ from the scenario's outfit: give the materials tool their fabrics
        materials_layer.used_materials = lambda s: sorted(set(original(s)) | set(fabrics(garments)))
        materials = materials_layer.build(scenario)
    finally:
        materials_layer.used_materials = original
    stage = compose_in_memory([materials, avatar, clothing], scenario["general"]["fps"])
    return stage, clothing, garments, frames


def test_layer_structure_materials_and_air_gap(clothed_stage):
    stage, layer, garments, frames = clothed_stage
    assert layer.GetPrimAtPath("/World/Humans").specifier == Sdf.SpecifierOver
    assert layer.GetPrimAtPath("/World/Humans/p1").specifier == Sdf.SpecifierOver
    for name in garments:
        prim = stage.GetPrimAtPath(f"/World/Humans/p1/Clothing/{name}")
        assert prim.IsA(UsdGeom.Mesh) and prim.HasAPI(S.CLOTHING_API)
        assert prim.GetAttribute(S.CLOTHING_GARMENT).Get() == name
        assert prim.GetAttribute(S.CLOTHING_EASE).Get() == pytest.approx(garment(name).ease)
        material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        assert material and material.GetPrim().HasAPI(S.MATERIAL_API)
        assert material.GetPath().name == garment(name).fabric
        assert (
            material.GetPrim().GetAttribute(S.MATERIAL_SOURCE).Get() == LIBRARY[garment(name).fabric].source
        )
        n = len(UsdGeom.Mesh(prim).GetPointsAttr().Get(0))
        gap = UsdGeom.PrimvarsAPI(prim).GetPrimvar("humv:clothing:airGap")
        assert gap.GetInterpolation() == UsdGeom.Tokens.vertex
        times = gap.GetAttr().GetTimeSamples()
        assert times == [float(f) for f in range(frames)]
        for t in times:
            values = np.asarray(gap.Get(t))
            assert len(values) == n and values.min() >= garment(name).minimum_gap - TOL
        fix = prim.GetCustomDataByKey("humv:clothing:fix")
        assert fix["insideAfterMax"] == 0 and fix["frames"] == frames
        # garments inherit the person's instance id (nearest labelled ancestor)
        assert not prim.HasAPI(S.LABEL_API)
        assert prim.GetParent().GetParent().GetAttribute(S.LABEL_INSTANCE_ID).Get() >= 1


def test_usdskel_poses_garments_outside_the_posed_body(clothed_stage):
    """What the render sees: the garments' point cache keeps every vertex at least the minimum
    gap outside the UsdSkel-skinned body, at every frame."""
    stage, _, garments, frames = clothed_stage
    body_path = "/World/Humans/p1/Body"
    counts = UsdGeom.Mesh(stage.GetPrimAtPath(body_path)).GetFaceVertexCountsAttr().Get()
    indices = UsdGeom.Mesh(stage.GetPrimAtPath(body_path)).GetFaceVertexIndicesAttr().Get()
    from humv_usd.geometry.mesh import fan_triangulate

    tris, _ = fan_triangulate(np.asarray(counts), np.asarray(indices))
    rest_legs = None
    for f in range(frames):
        body = skinned_points(stage, body_path, Usd.TimeCode(f))
        surface = Surface(body, tris)
        for name in garments:
            pts = skinned_points(stage, f"/World/Humans/p1/Clothing/{name}", Usd.TimeCode(f))
            assert surface.closest(pts).signed.min() >= garment(name).minimum_gap - 1e-5
            if name == "leggings":
                rest_legs = pts if rest_legs is None else rest_legs
                last_legs = pts
    assert np.abs(last_legs - rest_legs).max() > 0.1  # the bent right leg moved them


def test_bake_skinning_and_the_render_agree_on_garments(clothed_stage):
    """Standard consumers deform the garments as the render does: ``UsdSkel.BakeSkinning`` of
    a flattened copy of the stage puts every garment (and body) vertex within 1 mm of the
    render's points (:class:`SceneMeshes`) at every frame. Garments are a plain point cache
    (no skel binding, a time sample per frame); with the former time-sampled rest points under
    a skel binding BakeSkinning skinned the default rest points instead (65-80 mm off on
    examples/walk.toml)."""
    from pxr import Gf, UsdSkel

    from humv_usd.render.scene_export import SceneMeshes

    stage, _, garments, frames = clothed_stage
    meshes = SceneMeshes(stage)
    paths = ["/World/Humans/p1/Body", *(f"/World/Humans/p1/Clothing/{n}" for n in garments)]
    render = {}
    for path in paths:
        for f in range(frames):
            pts, m = meshes.points(stage.GetPrimAtPath(path), path, Usd.TimeCode(f), UsdGeom.XformCache(f))
            render[path, f] = pts @ m[:3, :3] + m[3, :3]
    baked = Usd.Stage.Open(stage.Flatten())  # BakeSkinning writes into the edit target
    worst = 0.0
    assert UsdSkel.BakeSkinning(baked.Traverse(), Gf.Interval(0, frames - 1))
    for path in paths:
        prim = baked.GetPrimAtPath(path)
        if "/Clothing/" in path:
            assert not stage.GetPrimAtPath(path).HasAPI(UsdSkel.BindingAPI)
            assert UsdGeom.Mesh(prim).GetPointsAttr().GetTimeSamples() == [float(f) for f in range(frames)]
        for f in range(frames):
            pts = np.asarray(UsdGeom.Mesh(prim).GetPointsAttr().Get(f), dtype=float)
            m = np.asarray(UsdGeom.XformCache(f).GetLocalToWorldTransform(prim))
            distance = np.linalg.norm(pts @ m[:3, :3] + m[3, :3] - render[path, f], axis=1)
            worst = max(worst, float(distance.max()))
    print(f"BakeSkinning vs render: max {worst * 1e3:.4f} mm over {frames} frames")
    assert worst < 1e-3


def test_static_person_gets_one_value(humvvex_raw):
    scenario = validate(humvvex_raw)  # one frame, standing
    # the clothing tool reads the person from the avatar layer
    upstream = compose_in_memory(
        [avatar_layer.build_one(scenario, scenario["human"][0])], scenario["general"]["fps"]
    )
    layer = clothing_layer.build_one(scenario, scenario["human"][0], upstream, garments=["shorts"])
    stage = Usd.Stage.Open(layer)
    prim = stage.GetPrimAtPath("/World/Humans/p1/Clothing/shorts")
    gap = prim.GetAttribute(S.AIR_GAP_PRIMVAR)
    assert gap.GetNumTimeSamples() == 0 and len(gap.Get()) == len(UsdGeom.Mesh(prim).GetPointsAttr().Get())
    assert clothing_layer.layer_name("p1") == "clothing_p1"
    assert set(clothing_layer.build(scenario, upstream)) == {"clothing_p1"}  # humvvex is dressed
    humvvex_raw = dict(humvvex_raw, human=[dict(humvvex_raw["human"][0], clothing=[])])
    assert clothing_layer.build(validate(humvvex_raw), None) == {}  # nobody wears anything

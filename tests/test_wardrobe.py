"""The issue-29 wardrobe: hair styles, garments and worn props fitted to varied bodies and
layered without intersections (independent ray-parity checks against the posed body and the
props' closed meshes)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import quat_x
from pxr import Usd

from humv_usd.avatar.api import avatar_scenario_dict
from humv_usd.catalog.garments import GARMENTS, garment
from humv_usd.catalog.materials import LIBRARY
from humv_usd.clothing.collide import apply, blend_transforms, dress, simulate
from humv_usd.clothing.fit import WORN_PROP_CLEARANCE, prepare
from humv_usd.clothing.person import FIT_DATA, fit_proportions
from humv_usd.geometry.mesh import Surface, fan_triangulate
from humv_usd.geometry.raycast import RayCaster
from humv_usd.human import labels as L
from humv_usd.human.body import build_body
from humv_usd.human.carry import CLEARANCE, apply_rifle_carry
from humv_usd.human.motion import make_motion
from humv_usd.human.skeleton import forward_kinematics, skeleton_for, skinning_matrices
from humv_usd.scenario.inputs import DERIVED_PER_PERSON
from humv_usd.scenario.load import validate
from humv_usd.usd.paths import human_path

NEW = (
    "hair_long", "hair_tied", "beard", "dress", "skirt", "hoodie", "gloves", "scarf", "beanie",
    "helmet", "socks", "shotgun", "backpack", "bag", "phone", "glasses",
)  # fmt: skip
#: one layered outfit per body: a girl of 8, a man of BMI 40, a tall woman
CASES = {
    "girl_8": (("female", 8.0, 1.28, 26.0), ("hair_long", "socks", "shoes", "dress", "beanie", "bag")),
    "man_bmi40": (
        ("male", 45.0, 1.76, 124.0),
        ("hair_tied", "beard", "jeans", "tshirt_white", "hoodie", "scarf", "gloves", "backpack", "glasses"),
    ),
    "woman_tall": (
        ("female", 70.0, 1.80, 70.0),
        ("hair_short", "leggings", "skirt", "longsleeve", "winter_coat", "helmet", "phone"),
    ),
}
TOL = 1e-6
TRUNK = [L.REGION_ID[r] for r in ("chest", "abdomen", "back", "pelvis", "leftUpperLeg", "rightUpperLeg")]


def test_catalogue_has_the_wardrobe():
    assert len(GARMENTS) >= 25
    for name in NEW:
        g = garment(name)
        assert g.description and LIBRARY[g.fabric].source
        assert g.is_prop == (name in ("shotgun", "backpack", "bag", "phone", "glasses"))


def _stride(skeleton):
    """Skinning matrices (2, J, 4, 4): rest, then a stride with the arms swung."""
    bends = {"LeftUpLeg": -35.0, "LeftLeg": 40.0, "RightUpLeg": 20.0, "LeftArm": 30.0, "RightArm": -30.0}
    q = np.zeros((2, len(skeleton.names), 4))
    q[..., 0] = 1.0
    for joint, deg in bends.items():
        q[1, skeleton.index(joint)] = quat_x(deg)
    root = np.repeat(skeleton.rest_positions[:1], 2, axis=0)
    return skinning_matrices(skeleton, forward_kinematics(skeleton, q, root))


@pytest.mark.parametrize(
    "case",
    # one case in `make test` (~10 s), the other two in `make test-extended`
    [
        "man_bmi40",
        pytest.param("girl_8", marks=pytest.mark.extended),
        pytest.param("woman_tall", marks=pytest.mark.extended),
    ],
)
def test_layered_outfit_on_a_varied_body(case):
    (sex, age, stature, mass), outfit = CASES[case]
    rig = prepare(build_body(sex, age, stature, mass))
    skin = _stride(rig.skeleton)
    sim = simulate(dress(rig, outfit), skin)
    assert sorted(a.name for a in sim.garments) == sorted(outfit)
    holding = np.isin(rig.face_regions, [L.REGION_ID[r] for r in ("leftHand", "rightHand")])
    for f in range(skin.shape[0]):
        body = apply(blend_transforms(rig.joint_indices, rig.joint_weights, skin[f]), rig.mesh.points)
        caster, surface = RayCaster(body, rig.triangles), Surface(body, rig.triangles)
        free = np.unique(np.asarray(rig.triangles)[~holding[rig.triangle_face]])  # not the hands
        trunk = np.unique(np.asarray(rig.triangles)[np.isin(rig.face_regions, TRUNK)[rig.triangle_face]])
        for anim in sim.garments:
            g = anim.fitted
            if g.garment.is_prop:
                # no body vertex (hands aside) inside the prop's closed mesh (parity test)
                tris, _ = fan_triangulate(g.face_counts, g.face_indices)
                inside = RayCaster(anim.posed[f], tris).inside(body[free])
                assert not inside.any(), (case, g.name, f)
                if g.garment.prop.placement in ("on_back", "at_left_hip") and f == 0:
                    # the clearance it was placed with, from the trunk (arms swing past it)
                    gap = Surface(anim.posed[f], tris).closest(body[trunk]).signed
                    assert np.abs(gap).min() >= WORN_PROP_CLEARANCE - 1e-3, (case, g.name)
                continue
            c = anim.counts[f]
            assert c.inside_after == 0 and c.close_after == 0 and c.layered_after == 0, (case, g.name, f, c)
            # between the vertices: no face of a garment inside one under it (edge midpoints and
            # centroids inside the body are not asserted: shoes and boots on toes have them too)
            assert c.between_layered_after == 0, (case, g.name, f, c)
            assert not caster.inside(anim.posed[f]).any(), (case, g.name, f)
            assert surface.closest(anim.posed[f]).signed.min() >= g.garment.minimum_gap - TOL, (case, g.name)
            assert g.face_regions.min() >= 1  # every garment face has a body region label


def test_the_shotgun_is_carried_like_the_rifle_and_clears_the_body():
    body = build_body("male", 30, 1.78, 80.0)
    skeleton = skeleton_for(body.points, body.groups)
    walk = make_motion("walk", skeleton, 30, 12, mass_kg=80.0, body_points=body.points)
    report = {}
    apply_rifle_carry(walk, skeleton, body, report=report, prop=garment("shotgun").prop)
    assert report["minDistanceAfter_m"].min() >= CLEARANCE - 1e-3
    assert max(report["graspErrorMax_m"].values()) < 1e-3  # both hands on the gun
    raw = avatar_scenario_dict()
    raw["human"][0]["clothing"] = ["shotgun"]
    assert DERIVED_PER_PERSON["@carriesRifle"](validate(raw), "p1")


def test_the_clothing_tool_rebuilds_the_proportions_the_avatar_used():
    stage = Usd.Stage.CreateInMemory()
    prim = stage.DefinePrim(human_path("p1"))
    assert fit_proportions(stage, "p1") == 0.5  # not recorded: none
    prim.SetCustomDataByKey(FIT_DATA, {"macros": {"proportions": 0.8, "weight": 0.4}})
    assert fit_proportions(stage, "p1") == 0.8
    prim.SetCustomDataByKey(FIT_DATA, {"macros": {"proportions": "x"}})
    assert fit_proportions(stage, "p1") == 0.5
    assert fit_proportions(stage, "nobody") == 0.5

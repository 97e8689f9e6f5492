"""The seed's Table 1 options, each reachable from the scenario, each changing the thermal
signature the physical way (JOS-3, skin per facet, coupled garment balance)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from pxr import Usd, UsdGeom

from humv_usd.human import labels as L
from humv_usd.pipeline.compose import compose
from humv_usd.scenario import validate
from humv_usd.usd import avatar as UA
from humv_usd.usd import schemas as S

pytestmark = pytest.mark.slow

SEGMENTS = list(L.JOS3_SEGMENTS)
TORSO = [SEGMENTS.index(s) for s in ("Chest", "Back")]
LEGS = [SEGMENTS.index(s) for s in ("LLeg", "RLeg")]  # shins: bare under shorts
FEET = [SEGMENTS.index(s) for s in ("LFoot", "RFoot")]
#: a 6 m wall 2.5 m south of the person: the afternoon sun (south-south-west, 38 deg up)
#: leaves the person in its shadow; "full sun or shadow" is the scene's geometry
SHADE_WALL = {
    "id": "shade",
    "kind": "box",
    "class": "building",
    "material": "painted_metal",
    "center_m": [0.0, -2.5, 0.0],
    "size_m": [12.0, 0.3, 6.0],
    "temperature_k": 289.0,
}


def _faces(stage, path):
    prim = stage.GetPrimAtPath(path)
    return np.asarray(prim.GetAttribute(S.TEMPERATURE_PRIMVAR).Get(0), dtype=float)


def _segments(stage, path):
    return L.jos3_segments(np.asarray(stage.GetPrimAtPath(path).GetAttribute(UA.BODY_REGION_PRIMVAR).Get()))


def _signature(stage) -> dict:
    """Mean skin, skin by segment group, each garment's mean and the outermost surface
    (garment where one covers, else skin) over the torso and the legs [K]."""
    body = "/World/Humans/p1/Body"
    skin, seg = _faces(stage, body), _segments(stage, body)
    sig = {"skin": skin.mean(), "torso_skin": skin[np.isin(seg, TORSO)].mean()}
    sig["head_skin"] = skin[seg == SEGMENTS.index("Head")].mean()
    sig["legs_skin"] = skin[np.isin(seg, LEGS)].mean()
    sig["feet_skin"] = skin[np.isin(seg, FEET)].mean()
    outer = {"torso": [skin[np.isin(seg, TORSO)]], "legs": [skin[np.isin(seg, LEGS)]]}
    clothing = stage.GetPrimAtPath("/World/Humans/p1/Clothing")
    for child in clothing.GetChildren() if clothing else []:
        path = str(child.GetPath())
        t, s = _faces(stage, path), _segments(stage, path)
        sig[child.GetName()] = t.mean()
        for key, group in (("torso", TORSO), ("legs", LEGS)):
            if np.isin(s, group).sum() > 50:
                outer[key] = [t[np.isin(s, group)]]  # a garment hides the skin under it
    sig.update({f"{k}_outer": np.concatenate(v).mean() for k, v in outer.items()})
    props = stage.GetPrimAtPath("/World/Humans/p1/Props")
    for prop in Usd.PrimRange(props) if props else []:
        if prop.IsA(UsdGeom.Mesh):
            sig.setdefault("props", []).append(_faces(stage, str(prop.GetPath())).mean())
    return sig


@pytest.fixture(scope="module")
def signature(tmp_path_factory, humvvex_raw):
    """signature(**changes) composes humvvex (JOS-3, held surfaces, one LWIR camera, analytic
    sky, few rays) with the changes into one folder (unchanged layers are reused)."""
    out = tmp_path_factory.mktemp("table1")
    base = copy.deepcopy(humvvex_raw)
    base["thermal"].update(model="jos3", radiation_rays=16, radiation_resolution=45)
    base["scene"]["ground"]["temperature_k"] = 297.0
    base["scene"]["object"][0]["temperature_k"] = 293.0
    base["atmosphere"]["model"] = "analytic"
    base["sensor"] = base["sensor"][:1]
    cache = {}

    def run(clothing=("tshirt_white", "shorts"), shade=False, **human):
        key = (tuple(clothing), shade, tuple(sorted(human.items())))
        if key not in cache:
            raw = copy.deepcopy(base)
            raw["human"][0].update(clothing=list(clothing), **human)
            if shade:
                raw["scene"]["object"].append(dict(SHADE_WALL))
            compose(validate(raw), out)
            cache[key] = _signature(Usd.Stage.Open(str(out / "stage.usda")))
        return cache[key]

    return run


def test_shadow_cooler_than_full_sun(signature):
    sun, shade = signature(), signature(shade=True)
    assert shade["skin"] < sun["skin"] - 0.5
    assert shade["tshirt_white"] < sun["tshirt_white"] - 1.0
    assert shade["torso_outer"] < sun["torso_outer"] - 1.0


def test_black_shirt_warmer_than_white_in_the_sun(signature):
    white = signature(("tshirt_white", "shorts"))
    black = signature(("tshirt_black", "shorts"))
    assert black["tshirt_black"] > white["tshirt_white"] + 2.0
    # in the shade the colour matters far less (no sun to absorb)
    w, b = (
        signature(("tshirt_white", "shorts"), shade=True),
        signature(("tshirt_black", "shorts"), shade=True),
    )
    assert abs(b["tshirt_black"] - w["tshirt_white"]) < 0.5 * (black["tshirt_black"] - white["tshirt_white"])


def test_bare_upper_body_shows_warm_skin_a_shirt_hides_it(signature):
    bare, shirt = signature(("shorts",)), signature(("tshirt_white", "shorts"))
    assert bare["torso_outer"] > shirt["torso_outer"] + 2.0  # the LWIR sees skin vs fabric
    assert shirt["torso_skin"] > bare["torso_skin"]  # insulated skin stays warmer


@pytest.mark.parametrize("outfit", [("tshirt_white", "leggings"), ("uniform_trousers", "jacket"), ("robe",)])
def test_covered_legs_warmer_skin_cooler_outside(signature, outfit):
    """Shins covered (leggings, uniform trousers, robe) vs bare under shorts: the insulated
    skin is warmer, and what the camera sees is the fabric, colder than that skin."""
    shorts = signature(("tshirt_white", "shorts"))
    covered = signature(outfit)
    assert covered["legs_skin"] > shorts["legs_skin"] + 0.3
    assert covered["legs_outer"] < covered["legs_skin"]


def test_post_exercise_and_walking_warmer_skin_than_standing(signature):
    stand = signature()
    after = signature(activity="postExercise")
    walk = signature(activity="walk")
    assert after["skin"] > stand["skin"] + 0.2
    assert walk["skin"] > stand["skin"] + 0.2


def test_standing_and_turning_reachable(signature):
    turn = signature(activity="standTurn")
    assert 295.0 < turn["skin"] < 310.0


def test_weapon_is_a_cool_prop_in_front_of_the_body(signature):
    armed = signature(("tshirt_white", "shorts", "rifle"))
    assert len(armed["props"]) >= 1
    assert all(t < armed["torso_skin"] - 3.0 for t in armed["props"])


def test_female_and_male_differ(signature):
    male, female = signature(), signature(sex="female", stature_m=1.65, mass_kg=60.0)
    assert abs(female["skin"] - male["skin"]) > 0.05


def test_hair_insulates_the_scalp_and_shows_cooler(signature):
    """Head hair (``hair_short`` in [[human]] clothing; its own fibre+air layer) keeps the scalp
    warmer than bare and shows the camera a cooler surface than the skin under it; shoes
    likewise over the feet."""
    bald = signature(("tshirt_white", "shorts"))
    hair = signature(("tshirt_white", "shorts", "hair_short", "shoes"))
    assert hair["head_skin"] > bald["head_skin"]
    assert hair["hair_short"] < hair["head_skin"]
    # against the skin of the feet, not the whole body: shoes stand ~6 mm off the feet since
    # clothing v5, and the feet under them run warmer (307 K) than the mean skin (304 K)
    assert hair["shoes"] < hair["feet_skin"]

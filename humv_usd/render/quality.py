"""The automatic quality of a render: stopping rules, batching and error summaries per region.

One module for what decides how many samples an image gets and what its stated error means
(issues 24 and 25). The render (:mod:`humv_usd.pipeline.render`) renders a frame in batches of
independent samples (:data:`AUTO_SEED_STRIDE` apart) until the error targets are met on the
image *and* on every labelled region class it shows, people first, or the sample cap is spent:

- **Regions.** A pixel's region is the label class of the surface its pixel-centre ray hits
  (``humv:label:class`` at the prim that carries the instance id, as the ground truth's class;
  "background" for the sky). The render computes it from its own first hit
  (:func:`region_map`), so the labels (ground truth) and the render stay independent.
- **Targets** (away from geometric edges, where a pixel's footprint mixes surfaces and the
  spread is signal): the mean per-pixel error <= NETD / :data:`AUTO_NETD_FRACTION` and its 99th
  percentile <= :data:`AUTO_P99_K`, on the image and on each region with at least
  :data:`MIN_REGION_PIXELS` such pixels (:func:`verdict`). The person is 0.7 % of the humvvex
  frame: an image-only rule stopped at 2 spp with 11 mK while the person's pixels carried
  349 mK (issue 25).
- **Per-pixel error that can be trusted.** Each batch's estimator gives a pixel mean and its
  standard error from r independent replicas (r - 1 degrees of freedom); :class:`Batches`
  pools the replicas' spread within each batch with the spread of the batch means between
  batches (one-way analysis of variance; the pooled estimate has k r - 1 degrees of freedom
  after k batches), and at least :data:`MIN_BATCHES` batches are taken, so that each pixel's
  error rests on >= 4 replicas (3 degrees of freedom; with 2 replicas, 1 degree of freedom,
  8-13 % of skin pixels deviated by more than 4 sigma).
- **Outliers** are counted per region (:func:`region_stats`): pixels whose camera samples saw a
  one-sided face from behind (rendered as the cavity radiance, see
  :func:`humv_usd.render.estimator.cavity_table`) and pixels whose stated error is above
  :data:`UNRESOLVED_K` (not resolved at the cap).

References: Montgomery, *Design and Analysis of Experiments*, 8th ed., 2013, ch. 3 (one-way
ANOVA, pooled variance); Owen, "Scrambled net variance", SIAM J. Numer. Anal. 34 (1997) 1884
(replicated randomised QMC error).
"""

from __future__ import annotations

from math import exp, lgamma, sqrt

import numpy as np

#: Seed offset between the sample batches of one frame.
AUTO_SEED_STRIDE = 1_000_003
#: Most camera samples per pixel the automatic quality spends on one frame.
AUTO_MAX_SPP = 32
#: The target: mean per-pixel error away from edges <= NETD / this, on the image and per region.
AUTO_NETD_FRACTION = 3.0
#: ... and its 99th percentile away from edges <= this [K] (issue 13: a few noisy pixels, e.g.
#: where one pixel spans facets of different temperature in the MWIR, are noise a camera does
#: not have).
AUTO_P99_K = 0.1
#: Fewest batches of the automatic quality: 2 batches of 2 replicas = 4 replicas per pixel.
MIN_BATCHES = 2
#: Fewest pixels away from edges for a region to be held to the targets (a 99th percentile of
#: fewer pixels is its largest value); smaller regions are reported, not judged.
MIN_REGION_PIXELS = 16
#: A pixel whose stated error is above this [K] counts as unresolved.
UNRESOLVED_K = 1.0
#: Region name of pixels that hit no surface.
BACKGROUND = "background"


def c4(n: int) -> float:
    """E[s] = c4(n) sigma for the sample standard deviation of n normal values."""
    return sqrt(2.0 / (n - 1)) * exp(lgamma(n / 2) - lgamma((n - 1) / 2))


def region_map(part_index: np.ndarray, part_classes) -> tuple[np.ndarray, list[str]]:
    """(H, W) region ids and their names: the label class of each pixel's pixel-centre hit.

    ``part_index`` (H, W): the part hit by the pixel-centre ray (-1: none); ``part_classes``:
    the class token of each part (None: unlabelled, counted as background)."""
    names = [BACKGROUND] + sorted({c for c in part_classes if c and c != BACKGROUND})
    ident = {name: i for i, name in enumerate(names)}
    lookup = np.array([ident.get(c or BACKGROUND, 0) for c in part_classes] + [0], dtype=np.int64)
    part = np.asarray(part_index)
    return lookup[np.where(part >= 0, part, len(part_classes))], names


class Batches:
    """Pixel means and standard errors pooled over independent batches of equal sample count.

    ``add(mean, stderr, replicas)``: one batch's pixel means and standard errors (the spread of
    its ``replicas`` replica means, divided by c4(replicas) as the estimator reports it)."""

    def __init__(self):
        self.count = 0
        self.replicas = 0
        self._sum = None
        self._sumsq = None  # of the batch means: the between-batch sum of squares
        self._within = None  # sum over batches of (replicas - 1) x the batch mean's variance

    def add(self, mean, stderr, replicas: int) -> None:
        mean = np.asarray(mean, dtype=np.float64)
        r = int(replicas)
        var = (np.asarray(stderr, dtype=np.float64) * (c4(r) if r > 1 else 1.0)) ** 2
        within = np.nan_to_num(var) * (r - 1) if r > 1 else np.zeros_like(mean)
        if self._sum is None:
            self._sum, self._sumsq, self._within = mean.copy(), mean**2, within
            self.replicas = r
        else:
            if r != self.replicas:
                raise ValueError(f"batches of {r} and {self.replicas} replicas")
            self._sum += mean
            self._sumsq += mean**2
            self._within += within
        self.count += 1

    @property
    def dof(self) -> int:
        """Degrees of freedom of each pixel's pooled variance: k r - 1."""
        return self.count * self.replicas - 1

    def mean(self) -> np.ndarray:
        return self._sum / self.count

    def stderr(self) -> np.ndarray:
        """The standard error of the mean over all batches: the pooled variance of a batch mean
        over k, c4-corrected for its k r - 1 degrees of freedom (NaN without any)."""
        k, dof = self.count, self.dof
        if dof < 1:
            return np.full(self._sum.shape, np.nan)
        between = np.maximum(self._sumsq - self._sum**2 / k, 0.0)  # sum of (m_b - mean)^2
        pooled = (self._within + between) / dof
        return np.sqrt(pooled / k) / c4(dof + 1)


def _summary(values: np.ndarray) -> dict:
    if not values.size:
        return {"pixels": 0, "mean_k": None, "p99_k": None, "max_k": None}
    return {
        "pixels": int(values.size),
        "mean_k": float(values.mean()),
        "p99_k": float(np.percentile(values, 99)),
        "max_k": float(values.max()),
    }


def region_stats(stderr_k, edge, regions, names, back_face=None) -> dict:
    """Per region name: the per-pixel error [K] away from edges (pixels, mean, p99, max), the
    pixels that saw a back side (``back_face`` (H, W) fraction > 0, any pixel) and the pixels
    whose stated error is above :data:`UNRESOLVED_K` (away from edges)."""
    stderr_k = np.asarray(stderr_k, dtype=np.float64)
    ok = np.isfinite(stderr_k)
    out = {}
    for rid, name in enumerate(names):
        where = regions == rid
        inner = where & ~edge & ok
        if not where.any():
            continue
        rec = _summary(stderr_k[inner])
        rec["unresolved_pixels"] = int(np.count_nonzero(stderr_k[inner] > UNRESOLVED_K))
        if back_face is not None:
            rec["back_face_pixels"] = int(np.count_nonzero(where & (back_face > 0)))
        out[name] = rec
    return out


def targets(netd_k) -> dict | None:
    """The targets for a sensor's NETD [K] (None: no NETD, no target)."""
    if netd_k is None or not np.isfinite(netd_k) or netd_k <= 0:
        return None
    return {"mean_k": float(netd_k) / AUTO_NETD_FRACTION, "p99_k": AUTO_P99_K}


def verdict(image: dict, regions: dict, netd_k) -> dict:
    """Whether the targets are met: ``{"met": bool | None, "regions": {name: bool | None}}``
    (None: not judged, no NETD or too few pixels away from edges; the image counts as region
    "image"). ``image`` and each region: ``{"mean_k", "p99_k", "pixels"}``."""
    goal = targets(netd_k)
    judged = {}
    for name, rec in [("image", image), *regions.items()]:
        if (
            goal is None
            or rec.get("mean_k") is None
            or (name != "image" and rec["pixels"] < MIN_REGION_PIXELS)
        ):
            judged[name] = None
            continue
        judged[name] = bool(rec["mean_k"] <= goal["mean_k"] and (rec["p99_k"] or 0.0) <= goal["p99_k"])
    verdicts = [v for v in judged.values() if v is not None]
    return {"met": (all(verdicts) if verdicts else None), "regions": judged}


def needs_more(auto: bool, judged: dict, batches: int, spp_per_batch: int) -> bool:
    """Another batch: automatic quality, fewer than :data:`MIN_BATCHES` batches or a target not
    met, and the next batch within :data:`AUTO_MAX_SPP`."""
    if not auto:
        return False
    within_cap = spp_per_batch * (batches + 1) <= AUTO_MAX_SPP
    if batches < MIN_BATCHES:
        return within_cap
    return judged.get("met") is False and within_cap


#: Region classes the first batch's per-pixel boosts serve (people first): the estimator's boosts
#: have a budget (:data:`humv_usd.render.estimator.BOOST_BUDGET`) that the humvvex ground's
#: 294,000 pixels otherwise took from the person's 4,500.
FIRST_BOOST_CLASSES = ("person",)


def first_boost(regions, names) -> np.ndarray:
    """(H, W) bool: the pixels the first batch's boosts may serve: those of
    :data:`FIRST_BOOST_CLASSES` when the image shows any, else every surface."""
    wanted = [i for i, name in enumerate(names) if name in FIRST_BOOST_CLASSES]
    mask = np.isin(regions, wanted)
    return mask if mask.any() else np.asarray(regions) > 0


def likely_to_miss(stderr_k, edge, regions, names, netd_k, batches: int = MIN_BATCHES) -> np.ndarray:
    """(H, W) bool: the pixels of the regions that would miss their targets after ``batches``
    batches like this one without boosts (its per-pixel error ``stderr_k`` [K] over the square
    root of ``batches``: :class:`Batches` pools equal batches), so the first batch boosts them
    too: the humvvex MWIR ground (28 mK per unboosted batch, target 6.7) boosted from the second
    batch on only needed 5 batches (the unboosted first one weighs as much as the others), from
    the first 3; the LWIR grounds, within their targets unboosted, spend nothing."""
    err = np.asarray(stderr_k, dtype=np.float64) / sqrt(max(int(batches), 1))
    per_region = region_stats(err, edge, regions, names)
    judged = verdict(noise_summary(err, edge), per_region, netd_k)
    missing = [i for i, name in enumerate(names) if judged["regions"].get(name) is False]
    return np.isin(regions, missing)


def noise_summary(stderr_k, edge) -> dict:
    """Mean and 99th percentile of the per-pixel error [K] away from edges (the image's record
    of :func:`verdict`)."""
    err = np.asarray(stderr_k, dtype=np.float64)
    return _summary(err[~np.asarray(edge, bool) & np.isfinite(err)])


def next_boost(regions, names, judged: dict) -> np.ndarray:
    """(H, W) bool: the pixels of the regions that have not met their targets yet (a later
    batch's boosts serve them; none when only the image as a whole falls short), and always
    those of :data:`FIRST_BOOST_CLASSES`: the batches are pooled as equals (:class:`Batches`),
    so a person's pixels boosted in the first batch and not in the next were pooled with a
    noisier batch whose disagreement the pooled error then carried (humvvex atom1024 with
    smooth shading: the person's p99 65 mK after one batch, 617 mK after two, 13 batches
    to 94 mK; boosted in every batch: 2 batches)."""
    failing = [
        i
        for i, name in enumerate(names)
        if judged["regions"].get(name) is False or name in FIRST_BOOST_CLASSES
    ]
    return np.isin(regions, failing)


def batch_target_factor(batches_done: int) -> float:
    """How many times the pooled per-pixel target variance one batch's own boosts aim at, the
    batch after ``batches_done`` others (:func:`pixel_target_var`).

    :class:`Batches` averages k equal batches, so batches of variance v_i pool to sum(v_i) / k^2:
    the :data:`MIN_BATCHES` batches every frame takes meet a target T when each is within
    :data:`MIN_BATCHES` T. Aiming each batch at T itself (as before) spent the boosts on a
    pooled error half the target's variance (the demo person 10.0 mK against 16.7; issue 31).
    A later batch (a target missed) aims at (k + 1) T: with k earlier batches within k T (or
    :data:`MIN_BATCHES` T) the pool of k + 1 stays within T."""
    return float(max(MIN_BATCHES, int(batches_done) + 1))


def pixel_target_var(netd_k, dl_dt, where=None, batches_done: int | None = None) -> np.ndarray | None:
    """The variance [radiance^2] under which each pixel's error should be: (NETD /
    :data:`AUTO_NETD_FRACTION` x dL/dT)^2 where ``where`` (H, W bool; default everywhere), NaN
    elsewhere; None without a NETD. With ``batches_done``: one batch's own target, that times
    :func:`batch_target_factor` (the batches are pooled)."""
    goal = targets(netd_k)
    if goal is None:
        return None
    target = (goal["mean_k"] * np.asarray(dl_dt, dtype=np.float64)) ** 2
    if batches_done is not None:
        target = target * batch_target_factor(batches_done)
    if where is not None:
        target = np.where(where, target, np.nan)
    return target


def rule_text(auto: bool, spp: int, netd_text: str) -> str:
    """The automatic quality's rule in words (manifest, records)."""
    if not auto:
        return f"given: {spp} spp"
    return (
        f"automatic: at least {MIN_BATCHES} batches of {spp} spp (>= {MIN_BATCHES * 2} replicas per pixel), "
        f"more until the mean error away from edges is <= NETD/{AUTO_NETD_FRACTION:g} ({netd_text} / "
        f"{AUTO_NETD_FRACTION:g}) and its 99th percentile <= {AUTO_P99_K:g} K on the image and on every "
        f"labelled region class with >= {MIN_REGION_PIXELS} such pixels, or {AUTO_MAX_SPP} spp; pixels "
        "above the per-pixel target get more direct-term positions"
    )


def combine_error(stderr_k, extra_k) -> np.ndarray:
    """Independent errors [K] added in quadrature (``extra_k`` broadcast; NaN where either is)."""
    return np.sqrt(np.asarray(stderr_k, float) ** 2 + np.asarray(extra_k, float) ** 2)


def add_thermal_noise(per_region: dict, stderr_k, thermal_k, edge, regions, names) -> None:
    """Add to each region's record (:func:`region_stats`) the thermal layer's own noise [K]
    (``thermal_k`` (H, W), e.g. the q_rad rays' noise of a person's faces) away from edges,
    ``thermal_noise_mean_k``, and the total stated error, the render's and the layer's in
    quadrature (independent), ``total_error_mean_k`` / ``total_error_p99_k``."""
    total = combine_error(stderr_k, thermal_k)
    for rid, name in enumerate(names):
        if name not in per_region:
            continue
        inner = (regions == rid) & ~edge & np.isfinite(total)
        if not inner.any():
            continue
        per_region[name]["thermal_noise_mean_k"] = float(np.mean(np.asarray(thermal_k)[inner]))
        per_region[name]["total_error_mean_k"] = float(total[inner].mean())
        per_region[name]["total_error_p99_k"] = float(np.percentile(total[inner], 99))


# --- the visible (EO) counterpart: error of Y relative to the mean Y -------------------------

#: EO automatic quality: batches until the mean Y error away from edges is <= this fraction of
#: the mean Y there.
EO_TARGET_RELATIVE = 0.01
#: Most camera samples per pixel the automatic EO quality spends on one frame.
EO_MAX_SPP = 32


def relative_noise(y, y_stderr, edges) -> dict:
    """The error of Y relative to the mean Y away from geometric edges (edge pixels apart: their
    spread is the pixel footprint, signal): mean and 99th percentile of the per-pixel standard
    error over those pixels, and the edge pixels' mean, each divided by the mean Y of the pixels
    away from edges."""
    y, err = np.asarray(y, float), np.asarray(y_stderr, float)
    inner = ~np.asarray(edges, bool)
    mean_y = float(np.mean(y[inner])) if inner.any() else float(np.mean(y))
    e_in = err[inner & np.isfinite(err)]
    e_out = err[~inner & np.isfinite(err)]
    ok = mean_y > 0
    return {
        "mean": float(e_in.mean() / mean_y) if e_in.size and ok else None,
        "p99": float(np.percentile(e_in, 99) / mean_y) if e_in.size and ok else None,
        "edge_mean": float(e_out.mean() / mean_y) if e_out.size and ok else None,
        "mean_y": mean_y,
        "edge_fraction": float(np.mean(~inner)),
    }


def pool_equal_batches(batches) -> tuple[np.ndarray, np.ndarray]:
    """Mean and its standard error from independent batches of equal samples per pixel, each a
    (value, stderr) pair: the batch mean and sqrt(sum stderr^2) / k over k batches."""
    value = np.mean([b[0] for b in batches], axis=0)
    stderr = np.sqrt(np.sum([np.asarray(b[1]) ** 2 for b in batches], axis=0)) / len(batches)
    return value, stderr


#: The infrared rule's "NETD" for images of reflected light (EO, NIR, SWIR: no NETD), in units
#: of the mean Y or radiance away from edges: their mean error <= it / AUTO_NETD_FRACTION =
#: EO_TARGET_RELATIVE (1 %) and p99 <= AUTO_P99_K read as 10 %, on the image and every region.
RELATIVE_NETD = EO_TARGET_RELATIVE * AUTO_NETD_FRACTION


def needs_more_relative(auto: bool, noise: dict, spp_per_batch: int, batches: int) -> bool:
    """Another EO batch: automatic quality, the mean relative error (:func:`relative_noise`)
    above :data:`EO_TARGET_RELATIVE`, and the next batch within :data:`EO_MAX_SPP`."""
    return (
        bool(auto)
        and noise["mean"] is not None
        and noise["mean"] > EO_TARGET_RELATIVE
        and spp_per_batch * (batches + 1) <= EO_MAX_SPP
    )


def frames_summary(per_frame: list[dict], mean: str, p99: str, edge: str) -> dict:
    """Per-sensor error summary over frames (infrared in K, EO relative to Y): the mean of the
    frames' ``mean`` values, the worst ``p99``, the mean ``edge`` value, the samples spent and
    the rule (keys named by the caller)."""

    def values(key):
        return [f[key] for f in per_frame if f.get(key) is not None]

    means, p99s, edges = values(mean), values(p99), values(edge)
    return {
        "mean": float(np.mean(means)) if means else None,
        "p99_max": float(np.max(p99s)) if p99s else None,
        "edge_mean": float(np.mean(edges)) if edges else None,
        "spp_used": sorted({f["spp_used"] for f in per_frame if f.get("spp_used") is not None}),
        "spp_rule": per_frame[-1].get("spp_rule") if per_frame else None,
    }


def relative_summary(per_frame: list[dict]) -> dict:
    """Per-sensor summary of :func:`relative_noise` over frames (:func:`frames_summary`) with the
    target and the definition."""
    s = frames_summary(per_frame, "mean", "p99", "edge_mean")
    return {
        "mean": s["mean"],
        "p99_max": s["p99_max"],
        "edge_mean": s["edge_mean"],
        "target": EO_TARGET_RELATIVE,
        "definition": "per-pixel Monte Carlo standard error of CIE Y divided by the mean Y, both over "
        "pixels away from geometric edges (8-neighbours on the same part within 2 % depth); mean "
        "and 99th percentile over those pixels, edge pixels apart (the EO counterpart of "
        "monte_carlo_error_k)",
        "not_estimable": None
        if s["mean"] is not None
        else "spp < 2: one replica, the error is not estimable",
        "spp_used": s["spp_used"],
        "spp_rule": s["spp_rule"],
    }


def quality_summary(entries: list[dict], definition: str | None = None) -> dict:
    """Per sensor: whether the automatic quality met its targets on every frame (False when a
    frame stopped at the sample cap short of them, None when no frame was judged), the frames
    that fell short and the regions that did."""
    judged = [(e["frame"], e.get("quality") or {}) for e in entries]
    short = [(f, q) for f, q in judged if q.get("met") is False]
    verdicts = [q.get("met") for _, q in judged if q.get("met") is not None]
    regions = sorted(
        {name for _, q in short for name, rec in (q.get("regions") or {}).items() if rec.get("met") is False}
        | {"image" for _, q in short if q.get("image_met") is False}
    )
    return {
        "met": (all(verdicts) if verdicts else None),
        "frames_not_met": [f for f, _ in short],
        "regions_not_met": regions,
        "definition": definition
        or "automatic quality (humv_usd.render.quality): mean per-pixel error away from edges "
        "<= NETD/3 and its p99 <= 0.1 K on the image and on every region class (label class of the "
        "pixel-centre hit) with enough pixels; per frame in frames[].quality",
    }

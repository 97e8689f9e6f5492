"""The infrared estimator: deterministic emission, sky control variate, sub-bands on one path.

:func:`render_band_fast` computes the same quantity as :func:`humv_usd.render.ir.render_band`
(the plain path tracer, kept as the reference and for the scalar fallback variant), the at-sensor
band radiance :math:`L = \\sum_k \\tau_k(r) S_k + P_k(r)` of opaque, one-sided, gray-per-sub-band
Lambertian surfaces under a zenith-only sky, a directional sun and a slant path, with far less
Monte Carlo noise for the same rays:

- **One geometric path for all sub-bands.** Directions do not depend on the sub-band; each
  vertex carries the n sub-band throughputs, so the sub-band count costs no rays.
- **Emission at a hit is evaluated, not sampled** (:math:`\\varepsilon_k L_k(T)` of the face).
- **Sun by next-event estimation** (one shadow ray per vertex facing the sun); **lamps** too
  (``radiometry.lamps``, a :class:`humv_usd.render.lights.LampTable`: a shadow ray per point
  lamp or spot per vertex, one sampled point per lit window, :func:`_lamp_irradiance`; camera
  rays see a window's radiance, :func:`_windows_seen`).
- **Calm water is a mirror** for camera rays (the puddles: :func:`_mirror_tables`): emission
  :math:`(1 - R(\\mu)) B(T)` and one mirror ray of throughput :math:`R(\\mu)` (Fresnel) with no
  control variate, in place of the Lambertian terms; its reflected part is not filtered.
- **Control variate for the reflected sky.** The reflected radiance of a Lambertian vertex with
  normal :math:`n` is :math:`\\rho_k \\int L_{in}(\\omega) (n\\cdot\\omega)/\\pi\\,d\\omega`. With
  :math:`C_k(\\omega)` = the sky radiance above the horizon and a ground radiance :math:`L_g`
  below it, whose cosine-weighted hemispherical mean :math:`G_k(n_z)` is tabulated exactly
  (azimuthal integral in closed form, :func:`control_variate_table`), the estimator is
  :math:`\\rho_k [G_k(n_z) + L_{in}(\\omega) - C_k(\\omega)]` with :math:`\\omega` cosine
  distributed: unbiased for any :math:`C`, and zero-variance where the hemisphere is open sky over
  a uniform ground (Glasserman, *Monte Carlo Methods in Financial Engineering*, 2004, sec. 4.1;
  control variates in rendering: Lafortune & Willems 1994).
- **Stratified samples.** The pixel position and the first bounce direction of a pixel's spp
  samples are a Cranley-Patterson rotated 2-D Fibonacci lattice per (pixel, replica) cell (one
  random shift per cell and dimension pair, :func:`_cell_shift`); the standard error is
  estimated from ``replicas`` independent randomisations (the unbiased estimator for randomised
  quasi-Monte Carlo, Owen 1997), so the stratification's gain is measured, not assumed.
- **Russian roulette** from the second bounce (survival :math:`\\min(0.95, \\max(\\beta, 0.1))`),
  so the estimator is unbiased for any reflectance (furnace test).

- **More pixel positions for the direct term where it dominates** (faces of different
  temperatures inside a pixel's footprint): a second, larger lattice of camera samples that
  evaluates only the direct term, sized per call by the optimal allocation of samples between
  the two terms from their measured variances and costs (:func:`extra_direct_points`).
- **One approximation: the reflected part is averaged over the surface** around each pixel
  (same part, normal and depth; at most :data:`FILTER_HALF_WIDTH_M` and
  :data:`DEFAULT_FILTER_RADIUS` px; :func:`filter_reflected`), its variance propagated; the
  bias this costs per labelled region is measured by ``humv-usd bench render``.

The atmospheric path is applied per sample at the range of that sample's first hit (sky samples
get none: the sky radiance is the at-sensor value).

How the work is laid out (the result does not depend on it): a wavefront of lanes per bounce,
compacted after each intersection to the lanes that hit a front face (an escape above the
horizon adds :math:`L_{sky} - C = 0` and needs nothing more; back faces and escapes below the
horizon are few and handled on their own compacted lanes; Laine, Karras & Aila, "Megakernels
considered harmful", HPG 2013); a per-triangle table holds per sub-band the surface term in
shadow (:math:`\varepsilon_k L_k(T) + \rho_k G_k(n_z)`, the geometric normal being constant
per triangle), the same in the sun, and :math:`\rho_k`, so a vertex costs two gathers per
sub-band; per-lane sums are reduced to pixels in a fixed order, so a seed gives the same image
whatever the thread count. ``weights`` turns the n sub-bands into c output channels
:math:`\\sum_k W_{ck} L_k` estimated from the same paths (the EO estimator's colour channels).

References: Kajiya, "The rendering equation", SIGGRAPH 1986; Cranley & Patterson, SIAM J. Numer.
Anal. 13 (1976) 904; Owen, "Scrambled net variance", SIAM J. Numer. Anal. 34 (1997) 1884;
Neyman, "On the two different aspects of the representative method", J. R. Stat. Soc. 97 (1934)
558 (optimal allocation).
"""

from __future__ import annotations

import functools
import logging
import threading
import time
from dataclasses import dataclass
from math import exp, lgamma, sqrt
from types import SimpleNamespace

import numpy as np

from humv_usd import mode
from humv_usd.geometry import shading
from humv_usd.physics import water_film
from humv_usd.render.ir import corner_blend
from humv_usd.render.radiometry import SKY_MAP_HEIGHT
from humv_usd.render.scene_export import face_corners
from humv_usd.scene.puddles import MATERIAL as PUDDLE_MATERIAL

log = logging.getLogger(__name__)

#: Nodes of the control-variate table G(n_z) over n_z in [-1, 1].
CV_NODES = 257
#: Survival probability bounds of Russian roulette after the first bounce.
RR_MIN, RR_MAX = 0.1, 0.95
#: First path depth with Russian roulette (0 = camera vertex).
RR_DEPTH = 3
#: Longest path (vertices) before a path is cut; Russian roulette ends paths long before.
MAX_DEPTH = 64
#: Independent randomisations per pixel for the standard error (replicas x lattice points = spp;
#: :func:`replica_count`: the smallest divisor of spp that is at least this). 4 (3 degrees of
#: freedom from spp 4 on; was 2): each replica is a stratified lattice (:func:`_rotated_lattice`)
#: whose mean takes few values over a step or a small hot surface, and two replicas then agree
#: exactly (stated error 0) in about half such pixels. Test scene, 32 spp, 6 seeds: rms error
#: 73 mK at 2 replicas, 77 at 4, 105 at 8 (iid points: 155 / 144 / 146); a 2-spp boosted batch
#: against a 32-spp image at 4 replicas: |z| > 6 in 3.8-5.9 % of pixels away from edges (4 seed
#: pairs; at 2 replicas 7.3-7.9 %). The automatic quality's batches of 2 spp keep 2 replicas
#: (pooled over >= 2 batches, :class:`humv_usd.render.quality.Batches`: >= 3 degrees of freedom).
DEFAULT_REPLICAS = 4
#: Camera samples per pixel of the fast estimator when the user gives none.
DEFAULT_SPP = 2
#: Reflection directions per camera vertex (first bounce), stratified over the pixel's samples:
#: 4 is the cheapest to NETD/3 on humvvex and walk (measured: noise^2 x CPU-s lowest at 4 of
#: 1, 2, 4, 8, 16; walk LWIR 2 spp 0.0125 K in 7.4 CPU-s vs 0.0094 K in 13.5 at 8). Re-measured
#: after the compaction and the wider filter (2 spp, noise^2 x CPU-s): walk 178 at 4 vs 269 at 3
#: and 383 at 2; humvvex atom1024 315 / 353 / 522, lwir640 352 / 417 / 530.
DEFAULT_SPLITS = 4
#: Half width [px] of the window over which the reflected radiance is averaged (0: off).
#: 16 px / 0.2 m (was 8 / 0.1; the filter's cost no longer grows with it): at 2 spp the mean
#: error falls 12.4 -> 8.6 mK (walk), 15.8 -> 11.1 (humvvex atom1024), 20.5 -> 15.5 (lwir640);
#: the filter's own bias per labelled region (filtered minus unfiltered, same samples) stays
#: under 2.2 mK (person), 0.4 mK (wall, ground); MWIR under 0.9 mK.
DEFAULT_FILTER_RADIUS = 16
#: Neighbours share a surface when their normals agree to this cosine and depths to this fraction.
FILTER_NORMAL_COS = 0.95
FILTER_DEPTH_REL = 0.02
#: Largest half width [m] of that window on the surface (the irradiance is smooth on this scale).
FILTER_HALF_WIDTH_M = 0.2
#: Most pixel positions of the direct term per camera sample (see :func:`extra_direct_points`).
MAX_DIRECT_FACTOR = 16
#: Ray origin offset along the normal, relative to the coordinates' magnitude (float32).
RAY_OFFSET = 2e-5
#: a leaving ray's least height above a large face's plane, in float32 units of the face's
#: largest vertex coordinate (:func:`face_leave_offsets`)
LEAVE_ULPS = 16
#: Label classes whose faces seen from behind render as the cavity (:func:`cavity_table`): a
#: person's closed body, shoes and garments, where a back side is seen only through a crack or
#: an intersection; elsewhere a one-sided face stays black from behind (an open plate, as
#: Mitsuba's one-sided area lights and the path tracer).
CAVITY_CLASSES = ("person",)
#: Most pixel positions of the direct term per camera sample in one pixel where its own error is
#: above the caller's target (:func:`fresh_factors`; issue 25: a person's pixels span faces
#: up to 17 K apart, whose sub-pixel mix the image-wide factor left 5-100x NETD/3).
#: 1024: the direct term is cheap (a camera ray and a sun shadow ray per position) and a pixel
#: over a step between two faces converges as N^-3/4 on the stratified lattice; at 64 the humvvex
#: person kept 0.23 K mean per 2-spp batch (its reflected part 0.06 K).
MAX_PIXEL_DIRECT_FACTOR = 1024
#: how the direct term's per-pixel position count follows its variance ratio to the goal: a
#: lattice's error variance at a step inside the pixel falls as n^-3/2 (Mitchell 1996), so the
#: count is (V / goal)^(2/3) (1: the 1/n law of independent positions)
DIRECT_LATTICE_EXPONENT = 2.0 / 3.0
#: Most more camera samples (with their reflections) per camera sample in one pixel whose
#: reflected part is above half the caller's target (small surfaces, e.g. a person's garments,
#: where the filter's window is small): 64 (the humvvex person's reflected part, 0.06 K mean per
#: 2-spp batch, needed about 26 for NETD/3).
MAX_PIXEL_REFLECT_FACTOR = 64
#: Most more camera samples per camera sample of the image that either per-pixel boost spends in
#: one call, as a multiple of the pixel count (shared as the cube roots of the pixels' needs,
#: :func:`within_budget`; the people's pixels, ``boost_first``, a budget of their own): bounds
#: the boosts to about the cost of the call's own samples, so a large region near its target
#: (the humvvex ground: 199,000 pixels) does not take the samples a small one needs (the person).
BOOST_BUDGET = 1.0
#: The same for the direct term alone, whose positions cost a camera ray and a sun shadow ray
#: each (a camera sample with its reflections about ten rays).
DIRECT_BOOST_BUDGET = 16.0
#: ... and at least this many (16 times it for the direct term) whatever the image size: a small
#: image's boosts cost little in absolute terms (a 64 x 48 test scene's person needed 440,000).
MIN_BOOST_BUDGET = 1 << 18
#: Most lanes of one per-pixel direct pass (bounds its memory: a few hundred bytes per lane).
MAX_DIRECT_LANES = 1 << 22
#: Largest angle [deg] between faces whose surface terms blend at a shared vertex
#: (:data:`humv_usd.geometry.shading.SMOOTH_CREASE_DEG`).
SMOOTH_CREASE_DEG = shading.SMOOTH_CREASE_DEG
#: Shade smooth when the caller does not say (issue 25; False: one value per flat face).
SMOOTH_SHADING = True
#: Van Cittert steps that sharpen the blended sun term back toward each face's own mean
#: (:func:`corner_table`) when the caller does not say. 0 (the plain blend) for the thermal
#: bands: 2 steps take the person's sun term from -1.5 % to -0.4 % against flat faces (render
#: bench) and the humvvex MWIR person +23.5 mK (1 step: +20.2 mK) toward the flat faces' mean,
#: but sharpen the sunlit white T-shirt's shading past the smooth-surface acceptance
#: (``tests/test_person_surfaces.py``: d2 p90 0.102 -> 0.130 K against 0.119; 1 step 0.117).
#: The reflected-light bands use :data:`REFLECTIVE_SUN_MEAN_STEPS`; every band now restores the
#: faces' means by one-ring gains instead (:data:`SUN_GAIN_STEPS`, :data:`REFLECTIVE_SUN_GAIN_STEPS`).
SUN_MEAN_STEPS = 0
#: One-ring gain steps of the blended sun term (:func:`corner_table`) when the caller does not
#: say: 1 for the thermal bands (the reflective ones: :data:`REFLECTIVE_SUN_GAIN_STEPS`). Each corner's sun term is scaled by the ratio of the blended
#: faces' own sun terms to the blended face means of the smooth field around it, so that every
#: one-ring of faces reflects what its flat faces receive (the per-face energy balance of the
#: thermal layer and of the flat-faced path tracer). Against the plain blend's -2.4 % (close-up)
#: / -1.9 % (humvvex) of the person's sun cosine, 1 gain step leaves -0.23 % / -0.49 % at the
#: roughness of 1 Van Cittert step (-0.70 % / -0.72 %). Against the IR path tracer (flat faces)
#: the close-up MWIR person (fixed temperatures) -52.5 -> +1.3 mK (+-0.6), the humvvex MWIR person
#: +24 mK (issue 25); the smooth-surface acceptance passes (``tests/test_person_surfaces.py``).
SUN_GAIN_STEPS = 1
#: Largest one-ring gain (near the terminator both of its sums vanish).
SUN_GAIN_CAP = 4.0
#: Van Cittert steps of the blended shadowed term (emission + rho G) toward each face's mean
#: (:func:`corner_table`): 0, the plain blend. The blend of the faces' temperatures loses their
#: covariance with the projected area as the sun term's did: the humvvex person reads about
#: 90 mK under the flat-faced IR path tracer in MWIR and LWIR; 1 step: MWIR -92 -> -22 mK, LWIR
#: -89 -> -5 mK, but the sunlit T-shirt's d2 p90 0.117 -> 0.121 K against the smooth-surface
#: acceptance's 0.119 (issue 25, open). If set, ``groundtruth.labels.smooth_temperature``
#: should follow the same field.
DARK_MEAN_STEPS = 0
#: One-ring gain steps of the blended shadowed term (:func:`corner_table`) for the thermal bands
#: when the caller does not say (the reflective ones: :data:`REFLECTIVE_DARK_GAIN_STEPS`).
DARK_GAIN_STEPS = shading.FIELD_GAIN_STEPS
#: ... and for the bands of reflected light (EO: :data:`humv_usd.render.eo_fast.SUN_MEAN_STEPS`;
#: NIR, SWIR: ``pipeline.ir_pass``), where the sun term is the signal: with the plain blend the
#: render bench's EO person was 0.78 % and a close-up NIR person 1.36 % under the path tracer
#: (which shades flat faces), with 2 steps 0.19 % and 0.18 % (s6). Now 0: the one-ring gain
#: (:data:`REFLECTIVE_SUN_GAIN_STEPS`) instead.
REFLECTIVE_SUN_MEAN_STEPS = 0
#: ... and their one-ring gain steps (:data:`SUN_GAIN_STEPS`): 1, as the thermal bands. Against
#: the path tracers (256 spp; fast 16 spp, 12 bins) the person: the render bench's close-up EO
#: camera (360 x 270) Y -0.270 +- 0.015 % with 2 Van Cittert steps, -0.016 % with 1 gain step
#: (flat faces -0.096 %; about -0.10 % is the reference's own Y normalisation); humvvex's EO
#: camera (360 x 270) -0.414 +- 0.043 % and -0.418 % (flat -0.130 %); a close-up NIR person
#: (nir_imx273 360 x 270, IR path tracer) -0.232 +- 0.009 % and -0.076 % (flat -0.019 %); at
#: the roughness of 1 Van Cittert step instead of 2.
REFLECTIVE_SUN_GAIN_STEPS = 1
#: ... and their shadowed term's gain steps (:data:`DARK_GAIN_STEPS`): 0, the plain blend. The
#: humvvex EO person (eo_rgb 360 x 270, 12 bins, 16 spp) against the spectral path tracer: Y
#: -0.418 +- 0.043 % with 0, -0.419 % with 1 (flat faces -0.130 %): no effect there, where the
#: shadowed term is the sky's reflection alone; NIR and SWIR not measured.
REFLECTIVE_DARK_GAIN_STEPS = 0
#: Point lamps and spots traced each (a shadow ray per lamp per hit); with more, one lamp per hit
#: is chosen by its unoccluded irradiance (:func:`_lamp_irradiance`; windows always so).
MAX_LAMP_RAYS = 8


def sky_rows(radiometry, k: int) -> np.ndarray:
    """The sky of sub-band k as SKY_MAP_HEIGHT rows against zenith 0..180 deg (the envmap's
    rows, :func:`humv_usd.render.radiometry.sky_latlong`; a constant sky repeated)."""
    if radiometry.sky_maps is not None:
        return np.asarray(radiometry.sky_maps[k], dtype=float)[:, 0, 0]
    return np.full(SKY_MAP_HEIGHT, float(radiometry.sky_constant[k]))


def azimuthal_cosine_integral(normal_z, mu) -> np.ndarray:
    """:math:`\\int_0^{2\\pi} \\max(0, n\\cdot\\omega)\\,d\\varphi` for a unit normal with z
    component ``normal_z`` and directions of z component ``mu`` (broadcast): with
    :math:`a = \\sqrt{1-n_z^2}\\sqrt{1-\\mu^2}`, :math:`b = n_z \\mu`, it is :math:`2\\pi b` when
    :math:`b \\ge a`, 0 when :math:`b \\le -a`, else :math:`2(b\\varphi_0 + a\\sin\\varphi_0)` with
    :math:`\\varphi_0 = \\arccos(-b/a)`."""
    t = np.asarray(normal_z, dtype=float)
    m = np.asarray(mu, dtype=float)
    a = np.sqrt(np.clip(1 - t**2, 0, 1)) * np.sqrt(np.clip(1 - m**2, 0, 1))
    b = t * m
    with np.errstate(divide="ignore", invalid="ignore"):
        phi0 = np.arccos(np.clip(np.where(a > 0, -b / a, 0.0), -1.0, 1.0))
    mid = 2.0 * (b * phi0 + a * np.sin(phi0))
    return np.where(b >= a, 2 * np.pi * b, np.where(b <= -a, 0.0, mid))


def control_variate_table(rows: np.ndarray, ground, nodes: int = CV_NODES) -> np.ndarray:
    """G(n_z) on ``nodes`` even points of n_z in [-1, 1]: the cosine-weighted hemispherical mean
    :math:`\\frac{1}{\\pi}\\int_{n\\cdot\\omega>0} C(\\omega)\\,n\\cdot\\omega\\,d\\omega` of the
    control variate C = the sky rows above the horizon (linear in zenith between rows, as the
    envmap) and ``ground`` below it. Midpoint rule in zenith on 4 points per sky row (the
    integrand is smooth between rows; the exact azimuthal integral handles the cosine clip).
    ``rows`` (H,) with a scalar ground, or (n, H) with n grounds: then (n, nodes), one table per
    sub-band from one quadrature matrix."""
    rows = np.asarray(rows, dtype=float)
    h = rows.shape[-1]
    per = 4 * (h - 1)
    theta = (np.arange(2 * per) + 0.5) * np.pi / (2 * per)  # 0..pi
    mu = np.cos(theta)
    grounds = np.broadcast_to(np.asarray(ground, dtype=float), rows.shape[:-1])
    zen = np.linspace(0, np.pi, h)
    c = np.where(
        mu >= 0,
        np.stack([np.interp(theta, zen, r) for r in rows.reshape(-1, h)]).reshape(
            rows.shape[:-1] + (theta.size,)
        ),
        grounds[..., None],
    )
    return (c @ _cosine_weights(h, nodes).T) / np.pi


@functools.lru_cache(maxsize=8)
def _cosine_weights(h: int, nodes: int) -> np.ndarray:
    """(nodes, zeniths) quadrature weights of :func:`control_variate_table` (read-only, cached:
    they depend only on the sky's rows and the nodes)."""
    per = 4 * (h - 1)
    theta = (np.arange(2 * per) + 0.5) * np.pi / (2 * per)
    t = np.linspace(-1.0, 1.0, nodes)
    w = azimuthal_cosine_integral(t[:, None], np.cos(theta)[None, :]) * np.sin(theta)[None, :]
    w *= np.pi / (2 * per)
    w.flags.writeable = False
    return w


@dataclass
class FaceTables:
    """Global per-triangle tables of one IR scene for one sensor and frame.

    ``emission`` (T, n) [W m-2 sr-1] = eps_k L_k(T_face); ``reflectance`` (T, n);
    ``offset`` per part (index into the global triangle order of ``IRScene.parts``)."""

    emission: np.ndarray
    reflectance: np.ndarray
    offset: np.ndarray


def face_tables(scene, state, sub, emissivity_of, transmittance_of=None) -> FaceTables:
    """Per-triangle emission and reflectance of every part for one sensor (sub-band model)."""
    n = len(sub)
    temps = {m.path: state.temperatures[m.path] for m in state.meshes}
    planck_of = {path: sub.radiance(t) for path, t in temps.items()}  # (F, n)
    mesh_of_part = {part.key: m.path for m in state.meshes for part in m.parts}
    emission, reflectance, offset = [], [], [0]
    for part in scene.parts:
        eps = np.asarray(emissivity_of(part.material), dtype=float).reshape(n)
        tau = None if transmittance_of is None else transmittance_of(part.material)
        rho = np.clip(1.0 - eps - (0.0 if tau is None else np.asarray(tau, float).reshape(n)), 0.0, None)
        t = len(part.triangles)
        emission.append(eps[None, :] * planck_of[mesh_of_part[part.key]][part.triangle_face])
        reflectance.append(np.broadcast_to(rho, (t, n)))
        offset.append(offset[-1] + t)
    return FaceTables(np.concatenate(emission), np.concatenate(reflectance), np.asarray(offset[:-1]))


def face_normals(scene) -> tuple[np.ndarray, np.ndarray]:
    """Unit geometric normals (T, 3) and areas (T,) [m2] of every triangle of the scene in the
    global order of :class:`FaceTables` (winding flips applied, as Mitsuba's ``si.n``)."""
    normals, areas = [], []
    for part in scene.parts:
        v = scene.vertices(part).astype(float)
        tris = face_corners(part.triangles, scene.flipped(part))
        a, b, c = (v[tris[:, i]] for i in range(3))
        cr = np.cross(b - a, c - a)
        norm = np.linalg.norm(cr, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            normals.append(np.where(norm[:, None] > 0, cr / norm[:, None], 0.0))
        areas.append(0.5 * norm)
    if not normals:
        return np.zeros((0, 3)), np.zeros(0)
    return np.concatenate(normals), np.concatenate(areas)


def ground_radiance(
    scene, tables: FaceTables, g_up: np.ndarray, sun_cos: float, sun_e, normals=None
) -> np.ndarray:
    """Radiance (n,) of the control variate below the horizon: area-weighted mean surface-leaving
    radiance of the upward faces (n_z > 0.9) lit by the open sky and the unshadowed sun. Any value
    keeps the estimator unbiased; this one makes it nearly zero-variance over a uniform ground."""
    n = tables.emission.shape[1]
    nrm, area = face_normals(scene) if normals is None else normals
    up = nrm[:, 2] > 0.9
    if not up.any() or area[up].sum() <= 0:
        return np.zeros(n)
    leave = tables.emission[up] + tables.reflectance[up] * (
        g_up[None, :] + (0.0 if sun_e is None else sun_e[None, :] * max(sun_cos, 0.0) / np.pi)
    )
    return (area[up, None] * leave).sum(axis=0) / float(area[up].sum())


def surface_table(scene, tables: FaceTables, g_tab: np.ndarray, sun_dir, sun_e, normals=None) -> np.ndarray:
    """(T, 3, n) per triangle and sub-band: the surface term of a front-facing vertex in shadow,
    emission + rho G(n_z) (G the control variate's hemispherical mean at the face's normal,
    interpolated in :func:`control_variate_table`'s nodes); the same plus the sun's
    rho E_sun max(0, n.s) / pi (a vertex that sees the sun); and rho. One table row holds all
    that a vertex needs, so the estimator reads it with 2 gathers per sub-band."""
    nrm = face_normals(scene)[0] if normals is None else normals[0]
    # G at each face's n_z, linear between the even nodes (one index and weight for all sub-bands)
    last = g_tab.shape[1] - 1
    x = (np.clip(nrm[:, 2], -1.0, 1.0) + 1.0) * (last / 2.0)
    i = np.minimum(x.astype(np.int64), max(last - 1, 0))
    t = (x - i)[:, None]
    g_nodes = np.ascontiguousarray(g_tab.T)  # (nodes, n)
    lo = g_nodes[i]
    g = lo + (g_nodes[np.minimum(i + 1, last)] - lo) * t  # (T, n)
    rho = tables.reflectance
    dark = tables.emission + rho * g
    lit = dark
    if sun_dir is not None and sun_e is not None:
        cos_s = np.maximum(nrm @ np.asarray(sun_dir, float), 0.0)
        lit = dark + rho * (np.asarray(sun_e, float)[None, :] * cos_s[:, None] / np.pi)
    return np.ascontiguousarray(np.stack([dark, lit, np.broadcast_to(rho, dark.shape)], axis=1))


def cavity_table(tables: FaceTables) -> np.ndarray:
    r"""(T, n) radiance of a triangle's back side seen from the camera: the blackbody radiance
    :math:`B_k(T_{face}) = \varepsilon_k L_k(T) / \varepsilon_k` at the face's temperature.

    A one-sided face is seen from behind only through a crack or an intersection into the
    inside of a closed surface (a shoe's fold, a foot through its shoe). An isothermal cavity
    radiates as a blackbody at its wall temperature whatever the walls' emissivity (Kirchhoff's
    law; Siegel & Howell, *Thermal Radiation Heat Transfer*, 4th ed., 2002, sec. 1.3), so the
    inside is rendered at the face's temperature; the former value, 0 (a black, cold back), made
    camera samples of 0 K: in the humvvex demo 5-10 % of a shoe pixel's samples, pixels 50 K too
    cold with an error of 58 K, and where every sample of a pixel hit a back side a pixel of
    -110 degC with an error of 5e-5 K. Faces with no emissivity (a mirror, the EO bands) stay 0;
    the estimator applies it to the parts of :data:`CAVITY_CLASSES` only.
    """
    eps = np.clip(1.0 - tables.reflectance, 0.0, 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(eps > 1e-6, tables.emission / eps, 0.0)
    return np.ascontiguousarray(out)


def corner_table(
    surface: np.ndarray, blend, sun_mean_steps: int = 0, sun_gain_steps: int = 0, dark_gain_steps: int = 0
) -> np.ndarray:
    """(T, 7 n) the estimator's per-triangle rows: per corner the surface term in shadow
    (:func:`surface_table`'s ``dark``: emission + rho G) and in the sun (``lit``), blended by
    ``blend`` (:func:`corner_blend`; None: flat, every corner its face's value), then rho.

    The sun's reflection (``lit - dark``) is blended over the faces that face the sun only: a
    sunlit face's corners that took in the zero sun term of neighbours turned away from it
    darkened the terminator, while those neighbours, shaded dark (their shadow ray is not
    cast), gained nothing (the visible person's Y 1.3-1.4 % low against the spectral path
    tracer on the render bench); per face, the reflected sun faceted MWIR garments.

    Blending alone averages each face's sun cosine with its neighbours' at the corners and
    interpolates again, which on a curved surface shrinks its peak by about cos^2 of half the
    angle between neighbouring normals (a cylinder: exactly; 7.4 deg, the garments' median:
    -0.4 %) and loses the flat faces' covariance of projected area and cosine: 1.5 % of the sun's
    reflection off the render bench's person, its Y 0.8 % under the spectral path tracer (which
    shades flat faces; Loop subdivision of the person's meshes, the smooth surface they sample,
    agrees with the flat faces within 0.2 %). So the blended values can be sharpened back toward
    the faces' own by ``sun_mean_steps`` Van Cittert steps, f' = f' + (f - A f'), A the
    face mean of the blended corners (the linear interpolant's mean over each face), which
    leaves the field continuous and a linear field unchanged: the person's sun term -1.5 % ->
    -0.4 % at 2 steps (issue 25), at the price of more shading within the faces (the
    covariance it restores lives on the faces' scale; see :data:`SUN_MEAN_STEPS`). Van Cittert, Z. Phys. 69 (1931) 298; Jansson, *Deconvolution of Images and
    Spectra*, 2nd ed., 1997, ch. 3.

    Or (``sun_gain_steps``, every band's default) the blended sun term is scaled at each corner by
    the one-ring gain g = sum_f w_f s_f / sum_f w_f mean_f(s'), the blend's weights w_f over the
    sunward faces f around the corner, s_f a face's own sun term and mean_f(s') the face mean of
    the smooth field: each corner's ring of faces then reflects what its flat faces receive,
    ρ E A max(0, n.s) / π per face (Lambert's law, which the thermal layer's per-face energy
    balance and the flat-faced path tracer both use), while the gain varies smoothly because the
    plain blend's shrink follows the local curvature. A multiplicative step (as Richardson,
    J. Opt. Soc. Am. 62 (1972) 55 and Lucy, Astron. J. 79 (1974) 745 to Van Cittert's additive
    one): a ratio of sums, positive, exact for a uniform field. At the roughness of one Van
    Cittert step it removes more of the bias: the person's unshadowed sun cosine at the pixel
    centres, against flat faces, -2.38 % with the plain blend, -0.70 % with 1 Van Cittert step,
    -0.23 % with 1 gain step (close-up); -1.93 %, -0.72 %, -0.49 % (humvvex).
    Interpolated (Phong) normals per hit (Phong, Commun. ACM 18 (1975) 311) keep the flat faces'
    projected area but not their covariance of area and cosine: -0.95 % (close-up), -0.13 %
    (humvvex; its T-shirt +0.28 %), a bias that depends on the view; they conserve no face's
    reflection.

    The shadowed term (emission + rho G: the faces' temperatures) loses the same covariance
    when blended: on a sunlit person the faces turned to the sun, which the camera also sees
    face-on, are the hot ones and their neighbours turned away the cold ones, so the plain
    blend reads the humvvex person about 100 mK under flat faces in MWIR and LWIR (shorts and
    shoes -340 mK). ``dark_gain_steps`` one-ring gain steps restore it as the sun term's do:
    each corner's blended shadowed term is scaled by g = sum_f w_f d_f / sum_f w_f mean_f(d'),
    over all the faces blended at the corner (the shadowed term is positive on every face), so
    that each ring of faces emits and reflects the sky as its flat faces do (their per-face
    energy balance); :data:`DARK_GAIN_STEPS`. (``DARK_MEAN_STEPS``: Van Cittert steps instead;
    at the same roughness they leave more bias.)"""
    t, _, n = surface.shape
    if blend is None:
        corners = np.repeat(surface[:, None, :2, :], 3, axis=1)  # (T, 3, 2, n)
    else:
        own_dark, sharp_dark = surface[:, 0, :], surface[:, 0, :]
        dark = np.asarray(blend @ own_dark).reshape(t, 3, n)
        for _ in range(int(DARK_MEAN_STEPS)):  # Van Cittert: the faces' means back toward their own
            sharp_dark = sharp_dark + (own_dark - dark.mean(axis=1))
            dark = np.asarray(blend @ sharp_dark).reshape(t, 3, n)
        # one-ring gains: each corner's ring leaves its flat faces' radiance
        dark = shading.ring_gains(blend, own_dark, dark, dark_gain_steps)
        sun = surface[:, 1, :] - surface[:, 0, :]
        facing = (sun.sum(axis=1) > 0.0).astype(float)
        weight = np.asarray(blend @ facing).reshape(t, 3)

        def spread(values):
            """Blended over the faces that face the sun (a face without any: its own value)."""
            with np.errstate(invalid="ignore", divide="ignore"):
                c = np.asarray(blend @ (values * facing[:, None])).reshape(t, 3, n) / weight[..., None]
            return np.where(weight[..., None] > 0.0, c, values[:, None, :])

        lit_sun, sharp = spread(sun), sun
        for _ in range(int(sun_mean_steps)):  # Van Cittert: the faces' means back toward their own
            sharp = sharp + (sun - lit_sun.mean(axis=1)) * facing[:, None]
            lit_sun = spread(sharp)
        lit_sun = np.maximum(lit_sun, 0.0)
        if int(sun_gain_steps) > 0:  # one-ring gains: each corner's ring reflects its flat faces' sun
            own = np.asarray(blend @ (sun * facing[:, None])).reshape(t, 3, n)
            for _ in range(int(sun_gain_steps)):
                now = np.asarray(blend @ (lit_sun.mean(axis=1) * facing[:, None])).reshape(t, 3, n)
                with np.errstate(invalid="ignore", divide="ignore"):
                    gain = np.where(now > 0.0, own / now, 1.0)
                lit_sun = lit_sun * np.clip(gain, 0.0, SUN_GAIN_CAP)
        corners = np.stack([dark, dark + lit_sun], axis=2)  # (T, 3, 2, n)
    return np.ascontiguousarray(np.concatenate([corners.reshape(t, 6 * n), surface[:, 2, :]], axis=1))


def _smooth_blend(scene):
    """The scene's :func:`corner_blend` (cached by the scene against its geometry:
    :meth:`humv_usd.render.ir.IRScene.corner_blend`)."""
    cached = getattr(scene, "corner_blend", None)
    return cached() if cached is not None else corner_blend(scene)


def fresh_factors(var, target_var, factor_cap: int) -> np.ndarray:
    r"""Fresh samples per sample of the pilot (H, W) int for pixels whose estimate is to come
    from the fresh samples alone: :math:`F = \lceil V / V_t \rceil` (their variance
    :math:`V / F` is then within the target), rounded up to a power of two and capped at
    ``factor_cap``; 0 where the pilot is already within the target (``var`` (c, H, W) summed
    over c; ``target_var`` (H, W), NaN or <= 0: no target).

    Why fresh alone: the counts are chosen from the pilot's own replicas, so pooling the pilot
    with the samples whose number it chose weights each pilot by a function of its own value: a
    pixel over a hot/cold step whose replicas happened to agree keeps its pilot at full weight,
    one whose replicas disagreed is diluted; the mean is biased (the humvvex person -5.9 mK at
    lwir640, 2.7 standard errors; a hot box in a test scene +85 mK at 7). Fresh samples whose
    number depends only on the pilot are unbiased given it: the pilot sets the allocation only,
    as in double sampling (Cochran 1977, *Sampling Techniques*, 3rd ed., ch. 12)."""
    v = np.nansum(np.asarray(var, float), axis=0)
    t = np.asarray(target_var, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        need = np.where((t > 0) & np.isfinite(t) & np.isfinite(v), np.ceil(v / t), 0.0)
    need = np.clip(need, 0, factor_cap)
    out = np.zeros(need.shape, dtype=np.int64)
    on = need > 1
    out[on] = np.minimum(2 ** np.ceil(np.log2(need[on])).astype(np.int64), factor_cap)
    return out


def step_variance(direct, part, samples: int) -> np.ndarray:
    r"""(H, W) a floor for the variance of a pixel's direct-term mean over ``samples`` pixel
    positions, from the steps to its 4 neighbours on the same part: a footprint that straddles
    a step :math:`\Delta L` between faces (a faceted garment: up to 17 K between neighbouring
    faces) has a per-position variance :math:`f(1-f)\Delta L^2 \le \Delta L^2 / 4`. Two
    replicas rarely see such a step when one face covers most of the pixel (both on it with
    probability :math:`(1-f)^2`), so their spread alone misses most of these pixels (humvvex:
    16 pooled batches showed 3.5x the error the single batches claimed)."""
    d = np.nansum(np.asarray(direct, float).reshape((-1,) + np.shape(part)), axis=0)
    part = np.asarray(part)
    step = np.zeros(d.shape)
    for axis in (0, 1):
        a = [slice(None), slice(None)]
        b = [slice(None), slice(None)]
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        a, b = tuple(a), tuple(b)
        same = (part[a] == part[b]) & (part[a] >= 0)
        diff = np.where(same, np.abs(d[a] - d[b]), 0.0)
        step[a] = np.maximum(step[a], diff)
        step[b] = np.maximum(step[b], diff)
    return step**2 / 4.0 / max(int(samples), 1)


def within_budget(factor: np.ndarray, budget: float, need=None, first=None) -> np.ndarray:
    r"""``factor`` (per pixel more samples, int >= 0) fitted into ``budget`` (their sum):
    unchanged when it fits; else each pixel gets :math:`f_i = \min(F_i, \lfloor \lambda
    s_i \rfloor)` with the largest :math:`\lambda` that fits, :math:`s_i = r_i^{1/3}` and
    :math:`r_i` its ``need`` (same shape: e.g. the uncapped ratio of a pixel's variance to its
    target; None: the factor itself). That shape minimises the mean standard error
    :math:`\sum_i \sqrt{v_i / (1 + f_i)}` under :math:`\sum f_i = B` (Lagrange:
    :math:`(1 + f_i)^{3/2} \propto \sqrt{v_i}`, i.e. :math:`1 + f_i \propto v_i^{1/3}`; Neyman
    1934's allocation for a sum of errors instead of variances). The greedy rule it replaces
    (the largest needs first, each at its full factor) gave the humvvex MWIR person's 3,413
    neediest pixels 1024 direct positions each and its other 22,929 none (person mean error
    per batch 31 mK, 16 batches to the cap).
    ``first`` (same shape, bool): pixels with a budget of their own, e.g. a person's, and the
    others another as large (plus what the first leave): from the second batch on the failing
    ground shared one budget and the humvvex MWIR person's error per batch rose from 12 to
    28 mK (320x256); the person served first from one budget left the ground (28 mK per batch
    unboosted) none, 16 batches to the cap."""
    flat = np.asarray(factor).ravel().astype(np.int64)
    out = np.zeros_like(flat)
    if flat.sum() <= budget:
        out[:] = flat
        return out.reshape(np.shape(factor))
    shape = flat.astype(float) if need is None else np.asarray(need, dtype=float).ravel()
    shape = np.cbrt(np.clip(np.nan_to_num(shape, nan=0.0, posinf=np.finfo(float).max / 2), 0.0, None))
    groups = [np.ones(flat.shape, bool)]
    if first is not None:
        served = np.asarray(first, dtype=bool).ravel()
        groups = [served, ~served]
    left = 0.0
    for group in groups:
        left += float(budget)
        want = np.where(group, flat, 0)
        if want.sum() <= left:
            out += want
            left -= want.sum()
            continue
        at = np.flatnonzero((want > 0) & (shape > 0))  # the pixels that share it
        w, s = want[at], shape[at]
        lo, hi = 0.0, float((w / s).max()) if at.size else 0.0  # at hi every pixel has its want
        for _ in range(64):  # the largest lambda whose sum fits (monotone in lambda)
            mid = 0.5 * (lo + hi)
            if np.minimum(w, np.floor(mid * s)).sum() <= left:
                lo = mid
            else:
                hi = mid
        out[at] += np.minimum(w, np.floor(lo * s)).astype(np.int64)
        left = 0.0  # spent
    return out.reshape(np.shape(factor))


def variance_ratio(var, target_var) -> np.ndarray:
    """(H, W) how far each pixel's variance (c, H, W, summed over c) is above its target
    (H, W): their ratio, 0 where there is no target or no finite variance (the order of
    :func:`within_budget`)."""
    v = np.nansum(np.asarray(var, float), axis=0)
    t = np.asarray(target_var, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where((t > 0) & np.isfinite(t) & np.isfinite(v), v / t, 0.0)


def replica_count(spp: int, wanted: int = DEFAULT_REPLICAS) -> int:
    """Independent randomisations for ``spp`` samples: the smallest divisor of spp that is at
    least ``wanted`` (spp itself when prime), so that exactly spp samples are taken; 1 for spp 1."""
    spp = int(spp)
    if spp <= 1:
        return 1
    for r in range(max(2, int(wanted)), spp + 1):
        if spp % r == 0:
            return r
    return spp


def c4(n: int) -> float:
    """Bias factor of the sample standard deviation of n normal values, E[s] = c4 sigma
    (:math:`\\sqrt{2/(n-1)}\\,\\Gamma(n/2)/\\Gamma((n-1)/2)`); dividing by it makes the mean of
    per-pixel standard errors unbiased."""
    return sqrt(2.0 / (n - 1)) * exp(lgamma(n / 2) - lgamma((n - 1) / 2))


def _offset(dr, p):
    """Distance [m] to move a ray origin off its surface along the normal (float32 safe)."""
    return RAY_OFFSET * (1.0 + dr.maximum(dr.maximum(dr.abs(p.x), dr.abs(p.y)), dr.abs(p.z)))


def face_leave_offsets(scene) -> np.ndarray:
    """Per triangle (global order of :class:`FaceTables`) the height [m] above its plane that a
    ray leaving it must start from so that the ray tracer cannot meet that plane again:
    :data:`LEAVE_ULPS` float32 units of its largest vertex coordinate. A ray tracer computes a
    triangle's intersection relative to the ray origin, so its error grows with the triangle's
    vertices' distance from the origin, not with the hit point's coordinates (Woop, Benthin &
    Wald 2013, watertight ray/triangle intersection, JCGT 2(1); Waechter & Binder 2019,
    "A fast and robust method for avoiding self-intersection", Ray Tracing Gems ch. 6). OptiX on
    a 10 km plate met the face a ray leaves with :func:`_offset` alone; for a person's or a
    building's faces :func:`_offset` is the larger and nothing changes."""
    out = []
    for part in scene.parts:
        v = np.abs(scene.vertices(part)).max(axis=1)
        tris = part.triangles
        out.append(v[tris].max(axis=1) if len(tris) else np.zeros(0))
    if not out:
        return np.zeros(0, dtype=np.float32)
    return (LEAVE_ULPS * np.finfo(np.float32).eps * np.concatenate(out)).astype(np.float32)


def _rotated_lattice(mi, dr, count: int, index, cell, seed: int):
    """Point ``index`` of a ``count``-point Fibonacci lattice shifted modulo 1 by one random vector
    per ``cell`` (Cranley-Patterson rotation, :func:`_cell_shift`): a cell's x coordinates are
    evenly spaced, 1/count apart (stratified), and the cells' shifts are independent, so the
    replicas' spread estimates the error (randomised QMC; Owen 1997). Until issue 31.1 the shift
    was drawn per lane (iid uniform points); per cell, at the same cost, the demo stage's LWIR
    ground error fell 13.0 -> 10.1 mK and its MWIR frame stopped after 2 batches instead of 4.
    Such a cell's mean is a discrete variable over a step between faces or a small hot surface
    seen by the reflected rays (the count of points on one side takes 2 or 3 values), so two
    replicas often agree exactly: see :data:`DEFAULT_REPLICAS`."""
    lat = _fibonacci_lattice(count).astype(np.float32)
    x = dr.gather(mi.Float, mi.Float(lat[:, 0]), index)
    y = dr.gather(mi.Float, mi.Float(lat[:, 1]), index)
    sx, sy = _cell_shift(mi, dr, cell, seed)
    x, y = x + sx, y + sy
    return x - dr.floor(x), y - dr.floor(y)


def _cell_shift(mi, dr, cell, seed: int):
    """The Cranley-Patterson shift (x, y) in [0, 1)^2 of each ``cell`` (UInt32), the same for
    every lane of the cell, so that a cell's points stay a shifted lattice: a hash of the cell
    and the seed, TEA with 8 rounds (Zafar, Olano & Curtis, "GPU random numbers via the tiny
    encryption algorithm", HPG 2010), 24-bit floats. (Not ``PCG32(size=n, initseq=cell)``:
    drjit's constructor adds ``arange(n)`` to the state and the stream, which gave every lane
    a shift of its own, i.e. iid uniform points; issue 31.1 found it.) The seed (folded to 32
    bits) is a kernel parameter, not a literal: one compiled kernel for every seed."""
    seed32 = (int(seed) ^ (int(seed) >> 32)) & 0xFFFFFFFF
    a, b = mi.sample_tea_32(mi.UInt32(cell), dr.opaque(mi.UInt32, seed32), 8)
    scale = 1.0 / (1 << 24)
    return mi.Float(a >> 8) * scale, mi.Float(b >> 8) * scale


def _fibonacci_lattice(m: int) -> np.ndarray:
    """(m, 2) points of the 2-D Fibonacci (golden-ratio rank-1) lattice in [0, 1)^2."""
    i = np.arange(m)
    return np.stack([(i + 0.5) / m, np.mod(i * 0.6180339887498949, 1.0)], axis=1)


def _rotated_lattice_sized(mi, dr, count, index, cell, seed: int, largest: int):
    """:func:`_rotated_lattice` with a lattice size per lane (``count``, UInt32, at most
    ``largest``): point ``index`` of a ``count``-point Fibonacci lattice, x = (i + 1/2) / count
    and y = frac(i phi) (the y column of :func:`_fibonacci_lattice` does not depend on the size:
    one table up to the largest index), shifted modulo 1 by the random vector of ``cell``."""
    n = 1 << max(int(largest) - 1, 1).bit_length()  # a power of two >= largest: few tables
    x = (mi.Float(index) + 0.5) / mi.Float(count)
    y = dr.gather(mi.Float, mi.Float(_golden_column(n)), index)
    sx, sy = _cell_shift(mi, dr, cell, seed)
    x, y = x + sx, y + sy
    return x - dr.floor(x), y - dr.floor(y)


@functools.lru_cache(maxsize=4)
def _golden_column(n: int) -> np.ndarray:
    """The y column of :func:`_fibonacci_lattice` for indices 0..n-1, float32 (read-only)."""
    out = np.ascontiguousarray(_fibonacci_lattice(n)[:, 1], dtype=np.float32)
    out.flags.writeable = False
    return out


class PixelLayout:
    r"""The lanes of one camera pass that gives each pixel its own sample count (prefix-sum
    layout): pixel k of ``pixels`` (flat indices) has ``replicas`` cells of ``points[k]``
    consecutive lanes each, lattice indices 0..points[k]-1; the pixels follow one another in
    the list's order. Lane :math:`\ell` belongs to the pixel k whose start
    :math:`s_k = \sum_{i<k} r\,P_i` is the last at or before it (found on the device by a
    prefix sum of start marks), its replica is :math:`\lfloor(\ell - s_k)/P_k\rfloor` and
    its lattice index the remainder. Replaces one pass per distinct count (about 50 per batch of
    the automatic quality, each traced and launched from Python) with one pass (issue 31.1);
    every cell keeps its own stratified lattice of its full size and its own random shift, so
    each pixel's estimate is the one a pass of that count alone gives."""

    def __init__(self, pixels, points, replicas: int):
        self.pixels = np.asarray(pixels, dtype=np.int64).ravel()
        self.points = np.asarray(points, dtype=np.int64).ravel()
        self.replicas = int(replicas)
        if self.pixels.shape != self.points.shape or (self.points < 1).any():
            raise ValueError("PixelLayout: one count >= 1 per pixel")
        per_pixel = self.points * self.replicas
        self.pixel_start = np.zeros(len(per_pixel), dtype=np.int64)
        np.cumsum(per_pixel[:-1], out=self.pixel_start[1:])
        self.lanes = int(per_pixel.sum())
        cell_size = np.repeat(self.points, self.replicas)
        self.cell_start = np.zeros(len(cell_size), dtype=np.int64)
        np.cumsum(cell_size[:-1], out=self.cell_start[1:])
        if self.lanes >= 2**32:
            raise ValueError(f"PixelLayout: {self.lanes} lanes, at most 2^32 - 1")
        self.count_dr = None  # set by the camera pass: the lattice size per camera lane (device)

    def lanes_on_device(self, mi, dr):
        """(k, replica, lattice index, count) per lane, UInt32 on the device."""
        marks = dr.zeros(mi.UInt32, self.lanes)
        if len(self.pixels) > 1:
            dr.scatter(marks, mi.UInt32(1), mi.UInt32(self.pixel_start[1:].astype(np.uint32)))
        k = dr.cumsum(marks)  # inclusive: the pixel position of each lane
        start = dr.gather(mi.UInt32, mi.UInt32(self.pixel_start.astype(np.uint32)), k)
        count = dr.gather(mi.UInt32, mi.UInt32(self.points.astype(np.uint32)), k)
        offset = dr.arange(mi.UInt32, self.lanes) - start
        # (at least 1: the LLVM backend divides a vector's padding lanes too, and x86 traps on 0)
        replica = offset // dr.maximum(count, 1)
        return k, replica, offset - replica * count, count

    def cell_sums(self, values) -> np.ndarray:
        """Per-lane values (..., lanes) summed per cell (..., pixels x replicas), float64, in a
        fixed order (deterministic whatever the thread count)."""
        return np.add.reduceat(np.asarray(values, dtype=np.float64), self.cell_start, axis=-1)

    def cell_points(self) -> np.ndarray:
        """Lattice points of each cell (pixels x replicas,)."""
        return np.repeat(self.points, self.replicas)


def merged_chunks(lanes_per_pixel, max_lanes: int) -> list[slice]:
    """Consecutive runs of pixels whose lanes stay within ``max_lanes`` (a pixel above it alone):
    the merged passes' memory bound (:data:`MAX_DIRECT_LANES`)."""
    lanes = np.asarray(lanes_per_pixel, dtype=np.int64)
    out, first, total = [], 0, 0
    for i, n in enumerate(lanes):
        if total and total + n > max_lanes:
            out.append(slice(first, i))
            first, total = i, 0
        total += int(n)
    if len(lanes):
        out.append(slice(first, len(lanes)))
    return out


def render_band_fast(
    scene,
    sensor_id: str,
    state,
    sub,
    emissivity_of,
    radiometry,
    spp: int,
    seed: int,
    transmittance_of=None,
    replicas: int = DEFAULT_REPLICAS,
    splits: int = DEFAULT_SPLITS,
    filter_radius: int = DEFAULT_FILTER_RADIUS,
    weights=None,
    tables: FaceTables | None = None,
    direct_points: int | None = None,
    direct_target=None,
    info: dict | None = None,
    smooth: bool | None = None,
    boost_first=None,
    sun_mean_steps: int | None = None,
    reuse: dict | None = None,
    sun_gain_steps: int | None = None,
    dark_gain_steps: int | None = None,
):
    """At-sensor band radiance and its Monte Carlo standard error of one IR sensor at one frame.

    Parameters are those of :func:`humv_usd.render.ir.render_band`; ``spp`` is the pixel's total
    sample count (shared by all sub-bands) and ``replicas`` the independent randomisations it is
    split into for the error estimate (spp = 1: one replica, error not estimable, NaN).
    ``weights`` (c, n): c output channels :math:`\\sum_k W_{ck} L_k` of the n sub-band radiances
    (None: the band radiance :math:`\\sum_k L_k`, one channel); every channel is estimated from
    the same paths. ``tables``: precomputed :class:`FaceTables` (then ``state``,
    ``emissivity_of`` and ``transmittance_of`` are not read), e.g. zero emission and per-bin
    reflectance for a reflective band. ``direct_points``: more pixel positions per camera
    sample for the direct term (None: chosen by :func:`extra_direct_points`).
    ``direct_target``: ``fn(radiance (c, H, W), variance (c, H, W)) -> (H, W)`` the variance
    [W2 m-4 sr-2] under which the caller wants each pixel's direct term (e.g. a share of its
    error target in K times dL/dT), given the call's pixel means and their stated variance
    before any boost (e.g. to boost only the regions that would miss their targets); every
    pixel with a target is estimated afresh from samples whose count this call's own (the
    pilot) chose (:func:`fresh_factors`, two-stage sampling; one pass over those pixels only,
    each with its own count: :class:`PixelLayout`). ``info``: a dict filled with
    ``back_face_fraction`` (H, W),
    the share of a pixel's camera samples that saw a one-sided face from behind (rendered as the
    cavity radiance, :func:`cavity_table`), ``pixel_direct_points`` and ``pixel_reflect_samples``
    (H, W) (the fresh direct positions and camera samples per pilot camera sample), and for diagnostics the variances (c, H, W) of each pixel's direct and
    reflected means as the replicas give them (before the c4 correction): ``direct_var``,
    ``reflect_var`` (final), ``direct_var_before_boosts``, ``reflect_var_before_boosts`` and
    ``reflect_var_unfiltered`` (the call's own samples).
    ``smooth``: shade each hit with its faces' surface terms blended to the corners and
    interpolated at the hit (:func:`corner_blend`, Gouraud); False: one value per flat face,
    as the path tracer (:func:`humv_usd.render.ir.render_band`) shades; None:
    :data:`SMOOTH_SHADING`. ``boost_first`` (H, W) bool: pixels whose boosts have budgets of
    their own, the other pixels as large ones (:func:`within_budget`; e.g. the people's).
    ``sun_mean_steps``: Van Cittert steps of the smooth sun term toward each face's mean
    (:func:`corner_table`; None: :data:`SUN_MEAN_STEPS`); ``sun_gain_steps``: its one-ring
    gain steps (None: :data:`SUN_GAIN_STEPS`); ``dark_gain_steps``: the one-ring gain steps of
    the smooth shadowed term (None: :data:`DARK_GAIN_STEPS`).
    ``reuse``: a dict the caller keeps across calls with the same scene geometry, state,
    sub-bands, emissivities, radiometry and options (the batches of one frame): the first call
    stores the per-triangle tables on the device there, the later ones read them (issue 31.1:
    0.1-0.2 CPU-s per 1024x768 batch).

    Returns
    -------
    radiance, stderr : (H, W) float64, or (c, H, W) when ``weights`` is given
        [W m^-2 sr^-1]; stderr from the spread of the replica means (RQMC), NaN when one replica.
    """
    mi = mode.mitsuba()
    import drjit as dr

    t0, c0 = time.perf_counter(), time.process_time()

    def note(msg: str, *args) -> None:
        """A debug timing (kernels run asynchronously: wait for them, only when debugging)."""
        if log.isEnabledFor(logging.DEBUG):
            dr.sync_thread()
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            log.debug(msg + ", %.3f s wall, %.3f CPU-s", *args, wall, cpu)

    spp = int(spp)
    splits = max(1, int(splits))
    replicas = replica_count(spp, replicas)
    lattice_n = spp // replicas
    n = len(sub)
    setup = scene.sensors[sensor_id]
    w, h = int(setup.width), int(setup.height)
    # the filter's windows and the edges depend only on the pixel-centre hits: built on a
    # thread while the device traces the paths (numpy releases the GIL)
    hits = scene.hits(sensor_id)
    windows = _InBackground(_filter_windows, hits, setup.pose.fov_x_deg, filter_radius)
    wts = channel_weights(weights, n)
    channels = wts.shape[0]
    f32 = mi.Float
    built = None if reuse is None else reuse.get("device_tables")
    if built is None:
        if tables is None:
            tables = face_tables(scene, state, sub, emissivity_of, transmittance_of)

        # --- sky, control variate, sun, path as flat tables --------------------------------------
        rows = np.stack([sky_rows(radiometry, k) for k in range(n)])  # (n, H)
        sun_e = radiometry.sun_irradiance if (scene_sun := radiometry.sun_direction) is not None else None
        sun_dir = None if scene_sun is None else np.asarray(scene_sun, float)
        g_up = control_variate_table(rows, rows[:, SKY_MAP_HEIGHT // 2], nodes=2)[:, -1]  # up-facing
        normals = face_normals(scene)
        ground = ground_radiance(scene, tables, g_up, 0.0 if sun_dir is None else sun_dir[2], sun_e, normals)
        g_tab = control_variate_table(rows, ground)  # (n, CV_NODES)
        cloud = getattr(radiometry, "clouds", None) if sun_e is not None else None
        if cloud is not None:  # broken clouds: the clear-sky beam between them, none under them
            sun_e = np.asarray(sun_e, float) * cloud.clear_factor
        surface = surface_table(scene, tables, g_tab, sun_dir, sun_e, normals)  # (T, 3, n)
        smooth = SMOOTH_SHADING if smooth is None else bool(smooth)
        steps = SUN_MEAN_STEPS if sun_mean_steps is None else int(sun_mean_steps)
        gains = SUN_GAIN_STEPS if sun_gain_steps is None else int(sun_gain_steps)
        dark_gains = DARK_GAIN_STEPS if dark_gain_steps is None else int(dark_gain_steps)
        rows_7n = corner_table(
            surface, _smooth_blend(scene) if smooth else None, steps, gains, dark_gains
        )  # (T, 7n)
        note("tables: %d triangles", len(surface))

        surf_dr = f32(rows_7n.astype(np.float32).ravel())
        cavity = cavity_table(tables)  # (T, n): back sides, on the classes of CAVITY_CLASSES only
        ends = list(tables.offset[1:]) + [len(cavity)]
        for part, first, last in zip(scene.parts, tables.offset, ends):
            if getattr(part, "label_class", None) not in CAVITY_CLASSES:
                cavity[first:last] = 0.0
        cavity_dr = f32(cavity.astype(np.float32).ravel())
        mirrors = _mirror_tables(mi, scene, tables, sub)  # calm water (puddles): Fresnel mirrors
        sky_dr = f32(np.ascontiguousarray(rows.T, dtype=np.float32).ravel())  # (H, n)
        ground_k = [dr.opaque(f32, float(g)) for g in ground]
        part_of_key = {p.key: i for i, p in enumerate(scene.parts)}
        keys, offs = [], []
        for shape in scene.scene.shapes():
            keys.append(int(np.asarray(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape)))[0]))
            offs.append(int(tables.offset[part_of_key[shape.id()]]))
        offset_lookup = np.zeros(max(keys) + 1, dtype=np.uint32)
        offset_lookup[keys] = offs
        offset_dr = mi.UInt32(offset_lookup)
        leave_dr = f32(face_leave_offsets(scene))
        sun_vec = None
        if sun_dir is not None:
            sun_vec = mi.Vector3f(*(dr.opaque(f32, float(v)) for v in sun_dir))
        lamps = _lamps_on_device(mi, dr, getattr(radiometry, "lamps", None), n)
        cloud_dev = None if cloud is None or sun_vec is None else _clouds_on_device(mi, dr, cloud)
        built = (
            surf_dr,
            cavity_dr,
            mirrors,
            sky_dr,
            ground_k,
            offset_dr,
            leave_dr,
            sun_vec,
            lamps,
            cloud_dev,
        )
        if reuse is not None:  # the next batch of this frame: the same tables
            reuse["device_tables"] = built
    surf_dr, cavity_dr, mirrors, sky_dr, ground_k, offset_dr, leave_dr, sun_vec, lamps, cloud_dev = built
    lamp_calls = [0]  # a window's sample points: a new random sequence per call

    def sky_at(dz):
        """(row index, weight) of a direction's zenith in the sky rows, shared by the sub-bands."""
        x = dr.clip(
            dr.acos(dr.clip(dz, -1.0, 1.0)) * ((SKY_MAP_HEIGHT - 1) / np.pi), 0.0, SKY_MAP_HEIGHT - 1.0
        )
        i = dr.minimum(mi.UInt32(dr.floor(x)), SKY_MAP_HEIGHT - 2)
        return i * n, x - mi.Float(i)

    def sky(k, at, active=True):
        base, t = at
        lo = dr.gather(f32, sky_dr, base + k, active)
        return lo + (dr.gather(f32, sky_dr, base + (n + k), active) - lo) * t

    def triangle(si, active):
        """Global triangle index of a hit (face table row)."""
        shape = dr.reinterpret_array(mi.UInt32, si.shape)
        return dr.gather(mi.UInt32, offset_dr, shape, active) + si.prim_index

    def leave(p, tri, active=True):
        """How far [m] a ray leaving face ``tri`` at ``p`` starts off it: :func:`_offset`, or
        more on a large face (:func:`face_leave_offsets`)."""
        return dr.maximum(_offset(dr, p), dr.gather(f32, leave_dr, tri, active))

    def surface_terms(p, nrm, tri, uv, active=True):
        """(surface-leaving radiance - the reflected sky/ground part sampled later, reflectance)
        per sub-band at front-facing vertices: emission + rho (G + sun if the sun is seen),
        interpolated between the triangle's corners at the hit's barycentric coordinates
        ``uv`` (Mitsuba's ``si.uv`` of a mesh without texture coordinates: b1, b2)."""
        row = tri * (7 * n)
        base = row
        if sun_vec is not None:
            lit = active & (dr.dot(nrm, sun_vec) > 0.0)
            if cloud_dev is not None:  # no sun under a cloud (the thermal tool's field)
                lit &= _between_clouds(mi, dr, cloud_dev, p, lit)
            blocked = scene.scene.ray_test(mi.Ray3f(p + nrm * leave(p, tri, lit), sun_vec), True, lit)
            base = dr.select(lit & ~blocked, base + n, base)
        b1, b2 = uv.x, uv.y
        surf = []
        for k in range(n):  # v0 + (v1 - v0) b1 + (v2 - v0) b2: exactly v0 on a uniform face
            v0 = dr.gather(f32, surf_dr, base + k, active)
            v1 = dr.gather(f32, surf_dr, base + (2 * n + k), active)
            v2 = dr.gather(f32, surf_dr, base + (4 * n + k), active)
            surf.append(v0 + (v1 - v0) * b1 + (v2 - v0) * b2)
        rho = [dr.gather(f32, surf_dr, row + (6 * n + k), active) for k in range(n)]
        if lamps is not None:  # the lamps' direct light (next-event estimation)
            lamp_calls[0] += 1
            e = _lamp_irradiance(mi, dr, scene.scene, lamps, p, nrm, active, seeds[2] + 7919 * lamp_calls[0])
            surf = [surf[k] + rho[k] * e[k] for k in range(n)]
        return surf, rho

    # --- camera samples: pixel x replica x lattice point -------------------------------------
    total = w * h * spp
    rng_np = np.random.default_rng([int(seed) % 2**32, 0x13])
    seeds = [int(v) for v in rng_np.integers(0, 2**62, size=4)]
    sensor = scene.mitsuba_sensor(sensor_id)

    back_counts = []  # per pass: back-side camera samples per cell

    def camera_pass(points, shift_seed: int, reflect: bool):
        """Camera samples: ``points`` stratified pixel positions per (pixel, replica) cell of
        every pixel, or a :class:`PixelLayout` (its pixels only, each with its own count, cells
        in its order); returns the per-cell mean of the direct term (c, cells) and, if
        ``reflect``, what the reflected term needs (lattice index, cell, first hit, its
        throughput per sub-band)."""
        layout = points if isinstance(points, PixelLayout) else None
        if layout is not None:  # a count per pixel, one pass (PixelLayout)
            k, replica, j, per_cell = layout.lanes_on_device(mi, dr)
            pixel = dr.gather(mi.UInt32, mi.UInt32(layout.pixels.astype(np.uint32)), k)
            rot_cell = cell = pixel * replicas + replica
            largest = int(layout.points.max())
            px, py = _rotated_lattice_sized(mi, dr, per_cell, j, rot_cell, shift_seed, largest)
        else:
            idx = dr.arange(mi.UInt32, w * h * replicas * points)
            per_cell = dr.opaque(mi.UInt32, points)  # a parameter: kernels are reused across counts
            j = idx % per_cell
            rot_cell = cell = idx // per_cell  # pixel * replicas + replica
            pixel = cell // replicas
            px, py = _rotated_lattice(mi, dr, points, j, rot_cell, shift_seed)
        fx = (mi.Float(pixel % w) + px) / w
        fy = (mi.Float(pixel // w) + py) / h
        ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(fx, fy), mi.Point2f(0.5, 0.5))
        # camera rays are coherent (a pixel's lanes are consecutive): Embree's coherent mode
        # traces them ~3x faster on the CPU (same hits but for ties at shared edges)
        si = scene.scene.ray_intersect(ray, mi.RayFlags.All, True)
        hit = si.is_valid()
        front = hit & (dr.dot(si.n, ray.d) < 0.0)
        back = hit & ~front
        surf, rho = surface_terms(si.p, si.n, triangle(si, front), si.uv, front)
        back_base = triangle(si, back) * n
        where = sky_at(ray.d.z)
        value = [
            dr.select(
                hit,
                dr.select(front, surf[k], dr.gather(f32, cavity_dr, back_base + k, back)),
                sky(k, where, ~hit),
            )
            for k in range(n)
        ]
        rho = [dr.select(front, r, 0.0) for r in rho]
        mirror = None
        if mirrors is not None:  # a mirror: (1 - R) B(T) emitted, R times the mirror ray's radiance
            tri_f = triangle(si, front)
            mirror = front & (dr.gather(f32, mirrors.flag, tri_f, front) > 0.5)
            mu = dr.clip(-dr.dot(ray.d, si.n), 0.0, 1.0)
            fresnel = _fresnel(mi, dr, mirrors, mu, n, mirror)
            for k in range(n):
                body = dr.gather(f32, mirrors.blackbody, tri_f * n + k, mirror)
                value[k] = dr.select(mirror, (1.0 - fresnel[k]) * body, value[k])
                rho[k] = dr.select(mirror, fresnel[k], rho[k])
        if lamps is not None and lamps.rects:  # a lit window in front of the first hit
            seen, t_window, window = _windows_seen(mi, dr, lamps, ray, dr.select(hit, si.t, dr.inf))
            value = [dr.select(seen, window[k], value[k]) for k in range(n)]
            rho = [dr.select(seen, 0.0, r) for r in rho]
            front, back = front & ~seen, back & ~seen
            if mirror is not None:
                mirror = mirror & ~seen
            si.t = dr.select(seen, t_window, si.t)
            hit = hit | seen
        backs = dr.select(back, f32(1.0), f32(0.0))
        if layout is not None:
            back_counts.append(backs)  # per lane: summed per cell below
        else:
            back_counts.append(dr.block_sum(backs, points) if points > 1 else backs)
        # the atmospheric path per camera sample, at the range of its first hit (sky: none)
        # (the path radiance enters each channel as one weighted sum, tabulated per channel)
        path = radiometry.path
        if path is None:
            direct_dr = [_weighted_sum(value, wts[c]) for c in range(channels)]
        else:
            lerp = _path_interpolation(mi, dr, path, dr.select(hit, si.t, 0.0), n, wts)
            tau = [lerp(0, k) for k in range(n)]
            seen = [tau[k] * value[k] for k in range(n)]
            direct_dr = [
                dr.select(hit, _weighted_sum(seen, wts[c]) + lerp(2, c), _weighted_sum(value, wts[c]))
                for c in range(channels)
            ]
            rho = [rho[k] * tau[k] for k in range(n)]  # the reflected term's throughput
        if layout is not None:  # per cell, on the host in a fixed order: sums / points
            dr.eval(
                direct_dr,
                back_counts[-1],
                *(
                    [rho, front, si.p, si.n, per_cell, ray.d] + ([mirror] if mirror is not None else [])
                    if reflect
                    else []
                ),
            )
            back_counts[-1] = layout.cell_sums(back_counts[-1])
            direct = layout.cell_sums(np.stack([np.asarray(v) for v in direct_dr])) / layout.cell_points()
            if not reflect:
                return direct, None
            layout.count_dr = per_cell  # the reflected term's lattice sizes, per camera lane
            return direct, (j, cell, front, si, rho, mirror, ray.d)
        # per (pixel, replica) cell: the mean of its lattice points, per channel
        if points > 1:
            inv_points = dr.opaque(f32, 1.0 / points)
            direct_dr = [dr.block_sum(v, points) * inv_points for v in direct_dr]
        if not reflect:
            dr.eval(direct_dr, back_counts[-1])
            return np.stack([np.asarray(v, dtype=np.float64) for v in direct_dr]), None
        dr.eval(
            direct_dr,
            rho,
            front,
            si.p,
            si.n,
            back_counts[-1],
            ray.d,
            *([mirror] if mirror is not None else []),
        )
        direct = np.stack([np.asarray(v, dtype=np.float64) for v in direct_dr])  # (c, cells)
        return direct, (j, cell, front, si, rho, mirror, ray.d)

    rays = 0  # reflection rays traced (the cost of the reflected term, in camera samples)

    def reflect_pass(
        j, cell, front, si, beta0, mirror, ray_d, points: int, samples: int, dir_seed: int, rr_seed: int
    ):
        """The reflected term of a camera pass's front-facing vertices: per-cell means (c,
        cells) of ``splits`` stratified cosine directions per vertex, continued by Russian
        roulette; ``points`` lattice points per cell, ``samples`` camera samples in all."""
        nonlocal rays
        parent = dr.compress(front)
        m = dr.width(parent)

        # --- reflection: `splits` stratified cosine directions per front-facing camera vertex ------
        # per lane sums (each scatter has distinct targets: the order of additions, and so the
        # result, does not depend on the threads), reduced to cells in a fixed order at the end
        acc = [dr.zeros(f32, m * splits) for _ in range(channels)]
        if m:
            b = dr.arange(mi.UInt32, m * splits)
            par = dr.gather(mi.UInt32, parent, b // splits)
            d_index = dr.gather(mi.UInt32, j, par) * splits + b % splits
            par_cell = dr.gather(mi.UInt32, cell, par)
            if isinstance(points, PixelLayout):  # a lattice size per cell (count per camera lane)
                sized = dr.gather(mi.UInt32, points.count_dr, par) * splits
                largest = int(points.points.max()) * splits
                u1, u2 = _rotated_lattice_sized(mi, dr, sized, d_index, par_cell, dir_seed, largest)
                inv_lanes = 1.0 / f32(points.count_dr * splits)  # per camera lane
            else:
                u1, u2 = _rotated_lattice(mi, dr, points * splits, d_index, par_cell, dir_seed)
                inv_lanes = dr.opaque(f32, 1.0 / (splits * points))
            p0 = dr.gather(mi.Point3f, si.p, par)
            n0 = mi.Vector3f(dr.gather(mi.Normal3f, si.n, par))
            beta = None  # first bounce: read from the camera vertices' throughput when needed

            def beta_at(lanes):
                """Throughput per sub-band of the given lanes (at the first bounce each lane's term
                enters its cell's mean over lattice points and directions)."""
                if beta is not None:
                    return [dr.gather(f32, bk, lanes) for bk in beta]
                src = dr.gather(mi.UInt32, parent, lanes // splits)
                inv = inv_lanes if dr.width(inv_lanes) == 1 else dr.gather(f32, inv_lanes, src)
                return [dr.gather(f32, bk, src) * inv for bk in beta0]

            lane_id = b
            origin = dr.gather(mi.UInt32, triangle(si, front), par)  # the face each ray leaves
            d = mi.Frame3f(n0).to_world(mi.warp.square_to_cosine_hemisphere(mi.Point2f(u1, u2)))
            mirror_lane = None
            if mirror is not None:  # a mirror's lanes follow its mirror direction, no control variate
                mirror_lane = dr.gather(mi.Bool, mirror, par)
                incident = dr.gather(mi.Vector3f, ray_d, par)
                d = dr.select(mirror_lane, incident - n0 * (2.0 * dr.dot(incident, n0)), d)
            start = leave(p0, origin)
            ray = mi.Ray3f(p0 + n0 * start, d)
            for depth in range(1, MAX_DEPTH):
                si = _intersect_leaving(mi, dr, scene.scene, ray, n0, start, origin, triangle)
                rays += dr.width(ray.d.z)
                hit = si.is_valid()
                front = hit & (dr.dot(si.n, ray.d) < 0.0)
                dz = ray.d.z
                # escaping above the horizon: sky - C = 0; no surface: sky - L_g below the horizon;
                # a back face: its cavity radiance - C (:func:`cavity_table`)
                odd = ~front & (hit | (dz < 0.0))
                first_mirror = mirror_lane if depth == 1 else None
                if first_mirror is not None:  # a mirror ray escaping to the sky: its radiance - 0
                    odd |= first_mirror & ~hit
                tri = triangle(si, hit)
                dr.eval(hit, front, odd, tri, si.p, si.n, si.uv, dz)
                lanes_odd = dr.compress(odd)
                if dr.width(lanes_odd):
                    beta_o = beta_at(lanes_odd)
                    dz_o = dr.gather(f32, dz, lanes_odd)
                    hit_o = dr.gather(mi.Bool, hit, lanes_odd)
                    back_o = dr.gather(mi.UInt32, tri, lanes_odd, hit_o) * n
                    up_o = dz_o >= 0.0
                    where = sky_at(dz_o)
                    terms = []
                    for k in range(n):
                        sky_k = sky(k, where)
                        seen = dr.select(hit_o, dr.gather(f32, cavity_dr, back_o + k, hit_o), sky_k)
                        control = dr.select(up_o, sky_k, ground_k[k])
                        if first_mirror is not None:
                            control = dr.select(dr.gather(mi.Bool, first_mirror, lanes_odd), 0.0, control)
                        terms.append(beta_o[k] * (seen - control))
                    _scatter_channels(dr, acc, terms, wts, dr.gather(mi.UInt32, lane_id, lanes_odd))
                on = dr.compress(front)
                width = dr.width(on)
                note(
                    "depth %d: %d lanes, %d front, %d other",
                    depth,
                    dr.width(front),
                    width,
                    dr.width(lanes_odd),
                )
                if width == 0:
                    break
                p = dr.gather(mi.Point3f, si.p, on)
                nrm = mi.Vector3f(dr.gather(mi.Normal3f, si.n, on))
                dz_f = dr.gather(f32, dz, on)
                beta = beta_at(on)
                lane_id = dr.gather(mi.UInt32, lane_id, on)
                origin = dr.gather(mi.UInt32, tri, on)
                surf, rho = surface_terms(
                    p, nrm, dr.gather(mi.UInt32, tri, on), dr.gather(mi.Point2f, si.uv, on)
                )
                up = dz_f >= 0.0
                where = sky_at(dz_f)
                terms = []
                mirror_on = None if first_mirror is None else dr.gather(mi.Bool, first_mirror, on)
                for k in range(n):
                    control = dr.select(up, sky(k, where, up), ground_k[k])
                    if mirror_on is not None:
                        control = dr.select(mirror_on, 0.0, control)
                    terms.append(beta[k] * (surf[k] - control))
                _scatter_channels(dr, acc, terms, wts, lane_id)
                beta = [beta[k] * rho[k] for k in range(n)]
                bmax = beta[0]
                for bk in beta[1:]:
                    bmax = dr.maximum(bmax, bk)
                alive = bmax > 0.0
                rng = mi.PCG32(
                    size=width, initstate=dr.opaque(mi.UInt64, rr_seed + depth), initseq=mi.UInt64(lane_id)
                )
                if depth + 1 >= RR_DEPTH:
                    q = dr.clip(bmax, RR_MIN, RR_MAX)
                    alive &= rng.next_float32() < q
                    beta = [bk / q for bk in beta]
                u1, u2 = rng.next_float32(), rng.next_float32()
                dr.eval(acc, beta, alive, u1, u2)
                keep = dr.compress(alive)
                if dr.width(keep) == 0:
                    break
                beta = [dr.gather(f32, bk, keep) for bk in beta]
                lane_id = dr.gather(mi.UInt32, lane_id, keep)
                origin = dr.gather(mi.UInt32, origin, keep)
                p0 = dr.gather(mi.Point3f, p, keep)
                n0 = dr.gather(mi.Vector3f, nrm, keep)
                local = mi.warp.square_to_cosine_hemisphere(
                    mi.Point2f(dr.gather(f32, u1, keep), dr.gather(f32, u2, keep))
                )
                start = leave(p0, origin)
                ray = mi.Ray3f(p0 + n0 * start, mi.Frame3f(n0).to_world(local))
        if isinstance(points, PixelLayout):  # lanes -> camera samples -> cells (host, fixed order)
            return points.cell_sums(
                np.stack([_lanes_to_cells(mi, dr, a, parent, splits, samples, 1) for a in acc])
            )
        return np.stack(
            [np.asarray(_lanes_to_cells(mi, dr, a, parent, splits, samples, points)) for a in acc]
        )

    direct_r, (j, cell, front, si, beta0, mirror0, ray_d0) = camera_pass(lattice_n, seeds[0], True)
    note("camera vertices and path: %d samples", total)
    reflect_r = reflect_pass(j, cell, front, si, beta0, mirror0, ray_d0, lattice_n, total, seeds[1], seeds[2])
    note("paths done")

    # --- per pixel means, RQMC errors, and the reflected part filtered over the surface --------
    def replica_stats(values):
        """Per pixel mean (c, H, W) and the variance of that mean from its replicas."""
        values = values.reshape(channels, h, w, replicas)
        if replicas == 1:
            return values[..., 0], np.full((channels, h, w), np.nan)
        # one replica at a time (strided views): no (c, H, W, replicas) temporaries
        total = values[..., 0].copy()
        for r in range(1, replicas):
            total += values[..., r]
        mean = total / replicas
        var = np.zeros_like(mean)
        for r in range(replicas):
            dev = values[..., r] - mean
            var += dev * dev
        return mean, var / (replicas * (replicas - 1))

    direct, direct_var = replica_stats(direct_r)
    reflect_mean, reflect_var = replica_stats(reflect_r)
    if info is not None:  # the batch's own terms before any boost (diagnostics)
        info["reflect_var_unfiltered"] = reflect_var
    radius_px = windows.result()
    note("replica statistics (filter windows ready)")
    if filter_radius > 0:
        reflect_mean, reflect_var = _filtered(
            reflect_mean, reflect_var, hits, filter_radius, radius_px, mirrors
        )
    # --- more pixel positions for the direct term where it dominates the error ----------------
    if direct_points is None:
        extra = extra_direct_points(direct_var, reflect_var, _cached_edges(hits), total, rays)
    else:
        extra = max(0, int(direct_points))
    back_seen = np.asarray(back_counts[0], dtype=np.float64).reshape(h * w, replicas).sum(axis=1)
    samples_seen = np.full(h * w, float(spp))
    if extra:
        more, _ = camera_pass(lattice_n * extra, seeds[3], False)
        direct_r = (direct_r + extra * more) / (1 + extra)
        direct, direct_var = replica_stats(direct_r)
        back_seen += np.asarray(back_counts[-1], dtype=np.float64).reshape(h * w, replicas).sum(axis=1)
        samples_seen += spp * extra
        note("direct term: %d more pixel positions per camera sample", extra)
    # --- and per pixel, where the caller's target asks for it (sub-pixel temperature mixes,
    # small surfaces whose reflected part the filter cannot average) ---------------------------
    boost = np.zeros((h, w), dtype=np.int64)
    boost_reflect = np.zeros((h, w), dtype=np.int64)
    if info is not None:
        info["direct_var_before_boosts"] = direct_var
        info["reflect_var_before_boosts"] = reflect_var
    if direct_target is not None and replicas > 1:
        scale = c4(replicas) ** -2  # the error as stated is divided by c4 (below)
        target = np.asarray(
            direct_target(direct + reflect_mean, scale * (direct_var + reflect_var)), dtype=float
        )
        aimed = (target > 0) & np.isfinite(target)
        # Two-stage sampling (:func:`fresh_factors`): the counts come from this batch's samples
        # (the pilot) and every pixel with a target is estimated from fresh samples alone.
        # Pooling the pilot with samples whose count it chose biased the means (the humvvex
        # person -5.9 mK at lwir640, 2.7 SE; a warm wall next to a hot box +37 mK, 34 SE).
        # 1. the reflected part above half the target: f_r fresh camera samples with their
        # reflections per camera sample of the pilot, enough alone
        boost_reflect = fresh_factors(scale * reflect_var, 0.5 * target, MAX_PIXEL_REFLECT_FACTOR)
        boost_reflect = within_budget(
            boost_reflect,
            max(BOOST_BUDGET * h * w, MIN_BOOST_BUDGET),
            variance_ratio(scale * reflect_var, 0.5 * target),
            boost_first,
        )
        # every pixel with a target is estimated afresh (at least one fresh camera sample set
        # per pilot's): whether a pixel is boosted must not depend on its own pilot either (a
        # warm wall's unboosted pixels, chosen by their pilots' agreement, read +37 mK, 30 SE)
        boost_reflect = np.where(aimed, np.maximum(boost_reflect, 1), 0)
        d_cells = direct_r.reshape(channels, h * w, replicas)  # views: replaced in place
        r_cells = reflect_r.reshape(channels, h * w, replicas)
        second = np.zeros((channels, h * w, replicas))  # the reflected pass's direct term
        chosen = np.flatnonzero(boost_reflect.ravel() > 0)
        factors = boost_reflect.ravel()[chosen].astype(np.int64)
        lanes = replicas * lattice_n * factors * splits
        # one pass for all the chosen pixels, each with its own count (PixelLayout), in chunks
        # of at most MAX_DIRECT_LANES reflection lanes; seeds apart from the batch's own passes
        for c, part in enumerate(merged_chunks(lanes, MAX_DIRECT_LANES)):
            pixels, factor = chosen[part], factors[part]
            layout = PixelLayout(pixels, lattice_n * factor, replicas)
            more_d, cam = camera_pass(layout, seeds[0] + 1, True)
            more_r = reflect_pass(*cam, layout, layout.lanes, seeds[1] + 1, seeds[2] + ((c + 1) << 8))
            shape = (channels, len(pixels), replicas)
            r_cells[:, pixels, :] = more_r.reshape(shape)
            second[:, pixels, :] = more_d.reshape(shape)
            back_seen[pixels] += np.asarray(back_counts.pop(), np.float64).reshape(-1, replicas).sum(axis=1)
            samples_seen[pixels] += spp * factor
            note(
                "reflected term: %d fresh reflection lanes in %d pixels (one pass)",
                int(lanes[part].sum()),
                len(pixels),
            )
        if boost_reflect.any():
            reflect_mean, reflect_var = replica_stats(reflect_r)
            if filter_radius > 0:
                reflect_mean, reflect_var = _filtered(
                    reflect_mean, reflect_var, hits, filter_radius, radius_px, mirrors
                )
        # 2. the direct term, afresh in every pixel with a target: its count from the pilot's
        # direct samples and the reflected pass's (a second pilot: two replicas alone rarely see
        # a step between faces that covers a small part of the pixel), enough for what the
        # reflected part leaves of the target, at least half of it, and at least as many
        # positions as the two pilots had (direct positions are cheap: a camera ray and a sun
        # shadow ray each)
        positions = 1.0 + extra  # the pilot's direct positions per camera sample
        per_position = scale * direct_var.sum(axis=0) * positions
        mix = direct
        on = boost_reflect.ravel() > 0
        if on.any():
            mean2 = second[:, on, :].mean(axis=2)
            var2 = ((second[:, on, :] - mean2[..., None]) ** 2).sum(axis=2) / (replicas * (replicas - 1))
            f_r = boost_reflect.ravel()[on]
            flat = per_position.reshape(-1)  # a view: the two pilots' per-position variances
            flat[on] = 0.5 * (flat[on] + scale * var2.sum(axis=0) * f_r)
            mix = direct.reshape(channels, -1).copy()
            mix[:, on] = (positions * mix[:, on] + f_r * mean2) / (positions + f_r)
            mix = mix.reshape(direct.shape)
        seen = positions + boost_reflect  # positions per camera sample in the two pilots
        floor = scale * step_variance(mix, hits.part, replicas * lattice_n)
        direct_goal = np.maximum(target - scale * np.nansum(reflect_var, axis=0), 0.5 * target)
        with np.errstate(invalid="ignore", divide="ignore"):
            if lamps is None or (not lamps.rects and len(lamps.points) <= MAX_LAMP_RAYS):
                # The direct term is a function of the pixel position alone (emission, the sun
                # behind one shadow ray, the path): each cell's lattice integrates it over the
                # footprint, and the error variance of a lattice at a step between faces falls
                # as n^-3/2, not 1/n (Mitchell, "Consequences of stratified sampling in
                # graphics", SIGGRAPH 1996): from a pilot of n0 position sets with variance V0,
                # n = n0 (V0 / goal)^(2/3) sets (the floor: V0 at one set). A lit window's random
                # sample point, or one lamp drawn of many, is not a function of the position:
                # with those, 1/n.
                e = DIRECT_LATTICE_EXPONENT
                ratio = np.maximum(
                    positions * (per_position / positions / direct_goal) ** e, (floor / direct_goal) ** e
                )
            else:
                ratio = np.maximum(per_position, floor) / direct_goal  # independent positions: 1/n
            wanted = np.where(aimed, np.ceil(ratio), 0.0)
        per_position = np.maximum(per_position, floor)
        wanted = np.clip(np.nan_to_num(wanted, nan=0.0, posinf=0.0), 0, MAX_PIXEL_DIRECT_FACTOR)
        boost = within_budget(
            np.where(aimed, np.maximum(wanted, seen), 0).astype(np.int64),
            max(DIRECT_BOOST_BUDGET * h * w, 16 * MIN_BOOST_BUDGET),
            variance_ratio(per_position[None], direct_goal),
            boost_first,
        )
        boost = np.where(aimed, np.maximum(boost, 1), 0)  # every pixel with a target afresh
        chosen = np.flatnonzero(boost.ravel() > 0)
        factors = boost.ravel()[chosen].astype(np.int64)
        lanes = replicas * lattice_n * factors
        for part in merged_chunks(lanes, MAX_DIRECT_LANES):
            pixels, factor = chosen[part], factors[part]
            more, _ = camera_pass(PixelLayout(pixels, lattice_n * factor, replicas), seeds[3] + 1, False)
            d_cells[:, pixels, :] = more.reshape(channels, len(pixels), replicas)
            back_seen[pixels] += np.asarray(back_counts.pop(), np.float64).reshape(-1, replicas).sum(axis=1)
            samples_seen[pixels] += spp * factor
            note(
                "direct term: %d fresh pixel positions in %d pixels (one pass)",
                int(lanes[part].sum()),
                len(pixels),
            )
        if boost.any():
            direct, direct_var = replica_stats(direct_r)
    if info is not None:
        info["back_face_fraction"] = (back_seen / samples_seen).reshape(h, w)
        info["pixel_direct_points"] = boost
        info["pixel_reflect_samples"] = boost_reflect
        info["direct_points"] = extra
        info["direct_var"] = direct_var  # (c, H, W) variance of each term's pixel mean, as
        info["reflect_var"] = reflect_var  # the replicas give it (before the c4 correction)
    radiance = direct + reflect_mean
    stderr = np.sqrt(direct_var + reflect_var)
    if log.isEnabledFor(logging.DEBUG):
        rms = [
            float(np.sqrt(np.mean(v[np.isfinite(v)]))) if np.isfinite(v).any() else np.nan
            for v in (direct_var, reflect_var)
        ]
        note("filtered (rms error direct %.3g, reflected %.3g W m-2 sr-1)", *rms)
    if replicas > 1:
        stderr = stderr / c4(replicas)
    if weights is None:
        return radiance[0], stderr[0]
    return radiance, stderr


@dataclass
class _DeviceLamps:
    """A :class:`humv_usd.render.lights.LampTable` as kernel parameters (opaque scalars, so the
    kernels are reused when the lamps move or change)."""

    points: list
    rects: list


def _lamps_on_device(mi, dr, table, n: int):
    """The lamps of ``table`` (a :class:`humv_usd.render.lights.LampTable` or None) on the
    device, those with no light left out; None when none is left."""
    if table is None or len(table) == 0:
        return None

    def scalar(v):
        return dr.opaque(mi.Float, float(v))

    def vector(v):
        return mi.Vector3f(*(scalar(x) for x in v))

    points, rects = [], []
    for i in range(len(table.position)):
        intensity = np.asarray(table.intensity[i], float).reshape(n)
        if not np.any(intensity > 0):
            continue
        cut, beam = float(table.cutoff_rad[i]), float(table.beam_rad[i])
        points.append(
            SimpleNamespace(
                position=vector(table.position[i]),
                axis=vector(table.axis[i]) if cut < np.pi else None,
                cutoff=scalar(cut),
                beam=scalar(beam),
                inv_transition=scalar(1.0 / max(cut - beam, 1e-12)),
                value=[scalar(v) for v in intensity],
                total=float(intensity.sum()),
            )
        )
    for i in range(len(table.rect_centre)):
        radiance = np.asarray(table.rect_radiance[i], float).reshape(n)
        u, v = np.asarray(table.rect_u[i], float), np.asarray(table.rect_v[i], float)
        area = 4.0 * float(np.linalg.norm(np.cross(u, v)))
        if not np.any(radiance > 0) or area <= 0:
            continue
        rects.append(
            SimpleNamespace(
                centre=vector(table.rect_centre[i]),
                u=vector(u),
                v=vector(v),
                u_inv=vector(u / float(u @ u)),
                v_inv=vector(v / float(v @ v)),
                normal=vector(table.rect_normal[i]),
                area=scalar(area),
                value=[scalar(x) for x in radiance],
                total=float(radiance.sum()),
            )
        )
    return _DeviceLamps(points, rects) if points or rects else None


def _lamp_irradiance(mi, dr, scene, lamps: _DeviceLamps, p, nrm, active, seed: int) -> list:
    r"""Per sub-band :math:`E_k / \pi` of the lamps' direct light at points ``p`` with normals
    ``nrm`` (a Lambertian surface of reflectance :math:`\rho_k` reflects :math:`\rho_k E_k/\pi`),
    by next-event estimation:

    - a point lamp or spot of axial intensity :math:`I_k` at distance d along the unit vector
      :math:`\omega` (surface to lamp): :math:`E_k = I_k f(\theta)\,(n\cdot\omega)/d^2` if
      nothing lies between (the inverse-square and cosine laws; Kajiya 1986's rendering equation
      for a delta light), f the spot's falloff at :math:`\theta` off its axis (1 inside the
      beam angle, linear in angle to 0 at the cutoff: Mitsuba 3's ``spot``,
      :func:`humv_usd.render.lights.spot_falloff`); one shadow ray per lamp, up to
      :data:`MAX_LAMP_RAYS` lamps;
    - a window (a rectangle of area A and radiance :math:`L_k` emitting along N): one point y
      uniform on it, :math:`E_k = L_k A (n\cdot\omega)(-N\cdot\omega)/d^2` if visible
      (area sampling of the rendering equation's irradiance integral, unbiased; Pharr, Jakob &
      Humphreys, *Physically Based Rendering*, 4th ed., 2023, sec. 12.5).

    Many lights (the windows, and point lamps beyond :data:`MAX_LAMP_RAYS`): one of them per
    point, chosen with probability :math:`p_i` proportional to its unoccluded irradiance there
    (at a window's centre) plus a floor of 1e-3 of the mean (every light that can reach the
    point has :math:`p_i > 0`), its contribution divided by :math:`p_i`: one shadow ray instead
    of one per light, unbiased (light selection by estimated contribution, PBRT 4th ed.
    sec. 12.6)."""
    width = dr.width(p)
    n = len((lamps.points or lamps.rects)[0].value)
    out = [dr.zeros(mi.Float, width) for _ in range(n)]
    o = p + nrm * _offset(dr, p)
    rng = mi.PCG32(
        size=width, initstate=dr.opaque(mi.UInt64, int(seed) % 2**62), initseq=dr.arange(mi.UInt64, width)
    )

    def towards(target, on):
        v = target - o
        d2 = dr.squared_norm(v)
        dist = dr.sqrt(d2)
        w = v / dist
        cos_s = dr.dot(nrm, w)
        on = on & (cos_s > 0.0)
        return w, d2, dist, cos_s, on

    def add(weight, values):
        for k, value in enumerate(values):
            out[k] += weight * value

    def point_geometry(position, axis, beam, cutoff, inv_transition):
        w, d2, dist, cos_s, on = towards(position, active)
        fall = 1.0
        if axis is not None:  # a spot: Mitsuba's falloff, linear in angle
            theta = dr.acos(dr.clip(-dr.dot(w, axis), -1.0, 1.0))
            fall = dr.select(theta <= beam, 1.0, dr.clip((cutoff - theta) * inv_transition, 0.0, 1.0))
            on &= theta < cutoff
        return w, dist, dr.select(on, fall * cos_s / (d2 * np.pi), 0.0), on

    def trace(w, dist, weight, on, values):
        blocked = scene.ray_test(mi.Ray3f(mi.Ray3f(o, w), dist * (1.0 - 1e-4)), on)
        add(dr.select(on & ~blocked, weight, 0.0), values)

    def choose(estimates):
        """(index, probability) of one light per lane, p_i ~ estimate_i + floor."""
        total = estimates[0]
        for e in estimates[1:]:
            total = total + e
        floor = 1e-3 * total / len(estimates) + 1e-30
        total = total + floor * len(estimates)
        target = rng.next_float32() * total
        index = dr.full(mi.UInt32, len(estimates) - 1, width)
        chosen = estimates[-1] + floor
        acc = dr.zeros(mi.Float, width)
        found = dr.zeros(mi.Bool, width)
        for i, e in enumerate(estimates):
            acc = acc + e + floor
            take = ~found & (target < acc)
            index = dr.select(take, i, index)
            chosen = dr.select(take, e + floor, chosen)
            found |= take
        return index, chosen / total

    def pick(index, values):
        """values[index] per lane (a list of per-light device values or vectors)."""
        out_v = values[0]
        for i, v in enumerate(values[1:], start=1):
            out_v = dr.select(index == i, v, out_v)
        return out_v

    if len(lamps.points) <= MAX_LAMP_RAYS:
        for lamp in lamps.points:
            w, dist, weight, on = point_geometry(
                lamp.position, lamp.axis, lamp.beam, lamp.cutoff, lamp.inv_transition
            )
            trace(w, dist, weight, on, lamp.value)
    else:  # one lamp per point, by its unoccluded irradiance
        geo = [
            point_geometry(lamp.position, lamp.axis, lamp.beam, lamp.cutoff, lamp.inv_transition)
            for lamp in lamps.points
        ]
        index, prob = choose([g[2] * lamp.total for g, lamp in zip(geo, lamps.points)])
        w = pick(index, [g[0] for g in geo])
        dist = pick(index, [g[1] for g in geo])
        weight = pick(index, [g[2] for g in geo]) / prob
        on = pick(index, [g[3] for g in geo])
        trace(w, dist, weight, on, [pick(index, [lamp.value[k] for lamp in lamps.points]) for k in range(n)])
    if lamps.rects:  # one window per point, by its unoccluded irradiance at its centre
        rects = lamps.rects
        if len(rects) == 1:
            rect, prob = rects[0], 1.0
            centre, u, v, normal, area = rect.centre, rect.u, rect.v, rect.normal, rect.area
            values = rect.value
        else:
            estimates = []
            for r in rects:
                w_c, d2_c, _, cos_c, on_c = towards(r.centre, active)
                cos_lc = dr.maximum(-dr.dot(w_c, r.normal), 0.0)
                estimates.append(dr.select(on_c, r.total * r.area * cos_c * cos_lc / d2_c, 0.0))
            index, prob = choose(estimates)
            centre = pick(index, [r.centre for r in rects])
            u = pick(index, [r.u for r in rects])
            v = pick(index, [r.v for r in rects])
            normal = pick(index, [r.normal for r in rects])
            area = pick(index, [r.area for r in rects])
            values = [pick(index, [r.value[k] for r in rects]) for k in range(n)]
        a, b = 2.0 * rng.next_float32() - 1.0, 2.0 * rng.next_float32() - 1.0
        w, d2, dist, cos_s, on = towards(centre + u * a + v * b, active)
        cos_l = -dr.dot(w, normal)
        on &= cos_l > 0.0
        trace(w, dist, area * cos_s * cos_l / (d2 * np.pi) / prob, on, values)
    return out


def _windows_seen(mi, dr, lamps: _DeviceLamps, ray, t_max):
    """Camera rays that see a window's lit side before ``t_max`` (their first hit): (mask,
    distance, radiance per sub-band of the nearest window). A window is not in the scene's
    geometry (it lies just in front of its pane), so it neither occludes nor is met by
    reflected rays: its light reaches surfaces by :func:`_lamp_irradiance` only."""
    seen = dr.zeros(mi.Bool, dr.width(ray.d.z))
    t_best = mi.Float(t_max)
    value = [dr.zeros(mi.Float, dr.width(ray.d.z)) for _ in lamps.rects[0].value]
    for rect in lamps.rects:
        denom = dr.dot(ray.d, rect.normal)
        facing = denom < 0.0
        t = dr.dot(rect.centre - ray.o, rect.normal) / dr.select(facing, denom, -1.0)
        q = ray.o + ray.d * t - rect.centre
        inside = (dr.abs(dr.dot(q, rect.u_inv)) <= 1.0) & (dr.abs(dr.dot(q, rect.v_inv)) <= 1.0)
        on = facing & inside & (t > 0.0) & (t < t_best)
        seen |= on
        t_best = dr.select(on, t, t_best)
        value = [dr.select(on, rect.value[k], value[k]) for k in range(len(value))]
    return seen, t_best, value


def _filtered(mean, var, hits, radius: int, radius_px, mirrors):
    """:func:`filter_reflected`, but a mirror's pixels (calm water) keep their own reflected
    radiance: a mirror image is not smooth over the surface, as a Lambertian surface's
    irradiance is."""
    out_m, out_v = filter_reflected(mean, var, hits, radius, radius_px)
    if mirrors is None:
        return out_m, out_v
    own = np.isin(hits.part, mirrors.parts)
    if own.any():
        out_m = np.where(own, mean, out_m)
        out_v = np.where(own, var, out_v)
    return out_m, out_v


#: Incidence-cosine nodes of a mirror's Fresnel table (:func:`_mirror_tables`).
FRESNEL_NODES = 65


def _mirror_tables(mi, scene, tables: FaceTables, sub):
    r"""The scene's mirrors (None without): the parts of calm water (material
    :data:`humv_usd.scene.puddles.MATERIAL`, the puddles), each triangle's flag and blackbody
    radiance :math:`B_k(T) = \varepsilon_k L_k(T)/\varepsilon_k` (:func:`cavity_table`), and
    per sub-band the unpolarized Fresnel reflectance of water against the incidence cosine,
    :math:`R_k(\mu)` (Hale & Querry's index, :func:`humv_usd.physics.water_film.fresnel_reflectance`),
    averaged over the sub-band with ``sub.weighted_mean`` (Planck and response weighted;
    the EO bins' sensitivity). A camera ray on such a face sees
    :math:`(1 - R_k(\mu)) B_k(T) + R_k(\mu) L_k(\omega_r)`: Kirchhoff's law for an opaque
    specular interface (emissivity 1 - R) and the radiance along the mirror direction; the
    light scattered back from under the water (a puddle's bottom) is left out."""
    parts = [
        i for i, p in enumerate(scene.parts) if str(p.material.path).rsplit("/", 1)[-1] == PUDDLE_MATERIAL
    ]
    band_mean = getattr(sub, "weighted_mean", None)
    if not parts or band_mean is None:
        return None
    n = tables.emission.shape[1]
    flag = np.zeros(len(tables.emission), dtype=np.float32)
    ends = list(tables.offset[1:]) + [len(flag)]
    for i in parts:
        flag[tables.offset[i] : ends[i]] = 1.0
    wl = np.geomspace(0.35, 15.0, 1200)
    mu = np.linspace(0.0, 1.0, FRESNEL_NODES)
    spectral = water_film.fresnel_reflectance(
        mu[:, None], water_film.water_refractive_index(np.clip(wl, 0.4, 14.0))[None, :]
    )
    fresnel = band_mean(wl, spectral)
    if fresnel is None:
        return None
    fresnel = np.clip(np.asarray(fresnel, float).reshape(FRESNEL_NODES, n), 0.0, 1.0)
    blackbody = cavity_table(tables) * flag[:, None]
    return SimpleNamespace(
        parts=np.asarray(parts),
        flag=mi.Float(flag),
        blackbody=mi.Float(blackbody.astype(np.float32).ravel()),
        fresnel=mi.Float(np.ascontiguousarray(fresnel.T, dtype=np.float32).ravel()),  # (n, nodes)
        table=fresnel,
    )


def _fresnel(mi, dr, mirrors, mu, n: int, active) -> list:
    """R_k(mu) per sub-band, linear between the table's nodes."""
    x = dr.clip(mu, 0.0, 1.0) * (FRESNEL_NODES - 1)
    i = dr.minimum(mi.UInt32(dr.floor(x)), FRESNEL_NODES - 2)
    t = x - mi.Float(i)
    out = []
    for k in range(n):
        lo = dr.gather(mi.Float, mirrors.fresnel, k * FRESNEL_NODES + i, active)
        hi = dr.gather(mi.Float, mirrors.fresnel, k * FRESNEL_NODES + i + 1, active)
        out.append(lo + (hi - lo) * t)
    return out


def _clouds_on_device(mi, dr, cloud):
    """A :class:`humv_usd.render.light.CloudShadows` as device arrays: per wave its vector,
    amplitude and phase with the displacement folded in (k . (p - d) + phi)."""
    f = cloud.field
    phase = f.phases - f.wavevectors @ np.asarray(cloud.displacement, float)
    table = np.stack([f.wavevectors[:, 0], f.wavevectors[:, 1], f.amplitudes, phase], axis=1)
    return SimpleNamespace(
        waves=mi.Float(np.ascontiguousarray(table, dtype=np.float32).ravel()),
        count=len(table),
        threshold=dr.opaque(mi.Float, float(cloud.threshold)),
    )


def _between_clouds(mi, dr, clouds, p, active):
    r"""Whether the points ``p`` see the sun between the clouds: the cloud field
    (:func:`humv_usd.physics.clouds.moving_values`, :math:`f = \sum_j a_j \cos(k_j\cdot(x - d) +
    \varphi_j)`) at the point's ground position (x, y) is at most the threshold, as the thermal
    tool gates the sun on a face at its centroid (the shadow is cast vertically: a cloud base
    at 1 km shifts it by 1 km tan(zenith), which the thermal tool's field leaves out too).
    A loop over the waves on the device (one small kernel, not one cosine per wave inlined in
    every pass's kernel: 96 of them cost seconds of compilation per pass)."""
    x = dr.select(active, p.x, 0.0)
    y = dr.select(active, p.y, 0.0)
    waves = clouds.waves

    def body(j, f):
        base = j * 4
        kx = dr.gather(mi.Float, waves, base, active)
        ky = dr.gather(mi.Float, waves, base + 1, active)
        a = dr.gather(mi.Float, waves, base + 2, active)
        ph = dr.gather(mi.Float, waves, base + 3, active)
        return j + 1, f + a * dr.cos(kx * x + ky * y + ph)

    count = dr.opaque(mi.UInt32, clouds.count)
    _, f = dr.while_loop(
        (dr.zeros(mi.UInt32, dr.width(x)), dr.zeros(mi.Float, dr.width(x))),
        lambda j, f: j < count,
        body,
    )
    return f <= clouds.threshold


def _intersect_leaving(mi, dr, scene, ray, n0, height, origin, triangle):
    """First hit of rays leaving the flat faces ``origin`` (normals ``n0``; each ray starts
    ``height`` [m] above its face), never that face itself nor a face in its plane.

    A ray leaving a flat triangle into the hemisphere of its normal cannot meet that triangle,
    or another in the same plane, again; such a hit is the ray tracer's rounding error. Ray
    origins start above large faces by :func:`face_leave_offsets`; OptiX (the CUDA backend) was
    seen to report such hits on a 10 km plate (reflected skies 15 % low, an H100) when rays
    started at :func:`_offset` alone. What is left is caught here: a hit on the origin face, or
    on a face parallel to it lower than twice the start height, is traced again from higher
    along the ray, up to twice. Embree reports none on the test scenes (CPU images unchanged)."""
    si = scene.ray_intersect(ray)
    rise = dr.maximum(dr.dot(ray.d, n0), 0.05)  # height gained per metre along the ray
    for _ in range(2):
        valid = si.is_valid()
        same_plane = (dr.abs(dr.dot(si.n, n0)) > 0.9999) & (si.t * rise < height)
        again = valid & ((triangle(si, valid) == origin) | same_plane)
        past = mi.Ray3f(ray.o + ray.d * (si.t + height / rise), ray.d)
        si = dr.select(again, scene.ray_intersect(past, again), si)
        ray = mi.Ray3f(dr.select(again, past.o, ray.o), ray.d)
    return si


def _filter_windows(hits, fov_x_deg: float, filter_radius: int) -> np.ndarray:
    """Each pixel's filter half width [px] (:data:`FILTER_HALF_WIDTH_M` on its surface, at most
    ``filter_radius``), with its windows (:func:`_windows`) and the edges cached on the way."""
    h, w = hits.depth.shape
    pixel_m = hits.depth * (2.0 * np.tan(np.radians(fov_x_deg) / 2.0) / w)
    with np.errstate(invalid="ignore", divide="ignore"):
        radius_px = np.where(np.isfinite(pixel_m), np.floor(FILTER_HALF_WIDTH_M / pixel_m), 0.0)
    radius_px = np.minimum(radius_px, filter_radius)
    if filter_radius > 0:
        windows = _windows(hits, np.minimum(radius_px, filter_radius))  # the cap of filter_reflected
        for axis in (1, 0):
            _window_plan(windows, axis)
    _cached_edges(hits)
    return radius_px


class _InBackground(threading.Thread):
    """``fn(*args)`` on a thread; :meth:`result` waits for it and returns it (or raises)."""

    def __init__(self, fn, *args):
        super().__init__(name="humv-estimator-prep", daemon=True)
        self._fn, self._args, self._out, self._error = fn, args, None, None
        self.start()

    def run(self) -> None:
        try:
            self._out = self._fn(*self._args)
        except BaseException as error:  # re-raised on the caller's thread
            self._error = error

    def result(self):
        self.join()
        if self._error is not None:
            raise self._error
        return self._out


def extra_direct_points(direct_var, reflect_var, edge, camera_samples: int, reflection_rays: int) -> int:
    r"""How many more pixel positions per camera sample the direct term should get (0: none).

    The direct term (emission, sun and path at the first hit) varies inside a pixel where its
    footprint covers faces of different temperatures; a camera sample costs about one
    reflection ray. With per pixel variances :math:`V_{d,i}` (direct) and :math:`V_{r,i}`
    (reflected, filtered) away from edges, D pixel positions per camera sample give the mean
    error :math:`E(D) = \langle\sqrt{V_{d,i}/D + V_{r,i}}\rangle` at the cost
    :math:`c(D) = D c_d + c_r`; the samples needed for a target error scale as
    :math:`E^2`, so D minimises :math:`c(D) E(D)^2` (1 to :data:`MAX_DIRECT_FACTOR`: the
    optimal allocation of samples between independent estimators, Neyman 1934). The extra
    positions come from a second, larger lattice (the two per-pixel means weighted by their
    sample counts)."""
    inner = ~edge & np.all(np.isfinite(direct_var), axis=0) & np.all(np.isfinite(reflect_var), axis=0)
    if not inner.any() or camera_samples <= 0:
        return 0
    v_d = direct_var.sum(axis=0)[inner][::7]  # a spread subset of the pixels is enough
    v_r = reflect_var.sum(axis=0)[inner][::7]
    factors = np.arange(1, MAX_DIRECT_FACTOR + 1)
    cost = factors * camera_samples + reflection_rays
    error = np.array([np.sqrt(v_d / f + v_r).mean() for f in factors])
    return int(factors[np.argmin(cost * error**2)]) - 1


#: Edge masks of the last few pixel-centre hits (see :func:`geometric_edges`).
_EDGES: list = []


def _cached_edges(hits) -> np.ndarray:
    for cached_hits, edge in _EDGES:
        if cached_hits is hits:
            return edge
    edge = _edges_of(hits)
    edge.flags.writeable = False
    _EDGES.insert(0, (hits, edge))
    del _EDGES[4:]
    return edge


def _path_interpolation(mi, dr, path, range_m, n: int, wts):
    """``lerp(table, k)``: the path transmittance (table 0) or path radiance (table 1) of
    sub-band k, or the path radiance of output channel k (table 2, weighted by ``wts`` (c, n)),
    at ``range_m``, linear in the path table's ascending ranges and held beyond its ends (as
    :func:`humv_usd.render.radiometry.range_weights`), on the device."""
    ranges = np.atleast_1d(np.asarray(path.ranges_m, dtype=np.float32))
    radiance = np.asarray(path.radiance, dtype=float).reshape(-1, n)
    tables = (path.transmittance, radiance, radiance @ np.asarray(wts, float).T)
    tabs = [mi.Float(np.ascontiguousarray(t, dtype=np.float32).ravel()) for t in tables]
    width = [n, n, len(wts)]
    if ranges.size == 1:
        return lambda table, k: dr.gather(mi.Float, tabs[table], mi.UInt32(k))
    x = mi.Float(ranges)
    last = ranges.size - 1
    j = dr.binary_search(1, last, lambda i: dr.gather(mi.Float, x, i) <= range_m)
    i = j - 1
    lo_x, hi_x = dr.gather(mi.Float, x, i), dr.gather(mi.Float, x, j)
    t = dr.clip((range_m - lo_x) / (hi_x - lo_x), 0.0, 1.0)

    def lerp(table, k):
        m = width[table]
        lo = dr.gather(mi.Float, tabs[table], i * m + k)
        return lo + (dr.gather(mi.Float, tabs[table], j * m + k) - lo) * t

    return lerp


def _lanes_to_cells(mi, dr, lanes, parent, splits: int, total: int, lattice_n: int):
    """Sum per-lane values (``splits`` consecutive lanes per parent camera sample) into the
    camera samples ``parent`` and then into cells of ``lattice_n`` consecutive samples."""
    per_parent = dr.block_sum(lanes, splits) if splits > 1 else lanes
    per_sample = dr.zeros(mi.Float, total)
    if dr.width(parent):
        dr.scatter(per_sample, per_parent, parent)
    out = dr.block_sum(per_sample, lattice_n) if lattice_n > 1 else per_sample
    return np.asarray(out, dtype=np.float64)


def _scatter_channels(dr, acc, terms, wts, target) -> None:
    """Add each channel's weighted sum of the sub-band ``terms`` into ``acc[c]`` at ``target``."""
    for c, row in enumerate(wts):
        dr.scatter_reduce(dr.ReduceOp.Add, acc[c], _weighted_sum(terms, row), target)


def channel_weights(weights, n: int) -> np.ndarray:
    """The (c, n) channel weights of n sub-bands (None: one channel, all ones)."""
    if weights is None:
        return np.ones((1, n))
    wts = np.asarray(weights, dtype=float)
    if wts.ndim != 2 or wts.shape[1] != n or wts.shape[0] < 1 or not np.all(np.isfinite(wts)):
        raise ValueError(f"weights: shape {wts.shape}, want (channels >= 1, {n}) finite values")
    return wts


def _weighted_sum(terms, row):
    """sum_k row[k] terms[k] on the device, skipping zero weights and unit multiplications."""
    out = None
    for term, wk in zip(terms, row):
        if wk == 0.0:
            continue
        v = term if wk == 1.0 else term * float(wk)
        out = v if out is None else out + v
    return out if out is not None else terms[0] * 0.0


def _same_surface(hits, dy: int, dx: int):
    """Pixels whose pixel-centre hit lies on the same part, with nearly the same normal and
    depth, as the pixel (dy, dx) away (False across the image border)."""
    h, w = hits.part.shape
    ok = np.zeros((h, w), dtype=bool)
    ys = slice(max(0, -dy), h - max(0, dy))
    xs = slice(max(0, -dx), w - max(0, dx))
    yo = slice(max(0, dy), h - max(0, -dy))
    xo = slice(max(0, dx), w - max(0, -dx))
    a_part, b_part = hits.part[ys, xs], hits.part[yo, xo]
    a_n, b_n = hits.normal[ys, xs], hits.normal[yo, xo]
    a_d, b_d = hits.depth[ys, xs], hits.depth[yo, xo]
    with np.errstate(invalid="ignore"):
        same = (
            (a_part == b_part)
            & (a_part >= 0)
            & (np.einsum("ijk,ijk->ij", a_n, b_n) > FILTER_NORMAL_COS)
            & (np.abs(a_d - b_d) <= FILTER_DEPTH_REL * a_d)
        )
    ok[ys, xs] = same
    return ok, (ys, xs), (yo, xo)


def filter_reflected(mean, var, hits, radius: int, radius_px=None):
    r"""Average the per-pixel reflected radiance over a (2 radius + 1)^2 window (two separable
    passes, rows then columns), using only pixels on the same surface as the centre: the run of
    neighbours linked pixel to pixel by the same part, normals agreeing to
    :data:`FILTER_NORMAL_COS` and depths to :data:`FILTER_DEPTH_REL` (cross-bilateral with binary
    weights), cut where the depth or the normal has drifted from the centre's by as much (from
    the local gradients). Returns the filtered mean and its variance
    :math:`\sum_i w_i^2 \sigma_i^2` (pixels' estimates are independent; the second pass combines
    rows built from disjoint pixels). Running sums make its cost independent of the window.
    The reflected radiance of a Lambertian surface is its irradiance times a constant, smooth on
    the scale of the window (a few cm on the examples' surfaces); what the averaging costs in
    bias is measured against the path tracer by ``humv-usd bench render`` (per labelled region).
    ``radius_px`` (H, W) caps the half width per pixel (a pixel's own window,
    :data:`FILTER_HALF_WIDTH_M` in world units). ``mean`` and ``var`` may carry leading channel
    axes (..., H, W): one window for every channel."""
    out_m, out_v = np.asarray(mean, float), np.asarray(var, float)
    shape = out_m.shape[-2:]
    cap = (
        np.full(shape, float(radius))
        if radius_px is None
        else np.minimum(np.asarray(radius_px, float), radius)
    )
    known = np.isfinite(out_v)
    both = np.concatenate([out_m.reshape((-1,) + shape), np.nan_to_num(out_v).reshape((-1,) + shape)])
    half = both.shape[0] // 2
    windows = _windows(hits, cap)
    for axis in (1, 0):
        first, last, inv_count, inv_count2 = _window_plan(windows, axis)
        both = _window_sum(both, (first, last), axis)
        both[:half] *= inv_count
        both[half:] *= inv_count2
    out_m = both[:half].reshape(out_m.shape)
    return out_m, np.where(known, both[half:].reshape(out_m.shape), np.nan)


def _window_plan(windows, axis: int):
    """The flat running-sum indices of :func:`_window_sum` and 1 / count, 1 / count^2 of the
    windows along ``axis`` (0 or 1), computed once per windows (a frame's batches share them)."""
    plans = windows[2]
    if axis not in plans:
        lo, hi = windows[1 - axis]  # axis 1 (along rows): the row windows, windows[0]
        h, w = lo.shape
        if axis == 0:  # (k, H + 1, W): row index * W + column
            col = np.arange(w)
            first, last = (lo * w + col).ravel(), ((hi + 1) * w + col).ravel()
        else:  # (k, H, W + 1): row * (W + 1) + column index
            row = np.arange(h)[:, None] * (w + 1)
            first, last = (row + lo).ravel(), (row + hi + 1).ravel()
        count = (hi - lo + 1).astype(float)
        plans[axis] = (first, last, 1.0 / count, 1.0 / count**2)
    return plans[axis]


#: Windows of the last few (hits, cap) pairs: the automatic quality renders a frame in batches.
_WINDOWS: list = []


def _windows(hits, cap):
    """The row and column windows of :func:`filter_reflected` (cached per hits and cap)."""
    for cached_hits, cached_cap, windows in _WINDOWS:
        if cached_hits is hits and np.array_equal(cached_cap, cap):
            return windows
    windows = (_window(hits, cap, 1), _window(hits, cap, 0), {})  # rows, columns, plans
    _WINDOWS.insert(0, (hits, cap, windows))
    del _WINDOWS[3:]
    return windows


def _window(hits, cap, axis: int):
    """First and last index (H, W) along ``axis`` of each pixel's same-surface window."""
    if axis == 0:
        lo, hi = _window(_transposed(hits), cap.T, 1)
        return np.ascontiguousarray(lo.T), np.ascontiguousarray(hi.T)
    h, w = cap.shape
    if w < 2:  # one column (a 1-pixel-wide or -high image): each window is the pixel itself
        zero = np.zeros((h, w), dtype=np.int64)
        return zero, zero.copy()
    part, normal = hits.part, hits.normal
    depth = np.where(np.isfinite(hits.depth), hits.depth, 0.0)
    # neighbours x and x + 1: the cosine between their normals, their depth step, and whether
    # they share a surface (as :func:`_same_surface`), each (H, W - 1)
    cos = (
        normal[:, :-1, 0] * normal[:, 1:, 0]
        + normal[:, :-1, 1] * normal[:, 1:, 1]
        + normal[:, :-1, 2] * normal[:, 1:, 2]
    )
    step = depth[:, 1:] - depth[:, :-1]
    a_part = part[:, :-1]
    link = (
        (a_part == part[:, 1:])
        & (a_part >= 0)
        & (cos > FILTER_NORMAL_COS)
        & (np.abs(step) <= FILTER_DEPTH_REL * depth[:, :-1])
    )
    # how far the depth and the normal drift per pixel (the larger of its two steps in the run)
    step = np.abs(np.where(link, step, 0.0))
    cos = np.where(link, cos, 1.0)
    depth_step = np.empty((h, w))
    depth_step[:, 0], depth_step[:, -1] = step[:, 0], step[:, -1]
    np.maximum(step[:, 1:], step[:, :-1], out=depth_step[:, 1:-1])
    min_cos = np.empty((h, w))
    min_cos[:, 0], min_cos[:, -1] = cos[:, 0], cos[:, -1]
    np.minimum(cos[:, 1:], cos[:, :-1], out=min_cos[:, 1:-1])
    with np.errstate(invalid="ignore", divide="ignore"):
        depth_step /= np.maximum(depth, 1e-30)
        angle_step = np.arccos(np.clip(min_cos, -1.0, 1.0))
        reach = np.minimum(
            np.where(depth_step > 0, np.floor(FILTER_DEPTH_REL / depth_step), np.inf),
            np.where(angle_step > 0, np.floor(np.arccos(FILTER_NORMAL_COS) / angle_step), np.inf),
        )
    reach = np.minimum(cap, reach).astype(np.int64)
    x = np.broadcast_to(np.arange(w), (h, w))
    run_start = np.empty((h, w), dtype=np.int64)  # x where x - 1 is not linked to x, else 0
    run_start[:, 0] = 0
    run_start[:, 1:] = np.where(link, 0, x[:, 1:])
    run_end = np.empty((h, w), dtype=np.int64)  # x where x + 1 is not linked to x, else w - 1
    run_end[:, -1] = w - 1
    run_end[:, :-1] = np.where(link, w - 1, x[:, :-1])
    start = np.maximum.accumulate(run_start, axis=1)
    end = np.minimum.accumulate(run_end[:, ::-1], axis=1)[:, ::-1]
    return np.maximum(x - reach, start), np.minimum(x + reach, end)


def _transposed(hits):
    """The pixel-centre hits the column pass reads (part, depth, normal), rows and columns
    swapped (views)."""
    return SimpleNamespace(part=hits.part.T, depth=hits.depth.T, normal=np.swapaxes(hits.normal, 0, 1))


def _window_sum(values, flat, axis: int):
    """Sum over each pixel's window along ``axis`` (0: columns, 1: rows) of (k, H, W) values,
    by running sums read at the flat indices ``flat`` = (first, last) of :func:`_window_plan`."""
    k, h, w = values.shape
    if axis == 0:
        csum = np.empty((k, h + 1, w))
        csum[:, 0, :] = 0.0
        np.cumsum(values, axis=1, out=csum[:, 1:, :])
    else:
        csum = np.empty((k, h, w + 1))
        csum[:, :, 0] = 0.0
        np.cumsum(values, axis=2, out=csum[:, :, 1:])
    csum = csum.reshape(k, -1)
    out = np.take(csum, flat[1], axis=1)
    out -= np.take(csum, flat[0], axis=1)
    return out.reshape(k, h, w)


def geometric_edges(hits) -> np.ndarray:
    """Pixels whose 8-neighbourhood holds another part, the sky, or a depth more than 2 %
    away: silhouettes and material borders, where the pixel footprint mixes surfaces.
    Cached per hits object (the pipeline, the estimator and the statistics of one frame share
    it); read-only."""
    return _cached_edges(hits)


def _edges_of(hits) -> np.ndarray:
    """:func:`geometric_edges`, computed: each of the 4 neighbour directions is compared once
    (the test is symmetric) and marks both pixels of a differing pair."""
    part = hits.part
    depth = np.where(np.isfinite(hits.depth), hits.depth, 1e30)
    edge = np.zeros(part.shape, dtype=bool)
    h, w = part.shape
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        ys, yo = slice(0, h - dy), slice(dy, h)
        xs, xo = slice(max(0, -dx), w - max(0, dx)), slice(max(0, dx), w - max(0, -dx))
        a, b = depth[ys, xs], depth[yo, xo]
        diff = (part[ys, xs] != part[yo, xo]) | (np.abs(a - b) > 0.02 * np.minimum(a, b))
        edge[ys, xs] |= diff
        edge[yo, xo] |= diff
    return edge


def noise_stats(stderr_k: np.ndarray, edge: np.ndarray) -> dict:
    """Mean and 99th percentile of the per-pixel error [K] away from edges, and the edge mean."""
    inner = stderr_k[~edge & np.isfinite(stderr_k)]
    outer = stderr_k[edge & np.isfinite(stderr_k)]
    return {
        "mean_k": float(inner.mean()) if inner.size else None,
        "p99_k": float(np.percentile(inner, 99)) if inner.size else None,
        "edge_mean_k": float(outer.mean()) if outer.size else None,
        "edge_fraction": float(edge.mean()),
    }

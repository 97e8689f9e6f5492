"""Collision avoidance between walkers: the social force model (Helbing & Molnár 1995).

Helbing, D. & Molnár, P. (1995) Social force model for pedestrian dynamics, *Phys. Rev. E*
51:4282-4286. Each pedestrian a is accelerated toward its desired velocity and repelled by the
others::

    dv_a/dt = (v0_a e_a - v_a) / tau  +  sum_b w(e_a, -f_ab) f_ab,    f_ab = -grad_r V(b),
    V(b) = V0 exp(-b / sigma),
    2 b = sqrt((|r| + |r - v_b dt_s e_b|)^2 - (v_b dt_s)^2)     (r = r_a - r_b)

with the paper's values tau = 0.5 s, V0 = 2.1 m^2/s^2, sigma = 0.3 m, dt_s = 2 s (the
elliptical equipotentials stretch along the other's walking direction) and the field-of-view
weight w = 1 within 2 phi = 200 deg of the walking direction, c = 0.5 outside.

Body contact: with the walkers' speeds fixed (below) the soft potential alone let crossing
walkers overlap, so the circular repulsion of Helbing, Farkas & Vicsek (2000, *Nature*
407:487-490) is added: A/m exp((r_ab - d_ab)/B) along n_ab with A = 2000 N, m = 80 kg,
B = 0.08 m and r_ab the sum of the two body radii (:data:`BODY_RADIUS_M` each, about half a
shoulder width plus arm swing).

Steering variant (our choice, stated): the body motion model walks a path at a constant speed
(:mod:`humv_usd.human.motion`), so each walker keeps its own speed v0 and the social force only
turns its velocity (:func:`steer`): its component along the desired direction is turned
sideways (a walker that cannot slow down would be turned round by a push from ahead) and |v|
is reset to v0 every step. The avoided tracks are returned as dense
ground points and handed to the walk as waypoints; people who do not walk (standing, sitting,
lying ...) are fixed obstacles (V from a standing person, b = |r|).

Desired direction: toward the walker's next waypoint (reached within :data:`REACH_M`), then
straight on along the last segment (as :class:`humv_usd.human.motion.Path` extends a path).
"""

from __future__ import annotations

import numpy as np

#: Helbing & Molnár (1995) parameters
TAU_S = 0.5
V0_M2_S2 = 2.1
SIGMA_M = 0.3
DT_STEP_S = 2.0
FOV_HALF_RAD = np.radians(100.0)
OUTSIDE_WEIGHT = 0.5
#: Helbing, Farkas & Vicsek (2000) body repulsion
A_N = 2000.0
MASS_KG = 80.0
B_M = 0.08
BODY_RADIUS_M = 0.3
#: integration step [s] and the distance at which a waypoint counts as reached [m]
STEP_S = 0.05
REACH_M = 0.5
#: how far ahead on its line a walker past its last waypoint aims [m]
LOOKAHEAD_M = 3.0


def _b(r: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Semi-minor axis b of the elliptical equipotential through r (..., 2), for the other's
    step v_b dt_s e_b (..., 2)."""
    rn = np.linalg.norm(r, axis=-1)
    rs = np.linalg.norm(r - step, axis=-1)
    s = np.linalg.norm(step, axis=-1)
    return 0.5 * np.sqrt(np.maximum((rn + rs) ** 2 - s**2, 1e-12))


def social_force(r: np.ndarray, step: np.ndarray, h: float = 1e-4) -> np.ndarray:
    """f = -grad_r V0 exp(-b(r)/sigma) (..., 2) [m/s^2] by central differences."""
    f = np.zeros(r.shape)
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        vp = V0_M2_S2 * np.exp(-_b(r + e, step) / SIGMA_M)
        vm = V0_M2_S2 * np.exp(-_b(r - e, step) / SIGMA_M)
        f[..., k] = -(vp - vm) / (2 * h)
    return f


def _desired(pos, targets, idx, line_start, last_dir):
    """Unit desired directions and updated waypoint indices: toward the next waypoint, after
    the last one toward a point :data:`LOOKAHEAD_M` ahead on the straight line it continues
    (so that a walker pushed aside comes back to its line)."""
    n = len(pos)
    e = np.empty((n, 2))
    for a in range(n):
        w = targets[a]
        while idx[a] < len(w) and np.linalg.norm(w[idx[a]] - pos[a]) < REACH_M:
            idx[a] += 1
        if idx[a] < len(w):
            d = w[idx[a]] - pos[a]
        else:
            p0 = w[-1] if len(w) else line_start[a]
            ahead = float(np.dot(pos[a] - p0, last_dir[a])) + LOOKAHEAD_M
            d = p0 + ahead * last_dir[a] - pos[a]
        e[a] = d / max(np.linalg.norm(d), 1e-9)
    return e


def steer(social: np.ndarray, e: np.ndarray) -> np.ndarray:
    """The social acceleration (N, 2) as a turn: its part across the desired direction ``e``
    (N, 2), plus a push back turned sideways (to the side the push already leans to; to the
    right when it has none) -- a walker who keeps its speed sidesteps instead of braking."""
    along = np.einsum("ai,ai->a", social, e)
    across = social - along[:, None] * e
    right = np.column_stack([e[:, 1], -e[:, 0]])
    n = np.linalg.norm(across, axis=1, keepdims=True)
    side = np.where(n > 1e-6, across / np.maximum(n, 1e-12), right)
    return across + np.maximum(-along, 0.0)[:, None] * side


def avoid(
    starts: np.ndarray,
    waypoints: list,
    speeds: np.ndarray,
    duration_s: float,
    headings: np.ndarray | None = None,
    step_s: float = STEP_S,
) -> np.ndarray:
    """Tracks (N, T, 2) [m] of N people sampled every ``step_s`` over ``duration_s``.

    starts (N, 2) ground positions; waypoints: per person an (M, 2) array (may be empty) of
    points to pass in order; speeds (N,) [m/s] (0: a person standing still, an obstacle);
    headings (N,) [rad, compass: 0 = +y, 90 deg = +x] of people without waypoints.
    """
    starts = np.asarray(starts, dtype=np.float64)
    speeds = np.asarray(speeds, dtype=np.float64)
    n = len(starts)
    headings = np.zeros(n) if headings is None else np.asarray(headings, dtype=np.float64)
    targets, last_dir = [], np.empty((n, 2))
    for a in range(n):
        w = np.asarray(waypoints[a], dtype=np.float64).reshape(-1, 2)
        targets.append(w)
        if len(w) >= 1:
            prev = w[-2] if len(w) >= 2 else starts[a]
            d = w[-1] - prev
        else:
            d = np.array([np.sin(headings[a]), np.cos(headings[a])])
        last_dir[a] = d / max(np.linalg.norm(d), 1e-9)
    steps = int(np.ceil(duration_s / step_s)) + 1
    out = np.empty((n, steps, 2))
    pos = starts.copy()
    idx = np.zeros(n, int)
    e = _desired(pos, targets, idx, starts, last_dir)
    vel = speeds[:, None] * e
    moving = speeds > 0
    half_angle = np.cos(FOV_HALF_RAD)
    for t in range(steps):
        out[:, t] = pos
        e = _desired(pos, targets, idx, starts, last_dir)
        acc = (speeds[:, None] * e - vel) / TAU_S
        r = pos[:, None, :] - pos[None, :, :]  # r_a - r_b
        other_step = np.where(moving[None, :, None], vel[None, :, :] * DT_STEP_S, 0.0)
        other_step = np.broadcast_to(other_step, r.shape)
        f = social_force(r, other_step)
        dist = np.linalg.norm(r, axis=-1)
        nrm = r / np.maximum(dist, 1e-9)[..., None]
        f = f + (A_N / MASS_KG * np.exp((2 * BODY_RADIUS_M - dist) / B_M))[..., None] * nrm
        np.einsum("aai->ai", f)[:] = 0.0
        # field of view: full weight for others ahead (the force points back at a)
        cos = np.einsum("ai,abi->ab", e, -f) / np.maximum(np.linalg.norm(f, axis=-1), 1e-12)
        w = np.where(cos >= half_angle, 1.0, OUTSIDE_WEIGHT)
        social = np.einsum("ab,abi->ai", w, f)
        acc = acc + steer(social, e)
        vel = vel + acc * step_s
        # steering: each walker keeps its speed (see the module doc)
        norm = np.linalg.norm(vel, axis=1, keepdims=True)
        vel = np.where(norm > 1e-9, vel / np.maximum(norm, 1e-9), e) * speeds[:, None]
        pos = pos + np.where(moving[:, None], vel, 0.0) * step_s
    return out


def track_waypoints(track: np.ndarray, spacing_m: float = 0.25) -> np.ndarray:
    """Points (M, 2) about ``spacing_m`` apart along a track (T, 2), the start left out (the
    walk starts at the person's position)."""
    d = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(track, axis=0), axis=1))]
    if d[-1] < spacing_m:
        return np.zeros((0, 2))
    s = np.arange(spacing_m, d[-1] + 1e-9, spacing_m)
    return np.column_stack([np.interp(s, d, track[:, 0]), np.interp(s, d, track[:, 1])])


def min_separation(tracks: np.ndarray) -> float:
    """Smallest distance [m] between any two tracks (N, T, 2) at the same time."""
    n = len(tracks)
    best = np.inf
    for a in range(n):
        for b in range(a + 1, n):
            best = min(best, float(np.linalg.norm(tracks[a] - tracks[b], axis=1).min()))
    return best

"""Ground contact of the feet: ground queries, contact points, planted stance feet, swing-foot
clearance, two-bone leg IK and the per-clip contact report.

Contact points. Each foot carries a set of points skinned to the foot (``LeftFoot``) and toe
(``LeftToeBase``) joints: the sole vertices of the fitted body (:func:`foot_points_from_body`,
rest height < 1 cm, MakeHuman's skin weights renormalized over the two joints, i.e. where the
skinned mesh puts them) or, without a body, points derived from the joints
(:func:`foot_points_from_joints`: heel, ball and toe tip on the rest sole plane z = 0, rigid).
The rest pose stands on z = 0.

Stance (:func:`plant_stance`). At the first frame of a stance phase the foot gets a support
plane: a least-squares plane through the ground heights under its flat footprint, lifted so that
no footprint point is below the ground. The foot then *rolls without slipping* on that plane:
each frame its lowest contact point (in the plane's frame, for the foot's target orientation) is
the pivot; a pivot stays where it touched down, so heel rocker, foot flat and the forefoot
rocker (toes kept flat, the foot turning about the toe joint) follow without sliding. Its
heading is frozen for the whole stance.

Swing (:func:`swing_targets`). The nominal swing foot is blended from the offset it has at
toe-off (planted - nominal) to the offset it needs at the next touch-down, and lifted wherever
a contact point would dip into the ground (clearance over bumps).

Legs (:func:`leg_ik`): analytic two-bone IK (hip ball joint, knee hinge about the thigh's X
axis) to the ankle target; the hip turns by the minimal rotation from its nominal orientation
(keeps the knee's swivel), the ankle and toes take the target orientations.

Ground: ``None`` (flat z = 0), a callable ``height(x, y)`` (vectorized) or a
``trimesh.Trimesh`` (vertical rays cast down, :mod:`humv_usd.geometry.raycast`), all in the
avatar frame.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from humv_usd.geometry.raycast import RayCaster
from humv_usd.human.gait import (
    align_matrix,
    axis_angle_matrix,
    fk_matrices,
    matrix_to_quat,
    quat_slerp,
    rot_x,
    rot_z,
)
from humv_usd.human.macro import obj_data
from humv_usd.human.skeleton import Skeleton, quat_to_matrix, skin_weights

SIDES = ("Left", "Right")


# ------------------------------------------------------------------------- ground
class Ground:
    """Height of the ground under points (x, y) of the avatar frame."""

    def __init__(self, ground=None):
        self.source = ground
        if ground is None:
            self.kind = "flat"
        elif callable(ground) and not hasattr(ground, "ray"):
            self.kind = "function"
        elif hasattr(ground, "ray") and hasattr(ground, "bounds"):
            self.kind = "mesh"
            self._top = float(ground.bounds[1][2]) + 1.0
            self._caster = RayCaster(ground.vertices, ground.faces)
            self._tree = None
        else:
            raise TypeError("ground must be None, a callable height(x, y) or a trimesh.Trimesh")

    def height(self, xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=np.float64)
        shape = xy.shape[:-1]
        flat = xy.reshape(-1, 2)
        if self.kind == "flat":
            out = np.zeros(len(flat))
        elif self.kind == "function":
            out = np.broadcast_to(
                np.asarray(self.source(flat[:, 0], flat[:, 1]), dtype=np.float64), (len(flat),)
            ).copy()
        else:
            out = self._cast(flat)
        return out.reshape(shape)

    def _cast(self, xy: np.ndarray) -> np.ndarray:
        out = np.full(len(xy), np.nan)
        if len(xy) == 0:
            return out
        origins = np.column_stack([xy, np.full(len(xy), self._top)])
        dirs = np.tile([0.0, 0.0, -1.0], (len(xy), 1))
        _, points = self._caster.first_points(origins, dirs)  # the highest hit: first one down
        out[:] = points[:, 2]
        miss = np.isnan(out)
        if miss.any():
            # outside the mesh's footprint (or through a hole): the nearest vertex's height
            if self._tree is None:
                from scipy.spatial import cKDTree

                self._tree = cKDTree(np.asarray(self.source.vertices)[:, :2])
            _, i = self._tree.query(xy[miss])
            out[miss] = np.asarray(self.source.vertices)[i, 2]
        return out


# ------------------------------------------------------------------------- contact points
@dataclass(frozen=True)
class FootPoints:
    """Contact points of one foot: ``rest`` (n, 3) rest positions relative to the rest ankle,
    skinned to the foot and toe joints with weights 1 - ``toe_weight`` and ``toe_weight``
    (linear blend skinning restricted to those two joints, as the mesh deforms)."""

    side: str
    foot: int  # joint index of <side>Foot
    toe: int  # joint index of <side>ToeBase
    rest: np.ndarray
    toe_weight: np.ndarray
    toe_offset: np.ndarray  # (3,) rest toe joint minus rest ankle
    source: str

    def relative(self, foot_rot: np.ndarray, toe_rot: np.ndarray) -> np.ndarray:
        """(..., n, 3) points relative to the ankle for foot/toe rotations (..., 3, 3)."""
        pf = np.einsum("...ij,nj->...ni", foot_rot, self.rest)
        pt = np.einsum("...ij,nj->...ni", toe_rot, self.rest - self.toe_offset)
        off = np.einsum("...ij,j->...i", foot_rot, self.toe_offset)[..., None, :]
        return pf + self.toe_weight[:, None] * (pt + off - pf)

    def world(self, world_rot: np.ndarray, world_pos: np.ndarray) -> np.ndarray:
        """(F, n, 3) world points from skeleton world rotations/positions (F, J, ...)."""
        rel = self.relative(world_rot[:, self.foot], world_rot[:, self.toe])
        return world_pos[:, self.foot][:, None, :] + rel


def _foot_points(
    skeleton: Skeleton, side: str, points: np.ndarray, toe_weight: np.ndarray, source: str
) -> FootPoints:
    f, t = skeleton.index(f"{side}Foot"), skeleton.index(f"{side}ToeBase")
    rest = skeleton.rest_positions
    return FootPoints(
        side, f, t, points - rest[f], np.asarray(toe_weight, dtype=np.float64), rest[t] - rest[f], source
    )


def foot_points_from_joints(skeleton: Skeleton) -> dict[str, FootPoints]:
    """Heel, ball and toe-tip points on the rest sole plane z = 0, from the foot joints.

    Proportions of MakeHuman's foot (ankle-to-toe-joint length a): heel 0.42 a behind the
    ankle, toe tip 0.39 a ahead of the toe joint, ball +-0.30 a and heel +-0.18 a wide. Ball
    and tip points ride on the toes (the ball is under the toe joint, which stays put while
    the heel rises)."""
    out = {}
    rest = skeleton.rest_positions
    for side in SIDES:
        ankle, toe = rest[skeleton.index(f"{side}Foot")], rest[skeleton.index(f"{side}ToeBase")]
        d = np.array([toe[0] - ankle[0], toe[1] - ankle[1], 0.0])
        a = np.linalg.norm(d)
        fwd = d / a
        lat = np.array([-fwd[1], fwd[0], 0.0])
        a0 = np.array([ankle[0], ankle[1], 0.0])
        t0 = np.array([toe[0], toe[1], 0.0])
        pts, on_toe = [], []
        for s in (-1.0, 0.0, 1.0):
            pts.append(a0 - 0.42 * a * fwd + s * 0.18 * a * lat)
            on_toe.append(False)
            pts.append(t0 + s * 0.30 * a * lat)
            on_toe.append(True)
            pts.append(t0 + 0.39 * a * fwd + s * 0.12 * a * lat)
            on_toe.append(True)
        out[side] = _foot_points(skeleton, side, np.array(pts), np.array(on_toe, float), "joints")
    return out


def foot_points_from_body(
    skeleton: Skeleton, body_points: np.ndarray, max_height: float = 0.01, spacing: float = 0.012
) -> dict[str, FootPoints]:
    """Sole vertices of a fitted body (``body_points``: the FULL base.obj vertex list, e.g.
    ``Body.points``) below ``max_height`` at rest, thinned to about one per ``spacing`` grid
    cell, skinned with their MakeHuman weights renormalized over the foot and toe joints."""

    _, groups = obj_data()
    used = np.unique(groups["body"])
    P = np.asarray(body_points, dtype=np.float64)
    sole = used[P[used, 2] < P[used, 2].min() + max_height]
    out = {}
    for side in SIDES:
        f, t = skeleton.index(f"{side}Foot"), skeleton.index(f"{side}ToeBase")
        sign = 1.0 if side == "Left" else -1.0
        ids = sole[sign * P[sole, 0] > 0]
        idx, w = skin_weights(skeleton, ids)
        wt = np.where(idx == t, w, 0.0).sum(1)
        wf = np.where(idx == f, w, 0.0).sum(1)
        keep = (wt + wf) > 0.5
        ids, wt, wf = ids[keep], wt[keep], wf[keep]
        # thin: the lowest vertex per grid cell
        cells = np.floor(P[ids, :2] / spacing).astype(np.int64)
        order = np.lexsort((P[ids, 2], cells[:, 1], cells[:, 0]))
        cs = cells[order]
        first = np.r_[True, np.any(cs[1:] != cs[:-1], axis=1)]
        pick = order[first]
        out[side] = _foot_points(skeleton, side, P[ids[pick]], wt[pick] / (wt[pick] + wf[pick]), "body")
    return out


# ------------------------------------------------------------------------- stance
@dataclass
class Stance:
    """One planted stance phase of one foot (frames ``start`` .. ``stop - 1``)."""

    start: int
    stop: int
    origin: np.ndarray  # (3,) plane point under the first pivot (world)
    plane: np.ndarray  # (3, 3) rotation: plane frame -> world (z = plane normal)
    yaw: float  # frozen heading [rad]
    ankle: np.ndarray | None = None  # (n, 3) world ankle positions
    foot_rot: np.ndarray | None = None  # (n, 3, 3) world foot rotations
    toe_rot: np.ndarray | None = None  # (n, 3, 3) world toe rotations
    pivot_z: np.ndarray | None = None  # (n,) world height of the pivot


def intervals(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) runs of True in a boolean array."""
    m = np.r_[False, np.asarray(mask, bool), False]
    d = np.flatnonzero(m[1:] != m[:-1])
    return list(zip(d[::2], d[1::2]))


def _fit_planes(ground: Ground, prints: list[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Support planes under footprints (each (n, 2), first row = pivot): least squares,
    lifted so no footprint point is under the ground. Returns (origin (3,), rotation)."""
    if not prints:
        return []
    heights = ground.height(np.concatenate(prints))
    out, k = [], 0
    for fp in prints:
        h = heights[k : k + len(fp)]
        k += len(fp)
        d = fp - fp[0]
        A = np.column_stack([np.ones(len(fp)), d])
        coef, *_ = np.linalg.lstsq(A, h, rcond=None)
        coef[0] += max(float(np.max(h - A @ coef)), 0.0)
        n = np.array([-coef[1], -coef[2], 1.0])
        n /= np.linalg.norm(n)
        out.append((np.array([fp[0, 0], fp[0, 1], coef[0]]), align_matrix(np.array([0.0, 0.0, 1.0]), n)))
    return out


def plant_stance(
    ground: Ground,
    feet: FootPoints,
    stance: np.ndarray,
    ankle_xy: np.ndarray,
    yaw: np.ndarray,
    pitch: np.ndarray,
) -> list[Stance]:
    """Planted stance phases of one foot.

    stance (F,) bool; ankle_xy (F, 2) nominal ankle position (only the first frame of each
    stance is used); yaw (F,) nominal foot heading; pitch (F,) target foot pitch to the ground
    [rad] (+ = toes up; the toes stay flat while the heel is up).
    """
    runs = intervals(stance)
    prints, firsts = [], []
    flat_rel = feet.relative(np.eye(3), np.eye(3))  # (n, 3)
    for a, _ in runs:
        qf = rot_z(yaw[a]) @ rot_x(-pitch[a])
        qt = rot_z(yaw[a]) @ rot_x(-max(pitch[a], 0.0))
        rel = feet.relative(qf, qt)
        k = int(np.argmin(rel[:, 2]))
        pivot = ankle_xy[a] + rel[k, :2]
        flat = (rot_z(yaw[a]) @ flat_rel.T).T
        prints.append(np.vstack([pivot, pivot + flat[:, :2] - flat[k, :2]]))
        firsts.append(k)
    planes = _fit_planes(ground, prints)
    out = []
    for (a, b), (origin, plane), k in zip(runs, planes, firsts):
        psi = float(yaw[a])
        p = pitch[a:b]
        qf = rot_z(psi) @ rot_x(-p)
        qt = rot_z(psi) @ rot_x(-np.maximum(p, 0.0))
        rel = feet.relative(qf, qt)  # (n, m, 3) plane frame
        ankle = np.empty((b - a, 3))
        anchor = np.zeros(3)
        for i in range(b - a):
            kk = int(np.argmin(rel[i, :, 2]))
            if i > 0 and kk != k:
                anchor = ankle[i - 1] + rel[i - 1, kk]
                anchor[2] = 0.0
                k = kk
            ankle[i] = anchor - rel[i, k]
        st = Stance(int(a), int(b), origin, plane, psi)
        st.ankle = origin + ankle @ plane.T
        st.foot_rot = plane @ qf
        st.toe_rot = plane @ qt
        # pivot height in the world: the pivot is on the plane at the current anchor
        piv = ankle + rel[np.arange(b - a), np.argmin(rel[:, :, 2], axis=1)]
        st.pivot_z = (origin + piv @ plane.T)[:, 2]
        out.append(st)
    return out


def support_height(stances: dict[str, list[Stance]], frames: int) -> np.ndarray:
    """Ground height under the body: through the mean pivot height of each stance phase at
    its middle frame, linear in between (a ramp on a slope, a smooth track over bumps)."""
    keys = sorted(
        ((st.start + st.stop - 1) / 2.0, float(np.mean(st.pivot_z)))
        for runs in stances.values()
        for st in runs
    )
    if not keys:
        return np.zeros(frames)
    t, h = np.array(keys).T
    return np.interp(np.arange(frames), t, h)


# ------------------------------------------------------------------------- swing
@dataclass
class FootTargets:
    ankle: np.ndarray  # (F, 3)
    foot_rot: np.ndarray  # (F, 3, 3)
    toe_rot: np.ndarray  # (F, 3, 3)
    lift: np.ndarray  # (F,) clearance lift applied in swing [m]


def _rot_blend(r0: np.ndarray, r1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Rotations interpolated from r0 to r1 along the geodesic (slerp), s (n,) in [0, 1]."""
    q = quat_slerp(matrix_to_quat(r0), matrix_to_quat(r1), s)
    return quat_to_matrix(q)


def swing_targets(
    ground: Ground,
    feet: FootPoints,
    stances: list[Stance],
    nominal_ankle: np.ndarray,
    nominal_foot: np.ndarray,
    nominal_toe_angle: np.ndarray,
    support: np.ndarray | None = None,
    margin: float = 0.005,
    max_dorsi: float = np.radians(15.0),
) -> FootTargets:
    """Targets for every frame: planted poses in stance; in swing the nominal pose plus an
    offset blended from lift-off to touch-down, following the terrain under the foot (the
    nominal swing is designed over flat ground at height ``support`` (F,)), plus a clearance
    correction.

    nominal_ankle (F, 3), nominal_foot (F, 3, 3) world; nominal_toe_angle (F,) toe extension
    relative to the foot [rad]. Clearance: where a contact point would come within ``margin``
    (tapered to 0 at lift-off and touch-down) of the ground, the foot is first dorsiflexed (up
    to ``max_dorsi``, as the tibialis anterior does) and then lifted."""
    F = len(nominal_ankle)
    ankle = nominal_ankle.copy()
    foot = nominal_foot.copy()
    in_stance = np.zeros(F, bool)
    for st in stances:
        ankle[st.start : st.stop] = st.ankle
        foot[st.start : st.stop] = st.foot_rot
        in_stance[st.start : st.stop] = True
    toe = foot @ rot_x(-nominal_toe_angle)
    for st in stances:
        toe[st.start : st.stop] = st.toe_rot
    swing = ~in_stance
    taper = np.zeros(F)
    runs = intervals(swing)
    for a, b in runs:
        n = b - a
        u = (np.arange(n) + 1.0) / (n + 1.0)
        s = u * u * (3 - 2 * u)
        taper[a:b] = np.sin(np.pi * u)
        prev = a - 1 if a > 0 else None
        nxt = b if b < F else None

        def offsets(i):
            dp = ankle[i] - nominal_ankle[i]
            dr = foot[i] @ nominal_foot[i].T
            rel = foot[i].T @ toe[i]
            dt = np.arctan2(-rel[2, 1], rel[1, 1]) - nominal_toe_angle[i]
            return dp, dr, dt

        p0, r0, t0 = offsets(prev) if prev is not None else (np.zeros(3), np.eye(3), 0.0)
        p1, r1, t1 = offsets(nxt) if nxt is not None else (p0, r0, 0.0)
        if prev is None:
            p0, r0 = p1, r1
        ankle[a:b] = nominal_ankle[a:b] + (1 - s)[:, None] * p0 + s[:, None] * p1
        if support is not None:
            ends = [i for i in (prev, nxt) if i is not None]
            g = ground.height(np.vstack([ankle[a:b, :2], ankle[ends, :2]]))
            terrain = g[:n] - support[a:b]
            ta = g[n] - support[prev] if prev is not None else terrain[0]
            tb = g[-1] - support[nxt] if nxt is not None else terrain[-1]
            ankle[a:b, 2] += terrain - ((1 - s) * ta + s * tb)
        foot[a:b] = _rot_blend(r0, r1, s) @ nominal_foot[a:b]
        toe[a:b] = foot[a:b] @ rot_x(-(nominal_toe_angle[a:b] + (1 - s) * t0 + s * t1))
    lift = np.zeros(F)
    if runs:
        deficit, reach, ahead = _clearance(ground, feet, ankle, foot, toe, swing, margin * taper)
        if deficit.max() > 0:
            need = np.where(ahead, deficit / np.maximum(reach, 0.05), 0.0)
            tilt = np.minimum(_envelope(need, swing), max_dorsi)
            lat = foot[:, :, 0]  # foot's lateral axis
            turn = np.stack([_axis_rot(lat[i], tilt[i]) for i in range(F)])
            foot = turn @ foot
            toe = turn @ toe
            deficit, _, _ = _clearance(ground, feet, ankle, foot, toe, swing, margin * taper)
            lift = _envelope(deficit, swing)
            ankle[:, 2] += lift
    return FootTargets(ankle, foot, toe, lift)


def _clearance(ground, feet, ankle, foot, toe, swing, margin):
    """Per frame (swing frames only): how far [m] the lowest contact point is below
    ``margin`` (F,) above the ground, its horizontal distance from the ankle and whether it
    is ahead of the ankle (a toe that dorsiflexion can lift)."""
    F = len(ankle)
    deficit = np.zeros(F)
    reach = np.ones(F)
    ahead = np.zeros(F, bool)
    rel = feet.relative(foot[swing], toe[swing])  # (m, n, 3)
    pts = ankle[swing][:, None, :] + rel
    h = pts[..., 2] - ground.height(pts[..., :2])
    k = np.argmin(h, axis=1)
    r = rel[np.arange(len(k)), k]
    deficit[swing] = np.maximum(margin[swing] - h[np.arange(len(k)), k], 0.0)
    reach[swing] = np.linalg.norm(r[:, :2], axis=1)
    ahead[swing] = np.einsum("mi,mi->m", r, -foot[swing][:, :, 1]) > 0
    return deficit, reach, ahead


def _envelope(d: np.ndarray, swing: np.ndarray) -> np.ndarray:
    """A smooth curve >= ``d`` within each swing run (0 elsewhere)."""
    out = np.zeros_like(d)
    for a, b in intervals(swing):
        x = d[a:b]
        if x.max() <= 0:
            continue
        env = gaussian_filter1d(maximum_filter1d(x, size=5, mode="nearest"), 1.5, mode="nearest")
        out[a:b] = np.maximum(env, x)
    return out


def _axis_rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Toes-up rotation by ``angle`` about the foot's lateral (+X) ``axis``."""
    return axis_angle_matrix(axis, -angle)


# ------------------------------------------------------------------------- IK
@dataclass(frozen=True)
class LegChain:
    hip: int
    knee: int
    ankle: int
    toe: int
    hip_offset: np.ndarray  # rest hip joint minus rest root
    u: np.ndarray  # rest thigh vector
    w: np.ndarray  # rest shank vector
    phi0: float  # knee angle of the straightest leg [rad]
    reach: float  # max hip-ankle distance (knee at phi0 + min flexion)


def leg_chain(skeleton: Skeleton, side: str, min_flexion: float = np.radians(1.0)) -> LegChain:
    ix = skeleton.index
    P = skeleton.rest_positions
    h, k, a = ix(f"{side}UpLeg"), ix(f"{side}Leg"), ix(f"{side}Foot")
    u, w = P[k] - P[h], P[a] - P[k]
    pp = u[1] * w[1] + u[2] * w[2]
    qq = u[2] * w[1] - u[1] * w[2]
    phi0 = float(np.arctan2(qq, pp))
    reach = float(np.linalg.norm(u + rot_x(phi0 + min_flexion) @ w))
    return LegChain(h, k, a, ix(f"{side}ToeBase"), P[h] - P[0], u, w, phi0, reach)


def hip_positions(chain: LegChain, root_pos: np.ndarray, root_rot: np.ndarray) -> np.ndarray:
    return root_pos + root_rot @ chain.hip_offset


def reach_drop(chain: LegChain, root_pos, root_rot, ankle: np.ndarray) -> np.ndarray:
    """How far (>= 0) [m] the root must drop per frame for the ankle target to be in reach."""
    r = ankle - hip_positions(chain, root_pos, root_rot)
    lim = chain.reach * 0.9995
    horiz = np.maximum(lim**2 - r[:, 0] ** 2 - r[:, 1] ** 2, 0.0)
    return np.maximum(-np.sqrt(horiz) - r[:, 2], 0.0)


def leg_ik(
    chain: LegChain, root_pos: np.ndarray, root_rot: np.ndarray, hip_nominal: np.ndarray, targets: FootTargets
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Local rotations (hip, knee, ankle, toe), each (F, 3, 3), placing the ankle on its target
    (clamped to the leg's reach) with the target foot and toe orientations. ``hip_nominal``
    (F, 3, 3) is the hip's nominal local rotation (its swivel is kept)."""
    u, w = chain.u, chain.w
    H = hip_positions(chain, root_pos, root_rot)
    r = targets.ankle - H
    d = np.linalg.norm(r, axis=1)
    uu, ww = u @ u, w @ w
    pp = u[1] * w[1] + u[2] * w[2]
    qq = u[2] * w[1] - u[1] * w[2]
    rho = np.hypot(pp, qq)
    c = (d**2 - uu - ww - 2 * u[0] * w[0]) / (2 * rho)
    min_flex = np.arccos(np.clip((chain.reach**2 - uu - ww - 2 * u[0] * w[0]) / (2 * rho), -1.0, 1.0))
    kappa = chain.phi0 + np.maximum(np.arccos(np.clip(c, -1.0, 1.0)), min_flex)
    knee = rot_x(kappa)
    thigh_nom = root_rot @ hip_nominal
    v = np.einsum("fij,fj->fi", thigh_nom, u + np.einsum("fij,j->fi", knee, w))
    thigh = align_matrix(v, r) @ thigh_nom
    hip = np.swapaxes(root_rot, -1, -2) @ thigh
    shank = thigh @ knee
    ankle = np.swapaxes(shank, -1, -2) @ targets.foot_rot
    toe = np.swapaxes(targets.foot_rot, -1, -2) @ targets.toe_rot
    return hip, knee, ankle, toe


# ------------------------------------------------------------------------- settle
def settle_root(
    ground: Ground,
    feet: dict[str, FootPoints],
    world_rot: np.ndarray,
    world_pos: np.ndarray,
    fps: float,
    speed_tol: float = 0.25,
    near: float = 0.05,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Vertical root offsets (F,) for a given motion (e.g. imported mocap): in frames where a
    foot is planted (its lowest point within ``near`` of the ground and moving horizontally
    slower than ``speed_tol`` [m/s]) the lowest planted point is put on the ground; no foot
    point is left under the ground in any frame. Also returns the planted masks per side."""
    F = len(world_pos)
    low_all = np.full(F, np.inf)
    low_planted = np.full(F, np.inf)
    planted = {}
    for side, fp in feet.items():
        pts = fp.world(world_rot, world_pos)
        h = pts[..., 2] - ground.height(pts[..., :2])
        k = np.argmin(h, axis=1)
        low = h[np.arange(F), k]
        xy = pts[np.arange(F), k, :2]
        if F > 1:
            nxt = pts[np.minimum(np.arange(F) + 1, F - 1), k, :2]
            prv = pts[np.maximum(np.arange(F) - 1, 0), k, :2]
            steps = np.where(np.arange(F)[:, None] < F - 1, nxt - xy, xy - prv)
            speed = np.linalg.norm(steps, axis=1) * fps
        else:
            speed = np.zeros(F)
        planted[side] = (low < near) & (speed < speed_tol)
        low_all = np.minimum(low_all, low)
        low_planted = np.where(planted[side], np.minimum(low_planted, low), low_planted)
    floor = -low_all  # lift out of the ground
    want = np.where(np.isfinite(low_planted), -low_planted, floor)
    off = np.maximum(gaussian_filter1d(np.maximum(want, floor), 1.0, mode="nearest"), floor)
    return off, planted


# ------------------------------------------------------------------------- report
def smooth_drop(need: np.ndarray, sigma: float) -> np.ndarray:
    """A smooth curve >= ``need`` (root drops), widened then blurred."""
    if need.max() <= 0:
        return need
    w = max(int(3 * sigma) | 1, 3)
    env = gaussian_filter1d(maximum_filter1d(need, size=w, mode="nearest"), sigma, mode="nearest")
    return np.maximum(env, need)


def contact_report(
    ground: Ground,
    feet: dict[str, FootPoints],
    world_rot: np.ndarray,
    world_pos: np.ndarray,
    stance: dict[str, np.ndarray],
    contact_tol: float = 0.01,
) -> dict:
    """Gap, penetration and stance slip of the posed feet.

    * gap: per frame with a foot in stance, the height of the lowest point of the stance feet
      above the ground (max over the clip; flight frames of running are excluded);
    * penetration: depth of the deepest contact point of either foot below the ground;
    * slip: per stance phase, the largest horizontal excursion of a contact point while it is
      in contact (within ``contact_tol`` of the ground), max over phases.
    """
    F = len(world_pos)
    per = {}
    lowest = np.full(F, np.inf)
    deepest = 0.0
    for side, fp in feet.items():
        pts = fp.world(world_rot, world_pos)  # (F, n, 3)
        h = pts[..., 2] - ground.height(pts[..., :2])
        st = np.asarray(stance[side], bool)
        low = h.min(axis=1)
        pen = float(max(-low.min(), 0.0))
        deepest = max(deepest, pen)
        gap = float(max(low[st].max(), 0.0)) if st.any() else 0.0
        lowest = np.where(st, np.minimum(lowest, low), lowest)
        slip = 0.0
        for a, b in intervals(st):
            hh, xy = h[a:b], pts[a:b, :, :2]
            touch = hh <= contact_tol
            for j in np.flatnonzero(touch.any(axis=0)):
                sel = xy[touch[:, j], j]
                if len(sel) > 1:
                    slip = max(slip, float(np.max(np.linalg.norm(sel - sel[0], axis=1))))
        per[side.lower()] = {
            "max_gap_m": gap,
            "max_penetration_m": pen,
            "max_slip_m": slip,
            "stance_frames": int(st.sum()),
        }
    have = np.isfinite(lowest)
    return {
        "max_gap_m": float(max(lowest[have].max(), 0.0)) if have.any() else 0.0,
        "max_penetration_m": deepest,
        "max_slip_m": max(v["max_slip_m"] for v in per.values()),
        "left": per["left"],
        "right": per["right"],
        "flight_frames": int((~have).sum()),
        "contact_points": next(iter(feet.values())).source,
        "contact_tolerance_m": contact_tol,
        "ground": ground.kind,
    }


# ------------------------------------------------------------------------- foot locking
#: shortest planted run kept and longest gap bridged by :func:`clean_stance` [s]
MIN_STANCE_S = 0.1
MAX_STANCE_GAP_S = 0.07
#: how far [m] the root may drop for a leg to reach its locked foot (:func:`lock_feet`; the
#: DeepMimic run's stance feet skate 5 cm sideways: 1 cm to reach them planted at mid-skate)
MAX_LOCK_DROP_M = 0.02
#: a foot is locked where its lowest point is within this height [m] of the ground and moves
#: slower than LOCK_SPEED_M_S or LOCK_SPEED_SHARE of the body's pace (mocap's skating stance
#: feet move ~1 m/s in a 3.8 m/s run, a walker's lifting swing foot > 2 m/s)
LOCK_NEAR_M = 0.02
LOCK_SPEED_M_S = 0.25
LOCK_SPEED_SHARE = 0.3


def clean_stance(mask: np.ndarray, fps: float) -> np.ndarray:
    """A planted mask with gaps up to :data:`MAX_STANCE_GAP_S` filled and runs shorter than
    :data:`MIN_STANCE_S` dropped (a detector's flicker at touch-down and lift-off)."""
    m = np.asarray(mask, bool).copy()
    gap = int(round(MAX_STANCE_GAP_S * fps))
    runs = intervals(m)
    for (_, b), (a2, _) in zip(runs[:-1], runs[1:]):
        if a2 - b <= gap:
            m[b:a2] = True
    shortest = max(int(round(MIN_STANCE_S * fps)), 2)
    for a, b in intervals(m):
        if b - a < shortest:
            m[a:b] = False
    return m


def _foot_yaw(fp: FootPoints, foot_rot: np.ndarray) -> np.ndarray:
    """Heading [rad] of the foot's rest ankle-to-toe direction, unwrapped over frames."""
    d = fp.toe_offset * [1.0, 1.0, 0.0]
    fwd = np.einsum("fij,j->fi", foot_rot, d / np.linalg.norm(d))
    return np.unwrap(np.arctan2(fwd[:, 1], fwd[:, 0]))


def _bridge(values: np.ndarray, mask: np.ndarray, fade: int, longest: int) -> np.ndarray:
    """Fill the frames outside ``mask`` by minimum-jerk blends: across a gap of at most
    ``longest`` frames from the value at the end of the run before to the value at the start
    of the run after; before the first run, after the last and across longer gaps from or to
    zero over ``fade`` frames (zero beyond). ``values`` (F, ...) is read on the masked frames."""

    def ease(n):
        u = np.arange(1, n + 1) / (n + 1.0)
        return (u**3 * (10 - 15 * u + 6 * u * u)).reshape((-1,) + (1,) * (values.ndim - 1))

    out = np.zeros_like(values)
    runs = intervals(mask)
    for a, b in runs:
        out[a:b] = values[a:b]
    for i, (a, b) in enumerate(runs):
        # the fade in before a run that no bridge reaches (before s8 a first run followed by a
        # bridge skipped it: the correction jumped in at the run's first frame)
        prev = runs[i - 1][1] if i > 0 else None
        if i == 0 or a - prev > longest:
            n = min(fade, a - (prev or 0))
            out[a - n : a] = ease(fade)[fade - n :] * values[a]
        nxt = runs[i + 1][0] if i + 1 < len(runs) else None
        if nxt is not None and nxt - b <= longest:
            s = ease(nxt - b)
            out[b:nxt] = (1 - s) * values[b - 1] + s * values[nxt]
            continue
        n = min(fade, (nxt if nxt is not None else len(values)) - b)
        out[b : b + n] = (1 - ease(fade)[:n]) * values[b - 1]
    return out


def lock_feet(
    skeleton: Skeleton,
    ground: Ground,
    feet: dict[str, FootPoints],
    local: np.ndarray,
    root_rot: np.ndarray,
    root_pos: np.ndarray,
    stance: dict[str, np.ndarray],
    fps: float,
    margin: float = 0.002,
) -> tuple[np.ndarray, np.ndarray, dict]:
    """Planted feet of a given motion (e.g. retargeted motion capture) that do not slide and
    stand on the ground; returns new local rotations (F, J, 3, 3), root positions (F, 3) and
    the planted masks kept (a run the leg cannot reach within :data:`MAX_LOCK_DROP_M` is
    dragged rather than planted and left as it is).

    In each planted run of ``stance`` (per side, (F,) bool) the foot's heading is frozen at
    its first frame (turned about the vertical through the ankle), the foot *rolls without
    slipping*: from frame to frame its lowest contact point (the pivot) keeps its horizontal
    position, as :func:`plant_stance` does for the designed gait, and the foot is moved up or down so that its lowest point over the run touches the
    ground. Between runs these corrections (offset,
    height, heading) are blended by minimum jerk, a swing foot is lifted where a point would
    dip below ``margin`` over the ground, and the legs are posed on the corrected ankle
    targets by :func:`leg_ik` (the hip keeps the clip's swivel; the root drops where a leg
    cannot reach, smoothed)."""
    stance = {side: np.asarray(stance[side], bool).copy() for side in feet}
    wrot, wpos = fk_matrices(skeleton, local, root_rot, root_pos)

    def extra_drop(side, target):  # beyond what the clip's own (e.g. straight) leg needs
        chain = leg_chain(skeleton, side)
        own = reach_drop(chain, root_pos, root_rot, wpos[:, feet[side].foot])
        return np.maximum(reach_drop(chain, root_pos, root_rot, target) - own, 0.0)

    targets = _locked_targets(skeleton, ground, feet, local, root_rot, root_pos, stance, margin, fps)
    # a run whose locked foot the leg cannot reach is dragged, not planted (a crawl's toes, a
    # knee-walk): released, so that the lock never pulls the body down to it
    for side in feet:
        need = extra_drop(side, targets[side].ankle)
        for a, b in intervals(stance[side]):
            if need[a:b].max() > MAX_LOCK_DROP_M:
                stance[side][a:b] = False
    targets = _locked_targets(skeleton, ground, feet, local, root_rot, root_pos, stance, margin, fps)
    need = np.zeros(len(root_pos))
    for side in feet:
        need = np.maximum(need, extra_drop(side, targets[side].ankle))
    root_pos0, root_pos = root_pos, root_pos.copy()
    root_pos[:, 2] -= smooth_drop(need, 1.0)
    # the legs moved by what the IK changes between the clip's own ankles and the locked ones
    # (zero where nothing is corrected: the IK's knee is a hinge with at least 1 deg of
    # flexion, a clip's knee need not be, so the IK alone would change legs that need no change)
    # (the change is exact to first order: two passes aim at the ankle the first one missed)
    out = local.copy()
    T = np.swapaxes
    for side, fp in feet.items():
        chain = leg_chain(skeleton, side)
        own = FootTargets(wpos[:, fp.foot], wrot[:, fp.foot], wrot[:, fp.toe], np.zeros(len(root_pos)))
        h0, k0, _, _ = leg_ik(chain, root_pos0, root_rot, local[:, chain.hip], own)
        aim = targets[side].ankle
        for _ in range(2):
            h1, k1, _, _ = leg_ik(
                chain, root_pos, root_rot, local[:, chain.hip], replace(targets[side], ankle=aim)
            )
            hip = h1 @ T(h0, -1, -2) @ local[:, chain.hip]
            knee = local[:, chain.knee] @ T(k0, -1, -2) @ k1
            thigh = wrot[:, skeleton.parents[chain.hip]] @ hip
            shank = thigh @ knee
            got = (
                hip_positions(chain, root_pos, root_rot)
                + np.einsum("fij,j->fi", thigh, chain.u)
                + np.einsum("fij,j->fi", shank, chain.w)
            )
            aim = aim + (targets[side].ankle - got)
        out[:, chain.hip], out[:, chain.knee] = hip, knee
        out[:, chain.ankle] = T(shank, -1, -2) @ targets[side].foot_rot
        out[:, chain.toe] = T(targets[side].foot_rot, -1, -2) @ targets[side].toe_rot
    return out, root_pos, stance


#: frames over which a lock correction fades in or out, and the longest gap between two planted
#: runs of a foot that is bridged (longer gaps fade out and in) [s]
LOCK_FADE_S = 0.25
LOCK_BRIDGE_S = 1.0


def _fade_frames(fps: float) -> tuple[int, int]:
    return max(int(round(LOCK_FADE_S * fps)), 2), int(round(LOCK_BRIDGE_S * fps))


def _locked_targets(skeleton, ground, feet, local, root_rot, root_pos, stance, margin, fps) -> dict:
    frames = len(root_pos)
    fade, longest = _fade_frames(fps)
    wrot, wpos = fk_matrices(skeleton, local, root_rot, root_pos)
    targets = {}
    for side, fp in feet.items():
        m = stance[side]
        ankle = wpos[:, fp.foot].copy()
        frot, trot = wrot[:, fp.foot], wrot[:, fp.toe]
        yaw = _foot_yaw(fp, frot)
        dpsi = np.zeros(frames)
        off = np.zeros((frames, 3))
        for a, b in intervals(m):
            dpsi[a:b] = yaw[a] - yaw[a:b]
        dpsi = _bridge(dpsi, m, fade, longest)
        turn = rot_z(dpsi)
        frot, trot = turn @ frot, turn @ trot
        rel = fp.relative(frot, trot)  # (F, n, 3) about the ankle
        pts = ankle[:, None, :] + rel
        h = pts[..., 2] - ground.height(pts[..., :2])
        for a, b in intervals(m):
            lowest = h[a:b].min(axis=1)
            for f in range(a + 1, b):
                k = int(np.argmin(h[f]))  # the pivot stays where it was in the frame before
                off[f, :2] = off[f - 1, :2] - (pts[f, k, :2] - pts[f - 1, k, :2])
            # planted where the clip has it on average over the run (not where it touched
            # down): the legs reach half the skate each way
            off[a:b, :2] -= off[a:b, :2].mean(axis=0)
            # the run's lowest moment on the ground (not every frame: a foot lifting off at the
            # end of its run is not pulled back down)
            off[a:b, 2] = -lowest.min()
        off = _bridge(off, m, fade, longest)
        target = ankle + off

        # swing: no lower than the clip's own foot where that is near the ground (the bridged
        # height may pass under a toe)
        def dip(p):
            return np.max(ground.height(p[..., :2]) + margin - p[..., 2], axis=1)

        lift = np.maximum(dip(target[:, None, :] + rel) - np.maximum(dip(pts), 0.0), 0.0)
        target[:, 2] += np.where(m, 0.0, lift)
        targets[side] = FootTargets(target, frot, trot, np.zeros(frames))
    return targets

"""Procedural motion of the avatar: standing, turning in place, walking, running, recovering.

``make_motion(activity, skeleton, fps, frame_count, ...)`` returns a :class:`Motion`: per-frame
local joint rotations (wxyz, joint order = ``skeleton.names``) and the world position of the
Hips joint in the avatar's frame (+Z up, rest facing -Y; the avatar layer places that frame in
the scene), a metabolic rate per frame and a contact report.

Pipeline (walk/run):

1. :mod:`humv_usd.human.gait` gives the nominal body-frame pose per gait phase: normative
   sagittal hip/knee/ankle curves (Winter 2009, Perry & Burnfield 2010; running Novacheck
   1998), pelvis rotation/obliquity/tilt, counter-rotating thorax, arm swing opposite to the
   legs, cadence and stride length from the speed (Grieve & Gear 1966; Cavanagh & Kram 1989).
2. The root is *locked* to the stance foot on flat ground: its forward progression is minus
   the motion of the stance foot's rolling pivot and its height puts that pivot on the ground
   (ballistic between stances when running). The sagittal hip amplitude is calibrated (secant)
   so that the progression speed equals the requested speed, i.e. the stride length the
   cadence law asks for. Vertical CoM oscillation is therefore a result, not an input.
3. The root follows the path (arc length = speed * time + the within-stride fluctuation of
   step 2), heading along the path's tangent, with a mediolateral sway toward the stance foot;
   its height follows the ground under the stance feet. The clip is steady-state gait (it
   starts and ends mid-stride; one stride is simulated beyond each end and cropped).
4. :mod:`humv_usd.human.contact` plants each stance foot on the ground (support plane,
   rolling without slipping); a contact the leg cannot reach starts up to 5 % of a cycle later
   or ends up to 8 % earlier (the tables do not close exactly in double support), swing feet
   are blended between plants and follow the terrain with clearance, the root drops where a
   stance leg still could not reach, and two-bone IK poses the legs.

These steps work per frame (stance runs, finite differences of the stance pivots, flight
between stance frames), which needs several frames per step: below ``SIM_FPS_MIN`` (30 fps)
the walk, run, carry, standing and pose activities are simulated at the smallest integer
multiple of the frame rate at or above it and every k-th frame is kept, so that a clip at 1,
2, 3, 5, 6, 10 or 15 fps is the 30 fps clip at its times.

Standing activities keep both feet planted (``standTurn`` steps them round a turn) and move
the pelvis: quiet-standing sway (Winter 1995, *Gait & Posture* 3:193-214: CoM/CoP sway of a few
mm to ~1 cm, mostly 0.1-0.5 Hz) and breathing (12-16 breaths/min at rest; faster and deeper
after exercise).

Metabolic rate (:func:`metabolic_rate`): ACSM's Guidelines for Exercise Testing and
Prescription (10th ed., 2018, ch. 6) walking and running equations, VO2 [mL/kg/min] =
3.5 + 0.1 v + 1.8 v G (walking) or 3.5 + 0.2 v + 0.9 v G (running), v in m/min, G the
fractional grade (>= 0; the equations are not valid downhill, which is costed as level);
standing 1.3 MET and stepping/turning 2.0 MET (Ainsworth et al. 2011 Compendium of Physical
Activities, *Med Sci Sports Exerc* 43:1575-1581: "standing quietly" 1.3 MET, very slow walking
2.0 MET); 1 MET = 3.5 mL/kg/min; 1 L O2 = 20.1 kJ (RER ~0.85-0.9). On uneven ground the grade
is the smoothed slope of the ground under the stance feet.
After exercise the rate decays to rest as 0.9 exp(-t/40 s) + 0.1 exp(-t/600 s) of the excess:
the fast VO2 off-transient (tau ~ 30-40 s for moderate exercise, Ozyener et al. 2001, *J Physiol*
533:891-902) plus a small prolonged EPOC component (Borsheim & Bahr 2003, *Sports Med*
33:1037-1060).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.ndimage import gaussian_filter1d

from humv_usd.errors import InputError, bad_value
from humv_usd.human import contact as C
from humv_usd.human import poses as PO
from humv_usd.human.carry import apply_box_carry
from humv_usd.human.gait import (
    GaitParams,
    NominalGait,
    axis_angle_matrix,
    fk_matrices,
    gait_params,
    matrix_to_quat,
    nominal_gait,
    rig_info,
    rot_x,
    rot_y,
    rot_z,
    set_ankles,
)
from humv_usd.human.skeleton import Skeleton, quat_to_matrix
from humv_usd.scenario.spec import ACTIVITIES  # noqa: F401 (the activities make_motion builds)

SPEED_RANGE = {"walk": (0.3, 2.2), "run": (1.8, 6.0), "carry": (0.3, 2.2)}
DEFAULT_SPEED = {"walk": 1.4, "run": 3.5, "carry": 1.2}
MET_ML_KG_MIN = 3.5
J_PER_ML_O2 = 20.1
MET_STAND = 1.3
MET_STEPPING = 2.0
EPOC = ((0.9, 40.0), (0.1, 600.0))  # (fraction, time constant [s]) of the excess


@dataclass(frozen=True)
class Motion:
    fps: float
    root_translation: np.ndarray  # (F, 3) world position of the Hips joint [m], avatar frame
    local_rotations: np.ndarray  # (F, J, 4) wxyz, joint order = skeleton.names
    activity: str
    metabolic_rate_w: np.ndarray  # (F,) metabolic rate [W] per frame
    contact: dict  # per-clip report: max gap, max penetration, max slip per foot
    gait: dict = field(default_factory=dict)  # cadence, step length, stance masks, ...

    @property
    def frame_count(self) -> int:
        return len(self.root_translation)

    @property
    def times(self) -> np.ndarray:
        return np.arange(self.frame_count) / self.fps

    def world(self, skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray]:
        """World joint rotations (F, J, 3, 3) and positions (F, J, 3)."""
        rot = quat_to_matrix(self.local_rotations)
        return fk_matrices(skeleton, rot, rot[:, 0], self.root_translation)


# ------------------------------------------------------------------------- metabolic rate
def met_to_watts(met, mass_kg: float) -> np.ndarray:
    return np.asarray(met) * MET_ML_KG_MIN * mass_kg * J_PER_ML_O2 / 60.0


def acsm_vo2(mode: str, speed_m_s, grade=0.0) -> np.ndarray:
    """ACSM (2018) VO2 [mL/kg/min] of walking or running; grade < 0 is costed as level."""
    v = np.asarray(speed_m_s, dtype=np.float64) * 60.0
    g = np.maximum(np.asarray(grade, dtype=np.float64), 0.0)
    if mode == "walk":
        return MET_ML_KG_MIN + 0.1 * v + 1.8 * v * g
    if mode == "run":
        return MET_ML_KG_MIN + 0.2 * v + 0.9 * v * g
    raise ValueError(f"no ACSM equation for {mode!r}")


def epoc_met(t_s, exercise_met: float, rest_met: float = MET_STAND) -> np.ndarray:
    """MET after exercise at ``exercise_met`` stopped at t = 0 (see the module docstring)."""
    t = np.maximum(np.asarray(t_s, dtype=np.float64), 0.0)
    excess = max(exercise_met - rest_met, 0.0)
    return rest_met + excess * sum(a * np.exp(-t / tau) for a, tau in EPOC)


def metabolic_rate(
    activity: str,
    mass_kg: float,
    times: np.ndarray,
    speed_m_s: float = 0.0,
    grade=0.0,
    exercise_met: float = 10.0,
    time_since_exercise_s: float = 0.0,
    stepping=None,
) -> np.ndarray:
    """Metabolic rate [W] per frame (``times`` [s]); ``stepping`` (F,) bool marks the turning
    steps of ``standTurn``."""
    n = len(times)
    if activity in ("walk", "run"):
        vo2 = acsm_vo2(activity, speed_m_s, np.broadcast_to(grade, (n,)))
        return vo2 * mass_kg * J_PER_ML_O2 / 60.0
    if activity == "postExercise":
        return met_to_watts(epoc_met(times + time_since_exercise_s, exercise_met), mass_kg)
    met = np.full(n, MET_STAND)
    if activity == "standTurn" and stepping is not None:
        met = np.where(stepping, MET_STEPPING, met)
    return met_to_watts(met, mass_kg)


# ------------------------------------------------------------------------- paths
class Path:
    """The Hips' ground track: ``waypoints`` (N, 2) in the avatar frame, corners rounded by a
    Gaussian of ``smooth_m``; extended straight beyond both ends. ``None``: a straight line
    from ``start`` along the avatar's facing (-Y)."""

    def __init__(self, waypoints, start: np.ndarray, smooth_m: float = 0.4):
        if waypoints is None:
            self.s = np.array([0.0, 1.0])
            self.xy = np.array([start, start + [0.0, -1.0]], dtype=np.float64)
        else:
            w = np.asarray(waypoints, dtype=np.float64)
            if w.ndim != 2 or w.shape[1] != 2 or len(w) < 2 or not np.isfinite(w).all():
                raise InputError(
                    bad_value(
                        "path", np.asarray(waypoints).tolist(), "expected at least two (x, y) waypoints [m]"
                    )
                )
            seg = np.linalg.norm(np.diff(w, axis=0), axis=1)
            w = w[np.r_[True, seg > 1e-9]]
            if len(w) < 2:
                raise InputError(bad_value("path", w.tolist(), "waypoints must not coincide"))
            s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(w, axis=0), axis=1))]
            step = 0.01
            ss = np.arange(0.0, s[-1] + step / 2, step)
            dense = np.column_stack([np.interp(ss, s, w[:, 0]), np.interp(ss, s, w[:, 1])])
            if len(w) > 2:
                sig = smooth_m / step
                pad = int(4 * sig) + 1
                t0 = dense[1] - dense[0]
                t1 = dense[-1] - dense[-2]
                head = dense[0] - np.arange(pad, 0, -1)[:, None] * t0
                tail = dense[-1] + np.arange(1, pad + 1)[:, None] * t1
                ext = np.vstack([head, dense, tail])
                dense = gaussian_filter1d(ext, sig, axis=0, mode="nearest")[pad:-pad]
                dense[0], dense[-1] = w[0], w[-1]
            self.xy = dense
            self.s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))]

    def at(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (F, 2) and headings (F,) [rad about +Z from the rest facing] at arc
        lengths ``s`` (F,)."""
        s = np.asarray(s, dtype=np.float64)
        L = self.s[-1]
        tang = np.gradient(self.xy, self.s, axis=0)
        tang /= np.linalg.norm(tang, axis=1, keepdims=True)
        sc = np.clip(s, 0.0, L)
        xy = np.column_stack([np.interp(sc, self.s, self.xy[:, 0]), np.interp(sc, self.s, self.xy[:, 1])])
        tx = np.interp(sc, self.s, tang[:, 0])
        ty = np.interp(sc, self.s, tang[:, 1])
        before, after = s < 0, s > L
        xy[before] = self.xy[0] + s[before, None] * tang[0]
        xy[after] = self.xy[-1] + (s[after] - L)[:, None] * tang[-1]
        psi = np.unwrap(np.arctan2(tx, -ty))
        return xy, psi


# ------------------------------------------------------------------------- locomotion
def _pivots(feet: dict, rot: np.ndarray, pos: np.ndarray) -> dict:
    out = {}
    for side, fp in feet.items():
        pts = fp.world(rot, pos)
        out[side] = (pts, np.argmin(pts[..., 2], axis=1))
    return out


def _lock(
    nom: NominalGait, rot: np.ndarray, pos: np.ndarray, feet: dict, dt: float, speed: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Root forward progression (F,) and height (F,) that keep the stance foot's pivot still
    on flat ground z = 0, and the (F - 1,) mask of steps carried by a stance foot. In double
    support the newly landed foot carries the progression and the height is load-weighted."""
    n = len(nom.phase)
    num = np.zeros(n - 1)
    den = np.zeros(n - 1)
    znum = np.zeros(n)
    zden = np.zeros(n)
    i = np.arange(n - 1)
    # the most recently landed stance foot carries the progression (in double support the
    # tables' two pivots do not move exactly alike; the trailing leg, still flexed, absorbs it)
    age = {
        s: np.where(nom.stance[s], np.mod(nom.phase + off, 1.0), np.inf)
        for s, off in (("Left", 0.0), ("Right", 0.5))
    }
    for side, (pts, k) in _pivots(feet, rot, pos).items():
        st = nom.stance[side]
        other = age["Right" if side == "Left" else "Left"]
        wz = np.where(st, nom.load[side] + 1e-6, 0.0)
        znum += wz * -pts[np.arange(n), k, 2]
        zden += wz
        d = pts[i + 1, k[:-1], 1] - pts[i, k[:-1], 1]  # foot moves back = body forward
        w = np.where(st[:-1] & st[1:] & (age[side][:-1] <= other[:-1]), 1.0, 0.0)
        num += w * d
        den += w
    carried = den > 0
    step = np.where(carried, num / np.where(carried, den, 1.0), speed * dt)
    prog = np.r_[0.0, np.cumsum(step)]
    # height: the loaded foot's pivot on the ground; ballistic flight between stances
    have = zden > 0
    z = np.where(have, znum / np.where(have, zden, 1.0), np.inf)
    for a, b in C.intervals(~have):
        if a == 0 or b == n:
            z[a:b] = z[b] if a == 0 and b < n else (z[a - 1] if a > 0 else 0.0)
            continue
        z0, z1 = z[a - 1], z[b]
        tf = (b - a + 1) * dt
        tau = (np.arange(a, b) - (a - 1)) * dt
        z[a:b] = z0 + (z1 - z0) * tau / tf + 0.5 * 9.81 * tau * (tf - tau)
    return prog, z, carried


def _stance_speed(
    skeleton: Skeleton, params: GaitParams, feet: dict, fps: float, start_phase: float = 0.0
) -> float:
    """Mean progression speed over the stance-carried steps of ~3 cycles sampled at ``fps``
    (the flat-ground lock depends a little on the sampling)."""
    dt = 1.0 / fps
    n = int(np.ceil(3.0 * fps / params.frequency)) + 1
    phase = start_phase + params.frequency * dt * np.arange(n)
    nom = nominal_gait(skeleton, params, phase)
    set_ankles(skeleton, nom)
    rot, pos = fk_matrices(skeleton, nom.local, nom.pelvis, nom.root)
    prog, _, carried = _lock(nom, rot, pos, feet, dt, params.speed)
    steps = np.diff(prog)
    return float(steps[carried].sum() / (carried.sum() * dt))


def calibrated_params(
    mode: str, speed: float, skeleton: Skeleton, feet: dict, fps: float = 120.0, start_phase: float = 0.0
) -> GaitParams:
    """Gait parameters whose hip amplitude makes the locked stance progression match the
    requested speed (secant iteration on ``hip_scale``)."""
    p = gait_params(mode, speed, skeleton)
    k0, v0 = 1.0, _stance_speed(skeleton, p, feet, fps, start_phase)
    k1 = float(np.clip(k0 * speed / v0, 0.3, 2.0))
    for _ in range(8):
        v1 = _stance_speed(skeleton, replace(p, hip_scale=k1), feet, fps, start_phase)
        if abs(v1 - speed) < 1e-3 * speed or abs(v1 - v0) < 1e-9:
            break
        k0, k1, v0 = k1, float(np.clip(k1 + (speed - v1) * (k1 - k0) / (v1 - v0), 0.3, 2.0)), v1
    return replace(p, hip_scale=k1)


def _continuous(q: np.ndarray) -> np.ndarray:
    """Flip quaternion signs so consecutive frames lie in the same hemisphere."""
    q = q.copy()
    for f in range(1, len(q)):
        flip = np.sum(q[f] * q[f - 1], axis=-1) < 0
        q[f, flip] *= -1
    return q


def _finish(skeleton, ground, feet, local, root_pos, stance, keep) -> tuple:
    rot, pos = fk_matrices(skeleton, local, local[:, 0], root_pos)
    rot, pos = rot[keep], pos[keep]
    report = C.contact_report(ground, feet, rot, pos, {s: m[keep] for s, m in stance.items()})
    quats = _continuous(matrix_to_quat(local[keep]))
    return quats, root_pos[keep], report


def _locomotion(mode, skeleton, fps, frames, speed, path, ground, feet, start_phase):
    params = calibrated_params(mode, speed, skeleton, feet, fps, start_phase)
    ix = rig_info(skeleton).index
    pad = int(np.ceil(fps / params.frequency)) + 2
    n = frames + 2 * pad
    t = (np.arange(n) - pad) / fps
    phase = start_phase + params.frequency * t
    nom = nominal_gait(skeleton, params, phase)
    set_ankles(skeleton, nom)
    rot_b, pos_b = fk_matrices(skeleton, nom.local, nom.pelvis, nom.root)
    prog, z_lock, _ = _lock(nom, rot_b, pos_b, feet, 1.0 / fps, speed)
    # keep the within-stride fluctuation, impose the mean speed
    slope = np.polyfit(t, prog, 1)[0]
    s = speed * t + (prog - slope * t) - (prog[pad] - slope * t[pad])
    track, psi = path.at(s)
    heading = rot_z(psi)
    xy = track + np.einsum("fij,fj->fi", heading, nom.root)[:, :2]  # + sway
    stances, stance_mask, ankle_xys = {}, {}, {}
    for side in C.SIDES:
        j = ix[f"{side}Foot"]
        ankle_xys[side] = track + np.einsum("fij,fj->fi", heading, pos_b[:, j])[:, :2]
        stances[side] = C.plant_stance(
            ground, feet[side], nom.stance[side], ankle_xys[side], psi + nom.yaw[side], nom.pitch[side]
        )
        stance_mask[side] = nom.stance[side].copy()
    root_rot = heading @ nom.pelvis
    root_pos = np.column_stack([xy, z_lock + C.support_height(stances, n)])
    # contacts the legs cannot reach start a little later / end a little earlier; re-plant
    cycle = fps / params.frequency
    for side in C.SIDES:
        stance_mask[side] = _trim_contacts(
            skeleton,
            side,
            stance_mask[side],
            stances[side],
            root_pos,
            root_rot,
            int(round(0.05 * cycle)),
            int(round(0.08 * cycle)),
        )
        stances[side] = C.plant_stance(
            ground, feet[side], stance_mask[side], ankle_xys[side], psi + nom.yaw[side], nom.pitch[side]
        )
    support = C.support_height(stances, n)
    root_pos = np.column_stack([xy, z_lock + support])
    drop = _reach_drop(skeleton, stances, root_pos, root_rot, n)
    root_pos[:, 2] -= drop
    local = nom.local.copy()
    lifts = {}
    for side in C.SIDES:
        j = ix[f"{side}Foot"]
        nominal_ankle = root_pos + np.einsum("fij,fj->fi", heading, pos_b[:, j] - nom.root)
        targets = C.swing_targets(
            ground,
            feet[side],
            stances[side],
            nominal_ankle,
            heading @ rot_b[:, j],
            nom.toe[side],
            support - drop,
        )
        chain = C.leg_chain(skeleton, side)
        hip, knee, ankle, toe = C.leg_ik(chain, root_pos, root_rot, nom.local[:, chain.hip], targets)
        local[:, chain.hip], local[:, chain.knee] = hip, knee
        local[:, chain.ankle], local[:, chain.toe] = ankle, toe
        lifts[side] = targets.lift
    local[:, 0] = root_rot
    keep = slice(pad, pad + frames)
    quats, root, report = _finish(skeleton, ground, feet, local, root_pos, stance_mask, keep)
    # grade along the path: slope of the ground under the stance feet, over about a stride
    sigma = max(fps / params.frequency / 2, 1.0)
    dz = np.gradient(gaussian_filter1d(support, sigma, mode="nearest"))
    ds = np.gradient(gaussian_filter1d(s, sigma, mode="nearest"))
    grade = (dz / np.maximum(ds, 1e-9))[keep]
    info = {
        "speed_m_s": speed,
        "cadence_steps_min": params.cadence,
        "step_length_m": params.step_length,
        "stride_length_m": params.stride_length,
        "stride_frequency_hz": params.frequency,
        "duty_factor": params.duty,
        "hip_scale": params.hip_scale,
        "phase": np.mod(phase[keep], 1.0),
        "stance": {s.lower(): m[keep] for s, m in stance_mask.items()},
        "grade": grade,
        "swing_lift_max_m": max(float(v[keep].max()) for v in lifts.values()),
        "source": "gait tables: "
        + {"walk": "Winter 2009 / Perry & Burnfield 2010", "run": "Novacheck 1998"}[mode],
    }
    return quats, root, report, info


def _trim_contacts(
    skeleton, side, mask, stances, root_pos, root_rot, max_head: int, max_tail: int, tol=1e-3
) -> np.ndarray:
    """Contact mask of one foot with each stance shortened (by at most ``max_head`` frames at
    the start and ``max_tail`` at the end) to the frames its leg can reach: a late touch-down
    (heel still above the ground) or an early lift-off of the unloading trailing foot. The
    gait tables do not close exactly in double support; this keeps the pelvis from being
    pulled down there (larger misses, e.g. on slopes, lower the pelvis instead)."""
    chain = C.leg_chain(skeleton, side)
    out = mask.copy()
    for st in stances:
        n = st.stop - st.start
        sl = slice(st.start, st.stop)
        bad = C.reach_drop(chain, root_pos[sl], root_rot[sl], st.ankle) > tol
        head = 0
        while head < min(max_head, n // 2) and bad[head]:
            head += 1
        stop = n
        lo = max(n - max_tail, n // 2)
        tail = np.flatnonzero(bad[lo:])
        if len(tail):
            stop = lo + int(tail[0])
        out[st.start : st.start + head] = False
        out[st.start + stop : st.stop] = False
    return out


def _reach_drop(skeleton, stances, root_pos, root_rot, n) -> np.ndarray:
    need = np.zeros(n)
    for side, runs in stances.items():
        chain = C.leg_chain(skeleton, side)
        for st in runs:
            sl = slice(st.start, st.stop)
            need[sl] = np.maximum(need[sl], C.reach_drop(chain, root_pos[sl], root_rot[sl], st.ankle))
    return C.smooth_drop(need, 2.0)


# ------------------------------------------------------------------------- standing
def _minjerk(x) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10 - 15 * x + 6 * x * x)


def _sway(t: np.ndarray, rng: np.random.Generator, rms: float) -> np.ndarray:
    """Quiet-standing sway: a few random-phase components at 0.1-0.5 Hz with the given RMS."""
    freqs = np.array([0.11, 0.17, 0.26, 0.37, 0.48])
    amp = rng.uniform(0.5, 1.0, len(freqs)) / np.sqrt(freqs / freqs[0])
    ph = rng.uniform(0, 2 * np.pi, len(freqs))
    x = (amp[:, None] * np.sin(2 * np.pi * freqs[:, None] * t + ph[:, None])).sum(0)
    norm = np.sqrt(0.5 * np.sum(amp**2))
    return rms * x / norm


#: The standing arms' angle from the vertical in the frontal plane [rad]. 8 deg put the upper
#: arm into the torso with linear-blend skinning (demo body: 90 of 758 armpit vertices inside
#: the body, 40 T-shirt triangle centres inside it); at 18 deg 14 and 4 (13 deg: 46 and 29).
#: A relaxed arm hangs clear of the latissimus, about 10-20 deg at the humerus; the walking
#: gait uses 9-12 deg (gait_params).
STAND_ARM_ABDUCTION = np.radians(18.0)


def _standing(
    activity,
    skeleton,
    fps,
    frames,
    path,
    ground,
    feet,
    seed,
    turn_deg,
    turn_duration_s,
    exercise_met,
    time_since_exercise_s,
):
    info = rig_info(skeleton)
    ix = info.index
    rest = skeleton.rest_positions
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / fps
    hips = rest[0]
    start = hips[:2].copy()
    psi0 = 0.0
    if path is not None:
        w = np.asarray(path, dtype=np.float64)
        start = w[0].copy()
        if len(w) > 1:
            d = w[1] - w[0]
            psi0 = float(np.arctan2(d[0], -d[1]))
    # heading and turning steps
    psi = np.full(frames, psi0)
    stance = {s: np.ones(frames, bool) for s in C.SIDES}
    foot_yaw = {s: np.full(frames, psi0) for s in C.SIDES}
    lift_s = {s: np.zeros(frames) for s in C.SIDES}
    shift = np.zeros(frames)
    stepping = np.zeros(frames, bool)
    if activity == "standTurn":
        turn = np.radians(turn_deg)
        pairs = max(int(np.ceil(abs(turn_deg) / 60.0 - 1e-9)), 1)
        dur = turn_duration_s if turn_duration_s else 1.0 * pairs
        t0 = min(0.5, 0.1 * frames / fps)
        psi = psi0 + turn * _minjerk((t - t0) / dur)
        lead, trail = ("Left", "Right") if turn >= 0 else ("Right", "Left")
        steps = 2 * pairs
        ts = dur / steps
        for i in range(steps):
            side = lead if i % 2 == 0 else trail
            target = psi0 + turn * (i // 2 + 1) / pairs
            a, b = t0 + (i + 0.15) * ts, t0 + (i + 0.85) * ts
            swing = (t >= a) & (t < b)
            if not swing.any():
                continue
            stance[side] &= ~swing
            stepping |= swing
            u = (t[swing] - a) / (b - a)
            before = foot_yaw[side][np.argmax(swing) - 1] if np.argmax(swing) > 0 else psi0
            foot_yaw[side][swing] = before + (target - before) * _minjerk(u)
            foot_yaw[side][t >= b] = target
            lift_s[side][swing] = np.sin(np.pi * u)
            # shift the pelvis over the stance foot while the other one steps
            other = trail if side == lead else lead
            sgn = 1.0 if other == "Left" else -1.0
            shift += sgn * 0.025 * np.sin(np.pi * np.clip((t - a + 0.1 * ts) / (b - a + 0.2 * ts), 0, 1)) ** 2
    # breathing and sway
    if activity == "postExercise":
        # breathing follows the fast EPOC component: ~39/min and 3x deeper right after
        # ~10 MET, back to ~15/min at rest
        excess = float(np.clip((exercise_met - MET_STAND) / (10.0 - MET_STAND), 0.0, 1.5))
        decay = excess * np.exp(-(t + time_since_exercise_s) / EPOC[0][1])
        rate = 0.25 + 0.40 * decay  # breaths/s
        depth = 1.0 + 2.0 * decay
        sway_rms = (0.006, 0.004)
        lean = np.radians(3.0)
    else:
        rate = np.full(frames, rng.uniform(0.22, 0.27))
        depth = np.ones(frames)
        sway_rms = (0.004, 0.0025)
        lean = 0.0
    breath_phase = 2 * np.pi * np.cumsum(rate) / fps + rng.uniform(0, 2 * np.pi)
    breath = depth * 0.5 * (1 - np.cos(breath_phase))  # 0 (exhaled) .. depth (inhaled)
    ap = _sway(t, rng, sway_rms[0])
    ml = _sway(t, rng, sway_rms[1])
    # root
    heading = rot_z(psi)
    lateral = np.column_stack([np.cos(psi), np.sin(psi)])
    forward = np.column_stack([np.sin(psi), -np.cos(psi)])
    xy = start + (ml + shift)[:, None] * lateral + ap[:, None] * forward
    # feet: under the hip joints, rest toe-out, flat
    local = np.tile(np.eye(3), (frames, len(skeleton.names), 1, 1))
    stances = {}
    nominal_ankle = {}
    for side in C.SIDES:
        sign = 1.0 if side == "Left" else -1.0
        j = ix[f"{side}Foot"]
        off = np.array([rest[ix[f"{side}UpLeg"]][0], rest[j][1]]) - hips[:2]
        off_w = np.einsum("fij,j->fi", rot_z(foot_yaw[side])[:, :2, :2], off)
        ankle_xy = start + off_w
        stances[side] = C.plant_stance(
            ground, feet[side], stance[side], ankle_xy, foot_yaw[side], np.zeros(frames)
        )
        nominal_ankle[side] = np.column_stack([ankle_xy, np.full(frames, rest[j][2])])
        local[:, ix[f"{side}UpLeg"]] = rot_y(sign * info.rest_abd[side])
        local[:, ix[f"{side}Leg"]] = rot_x(np.radians(5.0) - info.rest_knee[side])
    # swing nominal of the stepping feet: between plants, lifted
    for side in C.SIDES:
        na = nominal_ankle[side]
        for a, b in C.intervals(~stance[side]):
            prev = next((s for s in stances[side] if s.stop == a), None)
            nxt = next((s for s in stances[side] if s.start == b), None)
            p0 = prev.ankle[-1] if prev else na[a]
            p1 = nxt.ankle[0] if nxt else p0
            u = (np.arange(a, b) - a + 1.0) / (b - a + 1.0)
            na[a:b] = p0 + np.outer(u, p1 - p0)
            na[a:b, 2] += 0.06 * lift_s[side][a:b]
    root_rot = heading.copy()
    # root height: legs at the nominal 5 deg knee flexion over the stance feet
    z = np.full(frames, np.inf)
    for side in C.SIDES:
        chain = C.leg_chain(skeleton, side)
        d_nom = np.linalg.norm(chain.u + rot_x(np.radians(5.0) - info.rest_knee[side]) @ chain.w)
        hip_off = np.einsum("fij,j->fi", root_rot, chain.hip_offset)
        for st in stances[side]:
            sl = slice(st.start, st.stop)
            r = st.ankle - (np.column_stack([xy[sl], np.zeros(st.stop - st.start)]) + hip_off[sl])
            horiz = np.maximum(d_nom**2 - r[:, 0] ** 2 - r[:, 1] ** 2, 0.0)
            z[sl] = np.minimum(z[sl], st.ankle[:, 2] - hip_off[sl, 2] + np.sqrt(horiz))
    z = np.where(np.isfinite(z), z, hips[2])
    z = gaussian_filter1d(z, 1.0, mode="nearest") - 0.002 * breath
    root_pos = np.column_stack([xy, z])
    root_pos[:, 2] -= _reach_drop(skeleton, stances, root_pos, root_rot, frames)
    for side in C.SIDES:
        j = ix[f"{side}Foot"]
        targets = C.swing_targets(
            ground, feet[side], stances[side], nominal_ankle[side], rot_z(foot_yaw[side]), np.zeros(frames)
        )
        chain = C.leg_chain(skeleton, side)
        hip, knee, ankle, toe = C.leg_ik(chain, root_pos, root_rot, local[:, chain.hip], targets)
        local[:, chain.hip], local[:, chain.knee] = hip, knee
        local[:, chain.ankle], local[:, chain.toe] = ankle, toe
    # upper body: breathing (chest and shoulders rise), relaxed arms, a slow head drift
    for name, w in (("LowerBack", 0.3), ("Spine", 0.35), ("Spine1", 0.35)):
        local[:, ix[name]] = rot_x(w * lean)
    local[:, ix["Spine"]] = local[:, ix["Spine"]] @ rot_x(-np.radians(0.4) * breath)
    local[:, ix["Spine1"]] = local[:, ix["Spine1"]] @ rot_x(-np.radians(0.8) * breath)
    head_yaw = np.radians(2.0) * np.sin(2 * np.pi * 0.05 * t + rng.uniform(0, 2 * np.pi))
    local[:, ix["Neck"]] = rot_z(0.5 * head_yaw) @ rot_x(-0.5 * lean)
    local[:, ix["Head"]] = rot_z(0.5 * head_yaw) @ rot_x(-0.3 * lean)
    for side in C.SIDES:
        sign = 1.0 if side == "Left" else -1.0
        local[:, ix[f"{side}Shoulder"]] = rot_y(-sign * np.radians(0.8) * breath)
        add = info.arm_rest_abd[side] - STAND_ARM_ABDUCTION
        local[:, ix[f"{side}Arm"]] = rot_x(-np.radians(2.0) * breath) @ rot_y(sign * add)
        local[:, ix[f"{side}ForeArm"]] = axis_angle_matrix(
            info.elbow_axis[side], np.radians(15.0) - info.elbow_rest[side]
        )
    local[:, 0] = root_rot
    quats, root, report = _finish(skeleton, ground, feet, local, root_pos, stance, slice(0, frames))
    extra = {
        "breath_rate_hz": rate,
        "stance": {s.lower(): m for s, m in stance.items()},
        "stepping": stepping,
        "sway_rms_m": {"ap": sway_rms[0], "ml": sway_rms[1]},
    }
    return quats, root, report, extra


# ------------------------------------------------------------------------- poses
def _pose_motion(activity, skeleton, fps, frames, path, ground, feet, mass_kg, body_points) -> Motion:
    """A pose activity of :mod:`humv_usd.human.poses`, started at the path's first point and
    facing its first segment (as the standing activities); below ``SIM_FPS_MIN`` simulated at
    k * fps and every k-th frame kept (the rolling root and the planted feet work frame to
    frame: a 2 fps fall ended 30 cm from the 30 fps one)."""
    k = max(int(np.ceil(SIM_FPS_MIN / fps - 1e-9)), 1)
    if k > 1:
        m = _pose_motion(
            activity, skeleton, k * float(fps), (frames - 1) * k + 1, path, ground, feet, mass_kg, body_points
        )
        keep = slice(0, None, k)
        quats, root = _continuous(m.local_rotations[keep]), m.root_translation[keep]
        stance = {s: v[keep] for s, v in m.gait["stance"].items()}
        rot = quat_to_matrix(quats)
        wrot, wpos = fk_matrices(skeleton, rot, rot[:, 0], root)
        pts = PO.body_points(skeleton, body_points)
        chair = m.gait["chair"]
        g = C.Ground(PO._with_box(ground, chair)) if chair is not None else ground
        report = PO.body_contact_report(g, pts.posed(wrot, wpos, skeleton), float(fps))
        report.update(C.contact_report(g, feet, wrot, wpos, {s: stance[s.lower()] for s in C.SIDES}))
        report["body_max_penetration_m"] = report.pop("body_penetration_m")
        info = dict(m.gait, stance=stance)
        return Motion(float(fps), root, quats, activity, m.metabolic_rate_w[keep], report, info)
    start = skeleton.rest_positions[0, :2].copy()
    psi0 = 0.0
    if path is not None:
        w = np.asarray(path, dtype=np.float64)
        start = w[0].copy()
        if len(w) > 1:
            d = w[1] - w[0]
            psi0 = float(np.arctan2(d[0], -d[1]))
    out = PO.make_pose_motion(
        activity,
        skeleton,
        fps,
        frames,
        start_xy=start,
        heading=psi0,
        ground=ground,
        feet=feet,
        points=PO.body_points(skeleton, body_points),
    )
    quats = _continuous(matrix_to_quat(out["local"]))
    info = {
        "stance": {s.lower(): m for s, m in out["pinned"].items()},
        "keys": out["keys"],
        "transition_start_s": out["transition_start_s"],
        "chair": out["chair"],
        "source": "procedural key poses (humv_usd.human.poses)",
    }
    rate = met_to_watts(out["met"], mass_kg)
    return Motion(float(fps), out["root"], quats, activity, rate, out["report"], info)


# ------------------------------------------------------------------------- resampling
#: Lowest simulation rate [frames/s] of the walk, run, carry and standing activities. The
#: simulation works per frame (stance runs of consecutive frames, finite differences of the
#: stance pivots, flight parabolas between stance frames, reach smoothing over frames): at
#: 2 fps a walking swing (~0.4 s) falls between two frames, two stances of a foot merge into
#: one planted for more than a stride, and the pelvis is lowered ~0.8 m to reach it. Below
#: this rate a clip is simulated at the smallest integer multiple of its rate >= this one and
#: every k-th frame kept: at 1, 2, 3, 5, 6, 10 and 15 fps that is the 30 fps (default) motion.
SIM_FPS_MIN = 30.0


def _decimate(k: int, quats, root, info, frames) -> tuple:
    """Every ``k``-th frame of a simulated clip (``frames`` of them), its gait info arrays
    likewise. The contact report stays the simulated clip's (every simulated frame): measured on
    the kept frames, a foot's stances merged into one where a swing falls between two kept frames
    (a 1 fps walk reported 4.6 m of slip)."""
    n = len(root)
    keep = slice(0, (frames - 1) * k + 1, k)
    out = {}
    for key, val in info.items():
        if isinstance(val, dict):
            out[key] = {s: v[keep] if np.ndim(v) and len(v) == n else v for s, v in val.items()}
        else:
            out[key] = val[keep] if np.ndim(val) and len(val) == n else val
    return _continuous(quats[keep]), root[keep], out


# ------------------------------------------------------------------------- entry point
def make_motion(
    activity: str,
    skeleton: Skeleton,
    fps: float,
    frame_count: int,
    speed_m_s: float | None = None,
    path=None,
    ground=None,
    mass_kg: float = 75.0,
    *,
    body_points: np.ndarray | None = None,
    start_phase: float = 0.0,
    turn_deg: float = 180.0,
    turn_duration_s: float | None = None,
    exercise_met: float = 10.0,
    time_since_exercise_s: float = 0.0,
    seed: int = 0,
) -> Motion:
    """Synthesize ``frame_count`` frames at ``fps`` of ``activity`` (one of ACTIVITIES).

    speed_m_s: walk (default 1.4, 0.3-2.2) or run (default 3.5, 1.8-6.0) speed [m/s];
    path: Hips ground-track waypoints (N, 2) [m] in the avatar frame, walked at the speed
    from the first point, corners rounded over ~0.4 m, continued straight beyond the last
    point (default: straight ahead along -Y from the rest position); standing activities
    stand at its first point facing its first segment; ground: None (flat z = 0), callable
    height(x, y) (vectorized) or trimesh.Trimesh, in the avatar frame, covering the track and
    a stride beyond its ends (outside a mesh the nearest vertex's height is used); mass_kg:
    for the metabolic rate; body_points: the fitted body's FULL vertex list (``Body.points``)
    to use its sole vertices as contact points (default: points derived from the foot
    joints); start_phase: left-leg gait phase at frame 0 (0 = left heel strike);
    turn_deg/turn_duration_s: standTurn's turn (+ = to the left, counter-clockwise seen from
    above; starts after min(0.5 s, 10 % of the clip)) and its duration (default 1 s per
    60 deg, stepping each foot once per 60 deg); exercise_met and time_since_exercise_s: the
    effort postExercise recovers from; seed: sway and breathing phases.

    ``Motion.contact`` is the :func:`contact.contact_report` of the clip; ``Motion.gait``
    holds cadence, step length, duty factor, per-frame gait phase, stance masks ("left",
    "right"), grade, breathing rate etc. as applicable.
    """
    if activity not in ACTIVITIES:
        raise InputError(bad_value("activity", activity, f"expected one of {list(ACTIVITIES)}"))
    if activity == "carry":  # walking with a box held in front in both hands
        walk = make_motion(
            "walk",
            skeleton,
            fps,
            frame_count,
            DEFAULT_SPEED["carry"] if speed_m_s is None else speed_m_s,
            path,
            ground,
            mass_kg,
            body_points=body_points,
            start_phase=start_phase,
            seed=seed,
        )
        return replace(apply_box_carry(walk, skeleton), activity="carry")
    frames = int(frame_count)
    if frames < 2 or not fps > 0:
        raise InputError(
            bad_value("frame_count/fps", (frame_count, fps), "expected >= 2 frames at a positive fps")
        )
    feet = (
        C.foot_points_from_body(skeleton, body_points)
        if body_points is not None
        else C.foot_points_from_joints(skeleton)
    )
    g = C.Ground(ground)
    times = np.arange(frames) / fps
    if activity in PO.POSE_ACTIVITIES:
        return _pose_motion(activity, skeleton, fps, frames, path, g, feet, mass_kg, body_points)
    # below SIM_FPS_MIN: simulated at k * fps >= SIM_FPS_MIN, every k-th frame kept
    k = max(int(np.ceil(SIM_FPS_MIN / fps - 1e-9)), 1)
    sim_fps, sim_frames = k * float(fps), (frames - 1) * k + 1
    if activity in ("walk", "run"):
        v = DEFAULT_SPEED[activity] if speed_m_s is None else float(speed_m_s)
        lo, hi = SPEED_RANGE[activity]
        if not lo <= v <= hi:
            raise InputError(bad_value("speed_m_s", v, f"{activity} speed must be in {lo}..{hi} m/s"))
        start = skeleton.rest_positions[0, :2]
        quats, root, report, info = _locomotion(
            activity, skeleton, sim_fps, sim_frames, v, Path(path, start), g, feet, start_phase
        )
        if k > 1:
            quats, root, info = _decimate(k, quats, root, info, frames)
        rate = metabolic_rate(activity, mass_kg, times, v, info["grade"])
    else:
        quats, root, report, info = _standing(
            activity,
            skeleton,
            sim_fps,
            sim_frames,
            path,
            g,
            feet,
            seed,
            turn_deg,
            turn_duration_s,
            exercise_met,
            time_since_exercise_s,
        )
        if k > 1:
            quats, root, info = _decimate(k, quats, root, info, frames)
        rate = metabolic_rate(
            activity,
            mass_kg,
            times,
            exercise_met=exercise_met,
            time_since_exercise_s=time_since_exercise_s,
            stepping=info.get("stepping"),
        )
    return Motion(float(fps), root, quats, activity, rate, report, info)

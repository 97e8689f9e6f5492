"""Gait data and the nominal (flat-ground, straight-line) gait kinematics of the avatar.

Everything here is in the *body frame*: the avatar frame of :mod:`humv_usd.human.skeleton`
(+Z up, the body faces -Y, +X is the person's left) with the root (Hips) at the origin and no
heading. :mod:`humv_usd.human.motion` places it on a path and :mod:`humv_usd.human.contact`
plants the feet on the ground.

Sign conventions (rest frames are world-aligned, see ``skeleton``): a rotation about -X swings
a downward bone forward (-Y) and lifts a forward-pointing bone (toes up). So, in degrees,

* hip flexion ``h`` (+ = thigh forward of the vertical) -> thigh local rotation R_x(-(h - h0));
* knee flexion ``k`` (+ = shank behind the thigh)        -> shank local rotation R_x(+(k - k0));
* ankle dorsiflexion ``a`` (+ = toes up)                  -> foot pitch relative to the ground
  ``p = h - k + a`` (+ = toes up; exact for the sagittal-plane chain, pelvis level);
* h0, k0 are the rest (A-pose) angles measured on the rig; the rest ankle angle is the forward
  lean of the shank, so the rest foot is flat (p = 0) by construction.

Normative joint angles (one gait cycle from initial contact (IC) of the same foot, degrees).
The tables are key points read off published mean curves (accurate to ~2 deg) and joined by a
periodic cubic spline:

* walking (self-selected speed, adults): hip = thigh angle to the vertical, knee and ankle
  from Winter, D. A. (2009) *Biomechanics and Motor Control of Human Movement*, 4th ed., Wiley,
  ch. 5 and Appendix A, and Perry, J. & Burnfield, J. M. (2010) *Gait Analysis: Normal and
  Pathological Function*, 2nd ed., SLACK (thigh: ~22 deg flexion at IC, ~18 deg "apparent
  hyperextension" in terminal stance at ~55 %, ~24 deg peak in late swing; knee: ~18 deg
  loading flexion at ~14 %, ~40 deg at toe-off 62 %, 60-62 deg peak at ~73 %; ankle: ~6 deg
  plantarflexion in loading, ~10 deg dorsiflexion in terminal stance, ~18 deg plantarflexion
  just after toe-off, neutral by mid-swing). The hip amplitude is then scaled to the stride
  length the cadence law asks for (``hip_scale``, ~1.05 at 1.4 m/s for a 1.78 m man).
* running (~3-4 m/s, rear-foot strike): Novacheck, T. F. (1998) The biomechanics of running,
  *Gait & Posture* 7:77-95 (toe-off at ~39 % of the cycle, knee ~40 deg at mid-stance and
  ~90 deg in swing, ankle ~20 deg dorsiflexion at mid-stance and ~20 deg plantarflexion at
  toe-off, thigh from ~-15 deg at toe-off to ~40 deg in late swing); with the hip scaled to
  the stride length as for walking.

The stance foot's pitch follows the tables except in the foot-flat window (``GaitTable.flat``,
loading response to heel rise), where it is held flat; the tables are not exactly closed there.

Pelvis and trunk: rotation +-4 deg, obliquity +-4 deg, tilt +-1.5 deg at self-selected speed
(Perry & Burnfield 2010, ch. 9; Kadaba, Ramakrishnan & Wootten 1990, *J Orthop Res*
8:383-392); thorax counter-rotates (Perry & Burnfield 2010). Arm swing: shoulder ~30 deg total
excursion at free speed, maximal flexion near contralateral IC, elbow flexing with forward swing
(Murray, Sepic & Barnard 1967, *Phys Ther* 47:272-284).

Spatio-temporal relations (see :func:`walk_stride`, :func:`run_stride`):

* walking: stride length S = 1.60 L (v_hat / 0.459)^0.42 with leg length L (hip-joint height),
  Froude speed v_hat = v / sqrt(g L). The exponent is Grieve & Gear's (1966, *Ergonomics*
  9:379-399; Grieve 1968) stride-length/speed power law; the factor puts a 0.91 m leg at
  Perry & Burnfield's mean adult free walk (1.37 m/s, 113 steps/min, 1.46 m strides).
  Stance fraction 0.615 - 0.035 (v - 1.37), clipped to 0.57..0.66 (it shortens with speed,
  e.g. Andriacchi, Ogle & Galante 1977 *J Biomech* 10:261-268).
* running: cadence 142 + 8 v steps/min (v in m/s): ~167 at 3.15 m/s rising ~4-5 % to 4.12
  m/s, as in Cavanagh & Kram (1989, *Med Sci Sports Exerc* 21:467-479: stride frequency nearly
  constant, stride length +28 %); stance fraction 0.39 at 3.2 m/s (Novacheck 1998) falling to
  0.33 at 5 m/s.
* mediolateral pelvis sway +-3.5 cm at 0.7 m/s falling to +-2 cm at 1.6 m/s (Orendurff et al.
  2004, *J Rehabil Res Dev* 41:829-834); vertical excursion is not imposed -- it follows from
  the leg kinematics and the ground contact.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.interpolate import CubicSpline

from humv_usd.human.skeleton import Skeleton

G = 9.81

# ------------------------------------------------------------------------- rotations
# Quaternions are (w, x, y, z), unit, active; matrices act on column vectors.


def rot_x(a) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def rot_y(a) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def rot_z(a) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def axis_angle_matrix(axis, angle) -> np.ndarray:
    """Rotation matrices about a fixed unit ``axis`` (3,) by ``angle`` (...,) [rad]."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    a = np.asarray(angle, dtype=np.float64)[..., None, None]
    return np.eye(3) + np.sin(a) * kx + (1 - np.cos(a)) * (kx @ kx)


def axis_angle_quat(axis, angle) -> np.ndarray:
    """Unit quaternions (..., 4) (w, x, y, z) about a fixed ``axis`` (3,) by ``angle`` (...,) [rad]."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    half = np.asarray(angle, dtype=np.float64)[..., None] / 2.0
    return np.concatenate([np.cos(half), np.sin(half) * k], axis=-1)


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions (w, x, y, z), w >= 0."""
    m = np.asarray(m, dtype=np.float64)
    shape = m.shape[:-2]
    m = m.reshape(-1, 3, 3)
    t = np.einsum("nii->n", m)
    cand = np.stack(
        [
            np.stack([1 + t, m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]], -1),
            np.stack(
                [
                    m[:, 2, 1] - m[:, 1, 2],
                    1 + 2 * m[:, 0, 0] - t,
                    m[:, 0, 1] + m[:, 1, 0],
                    m[:, 0, 2] + m[:, 2, 0],
                ],
                -1,
            ),
            np.stack(
                [
                    m[:, 0, 2] - m[:, 2, 0],
                    m[:, 0, 1] + m[:, 1, 0],
                    1 + 2 * m[:, 1, 1] - t,
                    m[:, 1, 2] + m[:, 2, 1],
                ],
                -1,
            ),
            np.stack(
                [
                    m[:, 1, 0] - m[:, 0, 1],
                    m[:, 0, 2] + m[:, 2, 0],
                    m[:, 1, 2] + m[:, 2, 1],
                    1 + 2 * m[:, 2, 2] - t,
                ],
                -1,
            ),
        ],
        1,
    )  # (n, 4, 4)
    diag = np.stack([t, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], -1)
    best = np.argmax(diag, axis=1)  # Shepperd's choice
    q = cand[np.arange(len(m)), best]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q.reshape(*shape, 4)


def quat_slerp(q0: np.ndarray, q1: np.ndarray, t) -> np.ndarray:
    """Spherical linear interpolation (shortest arc), broadcasting over leading axes."""
    q0 = np.asarray(q0, dtype=np.float64)
    q1 = np.asarray(q1, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)[..., None]
    d = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(d < 0, -q1, q1)
    d = np.abs(d)
    theta = np.arccos(np.clip(d, -1.0, 1.0))
    s = np.sin(theta)
    small = s < 1e-8
    safe = np.where(small, 1.0, s)
    w0 = np.where(small, 1 - t, np.sin((1 - t) * theta) / safe)
    w1 = np.where(small, t, np.sin(t * theta) / safe)
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def align_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 3, 3) minimal rotations taking directions ``a`` to ``b`` (not antiparallel)."""
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    v = np.cross(a, b)
    c = np.sum(a * b, axis=-1)[..., None, None]
    z = np.zeros(v.shape[:-1])
    k = np.stack(
        [
            np.stack([z, -v[..., 2], v[..., 1]], -1),
            np.stack([v[..., 2], z, -v[..., 0]], -1),
            np.stack([-v[..., 1], v[..., 0], z], -1),
        ],
        -2,
    )
    return np.eye(3) + k + (k @ k) / np.maximum(1.0 + c, 1e-9)


def yaw_of(m: np.ndarray) -> np.ndarray:
    """Heading angle [rad] of rotation(s) ``m``: the rotation about +Z that takes the rest
    forward axis (-Y) to the horizontal projection of ``m @ -Y``."""
    f = -m[..., :, 1]
    return np.arctan2(f[..., 0], -f[..., 1])


def fk_matrices(
    skeleton: Skeleton, local: np.ndarray, root_rotation: np.ndarray, root_translation: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """World rotations (F, J, 3, 3) and positions (F, J, 3) from local rotation matrices
    (F, J, 3, 3); the root's local entry is ignored in favour of ``root_rotation`` (F, 3, 3)."""
    frames, joints = local.shape[:2]
    rot = np.empty((frames, joints, 3, 3))
    pos = np.empty((frames, joints, 3))
    t = skeleton.rest_local_translations
    for j in range(joints):
        p = skeleton.parents[j]
        if p < 0:
            rot[:, j] = root_rotation
            pos[:, j] = root_translation
        else:
            rot[:, j] = rot[:, p] @ local[:, j]
            pos[:, j] = rot[:, p] @ t[j] + pos[:, p]
    return rot, pos


# ------------------------------------------------------------------------- data
@dataclass(frozen=True)
class GaitTable:
    """Normative sagittal angles over one cycle (percent -> degrees) of one gait mode."""

    name: str
    toe_off_pct: float  # stance fraction of the source data [%]
    hip: tuple  # ((pct, deg), ...) thigh angle to the vertical
    knee: tuple
    ankle: tuple
    flat: tuple  # (start, full, end-full, end) foot-flat window [%]
    source: str


WALK = GaitTable(
    name="walk",
    toe_off_pct=62.0,
    hip=(
        (0, 22),
        (8, 21),
        (15, 17),
        (30, 3),
        (42, -10),
        (50, -17),
        (55, -18),
        (62, -12),
        (70, 2),
        (80, 18),
        (87, 24),
        (94, 23.5),
        (100, 22),
    ),
    knee=(
        (0, 4),
        (6, 12),
        (14, 18),
        (25, 11),
        (35, 5),
        (42, 4),
        (50, 10),
        (56, 24),
        (62, 40),
        (68, 56),
        (73, 61),
        (80, 52),
        (87, 30),
        (93, 11),
        (100, 4),
    ),
    ankle=(
        (0, 0),
        (6, -6),
        (12, -2),
        (25, 5),
        (40, 9),
        (48, 10),
        (54, 4),
        (58, -6),
        (62, -16),
        (66, -18),
        (72, -9),
        (78, -3),
        (85, 1),
        (92, 1.5),
        (100, 0),
    ),
    flat=(6, 12, 30, 40),
    source="Winter (2009) ch. 5/App. A; Perry & Burnfield (2010) ch. 4-6 (key points, +-2 deg)",
)

RUN = GaitTable(
    name="run",
    toe_off_pct=39.0,
    hip=(
        (0, 28),
        (10, 20),
        (20, 8),
        (30, -6),
        (39, -15),
        (45, -16),
        (52, -8),
        (60, 8),
        (70, 26),
        (80, 40),
        (87, 42),
        (94, 36),
        (100, 28),
    ),
    knee=(
        (0, 18),
        (8, 32),
        (15, 40),
        (25, 30),
        (35, 18),
        (39, 17),
        (45, 25),
        (55, 55),
        (65, 85),
        (72, 92),
        (80, 75),
        (88, 45),
        (95, 25),
        (100, 18),
    ),
    ankle=(
        (0, 3),
        (7, 12),
        (15, 20),
        (25, 14),
        (33, -5),
        (39, -20),
        (45, -22),
        (55, -10),
        (65, 2),
        (75, 8),
        (85, 7),
        (95, 4),
        (100, 3),
    ),
    flat=(4, 8, 13, 18),
    source="Novacheck (1998) Gait & Posture 7:77-95, running (key points, +-3 deg)",
)

TABLES = {"walk": WALK, "run": RUN}


@lru_cache(maxsize=16)
def _spline(table: str, joint: str) -> CubicSpline:
    pts = np.asarray(getattr(TABLES[table], joint), dtype=np.float64)
    return CubicSpline(pts[:, 0] / 100.0, pts[:, 1], bc_type="periodic")


def table_curve(table: str, joint: str, phase_ref) -> np.ndarray:
    """Normative angle [deg] at reference phase(s) in [0, 1) (data's own stance fraction)."""
    return _spline(table, joint)(np.mod(phase_ref, 1.0))


def warp_phase(phase, duty: float, toe_off_ref: float) -> np.ndarray:
    """Map a gait phase with stance fraction ``duty`` onto the data's phase (toe-off at
    ``toe_off_ref``), piecewise linear in stance and in swing."""
    p = np.mod(phase, 1.0)
    return np.where(
        p < duty, p * toe_off_ref / duty, toe_off_ref + (p - duty) * (1 - toe_off_ref) / (1 - duty)
    )


def smoothstep(x) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


# ------------------------------------------------------------------------- spatio-temporal
def leg_length(skeleton: Skeleton) -> float:
    """Hip-joint height at rest [m] (mean of both sides): the leg length of the gait laws."""
    return float(
        np.mean([skeleton.rest_positions[skeleton.index(n), 2] for n in ("LeftUpLeg", "RightUpLeg")])
    )


def walk_stride(speed: float, leg: float) -> tuple[float, float]:
    """(stride length [m], stride frequency [Hz]) of walking at ``speed`` [m/s]; see the
    module docstring (Grieve & Gear 1966 exponent, Perry & Burnfield 2010 anchor)."""
    v_hat = speed / np.sqrt(G * leg)
    stride = 1.60 * leg * (v_hat / 0.459) ** 0.42
    return float(stride), float(speed / stride)


def walk_duty(speed: float) -> float:
    return float(np.clip(0.615 - 0.035 * (speed - 1.37), 0.57, 0.66))


def run_stride(speed: float, leg: float) -> tuple[float, float]:
    """(stride length [m], stride frequency [Hz]) of running (Cavanagh & Kram 1989)."""
    cadence = float(np.clip(142.0 + 8.0 * speed, 150.0, 200.0))  # steps/min
    freq = cadence / 120.0
    return speed / freq, freq


def run_duty(speed: float) -> float:
    return float(np.interp(speed, [2.0, 3.2, 5.0], [0.42, 0.39, 0.33]))


# ------------------------------------------------------------------------- gait parameters
@dataclass(frozen=True)
class GaitParams:
    """Everything the nominal gait needs besides the clock; see :func:`gait_params`."""

    mode: str  # "walk" | "run"
    speed: float  # [m/s]
    stride_length: float  # [m]
    frequency: float  # stride frequency [Hz]
    duty: float  # stance fraction
    hip_scale: float  # sagittal hip amplitude factor (calibrated to the stride length)
    knee_stance_scale: float
    half_width: float  # foot (ankle) distance from the line of progression [m]
    pelvis_rotation: float  # amplitudes [rad]
    pelvis_obliquity: float
    pelvis_tilt: float
    thorax_rotation: float
    trunk_lean: float  # [rad], forward
    lateral_sway: float  # [m] amplitude of the pelvis' side-to-side motion
    shoulder_mean: float  # [rad] flexion
    shoulder_amp: float
    elbow_mean: float  # [rad] anatomical elbow flexion
    elbow_amp: float
    arm_abduction: float  # [rad] arm angle from the vertical in the frontal plane

    @property
    def cadence(self) -> float:
        return 120.0 * self.frequency

    @property
    def step_length(self) -> float:
        return self.stride_length / 2.0


def gait_params(mode: str, speed: float, skeleton: Skeleton) -> GaitParams:
    """Speed-dependent gait parameters (``hip_scale`` 1: see ``motion.calibrated_params``).

    Walking amplitudes scale with r = speed / 1.37 m/s from their self-selected values:
    pelvic rotation 4 deg (r^0.8), obliquity 4 deg (r^0.5), thorax counter-rotation 3 deg,
    arm swing +-15 deg (r^0.8), elbow +-8 deg; loading-response knee flexion r^0.6;
    mediolateral sway from Orendurff et al. (2004). Running: Novacheck (1998) pelvis
    (+-6 deg), forward trunk lean ~6 deg, elbows ~85 deg, arm swing growing with speed.
    """
    leg = leg_length(skeleton)
    if mode == "walk":
        stride, freq = walk_stride(speed, leg)
        r = speed / 1.37
        return GaitParams(
            mode=mode,
            speed=speed,
            stride_length=stride,
            frequency=freq,
            duty=walk_duty(speed),
            hip_scale=1.0,
            knee_stance_scale=float(np.clip(r**0.6, 0.5, 1.35)),
            half_width=0.05,
            pelvis_rotation=np.radians(np.clip(4.0 * r**0.8, 2.0, 8.0)),
            pelvis_obliquity=np.radians(np.clip(4.0 * r**0.5, 2.0, 6.0)),
            pelvis_tilt=np.radians(1.5),
            thorax_rotation=np.radians(np.clip(3.0 * r, 1.5, 6.0)),
            trunk_lean=np.radians(2.0 + 2.0 * max(speed - 1.0, 0.0)),
            lateral_sway=float(np.clip(0.035 - 0.017 * (speed - 0.7), 0.01, 0.04)),
            shoulder_mean=np.radians(-6.0),
            shoulder_amp=np.radians(np.clip(15.0 * r**0.8, 5.0, 30.0)),
            elbow_mean=np.radians(25.0 + 5.0 * max(r - 1.0, 0.0)),
            elbow_amp=np.radians(np.clip(8.0 * r, 3.0, 15.0)),
            arm_abduction=np.radians(9.0),
        )
    if mode == "run":
        stride, freq = run_stride(speed, leg)
        return GaitParams(
            mode=mode,
            speed=speed,
            stride_length=stride,
            frequency=freq,
            duty=run_duty(speed),
            hip_scale=1.0,
            knee_stance_scale=1.0,
            half_width=0.03,
            pelvis_rotation=np.radians(6.0),
            pelvis_obliquity=np.radians(6.0),
            pelvis_tilt=np.radians(2.5),
            thorax_rotation=np.radians(5.0),
            trunk_lean=np.radians(6.0 + 1.5 * (speed - 3.0)),
            lateral_sway=0.012,
            shoulder_mean=np.radians(-10.0),
            shoulder_amp=np.radians(np.clip(20.0 + 4.0 * speed, 20.0, 45.0)),
            elbow_mean=np.radians(85.0),
            elbow_amp=np.radians(12.0),
            arm_abduction=np.radians(12.0),
        )
    raise ValueError(f"unknown gait mode {mode!r}")


# ------------------------------------------------------------------------- rig geometry
@dataclass(frozen=True)
class RigInfo:
    """Rest-pose quantities of a skeleton the gait code needs (per side 'Left'/'Right')."""

    index: dict
    rest_hip: dict  # rest anatomical hip flexion [rad] (thigh to vertical)
    rest_knee: dict
    rest_abd: dict  # rest thigh abduction [rad] (ankle outward of the hip)
    arm_rest_abd: dict  # rest upper-arm angle from the vertical, frontal plane [rad]
    elbow_axis: dict  # (3,) unit flexion axis of the elbow at rest
    elbow_rest: dict  # rest anatomical elbow flexion [rad]


def _sag(v: np.ndarray) -> float:
    """Forward angle [rad] of a downward vector in the sagittal plane (+ = forward, -Y)."""
    return float(np.arctan2(-v[1], -v[2]))


_RIG_CACHE: dict[int, tuple[Skeleton, RigInfo]] = {}


def rig_info(skeleton: Skeleton) -> RigInfo:
    hit = _RIG_CACHE.get(id(skeleton))
    if hit is not None and hit[0] is skeleton:
        return hit[1]
    info = _rig_info(skeleton)
    if len(_RIG_CACHE) > 16:
        _RIG_CACHE.clear()
    _RIG_CACHE[id(skeleton)] = (skeleton, info)
    return info


def _rig_info(skeleton: Skeleton) -> RigInfo:
    s = skeleton
    idx = {n: i for i, n in enumerate(s.names)}
    P = s.rest_positions
    rest_hip, rest_knee, rest_abd, arm_abd, eax, erest = {}, {}, {}, {}, {}, {}
    for side in ("Left", "Right"):
        hip, knee, ankle = (P[idx[f"{side}UpLeg"]], P[idx[f"{side}Leg"]], P[idx[f"{side}Foot"]])
        thigh, shank = knee - hip, ankle - knee
        rest_hip[side] = _sag(thigh)
        rest_knee[side] = _sag(thigh) - _sag(shank)
        sign = 1.0 if side == "Left" else -1.0
        rest_abd[side] = float(np.arctan2(sign * (ankle - hip)[0], -(ankle - hip)[2]))
        sh, el, wr = P[idx[f"{side}Arm"]], P[idx[f"{side}ForeArm"]], P[idx[f"{side}Hand"]]
        upper, fore = el - sh, wr - el
        arm_abd[side] = float(np.arctan2(sign * upper[0], -upper[2]))
        ax = np.cross(upper, fore)
        eax[side] = ax / np.linalg.norm(ax)
        erest[side] = float(np.arccos(np.dot(upper, fore) / np.linalg.norm(upper) / np.linalg.norm(fore)))
    return RigInfo(idx, rest_hip, rest_knee, rest_abd, arm_abd, eax, erest)


# ------------------------------------------------------------------------- nominal gait
@dataclass(frozen=True)
class NominalGait:
    """Body-frame gait (root at the origin, no heading) sampled at given times.

    local: (F, J, 3, 3) local rotations (legs from the tables; the root entry is unused);
    pelvis: (F, 3, 3) root rotation (tilt, obliquity, rotation); root: (F, 3) root position
    (the mediolateral sway along x); phase: (F,) left-leg phase;
    per side ('Left'/'Right'): stance (F,) bool, load (F,) weight in [0, 1] of that foot
    while in stance, pitch (F,) target foot pitch to the ground [rad] (+ = toes up),
    toe (F,) toe extension [rad], yaw (F,) foot heading in the body frame [rad].
    """

    params: GaitParams
    local: np.ndarray
    pelvis: np.ndarray
    root: np.ndarray
    phase: np.ndarray
    stance: dict
    load: dict
    pitch: dict
    toe: dict
    yaw: dict


def _window(u, a, b, c, d) -> np.ndarray:
    """0 outside [a, d], 1 on [b, c], smooth ramps between (u, a..d in the same units)."""
    return smoothstep((u - a) / max(b - a, 1e-9)) * (1 - smoothstep((u - c) / max(d - c, 1e-9)))


def stance_load(phase, duty: float) -> np.ndarray:
    """Share of the body weight on a foot at its own gait phase(s): ramps up over the first
    double support, down over the last one (walking); 1 throughout stance when running."""
    p = np.mod(phase, 1.0)
    ds = duty - 0.5
    if ds <= 1e-6:
        return np.where(p < duty, 1.0, 0.0)
    up = smoothstep(p / ds)
    down = 1 - smoothstep((p - 0.5) / ds)
    return np.where(p < duty, np.minimum(up, down), 0.0)


def side_angles(params: GaitParams, phase) -> dict:
    """Sagittal hip, knee, ankle [deg], foot pitch [deg] and toe extension [deg] of one leg
    at its own phase(s); hip amplitude and knee loading flexion scaled per ``params``."""
    table = TABLES[params.mode]
    ref = warp_phase(phase, params.duty, table.toe_off_pct / 100.0)
    hip = table_curve(table.name, "hip", ref)
    hip_mean = _hip_mean(table.name)
    hip = hip_mean + params.hip_scale * (hip - hip_mean)
    knee = table_curve(table.name, "knee", ref)
    if params.knee_stance_scale != 1.0:
        base = min(v for _, v in table.knee)
        w = 1 - smoothstep((ref * 100 - 30.0) / 10.0)  # loading-response bump only
        knee = knee + (params.knee_stance_scale - 1.0) * (knee - base) * w
    ankle = table_curve(table.name, "ankle", ref)
    pitch = hip - knee + ankle
    p = np.mod(phase, 1.0)
    stance = p < params.duty
    f0, f1, f2, f3 = (x / table.toe_off_pct for x in table.flat)
    u = p / params.duty
    pitch = np.where(stance, pitch * (1 - _window(u, f0, f1, f2, f3)), pitch)
    # toes stay flat on the ground once the heel rises; they relax early in swing
    toe_stance = np.maximum(-pitch, 0.0)
    to_ref = table.toe_off_pct / 100.0
    hip_to = hip_mean + params.hip_scale * (table_curve(table.name, "hip", to_ref) - hip_mean)
    toe_at_off = max(
        -(hip_to - table_curve(table.name, "knee", to_ref) + table_curve(table.name, "ankle", to_ref)), 0.0
    )
    sw = (p - params.duty) / (1 - params.duty)
    toe_swing = toe_at_off * (1 - smoothstep(sw / 0.25))
    toe = np.where(stance, toe_stance, toe_swing)
    return {"hip": hip, "knee": knee, "ankle": ankle, "pitch": pitch, "toe": toe, "stance": stance}


@lru_cache(maxsize=4)
def _hip_peak_phase(table: str) -> float:
    """Phase of the maximum of the thigh curve's first harmonic."""
    x = np.linspace(0, 1, 400, endpoint=False)
    c = np.sum(table_curve(table, "hip", x) * np.exp(-2j * np.pi * x))
    return float(np.mod(-np.angle(c) / (2 * np.pi), 1.0))


@lru_cache(maxsize=4)
def _hip_mean(table: str) -> float:
    x = np.linspace(0, 1, 400, endpoint=False)
    return float(np.mean(table_curve(table, "hip", x)))


def nominal_gait(skeleton: Skeleton, params: GaitParams, phase: np.ndarray) -> NominalGait:
    """Body-frame local rotations and foot targets at left-leg phases ``phase`` (F,)."""
    info = rig_info(skeleton)
    ix = info.index
    F = len(phase)
    J = len(skeleton.names)
    local = np.tile(np.eye(3), (F, J, 1, 1))
    tau = 2 * np.pi
    gamma = -params.pelvis_rotation * np.cos(tau * phase)  # left side forward at IC
    beta = -params.pelvis_obliquity * np.cos(tau * (phase - 0.17))  # right side drops after IC
    alpha = params.pelvis_tilt * np.cos(2 * tau * (phase - 0.45))
    pelvis = rot_z(gamma) @ rot_y(beta) @ rot_x(alpha)
    sway = params.lateral_sway * np.cos(tau * (phase - 0.3))  # toward the stance foot
    stance, load, pitch, toe, yaw = {}, {}, {}, {}, {}
    for side, off in (("Left", 0.0), ("Right", 0.5)):
        ph = np.mod(phase + off, 1.0)  # right IC half a cycle after the left one
        a = side_angles(params, ph)
        sign = 1.0 if side == "Left" else -1.0
        hip_x = skeleton.rest_positions[ix[f"{side}UpLeg"]][0]
        leg = np.linalg.norm(
            skeleton.rest_positions[ix[f"{side}Foot"]] - skeleton.rest_positions[ix[f"{side}UpLeg"]]
        )
        # adduct the (rest-abducted) leg so the ankle runs at half_width from the midline
        want = np.arctan2(sign * params.half_width - hip_x, leg) * sign
        add = info.rest_abd[side] - want
        flex = np.radians(a["hip"]) - info.rest_hip[side]
        # the thigh's orientation is set in the body frame (the table's hip angle is the thigh
        # to the vertical); pelvic tilt, obliquity and rotation are absorbed at the hip. Both
        # legs lean with the pelvis' sway so the feet keep their lines.
        thigh = rot_x(-flex) @ rot_y(sign * add + sway / leg)
        local[:, ix[f"{side}UpLeg"]] = np.swapaxes(pelvis, -1, -2) @ thigh
        local[:, ix[f"{side}Leg"]] = rot_x(np.radians(a["knee"]) - info.rest_knee[side])
        stance[side] = a["stance"]
        load[side] = stance_load(ph, params.duty)
        pitch[side] = np.radians(a["pitch"])
        toe[side] = np.radians(a["toe"])
        yaw[side] = np.zeros(F)
        local[:, ix[f"{side}ToeBase"]] = rot_x(-toe[side])
    # trunk: undo pelvic tilt/obliquity, lean forward, counter-rotate the thorax
    spine = [("LowerBack", 0.3), ("Spine", 0.35), ("Spine1", 0.35)]
    twist = (params.pelvis_rotation + params.thorax_rotation) * np.cos(tau * phase)
    for name, w in spine:
        local[:, ix[name]] = rot_z(w * twist) @ rot_y(-w * beta) @ rot_x(w * (params.trunk_lean - alpha))
    thorax_yaw = params.thorax_rotation * np.cos(tau * phase)
    for name, w in (("Neck", 0.5), ("Neck1", 0.3), ("Head", 0.2)):
        local[:, ix[name]] = rot_z(-w * thorax_yaw) @ rot_x(-w * 0.8 * params.trunk_lean)
    # arms: adduct from the A-pose, swing opposite to the same-side leg: the shoulder is most
    # flexed half a cycle after the thigh's fundamental peak (i.e. with the other thigh)
    peak = _hip_peak_phase(params.mode) + 0.5 + 0.02
    for side, off in (("Left", 0.0), ("Right", 0.5)):
        sign = 1.0 if side == "Left" else -1.0
        add = info.arm_rest_abd[side] - params.arm_abduction
        flex = params.shoulder_mean + params.shoulder_amp * np.cos(tau * (phase - off - peak))
        local[:, ix[f"{side}Arm"]] = rot_x(-flex) @ rot_y(sign * add)
        elbow = params.elbow_mean + params.elbow_amp * np.cos(tau * (phase - off - peak - 0.03))
        local[:, ix[f"{side}ForeArm"]] = axis_angle_matrix(
            info.elbow_axis[side], elbow - info.elbow_rest[side]
        )
    root = np.zeros((F, 3))
    root[:, 0] = sway
    return NominalGait(params, local, pelvis, root, np.mod(phase, 1.0), stance, load, pitch, toe, yaw)


def set_ankles(skeleton: Skeleton, gait: NominalGait) -> None:
    """Fill the ankle local rotations of ``gait.local`` in place so that each foot has the
    body-frame orientation R_z(yaw) R_x(-pitch) (flat sole for pitch 0)."""
    ix = rig_info(skeleton).index
    rot, _ = fk_matrices(skeleton, gait.local, gait.pelvis, gait.root)
    for side in ("Left", "Right"):
        shank = rot[:, ix[f"{side}Leg"]]
        target = rot_z(gait.yaw[side]) @ rot_x(-gait.pitch[side])
        gait.local[:, ix[f"{side}Foot"]] = np.swapaxes(shank, -1, -2) @ target


# ------------------------------------------------------------------------- measurement
def sagittal_angles(skeleton: Skeleton, world_rot: np.ndarray, world_pos: np.ndarray) -> dict:
    """Anatomical sagittal angles [deg] measured on posed joints: hip (thigh to the pelvis
    vertical), knee (thigh minus shank), ankle (dorsiflexion; rest = forward lean of the
    shank) per side, all in the pelvis' sagittal plane; shoulder flexion in the thorax'
    (Spine1) sagittal plane. ``world_rot`` (F, J, 3, 3), ``world_pos`` (F, J, 3)."""
    ix = rig_info(skeleton).index
    out = {}
    pel = world_rot[:, ix["Hips"]]
    thx = world_rot[:, ix["Spine1"]]

    def in_frame(frame, v):
        return np.einsum("fji,fj->fi", frame, v)

    def sag(v):
        return np.degrees(np.arctan2(-v[:, 1], -v[:, 2]))

    for side in ("Left", "Right"):
        hip, knee, ankle, toe = (world_pos[:, ix[f"{side}{n}"]] for n in ("UpLeg", "Leg", "Foot", "ToeBase"))
        th = sag(in_frame(pel, knee - hip))
        sh = sag(in_frame(pel, ankle - knee))
        foot = in_frame(pel, toe - ankle)
        rest_foot = skeleton.rest_positions[ix[f"{side}ToeBase"]] - skeleton.rest_positions[ix[f"{side}Foot"]]
        fp = np.degrees(np.arctan2(foot[:, 2], -foot[:, 1]) - np.arctan2(rest_foot[2], -rest_foot[1]))
        out[f"{side}Hip"] = th
        out[f"{side}Knee"] = th - sh
        out[f"{side}Ankle"] = fp - sh
        sh_pos, el = world_pos[:, ix[f"{side}Arm"]], world_pos[:, ix[f"{side}ForeArm"]]
        out[f"{side}Shoulder"] = sag(in_frame(thx, el - sh_pos))
    return out

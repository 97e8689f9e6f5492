"""Motion sequences: a person who walks, stops and stands, sits down (or crouches, kneels, lies
down, waves, falls), gets up and walks on, along one path.

A sequence is a list of *segments* (the scenario's ``[[human.segment]]``): an activity, how long
it lasts (``duration_s``, or ``distance_m`` at ``speed_m_s`` for walking and running) and the
*transition* from the segment before (``transition_s``). The walking segments follow the
placement's path (its waypoints) one after the other: a stop ends a walk where the person is,
the next walk goes on from there along the rest of the path.

How the pieces are made and joined (:func:`make_sequence_motion`):

* a walking or running segment is the procedural gait of :mod:`humv_usd.human.motion` (stance
  feet planted by its lock), simulated over the segment and the transitions at its ends;
* the stationary segments between two walks are one run of the key-pose engine of
  :mod:`humv_usd.human.poses`: from standing, the activity's own transitions (e.g. stand ->
  crouch -> sit), held, and before the next segment the quickest chain of designed
  transitions to its pose (:func:`humv_usd.human.poses.route`: sit -> lie supine goes through
  hook lying; before a walk back up to standing, e.g. prone -> hands and knees -> kneeling ->
  standing); ``stand`` holds the standing key pose;
* a **stop** (walk -> standing) starts at the heel strike nearest the walk's end: the leading
  foot rolls onto its flat foot as in the gait and stays planted; the standing pose is placed
  so that its foot is exactly there (heading = the walk's mean heading); the trailing foot
  pushes off as in the gait, then swings (lifted 4 cm at mid-swing) to its place beside it;
* a **start** (standing -> walk) mirrors it: the gait is timed so that the left heel strikes
  at the end of the transition and placed so that the right foot's flat mid-stance is exactly
  the standing right foot (it stays planted and rolls off as in the gait); the left foot
  swings from the standing pose to its heel strike;
* over a transition window every joint rotation (the root's too) is blended from one motion to
  the other by quaternion slerp with a minimum-jerk weight (Flash & Hogan 1985, *J Neurosci*
  5:1688-1703); the root follows a cubic Hermite curve between the two motions' positions and
  velocities (continuous position and velocity; shortened where the walking speed would
  overshoot the standing position), and the legs are posed on the feet by the two-bone IK of
  :mod:`humv_usd.human.contact` (the root drops where a leg cannot reach).

The metabolic rate follows the segments: ACSM walking/running for the walks, the Compendium
values of :mod:`humv_usd.human.poses` for the poses and their transitions, blended linearly over
a transition window; after a walk the excess over standing decays as after exercise
(:data:`humv_usd.human.motion.EPOC`: 0.9 exp(-t/40 s) + 0.1 exp(-t/600 s) from the stop, Ozyener
et al. 2001, Borsheim & Bahr 2003), added to the poses' own rates. Below 30 fps the sequence is simulated at the smallest integer multiple of
the frame rate at or above it and every k-th frame kept (as the single activities).

Sources for the stop and start: gait termination takes one step after the decision to stop,
with the trailing foot brought beside the leading one (Jaeger & Vanitchatchavan 1992,
*J Biomech* 25:1233-1236; Tirosh & Sparrow 2004, *Gait Posture* 19:243-251); gait initiation
begins with a swing of one foot while the other stays planted (Brenière & Do 1986, *J Biomech*
19:1035-1040). Transition windows of 0.4-3 s: one step lasts ~0.5 s at 1.4 m/s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from humv_usd.errors import InputError, bad_value
from humv_usd.human import contact as C
from humv_usd.human import poses as PO
from humv_usd.human.carry import apply_box_carry
from humv_usd.human.gait import fk_matrices, gait_params, matrix_to_quat, quat_slerp, rot_z
from humv_usd.human.motion import (
    DEFAULT_SPEED,
    EPOC,
    MET_STAND,
    SIM_FPS_MIN,
    SPEED_RANGE,
    Motion,
    Path,
    _continuous,
    make_motion,
    met_to_watts,
)
from humv_usd.human.skeleton import Skeleton, quat_to_matrix
from humv_usd.scenario.spec import SEGMENT_ACTIVITIES, SEGMENT_TRANSITION_S, SEGMENT_WITH_BOX

#: activities a segment may have: walking, running and carrying along the path, and the
#: stationary ones (the scenario's keys: humv_usd.scenario.spec.SEGMENT_ACTIVITIES)
LOCOMOTION = ("walk", "run", "carry")
#: what a sequence that carries the box may do between its carries (the arms hold the box)
WITH_BOX = SEGMENT_WITH_BOX
#: a turn on the spot: at most this angle per pair of steps [deg], each pair taking this long
#: [s] (as the single activity standTurn: humv_usd.human.motion), the swinging foot lifted [m]
TURN_STEP_DEG = 60.0
TURN_PAIR_S = 1.0
TURN_LIFT_M = 0.05
STATIONARY = tuple(a for a in SEGMENT_ACTIVITIES if a not in LOCOMOTION)
#: transition window [s]: default and allowed range (humv_usd.scenario.spec.SEGMENT_TRANSITION_S)
DEFAULT_TRANSITION_S = 0.8
TRANSITION_RANGE_S = SEGMENT_TRANSITION_S
#: lift of the foot that swings in a stop or a start, at mid-swing [m]
STEP_LIFT_M = 0.04


@dataclass(frozen=True)
class Segment:
    activity: str
    duration_s: float | None = None
    distance_m: float | None = None
    speed_m_s: float | None = None
    transition_s: float = DEFAULT_TRANSITION_S
    turn_deg: float | None = None

    @property
    def speed(self) -> float:
        return DEFAULT_SPEED[self.activity] if self.speed_m_s is None else float(self.speed_m_s)


@dataclass
class _Clip:
    """A piece of motion whose frame 0 is the sequence's frame ``f0``; read with clamping."""

    f0: int
    local: np.ndarray  # (n, J, 3, 3), [:, 0] = root rotation
    root: np.ndarray  # (n, 3)
    met_w: np.ndarray  # (n,)
    stance: dict  # side -> (n,) bool
    skeleton: Skeleton
    _world: tuple | None = field(default=None, repr=False)

    def idx(self, f) -> np.ndarray:
        return np.clip(np.asarray(f) - self.f0, 0, len(self.root) - 1)

    def world(self) -> tuple[np.ndarray, np.ndarray]:
        if self._world is None:
            self._world = fk_matrices(self.skeleton, self.local, self.local[:, 0], self.root)
        return self._world

    def velocity(self, f: int, fps: float) -> np.ndarray:
        i = int(self.idx(f))
        a, b = max(i - 1, 0), min(i + 1, len(self.root) - 1)
        return (self.root[b] - self.root[a]) * fps / max(b - a, 1)


def segments_from(table: list) -> list[Segment]:
    """Segments from the scenario's ``human.segment`` tables (keys as :class:`Segment`)."""
    keys = ("activity", "duration_s", "distance_m", "speed_m_s", "transition_s", "turn_deg")
    out = []
    for t in table:
        kw = {k: t[k] for k in keys if t.get(k) is not None}
        out.append(Segment(**kw))
    return out


#: how deep [m] a body point may be inside the chair's seat box (the seated pose rests on it)
CHAIR_TOLERANCE_M = 0.01


def _check_chair(chair: dict, posed: np.ndarray, segs, where: str, fps: float) -> None:
    """One :class:`InputError` line if a body point (``posed`` (F, n, 3)) is ever deeper than
    :data:`CHAIR_TOLERANCE_M` inside the seat box of a sitChair segment's chair (authored for the
    whole clip: e.g. a walk up to it without a turn would pass through it)."""
    cx, cy, cz = chair["center_m"]
    w, d, h = chair["size_m"]
    c, s = np.cos(chair["yaw_rad"]), np.sin(chair["yaw_rad"])
    dx, dy = posed[..., 0] - cx, posed[..., 1] - cy
    u, v = c * dx + s * dy, -s * dx + c * dy
    depth = np.min([w / 2 - np.abs(u), d / 2 - np.abs(v), h / 2 - np.abs(posed[..., 2] - cz)], axis=0)
    inside = depth.max(axis=1) > CHAIR_TOLERANCE_M
    if inside.any():
        j = next(i for i, seg in enumerate(segs) if seg.activity == "sitChair")
        t = float(np.argmax(inside)) / fps
        raise InputError(
            bad_value(
                f"{where}[{j}].activity",
                "sitChair",
                f"its chair (there for the whole clip) stands where the body passes at {t:.1f} s: "
                "turn round first (a turn segment before it), then sit down",
            )
        )


def _gait_mode(activity: str) -> str:
    """The gait a locomotion segment walks (carry: the walk; the arms hold the box)."""
    return "walk" if activity == "carry" else activity


def _minjerk(x) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10 - 15 * x + 6 * x * x)


def _ramp(fr: np.ndarray, a: int, b: int) -> np.ndarray:
    return _minjerk((fr - a) / max(b - a, 1))


def make_sequence_motion(
    segments,
    skeleton: Skeleton,
    fps: float,
    frame_count: int,
    path=None,
    ground=None,
    mass_kg: float = 75.0,
    *,
    body_points: np.ndarray | None = None,
    seed: int = 0,
    where: str = "human.segment",
) -> Motion:
    """The motion of a sequence of segments (:class:`Segment` or the scenario's tables) over
    ``frame_count`` frames at ``fps``; ``path``, ``ground``, ``mass_kg``, ``body_points`` as
    :func:`humv_usd.human.motion.make_motion`. ``where`` names the segments in error messages
    (a segment too short for its transitions is one :class:`InputError` line)."""
    segs = [s if isinstance(s, Segment) else segments_from([s])[0] for s in segments]
    carries = any(s.activity == "carry" for s in segs)
    for j, s in enumerate(segs):
        if carries and s.activity not in WITH_BOX:
            raise InputError(
                bad_value(
                    f"{where}[{j}].activity",
                    s.activity,
                    "the hands hold the box of this sequence's carry: only " + ", ".join(WITH_BOX),
                )
            )
    frames = int(frame_count)
    if frames < 2 or not fps > 0:
        raise InputError(
            bad_value("frame_count/fps", (frame_count, fps), "expected >= 2 frames at a positive fps")
        )
    k = max(int(np.ceil(SIM_FPS_MIN / fps - 1e-9)), 1)
    sim = _Sequence(
        segs, skeleton, k * float(fps), (frames - 1) * k + 1, path, ground, mass_kg, body_points, seed, where
    )
    local, root, met, stance, info = sim.run()
    # the contact report on every simulated frame: on the kept ones a foot's stances a stride
    # apart merged into one (a 1 fps walk reported metres of slip)
    wrot, wpos = fk_matrices(skeleton, local, local[:, 0], root)
    report = C.contact_report(sim.ground, sim.feet, wrot, wpos, stance)
    if "chair" in info:  # the chair stands for the whole clip: nothing else may pass through it
        _check_chair(info["chair"], sim.points.posed(wrot, wpos, skeleton), segs, where, k * float(fps))
    keep = slice(0, None, k)
    local, root, met = local[keep], root[keep], met[keep]
    stance = {s: m[keep] for s, m in stance.items()}
    info["stance"] = {s.lower(): m for s, m in stance.items()}
    info["windows"] = [(kind, w0 / k, w1 / k) for kind, w0, w1 in info["windows"]]
    quats = _continuous(matrix_to_quat(local))
    motion = Motion(float(fps), root, quats, "sequence", met, report, info)
    # a sequence with carry holds the box in both hands throughout (standing, turning too)
    return apply_box_carry(motion, skeleton) if carries else motion


class _Sequence:
    def __init__(self, segs, skeleton, fps, frames, path, ground, mass_kg, body_points, seed, where):
        self.segs, self.sk, self.fps, self.F = segs, skeleton, fps, frames
        self.path, self.ground_src, self.mass, self.bp, self.seed, self.where = (
            path,
            ground,
            mass_kg,
            body_points,
            seed,
            where,
        )
        self.ground = C.Ground(ground)
        self.feet = (
            C.foot_points_from_body(skeleton, body_points)
            if body_points is not None
            else C.foot_points_from_joints(skeleton)
        )
        self.points = PO.body_points(skeleton, body_points)
        self.route = Path(path, skeleton.rest_positions[0, :2].copy())
        self.end_t = (frames - 1) / fps
        self.chair = None  # the seat box of a sitChair segment (poses._chair_box)

    # ------------------------------------------------------------------ timing
    def _bounds(self) -> list[float]:
        b = [0.0]
        for i, s in enumerate(self.segs):
            if s.duration_s is not None:
                d = s.duration_s
            elif s.distance_m is not None:
                d = s.distance_m / s.speed + (0.5 * s.transition_s if i > 0 else 0.0)
            else:
                d = np.inf
            b.append(b[-1] + d)
        return b

    def _blocks(self) -> list[tuple[str, list[int]]]:
        out: list[tuple[str, list[int]]] = []
        for i, s in enumerate(self.segs):
            kind = "loco" if s.activity in LOCOMOTION else "still"
            if kind == "loco" and out and out[-1][0] == "loco":
                raise InputError(
                    bad_value(
                        f"{self.where}[{i}].activity",
                        s.activity,
                        "a walk or run cannot follow another: put a stationary segment (e.g. stand) between",
                    )
                )
            if out and out[-1][0] == kind == "still":
                out[-1][1].append(i)
            else:
                out.append((kind, [i]))
        return out

    # ------------------------------------------------------------------ pieces
    def _walk(self, seg: Segment, f0: int, n: int, waypoints, start_phase: float) -> _Clip:
        m = make_motion(
            _gait_mode(seg.activity),
            self.sk,
            self.fps,
            max(n, 2),
            seg.speed,
            waypoints,
            self.ground_src,
            self.mass,
            body_points=self.bp,
            start_phase=start_phase,
            seed=self.seed,
        )
        local = quat_to_matrix(m.local_rotations)
        st = {s: m.gait["stance"][s.lower()] for s in C.SIDES}
        return _Clip(f0, local, m.root_translation.copy(), m.metabolic_rate_w, st, self.sk)

    def _still(self, f0: int, n: int, plan, start_xy, heading) -> _Clip:
        out = PO.make_pose_motion(
            "sequence",
            self.sk,
            self.fps,
            max(n, 2),
            start_xy=start_xy,
            heading=heading,
            ground=self.ground,
            feet=self.feet,
            points=self.points,
            start_s=0.0,
            plan=plan,
        )
        if out["chair"] is not None and self.chair is None:
            self.chair = out["chair"]
        return _Clip(
            f0, out["local"], out["root"], met_to_watts(out["met"], self.mass), out["pinned"], self.sk
        )

    def _ankle(self, clip: _Clip, side: str, f) -> np.ndarray:
        wrot, wpos = clip.world()
        return wpos[clip.idx(f), self.feet[side].foot]

    def _heading(self, clip: _Clip, f: int, half: int) -> float:
        """Mean heading of the root (rest facing -Y) over frames f +- half."""
        i = clip.idx(np.arange(f - half, f + half + 1))
        fwd = -clip.local[i, 0][:, :, 1]
        psi = np.unwrap(np.arctan2(fwd[:, 0], -fwd[:, 1]))
        return float(np.mean(psi))

    def _stand_foot_yaw(self, side: str) -> float:
        """The standing key pose's foot heading at root heading 0 [rad]."""
        root_rot, local = PO.key_rotations(self.sk, PO.STAND)
        wrot, _ = fk_matrices(self.sk, local[None], root_rot[None], np.zeros((1, 3)))
        return float(C._foot_yaw(self.feet[side], wrot[:, self.feet[side].foot])[0])

    def _stand_offset(self, side: str, heading: float) -> np.ndarray:
        """The standing key pose's ankle relative to its root, horizontally, at ``heading``."""
        root_rot, local = PO.key_rotations(self.sk, PO.STAND)
        local = local[None].copy()
        wrot, wpos = fk_matrices(self.sk, local, (rot_z(heading) @ root_rot)[None], np.zeros((1, 3)))
        return wpos[0, self.feet[side].foot, :2]

    # ------------------------------------------------------------------ the run
    def run(self):
        fps, F = self.fps, self.F
        bounds = self._bounds()
        blocks = self._blocks()
        # segments that start after the clip's end are not simulated (the one before lasts)
        blocks = [b for n, b in enumerate(blocks) if n == 0 or bounds[b[1][0]] < self.end_t]
        owners: list[tuple[int, _Clip]] = []  # (first global frame owned, clip)
        windows = []  # (kind, A, B, w0, w1, plans)
        prev: _Clip | None = None
        stop = None  # pending stop: (walk clip, w0, w1, lead side, mid frame)
        for bi, (kind, idxs) in enumerate(blocks):
            nxt = blocks[bi + 1] if bi + 1 < len(blocks) else None
            if kind == "loco":
                i = idxs[0]
                seg = self.segs[i]
                lo, hi = SPEED_RANGE[seg.activity]
                if not lo <= seg.speed <= hi:
                    raise InputError(
                        bad_value(
                            f"{self.where}[{i}].speed_m_s",
                            seg.speed,
                            f"{seg.activity} speed must be in {lo}..{hi} m/s",
                        )
                    )
                freq = gait_params(_gait_mode(seg.activity), seg.speed, self.sk).frequency
                t0 = bounds[i]
                t_next = bounds[i + 1] if nxt else self.end_t
                t_need = min(
                    t_next + (self.segs[i + 1].transition_s if nxt else 0.0) + 1.5 / freq + 0.5,
                    self.end_t + 1.5 / freq,
                )
                if prev is None:
                    f0, phase = 0, 0.0
                    clip = self._walk(seg, 0, int(round(t_need * fps)) + 1, self.path, phase)
                    owners.append((0, clip))
                    w_start_end = 0
                else:
                    hs = t0 + seg.transition_s  # the left heel strikes at the end of the start
                    f0 = int(np.floor((t0 - 1.0 / freq) * fps))
                    phase = float(np.mod(freq * (f0 / fps - hs), 1.0))
                    n = int(round(t_need * fps)) - f0 + 1
                    w0, w1 = int(round(t0 * fps)), int(round(hs * fps))
                    stand_y = self._ankle(prev, "Right", w0)
                    heading = self._heading(prev, prev.f0 + len(prev.root) - 1, 0)
                    P = prev.root[prev.idx(w0), :2]
                    ahead = self._route_ahead(P, heading)
                    clip = self._walk(seg, f0, n, np.vstack([P, ahead]), phase)
                    mid_y = self._mid_before(clip, "Right", w1)
                    delta = stand_y[:2] - self._ankle(clip, "Right", mid_y)[:2]
                    # along the heading: a longer run-up to the first waypoint; across it: the
                    # path moved sideways (its direction kept)
                    fwd = np.array([np.sin(heading), -np.cos(heading)])
                    side_shift = delta - (delta @ fwd) * fwd
                    clip = self._walk(seg, f0, n, np.vstack([P + delta, ahead + side_shift]), phase)
                    mid_y = self._mid_before(clip, "Right", w1)
                    clip.root[:, :2] += stand_y[:2] - self._ankle(clip, "Right", mid_y)[:2]
                    clip._world = None
                    fr = np.arange(w0, w1)
                    plans = {
                        "Right": (fr, np.maximum(fr, mid_y), _ramp(fr, w0, max(mid_y, w0 + 2)), None),
                        # the left foot from standing into the walk's own swing (relative to
                        # the hips, so that the leg reaches it), landing at the heel strike
                        "Left": (fr, fr, None, (w0 + int(0.15 * (w1 - w0)), w1)),
                    }
                    windows.append(("start", prev, clip, w0, w1, plans))
                    owners.append((w1, clip))
                    w_start_end = w1
                if nxt:  # stop at the last heel strike before the segment's end (else the first after)
                    want = bounds[i + 1] * fps + 1
                    strikes = sorted(
                        (clip.f0 + a, side, clip.f0 + (a + b - 1) // 2)
                        for side in C.SIDES
                        for a, b in C.intervals(clip.stance[side])
                        if a > 0 and clip.f0 + a >= w_start_end + 2
                    )
                    before = [x for x in strikes if x[0] <= want]
                    g, lead, mid_l = before[-1] if before else strikes[0]
                    trail = "Right" if lead == "Left" else "Left"
                    toe_off = g
                    for a, b in C.intervals(clip.stance[trail]):
                        if clip.f0 + a <= g < clip.f0 + b:
                            toe_off = clip.f0 + b - 1
                    T = self.segs[i + 1].transition_s
                    w1 = max(g + int(round(T * fps)), mid_l + 2, toe_off + int(round(0.3 * fps)))
                    stop = (clip, g, w1, lead, mid_l, toe_off, freq)
                prev = clip
            else:
                s0 = stop[1] if stop else 0
                ready = stop[2] if stop else 0
                if stop:
                    walk, g, w1, lead, mid_l, toe_off, freq = stop
                    # the standing pose turned so that its leading foot points where the planted
                    # one does (on a curve the hips' heading differs), and placed on it
                    wrot, _ = walk.world()
                    foot_yaw = C._foot_yaw(self.feet[lead], wrot[walk.idx([mid_l]), self.feet[lead].foot])[0]
                    heading = float(foot_yaw - self._stand_foot_yaw(lead))
                    start_xy = self._ankle(walk, lead, mid_l)[:2] - self._stand_offset(lead, heading)
                else:
                    _, psi = self.route.at(np.zeros(1))
                    heading = float(psi[0])
                    start_xy = self.route.xy[0].copy()
                t_end = (
                    (bounds[idxs[-1] + 1] + self.segs[idxs[-1] + 1].transition_s + 0.1) if nxt else self.end_t
                )
                n = int(round(t_end * fps)) - s0 + 1
                clip = self._still_block(idxs, bounds, s0, ready, n, start_xy, heading, nxt is not None)
                if stop:  # after the walk the excess metabolic rate decays (EPOC, as postExercise)
                    walk, g = stop[0], stop[1]
                    cycle = int(round(fps / stop[6]))
                    excess = float(np.mean(walk.met_w[walk.idx(np.arange(g - cycle, g))])) - met_to_watts(
                        MET_STAND, self.mass
                    )
                    t_after = (np.arange(len(clip.root)) + clip.f0 - g) / fps
                    clip.met_w = clip.met_w + max(excess, 0.0) * sum(
                        a * np.exp(-t_after / tau) for a, tau in EPOC
                    )
                    walk, g, w1, lead, mid_l, toe_off, _ = stop
                    trail = "Right" if lead == "Left" else "Left"
                    fr = np.arange(g, w1)
                    t_off = max(toe_off, g)
                    plans = {
                        lead: (np.minimum(fr, mid_l), fr, _ramp(fr, mid_l, w1), None),
                        trail: (np.minimum(fr, t_off), fr, None, (t_off, w1 - int(0.1 * (w1 - g)))),
                    }
                    windows.append(("stop", walk, clip, g, w1, plans))
                    owners.append((w1, clip))
                else:
                    owners.append((0, clip))
                stop = None
                prev = clip
        # assemble
        J = len(self.sk.names)
        local = np.empty((F, J, 3, 3))
        root = np.empty((F, 3))
        met = np.empty(F)
        stance = {s: np.zeros(F, bool) for s in C.SIDES}
        starts = [o[0] for o in owners] + [F]
        for (a, clip), b in zip(owners, starts[1:]):
            a, b = max(a, 0), min(max(b, a), F)
            if a >= b:
                continue
            i = clip.idx(np.arange(a, b))
            local[a:b], root[a:b], met[a:b] = clip.local[i], clip.root[i], clip.met_w[i]
            for s in C.SIDES:
                stance[s][a:b] = clip.stance[s][i]
        info_windows = []
        for kind, A, B, w0, w1, plans in windows:
            if w0 >= F:
                continue
            hi = min(w1, F)
            lo_, ro, me, st = self._blend(kind, A, B, w0, w1, plans)
            n = hi - w0
            local[w0:hi], root[w0:hi], met[w0:hi] = lo_[:n], ro[:n], me[:n]
            for s in C.SIDES:
                stance[s][w0:hi] = st[s][:n]
            info_windows.append((kind, w0, w1))
        info = {
            "segments": [s.activity for s in self.segs],
            "segment_start_s": [float(b) for b in bounds[:-1]],
            "windows": info_windows,
            "source": "motion sequence (humv_usd.human.sequence)",
        }
        if self.chair is not None:  # the avatar tool authors the chair (humv_usd.human.chair)
            info["chair"] = self.chair
        return local, root, met, stance, info

    def _still_block(self, idxs, bounds, s0, ready, n, start_xy, heading, before_walk) -> _Clip:
        """The stationary segments ``idxs`` over frames s0 .. s0 + n - 1 as one clip: runs of poses
        by the key-pose engine, split at each turn (the poses before a turn end standing, the
        turn steps round on the spot, the poses after it start standing at the new heading)."""
        fps = self.fps
        groups: list[tuple[str, list[int]]] = []
        for j in idxs:
            if self.segs[j].activity == "turn":
                groups.append(("turn", [j]))
            elif groups and groups[-1][0] == "pose":
                groups[-1][1].append(j)
            else:
                groups.append(("pose", [j]))
        parts = []
        f, xy, h, rdy = s0, np.asarray(start_xy, float), float(heading), ready
        for gi, (kind, js) in enumerate(groups):
            last = gi == len(groups) - 1
            f_end = s0 + n if last else int(round(bounds[groups[gi + 1][1][0]] * fps))
            m = max(f_end - f, 1)
            if kind == "pose":
                plan = self._plan(js, bounds, (rdy - f) / fps, f / fps, before_walk or not last)
                clip = self._still(f, m + 1, plan, xy, h)
            else:
                j = js[0]
                if f == s0 and rdy > f:  # after a stop: its closing step first, standing
                    pre = self._still(f, rdy - f + 1, [(PO.STAND, 0.0)], xy, h)
                    parts.append((pre, rdy - f))
                    f, m = rdy, max(f_end - rdy, 1)
                # the turn ends within its segment (a start or a pose follows it)
                room = min(m, int(round(bounds[j + 1] * fps)) - f) if np.isfinite(bounds[j + 1]) else m
                clip = self._turn(j, f, m + 1, xy, h, self._turn_angle(j, xy, h), room)
                h += self._turn_angle(j, xy, h)
            parts.append((clip, m))
            xy = clip.root[min(m, len(clip.root) - 1), :2].copy()
            f, rdy = f_end, f_end
        if len(parts) == 1:
            return parts[0][0]
        cat = [(c, slice(0, k)) for c, k in parts[:-1]] + [(parts[-1][0], slice(0, None))]
        return _Clip(
            s0,
            np.concatenate([c.local[sl] for c, sl in cat]),
            np.concatenate([c.root[sl] for c, sl in cat]),
            np.concatenate([c.met_w[sl] for c, sl in cat]),
            {s: np.concatenate([c.stance[s][sl] for c, sl in cat]) for s in C.SIDES},
            self.sk,
        )

    def _turn_angle(self, j: int, xy, heading: float) -> float:
        """A turn segment's angle [rad]: its ``turn_deg``, else to face the rest of the path
        (the direction to the path 1 m on from the nearest point), 180 deg at its end."""
        seg = self.segs[j]
        if seg.turn_deg is not None:
            return float(np.radians(seg.turn_deg))
        r = self.route
        s0 = float(r.s[np.argmin(np.linalg.norm(r.xy - xy, axis=1))])
        if float(r.s[-1]) - s0 < 0.5:
            return float(np.pi)
        ahead, _ = r.at(np.array([min(s0 + 1.0, float(r.s[-1]))]))
        d = ahead[0] - xy
        want = float(np.arctan2(d[0], -d[1]))
        return float(np.mod(want - heading + np.pi, 2 * np.pi) - np.pi)

    def _turn(self, j: int, f0: int, n: int, xy, heading: float, theta: float, room: int) -> _Clip:
        """A turn on the spot by ``theta`` [rad] from the standing key pose at ``xy``/``heading``:
        the body turns about the point between the ankles (minimum jerk) while the feet step
        round it in pairs (the foot on the turn's side first, each lifted and set down turned
        by up to :data:`TURN_STEP_DEG` about that point), legs by IK; then stands."""
        fps, sk = self.fps, self.sk
        pairs = max(int(np.ceil(abs(np.degrees(theta)) / TURN_STEP_DEG - 1e-9)), 1)
        T = pairs * TURN_PAIR_S
        if room / fps < T - 1e-6:  # room: frames the segment leaves for the turn
            seg = self.segs[j]
            raise InputError(
                bad_value(
                    f"{self.where}[{j}].duration_s",
                    seg.duration_s,
                    f"a turn of {np.degrees(theta):.0f} deg needs {T:.2f} s ({pairs} pair(s) of "
                    f"steps) within the segment, after a stop's closing step: {T - room / fps:.2f} s more",
                )
            )
        base = self._still(f0, n, [(PO.STAND, 0.0)], xy, heading)
        local, root = base.local.copy(), base.root.copy()
        wrot, wpos = base.world()
        t = np.arange(n) / fps
        psi = theta * _minjerk(t / T)
        c = 0.5 * (wpos[0, self.feet["Left"].foot, :2] + wpos[0, self.feet["Right"].foot, :2])
        R = rot_z(psi)
        root[:, :2] = c + np.einsum("fij,j->fi", R[:, :2, :2], root[0, :2] - c)
        local[:, 0] = R @ local[:, 0]
        root_rot = local[:, 0]
        lead, trail = ("Left", "Right") if theta >= 0 else ("Right", "Left")
        ts = T / (2 * pairs)
        yaw = {s: np.zeros(n) for s in C.SIDES}
        lift = {s: np.zeros(n) for s in C.SIDES}
        stance = {s: np.ones(n, bool) for s in C.SIDES}
        done = {s: 0.0 for s in C.SIDES}
        for i in range(2 * pairs):
            side = lead if i % 2 == 0 else trail
            target = theta * (i // 2 + 1) / pairs
            a, b = (i + 0.15) * ts, (i + 0.85) * ts
            sw = (t >= a) & (t < b)
            u = (t[sw] - a) / (b - a)
            yaw[side][sw] = done[side] + (target - done[side]) * _minjerk(u)
            yaw[side][t >= b] = target
            lift[side][sw] = np.sin(np.pi * u)
            stance[side][sw] = False
            done[side] = target
        targets = {}
        need = np.zeros(n)
        for side in C.SIDES:
            fp = self.feet[side]
            Ry = rot_z(yaw[side])
            a0 = wpos[0, fp.foot]
            ankle = np.empty((n, 3))
            ankle[:, :2] = c + np.einsum("fij,j->fi", Ry[:, :2, :2], a0[:2] - c)
            g0 = float(np.asarray(self.ground.height(a0[None, :2]))[0])
            ankle[:, 2] = a0[2] + np.asarray(self.ground.height(ankle[:, :2])) - g0 + TURN_LIFT_M * lift[side]
            targets[side] = C.FootTargets(ankle, Ry @ wrot[0, fp.foot], Ry @ wrot[0, fp.toe], np.zeros(n))
            need = np.maximum(need, C.reach_drop(C.leg_chain(sk, side), root, root_rot, ankle))
        root[:, 2] -= C.smooth_drop(need, 1.0)
        for side in C.SIDES:
            chain = C.leg_chain(sk, side)
            hip, knee, ankle, toe = C.leg_ik(chain, root, root_rot, local[:, chain.hip], targets[side])
            local[:, chain.hip], local[:, chain.knee] = hip, knee
            local[:, chain.ankle], local[:, chain.toe] = ankle, toe
        met = np.where(t < T, met_to_watts(PO.MET_TRANSITION, self.mass), base.met_w)
        return _Clip(f0, local, root, met, stance, sk)

    def _mid_before(self, clip: _Clip, side: str, f: int) -> int:
        """Middle frame (global) of ``side``'s last stance run starting at or before ``f``."""
        best = None
        for a, b in C.intervals(clip.stance[side]):
            if clip.f0 + a <= f:
                best = clip.f0 + (a + b - 1) // 2
        if best is None:
            raise AssertionError("no stance before the start's heel strike")
        return best

    def _route_ahead(self, P: np.ndarray, heading: float) -> np.ndarray:
        """Waypoints of the rest of the path from the point nearest ``P`` on (every 0.5 m; a
        straight line along ``heading`` beyond its end)."""
        r = self.route
        s0 = float(r.s[np.argmin(np.linalg.norm(r.xy - P, axis=1))])
        L = float(r.s[-1])
        s = np.arange(s0 + 0.5, max(L, s0 + 1.0) + 1e-9, 0.5)
        xy, _ = r.at(s)
        if L - s0 < 0.5:  # at or past the end: straight on along the heading
            xy = P + np.outer(np.arange(1, 3), [np.sin(heading), -np.cos(heading)])
        return xy

    def _plan(self, idxs, bounds, ready_s, t0, before_walk):
        """The key plan of one stationary block (times relative to its first frame)."""
        plan = [(PO.STAND, 0.0)]
        cur, tau = "stand", 0.0
        for n, j in enumerate(idxs):
            seg = self.segs[j]
            start = ready_s if n == 0 else bounds[j] - t0
            end = (bounds[j + 1] - t0) if (before_walk or n < len(idxs) - 1) else np.inf
            down = PO.route(cur, seg.activity)
            up = (
                PO.route(PO.final_key(seg.activity).name, "stand")
                if (before_walk and n == len(idxs) - 1)
                else []
            )
            d, u = sum(x for _, x in down), sum(x for _, x in up)
            if start + d + u > end + 1e-6:
                need = start + d + u - (bounds[j] - t0)
                raise InputError(
                    bad_value(
                        f"{self.where}[{j}].duration_s",
                        seg.duration_s,
                        f"{seg.activity!r} here needs at least {need:.2f} s "
                        f"(its transitions {d:.2f} s down, {u:.2f} s up"
                        + (", after the stop's closing step)" if n == 0 and start > 0 else ")"),
                    )
                )
            if start - tau > 1e-6:
                plan.append((PO.KEYS[cur], start - tau))
                tau = start
            plan += down
            tau += d
            cur = PO.final_key(seg.activity).name
            if up:
                if end - u - tau > 1e-6:
                    plan.append((PO.KEYS[cur], end - u - tau))
                plan += up
                tau, cur = end, "stand"
        return plan

    # ------------------------------------------------------------------ blending
    def _blend(self, kind, A: _Clip, B: _Clip, w0: int, w1: int, plans: dict):
        fps, sk = self.fps, self.sk
        fr = np.arange(w0, w1)
        s = _ramp(fr, w0, w1)
        qa, qb = matrix_to_quat(A.local[A.idx(fr)]), matrix_to_quat(B.local[B.idx(fr)])
        local = quat_to_matrix(quat_slerp(qa, qb, s[:, None]))
        root_rot = local[:, 0]
        # root: cubic Hermite between the two motions (position and velocity continuous)
        p0, v0 = A.root[A.idx(w0)], A.velocity(w0, fps)
        p1, v1 = B.root[B.idx(w1)], B.velocity(w1, fps)
        d = np.linalg.norm((p1 - p0)[:2])
        v = np.linalg.norm((v0 if kind == "stop" else v1)[:2])
        T = (w1 - w0) / fps
        Tr = float(np.clip(3.0 * d / v, 2.0 / fps, T)) if v > 1e-9 else T
        nr = max(int(round(Tr * fps)), 2)
        root = np.empty((len(fr), 3))
        if kind == "stop":
            a, b = w0, w0 + nr
            root[:] = B.root[B.idx(fr)]
            p1, v1 = B.root[B.idx(b)], np.zeros(3)
        else:
            a, b = w1 - nr, w1
            root[:] = A.root[A.idx(fr)]
            p0, v0 = A.root[A.idx(a)], np.zeros(3)
        sel = (fr >= a) & (fr < b)
        u = ((fr[sel] - a) / (b - a))[:, None]
        Th = (b - a) / fps
        root[sel] = (
            (2 * u**3 - 3 * u**2 + 1) * p0
            + (u**3 - 2 * u**2 + u) * Th * v0
            + (-2 * u**3 + 3 * u**2) * p1
            + (u**3 - u**2) * Th * v1
        )
        # feet: each from one motion to the other (planted or swinging), legs by IK
        wa, wb = A.world(), B.world()
        targets, stance = {}, {}
        for side, (ia, ib, w, span) in plans.items():
            fp = self.feet[side]
            swing = span is not None
            if swing:  # the swing keeps up with the hips: its time ramp, or the root's progress
                a, b = span
                if kind == "stop":
                    b = min(b, max(w0 + nr, a + int(round(0.3 * fps))))
                else:
                    a = min(max(a, w1 - nr), b - int(round(0.3 * fps)))
                ra_, rb_ = root[min(max(a - w0, 0), len(fr) - 1), :2], root[min(b - w0, len(fr) - 1), :2]
                span_xy = rb_ - ra_
                L = float(np.linalg.norm(span_xy))
                prog = (root[:, :2] - ra_) @ span_xy / L**2 if L > 1e-6 else np.zeros(len(fr))
                w = np.clip(np.where(fr >= a, prog, 0.0), 0.0, 1.0)
                if kind == "stop":  # the hips slow down: the foot also lands in its own time
                    w = np.maximum(w, _ramp(fr, a, b))
            ra, rb = A.idx(ia), B.idx(ib)
            to = wb[1][rb, fp.foot]
            if swing and kind == "start":
                to = to - B.root[rb] + root
            ankle = (1 - w)[:, None] * wa[1][ra, fp.foot] + w[:, None] * to
            if swing:
                ankle[:, 2] += STEP_LIFT_M * np.sin(np.pi * w) * (1 - w if kind == "start" else 1.0)
            frot = quat_to_matrix(
                quat_slerp(matrix_to_quat(wa[0][ra, fp.foot]), matrix_to_quat(wb[0][rb, fp.foot]), w)
            )
            trot = quat_to_matrix(
                quat_slerp(matrix_to_quat(wa[0][ra, fp.toe]), matrix_to_quat(wb[0][rb, fp.toe]), w)
            )
            targets[side] = C.FootTargets(ankle, frot, trot, np.zeros(len(fr)))
            stance[side] = np.where(
                w <= 0, A.stance[side][ra], np.where(w >= 1, B.stance[side][rb], not swing)
            )
        need = np.zeros(len(fr))
        for side in plans:
            chain = C.leg_chain(sk, side)
            need = np.maximum(need, C.reach_drop(chain, root, root_rot, targets[side].ankle))
        root[:, 2] -= C.smooth_drop(need, 1.0)
        for side in plans:
            chain = C.leg_chain(sk, side)
            hip, knee, ankle, toe = C.leg_ik(chain, root, root_rot, local[:, chain.hip], targets[side])
            local[:, chain.hip], local[:, chain.knee] = hip, knee
            local[:, chain.ankle], local[:, chain.toe] = ankle, toe
        met = (1 - s) * A.met_w[A.idx(fr)] + s * B.met_w[B.idx(fr)]
        return local, root, met, stance

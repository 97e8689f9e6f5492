"""Biovision BVH motion: read, write and retarget onto the avatar's rig.

Format (Biovision/Acclaim practice, as written by MotionBuilder and the CMU database):
``HIERARCHY`` with ``ROOT``/``JOINT`` blocks (``OFFSET x y z``, ``CHANNELS n <names>``, an
optional ``End Site { OFFSET }``), then ``MOTION``, ``Frames: N``, ``Frame Time: dt`` and N
lines of channel values. Channels are ``Xposition Yposition Zposition`` and ``Xrotation
Yrotation Zrotation`` [degrees] in any order and subset; the rotation channels compose left to
right in the listed order (``Zrotation Xrotation Yrotation`` -> R = Rz Rx Ry, column vectors;
a joint maps child points as p_parent = T + R p_child). A joint's position channels replace its
OFFSET (as in Blender's importer); without them the OFFSET is its translation.

Retargeting (:func:`motion_from_bvh`):

* names: CMU-style names map one to one onto our rig (MakeHuman's CMU MotionBuilder rig;
  ``LeftHandIndex1`` is our ``LeftHandFinger1``), other skeletons through ``name_map``
  ({bvh name: our name}); our joints without a source stay at rest (identity local rotation);
* axes: ``up_axis`` and ``forward_axis`` name the BVH's up direction and the direction its
  rest pose faces (CMU: ``"Y"`` and ``"Z"``, left = +X); they map to our +Z and -Y;
* units: ``scale`` [m per BVH unit], default our hip height over the BVH's rest hip height
  (root above the lowest rest joint or end site);
* rest pose: the BVH's rest frames are world-aligned (BVH convention) but its rest pose is
  usually a T-pose and ours MakeHuman's A-pose. Each limb bone (thigh, shank, upper arm,
  forearm, hand) gets a fixed rest correction C, the minimal rotation turning our rest bone
  direction onto the BVH's; our world rotation is the BVH bone's world rotation times C, so
  our limbs point where the BVH limbs point. Other bones (pelvis, spine, clavicles, head,
  feet, toes) take the BVH's world rotation as is: their rest directions differ by anatomy
  (e.g. the pelvis-to-hip offsets), not by pose;
* time: resampled to the scenario's fps by slerp (rotations) and linear interpolation (root),
  holding the last frame beyond the end;
* contact: the root settled so that planted feet touch the ground and nothing is under it,
  then the planted feet locked (:func:`humv_usd.human.contact.lock_feet`: heading frozen,
  rolling without slipping, legs re-posed by IK), so that a retargeted clip's skating feet
  (DeepMimic walk 7 mm, run 77 mm, get-up 43 mm) stand still (2-6 mm).

Errors in a file raise :class:`humv_usd.errors.InputError` with one line naming the file, the
line number and what was expected.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial.transform import Rotation

from humv_usd.errors import InputError
from humv_usd.fileio import write_text_atomic
from humv_usd.human import contact as C
from humv_usd.human.gait import align_matrix, fk_matrices, matrix_to_quat, quat_slerp
from humv_usd.human.limbs import lock_supports
from humv_usd.human.macro import obj_data
from humv_usd.human.motion import SIM_FPS_MIN, Motion, _continuous, metabolic_rate
from humv_usd.human.poses import body_points as body_points_of
from humv_usd.human.skeleton import (
    Skeleton,
    linear_blend_skinning,
    quat_to_matrix,
    skin_weights,
    skinning_matrices,
)

log = logging.getLogger(__name__)

POS_CHANNELS = ("Xposition", "Yposition", "Zposition")
ROT_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")
CMU_ALIASES = {"LeftHandIndex1": "LeftHandFinger1", "RightHandIndex1": "RightHandFinger1"}
_AXES = {"X": np.array([1.0, 0, 0]), "Y": np.array([0, 1.0, 0]), "Z": np.array([0, 0, 1.0])}


@dataclass
class BVHJoint:
    name: str
    parent: int  # index into BVH.joints, -1 for the root
    offset: np.ndarray  # (3,)
    channels: list[str]
    end_site: np.ndarray | None = None
    first_channel: int = 0  # column of its first channel in BVH.values


@dataclass
class BVH:
    joints: list[BVHJoint]
    frame_time: float
    values: np.ndarray  # (frames, channels)
    path: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def names(self) -> list[str]:
        return [j.name for j in self.joints]

    @property
    def frame_count(self) -> int:
        return len(self.values)

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    def channel(self, joint: int, name: str) -> np.ndarray | None:
        j = self.joints[joint]
        if name not in j.channels:
            return None
        return self.values[:, j.first_channel + j.channels.index(name)]

    def local(self) -> tuple[np.ndarray, np.ndarray]:
        """Local rotations (F, J, 3, 3) and translations (F, J, 3) in the file's axes/units."""
        F, J = self.frame_count, len(self.joints)
        rot = np.tile(np.eye(3), (F, J, 1, 1))
        trans = np.empty((F, J, 3))
        for i, j in enumerate(self.joints):
            order = [c for c in j.channels if c in ROT_CHANNELS]
            if order:
                ang = np.column_stack([self.channel(i, c) for c in order])
                rot[:, i] = Rotation.from_euler("".join(c[0] for c in order), ang, degrees=True).as_matrix()
            trans[:, i] = j.offset
            for k, c in enumerate(POS_CHANNELS):
                v = self.channel(i, c)
                if v is not None:
                    trans[:, i, k] = v
        return rot, trans

    def rest_positions(self) -> tuple[np.ndarray, list[np.ndarray | None]]:
        """Rest joint positions (J, 3) from the offsets, and end-site positions per joint."""
        pos = np.zeros((len(self.joints), 3))
        ends = []
        for i, j in enumerate(self.joints):
            pos[i] = j.offset + (pos[j.parent] if j.parent >= 0 else 0.0)
            ends.append(None if j.end_site is None else pos[i] + j.end_site)
        return pos, ends


# ------------------------------------------------------------------------- parsing
class _Lines:
    """Token stream that remembers line numbers."""

    def __init__(self, text: str, path: str):
        self.path = path
        self.toks: list[tuple[str, int]] = []
        self.lines = text.splitlines()
        self.line_of_motion = None
        for n, line in enumerate(self.lines, 1):
            if line.strip().upper() == "MOTION" and self.line_of_motion is None:
                self.line_of_motion = n
                self.toks.append(("MOTION", n))
                break
            for t in re.findall(r"[{}]|[^\s{}]+", line):
                self.toks.append((t, n))
        self.i = 0

    def fail(self, line: int, expected: str, got) -> InputError:
        got_s = "end of file" if got is None else repr(got)
        return InputError(f"{self.path}:{line}: expected {expected}, got {got_s}")

    def peek(self):
        return self.toks[self.i] if self.i < len(self.toks) else (None, self._last_line())

    def _last_line(self) -> int:
        return len(self.lines)

    def next(self, expected: str):
        tok, line = self.peek()
        if tok is None:
            raise self.fail(line, expected, None)
        self.i += 1
        return tok, line

    def expect(self, word: str):
        tok, line = self.next(repr(word))
        if tok != word:
            raise self.fail(line, repr(word), tok)
        return line

    def number(self, what: str) -> float:
        tok, line = self.next(what)
        try:
            v = float(tok)
        except ValueError:
            raise self.fail(line, what, tok) from None
        if not np.isfinite(v):
            raise self.fail(line, what, tok)
        return v


#: deepest joint hierarchy read (a human rig is about 10 deep; a deeper file would exhaust
#: Python's recursion in the parser, issue 26)
MAX_DEPTH = 256


def _parse_joint(s: _Lines, joints: list[BVHJoint], parent: int, name: str, n_ch: list[int], depth: int = 1):
    if depth > MAX_DEPTH:
        raise s.fail(s.peek()[1], f"a joint hierarchy at most {MAX_DEPTH} joints deep", f"JOINT {name}")
    s.expect("{")
    tok, line = s.next("'OFFSET'")
    if tok != "OFFSET":
        raise s.fail(line, "'OFFSET'", tok)
    offset = np.array([s.number("a number (OFFSET x y z)") for _ in range(3)])
    channels: list[str] = []
    tok, line = s.peek()
    if tok == "CHANNELS":
        s.next("'CHANNELS'")
        tok, cline = s.next("a channel count")
        try:
            count = int(tok)
        except ValueError:
            raise s.fail(cline, "a channel count (integer)", tok) from None
        if not 0 <= count <= 6:
            raise s.fail(cline, "a channel count of 0..6", tok)
        for _ in range(count):
            tok, cl = s.next("a channel name")
            if tok not in POS_CHANNELS + ROT_CHANNELS:
                raise s.fail(
                    cl,
                    f"a channel name ({', '.join(POS_CHANNELS + ROT_CHANNELS)}) "
                    f"-- CHANNELS {count} lists {count} names",
                    tok,
                )
            if tok in channels:
                raise s.fail(cl, "each channel once per joint", tok)
            channels.append(tok)
    me = len(joints)
    joints.append(BVHJoint(name, parent, offset, channels, first_channel=n_ch[0]))
    n_ch[0] += len(channels)
    while True:
        tok, line = s.next("'JOINT', 'End Site' or '}'")
        if tok == "}":
            return
        if tok == "JOINT":
            child, _ = s.next("a joint name")
            _parse_joint(s, joints, me, child, n_ch, depth + 1)
        elif tok == "End":
            s.expect("Site")
            s.expect("{")
            tok, l2 = s.next("'OFFSET'")
            if tok != "OFFSET":
                raise s.fail(l2, "'OFFSET'", tok)
            joints[me].end_site = np.array([s.number("a number (OFFSET x y z)") for _ in range(3)])
            s.expect("}")
        else:
            raise s.fail(line, "'JOINT', 'End Site' or '}'", tok)


def parse_bvh(text: str, path: str = "<bvh>") -> BVH:
    """Parse BVH text; errors name ``path`` and the line."""
    s = _Lines(text, path)
    tok, line = s.next("'HIERARCHY'")
    if tok.upper() != "HIERARCHY":
        raise s.fail(line, "'HIERARCHY'", tok)
    tok, line = s.next("'ROOT'")
    if tok != "ROOT":
        raise s.fail(line, "'ROOT'", tok)
    name, _ = s.next("a root joint name")
    joints: list[BVHJoint] = []
    n_ch = [0]
    _parse_joint(s, joints, -1, name, n_ch)
    tok, line = s.next("'MOTION'")
    if tok != "MOTION":
        raise s.fail(line, "'MOTION' after the hierarchy", tok)
    names = [j.name for j in joints]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise InputError(
            f"{path}:{s.line_of_motion}: expected unique joint names, got duplicates {sorted(dup)}"
        )
    # MOTION section: "Frames: N", "Frame Time: dt", N lines of values
    lines = s.lines
    n = s.line_of_motion
    body = [(k + 1, lines[k].strip()) for k in range(n, len(lines))]
    body = [(k, t) for k, t in body if t]
    if not body:
        raise InputError(f"{path}:{len(lines)}: expected 'Frames: N', got end of file")
    k, t = body[0]
    m = re.fullmatch(r"Frames:\s*(\S+)", t, flags=re.IGNORECASE)
    if not m or not m.group(1).isdigit():
        raise InputError(f"{path}:{k}: expected 'Frames: N' with an integer N >= 1, got {t!r}")
    frames = int(m.group(1))
    if frames < 1:
        raise InputError(f"{path}:{k}: expected 'Frames: N' with N >= 1, got {t!r}")
    if len(body) < 2:
        raise InputError(f"{path}:{len(lines)}: expected 'Frame Time: dt', got end of file")
    k, t = body[1]
    m = re.fullmatch(r"Frame\s+Time:\s*(\S+)", t, flags=re.IGNORECASE)
    try:
        dt = float(m.group(1)) if m else None
    except ValueError:
        dt = None
    if dt is None or not np.isfinite(dt) or dt <= 0:
        raise InputError(f"{path}:{k}: expected 'Frame Time: dt' with dt > 0 [s], got {t!r}")
    rows = body[2:]
    if len(rows) < frames:
        last = rows[-1][0] if rows else k
        raise InputError(f"{path}:{last}: expected {frames} frame lines (Frames: {frames}), got {len(rows)}")
    values = np.empty((frames, n_ch[0]))
    for f, (k, t) in enumerate(rows[:frames]):
        parts = t.split()
        if len(parts) != n_ch[0]:
            raise InputError(f"{path}:{k}: expected {n_ch[0]} channel values (frame {f}), got {len(parts)}")
        try:
            values[f] = [float(p) for p in parts]
        except ValueError:
            bad = next(p for p in parts if not _is_float(p))
            raise InputError(f"{path}:{k}: expected a number (frame {f}), got {bad!r}") from None
        if not np.isfinite(values[f]).all():
            raise InputError(f"{path}:{k}: expected finite numbers (frame {f}), got {t[:40]!r}")
    if len(rows) > frames:
        k, t = rows[frames]
        raise InputError(f"{path}:{k}: expected end of file after {frames} frames, got {t[:40]!r}")
    return BVH(joints, dt, values, path)


def _is_float(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def read_bvh(path) -> BVH:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise InputError(f"{p}: cannot read BVH file ({e.strerror or e})") from None
    return parse_bvh(text, str(p))


# ------------------------------------------------------------------------- writing
def format_bvh(bvh: BVH, precision: int = 6) -> str:
    out = ["HIERARCHY"]
    children: dict[int, list[int]] = {}
    for i, j in enumerate(bvh.joints):
        children.setdefault(j.parent, []).append(i)

    def num(v):
        return " ".join(f"{x:.{precision}f}" for x in v)

    def emit(i: int, depth: int):
        j = bvh.joints[i]
        pad = "  " * depth
        out.append(f"{pad}{'ROOT' if j.parent < 0 else 'JOINT'} {j.name}")
        out.append(f"{pad}{{")
        out.append(f"{pad}  OFFSET {num(j.offset)}")
        if j.channels:
            out.append(f"{pad}  CHANNELS {len(j.channels)} {' '.join(j.channels)}")
        for c in children.get(i, []):
            emit(c, depth + 1)
        if j.end_site is not None:
            out.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET {num(j.end_site)}", f"{pad}  }}"])
        out.append(f"{pad}}}")

    emit(children[-1][0], 0)
    out += ["MOTION", f"Frames: {bvh.frame_count}", f"Frame Time: {bvh.frame_time:.8f}"]
    out += [num(row) for row in bvh.values]
    return "\n".join(out) + "\n"


def write_bvh(path, bvh: BVH, precision: int = 6) -> None:
    """Write ``bvh`` to ``path`` atomically (temp file + rename)."""

    write_text_atomic(Path(path), format_bvh(bvh, precision))


# ------------------------------------------------------------------------- axes
def axis_matrix(up_axis: str = "Y", forward_axis: str = "Z") -> np.ndarray:
    """Rotation A taking BVH vectors to ours: BVH up -> +Z, BVH facing -> -Y, BVH left
    (up x facing) -> +X. Axes are "X", "Y", "Z", optionally signed ("-Z")."""

    def parse(a: str, what: str) -> np.ndarray:
        a = str(a).strip().upper()
        sign = -1.0 if a.startswith("-") else 1.0
        a = a.lstrip("+-")
        if a not in _AXES:
            raise InputError(f"{what} = {a!r}: expected one of X, Y, Z, -X, -Y, -Z")
        return sign * _AXES[a]

    up, fw = parse(up_axis, "up_axis"), parse(forward_axis, "forward_axis")
    if abs(np.dot(up, fw)) > 0.5:
        raise InputError(
            f"up_axis = {up_axis!r}, forward_axis = {forward_axis!r}: expected two different axes"
        )
    left = np.cross(up, fw)
    src = np.column_stack([left, fw, up])
    dst = np.column_stack([[1.0, 0, 0], [0, -1.0, 0], [0, 0, 1.0]])
    return dst @ src.T


# ------------------------------------------------------------------------- rig -> BVH
def motion_to_bvh(
    skeleton: Skeleton,
    local_rotations: np.ndarray,
    root_translation: np.ndarray,
    fps: float,
    rotation_order: str = "ZXY",
    up_axis: str = "Y",
    forward_axis: str = "Z",
    scale: float = 0.01,
    position_channels: str = "XYZ",
) -> BVH:
    """Our rig's motion as a BVH (CMU names, world-aligned rest frames = our A-pose): local
    rotations (F, J, 4) wxyz and root translation (F, 3) [m] in our frame; ``scale`` [m per
    BVH unit] (0.01: centimetres); ``rotation_order`` e.g. "ZXY" (-> Zrotation Xrotation
    Yrotation)."""
    A = axis_matrix(up_axis, forward_axis)
    At = A.T
    rot = quat_to_matrix(local_rotations)
    F, J = rot.shape[:2]
    order = rotation_order.upper()
    pos_ch = [f"{c}position" for c in position_channels.upper()]
    rot_ch = [f"{c}rotation" for c in order]
    t_rest = skeleton.rest_local_translations
    children = {j: [k for k in range(J) if skeleton.parents[k] == j] for j in range(J)}
    joints, values = {}, {}
    for j, name in enumerate(skeleton.names):
        p = int(skeleton.parents[j])
        off = At @ (t_rest[j] if p >= 0 else skeleton.rest_positions[j]) / scale
        end = None
        if not children[j]:
            end = At @ (skeleton.tail_positions[j] - skeleton.rest_positions[j]) / scale
        joints[j] = BVHJoint(name, p, off, (pos_ch if p < 0 else []) + rot_ch, end)
        eul = Rotation.from_matrix(At @ rot[:, j] @ A).as_euler(order, degrees=True)
        if p < 0:
            P = (root_translation @ At.T) / scale
            eul = np.column_stack([P[:, "XYZ".index(c[0])] for c in pos_ch] + [eul])
        values[j] = eul
    # BVH lists children inside their parents: depth-first order
    order_idx = _depth_first(skeleton)
    remap = {old: new for new, old in enumerate(order_idx)}
    out, c0 = [], 0
    for old in order_idx:
        jt = joints[old]
        jt.parent = remap[jt.parent] if jt.parent >= 0 else -1
        jt.first_channel = c0
        c0 += len(jt.channels)
        out.append(jt)
    return BVH(out, 1.0 / fps, np.column_stack([values[old] for old in order_idx]))


def _depth_first(skeleton: Skeleton) -> list[int]:
    out: list[int] = []

    def visit(j):
        out.append(j)
        for k in range(len(skeleton.names)):
            if skeleton.parents[k] == j:
                visit(k)

    visit(int(np.flatnonzero(skeleton.parents < 0)[0]))
    return out


# ------------------------------------------------------------------------- BVH -> rig
@dataclass(frozen=True)
class Retarget:
    """How BVH joints drive our rig (see the module docstring)."""

    source: dict  # our joint index -> BVH joint index
    correction: np.ndarray  # (J, 3, 3) rest correction C per our joint
    axes: np.ndarray  # (3, 3) A
    scale: float


def _primary_child(skeleton: Skeleton, j: int) -> int | None:
    kids = [k for k in range(len(skeleton.names)) if skeleton.parents[k] == j]
    return kids[0] if len(kids) == 1 else None


ALIGN = ("UpLeg", "Leg", "Arm", "ForeArm", "Hand")


def build_retarget(
    bvh: BVH,
    skeleton: Skeleton,
    name_map: dict | None = None,
    up_axis: str = "Y",
    forward_axis: str = "Z",
    scale: float | None = None,
    align=ALIGN,
) -> Retarget:
    """Joint mapping, rest corrections, axes and scale. ``align``: name endings of our joints
    whose rest direction is aligned to the BVH's (the limb bones, where T- and A-pose
    differ); the others (pelvis, spine, clavicles, head, feet, toes, fingers) keep the BVH's
    world rotation, since their rest directions differ by anatomy, not by pose."""
    A = axis_matrix(up_axis, forward_axis)
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise InputError(f"scale = {scale!r}: expected a positive number [m per BVH unit]")
    mapping = dict(CMU_ALIASES)
    if name_map:
        mapping.update(name_map)
    ours = {n: i for i, n in enumerate(skeleton.names)}
    source: dict[int, int] = {}
    for b, j in enumerate(bvh.joints):
        target = mapping.get(j.name, j.name)
        if target in ours and ours[target] not in source:
            source[ours[target]] = b
    if not source:
        raise InputError(
            f"{bvh.path}: no BVH joint maps onto the rig (BVH joints "
            f"{bvh.names[:6]}...; pass name_map={{bvh name: rig name}})"
        )
    used = set(source.values())
    unmapped = [j.name for b, j in enumerate(bvh.joints) if b not in used]
    if unmapped:
        shown = ", ".join(unmapped[:8]) + (f" and {len(unmapped) - 8} more" if len(unmapped) > 8 else "")
        log.warning(
            "%s: %d BVH joint(s) not mapped onto the rig, their motion is dropped: %s "
            "(pass name_map={bvh name: rig name})",
            bvh.path,
            len(unmapped),
            shown,
        )
    rest_b, ends_b = bvh.rest_positions()
    rest_b = rest_b @ A.T
    ends_b = [None if e is None else A @ e for e in ends_b]
    if scale is None:
        # hip height ratio: Hips above the ankles when both rigs name them, else the root
        # above the lowest rest joint/end site against our Hips above the soles (z = 0)
        ankles = [ours[n] for n in ("LeftFoot", "RightFoot") if ours[n] in source]
        if 0 in source and ankles:
            h_b = np.mean([rest_b[source[0], 2] - rest_b[source[a], 2] for a in ankles])
            h_o = np.mean([skeleton.rest_positions[0, 2] - skeleton.rest_positions[a, 2] for a in ankles])
        else:
            pts = np.vstack([rest_b] + [e[None] for e in ends_b if e is not None])
            h_b = rest_b[0, 2] - pts[:, 2].min()
            h_o = skeleton.rest_positions[0, 2]
        if h_b <= 1e-9:
            raise InputError(
                f"{bvh.path}: cannot derive the BVH scale (its rest pose has no "
                f"height along up_axis={up_axis!r}); pass scale"
            )
        scale = h_o / h_b
    J = len(skeleton.names)
    corr = np.tile(np.eye(3), (J, 1, 1))
    bchildren: dict[int, list[int]] = {}
    for i, j in enumerate(bvh.joints):
        bchildren.setdefault(j.parent, []).append(i)
    for j, b in source.items():
        name = skeleton.names[j]
        if not any(name.endswith(a) and name[: -len(a)] in ("Left", "Right") for a in align):
            continue
        c = _primary_child(skeleton, j)
        if c is None:
            continue
        d_o = skeleton.rest_positions[c] - skeleton.rest_positions[j]
        if c in source and bvh.joints[source[c]].parent == b:
            d_b = rest_b[source[c]] - rest_b[b]
        elif len(bchildren.get(b, [])) == 1:
            d_b = rest_b[bchildren[b][0]] - rest_b[b]
        elif ends_b[b] is not None and not bchildren.get(b):
            d_b = ends_b[b] - rest_b[b]
        else:
            continue
        if np.linalg.norm(d_b) < 1e-9 or np.linalg.norm(d_o) < 1e-9:
            continue
        if np.dot(d_o, d_b) / (np.linalg.norm(d_o) * np.linalg.norm(d_b)) < -0.999:
            continue  # antiparallel: no unique minimal rotation
        corr[j] = align_matrix(d_o, d_b)
    return Retarget(source, corr, A, float(scale))


def retarget(bvh: BVH, skeleton: Skeleton, rt: Retarget) -> tuple[np.ndarray, np.ndarray]:
    """Our local rotations (F, J, 3, 3) and root translation (F, 3) at the BVH's frames."""
    rot_b, trans_b = bvh.local()
    F = bvh.frame_count
    A = rt.axes
    # BVH world rotations in our axes
    Jb = len(bvh.joints)
    world_b = np.empty((F, Jb, 3, 3))
    for i, j in enumerate(bvh.joints):
        r = A @ rot_b[:, i] @ A.T
        world_b[:, i] = r if j.parent < 0 else world_b[:, j.parent] @ r
    J = len(skeleton.names)
    world = np.empty((F, J, 3, 3))
    local = np.empty((F, J, 3, 3))
    for j in range(J):
        p = int(skeleton.parents[j])
        parent = world[:, p] if p >= 0 else np.eye(3)
        if j in rt.source:
            world[:, j] = world_b[:, rt.source[j]] @ rt.correction[j]
            local[:, j] = np.swapaxes(parent, -1, -2) @ world[:, j]
        else:
            local[:, j] = np.eye(3)
            world[:, j] = parent
    if 0 not in rt.source:  # nothing drives our Hips: it stays where it rests
        return local, np.tile(skeleton.rest_positions[0], (F, 1))
    b0 = rt.source[0]
    if bvh.joints[b0].parent < 0:
        root = (trans_b[:, b0] @ A.T) * rt.scale
    else:  # a non-root BVH joint drives our Hips: its world position
        _, pos = fk_matrices_bvh(bvh, rot_b, trans_b)
        root = (pos[:, b0] @ A.T) * rt.scale
    return local, root


def fk_matrices_bvh(bvh: BVH, rot: np.ndarray, trans: np.ndarray):
    """World rotations and positions of the BVH's joints (its axes and units)."""
    F, J = rot.shape[:2]
    wr = np.empty_like(rot)
    wp = np.empty((F, J, 3))
    for i, j in enumerate(bvh.joints):
        if j.parent < 0:
            wr[:, i], wp[:, i] = rot[:, i], trans[:, i]
        else:
            wr[:, i] = wr[:, j.parent] @ rot[:, i]
            wp[:, i] = wp[:, j.parent] + np.einsum("fij,fj->fi", wr[:, j.parent], trans[:, i])
    return wr, wp


def resample(
    times_src: np.ndarray, quats: np.ndarray, root: np.ndarray, times: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Slerp local quaternions (F, J, 4) and lerp the root (F, 3) onto ``times``."""
    t = np.clip(times, times_src[0], times_src[-1])
    k = np.clip(np.searchsorted(times_src, t, side="right") - 1, 0, len(times_src) - 1)
    k1 = np.minimum(k + 1, len(times_src) - 1)
    span = np.where(k1 > k, times_src[k1] - times_src[k], 1.0)
    u = np.where(k1 > k, (t - times_src[k]) / span, 0.0)
    q = quat_slerp(quats[k], quats[k1], np.broadcast_to(u[:, None], (len(t), quats.shape[1])))
    r = root[k] + u[:, None] * (root[k1] - root[k])
    return q, r


def _lowest_above_ground(
    skeleton: Skeleton, body_points, wr: np.ndarray, wp: np.ndarray, ground
) -> np.ndarray:
    """Per frame, the height above the ground of the lowest body point (every 8th body vertex,
    skinned with its MakeHuman weights) or, without ``body_points``, of the lowest joint."""
    if body_points is None:
        return (wp[..., 2] - ground.height(wp[..., :2])).min(axis=1)
    _, groups = obj_data()
    ids = np.unique(groups["body"])[::8]
    idx, w = skin_weights(skeleton, ids)
    rest = np.asarray(body_points, dtype=np.float64)[ids]
    world = np.tile(np.eye(4), (*wr.shape[:2], 1, 1))
    world[..., :3, :3] = wr
    world[..., :3, 3] = wp
    skin = skinning_matrices(skeleton, world)
    out = np.empty(len(wr))
    for f in range(len(wr)):
        pts = linear_blend_skinning(rest, idx, w, skin[f])
        out[f] = (pts[:, 2] - ground.height(pts[:, :2])).min()
    return out


def motion_from_bvh(
    path,
    skeleton: Skeleton,
    fps: float,
    frame_count: int | None = None,
    name_map: dict | None = None,
    up_axis: str = "Y",
    forward_axis: str = "Z",
    scale: float | None = None,
    recenter: bool = True,
    settle: bool = True,
    activity: str = "walk",
    mass_kg: float = 75.0,
    ground=None,
    body_points=None,
    align=ALIGN,
    bvh: BVH | None = None,
    lock_feet: bool = True,
):
    """A :class:`humv_usd.human.motion.Motion` from a BVH file retargeted onto ``skeleton``
    and resampled to ``fps`` (``frame_count`` frames; default: the file's duration).

    recenter: move the first frame's root ground position onto our rest Hips position (the
    BVH's vertical is kept: its floor is assumed at up = 0, as in CMU files). settle: shift
    the root vertically so planted feet (lowest point within 5 cm of the ground, moving
    < 0.25 m/s) touch the ground and no foot is under it (:func:`contact.settle_root`; the
    proportions of the two rigs differ, so scaled mocap floats or sinks by a few cm).
    lock_feet: the feet planted after settling (lowest point within 2 cm of the ground and
    slower than 0.25 m/s or 0.3 x the body's pace, runs shorter than 0.1 s dropped) are locked by :func:`contact.lock_feet`: heading frozen, rolling without
    slipping, lowest point on the ground, legs re-posed by IK; below 30 fps this runs at the
    smallest integer multiple of ``fps`` >= 30 and every k-th frame is kept (as the built-in
    motions). False: the source's own sliding is kept and only reported. The metabolic rate
    uses ``activity`` with the clip's mean horizontal root speed (walk/run) or the standing
    rate.
    """

    src = bvh if bvh is not None else read_bvh(path)
    rt = build_retarget(src, skeleton, name_map, up_axis, forward_axis, scale, align)
    local, root = retarget(src, skeleton, rt)
    if recenter:
        root[:, :2] += skeleton.rest_positions[0, :2] - root[0, :2]
    quats = _continuous(matrix_to_quat(local))
    t_src = np.arange(src.frame_count) * src.frame_time
    if frame_count is None:
        frame_count = int(np.floor(t_src[-1] * fps + 1e-3)) + 1
    times = np.arange(int(frame_count)) / fps
    # the foot lock works frame to frame: below SIM_FPS_MIN on k * fps, every k-th frame kept
    k = max(int(np.ceil(SIM_FPS_MIN / fps - 1e-9)), 1) if lock_feet else 1
    sim_fps = k * float(fps)
    q, r = resample(t_src, quats, root, np.arange((int(frame_count) - 1) * k + 1) / sim_fps)
    q = _continuous(q)
    # contact report with detected stance
    feet = (
        C.foot_points_from_body(skeleton, body_points)
        if body_points is not None
        else C.foot_points_from_joints(skeleton)
    )
    g = C.Ground(ground)
    rot = quat_to_matrix(q)
    wr, wp = fk_matrices(skeleton, rot, rot[:, 0], r)
    off, stance = C.settle_root(g, feet, wr, wp, sim_fps)
    # nothing else under the ground either: lying, crawling and get-up clips rest on other body
    # parts while the feet are in the air, where settle_root alone would pull the body down
    # until a foot touches the ground (the body's surface when given, else its joints)
    off = np.maximum(off, -_lowest_above_ground(skeleton, body_points, wr, wp, g))
    if settle:
        r[:, 2] += off
        wp[..., 2] += off[:, None]
    supports: dict = {}
    if lock_feet:
        # a planted foot: near the ground and slow, for the body's pace (a run's skating
        # stance foot moves faster than a walker's lifting one)
        pace = np.linalg.norm(np.gradient(r[:, :2], axis=0), axis=1) * sim_fps
        tol = np.maximum(
            C.LOCK_SPEED_M_S, C.LOCK_SPEED_SHARE * gaussian_filter1d(pace, sim_fps / 2, mode="nearest")
        )
        _, planted = C.settle_root(g, feet, wr, wp, sim_fps, speed_tol=tol, near=C.LOCK_NEAR_M)
        stance = {s: C.clean_stance(m, sim_fps) for s, m in planted.items()}
        rot, r, locked = C.lock_feet(skeleton, g, feet, rot, rot[:, 0], r, stance, sim_fps)
        if body_points is not None:  # knees and hands that support the body (a crawl) held too
            rot, r, supports = lock_supports(
                skeleton, g, body_points_of(skeleton, body_points), rot, rot[:, 0], r, sim_fps, locked
            )
        q = _continuous(matrix_to_quat(rot))
        wr, wp = fk_matrices(skeleton, rot, rot[:, 0], r)
    else:
        locked = {s: np.zeros_like(m) for s, m in stance.items()}
    keep = slice(0, None, k)
    supports = {n: m[keep] for n, m in supports.items()}
    q, r, wr, wp = _continuous(q[keep]), r[keep], wr[keep], wp[keep]
    locked = {s: m[keep] for s, m in locked.items()}
    stance = {s: m[keep] for s, m in stance.items()}
    report = C.contact_report(g, feet, wr, wp, stance)
    speed = float(np.linalg.norm(r[-1, :2] - r[0, :2]) / max(times[-1], 1e-9)) if len(times) > 1 else 0.0
    act = activity if activity in ("walk", "run") else "stand"
    rate = metabolic_rate(act, mass_kg, times, speed)
    info = {
        "source": str(src.path),
        "bvh_fps": src.fps,
        "bvh_frames": src.frame_count,
        "scale_m_per_unit": rt.scale,
        "mapped": {skeleton.names[j]: src.joints[b].name for j, b in rt.source.items()},
        "stance": {s.lower(): m for s, m in stance.items()},
        "locked": {s.lower(): m for s, m in locked.items()},  # the planted runs the lock kept
        "supports": supports,  # knee and hand support runs; the hands held (humv_usd.human.limbs)
        "speed_m_s": speed,
    }
    return Motion(float(fps), r, q, activity, rate, report, info)

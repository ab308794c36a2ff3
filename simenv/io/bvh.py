"""BVH (Biovision Hierarchy) reader.

Reads any channel layout: 0-6 channels per joint, position and rotation
channels in any order, several roots, ``End Site`` leaves, LF/CRLF/CR line
endings. Joint positions follow from forward kinematics (vectorised over
frames, see :mod:`simenv.io._kinematics`) with the BVH conventions:

* a joint's rotation channels listed as ``Zrotation Yrotation Xrotation``
  give the local rotation ``R = R_Z(z) @ R_Y(y) @ R_X(x)`` (intrinsic, in
  listed order, degrees);
* position channels *replace* the matching components of the joint's
  OFFSET (for CMU files the root OFFSET is zero, so this is the same as
  adding them);
* a joint sits at its parent's position plus the parent's world rotation
  applied to its (translated) offset.

The result is converted to simenv conventions: metres (units detected from
the skeleton's size, see :func:`simenv.io._kinematics.detect_units`) and
Z-up (a Y-up file is mapped by ``(x, y, z) -> (x, -z, y)``). Local rotations
are returned as quaternions expressed in the converted frame, i.e.
``C R C^T`` with ``C`` the axis change, so FK with the converted offsets
(``metadata["offsets_m"]``) reproduces the positions.

End Sites: kept as joints named ``<parent>_end`` only when a canonical
keypoint needs one (the Poser/Second-Life template's toes are its foot End
Sites) or when ``end_sites=True``. CMU skeletons therefore keep their 31
joints, whose positions are the *start* of each named bone.

Source quirks are detected and written to ``metadata["quirks"]``: the
T-pose frame 0 the cgspeed converter prepends (dropped by default),
template skeletons that are not the performer's proportions, header frame
rates that were overridden, unusual sizes.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import FormatError, UnitsError
from simenv.core.joint_map import (
    JointMapping,
    JointMapSource,
    infer_joint_map,
    user_joint_mapping,
)
from simenv.core.motion import Motion
from simenv.core.skeletons import (
    CANONICAL_TREE,
    Skeleton,
    cmu_canonical_map,
    is_poser_template,
    poser_canonical_map,
)
from simenv.io._kinematics import (
    CMU_UNIT_M,
    detect_units,
    euler_to_matrices,
    forward_kinematics,
    is_tpose_frame0,
    matrices_to_quaternions,
    posed_extents,
    rest_extent,
    rest_extents,
    rigid_bones,
    to_z_up_metres,
    units_metadata,
)
from simenv.io._text import parse_float, parse_float_rows, read_text, split_lines

FORMAT = "bvh"
EXTENSIONS = (".bvh",)

_CHANNELS = {
    "xposition": ("p", "X"),
    "yposition": ("p", "Y"),
    "zposition": ("p", "Z"),
    "xrotation": ("r", "X"),
    "yrotation": ("r", "Y"),
    "zrotation": ("r", "Z"),
}

#: Snap a header rate to the nearest integer when within this relative
#: distance (``Frame Time: .0083333`` is 120.0005 fps).
_FPS_SNAP = 1e-3


@dataclass
class _Joint:
    name: str
    parent: int
    line: int
    end_site: bool = False
    offset: np.ndarray | None = None
    channels: list[str] = field(default_factory=list)


@dataclass
class BvhFile:
    """Raw content of a BVH file, in file units and file axes.

    Attributes:
        joints: joint names, End Sites included as ``<parent>_end``.
        parents: (J,) parent indices.
        end_site: (J,) True for End Site joints.
        offsets: (J, 3) OFFSETs, file units.
        channels: per joint, channel names (``"Xposition"``...).
        frame_time: seconds per frame from the header.
        data: (T, C) channel values, rows = frames.
    """

    joints: list[str]
    parents: list[int]
    end_site: list[bool]
    offsets: np.ndarray
    channels: list[list[str]]
    frame_time: float
    data: np.ndarray


def sniff(path: Path, head: bytes) -> bool:
    """True when the file starts with the ``HIERARCHY`` keyword."""
    return head.lstrip(b"\xef\xbb\xbf \t\r\n")[:9].upper() == b"HIERARCHY"


def parse(path: Path) -> BvhFile:
    """Parse a BVH file without interpreting it (no units, no FK).

    Raises:
        FormatError: naming file and line for a missing HIERARCHY/MOTION
            section, bad tokens, wrong channel counts, duplicate joint names,
            a ``Frames:`` count that does not match the data lines, zero
            frames or non-numeric values.
    """
    path = Path(path)
    lines = split_lines(read_text(path))
    first = next((i for i, ln in enumerate(lines) if ln.strip()), None)
    if first is None or lines[first].split()[0].lstrip("\ufeff").upper() != "HIERARCHY":
        raise FormatError(
            "expected the file to start with 'HIERARCHY'",
            source=path,
            line=1 if first is None else first + 1,
        )
    motion_line = None
    for i, text in enumerate(lines):
        if text.strip().upper() == "MOTION":
            motion_line = i
            break
    if motion_line is None:
        raise FormatError(
            "no MOTION section; expected a line 'MOTION' after the hierarchy", source=path
        )
    joints = _Hierarchy(lines[:motion_line], path).parse()
    frame_time, data_start, n_frames = _parse_motion_header(lines, motion_line, path)
    names = [j.name for j in joints]
    field_names = [f"{j.name}.{c}" for j in joints for c in j.channels]
    n_ch = len(field_names)
    rows: list[list[str]] = []
    row_lines: list[int] = []
    for i in range(data_start, len(lines)):
        toks = lines[i].split()
        if not toks:
            continue
        if len(toks) != n_ch:
            raise FormatError(
                f"expected {n_ch} channel values (as declared in the hierarchy), found "
                f"{len(toks)}" + (" (truncated file?)" if len(toks) < n_ch else ""),
                source=path,
                line=i + 1,
                frame=len(rows),
            )
        rows.append(toks)
        row_lines.append(i + 1)
    if len(rows) != n_frames:
        raise FormatError(
            f"header says Frames: {n_frames} but the file has {len(rows)} data lines"
            + (" (truncated file?)" if len(rows) < n_frames else ""),
            source=path,
            line=data_start,
        )
    if n_ch == 0:
        data = np.zeros((n_frames, 0))
    else:
        data = parse_float_rows(rows, source=path, lines=row_lines, field_names=field_names)
    return BvhFile(
        joints=names,
        parents=[j.parent for j in joints],
        end_site=[j.end_site for j in joints],
        offsets=np.array([j.offset for j in joints], dtype=np.float64),
        channels=[j.channels for j in joints],
        frame_time=frame_time,
        data=data,
    )


class _Hierarchy:
    """Parser of the HIERARCHY section, token by token: one method per keyword (ROOT or
    JOINT, End Site, OFFSET, CHANNELS, the closing brace) on a stack of open joints.
    ``i`` is the index of the next token; every error names the file and line."""

    def __init__(self, lines: list[str], path: Path) -> None:
        self.toks = [(tok, i + 1) for i, text in enumerate(lines) for tok in text.split()]
        self.path = path
        self.joints: list[_Joint] = []
        self.seen: dict[str, int] = {}
        self.stack: list[int] = []
        self.i = 1

    def error(self, message: str, line: int, **where: Any) -> FormatError:
        return FormatError(message, source=self.path, line=line, **where)

    def parse(self) -> list[_Joint]:
        toks = self.toks
        if not toks or toks[0][0].lstrip("\ufeff").upper() != "HIERARCHY":
            raise self.error("expected the file to start with 'HIERARCHY'",
                             toks[0][1] if toks else 1)
        keywords = {"ROOT": self.joint, "JOINT": self.joint, "END": self.end_site,
                    "OFFSET": self.offset, "CHANNELS": self.channels}
        while self.i < len(toks):
            tok, line = toks[self.i]
            if tok.upper() in keywords:
                keywords[tok.upper()](tok, line)
            elif tok == "}":
                self.close(line)
            else:
                raise self.error(
                    f"unexpected token {tok[:40]!r} in hierarchy; expected ROOT, JOINT, "
                    "End Site, OFFSET, CHANNELS or a brace", line)
        if self.stack:
            last = self.joints[self.stack[-1]]
            raise self.error(f"joint {last.name!r} is not closed by '}}' before "
                             "MOTION (truncated hierarchy?)", last.line)
        if not self.joints:
            raise self.error("hierarchy defines no joints; expected a ROOT", toks[0][1])
        return self.joints

    def need(self, k: int, what: str) -> tuple[str, int]:
        """Token ``k``; an error when the hierarchy ends before it."""
        if k >= len(self.toks):
            raise self.error(f"hierarchy ends early; expected {what} (truncated file?)",
                             self.toks[-1][1])
        return self.toks[k]

    def open(self, name: str, line: int, end_site: bool) -> None:
        """A new joint, child of the innermost open one, now open itself."""
        if name in self.seen:
            raise self.error(f"duplicate joint name {name!r} (first defined on line "
                             f"{self.seen[name]}); joint names must be unique", line,
                             field=name)
        self.seen[name] = line
        self.joints.append(_Joint(name, self.stack[-1] if self.stack else -1, line, end_site))
        self.stack.append(len(self.joints) - 1)

    def brace(self, k: int, after: str) -> None:
        """Token ``k`` must open the block just declared."""
        brace, bline = self.need(k, "'{'")
        if brace != "{":
            raise self.error(f"expected '{{' after {after}, found {brace[:40]!r}", bline)

    def current(self, keyword: str, line: int) -> _Joint:
        """The innermost open joint, which ``keyword`` describes."""
        if not self.stack:
            raise self.error(f"{keyword} outside a joint", line)
        return self.joints[self.stack[-1]]

    def joint(self, tok: str, line: int) -> None:
        key = tok.upper()
        if key == "JOINT" and not self.stack:
            raise self.error("JOINT outside any ROOT block", line)
        if key == "ROOT" and self.stack:
            raise self.error("ROOT inside another joint; missing '}'?", line)
        k = self.i + 1
        name_parts = []
        while k < len(self.toks) and self.toks[k][1] == line and self.toks[k][0] != "{":
            name_parts.append(self.toks[k][0])
            k += 1
        if not name_parts:
            raise self.error(f"{tok} without a name", line)
        if self.stack and self.joints[self.stack[-1]].end_site:
            raise self.error("joint inside an End Site", line)
        self.open(" ".join(name_parts), line, False)
        self.brace(k, f"{tok} {' '.join(name_parts)}")
        self.i = k + 1

    def end_site(self, tok: str, line: int) -> None:
        site, sline = self.need(self.i + 1, "'Site'")
        if site.upper() != "SITE":
            raise self.error(f"expected 'End Site', found 'End {site[:40]}'", sline)
        if not self.stack or self.joints[self.stack[-1]].end_site:
            raise self.error("End Site outside a joint", line)
        name = f"{self.joints[self.stack[-1]].name}_end"
        while name in self.seen:
            name += "_"
        self.open(name, line, True)
        self.brace(self.i + 2, "End Site")
        self.i += 3

    def offset(self, tok: str, line: int) -> None:
        joint = self.current("OFFSET", line)
        if joint.offset is not None:
            raise self.error(f"second OFFSET for joint {joint.name!r}", line, field=joint.name)
        vals = []
        for k in range(3):
            t, tl = self.need(self.i + 1 + k, "3 OFFSET values")
            vals.append(parse_float(t, source=self.path, line=tl,
                                    field=f"{joint.name} OFFSET"))
        joint.offset = np.array(vals)
        self.i += 4

    def channels(self, tok: str, line: int) -> None:
        joint = self.current("CHANNELS", line)
        count_tok, cline = self.need(self.i + 1, "a channel count")
        if not count_tok.isdecimal() or int(count_tok) > 6:
            raise self.error(f"expected a channel count 0-6, found {count_tok[:40]!r}", cline,
                             field=joint.name)
        count = int(count_tok)
        if joint.end_site and count:
            raise self.error("End Site cannot have channels", line)
        if joint.channels:
            raise self.error(f"second CHANNELS for joint {joint.name!r}", line,
                             field=joint.name)
        chans: list[str] = []
        for k in range(count):
            c, cl = self.need(self.i + 2 + k, f"{count} channel names")
            if c.lower() not in _CHANNELS:
                raise self.error(
                    f"CHANNELS {count} declares {count} channels but found {c[:40]!r} "
                    f"among them; expected names like Xposition or Zrotation", cl,
                    field=joint.name)
            if c.lower() in (x.lower() for x in chans):
                raise self.error(f"channel {c} repeated", cl, field=joint.name)
            chans.append(c)
        joint.channels = chans
        self.i += 2 + count

    def close(self, line: int) -> None:
        if not self.stack:
            raise self.error("unbalanced '}'", line)
        joint = self.joints[self.stack.pop()]
        if joint.offset is None:
            raise self.error(f"joint {joint.name!r} has no OFFSET", joint.line, field=joint.name)
        self.i += 1


def _parse_motion_header(lines: list[str], motion_line: int, path: Path) -> tuple[float, int, int]:
    """Returns (frame time s, index of first data line, number of frames)."""
    i = motion_line + 1
    found: dict[str, tuple[str, int]] = {}
    for label in ("frames:", "frame time:"):
        while i < len(lines) and not lines[i].strip():
            i += 1
        if i >= len(lines):
            raise FormatError(
                f"MOTION section ends before '{label[:-1].title()}:' (truncated file?)",
                source=path,
                line=len(lines),
            )
        text = lines[i].strip()
        if not text.lower().startswith(label):
            raise FormatError(
                f"expected '{label[:-1].title()}: <value>', found {text[:40]!r}",
                source=path,
                line=i + 1,
            )
        found[label] = (text[len(label) :].strip(), i + 1)
        i += 1
    frames_tok, fline = found["frames:"]
    if not frames_tok.isdecimal():
        raise FormatError(
            f"expected an integer frame count, found {frames_tok[:40]!r}",
            source=path,
            line=fline,
            field="Frames",
        )
    n_frames = int(frames_tok)
    if n_frames == 0:
        raise FormatError(
            "file has 0 frames; expected at least 1", source=path, line=fline, field="Frames"
        )
    ft_tok, ftline = found["frame time:"]
    frame_time = parse_float(ft_tok, source=path, line=ftline, field="Frame Time")
    if frame_time <= 0 or not np.isfinite(1.0 / frame_time):
        raise FormatError(
            f"Frame Time must be positive seconds, found {ft_tok!r}",
            source=path,
            line=ftline,
            field="Frame Time",
        )
    return frame_time, i, n_frames


def header_fps(frame_time: float) -> float:
    """Frame rate from a header frame time, snapped to an integer when the
    header rounds it (``.0083333`` -> 120)."""
    fps = 1.0 / frame_time
    r = round(fps)
    return float(r) if r > 0 and abs(fps - r) <= _FPS_SNAP * r else fps


def skeleton_variant(names: list[str]) -> str:
    """Short name of a known skeleton layout, from its joint names."""
    s = set(names)
    if is_poser_template(names):
        return "poser"
    if {"LHipJoint", "LeftUpLeg"} <= s:
        return "cmu_mb"
    if {"LeftCollar", "LeftHip"} <= s:
        return "cmu_max"
    if {"lfemur", "ltibia"} <= s:
        return "cmu_asf"
    return "bvh"


def canonical_map(names: list[str]) -> dict[str, str]:
    """Canonical keypoint map for a BVH joint list (CMU or Poser namings)."""
    if is_poser_template(names):
        return poser_canonical_map(names)
    return cmu_canonical_map(names)


#: Least height of the head over the feet in a standing rest pose, as a fraction of the rest
#: pose's size (:func:`~simenv.io._kinematics.rest_extent`): a standing body's head is about
#: 0.85 of its height over its ankles; a folded rest (limbs up beside the head) puts them level.
REST_HEAD_OVER_FEET = 0.4


def _head_over_feet(bvh: BvhFile, pos: np.ndarray) -> np.ndarray | None:
    """(T, 3) head minus the ankles' (else toes') midpoint, file units and axes, when the
    names give a head and both ankles or toes (names alone: positions are not needed)."""
    canon = infer_joint_map(bvh.joints, bvh.parents).canonical
    index = {n: i for i, n in enumerate(bvh.joints)}
    for feet in (("left_ankle", "right_ankle"), ("left_toe", "right_toe")):
        if "head" in canon and all(f in canon for f in feet):
            mid = 0.5 * sum(pos[:, index[canon[f]]] for f in feet)
            return pos[:, index[canon["head"]]] - mid
    return None


def _posed_if_rest_lies(bvh: BvhFile, quirks: list[str]) -> np.ndarray | None:
    """The (T, J, 3) positions of the motion, file units and axes, when the all-zero rest
    pose is no standing body: its head not above its feet along Y or Z by half their
    distance (a rig whose joints carry their own axes writes every OFFSET along the joint's
    X: SNU Motion Database), or by less than :data:`REST_HEAD_OVER_FEET` of the rest pose's
    size (every OFFSET along +Y, arms and legs pointing up beside the head: Berkeley MHAD's
    skeletons, whose folded rest is about 1 m tall for a 1.7-m person). None for a standing
    rest pose (then the rest pose says the up axis and the size, as before) or when the
    names give no head and feet."""
    rest = np.broadcast_to(np.eye(3), (1, len(bvh.joints), 3, 3))
    rest_pos, _ = forward_kinematics(bvh.parents, bvh.offsets, rest)
    v = _head_over_feet(bvh, rest_pos)
    if v is None:
        return None
    v = v[0]
    rise = max(v[1], v[2])
    if (rise > 0.5 * np.linalg.norm(v)
            and rise > REST_HEAD_OVER_FEET * rest_extent(bvh.parents, bvh.offsets)):
        return None
    local, offsets, translations = _local_rotations(bvh, bvh.offsets)
    pos, _ = forward_kinematics(bvh.parents, offsets, local, translations)
    quirks.append("rest pose is no standing body (head not above the feet with every "
                  "rotation zero: the joints carry their own axes): up axis and units "
                  "measured on the motion")
    return pos


def _up_from_motion(bvh: BvhFile, pos: np.ndarray) -> str:
    """The up axis along which the head stands over the feet in the motion (median over
    frames of :func:`_head_over_feet` on ``pos``), for a rest pose that is no standing
    body (:func:`_posed_if_rest_lies`)."""
    v = _head_over_feet(bvh, pos)
    assert v is not None  # _posed_if_rest_lies found the head and the feet
    m = np.median(v, axis=0)
    return "z" if m[2] > m[1] else "y"


def _units_from_motion(bvh: BvhFile, pos: np.ndarray, height: float, path: Path,
                       units: str | None, scale: float | None
                       ) -> tuple[str, float, str, list[str]]:
    """:func:`detect_units` on the body's size in the motion (:func:`posed_extents` of
    ``pos``, file units) for a rest pose that is no standing body; on the rest pose's size
    ``height`` when the caller gave the unit or the motion's size is no person either."""
    if units is not None or scale is not None:
        return detect_units(height, source=path, units=units, scale=scale)
    size = float(posed_extents(bvh.parents, pos).max())
    try:
        name, s, reason, notes = detect_units(size, source=path)
    except UnitsError:
        return detect_units(height, source=path)
    reason = reason.replace("rest-pose size", "size in the motion", 1)
    return name, s, (f"{reason} (the all-zero rest pose, {height:.4g} file units across, is "
                     "no standing body)"), notes


def _detect_up(bvh: BvhFile, quirks: list[str]) -> str:
    """The file's up axis: ``"y"`` (the BVH standard) unless the rest pose stands along Z
    (its Z side over 1.5 times its Y side; a T-pose's depth is a fraction of its height),
    as Z-up exporters (Blender, 3ds Max, some capture suites) write it."""
    sides = rest_extents(bvh.parents, bvh.offsets)
    if sides[2] > 1.5 * sides[1]:
        quirks.append(f"up axis Z: the rest pose stands along Z ({sides[2]:.3g} file units) "
                      f"and is {sides[1]:.3g} deep along Y (read with up='y' to override)")
        return "z"
    return "y"


def _up_checked_on_motion(bvh: BvhFile, pos: np.ndarray, up: str, quirks: list[str]) -> str:
    """``up`` (from the rest pose, :func:`_detect_up`) unless the motion stands along the
    other axis: the median over frames of the head over the feet (``pos``, file units and
    axes) rises along it by more than half its length and along ``up`` by less. A root
    rotation can stand a rest pose up along another axis on every frame (a Shadow-suit
    export: rest along Z, every frame along Y); the motion is what is judged. A clip that
    stands along neither (lying, crawling) keeps the rest pose's axis."""
    v = _head_over_feet(bvh, pos)
    if v is None:
        return up
    m = np.median(v, axis=0)
    half = 0.5 * float(np.linalg.norm(m))
    axis = {"y": 1, "z": 2}
    other = "y" if up == "z" else "z"
    if m[axis[other]] <= half or m[axis[up]] > half:
        return up
    quirks[:] = [q for q in quirks if not q.startswith("up axis Z: the rest pose")]
    quirks.append(f"up axis {other.upper()} from the motion: the rest pose stands along "
                  f"{up.upper()}, but the root's rotation stands every frame up along "
                  f"{other.upper()} (median head over feet {m[axis[other]]:.3g} file units; "
                  f"read with up='{up}' to override)")
    return other


def _joint_map(bvh: BvhFile, pos: np.ndarray, joint_map: JointMapSource | None, path: Path
               ) -> tuple[dict[str, str], JointMapping | None]:
    """The canonical map of every joint of the file (End Sites included, as
    ``<parent>_end``) and, when it did not come from the CMU/Poser tables, how it was
    found: the user's ``joint_map``, or, for any skeleton but the CMU conversions',
    :func:`~simenv.core.joint_map.infer_joint_map` on the names, the hierarchy and ``pos``
    (T, J, 3) metres, Z up."""
    if joint_map is not None:
        mapping = user_joint_mapping(bvh.joints, joint_map, source=str(path))
        return dict(mapping.canonical), mapping
    if skeleton_variant(bvh.joints) != "bvh":  # a CMU conversion: its own tables
        return canonical_map(bvh.joints), None
    mapping = infer_joint_map(bvh.joints, bvh.parents, pos)
    return dict(mapping.canonical), mapping


def _avoid_coincident(
    canon: dict[str, str], names: list[str], parents: list[int], rest: np.ndarray,
    cmu: bool = True,
) -> tuple[dict[str, str], list[str]]:
    """Keep canonical keypoints off zero-length bones.

    The CMU BVH converters collapse the ASF ``thorax`` and ``wrist`` bones:
    ``Neck`` sits on ``Spine1`` and ``LeftFingerBase`` on ``LeftHand``, so
    the canonical neck/hand would coincide with chest/wrist. Such a keypoint
    moves down its joint's single-child chain to the first joint that is
    apart from the canonical parent (``Neck1``, ``LeftHandIndex1``); with no
    such chain it is declared missing. Returns the map and quirk notes (``cmu``: the
    notes explain the CMU converters' collapsed bones; else they only say what moved).
    """
    index = {n: i for i, n in enumerate(names)}
    children: dict[int, list[int]] = {}
    for k, p in enumerate(parents):
        children.setdefault(p, []).append(k)
    extent = float(np.ptp(rest, axis=0).max()) or 1.0
    out = dict(canon)
    notes = []
    for key, joint in canon.items():
        parent_key = CANONICAL_TREE.get(key)
        if parent_key is None or parent_key not in canon:
            continue
        anchor = rest[index[canon[parent_key]]]
        j = index[joint]
        while np.linalg.norm(rest[j] - anchor) < 1e-4 * extent:
            kids = children.get(j, [])
            if len(kids) != 1:
                j = -1
                break
            j = kids[0]
        if j < 0:
            del out[key]
            notes.append(
                f"canonical {key} dropped: joint {joint} coincides with "
                f"{canon[parent_key]} ({parent_key})"
            )
        elif names[j] != joint and not cmu:
            out[key] = names[j]
            notes.append(f"canonical {key} -> {names[j]}: {joint} coincides with "
                         f"{canon[parent_key]} ({parent_key}) in the file")
        elif names[j] != joint:
            out[key] = names[j]
            notes.append(
                f"canonical {key} -> {names[j]}: {joint} coincides with "
                f"{canon[parent_key]} ({parent_key}), a bone the converter collapsed: its "
                "offset is zero in the file, so every joint below it is displaced by the "
                "missing bone's length (the CMU cgspeed and ASF-name conversions drop the "
                "thorax, ~12 cm, and the wrist bone, half the forearm: upper body low, "
                "forearms short; measured on 02_01 against its ASF/AMC)"
            )
    return out, notes


#: The bones the CMU BVH converters collapse, per joint naming
#: (:func:`skeleton_variant`): ``(bone, parent joint, zero-offset children)``.
#: The thorax sits at the end of the upper back, its children (neck and both
#: clavicles) at the end of the thorax; each wrist bone starts at the end of
#: the forearm, the hand and the thumb start at its end.
_COLLAPSED_BONES: dict[str, tuple[tuple[str, str, tuple[str, ...]], ...]] = {
    "cmu_mb": (
        ("thorax", "Spine1", ("Neck", "LeftShoulder", "RightShoulder")),
        ("lwrist", "LeftHand", ("LeftFingerBase", "LThumb")),
        ("rwrist", "RightHand", ("RightFingerBase", "RThumb")),
    ),
    "cmu_max": (
        ("thorax", "Chest2", ("lowerneck", "LeftCollar", "RightCollar")),
        ("lwrist", "LeftWrist", ("lhand", "LThumb")),
        ("rwrist", "RightWrist", ("rhand", "RThumb")),
    ),
    "cmu_asf": (
        ("thorax", "thorax", ("lowerneck", "lclavicle", "rclavicle")),
        ("lwrist", "lwrist", ("lhand", "lthumb")),
        ("rwrist", "rwrist", ("rhand", "rthumb")),
    ),
}


def _restore_collapsed(bvh: BvhFile, s: float) -> tuple[np.ndarray, list[str], list[str]]:
    """Offsets with the CMU converters' collapsed thorax and wrist bones
    restored, the repair notes and the notes on what was left alone.

    The thorax becomes a copy of the parent's own offset (the upper back:
    the ASF thorax is 0.997-1.034 times the upper back over six CMU
    skeletons, and nearly parallel to it); the wrist becomes half the
    forearm offset, along the forearm (exact: every CMU ASF wrist is half
    its radius).
    """
    offsets = bvh.offsets.copy()
    variant = skeleton_variant(bvh.joints)
    groups = _COLLAPSED_BONES.get(variant)
    if groups is None:
        return (
            offsets,
            [],
            [
                f"restore_collapsed_bones: nothing restored: the joint names ({variant} "
                "layout) are not one of the CMU conversions whose thorax and wrist bones are "
                "known to be collapsed"
            ],
        )
    index = {n: i for i, n in enumerate(bvh.joints)}
    extent = rest_extent(bvh.parents, bvh.offsets) or 1.0
    tol = 1e-6 * extent
    repairs: list[str] = []
    skipped: list[str] = []
    for bone, parent, kids in groups:
        missing = [n for n in (parent, *kids) if n not in index]
        if missing:
            skipped.append(
                f"restore_collapsed_bones: {bone} not restored: no joint {', '.join(missing)}"
            )
            continue
        p = index[parent]
        wrong = [n for n in kids if bvh.parents[index[n]] != p]
        nonzero = [n for n in kids if np.linalg.norm(bvh.offsets[index[n]]) > tol]
        length = float(np.linalg.norm(bvh.offsets[p]))
        if wrong or nonzero or length <= tol:
            why = (
                f"{', '.join(wrong)} not a child of {parent}"
                if wrong
                else f"{', '.join(nonzero)} already has a non-zero offset"
                if nonzero
                else f"{parent} has a zero offset to copy from"
            )
            skipped.append(f"restore_collapsed_bones: {bone} not restored: {why}")
            continue
        if bone == "thorax":
            new = bvh.offsets[p]
            source = (
                f"a copy of the upper-back offset ({parent}'s, {length * s * 100:.1f} cm; "
                "the ASF thorax is 0.997-1.034 x the upper back in CMU skeletons, so "
                "joints below it are placed to ~1 cm)"
            )
        else:
            new = bvh.offsets[p] / 2.0
            source = (
                f"half the forearm offset ({parent}'s, {length * s * 100:.1f} cm), along "
                "the forearm (every CMU ASF wrist is half its forearm)"
            )
        for n in kids:
            offsets[index[n]] = new
        repairs.append(
            f"restored collapsed {bone} bone: {', '.join(kids)} offset set from 0 to "
            f"{float(np.linalg.norm(new)) * s * 100:.1f} cm from {parent}, {source}; "
            "every joint below it moved accordingly (restore_collapsed_bones=True)"
        )
    return offsets, repairs, skipped


def read(
    path: Path,
    *,
    units: str | None = None,
    scale: float | None = None,
    up: str | None = None,
    drop_tpose: bool = True,
    fps: float | None = None,
    end_sites: bool | None = None,
    name: str | None = None,
    restore_collapsed_bones: bool = False,
    joint_map: JointMapSource | None = None,
) -> Motion:
    """Read a BVH file as a :class:`Motion` (metres, Z-up).

    Args:
        path: the .bvh file.
        units: force a length unit (``"m"``, ``"cm"``, ``"mm"``, ``"inch"``,
            ``"cmu"``) instead of detecting it from the skeleton size.
        scale: force metres per file unit (overrides ``units``).
        up: up axis of the file, ``"y"`` (BVH standard) or ``"z"``; None
            detects it from the rest pose (Y unless the body stands along Z,
            noted in ``metadata["quirks"]``).
        drop_tpose: drop a detected converter T-pose at frame 0 (noted in
            ``metadata["quirks"]``); when False it is kept and still noted.
        fps: override the header frame rate (noted as a quirk).
        end_sites: keep all (True), no (False) or only canonically needed
            (None) End Sites as joints ``<parent>_end``.
        name: clip name; default the file stem.
        restore_collapsed_bones: opt-in repair of the CMU BVH conversions
            (cgspeed Motionbuilder-friendly ``Spine1``/``LeftFingerBase``
            names, 3dsMax-friendly ``Chest2``/``lhand``, ASF names
            ``thorax``/``lhand``) that write a zero OFFSET where the ASF
            skeleton has a bone, displacing every joint below it (upper body
            ~12 cm low, forearms short). The wrist bone is set to half the
            forearm offset, along the forearm (exact for CMU skeletons); the
            thorax to a copy of the skeleton's own upper-back offset (the
            ASF thorax is 0.997-1.034 times it, so shoulders, elbows and
            wrists land within ~1-2 cm of the ASF/AMC; legs and root are
            unchanged). Each restored bone, with its length, is listed in
            ``metadata["repairs"]``; a hierarchy that is not such a
            conversion (or a bone that is not collapsed) is left unchanged
            and said so in ``metadata["quirks"]``. Units are detected from
            the file's own offsets either way. Default False: the file as
            written.
        joint_map: the canonical map to use (a TOML file or a mapping, see
            :func:`simenv.core.joint_map.read_joint_map`; End Sites are
            ``<parent>_end``). Default: the CMU/Poser tables for those
            skeletons, else :func:`simenv.core.joint_map.infer_joint_map`
            (names, hierarchy, pose), recorded in ``metadata["joint_map"]``.

    Returns:
        Motion with positions (T, J, 3) float32 metres, rotations (T, J, 4)
        local quaternions (w, x, y, z), metadata ``source``, ``format``,
        ``subject``, ``units``, ``units_reason``, ``scale_m_per_unit``,
        ``up_axis_in_file``, ``header_fps``, ``frames_in_file``,
        ``tpose_frame0``, ``offsets_m`` (J x 3 list) and ``quirks``; with
        ``restore_collapsed_bones=True`` also ``repairs`` (``offsets_m``
        then holds the restored offsets).
    """
    path = Path(path)
    if up is not None and up.lower() not in ("y", "z"):
        raise FormatError(f"up must be 'y', 'z' or None (detect); got {up!r}", source=path)
    bvh = parse(path)
    with np.errstate(all="ignore"):
        return _to_motion(
            bvh,
            path,
            units=units,
            scale=scale,
            up=None if up is None else up.lower(),
            drop_tpose=drop_tpose,
            fps=fps,
            end_sites=end_sites,
            name=name,
            restore_collapsed_bones=restore_collapsed_bones,
            joint_map=joint_map,
        )


def _to_motion(
    bvh: BvhFile,
    path: Path,
    *,
    units: str | None,
    scale: float | None,
    up: str | None,
    drop_tpose: bool,
    fps: float | None,
    end_sites: bool | None,
    name: str | None,
    restore_collapsed_bones: bool = False,
    joint_map: JointMapSource | None = None,
) -> Motion:
    quirks: list[str] = []
    height = rest_extent(bvh.parents, bvh.offsets)
    posed = _posed_if_rest_lies(bvh, quirks)
    rest_up = up is None and posed is None
    if up is None:
        up = _detect_up(bvh, quirks) if posed is None else _up_from_motion(bvh, posed)
    unit_name, s, reason, unit_quirks = (
        detect_units(height, source=path, units=units, scale=scale) if posed is None
        else _units_from_motion(bvh, posed, height, path, units, scale))
    quirks += unit_quirks

    repairs: list[str] | None = None
    file_offsets = bvh.offsets
    if restore_collapsed_bones:
        file_offsets, repairs, skipped = _restore_collapsed(bvh, s)
        quirks += skipped
    local, offsets, translations = _local_rotations(bvh, file_offsets)
    pos, _ = forward_kinematics(bvh.parents, offsets, local, translations)
    if rest_up:
        up = _up_checked_on_motion(bvh, pos, up, quirks)
    pos, local, offsets_m = to_z_up_metres(pos, local, file_offsets, up, s)

    all_canon, mapping = _joint_map(bvh, pos, joint_map, path)
    needed = set(all_canon.values())
    keep = [
        not es or end_sites is True or (end_sites is None and n in needed)
        for n, es in zip(bvh.joints, bvh.end_site, strict=True)
    ]
    idx = [k for k in range(len(bvh.joints)) if keep[k]]
    remap = {old: new for new, old in enumerate(idx)}
    names = [bvh.joints[k] for k in idx]
    parents = [remap[bvh.parents[k]] if bvh.parents[k] >= 0 else -1 for k in idx]
    pos, local, offsets_m = pos[:, idx], local[:, idx], offsets_m[idx]

    pos, local, tpose = _tpose_frame0(pos, local, drop_tpose, quirks)
    rest_pos, _ = forward_kinematics(
        parents, offsets_m, np.broadcast_to(np.eye(3), (1, len(idx), 3, 3))
    )
    canon, canon_notes = _avoid_coincident(
        {k: v for k, v in all_canon.items() if v in names}, names, parents, rest_pos[0],
        cmu=mapping is None,
    )
    if joint_map is not None:
        canon = {k: v for k, v in all_canon.items() if v in names}  # the user's word stands
    else:
        quirks += canon_notes
    variant = skeleton_variant(names)
    if variant == "poser":
        quirks.append(
            "template skeleton (Poser/Second-Life layout, outworldz conversion): bone lengths "
            "are the template's, not the performer's proportions"
            + (f"; {height * s:.2f} m tall" if height * s < 1.5 else "")
        )
    file_fps = header_fps(bvh.frame_time)
    rate = _frame_rate(file_fps, fps, bvh.frame_time, quirks)

    stem = path.stem
    meta: dict[str, Any] = {
        "source": str(path),
        **units_metadata(FORMAT, stem, unit_name, reason, s, up),
        "header_fps": file_fps,
        "frames_in_file": int(bvh.data.shape[0]),
        "tpose_frame0": bool(tpose),
        "offsets_m": offsets_m.round(6).tolist(),
        "rigid_bones": rigid_bones(bvh.parents, translations),
        "quirks": quirks,
    }
    if repairs is not None:
        meta["repairs"] = repairs
    if mapping is not None:
        meta["joint_map"] = replace(mapping, canonical=canon,
                                    how={k: mapping.how.get(k, "") for k in canon}).as_metadata()
    if unit_name == "cmu":
        meta["units_note"] = f"CMU skeleton units: 1 unit = 0.0254/0.45 m = {CMU_UNIT_M:.5f} m"
    skeleton = Skeleton(f"{variant}{len(names)}", tuple(names), tuple(parents), canon)
    return Motion(
        positions=pos.astype(np.float32),
        fps=rate,
        skeleton=skeleton,
        name=name or stem,
        metadata=meta,
        rotations=matrices_to_quaternions(local).astype(np.float32),
    )


def _local_rotations(bvh: BvhFile, file_offsets: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, dict[int, np.ndarray]]:
    """The FK inputs of the channels, file units and axes: (T, J, 3, 3) local rotations
    (each joint's rotation channels, intrinsic in listed order), the (J, 3) offsets with
    the components its position channels replace set to zero, and joint -> (T, 3) those
    position channels' values."""
    t, j = bvh.data.shape[0], len(bvh.joints)
    local = np.empty((t, j, 3, 3))
    offsets = file_offsets.copy()
    translations: dict[int, np.ndarray] = {}
    col = 0
    for k, chans in enumerate(bvh.channels):
        kinds = [_CHANNELS[c.lower()] for c in chans]
        cols = np.arange(col, col + len(chans))
        col += len(chans)
        rot_cols = [c for c, (kind, _) in zip(cols, kinds, strict=True) if kind == "r"]
        axes = "".join(ax for kind, ax in kinds if kind == "r")
        local[:, k] = euler_to_matrices(bvh.data[:, rot_cols], axes)
        pos_axes = [
            ("XYZ".index(ax), c) for c, (kind, ax) in zip(cols, kinds, strict=True) if kind == "p"
        ]
        if pos_axes:
            tr = np.zeros((t, 3))
            for axis, c in pos_axes:
                offsets[k, axis] = 0.0
                tr[:, axis] = bvh.data[:, c]
            translations[k] = tr
    return local, offsets, translations


def _tpose_frame0(pos: np.ndarray, local: np.ndarray, drop: bool, quirks: list[str]
                  ) -> tuple[np.ndarray, np.ndarray, bool]:
    """(T, J, 3) positions and (T, J, 3, 3) rotations without the converter's T-pose
    frame 0 when there is one and ``drop`` (noted in ``quirks`` either way), and whether
    there was one."""
    tpose, tpose_note = is_tpose_frame0(pos)
    if tpose and drop:
        pos, local = pos[1:], local[1:]
        quirks.append(
            f"dropped T-pose frame 0 ({tpose_note}); frame k of this motion is "
            f"frame k+1 of the file"
        )
    elif tpose:
        quirks.append(f"frame 0 is a T-pose ({tpose_note}); kept because drop_tpose=False")
    return pos, local, tpose


def _frame_rate(file_fps: float, fps: float | None, frame_time: float, quirks: list[str]
                ) -> float:
    """The motion's frame rate: the header's, or the caller's ``fps`` (a quirk noted in
    ``quirks`` when they differ)."""
    if fps is None:
        return file_fps
    rate = float(fps)
    if abs(rate - file_fps) > 1e-6 * rate:
        quirks.append(
            f"frame rate set to {rate:g} fps by the caller; the header says "
            f"{file_fps:g} fps (Frame Time {frame_time:g} s)"
        )
    return rate

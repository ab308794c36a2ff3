"""Acclaim ASF (skeleton) / AMC (motion) reader, as used by the CMU database.

ASF bones are segments given in the global rest frame: a unit ``direction``,
a ``length`` and an ``axis`` (Euler angles + order) that defines the bone's
local frame ``C`` relative to the global frame. An AMC frame gives each
bone's DOF angles ``M`` (applied in the bone's local frame). Forward
kinematics (the Acclaim / CMU ``mocapPlayer`` convention)::

    L_b     = C_b @ M_b @ C_b^-1            (bone motion in the rest frame)
    W_b     = W_parent @ L_b                 (world rotation of the bone)
    end_b   = start_b + W_b @ (length_b * direction_b)
    start_b = end_parent                     (root: the root translation)

``M_b`` and ``C_b`` are extrinsic rotations in listed axis order: for
``dof rx ry rz`` (or ``axis ... XYZ``) ``M = R_z @ R_y @ R_x``.

The Motion has one joint per bone plus ``root``, placed at the bone's
*start*, exactly like the cgspeed BVH conversions (``lfemur`` = hip joint,
``ltibia`` = knee; end points of leaf bones are not joints). Local
rotations are ``L_b`` in the converted Z-up frame. Units: the ASF
``:units length L`` says lengths are inches times ``L`` (CMU: L = 0.45, so
one unit is 0.0254/0.45 m); this is used when it gives a plausible height,
otherwise units are detected from the skeleton's size. AMC has no frame
rate field: 120 fps (the CMU capture rate) unless ``fps=`` is given.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import FormatError
from simenv.core.motion import Motion
from simenv.core.skeletons import Skeleton, cmu_canonical_map
from simenv.io._kinematics import (
    PLAUSIBLE_HEIGHT_M,
    detect_units,
    euler_to_matrices,
    forward_kinematics,
    matrices_to_quaternions,
    rest_extent,
    rigid_bones,
    to_z_up_metres,
    units_metadata,
)
from simenv.io._text import parse_float, parse_float_rows, read_text, split_lines

FORMAT = "asf_amc"
EXTENSIONS = (".amc", ".asf")

#: Frame rate used for AMC files, which carry none (CMU captured at 120 Hz).
DEFAULT_AMC_FPS = 120.0

_DOFS = ("tx", "ty", "tz", "rx", "ry", "rz")


@dataclass
class Bone:
    """One ASF bone (or the root), in ASF file units and axes.

    Attributes:
        name: bone name.
        direction: (3,) unit direction in the global rest frame.
        length: bone length, file units.
        axis: (3,) Euler angles of the bone's local frame, ASF angle unit.
        axis_order: axes of ``axis`` in application order, e.g. ``"XYZ"``.
        dofs: DOF names in AMC column order (``"rx"``, ``"tx"``...).
        line: line where the bone starts.
    """

    name: str
    direction: np.ndarray
    length: float
    axis: np.ndarray
    axis_order: str
    dofs: list[str] = field(default_factory=list)
    line: int = 0


@dataclass
class Asf:
    """Parsed ASF skeleton.

    Attributes:
        bones: name -> Bone (``root`` included, length 0).
        order: joint names parents-first (root, then DFS of the hierarchy).
        parents: (J,) parent index per joint in ``order``.
        length_unit: ``:units length`` value (1.0 if absent).
        angle_unit: ``"deg"`` or ``"rad"``.
        root_position: (3,) ``:root position``.
    """

    bones: dict[str, Bone]
    order: list[str]
    parents: list[int]
    length_unit: float
    angle_unit: str
    root_position: np.ndarray
    path: Path


def sniff(path: Path, head: bytes) -> bool:
    """ASF: ``:version``/``:name``/``:units``/``:root``/``:bonedata`` keywords;
    AMC: ``:FULLY-SPECIFIED``/``:DEGREES`` or a ``root`` line after a frame
    number."""
    text = head.decode("latin-1").lower()
    if ":bonedata" in text or (":root" in text and ":units" in text):
        return True
    if ":fully-specified" in text or ":degrees" in text or ":radians" in text:
        return True
    lines = [ln.split() for ln in text.splitlines() if ln.strip() and ln.strip()[0] not in "#:"]
    return len(lines) >= 2 and lines[0] == ["1"] and lines[1][:1] == ["root"]


def parse_asf(path: Path) -> Asf:
    """Parse an ASF skeleton file.

    Raises:
        FormatError: naming file and line for missing sections, unknown
            keywords in a bone, non-numeric values, duplicate bones, bones
            missing from or repeated in the hierarchy.
    """
    return _AsfParser(Path(path)).parse()


#: The sections of an ASF file.
_ASF_SECTIONS = (":version", ":name", ":documentation", ":units", ":root", ":bonedata",
                 ":hierarchy", ":skin")


class _AsfParser:
    """Line-by-line parser of an ASF file: the ``:keyword`` lines switch the section, one
    method reads a line of each section that carries data (units, root, bone data,
    hierarchy); the others are skipped."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.length_unit, self.angle_unit = 1.0, "deg"
        self.root = Bone("root", np.zeros(3), 0.0, np.zeros(3), "XYZ", line=1)
        self.root_order: list[str] = []
        self.root_position = np.zeros(3)
        self.bones: dict[str, Bone] = {}
        self.current: dict[str, Any] | None = None
        self.hierarchy: list[tuple[str, list[str], int]] = []

    def parse(self) -> Asf:
        path = self.path
        section = None
        seen_sections: set[str] = set()
        readers = {":units": self.units, ":root": self.root_line,
                   ":bonedata": self.bonedata, ":hierarchy": self.hierarchy_line}
        for i, raw in enumerate(split_lines(read_text(path))):
            ln = i + 1
            toks = raw.split()
            if not toks or toks[0].startswith("#"):
                continue
            key = toks[0].lower()
            if key.startswith(":"):
                section = key
                seen_sections.add(key)
                if key not in _ASF_SECTIONS:
                    raise FormatError(f"unknown ASF section {toks[0][:40]!r}", source=path,
                                      line=ln)
            elif section in readers:
                readers[section](key, toks, ln)
        if self.current is not None:
            raise FormatError("bone block not closed by 'end' (truncated file?)", source=path,
                              line=self.current["line"])
        for needed in (":bonedata", ":hierarchy"):
            if needed not in seen_sections:
                raise FormatError(f"no {needed} section; expected an ASF skeleton file",
                                  source=path)
        self.root.dofs = self.root_order or ["tx", "ty", "tz", "rx", "ry", "rz"]
        bones = {"root": self.root, **self.bones}
        order, parents = _topological(bones, self.hierarchy, path)
        return Asf(bones, order, parents, self.length_unit, self.angle_unit,
                   self.root_position, path)

    def units(self, key: str, toks: list[str], ln: int) -> None:
        path = self.path
        if len(toks) < 2:
            raise FormatError(f"expected '{toks[0]} <value>'", source=path, line=ln)
        if key == "length":
            self.length_unit = parse_float(toks[1], source=path, line=ln, field="units length")
            if self.length_unit <= 0:
                raise FormatError(
                    "units length must be positive", source=path, line=ln, field="units length"
                )
        elif key == "angle":
            self.angle_unit = toks[1].lower()[:3]
            if self.angle_unit not in ("deg", "rad"):
                raise FormatError(
                    f"expected angle deg or rad, found {toks[1][:40]!r}",
                    source=path,
                    line=ln,
                    field="units angle",
                )

    def root_line(self, key: str, toks: list[str], ln: int) -> None:
        path = self.path
        if key == "order":
            self.root_order = [t.lower() for t in toks[1:]]
            bad = [t for t in self.root_order if t not in _DOFS]
            if bad or len(set(self.root_order)) != len(self.root_order):
                raise FormatError(
                    f"root order must list distinct TX TY TZ RX RY RZ, found "
                    f"{' '.join(toks[1:])[:60]!r}",
                    source=path,
                    line=ln,
                )
        elif key == "axis":
            self.root.axis_order = _axis_order(toks[1:2], path, ln)
        elif key == "position":
            self.root_position = _floats(toks[1:], 3, path, ln, "root position")
        elif key == "orientation":
            self.root.axis = _floats(toks[1:], 3, path, ln, "root orientation")

    def bonedata(self, key: str, toks: list[str], ln: int) -> None:
        path = self.path
        if key == "begin":
            if self.current is not None:
                raise FormatError(
                    "'begin' inside a bone block; missing 'end'", source=path, line=ln
                )
            self.current = {"line": ln}
        elif key == "end":
            if self.current is None:
                raise FormatError("'end' without 'begin'", source=path, line=ln)
            bone = _make_bone(self.current, path)
            if bone.name in self.bones or bone.name == "root":
                raise FormatError(
                    f"duplicate bone name {bone.name!r}; names must be unique",
                    source=path,
                    line=self.current["line"],
                    field=bone.name,
                )
            self.bones[bone.name] = bone
            self.current = None
        elif self.current is None:
            raise FormatError(
                f"{toks[0][:40]!r} outside a begin/end bone block", source=path, line=ln
            )
        else:
            _bone_field(self.current, key, toks, path, ln)

    def hierarchy_line(self, key: str, toks: list[str], ln: int) -> None:
        if key not in ("begin", "end"):
            self.hierarchy.append((toks[0], toks[1:], ln))


def _floats(toks: list[str], n: int, path: Path, line: int, what: str) -> np.ndarray:
    if len(toks) < n:
        raise FormatError(
            f"expected {n} numbers for {what}, found {len(toks)}",
            source=path,
            line=line,
            field=what,
        )
    return np.array([parse_float(t, source=path, line=line, field=what) for t in toks[:n]])


def _axis_order(toks: list[str], path: Path, line: int) -> str:
    order = toks[0].upper() if toks else ""
    if sorted(order) != ["X", "Y", "Z"]:
        raise FormatError(
            f"expected an axis order such as XYZ, found {order[:40]!r}",
            source=path,
            line=line,
            field="axis",
        )
    return order


def _bone_field(bone: dict[str, Any], key: str, toks: list[str], path: Path, ln: int) -> None:
    if key == "id":
        return
    if key == "name":
        if len(toks) < 2:
            raise FormatError("bone 'name' without a value", source=path, line=ln)
        bone["name"] = toks[1]
    elif key == "direction":
        bone["direction"] = _floats(toks[1:], 3, path, ln, "direction")
    elif key == "length":
        bone["length"] = _floats(toks[1:], 1, path, ln, "length")[0]
    elif key == "axis":
        bone["axis"] = _floats(toks[1:], 3, path, ln, "axis")
        bone["axis_order"] = _axis_order(toks[4:5], path, ln)
    elif key == "dof":
        dofs = [t.lower() for t in toks[1:]]
        for d in dofs:
            if d not in _DOFS:
                raise FormatError(
                    f"unsupported DOF {d[:20]!r}; expected rx ry rz tx ty tz",
                    source=path,
                    line=ln,
                    field=bone.get("name"),
                )
        if len(set(dofs)) != len(dofs):
            raise FormatError("repeated DOF", source=path, line=ln, field=bone.get("name"))
        bone["dofs"] = dofs
    elif key == "limits" or key.startswith("("):
        return
    elif key in ("bodymass", "cofmass"):
        return
    else:
        raise FormatError(
            f"unknown bone keyword {key[:40]!r}; expected id, name, direction, "
            "length, axis, dof or limits",
            source=path,
            line=ln,
        )


def _make_bone(b: dict[str, Any], path: Path) -> Bone:
    for key in ("name", "direction", "length"):
        if key not in b:
            raise FormatError(
                f"bone block has no {key!r}", source=path, line=b["line"], field=b.get("name")
            )
    d = b["direction"]
    norm = float(np.linalg.norm(d))
    # Some writers leave tiny non-unit directions; normalise, but a zero one is meaningless.
    if norm < 1e-9 and b["length"] != 0:
        raise FormatError(
            "bone direction is the zero vector", source=path, line=b["line"], field=b["name"]
        )
    return Bone(
        b["name"],
        d / norm if norm >= 1e-9 else d,
        float(b["length"]),
        b.get("axis", np.zeros(3)),
        b.get("axis_order", "XYZ"),
        b.get("dofs", []),
        b["line"],
    )


def _topological(
    bones: dict[str, Bone], hierarchy: list[tuple[str, list[str], int]], path: Path
) -> tuple[list[str], list[int]]:
    children: dict[str, list[str]] = {}
    parent_of: dict[str, str] = {}
    for par, kids, ln in hierarchy:
        for name in (par, *kids):
            if name not in bones:
                raise FormatError(
                    f"hierarchy names unknown bone {name[:40]!r}", source=path, line=ln, field=name
                )
        for kid in kids:
            if kid in parent_of or kid == "root":
                raise FormatError(
                    f"bone {kid!r} has two parents in the hierarchy",
                    source=path,
                    line=ln,
                    field=kid,
                )
            parent_of[kid] = par
        children.setdefault(par, []).extend(kids)
    order: list[str] = []
    parents: list[int] = []
    stack: list[tuple[str, int]] = [("root", -1)]
    while stack:
        name, par = stack.pop()
        order.append(name)
        parents.append(par)
        me = len(order) - 1
        stack.extend((kid, me) for kid in reversed(children.get(name, [])))
    missing = [b for b in bones if b not in order]
    if missing:
        raise FormatError(
            f"bones not connected to root by the hierarchy: {', '.join(missing)}",
            source=path,
            field=missing[0],
        )
    return order, parents


def parse_amc(path: Path, asf: Asf) -> tuple[np.ndarray, list[str], bool]:
    """Parse an AMC file against its skeleton.

    Returns:
        (values (T, D) float64 in ``asf`` DOF order: bones in ``asf.order``,
        each bone's DOFs in its ``dof`` order; column labels ``bone.dof``;
        whether angles are in degrees).

    Raises:
        FormatError: non-contiguous frame numbers, unknown bones, wrong DOF
            counts, bones missing from a frame, non-numeric values, no frames.
    """
    return _AmcParser(Path(path), asf).parse()


class _AmcParser:
    """Line-by-line parser of an AMC file against its skeleton: header keywords, then
    frames (a frame number, then one line per bone with DOFs); the value tokens are
    collected per bone and parsed to floats at the end."""

    def __init__(self, path: Path, asf: Asf) -> None:
        self.path, self.asf = path, asf
        self.dof_bones = [b for b in asf.order if asf.bones[b].dofs]
        self.expected = {b: len(asf.bones[b].dofs) for b in self.dof_bones}
        self.tokens: dict[str, list[list[str]]] = {b: [] for b in self.dof_bones}
        self.lines_of: dict[str, list[int]] = {b: [] for b in self.dof_bones}
        self.degrees = asf.angle_unit == "deg"
        self.frame_no: int | None = None
        self.frame_line = 0
        self.in_frame: set[str] = set()
        self.n_frames = 0

    def parse(self) -> tuple[np.ndarray, list[str], bool]:
        path = self.path
        for i, raw in enumerate(split_lines(read_text(path))):
            ln = i + 1
            toks = raw.split()
            if not toks or toks[0].startswith("#"):
                continue
            if toks[0].startswith(":"):
                self.keyword(toks[0], ln)
            elif len(toks) == 1 and toks[0].isdecimal():
                self.frame(int(toks[0]), ln)
            else:
                self.bone(toks, ln)
        if self.n_frames == 0:
            raise FormatError("AMC file has no frames; expected at least 1", source=path)
        self.close_frame()
        cols = []
        labels = []
        for b in self.dof_bones:
            names = [f"{b}.{d}" for d in self.asf.bones[b].dofs]
            cols.append(parse_float_rows(self.tokens[b], source=path, lines=self.lines_of[b],
                                         field_names=names))
            labels += names
        values = np.concatenate(cols, axis=1) if cols else np.zeros((self.n_frames, 0))
        return values, labels, self.degrees

    def keyword(self, tok: str, ln: int) -> None:
        if self.n_frames:
            raise FormatError(f"keyword {tok[:40]!r} after motion data", source=self.path,
                              line=ln)
        key = tok.upper()
        if key == ":DEGREES":
            self.degrees = True
        elif key == ":RADIANS":
            self.degrees = False

    def close_frame(self) -> None:
        if self.frame_no is not None and len(self.in_frame) != len(self.dof_bones):
            missing = [b for b in self.dof_bones if b not in self.in_frame]
            raise FormatError(
                f"frame {self.frame_no} lacks bone(s) {', '.join(missing[:5])}; every "
                "frame must list every bone that has DOFs",
                source=self.path,
                line=self.frame_line,
                frame=self.n_frames - 1,
                field=missing[0],
            )

    def frame(self, num: int, ln: int) -> None:
        self.close_frame()
        if self.frame_no is not None and num != self.frame_no + 1:
            raise FormatError(
                f"frame number {num} follows {self.frame_no}; expected "
                f"{self.frame_no + 1} (frame numbers must be contiguous)",
                source=self.path,
                line=ln,
                frame=self.n_frames,
            )
        self.frame_no, self.frame_line = num, ln
        self.in_frame = set()
        self.n_frames += 1

    def bone(self, toks: list[str], ln: int) -> None:
        path, frame = self.path, self.n_frames - 1
        if self.frame_no is None:
            raise FormatError(
                f"expected a frame number before {toks[0][:40]!r}", source=path, line=ln
            )
        bone = toks[0]
        if bone not in self.expected:
            known = "has no DOFs" if bone in self.asf.bones else "is not in the ASF"
            raise FormatError(f"bone {bone[:40]!r} {known}", source=path, line=ln, frame=frame,
                              field=bone[:40])
        if bone in self.in_frame:
            raise FormatError(f"bone {bone!r} listed twice in frame {self.frame_no}",
                              source=path, line=ln, frame=frame, field=bone)
        if len(toks) - 1 != self.expected[bone]:
            raise FormatError(
                f"expected {self.expected[bone]} values for {bone} "
                f"({' '.join(self.asf.bones[bone].dofs)}), found {len(toks) - 1}",
                source=path, line=ln, frame=frame, field=bone)
        self.in_frame.add(bone)
        self.tokens[bone].append(toks[1:])
        self.lines_of[bone].append(ln)


def find_asf(amc: Path) -> Path:
    """The ASF skeleton of an AMC file in the same folder: the ASF whose name
    is or starts with the AMC's subject prefix (text before the first ``_``,
    e.g. ``07.asf`` for ``07_05.amc``, ``103_charleston.asf`` for
    ``103_charleston1.amc``), else the only ASF there.

    Raises:
        FormatError: listing what was looked for when none or several match.
    """
    amc = Path(amc)
    folder = amc.parent
    prefix = amc.stem.split("_")[0]
    asfs = sorted(p for p in folder.iterdir() if p.suffix.lower() == ".asf" and p.is_file())
    exact = [p for p in asfs if p.stem == prefix]
    if exact:
        return exact[0]
    starts = [
        p
        for p in asfs
        if p.stem.startswith(prefix) and not p.stem[len(prefix) : len(prefix) + 1].isalnum()
    ]
    if len(starts) == 1:
        return starts[0]
    if len(asfs) == 1 and not starts:
        return asfs[0]
    found = ", ".join(p.name for p in asfs) or "none"
    why = "several match" if len(starts) > 1 else "none matches"
    raise FormatError(
        f"cannot find the ASF skeleton: looked in {folder} for '{prefix}.asf' or "
        f"'{prefix}_*.asf', else a single .asf file ({why}; ASF files there: {found}). "
        "Pass asf=PATH",
        source=amc,
    )


def _rest_geometry(asf: Asf) -> tuple[np.ndarray, np.ndarray]:
    """Offsets (J, 3), file units: each joint's offset is its parent bone's
    rest vector ``length * direction``; and the bone frames C (J, 3, 3)."""
    n = len(asf.order)
    offsets = np.zeros((n, 3))
    frames = np.empty((n, 3, 3))
    for k, name in enumerate(asf.order):
        bone = asf.bones[name]
        p = asf.parents[k]
        if p >= 0:
            parent = asf.bones[asf.order[p]]
            offsets[k] = parent.direction * parent.length
        ax = bone.axis if asf.angle_unit == "deg" else np.degrees(bone.axis)
        frames[k] = euler_to_matrices(ax[None], bone.axis_order, intrinsic=False)[0]
    return offsets, frames


def read_asf(
    path: Path,
    *,
    units: str | None = None,
    scale: float | None = None,
    up: str = "y",
    name: str | None = None,
) -> Motion:
    """An ASF skeleton alone as a one-frame :class:`Motion` of its rest pose
    (ASF has no motion; the quirk list says so). fps is
    :data:`DEFAULT_AMC_FPS`."""
    asf = parse_asf(Path(path))
    values = np.zeros((1, sum(len(asf.bones[b].dofs) for b in asf.order)))
    motion = _to_motion(
        asf, values, True, Path(path), units=units, scale=scale, up=up, fps=None, name=name
    )
    motion.metadata["quirks"].append(
        "ASF holds a skeleton only: this one frame is its rest pose (all DOFs zero)"
    )
    return motion


def read(
    path: Path,
    *,
    asf: Path | str | None = None,
    units: str | None = None,
    scale: float | None = None,
    up: str = "y",
    fps: float | None = None,
    name: str | None = None,
) -> Motion:
    """Read an AMC motion (or an ASF alone, see :func:`read_asf`).

    Args:
        path: the .amc (or .asf) file.
        asf: the skeleton file; default: found by :func:`find_asf`.
        units: force a length unit (``"cmu"``, ``"inch"``, ``"m"``, ...).
        scale: force metres per file unit.
        up: up axis of the file (``"y"`` for CMU).
        fps: frame rate; default :data:`DEFAULT_AMC_FPS` (AMC has no rate).
        name: clip name; default the file stem.

    Returns:
        Motion (T, J, 3) metres Z-up with J = bones + root, rotations (T, J,
        4) local quaternions (w, x, y, z), metadata ``source``, ``asf``,
        ``format``, ``subject``, ``units``, ``units_reason``,
        ``scale_m_per_unit``, ``up_axis_in_file``, ``offsets_m``, ``quirks``.
    """
    path = Path(path)
    if up.lower() not in ("y", "z"):
        raise FormatError(f"up must be 'y' or 'z'; got {up!r}", source=path)
    if path.suffix.lower() == ".asf" and asf is None:
        return read_asf(path, units=units, scale=scale, up=up, name=name)
    asf_path = Path(asf) if asf is not None else find_asf(path)
    skel = parse_asf(asf_path)
    values, _, degrees = parse_amc(path, skel)
    return _to_motion(
        skel, values, degrees, path, units=units, scale=scale, up=up, fps=fps, name=name
    )


def _to_motion(
    asf: Asf,
    values: np.ndarray,
    degrees: bool,
    path: Path,
    *,
    units: str | None,
    scale: float | None,
    up: str,
    fps: float | None,
    name: str | None,
) -> Motion:
    with np.errstate(all="ignore"):
        offsets, frames = _rest_geometry(asf)
        height = rest_extent(asf.parents, offsets)
        unit_name, s, reason, quirks = _units(asf, height, path, units, scale)
        local, translations = _local_rotations(asf, values, degrees, frames)
        pos, _ = forward_kinematics(asf.parents, offsets, local, translations)
        pos, local, offsets_m = to_z_up_metres(pos, local, offsets, up, s)
        quats = matrices_to_quaternions(local)
    rate = DEFAULT_AMC_FPS if fps is None else float(fps)
    stem = path.stem
    meta: dict[str, Any] = {
        "source": str(path),
        "asf": str(asf.path),
        **units_metadata(FORMAT, stem, unit_name, reason, s, up),
        "fps_source": "AMC has no rate field; CMU capture rate assumed"
        if fps is None
        else "given by the caller",
        "offsets_m": offsets_m.round(6).tolist(),
        "rigid_bones": rigid_bones(asf.parents, translations),
        "quirks": quirks,
    }
    names = tuple(asf.order)
    skeleton = Skeleton(f"cmu_asf{len(names)}", names, tuple(asf.parents), cmu_canonical_map(names))
    return Motion(
        pos.astype(np.float32), rate, skeleton, name or stem, meta, quats.astype(np.float32)
    )


def _units(asf: Asf, height: float, path: Path, units: str | None, scale: float | None
           ) -> tuple[str, float, str, list[str]]:
    """(unit name, metres per unit, reason, quirks) of the file: the ASF's own
    ``:units length`` (inches times it) when the rest pose is then of a plausible height
    and the caller gave neither ``units`` nor ``scale``; otherwise
    :func:`~simenv.io._kinematics.detect_units`."""
    if scale is not None or units is not None:
        return detect_units(height, source=path, units=units, scale=scale)
    s_asf = 0.0254 / asf.length_unit
    lo, hi = PLAUSIBLE_HEIGHT_M
    if not lo <= height * s_asf <= hi:
        return detect_units(height, source=path)
    unit_name = "cmu" if abs(asf.length_unit - 0.45) < 1e-9 else f"inch/{asf.length_unit:g}"
    reason = (
        f"ASF ':units length {asf.length_unit:g}' = inches x "
        f"{asf.length_unit:g}, so 1 unit = {s_asf:.5f} m; rest-pose size "
        f"{height:.4g} units = {height * s_asf:.3f} m, plausible"
    )
    return unit_name, s_asf, reason, []


def _local_rotations(asf: Asf, values: np.ndarray, degrees: bool, frames: np.ndarray
                     ) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """(T, J, 3, 3) local rotations of the bones (each bone's DOF rotations, extrinsic,
    expressed in its parent's frame through the bone's ``frames``) and the per-frame
    translations of the bones with translation DOFs and of the root (its ASF position
    added), from the (T, C) AMC ``values``."""
    t = values.shape[0]
    local = np.empty((t, len(asf.order), 3, 3))
    translations: dict[int, np.ndarray] = {}
    col = 0
    for k, bname in enumerate(asf.order):
        bone = asf.bones[bname]
        block = values[:, col : col + len(bone.dofs)]
        col += len(bone.dofs)
        rot_axes = "".join(d[1] for d in bone.dofs if d[0] == "r")
        rot_vals = block[:, [i for i, d in enumerate(bone.dofs) if d[0] == "r"]]
        if not degrees:
            rot_vals = np.degrees(rot_vals)
        m = euler_to_matrices(rot_vals, rot_axes, intrinsic=False)
        c = frames[k]
        local[:, k] = c @ m @ c.T
        tr_idx = [(i, "xyz".index(d[1])) for i, d in enumerate(bone.dofs) if d[0] == "t"]
        if tr_idx or bname == "root":
            tr = np.zeros((t, 3))
            for i, axis in tr_idx:
                tr[:, axis] = block[:, i]
            if bname == "root":
                tr += asf.root_position
            translations[k] = tr
    return local, translations

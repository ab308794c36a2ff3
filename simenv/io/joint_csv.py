"""Joint-position tables: one row per frame, three columns per joint (``.csv``).

Capture suites and depth-camera tools export global joint positions as text tables: Xsens
MVN Analyze's "Segment Position" sheet (``Frame, Pelvis x, Pelvis y, ..., Right Upper Arm x``;
converted MVNX files write ``Pelvis_x``), Azure Kinect recorders (``PELVIS.x, SPINE_NAVAL.x``),
Nuitrack's CSV recorder (``<joint>.x`` plus ``Timestamp`` in microseconds), Kinect v2 tools
(``SpineBase_X``). This reader takes any such table.

**Columns.** A header row names every column. A column ``<joint><sep><axis>`` holds one
coordinate: ``sep`` is one or more of space, ``_``, ``.``, ``-``, ``:``; ``axis`` is ``x``,
``y`` or ``z`` in either case; a position word between them is dropped (``Pelvis_pos_x``,
``Head_position_x``). Every joint needs its three axes. The delimiter is ``,``, ``;`` or a tab
(whichever splits the header into the most columns). Columns that are neither coordinates nor
time (Nuitrack's ``rot``, confidences, labels) are ignored and listed in
``metadata["ignored_columns"]``. Tables without a header row (the MSRC-12 gesture files) are
not this format.

**Time.** The clock is the first column named as time (:data:`TIME_COLUMNS`: ``ms``,
``time``, ``timestamp``, ``Time (Seconds)``, ...), else a frame-number column
(:data:`FRAME_COLUMNS`: ``Frame``, ``frame_idx``). A clock's unit comes from its name (``ms``,
``us``, ``seconds``) or, for a bare ``time``/``timestamp``, from its step: the one unit of
:data:`TIME_UNITS` in which the step is a capture rate within :data:`PLAUSIBLE_FPS`. The frame
rate is measured: the mean step over the steps within half the median step of it (so a
millisecond clock at 240 Hz, stepping 4 or 5 ms, gives 239.96 Hz), rounded to a nominal rate
of :data:`NOMINAL_FPS` when that rate lies within the clock's rounding (two units of its grain
over the clip; the grain is the last digit written, or the spacing of the step values when
coarser). A clock that stands still or goes backwards is a :class:`FormatError` naming the
line; a step more than half a nominal step off (dropped frames) is a :class:`FormatError` too,
unless ``irregular_time="resample"``, which resamples the positions linearly onto a regular
grid at the measured rate (logged in ``metadata["repairs"]``). Frame numbers give no rate:
``fps=`` is then required; ``fps=`` given with a clock overrides it (noted when they disagree).

**Cells.** Empty and ``NaN`` coordinates are gaps: a :class:`MotionError` naming the line,
frame and column, unless ``gaps="interpolate"`` (each joint filled linearly between its
measured frames; logged). Any other non-number is a :class:`FormatError`. A table needs at
least two rows.

**Units and axes.** Length units are detected from the body's size (the 95th percentile over
frames of the largest side of the body's bounding box, through
:func:`simenv.io._kinematics.detect_units`); ``units=``/``scale=`` override. The up axis is the
file axis along which the body stands over the clip: the median direction from the feet
(ankles or toes, else the pelvis) to the head (or neck), whose largest component, with its
sign, is up; a table whose names give neither end falls back to the axis of the largest
per-frame extent, positive. ``up=`` (``"x"``, ``"-y"``, ...) overrides. The conversion is the
smallest proper rotation taking that axis to +Z (:data:`UP_TO_Z_UP`; a Y-up file maps
``(x, y, z) -> (x, -z, y)`` as in every simenv reader), never a mirror. Depth-camera coordinates
(``frame="camera"``; up along +Y or -Y, the sensor tilted and above the floor) are turned so
that up is +Y, then levelled and put on the floor from the feet (:mod:`simenv.io.camera_frame`).
By default (``frame=None``) a table of a depth camera's declared layout (Azure Kinect, Kinect
v2, Kinect v1, Nuitrack: their SDKs write camera coordinates) is read as camera coordinates and
any other as a world frame (``frame="world"``), whose origin is kept; feet far from z = 0 are
then noted as a quirk.

**Hierarchy.** A table has none, so the reader gives the skeleton its tree:

1. *Declared layouts.* When every joint name (compared in lower case without separators, so
   ``Right Upper Arm`` = ``RightUpperArm``) belongs to one declared skeleton and its root is
   present, that skeleton's tree is used, restricted to the joints present: the Xsens MVN 23
   segments (:data:`MVN_SEGMENTS`, :func:`mvn_skeleton`), Azure Kinect's 32 joints
   (:data:`AZURE_KINECT_JOINTS`, :func:`azure_kinect_skeleton`), and the library's Kinect v2,
   Kinect v1 and Nuitrack skeletons.
2. *Any other names.* Each joint is named onto a canonical keypoint by the naming conventions of
   :mod:`simenv.core.joint_map` (the declared :data:`~simenv.core.joint_map.CONVENTIONS`, read
   after :func:`~simenv.core.joint_map.normalise`; the convention naming most keypoints first,
   the others filling what it lacks) or, when given, by the user's ``joint_map``. A named joint
   hangs from the joint of the nearest canonical ancestor of its keypoint that the table has
   (:data:`~simenv.core.skeletons.CANONICAL_TREE`: a knee from the hip, a shoulder from the
   chest, else the spine, else the pelvis). A joint no keypoint names (fingertips, eyes,
   clavicles) hangs from the named joint nearest to it over the clip (median distance), as a
   leaf. The pelvis and both hips must be named; a table that does not name them is a
   :class:`SkeletonError` listing its joints and columns, with how to name them
   (``joint_map=``).

The canonical map is then :func:`simenv.core.joint_map.infer_joint_map` on the names, that tree
and the converted positions (the user's map instead, when given), recorded in
``metadata["joint_map"]``.

Left out: OptiTrack Motive's multi-row CSV header (Type / Name / ID / Position rows above
``Frame, Time (Seconds), X, Y, Z``; :mod:`simenv.io.motive_csv` reads it), several people in
one table, and telling a "Segment Velocity" sheet (same column names) from positions.
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any, Literal

import numpy as np

from simenv.core.errors import FormatError, MotionError, SkeletonError
from simenv.core.joint_map import (
    CONVENTIONS,
    REQUIRED_FOR_BODY,
    JointMapSource,
    NormalisedName,
    apply_user_map,
    common_prefix,
    infer_joint_map,
    normalise,
    read_joint_map,
)
from simenv.core.motion import Motion, interpolate_gaps
from simenv.core.skeletons import (
    CANONICAL_KEYPOINTS,
    CANONICAL_TREE,
    Skeleton,
    kinect_v1_skeleton,
    kinect_v2_skeleton,
    nuitrack_skeleton,
)
from simenv.io._kinematics import detect_units, units_metadata
from simenv.io._text import read_text, split_lines
from simenv.io.camera_frame import camera_to_world

#: Extensions this reader claims when no sniffer accepts a file.
EXTENSIONS = (".csv",)
#: In a folder, a ``.csv`` counts as motion only when :func:`sniff` accepts it (an index or
#: label table beside the recordings is not a malformed motion).
FOLDER_NEEDS_SNIFF = True
FORMAT = "joint_csv"

#: Column delimiters tried on the header row.
DELIMITERS: tuple[str, ...] = (",", ";", "\t")

#: Bytes of a file read to sniff it (a 32-joint header is ~1.5 kB; room for a long one).
SNIFF_BYTES = 65536

#: Non-blank lines searched for the header row (the lines above it are a preamble).
HEADER_SEARCH_LINES = 20

#: A table must have at least this many complete joints to be taken for joint positions.
MIN_JOINTS = 3

#: Time-column names (lower case, letters and digits only) -> unit, or None when the unit is
#: told from the step (see :data:`TIME_UNITS`).
TIME_COLUMNS: dict[str, str | None] = {
    "ms": "ms", "msec": "ms", "millis": "ms", "milliseconds": "ms", "timems": "ms",
    "timemsec": "ms", "timestampms": "ms", "timemilliseconds": "ms",
    "us": "us", "usec": "us", "microseconds": "us", "timeus": "us", "timestampus": "us",
    "ns": "ns", "timens": "ns", "timestampns": "ns",
    "s": "s", "sec": "s", "secs": "s", "seconds": "s", "times": "s", "timesec": "s",
    "timeseconds": "s", "timesecs": "s", "elapseds": "s",
    "time": None, "timestamp": None, "t": None, "elapsed": None, "elapsedtime": None,
}
#: Frame-number column names (lower case, letters and digits only).
FRAME_COLUMNS: frozenset[str] = frozenset({
    "frame", "frames", "frameidx", "frameindex", "framenumber", "frameno", "framenum",
    "frameid", "framecount",
})
#: Seconds per unit of a clock.
TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: Capture rates (Hz) a clock's step must give to tell its unit from the step alone: the
#: ranges of the four units do not overlap (a step of 0.5-200 is milliseconds, ...).
PLAUSIBLE_FPS = (5.0, 2000.0)
#: Capture rates (Hz) a measured rate is rounded to when within the clock's rounding.
NOMINAL_FPS: tuple[float, ...] = (
    10, 12, 15, 20, 24, 25, 29.97, 30, 48, 50, 59.94, 60, 90, 100, 120, 125, 128, 150, 180,
    200, 240, 250, 256, 300, 360, 400, 480, 500, 960, 1000,
)
#: A step more than this fraction of the nominal step off it is irregular (a dropped frame
#: doubles a step; a millisecond clock at 240 Hz is 14 % off at most).
IRREGULAR_STEP_FRACTION = 0.5

#: Feet lower or higher than this above z = 0 (m, median lowest joint over the clip) are noted:
#: the table's origin is not on the floor.
FLOOR_NOTE_M = 0.25

#: Smallest proper rotation taking each file up axis to +Z: about X for Y and Z, about Y for X.
UP_TO_Z_UP: dict[str, np.ndarray] = {
    "x": np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),
    "-x": np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
    "y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
    "-y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
    "z": np.eye(3),
    "-z": np.diag([1.0, -1.0, -1.0]),
}
#: Camera frame with its up along -Y (Azure Kinect, OpenCV: x right, y down) -> the Kinect
#: convention :mod:`simenv.io.camera_frame` expects (x left, y up): 180 deg about the optical
#: axis, a proper rotation.
Y_DOWN_TO_Y_UP = np.diag([-1.0, -1.0, 1.0])

_SEPARATOR = r"[\s_.\-:]"
_AXIS_COLUMN = re.compile(
    rf"^(?P<joint>.*?[^\s_.\-:]){_SEPARATOR}+(?:(?:pos|position){_SEPARATOR}*)?(?P<axis>[xyz])$",
    re.IGNORECASE)
_POSITION_WORD = re.compile(rf"{_SEPARATOR}+(?:pos|position)$", re.IGNORECASE)


# -- declared layouts --------------------------------------------------------------------

#: Xsens MVN's 23 segments in MVNX order (segment ids 1-23). A segment's position is its
#: origin: the upper leg's is the hip joint, the lower leg's the knee, the foot's the ankle,
#: the toe's the ball of the foot, the upper arm's the shoulder joint, the hand's the wrist.
MVN_SEGMENTS: tuple[str, ...] = (
    "Pelvis", "L5", "L3", "T12", "T8", "Neck", "Head",
    "RightShoulder", "RightUpperArm", "RightForeArm", "RightHand",
    "LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand",
    "RightUpperLeg", "RightLowerLeg", "RightFoot", "RightToe",
    "LeftUpperLeg", "LeftLowerLeg", "LeftFoot", "LeftToe",
)
#: MVN's segment tree: Pelvis -> L5 -> L3 -> T12 -> T8 -> Neck -> Head; T8 -> shoulders ->
#: upper arms -> forearms -> hands; Pelvis -> upper legs -> lower legs -> feet -> toes.
MVN_PARENTS: tuple[int, ...] = (
    -1, 0, 1, 2, 3, 4, 5,
    4, 7, 8, 9,
    4, 11, 12, 13,
    0, 15, 16, 17,
    0, 19, 20, 21,
)

#: Azure Kinect Body Tracking joints (``k4abt_joint_id_t`` order, 0-31).
AZURE_KINECT_JOINTS: tuple[str, ...] = (
    "PELVIS", "SPINE_NAVAL", "SPINE_CHEST", "NECK",
    "CLAVICLE_LEFT", "SHOULDER_LEFT", "ELBOW_LEFT", "WRIST_LEFT", "HAND_LEFT", "HANDTIP_LEFT",
    "THUMB_LEFT",
    "CLAVICLE_RIGHT", "SHOULDER_RIGHT", "ELBOW_RIGHT", "WRIST_RIGHT", "HAND_RIGHT",
    "HANDTIP_RIGHT", "THUMB_RIGHT",
    "HIP_LEFT", "KNEE_LEFT", "ANKLE_LEFT", "FOOT_LEFT",
    "HIP_RIGHT", "KNEE_RIGHT", "ANKLE_RIGHT", "FOOT_RIGHT",
    "HEAD", "NOSE", "EYE_LEFT", "EAR_LEFT", "EYE_RIGHT", "EAR_RIGHT",
)
#: Parents from the Azure Kinect joint hierarchy (Microsoft's "Azure Kinect body tracking
#: joints" page): clavicles on the chest, thumbs on the wrists, face points on the head.
AZURE_KINECT_PARENTS: tuple[int, ...] = (
    -1, 0, 1, 2,
    2, 4, 5, 6, 7, 8, 7,
    2, 11, 12, 13, 14, 15, 14,
    0, 18, 19, 20,
    0, 22, 23, 24,
    3, 26, 26, 26, 26, 26,
)


@cache
def mvn_skeleton() -> Skeleton:
    """The Xsens MVN 23-segment skeleton (its canonical map is left to
    :func:`~simenv.core.joint_map.infer_joint_map`, which knows MVN's names)."""
    return Skeleton("xsens_mvn23", MVN_SEGMENTS, MVN_PARENTS)


@cache
def azure_kinect_skeleton() -> Skeleton:
    """The Azure Kinect 32-joint skeleton (canonical map by name, as for MVN)."""
    return Skeleton("azure_kinect32", AZURE_KINECT_JOINTS, AZURE_KINECT_PARENTS)


#: Names of the declared layouts whose tables are depth-camera coordinates.
DEPTH_CAMERA_LAYOUTS: tuple[str, ...] = ("azure_kinect32", "kinect_v2_25", "kinect_v1_20",
                                         "nuitrack")

#: Declared skeletons a table's joint names are matched against, in order.
DECLARED_LAYOUTS: tuple[Callable[[], Skeleton], ...] = (
    mvn_skeleton, azure_kinect_skeleton, kinect_v2_skeleton, kinect_v1_skeleton,
    nuitrack_skeleton,
)


# -- header --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Header:
    """What a table's header row says.

    Attributes:
        delimiter: the column delimiter.
        line: 1-based line of the header row.
        columns: every column name, stripped of quotes and spaces.
        joints: joint name -> {axis letter -> column index}, joints in column order.
        time: index of the clock column, or None.
        frame: index of the frame-number column, or None.
    """

    delimiter: str
    line: int
    columns: tuple[str, ...]
    joints: dict[str, dict[str, int]]
    time: int | None
    frame: int | None

    @property
    def complete(self) -> list[str]:
        """Joints with all three axes."""
        return [j for j, axes in self.joints.items() if len(axes) == 3]


def _key(name: str) -> str:
    """Lower case, letters and digits only: how column and joint names are compared."""
    return re.sub(r"[^0-9a-z]", "", name.lower())


def _cells(line: str, delimiter: str) -> list[str]:
    return [c.strip().strip('"').strip() for c in next(csv.reader([line], delimiter=delimiter))]


def _is_numbers(line: str) -> bool:
    cells = [c for c in re.split(r"[,;\t\s]+", line.strip()) if c]
    try:
        [float(c) for c in cells]
    except ValueError:
        return False
    return bool(cells)


def parse_header(lines: Sequence[str], source: Path | None = None) -> Header | None:
    """The header of a table: the first of its first :data:`HEADER_SEARCH_LINES` non-blank
    lines (``#`` comments skipped) that names a coordinate column, split by the delimiter of
    :data:`DELIMITERS` that gives the most columns; lines above it are a preamble (LSL Kinect
    writes ``Software : LSL_Kinect,...`` and a blank line first). None when no such line
    comes before the first row of numbers (a headerless table) or at all.

    Raises:
        FormatError: a joint with two columns of one axis.
    """
    seen = 0
    for i, line in enumerate(lines):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        if _is_numbers(line) or seen == HEADER_SEARCH_LINES:
            return None
        seen += 1
        header = _header_line(line, i + 1, source)
        if header is not None:
            return header
    return None


def _header_line(line: str, number: int, source: Path | None) -> Header | None:
    """The header of one line (see :func:`parse_header`), or None without coordinates."""
    delimiter = max(DELIMITERS, key=lambda d: len(_cells(line, d)))
    columns = _cells(line, delimiter)
    joints: dict[str, dict[str, int]] = {}
    names: dict[str, str] = {}  # compared key -> joint name as first written
    time = frame = None
    time_rank = len(TIME_COLUMNS)
    ranks = {k: r for r, k in enumerate(TIME_COLUMNS)}
    for c, col in enumerate(columns):
        m = _AXIS_COLUMN.match(col)
        if m:
            joint = _POSITION_WORD.sub("", m.group("joint"))
            joint = names.setdefault(_key(joint), joint)
            axes = joints.setdefault(joint, {})
            axis = m.group("axis").lower()
            if axis in axes:
                raise FormatError(
                    f"joint {joint!r} has two {axis} columns ({columns[axes[axis]]!r} and "
                    f"{col!r}); expected one column per joint and axis", source=source,
                    line=number, field=col)
            axes[axis] = c
            continue
        key = _key(col)
        # Explicit units first: "ms" beats a bare "time" when a table has both.
        if key in TIME_COLUMNS and (rank := ranks[key]) < time_rank:
            time, time_rank = c, rank
        elif key in FRAME_COLUMNS and frame is None:
            frame = c
    if not joints:
        return None
    return Header(delimiter, number, tuple(columns), joints, time, frame)


def _head_lines(path: Path) -> list[str]:
    with path.open("rb") as fh:
        data = fh.read(SNIFF_BYTES)
    return split_lines(data.decode("utf-8", errors="replace"))[:-1] or [""]


def sniff(path: Path, head: bytes) -> bool:
    """A text table whose header names at least :data:`MIN_JOINTS` joints with x, y and z
    columns and whose first data row is numbers in those columns."""
    del head  # a long header can exceed the loader's head; read up to SNIFF_BYTES instead
    lines = _head_lines(path)
    try:
        header = parse_header(lines)
    except FormatError:
        return False
    if header is None or len(header.complete) < MIN_JOINTS:
        return False
    row = next((ln for ln in lines[header.line:] if ln.strip()), None)
    if row is None:
        return False
    cells = _cells(row, header.delimiter)
    try:
        for joint in header.complete:
            for c in header.joints[joint].values():
                float(cells[c])
    except (IndexError, ValueError):
        return False
    return True


# -- rows ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Table:
    """The parsed rows of a joint table.

    Attributes:
        header: the table's header.
        positions: (T, J, 3) float64 file units and axes; NaN where a cell was empty or NaN.
        joints: (J,) joint names, header order.
        lines: (T,) 1-based file line of each row.
        time: (T,) clock values in file units, or None; time_tokens the clock's cells.
        ignored: columns neither coordinates nor clock.
    """

    header: Header
    positions: np.ndarray
    joints: tuple[str, ...]
    lines: np.ndarray
    time: np.ndarray | None
    time_tokens: tuple[str, ...]
    ignored: tuple[str, ...]


def _missing_axis_error(header: Header, path: Path) -> FormatError:
    joint = next(j for j, axes in header.joints.items() if len(axes) < 3)
    axes = header.joints[joint]
    have = ", ".join(repr(header.columns[c]) for c in axes.values())
    lacking = ", ".join(a for a in "xyz" if a not in axes)
    flat = all(set(a) <= {"x", "y"} for a in header.joints.values())
    hint = " (every joint has only x and y: a 2-D table; this reader needs 3-D positions)" \
        if flat else ""
    return FormatError(
        f"joint {joint!r} has {have} but no {lacking} column{hint}; expected x, y and z "
        f"columns for every joint", source=path, line=header.line, field=joint)


def read_table(path: Path) -> Table:
    """The header and rows of a joint table, in file units and axes.

    Raises:
        FormatError: no header naming coordinate columns, a joint without its three axes, a
            row with too few cells, a non-number in a coordinate or clock cell.
        MotionError: fewer than two rows.
    """
    lines = split_lines(read_text(path))
    header = parse_header(lines, path)
    if header is None:
        first = next((ln for ln in lines if ln.strip()), "")
        raise FormatError(
            "expected a header row naming joint coordinate columns (<joint>_x, <joint>_y, "
            f"<joint>_z, e.g. Pelvis_x); the first line is {first[:80]!r}",
            source=path, line=1)
    if len(header.complete) < len(header.joints):
        raise _missing_axis_error(header, path)
    joints = tuple(header.joints)
    coord_cols = [header.joints[j][a] for j in joints for a in "xyz"]
    used = set(coord_cols) | {c for c in (header.time, header.frame) if c is not None}
    rows: list[list[str]] = []
    row_lines: list[int] = []
    n_cols = len(header.columns)
    for k, line in enumerate(lines[header.line:], start=header.line + 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        cells = _cells(line, header.delimiter)
        if len(cells) < n_cols:
            raise FormatError(
                f"row has {len(cells)} cells; the header has {n_cols} columns",
                source=path, line=k, frame=len(rows))
        rows.append(cells)
        row_lines.append(k)
    if len(rows) < 2:
        raise MotionError(
            f"table holds {len(rows)} data row(s); expected at least 2 frames (one row per "
            "frame)", source=path)
    pos = _parse_cells(rows, coord_cols, header.columns, row_lines, path)
    clock = header.time if header.time is not None else header.frame
    time = tokens = None
    if clock is not None:
        tokens = tuple(r[clock] for r in rows)
        time = _parse_cells(rows, [clock], header.columns, row_lines, path, gaps=False)[:, 0]
    return Table(header, pos.reshape(len(rows), len(joints), 3), joints, np.asarray(row_lines),
                 time, tokens or (), tuple(c for i, c in enumerate(header.columns)
                                           if i not in used and c))


def _parse_cells(rows: list[list[str]], cols: list[int], names: Sequence[str],
                 lines: list[int], path: Path, *, gaps: bool = True) -> np.ndarray:
    """(T, len(cols)) float64 of the given columns; empty and NaN cells become NaN when
    ``gaps`` (else a FormatError, as is any other non-number, naming line and column)."""
    tokens = [[r[c] for c in cols] for r in rows]
    try:
        values = np.array(tokens, dtype=np.float64)
    except ValueError:
        values = None
    if values is not None and not np.isinf(values).any() and (gaps or np.isfinite(values).all()):
        return values
    out = np.empty((len(rows), len(cols)))
    for t, row in enumerate(tokens):
        for k, tok in enumerate(row):
            try:
                v = float(tok) if tok else math.nan
            except ValueError:
                v = None
            if v is None or math.isinf(v) or (math.isnan(v) and not gaps):
                raise FormatError(f"expected a number, found {tok[:40]!r}", source=path,
                                  line=lines[t], frame=t, field=names[cols[k]])
            out[t, k] = v
    return out


# -- time ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Clock:
    """A table's frame rate and how it was found.

    Attributes:
        fps: frames per second.
        reason: how the rate was found, for ``metadata["fps_reason"]``.
        times: (T,) seconds from the first row, or None without a clock.
        irregular: 0-based rows whose step from the previous row is irregular.
    """

    fps: float
    reason: str
    times: np.ndarray | None
    irregular: np.ndarray


def _resolution(tokens: Sequence[str], steps: np.ndarray) -> float:
    """The clock's rounding: one unit of the last digit written (1 for integers), or the
    spacing of the step values it takes when coarser (a millisecond clock written in seconds
    with six decimals steps 0.004 or 0.005: its grain is 0.001)."""
    decimals = 0
    for tok in tokens:
        mantissa = tok.lower().split("e")[0]
        if "." in mantissa:
            decimals = max(decimals, len(mantissa.split(".")[1]))
    written = 10.0 ** -decimals
    values = np.unique(np.round(steps / written))
    grain = float(np.diff(values).min()) * written if len(values) > 1 else 0.0
    return max(written, grain)


def _time_unit(name: str, step: float, path: Path) -> tuple[str, str]:
    """(unit, why) of a clock column from its name, else from its median step."""
    unit = TIME_COLUMNS.get(_key(name))
    if unit is not None:
        return unit, f"column {name!r} names the unit"
    lo, hi = PLAUSIBLE_FPS
    fits = [u for u, s in TIME_UNITS.items() if lo <= 1.0 / (step * s) <= hi]
    if len(fits) != 1:
        raise FormatError(
            f"cannot tell the unit of the clock (median step {step:g}): no unit of "
            f"{', '.join(TIME_UNITS)} gives a capture rate within {lo:g}-{hi:g} Hz; pass fps=",
            source=path, field=name)
    return fits[0], (f"median step {step:g} is {lo:g}-{hi:g} Hz only in {fits[0]}")


def measure_clock(table: Table, header_name: str | None, is_frame: bool, fps: float | None,
                  path: Path, quirks: list[str]) -> Clock:
    """The frame rate of a table (module docstring, **Time**).

    Raises:
        FormatError: a clock that stands still or goes backwards (naming the line), a clock
            whose unit cannot be told, no clock and no ``fps``.
    """
    t = table.time
    if t is None or header_name is None:
        if fps is None:
            raise FormatError(
                "the table has no time column (expected one of ms, time, timestamp, "
                "Time (Seconds), ...); pass fps=", source=path)
        return Clock(float(fps), f"fps={fps:g} given by the caller (no clock in the file)",
                     None, np.zeros(0, dtype=int))
    steps = np.diff(t)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        word = "goes backwards" if steps[k - 1] < 0 else "stands still"
        raise FormatError(
            f"time {word}: {header_name} = {table.time_tokens[k]} after "
            f"{table.time_tokens[k - 1]} (line {int(table.lines[k - 1])}); expected "
            f"increasing time ({bad.size} such step(s))",
            source=path, line=int(table.lines[k]), frame=k, field=header_name)
    median = float(np.median(steps))
    regular = np.abs(steps - median) <= IRREGULAR_STEP_FRACTION * median
    nominal_step = float(steps[regular].mean())
    resolution = _resolution(table.time_tokens, steps)
    irregular = np.flatnonzero(np.abs(steps - nominal_step)
                               > IRREGULAR_STEP_FRACTION * nominal_step + resolution) + 1
    if is_frame:
        if fps is None:
            raise FormatError(
                f"column {header_name!r} numbers the frames but gives no time; pass fps=",
                source=path, field=header_name)
        times = (t - t[0]) / nominal_step / fps
        return Clock(float(fps), f"fps={fps:g} given by the caller; frame numbers in "
                     f"{header_name!r}", times, irregular)
    unit, why = _time_unit(header_name, median, path)
    seconds = TIME_UNITS[unit]
    measured = 1.0 / (nominal_step * seconds)
    span = float(steps[regular].sum())
    tolerance = measured * 2.0 * resolution / span
    near = [f for f in NOMINAL_FPS if abs(f - measured) <= tolerance]
    rate = float(min(near, key=lambda f: abs(f - measured))) if near else measured
    reason = (f"measured from {header_name!r} ({unit}; {why}): mean step "
              f"{nominal_step:.6g} {unit} over {int(regular.sum())} steps = {measured:.4f} Hz")
    if near:
        reason += (f", the nominal {rate:g} Hz within the clock's rounding "
                   f"({resolution:g} {unit} over {span:.6g} {unit})")
    times = (t - t[0]) * seconds
    if fps is not None:
        if abs(fps - rate) > 0.01 * rate:
            quirks.append(f"fps={fps:g} given by the caller; the clock {header_name!r} "
                          f"measures {measured:.3f} Hz")
        return Clock(float(fps), f"fps={fps:g} given by the caller ({reason})", times,
                     irregular)
    return Clock(rate, reason, times, irregular)


def _irregular_error(table: Table, clock: Clock, name: str, path: Path) -> FormatError:
    k = int(clock.irregular[0])
    assert clock.times is not None
    step = (clock.times[k] - clock.times[k - 1]) * 1e3
    return FormatError(
        f"irregular time: {name} steps {step:.4g} ms from line {int(table.lines[k - 1])}, "
        f"where one frame at {clock.fps:g} Hz is {1e3 / clock.fps:.4g} ms ({clock.irregular.size} "
        f"irregular step(s): dropped or repeated frames); pass irregular_time='resample' to "
        "resample onto a regular grid", source=path, line=int(table.lines[k]), frame=k,
        field=name)


def _resample(positions: np.ndarray, times: np.ndarray, fps: float) -> np.ndarray:
    """(T, J, 3) at ``times`` (s) -> (N, J, 3) at ``k / fps``, linear."""
    grid = np.arange(int(np.floor(times[-1] * fps + 1e-9)) + 1) / fps
    flat = positions.reshape(len(times), -1)
    out = np.stack([np.interp(grid, times, flat[:, c]) for c in range(flat.shape[1])], axis=1)
    return out.reshape(len(grid), *positions.shape[1:])


# -- hierarchy -----------------------------------------------------------------------------


#: Spellings of one declared joint: Azure Kinect Body Tracking 1.0 renamed ``SPINE_NAVAL``
#: (the layout's name) to ``SPINE_NAVEL`` (C#: ``SpineNavel``).
_LAYOUT_ALIASES = {"spinenavel": "spinenaval"}


def _layout_key(name: str) -> str:
    key = _key(name)
    return _LAYOUT_ALIASES.get(key, key)


def _declared_layout(joints: Sequence[str]) -> Skeleton | None:
    """The declared skeleton whose joints include all of ``joints`` and whose root is among
    them, renamed and restricted to the table's joints (fewest extra joints wins a tie)."""
    keys = {_layout_key(j): j for j in joints}
    fits = []
    for make in DECLARED_LAYOUTS:
        sk = make()
        own = {_layout_key(n): n for n in sk.joint_names}
        root = sk.joint_names[sk.parents.index(-1)]
        if set(keys) <= set(own) and _layout_key(root) in keys:
            fits.append((sk.num_joints - len(keys), sk, own))
    if not fits:
        return None
    _, sk, own = min(fits, key=lambda f: f[0])
    sub = sk.subset([own[k] for k in keys], name=sk.name if len(keys) == sk.num_joints
                    else f"{sk.name}_{len(keys)}")
    return Skeleton(sub.name, tuple(keys[_layout_key(n)] for n in sub.joint_names), sub.parents)


def name_keypoints(joints: Sequence[str]) -> dict[str, str]:
    """Canonical keypoint -> joint, from the names alone, by the declared naming conventions of
    :mod:`simenv.core.joint_map` (the convention naming most keypoints first; the others fill
    what it lacks; a name matched by two joints of one convention is left out)."""
    prefix = common_prefix(list(joints))
    lookup: dict[NormalisedName, list[str]] = {}
    for j in joints:
        lookup.setdefault(normalise(j, prefix), []).append(j)
    found_by: list[dict[str, str]] = []
    for conv in CONVENTIONS:
        found: dict[str, str] = {}
        for key in CANONICAL_KEYPOINTS:
            side = key.split("_")[0] if key.startswith(("left_", "right_")) else None
            for alias in conv.keypoints.get(key.replace("right_", "left_"), ()):
                want = normalise(alias)
                if side is not None and want.side is not None:
                    want = NormalisedName(side, want.stem)
                hits = lookup.get(want, [])
                if len(hits) == 1:
                    found[key] = hits[0]
                    break
        found_by.append(found)
    canonical: dict[str, str] = {}
    for found in sorted(found_by, key=len, reverse=True):
        for key, joint in found.items():
            if key not in canonical and joint not in canonical.values():
                canonical[key] = joint
    return canonical


def _tree_from_keypoints(joints: Sequence[str], canonical: Mapping[str, str],
                         positions: np.ndarray) -> tuple[list[str], list[int]]:
    """(names, parents) in topological order (module docstring, **Hierarchy** 2)."""
    by_joint = {j: k for k, j in canonical.items()}
    index = {j: i for i, j in enumerate(joints)}
    parent: dict[str, str | None] = {}
    for key, joint in canonical.items():
        up = CANONICAL_TREE[key]
        while up is not None and up not in canonical:
            up = CANONICAL_TREE[up]
        parent[joint] = None if up is None else canonical[up]
    named = [j for j in joints if j in by_joint]
    for j in joints:
        if j not in by_joint:
            d = np.linalg.norm(positions[:, [index[n] for n in named]]
                               - positions[:, index[j]][:, None], axis=-1)
            parent[j] = named[int(np.argmin(np.nanmedian(d, axis=0)))]
    order: list[str] = []
    stack = [canonical["pelvis"]]
    while stack:
        j = stack.pop(0)
        order.append(j)
        stack.extend(c for c in joints if parent[c] == j)
    pos_of = {j: i for i, j in enumerate(order)}
    return order, [-1 if parent[j] is None else pos_of[parent[j]] for j in order]  # type: ignore[index]


def _unmapped_error(joints: Sequence[str], canonical: Mapping[str, str], columns: Sequence[str],
                    path: Path) -> SkeletonError:
    found = ", ".join(f"{k}={v}" for k, v in canonical.items()) or "none"
    lacking = [k for k in REQUIRED_FOR_BODY if k not in canonical]
    return SkeletonError(
        f"cannot build a skeleton: no joint name gives {', '.join(lacking)} (keypoints named: "
        f"{found}). Joints: {', '.join(joints)}. Columns: {', '.join(columns)}. Name them with "
        "joint_map= (simenv.load(path, joint_map={'pelvis': ..., 'left_hip': ..., "
        "'right_hip': ...}) or --joint-map FILE.toml with a [canonical] table)", source=path)


# -- units and axes ------------------------------------------------------------------------


def body_size(positions: np.ndarray) -> float:
    """95th percentile over frames of the largest bounding-box side, file units; (T, J, 3)."""
    return float(np.nanpercentile(np.nanmax(np.ptp(positions, axis=1), axis=1), 95))


def detect_up(positions: np.ndarray, joints: Sequence[str], canonical: Mapping[str, str]
              ) -> tuple[str, str]:
    """(up axis such as ``"y"`` or ``"-y"``, why) of (T, J, 3) file positions (module
    docstring, **Units and axes**)."""
    idx = {j: i for i, j in enumerate(joints)}
    top = next((canonical[k] for k in ("head", "neck") if k in canonical), None)
    bottom = [canonical[k] for k in ("left_ankle", "right_ankle", "left_toe", "right_toe")
              if k in canonical] or [canonical[k] for k in ("pelvis",) if k in canonical]
    if top is not None and bottom:
        v = np.nanmedian(positions[:, idx[top]]
                         - np.nanmean(positions[:, [idx[b] for b in bottom]], axis=1), axis=0)
        a = int(np.argmax(np.abs(v)))
        axis = ("-" if v[a] < 0 else "") + "xyz"[a]
        return axis, (f"{top} lies {abs(v[a]):.4g} file units from {'/'.join(bottom)} along "
                      f"{axis.upper()} (median over the clip; {np.round(v, 4).tolist()})")
    ext = np.nanmedian(np.ptp(positions, axis=1), axis=0)
    a = int(np.argmax(ext))
    return "xyz"[a], (f"no head and feet named: the body's largest median extent is along "
                      f"{'XYZ'[a]} ({np.round(ext, 4).tolist()} file units), taken as +up")


def _check_up(up: str, path: Path) -> str:
    u = up.lower().lstrip("+")
    if u not in UP_TO_Z_UP:
        raise FormatError(f"up must be one of {', '.join(UP_TO_Z_UP)} or None (detect); got "
                          f"{up!r}", source=path)
    return u


# -- read ----------------------------------------------------------------------------------


def read(
    path: Path,
    *,
    units: str | None = None,
    scale: float | None = None,
    up: str | None = None,
    fps: float | None = None,
    frame: Literal["world", "camera"] | None = None,
    irregular_time: Literal["error", "resample"] = "error",
    gaps: Literal["error", "interpolate"] = "error",
    joint_map: JointMapSource | None = None,
    name: str | None = None,
) -> Motion:
    """Read a joint-position table as a :class:`Motion` (metres, Z up; see the module
    docstring for every rule).

    Args:
        path: the table (``.csv``; ``;`` or tab delimiters accepted).
        units: force a length unit (``"m"``, ``"cm"``, ``"mm"``, ``"inch"``) instead of
            detecting it from the body's size; ``scale``: metres per file unit (overrides).
        up: the file's up axis, ``"x"``, ``"y"``, ``"z"`` or negated (``"-y"``); None
            detects it from the body.
        fps: frame rate; required when the table has no clock, else overrides the measured
            rate (noted when they differ by over 1 %).
        frame: ``"world"`` (the table's origin kept), ``"camera"`` (depth-camera
            coordinates, up along +Y or -Y: levelled and put on the floor from the feet) or
            None: camera for a depth camera's declared layout, else world.
        irregular_time: ``"error"`` or ``"resample"`` (onto a regular grid, logged).
        gaps: ``"error"`` or ``"interpolate"`` empty / NaN coordinates (logged).
        joint_map: canonical keypoint -> column joint name (a TOML file or a mapping, see
            :func:`simenv.core.joint_map.read_joint_map`): builds the tree of a table whose
            names no convention gives, and is the canonical map.
        name: clip name; default the file stem.

    Returns:
        Motion (T, J, 3) float32 metres, Z up, joints in tree order; metadata ``source``,
        ``format``, ``units`` and how found, ``up_axis_in_file`` and ``up_reason``,
        ``fps_reason``, ``layout``, ``time_column``, ``ignored_columns``, ``quirks``,
        ``repairs``, ``joint_map``.

    Raises:
        FormatError: bad header, cells or clock (line and column named).
        MotionError: gaps (with ``gaps="error"``), fewer than two rows.
        SkeletonError: joint names that give no pelvis and hips (joints and columns listed).
        UnitsError: a body of no plausible size in any unit.
    """
    path = Path(path)
    if frame not in ("world", "camera", None):
        raise FormatError(f"frame must be 'world', 'camera' or None (detect); got {frame!r}",
                          source=path)
    if irregular_time not in ("error", "resample"):
        raise FormatError(f"irregular_time must be 'error' or 'resample'; got "
                          f"{irregular_time!r}", source=path)
    if gaps not in ("error", "interpolate"):
        raise FormatError(f"gaps must be 'error' or 'interpolate'; got {gaps!r}", source=path)
    forced_up = None if up is None else _check_up(up, path)
    table = read_table(path)
    header = table.header
    quirks: list[str] = []
    repairs: list[str] = []
    pos = _fill_gaps(table, gaps, path, repairs)

    clock_col = header.time if header.time is not None else header.frame
    clock_name = None if clock_col is None else header.columns[clock_col]
    clock = measure_clock(table, clock_name, header.time is None, fps, path, quirks)
    if clock.irregular.size:
        if irregular_time == "error":
            raise _irregular_error(table, clock, clock_name or "", path)
        assert clock.times is not None
        n_in = len(pos)
        pos = _resample(pos, clock.times, clock.fps)
        repairs.append(
            f"time {clock_name!r} irregular at {clock.irregular.size} step(s) (first at line "
            f"{int(table.lines[clock.irregular[0]])}): {n_in} rows resampled linearly onto a "
            f"regular {clock.fps:g} Hz grid ({len(pos)} frames)")

    user = None if joint_map is None else read_joint_map(joint_map)
    where = None if joint_map is None or isinstance(joint_map, Mapping) else str(joint_map)
    declared = _declared_layout(table.joints) if user is None else None
    if declared is not None:
        names, parents, layout = list(declared.joint_names), list(declared.parents), declared.name
    else:
        named = (apply_user_map(table.joints, user, source=where).canonical if user is not None
                 else name_keypoints(table.joints))
        if not all(k in named for k in REQUIRED_FOR_BODY):
            raise _unmapped_error(table.joints, named, header.columns, path)
        names, parents = _tree_from_keypoints(table.joints, named, pos)
        layout = "tree from the joint names" if user is None else "tree from the joint map"
    order = [table.joints.index(n) for n in names]
    pos = pos[:, order]

    by_name = infer_joint_map(names, parents)
    if forced_up is None:
        up_axis, up_reason = detect_up(pos, names, by_name.canonical)
    else:
        up_axis, up_reason = forced_up, f"up={up!r} given by the caller"
    unit_name, s, units_reason, unit_quirks = detect_units(
        body_size(pos), source=path, units=units, scale=scale)
    quirks += unit_quirks
    rot = UP_TO_Z_UP[up_axis]
    metres = (pos @ rot.T) * s
    mapping = (apply_user_map(names, user, source=where) if user is not None
               else infer_joint_map(names, parents, metres))
    skeleton = Skeleton(layout if declared is not None else f"csv{len(names)}", tuple(names),
                        tuple(parents), mapping.canonical)
    meta: dict[str, Any] = {
        "source": str(path),
        **units_metadata(FORMAT, path.stem, unit_name, units_reason, s, up_axis),
        "up_reason": up_reason,
        "fps_reason": clock.reason,
        "layout": layout,
        "time_column": clock_name,
        "rows_in_file": len(table.lines),
        "ignored_columns": list(table.ignored),
        "quirks": quirks,
        "repairs": repairs,
        "joint_map": mapping.as_metadata(),
    }
    if clock.times is not None and table.time is not None:
        meta["time_start"] = table.time_tokens[0]
    if frame is None:
        frame = "camera" if declared is not None and declared.name.startswith(
            DEPTH_CAMERA_LAYOUTS) else "world"
        meta["frame_reason"] = (f"{declared.name}: a depth camera's layout, camera coordinates"
                                if frame == "camera" else "world frame (the table's origin)")
    else:
        meta["frame_reason"] = f"frame={frame!r} given by the caller"
    if frame == "camera":
        if up_axis not in ("y", "-y"):
            raise FormatError(f"frame='camera' needs a camera up axis along +Y or -Y; the body "
                              f"stands along {up_axis.upper()} ({up_reason})", source=path)
        cam = pos * s if up_axis == "y" else (pos @ Y_DOWN_TO_Y_UP.T) * s
        world, est = camera_to_world(cam, skeleton, source=str(path))
        meta["camera_frame"] = est.as_metadata()
        return Motion(world, clock.fps, skeleton, name or path.stem, meta)
    lowest = float(np.median(metres[..., 2].min(axis=1)))
    if abs(lowest) > FLOOR_NOTE_M:
        quirks.append(f"the lowest joint is {lowest:+.2f} m from z = 0 (median over the clip): "
                      "the table's origin is not on the floor (depth-camera coordinates? read "
                      "with frame='camera')")
    return Motion(metres.astype(np.float32), clock.fps, skeleton, name or path.stem, meta)


def _fill_gaps(table: Table, gaps: str, path: Path, repairs: list[str]) -> np.ndarray:
    """The table's positions with NaN gaps refused or, with ``gaps="interpolate"``, filled
    per joint (logged)."""
    pos = table.positions
    missing = np.isnan(pos).any(axis=-1)
    if not missing.any():
        return pos
    t, j = (int(v) for v in np.argwhere(missing)[0])
    if gaps == "error":
        raise MotionError(
            f"missing coordinate (empty or NaN cell) of joint {table.joints[j]!r} in "
            f"{int(missing.sum())} joint-frame(s); expected a number. Pass gaps='interpolate' "
            "to fill gaps linearly", source=path, line=int(table.lines[t]), frame=t,
            field=table.joints[j])
    out = pos.copy()
    for k in np.flatnonzero(missing.any(axis=0)):
        if missing[:, k].all():
            raise MotionError(f"joint {table.joints[k]!r} has no coordinate in any row; "
                              "expected numbers", source=path, field=table.joints[k])
        filled, notes = interpolate_gaps(pos[:, k:k + 1], ~missing[:, k])
        out[:, k] = filled[:, 0]
        repairs += [f"{table.joints[k]}: {n}" for n in notes]
    return out


__all__ = ["AZURE_KINECT_JOINTS", "DECLARED_LAYOUTS", "EXTENSIONS", "MVN_SEGMENTS",
           "azure_kinect_skeleton", "body_size", "detect_up", "measure_clock", "mvn_skeleton",
           "name_keypoints", "parse_header", "read", "read_table", "sniff"]

"""OptiTrack Motive's CSV export of a take: the skeletons' bone positions.

Motive (OptiTrack's capture software) exports a take as one ``.csv``:

1. a take row of ``key,value`` pairs: ``Format Version`` (first), ``Take Name``,
   ``Capture Frame Rate``, ``Export Frame Rate``, ``Total Exported Frames``, ``Rotation Type``
   (``Quaternion``, ``XYZ``, ...), ``Length Units`` (``Millimeters``, ``Centimeters``,
   ``Meters``), ``Coordinate Space`` (``Global`` or ``Local``);
2. a blank row, then one header row per column property, labelled in its second cell:
   ``Type`` (``Bone``, ``Bone Marker``, ``Rigid Body``, ``Rigid Body Marker``, ``Marker``),
   ``Name`` (a bone is ``<Asset>:<Bone>``), ``ID``, ``Parent`` (Motive 3; a bone's parent bone,
   ``Root`` for the hip); then an unlabelled property row (``Rotation``, ``Position``,
   ``Mean Marker Error``, ``Marker Quality``) and the axis row
   (``Frame,Time (Seconds),X,Y,Z,W,...``);
3. one row per frame: frame number, time, then the cells; a cell Motive has no value for
   (a skeleton or marker it lost) is empty.

**Skeletons.** Every ``Bone`` with ``Position`` X, Y and Z columns becomes a joint at that
position, named as written (``763:LThigh``); the bones of one asset (the name before the first
``:``) are one person. Parents come from the ``Parent`` row; without one (Motive 2 and older),
from Motive's fixed skeleton (:data:`MOTIVE_PARENTS`: ``Hip`` > ``Ab`` > ``Chest`` > ``Neck`` >
``Head``, ``Chest`` > ``LShoulder`` > ``LUArm`` > ``LFArm`` > ``LHand`` > fingers, ``Hip`` >
``LThigh`` > ``LShin`` > ``LFoot`` > ``LToe``; Motive 3 names the hip bone after the asset,
``763:763``), a bone whose parent was not exported hanging from its nearest exported ancestor.
Bone rotations, bone markers, rigid bodies and markers are not read (counted in
``metadata["ignored_columns"]``). A take with two skeletons is an :class:`Interaction` (roles
unknown), with more a list of :class:`Motion`; ``skeleton=`` reads one asset.

**Units and axes.** ``Length Units`` gives the scale to metres (:data:`LENGTH_UNITS`); the rate
is ``Export Frame Rate`` (``Capture Frame Rate`` when an older file has no export rate).
Motive's axes are Y up (its default axis convention) and are turned to simenv's Z up as in
every Y-up reader (``(x, y, z) -> (x, -z, y)``); a take exported with another convention is
recognised from the body (the feet-to-head direction, :func:`simenv.io.joint_csv.detect_up`),
converted from that axis and noted in ``quirks``; ``up=`` gives the axis instead (a take in
which the body never stands up). ``Coordinate Space Local`` (bone positions
relative to their parents) is refused: export with Global.

**Lost frames.** Frames where Motive lost a skeleton (its bone cells empty) are never dropped
silently: leading and trailing frames where any skeleton is incomplete are trimmed; inside, each
bone is interpolated linearly over its empty frames; both are listed in ``metadata["repairs"]``
with their file lines. A run of empty frames longer than ``max_gap_s`` is a :class:`MotionError`
naming the lines (interpolating it would invent motion); a skeleton with no complete frame is
left out of a take with others (noted) and is a :class:`MotionError` alone.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import FormatError, MotionError, SkeletonError, UnitsError
from simenv.core.joint_map import infer_joint_map
from simenv.core.motion import Interaction, Motion, interpolate_gaps
from simenv.core.skeletons import Skeleton
from simenv.io.joint_csv import UP_TO_Z_UP, detect_up

#: The loader asks this reader's sniff about ``.csv`` files too (joint_csv stays the reader
#: that explains a ``.csv`` nobody recognises: it comes first in the loader's READERS).
EXTENSIONS = (".csv",)
FORMAT = "motive_csv"

#: ``Length Units`` of the take row -> metres per file unit.
LENGTH_UNITS: dict[str, float] = {"millimeters": 1e-3, "centimeters": 1e-2, "meters": 1.0}

#: A skeleton lost for longer than this (seconds) is an error rather than interpolated: half a
#: second is about one walking step, over which a straight line is no longer the motion.
MAX_GAP_S = 0.5

#: Motive's skeleton bone -> parent bone (the hip, ``Hip`` or the asset's name, is the root):
#: the hierarchy of Motive's skeleton models when the file has no ``Parent`` row.
MOTIVE_PARENTS: dict[str, str] = {
    "Ab": "Hip", "Chest": "Ab", "Neck": "Chest", "Head": "Neck",
    **{f"{s}{b}": p for s in "LR" for b, p in (
        ("Shoulder", "Chest"), ("UArm", f"{s}Shoulder"), ("FArm", f"{s}UArm"),
        ("Hand", f"{s}FArm"), ("Thigh", "Hip"), ("Shin", f"{s}Thigh"), ("Foot", f"{s}Shin"),
        ("Toe", f"{s}Foot"))},
    **{f"{s}{f}{k}": (f"{s}{f}{k - 1}" if k > 1 else f"{s}Hand")
       for s in "LR" for f in ("Thumb", "Index", "Middle", "Ring", "Pinky") for k in (1, 2, 3)},
}

_LABELS = ("Type", "Name", "ID", "Parent")


def sniff(path: Path, head: bytes) -> bool:
    """A text file whose first cell is Motive's ``Format Version``."""
    del path
    first = head.decode("utf-8", errors="replace").lstrip("\ufeff").split("\n", 1)[0]
    return first.split(",", 1)[0].strip().strip('"') == "Format Version"


# -- header ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Take:
    """A Motive CSV export: its header and the numbers simenv reads.

    Attributes:
        info: take row ``key -> value`` (``"Format Version"``, ``"Length Units"``, ...).
        labelled: header label (``"Type"``, ``"Name"``, ``"ID"``, ``"Parent"``) -> its cells.
        properties: the property row's cells (``Position``, ``Rotation``, ...).
        axes: the axis row's cells (``Frame``, ``Time (Seconds)``, ``X``, ...).
        header_lines: label (and ``"property"``, ``"axis"``) -> 1-based file line.
        columns: the file columns held in ``values``: the frame number, the time when there
            is one (``clock`` of them), then every ``Bone`` ``Position`` column.
        values: (R, len(columns)) float64 of the R frame rows; NaN where a bone cell is empty.
        lines: (R,) 1-based file line of each frame row.
    """

    info: dict[str, str]
    labelled: dict[str, list[str]]
    properties: list[str]
    axes: list[str]
    header_lines: dict[str, int]
    columns: tuple[int, ...]
    clock: int
    values: np.ndarray
    lines: list[int]

    def column_name(self, c: int) -> str:
        """File column ``c`` as ``<Name> <property> <axis>`` (``763:LShin Position X``)."""
        return f"{self.labelled['Name'][c]} {self.properties[c]} {self.axes[c]}".strip()


def parse_take(path: Path) -> Take:
    """The take row, header rows and frame rows of a Motive CSV export (module docstring),
    read row by row (a full take is ~10^4 rows of ~10^3 cells; only bone positions are kept).

    Raises:
        FormatError: no ``Format Version`` first, a missing ``Type``, ``Name``, property or
            axis row, a header or frame row with another cell count than the axis row, a kept
            cell that is not a number or an empty frame number / time (naming the line).
    """
    path = Path(path)
    try:
        fh = path.open(encoding="utf-8-sig", errors="replace", newline="")
    except OSError as exc:
        raise FormatError(f"cannot read file: {exc.strerror or exc}", source=path) from None
    with fh:
        reader = csv.reader(fh)
        try:
            return _parse(path, ((reader.line_num, [c.strip() for c in cells])
                                 for cells in reader))
        except csv.Error as exc:
            raise FormatError(f"not CSV: {exc}", source=path, line=reader.line_num) from None


def _parse(path: Path, rows: Iterator[tuple[int, list[str]]]) -> Take:
    _, first = next(rows, (1, []))
    if not first or first[0] != "Format Version":
        raise FormatError("expected Motive's take row starting 'Format Version,<version>'",
                          source=path, line=1, field="Format Version")
    info = {k: v for k, v in zip(first[0::2], first[1::2], strict=False) if k}
    labelled: dict[str, list[str]] = {}
    header_lines: dict[str, int] = {}
    previous: tuple[int, list[str]] | None = None
    axes: list[str] | None = None
    for line, cells in rows:
        if not any(cells):
            continue
        if cells[0] == "Frame":
            if previous is None or any(c in _LABELS for c in previous[1][:2]):
                raise FormatError("expected the property row (Position, Rotation, ...) above "
                                  "the axis row", source=path, line=line, field="property")
            header_lines["property"], header_lines["axis"] = previous[0], line
            axes = cells
            break
        label = next((c for c in cells[:2] if c), "")
        if label in _LABELS:
            labelled[label], header_lines[label] = cells, line
        previous = (line, cells)
    if axes is None or previous is None:
        raise FormatError("no axis row ('Frame,Time (Seconds),X,Y,Z,...'); expected it below "
                          "the Type / Name / ID rows", source=path)
    for label in ("Type", "Name"):
        if label not in labelled:
            raise FormatError(f"no {label!r} header row; expected a row whose second cell is "
                              f"{label!r} above the axis row", source=path, field=label)
    properties = previous[1]
    width = len(axes)
    for name, line, row in [*((lab, header_lines[lab], labelled[lab]) for lab in labelled),
                            ("property", header_lines["property"], properties)]:
        if len(row) != width:
            raise FormatError(f"the {name} row has {len(row)} cells; the axis row has {width}",
                              source=path, line=line, field=name)
    types = labelled["Type"]
    clock = [0] + [c for c, a in enumerate(axes) if a == "Time (Seconds)"][:1]
    keep = clock + [c for c in range(width) if types[c] == "Bone" and properties[c] == "Position"]
    take = Take(info, labelled, properties, axes, header_lines, tuple(keep), len(clock),
                np.empty((0, len(keep))), [])
    values: list[list[float]] = []
    for line, cells in rows:
        if not any(cells):
            continue
        if len(cells) != width:
            raise FormatError(f"row has {len(cells)} cells; the header has {width} columns "
                              "(a ragged or truncated row)", source=path, line=line)
        tokens = [cells[c] for c in keep]
        try:
            row = [float(t) if t else math.nan for t in tokens]
        except ValueError:
            row = []
        # Bone cells may be empty (a lost skeleton); the frame number and time may not.
        if len(row) != len(keep) or not all(math.isfinite(v) for v in row[:len(clock)]) or \
                any(math.isinf(v) for v in row):
            _bad_cell(take, tokens, line, len(values), path)
        values.append(row)
        take.lines.append(line)
    return replace(take, values=np.array(values, dtype=np.float64).reshape(-1, len(keep)))


def _bad_cell(take: Take, tokens: list[str], line: int, frame: int, path: Path) -> None:
    """Raise the FormatError of the first kept cell of a row that is not a number (or is
    empty in the frame number or time column)."""
    for k, (c, tok) in enumerate(zip(take.columns, tokens, strict=True)):
        try:
            v = float(tok) if tok or k >= take.clock else math.nan
        except ValueError:
            v = None
        if v is None or math.isinf(v) or (k < take.clock and not math.isfinite(v)):
            raise FormatError(f"expected a number, found {tok[:40]!r}", source=path,
                              line=line, frame=frame, field=take.column_name(c))


# -- skeletons -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Person:
    """One skeleton asset of a take: bones (file names, parents before children), their
    parents (indices, -1 for the root) and the (X, Y, Z) column of each bone."""

    asset: str
    bones: tuple[str, ...]
    parents: tuple[int, ...]
    columns: tuple[tuple[int, int, int], ...]
    parents_from: str


def _asset(name: str) -> str:
    return name.split(":", 1)[0] if ":" in name else ""


def _bone(name: str) -> str:
    return name.split(":", 1)[1] if ":" in name else name


def _fixed_parent(bone: str, asset: str, present: set[str]) -> str | None:
    """The nearest exported ancestor of ``bone`` (its short name) in :data:`MOTIVE_PARENTS`
    (None for the hip), or ``""`` for a bone Motive's skeleton does not have."""
    if bone in ("Hip", asset):
        return None
    if bone not in MOTIVE_PARENTS:
        return ""
    up = MOTIVE_PARENTS[bone]
    while True:
        for candidate in ((up, asset) if up == "Hip" else (up,)):
            if candidate in present:
                return candidate
        if up == "Hip":
            return ""
        up = MOTIVE_PARENTS[up]


def skeletons(take: Take, path: Path) -> tuple[list[Person], dict[str, int]]:
    """The take's skeletons (file order) and the count of every column type not read.

    Raises:
        SkeletonError: no ``Bone`` position columns (naming what the take holds), a parent
            that is not a bone of its skeleton, a cycle, a bone outside Motive's skeleton with
            no ``Parent`` row.
        FormatError: a bone without its three Position axes.
    """
    types, names = take.labelled["Type"], take.labelled["Name"]
    parent_row = take.labelled.get("Parent")
    columns: dict[str, dict[str, int]] = {}
    ignored: dict[str, int] = {}
    for c in range(len(types)):
        if types[c] in ("", *_LABELS):
            continue
        if types[c] == "Bone" and take.properties[c] == "Position":
            axes = columns.setdefault(names[c], {})
            axis = take.axes[c].lower()
            if axis not in ("x", "y", "z") or axis in axes:
                raise FormatError(f"bone {names[c]!r}: Position column with axis "
                                  f"{take.axes[c]!r}; expected one X, one Y and one Z",
                                  source=path, line=take.header_lines["axis"], field=names[c])
            axes[axis] = c
        else:
            key = f"{types[c]} {take.properties[c]}".strip()
            ignored[key] = ignored.get(key, 0) + 1
    if not columns:
        held = ", ".join(f"{k}: {n}" for k, n in ignored.items()) or "no data columns"
        raise SkeletonError(f"the take has no skeleton (no Bone Position columns; it holds "
                            f"{held}); export it with Skeletons / Bones enabled", source=path,
                            line=take.header_lines["Type"], field="Type")
    for bone, axes in columns.items():
        if len(axes) != 3:
            raise FormatError(f"bone {bone!r} has Position {', '.join(sorted(axes)).upper()}; "
                              "expected X, Y and Z", source=path,
                              line=take.header_lines["axis"], field=bone)
    people = []
    for asset in dict.fromkeys(_asset(n) for n in columns):
        bones = [n for n in columns if _asset(n) == asset]
        if parent_row is not None:
            parent = {n: parent_row[columns[n]["x"]] for n in bones}
            for n, p in parent.items():
                if p not in ("", "Root") and p not in parent:
                    raise SkeletonError(f"bone {n!r} has parent {p!r}, which is not a bone of "
                                        f"skeleton {asset!r}", source=path,
                                        line=take.header_lines["Parent"], field=n)
            parent = {n: (None if p in ("", "Root") else p) for n, p in parent.items()}
            how = "the file's Parent row"
        else:
            short = {_bone(n): n for n in bones}
            parent = {}
            for n in bones:
                p = _fixed_parent(_bone(n), asset, set(short))
                if p == "":
                    raise SkeletonError(f"bone {n!r} is not in Motive's skeleton and the file "
                                        "has no Parent row to place it", source=path,
                                        line=take.header_lines["Name"], field=n)
                parent[n] = None if p is None else short[p]
            how = "Motive's skeleton hierarchy (no Parent row)"
        people.append(_person(asset, parent, columns, path, how))
    return people, ignored


def _person(asset: str, parent: dict[str, str | None], columns: dict[str, dict[str, int]],
            path: Path, how: str) -> Person:
    """The bones in an order with parents before children (file order otherwise)."""
    roots = [n for n, p in parent.items() if p is None]
    if len(roots) != 1:
        raise SkeletonError(f"skeleton {asset!r} has {len(roots)} root bones "
                            f"({', '.join(roots) or 'none'}); expected one (the hip)",
                            source=path, field=asset)
    order: list[str] = []
    placed: set[str] = set()
    while len(order) < len(parent):
        before = len(order)
        for n, p in parent.items():  # one pass when the file lists parents first
            if n not in placed and (p is None or p in placed):
                order.append(n)
                placed.add(n)
        if len(order) == before:
            loop = [n for n in parent if n not in placed]
            raise SkeletonError(f"skeleton {asset!r}: the Parent row makes a cycle through "
                                f"{', '.join(loop)}", source=path, field=loop[0])
    index = {n: i for i, n in enumerate(order)}
    parents = tuple(-1 if parent[n] is None else index[parent[n]] for n in order)
    cols = tuple((columns[n]["x"], columns[n]["y"], columns[n]["z"]) for n in order)
    return Person(asset, tuple(order), parents, cols, how)


# -- frames ----------------------------------------------------------------------------------


def _span(complete: np.ndarray) -> tuple[int, int] | None:
    """First and last frame index where ``complete``, or None."""
    idx = np.flatnonzero(complete)
    return (int(idx[0]), int(idx[-1])) if idx.size else None


def _fill(pos: np.ndarray, person: Person, lines: Sequence[int], max_gap: int | None,
          fps: float, path: Path) -> tuple[np.ndarray, list[str]]:
    """``pos`` (T, J, 3) with each bone's empty frames interpolated linearly (notes with the
    file lines).

    Raises:
        MotionError: a run of empty frames longer than ``max_gap`` frames.
    """
    missing = np.isnan(pos).any(axis=-1)
    notes: list[str] = []
    out = pos.copy()
    lost = missing.all(axis=1)
    for j in np.flatnonzero(missing.any(axis=0)):
        bad = np.flatnonzero(missing[:, j])
        for run in np.split(bad, np.flatnonzero(np.diff(bad) > 1) + 1):
            if max_gap is not None and len(run) > max_gap:
                raise MotionError(
                    f"bone {person.bones[j]!r} is empty for {len(run)} frames "
                    f"({len(run) / fps:.2f} s, lines {lines[run[0]]}-{lines[run[-1]]}), longer "
                    f"than max_gap_s={max_gap / fps:.2f} s; pass a larger max_gap_s (or None) "
                    "to interpolate over it", source=path, line=lines[run[0]],
                    frame=int(run[0]), field=person.bones[j])
        filled, _ = interpolate_gaps(pos[:, j:j + 1], ~missing[:, j])
        out[:, j] = filled[:, 0]
    if lost.any():
        bad = np.flatnonzero(lost)
        runs = np.split(bad, np.flatnonzero(np.diff(bad) > 1) + 1)
        notes += [f"skeleton lost at frames {r[0]}-{r[-1]} (lines {lines[r[0]]}-"
                  f"{lines[r[-1]]}, {len(r)} frames): every bone interpolated linearly"
                  for r in runs]
    partial = missing.any(axis=0) & ~(missing == lost[:, None]).all(axis=0)
    for j in np.flatnonzero(partial):
        n = int((missing[:, j] & ~lost).sum())
        notes.append(f"bone {person.bones[j]!r} empty in {n} frame(s) where others were "
                     "tracked: interpolated linearly")
    return out, notes


def _info_float(take: Take, key: str, path: Path) -> float | None:
    if key not in take.info:
        return None
    try:
        value = float(take.info[key])
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise FormatError(f"{key} is {take.info[key]!r}; expected a positive number",
                          source=path, line=1, field=key)
    return value


def read(path: str | Path, *, skeleton: str | None = None, max_gap_s: float | None = MAX_GAP_S,
         up: str | None = None, name: str | None = None
         ) -> Motion | Interaction | list[Motion]:
    """Read the skeletons of an OptiTrack Motive CSV export (module docstring).

    Args:
        path: the ``.csv`` Motive exported.
        skeleton: the asset to read (the name before ``:`` in its bone names); default all.
        max_gap_s: longest run of frames (seconds) a bone may be empty and be interpolated;
            None interpolates any run.
        up: the file's up axis (``"y"``, ``"z"``, ``"-x"``, ...: the take's export axis
            convention); None detects it from the body (Y for Motive's default convention).
        name: clip name; default the file stem (``<name>:<asset>`` for several skeletons).

    Returns:
        One skeleton: a :class:`Motion` (T, J, 3) float32 metres, Z up, one joint per bone;
        two: an :class:`Interaction` (roles unknown); more: a list of Motions. Metadata:
        ``source``, ``format``, ``take`` (the take row), ``skeleton`` (asset), ``units``,
        ``scale_m_per_unit``, ``up_axis_in_file`` and ``up_reason``, ``fps_reason``,
        ``parents_from``, ``rows_in_file``, ``first_frame``, ``time_start_s``,
        ``ignored_columns``, ``repairs``, ``quirks``, ``joint_map``.

    Raises:
        FormatError: a malformed take row, header or frame row (naming the line and field), a
            missing frame rate, ``Coordinate Space Local``.
        UnitsError: ``Length Units`` that are not Millimeters, Centimeters or Meters.
        SkeletonError: no skeleton, no asset named ``skeleton``, a bad ``Parent`` row.
        MotionError: fewer than two frames where the skeletons are tracked, a longer gap
            than ``max_gap_s``.
    """
    path = Path(path)
    if max_gap_s is not None and not max_gap_s >= 0:
        raise FormatError(f"max_gap_s must be >= 0 or None, got {max_gap_s!r}", source=path,
                          field="max_gap_s")
    if up is not None and up.lower() not in UP_TO_Z_UP:
        raise FormatError(f"up must be one of {', '.join(UP_TO_Z_UP)}, got {up!r}",
                          source=path, field="up")
    take = parse_take(path)
    info = take.info
    space = info.get("Coordinate Space", "Global")
    if space.lower() != "global":
        raise FormatError(f"Coordinate Space is {space!r}: bone positions relative to their "
                          "parents are not read; export the take with Coordinate Space Global",
                          source=path, line=1, field="Coordinate Space")
    fps = _info_float(take, "Export Frame Rate", path)
    fps_reason = "Export Frame Rate of the take row"
    if fps is None:
        fps = _info_float(take, "Capture Frame Rate", path)
        fps_reason = "Capture Frame Rate of the take row (it has no Export Frame Rate)"
    if fps is None:
        raise FormatError("the take row has no Export Frame Rate (nor Capture Frame Rate); "
                          "expected 'Export Frame Rate,<Hz>'", source=path, line=1,
                          field="Export Frame Rate")
    if "Length Units" not in info:
        raise FormatError("the take row has no Length Units; expected 'Length Units,"
                          "Millimeters' (or Centimeters, Meters)", source=path, line=1,
                          field="Length Units")
    unit = info["Length Units"]
    if unit.lower() not in LENGTH_UNITS:
        raise UnitsError(f"Length Units {unit!r} is not one Motive writes; expected "
                         f"{', '.join(u.capitalize() for u in LENGTH_UNITS)}", source=path,
                         line=1, field="Length Units")
    scale = LENGTH_UNITS[unit.lower()]
    people, ignored = skeletons(take, path)
    if skeleton is not None:
        chosen = [p for p in people if p.asset == skeleton]
        if not chosen:
            raise SkeletonError(f"no skeleton {skeleton!r}; the take has "
                                f"{', '.join(repr(p.asset) for p in people)}", source=path,
                                field="skeleton")
        people = chosen
    at = {c: k for k, c in enumerate(take.columns)}
    values = take.values[:, [at[c] for p in people for trio in p.columns for c in trio]]
    clock = take.values[:, :take.clock]
    quirks: list[str] = []
    if take.clock == 2 and len(take.lines) > 1:
        # Over the whole take: Motive rounds the times it writes (0.008, 0.016, 0.025 s).
        step = (clock[-1, 1] - clock[0, 1]) / (len(take.lines) - 1)
        if abs(step * fps - 1.0) > 0.01:
            quirks.append(f"Time (Seconds) advances {step * 1e3:.3f} ms per row on average, "
                          f"not the {1e3 / fps:.3f} ms of {fps:g} fps: rows missing or "
                          "re-timed; the frame rate is taken from the take row")
    pos_all, start = [], 0
    for p in people:
        n = 3 * len(p.bones)
        pos_all.append(values[:, start:start + n].reshape(len(take.lines), len(p.bones), 3))
        start += n
    complete = [~np.isnan(p).any(axis=(1, 2)) for p in pos_all]
    kept = [k for k, c in enumerate(complete) if c.any()]
    for k in set(range(len(people))) - set(kept):
        quirks.append(f"skeleton {people[k].asset!r} has no frame with every bone tracked: "
                      "left out")
    if not kept:
        raise MotionError(f"no frame has every bone of a skeleton ({len(take.lines)} frame "
                          "rows); Motive lost the skeleton throughout", source=path)
    people, pos_all = [people[k] for k in kept], [pos_all[k] for k in kept]
    span = _span(np.logical_and.reduce([complete[k] for k in kept]))
    if span is None or span[1] - span[0] < 1:
        raise MotionError("fewer than two frames where every skeleton is tracked together",
                          source=path)
    first, last = span
    repairs: list[str] = []
    if first or last < len(take.lines) - 1:
        repairs.append(f"trimmed {first} leading and {len(take.lines) - 1 - last} trailing "
                       f"frame(s) where a skeleton was not tracked (kept lines "
                       f"{take.lines[first]}-{take.lines[last]})")
    lines = take.lines[first:last + 1]
    max_gap = None if max_gap_s is None else int(round(max_gap_s * fps))
    motions = []
    for p, pos in zip(people, pos_all, strict=True):
        filled, notes = _fill(pos[first:last + 1], p, lines, max_gap, fps, path)
        clip = name or path.stem
        motions.append(_motion(p, filled, take, path, fps, fps_reason, scale, unit, ignored,
                               repairs + notes, list(quirks), up,
                               f"{clip}:{p.asset or 'skeleton'}" if len(people) > 1 else clip,
                               clock[first]))
    if len(motions) == 1:
        return motions[0]
    if len(motions) == 2:
        return Interaction(motions[0], motions[1], label=None, roles_known=False,
                           name=name or path.stem,
                           metadata={"source": str(path), "format": FORMAT,
                                     "skeletons": [p.asset for p in people],
                                     "repairs": [f"{m.name}: {r}" for m in motions
                                                 for r in m.metadata["repairs"]],
                                     "quirks": quirks})
    return motions


def _motion(person: Person, pos: np.ndarray, take: Take, path: Path, fps: float,
            fps_reason: str, scale: float, unit: str, ignored: dict[str, int],
            repairs: list[str], quirks: list[str], forced_up: str | None, name: str,
            clock0: np.ndarray) -> Motion:
    """One person's Motion: file axes to Z up, file units to metres, the joint map."""
    names, parents = list(person.bones), list(person.parents)
    if forced_up is not None:
        up, up_reason = forced_up.lower(), f"up={forced_up!r} given by the caller"
    else:
        up, up_reason = detect_up(pos, names, infer_joint_map(names, parents).canonical)
    if up != "y" and forced_up is None:
        quirks.append(f"the body stands along {up.upper()} in the file, not Motive's default "
                      f"Y up ({up_reason}): read with {up.upper()} up")
    metres = (pos @ UP_TO_Z_UP[up].T) * scale
    mapping = infer_joint_map(names, parents, metres)
    meta: dict[str, Any] = {
        "source": str(path), "format": FORMAT, "take": dict(take.info),
        "skeleton": person.asset, "units": unit, "scale_m_per_unit": scale,
        "up_axis_in_file": up, "up_reason": up_reason, "fps_reason": fps_reason,
        "parents_from": person.parents_from, "rows_in_file": len(take.lines),
        "first_frame": int(clock0[0]),
        "time_start_s": float(clock0[1]) if len(clock0) > 1 else None,
        "ignored_columns": {**ignored, "note": "positions of the skeletons' bones are read; "
                            "bone rotations, markers and rigid bodies are not"},
        "repairs": repairs, "quirks": quirks, "joint_map": mapping.as_metadata(),
    }
    skel = Skeleton(f"motive{len(names)}", tuple(names), tuple(parents), mapping.canonical)
    return Motion(metres.astype(np.float32), float(fps), skel, name, meta)


__all__ = ["EXTENSIONS", "FORMAT", "LENGTH_UNITS", "MAX_GAP_S", "MOTIVE_PARENTS", "Person",
           "Take", "parse_take", "read", "skeletons", "sniff"]

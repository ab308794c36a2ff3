"""Azure Kinect Body Tracking recordings: the offline processor's JSON and SDK joint tables.

The Azure Kinect Body Tracking SDK (``k4abt``) tracks 32 joints per body (``PELVIS``,
``SPINE_NAVEL``, ``SPINE_CHEST``, ``NECK``, ``CLAVICLE_LEFT``, ``SHOULDER_LEFT``, ...,
``EAR_RIGHT``; :data:`simenv.io.joint_csv.AZURE_KINECT_JOINTS`) in the depth camera's frame:
x right, y **down**, z away from the sensor, millimetres. Two recording layouts are read:

* **Offline processor JSON** (``.json``; Microsoft's ``Azure-Kinect-Samples``
  ``body-tracking-samples/offline_processor`` and the tools built on it): an object with
  ``frames`` (each ``{"frame_id", "timestamp_usec", "num_bodies", "bodies": [{"body_id",
  "joint_positions": [[x, y, z] x 32], "joint_orientations": ...}]}``), ``joint_names`` (the
  32 names, SDK order; SDK order is assumed when absent) and ``bone_list``. One body is read:
  ``body_id=`` or, by default, the body id present in most frames. The clock is
  ``timestamp_usec``; the rate is the median step rounded to the sensor's nearest rate
  (:data:`SENSOR_FPS`). Frames where the body is missing, or a step over
  :data:`GAP_STEPS` nominal steps, are resampled linearly onto a uniform grid at that rate
  (logged in ``metadata["repairs"]``).
* **SDK joint tables** (``.csv``), as written by applications of the C# SDK (``Enum.GetName
  (typeof(JointId), i)`` headers): a header row naming the joints in the SDK's C or C#
  spelling (``SPINE_NAVEL`` or ``SpineNavel``), and one row per frame whose cell per joint
  holds ``x y z`` separated by spaces. Such a table has no clock: the rate is ``fps=``, by
  default :data:`DEFAULT_FPS` (the sensor's highest rate), which is noted in
  ``metadata["fps_reason"]`` as assumed.

Joint names are compared in lower case without separators; the SDK's pre-1.0 spelling
``SPINE_NAVAL`` (renamed ``SPINE_NAVEL`` in SDK 1.0) is accepted too. Every one of the 32
joints must be present. Length units are detected from the body's size (``units=`` /
``scale=`` override; the offline processor writes millimetres, the C# tables often metres);
the camera frame is converted to the world frame as for every depth camera
(:func:`simenv.io.camera_frame.world_motion`: levelled and put on the floor from the feet).
Joints are named as in :func:`simenv.io.joint_csv.azure_kinect_skeleton`; the canonical map
comes from :mod:`simenv.core.joint_map` (convention ``azure_kinect``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import FormatError, MotionError
from simenv.core.joint_map import infer_joint_map
from simenv.core.motion import Motion
from simenv.core.skeletons import Skeleton
from simenv.io._kinect_text import resample_stamped
from simenv.io._kinematics import detect_units
from simenv.io._text import read_text, split_lines
from simenv.io.camera_frame import world_motion
from simenv.io.joint_csv import (
    AZURE_KINECT_JOINTS,
    Y_DOWN_TO_Y_UP,
    azure_kinect_skeleton,
    body_size,
)

#: Extensions this reader claims when no sniffer accepts a file.
EXTENSIONS = (".json",)
#: In a folder, a file counts as motion only when :func:`sniff` accepts it.
FOLDER_NEEDS_SNIFF = True
FORMAT = "azure_kinect"

#: Frame rates the Azure Kinect depth camera runs at (Hz).
SENSOR_FPS: tuple[float, ...] = (5.0, 15.0, 30.0)
#: Rate assumed for a table without a clock (Hz): the sensor's highest.
DEFAULT_FPS = 30.0
#: A clock step longer than this many nominal steps is a gap (dropped frames).
GAP_STEPS = 1.5

#: The joints compared by :func:`joint_key`, in SDK order.
_KEYS: tuple[str, ...] = tuple(re.sub(r"[^0-9a-z]", "", j.lower()) for j in AZURE_KINECT_JOINTS)
#: Spellings of one joint: the pre-1.0 SDK's "naval", the 1.0 SDK's "navel".
_ALIASES = {"spinenavel": "spinenaval"}


def joint_key(name: str) -> str:
    """A joint name as compared with the SDK's: lower case, letters and digits only, the
    1.0 SDK's ``SPINE_NAVEL`` read as the pre-1.0 ``SPINE_NAVAL`` simenv's layout uses."""
    key = re.sub(r"[^0-9a-z]", "", name.lower())
    return _ALIASES.get(key, key)


def _order(names: list[str]) -> list[int] | None:
    """Index in ``names`` of each SDK joint, SDK order; None unless all 32 are there."""
    keys = [joint_key(n) for n in names]
    if any(k not in keys for k in _KEYS):
        return None
    return [keys.index(k) for k in _KEYS]


# -- sniff ---------------------------------------------------------------------------------


def _table_header(line: str) -> list[str]:
    return [c.strip().strip('"') for c in line.lstrip("\ufeff").split(",")]


def sniff(path: Path, head: bytes) -> bool:
    """An offline-processor JSON (``"bodies"`` and ``"joint_positions"`` in its head) or a
    ``.csv`` whose header names the 32 SDK joints and whose first row has ``x y z`` cells."""
    text = head.decode("utf-8", errors="replace")
    suffix = path.suffix.lower()
    if suffix == ".json":
        return '"bodies"' in text and ('"joint_positions"' in text or '"body_id"' in text)
    if suffix != ".csv":
        return False
    lines = [ln for ln in split_lines(text) if ln.strip()]
    if len(lines) < 2 or _order(_table_header(lines[0])) is None:
        return False
    cells = lines[1].split(",")
    return all(len(c.split()) == 3 for c in cells[:len(_KEYS)])


# -- read ----------------------------------------------------------------------------------


def _read_table(path: Path) -> tuple[np.ndarray, list[int]]:
    """(T, 32, 3) file-unit positions in SDK order and each row's 1-based line."""
    lines = split_lines(read_text(path))
    rows = [(k, ln) for k, ln in enumerate(lines, start=1) if ln.strip()]
    if not rows:
        raise FormatError("file is empty; expected a header row of Azure Kinect joint names",
                          source=path)
    header = _table_header(rows[0][1])
    order = _order(header)
    if order is None:
        missing = [j for j, k in zip(AZURE_KINECT_JOINTS, _KEYS, strict=True)
                   if k not in {joint_key(h) for h in header}]
        raise FormatError(f"header lacks Azure Kinect joint(s) {', '.join(missing)}; expected "
                          "the 32 Body Tracking joints", source=path, line=rows[0][0])
    frames: list[np.ndarray] = []
    line_numbers: list[int] = []
    for n, (line, text) in enumerate(rows[1:]):
        cells = text.split(",")
        if len(cells) < len(header):
            raise FormatError(f"row has {len(cells)} cells; the header names {len(header)} "
                              "joints", source=path, line=line, frame=n)
        xyz = np.empty((len(_KEYS), 3))
        for j, c in enumerate(order):
            parts = cells[c].split()
            try:
                if len(parts) != 3:
                    raise ValueError
                xyz[j] = [float(p) for p in parts]
            except ValueError:
                raise FormatError(f"expected 'x y z' (three numbers), found {cells[c][:40]!r}",
                                  source=path, line=line, frame=n, field=header[c]) from None
        if not np.isfinite(xyz).all():
            raise FormatError("expected finite coordinates", source=path, line=line, frame=n)
        frames.append(xyz)
        line_numbers.append(line)
    if len(frames) < 2:
        raise MotionError(f"table holds {len(frames)} frame row(s); expected at least 2",
                          source=path)
    return np.stack(frames), line_numbers


def _field(obj: Any, key: str, kind: type | tuple[type, ...], path: Path, frame: int | None,
           where: str) -> Any:
    value = obj.get(key) if isinstance(obj, dict) else None
    if not isinstance(value, kind) or isinstance(value, bool):
        raise FormatError(f"expected {where} to have {key!r} ({getattr(kind, '__name__', kind)})"
                          f", found {type(value).__name__}", source=path, frame=frame,
                          field=key)
    return value


def _read_json(path: Path, body_id: int | None) -> tuple[np.ndarray, np.ndarray, int, int]:
    """(N, 32, 3) file-unit positions of one body, (N,) seconds from its first frame, the
    body id and the number of frames in the file."""
    try:
        data = json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise FormatError(f"not JSON: {exc.msg}", source=path, line=exc.lineno) from None
    frames = _field(data, "frames", list, path, None, "the top-level object")
    names = data.get("joint_names", list(AZURE_KINECT_JOINTS))
    order = _order(names) if isinstance(names, list) and all(isinstance(n, str) for n in names) \
        else None
    if order is None:
        raise FormatError("'joint_names' are not the 32 Azure Kinect Body Tracking joints",
                          source=path, field="joint_names")
    counts: dict[int, int] = {}
    for n, fr in enumerate(frames):
        for b in _field(fr, "bodies", list, path, n, f"frame {n}"):
            bid = _field(b, "body_id", int, path, n, f"a body of frame {n}")
            counts[bid] = counts.get(bid, 0) + 1
    if not counts:
        raise MotionError(f"no body in any of the {len(frames)} frames", source=path)
    if body_id is None:
        body_id = max(counts, key=lambda b: (counts[b], -b))
    elif body_id not in counts:
        raise MotionError(f"no body with body_id {body_id}; the file has "
                          f"{', '.join(str(b) for b in sorted(counts))}", source=path,
                          field="body_id")
    pos: list[np.ndarray] = []
    stamps: list[float] = []
    for n, fr in enumerate(frames):
        for b in fr["bodies"]:
            if b["body_id"] != body_id:
                continue
            joints = _field(b, "joint_positions", list, path, n, f"body {body_id} of frame {n}")
            try:
                xyz = np.asarray(joints, dtype=np.float64)
            except (TypeError, ValueError):
                xyz = np.empty(0)
            if xyz.shape != (len(names), 3) or not np.isfinite(xyz).all():
                raise FormatError(f"expected {len(names)} [x, y, z] joint positions (finite "
                                  f"numbers), found shape {xyz.shape}", source=path, frame=n,
                                  field="joint_positions")
            pos.append(xyz[order])
            stamps.append(float(_field(fr, "timestamp_usec", (int, float), path, n,
                                       f"frame {n}")))
    if len(pos) < 2:
        raise MotionError(f"body {body_id} is in {len(pos)} frame(s); expected at least 2",
                          source=path)
    t = np.asarray(stamps) * 1e-6
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        raise FormatError(f"timestamp_usec {stamps[back[0] + 1]:.0f} does not increase from "
                          f"{stamps[back[0]]:.0f}", source=path, frame=int(back[0]) + 1,
                          field="timestamp_usec")
    return np.stack(pos), t - t[0], body_id, len(frames)


def _nominal_fps(t: np.ndarray) -> float:
    """The sensor rate (:data:`SENSOR_FPS`) nearest the median clock step's."""
    rate = 1.0 / float(np.median(np.diff(t)))
    return min(SENSOR_FPS, key=lambda f: abs(np.log(f / rate)))


def read(path: str | Path, *, fps: float | None = None, body_id: int | None = None,
         units: str | None = None, scale: float | None = None,
         name: str | None = None) -> Motion:
    """Read one body of an Azure Kinect Body Tracking recording (module docstring).

    Args:
        path: an offline-processor ``.json`` or an SDK joint table ``.csv``.
        fps: frames per second: for a JSON, the rate of the uniform grid (default: the
            sensor rate its clock gives); for a table (no clock), its rate (default
            :data:`DEFAULT_FPS`, noted as assumed).
        body_id: the JSON body to read (default: the one in most frames).
        units: force a length unit (``"m"``, ``"mm"``, ...); ``scale``: metres per file unit.
        name: clip name; default the file stem.

    Returns:
        A world-frame :class:`Motion` (T, 32, 3) metres, Z up, on the Azure Kinect skeleton;
        metadata ``source``, ``format``, ``units`` and ``units_reason``, ``fps_reason``,
        ``body_id`` (JSON), ``repairs``, ``quirks``, ``camera_frame``, ``joint_map``.

    Raises:
        FormatError: a header, cell, JSON field or clock that is not the format (naming the
            file and the line, frame or field).
        MotionError: fewer than two frames of the body, or no such body.
        UnitsError: a body of no plausible size in any unit.
    """
    path = Path(path)
    if fps is not None and not fps > 0:
        raise FormatError(f"fps must be positive, got {fps!r}", source=path, field="fps")
    repairs: list[str] = []
    quirks: list[str] = []
    meta: dict[str, Any] = {}
    if path.suffix.lower() == ".json":
        pos, t, bid, n_frames = _read_json(path, body_id)
        nominal = _nominal_fps(t)
        rate = fps or nominal
        meta["body_id"] = bid
        fps_reason = (f"fps={fps:g} given by the caller" if fps else
                      f"timestamp_usec: median step {np.median(np.diff(t)) * 1e3:.2f} ms, "
                      f"the sensor's {nominal:g} Hz")
        gaps = int((np.diff(t) > GAP_STEPS / nominal).sum())
        if gaps or fps:
            n_in = len(pos)
            t, pos = resample_stamped(t, pos, rate)
            repairs.append(f"{n_in} frames of body {bid} ({n_frames} in the file; {gaps} "
                           f"step(s) over {GAP_STEPS:g} frames) resampled linearly onto a "
                           f"uniform {rate:g} Hz grid ({len(pos)} frames)")
    else:
        if body_id is not None:
            raise FormatError("body_id= applies to the offline processor's JSON; a joint "
                              "table holds one body", source=path, field="body_id")
        pos, _ = _read_table(path)
        rate = fps or DEFAULT_FPS
        fps_reason = (f"fps={fps:g} given by the caller" if fps else
                      f"no clock in the table: {DEFAULT_FPS:g} Hz assumed (the sensor's "
                      "highest rate; pass fps= for another)")
    unit, s, units_reason, unit_quirks = detect_units(body_size(pos), source=path,
                                                      units=units, scale=scale)
    quirks += unit_quirks
    # Azure's camera frame (y down, x right) turned to the Kinect convention the floor
    # estimate expects (y up, x left): 180 deg about the optical axis.
    cam = (pos @ Y_DOWN_TO_Y_UP.T) * s
    declared = azure_kinect_skeleton()
    mapping = infer_joint_map(declared.joint_names, declared.parents)
    skeleton = Skeleton(declared.name, declared.joint_names, declared.parents,
                        mapping.canonical)
    meta.update({
        "source": str(path), "format": FORMAT, "units": unit, "units_reason": units_reason,
        "scale_m_per_unit": s, "fps_reason": fps_reason, "repairs": repairs, "quirks": quirks,
        "joint_map": mapping.as_metadata(),
    })
    return world_motion(cam.astype(np.float64), skeleton, fps=float(rate),
                        name=name or path.stem, metadata=meta, source=str(path))


__all__ = ["DEFAULT_FPS", "EXTENSIONS", "FORMAT", "GAP_STEPS", "SENSOR_FPS", "joint_key",
           "read", "sniff"]

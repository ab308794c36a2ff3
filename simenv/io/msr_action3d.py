"""MSR Action3D skeletons (``aAA_sSS_eEE_skeleton3D.txt``, real-world coordinates).

Format (see ``gestures/SOURCES.md``): plain text, 4 numbers per line ``x y z c``
(metres in the Kinect camera frame, ``c`` a per-joint confidence in [0, 1]),
20 lines per frame in MSR's own joint order, frames back to back, no header.
The reader reorders the joints to the Kinect SDK v1 order
(:func:`simenv.core.skeletons.kinect_v1_skeleton`) with :data:`MSR_TO_SDK`.

Quirks handled:

* **Dropouts.** A frame written as 20 lines of ``0 0 0 0`` is a tracking
  dropout. Dropouts between tracked frames are filled by linear interpolation
  (:func:`simenv.core.motion.interpolate_gaps`); leading and trailing dropouts are
  trimmed instead (holding a pose still for seconds would invent motion:
  ``a13_s09_e03`` has 740 such frames around 196 tracked ones). Both are
  listed in ``metadata["repairs"]`` and ``metadata["trimmed"]`` gives the
  (leading, trailing) counts. A file with no tracked frame at all (``a13_s09_e02``)
  raises :class:`MotionError`.
* **Confidence** ``c`` is not documented by the dataset; its per-joint mean is
  kept in ``metadata["confidence_mean"]`` and it does not change positions.
* **Frame rate.** No timestamps; the depth maps were captured at about 15 fps
  (Li et al. 2010), which the arm-wave periods confirm (~1.1 Hz), so
  ``fps=15`` by default.
* **Labels** come from the file name: class (1-20, names in
  :data:`MSR_CLASSES`), subject and repetition.

Positions are converted to the world frame by
:func:`simenv.io.camera_frame.world_motion` (floor from the feet).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Motion, interpolate_gaps
from simenv.core.skeletons import kinect_v1_skeleton
from simenv.io._kinect_text import check_counts, sniff_rows, table_lines, to_floats
from simenv.io.camera_frame import world_motion

#: Nominal frame rate of MSR Action3D, frames/s.
MSR_FPS = 15.0
JOINTS_PER_FRAME = 20

#: For each Kinect SDK v1 joint, its 0-based index in an MSR frame.
MSR_TO_SDK: tuple[int, ...] = (6, 3, 2, 19, 0, 7, 9, 11, 1, 8, 10, 12, 4, 13, 15, 17, 5, 14, 16, 18)

#: The 20 action classes, class id 1..20 in order.
MSR_CLASSES: tuple[str, ...] = (
    "high arm wave", "horizontal arm wave", "hammer", "hand catch", "forward punch",
    "high throw", "draw x", "draw tick", "draw circle", "hand clap", "two hand wave",
    "side-boxing", "bend", "forward kick", "side kick", "jogging", "tennis swing",
    "tennis serve", "golf swing", "pick up & throw",
)

_NAME = re.compile(r"a(\d+)_s(\d+)_e(\d+)", re.IGNORECASE)


def sniff(path: Path, head: bytes) -> bool:
    """A ``.txt`` whose lines hold exactly 4 numbers (``x y z c``)."""
    return sniff_rows(path, head, suffix=".txt", lines=40, sep=None, counts=(4,))


def labels_from_name(path: Path) -> dict[str, object]:
    """``label``, ``class_id``, ``subject`` and ``repetition`` parsed from an
    MSR file name (empty when the name does not follow the pattern)."""
    m = _NAME.search(path.name)
    if not m:
        return {}
    cls, subject, rep = (int(g) for g in m.groups())
    out: dict[str, object] = {"class_id": cls, "subject": subject, "repetition": rep}
    if 1 <= cls <= len(MSR_CLASSES):
        out["label"] = MSR_CLASSES[cls - 1]
    return out


def read(path: Path, *, fps: float = MSR_FPS) -> Motion:
    """Read one MSR Action3D skeleton file.

    Args:
        path: the ``*_skeleton3D.txt`` file.
        fps: frame rate to assign (default :data:`MSR_FPS`).

    Returns:
        A world-frame :class:`Motion` on the Kinect v1 skeleton, metres.
    """
    path = Path(path)
    rows = table_lines(path, None)
    check_counts(path, rows, (4,), "x y z confidence")
    if len(rows) % JOINTS_PER_FRAME:
        raise FormatError(
            f"{len(rows)} data lines is not a multiple of {JOINTS_PER_FRAME} (one line per "
            "joint); the file is truncated or has extra lines",
            source=path,
            line=rows[-1][0],
        )
    data = to_floats(path, rows, ["x", "y", "z", "confidence"])
    data = data.reshape(-1, JOINTS_PER_FRAME, 4)[:, MSR_TO_SDK]
    xyz, conf = data[..., :3], data[..., 3]
    valid = ~(data == 0).all(axis=(1, 2))
    if not valid.any():
        raise MotionError(
            f"all {len(data)} frames are zero (tracking dropouts); no skeleton to read",
            source=path,
        )
    repairs: list[str] = []
    tracked = np.flatnonzero(valid)
    first, last = int(tracked[0]), int(tracked[-1])
    lead, trail = first, len(valid) - 1 - last
    if lead or trail:
        repairs.append(f"trimmed {lead} leading and {trail} trailing all-zero (dropout) frames")
    xyz, conf, valid = xyz[first:last + 1], conf[first:last + 1], valid[first:last + 1]
    if not valid.all():
        xyz, notes = interpolate_gaps(xyz, valid)
        repairs += [f"tracking dropout (all-zero frame): {n} of the trimmed clip" for n in notes]
    meta: dict[str, object] = {
        "source": str(path),
        "format": "msr_action3d",
        "units": "m (camera frame)",
        "dataset": "MSR Action3D",
        "repairs": repairs,
        "dropout_frames": int((~valid).sum()) + lead + trail,
        "trimmed": [lead, trail],
        "confidence_mean": np.round(conf[valid].mean(axis=0), 3).tolist(),
        "fps_source": "nominal 15 fps capture (no timestamps in the file)",
    }
    meta |= labels_from_name(path)
    return world_motion(
        xyz, kinect_v1_skeleton(), fps=fps, name=path.name.split(".")[0], metadata=meta,
        source=str(path),
    )

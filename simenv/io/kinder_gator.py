"""Kinder-Gator Kinect v1 recordings (``POSE-p<PID>_<NN>-<Motion-name>-<unix ms>.csv``).

Kinder-Gator (Aloba et al., "Kinder-Gator: The UF Kinect Database of Child and Adult
Motion", Eurographics 2018 short paper): 10 adults and 10 children, 58 motions each
(wave your hand, wave your other hand, bow, touch your toes, throw a ball, ...), one
recording per motion and person, tracked by a Kinect v1.

Format (the dataset's README and its files):

* A header line ``Timestamp,HipCenterX,HipCenterY,HipCenterZ,...,FootRightZ,User-ID,
  Action,`` naming the 20 Kinect SDK v1 joints in SDK order (hip centre, spine, shoulder
  centre, head, left arm, right arm, left leg, right leg), x y z each.
* One line per frame, comma-separated: a time stamp in **milliseconds** (a clock of the
  recording machine; rows come about every 33 ms, unevenly), the 60 coordinates (metres
  in the Kinect camera frame, y up, z away from the sensor), the participant id and the
  motion name, and a trailing comma (64 fields).
* File name: ``POSE-p<PID>_<NN>-<Motion-name>-<unix time ms>.csv``: ``NN`` is the motion's
  place in the order this participant performed them (the order differs between
  participants), so the motion is read from its *name*, never its number.

The reader interpolates every joint linearly onto a uniform :data:`KINDER_GATOR_FPS`
grid over the time stamps (``fps=None`` keeps one frame per row), and converts to the
world frame (:func:`simenv.io.camera_frame.world_motion`, floor from the feet). A row
whose 60 coordinates are all zero (no skeleton tracked), or whose time stamp the next
row repeats (55 of the 1159 files hold such rows), is dropped and listed in
``metadata["repairs"]``. ``metadata`` carries ``subject`` (the PID), ``motion`` (the
name with spaces, e.g. ``"Wave your hand"``), ``order`` (NN) and ``group``
(``"adult"`` / ``"child"`` from the parent folder, when it is ``Adults`` / ``Children``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Motion
from simenv.core.skeletons import KINECT_V1_JOINTS, kinect_v1_skeleton
from simenv.io._kinect_text import resample_stamped, table_lines, to_floats
from simenv.io.camera_frame import world_motion

#: Output frame rate of the uniform grid, frames/s (the Kinect v1 skeleton stream).
KINDER_GATOR_FPS = 30.0
JOINTS = 20
#: Fields of a frame line: time, 60 coordinates, participant id, motion name.
FIELDS = 1 + 3 * JOINTS + 2
#: File-name pattern of a recording.
PATTERN = "POSE-p*_*-*.csv"

_NAME = re.compile(r"POSE-p(\d+)_(\d+)-(.+?)-(\d+)$", re.IGNORECASE)


def labels_from_name(path: Path) -> dict[str, object]:
    """``subject`` (PID), ``order`` (NN), ``motion`` (its name, dashes as spaces) and
    ``group`` parsed from a Kinder-Gator path (empty when the name does not follow
    ``POSE-p<PID>_<NN>-<Motion-name>-<unix ms>.csv``)."""
    m = _NAME.search(Path(path).stem)
    if not m:
        return {}
    pid, order, motion, _ = m.groups()
    out: dict[str, object] = {"subject": int(pid), "order": int(order),
                              "motion": " ".join(motion.replace("-", " ").split())}
    group = {"adults": "adult", "children": "child"}.get(Path(path).parent.name.lower())
    if group:
        out["group"] = group
    return out


def _header_ok(tokens: list[str]) -> bool:
    """Whether a header line names the time and the 20 SDK joints in SDK order."""
    want = ["timestamp"] + [f"{j}{c}".lower() for j in KINECT_V1_JOINTS for c in "XYZ"]
    return [t.lower() for t in tokens[:len(want)]] == want


def read(path: str | Path, *, fps: float | None = KINDER_GATOR_FPS) -> Motion:
    """Read one Kinder-Gator recording.

    Args:
        path: the ``.csv`` file.
        fps: frame rate of the uniform grid the rows are interpolated onto, frames/s;
            None: one frame per tracked row at the median rate (module docstring).

    Returns:
        A world-frame :class:`Motion` on the Kinect v1 skeleton, metres, with the labels
        of :func:`labels_from_name` in ``metadata``.

    Raises:
        FormatError: a header that is not the Kinder-Gator one, a frame line without 64
            fields or with a non-numeric coordinate, a time stamp that goes back (each
            naming file, line and field).
        MotionError: no tracked row, or fewer than 2 to interpolate between.
    """
    path = Path(path)
    rows = table_lines(path, ",")
    line0, header = rows[0]
    if not _header_ok(header):
        raise FormatError("expected the Kinder-Gator header 'Timestamp,HipCenterX,"
                          "HipCenterY,HipCenterZ,...' (20 Kinect v1 joints in SDK order); "
                          f"found {','.join(header[:4])!r}...", source=path, line=line0)
    frames = rows[1:]
    for n, (line, tokens) in enumerate(frames):
        # The trailing comma makes a 64th, empty field; a file written without it is fine.
        if len(tokens) == FIELDS + 1 and tokens[-1] == "":
            tokens.pop()
        if len(tokens) != FIELDS:
            raise FormatError(f"expected {FIELDS} comma-separated fields per frame (time, "
                              f"20 joints x y z, User-ID, Action), found {len(tokens)}",
                              source=path, line=line, frame=n)
    if not frames:
        raise MotionError("no frame line after the header", source=path)
    names = ["Timestamp"] + [f"{j}{c}" for j in KINECT_V1_JOINTS for c in "XYZ"]
    data = to_floats(path, [(line, tokens[:1 + 3 * JOINTS]) for line, tokens in frames],
                     names)
    lines = [line for line, _ in frames]
    t_ms = data[:, 0]
    step = np.diff(t_ms)
    bad = np.flatnonzero(step < 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise FormatError(f"time stamp {t_ms[k]:.4f} goes back from {t_ms[k - 1]:.4f}; "
                          "expected increasing milliseconds", source=path, line=lines[k],
                          frame=k, field="Timestamp")
    # Some recordings stamp two consecutive rows alike (55 of the 1159 files): the
    # later row is kept, the earlier one cannot be placed in time.
    repeated = np.concatenate([step == 0, [False]])
    xyz = data[:, 1:].reshape(-1, JOINTS, 3)
    tracked = ~(xyz == 0).all(axis=(1, 2)) & ~repeated
    if not tracked.any():
        raise MotionError(f"all {len(xyz)} frames are zero (no skeleton tracked)",
                          source=path)
    repairs = []
    if repeated.any():
        repairs.append(f"dropped {int(repeated.sum())} rows whose time stamp the next row "
                       f"repeats (first at line {lines[int(np.flatnonzero(repeated)[0])]})")
    untracked = int((~tracked).sum() - repeated.sum())
    if untracked:
        repairs.append(f"dropped {untracked} untracked (all-zero) frames")
    t_s = (t_ms[tracked] - t_ms[tracked][0]) / 1e3
    pos = xyz[tracked]
    gaps = np.diff(t_s)
    if fps is None:
        out_fps = 1.0 / float(np.median(gaps)) if gaps.size else KINDER_GATOR_FPS
    else:
        if len(pos) < 2:
            raise MotionError(f"only one tracked frame; need 2 to interpolate onto a {fps:g} "
                              "fps grid (or read with fps=None)", source=path)
        out_fps = float(fps)
        _, pos = resample_stamped(t_s, pos, out_fps)
    meta: dict[str, object] = {
        "source": str(path), "format": "kinder_gator", "units": "m (camera frame)",
        "dataset": "Kinder-Gator", "repairs": repairs,
        "timing": {"mode": "resample" if fps else "rows", "clock": "milliseconds",
                   "rows": int(len(t_ms)), "tracked_rows": int(tracked.sum()),
                   "spacing_ms": [round(float(gaps.min() * 1e3), 1) if gaps.size else 0.0,
                                  round(float(gaps.max() * 1e3), 1) if gaps.size else 0.0]},
    }
    meta |= labels_from_name(path)
    return world_motion(pos, kinect_v1_skeleton(), fps=out_fps, name=path.stem,
                        metadata=meta, source=str(path))


__all__ = ["FIELDS", "KINDER_GATOR_FPS", "PATTERN", "labels_from_name", "read"]

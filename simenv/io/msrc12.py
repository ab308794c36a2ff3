"""MSRC-12 Kinect gesture recordings (``P<A>_<B>_<C>_p<D>.csv`` + ``.tagstream``).

Format (the dataset's description, ``MSRC_12_gesture_dataset.pdf``, and its MATLAB
loaders ``load_file.m`` / ``load_tagstream.m`` / ``skel_model.m`` by S. Nowozin):

* ``.csv``: one line per frame, space-separated, **81 numbers**: a time stamp, then
  ``x y z w`` of the 20 Kinect SDK v1 joints in SDK order (hip centre, spine, shoulder
  centre, head, left arm, right arm, left leg, right leg), metres in the Kinect camera
  frame (y up, z away from the sensor). ``w`` is 1 on tracked frames (the homogeneous
  coordinate). A frame with no tracked skeleton is all zeros (recordings start with
  some). The time stamp counts microseconds (the tagstream's clock converted as
  ``load_tagstream.m`` does: ``(tick * 1000 + 49875 / 2) / 49875``); frames come about
  every 33 ms but unevenly (21-77 ms in ``P1_1_1_p19``).
* ``.tagstream`` beside it: a header ``XQPCTick;Tag``, then one line per gesture instance,
  ``<tick>;G<k> <name>``: the instant at which the gesture should be recognised (its
  "action point"), ``k`` in 1-12 (:data:`MSRC12_GESTURES`).
* File name: ``P<A>_<B>_<C>_p<D>``: ``A``, ``B`` the instruction given (text, images,
  video, combinations), ``C`` the gesture (``12A``: a second take), ``D`` the person
  (1-30).

The reader trims leading and trailing all-zero frames, drops the untracked frames between
(listed in ``metadata["repairs"]``) and interpolates every joint linearly onto a uniform
:data:`MSRC12_FPS` grid over the time stamps (by default; ``fps=None`` keeps one frame per
tracked row at its median rate, the uneven timing noted in ``quirks``). The tags go to
``metadata["gestures"]``: ``{"gesture_id", "label", "time_s", "frame"}``, ``time_s``
from the first kept frame and ``frame`` the nearest frame of the returned motion.

Person p06 of MSRC-12 is reserved for evaluation in this project; the reader reads any
person, the corpora that train (:mod:`simenv.learning.cross_dataset`) leave p06 out.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Motion
from simenv.core.skeletons import kinect_v1_skeleton
from simenv.io._kinect_text import (
    check_counts,
    resample_stamped,
    sniff_rows,
    table_lines,
    to_floats,
)
from simenv.io._text import read_text, split_lines
from simenv.io.camera_frame import world_motion

#: Output frame rate of the uniform grid, frames/s (the Kinect v1 skeleton stream).
MSRC12_FPS = 30.0
JOINTS = 20
VALUES_PER_ROW = 1 + 4 * JOINTS
#: Tagstream clock ticks per millisecond (``load_tagstream.m``).
TICKS_PER_MS = 49875.0
#: Gaps between tracked frames longer than this are listed as repairs, seconds.
LONG_GAP_S = 0.5
#: The 12 gestures, id 1..12 in order (as their tags name them).
MSRC12_GESTURES: tuple[str, ...] = (
    "lift outstretched arms", "duck", "push right", "goggles", "wind it up", "shoot",
    "bow", "throw", "had enough", "change weapon", "beat both", "kick",
)

_NAME = re.compile(r"p(\d+)_(\d+)_(\d+)(a?)_p(\d+)", re.IGNORECASE)
_TAG = re.compile(r"G(\d+)\b\s*(.*)")


def sniff(path: Path, head: bytes) -> bool:
    """A ``.csv`` whose lines hold 81 space-separated numbers, the first an integer."""
    return sniff_rows(path, head, suffix=".csv", lines=3, sep=None, counts=(VALUES_PER_ROW,),
                      accept=lambda t: float(t[0]).is_integer())


def labels_from_name(path: Path) -> dict[str, object]:
    """``instruction`` ([A, B]), ``gesture_id``, ``take`` (1, or 2 for an ``A`` file),
    ``subject`` and ``label`` parsed from an MSRC-12 file name (empty when the name does
    not follow ``P<A>_<B>_<C>_p<D>``)."""
    m = _NAME.search(path.name)
    if not m:
        return {}
    a, b, c, again, d = m.groups()
    out: dict[str, object] = {"instruction": [int(a), int(b)], "gesture_id": int(c),
                              "take": 2 if again else 1, "subject": int(d)}
    if 1 <= int(c) <= len(MSRC12_GESTURES):
        out["label"] = MSRC12_GESTURES[int(c) - 1]
    return out


def tick_to_us(tick: float) -> float:
    """A tagstream tick as the csv's microsecond clock (``load_tagstream.m``)."""
    return (tick * 1000.0 + TICKS_PER_MS / 2) / TICKS_PER_MS


def read_tagstream(path: Path) -> list[tuple[float, int, str]]:
    """The gesture instants of a ``.tagstream``: ``(time in microseconds, gesture id
    1-12, tag text)`` per line, in file order.

    Raises:
        FormatError: a missing ``XQPCTick;Tag`` header or a line that is not
            ``<integer tick>;G<k> <name>`` with ``k`` in 1-12 (naming the line).
    """
    path = Path(path)
    lines = [(i, ln.strip()) for i, ln in enumerate(split_lines(read_text(path)), start=1)
             if ln.strip()]
    if not lines or lines[0][1].replace(" ", "").lower() != "xqpctick;tag":
        raise FormatError("expected the header 'XQPCTick;Tag' on the first line",
                          source=path, line=lines[0][0] if lines else 1)
    out = []
    for i, text in lines[1:]:
        tick, sep, tag = text.partition(";")
        m = _TAG.match(tag.strip())
        if not sep or not tick.strip().isdigit() or m is None:
            raise FormatError(f"expected '<tick>;G<k> <gesture name>', found {text[:60]!r}",
                              source=path, line=i, field="Tag")
        k = int(m.group(1))
        if not 1 <= k <= len(MSRC12_GESTURES):
            raise FormatError(f"gesture G{k} is not one of G1-G12", source=path, line=i,
                              field="Tag")
        out.append((tick_to_us(float(tick)), k, tag.strip()))
    return out


def _rows(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[int]]:
    """(R,) times in microseconds, (R, 20, 3) positions (m, camera frame), (R,) tracked
    flags and the 1-based file line of each row.

    Raises:
        FormatError: a row without 81 numbers, a time that decreases or repeats.
    """
    rows = table_lines(path, None)
    check_counts(path, rows, (VALUES_PER_ROW,), "time + 20 joints x y z w")
    names = ["time"] + [f"{j}.{c}" for j in kinect_v1_skeleton().joint_names
                        for c in "xyzw"]
    data = to_floats(path, rows, names)
    lines = [r[0] for r in rows]
    t = data[:, 0]
    step = np.diff(t)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise FormatError(f"time stamp {t[k]:.0f} does not increase on {t[k - 1]:.0f}; "
                          "expected increasing microseconds", source=path, line=lines[k],
                          frame=k, field="time")
    joints = data[:, 1:].reshape(-1, JOINTS, 4)
    tracked = ~(joints == 0).all(axis=(1, 2))
    return t, joints[..., :3], tracked, lines


def read(path: Path, *, fps: float | None = MSRC12_FPS, tags: Path | str | None = None
         ) -> Motion:
    """Read one MSRC-12 recording and its gesture tags.

    Args:
        path: the ``.csv`` file.
        fps: frame rate of the uniform grid the tracked frames are interpolated onto;
            None: one frame per tracked row (module docstring).
        tags: the tagstream file; default the ``.tagstream`` beside ``path`` when present
            (a recording without one has no ``gestures``).

    Returns:
        A world-frame :class:`Motion` on the Kinect v1 skeleton, metres, with
        ``metadata["gestures"]`` and the labels of :func:`labels_from_name`.

    Raises:
        FormatError: bad rows or tagstream (naming line and field), a given tagstream
            that does not exist.
        MotionError: no tracked frame, or fewer than 2 to interpolate between.
    """
    path = Path(path)
    t_us, xyz, tracked, lines = _rows(path)
    if not tracked.any():
        raise MotionError(f"all {len(t_us)} frames are zero (no skeleton tracked)",
                          source=path)
    keep = np.flatnonzero(tracked)
    first, last = int(keep[0]), int(keep[-1])
    repairs: list[str] = []
    quirks: list[str] = []
    lead, trail = first, len(tracked) - 1 - last
    if lead or trail:
        repairs.append(f"trimmed {lead} leading and {trail} trailing all-zero (untracked) "
                       "frames")
    inner = int((~tracked[first:last + 1]).sum())
    if inner:
        repairs.append(f"dropped {inner} untracked (all-zero) frames between tracked ones "
                       "(bridged by interpolation)" if fps else
                       f"dropped {inner} untracked (all-zero) frames between tracked ones")
    t_s = (t_us[keep] - t_us[first]) / 1e6
    pos = xyz[keep]
    gaps = np.diff(t_s)
    for k in np.flatnonzero(gaps > LONG_GAP_S):
        repairs.append(f"{gaps[k]:.2f} s without a tracked skeleton after line "
                       f"{lines[keep[k]]}")
    if fps is None:
        out_fps = 1.0 / float(np.median(gaps)) if gaps.size else MSRC12_FPS
        quirks.append(f"one frame per tracked row at {out_fps:.3g} fps (median spacing); "
                      f"true spacing {gaps.min() * 1e3 if gaps.size else 0:.0f}-"
                      f"{gaps.max() * 1e3 if gaps.size else 0:.0f} ms")
        times = t_s
    else:
        if len(keep) < 2:
            raise MotionError("only one tracked frame; need 2 to interpolate onto a "
                              f"{fps:g} fps grid (or read with fps=None)", source=path)
        out_fps = float(fps)
        times, pos = resample_stamped(t_s, pos, out_fps)
    meta: dict[str, object] = {
        "source": str(path),
        "format": "msrc12",
        "units": "m (camera frame)",
        "dataset": "MSRC-12",
        "repairs": repairs,
        "quirks": quirks,
        "trimmed": [lead, trail],
        "timing": {"mode": "resample" if fps else "rows", "clock": "microseconds",
                   "rows": int(len(t_us)), "tracked_rows": int(len(keep))},
    }
    meta |= labels_from_name(path)
    tag_path = Path(tags) if tags is not None else path.with_suffix(".tagstream")
    if tags is not None and not tag_path.is_file():
        raise FormatError(f"tagstream {tag_path} not found", source=path)
    if tag_path.is_file():
        meta["tagstream"] = str(tag_path)
        meta["gestures"] = [
            {"gesture_id": k, "label": MSRC12_GESTURES[k - 1], "tag": tag,
             "time_s": round(float((us - t_us[first]) / 1e6), 4),
             "frame": int(np.argmin(np.abs(times - (us - t_us[first]) / 1e6)))}
            for us, k, tag in read_tagstream(tag_path)]
    return world_motion(pos, kinect_v1_skeleton(), fps=out_fps, name=path.stem,
                        metadata=meta, source=str(path))

"""UTKinect-Action3D sessions (``joints_sSS_eEE.txt`` + ``actionLabel.txt``).

Format (see ``gestures/SOURCES.md``): one row per stored skeleton, 61 numbers:
a frame number, then ``x y z`` of the 20 Kinect SDK v1 joints in SDK order,
metres, Kinect camera frame. Each file is one continuous session in which the
subject does all 10 actions; ``actionLabel.txt`` next to it gives, per session,
``label: start_frame end_frame`` in frame-number units.

Quirks handled:

* **Duplicate frame numbers** (~2.6 % of rows: a second skeleton estimate of
  the same frame): the first row is kept, the others dropped; the count is in
  ``metadata["repairs"]``. Decreasing frame numbers are a :class:`FormatError`.
* **Timing.** The frame-number clock runs at about :data:`FRAME_CLOCK_HZ` = 60
  units/s (SOURCES.md: walking speed, wave and clap periods all agree with
  60, not 30), and rows are stored every 2-8 units (median 4) with a few long
  jumps where tracking was lost. Rows are therefore *not* evenly spaced in
  time. By default (``timing="resample"``) the reader puts the rows at
  ``t = frame / 60`` s and interpolates linearly onto a uniform grid at
  ``fps`` = 15 (the dataset README's "about 15 f/sec"), so velocities are
  right; gaps longer than :data:`LONG_GAP_S` are listed in
  ``metadata["repairs"]``. ``timing="rows"`` instead gives one frame per kept
  row at ``fps = 60 / median step`` (uneven timing, noted in ``quirks``).
* **Segments.** ``metadata["segments"]`` is a list of ``{"label", "start",
  "end", "start_frame", "end_frame"}``: ``start``/``end`` are frame indices
  of the Motion (``end`` exclusive, so ``motion.slice(start, end)`` is the
  segment), converted from the label file's frame numbers. A segment given
  as ``NaN NaN`` (``s10_e02 carry``) is left out and noted in ``quirks``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Literal

import numpy as np

from simenv.core.errors import FormatError
from simenv.core.motion import Motion
from simenv.core.skeletons import kinect_v1_skeleton
from simenv.io._kinect_text import check_counts, sniff_rows, table_lines, to_floats
from simenv.io._text import read_text, split_lines
from simenv.io.camera_frame import world_motion

#: Units of the frame-number column per second (see module docstring).
FRAME_CLOCK_HZ = 60.0
#: Output frame rate when resampling, frames/s.
UTK_FPS = 15.0
#: Gaps between stored rows longer than this are reported as repairs, seconds.
LONG_GAP_S = 0.5
VALUES_PER_ROW = 61

_SESSION = re.compile(r"(s\d+_e\d+)", re.IGNORECASE)


def sniff(path: Path, head: bytes) -> bool:
    """A ``.txt`` whose rows hold 61 numbers, the first an integer frame number."""
    return sniff_rows(path, head, suffix=".txt", lines=3, sep=None, counts=(VALUES_PER_ROW,),
                      accept=lambda t: float(t[0]).is_integer())


def read_labels(path: Path) -> dict[str, list[tuple[str, float, float]]]:
    """Parse an ``actionLabel.txt``: session key (``s01_e01``) -> list of
    ``(label, start_frame, end_frame)`` (NaN bounds kept as ``nan``)."""
    path = Path(path)
    out: dict[str, list[tuple[str, float, float]]] = {}
    session: str | None = None
    for i, line in enumerate(split_lines(read_text(path)), start=1):
        s = line.strip()
        if not s:
            continue
        if ":" not in s:
            session = s.lower()
            out.setdefault(session, [])
            continue
        if session is None:
            raise FormatError(
                "segment line before any session name (expected e.g. 's01_e01')",
                source=path, line=i,
            )
        label, _, rest = s.partition(":")
        parts = rest.split()
        if len(parts) != 2:
            raise FormatError(
                f"expected 'label: start end', found {s[:60]!r}", source=path, line=i
            )
        try:
            start, end = float(parts[0]), float(parts[1])
        except ValueError:
            raise FormatError(
                f"segment bounds must be numbers (or NaN), found {rest.strip()[:40]!r}",
                source=path, line=i, field=label.strip(),
            ) from None
        out[session].append((label.strip(), start, end))
    if not out:
        raise FormatError("label file is empty; expected session blocks", source=path)
    return out


def read(
    path: Path,
    *,
    labels: Path | str | None | Literal[False] = None,
    timing: Literal["resample", "rows"] = "resample",
    fps: float = UTK_FPS,
) -> Motion:
    """Read one UTKinect session.

    Args:
        path: ``joints_sSS_eEE.txt``.
        labels: action-label file; default ``actionLabel.txt`` next to
            ``path`` when present; ``False`` to skip segments.
        timing: ``"resample"`` (uniform ``fps`` grid over ``frame / 60`` s) or
            ``"rows"`` (one frame per kept row); see module docstring.
        fps: output rate for ``timing="resample"``.

    Returns:
        World-frame :class:`Motion` (Kinect v1 skeleton) with
        ``metadata["segments"]``.
    """
    path = Path(path)
    frames, xyz, repairs = _rows(path)
    quirks: list[str] = []
    steps = np.diff(frames)
    median_step = float(np.median(steps)) if steps.size else 1.0
    xyz, out_fps, to_index = _timing(frames, xyz, timing, fps, median_step, repairs, quirks)
    segments, label_path = _segments(path, labels, to_index, quirks)
    meta: dict[str, object] = {
        "source": str(path),
        "format": "utkinect",
        "units": "m (camera frame)",
        "dataset": "UTKinect-Action3D",
        "repairs": repairs,
        "quirks": quirks,
        "segments": segments,
        "timing": {"mode": timing, "frame_clock_hz": FRAME_CLOCK_HZ,
                   "median_frame_step": median_step, "rows": int(len(frames))},
        "frame_numbers": frames.astype(int).tolist(),
    }
    if label_path is not None:
        meta["labels_file"] = str(label_path)
    m = re.search(r"s(\d+)_e(\d+)", path.name, re.IGNORECASE)
    if m:
        meta["subject"], meta["repetition"] = int(m.group(1)), int(m.group(2))
    return world_motion(
        xyz, kinect_v1_skeleton(), fps=out_fps, name=path.name.split(".")[0], metadata=meta,
        source=str(path),
    )


def _rows(path: Path) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The stored rows: (R,) frame numbers, strictly increasing, and (R, 20, 3) joint
    positions, m (camera frame), a row repeating the previous frame number dropped (a
    repair noted in the returned list).

    Raises:
        FormatError: a row without 61 numbers, a frame number that is not an integer or
            that decreases.
    """
    rows = table_lines(path, None)
    check_counts(path, rows, (VALUES_PER_ROW,), "frame number + 20 joints x y z")
    data = to_floats(path, rows)
    frames = data[:, 0]
    lines = [r[0] for r in rows]
    bad = np.flatnonzero(frames != np.round(frames))
    if bad.size:
        raise FormatError(
            f"frame number must be an integer, found {frames[bad[0]]!r}",
            source=path, line=lines[bad[0]], field="frame number",
        )
    step = np.diff(frames)
    dec = np.flatnonzero(step < 0)
    if dec.size:
        raise FormatError(
            f"frame number decreases ({frames[dec[0]]:.0f} -> {frames[dec[0] + 1]:.0f}); "
            "expected non-decreasing frame numbers",
            source=path, line=lines[dec[0] + 1], field="frame number",
        )
    keep = np.concatenate([[True], step > 0])
    repairs: list[str] = []
    if not keep.all():
        repairs.append(
            f"dropped {int((~keep).sum())} rows repeating the previous frame number "
            "(duplicate skeleton estimates; kept the first of each)"
        )
    return frames[keep], data[keep, 1:].reshape(-1, 20, 3), repairs


def _timing(frames: np.ndarray, xyz: np.ndarray, timing: str, fps: float, median_step: float,
            repairs: list[str], quirks: list[str]
            ) -> tuple[np.ndarray, float, Callable[..., int]]:
    """The frames of the motion (module docstring, *timing*): (T, 20, 3) positions, their
    rate, and ``to_index(frame_number, end=)``, the motion frame a segment bound falls on
    (its first frame, or one past its last with ``end``); gaps bridged by resampling go to
    ``repairs``, the rows' uneven spacing to ``quirks``."""
    steps = np.diff(frames)
    t_rows = (frames - frames[0]) / FRAME_CLOCK_HZ
    if timing == "resample" and len(frames) >= 2:
        n = int(math.floor(t_rows[-1] * fps + 1e-9)) + 1
        t_new = np.arange(n) / fps
        flat = xyz.reshape(len(frames), -1)
        xyz = np.stack([np.interp(t_new, t_rows, flat[:, c]) for c in range(flat.shape[1])],
                       axis=1).reshape(n, 20, 3)
        for k in np.flatnonzero(steps / FRAME_CLOCK_HZ > LONG_GAP_S):
            repairs.append(
                f"interpolated {steps[k] / FRAME_CLOCK_HZ:.2f} s without a stored skeleton "
                f"(frame numbers {frames[k]:.0f}-{frames[k + 1]:.0f})"
            )
        out_fps = float(fps)

        def to_index(frame_number: float, *, end: bool) -> int:
            t = (frame_number - frames[0]) / FRAME_CLOCK_HZ * out_fps
            i = math.floor(t + 1e-9) + 1 if end else math.ceil(t - 1e-9)
            return int(min(max(i, 0), n))
    elif timing in ("resample", "rows"):
        out_fps = FRAME_CLOCK_HZ / median_step
        quirks.append(
            f"one frame per stored row at {out_fps:g} fps (60 / median frame-number step "
            f"{median_step:g}); true row spacing varies from {steps.min() if steps.size else 0:g} "
            f"to {steps.max() if steps.size else 0:g} units; exact times in frame_numbers"
        )

        def to_index(frame_number: float, *, end: bool) -> int:
            side = "right" if end else "left"
            return int(np.searchsorted(frames, frame_number, side=side))
    else:
        raise ValueError(f"timing must be 'resample' or 'rows', got {timing!r}")
    return xyz, out_fps, to_index


def _segments(path: Path, labels: Path | str | None | Literal[False],
              to_index: Callable[..., int], quirks: list[str]
              ) -> tuple[list[dict[str, object]], Path | None]:
    """The labelled segments of the session (``start``/``end`` motion frames by
    ``to_index``, the file's ``start_frame``/``end_frame``) and the label file read
    (None: none); segments the file cannot give go to ``quirks``.

    Raises:
        FormatError: a given label file that is missing, a segment ending before it starts.
    """
    segments: list[dict[str, object]] = []
    session = _SESSION.search(path.name)
    label_path = None
    if labels is not False:
        label_path = Path(labels) if labels else path.with_name("actionLabel.txt")
        if labels and not label_path.is_file():
            raise FormatError(f"label file {label_path} not found", source=path)
    if label_path is None or not label_path.is_file():
        return segments, None
    if not session:
        return segments, label_path
    table = read_labels(label_path)
    key = session.group(1).lower()
    if key not in table:
        quirks.append(f"session {key} not found in {label_path.name}; no segments")
    for label, start, end in table.get(key, []):
        if math.isnan(start) or math.isnan(end):
            quirks.append(f"segment {label!r} has NaN bounds in {label_path.name}; left out")
            continue
        if end < start:
            raise FormatError(
                f"segment {label!r} ends ({end:g}) before it starts ({start:g})",
                source=label_path, field=label,
            )
        segments.append({
            "label": label, "start": to_index(start, end=False),
            "end": to_index(end, end=True), "start_frame": int(start), "end_frame": int(end),
        })
    return segments, label_path

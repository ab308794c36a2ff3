"""NTU RGB+D / Kinect v2 ``.skeleton`` text files (25 joints).

Format (the dataset's ``read_skeleton_file.m``), whitespace-separated lines:

* line 1: number of frames ``F``;
* per frame: number of bodies ``B``; per body: one line of 10 values
  (``bodyID clipedEdges handLeftConfidence handLeftState handRightConfidence
  handRightState isRestricted leanX leanY trackingState``), one line with the
  joint count (25), then 25 lines of 12 values (``x y z depthX depthY colorX
  colorY orientationW orientationX orientationY orientationZ
  trackingState``), joints in Kinect v2 SDK ``JointType`` order.

``x y z`` are Kinect v2 camera-space metres (x toward the sensor's left, y
up, z forward; right-handed), so the common camera -> world conversion
applies (:mod:`simenv.io.camera_frame`). Joints are reordered to
:func:`simenv.core.skeletons.kinect_v2_skeleton` with
:data:`~simenv.core.skeletons.KINECT_V2_SDK_ORDER`. NTU is captured at 30 fps.

Bodies are tracked by ``bodyID``. ``read`` keeps the body seen in the most
frames and, when a second body is present in at least
:data:`SECOND_BODY_MIN_FRACTION` of the frames, returns both as an
:class:`Interaction` (levelled with one floor estimate: one sensor). Frames
where a kept body is missing are filled by interpolation (``repairs``); a
file with no body at all is a :class:`MotionError`.

:func:`write` produces the same format from camera-frame positions.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Interaction, Motion, interpolate_gaps
from simenv.core.skeletons import KINECT_V2_SDK_ORDER, kinect_v2_skeleton
from simenv.io._kinect_text import head_text, is_number
from simenv.io._text import read_text, split_lines
from simenv.io.camera_frame import estimate_floor

#: Extensions this reader claims when no sniffer accepts a file.
EXTENSIONS = (".skeleton",)
NTU_FPS = 30.0
N_JOINTS = 25
BODY_VALUES = 10
JOINT_VALUES = 12
#: A second body must appear in at least this fraction of frames to be kept.
SECOND_BODY_MIN_FRACTION = 0.5


def sniff(path: Path, head: bytes) -> bool:
    """A ``.skeleton`` file starting with a frame count, a body count and (if
    a body follows) a 10-value body line."""
    if path.suffix.lower() != ".skeleton":
        return False
    lines = head_text(head)[:4]
    if len(lines) < 2 or any(len(ln.split()) != 1 for ln in lines[:2]):
        return False
    if not all(ln.strip().isdigit() for ln in lines[:2]):
        return False
    if int(lines[1]) > 0:
        return len(lines) >= 3 and len(t := lines[2].split()) == BODY_VALUES and all(
            is_number(v) for v in t)
    return True


class _Lines:
    """Cursor over non-blank lines that reports file line numbers."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.items = [(i, ln.split()) for i, ln in enumerate(split_lines(read_text(path)), 1)
                      if ln.strip()]
        self.k = 0

    def take(self, n_values: int, what: str, frame: int | None) -> tuple[int, list[str]]:
        if self.k >= len(self.items):
            last = self.items[-1][0] if self.items else 0
            raise FormatError(f"file ends early; expected {what}", source=self.path,
                              line=last + 1, frame=frame)
        line, tokens = self.items[self.k]
        self.k += 1
        if len(tokens) != n_values:
            raise FormatError(f"expected {n_values} values ({what}), found {len(tokens)}",
                              source=self.path, line=line, frame=frame)
        return line, tokens

    def integer(self, what: str, frame: int | None) -> int:
        line, (tok,) = self.take(1, what, frame)
        try:
            return int(tok)
        except ValueError:
            raise FormatError(f"expected an integer ({what}), found {tok[:40]!r}",
                              source=self.path, line=line, frame=frame) from None

    def floats(self, n_values: int, what: str, frame: int | None) -> np.ndarray:
        line, tokens = self.take(n_values, what, frame)
        try:
            values = np.array(tokens, dtype=np.float64)
        except ValueError:
            bad = next(t for t in tokens if not is_number(t))
            raise FormatError(f"expected numbers ({what}), found {bad[:40]!r}",
                              source=self.path, line=line, frame=frame) from None
        if not np.isfinite(values).all():
            raise FormatError(f"non-finite value ({what})", source=self.path, line=line,
                              frame=frame)
        return values


def parse(path: Path) -> tuple[int, dict[str, dict[int, np.ndarray]]]:
    """(frame count, {bodyID: {frame: (25, 3) camera-frame metres, SDK order}})."""
    path = Path(path)
    cur = _Lines(path)
    if not cur.items:
        raise FormatError("file is empty; expected an NTU .skeleton file", source=path)
    n_frames = cur.integer("frame count", None)
    if n_frames < 0:
        raise FormatError(f"frame count {n_frames} is negative", source=path, line=1)
    bodies: dict[str, dict[int, np.ndarray]] = {}
    for f in range(n_frames):
        n_bodies = cur.integer("body count", f)
        if not 0 <= n_bodies <= 6:
            raise FormatError(f"body count {n_bodies}; Kinect v2 tracks 0-6 bodies",
                              source=path, line=cur.items[cur.k - 1][0], frame=f)
        for _ in range(n_bodies):
            _, body = cur.take(BODY_VALUES, "body line: bodyID + 9 values", f)
            n_joints = cur.integer("joint count", f)
            if n_joints != N_JOINTS:
                raise FormatError(f"joint count {n_joints}; expected {N_JOINTS}",
                                  source=path, line=cur.items[cur.k - 1][0], frame=f)
            xyz = np.stack([cur.floats(JOINT_VALUES, "joint: 11 values + tracking state", f)[:3]
                            for _ in range(N_JOINTS)])
            bodies.setdefault(body[0], {})[f] = xyz
    if cur.k != len(cur.items):
        raise FormatError(f"unexpected data after the {n_frames} declared frames",
                          source=path, line=cur.items[cur.k][0])
    return n_frames, bodies


def read(path: Path, *, fps: float = NTU_FPS) -> Motion | Interaction:
    """Read an NTU ``.skeleton`` file (see module docstring)."""
    path = Path(path)
    n_frames, bodies = parse(path)
    if not bodies:
        raise MotionError("no body in any frame", source=path)
    ranked = sorted(bodies.items(), key=lambda kv: -len(kv[1]))
    keep = ranked[:1]
    if len(ranked) > 1 and len(ranked[1][1]) >= SECOND_BODY_MIN_FRACTION * n_frames:
        keep = ranked[:2]
    skeleton = kinect_v2_skeleton()
    tracks, repairs = [], []
    for body_id, frames in keep:
        cam = np.zeros((n_frames, N_JOINTS, 3))
        valid = np.zeros(n_frames, dtype=bool)
        for f, xyz in frames.items():
            cam[f], valid[f] = xyz[list(KINECT_V2_SDK_ORDER)], True
        if not valid.all():
            cam, notes = interpolate_gaps(cam, valid)
            repairs.append([f"body {body_id} missing: {n}" for n in notes])
        else:
            repairs.append([])
        tracks.append((body_id, cam))
    est = estimate_floor([(c, skeleton) for _, c in tracks], source=str(path))
    dropped = [b for b, _ in ranked[len(keep):]]
    motions = []
    for (body_id, cam), rep in zip(tracks, repairs, strict=True):
        meta = {
            "source": str(path), "format": "ntu", "units": "m (Kinect v2 camera frame)",
            "body_id": body_id, "repairs": rep, "camera_frame": est.as_metadata(),
            "quirks": [f"ignored bodies seen in too few frames: {', '.join(dropped)}"]
            if dropped else [],
        }
        name = path.stem if len(tracks) == 1 else f"{path.stem}_{body_id}"
        motions.append(Motion(est.apply(cam), fps, skeleton, name, meta))
    if len(motions) == 1:
        return motions[0]
    return Interaction(motions[0], motions[1], roles_known=False, name=path.stem,
                       metadata={"source": str(path), "format": "ntu"})


def write(path: Path, bodies: Sequence[np.ndarray]) -> None:
    """Write camera-frame bodies as an NTU ``.skeleton`` file.

    Args:
        path: output file.
        bodies: one (T, 25, 3) array per body, metres, Kinect camera frame,
            joints in :func:`~simenv.core.skeletons.kinect_v2_skeleton` order. A
            frame where a body's positions are NaN is written without that
            body (it was not seen). Fields NTU stores but we do not
            have (2D projections, orientations, hand states) are written as 0;
            tracking states as 2 (tracked).
    """
    arrays = [np.asarray(b, dtype=np.float64) for b in bodies]
    if not arrays or any(a.ndim != 3 or a.shape[1:] != (N_JOINTS, 3) for a in arrays):
        raise MotionError(f"bodies must be (T, {N_JOINTS}, 3) arrays")
    n = arrays[0].shape[0]
    if any(a.shape[0] != n for a in arrays):
        raise MotionError("all bodies must have the same number of frames")
    inverse = np.argsort(KINECT_V2_SDK_ORDER)
    out = [str(n)]
    for f in range(n):
        present = [b for b, a in enumerate(arrays) if np.isfinite(a[f]).all()]
        out.append(str(len(present)))
        for b in present:
            a = arrays[b]
            out.append(f"{72057594037930000 + b} 0 0 0 0 0 0 0 0 2")
            out.append(str(N_JOINTS))
            for x, y, z in a[f, inverse]:
                out.append(f"{x:.7g} {y:.7g} {z:.7g} 0 0 0 0 0 0 0 0 2")
    Path(path).write_text("\n".join(out) + "\n")

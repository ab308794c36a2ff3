"""UTD-MHAD skeletons (``aAA_sSS_tTT_skeleton.mat``, Kinect v1).

Format: a MATLAB 5 MAT-file holding one variable ``d_skel``, a double array
**(20, 3, T)**: 20 joints x (x, y, z) x frames, metres in the Kinect camera frame
(y up, z away from the sensor), the Kinect v1 skeleton at 30 fps (Chen, Jafari and
Kehtarnavaz, "UTD-MHAD: A Multimodal Dataset for Human Action Recognition", ICIP 2015).
The joints are in UTD-MHAD's own order: head, shoulder centre, spine, hip centre, then
the limbs in the Kinect SDK order (left shoulder, elbow, wrist, hand; right shoulder,
elbow, wrist, hand; left hip, knee, ankle, foot; right hip, knee, ankle, foot) -- the
order of public UTD-MHAD readers (``mduhme/fusion-gcn``
``datasets/utd_mhad/constants.py``: ``skeleton_joints``, frames on axis 2). The reader
reorders them to the Kinect SDK v1 order (:func:`simenv.core.skeletons.kinect_v1_skeleton`)
with :data:`UTD_TO_SDK`.

Labels come from the file name: action ``AA`` (1-27, names in :data:`UTD_CLASSES`),
subject ``SS`` (1-8), trial ``TT`` (1-4).

Quirks handled: frames whose 20 joints are all zero (no skeleton tracked) are trimmed at
either end and interpolated between tracked frames, each listed in
``metadata["repairs"]``; a file without a tracked frame is a :class:`MotionError`.
Corrupt MAT files are first parsed in a child process (as the Florence reader does), so a
crash of scipy's parser becomes a :class:`FormatError`.

UTD-MHAD is reserved for evaluation in this project (never for training, calibration,
thresholds or tests): the reader's tests write real recordings of other Kinect v1
datasets into this layout.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Motion, interpolate_gaps
from simenv.core.skeletons import kinect_v1_skeleton
from simenv.io._matfile import MAT_MAGIC, mat_parse_error
from simenv.io.camera_frame import world_motion

#: Frame rate of UTD-MHAD's Kinect v1 skeletons, frames/s.
UTD_FPS = 30.0
JOINTS = 20
#: The variable holding the skeleton.
VARIABLE = "d_skel"

#: For each Kinect SDK v1 joint (hip centre, spine, shoulder centre, head, then the
#: limbs), its row in ``d_skel``: the first four are reversed, the limbs keep their order.
UTD_TO_SDK: tuple[int, ...] = (3, 2, 1, 0, *range(4, JOINTS))

#: The 27 actions, action id 1..27 in order (the dataset's description).
UTD_CLASSES: tuple[str, ...] = (
    "right arm swipe to the left", "right arm swipe to the right", "right hand wave",
    "two hand front clap", "right arm throw", "cross arms in the chest",
    "basketball shoot", "right hand draw x", "right hand draw circle (clockwise)",
    "right hand draw circle (counter clockwise)", "draw triangle",
    "bowling (right hand)", "front boxing", "baseball swing from right",
    "tennis right hand forehand swing", "arm curl (two arms)", "tennis serve",
    "two hand push", "right hand knock on door", "right hand catch an object",
    "right hand pick up and throw", "jogging in place", "walking in place",
    "sit to stand", "stand to sit", "forward lunge (left foot forward)",
    "squat (two arms stretch out)",
)

_NAME = re.compile(r"a(\d+)_s(\d+)_t(\d+)", re.IGNORECASE)


def _loadmat(path: Path) -> dict[str, Any]:
    """The MAT-file's variables, parsed in a child process first (module docstring).

    Raises:
        FormatError: the file cannot be read or parsed.
    """
    from scipy.io import loadmat  # scipy.io (0.3 s) only for MAT-files

    try:
        reason = mat_parse_error(path)
    except OSError as exc:
        raise FormatError(f"cannot read file: {exc.strerror or exc}", source=path) from None
    if reason is None:
        try:
            return loadmat(str(path))
        except Exception as exc:  # scipy raises many types for corrupt files
            reason = f"{type(exc).__name__}: {exc}"
    raise FormatError(f"cannot read MATLAB file ({reason}); expected a MAT-file with "
                      f"'{VARIABLE}' (20 x 3 x T)", source=path)


def sniff(path: Path, head: bytes) -> bool:
    """A MATLAB 5 ``.mat`` holding a ``d_skel`` variable."""
    if path.suffix.lower() != ".mat" or not head.startswith(MAT_MAGIC):
        return False
    from scipy.io import whosmat  # lazy, as in _loadmat

    try:
        if mat_parse_error(path) is not None:
            return False
        return any(name == VARIABLE for name, _, _ in whosmat(str(path)))
    except Exception:
        return False


def labels_from_name(path: Path) -> dict[str, object]:
    """``label``, ``class_id``, ``subject`` and ``trial`` parsed from a UTD-MHAD file
    name (empty when the name does not follow ``aAA_sSS_tTT``)."""
    m = _NAME.search(path.name)
    if not m:
        return {}
    cls, subject, trial = (int(g) for g in m.groups())
    out: dict[str, object] = {"class_id": cls, "subject": subject, "trial": trial}
    if 1 <= cls <= len(UTD_CLASSES):
        out["label"] = UTD_CLASSES[cls - 1]
    return out


def read(path: Path, *, fps: float = UTD_FPS) -> Motion:
    """Read one UTD-MHAD skeleton file.

    Args:
        path: the ``*_skeleton.mat`` file.
        fps: frame rate to assign (default :data:`UTD_FPS`).

    Returns:
        A world-frame :class:`Motion` on the Kinect v1 skeleton, metres, with the
        labels of :func:`labels_from_name` in its metadata.

    Raises:
        FormatError: not a MAT-file, no ``d_skel``, or ``d_skel`` not (20, 3, T).
        MotionError: a non-finite coordinate (naming the frame and joint) or no
            tracked frame.
    """
    path = Path(path)
    data = _loadmat(path)
    if VARIABLE not in data:
        found = sorted(k for k in data if not k.startswith("__"))
        raise FormatError(f"no '{VARIABLE}' variable (found {', '.join(found) or 'none'}); "
                          "expected UTD-MHAD's skeleton (20 x 3 x T)", source=path,
                          field=VARIABLE)
    raw = np.asarray(data[VARIABLE])
    if raw.ndim == 2 and raw.shape == (JOINTS, 3):
        raw = raw[:, :, None]  # MATLAB drops a trailing singleton frame axis
    if raw.ndim != 3 or raw.shape[:2] != (JOINTS, 3) or raw.shape[2] == 0:
        raise FormatError(f"'{VARIABLE}' has shape {raw.shape}; expected (20, 3, T >= 1): "
                          "joints x (x, y, z) x frames", source=path, field=VARIABLE)
    if not np.issubdtype(raw.dtype, np.number):
        raise FormatError(f"'{VARIABLE}' holds {raw.dtype} values; expected numbers",
                          source=path, field=VARIABLE)
    xyz = raw.astype(np.float64).transpose(2, 0, 1)[:, UTD_TO_SDK]  # (T, 20, 3), SDK order
    bad = np.argwhere(~np.isfinite(xyz).all(axis=2))
    if bad.size:
        frame, joint = (int(v) for v in bad[0])
        raise MotionError(f"non-finite coordinate of joint "
                          f"{kinect_v1_skeleton().joint_names[joint]}; expected metres",
                          source=path, frame=frame, field=VARIABLE)
    valid = ~(xyz == 0).all(axis=(1, 2))
    if not valid.any():
        raise MotionError(f"all {len(xyz)} frames are zero (no skeleton tracked)",
                          source=path, field=VARIABLE)
    tracked = np.flatnonzero(valid)
    first, last = int(tracked[0]), int(tracked[-1])
    lead, trail = first, len(valid) - 1 - last
    repairs: list[str] = []
    if lead or trail:
        repairs.append(f"trimmed {lead} leading and {trail} trailing all-zero "
                       "(untracked) frames")
    xyz, valid = xyz[first:last + 1], valid[first:last + 1]
    if not valid.all():
        xyz, notes = interpolate_gaps(xyz, valid)
        repairs += [f"untracked (all-zero) frame: {n} of the trimmed clip" for n in notes]
    meta: dict[str, object] = {
        "source": str(path),
        "format": "utd_mhad",
        "units": "m (camera frame)",
        "dataset": "UTD-MHAD",
        "repairs": repairs,
        "trimmed": [lead, trail],
        "fps_source": "Kinect v1 skeleton stream, 30 fps (no timestamps in the file)",
    }
    meta |= labels_from_name(path)
    return world_motion(xyz, kinect_v1_skeleton(), fps=fps, name=path.name.split(".")[0],
                        metadata=meta, source=str(path))

"""Florence 3D Actions (``skeletal_data.mat``, Vemulapalli's packaging).

``skeletal_data`` is a 215x1 MATLAB cell, one struct per video in ``idvideo``
order, with ``original_skeletal_data`` (3 x 15 x T, metres, rows **(X, Z, Y)**:
world X, depth, Y-up — the dataset README's world coordinates / 1000 with
rows 2 and 3 swapped), ``subject`` (1-10) and ``action`` (1-9). Class names
come from ``action_names.mat`` next to it (else ``"action <k>"``). The other
field, ``joint_locations``, is a template-normalised skeleton and is ignored.

Joints are the README order (OpenNI 15: Head, Neck, Spine, shoulders, elbows,
wrists, hips, knees, ankles), :func:`simenv.core.skeletons.florence_skeleton`.
Frame rate: 20 fps (the dataset's AVI headers: 50 000 us/frame, frame counts
equal to the skeleton's; see ``gestures/SOURCES.md``).

Levelling: clips are short (8-35 frames) and some are seated, so one clip
alone gives a noisy floor (per-clip pitch estimates of one subject spread over
~40 deg). The sensor did not move within a subject's session, so by default
(``level="subject"``) one floor is estimated from all videos of a subject
together (:func:`simenv.io.camera_frame.estimate_floor`); ``level="video"``
levels each video on its own.

Corrupt MAT files can crash scipy's parser (a segmentation fault, found by
fuzzing), so every MAT file is first parsed in a child process
(:func:`simenv.io._matfile.mat_parse_error`, cached per file state); a failure there is a
:class:`FormatError`.

``read`` returns one :class:`Motion` per video (215), each with ``label``,
``class_id``, ``subject``, ``video_id`` and ``repetition`` (order of
appearance of that subject/class pair) in its metadata.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import numpy as np

from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Motion
from simenv.core.skeletons import florence_skeleton
from simenv.io._matfile import MAT_MAGIC, mat_parse_error
from simenv.io.camera_frame import FloorEstimate, estimate_floor

#: Extensions this reader claims when no sniffer accepts a file.
EXTENSIONS = (".mat",)
FLORENCE_FPS = 20.0


def _check_mat(path: Path) -> None:
    reason = mat_parse_error(path)
    if reason is not None:
        raise FormatError(f"cannot read MATLAB file ({reason}); expected a MAT-file with "
                          "'skeletal_data'", source=path)


def _loadmat(path: Path, **kwargs: Any) -> dict[str, Any]:
    # scipy.io (0.3 s) only for MAT-files: format detection imports every reader module.
    from scipy.io import loadmat

    try:
        _check_mat(path)
    except OSError as exc:
        raise FormatError(f"cannot read file: {exc}", source=path) from None
    try:
        return loadmat(str(path), squeeze_me=True, struct_as_record=False, **kwargs)
    except Exception as exc:  # scipy raises many types for corrupt files
        raise FormatError(
            f"cannot read MATLAB file ({type(exc).__name__}: {exc}); expected a MAT-file with "
            "'skeletal_data'",
            source=path,
        ) from None


def sniff(path: Path, head: bytes) -> bool:
    """A MATLAB 5 ``.mat`` holding a ``skeletal_data`` variable."""
    if path.suffix.lower() != ".mat" or not head.startswith(MAT_MAGIC):
        return False
    from scipy.io import whosmat  # lazy, as in _loadmat

    try:
        _check_mat(path)
        return any(name == "skeletal_data" for name, _, _ in whosmat(str(path)))
    except Exception:
        return False


def _class_names(path: Path) -> list[str] | None:
    names_file = path.with_name("action_names.mat")
    if not names_file.is_file():
        return None
    names = _loadmat(names_file).get("action_names")
    if names is None:
        return None
    return [str(n) for n in np.atleast_1d(names)]


def read(
    path: Path, *, fps: float = FLORENCE_FPS, level: Literal["subject", "video"] = "subject"
) -> list[Motion]:
    """Read every video of a Florence ``skeletal_data.mat``.

    Args:
        path: ``skeletal_data.mat``.
        fps: frame rate to assign (default 20).
        level: estimate the floor per ``"subject"`` (pooled) or per ``"video"``.

    Returns:
        One world-frame :class:`Motion` per video, in video-id order.
    """
    path = Path(path)
    data = _loadmat(path)
    if "skeletal_data" not in data:
        raise FormatError(
            "no 'skeletal_data' variable; expected Vemulapalli's Florence packaging",
            source=path, field="skeletal_data",
        )
    videos = np.atleast_1d(data["skeletal_data"])
    classes = _class_names(path)
    skeleton = florence_skeleton()
    seen: dict[tuple[int, int], int] = {}
    clips: list[tuple[np.ndarray, dict[str, Any]]] = []
    for i, video in enumerate(videos):
        where = f"skeletal_data[{i}]"
        try:
            raw = np.asarray(video.original_skeletal_data, dtype=np.float64)
            subject, action = int(video.subject), int(video.action)
        except (AttributeError, TypeError, ValueError):
            raise FormatError(
                "expected a struct with original_skeletal_data (3x15xT), subject and action",
                source=path, field=where,
            ) from None
        if raw.ndim == 2:
            raw = raw[:, :, None]
        if raw.ndim != 3 or raw.shape[:2] != (3, 15) or raw.shape[2] == 0:
            raise FormatError(
                f"original_skeletal_data has shape {raw.shape}; expected (3, 15, T>=1)",
                source=path, field=where,
            )
        if not np.isfinite(raw).all():
            raise MotionError("non-finite joint coordinates", source=path, field=where)
        xyz = raw[[0, 2, 1]].transpose(2, 1, 0)  # rows (X, Z, Y) -> (T, 15, XYZ)
        key = (subject, action)
        seen[key] = seen.get(key, 0) + 1
        label = (classes[action - 1] if classes and 1 <= action <= len(classes)
                 else f"action {action}")
        meta: dict[str, Any] = {
            "source": f"{path}#{where}",
            "format": "florence3d",
            "units": "m (camera frame)",
            "dataset": "Florence 3D Actions",
            "video_id": i + 1,
            "subject": subject,
            "class_id": action,
            "label": label,
            "repetition": seen[key],
            "repairs": [],
        }
        clips.append((xyz, meta))
    if not clips:
        raise MotionError("skeletal_data holds no video", source=path)
    if level not in ("subject", "video"):
        raise ValueError(f"level must be 'subject' or 'video', got {level!r}")
    floors: dict[object, FloorEstimate] = {}
    groups: dict[object, list[np.ndarray]] = {}
    for i, (xyz, meta) in enumerate(clips):
        groups.setdefault(meta["subject"] if level == "subject" else i, []).append(xyz)
    for key, group in groups.items():
        floors[key] = estimate_floor([(g, skeleton) for g in group], source=str(path))
    motions: list[Motion] = []
    for i, (xyz, meta) in enumerate(clips):
        est = floors[meta["subject"] if level == "subject" else i]
        meta["camera_frame"] = dict(est.as_metadata(), level=level)
        motions.append(Motion(est.apply(xyz), fps, skeleton, f"florence_{i + 1:03d}", meta))
    return motions

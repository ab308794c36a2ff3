"""PKU-MMD Kinect v2 skeleton sequences (``<name>-<view>.txt``) and their action labels.

Format (the dataset's README, ``github.com/ECHO960/PKU-MMD``; checked on a released file,
``A10N08-L.txt``, see ``docs/recognition.md``):

* Skeleton file: one line per frame, whitespace-separated, **150 numbers**: two bodies x 25
  joints x ``x y z``, joints in the Kinect v2 SDK ``JointType`` order, metres in the Kinect
  camera frame (x toward the sensor's left, y up, z away from it). A body that is not there
  is all zeros (the second body of a one-person sequence; either body on a frame without
  it). 30 frames/s. Names: ``NNNN-V`` (phase 1, e.g. ``0002-L``) or ``A##N##-V`` (phase 2,
  e.g. ``A10N08-L``), ``V`` the view: ``L``eft, ``M``iddle or ``R``ight Kinect.
* Label file of the same name in a sibling folder (phase 1: ``Train_Label_PKU_final/``):
  one action instance per line, ``action_id,start_frame,end_frame,confidence`` (integers;
  confidence 1 = slight, 2 = strong recommendation). Frames are 0-based indices of the
  skeleton file's lines, end inclusive.

``read`` keeps body 1, and body 2 when it is tracked on at least
:data:`SECOND_BODY_MIN_FRACTION` of the frames (then both come back as an
:class:`Interaction`, levelled with one floor estimate: one sensor; a body whose hips are
not above its ankles, :data:`MIN_UPRIGHT_FRACTION`, is left out of that estimate). Frames
where a kept body is all zeros are filled by interpolation (listed in ``repairs``); the
returned clip keeps one frame per file line, so label frames index it directly. Units are
checked from the body's size (metres expected; a file in millimetres is detected and
converted, noted in ``units_reason``). The action instances go to ``metadata["actions"]``
(``action_id``, ``label``, ``start_frame``, ``end_frame``, ``confidence``, ``start_s``,
``end_s``); :func:`action_clips` cuts them out.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Interaction, Motion, interpolate_gaps
from simenv.core.skeletons import KINECT_V2_SDK_JOINTS, KINECT_V2_SDK_ORDER, kinect_v2_skeleton
from simenv.io._kinect_text import check_counts, sniff_rows, table_lines, to_floats
from simenv.io._kinematics import detect_units
from simenv.io._text import read_text, split_lines
from simenv.io.camera_frame import estimate_floor
from simenv.io.joint_csv import body_size

#: Frame rate of the Kinect v2 skeleton stream, frames/s.
PKU_MMD_FPS = 30.0
JOINTS = 25
BODIES = 2
VALUES_PER_ROW = BODIES * JOINTS * 3
#: Body 2 is kept (an :class:`Interaction`) when tracked on at least this fraction of frames.
SECOND_BODY_MIN_FRACTION = 0.5
#: The 51 actions of phase 1, id 1..51 in order (``Actions.xlsx``; the list three public
#: loaders share, alphabetical, whose interaction ids 12, 14, 16, 18, 21, 24, 26, 27 a fourth
#: one lists separately).
PKU_MMD_ACTIONS: tuple[str, ...] = (
    "bow", "brushing hair", "brushing teeth", "check time (from watch)", "cheer up",
    "clapping", "cross hands in front (say stop)", "drink water", "drop", "eat meal/snack",
    "falling", "giving something to other person", "hand waving", "handshaking",
    "hopping (one foot jumping)", "hugging other person", "jump up", "kicking other person",
    "kicking something", "make a phone call/answer phone", "pat on back of other person",
    "pickup", "playing with phone/tablet", "point finger at the other person",
    "pointing to something with finger", "punching/slapping other person",
    "pushing other person", "put on a hat/cap", "put something inside pocket", "reading",
    "rub two hands together", "salute", "sitting down", "standing up", "take off a hat/cap",
    "take off glasses", "take off jacket", "take out something from pocket",
    "taking a selfie", "tear up paper", "throw", "touch back (backache)",
    "touch chest (stomachache/heart pain)", "touch head (headache)", "touch neck (neckache)",
    "typing on a keyboard", "use a fan (with hand or paper)/feeling warm", "wear jacket",
    "wear on glasses", "wipe face", "writing",
)
#: A body gives the floor estimate when its hips are above its ankles on at least this
#: fraction of its tracked frames (standing or seated); body 1 does when none does. A
#: released file's second body, hips below its folded ankles on 85 % of frames, tilted the
#: joint estimate to 43.5 deg against 1.3 deg from body 1 alone.
MIN_UPRIGHT_FRACTION = 0.5
#: Label confidences the README defines (1 slight, 2 strong recommendation).
CONFIDENCES = (1, 2)

_SDK = {name: i for i, name in enumerate(KINECT_V2_SDK_JOINTS)}
_NAME = re.compile(r"^(?:(\d{4})|(A\d+N\d+))-([LMR])$", re.IGNORECASE)
_VIEWS = {"L": "left", "M": "middle", "R": "right"}


def sniff(path: Path, head: bytes) -> bool:
    """A ``.txt`` whose first lines each hold 150 numbers."""
    return sniff_rows(path, head, suffix=".txt", lines=3, sep=None, counts=(VALUES_PER_ROW,))


def labels_from_name(path: Path) -> dict[str, object]:
    """``sequence``, ``phase`` (1 for ``NNNN``, 2 for ``A##N##``) and ``view`` parsed from a
    PKU-MMD file name; empty when the name is not of that form."""
    m = _NAME.match(Path(path).stem)
    if not m:
        return {}
    one, two, view = m.groups()
    return {"sequence": one or two.upper(), "phase": 1 if one else 2,
            "view": _VIEWS[view.upper()]}


def label_path(path: Path) -> Path | None:
    """The label file of a skeleton file: the file of the same name in a sibling folder
    whose name contains ``label`` (``Train_Label_PKU_final/`` beside ``PKU_Skeleton_Renew/``),
    first in name order; None when there is none."""
    path = Path(path)
    parent = path.parent.parent
    if not parent.is_dir():
        return None
    for folder in sorted(p for p in parent.iterdir()
                         if p.is_dir() and "label" in p.name.lower() and p != path.parent):
        if (folder / path.name).is_file():
            return folder / path.name
    return None


def read_labels(path: Path, *, frames: int | None = None, phase: int | None = 1
                ) -> list[dict[str, Any]]:
    """The action instances of a label file, in file order.

    Args:
        path: the label file.
        frames: number of frames of the skeleton file; when given, every instance must end
            before it.
        phase: 1 names the actions (:data:`PKU_MMD_ACTIONS`); otherwise ``label`` is None
            (phase 2's id list is not checked here).

    Returns:
        ``{"action_id", "label", "start_frame", "end_frame", "confidence", "start_s",
        "end_s"}`` per line; times in seconds at :data:`PKU_MMD_FPS`.

    Raises:
        FormatError: a line that is not four integers, an action id outside 1-51, a
            confidence not 1 or 2, a start after the end or an end past the last frame
            (naming the file, line and field).
    """
    path = Path(path)
    out: list[dict[str, Any]] = []
    fields = ("action_id", "start_frame", "end_frame", "confidence")
    for i, line in enumerate(split_lines(read_text(path)), start=1):
        if not line.strip():
            continue
        tokens = [t.strip() for t in line.strip().split(",")]
        if len(tokens) != len(fields):
            raise FormatError(f"expected 4 comma-separated integers "
                              f"(action_id,start_frame,end_frame,confidence), found "
                              f"{len(tokens)} values", source=path, line=i)
        values = []
        for name, tok in zip(fields, tokens, strict=True):
            try:
                values.append(int(tok))
            except ValueError:
                raise FormatError(f"expected an integer, found {tok[:40]!r}", source=path,
                                  line=i, field=name) from None
        action, start, end, conf = values
        if not 1 <= action <= len(PKU_MMD_ACTIONS):
            raise FormatError(f"action id {action} is not one of 1-{len(PKU_MMD_ACTIONS)}",
                              source=path, line=i, field="action_id")
        if conf not in CONFIDENCES:
            raise FormatError(f"confidence {conf}; expected 1 (slight) or 2 (strong)",
                              source=path, line=i, field="confidence")
        if not 0 <= start <= end:
            raise FormatError(f"start frame {start} is negative or after the end frame {end}",
                              source=path, line=i, field="start_frame")
        if frames is not None and end >= frames:
            raise FormatError(f"end frame {end} is past the skeleton file's last frame "
                              f"{frames - 1}", source=path, line=i, field="end_frame")
        out.append({"action_id": action,
                    "label": PKU_MMD_ACTIONS[action - 1] if phase == 1 else None,
                    "start_frame": start, "end_frame": end, "confidence": conf,
                    "start_s": round(start / PKU_MMD_FPS, 4),
                    "end_s": round(end / PKU_MMD_FPS, 4)})
    return out


def _upright_fraction(body: np.ndarray) -> float:
    """Fraction of frames of a (T, 25, 3) camera-frame body (SDK order) whose SpineBase is
    above (camera y) the mean of its two ankles."""
    ankles = body[:, [_SDK["AnkleLeft"], _SDK["AnkleRight"]], 1].mean(axis=1)
    return float(np.mean(body[:, _SDK["SpineBase"], 1] > ankles))


def _bodies(path: Path) -> np.ndarray:
    """(T, 2, 25, 3) file values, SDK joint order.

    Raises:
        FormatError: a line without 150 numbers, a non-numeric or non-finite value
            (naming line, frame and field ``body<b>.<joint>.<axis>``).
    """
    rows = table_lines(path, None)
    check_counts(path, rows, (VALUES_PER_ROW,), "2 bodies x 25 joints x y z")
    names = [f"body{b}.{j}.{c}" for b in (1, 2) for j in KINECT_V2_SDK_JOINTS for c in "xyz"]
    return to_floats(path, rows, names).reshape(-1, BODIES, JOINTS, 3)


def read(path: Path, *, fps: float = PKU_MMD_FPS, labels: Path | str | None = None,
         units: str | None = None, scale: float | None = None) -> Motion | Interaction:
    """Read one PKU-MMD skeleton sequence and its action labels.

    Args:
        path: the skeleton ``.txt`` file.
        fps: its frame rate (the sensor's 30 frames/s).
        labels: the label file; default :func:`label_path` (a sequence without one has no
            ``actions``).
        units: force a length unit (``"m"``, ``"mm"``, ...); ``scale``: metres per file
            unit. Default: detected from the body's size.

    Returns:
        A world-frame :class:`Motion` on :func:`~simenv.core.skeletons.kinect_v2_skeleton`
        (metres, Z up, one frame per file line), or an :class:`Interaction` of both bodies
        (module docstring); ``metadata`` ``source``, ``format``, ``dataset``, ``body``,
        ``units``, ``units_reason``, ``tracked_fraction``, ``repairs``, ``quirks``,
        ``camera_frame``, the name's ``sequence``, ``phase`` and ``view``, and ``actions``.

    Raises:
        FormatError: bad skeleton or label lines (naming file, line and field), a given
            label file that does not exist.
        MotionError: no tracked body 1, or fewer than 2 frames.
        UnitsError: a body of no plausible size in any unit.
    """
    path = Path(path)
    if not fps > 0:
        raise FormatError(f"fps must be positive, got {fps!r}", source=path, field="fps")
    data = _bodies(path)
    n = len(data)
    if n < 2:
        raise MotionError("one frame; a PKU-MMD sequence needs at least 2", source=path)
    tracked = ~(data == 0).all(axis=(2, 3))  # (T, 2)
    if not tracked[:, 0].any():
        raise MotionError(f"body 1 is all zeros on all {n} frames (no skeleton tracked)",
                          source=path)
    keep = [0] + ([1] if tracked[:, 1].mean() >= SECOND_BODY_MIN_FRACTION else [])
    unit, s, units_reason, quirks = detect_units(body_size(data[tracked[:, 0], 0]),
                                                 source=path, units=units, scale=scale)
    if tracked[:, 1].any() and 1 not in keep:
        quirks = [*quirks, f"ignored body 2: tracked on {int(tracked[:, 1].sum())} of {n} "
                  f"frames (< {SECOND_BODY_MIN_FRACTION:.0%})"]
    skeleton = kinect_v2_skeleton()
    order = list(KINECT_V2_SDK_ORDER)
    cams, repairs = [], []
    for b in keep:
        cam, notes = interpolate_gaps(data[:, b][:, order] * s, tracked[:, b])
        cams.append(cam)
        repairs.append([f"body {b + 1} not tracked (all zeros): {note}" for note in notes])
    upright = [_upright_fraction(data[tracked[:, b], b]) for b in keep]
    floor_bodies = [b for b, u in zip(keep, upright, strict=True)
                    if u >= MIN_UPRIGHT_FRACTION] or [0]
    for b, u in zip(keep, upright, strict=True):
        if b not in floor_bodies:
            quirks = [*quirks, f"body {b + 1}: hips above the ankles on only {u:.0%} of its "
                      "tracked frames (folded on the floor, or not a person); not used for the "
                      "floor estimate"]
    est = estimate_floor([(cams[keep.index(b)], skeleton) for b in floor_bodies],
                         source=str(path))
    meta: dict[str, Any] = {
        "source": str(path), "format": "pku_mmd", "dataset": "PKU-MMD",
        "units": unit, "units_reason": units_reason, "scale_m_per_unit": s,
        "camera_frame": est.as_metadata() | {"from_bodies": [b + 1 for b in floor_bodies]},
        "quirks": quirks,
    } | labels_from_name(path)
    label_file = Path(labels) if labels is not None else label_path(path)
    if labels is not None and not label_file.is_file():  # type: ignore[union-attr]
        raise FormatError(f"label file {label_file} not found", source=path)
    if label_file is not None:
        meta["labels_file"] = str(label_file)
        meta["actions"] = read_labels(label_file, frames=n, phase=meta.get("phase", 1))
    motions = []
    for b, cam, rep in zip(keep, cams, repairs, strict=True):
        person = meta | {"body": b + 1, "repairs": rep,
                         "tracked_fraction": round(float(tracked[:, b].mean()), 4)}
        name = path.stem if len(keep) == 1 else f"{path.stem}_body{b + 1}"
        motions.append(Motion(est.apply(cam), fps, skeleton, name, person))
    if len(motions) == 1:
        return motions[0]
    pair_meta = {k: v for k, v in meta.items() if k != "camera_frame"}
    return Interaction(motions[0], motions[1], roles_known=False, name=path.stem,
                       metadata=pair_meta)


def action_clips(loaded: Motion | Interaction) -> list[tuple[dict[str, Any],
                                                             Motion | Interaction]]:
    """The labelled action instances of a read sequence, each cut out of it.

    Args:
        loaded: what :func:`read` returned (its ``metadata["actions"]``; an
            :class:`Interaction`'s own metadata holds them).

    Returns:
        ``(action, clip)`` per instance: the ``metadata["actions"]`` entry and frames
        ``start_frame`` .. ``end_frame`` (inclusive) of ``loaded``; empty without labels.
    """
    return [(a, loaded.slice(a["start_frame"], a["end_frame"] + 1))
            for a in loaded.metadata.get("actions", [])]

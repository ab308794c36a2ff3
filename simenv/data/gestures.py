"""The gesture vocabulary shared with the room, and the gesture dataset builder.

Vocabulary
----------
One label set for every gesture source (MSR Action3D, UTKinect-Action3D, Florence 3D;
see ``shared/data/gestures/SOURCES.md``). Every dataset class maps to exactly one label
(:data:`SOURCE_CLASSES`); nothing is dropped. Classes the room has no reason to tell apart
(sports moves, drawing in the air, pushing a cart) are pooled as ``other``.

============= ================================================================== =========
label         dataset classes                                                     room
============= ================================================================== =========
wave          MSR high arm wave, horizontal arm wave, two hand wave;             greet
              UTKinect waveHands; Florence wave
answer_phone  Florence answer phone                                               hifi_down
bow           Florence bow                                                        bow_back
clap          MSR hand clap; UTKinect clapHands; Florence clap                    keep
drink         Florence drink                                                      keep
read_watch    Florence read watch                                                 keep
sit_down      UTKinect sitDown; Florence sit down                                 keep
stand_up      UTKinect standUp; Florence stand up                                 keep
bend_down     MSR bend; UTKinect pickUp; Florence tight lace (the trunk folds     keep
              toward the floor, hands near the feet)
walk          UTKinect walk, carry                                                keep
other         MSR hammer, hand catch, forward punch, high throw, draw x, draw     keep
              tick, draw circle, side-boxing, forward kick, side kick, jogging,
              tennis swing, tennis serve, golf swing, pick up & throw;
              UTKinect throw, push, pull
idle          no dataset class: near-still real frames (see *Idle* below)        keep
============= ================================================================== =========

The room column is :data:`ROOM_REACTIONS`: ``greet`` = stop idling, face the
user and wave back; ``hifi_down`` = turn the hi-fi down; ``bow_back`` = nod/bow back;
``keep`` = keep working (no reaction; ``idle`` is one of them).

Idle
----
``idle`` is "no gesture": standing or sitting still, small fidgets. No dataset labels it,
so it is cut from real frames that carry no label and where the person is near-still
(:func:`still_mask`): the speed of the head, elbows and wrists relative to the spine,
averaged over :data:`IDLE_SMOOTH_S` (0.4 s), stays below :data:`IDLE_LIMB_SPEED_MPS`
(0.35 m/s; a UTKinect or MSR wave moves the wrist at ~1 m/s, Kinect jitter of a still
person reads ~0.1-0.2 m/s), and the horizontal spine speed below
:data:`IDLE_ROOT_SPEED_MPS` (0.2 m/s; walking is ~0.65 m/s). Sources
(:func:`idle_ranges`):

* **UTKinect sessions** outside every labelled segment (a session's missing segment,
  ``s10_e02 carry``, excludes the whole gap where it was done): runs of still frames of
  at least :data:`IDLE_SESSION_MIN_S` (1 s), cut into equal pieces of at most 3 s;
* **MSR Action3D and Florence clips**: the still lead-in (frames before the action
  starts) and lead-out of each clip, when at least :data:`IDLE_EDGE_MIN_S` (0.5 s) long.
  (The clip itself stays a sample of its class, lead-in included.) Florence clips are
  0.4-1.8 s long and almost never start or end still.

They come from every subject, and :func:`split_cross_subject` puts them on the side of
their subject, so the classifier trains on idle stretches of training subjects only.
``load_gesture_clips(idle=True)`` adds them (default: the labelled clips only).

Dataset builder
---------------
1. **Load** every recording: MSR files (one clip each; the all-zero ``a13_s09_e02`` is
   skipped and listed), UTKinect sessions cut into their labelled segments
   (``metadata["segments"]``; the NaN ``s10_e02 carry`` is absent), Florence videos.
   The readers give world-frame (Z-up, metres, floor at 0) motions.
2. **Joints.** From the canonical keypoints of each skeleton to a joint set measured by
   all three datasets: ``gesture15`` (default; the thesis's 9 upper-body joints of
   :func:`simenv.core.skeletons.gesture9_skeleton` plus hips, knees and ankles, which sitting,
   standing, bending and walking need) or ``gesture9``. Both are rooted at ``spine``
   (Kinect v1 ``Spine``, OpenNI ``Torso``), with the hips as children of the spine.
3. **Resample** to 25 fps (linear, :meth:`simenv.core.motion.Motion.resample`).
4. **Windows** of 3 s = 75 frames. *Cropping*: a longer clip gives its centre 75 frames
   (``crop="centre"``, evaluation), its first 75 (``"start"``) or a seeded random 75
   (``"random"``, training). *Padding*: a shorter clip is padded at the end by holding
   its last pose, and the padded frames are marked invalid in ``valid`` (the classifier
   masks them out of temporal attention and pooling, so padding carries no signal).
   ``real_frames=k`` keeps only the first ``k`` frames as real (the thesis's "1 s of
   real motion": ``k = 25``); the rest is padded by the same rule.
5. **Normalise** each window from its own first :data:`NORM_FRAMES` valid frames (so a
   window made of 1 s real + 2 s predicted is normalised by its real part only):
   translate so the mean ``spine`` there is the origin; turn about Z so the person faces
   +X (forward = Z x (right shoulder - left shoulder), left = +Y); scale so the mean of
   shoulder width, upper-arm and forearm lengths is :data:`REFERENCE_SIZE_M`. Positions
   stay roughly metres of a reference adult. Vertical (Z) motion of the root is kept
   (sitting down lowers the spine).
6. **Subjects.** A subject is ``"<dataset>/s<id>"`` (subject 1 of MSR is not subject 1
   of UTKinect). :func:`split_cross_subject`: odd subject ids train, even ids test, in
   every dataset (MSR's usual protocol; MSR s10 is held out of the corpus, so its test
   side has s02, s04, s06, s08). No subject is in both.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from simenv.core.errors import MotionError, SimenvError, SkeletonError
from simenv.core.motion import Motion
from simenv.core.skeletons import GESTURE9_JOINTS, Skeleton, gesture9_skeleton
from simenv.io import florence3d, msr_action3d, utkinect

#: Gesture label -> what it means.
VOCABULARY: dict[str, str] = {
    "wave": "waving hello with one or both arms",
    "answer_phone": "bringing a phone to the ear",
    "bow": "bowing the trunk forward as a greeting",
    "clap": "clapping the hands",
    "drink": "bringing a cup or bottle to the mouth",
    "read_watch": "looking at a wrist watch",
    "sit_down": "sitting down on a chair",
    "stand_up": "standing up from a chair",
    "bend_down": "folding the trunk toward the floor (pick up, tie a lace)",
    "walk": "walking (possibly carrying something)",
    "other": "any other action (sports moves, drawing in the air, pushing, throwing)",
    "idle": "no gesture: standing or sitting still, small fidgets",
}

#: Class order of the classifier (index = class id).
GESTURE_LABELS: tuple[str, ...] = tuple(VOCABULARY)

#: What the room's agent does for each label; labels not listed: ``keep``.
ROOM_REACTIONS: dict[str, str] = {"wave": "greet", "answer_phone": "hifi_down",
                                  "bow": "bow_back"}

#: Dataset keys, as in the ``dataset`` column of ``gestures/index.csv``.
DATASETS: tuple[str, ...] = ("msr_action3d", "utkinect", "florence3d")

#: (dataset, class name as the dataset spells it) -> gesture label.
SOURCE_CLASSES: dict[tuple[str, str], str] = {
    ("msr_action3d", "high arm wave"): "wave",
    ("msr_action3d", "horizontal arm wave"): "wave",
    ("msr_action3d", "two hand wave"): "wave",
    ("msr_action3d", "hand clap"): "clap",
    ("msr_action3d", "bend"): "bend_down",
    **{("msr_action3d", c): "other" for c in (
        "hammer", "hand catch", "forward punch", "high throw", "draw x", "draw tick",
        "draw circle", "side-boxing", "forward kick", "side kick", "jogging", "tennis swing",
        "tennis serve", "golf swing", "pick up & throw")},
    ("utkinect", "waveHands"): "wave",
    ("utkinect", "clapHands"): "clap",
    ("utkinect", "sitDown"): "sit_down",
    ("utkinect", "standUp"): "stand_up",
    ("utkinect", "pickUp"): "bend_down",
    ("utkinect", "walk"): "walk",
    ("utkinect", "carry"): "walk",
    ("utkinect", "throw"): "other",
    ("utkinect", "push"): "other",
    ("utkinect", "pull"): "other",
    ("florence3d", "wave"): "wave",
    ("florence3d", "answer phone"): "answer_phone",
    ("florence3d", "bow"): "bow",
    ("florence3d", "clap"): "clap",
    ("florence3d", "drink"): "drink",
    ("florence3d", "read watch"): "read_watch",
    ("florence3d", "sit down"): "sit_down",
    ("florence3d", "stand up"): "stand_up",
    ("florence3d", "tight lace"): "bend_down",
}

#: Frame rate of every gesture window, frames/s.
GESTURE_FPS = 25.0
#: Window length: 3 s at 25 fps.
WINDOW_FRAMES = 75
#: Frames of real motion in the thesis's short condition: 1 s at 25 fps.
SHORT_FRAMES = 25
#: Leading valid frames a window's normalisation is computed from (0.4 s).
NORM_FRAMES = 10
#: Mean of shoulder width, upper-arm and forearm lengths after normalisation, metres
#: (typical adult: 0.34, 0.28 and 0.25 m; Kinect joint centres give ~0.27-0.30).
REFERENCE_SIZE_M = 0.28

#: Joints of ``gesture15``: gesture9 plus the legs. Parents: spine is the root; the hips
#: hang from the spine (Florence has no pelvis joint).
GESTURE15_JOINTS: tuple[str, ...] = GESTURE9_JOINTS + (
    "left_hip", "left_knee", "left_ankle", "right_hip", "right_knee", "right_ankle",
)
_GESTURE15_PARENTS = (-1, 0, 1, 1, 3, 4, 1, 6, 7, 0, 9, 10, 0, 12, 13)

JointSet = Literal["gesture15", "gesture9"]
Crop = Literal["centre", "start", "random"]

#: The "no gesture" label (no dataset class maps to it; see the module docstring, *Idle*).
IDLE_LABEL = "idle"
#: Speed of the head, elbows and wrists relative to the spine below which a frame is
#: still, m/s (after :data:`IDLE_SMOOTH_S` of moving average).
IDLE_LIMB_SPEED_MPS = 0.35
#: Horizontal speed of the spine below which a frame is still, m/s (same average).
IDLE_ROOT_SPEED_MPS = 0.2
#: Moving-average span of the still test, s.
IDLE_SMOOTH_S = 0.4
#: Shortest idle stretch cut from an unlabelled part of a UTKinect session, s.
IDLE_SESSION_MIN_S = 1.0
#: Shortest still lead-in / lead-out of a clip taken as idle, s.
IDLE_EDGE_MIN_S = 0.5
#: Longest idle clip, s (longer stretches are cut into equal pieces).
IDLE_MAX_S = 3.0
_IDLE_LIMBS = ("head", "left_elbow", "left_wrist", "right_elbow", "right_wrist")
#: UTKinect's actions in the order each session does them (for a missing segment).
_UTK_ORDER = ("walk", "sitDown", "standUp", "pickUp", "carry", "throw", "push", "pull",
              "waveHands", "clapHands")

#: Left/right joint pairs by name, for mirroring.
_MIRROR = {"left_shoulder": "right_shoulder", "left_elbow": "right_elbow",
           "left_wrist": "right_wrist", "left_hip": "right_hip", "left_knee": "right_knee",
           "left_ankle": "right_ankle"}


def gesture_label(dataset: str, class_name: str) -> str:
    """Gesture label of a dataset class (see the module table).

    Raises:
        SimenvError: the (dataset, class) pair is not in :data:`SOURCE_CLASSES`.
    """
    key = (dataset, class_name.strip())
    if key not in SOURCE_CLASSES:
        known = sorted(c for d, c in SOURCE_CLASSES if d == dataset)
        raise SimenvError(
            f"class {class_name!r} of dataset {dataset!r} is not in the gesture vocabulary; "
            f"known classes of {dataset!r}: {', '.join(known) or 'none (unknown dataset)'}",
            field="class_name",
        )
    return SOURCE_CLASSES[key]


def room_reaction(label: str) -> str:
    """Reaction of the room's agent to a gesture label (``keep`` = keep working)."""
    if label not in VOCABULARY:
        raise SimenvError(
            f"unknown gesture label {label!r}; expected one of {', '.join(GESTURE_LABELS)}",
            field="label",
        )
    return ROOM_REACTIONS.get(label, "keep")


def gesture_skeleton(joints: JointSet = "gesture15") -> Skeleton:
    """The classifier's joint layout: ``gesture15`` (default) or ``gesture9``."""
    if joints == "gesture9":
        return gesture9_skeleton()
    if joints == "gesture15":
        return Skeleton("gesture15", GESTURE15_JOINTS, _GESTURE15_PARENTS,
                        {k: k for k in GESTURE15_JOINTS})
    raise SkeletonError(f"unknown gesture joint set {joints!r}; expected gesture15 or gesture9",
                        field="joints")


def to_gesture_joints(motion: Motion, joints: JointSet = "gesture15") -> np.ndarray:
    """(T, J, 3) float32 positions of ``motion`` on the gesture joint set, metres.

    Joints are found through the motion skeleton's canonical keypoint map.

    Raises:
        SkeletonError: the skeleton lacks one of the keypoints (all missing ones named).
    """
    on = motion.on_layout(gesture_skeleton(joints), f"the {joints} gesture joint set")
    return np.ascontiguousarray(on.positions, dtype=np.float32)


# -- normalisation --------------------------------------------------------------------


def _first_valid(valid: np.ndarray, n: int) -> np.ndarray:
    """(N, T) bool: the first ``n`` valid frames of each row."""
    return valid & (np.cumsum(valid, axis=1) <= n)


def normalise_windows(
    windows: np.ndarray, valid: np.ndarray | None = None, *,
    joints: Sequence[str] = GESTURE15_JOINTS,
) -> np.ndarray:
    """Root-relative, facing- and scale-normalised copies of gesture windows.

    See the module docstring (step 5) for the transform: ``x' = k R_z(-theta) (x - o)``,
    with origin ``o``, heading ``theta`` and scale ``k = REFERENCE_SIZE_M / size``
    measured on the first :data:`NORM_FRAMES` valid frames of each window.

    Args:
        windows: (N, T, J, 3) or (T, J, 3) positions, metres, Z up.
        valid: (N, T) or (T,) bool, True for real frames; default all real.
        joints: joint names of axis J (must include spine, shoulders, elbows, wrists).

    Returns:
        float32 array of the shape of ``windows``.

    Raises:
        MotionError: wrong shape, no valid frame, non-finite values, or a degenerate
            pose (shoulders on top of each other) in a window.
    """
    x, v, single = _checked_windows(windows, valid, len(joints))
    names = list(joints)
    spine = names.index("spine")
    ls, rs = names.index("left_shoulder"), names.index("right_shoulder")
    le, re_ = names.index("left_elbow"), names.index("right_elbow")
    lw, rw = names.index("left_wrist"), names.index("right_wrist")

    ref = _first_valid(v, NORM_FRAMES)[..., None]  # (N, T, 1)
    cnt = ref.sum(axis=1)  # (N, 1)

    def ref_mean(a: np.ndarray) -> np.ndarray:
        return (a * ref[..., None] if a.ndim == 4 else a * ref).sum(axis=1) / cnt

    origin = ref_mean(x[:, :, spine])  # (N, 3)
    across = ref_mean(x[:, :, rs] - x[:, :, ls])  # left -> right shoulder
    norm_h = np.hypot(across[:, 0], across[:, 1])
    flat = np.flatnonzero(norm_h < 1e-4)
    if flat.size:
        raise MotionError(
            f"window {int(flat[0])}: shoulders have no horizontal separation; cannot tell "
            "which way the person faces",
            field="windows",
        )
    # forward = Z x across = (-across_y, across_x); rotate it onto +X.
    theta = np.arctan2(across[:, 0], -across[:, 1])
    c, s = np.cos(-theta), np.sin(-theta)
    rot = np.zeros((len(x), 3, 3))
    rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1] = c, -s, s, c
    rot[:, 2, 2] = 1.0

    def length(a: int, b: int) -> np.ndarray:
        return np.linalg.norm(x[:, :, a] - x[:, :, b], axis=-1)

    size = ref_mean(np.mean([length(ls, rs), length(ls, le), length(rs, re_),
                             length(le, lw), length(re_, rw)], axis=0)[..., None])[:, 0]
    tiny = np.flatnonzero(size < 1e-3)
    if tiny.size:
        raise MotionError(f"window {int(tiny[0])}: arm bones of zero length", field="windows")
    k = (REFERENCE_SIZE_M / size)[:, None, None, None]
    out = np.einsum("nij,ntkj->ntki", rot, x - origin[:, None, None, :]) * k
    out = out.astype(np.float32)
    return out[0] if single else out


def _checked_windows(windows: np.ndarray, valid: np.ndarray | None, joints: int
                     ) -> tuple[np.ndarray, np.ndarray, bool]:
    """(N, T, J, 3) float64 windows, (N, T) bool validity (default all real) and whether a
    single (T, J, 3) window was given.

    Raises:
        MotionError: wrong shapes, a window without a valid frame, or a non-finite
            position on a valid frame.
    """
    x = np.asarray(windows, dtype=np.float64)
    single = x.ndim == 3
    if single:
        x = x[None]
    if x.ndim != 4 or x.shape[-1] != 3 or x.shape[2] != joints:
        raise MotionError(
            f"windows must have shape (N, T, {joints}, 3); got {np.shape(windows)}",
            field="windows",
        )
    v = np.ones(x.shape[:2], bool) if valid is None else np.asarray(valid, bool)
    if single and valid is not None:
        v = v[None]
    if v.shape != x.shape[:2]:
        raise MotionError(f"valid must have shape {x.shape[:2]}; got {v.shape}", field="valid")
    empty = np.flatnonzero(~v.any(axis=1))
    if empty.size:
        raise MotionError(f"window {int(empty[0])} has no valid frame", field="valid")
    bad = np.argwhere(~np.isfinite(x).all(axis=(2, 3)) & v)
    if bad.size:
        raise MotionError(f"window {int(bad[0, 0])} has a non-finite position",
                          frame=int(bad[0, 1]), field="windows")
    return x, v, single


def mirror_windows(windows: np.ndarray, joints: Sequence[str] = GESTURE15_JOINTS
                   ) -> np.ndarray:
    """Left-right mirror image of normalised windows (Y negated, left/right joints
    swapped): a left-handed wave from a right-handed one. Shape kept, (..., J, 3)."""
    names = list(joints)
    perm = list(range(len(names)))
    for a, b in _MIRROR.items():
        if a in names and b in names:
            perm[names.index(a)], perm[names.index(b)] = names.index(b), names.index(a)
    out = np.array(windows, dtype=np.float32)[..., perm, :]
    out[..., 1] *= -1
    return out


# -- clips ----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class GestureClip:
    """One labelled gesture recording on the gesture joints.

    Attributes:
        positions: (T, J, 3) float32, metres, world frame Z up, :data:`GESTURE_FPS`.
        label: gesture label (:data:`GESTURE_LABELS`).
        source_label: the dataset's own class name.
        dataset: dataset key (:data:`DATASETS`).
        subject: the dataset's subject id.
        name: clip name (file stem, session + segment, or Florence video).
        source: the recording's frames of this clip as the reader gave them (own
            skeleton and frame rate), e.g. to retarget it into the room; None when the
            clip was built from positions alone.
    """

    positions: np.ndarray
    label: str
    source_label: str
    dataset: str
    subject: int
    name: str
    source: Motion | None = field(default=None, repr=False)

    @property
    def subject_key(self) -> str:
        """Subject id unique across datasets, e.g. ``"utkinect/s03"``."""
        return f"{self.dataset}/s{self.subject:02d}"

    @property
    def num_frames(self) -> int:
        return int(self.positions.shape[0])


@dataclass
class LoadReport:
    """What :func:`load_gesture_clips` skipped, and why (one line per recording)."""

    skipped: list[str] = field(default_factory=list)


def _clip(motion: Motion, dataset: str, source_label: str, subject: int, name: str,
          joints: JointSet, label: str | None = None) -> GestureClip:
    sub = motion.with_positions(to_gesture_joints(motion, joints),
                                skeleton=gesture_skeleton(joints))
    if sub.num_frames >= 2:
        sub = sub.resample(GESTURE_FPS)
    return GestureClip(sub.positions, label or gesture_label(dataset, source_label),
                       source_label, dataset, int(subject), name, motion)


# -- idle -----------------------------------------------------------------------------


def _moving_average(a: np.ndarray, n: int) -> np.ndarray:
    """(T, ...) centred moving average over ``n`` frames (shorter at the ends)."""
    c = np.cumsum(np.concatenate([np.zeros((1, *a.shape[1:])), a]), axis=0)
    t = np.arange(len(a))
    lo, hi = np.maximum(t - n // 2, 0), np.minimum(t - n // 2 + n, len(a))
    return (c[hi] - c[lo]) / (hi - lo).reshape(-1, *([1] * (a.ndim - 1)))


def still_mask(positions: np.ndarray, fps: float,
               joints: Sequence[str] = GESTURE15_JOINTS) -> np.ndarray:
    """(T,) bool: frames where the person is near-still (module docstring, *Idle*).

    Args:
        positions: (T, J, 3) positions, metres, Z up, on ``joints`` (spine, head, elbows
            and wrists needed).
        fps: frame rate of ``positions``, frames/s.

    Raises:
        MotionError: fewer than 2 frames, or a non-finite position.
    """
    x = np.asarray(positions, dtype=np.float64)
    if x.ndim != 3 or x.shape[1:] != (len(joints), 3) or len(x) < 2:
        raise MotionError(f"positions must be (T >= 2, {len(joints)}, 3); got {x.shape}",
                          field="positions")
    if not np.isfinite(x).all():
        raise MotionError("positions hold a non-finite value", field="positions")
    names = list(joints)
    spine = names.index("spine")
    limbs = x[:, [names.index(j) for j in _IDLE_LIMBS]] - x[:, spine:spine + 1]
    n = max(int(round(IDLE_SMOOTH_S * fps)), 1)
    limb = _moving_average(np.linalg.norm(np.gradient(limbs, axis=0), axis=-1) * fps, n)
    root = _moving_average(np.linalg.norm(np.gradient(x[:, spine, :2], axis=0), axis=-1)
                           * fps, n)
    return (limb.max(axis=1) < IDLE_LIMB_SPEED_MPS) & (root < IDLE_ROOT_SPEED_MPS)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True in a (T,) bool array."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def _pieces(start: int, stop: int, longest: int) -> list[tuple[int, int]]:
    """[start, stop) cut into the fewest equal pieces of at most ``longest`` frames."""
    n = -(-(stop - start) // longest)
    cuts = np.linspace(start, stop, n + 1).round().astype(int)
    return list(zip(cuts[:-1].tolist(), cuts[1:].tolist(), strict=True))


def idle_ranges(motion: Motion, *, labelled: np.ndarray | None = None) -> list[tuple[int, int]]:
    """Idle stretches of a recording as frame ranges ``[start, stop)`` of ``motion``.

    With ``labelled`` (a continuous session): every run of still frames outside the
    labelled ones of at least :data:`IDLE_SESSION_MIN_S`. Without (a clip of one action):
    its still lead-in and lead-out, each when at least :data:`IDLE_EDGE_MIN_S`. Runs
    longer than :data:`IDLE_MAX_S` are cut into equal pieces.

    Args:
        motion: the reader's motion (any skeleton with the gesture keypoints, any fps).
        labelled: (T,) bool, True on frames inside a labelled action.
    """
    if motion.num_frames < 2:
        return []
    still = still_mask(to_gesture_joints(motion), motion.fps)
    longest = max(int(IDLE_MAX_S * motion.fps), 1)
    if labelled is not None:
        shortest = IDLE_SESSION_MIN_S * motion.fps
        runs = [r for r in _runs(still & ~np.asarray(labelled, bool))
                if r[1] - r[0] >= shortest]
    else:
        shortest = IDLE_EDGE_MIN_S * motion.fps
        runs = [r for r in _runs(still) if (r[0] == 0 or r[1] == len(still))
                and r[1] - r[0] >= shortest]
    return [p for r in runs for p in _pieces(*r, longest)]


def _session_labelled(session: Motion) -> np.ndarray:
    """(T,) bool: frames inside a labelled segment of a UTKinect session, or inside the
    gap where a segment missing from the label file (NaN bounds) was done."""
    segs = sorted(session.metadata["segments"], key=lambda g: int(g["start"]))
    labelled = np.zeros(session.num_frames, bool)
    for g in segs:
        labelled[int(g["start"]):int(g["end"])] = True
    present = [str(g["label"]).strip() for g in segs]
    for k, action in enumerate(_UTK_ORDER):
        if action in present:
            continue
        before = [g for g in segs if str(g["label"]).strip() in _UTK_ORDER[:k]]
        after = [g for g in segs if str(g["label"]).strip() in _UTK_ORDER[k + 1:]]
        lo = int(before[-1]["end"]) if before else 0
        hi = int(after[0]["start"]) if after else session.num_frames
        labelled[lo:hi] = True
    return labelled


def load_gesture_clips(
    root: str | Path,
    *,
    datasets: Iterable[str] = DATASETS,
    joints: JointSet = "gesture15",
    report: LoadReport | None = None,
    idle: bool = False,
) -> list[GestureClip]:
    """Load the labelled gesture recordings under ``root`` (the ``gestures`` folder).

    Args:
        root: folder holding ``msr_action3d/``, ``utkinect/joints/`` and ``florence3d/``.
        datasets: which of :data:`DATASETS` to load.
        joints: gesture joint set.
        report: if given, filled with the recordings that were skipped and why.
        idle: also cut the ``idle`` clips (:func:`idle_ranges`, every subject), each
            right after the recording it comes from; their names end in ``_idle<k>``.

    Returns:
        Clips in a deterministic order (dataset, then file order).

    Raises:
        SimenvError: unknown dataset key, or no usable recording at all.
    """
    root = Path(root)
    report = report if report is not None else LoadReport()
    clips: list[GestureClip] = []
    for ds in datasets:
        if ds not in DATASETS:
            raise SimenvError(f"unknown gesture dataset {ds!r}; expected one of "
                              f"{', '.join(DATASETS)}", field="datasets")
        if ds == "msr_action3d":
            files = sorted((root / "msr_action3d").glob(MSR_PATTERN))
        elif ds == "utkinect":
            files = sorted((root / "utkinect" / "joints").glob(UTK_PATTERN))
        else:
            files = [f for f in [root / "florence3d" / FLORENCE_FILE] if f.is_file()]
        clips += _dataset_clips(ds, files, joints, report, idle)
    if not clips:
        raise SimenvError(
            f"no gesture recording found under {root} (expected msr_action3d/, "
            "utkinect/joints/ or florence3d/skeletal_data.mat)",
            source=root,
        )
    return clips


#: File-name patterns of the three datasets' recordings.
MSR_PATTERN = "a*_s*_e*_skeleton3D.txt"
UTK_PATTERN = "joints_s*_e*.txt"
FLORENCE_FILE = "skeletal_data.mat"


def _dataset_clips(dataset: str, files: Sequence[Path], joints: JointSet, report: LoadReport,
                   idle: bool) -> list[GestureClip]:
    """The labelled clips (and idle clips) of one dataset's recording files."""
    clips: list[GestureClip] = []
    for path in files:
        if dataset == "msr_action3d":
            try:
                m = msr_action3d.read(path)
            except SimenvError as exc:
                report.skipped.append(f"{path.name}: {exc.detail}")
                continue
            clips.append(_clip(m, dataset, str(m.metadata["label"]),
                               int(m.metadata["subject"]), m.name, joints))
            if idle:
                clips += _idle_clips(m, dataset, int(m.metadata["subject"]), joints)
        elif dataset == "utkinect":
            session = utkinect.read(path)
            report.skipped += [f"{path.name}: {q}" for q in session.metadata["quirks"]]
            for seg in session.metadata["segments"]:
                start, end = int(seg["start"]), int(seg["end"])
                if end - start < 2:
                    report.skipped.append(f"{path.name} {seg['label']}: {end - start} frame")
                    continue
                clips.append(_clip(session.slice(start, end), dataset, str(seg["label"]),
                                   int(session.metadata["subject"]),
                                   f"{session.name}_{seg['label']}", joints))
            if idle:
                clips += _idle_clips(session, dataset, int(session.metadata["subject"]),
                                     joints, _session_labelled(session))
        else:
            for m in florence3d.read(path):
                clips.append(_clip(m, dataset, str(m.metadata["label"]),
                                   int(m.metadata["subject"]), m.name, joints))
                if idle:
                    clips += _idle_clips(m, dataset, int(m.metadata["subject"]), joints)
    return clips


def load_labelled(paths: Sequence[str | Path], *, joints: JointSet = "gesture15",
                  report: LoadReport | None = None, idle: bool = False) -> list[GestureClip]:
    """Labelled gesture clips from any mix of paths, labels from each dataset's naming.

    A path may be a corpus root (``msr_action3d/``, ``utkinect/joints/``,
    ``florence3d/`` below it), one dataset's folder, or single recordings: MSR Action3D
    ``aAA_sSS_eEE_skeleton3D.txt`` (class, subject, repetition in the name), UTKinect
    ``joints_sSS_eEE.txt`` (segments from the ``actionLabel.txt`` next to it), Florence
    ``skeletal_data.mat``. A recording found twice is loaded once.

    Raises:
        SimenvError: a path that does not exist or holds none of these recordings (the
            message names it and what was expected).
    """
    report = report if report is not None else LoadReport()
    found: dict[str, list[Path]] = {d: [] for d in DATASETS}
    for raw in paths:
        path = Path(raw)
        if not path.exists():
            raise SimenvError("no such file or folder", source=path, field="data")
        before = sum(map(len, found.values()))
        if path.is_dir():
            for ds, sub, pattern in (("msr_action3d", "msr_action3d", MSR_PATTERN),
                                     ("utkinect", "utkinect/joints", UTK_PATTERN),
                                     ("florence3d", "florence3d", FLORENCE_FILE)):
                found[ds] += sorted((path / sub).glob(pattern)) + sorted(path.glob(pattern))
                if ds == "utkinect":
                    found[ds] += sorted((path / "joints").glob(pattern))
        elif path.match(MSR_PATTERN):
            found["msr_action3d"].append(path)
        elif path.match(UTK_PATTERN):
            found["utkinect"].append(path)
        elif path.name == FLORENCE_FILE:
            found["florence3d"].append(path)
        if sum(map(len, found.values())) == before:
            raise SimenvError(
                "no labelled gesture recording here: expected a corpus root, a dataset "
                f"folder, or files named {MSR_PATTERN} (MSR Action3D), {UTK_PATTERN} "
                f"(UTKinect, with actionLabel.txt beside it) or {FLORENCE_FILE} (Florence 3D)",
                source=path, field="data")
    clips: list[GestureClip] = []
    for ds, files in found.items():
        unique = list(dict.fromkeys(f.resolve() for f in files))
        clips += _dataset_clips(ds, unique, joints, report, idle)
    if not clips:
        raise SimenvError(f"the recordings under {', '.join(map(str, paths))} gave no usable "
                          f"clip ({'; '.join(report.skipped) or 'none'})", field="data")
    return clips


def _idle_clips(motion: Motion, dataset: str, subject: int, joints: JointSet,
                labelled: np.ndarray | None = None) -> list[GestureClip]:
    """The ``idle`` clips of one recording (:func:`idle_ranges`)."""
    kind = "unlabelled still" if labelled is not None else "still lead-in/out"
    return [_clip(motion.slice(a, b), dataset, kind, subject, f"{motion.name}_idle{k}",
                  joints, label=IDLE_LABEL)
            for k, (a, b) in enumerate(idle_ranges(motion, labelled=labelled))]


def split_cross_subject(clips: Sequence[GestureClip]
                        ) -> tuple[list[GestureClip], list[GestureClip]]:
    """Cross-subject split: odd subject ids train, even ids test, in every dataset."""
    train = [c for c in clips if c.subject % 2 == 1]
    test = [c for c in clips if c.subject % 2 == 0]
    return train, test


#: Folds of the leave-subjects-out protocol over the whole gesture corpus.
SUBJECT_FOLDS = 5


def subject_fold(subject_key: str, folds: int = SUBJECT_FOLDS) -> int:
    """Fold of a subject in the leave-subjects-out protocol: subject ``sNN`` of any dataset
    is in fold ``(NN - 1) % folds``, so every fold holds subjects of every dataset and each
    subject is tested exactly once (MSR s01..s09, UTKinect and Florence s01..s10: five or
    six subjects a fold)."""
    try:
        number = int(subject_key.rsplit("/s", 1)[1])
    except (IndexError, ValueError):
        raise SimenvError(f"subject key {subject_key!r} is not '<dataset>/s<id>'",
                          field="subject") from None
    return (number - 1) % folds


def split_subject_folds(clips: Sequence[GestureClip], folds: int = SUBJECT_FOLDS
                        ) -> list[tuple[list[GestureClip], list[GestureClip]]]:
    """Leave-subjects-out over every subject (:func:`subject_fold`): per fold, (train
    clips, test clips); no subject is on both sides of a fold, and every clip is a test
    clip of exactly one fold.

    Raises:
        SimenvError: ``folds < 2``, or a fold without test clips.
    """
    if folds < 2:
        raise SimenvError(f"need at least 2 folds; got {folds}", field="folds")
    fold_of = [subject_fold(c.subject_key, folds) for c in clips]
    out = []
    for k in range(folds):
        test = [c for c, f in zip(clips, fold_of, strict=True) if f == k]
        if not test:
            raise SimenvError(f"fold {k} of {folds} has no test clip (too few subjects)",
                              field="folds")
        out.append(([c for c, f in zip(clips, fold_of, strict=True) if f != k], test))
    return out


# -- windows --------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class GestureWindows:
    """Fixed-length, normalised gesture windows ready for the classifier.

    Attributes:
        x: (N, T, J, 3) float32 normalised positions (see :func:`normalise_windows`).
        valid: (N, T) bool, False on padded frames.
        y: (N,) int64 class index into :data:`GESTURE_LABELS`.
        subjects: (N,) subject keys (``"<dataset>/s<id>"``).
        datasets: (N,) dataset keys.
        names: (N,) clip names.
        joints: joint names of axis J.
    """

    x: np.ndarray
    valid: np.ndarray
    y: np.ndarray
    subjects: tuple[str, ...]
    datasets: tuple[str, ...]
    names: tuple[str, ...]
    joints: tuple[str, ...]

    def __len__(self) -> int:
        return int(self.x.shape[0])

    def take(self, idx: np.ndarray) -> GestureWindows:
        """Windows at indices ``idx``."""
        idx = np.asarray(idx)
        return GestureWindows(self.x[idx], self.valid[idx], self.y[idx],
                              tuple(self.subjects[i] for i in idx),
                              tuple(self.datasets[i] for i in idx),
                              tuple(self.names[i] for i in idx), self.joints)


def cut_window(positions: np.ndarray, *, length: int = WINDOW_FRAMES, offset: int = 0,
               real_frames: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Frames ``[offset, offset + length)`` of a clip, padded by holding the last real pose.

    Args:
        positions: (T, J, 3) clip.
        length: window length, frames.
        offset: first frame taken.
        real_frames: keep at most this many frames real (the rest padded).

    Returns:
        ((length, J, 3) float32 window, (length,) bool valid mask).
    """
    seg = positions[offset:offset + length]
    if real_frames is not None:
        seg = seg[:real_frames]
    if len(seg) == 0:
        raise MotionError(f"window at frame {offset} of a {len(positions)}-frame clip is empty",
                          frame=offset)
    n = len(seg)
    window = np.concatenate([seg, np.repeat(seg[-1:], length - n, axis=0)])
    valid = np.arange(length) < n
    return window.astype(np.float32), valid


def make_windows(
    clips: Sequence[GestureClip],
    *,
    crop: Crop = "centre",
    length: int = WINDOW_FRAMES,
    real_frames: int | None = None,
    rng: np.random.Generator | None = None,
    joints: Sequence[str] = GESTURE15_JOINTS,
) -> GestureWindows:
    """One normalised window per clip (rules in the module docstring, step 4).

    Args:
        clips: gesture clips (all on the joint set ``joints``).
        crop: ``"centre"``, ``"start"`` or ``"random"`` (needs ``rng``).
        length: window length, frames.
        real_frames: if given, only the first ``real_frames`` frames of each window are real.
        rng: random generator for ``crop="random"``.
        joints: joint names of the clips.
    """
    if not clips:
        raise SimenvError("no clips to cut windows from")
    if crop == "random" and rng is None:
        raise SimenvError("crop='random' needs a seeded rng", field="rng")
    xs, vs = [], []
    for clip in clips:
        if clip.positions.shape[1] != len(joints):
            raise SkeletonError(
                f"clip {clip.name!r} has {clip.positions.shape[1]} joints; expected "
                f"{len(joints)} ({', '.join(joints)})", field="joints")
        spare = max(clip.num_frames - length, 0)
        if crop == "centre":
            offset = spare // 2
        elif crop == "start":
            offset = 0
        elif crop == "random":
            offset = int(rng.integers(0, spare + 1))
        else:
            raise SimenvError(f"unknown crop {crop!r}; expected centre, start or random",
                              field="crop")
        w, v = cut_window(clip.positions, length=length, offset=offset, real_frames=real_frames)
        xs.append(w)
        vs.append(v)
    return pack_windows(clips, xs, vs, joints)


def pack_windows(clips: Sequence[GestureClip], windows: Sequence[np.ndarray],
                 valid: Sequence[np.ndarray], joints: Sequence[str] = GESTURE15_JOINTS
                 ) -> GestureWindows:
    """One :class:`GestureWindows` of cut windows, one per clip, normalised
    (:func:`normalise_windows`) and labelled from their clips.

    Args:
        clips: the clips the windows were cut from, in order.
        windows: per clip a (75, J, 3) window (:func:`cut_window`), metres.
        valid: per clip its (75,) bool mask of real frames.
        joints: joint names of the windows.
    """
    mask = np.stack(valid)
    x = normalise_windows(np.stack(windows), mask, joints=joints)
    y = np.array([GESTURE_LABELS.index(c.label) for c in clips], dtype=np.int64)
    return GestureWindows(x, mask, y, tuple(c.subject_key for c in clips),
                          tuple(c.dataset for c in clips), tuple(c.name for c in clips),
                          tuple(joints))

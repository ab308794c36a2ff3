"""History -> future windows of real motion for motion prediction (PredictiveMA-WGAN data).

Pipeline, per clip: resample explicitly to the target rate (25 fps by default) -> map onto
the fixed 17-joint layout :data:`PRED17_LAYOUT` from the clip's canonical keypoints ->
split into the root (pelvis) trajectory and root-relative joint positions -> cut sliding
windows. Splits into train/test are by clip (:func:`split_by_clip`).

The 17-joint layout
-------------------
Same tree and joint indices as the Human3.6M 17-joint skeleton (parents
``-1 0 1 2 0 4 5 0 7 8 9 8 11 12 8 14 15``), filled from canonical keypoints
(:mod:`simenv.core.skeletons`):

===  ===============  =========================  ==========================================
idx  joint            H36M joint at that index   note
===  ===============  =========================  ==========================================
0    pelvis           Hip                        root; removed from the other joints
1-3  right_hip/knee/ankle  RHip, RKnee, RFoot    H36M "Foot" is the ankle
4-6  left_hip/knee/ankle   LHip, LKnee, LFoot
7    spine            Spine                      lower/mid back
8    chest            Thorax                     upper back (CMU ``Spine1``/``thorax``)
9    neck             Neck/Nose                  base of the neck
10   head             Head                       base of the skull (CMU ``Head``); H36M's
                                                 is the head top
11-13 left_shoulder/elbow/wrist  LShoulder..LWrist
14-16 right_shoulder/elbow/wrist RShoulder..RWrist
===  ===============  =========================  ==========================================

Indices 8-10 sit one keypoint lower on the trunk than H36M's (which has no chest joint
and ends at the head top, a point no canonical skeleton measures); everything else is
the same joint. :func:`simenv.core.skeletons.h36m_skeleton` is the *file* layout of H36M data;
this layout needs all 17 keypoints above, which every CMU skeleton has (Kinect and
H36M skeletons lack ``chest`` and are rejected with a message naming it, unless
``to_pred17(motion, derive=True)`` stands in for the chest and, on OpenNI skeletons, the
pelvis by midpoints: :data:`DERIVED_KEYPOINTS`).

Windows
-------
A window of a ``P -> F`` configuration is ``1 + P + F`` consecutive frames at the target
rate: one *lead-in* frame, the ``P`` observed (past) frames, the ``F`` future frames.
The lead-in frame exists so that past and future are curves with the same number of
steps: ``past_curve = [lead_in, past]`` (P steps, ending at the last observed pose) and
``future_curve = [past[-1], future]`` (F steps, starting from it, so a predicted future
integrated from the last observed pose has no seam). With P = F their SRVFs
(:mod:`simenv.core.srvf`) are points of the same sphere.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from simenv.core.errors import MotionError, SkeletonError
from simenv.core.motion import Motion
from simenv.core.skeletons import Skeleton

#: Default frame rate of prediction windows (the MA-GAN paper's 25 fps).
TARGET_FPS = 25.0

#: (joint, parent) of the 17-joint prediction layout; joints are canonical keypoints.
PRED17_LAYOUT: tuple[tuple[str, str | None], ...] = (
    ("pelvis", None),
    ("right_hip", "pelvis"),
    ("right_knee", "right_hip"),
    ("right_ankle", "right_knee"),
    ("left_hip", "pelvis"),
    ("left_knee", "left_hip"),
    ("left_ankle", "left_knee"),
    ("spine", "pelvis"),
    ("chest", "spine"),
    ("neck", "chest"),
    ("head", "neck"),
    ("left_shoulder", "chest"),
    ("left_elbow", "left_shoulder"),
    ("left_wrist", "left_elbow"),
    ("right_shoulder", "chest"),
    ("right_elbow", "right_shoulder"),
    ("right_wrist", "right_elbow"),
)

PRED17_JOINTS: tuple[str, ...] = tuple(name for name, _ in PRED17_LAYOUT)


def pred17_skeleton() -> Skeleton:
    """The 17-joint prediction skeleton (canonical keypoint names, identity canonical map)."""
    parents = tuple(-1 if p is None else PRED17_JOINTS.index(p) for _, p in PRED17_LAYOUT)
    return Skeleton("pred17", PRED17_JOINTS, parents, {k: k for k in PRED17_JOINTS})


#: Keypoints :func:`to_pred17` can derive (``derive=True``) when a skeleton lacks them:
#: keypoint -> the two keypoints whose midpoint stands in for it.
DERIVED_KEYPOINTS: dict[str, tuple[str, str]] = {
    "chest": ("spine", "neck"),
    "pelvis": ("left_hip", "right_hip"),
}


def to_pred17(motion: Motion, *, derive: bool = False) -> Motion:
    """``motion`` on the 17-joint prediction layout (same frames, fps and metadata).

    Args:
        derive: stand in for a keypoint the skeleton lacks by the midpoint of two it has
            (:data:`DERIVED_KEYPOINTS`): the chest between spine and neck (Kinect v1/v2,
            OpenNI and Nuitrack skeletons have no chest joint), the pelvis between the
            hips (OpenNI skeletons have none). The same rule as the gesture15 -> pred17
            mapping of :func:`simenv.learning.train_classifier.extrapolate_with_predictor`.

    Raises:
        SkeletonError: the skeleton lacks one of the 17 canonical keypoints (and, with
            ``derive``, one of the two it would be derived from).
    """
    purpose = "the 17-joint prediction layout"
    canonical = motion.skeleton.canonical
    missing = [k for k in PRED17_JOINTS if k not in canonical]
    if not derive or not missing:
        return motion.on_layout(pred17_skeleton(), purpose)
    unknown = [k for k in missing if k not in DERIVED_KEYPOINTS
               or any(p not in canonical for p in DERIVED_KEYPOINTS[k])]
    if unknown:
        raise motion.missing_keypoints(unknown, PRED17_JOINTS, purpose,
                                       f" (not derivable from {', '.join(canonical)})")
    columns = []
    for k in PRED17_JOINTS:
        if k in canonical:
            columns.append(motion.joint(canonical[k]))
        else:
            a, b = DERIVED_KEYPOINTS[k]
            columns.append(0.5 * (motion.joint(canonical[a]) + motion.joint(canonical[b])))
    metadata = dict(motion.metadata) | {"derived_keypoints": {
        k: list(DERIVED_KEYPOINTS[k]) for k in missing}}
    return Motion(np.stack(columns, axis=1).astype(np.float32), motion.fps,
                  pred17_skeleton(), motion.name, metadata)


def split_root(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Root-relative positions and root trajectory of a pred17 motion.

    Returns:
        ``(relative, root)``: (T, 17, 3) float32 positions minus the pelvis (the pelvis
        row is 0) and the (T, 3) float32 world pelvis trajectory, metres. Translation
        only: the heading (rotation about Z) stays in the relative positions.
    """
    if motion.skeleton.joint_names != PRED17_JOINTS:
        raise SkeletonError(
            f"split_root expects the pred17 layout (use to_pred17); motion {motion.name!r} "
            f"has skeleton {motion.skeleton.name!r}",
            source=motion.metadata.get("source"),
        )
    root = motion.positions[:, 0]
    return motion.positions - root[:, None], root.copy()


@dataclass(frozen=True, eq=False)
class PredictionWindows:
    """Sliding ``P -> F`` windows over clips (see the module docstring for the layout).

    Attributes:
        frames: (N, 1 + P + F, 17, 3) float32 root-relative positions, metres
            (lead-in, past, future).
        root: (N, 1 + P + F, 3) float32 world pelvis positions, metres, Z-up.
        clip: (N,) int64 index into ``clip_names`` of each window's clip.
        start: (N,) int64 index of the lead-in frame in the clip resampled to ``fps``.
        clip_names: names of the clips; windows with the same name form one clip
            (e.g. one trial read from BVH and from AMC), which :func:`split_by_clip` keeps
            on one side.
        past_len: P; future_len: F; fps: frame rate of the windows.
        skipped: names of clips that were too short to give a window.
    """

    frames: np.ndarray
    root: np.ndarray
    clip: np.ndarray
    start: np.ndarray
    clip_names: tuple[str, ...]
    past_len: int
    future_len: int
    fps: float
    skipped: tuple[str, ...] = ()

    @property
    def num_windows(self) -> int:
        return int(self.frames.shape[0])

    def __len__(self) -> int:
        return self.num_windows

    @property
    def skeleton(self) -> Skeleton:
        return pred17_skeleton()

    @property
    def lead_in(self) -> np.ndarray:
        """(N, 17, 3) root-relative frame just before the past."""
        return self.frames[:, 0]

    @property
    def past(self) -> np.ndarray:
        """(N, P, 17, 3) root-relative observed frames."""
        return self.frames[:, 1 : 1 + self.past_len]

    @property
    def future(self) -> np.ndarray:
        """(N, F, 17, 3) root-relative frames to predict."""
        return self.frames[:, 1 + self.past_len :]

    @property
    def past_root(self) -> np.ndarray:
        """(N, P, 3) pelvis positions of the observed frames."""
        return self.root[:, 1 : 1 + self.past_len]

    @property
    def future_root(self) -> np.ndarray:
        """(N, F, 3) pelvis positions of the frames to predict."""
        return self.root[:, 1 + self.past_len :]

    @property
    def window_clip_names(self) -> np.ndarray:
        """(N,) clip name of each window."""
        return np.asarray(self.clip_names, dtype=object)[self.clip]

    def past_curve(self) -> np.ndarray:
        """(N, P + 1, 51) float64 flattened ``[lead_in, past]``: P steps to the last
        observed pose."""
        curve = self.frames[:, : 1 + self.past_len]
        return curve.reshape(len(self), self.past_len + 1, -1).astype(np.float64)

    def future_curve(self) -> np.ndarray:
        """(N, F + 1, 51) float64 flattened ``[past[-1], future]``: F steps from the last
        observed pose."""
        curve = self.frames[:, self.past_len :]
        return curve.reshape(len(self), self.future_len + 1, -1).astype(np.float64)

    def subset(self, index: np.ndarray | Sequence[int]) -> PredictionWindows:
        """Windows selected by an integer or boolean index (clip names are kept)."""
        index = np.asarray(index)
        return PredictionWindows(
            self.frames[index], self.root[index], self.clip[index], self.start[index],
            self.clip_names, self.past_len, self.future_len, self.fps, self.skipped,
        )


def _check_config(past_len: int, future_len: int, stride: int, fps: float) -> None:
    for name, value in (("past_len", past_len), ("future_len", future_len), ("stride", stride)):
        if int(value) != value or value < 1:
            raise MotionError(f"{name} must be a positive integer; got {value!r}", field=name)
    if not np.isfinite(fps) or fps <= 0:
        raise MotionError(f"fps must be a positive number; got {fps!r}", field="fps")


def _clip_windows(
    motion: Motion, past_len: int, future_len: int, stride: int, fps: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """(frames, root, start, frames at fps) of one clip; no window if it is too short."""
    if motion.fps != fps:
        motion.require_frames(2, f"resampling to {fps:g} fps for prediction windows")
        motion = motion.resample(fps)
    relative, root = split_root(to_pred17(motion))
    length = 1 + past_len + future_len
    starts = np.arange(0, motion.num_frames - length + 1, stride, dtype=np.int64)
    offsets = starts[:, None] + np.arange(length)
    return relative[offsets], root[offsets], starts, motion.num_frames


def windows_from_motions(
    motions: Iterable[Motion],
    past_len: int,
    future_len: int,
    *,
    stride: int = 1,
    fps: float = TARGET_FPS,
) -> PredictionWindows:
    """Sliding prediction windows over clips.

    Each clip is resampled to ``fps`` (linear interpolation, :meth:`Motion.resample`)
    unless it already is at that rate, mapped with :func:`to_pred17` and cut into windows
    of ``1 + past_len + future_len`` frames every ``stride`` frames. Clips are identified
    by ``Motion.name``.

    Args:
        motions: clips on skeletons with the 17 canonical keypoints of the layout.
        past_len: P, observed frames per window.
        future_len: F, frames to predict per window.
        stride: frames between the starts of consecutive windows of a clip.
        fps: frame rate of the windows, Hz.

    Returns:
        :class:`PredictionWindows` (clips too short for one window are listed in
        ``skipped``).

    Raises:
        MotionError: bad configuration, or no clip long enough for a single window.
        SkeletonError: a clip lacks a keypoint of the layout.
    """
    _check_config(past_len, future_len, stride, fps)
    names: list[str] = []
    frames, roots, clips, starts, skipped = [], [], [], [], []
    lengths: dict[str, int] = {}
    for motion in motions:
        f, r, s, n = _clip_windows(motion, int(past_len), int(future_len), int(stride),
                                   float(fps))
        lengths[motion.name] = max(lengths.get(motion.name, 0), n)
        if len(s) == 0:
            skipped.append(motion.name)
            continue
        if motion.name not in names:
            names.append(motion.name)
        frames.append(f)
        roots.append(r)
        starts.append(s)
        clips.append(np.full(len(s), names.index(motion.name), dtype=np.int64))
    if not frames:
        need = 1 + past_len + future_len
        seen = ", ".join(f"{n} ({t} frames)" for n, t in lengths.items()) or "none"
        raise MotionError(
            f"no clip gives a single {past_len}->{future_len} window (needs {need} frames "
            f"at {fps:g} fps, i.e. {(need - 1) / fps:.2f} s); clips: {seen}"
        )
    return PredictionWindows(
        np.concatenate(frames), np.concatenate(roots), np.concatenate(clips),
        np.concatenate(starts), tuple(names), int(past_len), int(future_len), float(fps),
        tuple(skipped),
    )


def concat_windows(*parts: PredictionWindows) -> PredictionWindows:
    """The windows of several :class:`PredictionWindows` of one configuration, in order;
    clips of the same name are one clip.

    Raises:
        MotionError: no part, or parts of different ``P -> F`` or fps.
    """
    if not parts:
        raise MotionError("concat_windows needs at least one set of windows")
    first = parts[0]
    for w in parts[1:]:
        if (w.past_len, w.future_len, w.fps) != (first.past_len, first.future_len, first.fps):
            raise MotionError(
                f"cannot join {w.past_len}->{w.future_len} windows at {w.fps:g} fps to "
                f"{first.past_len}->{first.future_len} at {first.fps:g} fps",
                field="windows")
    names: list[str] = []
    for w in parts:
        names += [n for n in w.clip_names if n not in names]
    clips = [np.array([names.index(n) for n in w.clip_names], dtype=np.int64)[w.clip]
             for w in parts]
    skipped = tuple(n for w in parts for n in w.skipped)
    return PredictionWindows(
        np.concatenate([w.frames for w in parts]), np.concatenate([w.root for w in parts]),
        np.concatenate(clips), np.concatenate([w.start for w in parts]), tuple(names),
        first.past_len, first.future_len, first.fps, skipped)


@dataclass(frozen=True)
class ClipSplit:
    """A train/test split of windows by clip.

    Attributes:
        train: (N_train,) int64 window indices; test: (N_test,) int64 window indices.
        train_clips: clip names on the train side; test_clips: on the test side
            (disjoint; together all clips).
    """

    train: np.ndarray
    test: np.ndarray
    train_clips: tuple[str, ...]
    test_clips: tuple[str, ...]


def split_by_clip(clip_names: Sequence[str], test_fraction: float, seed: int) -> ClipSplit:
    """Split windows into train and test so that no clip has windows on both sides.

    Clips are visited in a seeded random order; a clip goes to the test side when that
    brings the test side's share of *windows* closer to ``test_fraction``. At least one
    clip ends up on each side.

    Args:
        clip_names: (N,) clip name of each window (e.g.
            :attr:`PredictionWindows.window_clip_names`).
        test_fraction: target share of windows in the test split, in (0, 1).
        seed: seed of the clip order (same seed and names -> same split).

    Raises:
        MotionError: fewer than two distinct clips or a fraction outside (0, 1).
    """
    names = np.asarray(clip_names, dtype=object)
    if not 0 < test_fraction < 1:
        raise MotionError(f"test_fraction must be in (0, 1); got {test_fraction!r}",
                          field="test_fraction")
    unique, inverse, counts = np.unique(names.astype(str), return_inverse=True,
                                        return_counts=True)
    if len(unique) < 2:
        raise MotionError(
            f"a split by clip needs at least 2 distinct clips; got {len(unique)} "
            f"({', '.join(unique)})"
        )
    target = test_fraction * len(names)
    order = np.random.default_rng(seed).permutation(len(unique))
    is_test = np.zeros(len(unique), dtype=bool)
    taken = 0
    for c in order:
        if is_test.sum() == len(unique) - 1:
            break
        if abs(taken + counts[c] - target) < abs(taken - target):
            is_test[c] = True
            taken += counts[c]
    if not is_test.any():  # every clip alone overshoots: take the one closest to the target
        is_test[order[np.argmin(np.abs(counts[order] - target))]] = True
    window_test = is_test[inverse]
    return ClipSplit(
        train=np.flatnonzero(~window_test),
        test=np.flatnonzero(window_test),
        train_clips=tuple(str(u) for u in unique[~is_test]),
        test_clips=tuple(str(u) for u in unique[is_test]),
    )


def clip_folds(clip_names: Sequence[str], folds: int, seed: int) -> list[ClipSplit]:
    """K-fold splits of windows by clip: every clip is on the test side of exactly one
    fold, and no clip has windows on both sides of any fold.

    Clips are dealt, largest first (ties in a seeded random order), each to the fold
    with the fewest test windows so far, which balances the folds' window counts.

    Args:
        clip_names: (N,) clip name of each window.
        folds: number of folds K, 2 <= K <= number of distinct clips.
        seed: seed of the tie-break order.

    Returns:
        K :class:`ClipSplit`; fold ``k`` holds out the clips dealt to it.

    Raises:
        MotionError: fewer than ``folds`` distinct clips, or ``folds < 2``.
    """
    names = np.asarray(clip_names, dtype=object).astype(str)
    unique, inverse, counts = np.unique(names, return_inverse=True, return_counts=True)
    if not 2 <= folds <= len(unique):
        raise MotionError(f"folds must be in [2, {len(unique)}] (the number of distinct "
                          f"clips); got {folds}", field="folds")
    shuffled = np.random.default_rng(seed).permutation(len(unique))
    order = shuffled[np.argsort(-counts[shuffled], kind="stable")]
    fold_of = np.empty(len(unique), dtype=np.int64)
    load = np.zeros(folds, dtype=np.int64)
    for rank, c in enumerate(order):
        # the first K clips open one fold each, so that no fold is empty
        k = rank if rank < folds else int(np.argmin(load))
        fold_of[c] = k
        load[k] += counts[c]
    out = []
    for k in range(folds):
        test = fold_of[inverse] == k
        out.append(ClipSplit(train=np.flatnonzero(~test), test=np.flatnonzero(test),
                             train_clips=tuple(str(u) for u in unique[fold_of != k]),
                             test_clips=tuple(str(u) for u in unique[fold_of == k])))
    return out

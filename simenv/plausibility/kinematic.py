"""Joint-level kinematic plausibility metrics: bone length, jitter, velocity.

All metrics work in metres and seconds, world Z-up: :func:`bone_length` on
the source skeleton's own bones, the others on the canonical keypoints
(:meth:`Motion.to_canonical`). They are vectorised over frames and joints, and
return a :class:`~simenv.plausibility.timeline.MetricResult` with one timeline
value per frame.

Consistent rule for short or incomplete input: a metric that cannot be
computed (too few frames for its finite differences, no keypoints it needs)
does not raise; it returns ``MetricResult.not_available`` with ``passed=None``
and a ``reason`` naming what is missing, so a report can still show the other
metrics. Invalid *arguments* (a malformed reference skeleton) raise
:class:`~simenv.core.errors.MotionError`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import lru_cache

import numpy as np

from simenv.core.errors import MotionError
from simenv.core.motion import Motion, resample_weights
from simenv.core.skeletons import CANONICAL_TREE, Skeleton
from simenv.plausibility import kernels
from simenv.plausibility.clips import ClipBatch, MetricSpec, norm3, score_clip
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult

#: Keypoint groups for the speed limits (see :class:`Thresholds`).
TRUNK_KEYPOINTS: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine", "chest", "neck", "head",
    "left_shoulder", "right_shoulder",
)
LIMB_KEYPOINTS: tuple[str, ...] = ("left_knee", "right_knee", "left_elbow", "right_elbow")
DISTAL_KEYPOINTS: tuple[str, ...] = (
    "left_ankle", "right_ankle", "left_toe", "right_toe",
    "left_wrist", "right_wrist", "left_hand", "right_hand",
)


def canonical_or_reason(motion: Motion) -> tuple[Motion | None, str | None]:
    """The canonical-keypoint motion, or ``(None, reason)`` when the
    skeleton maps no canonical keypoint."""
    try:
        return motion.to_canonical(), None
    except MotionError as exc:
        return None, f"no canonical keypoints: {exc.detail}"


def keypoint_indices(motion: Motion, names: Sequence[str]) -> list[int]:
    """Indices of those of ``names`` that ``motion``'s skeleton has, in order."""
    present = motion.skeleton.joint_names
    return [present.index(n) for n in names if n in present]


def _limited(name: str, reason: str, num_frames: int, unit: str, threshold: float,
             **kwargs: object) -> MetricResult:
    return MetricResult.not_available(name, num_frames, unit, threshold, reason, **kwargs)


# -- bone length ---------------------------------------------------------------


def measured_bones(skeleton: Skeleton) -> list[tuple[int, int]]:
    """The source bones :func:`bone_length` measures: every parent-child pair
    of ``skeleton.parents`` (:attr:`Skeleton.bones`, in joint order) except
    those of an *extremity fan*.

    An extremity fan is two or more end joints (leaves of the tree) on one
    parent: a hand's tip and thumb (Kinect v2 ``HandTipLeft`` and
    ``ThumbLeft``, Azure Kinect ``HANDTIP_LEFT`` and ``THUMB_LEFT``), eyes
    and ears on a head (Poser ``leftEye`` and ``rightEye``, Azure ``EYE_LEFT``,
    ``EAR_LEFT``, ...). A depth camera estimates such points each on its own
    a few centimetres from their parent, so their relative deviation is
    sensor noise; marker capture and body models keep them rigid, so leaving
    them out costs no check of the limbs. A lone end joint (a toe, the head,
    CMU ASF ``lthumb``, the wrist of SMPL's 22 joints) is measured. Only the
    tree decides, never the canonical map. Bones whose clip median is shorter than
    ``bone_min_length_m`` (a converter's collapsed bones) are skipped when
    scoring.
    """
    parents = skeleton.parents
    children: list[list[int]] = [[] for _ in parents]
    for j, p in enumerate(parents):
        if p >= 0:
            children[p].append(j)
    fan = [sum(not children[c] for c in kids) > 1 for kids in children]
    return [(p, j) for j, p in enumerate(parents)
            if p >= 0 and not (fan[p] and not children[j])]


def bone_names(skeleton: Skeleton) -> list[str]:
    """Names of :func:`measured_bones`, ``"parent->child"`` in the source's
    own joint names (``"left_collar->left_shoulder"``, ``"LeftArm->LeftForeArm"``)."""
    names = skeleton.joint_names
    return [f"{names[p]}->{names[c]}" for p, c in measured_bones(skeleton)]


def bone_lengths(motion: Motion) -> tuple[list[str], np.ndarray]:
    """Per-frame lengths of the source bones :func:`bone_length` measures.

    Returns:
        (bone names as :func:`bone_names`, lengths (T, B) float64 metres).
    """
    bones = measured_bones(motion.skeleton)
    names = bone_names(motion.skeleton)
    if not bones:
        return names, np.zeros((motion.num_frames, 0))
    parent, child = np.array(bones).T
    pos = motion.positions.astype(np.float64)
    return names, norm3(pos[:, child] - pos[:, parent])


def bone_deviations(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS
                    ) -> list[dict[str, float | str | bool]]:
    """Per-bone breakdown of :func:`bone_length`: which source bone moves.

    Returns:
        One dict per bone of :func:`measured_bones`, in joint order: ``bone``
        (its name), ``median_m`` (reference length: median over the clip,
        metres), ``tolerance`` (relative), ``max_rel_deviation`` (largest
        ``|L(t) / median - 1|``), ``p95_tolerances`` (95th percentile over
        frames of the deviation in tolerances: the bone's own share of the
        metric's value) and ``checked`` (False for a bone shorter than
        ``bone_min_length_m``, whose deviations are then 0).
    """
    names, lengths = bone_lengths(motion)
    _, _, tol = _bones(motion.skeleton, thresholds)
    out: list[dict[str, float | str | bool]] = []
    for k, name in enumerate(names):
        med = float(np.median(lengths[:, k]))
        checked = bool(med >= thresholds.bone_min_length_m)
        dev = np.abs(lengths[:, k] / med - 1.0) if checked else np.zeros(len(lengths))
        out.append({"bone": name, "median_m": med, "tolerance": float(tol[k]),
                    "max_rel_deviation": float(dev.max(initial=0.0)),
                    "p95_tolerances": float(np.percentile(dev / tol[k], 95)),
                    "checked": checked})
    return out


def _canonical_bone_lengths(motion: Motion) -> tuple[list[str], np.ndarray]:
    """Per-frame lengths (T, B) float64 metres of the canonical keypoint
    pairs, named by child keypoint (``"left_knee"`` is hip to knee): the
    skeleton-independent bones :func:`bone_length_error` compares."""
    canon, reason = canonical_or_reason(motion)
    if canon is None:
        raise MotionError(reason or "no canonical keypoints", source=motion.metadata.get("source"))
    bones = canon.skeleton.bones
    names = [canon.skeleton.joint_names[c] for _, c in bones]
    if not bones:
        return names, np.zeros((canon.num_frames, 0))
    parent, child = np.array(bones).T
    pos = canon.positions.astype(np.float64)
    return names, norm3(pos[:, child] - pos[:, parent])


def reference_lengths(motion: Motion) -> dict[str, float]:
    """Median length (metres) of each canonical keypoint pair over the clip,
    keyed by child keypoint (``"left_knee"`` = thigh): a reference skeleton
    for :func:`bone_length_error`, comparable across source skeletons.

    Raises:
        MotionError: the skeleton maps no canonical keypoint.
    """
    names, lengths = _canonical_bone_lengths(motion)
    return {n: float(v) for n, v in zip(names, np.median(lengths, axis=0), strict=True)}


def bone_length(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricResult:
    """Bone-length consistency over time, on the source skeleton's own bones.

    The bones are the parent-child pairs of ``motion.skeleton.parents``
    (:func:`measured_bones`): each is one rigid segment in every source that
    keeps segments rigid (BVH and ASF/AMC forward kinematics, SMPL / AMASS
    joints), so a rigid source scores 0 and any change of a bone's length is
    the motion's. Canonical keypoint pairs are not measured: one may span a
    joint the source moves (SMPL's collar between chest and shoulder, CMU's
    upper neck between neck and head), whose length legitimately changes.
    For each bone b with median length ``m_b`` over the clip (its reference
    length) the relative deviation at frame t is ``d_b(t) = |L_b(t) / m_b -
    1|``, compared with the bone's tolerance ``tol_b``:
    ``bone_length_rel_max`` (5 %), or ``bone_length_head_rel_max`` (15 %)
    for a bone that ends at the joint the skeleton maps to canonical
    ``head`` (a head-centre estimate on depth cameras; the tolerance is the
    only use of the canonical map). Timeline: ``max_b d_b(t) / tol_b``
    (fraction of tolerance, violation above 1: the worst bone). Value: the
    95th percentile of the timeline over frames (robust to a single bad
    frame, which :func:`velocity` catches); passes when at most 1. Details:
    ``max`` (of the timeline), ``max_rel_deviation`` (largest ``d_b``),
    ``bones_checked``; :func:`bone_deviations` names the bone behind them.
    Bones with a median shorter than ``bone_min_length_m`` are skipped. Depth
    cameras estimate every joint independently, so their bones are not rigid:
    judge them with their sensor's profile
    (:data:`~simenv.plausibility.thresholds.SOURCE_THRESHOLDS`) or reference.
    The per-clip form of the seeds' bone-length consistency terms (MA-GAN's
    bone-length loss, the reactive GAN's bone constraint); works on one frame
    (the value is then 0).
    """
    return score_clip(motion, bone_length_spec, thresholds)


def bone_length_spec(batch: ClipBatch, thresholds: Thresholds = DEFAULT_THRESHOLDS
                     ) -> MetricSpec:
    """:func:`bone_length` as :func:`~simenv.plausibility.clips.score` runs it."""
    reason = "needs two joints joined by a bone (skeleton.parents) of non-zero length"
    args = None
    if batch.skeleton is None:
        # No canonical layout: the batch holds no positions; each clip says why.
        reason = ""
    else:
        parent, child, tol = _bones(batch.motions[0].skeleton, thresholds)
        if len(parent):
            args = (parent, child, tol, float(thresholds.bone_min_length_m), 95 / 100)
    return MetricSpec(kernels.BONE, "bone_length", "fraction of tolerance", 1.0, args,
                      ("max", "max_rel_deviation", "bones_checked"), reason=reason)


@lru_cache(maxsize=64)
def _bones(skeleton: Skeleton, thresholds: Thresholds
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K,) int64 parent and child source joints and float64 relative
    tolerance of each of :func:`measured_bones`, once per skeleton and
    thresholds (shared: never modified)."""
    bones = measured_bones(skeleton)
    parent = np.array([p for p, _ in bones], dtype=np.int64)
    child = np.array([c for _, c in bones], dtype=np.int64)
    head = skeleton.canonical.get("head")
    names = skeleton.joint_names
    tol = np.array([thresholds.bone_length_head_rel_max if head in (names[p], names[c])
                    else thresholds.bone_length_rel_max for p, c in bones], dtype=np.float64)
    return parent, child, tol


def bone_length_error(
    motion: Motion,
    reference_lengths: Mapping[str, float],
    thresholds: Thresholds = DEFAULT_THRESHOLDS,
) -> MetricResult:
    """Bone-length error against a reference skeleton (the interaction-
    augmentation seed's E_b).

    ``E_b(t) = mean_b |L_b(t) - L_b^ref|`` over the bones present in both,
    in millimetres (timeline); the value is the mean over frames. Passes
    when at most ``thresholds.bone_reference_error_max_mm``.

    Args:
        motion: the motion to check.
        reference_lengths: metres per bone, keyed by the bone's child
            canonical keypoint (``"left_knee"`` = thigh), e.g. from
            :func:`reference_lengths` of a real clip.

    Raises:
        MotionError: a key is not a canonical bone or a length is not a
            positive finite number of metres.
    """
    name, unit, thr = "bone_length_error", "mm", thresholds.bone_reference_error_max_mm
    ref: dict[str, float] = {}
    for key, length in reference_lengths.items():
        if CANONICAL_TREE.get(key) is None:
            raise MotionError(
                f"reference bone {key!r} is not a canonical bone; expected a child keypoint "
                f"among {', '.join(k for k, p in CANONICAL_TREE.items() if p is not None)}",
                field=str(key),
            )
        value = float(length)
        if not np.isfinite(value) or value <= 0 or value > 2.0:
            raise MotionError(
                f"reference length of {key!r} is {length!r}; expected a positive bone length "
                "in metres (below 2 m)",
                field=str(key),
            )
        ref[key] = value
    canon, reason = canonical_or_reason(motion)
    if canon is None:
        return _limited(name, reason or "", motion.num_frames, unit, thr)
    names, lengths = _canonical_bone_lengths(canon)
    common = [i for i, n in enumerate(names) if n in ref]
    if not common:
        return _limited(
            name, "the motion and the reference share no canonical bone",
            motion.num_frames, unit, thr,
        )
    target = np.array([ref[names[i]] for i in common])
    timeline = np.abs(lengths[:, common] - target).mean(axis=1) * 1000.0
    return MetricResult.from_timeline(
        name, timeline, float(timeline.mean()), unit, thr,
        details={"max": float(timeline.max()), "bones_compared": float(len(common))},
    )


# -- jitter --------------------------------------------------------------------


#: Path-length floor (metres) of the normalized jerk (ProtoMotions' value).
NJ_EPS = 0.1


def windowed_normalized_jerk(
    positions: np.ndarray, fps: float, window_frames: int, eps: float = NJ_EPS
) -> np.ndarray:
    """ProtoMotions' normalized jerk per sliding window and keypoint.

    For a window of ``w`` frames (duration ``T = (w - 1) / fps``) and one
    keypoint, with finite-difference velocity ``v``, jerk ``j`` and
    ``dt = 1 / fps``:
    ``NJ = T^5 * sum |j|^2 dt / (max(L, eps)^2 + eps)`` with path length
    ``L = sum |v| dt``. Dimensionless; windows advance one frame.

    Args:
        positions: (..., T, J, 3) metres; leading axes (e.g. clips) are
            batch axes.
        fps: frame rate of ``positions``.
        window_frames: ``w >= 4``.

    Returns:
        (..., T - w + 1, J) float64; empty along the window axis when ``T < w``.
    """
    pos = np.asarray(positions, dtype=np.float64)
    *lead, t_count, j_count, _ = pos.shape
    w = int(window_frames)
    if t_count < w or w < 4:
        return np.zeros((*lead, 0, j_count))
    dt = 1.0 / fps
    vel = np.diff(pos, axis=-3) / dt
    jerk = np.diff(pos, 3, axis=-3) / dt**3
    step = norm3(vel) * dt  # (..., T-1, J)
    jx, jy, jz = jerk[..., 0], jerk[..., 1], jerk[..., 2]
    jerk_sq = ((jx * jx + jy * jy) + jz * jz) * dt  # (..., T-3, J)
    # Window sums from cumulative sums: O(T) whatever the window length.
    zero = np.zeros((*lead, 1, j_count))
    cs_step = np.concatenate([zero, np.cumsum(step, axis=-2)], axis=-2)
    cs_jerk = np.concatenate([zero, np.cumsum(jerk_sq, axis=-2)], axis=-2)
    n = t_count - w + 1
    path = cs_step[..., w - 1 : w - 1 + n, :] - cs_step[..., :n, :]
    integrated = cs_jerk[..., w - 3 : w - 3 + n, :] - cs_jerk[..., :n, :]
    duration = (w - 1) * dt
    return duration**5 * integrated / (np.maximum(path, eps) ** 2 + eps)


def jitter(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricResult:
    """High-frequency jitter from ProtoMotions' windowed normalized jerk.

    The motion is first brought to at most ``thresholds.jerk_fps`` (30 Hz,
    ProtoMotions' rate; see :class:`Thresholds`). With windows of
    ``w = max(4, round(jerk_window_s * fps))`` frames (0.4 s),
    :func:`windowed_normalized_jerk` gives NJ per window and keypoint.

    Value: percentage of windows in which the *median* keypoint's NJ exceeds
    ``normalized_jerk_max`` (6500); passes when at most
    ``high_jerk_percent_max``. Capture or generation noise shakes every
    keypoint, whereas real jerky moments (landings, strikes, kicks) are
    local: ProtoMotions' published statistic, where *any* keypoint over 6500
    makes a window high-jerk, scores real CMU dance and athletics at 20-78 %,
    so it is reported in ``details["protomotions_high_jerk_percent"]`` for
    comparison but not used for the verdict. Timeline: the median keypoint's
    NJ of the window centred on each frame (NaN where no window is centred),
    against 6500. Details also: ``mean_jerk_mps3`` (mean over frames and
    keypoints of |jerk| at the analysis rate), ``normalized_jerk_mean``
    (ProtoMotions' ``normalized_jerk_mean``: mean over keypoints and windows)
    and ``analysis_fps``. Not available for clips shorter than one window.
    """
    return score_clip(motion, jitter_spec, thresholds)


def jitter_spec(batch: ClipBatch, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricSpec:
    """:func:`jitter` as :func:`~simenv.plausibility.clips.score` runs it."""
    fps = batch.fps
    fa, w, src, weight, reason = _jitter_setup(fps, batch.num_frames, thresholds)
    args = None
    if batch.skeleton is None:
        reason = ""
    elif reason is None:
        resample = src is not None
        if src is None:
            src, weight = _NO_RESAMPLE
        dt = 1.0 / fa
        args = (resample, src, weight, float(fps), float(fa), int(w), NJ_EPS,
                float(thresholds.normalized_jerk_max), dt**3, ((w - 1) * dt) ** 5, fa**3,
                _median_network(len(batch.names)))
    return MetricSpec(
        kernels.JITTER, "jitter", "%", thresholds.high_jerk_percent_max, args,
        ("protomotions_high_jerk_percent", "mean_jerk_mps3", "normalized_jerk_mean",
         ("analysis_fps", fa)),
        frame_threshold=thresholds.normalized_jerk_max, timeline_unit="normalized jerk",
        reason=reason or "")


@lru_cache(maxsize=64)
def _median_network(keypoints: int) -> np.ndarray:
    """:func:`simenv.plausibility.kernels.median_network` of a keypoint
    count, built once (shared: never modified)."""
    return kernels.median_network(keypoints)


#: Unused resampling arrays of a clip analysed at its own rate.
_NO_RESAMPLE = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.float32))


@lru_cache(maxsize=256)
def _jitter_setup(fps: float, frames: int, thresholds: Thresholds
                  ) -> tuple[float, int, np.ndarray | None, np.ndarray | None, str | None]:
    """Analysis rate, window (frames), resampling indices (N,) int64 and
    weights (N,) float32 (None without resampling), and why the metric is not
    available (None when it is), once per frame rate, length and thresholds."""
    fa = min(fps, thresholds.jerk_fps)
    w = max(4, round(thresholds.jerk_window_s * fa))
    needed = max(int(np.ceil((w - 1) * fps / fa)) + 1, 4)
    if frames < needed:
        return fa, w, None, None, (
            f"needs at least {needed} frames ({thresholds.jerk_window_s:g} s window at "
            f"{fa:g} fps); the motion has {frames}")
    # Down to the analysis rate (never up: interpolating up would add jerk
    # at every original sample), in float32 as Motion.resample.
    if not fps > fa * (1 + 1e-9):
        reason = None if frames >= w else f"resampled clip is shorter than one {w}-frame window"
        return fa, w, None, None, reason
    src, weight = resample_weights(frames, fps, fa)
    if len(src) < w:
        return fa, w, None, None, f"resampled clip is shorter than one {w}-frame window"
    return fa, w, src.astype(np.int64), weight.astype(np.float32), None


# -- velocity and teleports ----------------------------------------------------


def speed_limits(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> np.ndarray:
    """(J,) speed limit in m/s of each keypoint of a canonical ``motion``
    (trunk, mid-limb or distal limit; unknown names get the distal limit)."""
    return _speed_limits(tuple(motion.skeleton.joint_names), thresholds).copy()


@lru_cache(maxsize=64)
def _speed_limits(names: tuple[str, ...], thresholds: Thresholds) -> np.ndarray:
    """(J,) float64 limits, m/s, once per layout and thresholds (shared:
    never modified)."""
    group_limit = {
        **{n: thresholds.speed_limit_trunk_mps for n in TRUNK_KEYPOINTS},
        **{n: thresholds.speed_limit_limb_mps for n in LIMB_KEYPOINTS},
        **{n: thresholds.speed_limit_distal_mps for n in DISTAL_KEYPOINTS},
    }
    limits = [group_limit.get(n, thresholds.speed_limit_distal_mps)
              for n in names]
    return np.array(limits, dtype=np.float64)


def velocity(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricResult:
    """Keypoint speeds beyond human limits, and teleports between frames.

    Speed of keypoint j at frame t >= 1: ``s_j(t) = |p_j(t) - p_j(t-1)| * fps``
    against its group limit ``S_j`` (trunk / mid-limb / distal, see
    :class:`Thresholds`). Teleport: the departure from the constant-velocity
    path ``e_j(t) = |p_j(t+1) - 2 p_j(t) + p_j(t-1)|`` (metres) against
    ``E = max(teleport_distance_m, teleport_accel_mps2 / fps^2)``.
    Timeline (fraction of the limit):
    ``max_j max(s_j(t) / S_j, e_j(t) / E)``, NaN on frame 0; value: its
    maximum; passes when at most 1. Details: ``max_speed_mps``,
    ``max_speed_ratio``, ``max_jump_m``, ``teleport_frames``. Needs two frames
    (teleports need three; with two only speeds are checked).
    """
    return score_clip(motion, velocity_spec, thresholds)


def velocity_spec(batch: ClipBatch, thresholds: Thresholds = DEFAULT_THRESHOLDS
                  ) -> MetricSpec:
    """:func:`velocity` as :func:`~simenv.plausibility.clips.score` runs it."""
    frames, fps = batch.num_frames, batch.fps
    jump_limit = max(thresholds.teleport_distance_m, thresholds.teleport_accel_mps2 / fps**2)
    args, reason = None, ""
    if batch.skeleton is not None and frames < 2:
        reason = f"needs at least 2 frames for a speed; the motion has {frames}"
    elif batch.skeleton is not None:
        args = (_speed_limits(tuple(batch.names), thresholds), float(fps), float(jump_limit))
    return MetricSpec(
        kernels.VELOCITY, "velocity", "fraction of limit", 1.0, args,
        ("max_speed_mps", "max_speed_ratio", "max_jump_m", ("jump_limit_m", jump_limit),
         "teleport_frames"),
        reason=reason)

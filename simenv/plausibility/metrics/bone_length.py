"""Bone-length consistency over time, on the source skeleton's own bones.

The metric (:class:`BoneLength`, its kernel
:func:`simenv.plausibility.kernels.bone_length`), its per-bone breakdown
(:func:`bone_deviations`) and the bone-length error against a reference
skeleton (:func:`bone_length_error`, the interaction-augmentation seed's E_b).
Thresholds: ``bone_length_*`` and ``bone_*`` fields of
:class:`~simenv.plausibility.thresholds.Thresholds`. Metres, Z-up.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache

import numpy as np

from simenv.core.errors import MotionError
from simenv.core.motion import Motion
from simenv.core.skeletons import CANONICAL_TREE, Skeleton
from simenv.plausibility import kernels
from simenv.plausibility.clips import ClipBatch, MetricSpec, norm3, score_clip
from simenv.plausibility.metric import KeypointMetric, ScoreConfig
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult


def canonical_or_reason(motion: Motion) -> tuple[Motion | None, str | None]:
    """The canonical-keypoint motion, or ``(None, reason)`` when the
    skeleton maps no canonical keypoint."""
    try:
        return motion.to_canonical(), None
    except MotionError as exc:
        return None, f"no canonical keypoints: {exc.detail}"


def _limited(name: str, reason: str, num_frames: int, unit: str, threshold: float,
             **kwargs: object) -> MetricResult:
    return MetricResult.not_available(name, num_frames, unit, threshold, reason, **kwargs)


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


class BoneLength(KeypointMetric):
    """Bone-length consistency (:func:`bone_length`).

    Per frame ``max_b |L_b(t) / median_t L_b - 1| / tol_b`` over the source
    skeleton's own parent-child bones (fraction of the bone's tolerance: 5 %,
    15 % for the bone ending at the head); value: its 95th percentile over
    frames; passes at <= 1.
    """

    name, family, unit = "bone_length", "kinematic", "fraction of tolerance"

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        return 1.0, 1.0

    spec = staticmethod(bone_length_spec)
    function = staticmethod(bone_length)

"""Plausibility scoring of skeleton motion.

Joint-level (kinematic) metrics, each ``metric(motion, thresholds) ->
MetricResult`` on the canonical keypoints (metres, seconds, Z-up, floor at
z = 0):

================== ====================================================== =========
name               what                                                   module
================== ====================================================== =========
bone_length        bone-length consistency over time                      kinematic
foot_skate         GMD foot-skating ratio (+ PhysDiff skate)              contact
ground_penetration lowest keypoint below the floor                        contact
floating           airborne without a ballistic (free-fall) arc           contact
jitter             windows of high normalized jerk (ProtoMotions), jerk   kinematic
velocity           speeds beyond human limits, teleports                  kinematic
================== ====================================================== =========

:func:`kinematic_metrics` runs them all on one motion,
:func:`kinematic_metrics_batch` on many at once (vectorised over clips of
equal length; same values). Thresholds: :class:`Thresholds`.
"""

from __future__ import annotations

from collections.abc import Sequence

from simenv.motion import Motion
from simenv.plausibility.clips import ClipBatch, Plan, batches, score
from simenv.plausibility.contact import (
    floating,
    floating_spec,
    foot_contacts,
    foot_skate,
    foot_skate_spec,
    ground_penetration,
    ground_penetration_spec,
)
from simenv.plausibility.kinematic import (
    bone_length,
    bone_length_error,
    bone_length_spec,
    bone_lengths,
    jitter,
    jitter_spec,
    reference_lengths,
    velocity,
    velocity_spec,
)
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult, find_violations

#: The joint-level metrics in report order, by stable name.
KINEMATIC_METRICS = {
    "bone_length": bone_length,
    "foot_skate": foot_skate,
    "ground_penetration": ground_penetration,
    "floating": floating,
    "jitter": jitter,
    "velocity": velocity,
}


#: The same metrics as :func:`~simenv.plausibility.clips.score` runs them.
_SPECS = (bone_length_spec, foot_skate_spec, ground_penetration_spec, floating_spec,
          jitter_spec, velocity_spec)
#: Plans of the six metrics by batch shape (a plan depends on nothing else).
_PLANS: dict[tuple, Plan] = {}


def _plan(batch: ClipBatch, thresholds: Thresholds) -> Plan:
    """The six metrics' plan for batches of this layout, rate, length and
    thresholds, prepared once (the specs' lookups cost as much as the
    kernels on a short clip)."""
    key = (batch.skeleton, batch.fps, batch.num_frames, thresholds)
    plan = _PLANS.get(key)
    if plan is None:
        if len(_PLANS) >= 256:
            _PLANS.clear()
        plan = _PLANS[key] = Plan([spec(batch, thresholds) for spec in _SPECS])
    return plan


def kinematic_metrics(
    motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS
) -> dict[str, MetricResult]:
    """Every joint-level metric of ``motion``, keyed by metric name."""
    return kinematic_metrics_batch([motion], thresholds)[0]


def kinematic_metrics_batch(
    motions: Sequence[Motion], thresholds: Thresholds = DEFAULT_THRESHOLDS
) -> list[dict[str, MetricResult]]:
    """Every joint-level metric of every motion, in input order.

    Results equal :func:`kinematic_metrics` of each motion. Clips of equal
    skeleton, frame rate and length (e.g. a batch of generated motions) are
    scored together, vectorised over clips
    (:func:`simenv.plausibility.clips.batches`), all six metrics in one
    compiled call per batch (:func:`simenv.plausibility.clips.score`), which
    removes the per-call overhead that dominates short clips; any mix of
    clips is accepted.
    """
    out: list[dict[str, MetricResult]] = [{} for _ in motions]
    names = list(KINEMATIC_METRICS)
    for members, batch in batches(motions):
        per_metric = score(batch, _plan(batch, thresholds))
        for k, i in enumerate(members):
            out[i] = {name: rs[k] for name, rs in zip(names, per_metric, strict=True)}
    return out


__all__ = [
    "DEFAULT_THRESHOLDS",
    "KINEMATIC_METRICS",
    "MetricResult",
    "Thresholds",
    "bone_length",
    "bone_length_error",
    "bone_lengths",
    "find_violations",
    "floating",
    "foot_contacts",
    "foot_skate",
    "ground_penetration",
    "jitter",
    "kinematic_metrics",
    "kinematic_metrics_batch",
    "reference_lengths",
    "velocity",
]

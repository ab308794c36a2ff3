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

:func:`kinematic_metrics` runs them all. Thresholds: :class:`Thresholds`.
"""

from __future__ import annotations

from simenv.motion import Motion
from simenv.plausibility.contact import (
    floating,
    foot_contacts,
    foot_skate,
    ground_penetration,
)
from simenv.plausibility.kinematic import (
    bone_length,
    bone_length_error,
    bone_lengths,
    jitter,
    reference_lengths,
    velocity,
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


def kinematic_metrics(
    motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS
) -> dict[str, MetricResult]:
    """Every joint-level metric of ``motion``, keyed by metric name."""
    return {name: fn(motion, thresholds) for name, fn in KINEMATIC_METRICS.items()}


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
    "reference_lengths",
    "velocity",
]

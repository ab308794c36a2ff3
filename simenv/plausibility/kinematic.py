"""The joint-level kinematic metrics' former module, kept for code that imports from here.

Each metric is now one module of :mod:`simenv.plausibility.metrics`:
:mod:`~simenv.plausibility.metrics.bone_length`,
:mod:`~simenv.plausibility.metrics.jitter`,
:mod:`~simenv.plausibility.metrics.velocity`.
"""

from __future__ import annotations

from simenv.plausibility.metrics.bone_length import (
    bone_deviations,
    bone_length,
    bone_length_error,
    bone_length_spec,
    bone_lengths,
    bone_names,
    canonical_or_reason,
    measured_bones,
    reference_lengths,
)
from simenv.plausibility.metrics.jitter import (
    NJ_EPS,
    jitter,
    jitter_spec,
    windowed_normalized_jerk,
)
from simenv.plausibility.metrics.velocity import (
    DISTAL_KEYPOINTS,
    LIMB_KEYPOINTS,
    TRUNK_KEYPOINTS,
    speed_limits,
    velocity,
    velocity_spec,
)

__all__ = [
    "DISTAL_KEYPOINTS", "LIMB_KEYPOINTS", "NJ_EPS", "TRUNK_KEYPOINTS", "bone_deviations",
    "bone_length", "bone_length_error", "bone_length_spec", "bone_lengths", "bone_names",
    "canonical_or_reason", "jitter", "jitter_spec", "measured_bones", "reference_lengths",
    "speed_limits", "velocity", "velocity_spec", "windowed_normalized_jerk",
]

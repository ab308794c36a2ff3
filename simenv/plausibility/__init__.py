"""Plausibility scoring of skeleton motion.

The scorer is :func:`simenv.plausibility.report.score`; it runs every metric of
the list in :mod:`simenv.plausibility.metric_registry`, each one module of
:mod:`simenv.plausibility.metrics` (its math, thresholds and kernel spec).
This package exports the joint-level metrics, each
``metric(motion, thresholds) -> MetricResult`` on the canonical keypoints
(metres, seconds, Z-up, floor at z = 0): :func:`bone_length`,
:func:`foot_skate`, :func:`ground_penetration`, :func:`floating`,
:func:`jitter`, :func:`velocity`; :func:`kinematic_metrics` runs them all on
one motion, :func:`kinematic_metrics_batch` on many at once
(:mod:`simenv.plausibility.keypoints`). Thresholds: :class:`Thresholds`.
"""

from __future__ import annotations

from simenv.plausibility.keypoints import (
    KINEMATIC_METRICS,
    KinematicResults,
    kinematic_metrics,
    kinematic_metrics_batch,
)
from simenv.plausibility.metrics.bone_length import (
    bone_length,
    bone_length_error,
    bone_lengths,
    reference_lengths,
)
from simenv.plausibility.metrics.floating import floating
from simenv.plausibility.metrics.foot_skate import foot_skate
from simenv.plausibility.metrics.ground_penetration import ground_penetration
from simenv.plausibility.metrics.jitter import jitter
from simenv.plausibility.metrics.velocity import velocity
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult, find_violations

__all__ = [
    "DEFAULT_THRESHOLDS",
    "KINEMATIC_METRICS",
    "KinematicResults",
    "MetricResult",
    "Thresholds",
    "bone_length",
    "bone_length_error",
    "bone_lengths",
    "find_violations",
    "floating",
    "foot_skate",
    "ground_penetration",
    "jitter",
    "kinematic_metrics",
    "kinematic_metrics_batch",
    "reference_lengths",
    "velocity",
]

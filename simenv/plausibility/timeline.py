"""Per-metric result record: value, verdict, per-frame timeline and violations.

Every plausibility metric returns a :class:`MetricResult`. Its ``timeline``
has one value per frame of the scored motion, so timelines of different
metrics line up and can be plotted against their thresholds. Violations are
derived from the timeline alone: maximal runs of consecutive frames whose
value exceeds the per-frame threshold.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simenv.core.errors import MotionError

#: One violation: (first frame, last frame inclusive, worst timeline value).
Violation = tuple[int, int, float]


def find_violations(timeline: np.ndarray, threshold: float) -> list[Violation]:
    """Maximal runs of frames where ``timeline > threshold``.

    Args:
        timeline: (T,) per-frame values; NaN frames never violate (the
            quantity is undefined there, e.g. the first frame of a speed).
        threshold: per-frame limit, same unit as ``timeline``.

    Returns:
        ``[(start_frame, end_frame, worst_value), ...]`` with ``end_frame``
        inclusive and ``worst_value`` the maximum of the timeline in the run,
        sorted by start frame.
    """
    values = np.asarray(timeline, dtype=np.float64)
    if values.ndim != 1:
        raise MotionError(f"timeline must have shape (T,); got {values.shape}")
    with np.errstate(invalid="ignore"):
        over = values > threshold
    if not over.any():
        return []
    edges = np.diff(np.concatenate([[0], over.astype(np.int8), [0]]))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1) - 1
    runs = zip(starts, ends, strict=True)
    return [(int(s), int(e), float(values[s : e + 1].max())) for s, e in runs]


@dataclass(frozen=True)
class MetricResult:
    """Outcome of one plausibility metric on one motion.

    Attributes:
        name: stable metric name (e.g. ``"foot_skate"``).
        value: clip-level value in ``unit``; NaN when not computable.
        unit: unit of ``value`` and ``threshold``.
        threshold: limit on ``value``; the metric passes when
            ``value <= threshold``.
        passed: verdict, or None when the metric is not available.
        timeline: (T,) float32, one value per frame in ``timeline_unit``;
            NaN where the quantity is undefined (e.g. the first frame of a
            finite-difference speed) or the metric is not available.
        violations: runs of frames with ``timeline > frame_threshold`` as
            ``(start_frame, end_frame_inclusive, worst_value)``.
        frame_threshold: per-frame limit applied to ``timeline``; equals
            ``threshold`` when value and timeline share a unit.
        timeline_unit: unit of ``timeline`` (defaults to ``unit``).
        details: secondary statistics (e.g. the published variant of the
            metric, maxima, fractions), all floats.
        reason: why the metric is not available (None when it is).
    """

    name: str
    value: float
    unit: str
    threshold: float
    passed: bool | None
    timeline: np.ndarray
    violations: list[Violation]
    frame_threshold: float
    timeline_unit: str
    details: Mapping[str, float] = field(default_factory=dict)
    reason: str | None = None

    @property
    def available(self) -> bool:
        return self.reason is None

    @classmethod
    def from_timeline(
        cls,
        name: str,
        timeline: np.ndarray,
        value: float,
        unit: str,
        threshold: float,
        *,
        frame_threshold: float | None = None,
        timeline_unit: str | None = None,
        details: Mapping[str, float] | None = None,
    ) -> MetricResult:
        """Build a result, deriving ``passed`` from ``value <= threshold``
        and the violations from ``timeline`` against ``frame_threshold``
        (default: ``threshold``)."""
        tl = np.asarray(timeline, dtype=np.float32)
        ft = threshold if frame_threshold is None else frame_threshold
        value = float(value)
        return cls(
            name=name,
            value=value,
            unit=unit,
            threshold=float(threshold),
            passed=bool(value <= threshold),
            timeline=tl,
            violations=find_violations(tl, ft),
            frame_threshold=float(ft),
            timeline_unit=timeline_unit or unit,
            details={k: float(v) for k, v in (details or {}).items()},
        )

    @classmethod
    def not_available(
        cls,
        name: str,
        num_frames: int,
        unit: str,
        threshold: float,
        reason: str,
        *,
        frame_threshold: float | None = None,
        timeline_unit: str | None = None,
    ) -> MetricResult:
        """A result for a metric that cannot be computed on this motion
        (too few frames, missing keypoints): NaN value and timeline,
        ``passed=None``, no violations, and ``reason`` saying why."""
        return cls(
            name=name,
            value=float("nan"),
            unit=unit,
            threshold=float(threshold),
            passed=None,
            timeline=np.full(num_frames, np.nan, dtype=np.float32),
            violations=[],
            frame_threshold=float(threshold if frame_threshold is None else frame_threshold),
            timeline_unit=timeline_unit or unit,
            details={},
            reason=reason,
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (without the timeline): ``name``, ``value``
        (None if NaN), ``unit``, ``threshold``, ``passed``, ``violations``
        as dicts, ``details`` and ``reason``."""
        value = None if not np.isfinite(self.value) else self.value
        return {
            "name": self.name,
            "value": value,
            "unit": self.unit,
            "threshold": self.threshold,
            "passed": self.passed,
            "violations": [
                {"start_frame": s, "end_frame": e, "worst_value": w} for s, e, w in self.violations
            ],
            "details": dict(self.details),
            "reason": self.reason,
        }

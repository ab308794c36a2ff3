"""The joint-level ground metrics' former module, kept for code that imports from here.

Each metric is now one module of :mod:`simenv.plausibility.metrics`:
:mod:`~simenv.plausibility.metrics.foot_skate`,
:mod:`~simenv.plausibility.metrics.ground_penetration`,
:mod:`~simenv.plausibility.metrics.floating`.
"""

from __future__ import annotations

from simenv.plausibility.metrics.floating import (
    COM_KEYPOINTS,
    HAND_KEYPOINTS,
    ballistic_residual,
    floating,
    floating_spec,
)
from simenv.plausibility.metrics.foot_skate import foot_skate, foot_skate_spec
from simenv.plausibility.metrics.ground_penetration import (
    ground_penetration,
    ground_penetration_spec,
)

__all__ = [
    "COM_KEYPOINTS", "HAND_KEYPOINTS", "ballistic_residual", "floating", "floating_spec",
    "foot_skate", "foot_skate_spec", "ground_penetration", "ground_penetration_spec",
]

"""The body-level metrics' former module, kept for code that imports from here.

Each metric is now one module of :mod:`simenv.plausibility.metrics`:
:mod:`~simenv.plausibility.metrics.ground_penetration` (``body_penetration``),
:mod:`~simenv.plausibility.metrics.floating` (``body_floating``),
:mod:`~simenv.plausibility.metrics.joint_limits`,
:mod:`~simenv.plausibility.metrics.self_penetration`,
:mod:`~simenv.plausibility.metrics.inter_penetration`,
:mod:`~simenv.plausibility.metrics.contact`.
"""

from __future__ import annotations

from simenv.plausibility.metric import DEFAULT_CONTACT_PAIRS
from simenv.plausibility.metrics.contact import contact, pair_distances
from simenv.plausibility.metrics.floating import body_floating
from simenv.plausibility.metrics.ground_penetration import body_penetration
from simenv.plausibility.metrics.inter_penetration import inter_penetration
from simenv.plausibility.metrics.joint_limits import (
    hinge_keypoints,
    joint_limit_clamp_cost,
    joint_limit_demand,
    joint_limit_excess,
    joint_limit_least_excess,
    joint_limits,
    observed_hinges,
    relaxed_humanoid,
    sustained_max,
)
from simenv.plausibility.metrics.self_penetration import self_contact_pairs, self_penetration

__all__ = [
    "DEFAULT_CONTACT_PAIRS", "body_floating", "body_penetration", "contact", "hinge_keypoints",
    "inter_penetration", "joint_limit_clamp_cost", "joint_limit_demand", "joint_limit_excess",
    "joint_limit_least_excess", "joint_limits", "observed_hinges", "pair_distances",
    "relaxed_humanoid", "self_contact_pairs", "self_penetration", "sustained_max",
]

"""The metrics the scorer runs: one plain list, in report order.

:data:`METRICS` lists every metric once; each entry is the
:class:`~simenv.plausibility.metric.Metric` of one module of
:mod:`simenv.plausibility.metrics` (whose docstring gives its math and units).
Adding a metric is one module there and one entry here (docs/plausibility.md,
"Adding a metric"). A report name served on two inputs has two entries, the
preferred first: ``ground_penetration`` and ``floating`` run on the body's
geoms when a body was fitted, on the keypoints otherwise
(:func:`alternatives`).

Everything else is read off the list: :data:`PERSON_REGISTRY` (metrics of
one person) and :data:`PAIR_REGISTRY` (pairwise metrics of a two-person
clip, ``needs`` :attr:`~simenv.plausibility.metric.Needs.PAIR`), their report
names :data:`PERSON_METRICS` and :data:`PAIR_METRICS` (the JSON contract),
and :data:`KEYPOINT_REGISTRY`, the joint-level metrics whose kernels run in
one compiled pass (:mod:`simenv.plausibility.keypoints`).

Units: metres and seconds in, millimetres, degrees, body weights or
fractions out as each metric says; floor plane z = 0, Z up.
"""

from __future__ import annotations

from collections.abc import Sequence

from simenv.plausibility.metric import KeypointMetric, Metric, Needs
from simenv.plausibility.metrics import (
    balance,
    bone_length,
    contact,
    floating,
    foot_skate,
    ground_penetration,
    inter_penetration,
    jitter,
    joint_limits,
    pair_root_residual,
    root_residual,
    self_penetration,
    tracking,
    velocity,
)

#: Every metric, in report order (per person, then pairwise); of two entries with one
#: name the first whose input is there runs.
METRICS: list[Metric] = [
    bone_length.BoneLength(),
    foot_skate.FootSkate(),
    ground_penetration.GeomPenetration(),
    ground_penetration.KeypointPenetration(),
    floating.GeomFloating(),
    floating.KeypointFloating(),
    jitter.Jitter(),
    velocity.Velocity(),
    joint_limits.JointLimits(),
    self_penetration.SelfPenetration(),
    root_residual.RootResidual(),
    balance.Balance(),
    tracking.TRACKING,
    inter_penetration.InterPenetration(),
    contact.Contact(),
    pair_root_residual.PairRootResidual(),
]

#: Per-person metrics in report order.
PERSON_REGISTRY: tuple[Metric, ...] = tuple(m for m in METRICS if m.needs is not Needs.PAIR)
#: Pairwise metrics of a two-person clip, in report order.
PAIR_REGISTRY: tuple[Metric, ...] = tuple(m for m in METRICS if m.needs is Needs.PAIR)
#: The joint-level metrics of the one compiled pass over the keypoints, in report order.
KEYPOINT_REGISTRY: tuple[KeypointMetric, ...] = tuple(
    m for m in METRICS if isinstance(m, KeypointMetric))


def alternatives(registry: Sequence[Metric]) -> dict[str, tuple[Metric, ...]]:
    """Report name -> its metrics in ``registry`` order (the preferred first),
    names in order of first appearance."""
    out: dict[str, tuple[Metric, ...]] = {}
    for m in registry:
        out[m.name] = (*out.get(m.name, ()), m)
    return out


#: Per-person metric names, in report order (stable: part of the JSON contract).
PERSON_METRICS: tuple[str, ...] = tuple(alternatives(PERSON_REGISTRY))
#: Pairwise metric names of a two-person motion.
PAIR_METRICS: tuple[str, ...] = tuple(alternatives(PAIR_REGISTRY))

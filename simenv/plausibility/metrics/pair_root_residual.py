"""Pair root residual: root help the floor and the partner's hands together cannot give.

The pairwise metric (:class:`PairRootResidual`). Its math is
:func:`simenv.plausibility.pair_dynamics.pair_root_residual`, solved once per
pair for this metric and both people's ``root_residual``
(:attr:`simenv.plausibility.metric.PairInputs.partner_explained`). Thresholds:
``root_force_*``, ``pair_contact_gap_m`` and ``grip_force_max_bw`` of
:class:`~simenv.plausibility.body_thresholds.BodyThresholds`. Body weights out.
"""

from __future__ import annotations

from simenv.plausibility.metric import PairInputs, PairMetric, root_force_limits
from simenv.plausibility.timeline import MetricResult


class PairRootResidual(PairMetric):
    """Root help the floor and the partner's hands together cannot give
    (:func:`simenv.plausibility.pair_dynamics.pair_root_residual`).

    Per frame the larger of the two people's partner-explained residual
    forces (body weights; hand-contact forces bounded by
    ``grip_force_max_bw``); value: the larger of their means; passes at <=
    ``root_force_mean_max``; per-frame limit ``root_force_frame_max``.
    """

    name, family, basis, unit = "pair_root_residual", "dynamics", "dynamics", "body weight"
    thresholds = staticmethod(root_force_limits)

    def compute(self, inputs: PairInputs) -> MetricResult:
        return inputs.partner_explained[0]

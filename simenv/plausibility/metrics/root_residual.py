"""Root residual: the help from nowhere a motion needs (inverse dynamics).

The metric (:class:`RootResidual`). Its math is the inverse-dynamics module's
:func:`simenv.plausibility.dynamics.root_residual` (the root wrench no floor
contact explains; :mod:`simenv.plausibility.pair_dynamics` builds the
two-person version on the same wrench), measured where the unassisted
tracker followed (:mod:`simenv.plausibility.metrics.tracking`). Thresholds:
``root_force_*``, ``root_residual_tracked_m`` and the inverse-dynamics
settings of :class:`~simenv.plausibility.body_thresholds.BodyThresholds`.
Body weights out.
"""

from __future__ import annotations

from simenv.plausibility.dynamics import root_residual
from simenv.plausibility.metric import BodyMetric, PersonInputs, fitted_body, root_force_limits
from simenv.plausibility.metrics.tracking import TRACKING
from simenv.plausibility.timeline import MetricResult


class RootResidual(BodyMetric):
    """Help from nowhere: the root force no floor contact explains
    (:func:`simenv.plausibility.dynamics.root_residual`).

    ``mj_inverse`` of the retargeted trajectory gives the root wrench; the best
    friction-cone floor forces (NNLS) explain what they can. Per frame the
    residual force in body weights ``m g``, 0 on the frames the unassisted
    tracker followed (:class:`Tracking`); value: its mean; passes at <=
    ``root_force_mean_max``; per-frame limit ``root_force_frame_max``. Of two
    people, the partner-explained residual (hand contacts may help,
    :func:`simenv.plausibility.pair_dynamics.pair_root_residual`).
    """

    name, family, basis, unit = "root_residual", "dynamics", "dynamics", "body weight"
    thresholds = staticmethod(root_force_limits)

    def compute(self, inputs: PersonInputs) -> MetricResult:
        if inputs.pair is not None:
            return inputs.pair.partner_explained[1][inputs.person]
        # Measured by the unassisted controller where it ran (no help on the frames it
        # followed), inferred elsewhere.
        free = inputs.measure(TRACKING)
        tracked = free.timeline if free.available and not inputs.config.tracking_assist \
            else None
        return root_residual(fitted_body(inputs), inputs.config.body, tracked_error=tracked,
                             poses=inputs.poses)

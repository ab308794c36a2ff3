"""Physics tracking: can a simulated body perform the motion?

The metric (:class:`Tracking`, the instance :data:`TRACKING`, which
:mod:`simenv.plausibility.metrics.root_residual` also reads). Its math is the
tracker, :func:`simenv.plausibility.tracking.tracking` (the controllers in
:mod:`simenv.control`); this module chooses the runs the scorer asks for and
puts the other runs' outcomes in the details. Thresholds: ``tracking_*`` and
``assist_timeconst_s`` of
:class:`~simenv.plausibility.body_thresholds.BodyThresholds`. Metres out.
"""

from __future__ import annotations

from dataclasses import replace
from operator import attrgetter

from simenv.plausibility.metric import BodyMetric, PersonInputs, fitted_body, not_available
from simenv.plausibility.timeline import MetricResult
from simenv.plausibility.tracking import tracking


class Tracking(BodyMetric):
    """Can a simulated body perform the motion (:func:`simenv.plausibility.tracking.tracking`)?

    The unassisted controller (``ScoreConfig.tracking_controller``, MPC by
    default; the assisted PD servos with ``tracking_assist``) follows the
    retargeted trajectory in ``mj_step``; per frame the mean keypoint distance
    ``e_t`` (m) between the simulated and the reference body, NaN after a
    failure; value: the largest ``e_t``; passes at <= ``tracking_fail_m``
    (PHC). The other runs' outcomes go in the details (``unassisted_*``,
    ``assisted_*``). Off when ``ScoreConfig.tracking`` is False; needs 2 frames.
    """

    name, family, basis, unit = "tracking", "tracking", "simulation", "m"
    limit = attrgetter("tracking_fail_m")

    def compute(self, inputs: PersonInputs) -> MetricResult:
        config, T = inputs.config, inputs.frames
        if not config.tracking or T < 2:
            why = ("physics tracking disabled in the config" if not config.tracking
                   else f"needs at least 2 frames; the motion has {T}")
            return not_available(self, T, config, why)
        fitted, body = fitted_body(inputs), config.body

        def run(assist: bool) -> MetricResult:
            return tracking(fitted, body, assist=assist, max_seconds=body.tracking_max_seconds,
                            controller="pd" if assist else config.tracking_controller,
                            mpc=config.mpc, progress=config.progress)

        judged = run(config.tracking_assist)
        free = run(False) if config.tracking_assist else judged
        details = {**judged.details,
                   "unassisted_success": free.details["success"],
                   "unassisted_time_to_failure_s": free.details["time_to_failure_s"],
                   "unassisted_mpjpe_mm": free.details["mpjpe_mm"]}
        if not config.tracking_assist and config.tracking_assisted_detail:
            helped = run(True)
            details.update({"assisted_success": helped.details["success"],
                            "assisted_time_to_failure_s": helped.details["time_to_failure_s"],
                            "assisted_mpjpe_mm": helped.details["mpjpe_mm"],
                            "assisted_force_mean": helped.details["assist_force_mean"]})
        return replace(judged, details=details)


#: The registry's tracking metric; the root residual
#: (:mod:`simenv.plausibility.metrics.root_residual`) reads its result from the same inputs.
TRACKING = Tracking()

"""Physics tracking with the learned tracking policy and the planner as its fallback.

:func:`track_policy` is :func:`simenv.plausibility.tracking.track`'s whole-clip run with
:class:`simenv.control.policy.PolicyTracker` in the planner's place
(:func:`~simenv.plausibility.tracking.run_tracker`: the same start state, failure rule,
divergence checks and :class:`~simenv.plausibility.tracking.TrackingResult`, with
``controller="policy"``; ``rollout_steps`` counts the fallback planner's rolled-out steps),
plus how many physics steps the fallback drove. One attempt, one run over at most
``max_seconds``: segments and further seeds are the scorer's and are not wired to the policy
(docs/tracking_speed.md).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from simenv.body.retarget import RetargetResult
from simenv.control.policy import PolicyConfig, PolicyTracker, TrackingPolicy
from simenv.control.reference import TrackingReference
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.dynamics import dynamics_settings
from simenv.plausibility.tracking import TrackingResult, run_tracker


@dataclass(frozen=True)
class PolicyRun:
    """A policy-tracked run: the tracking result and who drove.

    Attributes:
        result: as :func:`simenv.plausibility.tracking.track` returns it.
        policy_steps, fallback_steps: physics steps the policy / the planner drove.
        engagements: times the planner took over.
        cpu_s: CPU seconds of the run (``time.process_time``, this process' threads).
    """

    result: TrackingResult
    policy_steps: int
    fallback_steps: int
    engagements: int
    cpu_s: float

    @property
    def fallback_fraction(self) -> float:
        """Share of the physics steps the planner drove."""
        return self.fallback_steps / max(self.policy_steps + self.fallback_steps, 1)


def track_policy(result: RetargetResult, policy: TrackingPolicy,
                 config: PolicyConfig | None = None,
                 thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS,
                 max_seconds: float | None = None, progress: bool = False) -> PolicyRun:
    """Track ``result.qpos`` unassisted with ``policy`` and the planner as fallback.

    Args:
        result: the retargeted reference trajectory (T >= 2 frames).
        policy: the trained policy (:meth:`TrackingPolicy.load`).
        config: fallback thresholds and planner (default :class:`PolicyConfig`).
        thresholds: failure distance and default length cap, as for ``track``.
        max_seconds: simulate at most this much of the clip.
        progress: show a progress bar over the reference frames.

    Raises:
        PhysicsError: bad qpos (shape, NaN/inf, fewer than 2 frames) or a policy made for
            another feature layout.
    """
    limit = thresholds.tracking_max_seconds if max_seconds is None else max_seconds
    ref = TrackingReference.from_retarget(result, result.humanoid.model,
                                          dynamics_settings(thresholds), limit)
    cpu = time.process_time()
    tracker = PolicyTracker(result.humanoid, ref, policy, config)
    tr = run_tracker(result, ref, tracker.model, tracker, thresholds, "policy",
                     progress=progress)
    return PolicyRun(tr, tracker.policy_steps, tracker.fallback_steps, tracker.engagements,
                     time.process_time() - cpu)


__all__ = ["PolicyRun", "track_policy"]

"""Physics tracking with the learned tracking policy and the planner as its fallback.

:func:`track_policy` is :func:`simenv.plausibility.tracking.track`'s whole-clip run with
:class:`simenv.control.policy.PolicyTracker` in the planner's place: the same simulation,
failure rule (body error above ``tracking_fail_m``), divergence checks and
:class:`~simenv.plausibility.tracking.TrackingResult` (``controller="policy"``;
``rollout_steps`` counts the fallback planner's rolled-out steps), plus how many physics
steps the fallback drove. One attempt, one run over at most ``max_seconds``: segments and
further seeds are the scorer's and are not wired to the policy (docs/tracking_speed.md).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from simenv.body.retarget import RetargetResult
from simenv.control.policy import PolicyConfig, PolicyTracker, TrackingPolicy
from simenv.control.reference import TrackingReference
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.dynamics import dynamics_settings
from simenv.plausibility.tracking import TrackingResult, _accel_error, _simulate


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
    h = result.humanoid
    limit = thresholds.tracking_max_seconds if max_seconds is None else max_seconds
    ref = TrackingReference.from_retarget(result, h.model, dynamics_settings(thresholds), limit)
    cpu, wall = time.process_time(), time.perf_counter()
    tracker = PolicyTracker(h, ref, policy, config)
    n_frames, fps = ref.n_frames, ref.fps
    bar = tqdm(total=n_frames - 1, desc=f"track {result.name} (policy)", unit="frame",
               disable=not progress)
    try:
        run = _simulate(result, ref, tracker.model, tracker, thresholds, False, bar)
    finally:
        bar.close()
        tracker.close()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    ok = run.failed_at is None
    tracked = n_frames if ok else run.failed_at + (0 if run.error else 1)
    full = np.full((len(result.qpos), len(h.site_ids), 3), np.nan)
    full[:n_frames] = run.kp_sim
    tr = TrackingResult(
        success=ok, frames_tracked=int(tracked),
        time_to_failure_s=(n_frames - 1) / fps if ok else run.failed_at / fps,
        simulated_s=(n_frames - 1) / fps, body_error=run.body_err,
        mpjpe_mm=float(np.nanmean(run.body_err[:tracked]) * 1000.0),
        accel_error=_accel_error(run.kp_sim[:tracked], ref.frame_keypoints),
        assisted=False, assist_force=run.assist_f, error=run.error, steps=run.steps,
        wall_s=wall, sim_keypoints=full, controller="policy", work_j=run.work,
        work_j_per_kg=run.work / h.total_mass, retries=run.retries, work_curve=run.work_at,
        segments_failed=int(not ok), rollout_steps=tracker.rollout_steps)
    return PolicyRun(tr, tracker.policy_steps, tracker.fallback_steps, tracker.engagements, cpu)


__all__ = ["PolicyRun", "track_policy"]

"""Physics tracking with the learned tracking policy and the planner as its fallback.

:func:`track_policy` is :func:`simenv.plausibility.tracking.track`'s whole-clip run with
:class:`simenv.control.policy.PolicyTracker` in the planner's place: the same start state,
failure rule (body error above ``tracking_fail_m`` at a reference frame), divergence checks
(:func:`simenv.body.divergence.physics_problem`) and
:class:`~simenv.plausibility.tracking.TrackingResult` (``controller="policy"``;
``rollout_steps`` counts the fallback planner's rolled-out steps), plus how many physics
steps the fallback drove. One attempt, one run over at most ``max_seconds``, no rewinds:
segments, further seeds and retries are the scorer's and are not wired to the policy
(docs/tracking_speed.md). The loop is :mod:`~simenv.plausibility.tracking`'s, written
again here because its simulation is private to that module.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import mujoco
import numpy as np
from tqdm import tqdm

from simenv.body.divergence import physics_problem, warning_counts
from simenv.body.retarget import RetargetResult
from simenv.control.policy import PolicyConfig, PolicyTracker, TrackingPolicy
from simenv.control.reference import TrackingReference
from simenv.core.errors import PhysicsError
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.dynamics import dynamics_settings
from simenv.plausibility.tracking import TrackingResult


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


@dataclass
class _Run:
    """What the simulation recorded, per reference frame (NaN after the stop)."""

    kp_sim: np.ndarray
    body_err: np.ndarray
    work_at: np.ndarray
    error: str | None = None
    failed_at: int | None = None
    steps: int = 0
    work: float = 0.0


def _simulate(result: RetargetResult, ref: TrackingReference, tracker: PolicyTracker,
              fail_m: float, bar: tqdm) -> _Run:
    """Drive the body from the reference's first state over frames 1 .. n_frames - 1,
    stopping at a divergence or once the body error at a frame exceeds ``fail_m``."""
    h, model = result.humanoid, tracker.model
    data = mujoco.MjData(model)
    warnings_at_start = warning_counts(data)
    tracker.reset(data)
    run = _Run(np.full((ref.n_frames, len(h.site_ids), 3), np.nan),
               np.full(len(result.qpos), np.nan), np.full(len(result.qpos), np.nan))
    run.kp_sim[0] = data.site_xpos[h.site_ids]
    run.body_err[0] = np.linalg.norm(run.kp_sim[0] - ref.frame_keypoints[0], axis=-1).mean()
    run.work_at[0] = 0.0
    for k in range(1, ref.n_frames):
        for s in range(ref.frame_step[k - 1], ref.frame_step[k]):
            data.ctrl[:] = tracker.control(data, s)
            mujoco.mj_step(model, data)
            p = data.actuator_force * data.actuator_velocity  # braking is not credited
            run.work += float(p[p > 0].sum()) * ref.dt
            run.steps += 1
        reason = physics_problem(model, data, warnings_at_start)
        if reason is not None:
            run.error = str(PhysicsError(f"tracking simulation diverged: {reason}", frame=k,
                                         source=result.name))
            run.failed_at = k
            break
        run.kp_sim[k] = data.site_xpos[h.site_ids]
        run.body_err[k] = np.linalg.norm(run.kp_sim[k] - ref.frame_keypoints[k], axis=-1).mean()
        run.work_at[k] = run.work
        bar.update(1)
        if run.body_err[k] > fail_m:
            run.failed_at = k
            break
    return run


def _accel_error(sim_pos: np.ndarray, ref_kp: np.ndarray) -> float:
    """Mean keypoint acceleration error (second differences), mm/frame^2, of the tracked
    frames ``sim_pos`` (N, K, 3) against the reference's first N; NaN below 3 frames."""
    n = len(sim_pos)
    if n < 3:
        return float("nan")
    acc_s = sim_pos[2:] - 2 * sim_pos[1:-1] + sim_pos[:-2]
    acc_r = ref_kp[2:n] - 2 * ref_kp[1:n - 1] + ref_kp[:n - 2]
    return float(np.linalg.norm(acc_s - acc_r, axis=-1).mean() * 1000.0)


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
        run = _simulate(result, ref, tracker, thresholds.tracking_fail_m, bar)
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
        assisted=False, assist_force=np.where(np.isfinite(run.body_err), 0.0, np.nan),
        error=run.error, steps=run.steps,
        wall_s=wall, sim_keypoints=full, controller="policy", work_j=run.work,
        work_j_per_kg=run.work / h.total_mass, work_curve=run.work_at,
        segments_failed=int(not ok), rollout_steps=tracker.rollout_steps)
    return PolicyRun(tr, tracker.policy_steps, tracker.fallback_steps, tracker.engagements, cpu)


__all__ = ["PolicyRun", "track_policy"]

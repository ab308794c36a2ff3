"""Physics tracking: can a simulated body perform the retargeted motion?

The humanoid's own position actuators (one PD servo per hinge, torque
``kp (q_ref - q) - kv qd`` with the gains and force limits of
:data:`simenv.body.humanoid.JOINTS`) follow the retargeted hinge angles in forward
simulation (``mj_step``, the model's 2 ms implicit-fast integrator), starting
from the first reference pose and velocity. No learning, no feed-forward
torques: this is the baseline a learned tracker (PHC, ProtoMotions) improves
on. The root is free, so the body must balance with its feet alone, or
optionally (``assist=True``) a soft weld to a mocap body that follows the
reference root ("hand of god") pulls it along, and the weld's force is
measured. Caveat, measured: MuJoCo's constraints are soft, so a static load
is shared between the weld and the floor contacts by their compliance (a
body standing still in its rest pose puts ~0.5 body weight on the weld); the
assisted force therefore compares clips, it is not the minimal help -- that
is :func:`simenv.plausibility.dynamics.root_residual`.

Per reference frame the simulated keypoints (the body's keypoint sites) are
compared with the reference body's keypoints:

* body error ``e_t = mean_k |x_sim,k(t) - x_ref,k(t)|`` (metres);
* failure (PHC, Luo et al. 2023): the first frame with ``e_t > 0.5 m``; the
  simulation stops there and ``time_to_failure_s`` is its time (an MPC allowed
  ``retries`` first rewinds to a state the body reached itself and tries again);
* global MPJPE: mean of ``e_t`` over the tracked frames, millimetres;
* acceleration error (PHC's "Acc"): mean over tracked frames and keypoints of
  ``|a_sim - a_ref|`` with ``a`` the second difference of keypoint positions,
  mm/frame^2.

Blow-ups never raise: a non-finite state, an acceleration beyond
:data:`simenv.body.divergence.MAX_QACC` or a MuJoCo warning (bad qacc, constraint arena overflow)
stops the simulation, marks the result failed and records a
:class:`~simenv.core.errors.PhysicsError` message naming the frame.

Long clips are judged in segments (``BodyThresholds.tracking_segment_s``, 4 s by
default; infinity for one run): each segment of the clip is a run of its own, simulated
from the captured state ``tracking_lead_s`` before it, and the clip is tracked when every
segment is. A whole-clip run asks the controller to hold a 20 s clip without drifting;
on the 23 s CMU 01_01 the MPC falls at 9.0 s, yet every 3 s stretch from 6 to 11.5 s is
tracked from the captured state (measured). Segments ask less than a whole run -- the
body is put back on the capture at each run-up -- and they say so in the details
(``segments``). A run-up that
falls (a capture glitch met at speed) is not judged: the segment is simulated again from
the frame before its judged ones.

The MPC is a stochastic search: :class:`~simenv.control.MPCConfig` ``attempts`` gives a run
(each segment) further tries with other planner seeds, planning further ahead
(``retry_horizon_s``), and the first that tracks is kept.
A tracked run is a trajectory the body performed with its own actuators, so one success
shows the motion can be done; a failure only shows that this seed found no way.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, replace
from typing import Any, Protocol

import mujoco
import numpy as np
from tqdm import tqdm

from simenv.body.divergence import physics_problem, warning_counts
from simenv.body.humanoid import Humanoid
from simenv.body.retarget import RetargetResult
from simenv.control.mpc import MPCConfig, TrackingMPC
from simenv.control.reference import TrackingReference, step_interpolator
from simenv.core.errors import PhysicsError
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.clips import norm3
from simenv.plausibility.dynamics import dynamics_settings
from simenv.plausibility.timeline import MetricResult

#: The tracking controllers :func:`track` runs.
CONTROLLERS: tuple[str, ...] = ("pd", "mpc")


@dataclass(frozen=True)
class TrackingResult:
    """Outcome of one tracking simulation.

    Attributes:
        success: the body error stayed within the failure distance over the
            whole simulated stretch and nothing diverged.
        frames_tracked: reference frames reached before stopping (a segmented run:
            judged frames its segments tracked).
        time_to_failure_s: time of the failing frame, or the simulated
            duration on success.
        simulated_s: duration of the reference stretch attempted.
        body_error: (T,) metres per reference frame, NaN after the stop.
        mpjpe_mm: mean body error over the tracked frames, mm.
        accel_error: mean keypoint acceleration error, mm/frame^2 (NaN below
            3 tracked frames).
        assisted: whether the root assistance was on.
        assist_force: (T,) root assistance force per frame as a fraction of
            body weight (zeros without assistance), NaN after the stop.
        error: PhysicsError message when the simulation diverged, else None.
        steps: simulator steps taken. wall_s: wall time, seconds.
        sim_keypoints: (T, K, 3) simulated keypoints, NaN after the stop.
        controller: ``"pd"`` or ``"mpc"``.
        work_j: positive mechanical work of the hinge actuators over the
            simulated stretch, ``sum_t sum_i max(tau_i qd_i, 0) dt``, joules.
        work_j_per_kg: ``work_j`` per kilogram of body mass.
        retries: rewinds the run used (MPC ``retries``; the discarded attempts
            count in ``steps`` and ``wall_s``, not in the work).
        work_curve: (T,) positive work done up to each reference frame, J, NaN after
            the stop (a segmented run: over the judged frames only).
        segments: runs the clip was judged in (1: the whole clip in one run).
        segments_failed: how many of them failed.
        runs: simulations made: every attempt (MPC ``attempts``) of the clip or of each
            segment, and each segment simulated again without its run-up; ``steps`` and
            ``wall_s`` count them all.
        rollout_steps: planning-model steps the MPC rolled out over all of them (0 for
            the PD servos): its cost in simulator steps, whatever the machine's load.
    """

    success: bool
    frames_tracked: int
    time_to_failure_s: float
    simulated_s: float
    body_error: np.ndarray
    mpjpe_mm: float
    accel_error: float
    assisted: bool
    assist_force: np.ndarray
    error: str | None
    steps: int
    wall_s: float
    sim_keypoints: np.ndarray
    controller: str = "pd"
    work_j: float = 0.0
    work_j_per_kg: float = 0.0
    retries: int = 0
    work_curve: np.ndarray | None = None
    segments: int = 1
    segments_failed: int = 0
    runs: int = 1
    rollout_steps: int = 0


def assisted_model(h: Humanoid, thresholds: BodyThresholds) -> mujoco.MjModel:
    """The humanoid plus a mocap body welded to the pelvis by a soft
    equality constraint (MuJoCo's implicit, stable "hand of god"): moving the
    mocap body along the reference root pulls the body along, and the weld's
    constraint force is the help. Time constant ``assist_timeconst_s``,
    critically damped."""
    spec = h.spec.copy()
    target = spec.worldbody.add_body()
    target.name = "assist_target"
    target.mocap = True
    target.pos = [0.0, 0.0, h.dims.hip_height]
    weld = spec.add_equality()
    weld.type = mujoco.mjtEq.mjEQ_WELD
    weld.objtype = mujoco.mjtObj.mjOBJ_BODY
    weld.name1, weld.name2 = "assist_target", "pelvis"
    weld.data[:11] = [0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1]
    weld.solref = [thresholds.assist_timeconst_s, 1.0]
    return spec.compile()


def _work(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Positive mechanical power of the actuators at this step, watts:
    ``sum_i max(tau_i qd_i, 0)`` (negative work, braking, is not credited)."""
    p = data.actuator_force * data.actuator_velocity
    return float(p[p > 0].sum())


class Tracker(Protocol):
    """What drives the simulated body in a tracking run: :class:`simenv.control.TrackingMPC`,
    or anything with its interface (:class:`simenv.control.policy.PolicyTracker`).

    ``config.retries`` / ``config.rewind_s`` say whether and how far a failed run rewinds
    (to states the body reached itself, with the plan taken by ``snapshot`` then)."""

    config: MPCConfig

    @property
    def rollout_steps(self) -> int:
        """Planning-model steps rolled out so far."""

    def control(self, data: mujoco.MjData, step: int) -> np.ndarray:
        """(nu,) servo targets for physics step ``step``."""

    def snapshot(self) -> Any:
        """The tracker's state, for :meth:`restore`."""

    def restore(self, snapshot: Any) -> None:
        """Go back to a state taken by :meth:`snapshot`."""

    def close(self) -> None:
        """Release the tracker's threads."""


def _controller(result: RetargetResult, thresholds: BodyThresholds, assist: bool,
                max_seconds: float | None, controller: str, mpc: MPCConfig | None
                ) -> tuple[TrackingReference, TrackingMPC | None, mujoco.MjModel]:
    """The reference per physics step, the planner (None for the PD servos) and
    the simulated model (with the assistance weld when ``assist``)."""
    if controller not in CONTROLLERS:
        raise PhysicsError(f"unknown controller {controller!r}; expected one of {CONTROLLERS}",
                           field="controller")
    if assist and controller != "pd":
        raise PhysicsError("root assistance is a PD-tracker option; the MPC is never assisted",
                           field="assist")
    h = result.humanoid
    settings = dynamics_settings(thresholds)
    limit = thresholds.tracking_max_seconds if max_seconds is None else max_seconds
    if controller == "mpc":
        ref = TrackingReference.from_retarget(result, h.model, settings, limit)
        planner = TrackingMPC(h, ref, mpc)
        return ref, planner, planner.model
    model = assisted_model(h, thresholds) if assist else copy.deepcopy(h.model)
    ref = TrackingReference.from_retarget(result, model, settings, limit, feedforward=False)
    return ref, None, model


def _mocap_path(result: RetargetResult, ref: TrackingReference
                ) -> tuple[np.ndarray, np.ndarray]:
    """Where the assistance's mocap target goes: (n_steps + 1, 3) positions per
    physics step, the reference root interpolated like the servo targets, and
    (T, 4) the root orientation per frame."""
    interp = step_interpolator(ref.frame_step, ref.fps, ref.dt)
    return interp(result.qpos[:ref.n_frames, :3]), result.qpos[:, 3:7]


def _advance(model: mujoco.MjModel, data: mujoco.MjData, ref: TrackingReference,
             planner: Tracker | None, k: int,
             mocap: tuple[np.ndarray, np.ndarray] | None, work: float) -> tuple[float, float]:
    """Step the physics from reference frame ``k - 1`` to ``k``.

    Returns:
        the mean assistance force over the steps (N; 0 without ``mocap``) and
        ``work`` plus the actuators' positive work over them (J).
    """
    force_sum, n_sub = 0.0, 0
    if mocap is not None:
        data.mocap_quat[0] = mocap[1][k]
    for s in range(ref.frame_step[k - 1], ref.frame_step[k]):
        data.ctrl[:] = planner.control(data, s) if planner is not None else ref.ctrl[s]
        if mocap is not None:
            data.mocap_pos[0] = mocap[0][s]
        mujoco.mj_step(model, data)
        work += _work(model, data) * ref.dt
        if mocap is not None:
            # The weld is the model's only equality constraint, and MuJoCo
            # puts equality rows first: rows 0-2 are its translation.
            force_sum += float(np.linalg.norm(data.efc_force[:3]))
            n_sub += 1
    return force_sum / max(n_sub, 1), work


@dataclass
class _Run:
    """What one simulation recorded (see :class:`TrackingResult`)."""

    kp_sim: np.ndarray
    body_err: np.ndarray
    assist_f: np.ndarray
    work_at: np.ndarray
    error: str | None = None
    failed_at: int | None = None
    steps: int = 0
    work: float = 0.0
    retries: int = 0


#: Seconds of reference time between the states a retrying run can rewind to.
CHECKPOINT_S = 0.25
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


@dataclass(frozen=True, eq=False)
class _Checkpoint:
    """A state the simulated body reached itself (after reference frame ``frame``), with
    the plan and the work up to it."""

    frame: int
    state: np.ndarray
    plan: tuple[np.ndarray, int, int]
    work: float


def _rewind(run: _Run, checkpoints: list[_Checkpoint], frame: int, back: int,
            model: mujoco.MjModel, data: mujoco.MjData, planner: Tracker) -> int:
    """Put the body and the plan back to the latest checkpoint at least ``back`` frames
    before ``frame`` (the first one if none is that early); forget what came after.
    Returns the checkpoint's frame."""
    i = max([j for j, c in enumerate(checkpoints) if c.frame <= frame - back], default=0)
    cp = checkpoints[i]
    del checkpoints[i + 1:]
    mujoco.mj_setState(model, data, cp.state, _FULL)
    mujoco.mj_forward(model, data)
    planner.restore(cp.plan)
    run.work, run.error, run.failed_at = cp.work, None, None
    for arr in (run.kp_sim, run.body_err, run.assist_f, run.work_at):
        arr[cp.frame + 1:] = np.nan
    run.retries += 1
    return cp.frame


def _simulate(result: RetargetResult, ref: TrackingReference, model: mujoco.MjModel,
              planner: Tracker | None, thresholds: BodyThresholds, assist: bool,
              bar: tqdm, frame0: int = 0) -> _Run:
    """Run the controller from the first reference state over the reference frames
    1 .. n_frames - 1 (``bar`` counts them; an error names frame ``frame0 + k``, the
    clip's frame when ``result`` is a piece of it from ``frame0``), stopping at a
    divergence or once the body error exceeds ``tracking_fail_m``; an MPC with
    ``retries`` left rewinds instead (:class:`~simenv.control.MPCConfig`): the run is
    then a trajectory the body performed, from states it reached itself."""
    h = result.humanoid
    T = len(result.qpos)
    mocap = _mocap_path(result, ref) if assist else None
    data = mujoco.MjData(model)
    warnings_at_start = warning_counts(data)
    data.qpos[:] = ref.qpos0
    data.qvel[:] = ref.qvel0
    mujoco.mj_forward(model, data)
    # The assistance force is read from the first three constraint rows (see
    # _advance); MuJoCo orders equality constraints first.
    assert not assist or (data.efc_type[:3] == mujoco.mjtConstraint.mjCNSTR_EQUALITY).all()
    weight = h.total_mass * thresholds.gravity_mps2
    run = _Run(np.full((ref.n_frames, len(h.site_ids), 3), np.nan), np.full(T, np.nan),
               np.full(T, np.nan), np.full(T, np.nan))
    run.kp_sim[0] = data.site_xpos[h.site_ids]
    run.body_err[0] = np.linalg.norm(run.kp_sim[0] - ref.frame_keypoints[0], axis=-1).mean()
    run.assist_f[0] = 0.0
    run.work_at[0] = 0.0
    retries = planner.config.retries if planner is not None else 0
    every = max(1, int(round(CHECKPOINT_S * ref.fps)))
    back = int(round(planner.config.rewind_s * ref.fps)) if planner is not None else 0
    checkpoints: list[_Checkpoint] = []
    k = 1
    while k < ref.n_frames:
        if retries and (k - 1) % every == 0:
            state = np.empty(mujoco.mj_stateSize(model, _FULL))
            mujoco.mj_getState(model, data, state, _FULL)
            checkpoints.append(_Checkpoint(k - 1, state, planner.snapshot(), run.work))
        force, run.work = _advance(model, data, ref, planner, k, mocap, run.work)
        run.steps += ref.frame_step[k] - ref.frame_step[k - 1]
        reason = physics_problem(model, data, warnings_at_start)
        if reason is not None:
            run.error = str(PhysicsError(f"tracking simulation diverged: {reason}",
                                         frame=frame0 + k, source=result.name))
            run.failed_at = k
        else:
            run.kp_sim[k] = data.site_xpos[h.site_ids]
            run.body_err[k] = norm3(run.kp_sim[k] - ref.frame_keypoints[k]).mean()
            run.assist_f[k] = force / weight
            run.work_at[k] = run.work
            if run.body_err[k] > thresholds.tracking_fail_m:
                run.failed_at = k
        if run.failed_at is None:
            k += 1
            bar.update(1)
            continue
        if run.retries >= retries or not checkpoints:
            break
        k = _rewind(run, checkpoints, k, back, model, data, planner) + 1
        # A divergence's warnings stay counted in data: judge from here on.
        warnings_at_start = warning_counts(data)
        bar.n = k - 1
        bar.refresh()
    return run


def _accel_error(sim_pos: np.ndarray, ref_kp: np.ndarray) -> float:
    """Mean keypoint acceleration error (second differences), mm/frame^2, of
    the tracked frames ``sim_pos`` (N, K, 3) against the reference's first N;
    NaN below 3 frames."""
    tracked = len(sim_pos)
    if tracked < 3:
        return float("nan")
    acc_s = sim_pos[2:] - 2 * sim_pos[1:-1] + sim_pos[:-2]
    acc_r = ref_kp[2:tracked] - 2 * ref_kp[1:tracked - 1] + ref_kp[:tracked - 2]
    return float(np.linalg.norm(acc_s - acc_r, axis=-1).mean() * 1000.0)


def track(result: RetargetResult, thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS,
          assist: bool = False, max_seconds: float | None = None, controller: str = "pd",
          mpc: MPCConfig | None = None, progress: bool = False) -> TrackingResult:
    """Track ``result.qpos`` in forward simulation (see the module docstring).

    Args:
        result: the retargeted reference trajectory (T >= 2 frames).
        thresholds: failure distance, assistance gain, default length cap, and the
            segments (``tracking_segment_s``, ``tracking_lead_s``; see the module
            docstring).
        assist: add the root assistance spring and measure its force (PD only).
        max_seconds: simulate at most this much of the clip (default
            ``thresholds.tracking_max_seconds``).
        controller: ``"pd"`` (the servos on the reference) or ``"mpc"``
            (:class:`simenv.control.TrackingMPC`, unassisted).
        mpc: the MPC's settings (default :class:`simenv.control.MPCConfig`).
        progress: show a progress bar over the reference frames.

    Raises:
        PhysicsError: bad qpos (shape, NaN/inf, fewer than 2 frames), an unknown
            controller, or ``assist`` with the MPC.
    """
    if not math.isinf(thresholds.tracking_segment_s):
        limit = thresholds.tracking_max_seconds if max_seconds is None else max_seconds
        # Checks the whole clip (frames named as in it) and gives the judged frames' keypoints.
        ref = TrackingReference.from_retarget(result, max_seconds=limit, feedforward=False)
        if ref.n_frames - 1 > thresholds.tracking_segment_s * ref.fps:
            return _track_segments(result, ref, thresholds, assist, controller, mpc, progress)
    runs = ((r, 0, r.frames_tracked) for r in (
        _track_run(result, thresholds, assist, max_seconds, controller, cfg, progress)
        for cfg in _attempt_configs(controller, mpc)))
    return _keep_best(runs)[0]


def _attempt_configs(controller: str, mpc: MPCConfig | None) -> list[MPCConfig | None]:
    """The planner settings of a run's attempts: seeds ``seed .. seed + attempts - 1``, the
    first over ``horizon_s``, the others over ``retry_horizon_s`` (one attempt for the PD
    servos, which draw nothing)."""
    if controller != "mpc":
        return [mpc]
    cfg = mpc or MPCConfig()
    return [cfg.attempt(i) for i in range(cfg.attempts)]


def _keep_best(runs: Iterable[tuple[TrackingResult, int, int]]
               ) -> tuple[TrackingResult, int]:
    """Of ``(run, start frame, judged frames tracked)`` simulated one after another (lazily:
    none after the first success), the first run that tracked, else the one that tracked
    the most judged frames, with its start; ``steps``, ``wall_s``, ``runs`` and
    ``rollout_steps`` are the totals of every run simulated."""
    best: tuple[TrackingResult, int, int] | None = None
    steps, wall, n, rolled = 0, 0.0, 0, 0
    for r, start, judged in runs:
        steps, wall, n = steps + r.steps, wall + r.wall_s, n + r.runs
        rolled += r.rollout_steps
        if best is None or r.success or judged > best[2]:
            best = (r, start, judged)
        if r.success:
            break
    assert best is not None, "a run has at least one attempt"
    return replace(best[0], steps=steps, wall_s=wall, runs=n, rollout_steps=rolled), best[1]


def segment_frames(n_frames: int, fps: float, segment_s: float,
                   lead_s: float) -> list[tuple[int, int, int]]:
    """The segments of a segmented tracking run over reference frames ``0 .. n_frames - 1``.

    Returns:
        ``(start, first, last)`` per segment: simulated from frame ``start``, judged on
        frames ``first .. last``; the judged ranges tile the clip without overlap, and
        ``start = max(0, first - 1 - lead)`` frames (the first segment starts at frame 0
        and is judged from it).
    """
    length = max(1, int(round(segment_s * fps)))
    lead = int(round(lead_s * fps))
    out, a = [], 0
    while a < n_frames - 1:
        b = min(a + length, n_frames - 1)
        out.append((max(0, a - lead), a + 1 if a else 0, b))
        a = b
    return out


def _track_segments(result: RetargetResult, ref: TrackingReference,
                    thresholds: BodyThresholds, assist: bool, controller: str,
                    mpc: MPCConfig | None, progress: bool) -> TrackingResult:
    """:func:`track` in segments (:func:`segment_frames`) of the ``ref.n_frames`` judged
    frames: each a run of its own from the captured state at its start; their judged
    frames put together."""
    h = result.humanoid
    fps, T, n_frames, ref_kp = ref.fps, len(result.qpos), ref.n_frames, ref.frame_keypoints
    err, force = np.full(T, np.nan), np.full(T, np.nan)
    work_curve = np.full(T, np.nan)
    kp = np.full((T, len(h.site_ids), 3), np.nan)
    fails: list[float] = []
    errors: list[str] = []
    steps, wall, work, retries, rolled = 0, 0.0, 0.0, 0, 0
    accel: list[tuple[float, int]] = []
    segments = segment_frames(n_frames, fps, thresholds.tracking_segment_s,
                              thresholds.tracking_lead_s)
    runs = 0
    for lead_start, first, last in tqdm(segments, desc=f"track {result.name} (segments)",
                                        unit="segment", disable=not progress):
        r, start = _keep_best(_segment_runs(result, lead_start, first, last, fps, thresholds,
                                            assist, controller, mpc))
        runs += r.runs
        judged = slice(first - start, last + 1 - start)
        err[first:last + 1] = r.body_error[judged]
        force[first:last + 1] = r.assist_force[judged]
        kp[first:last + 1] = r.sim_keypoints[judged]
        # Work over the judged frames: from the frame before them (the run-up's end).
        curve = r.work_curve[max(first - 1, 0) - start:last + 1 - start]
        work_curve[first:last + 1] = work + curve[-(last + 1 - first):] - curve[0]
        work = float(np.nanmax(work_curve[first:last + 1], initial=work))
        tracked = np.flatnonzero(np.isfinite(err[first:last + 1]))
        if len(tracked) >= 3:
            accel.append((_accel_error(kp[first:first + tracked[-1] + 1],
                                       ref_kp[first:]), len(tracked)))
        if not r.success:
            fails.append(start / fps + r.time_to_failure_s)
            if r.error:
                errors.append(r.error)
        steps, wall, retries = steps + r.steps, wall + r.wall_s, retries + r.retries
        rolled += r.rollout_steps
    simulated = (n_frames - 1) / fps
    return TrackingResult(
        success=not fails,
        frames_tracked=int(np.isfinite(err[:n_frames]).sum()),
        time_to_failure_s=min(fails, default=simulated),
        simulated_s=simulated,
        body_error=err,
        mpjpe_mm=float(np.nanmean(err[:n_frames]) * 1000.0),
        accel_error=(float(np.average([a for a, _ in accel], weights=[w for _, w in accel]))
                     if accel else float("nan")),
        assisted=assist,
        assist_force=force,
        error=errors[0] if errors else None,
        steps=steps,
        wall_s=wall,
        sim_keypoints=kp,
        controller=controller,
        work_j=work,
        work_j_per_kg=work / h.total_mass,
        retries=retries,
        work_curve=work_curve,
        segments=len(segments),
        segments_failed=len(fails),
        runs=runs,
        rollout_steps=rolled,
    )


def _segment_runs(result: RetargetResult, start: int, first: int, last: int, fps: float,
                  thresholds: BodyThresholds, assist: bool, controller: str,
                  mpc: MPCConfig | None) -> Iterator[tuple[TrackingResult, int, int]]:
    """The attempts at the segment judged on frames ``first .. last``: ``(run, start frame,
    judged frames tracked)``, each simulated from ``start``; an attempt that falls in its
    run-up is simulated again from frame ``first - 1``."""
    for cfg in _attempt_configs(controller, mpc):
        for s in dict.fromkeys((start, max(first - 1, 0))):
            piece = replace(result, qpos=result.qpos[s:last + 1],
                            residuals=result.residuals[s:last + 1],
                            targets=result.targets[s:last + 1])
            r = _track_run(piece, thresholds, assist, (last - s + 0.5) / fps, controller,
                           cfg, False, frame0=s)
            judged = r.frames_tracked - (first - s)
            yield r, s, judged
            if judged > 0:
                break


def _track_run(result: RetargetResult, thresholds: BodyThresholds, assist: bool,
               max_seconds: float | None, controller: str, mpc: MPCConfig | None,
               progress: bool, frame0: int = 0) -> TrackingResult:
    """One simulation from ``result``'s first frame (:func:`track`'s whole-clip run; a
    segment's, whose first frame is the clip's ``frame0``)."""
    ref, planner, model = _controller(result, thresholds, assist, max_seconds, controller, mpc)
    return run_tracker(result, ref, model, planner, thresholds, controller, assist=assist,
                       progress=progress, frame0=frame0)


def run_tracker(result: RetargetResult, ref: TrackingReference, model: mujoco.MjModel,
                tracker: Tracker | None, thresholds: BodyThresholds, name: str, *,
                assist: bool = False, progress: bool = False, frame0: int = 0
                ) -> TrackingResult:
    """One simulation of ``ref`` from its first state, driven by ``tracker`` (None: the PD
    servos on the reference targets), judged as :func:`track` judges; closes ``tracker``.

    Args:
        result: the retargeted clip ``ref`` was made from (its humanoid, name, frames).
        ref: the reference per physics step.
        model: the simulated model (``tracker.model`` for a planner; the assisted model
            with ``assist``).
        tracker: what drives the body (:class:`Tracker`).
        thresholds: failure distance and gravity.
        name: the result's ``controller`` field and the progress bar's label.
        assist: measure the root assistance (``model`` has its weld; PD only).
        progress: show a progress bar over the reference frames.
        frame0: the clip's frame ``result``'s first frame is (errors name clip frames).
    """
    h = result.humanoid
    fps, n_frames = ref.fps, ref.n_frames
    wall = time.perf_counter()
    bar = tqdm(total=n_frames - 1, desc=f"track {result.name} ({name})",
               unit="frame", disable=not progress)
    try:
        run = _simulate(result, ref, model, tracker, thresholds, assist, bar, frame0)
    finally:
        bar.close()
        if tracker is not None:
            tracker.close()
    wall = time.perf_counter() - wall
    rolled = tracker.rollout_steps if tracker is not None else 0
    failed_at = run.failed_at
    tracked = n_frames if failed_at is None else failed_at + (0 if run.error else 1)
    ok = failed_at is None
    full = np.full((len(result.qpos), len(h.site_ids), 3), np.nan)
    full[:n_frames] = run.kp_sim
    return TrackingResult(
        success=ok,
        frames_tracked=int(tracked),
        time_to_failure_s=(n_frames - 1) / fps if ok else failed_at / fps,
        simulated_s=(n_frames - 1) / fps,
        body_error=run.body_err,
        mpjpe_mm=float(np.nanmean(run.body_err[:tracked]) * 1000.0),
        accel_error=_accel_error(run.kp_sim[:tracked], ref.frame_keypoints),
        assisted=assist,
        assist_force=run.assist_f,
        error=run.error,
        steps=run.steps,
        wall_s=wall,
        sim_keypoints=full,
        controller=name,
        work_j=run.work,
        work_j_per_kg=run.work / h.total_mass,
        retries=run.retries,
        work_curve=run.work_at,
        segments_failed=int(not ok),
        rollout_steps=rolled,
    )


def tracking(result: RetargetResult, thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS,
             assist: bool = False, max_seconds: float | None = None, controller: str = "pd",
             mpc: MPCConfig | None = None, progress: bool = False) -> MetricResult:
    """Physics tracking as a metric (:func:`track`, same arguments).

    Timeline: body error per frame (m), NaN after the simulation stopped.
    Value: the largest body error reached (inf when the simulation
    diverged); passes when at most ``tracking_fail_m`` (PHC's success rule),
    i.e. the body tracked the whole simulated stretch. Details: ``success``
    (0/1), ``time_to_failure_s``, ``tracked_fraction`` (of the simulated
    stretch), ``simulated_s``, ``mpjpe_mm``, ``accel_error_mm_per_frame2``,
    ``assist_force_mean`` (body weights; 0 without assistance), ``diverged``
    (0/1), ``steps_per_s`` (simulator throughput, planning included),
    ``work_j`` and ``work_j_per_kg`` (positive work of the hinge actuators),
    ``mpc`` (1 when the MPC tracked, 0 for the PD servos), ``retries`` (rewinds used),
    ``segments`` and ``segments_failed`` (a whole-clip run: 1, and 1 when it failed),
    ``runs`` (simulations made: attempts and run-up restarts included) and
    ``realtime_ratio`` (wall time per simulated second, every run included).
    """
    tr = track(result, thresholds, assist=assist, max_seconds=max_seconds,
               controller=controller, mpc=mpc, progress=progress)
    value = float("inf") if tr.error else float(np.nanmax(tr.body_error))
    n_sim = int(round(tr.simulated_s * result.fps)) + 1
    sim_s = tr.steps * result.humanoid.model.opt.timestep
    return MetricResult.from_timeline(
        "tracking", tr.body_error, value, "m", thresholds.tracking_fail_m,
        details={"success": float(tr.success), "time_to_failure_s": tr.time_to_failure_s,
                 "tracked_fraction": tr.frames_tracked / n_sim, "simulated_s": tr.simulated_s,
                 "mpjpe_mm": tr.mpjpe_mm, "accel_error_mm_per_frame2": tr.accel_error,
                 "assist_force_mean": float(np.nanmean(tr.assist_force)),
                 "diverged": float(tr.error is not None),
                 "steps_per_s": tr.steps / max(tr.wall_s, 1e-9),
                 "work_j": tr.work_j, "work_j_per_kg": tr.work_j_per_kg,
                 "mpc": float(tr.controller == "mpc"), "retries": float(tr.retries),
                 "segments": float(tr.segments), "segments_failed": float(tr.segments_failed),
                 "runs": float(tr.runs),
                 "realtime_ratio": tr.wall_s / sim_s if sim_s > 0 else float("nan")},
    )

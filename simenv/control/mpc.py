"""Sampling-based model-predictive tracking of a retargeted clip.

The controller drives only the humanoid's hinge servos (``data.ctrl``); no
force or torque ever acts on the free root, no equality constraint is added:
the body balances on its own feet. Every ``replan_steps`` physics steps it

1. reads the current full physics state ``x`` (``mj_getState``);
2. draws N knot-offset samples around the nominal (:class:`~simenv.control.sampling.Sampler`);
3. rolls each out for the horizon's H planning steps with ``mujoco.rollout``
   (threads), the servo targets being

       u_i(j) = u*(s + f j) + delta_i(j),

   ``u*`` the reference PD targets with velocity feed-through
   (:class:`~simenv.control.reference.TrackingReference`), ``s`` the current
   step, ``f`` the planning model's ``timestep_factor`` and ``delta_i`` the
   sample's spline (:class:`~simenv.control.sampling.Spline`);
4. scores the rollouts (:class:`~simenv.control.costs.TrackingCost`) and
   takes their MPPI average (or the cheapest) as the new nominal, which is
   applied until the next replan and then shifted forward in time to
   warm-start it. The carried-over nominal acts as the integral term a PD
   lacks: the stance-leg offsets that hold the body weight persist from plan
   to plan.

Costs: N H f physics steps per replan, i.e. ``N H / replan_steps`` rolled-out
steps per simulated step (MuJoCo MPC's predictive sampling; Howell et al.
2022); :attr:`TrackingMPC.rollout_steps` counts them. The rollouts are 98 % of
the time (docs/tracking_speed.md). Deterministic for a seed: the rollouts are
independent of the thread that runs them, and the noise comes from one seeded
generator.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import mujoco
import numpy as np
from mujoco import rollout

from simenv.body.humanoid import Humanoid
from simenv.control.costs import CostWeights, TrackingCost
from simenv.control.feedback import FeedbackLaw
from simenv.control.model import SensorLayout, planning_model
from simenv.control.reference import TrackingReference, actuated_indices
from simenv.control.sampling import Sampler, Spline
from simenv.core.errors import PhysicsError

_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


@dataclass(frozen=True)
class MPCConfig:
    """Settings of :class:`TrackingMPC`.

    Attributes:
        horizon_s: planning horizon, seconds.
        n_knots: spline knots over the horizon.
        n_samples: rollouts per replan, the nominal included. 128 by default: on the
            first 4 s of the 20 non-acrobatic CMU clips of the corpus (one attempt, seed 0)
            it tracks 19 at 45 mm mean body error (median 41) against 64 samples' 18 at
            52 mm, closer on 15 of the 18 both track, at twice the cost (16-22x real time on
            2 threads; docs/plausibility.md).
        replan_steps: physics steps between replans.
        noise_rad: knot noise standard deviation, radians (per actuator times
            the ``noise_scaling`` factor).
        noise_scaling: scale each actuator's noise by its gain relative to the
            strongest one, ``(kp / kp_max) ** noise_scaling`` (0: uniform).
        sampled_parts: body parts (:data:`simenv.body.humanoid.JOINTS` keys) whose
            hinges get sampled offsets; the others follow the reference
            servo targets. Empty: every hinge.
        limit_rad: largest knot offset, radians.
        temperature: 0 = predictive sampling (keep the best), > 0 = MPPI, the
            weighted mean of the samples (:class:`~simenv.control.sampling.Sampler`).
            0.1 by default: on the first 4 s of the 20 non-acrobatic CMU clips of
            the corpus (64 samples, seed 0) it tracks 18 as keeping the best did,
            at 52 mm mean body error against 88 (walk 12_01: 131 -> 39 mm);
            chosen on six of them among 0.03 / 0.1 / 0.3 (0.3 fell on three of six,
            0.03 on one, both with larger errors).
        constant_fraction: share of the samples offset by the same amount on
            every knot (:class:`~simenv.control.sampling.Sampler`).
        antithetic: draw the knot noise in mirrored pairs ``+eps``, ``-eps``
            (:class:`~simenv.control.sampling.Sampler`): the MPPI average of a pair whose
            costs are alike stays on the nominal, so the update is less noisy for as many
            samples.
        timestep_factor: planning timestep as a multiple of the physics step.
        gain_scale: servo stiffness and damping (kp, kv) relative to the
            humanoid's; the force limits stay the humanoid's.
        feedforward: fraction of the reference's feed-forward torques added
            to the servo targets (as ``tau_ff / kp``).
        cost_stride: evaluate the cost every this many planning steps.
        nthread: rollout threads.
        seed: noise seed.
        weights: cost weights.
        retries: times a tracking run may rewind after a failure
            (:func:`simenv.plausibility.tracking.track`): the body goes back to a
            state it reached itself ``rewind_s`` earlier and the planner, its noise
            generator moved on, tries again. 0: a failure ends the run.
        rewind_s: how far back a retry starts, seconds of reference time.
        attempts: independent tries a tracking run (each segment of a segmented one)
            gets, with the seeds ``seed, seed + 1, ...``; the first that tracks is kept,
            else the one that got furthest. A tracked run is a trajectory the body
            performed on its own, whichever seed found it; a failed one only says that
            this seed's search found none.
        retry_horizon_s: planning horizon of the attempts after the first, seconds (None:
            ``horizon_s``). A longer look-ahead prices a fall the short one does not see
            coming, at ``retry_horizon_s / horizon_s`` times the cost, paid only where the
            first attempt failed. 0.6 by default: the two real dances the calibration's
            3 seeds failed at 0.45 s (the 05_02 one-leg balance at 7-8.7 s, the salsa 61_05
            follower's spins at 7-12 s) are tracked at 0.6 s with every seed tried (2 and 3;
            at 0.45 s neither 128 samples, finer noise nor the arms among the sampled parts
            tracked them; docs/plausibility.md).
        feedback: between replans, correct the sampled actuators' servo targets with
            time-varying LQR gains about the nominal's predicted states
            (:class:`~simenv.control.feedback.FeedbackLaw`); off by default.
        feedback_r: the feedback's control weight, per rad^2 of servo-target offset per
            planning step, against the planner's cost weights.
        feedback_knots: linearisations of the planning model per replan, spread over the
            horizon (1: one, about the replan's state); None: one per planning step. Fewer
            than one per step is cheaper but unreliable: on walk 02_01 one, three or twelve
            of FAST's 56 steps made the body drift further from the plan than no feedback
            did in some of four pushes (tests/test_control_feedback.py, docs/tracking_speed.md).
        screen_fraction: roll every sample over this fraction of the horizon only, and the
            cheaper half of them (by the cost of that part) on to its end from where they
            stopped; the other half never wins (:meth:`TrackingMPC.plan`). Rolled-out steps
            ``N H (f + (1 - f) / 2)``: a third saves a third. None: every sample rolls the
            whole horizon.
    """

    horizon_s: float = 0.45
    n_knots: int = 4
    n_samples: int = 128
    replan_steps: int = 10
    noise_rad: float = 0.2
    noise_scaling: float = 0.0
    sampled_parts: tuple[str, ...] = ("lumbar", "thigh", "shin", "foot", "toes")
    limit_rad: float = 0.8
    temperature: float = 0.1
    constant_fraction: float = 0.5
    antithetic: bool = False
    timestep_factor: int = 2
    gain_scale: float = 1.0
    feedforward: float = 1.0
    cost_stride: int = 5
    nthread: int = 2
    seed: int = 0
    weights: CostWeights = field(default_factory=CostWeights)
    retries: int = 0
    rewind_s: float = 1.0
    attempts: int = 1
    retry_horizon_s: float | None = 0.6
    feedback: bool = False
    feedback_r: float = 1e-2
    feedback_knots: int | None = None
    screen_fraction: float | None = None

    def __post_init__(self) -> None:
        checks = {
            "horizon_s": self.horizon_s > 0, "n_knots": self.n_knots >= 2,
            "n_samples": self.n_samples >= 2, "replan_steps": self.replan_steps >= 1,
            "noise_rad": self.noise_rad >= 0, "limit_rad": self.limit_rad > 0,
            "temperature": self.temperature >= 0, "timestep_factor": self.timestep_factor >= 1,
            "cost_stride": self.cost_stride >= 1, "nthread": self.nthread >= 1,
            "retries": self.retries >= 0, "rewind_s": self.rewind_s > 0,
            "attempts": self.attempts >= 1,
            "retry_horizon_s": self.retry_horizon_s is None or self.retry_horizon_s > 0,
            "feedback_r": self.feedback_r > 0,
            "feedback_knots": self.feedback_knots is None or self.feedback_knots >= 1,
            "screen_fraction": self.screen_fraction is None or 0 < self.screen_fraction < 1,
        }
        for name, ok in checks.items():
            if not ok:
                raise PhysicsError(f"MPCConfig.{name} out of range: {getattr(self, name)!r}",
                                   field=name)

    def attempt(self, i: int) -> MPCConfig:
        """The settings of a tracking run's attempt ``i`` (0-based): seed ``seed + i``, and
        from the second attempt on the horizon ``retry_horizon_s``."""
        horizon = (self.retry_horizon_s or self.horizon_s) if i else self.horizon_s
        return replace(self, seed=self.seed + i, horizon_s=horizon)


#: A planner a quarter of the default's cost (issue 35): 64 samples instead of 128, drawn
#: in mirrored pairs (``antithetic``), rolled out with an 8 ms planning step instead of 4 ms
#: (``timestep_factor=4``), i.e. 358 rolled-out steps per simulated step against 1434.
#: 3.2-3.9x faster than the default side by side (walk 02_01 on 2 threads, load 2.5: 3.9x
#: real time against 14.6x). Not the default: on the 20 clean CMU clips
#: (first 4 s, 3 attempts) it tracks 20 of 20 but at 56.8 mm mean body error against the
#: default's 44.7 mm (runs and leaps up to twice as far), and it follows the walk's 50 cm float
#: that the default fails (docs/tracking_speed.md).
FAST = MPCConfig(n_samples=64, timestep_factor=4, antithetic=True)


def fast_planner(like: MPCConfig) -> MPCConfig:
    """:data:`FAST`'s search (samples, planning step, mirrored noise) with ``like``'s seed,
    attempts, retry horizon and threads: the same run, searched a quarter as hard."""
    return replace(FAST, seed=like.seed, attempts=like.attempts,
                   retry_horizon_s=like.retry_horizon_s, nthread=like.nthread)


class TrackingMPC:
    """The sampling-based (MPPI) tracking controller (module docstring).

    Args:
        humanoid: the simulated body (its spec is copied for the planning model).
        reference: the clip resampled to the humanoid's timestep.
        config: planner settings.

    Attributes (besides the settings): ``replans`` of the current plan and
    ``rollout_steps``, the planning-model steps rolled out since construction (N x H per
    replan; neither :meth:`reset` nor a rewind takes them back).

    Per-step use::

        mpc = TrackingMPC(h, ref, config)
        model = mpc.model                  # simulate this model (sensors added)
        data = mujoco.MjData(model); mpc.reset(data)
        for s in range(ref.n_steps):
            data.ctrl[:] = mpc.control(data, s)
            mujoco.mj_step(model, data)
        mpc.close()                        # or use it as a context manager
    """

    def __init__(self, humanoid: Humanoid, reference: TrackingReference,
                 config: MPCConfig | None = None) -> None:
        self.config = config = config or MPCConfig()
        self.reference = reference
        self.model, self.layout = planning_model(humanoid, 1, config.gain_scale)
        if config.timestep_factor == 1:
            self.plan_model, plan_layout = self.model, self.layout
        else:
            self.plan_model, plan_layout = planning_model(humanoid, config.timestep_factor,
                                                         config.gain_scale)
        self._check_layout(plan_layout)
        f = config.timestep_factor
        self.horizon = max(2, int(round(config.horizon_s / (reference.dt * f))))
        self.spline = Spline(self.horizon, config.n_knots)
        kp = self.model.actuator_gainprm[:, 0]
        sigma = config.noise_rad * (kp / kp.max()) ** config.noise_scaling
        if config.sampled_parts:
            names = [self.model.actuator(i).name for i in range(self.model.nu)]
            sigma = sigma * np.array([any(part in n for part in config.sampled_parts)
                                      for n in names])
        self.sampler = Sampler(config.n_samples, sigma, config.limit_rad,
                               config.temperature, config.seed, config.constant_fraction,
                               config.antithetic)
        _, hinge_dofs = actuated_indices(self.model)
        qvel_offset = (mujoco.mj_stateSize(self.model, mujoco.mjtState.mjSTATE_TIME)
                       + self.model.nq)
        # A position servo adds kp (u - q): a target offset tau / kp is a torque tau.
        self.ctrl_ref = reference.ctrl + config.feedforward * reference.torque / kp
        self.cost = TrackingCost(reference, plan_layout, hinge_dofs, qvel_offset,
                                 config.weights)
        # Rollout rows whose cost is read: every cost_stride-th, always the last.
        rows = np.arange(config.cost_stride - 1, self.horizon, config.cost_stride)
        self._rows = rows if rows[-1] == self.horizon - 1 else np.append(rows, self.horizon - 1)
        nstate = mujoco.mj_stateSize(self.plan_model, _STATE)
        N, H = config.n_samples, self.horizon
        self._state = np.empty((N, H, nstate))
        self._sensor = np.empty((N, H, plan_layout.size))
        self._x0 = np.empty(mujoco.mj_stateSize(self.model, _STATE))
        self._datas = [mujoco.MjData(self.plan_model) for _ in range(config.nthread)]
        self._pool = rollout.Rollout(nthread=config.nthread) if config.nthread > 1 else None
        self.knots = np.zeros((config.n_knots, self.model.nu))
        self.plan_step = 0
        self.replans = 0
        self.rollout_steps = 0
        self.last_costs: np.ndarray = np.zeros(0)
        self.feedback: FeedbackLaw | None = None
        if config.feedback:
            self.feedback = FeedbackLaw(
                self.plan_model, reference, config.weights, humanoid.site_ids,
                np.flatnonzero(sigma > 0) if sigma.any() else np.arange(self.model.nu),
                f, config.feedback_r, config.feedback_knots or self.horizon, config.limit_rad)

    def _check_layout(self, layout: SensorLayout) -> None:
        if layout != self.layout:
            raise PhysicsError("planning and simulated models disagree on sensors",
                               field="timestep_factor")

    def __enter__(self) -> TrackingMPC:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the rollout thread pool (idempotent)."""
        if self._pool is not None:
            self._pool.close()
            self._pool = None

    def reset(self, data: mujoco.MjData) -> None:
        """Put ``data`` in the reference's first state and clear the plan."""
        mujoco.mj_resetData(self.model, data)
        data.qpos[:] = self.reference.qpos0
        data.qvel[:] = self.reference.qvel0
        mujoco.mj_forward(self.model, data)
        self.knots[:] = 0.0
        self.plan_step = 0
        self.replans = 0

    def snapshot(self) -> tuple[np.ndarray, int, int]:
        """The plan (knots, step planned at, replans) to :meth:`restore` on a rewind; the
        noise generator is not part of it, so a restored planner draws new samples."""
        return self.knots.copy(), self.plan_step, self.replans

    def restore(self, snapshot: tuple[np.ndarray, int, int]) -> None:
        """Go back to a plan taken by :meth:`snapshot`."""
        knots, self.plan_step, self.replans = snapshot
        self.knots = knots.copy()
        if self.feedback is not None:  # its gains are about a trajectory left behind
            self.feedback.clear()

    def _offsets(self, step: int) -> np.ndarray:
        """(nu,) the nominal's offset at physics step ``step``."""
        j = (step - self.plan_step) / self.config.timestep_factor
        return (self.spline.weights(np.array([j])) @ self.knots)[0]

    def plan(self, data: mujoco.MjData, step: int) -> None:
        """Replan from ``data``'s state at physics step ``step`` (module docstring)."""
        ref, f = self.reference, self.config.timestep_factor
        if self.replans:
            self.knots = self.spline.shift(self.knots, (step - self.plan_step) / f)
        samples = self.sampler.sample(self.knots)
        ctrl_steps = ref.window(step, self.horizon * f)[::f]
        controls = self.ctrl_ref[ctrl_steps] + self.spline.evaluate(samples)
        mujoco.mj_getState(self.model, data, self._x0, _STATE)
        state_steps = ref.window(step + f, self.horizon * f)[::f]
        if self.config.screen_fraction is None:
            self._roll(self._x0[None], controls, data.qacc_warmstart, self._state,
                       self._sensor)
            rows = self._rows
            costs = self.cost(ctrl_steps[rows], self._sensor[:, rows], state_steps[rows],
                              self._state[:, rows], samples)
            self.rollout_steps += costs.size * self.horizon
        else:
            costs = self._screened(controls, data.qacc_warmstart, ctrl_steps, state_steps,
                                   samples)
        self.knots = self.sampler.update(samples, costs)
        self.last_costs = costs
        self.plan_step = step
        self.replans += 1
        if self.feedback is not None:
            before = self.feedback.steps
            self.feedback.update(self._x0, self.ctrl_ref[ctrl_steps]
                                 + self.spline.evaluate(self.knots),
                                 step, data.qacc_warmstart)
            self.rollout_steps += self.feedback.steps - before

    def _roll(self, x0: np.ndarray, controls: np.ndarray, warmstart: np.ndarray,
              state: np.ndarray, sensor: np.ndarray) -> None:
        """Roll ``controls`` (N, h, nu) out from ``x0`` (1 or N, nstate) into ``state`` /
        ``sensor`` (N, h, ...)."""
        runner = self._pool if self._pool is not None else rollout
        runner.rollout(self.plan_model, self._datas, x0, controls,
                       initial_warmstart=warmstart[None], state=state, sensordata=sensor)

    def _screened(self, controls: np.ndarray, warmstart: np.ndarray, ctrl_steps: np.ndarray,
                  state_steps: np.ndarray, samples: np.ndarray) -> np.ndarray:
        """(N,) costs of a screened replan (:attr:`MPCConfig.screen_fraction`): every sample
        rolled over the first ``h1`` planning steps, priced by the cost rows among them; the
        cheaper half rolled on from their states after those steps and priced over the whole
        horizon; the others NaN (never win). The cost rows are :attr:`_rows`, the same as
        unscreened; the first part's are those before ``h1`` (at least its last step)."""
        N, H = len(controls), self.horizon
        h1 = min(H - 1, max(1, int(round(H * self.config.screen_fraction))))
        head_state = np.empty((N, h1, self._state.shape[-1]))
        head_sensor = np.empty((N, h1, self._sensor.shape[-1]))
        self._roll(self._x0[None], np.ascontiguousarray(controls[:, :h1]), warmstart,
                   head_state, head_sensor)
        rows = self._rows[self._rows < h1]
        rows = rows if rows.size else np.array([h1 - 1])
        head = self.cost(ctrl_steps[rows], head_sensor[:, rows], state_steps[rows],
                         head_state[:, rows], samples)
        keep = np.argsort(np.where(np.isfinite(head), head, np.inf), kind="stable")[:N // 2]
        tail_state = np.empty((len(keep), H - h1, self._state.shape[-1]))
        tail_sensor = np.empty((len(keep), H - h1, self._sensor.shape[-1]))
        self._roll(np.ascontiguousarray(head_state[keep, -1]),
                   np.ascontiguousarray(controls[keep, h1:]), warmstart, tail_state,
                   tail_sensor)
        full_state = np.concatenate([head_state[keep], tail_state], axis=1)
        full_sensor = np.concatenate([head_sensor[keep], tail_sensor], axis=1)
        rows = self._rows
        costs = np.full(N, np.nan)
        costs[keep] = self.cost(ctrl_steps[rows], full_sensor[:, rows], state_steps[rows],
                                full_state[:, rows], samples[keep])
        self.rollout_steps += N * h1 + len(keep) * (H - h1)
        return costs

    def control(self, data: mujoco.MjData, step: int) -> np.ndarray:
        """(nu,) servo targets for physics step ``step``, replanning when due."""
        if self.replans == 0 or step - self.plan_step >= self.config.replan_steps:
            self.plan(data, step)
        u = self.ctrl_ref[min(step, self.reference.n_steps)] + self._offsets(step)
        if self.feedback is not None:
            u[self.feedback.actuators] += self.feedback.correction(self.model, data,
                                                                   step - self.plan_step)
        return u

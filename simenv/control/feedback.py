"""Time-varying LQR feedback around the planner's nominal, between replans (issue 35).

The sampling planner replans every ``replan_steps`` physics steps and, in between, plays
its nominal servo targets open loop. This module gives the executed body feedback in
between instead: after each replan it

1. rolls the new nominal out once on the planning model from the replan's state, giving
   the predicted states ``x*_j`` at planning steps ``j = 0 .. H`` (the trajectory the
   planner priced; it differs from what the finer simulated model does with the same
   targets, and from what the body does once it has drifted);
2. linearises the planning model's step about ``n_knots`` of those states
   (``mujoco.mjd_transitionFD``: ``dx' = A dx + B du`` in MuJoCo's tangent space,
   ``dx = (dq, dqd)``, nv + nv), holding each linearisation to the next knot;
3. solves the finite-horizon Riccati recursion backwards over the horizon,

       K_j = (R + B'P B)^-1 B'P A,   P_j = Q_j + A'P (A - B K_j),   P_H = Q_H,

   ``Q_j`` the planner's own tracking cost (:class:`~simenv.control.costs.CostWeights`)
   made quadratic in ``dx`` about ``x*_j``: keypoints, planted feet and centre of mass
   through their Jacobians (``J'J``), the centre-of-mass velocity likewise, hinge
   velocities on the diagonal; ``R = r I`` per rad^2 of servo-target offset;
4. between replans sets the servo targets of the ``actuators`` it may move (the
   planner's sampled ones) to

       u = u*(t) - K(t) (x - x*(t)),

   ``x*(t)`` the prediction interpolated to the physics step (positions through
   ``mj_differentiatePos``, so the root's quaternion is handled), the correction clipped
   to ``limit`` radians per actuator.

Measured (docs/tracking_speed.md): the body drifts only 2-5 mm from the prediction over
40-80 ms, and the feedback did not let FAST replan less often at the same closeness; held
linearisations (fewer than one per planning step) can push the wrong way once contacts
switch within them. Off by default (:class:`~simenv.control.MPCConfig` ``feedback``).

Only the hinge servos' targets change: nothing acts on the root. Deterministic: no noise.
Cost per replan: one nominal rollout (H planning steps), ``n_knots`` linearisations
(``2 nv + nu + 1`` steps each) and H Riccati steps, against the planner's N x H
rolled-out steps.
"""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco import rollout

from simenv.control.costs import CostWeights
from simenv.control.model import root_dofs
from simenv.control.reference import TrackingReference, actuated_indices
from simenv.core.errors import PhysicsError

_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


class FeedbackLaw:
    """TVLQR gains about a nominal (module docstring).

    Args:
        plan_model: the planning model (rollouts and linearisations).
        reference: the clip per physics step (keypoints, planted feet for ``Q``).
        weights: the planner's cost weights (``Q``).
        site_ids: (K,) keypoint site ids in ``plan_model`` (the reference's order).
        actuators: (m,) indices of the actuators the feedback may move.
        timestep_factor: planning steps are this many physics steps.
        r: control weight per rad^2 of servo-target offset per planning step.
        n_knots: linearisations spread over the horizon (>= 1; 1: one, about the replan's
            state; at most one per planning step is made).
        limit: largest correction per actuator, radians.
        eps: finite-difference step of ``mjd_transitionFD``.
    """

    def __init__(self, plan_model: mujoco.MjModel, reference: TrackingReference,
                 weights: CostWeights, site_ids: np.ndarray, actuators: np.ndarray,
                 timestep_factor: int, r: float, n_knots: int, limit: float,
                 eps: float = 1e-6) -> None:
        if n_knots < 1 or r <= 0:
            raise PhysicsError(f"feedback needs n_knots >= 1 and r > 0; got {n_knots}, {r}",
                               field="feedback_knots" if n_knots < 1 else "feedback_r")
        self.model = plan_model
        self.ref = reference
        self.weights = weights
        self.site_ids = np.asarray(site_ids)
        self.actuators = np.asarray(actuators)
        self.f = int(timestep_factor)
        self.r = float(r)
        self.n_knots = int(n_knots)
        self.limit = float(limit)
        self.eps = float(eps)
        nv = plan_model.nv
        self.nx = 2 * nv + plan_model.na
        _, self.hinge_dofs = actuated_indices(plan_model)
        self.root = root_dofs(plan_model)
        self._data = mujoco.MjData(plan_model)
        self._A = np.zeros((self.nx, self.nx))
        self._B = np.zeros((self.nx, plan_model.nu))
        self._jac = np.zeros((3, nv))
        self._dq = np.zeros(nv)
        self.gains: np.ndarray | None = None   # (H, m, nx)
        self.qpos: np.ndarray = np.zeros((0, plan_model.nq))
        self.qvel: np.ndarray = np.zeros((0, nv))
        #: Planning-model steps taken (nominal rollouts and finite differences).
        self.steps = 0

    def clear(self) -> None:
        """No feedback until the next :meth:`update` (after a rewind)."""
        self.gains = None

    def _cost_hessian(self, step: int) -> np.ndarray:
        """(nx, nx) ``Q`` about ``self._data``'s state (forward already run) at reference
        physics step ``step`` (module docstring)."""
        m, d, w, nv = self.model, self._data, self.weights, self.model.nv
        jacs = np.empty((len(self.site_ids), 3, nv))
        for k, site in enumerate(self.site_ids):
            mujoco.mj_jacSite(m, d, jacs[k], None, int(site))
        Qq = w.keypoints / len(jacs) * np.einsum("kci,kcj->ij", jacs, jacs)
        planted = self.ref.planted[min(step, self.ref.n_steps)]
        if planted.any():
            feet = jacs[self.ref.foot_sites[planted]]
            Qq += w.foot / planted.sum() * np.einsum("kci,kcj->ij", feet, feet)
        mujoco.mj_jacSubtreeCom(m, d, self._jac, 1)
        Jc = self._jac
        Q = np.zeros((self.nx, self.nx))
        Q[:nv, :nv] = Qq + w.com * Jc.T @ Jc
        Q[nv:2 * nv, nv:2 * nv] = w.com_vel * Jc.T @ Jc
        Q[nv + self.hinge_dofs, nv + self.hinge_dofs] += w.qvel / len(self.hinge_dofs)
        return Q

    def update(self, x0: np.ndarray, controls: np.ndarray, step: int,
               warmstart: np.ndarray) -> None:
        """New gains about the nominal ``controls`` (H, nu) played from the full-physics
        state ``x0`` at physics step ``step`` (``warmstart``: the simulated body's
        ``qacc_warmstart``, (nv,))."""
        m, d = self.model, self._data
        H = len(controls)
        states = np.empty((1, H, mujoco.mj_stateSize(m, _STATE)))
        rollout.rollout(m, d, x0[None], controls[None], initial_warmstart=warmstart[None],
                        state=states)
        traj = np.concatenate([x0[None], states[0]])          # (H + 1, nstate)
        nq, nv = m.nq, m.nv
        self.qpos = traj[:, 1:1 + nq]
        self.qvel = traj[:, 1 + nq:1 + nq + nv]
        knots = np.unique(np.linspace(0, H - 1, self.n_knots).round().astype(int))
        lin = []
        for j in knots:
            mujoco.mj_setState(m, d, traj[j], _STATE)
            d.ctrl[:] = controls[j]
            mujoco.mj_forward(m, d)
            mujoco.mjd_transitionFD(m, d, self.eps, False, self._A, self._B, None, None)
            lin.append((self._A.copy(), self._B[:, self.actuators].copy(),
                        self._cost_hessian(step + self.f * j)))
        self.steps += H + len(knots) * (self.nx + m.nu + 1)
        # Riccati backwards; linearisation k holds from its knot to the next.
        R = self.r * np.eye(len(self.actuators))
        which = np.searchsorted(knots, np.arange(H), side="right") - 1
        P = lin[-1][2]
        gains = np.empty((H, len(self.actuators), self.nx))
        for j in range(H - 1, -1, -1):
            A, B, Q = lin[which[j]]
            PB = P @ B
            K = np.linalg.solve(R + B.T @ PB, PB.T @ A)
            P = Q + A.T @ P @ (A - B @ K)
            P = 0.5 * (P + P.T)
            gains[j] = K
        self.gains = gains

    def correction(self, model: mujoco.MjModel, data: mujoco.MjData, m: int) -> np.ndarray:
        """(n actuators,) servo-target corrections ``-K (x - x*)`` for ``data`` ``m``
        physics steps after the replan (``model``: the simulated one; same nq, nv)."""
        if self.gains is None:
            return np.zeros(len(self.actuators))
        j = m / self.f
        j0 = min(int(j), len(self.gains) - 1)
        a = min(j - j0, 1.0)
        dx = np.empty(self.nx)
        nv = model.nv
        # x* - x, positions in the tangent space at x.
        mujoco.mj_differentiatePos(model, dx[:nv], 1.0, data.qpos, self.qpos[j0])
        if a > 0:
            mujoco.mj_differentiatePos(model, self._dq, 1.0, self.qpos[j0], self.qpos[j0 + 1])
            dx[:nv] += a * self._dq
        dx[nv:2 * nv] = (1 - a) * self.qvel[j0] + a * self.qvel[j0 + 1] - data.qvel
        dx[2 * nv:] = 0.0
        return np.clip(self.gains[j0] @ dx, -self.limit, self.limit)

"""The planner's tracking cost of a rolled-out trajectory.

For rollout ``i`` and each evaluated horizon step ``j`` (every
``stride``-th step), with ``x`` the simulated and ``x*`` the reference
quantity at the same time::

    c_ij = w_kp   mean_k |p_k - p*_k|^2                     keypoints (m^2)
         + w_com  |c - c*|^2                                centre of mass (m^2)
         + w_vcom |v_c - v*_c|^2                            its velocity ((m/s)^2)
         + w_qvel mean_h (qd_h - qd*_h)^2                   hinge velocities ((rad/s)^2)
         + w_foot mean_{f planted in x*} |p_f - p*_f|^2     contact schedule (m^2)
         + w_trunk theta(R, R*)^2                           upper-trunk orientation (rad^2)

and the rollout's cost is ``mean_j c_ij + w_effort mean(theta_i^2)`` (the
last term, on the sampled knot offsets in rad^2, keeps the servos near the
reference when tracking is good anyway). The foot term weighs the feet again
where the reference stands on them: a planted reference foot that the body
lifts, or slides, is what makes a tracked body fall.

The trunk term is the geodesic angle between the simulated and the reference
world orientation of the upper trunk (the body the shoulders hang from), read
as unit quaternions ``r``, ``r*``::

    theta = 2 arccos |<r, r*>|        in [0, pi] rad

(the absolute value: ``r`` and ``-r`` are one rotation). The keypoint term
sees a trunk lean only through the few upper-body keypoints it moves, so a
planner free to bend the lower spine can buy balance with a lean that shifts
every arm keypoint; this term prices the lean itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simenv.control.model import SensorLayout, keypoints_of
from simenv.control.reference import TrackingReference


def trunk_angle(quat: np.ndarray, ref_quat: np.ndarray) -> np.ndarray:
    """Geodesic angle between unit quaternions ``(w, x, y, z)`` (module docstring),
    radians in [0, pi]; shapes (..., 4) broadcast to (...)."""
    dot = np.abs(np.einsum("...c,...c->...", quat, ref_quat))
    return 2.0 * np.arccos(np.minimum(dot, 1.0))


@dataclass(frozen=True)
class CostWeights:
    """Weights of the tracking cost terms (module docstring), each per its unit.

    Attributes:
        keypoints: per m^2 of mean squared keypoint error.
        com: per m^2 of centre-of-mass error.
        com_vel: per (m/s)^2 of centre-of-mass velocity error.
        qvel: per (rad/s)^2 of mean squared hinge velocity error.
        foot: per m^2 of mean squared planted-foot error.
        trunk: per rad^2 of squared upper-trunk orientation error (0: off). Off by
            default: on CMU clips 12_01, 131_04, 02_04, 05_02 and 55_02 (64 samples,
            seeds 0-2) weight 0.1 tracked 11 of 15 runs at 88 mm mean body error
            against 13 of 15 at 74 mm without it (0.3: 2 of 5 on seed 0). It does
            straighten a leaning trunk (12_01, seed 0: lean 23 -> 12 deg), but the
            balance the lower spine gave up then costs the legs and the pelvis.
        effort: per rad^2 of mean squared knot offset.
    """

    keypoints: float = 1.0
    com: float = 2.0
    com_vel: float = 0.02
    qvel: float = 1e-4
    foot: float = 1.0
    trunk: float = 0.0
    effort: float = 1e-3


class TrackingCost:
    """Evaluates :class:`CostWeights` on rollouts against a :class:`TrackingReference`.

    Args:
        reference: the resampled clip.
        layout: where the planning model's sensors put keypoints, the COM and the
            trunk orientation.
        hinge_dofs: (nu,) dof index of each actuated hinge (for ``qvel``).
        qvel_offset: column of ``qvel[0]`` in a rollout state row.
        weights: the term weights.
    """

    def __init__(self, reference: TrackingReference, layout: SensorLayout,
                 hinge_dofs: np.ndarray, qvel_offset: int, weights: CostWeights) -> None:
        self.ref = reference
        self.layout = layout
        self.hinge_dofs = np.asarray(hinge_dofs)
        self.hinge_cols = qvel_offset + self.hinge_dofs
        self.weights = weights

    def __call__(self, steps: np.ndarray, sensordata: np.ndarray, state_steps: np.ndarray,
                 state: np.ndarray, knots: np.ndarray) -> np.ndarray:
        """Costs of N rollouts.

        Args:
            steps: (J,) reference step of each evaluated sensor row.
            sensordata: (N, J, size) sensor rows at those steps (``mujoco.rollout``
                records the sensors of the state a step starts from).
            state_steps: (J,) reference step of each evaluated state row.
            state: (N, J, nstate) full-physics states (after each step).
            knots: (N, n, nu) the sampled offsets.

        Returns:
            (N,) costs; NaN where a rollout went non-finite.
        """
        w, ref = self.weights, self.ref
        kp = keypoints_of(sensordata, self.layout)
        d = kp - ref.keypoints[steps]
        sq = np.einsum("njkc,njkc->njk", d, d)
        c = w.keypoints * sq.mean(axis=-1)
        planted = ref.planted[steps]
        n_planted = planted.sum(axis=-1)
        foot_sq = (sq[:, :, ref.foot_sites] * planted).sum(axis=-1)
        c += w.foot * foot_sq / np.maximum(n_planted, 1)
        dc = sensordata[..., self.layout.com] - ref.com[steps]
        c += w.com * np.einsum("njc,njc->nj", dc, dc)
        dv = sensordata[..., self.layout.com_vel] - ref.com_vel[steps]
        c += w.com_vel * np.einsum("njc,njc->nj", dv, dv)
        dq = state[..., self.hinge_cols] - ref.qvel[state_steps][:, self.hinge_dofs]
        c += w.qvel * (dq * dq).mean(axis=-1)
        if w.trunk:  # off by default: no arccos over every rollout row for nothing
            c += w.trunk * trunk_angle(sensordata[..., self.layout.trunk],
                                       ref.trunk[steps]) ** 2
        total = c.mean(axis=1) + w.effort * (knots * knots).mean(axis=(1, 2))
        return np.where(np.isfinite(total), total, np.nan)

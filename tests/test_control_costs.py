"""The planner's tracking cost (simenv.control.costs)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from simenv.control.costs import CostWeights, TrackingCost
from simenv.control.model import planning_model
from simenv.control.reference import TrackingReference, actuated_indices


def test_cost_terms_match_their_definitions(walk_2s_retargeted) -> None:
    ref = TrackingReference.from_retarget(walk_2s_retargeted, max_seconds=0.2, feedforward=False)
    model, layout = planning_model(walk_2s_retargeted.humanoid)
    _, dofs = actuated_indices(model)
    qv0 = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_TIME) + model.nq
    steps = np.array([10, 20, 30])
    # Sensor rows and states exactly on the reference: only the knot effort costs.
    sensors = np.zeros((2, 3, layout.size))
    sensors[:, :, layout.keypoints] = ref.keypoints[steps].reshape(3, -1)
    sensors[:, :, layout.com] = ref.com[steps]
    sensors[:, :, layout.com_vel] = ref.com_vel[steps]
    state = np.zeros((2, 3, mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)))
    state[:, :, qv0 + dofs] = ref.qvel[steps][:, dofs]
    knots = np.zeros((2, 4, model.nu))
    knots[1] = 0.1
    w = CostWeights()
    cost = TrackingCost(ref, layout, dofs, qv0, w)
    np.testing.assert_allclose(cost(steps, sensors, steps, state, knots),
                               [0.0, w.effort * 0.01], atol=1e-12)
    # Every keypoint 0.1 m off: keypoint term 0.01 w_kp, planted feet 0.01 w_foot.
    shifted = sensors.copy()
    shifted[:, :, layout.keypoints] += 0.1 / np.sqrt(3)
    c = cost(steps, shifted, steps, state, np.zeros_like(knots))
    planted_any = ref.planted[steps].any(axis=1).mean()
    assert c[0] == pytest.approx(0.01 * w.keypoints + 0.01 * w.foot * planted_any)
    # A blown-up rollout costs NaN (the sampler never keeps it).
    shifted[1, 0, 0] = np.nan
    assert np.isnan(cost(steps, shifted, steps, state, knots)[1])

"""The planner's tracking cost (simenv.control.costs)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from simenv.control.costs import CostWeights, TrackingCost, trunk_angle
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
    sensors[:, :, layout.trunk] = ref.trunk[steps]
    state = np.zeros((2, 3, mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)))
    state[:, :, qv0 + dofs] = ref.qvel[steps][:, dofs]
    knots = np.zeros((2, 4, model.nu))
    knots[1] = 0.1
    w = CostWeights(trunk=0.5)
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


def test_trunk_term_is_zero_on_the_reference_and_prices_a_tilt(walk_2s_retargeted) -> None:
    r = walk_2s_retargeted
    ref = TrackingReference.from_retarget(r, max_seconds=0.5, feedforward=False)
    model, layout = planning_model(r.humanoid)
    _, dofs = actuated_indices(model)
    qv0 = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_TIME) + model.nq
    w = CostWeights(keypoints=0.0, com=0.0, com_vel=0.0, qvel=0.0, foot=0.0, effort=0.0,
                    trunk=3.0)
    cost = TrackingCost(ref, layout, dofs, qv0, w)
    state = np.zeros((1, 1, mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)))
    knots = np.zeros((1, 4, model.nu))
    data = mujoco.MjData(model)
    step = np.array([ref.frame_step[30]])  # frame 30 sits on its step: no interpolation
    costs = []
    for tilt in (0.0, 0.1, 0.3):
        # The whole body pitched forward by `tilt` about the world y axis through the origin.
        data.qpos[:] = r.qpos[30]
        turn = np.array([np.cos(tilt / 2), 0.0, np.sin(tilt / 2), 0.0])
        mujoco.mju_mulQuat(data.qpos[3:7], turn, r.qpos[30, 3:7].copy())
        mujoco.mj_forward(model, data)
        row = data.sensordata.copy()
        assert trunk_angle(row[layout.trunk], ref.trunk[step[0]]) == pytest.approx(tilt, abs=1e-6)
        costs.append(cost(step, row[None, None], step, state, knots)[0])
    np.testing.assert_allclose(costs, [0.0, 3.0 * 0.01, 3.0 * 0.09], atol=1e-9)
    # q and -q are one rotation.
    flipped = -ref.trunk[step]
    assert trunk_angle(flipped, ref.trunk[step])[0] == pytest.approx(0.0, abs=1e-6)

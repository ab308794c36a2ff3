"""The planning model's sensors (simenv.control.model)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from simenv.body.humanoid import Humanoid
from simenv.control.model import keypoints_of, planning_model, root_dofs
from simenv.core.errors import PhysicsError


def test_sensors_read_the_keypoints_and_the_centre_of_mass() -> None:
    h = Humanoid()
    model, layout = planning_model(h)
    data = mujoco.MjData(model)
    data.qpos[:] = h.default_qpos()
    data.qpos[7:] += 0.1  # bend every hinge a little
    data.qvel[0] = 0.7  # walk forward at 0.7 m/s
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(keypoints_of(data.sensordata, layout),
                               data.site_xpos[h.site_ids])
    np.testing.assert_allclose(data.sensordata[layout.com], data.subtree_com[1])
    np.testing.assert_allclose(data.sensordata[layout.com_vel], [0.7, 0.0, 0.0], atol=1e-9)
    # The trunk quaternion is the chest's body frame, not its inertia frame.
    np.testing.assert_allclose(data.sensordata[layout.trunk], data.xquat[model.body("chest").id])
    # Same body, same dynamics: the humanoid's model is left without sensors.
    assert h.model.nsensor == 0 and model.nbody == h.model.nbody and model.nu == h.model.nu
    np.testing.assert_array_equal(root_dofs(model), np.arange(6))


def test_coarse_planning_model_and_stiffer_servos() -> None:
    h = Humanoid()
    model, _ = planning_model(h, timestep_factor=2, gain_scale=3.0)
    assert model.opt.timestep == pytest.approx(2 * h.model.opt.timestep)
    np.testing.assert_allclose(model.actuator_gainprm[:, 0], 3 * h.model.actuator_gainprm[:, 0])
    np.testing.assert_allclose(model.actuator_forcerange, h.model.actuator_forcerange)
    with pytest.raises(PhysicsError) as err:
        planning_model(h, timestep_factor=0)
    assert err.value.field == "timestep_factor"


def test_coarser_planning_steps_predict_the_simulated_body_less_closely(
        walk_2s_retargeted) -> None:
    """The planner's cheaper models checked against the simulated one (2 ms step): the real
    walk's servo targets (with the feed-forward) played open loop from captured states, the
    keypoints compared after 0.1 s (what a replan's plan is mostly used for) and 0.44 s
    (the horizon's end). Measured on this walk: 4 ms 1.9 / 10.9 mm, 8 ms 6.5 / 30.7 mm."""
    from mujoco import rollout

    from simenv.control import TrackingReference

    h = walk_2s_retargeted.humanoid
    ref = TrackingReference.from_retarget(walk_2s_retargeted, max_seconds=2.0)
    u = ref.ctrl + ref.torque / h.model.actuator_gainprm[:, 0]
    starts = [f for f in range(0, 120, 30) if ref.frame_step[f] + 225 <= ref.n_steps]
    ends = {}
    for factor in (1, 2, 4):
        model, layout = planning_model(h, factor)
        data = mujoco.MjData(model)
        full = mujoco.mjtState.mjSTATE_FULLPHYSICS
        x0 = np.empty((len(starts), mujoco.mj_stateSize(model, full)))
        for i, f in enumerate(starts):
            mujoco.mj_resetData(model, data)
            data.qpos[:] = walk_2s_retargeted.qpos[f]
            data.qvel[:] = ref.qvel[ref.frame_step[f]]
            mujoco.mj_forward(model, data)
            mujoco.mj_getState(model, data, x0[i], full)
        ctrl = np.stack([u[ref.frame_step[f]:ref.frame_step[f] + 225:factor] for f in starts])
        _, sensors = rollout.rollout(model, [data], x0, ctrl)
        rows = [round(t / (h.model.opt.timestep * factor)) for t in (0.1, 0.44)]
        ends[factor] = keypoints_of(sensors[:, rows], layout)
    dev = {f: np.linalg.norm(ends[f] - ends[1], axis=-1).mean(axis=(0, 2)) for f in (2, 4)}
    assert (dev[2] < dev[4]).all()
    assert dev[2][0] < 0.005 and dev[4][0] < 0.02
    assert dev[4][1] < 0.06

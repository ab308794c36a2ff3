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

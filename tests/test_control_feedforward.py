"""Feed-forward hinge torques from inverse dynamics (simenv.control.feedforward)."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np

from simenv.control.feedforward import feedforward_torques
from simenv.control.reference import TrackingReference, actuated_indices


def _hold(result, feedforward: bool) -> float:
    """Largest hinge sag (rad) after 0.5 s of the servos holding a still pose."""
    ref = TrackingReference.from_retarget(result, feedforward=feedforward)
    model = result.humanoid.model
    data = mujoco.MjData(model)
    data.qpos[:] = ref.qpos0
    mujoco.mj_forward(model, data)
    kp = model.actuator_gainprm[:, 0]
    q_adr, _ = actuated_indices(model)
    for s in range(ref.n_steps):
        data.ctrl[:] = ref.ctrl[s] + ref.torque[s] / kp
        mujoco.mj_step(model, data)
    return float(np.abs(data.qpos[q_adr] - ref.qpos0[q_adr]).max())


def test_a_still_stance_is_held_closer_with_the_feedforward(walk_2s_retargeted) -> None:
    # One real frame of the walk (one foot planted, knees bent) held still for 0.5 s.
    still = replace(walk_2s_retargeted, qpos=np.repeat(walk_2s_retargeted.qpos[:1], 61, axis=0))
    tau = feedforward_torques(still)
    assert tau.shape == (61, still.humanoid.model.nu)
    np.testing.assert_allclose(tau, tau[:1].repeat(61, axis=0), atol=1e-6)  # a still pose
    # The servos alone sag under the body weight; the inverse-dynamics torques carry it.
    assert _hold(still, True) < 0.5 * _hold(still, False)

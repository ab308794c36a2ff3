"""Time-varying LQR feedback between replans (simenv.control.feedback) on the real CMU
walk 02_01 (the bundled clip's first 0.6 s): one replan, then the simulated body held to
the plan's predicted states with and without the gains."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from simenv.control import FAST, MPCConfig, TrackingMPC, TrackingReference
from simenv.core.errors import PhysicsError

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


@pytest.fixture(scope="module")
def planned(walk_2s_retargeted):
    """A FAST planner with feedback (a linearisation per planning step) after its first replan, its
    simulated model, a data at the replan's state and that state."""
    ref = TrackingReference.from_retarget(walk_2s_retargeted, max_seconds=0.6)
    cfg = replace(FAST, nthread=1, feedback=True)
    mpc = TrackingMPC(walk_2s_retargeted.humanoid, ref, cfg)
    data = mujoco.MjData(mpc.model)
    mpc.reset(data)
    mpc.plan(data, 0)
    x0 = np.empty(mujoco.mj_stateSize(mpc.model, _FULL))
    mujoco.mj_getState(mpc.model, data, x0, _FULL)
    yield mpc, data, x0
    mpc.close()


def _drift_mm(mpc: TrackingMPC, data: mujoco.MjData, x0: np.ndarray, push: float,
              feedback: bool) -> float:
    """Mean keypoint distance (mm) between the simulated body and the plan's prediction at
    the horizon's end, playing the nominal from ``x0`` with the root's forward velocity
    pushed by ``push`` m/s, with or without the feedback's corrections."""
    m, fb, f = mpc.model, mpc.feedback, mpc.config.timestep_factor
    mujoco.mj_setState(m, data, x0, _FULL)
    data.qvel[0] += push
    n = (mpc.horizon - 1) * f
    for s in range(n):
        u = mpc.ctrl_ref[s] + mpc._offsets(s)
        if feedback:
            u[fb.actuators] += fb.correction(m, data, s)
        data.ctrl[:] = u
        mujoco.mj_step(m, data)
    mujoco.mj_kinematics(m, data)
    sites = fb.site_ids
    predicted = mujoco.MjData(m)
    predicted.qpos[:] = fb.qpos[n // f]
    mujoco.mj_kinematics(m, predicted)
    gap = data.site_xpos[sites] - predicted.site_xpos[sites]
    return 1000.0 * float(np.linalg.norm(gap, axis=1).mean())


def test_gains_on_the_walks_first_frames_are_finite(planned) -> None:
    mpc, _, _ = planned
    fb = mpc.feedback
    assert fb.gains.shape == (mpc.horizon, len(fb.actuators), 2 * mpc.model.nv)
    assert np.isfinite(fb.gains).all() and np.abs(fb.gains).max() > 0
    # Only the sampled (leg and lumbar) servos are corrected; never more than the model has.
    assert 0 < len(fb.actuators) < mpc.model.nu


@pytest.mark.parametrize("push", [0.0, 0.3, -0.3])
def test_feedback_holds_the_body_closer_to_the_plan_than_none(planned, push) -> None:
    # push 0: the only disturbance is the 8 ms planning model's mismatch with the 2 ms
    # simulated one; +-0.3 m/s: a shove of the root forwards or backwards as well.
    mpc, data, x0 = planned
    assert _drift_mm(mpc, data, x0, push, True) < _drift_mm(mpc, data, x0, push, False)


def test_feedback_is_off_by_default_and_checked() -> None:
    assert not MPCConfig().feedback and not FAST.feedback
    with pytest.raises(PhysicsError, match="feedback_knots"):
        MPCConfig(feedback=True, feedback_knots=0)

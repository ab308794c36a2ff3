"""The tracking reference resampled to the physics step (simenv.control.reference)."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from simenv.control.reference import TrackingReference, actuated_indices, velocity_feedthrough
from simenv.core.errors import PhysicsError


@pytest.fixture(scope="module")
def reference(walk_2s_retargeted) -> TrackingReference:
    return TrackingReference.from_retarget(walk_2s_retargeted, max_seconds=0.5,
                                           feedforward=False)


def test_frames_land_on_their_steps(reference, walk_2s_retargeted) -> None:
    r = walk_2s_retargeted
    model = r.humanoid.model
    assert reference.n_frames == 61 and reference.n_steps == 250  # 0.5 s at 120 fps, 2 ms
    # Frame 30 (0.25 s) sits exactly on step 125: no interpolation there.
    assert reference.frame_step[30] == 125
    np.testing.assert_allclose(reference.keypoints[125], reference.frame_keypoints[30])
    q_adr, v_adr = actuated_indices(model)
    # Servo targets = hinge angles + (kv / kp) x hinge velocities; kv / kp = 0.1 s here.
    np.testing.assert_allclose(velocity_feedthrough(model), 0.1)
    np.testing.assert_allclose(reference.ctrl[125],
                               r.qpos[30, q_adr] + 0.1 * reference.qvel[125, v_adr])
    # The upper trunk's orientation is the chest's at that frame (up to sign), unit length.
    data = mujoco.MjData(model)
    data.qpos[:] = r.qpos[30]
    mujoco.mj_kinematics(model, data)
    assert abs(reference.trunk[125] @ data.xquat[model.body("chest").id]) == pytest.approx(1.0)
    np.testing.assert_allclose(np.linalg.norm(reference.trunk, axis=1), 1.0)
    # Between frames the keypoints lie on the segment joining them.
    mid = reference.keypoints[2]  # step 2 = 0.004 s, between frames 0 and 1
    a = (2 * 0.002 * 120.0)
    np.testing.assert_allclose(mid, (1 - a) * reference.frame_keypoints[0]
                               + a * reference.frame_keypoints[1])


def test_walk_reference_plants_one_foot_at_a_time(reference) -> None:
    planted = reference.planted  # left ankle, left toe, right ankle, right toe
    left, right = planted[:, :2].any(axis=1), planted[:, 2:].any(axis=1)
    assert (left | right).all()  # a walk always stands on a foot
    assert not (left & right).all()  # ... and lifts the other one at times
    assert reference.torque.shape == reference.ctrl.shape and not reference.torque.any()


def test_feedforward_torques_stay_in_the_actuator_limits(walk_2s_retargeted) -> None:
    ref = TrackingReference.from_retarget(walk_2s_retargeted, max_seconds=0.5)
    limits = walk_2s_retargeted.humanoid.model.actuator_forcerange
    assert (ref.torque >= limits[:, 0] - 1e-9).all() and (ref.torque <= limits[:, 1] + 1e-9).all()
    # The hips carry the body: tens of N m on average, not zero.
    names = [walk_2s_retargeted.humanoid.model.actuator(i).name for i in range(len(limits))]
    hip = [names.index("left_thigh_flex"), names.index("right_thigh_flex")]
    assert np.abs(ref.torque[:, hip]).mean() > 10.0


def test_bad_references_raise_physics_errors(walk_2s_retargeted) -> None:
    r = walk_2s_retargeted
    q = r.qpos.copy()
    q[7, 20] = np.inf
    with pytest.raises(PhysicsError) as err:
        TrackingReference.from_retarget(replace(r, qpos=q))
    assert err.value.frame == 7 and err.value.field == "qpos"
    with pytest.raises(PhysicsError, match="at least 2 frames"):
        TrackingReference.from_retarget(replace(r, qpos=r.qpos[:1]))
    with pytest.raises(PhysicsError) as err:
        TrackingReference.from_retarget(replace(r, fps=0.0))
    assert err.value.field == "fps"
    with pytest.raises(PhysicsError) as err:
        TrackingReference.from_retarget(r, max_seconds=-1.0)
    assert err.value.field == "max_seconds"

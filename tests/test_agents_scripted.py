"""Agent reactions carried out in simulation: reach IK, gravity feed-forward, PD plans, and
the seated agent pressing the cigarette out with its own hand."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from simenv.agents.reach import (
    PDPlan,
    PDTrajectory,
    arm_joints,
    min_jerk,
    pd_targets,
    reach_pose,
    upper_body_joints,
)
from simenv.agents.scripted import object_success, plan_cigarette_out
from simenv.errors import SimenvError
from simenv.room import Room


@pytest.fixture(scope="module")
def room() -> Room:
    return Room("default")


def _settled(room: Room) -> mujoco.MjData:
    data = room.make_data()
    for _ in range(250):  # 0.5 s: the seated agent settles on the chair
        mujoco.mj_step(room.model, data)
    return data


def test_min_jerk_and_plans():
    assert min_jerk(0.0) == 0.0 and min_jerk(1.0) == 1.0 and min_jerk(0.5) == 0.5
    assert min_jerk(-1.0) == 0.0 and min_jerk(2.0) == 1.0
    a, b, c = np.zeros(2), np.ones(2), np.array([3.0, -1.0])
    plan = PDPlan([PDTrajectory(a, b, 1.0), PDTrajectory(b, c, 0.5)])
    assert plan.duration == 1.5
    np.testing.assert_allclose(plan.at(0.0), a)
    np.testing.assert_allclose(plan.at(1.0), b)  # continuous at the joint
    np.testing.assert_allclose(plan.at(1.5), c)
    np.testing.assert_allclose(plan.at(9.0), c)
    with pytest.raises(SimenvError):
        PDPlan([])


def test_reach_pose_moves_only_the_arm(room: Room):
    h = room.agent
    q = room.seated_pose()
    hand = h.keypoints(q)[h.keypoint_names.index("right_hand")]
    goal = hand + [0.1, -0.05, 0.15]
    sol, err = reach_pose(h.model, q, "right_hand", goal, arm_joints("right"))
    assert err < 1e-3
    moved = np.flatnonzero(np.abs(sol - q) > 1e-12)
    arm = {int(h.model.joint(j).qposadr[0]) for j in arm_joints("right")}
    assert set(moved.tolist()) <= arm
    lo, hi = h.joint_limits[:, 0], h.joint_limits[:, 1]
    assert np.all(sol[h.hinge_qpos] >= lo - 1e-12) and np.all(sol[h.hinge_qpos] <= hi + 1e-12)
    with pytest.raises(SimenvError, match="side"):
        arm_joints("middle")


def test_gravity_feed_forward_removes_the_sag(room: Room):
    """Held with the hand raised, the servos alone sag by centimetres; with the upper body's
    gravity torque fed forward the hand stays within 1 cm of the pose."""
    h = room.agent
    data = _settled(room)
    q = data.qpos[room.agent_qpos].copy()
    hand_i = h.keypoint_names.index("right_hand")
    goal = room.agent_keypoints(data)[hand_i] + [0.0, 0.0, 0.12]
    sol, _ = reach_pose(h.model, q, "right_hand", goal, arm_joints("right"))
    errors = []
    for compensate in ((), upper_body_joints(h)):
        d = _settled(room)
        d.ctrl[room.agent_ctrl] = pd_targets(h, sol, compensate)
        for _ in range(1500):
            mujoco.mj_step(room.model, d)
        errors.append(np.linalg.norm(room.agent_keypoints(d)[hand_i] - goal))
    assert errors[0] > 0.03 and errors[1] < 0.01


def test_agent_presses_the_cigarette_out(room: Room):
    """The reaction's object state changes through simulation, by the agent's hand: the
    cigarette goes out during the press, after the reaction started, while the agent stays
    seated; nothing writes the cigarette's state."""
    data = _settled(room)
    before = room.object_labels(data)
    assert before["cigarette"] == "lit"
    pelvis0 = data.qpos[room.agent_qpos][:3].copy()
    plan = plan_cigarette_out(room, data)
    cig = room.objects["cigarette"]
    hand_geom = room.model.geom("agent/right_hand").id
    cig_geom = room.model.geom("cigarette/body").id
    dt, touched, out_at = room.model.opt.timestep, False, None
    for i in range(int(round(plan.duration / dt))):
        data.ctrl[room.agent_ctrl] = plan.at(i * dt)
        mujoco.mj_step(room.model, data)
        pairs = {tuple(sorted(g)) for g in data.contact.geom[:data.ncon].tolist()}
        touched |= tuple(sorted((hand_geom, cig_geom))) in pairs
        if out_at is None and cig.label(room.object_states(data)["cigarette"]) == "out":
            out_at = i * dt
    after = room.object_labels(data)
    assert touched, "the hand never touched the cigarette"
    assert out_at is not None and 1.0 < out_at < plan.duration
    assert object_success(room, before, after, "cigarette_out")
    assert not object_success(room, after, after, "cigarette_out")  # already out: no credit
    assert np.linalg.norm(data.qpos[room.agent_qpos][:3] - pelvis0) < 0.02
    assert data.warning.number.sum() == 0
    with pytest.raises(SimenvError, match="no object"):
        object_success(room, before, after, "greet")


def test_proximity_grasp_transmits_the_hand_force_to_the_object(room: Room):
    """Grasp mechanics in isolation (gravity off, the agent moved bodily so its right palm
    is at the door handle): far from the handle the grasp refuses to close; at the handle
    it closes, and pulling the hand into the room swings the door open through the
    constraint."""
    m = room.model
    data = room.make_data()
    assert not room.set_grasp(data, "right_hand", "door", True)
    grip = m.site("agent/right_hand_grip").id
    handle = m.site("door/handle").id
    data.qpos[room.agent_qpos.start:room.agent_qpos.start + 3] += (
        data.site_xpos[handle] - data.site_xpos[grip])
    mujoco.mj_forward(m, data)
    assert np.linalg.norm(data.site_xpos[grip] - data.site_xpos[handle]) < 1e-6
    assert room.set_grasp(data, "right_hand", "door", True)
    gravity = m.opt.gravity.copy()
    m.opt.gravity[:] = 0.0
    try:
        hand = m.body("agent/right_hand").id
        inward = -data.xmat[m.body("wall_south").id].reshape(3, 3)[:, 1]  # wall y = outward
        data.xfrc_applied[hand, :3] = 40.0 * inward
        for _ in range(int(round(1.0 / m.opt.timestep))):
            mujoco.mj_step(m, data)
    finally:
        m.opt.gravity[:] = gravity
    assert room.object_labels(data)["door"] == "open"
    assert np.linalg.norm(data.site_xpos[grip] - data.site_xpos[handle]) < 0.03
    assert data.warning.number.sum() == 0

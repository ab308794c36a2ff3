"""The agent walks on its own legs (simenv.agents.gait, simenv.agents.walk): footsteps
played by a statically balanced stepping gait, nothing but its servos and its contacts
acting on it; help and falls are measured, never hidden. Short walks in the open part of
the discomfort room."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from simenv.agents.gait import standing_agent
from simenv.agents.reach import pd_targets, upper_body_joints
from simenv.agents.walk import FALLEN_FRACTION, STEP_M, GaitMeter, plan_walk, walk_steps
from simenv.core.errors import SimenvError
from simenv.room.room import Room

#: An open spot of the discomfort room (clear of the furniture and the user) and a heading
#: towards the north wall, 1.7 m away.
OPEN = np.array([-0.4, 0.3])
NORTH = np.pi / 2


def _play(room: Room, data: mujoco.MjData, plan, shove: tuple[float, float, np.ndarray] | None
          = None) -> None:
    """Play ``plan`` as the environment does (targets every physics step); ``shove`` =
    (from, to s, (6,) wrench on the pelvis) is a test's outside push."""
    dt = room.model.opt.timestep
    pelvis = room.model.body("agent/pelvis").id
    for i in range(int(round(plan.duration / dt))):
        if shove is not None:
            data.xfrc_applied[pelvis] = shove[2] if shove[0] <= i * dt < shove[1] else 0.0
        data.ctrl[room.agent_ctrl] = plan.control(i * dt, data)
        mujoco.mj_step(room.model, data)


def test_walks_to_the_goal_upright_with_no_help():
    room = Room("discomfort")
    data = standing_agent(room, OPEN, NORTH)
    goal = OPEN + [0.0, 0.4]
    plan = plan_walk(room, data, goal, NORTH)
    assert isinstance(plan.feedback, GaitMeter)
    assert [s.side for s in plan.steps] == ["left", "right", "left"]  # two steps, closing
    _play(room, data, plan)
    out = plan.feedback.outcome(data)
    assert out["success"] and not out["fell"], out
    assert out["goal_error_m"] < 0.08
    assert out["lowest_pelvis_m"] > 0.85  # upright throughout (standing 1.0 m)
    # Nothing but the servos and the contacts: no applied force or torque anywhere on the
    # body, none on the free joint, no equality constraint on it, at every physics step.
    a = plan.feedback.summary()
    assert a["steps"] == int(round(plan.duration / room.model.opt.timestep))
    assert a["max_n"] == 0.0 and a["max_torque_nm"] == 0.0 and a["max_bw"] == 0.0
    assert not data.xfrc_applied.any() and not data.qfrc_applied.any()
    assert not data.eq_active.any()
    # Both feet took a step and stand side by side at the end, turned with the body.
    feet = [data.xpos[room.model.body(f"agent/{s}_foot").id, :2] for s in ("left", "right")]
    assert abs(feet[0][1] - feet[1][1]) < 0.05 and feet[0][1] > OPEN[1] + 0.3
    assert room.assist_wrench(data) == (0.0, 0.0)


def test_a_fall_is_detected_and_the_push_measured():
    """A shove on the pelvis in the middle of a step (an outside force the test applies)
    topples the body: the meter measures the force as help and reports the fall."""
    room = Room("discomfort")
    data = standing_agent(room, OPEN, NORTH)
    plan = plan_walk(room, data, OPEN + [0.0, 0.4], NORTH)
    _play(room, data, plan, shove=(2.0, 2.5, np.array([400.0, 0.0, 0.0, 0.0, 0.0, 0.0])))
    out = plan.feedback.outcome(data)
    assert out["fell"] and not out["success"], out
    assert out["lowest_pelvis_m"] < FALLEN_FRACTION * room.agent.default_qpos()[2]
    assert plan.feedback.fallen()
    assert plan.feedback.summary()["max_n"] == pytest.approx(400.0)


def test_turn_on_the_spot_then_walk_footsteps():
    """A quarter turn on the spot comes first (pairs of 45 deg steps, the foot on the side
    of the turn first), then the path's steps, then the closing step beside the other."""
    room = Room("discomfort")
    data = standing_agent(room, OPEN, NORTH)
    steps = walk_steps(room, data, OPEN + [-0.6, 0.0], np.pi, start_yaw=np.pi)
    turn = steps[:4]
    assert [s.side for s in turn] == ["left", "right", "left", "right"]
    assert np.rad2deg([s.yaw for s in turn]) == pytest.approx([135, 135, 180, 180])
    walk = steps[4:]  # steps of at most STEP_M along the 0.6 m path, then the closing one
    assert len(walk) >= 0.6 / STEP_M + 1 and walk[-1].side != walk[-2].side
    assert all(a.side != b.side for a, b in zip(walk[:-1], walk[1:], strict=True))
    ankles = np.array([s.xy for s in walk[-2:]])
    assert np.linalg.norm(ankles.mean(axis=0) - (OPEN + [-0.6, 0.0])) < 0.01


def test_walk_refuses_a_body_that_is_not_standing():
    """The seated agent (pelvis on the chair) is not walked anywhere."""
    room = Room("discomfort")
    data = room.make_data()
    mujoco.mj_forward(room.model, data)
    with pytest.raises(SimenvError, match="not standing"):
        plan_walk(room, data, np.array([-1.0, 1.5]), np.pi / 2)


def test_standing_act_keeps_its_balance_with_no_help():
    """A standing manipulation (the window push's and the curtain pull's form): the right
    arm reaches forward and sweeps sideways and back while the gait's balance holds the
    body over its feet; no hold on the pelvis, none needed (measured)."""
    from simenv.agents.reach import arm_joints, reach_pose
    from simenv.agents.walk import held_grasp_stroke

    room = Room("discomfort")
    data = standing_agent(room, OPEN, NORTH)
    h = room.agent
    upper = upper_body_joints(h)
    q = data.qpos[room.agent_qpos].copy()
    pelvis = q[:2].copy()
    ahead = np.array([np.cos(NORTH), np.sin(NORTH), 0.0])
    side = np.array([np.cos(NORTH - np.pi / 2), np.sin(NORTH - np.pi / 2), 0.0])
    shoulder = h.keypoints(q)[h.keypoint_names.index("right_shoulder")]
    targets = []
    for goal in (shoulder + 0.45 * ahead, shoulder + 0.45 * ahead + 0.1 * side,
                 shoulder + 0.45 * ahead + 0.2 * side):
        q, err = reach_pose(h.model, q, "right_hand", goal, arm_joints("right"))
        assert err < 0.03
        targets.append(pd_targets(h, q, upper))
    rest = data.ctrl[room.agent_ctrl].copy()
    plan = held_grasp_stroke(room, data, [(targets[0], 1.0)], targets[1:], [(rest, 1.0)],
                             "right_hand", "window")
    _play(room, data, plan)
    out = plan.feedback.outcome(data)
    assert not out["fell"] and out["lowest_pelvis_m"] > 0.9
    assert plan.feedback.summary()["max_n"] == 0.0
    assert np.linalg.norm(data.qpos[room.agent_qpos][:2] - pelvis) < 0.05  # stood its ground

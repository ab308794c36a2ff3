"""Agent reactions carried out in simulation: reach IK, gravity feed-forward, PD plans, and
the seated agent pressing the cigarette out, turning the hi-fi down and greeting the user
with its own body."""

from __future__ import annotations

from pathlib import Path

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
from simenv.agents.scripted import (
    PLANNERS,
    object_success,
    plan_bow_back,
    plan_cigarette_out,
    plan_greet,
    plan_hifi_down,
    user_bearing,
)
from simenv.core.errors import SimenvError
from simenv.room.room import Room
from simenv.room.scenario import load_scenario


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


def _play(room: Room, data: mujoco.MjData, plan, every: int = 25, extra_s: float = 0.5):
    """Play a plan (targets and grasp requests) in the room; yields (t, data) every
    ``every`` physics steps and returns the grasp results."""
    dt = room.model.opt.timestep
    pending, grasps = list(plan.grasps), []
    for i in range(int(round((plan.duration + extra_s) / dt))):
        while pending and pending[0].t <= i * dt:
            g = pending.pop(0)
            grasps.append((g, room.set_grasp(data, g.hand, g.name, g.close)))
        data.ctrl[room.agent_ctrl] = plan.at(i * dt)
        mujoco.mj_step(room.model, data)
        if i % every == 0:
            yield i * dt, grasps


def test_reach_pose_solves_several_sites_together(room: Room):
    """Both feet planted (ankle and toe targets fixed) while the pelvis turns: one solve
    over the leg hinges puts the four sites back where they were."""
    h = room.agent
    q = room.seated_pose()
    feet = ["left_ankle", "left_toe", "right_ankle", "right_toe"]
    idx = [h.keypoint_names.index(f) for f in feet]
    goal = h.keypoints(q)[idx]
    turned = q.copy()
    turned[3:7] = [np.cos(-0.2), 0.0, 0.0, np.sin(-0.2)]  # pelvis yawed -23 deg
    assert np.abs(h.keypoints(turned)[idx] - goal).max() > 0.05
    legs = [n for n in h.joint_names if n.split("_")[1] in ("thigh", "shin", "foot")]
    sol, err = reach_pose(h.model, turned, feet, goal, legs, iterations=400)
    assert err < 2e-3
    np.testing.assert_allclose(h.keypoints(sol)[idx], goal, atol=2e-3)
    with pytest.raises(SimenvError, match="target"):
        reach_pose(h.model, q, feet, goal[:2], legs)


def test_agent_greets_the_user_seated(room: Room):
    """The user stands behind the agent's right (139 deg off its chest's heading): the
    planted feet turn the chair's swivel, the spine turns the rest, and the right hand
    waves above the shoulder; Room.greeting measures the success. No force but the
    agent's own servos acts (no assistance)."""
    data = _settled(room)
    assert np.degrees(abs(user_bearing(room, data))) > 130.0
    plan = plan_greet(room, data)
    swivel = room.model.joint("chair/swivel").qposadr[0]
    feet = [room.agent.keypoint_names.index(f) for f in ("left_ankle", "right_ankle")]
    feet0 = room.agent_keypoints(data)[feet]
    facing, success_at, turned = [], None, 0.0
    for t, _ in _play(room, data, plan):
        g = room.greeting(data)
        facing.append(g["facing_deg"])
        turned = min(turned, float(data.qpos[swivel]))
        if g["success"] and success_at is None:
            success_at = t
    assert min(facing) < 30.0, min(facing)
    assert success_at is not None and success_at < plan.duration
    assert np.degrees(turned) < -20.0  # the seat turned toward the user (clockwise)
    assert np.abs(data.xfrc_applied).max() == 0.0
    assert data.warning.number.sum() == 0
    # Back at the desk afterwards: the agent no longer faces the user.
    assert not room.greeting(data)["success"]
    assert np.linalg.norm(room.agent_keypoints(data)[feet] - feet0, axis=1).max() < 0.15


def test_agent_turns_the_hifi_down_with_a_fingertip_grasp(room: Room):
    """The hi-fi stands by the desk (the default scenario): the fingertips reach the knob's
    handle, the proximity grasp closes there, and the knob crosses its threshold only
    after that, dragged round by the hand; the grasp is let go before the hand returns."""
    data = _settled(room)
    knob = room.objects["hifi"]
    before = room.object_labels(data)
    assert before["hifi"] == "loud"
    plan = plan_hifi_down(room, data)
    close, release = plan.grasps
    assert close.close and not release.close and close.t < release.t
    eq = room.model.equality("grasp/right_hand/hifi").id
    levels = []
    for t, grasps in _play(room, data, plan):
        levels.append((t, knob.level(room.object_states(data)["hifi"]), len(grasps)))
        if len(grasps) == 1:
            assert grasps[0][1], "the fingertips were not at the knob's handle"
    assert [ok for _, ok in grasps] == [True, False] and not data.eq_active[eq]
    ungrasped = [lv for _, lv, n in levels if n == 0]
    assert max(ungrasped) - min(ungrasped) < 0.02  # nothing turns it before the grasp
    after = room.object_labels(data)
    assert object_success(room, before, after, "hifi_down"), levels[-1]
    crossed = next(t for t, lv, _ in levels if lv < 0.5)
    assert close.t < crossed < release.t
    assert data.warning.number.sum() == 0
    with pytest.raises(SimenvError, match="already quiet"):
        plan_hifi_down(room, data)


def test_hifi_across_the_room_is_out_of_seated_reach(tmp_path):
    text = Path(load_scenario("default").source).read_text()
    far = text.replace("position = [0.75, -0.3]", "position = [-1.8, 1.6]").replace(
        "yaw_deg = 90.0 ", "yaw_deg = -90.0 ")
    assert far != text
    (tmp_path / "far.toml").write_text(far)
    room = Room(load_scenario(tmp_path / "far.toml"))
    with pytest.raises(SimenvError, match="out of the seated agent's"):
        plan_hifi_down(room, _settled(room))


def test_reactions_in_sequence_plan_from_the_state_they_find():
    """A greeting leaves the chair turned by ~11 deg (measured: the untwisting feet slip);
    the next reactions plan from the state they find and still succeed: cigarette out,
    then hi-fi down."""
    room = Room("discomfort")
    data = _settled(room)
    for _ in _play(room, data, plan_greet(room, data)):
        pass
    for planner, reaction in ((plan_cigarette_out, "cigarette_out"),
                              (plan_hifi_down, "hifi_down")):
        before = room.object_labels(data)
        for _ in _play(room, data, planner(room, data)):
            pass
        assert object_success(room, before, room.object_labels(data), reaction), reaction
    assert data.warning.number.sum() == 0


def test_agent_bows_back_seated(room: Room):
    """The user behind the agent's right: the seated agent turns to it (planted feet turn
    the swivel, the spine the rest), nods (neck flexion, trunk leaning away from the
    user's side to stay on the seat) and comes back up; Room.bow_meter measures it. A
    greeting, which turns the same way without nodding, is not a bow."""
    assert PLANNERS["bow_back"] is plan_bow_back
    data = _settled(room)
    plan = plan_bow_back(room, data)
    meter = room.bow_meter()
    pelvis_z, success_at = [], None
    for t, _ in _play(room, data, plan):
        if meter(data)["success"] and success_at is None:
            success_at = t
        pelvis_z.append(float(data.qpos[room.agent_qpos][2]))
    assert meter.bowed and meter.dip_max_deg >= 15.0, meter.dip_max_deg
    assert success_at is not None and success_at < plan.duration
    assert min(pelvis_z) > 0.95 * pelvis_z[0]  # still seated: it did not tip off the chair
    assert room.facing_deg(data) > 90.0  # turned back to the desk
    assert np.abs(data.xfrc_applied).max() == 0.0 and data.warning.number.sum() == 0
    data = _settled(room)
    greeting = room.bow_meter()
    for _ in _play(room, data, plan_greet(room, data)):
        greeting(data)
    assert not greeting.bowed and greeting.dip_max_deg < 15.0


def test_real_bow_is_bowed_back(shared_data):
    """A real Florence 3D "bow" recording (subject 1, its hips' midpoint as the pelvis) as
    the session, labelled bow, in the default scenario: the decision starts bow_back and
    the agent, measured step by step with Room.bow_meter, turns to the user, nods and
    comes back up, seated."""
    import simenv.io.florence3d as florence3d
    from simenv.core.motion import Motion
    from simenv.core.skeletons import Skeleton
    from simenv.envs.interaction_room import InteractionRoomEnv
    from simenv.room.session import PERCEPTION_FPS, GestureEvent

    clips = florence3d.read(shared_data / "gestures" / "florence3d" / "skeletal_data.mat")
    raw = clips[25]  # video id 26: subject 1's first bow (index.csv)
    # Florence has no pelvis joint; retargeting needs one: the hips' midpoint.
    sk = raw.skeleton
    hips = [sk.joint_names.index(n) for n in ("LeftHip", "RightHip")]
    skeleton = Skeleton("florence15+pelvis", (*sk.joint_names, "Pelvis"), (*sk.parents, 2),
                        {**sk.canonical, "pelvis": "Pelvis"})
    pelvis = raw.positions[:, hips].mean(axis=1, keepdims=True)
    bow = Motion(np.concatenate([raw.positions, pelvis], axis=1), raw.fps, skeleton,
                 name=raw.name)
    env = InteractionRoomEnv(bow, gestures=[GestureEvent("bow", 0.0, bow.duration)])
    env.reset(seed=0)
    act, decide = env.reactions.index("bow_back"), int(round(0.2 * PERCEPTION_FPS))
    meter, k, truncated, z0 = env.room.bow_meter(), 0, False, None
    while not truncated:
        *_, truncated, info = env.step(act if k == decide else 0)
        k += 1
        if k > decide:
            z0 = z0 or float(env.data.qpos[env.room.agent_qpos][2])
            meter(env.data)
    (entry,) = env.log
    assert entry["started"] and entry["gesture"] == "bow"
    assert meter.success and meter.dip_max_deg >= 15.0, meter.dip_max_deg
    assert float(env.data.qpos[env.room.agent_qpos][2]) > 0.95 * z0

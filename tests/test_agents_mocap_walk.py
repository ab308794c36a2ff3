"""The room agent walks at a person's pace (simenv.agents.mocap_walk): primitives of the
real CMU 02_01 walk, tracked offline by the unassisted planner on the agent's body,
replayed with time-varying feedback; nothing but the agent's servos and its contacts acts
on it. The long walks are measured in benchmarks/bench_mocap_walk.py."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest

import simenv
from simenv.agents.gait import standing_agent
from simenv.agents.mocap_walk import (
    ANCHOR_KEYPOINTS,
    ARRIVE_M,
    OVERSHOOT_M,
    SEAM_TOL_RAD,
    MocapWalkPlan,
    _swap,
    anchors_of,
    compose,
    fit_frame,
    load_library,
    mirror,
    plan_mocap_walk,
    plan_person_walk,
    seam_rms,
)
from simenv.assets import WALK, asset_path
from simenv.body.humanoid import BodyDimensions
from simenv.body.retarget import retarget_motion
from simenv.core.errors import SimenvError
from simenv.room.room import Room
from simenv.room.scenario import load_scenario

#: Along the south wall of the discomfort room, east of the user, clear of the furniture
#: (standing closer to the wall, the rest pose's hand touches it).
START = np.array([-0.3, -1.4])
EAST = 0.0


@pytest.fixture(scope="module")
def lib():
    return load_library()


def test_library_walks_at_a_persons_pace_and_joins_at_its_phases(lib):
    prims = lib.primitives
    for name, p in prims.items():
        assert len(p.qpos) == len(p.qvel) == len(p.ctrl) == len(p.coef), name
        assert np.isfinite(p.qpos).all() and np.isfinite(p.coef).all(), name
        assert {p.phase_in, p.phase_out} <= {"left", "right", "stand"}, name
    # Every tracked primitive has its mirror image, joining at the other foot.
    for name in [n for n in prims if not n.endswith("_mirrored")]:
        m = prims[f"{name}_mirrored"]
        assert m.mirrored and m.advance[1] == -prims[name].advance[1]
    # Each stop starts on the last state of the piece it was tracked after, and every
    # walking piece has a stop and a next piece starting on its last state (the pieces
    # join only there), except the last cycle of the tracked run.
    stops = {p.after: p for p in prims.values() if p.phase_out == "stand"}
    for name, stop in stops.items():
        assert stop.phase_in == prims[name].phase_out
        np.testing.assert_allclose(stop.qpos[0, 2:], prims[name].qpos[-1, 2:], atol=1e-6)
    walking = [n for n, p in prims.items() if p.phase_out != "stand"]
    for name in walking:
        nxt = [b for b in prims if seam_rms(prims[name], prims[b]) <= SEAM_TOL_RAD
               and prims[b].phase_in == prims[name].phase_out]
        assert any(prims[b].phase_out == "stand" for b in nxt), name
    assert seam_rms(prims["start"], prims["half_c"]) <= SEAM_TOL_RAD
    assert seam_rms(prims["half_c"], prims["half_b"]) <= SEAM_TOL_RAD
    # Mirrored and tracked pieces differ at the same phase by up to 1.7 rad (the neck's
    # side bend, measured): they never join.
    assert seam_rms(prims["start"], prims["half_b_mirrored"]) > 0.3
    # A gait cycle covers at least 0.8 m/s.
    cycle = prims["straight"]
    assert cycle.advance[0] / lib.seconds("straight") >= 0.8
    # The bends turn the heading, each its way.
    assert prims["left"].advance[2] > 0 > prims["left_mirrored"].advance[2]


def test_mirror_reflects_the_body_onto_its_twin(room):
    h = room.agent
    q = retarget_motion(simenv.load(asset_path(WALK)).slice(0, 13), h).qpos
    mq, _, _ = mirror(q, np.zeros((len(q), h.nv)), q[:, 7:], list(h.joint_names))
    m, d = h.model, mujoco.MjData(h.model)
    names = [m.geom(i).name for i in range(m.ngeom)]
    twin = [names.index(_swap(g)) for g in names]
    for t in range(len(q)):
        d.qpos[:] = q[t]
        mujoco.mj_kinematics(m, d)
        reflected = d.geom_xpos * [1.0, -1.0, 1.0]
        d.qpos[:] = mq[t]
        mujoco.mj_kinematics(m, d)
        np.testing.assert_allclose(d.geom_xpos[twin], reflected, atol=1e-9)


def _compose_check(lib, room, goals):
    anc = anchors_of(lib, room.agent)
    names = list(room.agent.keypoint_names)
    standing = room.agent.keypoints(room.agent.default_qpos())
    kp = standing[[names.index(k) for k in ANCHOR_KEYPOINTS], :2]
    step = lib.primitives["straight"].advance[0] / 2
    for goal in goals:
        seq, err = compose(anc, kp, np.array(goal))
        assert lib.primitives[seq[0]].phase_in == "stand"
        assert lib.primitives[seq[-1]].phase_out == "stand"
        for a, b in zip(seq, seq[1:], strict=False):
            assert lib.primitives[a].phase_out == lib.primitives[b].phase_in
        # Every seam joins a piece to one that starts on its last tracked state.
        for a, b in zip(seq, seq[1:], strict=False):
            assert seam_rms(lib.primitives[a], lib.primitives[b]) <= SEAM_TOL_RAD, seq
        end = anc.predicted_end(seq, fit_frame(anc.first[seq[0]], kp))
        assert np.linalg.norm(end - goal) == pytest.approx(err)
        assert err <= step / 2 + 0.1, (goal, seq, err)


@pytest.mark.xfail(strict=True, reason="pieces join only in the order they were tracked: "
                   "composed walks end 1.5, 2.2, 3.5, 3.6, 4.2, 4.9 or 6.2 m ahead; 3.0 m is "
                   "missed by 0.54 m")
def test_compose_ends_within_half_a_step_of_the_goal(lib, room):
    _compose_check(lib, room, ([3.0, 0.0], [4.0, -0.8]))


@pytest.mark.xfail(strict=True, reason="the walk heads where the body faces and bends "
                   "only in its 4th cycle: a goal 2.2 m ahead and 0.6 m aside is missed by "
                   "0.54 m")
def test_compose_reaches_a_near_goal_to_the_side(lib, room):
    _compose_check(lib, room, ([2.2, 0.6],))


def test_compose_never_passes_a_goal_in_front_of_a_wall(lib, room):
    """With ``overshoot_m`` no composed walk is predicted to end past the goal: a goal
    nearer than the shortest walk has none, a farther one the nearest that stays short."""
    anc = anchors_of(lib, room.agent)
    names = list(room.agent.keypoint_names)
    standing = room.agent.keypoints(room.agent.default_qpos())
    kp = standing[[names.index(k) for k in ANCHOR_KEYPOINTS], :2]
    ahead = np.array([1.0, 0.0])  # the rest pose faces +x
    seq, err = compose(anc, kp, kp[0] + 1.2 * ahead, overshoot_m=OVERSHOOT_M)
    assert seq is None and err == np.inf
    free, _ = compose(anc, kp, kp[0] + 3.0 * ahead)
    seq, _ = compose(anc, kp, kp[0] + 3.0 * ahead, overshoot_m=OVERSHOOT_M)
    for s in (free, seq):
        assert s is not None
    end = anc.predicted_end(seq, fit_frame(anc.first[seq[0]], kp))
    assert (end - kp[0]) @ ahead <= 3.0 + OVERSHOOT_M
    free_end = anc.predicted_end(free, fit_frame(anc.first[free[0]], kp))
    assert (free_end - kp[0]) @ ahead > 3.0 + OVERSHOOT_M  # the guard changed the choice


def _open_room():
    s = load_scenario("discomfort")
    return Room(replace(s, name="open_floor", room=replace(s.room, size=(16.0, 16.0))))


def _play(room, data, plan):
    dt = room.model.opt.timestep
    i = 0
    while i * dt < plan.duration:
        data.ctrl[room.agent_ctrl] = plan.control(i * dt, data)
        mujoco.mj_step(room.model, data)
        i += 1
    return i * dt


def test_person_walk_leaves_a_near_goal_to_the_stepping_gait():
    """A goal 0.2 m ahead, nearer than the shortest walk of the primitives: the stepping
    gait walks there alone, no help, and arrives."""
    room = _open_room()
    start = np.array([-6.0, -4.0])
    data = standing_agent(room, start, EAST)
    plan = plan_person_walk(room, data, start + [0.2, 0.0], EAST)
    _play(room, data, plan)
    assert [s[0] for s in plan.stages] == ["step"]
    out = plan.feedback.outcome(data)
    assert out["success"] and not out["fell"], out
    assert plan.feedback.summary()["max_n"] == 0.0


def test_person_walk_turns_then_walks_at_pace_to_a_goal_aside():
    """A goal 4 m ahead and 1.5 m aside on open floor: a stepping turn on the spot to face
    it, then the primitives' walk; no fall, no help, at several times the stepping gait's
    0.04 m/s, ending within a half cycle's advance of the goal. The stepping gait cannot
    take over from the walk's stance in stride (its first weight shift is out of the
    legs' reach): the correction is refused and reported."""
    room = _open_room()
    start = np.array([-6.0, -4.0])
    data = standing_agent(room, start, EAST)
    goal = start + [4.0, 1.5]
    plan = plan_person_walk(room, data, goal, float(np.arctan2(1.5, 4.0)))
    t = _play(room, data, plan)
    assert [s[0] for s in plan.stages] == ["turn", "mocap"]
    out = plan.feedback.outcome(data)
    assert not out["fell"], out
    assert plan.feedback.summary()["max_n"] == 0.0
    half = plan.lib.primitives["half_b"].advance[0]
    assert out["goal_error_m"] <= half, out
    assert out["goal_error_m"] > ARRIVE_M and plan.refused is not None
    assert np.linalg.norm(data.qpos[room.agent_qpos][:2] - start) / t > 0.15


def test_walks_two_metres_and_stops_unassisted_at_pace():
    room = Room("discomfort")
    data = standing_agent(room, START, EAST)
    plan = MocapWalkPlan(room, data, ["start", "stop_after_start"])
    dt = room.model.opt.timestep
    for i in range(int(round(plan.duration / dt))):
        data.ctrl[room.agent_ctrl] = plan.control(i * dt, data)
        mujoco.mj_step(room.model, data)
    out = plan.feedback.outcome(data)
    assert not out["fell"], out
    a = plan.feedback.summary()
    assert a["steps"] == int(round(plan.duration / dt))
    assert a["max_n"] == 0.0 and a["max_torque_nm"] == 0.0
    assert not data.xfrc_applied.any() and not data.qfrc_applied.any()
    moved = data.qpos[room.agent_qpos][:2] - START
    assert moved[0] > 2.0 and abs(moved[1]) < 0.4, moved
    assert moved[0] / plan.duration > 0.3  # standing start and stop included


def test_composed_walk_joins_its_pieces_at_pace_and_stands():
    """A 3.6 m goal on open floor: the start, two half cycles and a stop, each piece
    starting on the last tracked state of the one before; no fall, no help, and the end
    within half a half-cycle's advance of where the composition predicted."""
    room = _open_room()
    start = np.array([-6.0, -4.0])
    data = standing_agent(room, start, EAST)
    plan = plan_mocap_walk(room, data, start + [3.6, 0.0])
    anc = plan.anchors
    kp = data.site_xpos[room.agent_sites[anc.sites], :2].copy()
    _play(room, data, plan)
    assert len(plan.seams) >= 3, plan.names  # two seams between walking pieces at least
    out = plan.feedback.outcome(data)
    assert not out["fell"], (plan.names, out)
    assert plan.feedback.summary()["max_n"] == 0.0
    end = data.qpos[room.agent_qpos][:2]
    # (the walk as played: its tail may have been re-chosen at a seam)
    predicted = anc.predicted_end(plan.names, fit_frame(anc.first[plan.names[0]], kp))
    half = plan.lib.primitives["half_b"].advance[0]
    assert np.linalg.norm(end - predicted) <= half / 2, (plan.names, end, predicted)
    assert np.linalg.norm(end - start) / plan.duration > 0.4  # standing start and stop


def test_refuses_a_body_it_was_not_built_for_and_a_fallen_agent():
    tall = Room("discomfort", agent=BodyDimensions.from_scale({"left_knee": 1.1,
                                                               "right_knee": 1.1}))
    data = standing_agent(tall, START, EAST)
    with pytest.raises(SimenvError, match="another body"):
        plan_mocap_walk(tall, data, START + [2.0, 0.0])
    room = Room("discomfort")
    data = room.make_data()
    room.reset(data)  # seated
    with pytest.raises(SimenvError, match="not standing"):
        plan_mocap_walk(room, data, START)

"""Back to the chair (simenv.agents.seat): after closing the window or drawing the curtain
the agent turns on its feet, walks back between the chair and the desk, steps onto the
spot in front of the seat facing the desk, sits down, and rolls the chair back to the
desk with its heels; measured in simulation."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import pytest

import simenv
from simenv.agents.curtain import curtain_spot
from simenv.agents.seat import (
    CHAIR_AT_DESK_M,
    RETURN_STAGES,
    chair_from_desk,
    plan_roll_in,
    plan_settle,
    plan_step,
    seated_on_chair,
)
from simenv.agents.stand import plan_sit_down, plan_stand_up, standing
from simenv.agents.window import window_spot
from simenv.assets import WALK, asset_path
from simenv.core.errors import SimenvError
from simenv.envs.interaction_room import InteractionRoomEnv
from simenv.room.room import Room
from simenv.room.session import PERCEPTION_FPS, GestureEvent


def _run(room: Room, data: mujoco.MjData, plan) -> dict[str, Any]:
    """Play a plan on the agent as the environment does (targets every physics step); its
    measured external help, if it measures it, and the pelvis's path."""
    dt = room.model.opt.timestep
    lowest = np.inf
    for i in range(int(round(plan.duration / dt))):
        data.ctrl[room.agent_ctrl] = plan.control(i * dt, data)
        mujoco.mj_step(room.model, data)
        lowest = min(lowest, float(data.qpos[room.agent_qpos][2]))
    summary = getattr(plan.feedback, "summary", None)
    return {"assistance": summary() if summary else None, "lowest_pelvis_m": lowest}


def _react_and_return(env: InteractionRoomEnv, reaction: str, act: str
                      ) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """Decide ``reaction`` 0.3 s in and step the environment until the reaction is over
    (its chain: stand, walk, act, then the return stages, the user holding its last pose);
    the log entry and every stage's record by name, with the lowest pelvis height seen
    while the stage ran."""
    env.reset(seed=0)
    decide, k = int(round(0.3 * PERCEPTION_FPS)), 0
    action = env.reactions.index(reaction)
    lowest: dict[str, float] = {}
    while True:
        *_, truncated, _ = env.step(action if k == decide else 0)
        assert env.agent_assistance_n() == 0.0  # no help at any step
        k += 1
        if env.log and env.log[0].get("stages"):
            name = env.log[0]["stages"][-1]["stage"]
            z = float(env.data.qpos[env.room.agent_qpos][2])
            lowest[name] = min(lowest.get(name, np.inf), z)
        if truncated or (env.log and env.log[0]["success"] is not None):
            break
    (entry,) = env.log
    assert entry["success"] is True  # the object changed because of the hand
    assert [s["stage"] for s in entry["stages"]] == ["stand_up", "walk", act,
                                                     *(n for n, _ in RETURN_STAGES)]
    assert entry["returned"] is True and entry["stages"][-1]["outcome"]["success"]
    return entry, {s["stage"]: {**s, "lowest_pelvis_m": lowest[s["stage"]]}
                   for s in entry["stages"]}


def _assert_seated(env: InteractionRoomEnv, stages: dict[str, dict[str, Any]]) -> None:
    seat = seated_on_chair(env.room, env.data)
    assert seat["success"], seat
    assert seat["seat_contact"] and not seat["fallen"]
    assert abs(seat["pelvis_height_error_m"]) < 0.05 and seat["seat_distance_m"] < 0.15
    assert env.data.warning.number.sum() == 0
    # External help per stage, measured every physics step: none (the turns and the walk
    # back are on the agent's own legs; the sitting measures nothing, it has no help).
    for name in ("turn_away", "walk_back", "turn_to_desk"):
        a = stages[name]["assistance"]
        assert a["steps"] > 0 and a["max_n"] == 0.0 and a["max_torque_nm"] == 0.0, (name, a)
        assert not stages[name]["outcome"]["fell"]
    assert "assistance" not in stages["sit_down"] and "assistance" not in stages["settle"]
    # Rolled back to the desk with heel pulls on the agent's own legs, measured every step.
    roll = stages["roll_in"]
    assert roll["assistance"]["steps"] > 0 and roll["assistance"]["max_n"] == 0.0, roll
    assert roll["assistance"]["max_torque_nm"] == 0.0
    assert roll["assistance"]["grasp_max_n"] == 0.0  # no hand held anything
    assert stages["settle"]["outcome"]["chair_from_desk_m"] > 0.4  # sitting pushed it back
    assert roll["outcome"]["chair_from_desk_m"] <= CHAIR_AT_DESK_M
    assert chair_from_desk(env.room, env.data) <= CHAIR_AT_DESK_M
    assert all(s["lowest_pelvis_m"] > 0.85 for n, s in stages.items()
               if n in ("turn_away", "walk_back", "turn_to_desk"))  # standing throughout


@pytest.mark.parametrize(("label", "reaction", "act"), [("cold", "close_window", "push"),
                                                        ("bright", "close_curtain", "pull")])
def test_act_then_walk_back_and_sit_on_the_chair(label: str, reaction: str, act: str):
    """The real CMU walk's first half second labelled ``label`` (discomfort scenario): the
    reaction's chain stands, walks to the object on its own legs, acts with the hand (its
    object changes: the window's push, the curtain's pull through the palm's grasp), then
    returns and sits."""
    short = simenv.load(asset_path(WALK)).slice(0, 60)  # the user stays far away
    env = InteractionRoomEnv(short, gestures=[GestureEvent(label, 0.2, 0.5)],
                             scenario="discomfort", predictor="constant-velocity-50")
    # The reaction the scenario answers ``label`` with (what the labels agent of
    # simenv.envs.rehearsal decides).
    assert env.scenario.behaviour.reaction_for(label).name == reaction
    entry, stages = _react_and_return(env, reaction, act)
    assert entry["started"] and entry["gesture"] == label
    assert "assistance" not in stages["stand_up"]  # standing up has no help to measure
    walk = stages["walk"]
    assert not walk["outcome"]["fell"], entry.get("failed_stage")
    assert walk["assistance"]["steps"] > 0 and walk["assistance"]["max_n"] == 0.0
    # and per frame of the walk (20 physics steps), as summary.json records it
    assert len(walk["assistance"]["per_frame_n"]) == -(-walk["assistance"]["steps"] // 20)
    start = Room("discomfort")  # where the spot is with the objects as at the start
    d0 = start.make_data()
    mujoco.mj_forward(start.model, d0)
    spot, _ = (window_spot if act == "push" else curtain_spot)(start, d0)
    assert np.linalg.norm(np.asarray(walk["pelvis_end"][:2]) - spot) < 0.15
    # The object changed because of the hand, after the walk, and stays changed.
    act_start = entry["t_decision"] + stages["stand_up"]["duration_s"] + walk["duration_s"]
    assert entry["t_object_changed"] > act_start
    if act == "pull":
        assert entry["grasped"] is True  # the curtain is drawn through the palm's grasp
    assert env.room.object_labels(env.data)[reaction.split("_")[1]] == "closed"
    assert entry["assistance"]["max_bw"] == 0.0
    _assert_seated(env, stages)


def test_stepping_turn_re_places_the_feet():
    """A quarter turn on the spot after standing up: the heading turns, each foot leaves
    the floor and lands turned with the body, on its own legs (no help, measured)."""
    room = Room("default")
    data = room.make_data()
    for _ in range(250):
        mujoco.mj_step(room.model, data)
    _run(room, data, plan_stand_up(room, data))
    assert standing(room, data)["success"]
    h = room.agent
    ankles = [room.agent_sites[h.keypoint_names.index(f"{s}_ankle")] for s in ("left", "right")]
    start_z = data.site_xpos[ankles, 2].copy()
    q = data.qpos[room.agent_qpos]
    plan = plan_step(room, data, q[:2].copy(), np.pi / 2)
    dt, lift = room.model.opt.timestep, np.zeros(2)
    for i in range(int(round(plan.duration / dt))):
        data.ctrl[room.agent_ctrl] = plan.control(i * dt, data)
        mujoco.mj_step(room.model, data)
        lift = np.maximum(lift, data.site_xpos[ankles, 2] - start_z)
    assert (lift > 0.03).all(), lift  # both feet stepped
    pelvis = data.xmat[room.model.body("agent/pelvis").id].reshape(3, 3)[:2, 0]
    assert np.rad2deg(np.arctan2(pelvis[1], pelvis[0])) == pytest.approx(90.0, abs=12.0)
    feet = data.xmat[[room.model.body(f"agent/{s}_foot").id for s in ("left", "right")]]
    for m in feet:  # each foot's long axis turned with the body
        fwd = m.reshape(3, 3)[:2, 0]
        assert abs(np.rad2deg(np.arctan2(fwd[1], fwd[0])) - 90.0) < 25.0
    a = plan.feedback.summary()
    assert a["steps"] > 0 and a["max_n"] == 0.0 and a["max_torque_nm"] == 0.0
    assert not plan.feedback.outcome(data)["fell"]


def test_seated_agent_rolls_the_chair_back_to_the_desk():
    """Stand up (the feet push the chair ~0.4 m back), sit straight back down (on to ~0.5
    m), then the seated agent's heel pulls roll it back to the desk: within
    CHAIR_AT_DESK_M (0.1 m) of where it started, seated, and with no help on any physics
    step (no applied force or torque, no equality but grasps, and no grasp closed)."""
    room = Room("discomfort")
    data = room.make_data()
    for _ in range(250):
        mujoco.mj_step(room.model, data)
    for plan in (plan_stand_up(room, data), plan_sit_down(room, data),
                 plan_settle(room, data)):
        _run(room, data, plan)
    start = chair_from_desk(room, data)
    assert start > 0.4 and seated_on_chair(room, data)["success"]
    plan = plan_roll_in(room, data)
    run = _run(room, data, plan)
    out = plan.feedback.outcome(data)
    assert out["chair_start_m"] == pytest.approx(start)
    assert out["chair_from_desk_m"] <= CHAIR_AT_DESK_M, out
    assert out["chair_at_desk"] and out["success"] and out["seat_contact"] and not out["fallen"]
    assert out["seat_distance_m"] < 0.15 and abs(out["pelvis_height_error_m"]) < 0.05
    a = run["assistance"]
    assert a["steps"] == int(round(plan.duration / room.model.opt.timestep))
    assert a["max_n"] == 0.0 and a["max_torque_nm"] == 0.0 and a["grasp_max_n"] == 0.0
    assert room.assist_wrench(data) == (0.0, 0.0)
    assert run["lowest_pelvis_m"] > 0.5  # seated throughout (seated pelvis 0.57 m)
    assert data.warning.number.sum() == 0
    # At the desk already, the stage only settles into the seated pose.
    assert plan_roll_in(room, data).duration == pytest.approx(2.0)


def test_roll_in_needs_a_seated_agent():
    room = Room("discomfort")
    data = room.make_data()
    q = room.agent.default_qpos()
    q[:2] = [-1.0, -0.5]
    data.qpos[room.agent_qpos] = q
    mujoco.mj_forward(room.model, data)
    with pytest.raises(SimenvError, match="not seated"):
        plan_roll_in(room, data)


def test_seated_measure():
    """Settled in the initial seated pose the measure holds; standing it does not."""
    room = Room("discomfort")
    data = room.make_data()
    for _ in range(250):
        mujoco.mj_step(room.model, data)
    s = seated_on_chair(room, data)
    assert s["success"] and s["seat_contact"] and not s["fallen"]
    q = room.agent.default_qpos()
    q[:2] = [-1.0, -0.5]
    data.qpos[room.agent_qpos] = q
    mujoco.mj_forward(room.model, data)
    assert not seated_on_chair(room, data)["success"]

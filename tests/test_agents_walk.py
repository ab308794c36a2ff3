"""The agent stands up, walks to the window along a retargeted real walk (measured root
assistance) and tries to slide it shut, triggered by a ``cold`` label in the discomfort
scenario (simenv.agents.walk, simenv.agents.window)."""

from __future__ import annotations

import numpy as np

import simenv
from simenv.assets import WALK, asset_path
from simenv.envs.interaction_room import InteractionRoomEnv
from simenv.session import PERCEPTION_FPS, GestureEvent


def test_cold_label_stands_walks_to_the_window_with_measured_assistance():
    # The real CMU walk's first half second, labelled "cold" (the user stays far away).
    short = simenv.load(asset_path(WALK)).slice(0, 60)
    env = InteractionRoomEnv(short, gestures=[GestureEvent("cold", 0.2, 0.5)],
                             scenario="discomfort", predictor="constant-velocity-50")
    from simenv.agents.window import window_spot

    env.reset(seed=0)
    spot, _ = window_spot(env.room, env.data)
    decide, k, truncated = int(round(0.3 * PERCEPTION_FPS)), 0, False
    act = env.reactions.index("close_window")
    while not truncated and not (env.log and env.log[0]["success"] is not None):
        *_, truncated, info = env.step(act if k == decide else 0)
        k += 1
    (entry,) = env.log
    assert entry["started"] and entry["gesture"] == "cold"
    stages = {s["stage"]: s for s in entry["stages"]}
    assert "assistance" not in stages["stand_up"]  # standing up is unassisted
    walk = stages["walk"]
    # The walk ends at the spot in front of the window, measured in simulation.
    assert np.linalg.norm(np.asarray(walk["pelvis_end"][:2]) - spot) < 0.15
    a = walk["assistance"]
    assert a["steps"] > 0 and 0.0 < a["mean_bw"] <= a["max_bw"]
    # A stepping turn, then a first step lifting the front foot onto the clip's first
    # pose, instead of blending the planted feet round and apart (measured: 5.8 -> 2.6
    # body weights at the peak).
    assert a["max_bw"] < 4.0
    assert entry["assistance"]["max_n"] >= a["max_n"]
    # The return to the chair follows (tests/test_agents_seat.py).
    assert [s["stage"] for s in entry["stages"]][:3] == ["stand_up", "walk", "push"]
    # Success is what the window's joint says (measured: the hand pushes it shut).
    assert entry["success"] == (info["object_labels"]["window"] == "closed")
    assert entry["success"] is True and entry["t_object_changed"] > entry["t_decision"]
    assert env.room.assist_wrench(env.data) == (0.0, 0.0)  # released at the end


def test_bright_label_draws_the_curtain_through_the_grasp():
    """Discomfort scenario, "bright" on the real walk: stand up, walk to the curtain, the
    palm's proximity grasp closes on its edge and the hand draws it past its threshold."""
    short = simenv.load(asset_path(WALK)).slice(0, 60)
    env = InteractionRoomEnv(short, gestures=[GestureEvent("bright", 0.2, 0.5)],
                             scenario="discomfort", predictor="constant-velocity-50")
    env.reset(seed=0)
    decide, k, truncated = int(round(0.3 * PERCEPTION_FPS)), 0, False
    act = env.reactions.index("close_curtain")
    while not truncated and not (env.log and env.log[0]["success"] is not None):
        *_, truncated, info = env.step(act if k == decide else 0)
        k += 1
    (entry,) = env.log
    assert [s["stage"] for s in entry["stages"]][:3] == ["stand_up", "walk", "pull"]
    assert entry["grasped"] is True
    assert entry["success"] is True and info["object_labels"]["curtain"] == "closed"
    pull_start = entry["t_decision"] + sum(s["duration_s"] for s in entry["stages"][:2])
    assert entry["t_object_changed"] > pull_start
    assert entry["assistance"]["max_bw"] > 0


def test_walk_refuses_a_body_that_is_not_standing():
    """The seated agent (pelvis on the chair) is not walked anywhere by the weld."""
    import pytest

    from simenv.agents.walk import plan_walk
    from simenv.errors import SimenvError
    from simenv.room import Room

    room = Room("discomfort")
    data = room.make_data()
    with pytest.raises(SimenvError, match="not standing"):
        plan_walk(room, data, np.array([-1.0, 1.5]), np.pi / 2)

"""Seated idling (simenv.agents.idle): typing taps and a glance at the notebook, measured
in simulation; the environment idles between reactions."""

from __future__ import annotations

import mujoco
import numpy as np

from simenv.agents.idle import GLANCE_TURN_S, SETTLE_S, TYPE_S, notebook_bearing, plan_idle
from simenv.agents.seat import seated_on_chair
from simenv.envs.interaction_room import InteractionRoomEnv
from simenv.room.room import Room


def test_idle_cycle_types_glances_and_stays_seated():
    """Both wrists tap, the head turns most of the way to the notebook during the glance
    and back, and the agent stays on the chair without rolling it."""
    room = Room("default")
    m, data = room.model, room.make_data()
    for _ in range(250):
        mujoco.mj_step(m, data)
    plan = plan_idle(room, data)
    seat = m.body("chair_seat").id
    seat_start = data.xpos[seat, :2].copy()
    start = abs(notebook_bearing(room, data))
    wrists = [m.joint(f"agent/{s}_hand_flex").qposadr[0] for s in ("left", "right")]
    glance_at = SETTLE_S + TYPE_S + GLANCE_TURN_S + 0.5
    flex, bearing, seated = [], {}, True
    dt = m.opt.timestep
    for i in range(int(round(plan.duration / dt))):
        data.ctrl[room.agent_ctrl] = plan.control(i * dt, data)
        mujoco.mj_step(m, data)
        flex.append(data.qpos[wrists].copy())
        if i % 50 == 0:
            seated &= seated_on_chair(room, data)["success"]
        if abs(i * dt - glance_at) < dt / 2:
            bearing["glance"] = abs(notebook_bearing(room, data))
    flex = np.array(flex)
    assert (np.ptp(flex, axis=0) > np.deg2rad(4.0)).all(), np.rad2deg(np.ptp(flex, axis=0))
    assert start > np.deg2rad(20.0)  # the notebook is off to the side
    assert bearing["glance"] < 0.5 * start, np.rad2deg([start, bearing["glance"]])
    assert abs(notebook_bearing(room, data)) > 0.7 * start  # looked back at the keyboard
    assert seated and seated_on_chair(room, data)["success"]
    assert np.linalg.norm(data.xpos[seat, :2] - seat_start) < 0.01
    assert data.warning.number.sum() == 0


def test_environment_idles_when_no_reaction_runs():
    """With no-op actions the agent's wrists move (it types) instead of holding still."""
    env = InteractionRoomEnv(predictor="constant-velocity-50")
    env.reset(seed=0)
    m = env.model
    wrists = [m.joint(f"agent/{s}_hand_flex").qposadr[0] for s in ("left", "right")]
    flex = []
    for _ in range(75):
        env.step(0)
        flex.append(env.data.qpos[wrists].copy())
    assert (np.ptp(np.array(flex)[25:], axis=0) > np.deg2rad(3.0)).all()

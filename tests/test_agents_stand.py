"""Sit-to-stand in simulation: the legs roll the chair back, the agent leans and rises, and
centre-of-mass feedback keeps it standing (open loop it falls); then it sits back down."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from simenv.agents.stand import ComBalance, plan_sit_down, plan_stand_up, seated, standing
from simenv.room.room import Room


def _stand(room: Room, balance: bool) -> tuple[mujoco.MjData, list[dict], float]:
    data = room.make_data()
    for _ in range(250):  # 0.5 s: the seated agent settles on the chair
        mujoco.mj_step(room.model, data)
    plan = plan_stand_up(room, data, balance=balance)
    dt, states = room.model.opt.timestep, []
    roll = room.model.joint("chair/roll").qposadr[0]
    rolled = 0.0
    for i in range(int(round(plan.duration / dt))):
        data.ctrl[room.agent_ctrl] = plan.control(i * dt, data)
        mujoco.mj_step(room.model, data)
        rolled = min(rolled, float(data.qpos[roll]))
        if i % 50 == 0:
            states.append({"t": i * dt, **standing(room, data)})
    return data, states, rolled


def test_agent_stands_up_with_centre_of_mass_feedback(room: Room):
    data, states, rolled = _stand(room, balance=True)
    assert not states[0]["success"]  # seated at the start
    assert rolled < -0.2  # the legs pushed the chair back from the desk
    last = [s for s in states if s["t"] >= states[-1]["t"] - 1.5]
    assert all(s["success"] for s in last), last[-1]  # standing for the last 1.5 s
    assert abs(last[-1]["com_error_m"]) < 0.02
    assert np.abs(data.xfrc_applied).max() == 0.0  # no assistance
    assert data.warning.number.sum() == 0
    # ... and sits back down on the chair where it rolled.
    assert not seated(room, data)
    plan = plan_sit_down(room, data)
    dt = room.model.opt.timestep
    for i in range(int(round(plan.duration / dt))):
        data.ctrl[room.agent_ctrl] = plan.control(i * dt, data)
        mujoco.mj_step(room.model, data)
    assert seated(room, data)
    pelvis = data.qpos[room.agent_qpos][2]
    assert pelvis == pytest.approx(room.seated_pose()[2], abs=0.03)
    assert not standing(room, data)["success"]
    assert data.warning.number.sum() == 0


def test_open_loop_rise_falls(room: Room):
    """The same targets without the feedback tip the body forward: measured, not
    standing at the end."""
    _, states, _ = _stand(room, balance=False)
    assert not states[-1]["success"]
    assert states[-1]["com_error_m"] > 0.1 or states[-1]["other_contacts"] > 0


def test_balance_corrects_ankles_and_hips(room: Room):
    """The feedback's sign: centre of mass ahead of the feet -> plantarflex (push back);
    behind -> dorsiflex and flex the hips (lean forward); off before ``t_on``."""
    data = room.make_data()
    h = room.agent
    ankle = h.joint_names.index("left_foot_flex")
    hip = h.joint_names.index("left_thigh_flex")
    base = np.zeros(room.agent.model.nu)
    fb = ComBalance(room, t_on=1.0)
    e0 = fb.error(data)
    assert e0 < 0  # seated: the centre of mass is behind the feet
    assert np.array_equal(fb(0.5, data, base), base)
    u = fb(1.0, data, base)
    assert u[ankle] < 0 and u[hip] > 0
    # Standing, pitched 0.2 rad forward about the pelvis: the feet swing back behind it.
    q = h.default_qpos()
    q[3:7] = [np.cos(0.1), 0.0, np.sin(0.1), 0.0]
    data.qpos[room.agent_qpos] = q
    mujoco.mj_forward(room.model, data)
    assert fb.error(data) > 0
    u = ComBalance(room, t_on=0.0)(2.0, data, base)
    assert u[ankle] > 0 and u[hip] == 0

"""Seated idling: typing and glancing at the notebook, between reactions.

The issue's agent sits "at the desk, idling (typing, glancing at the notebook)" until a
gesture makes it react. :func:`plan_idle` is one idle cycle of PD targets around the seated
pose (:meth:`simenv.room.room.Room.seated_pose`, upper body gravity-compensated as every seated
plan here):

1. settle onto the seated pose from wherever the targets are (:data:`SETTLE_S`);
2. type: the wrists tap in turn, each hand flexing by :data:`TAP_RAD` and back, at
   :data:`TAP_HZ` taps per second (:data:`TYPE_S`);
3. glance: the head turns towards the notebook on the desk (its bearing from the head,
   measured in the current state, taken by ``neck_rot`` within :data:`MAX_GLANCE_RAD`) and
   tips down by :data:`GLANCE_PITCH_RAD`, holds :data:`GLANCE_HOLD_S`, and comes back;
4. type again.

The environment (:class:`simenv.envs.interaction_room.InteractionRoomEnv`) plays cycle after
cycle, each planned from the state the last one left, whenever no reaction runs; a reaction
starts from the idle's current targets and the idle takes over again when it ends. Only the
upper body moves: the legs hold the seated targets, so idling cannot roll the chair.
"""

from __future__ import annotations

import mujoco
import numpy as np

from simenv.agents.reach import PDPlan, PDTrajectory, pd_targets, upper_body_joints
from simenv.room.room import Room

#: Time to settle onto the seated pose at the start of a cycle, s.
SETTLE_S = 1.0
#: Typing before and after the glance, s each.
TYPE_S = 2.4
#: Wrist taps per second (both hands together; they alternate).
TAP_HZ = 2.5
#: Wrist flexion of one tap, rad (about 8 degrees).
TAP_RAD = 0.14
#: Largest head turn of a glance, rad (within the neck's range of 80 degrees).
MAX_GLANCE_RAD = np.deg2rad(60.0)
#: Head tip of a glance (neck flexion, forward), rad.
GLANCE_PITCH_RAD = np.deg2rad(20.0)
#: Turning the head to the notebook and back, s each; looking at it, s.
GLANCE_TURN_S = 0.7
GLANCE_HOLD_S = 1.2


def notebook_bearing(room: Room, data: mujoco.MjData) -> float:
    """Signed angle (rad, counter-clockwise about +z) from the head's forward axis to the
    notebook, in the horizontal plane, in the state ``data``."""
    m = room.model
    head = m.body("agent/head").id
    to = data.geom_xpos[m.geom("desk/notebook").id, :2] - data.xpos[head, :2]
    fwd = data.xmat[head].reshape(3, 3)[:2, 0]
    return float(np.arctan2(fwd[0] * to[1] - fwd[1] * to[0], fwd @ to))


def _neck_rot_sign(room: Room, data: mujoco.MjData) -> float:
    """+1 when raising ``neck_rot`` turns the head counter-clockwise (seen from above) in
    this state, else -1 (the hinge's axis is in the neck's frame, which leans)."""
    m = room.model
    probe = mujoco.MjData(m)
    probe.qpos[:] = data.qpos
    mujoco.mj_kinematics(m, probe)
    head = m.body("agent/head").id
    before = probe.xmat[head].reshape(3, 3)[:2, 0].copy()
    probe.qpos[m.joint("agent/neck_rot").qposadr[0]] += 0.1
    mujoco.mj_kinematics(m, probe)
    after = probe.xmat[head].reshape(3, 3)[:2, 0]
    return 1.0 if before[0] * after[1] - before[1] * after[0] > 0 else -1.0


def plan_idle(room: Room, data: mujoco.MjData) -> PDPlan:
    """One idle cycle (module docstring) from the current state.

    Returns:
        the plan of the agent's targets, ``SETTLE_S + 2 TYPE_S + 2 GLANCE_TURN_S +
        GLANCE_HOLD_S`` = 8.4 s long.
    """
    h = room.agent
    seated = pd_targets(h, room.seated_pose(), upper_body_joints(h))
    index = h.joint_names.index
    segments = [PDTrajectory(data.ctrl[room.agent_ctrl].copy(), seated, SETTLE_S)]

    def typing() -> None:
        half = 0.5 / TAP_HZ
        for k in range(int(round(TYPE_S * TAP_HZ))):
            tap = seated.copy()
            tap[index(f"{('left', 'right')[k % 2]}_hand_flex")] += TAP_RAD
            segments.append(PDTrajectory(seated, tap, half / 2))
            segments.append(PDTrajectory(tap, seated, half / 2))
            segments.append(PDTrajectory(seated, seated, half))

    typing()
    turn = np.clip(notebook_bearing(room, data), -MAX_GLANCE_RAD, MAX_GLANCE_RAD)
    look = seated.copy()
    look[index("neck_rot")] += _neck_rot_sign(room, data) * turn
    look[index("neck_flex")] += GLANCE_PITCH_RAD
    segments += [PDTrajectory(seated, look, GLANCE_TURN_S),
                 PDTrajectory(look, look, GLANCE_HOLD_S),
                 PDTrajectory(look, seated, GLANCE_TURN_S)]
    typing()
    return PDPlan(segments)


__all__ = ["notebook_bearing", "plan_idle"]

"""Scripted reactions carried out physically by the room's agent.

A reaction is planned from the current simulation state as a :class:`~simenv.agents.reach.PDPlan`
of the agent's position-servo targets: via-points of the hand solved with
:func:`~simenv.agents.reach.reach_pose`, joined by minimum-jerk segments, with the upper
body's gravity torque fed forward (:func:`~simenv.agents.reach.pd_targets`; the seated
legs rest on the chair and are not compensated). Playing the plan is the only thing the
reaction does: whether the object changes state is up to the simulated contact between the
hand and the object, and is measured, never assumed (:func:`object_success`).

Implemented: ``cigarette_out`` (seated: lift the hand off the desk, move above the
cigarette, press it into the ashtray, lift, return to the seated pose). Reactions that need
the agent to stand and walk (window, curtain, hi-fi, door, greeting the user) are planned
by later layers from reference motions of real clips.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco

from simenv.agents.reach import (
    PDPlan,
    PDTrajectory,
    arm_joints,
    pd_targets,
    reach_pose,
    upper_body_joints,
)
from simenv.errors import SimenvError
from simenv.room import Room
from simenv.scenario import REACTIONS

#: Hand clearance above the desk / the cigarette on the way, m.
LIFT_M = 0.12
APPROACH_M = 0.08
#: How far below the cigarette's top the pressing hand aims, m: the servos stop short of
#: a target they cannot reach, so aiming past the surface is what makes the hand push.
PRESS_DEPTH_M = 0.03


def plan_cigarette_out(room: Room, data: mujoco.MjData, side: str = "right") -> PDPlan:
    """Plan for pressing the cigarette out with the ``side`` hand, from the current state.

    Returns:
        the plan of the agent's targets (``data.ctrl[room.agent_ctrl]``), 3.9 s long.
    """
    h = room.agent
    q = data.qpos[room.agent_qpos].copy()
    site = f"{side}_hand"
    hand = data.site_xpos[room.agent_sites[h.keypoint_names.index(site)]].copy()
    handle = data.site_xpos[mujoco.mj_name2id(room.model, mujoco.mjtObj.mjOBJ_SITE,
                                              room.objects["cigarette"].handle)].copy()
    arm, upper = arm_joints(side), upper_body_joints(h)
    rest = pd_targets(h, room.seated_pose(), upper)
    targets, pose = [], q
    for goal in (hand + [0, 0, LIFT_M], handle + [0, 0, APPROACH_M],
                 handle - [0, 0, PRESS_DEPTH_M]):
        pose, err = reach_pose(h.model, pose, site, goal, arm)
        if err > 0.02:
            raise SimenvError(f"the cigarette is out of the agent's {side}-hand reach "
                              f"({err:.3f} m short)", field="cigarette")
        targets.append(pd_targets(h, pose, upper))
    lift, above, press = targets
    now = data.ctrl[room.agent_ctrl].copy()
    return PDPlan([PDTrajectory(now, lift, 0.6), PDTrajectory(lift, above, 0.8),
                   PDTrajectory(above, press, 0.6), PDTrajectory(press, press, 0.3),
                   PDTrajectory(press, above, 0.5), PDTrajectory(above, rest, 1.1)])


#: Reaction name -> planner (room, data) -> PDPlan.
PLANNERS: dict[str, Callable[[Room, mujoco.MjData], PDPlan]] = {
    "cigarette_out": plan_cigarette_out,
}


def object_success(room: Room, before: dict[str, str], after: dict[str, str],
                   reaction: str) -> bool:
    """Whether ``reaction``'s object went to its target label between two
    :meth:`~simenv.room.Room.object_labels` readings (False if it already was there)."""
    r = REACTIONS[reaction]
    if r.object is None:
        raise SimenvError(f"reaction {reaction!r} acts on no object", field="reaction")
    return before[r.object] != r.target and after[r.object] == r.target


__all__ = ["PLANNERS", "object_success", "plan_cigarette_out"]

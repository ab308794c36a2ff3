"""Drawing the curtain: stand up, walk to it, grasp its edge and pull it across the window,
then back to the chair (:data:`simenv.agents.seat.RETURN_STAGES`).

``close_curtain`` (:func:`plan_close_curtain`) is a :class:`~simenv.agents.reach.PlanChain`
like ``close_window`` (:mod:`simenv.agents.window`): stand up, turn on the feet and walk
(on its own legs) to a spot :data:`STAND_OFF_M` in front of the curtain's handle
(its leading edge) and :data:`ALONG_M` along its travel, then :func:`plan_curtain_pull`: the
right palm (``grip`` site) onto the handle, the proximity grasp closes there if the palm is
within the grasp radius, the hand draws the curtain along its rail towards
:data:`TARGET_FRACTION` of its travel in :data:`PULL_VIA` IK via-points, lets go and comes
back; the body stands balanced on both feet where the walk left it
(:func:`simenv.agents.walk.held_grasp_stroke`, no external help). The curtain closes only
if the hand drags it past its threshold. Then the
return to the chair.
"""

from __future__ import annotations

import mujoco
import numpy as np

from simenv.agents.gait import SteppingPlan
from simenv.agents.reach import (
    PDPlan,
    PlanChain,
    arm_joints,
    pd_targets,
    reach_pose,
    upper_body_joints,
)
from simenv.agents.seat import RETURN_STAGES, plan_turn_then_walk
from simenv.agents.stand import plan_stand_up
from simenv.agents.walk import REST_S, held_grasp_stroke, standing_targets
from simenv.agents.window import SPINE
from simenv.errors import SimenvError
from simenv.room import Room

#: Pelvis distance from the curtain's handle, across the wall, m (measured, the palm's grip
#: site when the grasp is asked for: 12.5 cm from the handle standing 0.33 m off, 5.5-6.2
#: cm at 0.38 m -- at the 6 cm grasp radius, closing or not with the decision's timing --,
#: 4.9 cm at 0.42 m).
STAND_OFF_M = 0.42
#: Where along the curtain's travel the agent stands, from the handle's position now, m.
ALONG_M = 0.30
#: The pull aims at this fraction of the curtain's travel (the ``closed`` threshold is
#: 0.75), and as far as the standing arm reaches.
TARGET_FRACTION = 0.95
#: Via-points of the pull (0.4 s each).
PULL_VIA = 10
#: The palm comes in from this far in front of the handle, m.
APPROACH_M = 0.10
#: After letting go the hand backs off the panel this far, then lowers this far, m.
BACK_OFF_M = 0.25
LOWER_M = 0.3
HAND = "right_hand"


def curtain_spot(room: Room, data: mujoco.MjData) -> tuple[np.ndarray, float]:
    """Where to stand to draw the curtain: pelvis (x, y), m, and the heading facing the
    wall, rad."""
    handle, closing, inward, _ = room.wall_slide_frame(data, "curtain")  # closes along +axis
    spot = handle + closing * ALONG_M + inward * STAND_OFF_M
    face = -inward
    return spot[:2], float(np.arctan2(face[1], face[0]))


def plan_curtain_pull(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for drawing the curtain from where the agent stands (module docstring).

    Raises:
        SimenvError: the curtain is already closed, or its handle is out of the standing
            agent's reach (IK more than 3 cm short); the pull stops at the last via-point
            within reach and fails if that is not past the ``closed`` threshold.
    """
    m, h, c = room.model, room.agent, room.objects["curtain"]
    handle, closing, inward, state = room.wall_slide_frame(data, "curtain")
    if state > c.threshold:
        raise SimenvError("the curtain is already closed", field="curtain")
    joints = [f"agent/{j}" for j in (*arm_joints(HAND.split("_")[0]), *SPINE)]
    site = f"agent/{HAND}_grip"
    travel = TARGET_FRACTION * c.upper - state
    upper = upper_body_joints(h)
    pose = data.qpos.copy()
    targets = []
    goals = [handle + inward * APPROACH_M, handle]
    goals += [handle + closing * travel * k / PULL_VIA for k in range(1, PULL_VIA + 1)]
    reached = 0.0
    for k, goal in enumerate(goals):
        solved, err = reach_pose(m, pose, site, goal, joints, iterations=300)
        if err > 0.03:
            if k < 2:
                raise SimenvError(f"the curtain's handle is out of the standing agent's "
                                  f"reach ({err:.3f} m short)", field="curtain")
            break
        pose = solved
        reached = (k - 1) * travel / PULL_VIA
        targets.append(pd_targets(h, pose[room.agent_qpos], upper))
    if state + reached <= c.threshold:
        raise SimenvError(f"the standing agent's hand reaches {reached:.2f} m along the "
                          f"rail; the curtain needs {c.threshold - state:.2f} m",
                          field="curtain")
    before, on, *pulling = targets
    # Back off the panel before lowering the arm: swinging down to rest straight from the
    # rail, the hand brushed the curtain and dragged it back (0.93 -> 0.66 m, measured).
    last = goals[len(targets) - 1]
    back, _ = reach_pose(m, pose, site, last + inward * BACK_OFF_M, joints, iterations=300)
    low, _ = reach_pose(m, back, site, last + inward * BACK_OFF_M - [0.0, 0.0, LOWER_M],
                        joints, iterations=300)
    away, down = (pd_targets(h, p[room.agent_qpos], upper) for p in (back, low))
    rest = standing_targets(room, data)
    return held_grasp_stroke(room, data, [(before, 1.2), (on, 0.6)], pulling,
                             [(away, 0.6), (down, 0.6), (rest, REST_S)], HAND,
                             "curtain")


def plan_walk_to_curtain(room: Room, data: mujoco.MjData) -> SteppingPlan:
    """Plan for walking to :func:`curtain_spot` on the agent's own legs
    (:func:`simenv.agents.seat.plan_turn_then_walk`): out from between the desk and the
    rolled-back chair (a step towards the desk, side-steps along it), a turn on the spot
    towards the spot, the walk straight there, a turn on the spot to face the wall."""
    spot, face = curtain_spot(room, data)
    return plan_turn_then_walk(room, data, spot, face)


def plan_close_curtain(room: Room, data: mujoco.MjData) -> PlanChain:
    """``close_curtain``: stand up, walk to the curtain, draw it, go back to the chair,
    sit down and roll it in (module docstring).

    Raises:
        SimenvError: the curtain is already closed.
    """
    c = room.objects["curtain"]
    if float(data.qpos[c.qpos_adr]) > c.threshold:
        raise SimenvError("the curtain is already closed", field="curtain")
    return PlanChain((("stand_up", plan_stand_up), ("walk", plan_walk_to_curtain),
                      ("pull", plan_curtain_pull), *RETURN_STAGES))


__all__ = ["curtain_spot", "plan_close_curtain", "plan_curtain_pull", "plan_walk_to_curtain"]

"""Drawing the curtain: stand up, walk to it, grasp its edge and pull it across the window,
then back to the chair.

``close_curtain`` (:data:`plan_close_curtain`) is an
:class:`~simenv.agents.object_task.ObjectTask` like ``close_window``
(:mod:`simenv.agents.window`), specified by:

* the approach pose, :func:`curtain_spot`: :data:`STAND_OFF_M` in front of the curtain's
  handle (its leading edge) and :data:`ALONG_M` along its travel, facing the wall;
* the act ``pull``, :func:`plan_curtain_pull`: the right palm (``grip`` site) onto the
  handle, the proximity grasp closes there if the palm is within the grasp radius, the
  hand draws the curtain along its rail towards :data:`TARGET_FRACTION` of its travel in
  :data:`PULL_VIA` IK via-points, lets go and comes back; the body stands balanced on both
  feet where the walk left it (:func:`simenv.agents.walk.held_grasp_stroke`, no external
  help). The curtain closes only if the hand drags it past its threshold.
"""

from __future__ import annotations

import mujoco
import numpy as np

from simenv.agents import object_task as task
from simenv.agents.reach import PDPlan, pd_targets, reach_pose, upper_body_joints
from simenv.core.errors import SimenvError
from simenv.room.room import Room

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
#: After backing off the panel the hand lowers this far, m.
LOWER_M = 0.3


def curtain_spot(room: Room, data: mujoco.MjData) -> tuple[np.ndarray, float]:
    """Where to stand to draw the curtain: pelvis (x, y), m, and the heading facing the
    wall, rad."""
    handle, closing, inward, _ = room.wall_slide_frame(data, "curtain")  # closes along +axis
    return task.facing_wall(handle + closing * ALONG_M, inward, STAND_OFF_M)


def plan_curtain_pull(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for drawing the curtain from where the agent stands (module docstring).

    Raises:
        SimenvError: the curtain is already closed, or its handle is out of the standing
            agent's reach (IK more than 3 cm short); the pull stops at the last via-point
            within reach and fails if that is not past the ``closed`` threshold.
    """
    task.check_not_done(room, data, "close_curtain")
    m, h, c = room.model, room.agent, room.objects["curtain"]
    handle, closing, inward, state = room.wall_slide_frame(data, "curtain")
    joints = task.hand_joints()
    travel = TARGET_FRACTION * c.upper - state
    goals = [handle + inward * task.APPROACH_M, handle]
    goals += [handle + closing * travel * k / PULL_VIA for k in range(1, PULL_VIA + 1)]
    targets, pose = task.reach_via_points(room, data, task.GRIP, goals, joints, "curtain",
                                          iterations=300, required=2)
    reached = (len(targets) - 2) * travel / PULL_VIA
    if state + reached <= c.threshold:
        raise SimenvError(f"the standing agent's hand reaches {reached:.2f} m along the "
                          f"rail; the curtain needs {c.threshold - state:.2f} m",
                          field="curtain")
    before, on, *pulling = targets
    # Back off the panel before lowering the arm: swinging down to rest straight from the
    # rail, the hand brushed the curtain and dragged it back (0.93 -> 0.66 m, measured).
    away = goals[len(targets) - 1] + inward * task.BACK_OFF_M
    back, _ = reach_pose(m, pose, task.GRIP, away, joints, iterations=300)
    low, _ = reach_pose(m, back, task.GRIP, away - [0.0, 0.0, LOWER_M], joints,
                        iterations=300)
    upper = upper_body_joints(h)
    off, down = (pd_targets(h, p[room.agent_qpos], upper) for p in (back, low))
    return task.grasp_stroke(room, data, "curtain", [(before, 1.2), (on, 0.6)], pulling,
                             [(off, 0.6), (down, 0.6)])


#: ``close_curtain``: stand up, walk to :func:`curtain_spot`, :func:`plan_curtain_pull`,
#: go back to the chair, sit down and roll it in.
plan_close_curtain = task.ObjectTask("close_curtain", "pull", curtain_spot, plan_curtain_pull)


__all__ = ["curtain_spot", "plan_close_curtain", "plan_curtain_pull"]

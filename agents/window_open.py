"""Opening the window: stand up, walk to it, take the pane's handle and slide it open,
then back to the chair.

``open_window`` (:data:`plan_open_window`) is an
:class:`~simenv.agents.object_task.ObjectTask` like ``close_window``
(:mod:`simenv.agents.window`), specified by:

* the approach pose, :func:`open_spot`: :data:`STAND_OFF_M` in front of the wall and
  :data:`ALONG_M` along the pane's opening direction from its handle, facing the wall;
* the act ``pull``, :func:`plan_window_pull`: the right hand comes to the handle's side in
  the opening direction, fingers pointing into the wall and palm facing the handle (a
  handshake posture; IK on the palm's ``grip`` site together with the fingertip and wrist
  sites, so the palm, not the hand's edge, meets the handle), the proximity grasp is
  asked for there (it closes only if the grip site is within the grasp radius), the hand
  moves along the wall in the opening direction by :data:`PULL_M` in :data:`PULL_VIA` IK
  via-points, lets go, backs off and comes back to rest. Moving away from the handle's
  face, the hand can drag the pane only through the grasp. The body stands balanced on
  both feet where the walk left it (no external help).
"""

from __future__ import annotations

import mujoco
import numpy as np

from simenv.agents import object_task as task
from simenv.agents.reach import PDPlan
from simenv.room.room import Room

#: Pelvis distance from the handle, across the wall, when the agent stands at the window, m.
STAND_OFF_M = 0.40
#: Where along the pane's opening direction the agent stands, from the handle, m.
ALONG_M = 0.10
#: How far the hand slides the handle in the opening direction, m (the ``open``
#: threshold is 0.10 m; the servos lag their targets).
PULL_M = 0.35
#: Via-points of the pull along the wall (0.4 s each).
PULL_VIA = 8
#: How far into the handle's side face the grip site aims, m: the servos stop short of a
#: target they cannot reach, so aiming into the handle lays the palm on it (aiming 2 cm
#: in, the palm pushed the handle away and the grasp failed at 8.4 cm, measured).
PRESS_M = 0.01
#: How far behind the handle's centre (towards the wall) the grip site aims, m: the hand
#: stops 3-5 cm short of its target across the wall. Measured grip-site distance from the
#: handle when the grasp is asked for, over 4-5 walk endings: 2.0-2.3 cm aiming 2 cm
#: behind, 1.9-3.3 cm aiming 1 cm behind, 2.6-5.5 cm aiming at the centre (at the 6 cm
#: grasp radius), 5.8 cm aiming 2 cm in front of it.
DEPTH_M = 0.02


def open_spot(room: Room, data: mujoco.MjData) -> tuple[np.ndarray, float]:
    """Where to stand to open the window: pelvis (x, y), m, :data:`ALONG_M` along the
    opening direction from the handle and :data:`STAND_OFF_M` into the room, and the
    heading facing the wall, rad."""
    handle, opening, inward, _ = room.wall_slide_frame(data, "window")  # opens along +axis
    return task.facing_wall(handle + opening * ALONG_M, inward, STAND_OFF_M)


def _palm_sites(goal: np.ndarray, into: np.ndarray, fingers: np.ndarray) -> np.ndarray:
    """(3, 3) targets of the grip, fingertip and wrist sites putting the palm's grip site
    at ``goal`` with the palm facing ``into`` and the fingers pointing along ``fingers``
    (unit vectors, world): the hand box's centre line lies 0.019 m behind the palm (half
    its thickness plus the site's 2 mm), the fingertip site 5.1 cm beyond the grip's level
    along it and the wrist 5 cm before (the hand's geometry, see
    :meth:`simenv.room.room.Room._add_grips`)."""
    centre = goal - into * 0.019
    return np.array([goal, centre + fingers * 0.051, centre - fingers * 0.05])


def plan_window_pull(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for sliding the closed pane open from where the agent stands (module
    docstring).

    Raises:
        SimenvError: the window is already open, or the handle or the end of the pull is
            out of the standing agent's reach (IK more than 3 cm short).
    """
    task.check_not_done(room, data, "open_window")
    handle, opening, inward, now = room.wall_slide_frame(data, "window")
    sites = [task.GRIP, f"agent/{task.HAND}_tip", f"agent/{task.SIDE}_wrist"]
    half_width = float(room.model.geom("window/handle").size[0])
    # The palm on the handle's face that looks along the opening direction.
    on = handle + opening * (half_width + 0.002 - PRESS_M) - inward * DEPTH_M
    travel = min(PULL_M, room.objects["window"].upper - now)
    goals = [on + opening * task.APPROACH_M / 2 + inward * task.APPROACH_M, on]
    goals += [on + opening * travel * k / PULL_VIA for k in range(1, PULL_VIA + 1)]
    goals.append(goals[-1] + opening * task.APPROACH_M / 2 + inward * task.BACK_OFF_M)
    palms = [_palm_sites(goal, -opening, -inward) for goal in goals]
    targets, _ = task.reach_via_points(room, data, sites, palms, task.hand_joints(wrist=True),
                                       "window", iterations=400)
    before, on_t, *pulling, after = targets
    return task.grasp_stroke(room, data, "window", [(before, 1.2), (on_t, 0.6)], pulling,
                             [(after, 0.6)])


#: ``open_window``: stand up, walk to :func:`open_spot`, :func:`plan_window_pull`, go back
#: to the chair, sit down and roll it in.
plan_open_window = task.ObjectTask("open_window", "pull", open_spot, plan_window_pull)


__all__ = ["open_spot", "plan_open_window", "plan_window_pull"]

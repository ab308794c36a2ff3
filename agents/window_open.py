"""Opening the window: stand up, walk to it, take the pane's handle and slide it open.

``open_window`` (:func:`plan_open_window`) is a :class:`~simenv.agents.reach.PlanChain`
like ``close_window`` (:mod:`simenv.agents.window`), each stage planned from the state the
previous one left: three stages, then the return to the chair
(:data:`simenv.agents.seat.RETURN_STAGES`):

1. :func:`simenv.agents.stand.plan_stand_up` (sit-to-stand, no assistance);
2. :func:`plan_walk_to_open`: a stepping turn onto the heading towards the wall, then
   :func:`simenv.agents.walk.plan_walk` to a spot :data:`STAND_OFF_M` in front of the
   wall and :data:`ALONG_M` along the pane's opening direction from its handle, facing the
   wall (on the agent's own legs, :mod:`simenv.agents.gait`);
3. :func:`plan_window_pull`: the right hand comes to the handle's side in the opening
   direction, fingers pointing into the wall and palm facing the handle (a handshake
   posture; IK on the palm's ``grip`` site together with the fingertip and wrist sites, so
   the palm, not the hand's edge, meets the handle), the proximity grasp is asked for
   there (it closes only if the grip site is within the grasp radius), the hand moves
   along the wall in the opening direction by :data:`PULL_M` in :data:`PULL_VIA` IK
   via-points, lets go, backs off and comes back to rest. Moving away from the handle's
   face, the hand can drag the pane only through the grasp. The body stands balanced on
   both feet where the walk left it (no external help).
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
from simenv.agents.window import BACK_OFF_M, SPINE
from simenv.errors import SimenvError
from simenv.room import Room

#: Pelvis distance from the handle, across the wall, when the agent stands at the window, m.
STAND_OFF_M = 0.40
#: Where along the pane's opening direction the agent stands, from the handle, m.
ALONG_M = 0.10
#: How far the hand slides the handle in the opening direction, m (the ``open``
#: threshold is 0.10 m; the servos lag their targets).
PULL_M = 0.35
#: Via-points of the pull along the wall (0.4 s each).
PULL_VIA = 8
#: The palm comes in from this far in front of the handle, and backs off as far, m.
APPROACH_M = 0.10
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
HAND = "right_hand"


def open_spot(room: Room, data: mujoco.MjData) -> tuple[np.ndarray, float]:
    """Where to stand to open the window: pelvis (x, y), m, :data:`ALONG_M` along the
    opening direction from the handle and :data:`STAND_OFF_M` into the room, and the
    heading facing the wall, rad."""
    handle, opening, inward, _ = room.wall_slide_frame(data, "window")  # opens along +axis
    spot = handle + opening * ALONG_M + inward * STAND_OFF_M
    face = -inward
    return spot[:2], float(np.arctan2(face[1], face[0]))


def _palm_sites(goal: np.ndarray, into: np.ndarray, fingers: np.ndarray) -> np.ndarray:
    """(3, 3) targets of the grip, fingertip and wrist sites putting the palm's grip site
    at ``goal`` with the palm facing ``into`` and the fingers pointing along ``fingers``
    (unit vectors, world): the hand box's centre line lies 0.019 m behind the palm (half
    its thickness plus the site's 2 mm), the fingertip site 5.1 cm beyond the grip's level
    along it and the wrist 5 cm before (the hand's geometry, see
    :meth:`simenv.room.Room._add_grips`)."""
    centre = goal - into * 0.019
    return np.array([goal, centre + fingers * 0.051, centre - fingers * 0.05])


def plan_window_pull(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for sliding the closed pane open from where the agent stands (module
    docstring).

    Raises:
        SimenvError: the window is already open, or the handle or the end of the pull is
            out of the standing agent's reach (IK more than 3 cm short).
    """
    m, h, w = room.model, room.agent, room.objects["window"]
    handle, opening, inward, now = room.wall_slide_frame(data, "window")
    if now > w.threshold:
        raise SimenvError("the window is already open", field="window")
    side = HAND.split("_")[0]
    joints = [f"agent/{j}" for j in (*arm_joints(side), f"{side}_hand_flex",
                                       f"{side}_hand_dev", *SPINE)]
    sites = [f"agent/{HAND}_grip", f"agent/{HAND}_tip", f"agent/{side}_wrist"]
    half_width = float(m.geom("window/handle").size[0])
    # The palm on the handle's face that looks along the opening direction.
    on = handle + opening * (half_width + 0.002 - PRESS_M) - inward * DEPTH_M
    travel = min(PULL_M, w.upper - now)
    goals = [on + opening * APPROACH_M / 2 + inward * APPROACH_M, on]
    goals += [on + opening * travel * k / PULL_VIA for k in range(1, PULL_VIA + 1)]
    goals.append(goals[-1] + opening * APPROACH_M / 2 + inward * BACK_OFF_M)
    upper = upper_body_joints(h)
    pose = data.qpos.copy()
    targets = []
    for goal in goals:
        pose, err = reach_pose(m, pose, sites, _palm_sites(goal, -opening, -inward), joints,
                               iterations=400)
        if err > 0.03:
            raise SimenvError(f"the window's handle is out of the standing agent's reach "
                              f"({err:.3f} m short)", field="window")
        targets.append(pd_targets(h, pose[room.agent_qpos], upper))
    before, on_t, *pulling, after = targets
    rest = standing_targets(room, data)
    return held_grasp_stroke(room, data, [(before, 1.2), (on_t, 0.6)], pulling,
                             [(after, 0.6), (rest, REST_S)], HAND, "window")


def plan_walk_to_open(room: Room, data: mujoco.MjData) -> SteppingPlan:
    """Plan for walking to :func:`open_spot` on the agent's own legs, as
    :func:`simenv.agents.window.plan_walk_to_window` does
    (:func:`simenv.agents.seat.plan_turn_then_walk`)."""
    spot, face = open_spot(room, data)
    return plan_turn_then_walk(room, data, spot, face)


def plan_open_window(room: Room, data: mujoco.MjData) -> PlanChain:
    """``open_window``: stand up, walk to the window, slide it open, then go back to the
    chair, sit down and roll it in (:data:`simenv.agents.seat.RETURN_STAGES`, as ``close_window``).

    Raises:
        SimenvError: the window is already open.
    """
    w = room.objects["window"]
    if float(data.qpos[w.qpos_adr]) > w.threshold:
        raise SimenvError("the window is already open", field="window")
    return PlanChain((("stand_up", plan_stand_up), ("walk", plan_walk_to_open),
                      ("pull", plan_window_pull), *RETURN_STAGES))


__all__ = ["open_spot", "plan_open_window", "plan_walk_to_open", "plan_window_pull"]

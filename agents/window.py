"""Closing the window: stand up, walk to it, slide the pane shut with a proximity grasp,
walk back to the chair, sit down and roll the chair back to the desk.

``close_window`` (:func:`plan_close_window`) is a :class:`~simenv.agents.reach.PlanChain`
of three stages and the return (:data:`simenv.agents.seat.RETURN_STAGES`: turn, walk back,
turn to the desk, sit down, settle, roll in), each planned from the state the previous one left:

1. :func:`simenv.agents.stand.plan_stand_up` (sit-to-stand, no assistance);
2. :func:`plan_walk_to_window`: a stepping turn onto the heading towards the wall, then
   :func:`simenv.agents.walk.plan_walk` to a spot :data:`STAND_OFF_M` in front of the
   wall, :data:`ALONG_M` along the pane's travel, facing the wall (on the agent's own
   legs, :mod:`simenv.agents.gait`);
3. :func:`plan_window_push`: the right palm (``grip`` site) to the pane's handle, the
   proximity grasp is asked for there (it closes only if the palm is within the grasp
   radius; measured: the hand's box meets the handle's first and the grip site stays
   7.7-8.4 cm away, so the grasp does not close and the hand pushes the handle by contact
   instead), the hand moves along the wall by the pane's opening plus
   :data:`OVERSHOOT_M` in :data:`PUSH_VIA` IK via-points, lets go and comes back. The
   body stands balanced on both feet where the walk left it (the gait's centre-of-mass
   feedback, :func:`simenv.agents.walk.held_grasp_stroke`; no external help). The pane
   closes only if the grasp closed and the hand dragged it.
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
from simenv.errors import SimenvError
from simenv.room import Room

#: Pelvis distance from the handle, across the wall, when the agent stands at the window, m.
STAND_OFF_M = 0.38
#: Where along the pane's travel the agent stands, from the handle's open position, m
#: (nearer the start than the middle: the closed end is by the hanging curtain, which the
#: arm otherwise hits).
ALONG_M = 0.15
#: The hand slides the pane this far past its closed position (the servos lag), m.
OVERSHOOT_M = 0.0
#: Via-points of the push along the wall (0.4 s each).
PUSH_VIA = 8
#: The palm comes in from this far in front of the handle, m, and backs off this far
#: from it before lowering (lowered from 10 cm off, the hand swept down the wall and its
#: push toppled the standing body backwards, measured).
APPROACH_M = 0.10
BACK_OFF_M = 0.25
#: Distance of the palm's grip site from the handle's centre, on its opening side, m (the
#: handle box is 1.5 cm half-wide; within the grasp radius).
HANDLE_FACE_M = 0.025
#: The palm comes onto the handle from this far to its opening side, m.
SIDE_M = 0.06
#: Spine hinges the reaching IK may use besides the arm.
#: (Rotation only: bending sideways towards the far end of the push, the standing body
#: leant past its feet and fell, measured; nothing holds the pelvis.)
SPINE = ("lumbar_rot", "thorax_rot", "chest_rot")
HAND = "right_hand"


def _window_frame(room: Room, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray,
                                                            np.ndarray, float]:
    """The handle (3,), the closing direction along the wall (3,), the wall's inward
    normal (3,), all world frame, and the pane's opening (m)."""
    handle, opens, inward, opening = room.wall_slide_frame(data, "window")
    return handle, -opens, inward, opening  # the slide opens along +axis


def window_spot(room: Room, data: mujoco.MjData) -> tuple[np.ndarray, float]:
    """Where to stand to close the window: pelvis (x, y), m, along the handle's travel
    (:data:`ALONG_M`) and :data:`STAND_OFF_M` into the room, and the heading facing the
    wall, rad."""
    handle, closing, inward, opening = _window_frame(room, data)
    spot = handle + closing * min(ALONG_M, opening) + inward * STAND_OFF_M
    face = -inward
    return spot[:2], float(np.arctan2(face[1], face[0]))


def plan_window_push(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for sliding the open pane shut from where the agent stands (module docstring).

    Raises:
        SimenvError: the window is not open, or the handle or the end of the push is out
            of the standing agent's reach (IK more than 3 cm short).
    """
    m, h, w = room.model, room.agent, room.objects["window"]
    handle, closing, inward, opening = _window_frame(room, data)
    if opening <= w.threshold:
        raise SimenvError("the window is already closed", field="window")
    side = HAND.split("_")[0]
    joints = [f"agent/{j}" for j in (*arm_joints(side), *SPINE)]
    site = f"agent/{HAND}_grip"
    travel = opening - w.lower + OVERSHOOT_M
    # The palm onto the handle's face on the opening side (its centre is inside the
    # handle's box), so that pushing it along the wall presses on that face.
    # It comes in from in front and to that side (the hand lags its targets: approaching
    # straight on, it overshot past the handle and pushed it the wrong way, measured).
    on = handle - closing * HANDLE_FACE_M
    beside = on - closing * SIDE_M
    goals = [beside + inward * APPROACH_M, beside, on]
    goals += [on + closing * travel * k / PUSH_VIA for k in range(1, PUSH_VIA + 1)]
    goals.append(goals[-1] + inward * BACK_OFF_M)
    upper = upper_body_joints(h)
    pose = data.qpos.copy()
    targets = []
    for goal in goals:
        pose, err = reach_pose(m, pose, site, goal, joints, iterations=300)
        if err > 0.03:
            raise SimenvError(f"the window's handle is out of the standing agent's reach "
                              f"({err:.3f} m short)", field="window")
        targets.append(pd_targets(h, pose[room.agent_qpos], upper))
    before, side, on, *pushing, after = targets
    rest = standing_targets(room, data)
    return held_grasp_stroke(room, data, [(before, 1.2), (side, 0.5), (on, 0.4)], pushing,
                             [(after, 0.6), (rest, REST_S)], HAND, "window")


def plan_walk_to_window(room: Room, data: mujoco.MjData) -> SteppingPlan:
    """Plan for walking to :func:`window_spot` on the agent's own legs
    (:func:`simenv.agents.seat.plan_turn_then_walk`): out from between the desk and the
    rolled-back chair (a step towards the desk, side-steps along it), a turn on the spot
    towards the spot, the walk straight there, a turn on the spot to face the wall."""
    spot, face = window_spot(room, data)
    return plan_turn_then_walk(room, data, spot, face)


def plan_close_window(room: Room, data: mujoco.MjData) -> PlanChain:
    """``close_window``: stand up, walk to the window, slide it shut, go back to the chair,
    sit down and roll it in (module docstring).

    Raises:
        SimenvError: the window is already closed.
    """
    w = room.objects["window"]
    if float(data.qpos[w.qpos_adr]) <= w.threshold:
        raise SimenvError("the window is already closed", field="window")
    return PlanChain((("stand_up", plan_stand_up), ("walk", plan_walk_to_window),
                      ("push", plan_window_push), *RETURN_STAGES))


__all__ = ["plan_close_window", "plan_walk_to_window", "plan_window_push", "window_spot"]

"""Closing the window: stand up, walk to it, slide the pane shut with a proximity grasp,
walk back to the chair, sit down and roll the chair back to the desk.

``close_window`` (:data:`plan_close_window`) is an :class:`~simenv.agents.object_task.ObjectTask`
(stand up, walk, act, return to the chair), specified by:

* the approach pose, :func:`window_spot`: :data:`STAND_OFF_M` in front of the wall,
  :data:`ALONG_M` along the pane's travel, facing the wall;
* the act ``push``, :func:`plan_window_push`: the right palm (``grip`` site) to the pane's
  handle, the proximity grasp is asked for there (it closes only if the palm is within the
  grasp radius; measured: the hand's box meets the handle's first and the grip site stays
  7.7-8.4 cm away, so the grasp does not close and the hand pushes the handle by contact
  instead), the hand moves along the wall by the pane's opening plus :data:`OVERSHOOT_M`
  in :data:`PUSH_VIA` IK via-points, lets go and comes back. The body stands balanced on
  both feet where the walk left it (the gait's centre-of-mass feedback,
  :func:`simenv.agents.walk.held_grasp_stroke`; no external help). The pane closes only if
  the hand drags or pushes it.
"""

from __future__ import annotations

import mujoco
import numpy as np

from simenv.agents import object_task as task
from simenv.agents.reach import PDPlan
from simenv.room.room import Room

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
#: Distance of the palm's grip site from the handle's centre, on its opening side, m (the
#: handle box is 1.5 cm half-wide; within the grasp radius).
HANDLE_FACE_M = 0.025
#: The palm comes onto the handle from this far to its opening side, m.
SIDE_M = 0.06


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
    return task.facing_wall(handle + closing * min(ALONG_M, opening), inward, STAND_OFF_M)


def plan_window_push(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for sliding the open pane shut from where the agent stands (module docstring).

    Raises:
        SimenvError: the window is not open, or the handle or the end of the push is out
            of the standing agent's reach (IK more than 3 cm short).
    """
    task.check_not_done(room, data, "close_window")
    handle, closing, inward, opening = _window_frame(room, data)
    travel = opening - room.objects["window"].lower + OVERSHOOT_M
    # The palm onto the handle's face on the opening side (its centre is inside the
    # handle's box), so that pushing it along the wall presses on that face.
    # It comes in from in front and to that side (the hand lags its targets: approaching
    # straight on, it overshot past the handle and pushed it the wrong way, measured).
    on = handle - closing * HANDLE_FACE_M
    beside = on - closing * SIDE_M
    goals = [beside + inward * task.APPROACH_M, beside, on]
    goals += [on + closing * travel * k / PUSH_VIA for k in range(1, PUSH_VIA + 1)]
    goals.append(goals[-1] + inward * task.BACK_OFF_M)
    targets, _ = task.reach_via_points(room, data, task.GRIP, goals, task.hand_joints(),
                                       "window", iterations=300)
    before, side, on_t, *pushing, after = targets
    return task.grasp_stroke(room, data, "window", [(before, 1.2), (side, 0.5), (on_t, 0.4)],
                             pushing, [(after, 0.6)])


#: ``close_window``: stand up, walk to :func:`window_spot`, :func:`plan_window_push`, go
#: back to the chair, sit down and roll it in.
plan_close_window = task.ObjectTask("close_window", "push", window_spot, plan_window_push)


__all__ = ["plan_close_window", "plan_window_push", "window_spot"]

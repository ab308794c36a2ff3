"""A standing act on one object of the room, as one template: stand up, walk to the
object, reach and grasp, act, let go, walk back to the chair, sit down and roll the chair
back to the desk.

An :class:`ObjectTask` is a reaction's planner (:data:`simenv.agents.scripted.PLANNERS`):
called with the room and the simulation state, it refuses an object already in the
reaction's target state and returns the :class:`~simenv.agents.reach.PlanChain` of the
stages below, each planned from the state the previous one left and logged by the
environment under its name (:class:`simenv.envs.interaction_room.InteractionRoomEnv`: the
stage, its duration, where the pelvis ended, the measured help and outcome):

1. ``stand_up``: :func:`simenv.agents.stand.plan_stand_up` (sit-to-stand, no assistance);
2. ``walk``: :meth:`ObjectTask.plan_walk`, out from between the desk and the rolled-back
   chair, a turn on the feet, the walk to the task's approach pose and a turn there to
   face the object (:func:`simenv.agents.seat.plan_turn_then_walk`, on the agent's own
   legs);
3. the act (:attr:`ObjectTask.act`, e.g. ``push``): the task's stroke, the reach/grasp
   plan from where the walk left the agent, the body balanced on both feet
   (:func:`grasp_stroke`);
4. the return to the chair, :data:`simenv.agents.seat.RETURN_STAGES` (turn, walk back,
   turn to the desk, sit down, settle, roll in).

What differs between the tasks is the reaction (hence the object and its target state,
:data:`simenv.room.scenario.REACTIONS`), the act's name, the approach pose and the
stroke: :mod:`simenv.agents.window`, :mod:`simenv.agents.window_open` and
:mod:`simenv.agents.curtain` specify them. Their strokes share the pieces here: the acting
hand and the hinges its IK moves (:func:`hand_joints`), the via-points solved one from the
other (:func:`reach_via_points`), a spot facing the wall (:func:`facing_wall`) and the
grasped stroke that ends with the arm back at rest (:func:`grasp_stroke`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

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
from simenv.core.errors import SimenvError
from simenv.room.room import Room
from simenv.room.scenario import REACTIONS

#: The acting side and hand; its palm's grasp site (the room's, on the agent's hand).
SIDE = "right"
HAND = f"{SIDE}_hand"
GRIP = f"agent/{HAND}_grip"
#: Spine hinges the reaching IK may use besides the arm.
#: (Rotation only: bending sideways towards the far end of the push, the standing body
#: leant past its feet and fell, measured; nothing holds the pelvis.)
SPINE = ("lumbar_rot", "thorax_rot", "chest_rot")
#: The palm comes in from this far in front of the handle, m, and after letting go backs
#: off this far from it before lowering (lowered from 10 cm off, the hand swept down the
#: wall and its push toppled the standing body backwards, measured).
APPROACH_M = 0.10
BACK_OFF_M = 0.25
#: Largest miss of a via-point by the reaching IK that the stroke accepts, m.
REACH_TOL_M = 0.03


def check_not_done(room: Room, data: mujoco.MjData, reaction: str) -> None:
    """Refuse ``reaction`` when its object is in its target state already.

    Raises:
        SimenvError: e.g. "the window is already closed" (``field`` the object).
    """
    r = REACTIONS[reaction]
    o = room.objects[r.object]
    if o.label(float(data.qpos[o.qpos_adr])) == r.target:
        raise SimenvError(f"the {r.object} is already {r.target}", field=r.object)


def hand_joints(wrist: bool = False) -> list[str]:
    """Room names of the hinges the reaching IK moves: the :data:`HAND` arm's (with the
    wrist's flexion and deviation when ``wrist``) and the spine's :data:`SPINE`."""
    hinges = (f"{SIDE}_hand_flex", f"{SIDE}_hand_dev") if wrist else ()
    return [f"agent/{j}" for j in (*arm_joints(SIDE), *hinges, *SPINE)]


def facing_wall(point: np.ndarray, inward: np.ndarray, stand_off: float
                ) -> tuple[np.ndarray, float]:
    """The pelvis (x, y), m, ``stand_off`` m into the room from ``point`` (3,) on a wall
    whose inward normal is ``inward`` (3,), and the heading facing the wall, rad."""
    spot = point + inward * stand_off
    face = -inward
    return spot[:2], float(np.arctan2(face[1], face[0]))


def reach_via_points(room: Room, data: mujoco.MjData, sites: str | Sequence[str],
                     goals: Sequence[np.ndarray], joints: Sequence[str], name: str, *,
                     iterations: int, required: int | None = None
                     ) -> tuple[list[np.ndarray], np.ndarray]:
    """Servo targets taking the standing agent's ``sites`` through ``goals`` (each (3,),
    or (S, 3) for S sites, world, m), each solved (:func:`~simenv.agents.reach.reach_pose`
    moving ``joints``) from the previous one's pose, gravity fed forward on the upper
    body (:func:`~simenv.agents.reach.pd_targets`).

    The via-points stop at the first one the IK misses by more than :data:`REACH_TOL_M`
    after the first ``required`` (default: all are required).

    Returns:
        the (nu,) targets of the via-points reached, in order, and the room's (nq,)
        configuration solved for the last of them.

    Raises:
        SimenvError: one of the first ``required`` via-points is out of reach (the
            ``name`` object's handle).
    """
    m, h = room.model, room.agent
    need = len(goals) if required is None else required
    upper = upper_body_joints(h)
    pose = data.qpos.copy()
    targets = []
    for k, goal in enumerate(goals):
        solved, err = reach_pose(m, pose, sites, goal, joints, iterations=iterations)
        if err > REACH_TOL_M:
            if k < need:
                raise SimenvError(f"the {name}'s handle is out of the standing agent's "
                                  f"reach ({err:.3f} m short)", field=name)
            break
        pose = solved
        targets.append(pd_targets(h, pose[room.agent_qpos], upper))
    return targets, pose


def grasp_stroke(room: Room, data: mujoco.MjData, name: str,
                 approach: Sequence[tuple[np.ndarray, float]], strokes: Sequence[np.ndarray],
                 leave: Sequence[tuple[np.ndarray, float]]) -> PDPlan:
    """The act on the ``name`` object by :data:`HAND`:
    :func:`simenv.agents.walk.held_grasp_stroke` through ``approach``, ``strokes`` and
    ``leave`` (targets and seconds), then the arm back to its standing targets over
    :data:`simenv.agents.walk.REST_S`."""
    rest = standing_targets(room, data)
    return held_grasp_stroke(room, data, approach, strokes, [*leave, (rest, REST_S)], HAND,
                             name)


@dataclass(frozen=True)
class ObjectTask:
    """A standing act on one object (module docstring); called as the reaction's planner.

    Attributes:
        reaction: the reaction's name in :data:`simenv.room.scenario.REACTIONS`, which
            names the object and its target state label.
        act: the act stage's name in the chain and the log (``push``, ``pull``).
        spot: (room, data) -> the approach pose: the pelvis (x, y), m, and the heading
            facing the object, rad.
        stroke: (room, data) -> the reach/grasp plan of the act from where the agent
            stands.
    """

    reaction: str
    act: str
    spot: Callable[[Room, mujoco.MjData], tuple[np.ndarray, float]]
    stroke: Callable[[Room, mujoco.MjData], PDPlan]

    def plan_walk(self, room: Room, data: mujoco.MjData) -> SteppingPlan:
        """Plan for walking to :attr:`spot` on the agent's own legs
        (:func:`simenv.agents.seat.plan_turn_then_walk`): out from between the desk and
        the rolled-back chair (a step towards the desk, side-steps along it), a turn on
        the spot towards the spot, the walk straight there, a turn on the spot to face
        the object."""
        spot, face = self.spot(room, data)
        return plan_turn_then_walk(room, data, spot, face)

    def __call__(self, room: Room, data: mujoco.MjData) -> PlanChain:
        """The reaction's stages (module docstring), planned one after the other.

        Raises:
            SimenvError: the object is in the reaction's target state already.
        """
        check_not_done(room, data, self.reaction)
        return PlanChain((("stand_up", plan_stand_up), ("walk", self.plan_walk),
                          (self.act, self.stroke), *RETURN_STAGES))


__all__ = ["APPROACH_M", "BACK_OFF_M", "GRIP", "HAND", "REACH_TOL_M", "SIDE", "SPINE", "ObjectTask",
           "check_not_done", "facing_wall", "grasp_stroke", "hand_joints",
           "reach_via_points"]

"""Back to the chair: turn on the feet, walk back to the desk, turn to face it, sit down.

The return stages (:data:`RETURN_STAGES`) follow a standing act (``close_window``,
``close_curtain``, ``open_window``) in its :class:`~simenv.agents.reach.PlanChain`, each
planned from the state the previous one left:

1. ``turn_away`` (:func:`plan_turn_away`): a turn on the feet (:func:`plan_step`) from
   facing the object onto the heading that leaves towards the chair;
2. ``walk_back`` (:func:`plan_walk_back`): :func:`simenv.agents.walk.plan_walk` from there
   to :data:`CLEAR_CHAIR_M` beside :func:`chair_spot` (where the chair is now) along the
   desk's edge, on the side the agent comes from, arriving facing the desk: clear of the
   chair, whose front legs stand where a path into the corridor between chair and desk
   would pass;
3. ``turn_to_desk`` (:func:`plan_turn_to_desk`): side-steps onto :func:`chair_spot`,
   facing the desk, the seat now behind the agent;
4. ``sit_down`` (:func:`simenv.agents.stand.plan_sit_down`) and ``settle``
   (:func:`plan_settle`): crouch onto the seat, then hold the seated pose; the settle's
   plan measures the result (:func:`seated_on_chair`) when it ends.

Every step is the stepping gait of :mod:`simenv.agents.gait` on the agent's own legs
(:func:`simenv.agents.walk.turn_steps`: pairs of steps, the foot on the side of the turn
first, each turning the feet by at most :data:`simenv.agents.walk.TURN_STEP_DEG` and
moving them by at most :data:`simenv.agents.walk.STEP_M`). :func:`plan_turn_then_walk`
puts side-steps out from between the desk and the chair (:data:`CLEAR_CHAIR_M`) and such
a turn before a walk in one plan (the walks to the window and the curtain).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from simenv.agents.gait import SteppingPlan, leg_ik, plan_footsteps, quat_yaw, wrap_angle
from simenv.agents.reach import PDPlan, PDTrajectory, pd_targets, upper_body_joints
from simenv.agents.stand import plan_sit_down
from simenv.agents.walk import GaitMeter, check_standing, plan_walk, turn_steps
from simenv.room.room import Room

#: Pelvis in front of the seat's centre along the desk's heading when the agent stands to
#: sit, m (measured where standing up leaves it: 0.25-0.26 m).
SEAT_STAND_OFF_M = 0.26
#: Before turning to walk away, the agent side-steps this far along the desk's edge, out
#: from between the desk and the rolled-back chair (turning there, its hand met the
#: keyboard and its heels the chair's front legs, measured), m.
CLEAR_CHAIR_M = 0.5
#: ... after a step this far towards the desk, away from the chair's front legs (6 cm
#: behind the standing heels; side-stepping there, a heel caught one, measured), m.
CLEAR_AHEAD_M = 0.12
#: Seated hold after sitting down, s.
SETTLE_S = 1.5


def desk_heading(room: Room) -> float:
    """The seated agent's heading, facing the desk, rad."""
    return float(np.deg2rad(room.scenario.desk.yaw_deg))


def chair_spot(room: Room, data: mujoco.MjData, off: float = SEAT_STAND_OFF_M
               ) -> np.ndarray:
    """Where the agent stands to sit down: pelvis (x, y), m, ``off`` in front of the
    seat's centre (where the chair is now) along the desk's heading."""
    seat = data.xpos[room.model.body("chair_seat").id, :2]
    yaw = desk_heading(room)
    return seat + off * np.array([np.cos(yaw), np.sin(yaw)])


def plan_step(room: Room, data: mujoco.MjData, goal: np.ndarray, goal_yaw: float
              ) -> SteppingPlan:
    """Plan for stepping the standing agent to ``goal`` (x, y, m, a short way) facing
    ``goal_yaw`` (rad), turning on the spot when ``goal`` is where it stands
    (:func:`simenv.agents.walk.turn_steps`), on its own legs; the plan's feedback
    (:class:`~simenv.agents.walk.GaitMeter`) measures the help (none) and whether it fell.

    Raises:
        SimenvError: the agent is not standing, or a foot's place is out of the legs'
            reach.
    """
    check_standing(room, data, "step")
    q = data.qpos[room.agent_qpos]
    steps = turn_steps(leg_ik(room.agent), q[:2].copy(), quat_yaw(q[3:7]), goal_yaw,
                       np.array(goal, float)[:2])
    plan = plan_footsteps(room, data, steps)
    plan.feedback = GaitMeter(room, plan.balance, np.array(goal, float)[:2])
    return plan


def plan_turn_then_walk(room: Room, data: mujoco.MjData, goal: np.ndarray, goal_yaw: float,
                        start_yaw: float | None = None) -> SteppingPlan:
    """One plan: a step :data:`CLEAR_AHEAD_M` towards the desk and side-steps
    :data:`CLEAR_CHAIR_M` along its edge (towards the goal's side), out from between the
    desk and the rolled-back chair, a turn on the feet onto ``start_yaw`` (rad; default:
    facing the goal, then a straight walk and a turn there), then the walk to ``goal``
    (x, y, m) facing ``goal_yaw`` (:func:`simenv.agents.walk.plan_walk`)."""
    q = data.qpos[room.agent_qpos]
    yaw = desk_heading(room)
    ahead = np.array([np.cos(yaw), np.sin(yaw)])
    across = np.array([-ahead[1], ahead[0]])  # the desk's left, seen seated
    side = 1.0 if float((np.asarray(goal, float)[:2] - q[:2]) @ across) >= 0 else -1.0
    forward = q[:2] + CLEAR_AHEAD_M * ahead
    return plan_walk(room, data, goal, goal_yaw, start_yaw=start_yaw,
                     side_to=[forward, forward + side * CLEAR_CHAIR_M * across])


def plan_turn_away(room: Room, data: mujoco.MjData) -> SteppingPlan:
    """Plan for the stepping turn from facing the object onto the heading that leaves
    towards the chair: a quarter turn from the current heading, to the side of
    :func:`chair_spot`."""
    q = data.qpos[room.agent_qpos]
    yaw = quat_yaw(q[3:7])
    to = chair_spot(room, data) - q[:2]
    side = np.sign(np.cos(yaw) * to[1] - np.sin(yaw) * to[0]) or 1.0  # left or right of it
    return plan_step(room, data, q[:2], wrap_angle(yaw + side * np.pi / 2))


def plan_walk_back(room: Room, data: mujoco.MjData) -> SteppingPlan:
    """Plan for walking from where the agent stands to :data:`CLEAR_CHAIR_M` beside
    :func:`chair_spot` along the desk's edge, on the side the agent comes from, arriving
    facing the desk (module docstring)."""
    spot = chair_spot(room, data)
    yaw = desk_heading(room)
    across = np.array([-np.sin(yaw), np.cos(yaw)])
    side = 1.0 if float((data.qpos[room.agent_qpos][:2] - spot) @ across) >= 0 else -1.0
    return plan_walk(room, data, spot + side * CLEAR_CHAIR_M * across, yaw)


def plan_turn_to_desk(room: Room, data: mujoco.MjData) -> SteppingPlan:
    """Plan for the side-steps onto :func:`chair_spot` (where the chair is now), facing
    the desk (the seat behind)."""
    return plan_step(room, data, chair_spot(room, data), desk_heading(room))


def seated_on_chair(room: Room, data: mujoco.MjData) -> dict[str, float | bool]:
    """Whether the agent sits on the chair now, measured:

    * ``seat_contact``: the pelvis or a thigh touches the chair's seat;
    * ``pelvis_height_m`` within 5 cm of the seated pose's (``pelvis_height_error_m``);
    * ``seat_distance_m``: the pelvis within 15 cm of the seat's centre on the floor;
    * ``torso_tilt_deg``: the chest's vertical axis within 30 deg of upright;
    * ``fallen``: any agent geom but a foot or toe touching the floor;
    * ``success``: all of them.
    """
    m = room.model
    seat = m.geom("chair/seat").id
    floor = 0  # the world's first geom
    sitting = {m.geom(f"agent/{n}").id for n in ("pelvis", "left_thigh", "right_thigh")}
    feet = {m.geom(f"agent/{n}").id for n in ("left_foot", "left_toes", "right_foot",
                                              "right_toes")}
    agent = {g for g in range(m.ngeom) if m.geom(g).name.startswith("agent/")}
    contact, fallen = False, False
    for g1, g2 in data.contact.geom[:data.ncon]:
        pair = {int(g1), int(g2)}
        if seat in pair and pair & sitting:
            contact = True
        if floor in pair and pair & agent and not pair & feet:
            fallen = True
    q = data.qpos[room.agent_qpos]
    dz = float(q[2] - room.seated_pose()[2])
    centre = data.xpos[m.body("chair_seat").id, :2]
    dist = float(np.linalg.norm(q[:2] - centre))
    up = data.xmat[m.body("agent/chest").id].reshape(3, 3)[:, 2]
    tilt = float(np.rad2deg(np.arccos(np.clip(up[2], -1.0, 1.0))))
    ok = contact and abs(dz) <= 0.05 and dist <= 0.15 and tilt <= 30.0 and not fallen
    return {"seat_contact": contact, "pelvis_height_m": float(q[2]),
            "pelvis_height_error_m": dz, "seat_distance_m": dist, "torso_tilt_deg": tilt,
            "fallen": fallen, "success": bool(ok)}


@dataclass
class SeatedCheck:
    """A :data:`~simenv.agents.reach.Feedback` that passes the targets through; its
    :meth:`outcome` is :func:`seated_on_chair` in the state given (the settle's end)."""

    room: Room

    def __call__(self, t: float, data: mujoco.MjData, targets: np.ndarray) -> np.ndarray:
        return targets

    def outcome(self, data: mujoco.MjData) -> dict[str, float | bool]:
        return seated_on_chair(self.room, data)


def plan_settle(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for settling into the seated pose over :data:`SETTLE_S` (after
    :func:`~simenv.agents.stand.plan_sit_down`); its feedback (:class:`SeatedCheck`)
    measures the result at the end."""
    h = room.agent
    seated = pd_targets(h, room.seated_pose(), upper_body_joints(h))
    return PDPlan([PDTrajectory(data.ctrl[room.agent_ctrl].copy(), seated, SETTLE_S)],
                  feedback=SeatedCheck(room))


#: The return to the chair, appended to a standing act's chain.
RETURN_STAGES = (("turn_away", plan_turn_away), ("walk_back", plan_walk_back),
                 ("turn_to_desk", plan_turn_to_desk), ("sit_down", plan_sit_down),
                 ("settle", plan_settle))


__all__ = ["RETURN_STAGES", "SeatedCheck", "chair_spot", "desk_heading", "plan_settle",
           "plan_step", "plan_turn_away", "plan_turn_then_walk", "plan_turn_to_desk",
           "plan_walk_back", "seated_on_chair"]

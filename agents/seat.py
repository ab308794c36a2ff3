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
   plan measures the result (:func:`seated_on_chair`) when it ends;
5. ``roll_in`` (:func:`plan_roll_in`): seated, the agent scoots the chair back to the
   desk with heel pulls (below); its plan measures the help (none) every physics step
   and, at its end, the seat and the chair's distance from the desk
   (:class:`RollInMeter`).

Rolling in: standing up pushes the chair ~0.4 m back from the desk and sitting down
pushes it on to 0.5-0.8 m (the slide ``chair/roll``, 30 N of Coulomb friction). A
*stroke* (:data:`ROLL_IN_SWING_S` x 4 + :data:`ROLL_IN_PULL_S`) lifts one foot (hip
flexed and knee extended :data:`ROLL_IN_LIFT_DEG` each, the leg's gravity fed forward),
sets its heel down ahead (knee :data:`ROLL_IN_REACH_DEG` extended, ankle dorsiflexed
:data:`ROLL_IN_DORSI_DEG`, hip pressing :data:`ROLL_IN_PRESS_DEG` down), does the same
with the other foot, then flexes both knees to :data:`ROLL_IN_PULL_DEG` beyond a right
angle with the heels pressed: the heels hold on the floor and the body and chair roll
towards the desk (0.19-0.20 m a pull, less 2.4-2.6 cm given back while the feet are
placed, measured). Only one foot is off the floor at a
time and it is lifted, not slid: a foot slid forward on the floor pushes the chair back
(measured: 8-30 cm for one leg's reach, the way :func:`~simenv.agents.stand.plan_stand_up`
pushes it on purpose). The chair's forward stop (0.02 m) ends the travel; strokes beyond
it leave the agent seated (measured).

Every step is the stepping gait of :mod:`simenv.agents.gait` on the agent's own legs
(:func:`simenv.agents.walk.turn_steps`: pairs of steps, the foot on the side of the turn
first, each turning the feet by at most :data:`simenv.agents.walk.TURN_STEP_DEG` and
moving them by at most :data:`simenv.agents.walk.STEP_M`). :func:`plan_turn_then_walk`
puts side-steps out from between the desk and the chair (:data:`CLEAR_CHAIR_M`) and such
a turn before a walk in one plan (the walks to the window and the curtain).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from simenv.agents.gait import SteppingPlan, leg_ik, plan_footsteps, quat_yaw, wrap_angle
from simenv.agents.reach import PDPlan, PDTrajectory, pd_targets, upper_body_joints
from simenv.agents.stand import plan_sit_down
from simenv.agents.walk import GaitMeter, check_standing, plan_walk, turn_steps
from simenv.core.errors import SimenvError
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
#: Rolling in (module docstring): hip flexion added and knee extension taken off while a
#: foot is in the air, deg; knee extension of a heel set down ahead, deg; ankle
#: dorsiflexion then (heel first), deg; hip extension pressing the heels down, deg; knee
#: flexion beyond a right angle at the end of a pull, deg.
ROLL_IN_LIFT_DEG = 20.0
ROLL_IN_REACH_DEG = 20.0
ROLL_IN_DORSI_DEG = 15.0
ROLL_IN_PRESS_DEG = 5.0
ROLL_IN_PULL_DEG = 15.0
#: Durations of a foot's lift or set-down, and of the pull, s.
ROLL_IN_SWING_S = 0.5
ROLL_IN_PULL_S = 1.0
#: Travel planned per stroke, m: about 2/3 of the ~0.17 m measured, so the strokes reach
#: the desk (extra strokes end on the chair's forward stop, measured harmless).
ROLL_IN_STROKE_M = 0.12
#: The chair counts as rolled back to the desk within this distance of where it started
#: (:func:`chair_from_desk`), m: the seated knees, 0.16 m under the desk top at the start,
#: are then still under it; the strokes end 1.6-1.8 cm from the start (measured), so
#: this bounds "at the desk", it is not a margin the strokes need.
CHAIR_AT_DESK_M = 0.1


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


def chair_from_desk(room: Room, data: mujoco.MjData) -> float:
    """How far the chair has rolled back from where the scenario puts it at the desk
    (its slide ``chair/roll``, 0 at the start, negative away from the desk), m >= 0."""
    return abs(float(data.qpos[room.model.joint("chair/roll").qposadr[0]]))


def seated_on_chair(room: Room, data: mujoco.MjData) -> dict[str, float | bool]:
    """Whether the agent sits on the chair now, measured:

    * ``seat_contact``: the pelvis or a thigh touches the chair's seat;
    * ``pelvis_height_m`` within 5 cm of the seated pose's (``pelvis_height_error_m``);
    * ``seat_distance_m``: the pelvis within 15 cm of the seat's centre on the floor;
    * ``torso_tilt_deg``: the chest's vertical axis within 30 deg of upright;
    * ``fallen``: any agent geom but a foot or toe touching the floor;
    * ``success``: all of them;
    * ``chair_from_desk_m`` (:func:`chair_from_desk`), reported, not part of ``success``.
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
            "fallen": fallen, "success": bool(ok),
            "chair_from_desk_m": chair_from_desk(room, data)}


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


def _passthrough(t: float, data: mujoco.MjData, targets: np.ndarray) -> np.ndarray:
    return targets


@dataclass
class RollInMeter:
    """A :data:`~simenv.agents.reach.Feedback` that passes the targets through and
    measures, every physics step, the external help on the agent (a
    :class:`~simenv.agents.walk.GaitMeter`'s bookkeeping: it must stay 0; :meth:`summary`);
    its :meth:`outcome` is :func:`seated_on_chair` at the stage's end with the chair's
    distance from the desk.

    Attributes:
        room: the room. meter: the help's bookkeeping (per physics step, N).
        chair_start_m: :func:`chair_from_desk` when the stage was planned, m.
    """

    room: Room
    chair_start_m: float = 0.0
    meter: GaitMeter = field(init=False)

    def __post_init__(self) -> None:
        self.meter = GaitMeter(self.room, _passthrough)

    def __call__(self, t: float, data: mujoco.MjData, targets: np.ndarray) -> np.ndarray:
        return self.meter(t, data, targets)

    def summary(self, steps_per_frame: int = 20) -> dict[str, float | int | list[float]]:
        """The help over the physics steps so far (:meth:`GaitMeter.summary`)."""
        return self.meter.summary(steps_per_frame)

    def outcome(self, data: mujoco.MjData) -> dict[str, float | bool]:
        """:func:`seated_on_chair` now, with ``chair_start_m`` (m), ``chair_at_desk``
        (within :data:`CHAIR_AT_DESK_M` of the desk) and ``success``: seated and the
        chair at the desk."""
        out = seated_on_chair(self.room, data)
        at_desk = out["chair_from_desk_m"] <= CHAIR_AT_DESK_M
        return {**out, "chair_start_m": self.chair_start_m, "chair_at_desk": bool(at_desk),
                "success": bool(out["success"] and at_desk)}


def roll_in_strokes(distance_m: float) -> int:
    """Heel-pull strokes planned for rolling the chair in from ``distance_m`` (m) behind
    the desk: ``ceil(distance / ROLL_IN_STROKE_M)``, none within :data:`CHAIR_AT_DESK_M`."""
    if distance_m <= CHAIR_AT_DESK_M:
        return 0
    return int(np.ceil(distance_m / ROLL_IN_STROKE_M))


def plan_roll_in(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for the seated agent scooting its chair back to the desk with heel pulls
    (module docstring): knees drawn in with the heels pressed (the first pull),
    :func:`roll_in_strokes` strokes, then each foot lifted back onto the seated pose's
    place and the seated pose held. Nothing but the agent's servos and contacts moves the
    chair; the plan's feedback (:class:`RollInMeter`) measures that, and the result.

    Raises:
        SimenvError: the agent is not seated on the chair (:func:`seated_on_chair`).

    Returns:
        the plan: ``1 + n (4 ROLL_IN_SWING_S + ROLL_IN_PULL_S) + 4 ROLL_IN_SWING_S + 1``
        s (n strokes; 2 s with none).
    """
    seat = seated_on_chair(room, data)
    if not seat["success"]:
        raise SimenvError("the agent is not seated on the chair: it cannot roll it in "
                          f"(pelvis {seat['seat_distance_m']:.2f} m from the seat's centre, "
                          f"{seat['pelvis_height_error_m']:+.2f} m from its height)",
                          field="roll_in")
    h = room.agent
    upper = upper_body_joints(h)
    start = chair_from_desk(room, data)
    strokes = roll_in_strokes(start)
    seated = pd_targets(h, room.seated_pose(), upper)
    now = data.ctrl[room.agent_ctrl].copy()
    if not strokes:  # at the desk already: settle into the seated pose
        return PDPlan([PDTrajectory(now, seated, 1.0), PDTrajectory(seated, seated, 1.0)],
                      feedback=RollInMeter(room, start))
    legs = {s: tuple(n for n in h.joint_names if n.startswith(f"{s}_")
                     and n.split("_")[1] in ("thigh", "shin", "foot")) for s in ("left", "right")}
    base = room.seated_pose()

    def leg(q: np.ndarray, side: str, hip: float, knee: float, ankle: float) -> np.ndarray:
        q = q.copy()  # hinge angles in deg from the seated pose's right angles
        for name, deg in (("thigh_flex", 90.0 + hip), ("shin_flex", 90.0 + knee),
                          ("foot_flex", ankle)):
            q[h.hinge_qpos[h.joint_names.index(f"{side}_{name}")]] = np.deg2rad(deg)
        return q

    press, lift = ROLL_IN_PRESS_DEG, ROLL_IN_LIFT_DEG
    pull = base
    for side in ("left", "right"):
        pull = leg(pull, side, -press, ROLL_IN_PULL_DEG, 0.0)
    pulled = pd_targets(h, pull, upper)
    poses: list[tuple[np.ndarray, float]] = [(pulled, 1.0)]
    q = pull
    for _ in range(strokes):
        for side in ("left", "right"):
            # The foot in the air carries only its leg: that leg's gravity is fed forward
            # (without, a stroke's two lifts give back 2.7-2.9 cm of travel instead of
            # 2.4-2.6, measured).
            up = leg(q, side, lift, -lift - ROLL_IN_REACH_DEG, -ROLL_IN_DORSI_DEG)
            poses.append((pd_targets(h, up, upper + legs[side]), ROLL_IN_SWING_S))
            q = leg(q, side, -press, -ROLL_IN_REACH_DEG, -ROLL_IN_DORSI_DEG)
            poses.append((pd_targets(h, q, upper), ROLL_IN_SWING_S))
        q = pull
        poses.append((pulled, ROLL_IN_PULL_S))
    for side in ("left", "right"):
        # Each foot back under its knee through the air: slid there, the feet pushed the
        # chair 8 cm back (measured).
        up = leg(q, side, lift, -lift, 0.0)
        poses.append((pd_targets(h, up, upper + legs[side]), ROLL_IN_SWING_S))
        q = leg(q, side, 0.0, 0.0, 0.0)
        poses.append((pd_targets(h, q, upper), ROLL_IN_SWING_S))
    poses.append((seated, 1.0))
    segments = []
    for target, duration in poses:
        segments.append(PDTrajectory(now, target, duration))
        now = target
    return PDPlan(segments, feedback=RollInMeter(room, start))


#: The return to the chair, appended to a standing act's chain.
RETURN_STAGES = (("turn_away", plan_turn_away), ("walk_back", plan_walk_back),
                 ("turn_to_desk", plan_turn_to_desk), ("sit_down", plan_sit_down),
                 ("settle", plan_settle), ("roll_in", plan_roll_in))


__all__ = ["CHAIR_AT_DESK_M", "RETURN_STAGES", "RollInMeter", "SeatedCheck",
           "chair_from_desk", "chair_spot", "desk_heading", "plan_roll_in", "plan_settle",
           "plan_step", "plan_turn_away", "plan_turn_then_walk", "plan_turn_to_desk",
           "plan_walk_back", "roll_in_strokes", "seated_on_chair"]

"""Walking the standing agent to a spot on its own legs, and standing still while its
hands work: footsteps played by the statically balanced stepping gait of
:mod:`simenv.agents.gait`. Nothing but the agent's servos and its contacts acts on it (no
weld, no applied force; :class:`GaitMeter` measures that every physics step, and whether
the body fell).

The footsteps (:func:`walk_steps`):

1. steps with the heading kept through waypoints (e.g. out from between the desk and the
   chair), each ``ceil(d / STEP_M)`` pairs of steps, the foot on the side of the move
   first;
2. a turn on the spot onto the start heading (by default facing the goal):
   ``K = ceil(|turn| / TURN_STEP_DEG)`` pairs of steps, the foot on the side of the turn
   first, each foot landing where the standing rest pose puts it for the pelvis turned by
   ``k turn / K`` (:func:`turn_steps`);
3. the path (:func:`path_steps`): a cubic Bezier curve ``B(u)`` from the pelvis to the
   goal leaving along the start heading and arriving along the arrival heading (handles
   :data:`HANDLE_FRACTION` of the distance; a straight line when both face the goal),
   ``n = ceil(L / STEP_M)`` steps along its arc length ``L``, feet alternating, step
   ``k`` landing where the rest pose puts that foot for a pelvis at ``B(s_k)`` heading
   along the tangent, ``s_k = k L / n``, then the closing step beside the other foot;
4. a turn on the spot onto the goal heading.

The former walk (a retargeted CMU walk tracked by the servos along a Bezier path) kept up
only with a pelvis weld carrying 0.57-0.78 body weights on average; without it the body
fell at the desk (docs/room.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np

from simenv.agents import gait
from simenv.agents.gait import Footstep, StepBalance, quat_yaw, wrap_angle
from simenv.agents.reach import (
    GraspEvent,
    PDPlan,
    PDTrajectory,
    hinge_adr,
    pd_targets,
    upper_body_joints,
)
from simenv.core.errors import SimenvError
from simenv.room.room import Room

#: The walk starts only with the pelvis at least this fraction of its standing height;
#: below :data:`FALLEN_FRACTION` of it the body has fallen.
STANDING_FRACTION = 0.9
FALLEN_FRACTION = 0.7
#: Bezier handle length as a fraction of the start-goal distance.
HANDLE_FRACTION = 0.45
#: Largest pelvis advance per step along the path, m; largest turn per step pair, deg;
#: headings closer than :data:`ALIGN_DEG` need no turn on the spot.
STEP_M = 0.2
TURN_STEP_DEG = 45.0
ALIGN_DEG = 10.0
GRAVITY = 9.81


def _bezier(p: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points and tangents (len(u), 2) of the cubic Bezier with control points p (4, 2)."""
    u = u[:, None]
    pts = ((1 - u) ** 3 * p[0] + 3 * (1 - u) ** 2 * u * p[1] + 3 * (1 - u) * u**2 * p[2]
           + u**3 * p[3])
    tan = 3 * (1 - u) ** 2 * (p[1] - p[0]) + 6 * (1 - u) * u * (p[2] - p[1]) + 3 * u**2 * (
        p[3] - p[2])
    return pts, tan


def walk_path(start: np.ndarray, start_yaw: float, goal: np.ndarray, goal_yaw: float
              ) -> np.ndarray:
    """(4, 2) control points of the planned path (module docstring), m."""
    start, goal = np.asarray(start, float)[:2], np.asarray(goal, float)[:2]
    a = HANDLE_FRACTION * float(np.linalg.norm(goal - start))
    h0 = np.array([np.cos(start_yaw), np.sin(start_yaw)])
    h1 = np.array([np.cos(goal_yaw), np.sin(goal_yaw)])
    return np.array([start, start + a * h0, goal - a * h1, goal])


def turn_steps(ik: gait.LegIK, pelvis: np.ndarray, yaw0: float, yaw1: float,
               to: np.ndarray | None = None) -> list[Footstep]:
    """Footsteps turning on the spot about ``pelvis`` (2,) from heading ``yaw0`` to
    ``yaw1`` (rad) (module docstring, 1), the pelvis moving on to ``to`` (2,) on the way
    when given (a side-step out from between furniture)."""
    turn = wrap_angle(yaw1 - yaw0)
    to = np.asarray(pelvis, float) if to is None else np.asarray(to, float)
    shift = float(np.linalg.norm(to - pelvis))
    k_pairs = max(int(np.ceil(abs(np.rad2deg(turn)) / TURN_STEP_DEG - 1e-9)),
                  int(np.ceil(shift / STEP_M - 1e-9)), 1)
    # The leading foot opens the way: on the side of the turn, or of the move when the
    # heading stays.
    left = turn if abs(np.rad2deg(turn)) > ALIGN_DEG else float(
        (to - pelvis) @ [-np.sin(yaw0), np.cos(yaw0)])
    lead = "left" if left >= 0 else "right"
    trail = "right" if lead == "left" else "left"
    out = []
    for k in range(1, k_pairs + 1):
        yaw = yaw0 + turn * k / k_pairs
        p = pelvis + (to - pelvis) * k / k_pairs
        out += [Footstep(s, ik.neutral(s, p, yaw), yaw) for s in (lead, trail)]
    return out


def path_steps(ik: gait.LegIK, start: np.ndarray, start_yaw: float, goal: np.ndarray,
               goal_yaw: float, first: str = "left") -> list[Footstep]:
    """Footsteps along :func:`walk_path` from a pelvis at ``start`` heading ``start_yaw``
    to ``goal`` facing ``goal_yaw`` (module docstring, 2 and 3)."""
    ctrl = walk_path(start, start_yaw, goal, goal_yaw)
    dense = np.linspace(0.0, 1.0, 400)
    pts, _ = _bezier(ctrl, dense)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    n = max(1, int(np.ceil(arc[-1] / STEP_M - 1e-9)))
    u = np.interp(arc[-1] * np.arange(1, n + 1) / n, arc, dense)
    p, tan = _bezier(ctrl, u)
    out, side = [], first
    for pk, tk in zip(p, tan, strict=True):
        yaw = float(np.arctan2(tk[1], tk[0]))
        out.append(Footstep(side, ik.neutral(side, pk, yaw), yaw))
        side = "right" if side == "left" else "left"
    out.append(Footstep(side, ik.neutral(side, np.asarray(goal, float), goal_yaw), goal_yaw))
    return out


@dataclass
class GaitMeter:
    """A :data:`~simenv.agents.reach.Feedback` wrapping the gait's balance: it passes
    the targets through ``inner`` and measures, every physics step, the external help on
    the agent (:meth:`simenv.room.room.Room.assist_wrench`: applied forces and torques, active
    equality constraints other than the hands' grasps; it must stay 0) and the pelvis's
    height; :meth:`summary` reports the help like the former root assistance, and
    :meth:`outcome` whether the body fell and where it ended.

    Attributes:
        room: the room. inner: the balance feedback. goal: (2,) where the pelvis should
            end, m, or None (standing in place). forces_n, torques_nm: per physics step,
            N and N m. lowest_m: the lowest pelvis height so far, m. grasp_max_n: the
            largest grasp force so far, N.
    """

    room: Room
    inner: StepBalance
    goal: np.ndarray | None = None
    forces_n: list[float] = field(default_factory=list)
    torques_nm: list[float] = field(default_factory=list)
    lowest_m: float = np.inf
    grasp_max_n: float = 0.0

    def __call__(self, t: float, data: mujoco.MjData, targets: np.ndarray) -> np.ndarray:
        f, tau = self.room.assist_wrench(data)
        self.forces_n.append(f)
        self.torques_nm.append(tau)
        self.grasp_max_n = max(self.grasp_max_n, self.room.grasp_force(data))
        self.lowest_m = min(self.lowest_m, float(data.qpos[self.room.agent_qpos][2]))
        return self.inner(t, data, targets)

    def summary(self, steps_per_frame: int = 20) -> dict[str, float | int | list[float]]:
        """External help over the physics steps so far: ``mean_n``, ``p95_n``, ``max_n``
        (N), the same as fractions of body weight (``*_bw``), ``mean_torque_nm``,
        ``max_torque_nm``, ``steps``, ``per_frame_n``, the mean force (N) over each
        ``steps_per_frame`` physics steps (one env step), and ``grasp_max_n``: the largest
        force of a closed proximity grasp on the hand (holding, not help; reported so
        that leaning on a handle shows, :meth:`simenv.room.room.Room.grasp_force`)."""
        f = np.asarray(self.forces_n) if self.forces_n else np.zeros(1)
        tq = np.asarray(self.torques_nm) if self.torques_nm else np.zeros(1)
        weight = float(self.room.agent.total_mass) * GRAVITY
        out: dict[str, float | int | list[float]] = {
            "mean_n": float(f.mean()), "p95_n": float(np.percentile(f, 95)),
            "max_n": float(f.max()), "mean_torque_nm": float(tq.mean()),
            "max_torque_nm": float(tq.max()), "steps": len(self.forces_n)}
        for k in ("mean", "p95", "max"):
            out[f"{k}_bw"] = float(out[f"{k}_n"]) / weight
        chunks = range(0, len(self.forces_n), steps_per_frame)
        out["per_frame_n"] = [round(float(f[i:i + steps_per_frame].mean()), 1) for i in chunks]
        out["grasp_max_n"] = self.grasp_max_n
        return out

    def fallen(self) -> bool:
        """Whether the pelvis went below :data:`FALLEN_FRACTION` of its standing height
        at some step so far."""
        return bool(self.lowest_m < FALLEN_FRACTION * float(self.room.agent.default_qpos()[2]))

    def outcome(self, data: mujoco.MjData) -> dict[str, float | bool | None]:
        """``fell``: the pelvis went below :data:`FALLEN_FRACTION` of its standing height
        at some step; ``lowest_pelvis_m``; ``goal_error_m``: the pelvis's distance from the
        goal on the floor now (None without a goal); ``success``: not fallen and (with a
        goal) within 0.15 m of it."""
        fell = self.fallen()
        err = None if self.goal is None else float(
            np.linalg.norm(data.qpos[self.room.agent_qpos][:2] - self.goal))
        return {"fell": fell, "lowest_pelvis_m": float(self.lowest_m), "goal_error_m": err,
                "success": bool(not fell and (err is None or err <= 0.15))}


def check_standing(room: Room, data: mujoco.MjData, what: str) -> None:
    q = data.qpos[room.agent_qpos]
    rest = float(room.agent.default_qpos()[2])
    if q[2] < STANDING_FRACTION * rest:
        raise SimenvError(f"the agent is not standing (pelvis {q[2]:.2f} m, standing "
                          f"{rest:.2f} m): it cannot {what}", field=what)


def walk_steps(room: Room, data: mujoco.MjData, goal: np.ndarray, goal_yaw: float,
               start_yaw: float | None = None, side_to: np.ndarray | None = None
               ) -> list[Footstep]:
    """Footsteps from where the agent stands to ``goal`` (x, y, m) facing ``goal_yaw``
    (rad) (module docstring): first steps with the heading kept through the waypoints
    ``side_to`` ((K, 2) or (2,), x, y, m) when given; the turn on the spot onto
    ``start_yaw`` (default: facing the goal); the path, arriving along ``goal_yaw`` when
    ``start_yaw`` is given, else straight, and then a turn on the spot onto ``goal_yaw``
    (a curved path turns on every step: measured, steps turning 50 deg while reaching
    0.28 m fell).
    """
    ik = gait.leg_ik(room.agent)
    q = data.qpos[room.agent_qpos]
    yaw0 = quat_yaw(q[3:7])
    pelvis = q[:2].copy()
    goal = np.asarray(goal, float)[:2]
    steps = []
    for way in [] if side_to is None else np.asarray(side_to, float).reshape(-1, 2):
        steps += turn_steps(ik, pelvis, yaw0, yaw0, way)
        pelvis = way
    far = float(np.linalg.norm(goal - pelvis)) > 0.05
    straight = start_yaw is None and far
    yaw1 = (float(np.arctan2(*(goal - pelvis)[::-1])) if straight else
            yaw0 if start_yaw is None else float(start_yaw))
    if abs(np.rad2deg(wrap_angle(yaw1 - yaw0))) > ALIGN_DEG:
        steps += turn_steps(ik, pelvis, yaw0, yaw1)
    if far:
        first = steps[-2].side if len(steps) > 1 else "left"
        arrive = yaw1 if straight else goal_yaw
        steps += path_steps(ik, pelvis, yaw1, goal, arrive, first)
        yaw1 = arrive
    if abs(np.rad2deg(wrap_angle(goal_yaw - yaw1))) > ALIGN_DEG:
        steps += turn_steps(ik, goal, yaw1, goal_yaw)
    return steps


def plan_walk(room: Room, data: mujoco.MjData, goal: np.ndarray, goal_yaw: float,
              start_yaw: float | None = None, side_to: np.ndarray | None = None
              ) -> gait.SteppingPlan:
    """Plan for walking the standing agent from where it is to ``goal`` (x, y, m),
    facing ``goal_yaw`` (rad) at the end, stepping first through the waypoints
    ``side_to`` ((K, 2) or (2,), x, y; default: none) with the heading kept and turning
    on the spot onto ``start_yaw`` (default: facing the goal, then a straight walk and a
    turn at the goal) (:func:`walk_steps`), on its own legs.

    Raises:
        SimenvError: the agent is not standing (pelvis below :data:`STANDING_FRACTION` of
            its standing height: it fell, it is seated), or a footstep is out of the
            legs' reach.

    Returns:
        the plan, whose feedback (:class:`GaitMeter`) measures the help (none) and the
        outcome (fallen or not, distance from the goal).
    """
    check_standing(room, data, "walk")
    steps = walk_steps(room, data, goal, goal_yaw, start_yaw, side_to)
    plan = gait.plan_footsteps(room, data, steps)
    plan.feedback = GaitMeter(room, plan.balance, np.array(goal, float)[:2])
    return plan


def standing_targets(room: Room, data: mujoco.MjData) -> np.ndarray:
    """(nu,) servo targets holding the standing agent where it stands: its leg hinges as
    they are, the upper body upright with the arms hanging (:data:`gait.ARM_ABD`),
    gravity fed forward on the upper body only (:func:`~simenv.agents.reach.pd_targets`).
    Nominal targets: the servo targets in ``data.ctrl`` also carry the last balance
    feedback, whose static leg torques the next stage's feedback would add a second time
    (measured: after a standing act the body leant back and fell)."""
    h = room.agent
    q = h.default_qpos()
    q[:7] = data.qpos[room.agent_qpos][:7]
    legs = [hinge_adr(h, n) for n in gait.leg_joints(h)]
    q[legs] = data.qpos[room.agent_qpos][legs]
    for side in ("left", "right"):
        q[hinge_adr(h, f"{side}_upper_arm_abd")] = gait.ARM_ABD
    return pd_targets(h, q, upper_body_joints(h))


#: Seconds per via-point of a grasped stroke, and the holds before and after it.
STROKE_STEP_S = 0.4
STROKE_HOLD_S = 0.3
#: The arm back to its standing targets after an act, s, and then standing still, s (the
#: arm swung down in 1 s and the body, leant back against its outstretched weight, rocked
#: back and fell once the act ended, measured).
REST_S = 2.5
STAND_S = 1.5


def held_grasp_stroke(room: Room, data: mujoco.MjData, approach: Sequence[tuple[np.ndarray,
                      float]], strokes: Sequence[np.ndarray], leave: Sequence[tuple[
                      np.ndarray, float]], hand: str, obj: str) -> PDPlan:
    """A standing manipulation, the body balanced on both feet by the gait's
    centre-of-mass feedback (:func:`simenv.agents.gait.stand_balance`, over the feet's
    centre): PD targets through ``approach`` ((targets, seconds) pairs, the last one on
    the object), held :data:`STROKE_HOLD_S`, the proximity grasp of ``obj`` by ``hand``
    asked for, the ``strokes`` via-points (:data:`STROKE_STEP_S` each), a hold, the grasp
    released, then ``leave`` ((targets, seconds) pairs), then :data:`STAND_S` standing
    still. Grasp events fire 50 ms before the end of each hold (so the hand is still and
    on its mark)."""
    check_standing(room, data, "act")
    now = standing_targets(room, data)
    segments, prev = [], now
    for target, seconds in approach:
        segments.append(PDTrajectory(prev, target, seconds))
        prev = target
    segments.append(PDTrajectory(prev, prev, STROKE_HOLD_S))
    t_close = sum(s.duration for s in segments) - 0.05
    for target in strokes:
        segments.append(PDTrajectory(prev, target, STROKE_STEP_S))
        prev = target
    segments.append(PDTrajectory(prev, prev, STROKE_HOLD_S))
    t_open = sum(s.duration for s in segments) - 0.05
    for target, seconds in leave:
        segments.append(PDTrajectory(prev, target, seconds))
        prev = target
    segments.append(PDTrajectory(prev, prev, STAND_S))
    total = sum(s.duration for s in segments)
    meter = GaitMeter(room, gait.stand_balance(room, data, total))
    return PDPlan(segments, [GraspEvent(t_close, hand, obj, True),
                             GraspEvent(t_open, hand, obj, False)], feedback=meter)


__all__ = ["GaitMeter", "held_grasp_stroke", "path_steps", "plan_walk", "standing_targets",
           "turn_steps", "walk_path", "walk_steps"]

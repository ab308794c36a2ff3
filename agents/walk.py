"""Walking the standing agent to a spot, by tracking a real walk retargeted onto its body,
with a measured root assistance.

Reference: a real walking clip (default the bundled CMU 02_01 walk) retargeted onto the
agent's humanoid (:func:`simenv.retarget.retarget_motion`) at :data:`REF_FPS`. Its root
path on the floor is mapped onto a planned path (:func:`plan_walk`): a cubic Bezier curve
``B(u)`` from the agent's pelvis to the goal, leaving along the start heading and
arriving along the goal heading. Reference frame ``k`` at arc length ``s_k`` of the clip's
own root path (scaled by ``L_path / s_N``) with the root's lateral sway ``l_k`` (m, from
the clip's straight mean line) and yaw ``psi_k`` relative to that line becomes::

    root_xy = B(s_k) + l_k n(s_k),    yaw = atan2(B'(s_k)) + psi_k

with ``n`` the path's left normal; height, tilt and hinge angles are the clip's. Time runs
:data:`SLOWDOWN` times slower than the clip, from its first frame. The hinge angles are
the PD servos' targets with the reference velocity fed through the servos' damping
(``ctrl = q_ref + (kv/kp) qd_ref``, as :func:`simenv.plausibility.tracking.track`
does). The path starts :func:`_first_step` ahead of the pelvis, where the clip's first
pose keeps its rear toe on the standing toe; the first step into that pose lifts the
front foot :data:`STEP_LIFT_M` half-way to its place and sets it there (two halves of
:data:`BLEND_IN_S`; blending the targets straight to that pose dragged both planted feet
0.56 m apart, measured 3.3 body weights of assistance), and a blend-out brings the body
to the standing rest pose at the goal.

Root assistance (:class:`RootAssist`): the PD servos alone do not keep the walking body up
(measured: see docs/room.md), so a force and a torque on the pelvis pull it along the
reference root through a soft weld from a mocap target to the pelvis
(:meth:`simenv.room.Room.set_assist`, time constant
:data:`simenv.room.ASSIST_TIMECONST_S`, critically damped: MuJoCo's implicit "hand of
god"; an explicit PD force on the light pelvis body went unstable at useful rotational
gains, measured). Every physics step's weld force ``|F|`` (N) and torque ``|tau|`` (N m)
is recorded and reported
(:meth:`RootAssist.summary`, also as a fraction of body weight); nothing is hidden.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache

import mujoco
import numpy as np

from simenv.agents.reach import (
    GraspEvent,
    PDPlan,
    PDTrajectory,
    pd_targets,
    reach_pose,
    upper_body_joints,
)
from simenv.agents.stand import FEET
from simenv.assets import WALK, asset_path
from simenv.errors import SimenvError
from simenv.humanoid import Humanoid
from simenv.room import Room

#: Frame rate of the reference walk, Hz.
REF_FPS = 25.0
#: The reference plays this many times slower than recorded (the clip walks 1.18 m/s).
SLOWDOWN = 2.0
#: The first step from the standing pose onto the path's first pose, and the blend from
#: its last pose to standing at the goal, s.
BLEND_IN_S = 1.2
BLEND_OUT_S = 1.2
#: The walk starts only with the pelvis at least this fraction of its standing height.
STANDING_FRACTION = 0.9
#: Bezier handle length as a fraction of the start-goal distance.
HANDLE_FRACTION = 0.45
GRAVITY = 9.81
#: The front foot's lift in the first step onto the clip's first pose, m.
STEP_LIFT_M = 0.08


@lru_cache(maxsize=4)
def _reference(humanoid: Humanoid, clip: str) -> np.ndarray:
    """(T, nq) the clip retargeted onto ``humanoid`` at :data:`REF_FPS`."""
    from simenv.io import load
    from simenv.retarget import retarget_motion

    motion = load(asset_path(clip) if clip == WALK else clip)
    return retarget_motion(motion.resample(REF_FPS), humanoid).qpos


def _yaw(quat: np.ndarray) -> np.ndarray:
    """Heading (rad) of (..., 4) wxyz quaternions: the body x axis on the floor."""
    w, x, y, z = np.moveaxis(np.asarray(quat), -1, 0)
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _yaw_quat(yaw: np.ndarray) -> np.ndarray:
    yaw = np.asarray(yaw)
    return np.stack([np.cos(yaw / 2), 0 * yaw, 0 * yaw, np.sin(yaw / 2)], axis=-1)


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = np.moveaxis(a, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2],
                    axis=-1)


def _bezier(p: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points and tangents (len(u), 2) of the cubic Bezier with control points p (4, 2)."""
    u = u[:, None]
    pts = ((1 - u) ** 3 * p[0] + 3 * (1 - u) ** 2 * u * p[1] + 3 * (1 - u) * u**2 * p[2]
           + u**3 * p[3])
    tan = 3 * (1 - u) ** 2 * (p[1] - p[0]) + 6 * (1 - u) * u * (p[2] - p[1]) + 3 * u**2 * (
        p[3] - p[2])
    return pts, tan


@dataclass
class RootAssist:
    """Measured pull on the agent's pelvis along a reference root (module docstring); a
    :data:`~simenv.agents.reach.Feedback` that passes the plan's targets through, moves
    the room's assistance weld target (:meth:`simenv.room.Room.set_assist`) every physics
    step and records the weld's force and torque.

    Attributes:
        room: the room. times: (N,) s into the plan. pos: (N, 3) m. quat: (N, 4) wxyz.
        forces_n, torques_nm: per physics step ``|F|`` (N) and ``|tau|`` (N m).
    """

    room: Room
    times: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    forces_n: list[float] = field(default_factory=list)
    torques_nm: list[float] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.mass = float(self.room.agent.total_mass)

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference root position (3,) and orientation (4,) at ``t`` s."""
        i = int(np.clip(np.searchsorted(self.times, t) - 1, 0, len(self.times) - 2))
        a = float(np.clip((t - self.times[i]) / (self.times[i + 1] - self.times[i]), 0, 1))
        q = (1 - a) * self.quat[i] + a * self.quat[i + 1]
        return (1 - a) * self.pos[i] + a * self.pos[i + 1], q / np.linalg.norm(q)

    def __call__(self, t: float, data: mujoco.MjData, targets: np.ndarray) -> np.ndarray:
        if self.forces_n or t > 0.0:  # the weld's force at the step just taken
            f, tau = self.room.assist_wrench(data)
            self.forces_n.append(f)
            self.torques_nm.append(tau)
        self.room.set_assist(data, *self.reference(t))
        return targets

    def summary(self, steps_per_frame: int = 20) -> dict[str, float | int | list[float]]:
        """Assistance over the physics steps so far: ``mean_n``, ``p95_n``, ``max_n`` (N),
        the same as fractions of body weight (``*_bw``), ``mean_torque_nm``,
        ``max_torque_nm``, ``steps``, and ``per_frame_n``: the mean force (N, 0.1 N
        resolution) over each ``steps_per_frame`` physics steps (one 25 fps env step)."""
        f = np.asarray(self.forces_n) if self.forces_n else np.zeros(1)
        tq = np.asarray(self.torques_nm) if self.torques_nm else np.zeros(1)
        weight = self.mass * GRAVITY
        out: dict[str, float | int | list[float]] = {
            "mean_n": float(f.mean()), "p95_n": float(np.percentile(f, 95)),
            "max_n": float(f.max()), "mean_torque_nm": float(tq.mean()),
            "max_torque_nm": float(tq.max()), "steps": len(self.forces_n)}
        for k in ("mean", "p95", "max"):
            out[f"{k}_bw"] = float(out[f"{k}_n"]) / weight
        chunks = range(0, len(self.forces_n), steps_per_frame)
        out["per_frame_n"] = [round(float(f[i:i + steps_per_frame].mean()), 1) for i in chunks]
        return out


@dataclass(frozen=True)
class KeyframeTrajectory:
    """PD targets interpolated linearly between keyframes ``frames`` (N, nu) ``dt`` s
    apart (a dense reference, where minimum-jerk segments would stop at every frame)."""

    frames: np.ndarray
    dt: float

    @property
    def duration(self) -> float:
        return float((len(self.frames) - 1) * self.dt)

    def at(self, t: float) -> np.ndarray:
        x = min(max(t / self.dt, 0.0), len(self.frames) - 1.0)
        i = min(int(x), len(self.frames) - 2)
        a = x - i
        return (1 - a) * self.frames[i] + a * self.frames[i + 1]


def _first_step(humanoid: Humanoid, first: np.ndarray) -> tuple[float, str]:
    """How far ahead of a standing pelvis the clip's first root must be for its rear toe
    to stay where the standing toe is (along the root's heading), m, and the side of its
    front foot."""
    names = humanoid.keypoint_names
    yaw = float(_yaw(first[3:7]))
    fwd = np.array([np.cos(yaw), np.sin(yaw)])
    kp = humanoid.keypoints(first)
    toe = {s: float((kp[names.index(f"{s}_toe"), :2] - first[:2]) @ fwd)
           for s in ("left", "right")}
    rear = min(toe, key=toe.get)
    standing = humanoid.keypoints(humanoid.default_qpos())[names.index(f"{rear}_toe")]
    front = "right" if rear == "left" else "left"
    return max(float(standing[0]) - toe[rear], 0.0), front


def _step_in(humanoid: Humanoid, q_now: np.ndarray, first: np.ndarray, front: str
             ) -> np.ndarray:
    """(nq,) the first step's middle: the pelvis half-way to the clip's first pose, the
    rear foot where it stands, the ``front`` foot lifted :data:`STEP_LIFT_M` half-way to
    its place in that pose (leg hinges by IK on the feet keypoints)."""
    names = humanoid.keypoint_names
    feet = [names.index(f) for f in FEET]
    now, there = humanoid.keypoints(q_now)[feet], humanoid.keypoints(first)[feet]
    goal = now.copy()
    moving = [FEET.index(f"{front}_ankle"), FEET.index(f"{front}_toe")]
    goal[moving] = 0.5 * (now[moving] + there[moving]) + [0.0, 0.0, STEP_LIFT_M]
    start = first.copy()
    start[:3] = 0.5 * (q_now[:3] + first[:3])
    quat = q_now[3:7] + first[3:7] * np.sign(q_now[3:7] @ first[3:7])
    start[3:7] = quat / np.linalg.norm(quat)
    legs = [n for n in humanoid.joint_names if n.split("_")[1] in ("thigh", "shin", "foot")]
    mid, _ = reach_pose(humanoid.model, start, FEET, goal, legs, iterations=400)
    return mid


def walk_path(start: np.ndarray, start_yaw: float, goal: np.ndarray, goal_yaw: float
              ) -> np.ndarray:
    """(4, 2) control points of the planned path (module docstring), m."""
    start, goal = np.asarray(start, float)[:2], np.asarray(goal, float)[:2]
    a = HANDLE_FRACTION * float(np.linalg.norm(goal - start))
    h0 = np.array([np.cos(start_yaw), np.sin(start_yaw)])
    h1 = np.array([np.cos(goal_yaw), np.sin(goal_yaw)])
    return np.array([start, start + a * h0, goal - a * h1, goal])


def plan_walk(room: Room, data: mujoco.MjData, goal: np.ndarray, goal_yaw: float,
              start_yaw: float | None = None, clip: str = WALK) -> PDPlan:
    """Plan for walking the standing agent from where it is to ``goal`` (x, y, m), facing
    ``goal_yaw`` (rad) at the end, along the path leaving at ``start_yaw`` (default: the
    pelvis's heading): the reference walk mapped onto the path, tracked by the PD servos
    with :class:`RootAssist` (the plan's feedback; read its ``summary()`` afterwards).

    Raises:
        SimenvError: the agent is not standing (pelvis below :data:`STANDING_FRACTION` of
            its standing height: it fell, it is seated), the goal is closer than 0.3 m, or
            farther than the clip walks.

    Returns:
        the plan: the first step (:data:`BLEND_IN_S`), the walk (the clip's frames up to
        the path's length, played :data:`SLOWDOWN` x slower), blend-out to standing at
        the goal, 1 s standing.
    """
    h = room.agent
    q_now = data.qpos[room.agent_qpos].copy()
    rest = float(h.default_qpos()[2])
    if q_now[2] < STANDING_FRACTION * rest:
        raise SimenvError(f"the agent is not standing (pelvis {q_now[2]:.2f} m, standing "
                          f"{rest:.2f} m): it cannot walk", field="walk")
    yaw0 = float(_yaw(q_now[3:7])) if start_yaw is None else float(start_yaw)
    ref = _reference(h, clip)
    # The first step: the path starts where the clip's first pose keeps the rear toe
    # where it stands, so that only the front foot moves to its place (lifted).
    ahead, front = _first_step(h, ref[0])
    h0 = np.array([np.cos(yaw0), np.sin(yaw0)])
    ctrl_pts = walk_path(q_now[:2] + ahead * h0, yaw0, goal, goal_yaw)
    dense = np.linspace(0.0, 1.0, 400)
    pts, _ = _bezier(ctrl_pts, dense)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    length = float(arc[-1])
    if length < 0.3:
        raise SimenvError(f"the walk's goal is {length:.2f} m away; at least 0.3 m expected",
                          field="goal")
    xy = ref[:, :2]
    s_ref = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    if s_ref[-1] < length:
        raise SimenvError(f"the reference walk covers {s_ref[-1]:.2f} m; the path is "
                          f"{length:.2f} m", field="goal")
    n = int(np.searchsorted(s_ref, length)) + 1
    ref, s_ref = ref[:n], s_ref[:n] * (length / s_ref[n - 1])
    # The clip's straight mean line: its lateral sway and yaw about it are kept.
    line = xy[n - 1] - xy[0]
    line_yaw = float(np.arctan2(line[1], line[0]))
    d = np.array([np.cos(line_yaw), np.sin(line_yaw)])
    lateral = (xy[:n] - xy[0]) @ np.array([-d[1], d[0]])
    u = np.interp(s_ref, arc, dense)
    p, tan = _bezier(ctrl_pts, u)
    path_yaw = np.arctan2(tan[:, 1], tan[:, 0])
    normal = np.stack([-np.sin(path_yaw), np.cos(path_yaw)], axis=1)
    walked = ref.copy()
    walked[:, :2] = p + lateral[:, None] * normal
    turn = _yaw_quat(path_yaw - line_yaw)
    walked[:, 3:7] = _quat_mul(turn, ref[:, 3:7])
    dt = SLOWDOWN / REF_FPS
    # Servo targets with the reference velocity passed through the servos' damping.
    m = h.model
    ratio = -m.actuator_biasprm[:, 2] / m.actuator_gainprm[:, 0]
    qd = np.gradient(walked[:, h.hinge_qpos], dt, axis=0)
    frames = walked[:, h.hinge_qpos] + ratio * qd
    upper = upper_body_joints(h)
    first = pd_targets(h, walked[0], upper) + ratio * qd[0]
    stand = h.default_qpos()
    stand[:2] = goal
    stand[2] = q_now[2]
    stand[3:7] = _yaw_quat(goal_yaw)
    rest = pd_targets(h, stand, upper)
    now = data.ctrl[room.agent_ctrl].copy()
    mid = _step_in(h, q_now, walked[0], front)
    lift = pd_targets(h, mid, upper)
    half = BLEND_IN_S / 2
    segments = [PDTrajectory(now, lift, half), PDTrajectory(lift, first, half),
                KeyframeTrajectory(frames, dt),
                PDTrajectory(frames[-1], rest, BLEND_OUT_S), PDTrajectory(rest, rest, 1.0)]
    # Root reference: blend-in from the pelvis now (its yaw turned to the path's first),
    # the walk, then standing at the goal.
    t_walk = BLEND_IN_S + dt * np.arange(n)
    t_end = t_walk[-1] + BLEND_OUT_S
    times = np.concatenate([[0.0, half], t_walk, [t_end]])
    pos = np.concatenate([q_now[None, :3], mid[None, :3], walked[:, :3], stand[None, :3]])
    quat = np.concatenate([q_now[None, 3:7], mid[None, 3:7], walked[:, 3:7], stand[None, 3:7]])
    for k in range(1, len(quat)):  # one hemisphere, so that interpolation takes the short way
        quat[k] *= np.sign(quat[k] @ quat[k - 1]) or 1.0
    return PDPlan(segments, feedback=RootAssist(room, times, pos, quat))


#: Seconds per via-point of a grasped stroke, and the holds before and after it.
STROKE_STEP_S = 0.4
STROKE_HOLD_S = 0.3


def held_grasp_stroke(room: Room, data: mujoco.MjData, approach: Sequence[tuple[np.ndarray,
                      float]], strokes: Sequence[np.ndarray], leave: Sequence[tuple[
                      np.ndarray, float]], hand: str, obj: str) -> PDPlan:
    """A standing manipulation with the pelvis held where it is (measured
    :class:`RootAssist`): PD targets through ``approach`` ((targets, seconds) pairs, the
    last one on the object), held :data:`STROKE_HOLD_S`, the proximity grasp of ``obj`` by
    ``hand`` asked for, the ``strokes`` via-points (:data:`STROKE_STEP_S` each), a hold,
    the grasp released, then ``leave`` ((targets, seconds) pairs). Grasp events fire 50 ms
    before the end of each hold (so the hand is still and on its mark)."""
    now = data.ctrl[room.agent_ctrl].copy()
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
    total = sum(s.duration for s in segments)
    q = data.qpos[room.agent_qpos]
    hold = RootAssist(room, np.array([0.0, total]), np.repeat(q[None, :3], 2, axis=0),
                      np.repeat(q[None, 3:7], 2, axis=0))
    return PDPlan(segments, [GraspEvent(t_close, hand, obj, True),
                             GraspEvent(t_open, hand, obj, False)], feedback=hold)


__all__ = ["KeyframeTrajectory", "RootAssist", "held_grasp_stroke", "plan_walk", "walk_path"]

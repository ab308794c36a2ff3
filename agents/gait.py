"""Walking on the agent's own legs: footsteps, a statically balanced stepping gait, and
centre-of-mass feedback through the legs. No force or torque acts on the body but its
own servos and its contacts.

A walk is a list of :class:`Footstep` (which foot, where its body lands on the floor, its
heading). Each step is planned when it starts, from where the feet are then (measured),
as keyframes of the whole body (the pelvis upright at the feet's mean heading,
:data:`CROUCH_M` below standing; leg hinges by damped least squares on each foot's 6D
pose, :class:`LegIK`; the pelvis moved until the centre of mass ``c(q)`` is over the
keyframe's target ``c*``, :func:`balanced_pose`):

1. *shift* (at least :data:`SHIFT_S`, at most :data:`SHIFT_SPEED` on average): both feet
   planted, ``c*`` moves along a minimum-jerk path to :data:`INSIDE_M` inside the stance
   foot's sole centre (:func:`support_centre`), in :data:`N_SUB` keyframes;
2. *settle* (:data:`SETTLE_S`) there;
3. *lift* (:data:`LIFT_S`): the swing foot rises :data:`LIFT_M` half-way to its footstep;
4. *place* (:data:`PLACE_S`): above its footstep, then down on it.

The closing stage centres ``c*`` between the soles and holds (:data:`HOLD_S`). The servo
targets are the keyframes' hinge angles moved at constant rate between keyframes, with
the rate passed through the servos' damping (:class:`LinearTrajectory`).

:class:`StepBalance` closes the loop at every physics step:

* static torques on the legs: gravity, and on each planted leg its share of the weight at
  its sole (lever rule on ``c*`` between the soles): ``tau = g(q) - J^T f``, fed to the
  position servos as ``tau / kp``;
* a virtual force ``F = -M (K e + D e')`` on the centre of mass (``e = c - c*``, m; ``e'``
  its velocity, m/s; at most :data:`F_MAX` body weights), made by the legs whose feet
  touch the floor, ``tau_i = J_i^T F / n`` with ``J_i`` the (2, n) Jacobian of the centre
  of mass relative to the planted foot (virtual model control, Pratt et al. 2001; the
  stance-leg virtual force of Coros et al. 2010);
* a lifted leg's hip holds its thigh in the world against the pelvis's rotation error and
  turns the foot onto its footstep's heading (the swing-hip world frame of SIMBICON,
  Yin et al. 2007).
"""

from __future__ import annotations

import bisect
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from simenv.agents.reach import (
    PDPlan,
    PDTrajectory,
    hinge_adr,
    min_jerk,
    pd_targets,
    upper_body_joints,
)
from simenv.body.humanoid import Humanoid
from simenv.core.errors import SimenvError
from simenv.room.room import Room

#: Durations of a step's keyframes (module docstring), s.
SHIFT_S = 1.6
LIFT_S = 0.5
PLACE_S = 1.0
#: Standing still at the end, balanced, s.
HOLD_S = 1.0
#: Swing foot's lift, m; the pelvis's drop below standing while stepping, m.
LIFT_M = 0.1
CROUCH_M = 0.08
#: ... and at the end, standing (knees a little bent: a straight knee is the IK's
#: singularity and the model's knee reaches 15 deg of hyperextension), m.
STAND_DROP_M = 0.01
#: The support centre of a foot is this far ahead of its ankle (the sole's box runs from
#: 6 cm behind the ankle to 14 cm ahead of it, the toes to 20 cm), m.
SUPPORT_AHEAD_M = 0.05
GRAVITY = 9.81
#: Centre-of-mass feedback gains (module docstring): ``K`` in 1/s^2, ``D`` in 1/s.
COM_K = 45.0
COM_D = 15.0
SIDES = ("left", "right")
#: A weight shift lasts at least :data:`SHIFT_S`, and moves the centre of mass at most
#: this fast on average, m/s (a 0.35 m shift in 1.6 s overshot the new stance foot and
#: fell, measured).
SHIFT_SPEED = 0.1
#: Settle over the stance foot before lifting the other, s.
SETTLE_S = 0.4
#: The centre of mass stands this far inside the stance foot's support centre (towards
#: the other foot) while that foot is lifted, m (0 / 0.015 / 0.03 m: 1.0 m walks fell /
#: walked / fell, k = 30 1/s^2, measured).
INSIDE_M = 0.02
#: Stepping places a foot this far from the midline, m (the standing rest pose's).
HALF_WIDTH_M = 0.09
#: The virtual force is at most this fraction of the body's weight (more asks the ankles
#: for more torque than the soles bear and tips the feet, measured).
F_MAX = 0.1
#: A foot takes part in the virtual force above this normal contact force, N.
TOUCH_N = 10.0
#: A lifted leg's hip keeps its thigh's orientation in the world against the pelvis's
#: tilt and turn error: ``K`` (rad per rad) and ``D`` (s); and turns its foot onto the
#: footstep's heading with gain ``K_YAW`` (rad per rad).
SWING_K = 1.0
SWING_D = 0.1
K_YAW = 1.0
#: Keyframes along a weight shift (each solved with the feet planted).
N_SUB = 4
#: Shoulder abduction while stepping, rad: the arms hang at the sides, hands 0.26 m from
#: the midline (the rest pose's A-pose holds them 0.56 m out, where they met the keyboard,
#: the chair's back and the north wall while walking, measured: the wall's push on the
#: right hand toppled the walk to the window).
ARM_ABD = -0.5


def _other(side: str) -> str:
    return "right" if side == "left" else "left"


def _rot(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


def _yaw_quat(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def quat_yaw(quat: np.ndarray) -> float:
    """Heading (rad) of a wxyz quaternion: the body x axis on the floor."""
    w, x, y, z = quat
    return float(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def wrap_angle(angle: float) -> float:
    """``angle`` (rad) wrapped into [-pi, pi)."""
    return float((angle + np.pi) % (2 * np.pi) - np.pi)


def _mean_yaw(a: float, b: float) -> float:
    return float(np.arctan2(np.sin(a) + np.sin(b), np.cos(a) + np.cos(b)))


@dataclass(frozen=True)
class Footstep:
    """One step: foot ``side`` lands with its ankle over ``xy`` (2,) m on the floor,
    heading ``yaw`` rad."""

    side: str
    xy: np.ndarray
    yaw: float


def support_centre(xy: np.ndarray, yaw: float) -> np.ndarray:
    """(2,) the middle of a foot's sole on the floor, m."""
    return np.asarray(xy, float) + SUPPORT_AHEAD_M * np.array([np.cos(yaw), np.sin(yaw)])


def feet_now(room: Room, data: mujoco.MjData) -> dict[str, tuple[np.ndarray, float]]:
    """Each foot body's position on the floor (x, y), m, and heading, rad, in the room
    now."""
    m = room.model
    out = {}
    for s in SIDES:
        b = m.body(f"agent/{s}_foot").id
        fwd = data.xmat[b].reshape(3, 3)[:2, 0]
        out[s] = (data.xpos[b, :2].copy(), float(np.arctan2(fwd[1], fwd[0])))
    return out


def leg_joints(h: Humanoid) -> tuple[str, ...]:
    """The hinges of both legs, hips to ankles."""
    return tuple(n for n in h.joint_names if n.split("_")[1] in ("thigh", "shin", "foot"))


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, a, b)
    return out


class LegIK:
    """Leg hinges putting each foot body at a pose: position of its ankle and orientation
    ``yaw`` about the vertical times the foot's standing rest orientation (sole flat), by
    damped least squares on the 6D error (position, m; rotation vector, rad) over that
    leg's hip, knee and ankle hinges; the pelvis stays where ``q`` puts it."""

    def __init__(self, h: Humanoid) -> None:
        m = self.model = h.model
        self.data = mujoco.MjData(m)
        rest = h.default_qpos()
        rest[:2] = 0.0
        rest[3:7] = _yaw_quat(0.0)
        self.data.qpos[:] = rest
        mujoco.mj_kinematics(m, self.data)
        self.body = [m.body(f"{s}_foot").id for s in SIDES]
        self.rest_quat = [self.data.xquat[b].copy() for b in self.body]
        #: (2, 2) the feet's bodies on the floor relative to a standing pelvis at the
        #: origin heading +x, and (2,) their height with the sole on the floor, m.
        self.offset = self.data.xpos[self.body, :2].copy()
        self.z = self.data.xpos[self.body, 2].copy()
        legs = leg_joints(h)
        self.joints = [[m.joint(n).id for n in legs if n.startswith(s) and "toes" not in n]
                       for s in SIDES]
        self.qadr = [m.jnt_qposadr[j] for j in self.joints]
        self.dadr = [m.jnt_dofadr[j] for j in self.joints]
        self.lo = [m.jnt_range[j, 0] for j in self.joints]
        self.hi = [m.jnt_range[j, 1] for j in self.joints]

    def solve(self, q: np.ndarray, feet: dict[str, tuple[np.ndarray, float]],
              iterations: int = 60, damping: float = 0.02) -> tuple[np.ndarray, float]:
        """(nq,) ``q`` with the leg hinges solved so that foot ``side``'s body is at
        ``feet[side]`` = (position (3,), yaw); and the largest position error, m."""
        m, d = self.model, self.data
        d.qpos[:] = q
        jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        err = np.inf
        for _ in range(iterations):
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            err = 0.0
            for i, side in enumerate(SIDES):
                pos, yaw = feet[side]
                b = self.body[i]
                goal = _quat_mul(_yaw_quat(yaw), self.rest_quat[i])
                rot = np.zeros(3)
                mujoco.mju_subQuat(rot, goal, d.xquat[b])
                rot = d.xmat[b].reshape(3, 3) @ rot  # from the foot's frame to the world's
                e = np.concatenate([pos - d.xpos[b], rot])
                err = max(err, float(np.linalg.norm(e[:3])))
                mujoco.mj_jacBody(m, d, jp, jr, b)
                j = np.concatenate([jp, jr])[:, self.dadr[i]]
                dq = j.T @ np.linalg.solve(j @ j.T + damping**2 * np.eye(6), e)
                d.qpos[self.qadr[i]] = np.clip(d.qpos[self.qadr[i]] + dq, self.lo[i],
                                               self.hi[i])
            if err < 1e-4:
                break
        return d.qpos.copy(), err

    def neutral(self, side: str, pelvis_xy: np.ndarray, yaw: float) -> np.ndarray:
        """(2,) where foot ``side`` stands under a standing pelvis at ``pelvis_xy``
        heading ``yaw`` when stepping: the rest pose's place brought to
        :data:`HALF_WIDTH_M` from the midline (a narrower stance shortens the sideways
        travel of the centre of mass at every step), m."""
        off = self.offset[SIDES.index(side)].copy()
        off[1] = np.sign(off[1]) * HALF_WIDTH_M
        return np.asarray(pelvis_xy, float) + _rot(yaw) @ off

    def place(self, side: str, xy: np.ndarray, yaw: float, lift: float = 0.0
              ) -> tuple[np.ndarray, float]:
        """The foot body's pose (position (3,), yaw) standing at ``xy``, lifted ``lift``."""
        return np.array([*xy, self.z[SIDES.index(side)] + lift]), float(yaw)

    def com(self, q: np.ndarray) -> np.ndarray:
        """(2,) the centre of mass of the body in ``q``, m."""
        self.data.qpos[:] = q
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        return self.data.subtree_com[1, :2].copy()

    def foot_pose(self, q: np.ndarray, side: str) -> tuple[np.ndarray, float]:
        """Foot ``side``'s body position (3,) and heading in ``q``."""
        self.data.qpos[:] = q
        mujoco.mj_kinematics(self.model, self.data)
        b = self.body[SIDES.index(side)]
        fwd = self.data.xmat[b].reshape(3, 3)[:2, 0]
        return self.data.xpos[b].copy(), float(np.arctan2(fwd[1], fwd[0]))


def balanced_pose(ik: LegIK, upper: np.ndarray, feet: dict[str, tuple[np.ndarray, float]],
                  com: np.ndarray, yaw: float, height: float, guess: np.ndarray
                  ) -> tuple[np.ndarray, float]:
    """(nq,) a pose with the feet's bodies at ``feet`` (:meth:`LegIK.solve`), the centre of
    mass over ``com`` (2,), the pelvis upright at ``height`` m heading ``yaw``, the
    hinges off the legs as in ``upper`` (nq,); and the feet's largest IK error, m."""
    q = guess.copy()
    legs = np.concatenate(ik.qadr)
    keep = np.ones(len(q), bool)
    keep[legs] = False
    keep[:7] = False
    q[keep] = upper[keep]
    for i in range(2):  # off a straight knee (singular for IK: no gradient downwards)
        hip, knee, ankle = ik.qadr[i][0], ik.qadr[i][3], ik.qadr[i][4]
        if q[knee] < 0.2:
            q[[hip, knee, ankle]] = [0.15, 0.3, -0.15]
    q[2] = height
    q[3:7] = _yaw_quat(yaw)
    q[:2] += com - ik.com(q)
    err = np.inf
    for _ in range(4):
        q, err = ik.solve(q, feet)
        q[:2] += com - ik.com(q)
    q, err = ik.solve(q, feet)
    return q, err


@dataclass(frozen=True)
class LinearTrajectory:
    """PD targets moving at constant rate from ``start`` to ``goal`` (both (nu,), rad) in
    ``duration`` s (keyframes dense enough for straight interpolation), with the rate
    passed through the servos' damping: ``ctrl = q(t) + (kv / kp) q'(t)``
    (``lead`` (nu,) = kv / kp, s), so that the damping does not hold the motion back."""

    start: np.ndarray
    goal: np.ndarray
    duration: float
    lead: np.ndarray | float = 0.0

    def at(self, t: float) -> np.ndarray:
        """Targets ``t`` seconds after the start (``goal`` from ``duration`` on)."""
        if self.duration <= 0 or t >= self.duration:
            return self.goal
        s = max(t / self.duration, 0.0)
        return self.start + s * (self.goal - self.start) + self.lead * (
            self.goal - self.start) / self.duration


@dataclass
class StepBalance:
    """Centre-of-mass feedback through the legs on the floor (module docstring), a
    :data:`~simenv.agents.reach.Feedback`.

    Attributes:
        room: the room. times: (N,) keyframe times, s into the plan. com: (N, 2) planned
            centre of mass at them, m. yaws: (N,) planned heading of the upright pelvis,
            rad. down: (N, 2) whether the left and right foot are planned on the floor
            at them. k, d: ``K`` (1/s^2) and ``D`` (1/s). f_max: the virtual force's
            largest magnitude, body weights.
    """

    room: Room
    times: np.ndarray
    com: np.ndarray
    yaws: np.ndarray
    down: np.ndarray
    k: float = COM_K
    d: float = COM_D
    f_max: float = F_MAX

    def __post_init__(self) -> None:
        #: The heading the lifted foot turns to, rad (set per step by the plan), or None.
        self.swing_yaw: float | None = None
        m, h = self.room.model, self.room.agent
        self._pelvis = m.body("agent/pelvis").id
        self._foot = [m.body(f"agent/{s}_foot").id for s in SIDES]
        legs = leg_joints(h)
        self._act = [np.array([h.joint_names.index(n) for n in legs if n.startswith(s)])
                     for s in SIDES]
        self._dof = [np.array([m.joint(f"agent/{n}").dofadr[0] for n in legs
                               if n.startswith(s)]) for s in SIDES]
        self._kp = m.actuator_gainprm[self.room.agent_ctrl, 0]
        self._mass = float(h.total_mass)
        self._jc = np.zeros((3, m.nv))
        self._jf = np.zeros((3, m.nv))
        self._jr = np.zeros((3, m.nv))
        #: (ngeom, 2) whether each geom is part of the left / right foot.
        self._foot_geom = np.zeros((m.ngeom, 2), dtype=bool)
        for i, s in enumerate(SIDES):
            for g in ("foot", "toes"):
                self._foot_geom[m.geom(f"agent/{s}_{g}").id, i] = True
        self._wrench = np.zeros(6)
        self._root = int(m.jnt_dofadr[m.body("agent/pelvis").jntadr[0]])
        hips = [[f"{s}_thigh_{p}" for p in ("flex", "abd", "rot")] for s in SIDES]
        self._hip = [np.array([h.joint_names.index(n) for n in hs]) for hs in hips]
        self._hipj = [np.array([m.joint(f"agent/{n}").id for n in hs]) for hs in hips]

    def loads(self, data: mujoco.MjData) -> np.ndarray:
        """(2,) the normal contact force on the left and right foot now, N."""
        out = np.zeros(2)
        # Per contact (in order), the feet it touches: (ncon, 2) from its two geoms.
        feet = self._foot_geom[data.contact.geom[:data.ncon]].any(axis=1)
        for k in np.flatnonzero(feet.any(axis=1)):
            mujoco.mj_contactForce(self.room.model, data, int(k), self._wrench)
            out[feet[k]] += self._wrench[0]
        return out

    def keyframe(self, t: float) -> int:
        """Index of the keyframe segment ``t`` s into the plan is in (clamped to the
        first and the last)."""
        return min(max(int(self.times.searchsorted(t, side="right")) - 1, 0),
                   len(self.times) - 2)

    def reference(self, t: float) -> tuple[np.ndarray, float]:
        """Planned centre of mass (2,), m, and pelvis heading, rad, at ``t`` s (straight
        between keyframes, as the targets)."""
        return self._reference(t, self.keyframe(t))

    def _reference(self, t: float, i: int) -> tuple[np.ndarray, float]:
        s = min(max(float((t - self.times[i]) / (self.times[i + 1] - self.times[i])), 0.0),
                1.0)
        return ((1 - s) * self.com[i] + s * self.com[i + 1],
                float((1 - s) * self.yaws[i] + s * self.yaws[i + 1]))

    def __call__(self, t: float, data: mujoco.MjData, targets: np.ndarray) -> np.ndarray:
        m = self.room.model
        i = self.keyframe(t)
        ref, yaw = self._reference(t, i)
        down = self.down[i] & self.down[i + 1]
        touch = self.loads(data) > TOUCH_N
        mujoco.mj_jacSubtreeCom(m, data, self._jc, self._pelvis)
        c = data.subtree_com[self._pelvis, :2]
        cd = (self._jc @ data.qvel)[:2]
        u = targets.copy()
        # Static torques: gravity on every hinge of the legs, and on a planted leg its
        # share of the weight at its sole's centre (lever rule on the planned centre of
        # mass between the two soles; all of it on the one planted foot):
        # tau_j = g_j(q) - J_j^T f_j, f_j = (0, 0, w_j M g).
        cen = [data.xpos[f, :2] + SUPPORT_AHEAD_M * data.xmat[f].reshape(3, 3)[:2, 0]
               for f in self._foot]
        share = down.astype(float)
        if down.all():
            ab = cen[1] - cen[0]
            r = min(max(float((ref - cen[0]) @ ab / max(float(ab @ ab), 1e-6)), 0.0), 1.0)
            share = np.array([1.0 - r, r])
        weight = self._mass * GRAVITY
        for j in range(2):
            tau = data.qfrc_bias[self._dof[j]].copy()
            if down[j]:
                pt = np.array([*cen[j], data.xpos[self._foot[j], 2]])
                mujoco.mj_jac(m, data, self._jf, None, pt, self._foot[j])
                tau -= self._jf[2, self._dof[j]] * share[j] * weight
            u[self._act[j]] += tau / self._kp[self._act[j]]
        # The virtual force on the centre of mass through the legs on the floor.
        force = -self._mass * (self.k * (c - ref) + self.d * cd)
        norm = float(np.sqrt(force @ force))  # np.linalg.norm's own formula, without its checks
        if norm > self.f_max * weight:
            force *= self.f_max * weight / norm
        for j in np.flatnonzero(touch):
            point = data.xpos[self._foot[j]]
            mujoco.mj_jac(m, data, self._jf, self._jr, point, self._foot[j])
            # The kinematic tree hangs from the pelvis; with the foot held still instead,
            # the centre of mass moves by (J_c - J_p + [r]x J_r) dq relative to it.
            r = data.subtree_com[self._pelvis] - point
            skew = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
            jrel = (self._jc - self._jf + skew @ self._jr)[:2, self._dof[j]]
            u[self._act[j]] += (jrel.T @ force) / touch.sum() / self._kp[self._act[j]]
        # A lifted leg: its hip keeps the thigh where the world wants it, turning against
        # the pelvis's rotation error e from upright at the planned heading (world
        # rotation vector; dq = A^-1 (K e - D w), A (3, 3) the hip's hinge axes in the
        # world, w the pelvis's angular velocity), and turns the foot onto its footstep's
        # heading (a turn's feet landed 10-13 deg short without it, measured).
        if down.all():
            return u
        e = np.zeros(3)
        mujoco.mju_subQuat(e, _yaw_quat(yaw), data.xquat[self._pelvis])
        rmat = data.xmat[self._pelvis].reshape(3, 3)
        rot = SWING_K * (rmat @ e) - SWING_D * (rmat @ data.qvel[self._root + 3:self._root + 6])
        for j in np.flatnonzero(~down):
            if self.swing_yaw is not None:
                fwd = data.xmat[self._foot[j]].reshape(3, 3)[:2, 0]
                rot = rot + [0.0, 0.0, K_YAW * wrap_angle(self.swing_yaw - np.arctan2(fwd[1],
                                                                                fwd[0]))]
            u[self._hip[j]] += np.linalg.solve(data.xaxis[self._hipj[j]].T, rot)
        return u


@dataclass
class _Stage:
    """One planned step (or the closing centring): its start ``t0`` (s into the plan),
    keyframe times (absolute, s), centre-of-mass references (K, 2), pelvis headings (K,),
    planned contacts (K, 2) and the servo-target segments between the keyframes."""

    t0: float
    times: list[float]
    coms: list[np.ndarray]
    yaws: list[float]
    down: list[np.ndarray]
    segments: list[LinearTrajectory]


class SteppingPlan:
    """The stepping gait over ``steps`` (module docstring), with the interface of a
    :class:`~simenv.agents.reach.PDPlan` (``duration``, ``grasps``, ``feedback``,
    :meth:`control`). Each step is planned when it starts, from where the feet are then
    (measured in the simulation), so a foot that landed off its mark is stood on where it
    is; the swing foot still goes to its footstep. All steps are planned once at
    construction from the footsteps alone, to refuse a walk out of the legs' reach.

    Raises:
        SimenvError: a keyframe is out of the legs' reach (IK more than 2 cm short).
    """

    def __init__(self, room: Room, data: mujoco.MjData, steps: Sequence[Footstep]) -> None:
        self.room = room
        self.steps = list(steps)
        self.grasps: tuple = ()
        h = room.agent
        self._ik = leg_ik(h)
        self._upper = h.default_qpos()
        for side in ("left", "right"):  # the arms hang at the sides (:data:`ARM_ABD`)
            self._upper[hinge_adr(h, f"{side}_upper_arm_abd")] = ARM_ABD
        self._rest = float(self._upper[2])
        m = h.model
        self._lead = -m.actuator_biasprm[:, 2] / m.actuator_gainprm[:, 0]
        pelvis = room.model.body("agent/pelvis").id
        com = data.subtree_com[pelvis, :2].copy()
        feet = feet_now(room, data)
        q = data.qpos[room.agent_qpos].copy()
        ctrl = data.ctrl[room.agent_ctrl].copy()
        #: Start of each stage (the steps, then the closing centring), s; its weight
        #: shift lasts at least :data:`SHIFT_S`, longer for a long shift
        #: (:data:`SHIFT_SPEED`), fixed by the dry run below.
        self.starts = [0.0]
        self._shift_s: list[float] = []
        for k in range(len(self.steps) + 1):  # the dry run: every keyframe within reach
            stage, feet, q = self._plan(k, feet, com, q, ctrl)
            com, ctrl = stage.coms[-1], stage.segments[-1].goal
            self.starts.append(stage.times[-1])
        self.duration = self.starts.pop()
        self._stage: _Stage | None = None
        #: Why a step could not be planned while walking (the feet were off every
        #: reachable place: the body fell), or None.
        self.failed: str | None = None
        self._last = (data.subtree_com[pelvis, :2].copy(), data.qpos[room.agent_qpos].copy(),
                      data.ctrl[room.agent_ctrl].copy())
        yaw = _mean_yaw(feet["left"][1], feet["right"][1])
        #: The balance feedback; :attr:`feedback` calls it (a wrapper may replace
        #: :attr:`feedback`, e.g. :class:`simenv.agents.walk.GaitMeter`).
        self.balance = StepBalance(room, np.array([0.0, 1.0]), np.array([com, com]),
                                   np.array([yaw, yaw]), np.ones((2, 2), bool))
        self.feedback: Callable[[float, mujoco.MjData, np.ndarray], np.ndarray] = self.balance

    def _plan(self, k: int, feet: dict[str, tuple[np.ndarray, float]], com: np.ndarray,
              q: np.ndarray, ctrl: np.ndarray
              ) -> tuple[_Stage, dict[str, tuple[np.ndarray, float]], np.ndarray]:
        """Stage ``k`` (step ``k``, or the closing centring for ``k = len(steps)``) from
        ``feet``, the centre-of-mass reference ``com`` (2,), the pose ``q`` (an IK guess)
        and the servo targets ``ctrl`` it starts from; the stage, the feet after it and
        its last pose."""
        h, ik = self.room.agent, self._ik
        feet = dict(feet)
        t0 = self.starts[k]
        st = _Stage(t0, [t0], [np.asarray(com, float)], [_mean_yaw(feet["left"][1],
                    feet["right"][1])], [np.array([True, True])], [])
        targets = [ctrl]
        guess = q

        def key(duration: float, poses: dict[str, tuple[np.ndarray, float]],
                c: np.ndarray, lifted: str | None, drop: float = CROUCH_M) -> None:
            nonlocal guess
            yaw = _mean_yaw(feet["left"][1], feet["right"][1])
            qk, err = balanced_pose(ik, self._upper, poses, c, yaw, self._rest - drop, guess)
            if err > 0.02:
                raise SimenvError(f"a step is out of the legs' reach ({err:.3f} m short)",
                                  field="step")
            guess = qk
            st.times.append(st.times[-1] + duration)
            st.coms.append(c)
            st.yaws.append(yaw)
            st.down.append(np.array([s != lifted for s in SIDES]))
            targets.append(pd_targets(h, qk, upper_body_joints(h)))

        def planted() -> dict[str, tuple[np.ndarray, float]]:
            return {s: ik.place(s, *feet[s]) for s in SIDES}

        def shift(c: np.ndarray) -> None:
            # Sub-keyframes along a minimum-jerk path of the centre of mass, each solved
            # with the feet planted (hinge angles interpolated straight across a whole
            # shift lifted a foot, measured).
            c0 = st.coms[-1]
            if len(self._shift_s) <= k:
                self._shift_s.append(max(SHIFT_S, float(np.linalg.norm(c - c0)) / SHIFT_SPEED))
            for j in range(1, N_SUB + 1):
                key(self._shift_s[k] / N_SUB, planted(), c0 + min_jerk(j / N_SUB) * (c - c0),
                    None)

        if k < len(self.steps):
            step = self.steps[k]
            stance, swing = _other(step.side), step.side
            centre = support_centre(*feet[stance])
            inward = support_centre(*feet[swing]) - centre
            centre = centre + INSIDE_M * inward / max(float(np.linalg.norm(inward)), 1e-6)
            shift(centre)
            key(SETTLE_S, planted(), centre, None)
            poses = planted()
            poses[swing] = ik.place(swing, 0.5 * (feet[swing][0] + step.xy),
                                    _mean_yaw(feet[swing][1], step.yaw), LIFT_M)
            key(LIFT_S, poses, centre, swing)
            poses = planted()
            poses[swing] = ik.place(swing, step.xy, step.yaw, LIFT_M / 2)
            key(PLACE_S / 2, poses, centre, swing)
            feet[swing] = (np.asarray(step.xy, float), float(step.yaw))
            key(PLACE_S / 2, planted(), centre, None)
        else:
            shift(0.5 * (support_centre(*feet["left"]) + support_centre(*feet["right"])))
            # Rise out of the stepping crouch: standing, the hands reach as high as before
            # the walk (crouched, the window's handle was 8 cm out of reach, measured).
            key(HOLD_S, planted(), st.coms[-1], None, STAND_DROP_M)
        st.yaws = list(np.unwrap(st.yaws))
        st.segments = [LinearTrajectory(a, b, t1 - ta, self._lead) for a, b, ta, t1 in zip(
            targets[:-1], targets[1:], st.times[:-1], st.times[1:], strict=True)]
        return st, feet, guess

    def control(self, t: float, data: mujoco.MjData) -> np.ndarray:
        """(nu,) servo targets ``t`` s into the plan, corrected by :class:`StepBalance`;
        a step is planned when it starts, from the feet where they are."""
        k = bisect.bisect_right(self.starts, t) - 1
        if self._stage is None or self._stage.t0 != self.starts[k]:
            com, q, ctrl = self._last
            try:
                st, _, _ = self._plan(k, feet_now(self.room, data), com, q, ctrl)
            except SimenvError as exc:  # the feet are not where a step can start: fallen
                self.failed = str(exc)
                t0 = self.starts[k]
                st = _Stage(t0, [t0, self.duration], [com, com], [0.0, 0.0],
                            [np.ones(2, bool)] * 2,
                            [LinearTrajectory(ctrl, ctrl, self.duration - t0)])
            self._stage = st
            self._last = (st.coms[-1], q, st.segments[-1].goal)
            fb = self.balance
            fb.times, fb.com = np.array(st.times), np.array(st.coms)
            fb.yaws, fb.down = np.array(st.yaws), np.array(st.down)
            fb.swing_yaw = self.steps[k].yaw if k < len(self.steps) else None
        st = self._stage
        i = min(max(bisect.bisect_right(st.times, t) - 1, 0), len(st.segments) - 1)
        return self.feedback(t, data, st.segments[i].at(t - st.times[i]))


def plan_footsteps(room: Room, data: mujoco.MjData, steps: Sequence[Footstep]
                   ) -> SteppingPlan:
    """Plan for the standing agent taking ``steps`` one after the other (module
    docstring), ending standing over both feet (:class:`SteppingPlan`)."""
    return SteppingPlan(room, data, steps)


_IK: dict[int, LegIK] = {}


def leg_ik(h: Humanoid) -> LegIK:
    """The :class:`LegIK` of ``h`` (one per humanoid)."""
    if id(h) not in _IK:
        _IK[id(h)] = LegIK(h)
    return _IK[id(h)]


def stand_balance(room: Room, data: mujoco.MjData, duration: float) -> StepBalance:
    """:class:`StepBalance` holding the standing body's centre of mass over the middle of
    its feet's support centres for ``duration`` s, both feet down, the pelvis upright at
    the feet's mean heading (a standing manipulation's balance)."""
    feet = feet_now(room, data)
    middle = 0.5 * (support_centre(*feet["left"]) + support_centre(*feet["right"]))
    yaw = _mean_yaw(feet["left"][1], feet["right"][1])
    return StepBalance(room, np.array([0.0, max(duration, 1e-3)]), np.array([middle, middle]),
                       np.array([yaw, yaw]), np.ones((2, 2), bool))


def play(room: Room, data: mujoco.MjData, plan: Any) -> None:
    """Play ``plan`` (``duration`` s, ``control(t, data)`` -> the agent's servo targets) as
    the environment does: its targets at every physics step."""
    dt = room.model.opt.timestep
    for i in range(int(round(plan.duration / dt))):
        data.ctrl[room.agent_ctrl] = plan.control(i * dt, data)
        mujoco.mj_step(room.model, data)


def standing_agent(room: Room, xy: np.ndarray, yaw: float, settle_s: float = 1.0
                   ) -> mujoco.MjData:
    """New data of ``room`` with the agent standing in its rest pose at ``xy`` (m) facing
    ``yaw`` (rad), its servos on the pose, balanced by :func:`stand_balance` for
    ``settle_s`` s (the start of a walk in the open)."""
    h = room.agent
    data = room.make_data()
    q = h.default_qpos()
    q[:2] = xy
    q[3:7] = _yaw_quat(yaw)
    data.qpos[room.agent_qpos] = q
    targets = pd_targets(h, q, upper_body_joints(h))
    data.ctrl[room.agent_ctrl] = targets
    mujoco.mj_forward(room.model, data)
    play(room, data, PDPlan([PDTrajectory(targets, targets, settle_s)],
                            feedback=stand_balance(room, data, settle_s)))
    return data


__all__ = ["Footstep", "LegIK", "LinearTrajectory", "StepBalance", "SteppingPlan",
           "balanced_pose", "feet_now", "leg_ik", "leg_joints", "plan_footsteps", "play",
           "quat_yaw", "stand_balance", "standing_agent", "support_centre", "wrap_angle"]

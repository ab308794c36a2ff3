"""Reaching with one arm of a PD-actuated humanoid: where to put the PD targets.

:func:`reach_pose` solves position-only inverse kinematics for one site with damped least
squares (Levenberg-Marquardt on the site error, Nakamura & Hanafusa 1986)::

    dq = J^T (J J^T + lambda^2 I)^-1 (x* - x(q)),    q <- clip(q + dq, limits)

over the chosen hinges only (the rest of the body and the root stay), with the Jacobian
``J`` (3 x n) of the site from ``mj_jacSite`` on the humanoid's own model. The solution is
a *target*: the position servos pull the arm there, against gravity and contacts, so the
hand lands short of it by the servo's static error; aiming slightly past a surface is how a
PD hand presses on it.

:class:`PDTrajectory` moves PD targets from one posture to another along a minimum-jerk
profile ``s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5`` (Flash & Hogan 1985), the smooth
point-to-point profile of human reaching: zero velocity and acceleration at both ends, so
the servos never see a step.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from simenv.body.humanoid import Humanoid
from simenv.core.errors import SimenvError

#: Hinges of one arm (side ``left`` or ``right``), shoulder girdle to wrist.
ARM_PARTS = ("clavicle_protract", "clavicle_elevate", "upper_arm_flex", "upper_arm_abd",
             "upper_arm_rot", "forearm_flex", "forearm_pronate")


def upper_body_joints(humanoid: Humanoid) -> tuple[str, ...]:
    """Hinges above the pelvis: spine, neck, shoulder girdles, arms and wrists (the part
    of a seated or standing body that hangs in the air)."""
    upper = ("lumbar", "thorax", "chest", "neck", "clavicle", "upper_arm", "forearm", "hand")
    return tuple(n for n in humanoid.joint_names if any(
        n.startswith(p) or n.startswith(f"left_{p}") or n.startswith(f"right_{p}")
        for p in upper))


def hinge_adr(humanoid: Humanoid, name: str) -> int:
    """Address in the humanoid's own qpos of its hinge ``name``."""
    return int(humanoid.hinge_qpos[humanoid.joint_names.index(name)])


def arm_joints(side: str) -> tuple[str, ...]:
    """Hinge names of the ``side`` arm (the wrist is left neutral)."""
    if side not in ("left", "right"):
        raise SimenvError(f"side must be 'left' or 'right'; got {side!r}", field="side")
    return tuple(f"{side}_{p}" for p in ARM_PARTS)


def reach_pose(model: mujoco.MjModel, qpos: np.ndarray, site: str | Sequence[str],
               target: Sequence[float] | np.ndarray, joints: Sequence[str], *,
               iterations: int = 200, damping: float = 0.03, tol: float = 1e-3
               ) -> tuple[np.ndarray, float]:
    """Hinge angles putting ``site`` at ``target`` (world, m), moving only ``joints``.

    Args:
        model: a model holding the site and the joints: a humanoid's own model, or the
            room's (then with the ``agent/`` prefix, e.g. for the room-only grip sites).
        qpos: (model.nq,) the current configuration (everything else is kept).
        site: site name (e.g. ``"right_hand"``), or S names solved together (their
            Jacobians stacked, e.g. a foot's ankle and toe to keep it planted).
        target: (3,) world position, m, or (S, 3) with several sites.
        joints: hinge names allowed to move.
        damping: lambda, m; larger is slower but robust near singular arm postures.

    Returns:
        The solved (nq,) configuration and the remaining site error, m (the largest over
        the sites).
    """
    m = model
    sites = [site] if isinstance(site, str) else list(site)
    goal = np.asarray(target, dtype=float).reshape(-1, 3)
    if goal.shape[0] != len(sites):
        raise SimenvError(f"target must be (3,) or ({len(sites)}, 3) for {len(sites)} "
                          f"site(s); got {np.shape(target)}", field="target")
    sids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, s) for s in sites]
    if min(sids) < 0:
        raise SimenvError(f"no site {sites[sids.index(min(sids))]!r} in the model",
                          field="site")
    jids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in joints]
    if min(jids) < 0:
        missing = [j for j, i in zip(joints, jids, strict=True) if i < 0]
        raise SimenvError(f"unknown joint(s) {missing}", field="joints")
    qadr, dadr = m.jnt_qposadr[jids], m.jnt_dofadr[jids]
    lo, hi = m.jnt_range[jids, 0], m.jnt_range[jids, 1]
    data = mujoco.MjData(m)
    data.qpos[:] = qpos
    jacp = np.zeros((3, m.nv))
    J = np.zeros((3 * len(sids), len(jids)))
    err = np.inf
    for _ in range(iterations):
        mujoco.mj_kinematics(m, data)
        mujoco.mj_comPos(m, data)
        e = (goal - data.site_xpos[sids]).ravel()
        err = float(np.linalg.norm(e.reshape(-1, 3), axis=1).max())
        if err < tol:
            break
        for k, sid in enumerate(sids):
            mujoco.mj_jacSite(m, data, jacp, None, sid)
            J[3 * k:3 * k + 3] = jacp[:, dadr]
        dq = J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(len(e)), e)
        data.qpos[qadr] = np.clip(data.qpos[qadr] + dq, lo, hi)
    return data.qpos.copy(), err


def pd_targets(humanoid: Humanoid, qpos: np.ndarray, compensate: Sequence[str] = ()
               ) -> np.ndarray:
    """(nu,) position-servo targets holding configuration ``qpos`` (nq,).

    For the hinges in ``compensate`` (an arm in the air) the target is offset by the
    gravity torque they carry divided by the servo gain, ``tau_g / kp``, so the servo's
    static error cancels and the limb ends where the pose says instead of sagging
    (``tau_g`` = MuJoCo's bias force at rest, ``qfrc_bias`` with ``qvel = 0``). Hinges
    resting on something (seated legs) must not be compensated: their load is not gravity
    alone.
    """
    m = humanoid.model
    data = mujoco.MjData(m)
    data.qpos[:] = qpos
    mujoco.mj_forward(m, data)
    targets = np.asarray(qpos, dtype=float)[humanoid.hinge_qpos].copy()
    kp = m.actuator_gainprm[:, 0]
    for name in compensate:
        j = m.joint(name)
        i = humanoid.joint_names.index(name)  # actuator i drives hinge i
        targets[i] += data.qfrc_bias[j.dofadr[0]] / kp[i]
    return targets


@dataclass(frozen=True)
class GraspEvent:
    """At ``t`` s into a plan, ask for the proximity grasp of ``hand`` on object ``name``
    to close (``close``) or open (:meth:`simenv.room.room.Room.set_grasp`: it closes only when
    the hand is at the handle then)."""

    t: float
    hand: str
    name: str
    close: bool


#: Feedback on a plan's targets: (t s into the plan, the simulation state, the plan's (nu,)
#: targets) -> the (nu,) targets to apply.
Feedback = Callable[[float, mujoco.MjData, np.ndarray], np.ndarray]


class PDPlan:
    """Consecutive :class:`PDTrajectory` segments played one after the other, with the
    grasp requests (:class:`GraspEvent`) to make on the way, in time order, and an
    optional state feedback on the targets (:meth:`control`; e.g. balance)."""

    def __init__(self, segments: Sequence[PDTrajectory],
                 grasps: Sequence[GraspEvent] = (), feedback: Feedback | None = None) -> None:
        if not segments:
            raise SimenvError("a PD plan needs at least one segment", field="segments")
        self.segments = tuple(segments)
        self.ends = np.cumsum([seg.duration for seg in self.segments])
        self.grasps = tuple(sorted(grasps, key=lambda g: g.t))
        self.feedback = feedback

    def control(self, t: float, data: mujoco.MjData) -> np.ndarray:
        """(nu,) targets to apply ``t`` s after the start: :meth:`at`, corrected by the
        feedback from the current state when the plan has one."""
        targets = self.at(t)
        return targets if self.feedback is None else self.feedback(t, data, targets)

    @property
    def duration(self) -> float:
        """Total duration, s."""
        return float(self.ends[-1])

    def at(self, t: float) -> np.ndarray:
        """(nu,) targets ``t`` s after the plan's start (the last goal from the end on)."""
        i = min(int(np.searchsorted(self.ends, t, side="right")), len(self.segments) - 1)
        start = self.ends[i] - self.segments[i].duration
        return self.segments[i].at(t - start)


@dataclass(frozen=True)
class PlanChain:
    """A reaction in named stages (``(name, planner)`` pairs, a planner taking the room
    and the simulation state and returning a :class:`PDPlan`), each planned when the one
    before it ends, from the state it left (e.g. stand up, walk, act)."""

    stages: tuple[tuple[str, Callable[..., PDPlan]], ...]


def min_jerk(tau: float) -> float:
    """Minimum-jerk progress 0..1 at normalised time ``tau`` (clipped to [0, 1])."""
    t = min(max(tau, 0.0), 1.0)
    return t**3 * (10.0 - 15.0 * t + 6.0 * t * t)


@dataclass(frozen=True)
class PDTrajectory:
    """PD targets moving from ``start`` to ``goal`` (both (nu,), rad) in ``duration`` s."""

    start: np.ndarray
    goal: np.ndarray
    duration: float

    def at(self, t: float) -> np.ndarray:
        """Targets ``t`` seconds after the start (``goal`` from ``duration`` on)."""
        s = min_jerk(t / self.duration) if self.duration > 0 else 1.0
        return self.start + s * (self.goal - self.start)


__all__ = ["ARM_PARTS", "Feedback", "GraspEvent", "PDPlan", "PDTrajectory", "PlanChain",
           "arm_joints", "hinge_adr", "min_jerk", "pd_targets", "reach_pose", "upper_body_joints"]

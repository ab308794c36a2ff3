"""Inverse dynamics of a qpos trajectory and the floor forces that can explain it.

The trajectory is differentiated (:func:`finite_differences`) and
``mj_inverse`` (constraints disabled, :func:`inverse_dynamics`) gives the
generalized force ``tau = M(q) qdd + c(q, qd) - tau_passive`` that would
produce it. The six entries of the free joint are the net external wrench
the body needs: force ``F`` and torque ``N`` about the root
(:class:`RootWrench`, :func:`root_wrench`). Only the floor may provide it,
through contact forces at the geom points near the floor
(:func:`simenv.body.geometry.geom_support_points`), each inside a
linearised friction cone (:func:`friction_pyramid`: 4-edge pyramid,
unilateral). The best such forces are found by non-negative least squares
per frame (:func:`floor_forces`)::

    min_{lambda >= 0} || A lambda - [F; N / L] ||,
    A = [e_k ; (p_i - x_root) x e_k / L]   for support point i, edge k

(``L`` = the body's hip height, so torque and force rows weigh alike); what
remains is the residual wrench no floor contact can explain
(:func:`floor_residual`). The filter, the floor's friction, which points may
carry load and gravity are :class:`DynamicsSettings`.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.optimize import nnls
from scipy.signal import butter, filtfilt

from simenv.body.geometry import (
    BodyPoses,
    body_geoms,
    body_poses,
    check_qpos,
    geom_support_points,
)
from simenv.body.retarget import RetargetResult
from simenv.core.errors import PhysicsError


@dataclass(frozen=True)
class DynamicsSettings:
    """How a trajectory's dynamics are inferred and where the floor may push.

    Attributes:
        cutoff_hz: low-pass cutoff of the velocities before differentiation
            (6 Hz, the standard for marker-based gait data), Hz.
        friction: Coulomb coefficient of the floor's friction pyramids.
        support_height_m: a geom point lower than this above the floor may
            carry load, metres.
        gravity_mps2: gravitational acceleration, m/s^2.
    """

    cutoff_hz: float = 6.0
    friction: float = 1.0
    support_height_m: float = 0.05
    gravity_mps2: float = 9.81


#: The defaults, those of the body-level plausibility thresholds
#: (:class:`~simenv.plausibility.body_thresholds.BodyThresholds`, which gives
#: their sources).
DEFAULT_DYNAMICS = DynamicsSettings()


def lowpass(x: np.ndarray, fps: float, cutoff_hz: float) -> np.ndarray:
    """Zero-phase 4th-order Butterworth low-pass along axis 0.

    Returned unchanged when the cutoff is at or above 0.9 x Nyquist (nothing
    to remove) or the signal is too short for ``filtfilt``'s padding.
    """
    nyq = fps / 2.0
    if cutoff_hz >= 0.9 * nyq or len(x) <= 15:
        return x
    b, a = butter(4, cutoff_hz / nyq)
    return filtfilt(b, a, x, axis=0)


def finite_differences(model: mujoco.MjModel, qpos: np.ndarray, fps: float,
                       cutoff_hz: float = DEFAULT_DYNAMICS.cutoff_hz
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Generalized velocities and accelerations of a qpos trajectory.

    ``qvel_t`` is the central difference ``mj_differentiatePos(q_{t-1},
    q_{t+1}) / (2 dt)`` (one-sided at the ends), which handles the free
    joint's quaternion (its angular velocity is in the body frame). ``qvel``
    is low-pass filtered (:func:`lowpass`, ``cutoff_hz``) and ``qacc`` is its
    central difference: body-frame angular velocity differentiates to
    body-frame angular acceleration (``omega x omega = 0``), so every
    coordinate is differentiated alike.

    Args:
        model: the model of ``qpos``.
        qpos: (T, nq), T >= 2.
        fps: frames per second.
        cutoff_hz: the velocities' low-pass cutoff, Hz.

    Returns:
        qvel, qacc: (T, nv) float64 in MuJoCo's conventions (m/s, rad/s;
        m/s^2, rad/s^2).
    """
    q = check_qpos(model, qpos)
    T = len(q)
    if T < 2:
        raise PhysicsError(f"velocities need at least 2 frames; got {T}", field="qpos")
    dt = 1.0 / fps
    qvel = np.empty((T, model.nv))
    v = np.empty(model.nv)
    for t in range(T):
        a, b = max(t - 1, 0), min(t + 1, T - 1)
        mujoco.mj_differentiatePos(model, v, (b - a) * dt, q[a], q[b])
        qvel[t] = v
    qvel = lowpass(qvel, fps, cutoff_hz)
    return qvel, np.gradient(qvel, dt, axis=0)


def inverse_dynamics(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray,
                     qacc: np.ndarray) -> np.ndarray:
    """``mj_inverse`` of every frame with all constraints (contacts, limits)
    disabled: the generalized force (T, nv) that produces ``qacc`` from
    gravity, inertia and passive forces alone (N for the free joint's
    translation, world frame; N m for its rotation, body frame)."""
    m = copy.deepcopy(model)
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    d = mujoco.MjData(m)
    out = np.empty_like(qvel)
    for t in range(len(qpos)):
        d.qpos[:], d.qvel[:], d.qacc[:] = qpos[t], qvel[t], qacc[t]
        mujoco.mj_inverse(m, d)
        out[t] = d.qfrc_inverse
    bad = ~np.isfinite(out).all(axis=1)
    if bad.any():
        raise PhysicsError("inverse dynamics produced NaN/inf (degenerate configuration)",
                           frame=int(np.flatnonzero(bad)[0]))
    return out


def friction_pyramid(friction: float) -> np.ndarray:
    """(4, 3) unit edges of the linearised friction cone (normal +z)."""
    e = np.array([[friction, 0, 1], [-friction, 0, 1], [0, friction, 1], [0, -friction, 1]])
    return e / np.linalg.norm(e, axis=1, keepdims=True)


@dataclass(frozen=True)
class RootWrench:
    """The external wrench a trajectory needs at its root, and where the floor may act.

    Per frame ``t`` the target is ``w_t = [F_t; N_t / L]`` (newtons): the free
    joint's inverse-dynamics force ``F`` (world frame) and torque ``N`` about
    the root (rotated to the world frame), the torque divided by the lever
    ``L`` (hip height) so torque and force rows weigh alike. An external force
    ``f`` applied at a world point ``p`` contributes the column
    ``[f; (p - x_root) x f / L]``.

    Attributes:
        wrench: (T, 6) ``w_t``, N.
        root: (T, 3) root (pelvis frame origin) positions, metres.
        support: per frame, (P_t, 3) geom points lower than ``support_height_m``
            (floor contact candidates), metres.
        weight: body weight ``m g``, N.
        lever: ``L``, metres.
        friction: Coulomb coefficient of the floor's friction pyramids.
        poses: the forward kinematics used.
        com_accel: (T, 3) centre-of-mass acceleration, m/s^2 (filtered).
    """

    wrench: np.ndarray
    root: np.ndarray
    support: list[np.ndarray]
    weight: float
    lever: float
    friction: float
    poses: BodyPoses
    com_accel: np.ndarray

    def point_columns(self, t: int, points: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """(6, P * D) wrench columns of unit forces along ``directions`` (D, 3)
        applied at each of ``points`` (P, 3) on frame ``t`` (point-major order)."""
        cols_f = np.tile(directions, (len(points), 1))
        arm = np.repeat(points - self.root[t], len(directions), axis=0)
        return np.concatenate([cols_f, np.cross(arm, cols_f) / self.lever], axis=1).T

    def floor_columns(self, t: int) -> np.ndarray:
        """(6, 4 P_t) columns of the floor's friction-pyramid edges at the support points."""
        return self.point_columns(t, self.support[t], friction_pyramid(self.friction))

    def residual_norms(self, r: np.ndarray) -> tuple[float, float]:
        """Force (body weights) and torque (metres: N m / m g) of a residual wrench (6,)."""
        return (float(np.linalg.norm(r[:3]) / self.weight),
                float(np.linalg.norm(r[3:]) * self.lever / self.weight))


def root_wrench(result: RetargetResult, settings: DynamicsSettings = DEFAULT_DYNAMICS, *,
                poses: BodyPoses | None = None) -> RootWrench:
    """Inverse dynamics of ``result`` as a :class:`RootWrench` (module docstring);
    ``poses``: ``result``'s forward kinematics when the caller has them."""
    h = result.humanoid
    model = h.model
    q = check_qpos(model, result.qpos)
    qvel, qacc = finite_differences(model, q, result.fps, settings.cutoff_hz)
    tau = inverse_dynamics(model, q, qvel, qacc)
    if poses is None:
        poses = body_poses(model, q)
    lever = h.dims.hip_height
    rot = np.empty((len(q), 9))
    for t in range(len(q)):
        mujoco.mju_quat2Mat(rot[t], q[t, 3:7])
    torque = np.einsum("tij,tj->ti", rot.reshape(-1, 3, 3), tau[:, 3:6])
    points = geom_support_points(model, poses, body_geoms(model))
    support = [p[p[:, 2] < settings.support_height_m] for p in points]
    com_acc = np.gradient(np.gradient(lowpass(poses.com, result.fps, settings.cutoff_hz),
                                      1 / result.fps, axis=0), 1 / result.fps, axis=0)
    return RootWrench(np.concatenate([tau[:, 0:3], torque / lever], axis=1),
                      q[:, 0:3].copy(), support, h.total_mass * settings.gravity_mps2,
                      lever, settings.friction, poses, com_acc)


def floor_forces(rw: RootWrench, t: int) -> np.ndarray:
    """The best floor forces of frame ``t``: ``lambda = argmin_{lambda >= 0}
    ||A lambda - w_t||`` (non-negative least squares over the friction-pyramid
    edges of :meth:`RootWrench.floor_columns`), (4 P_t,) newtons."""
    if len(rw.support[t]) == 0:
        return np.zeros(0)
    lam, _ = nnls(rw.floor_columns(t), rw.wrench[t], maxiter=200)
    return lam


def floor_residual(rw: RootWrench, t: int) -> np.ndarray:
    """Residual wrench (6,) of frame ``t`` after the best floor forces,
    ``w_t - A lambda`` (:func:`floor_forces`)."""
    if len(rw.support[t]) == 0:
        return rw.wrench[t].copy()
    return rw.wrench[t] - rw.floor_columns(t) @ floor_forces(rw, t)

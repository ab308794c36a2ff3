"""The tracking reference resampled to the physics timestep.

A retargeted clip (:class:`~simenv.body.retarget.RetargetResult`) holds one
configuration per motion-capture frame (``fps`` Hz); the controller steps
the physics every ``dt`` seconds (2 ms). :class:`TrackingReference` holds,
per physics step ``s`` (time ``s dt`` from the clip's first frame), the
quantities the planner compares a rollout with, linearly interpolated
between the two frames around ``s dt``:

* ``ctrl``: the position-servo targets that make the humanoid's actuators a
  PD on the reference, ``u = q_ref + (kv / kp) qd_ref`` (a position actuator
  applies ``kp (u - q) - kv qd``, so this is ``kp (q_ref - q) + kv (qd_ref -
  qd)``), radians, (S, nu);
* ``keypoints``: the reference body's keypoint sites, metres, (S, K, 3);
* ``com`` / ``com_vel``: the whole-body centre of mass and its velocity
  (metres, m/s), (S, 3);
* ``qvel``: generalized velocities, (S, nv);
* ``trunk``: the upper trunk's (:data:`~simenv.control.model.TRUNK_BODY`)
  world orientation, unit quaternions ``(w, x, y, z)``, (S, 4), normalised
  after the interpolation (each frame's sign chosen nearest the previous
  frame's, so the interpolation never passes through the long way round);
* ``torque``: feed-forward hinge torques from the inverse dynamics of the
  reference (:func:`simenv.control.feedforward.feedforward_torques`), N m,
  (S, nu), zeros when not requested;
* ``planted``: (S, F) whether each foot keypoint (:data:`FOOT_KEYPOINTS`) of
  the reference is on the floor (height below ``contact_height_m``) -- the
  contact schedule of the reference.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from simenv.body.dynamics import DEFAULT_DYNAMICS, DynamicsSettings, finite_differences
from simenv.body.geometry import check_qpos
from simenv.body.humanoid import Humanoid
from simenv.body.retarget import RetargetResult
from simenv.control.feedforward import feedforward_torques
from simenv.control.model import TRUNK_BODY
from simenv.core.errors import PhysicsError

#: The keypoints whose floor contact the planner tracks (heels are the ankles).
FOOT_KEYPOINTS: tuple[str, ...] = ("left_ankle", "left_toe", "right_ankle", "right_toe")


def actuated_indices(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """(qpos addresses, dof addresses) of the hinge each actuator drives, (nu,) each."""
    joints = model.actuator_trnid[:, 0]
    return model.jnt_qposadr[joints], model.jnt_dofadr[joints]


def velocity_feedthrough(model: mujoco.MjModel) -> np.ndarray:
    """``kv / kp`` per actuator (seconds), (nu,): the servo-target offset per
    unit of reference joint velocity that turns the position actuator's damping
    into damping of the velocity error."""
    return -model.actuator_biasprm[:, 2] / model.actuator_gainprm[:, 0]


@dataclass(frozen=True)
class TrackingReference:
    """A retargeted clip per physics step (module docstring).

    Attributes:
        name: the clip's name.
        dt: physics timestep, seconds. fps: the clip's frame rate.
        n_frames: reference frames covered; frame ``f`` is at step ``frame_step[f]``.
        frame_step: (n_frames,) physics step of each frame.
        qpos0, qvel0: (nq,), (nv,) the first frame's state (the start state).
        ctrl, torque, keypoints, com, com_vel, qvel, trunk, planted: per-step arrays, S =
            ``frame_step[-1] + 1`` rows (module docstring for units).
        frame_keypoints: (n_frames, K, 3) the reference keypoints per frame.
        foot_sites: (F,) indices into the keypoint axis of :data:`FOOT_KEYPOINTS`.
    """

    name: str
    dt: float
    fps: float
    n_frames: int
    frame_step: np.ndarray
    qpos0: np.ndarray
    qvel0: np.ndarray
    ctrl: np.ndarray
    torque: np.ndarray
    keypoints: np.ndarray
    com: np.ndarray
    com_vel: np.ndarray
    qvel: np.ndarray
    trunk: np.ndarray
    planted: np.ndarray
    frame_keypoints: np.ndarray
    foot_sites: np.ndarray

    @property
    def n_steps(self) -> int:
        """Physics steps from the first to the last reference frame."""
        return int(self.frame_step[-1])

    def window(self, start: int, length: int) -> np.ndarray:
        """Step indices ``start .. start + length - 1``, clamped to the last step
        (the reference holds its final pose beyond the clip's end), (length,)."""
        return np.minimum(np.arange(start, start + length), self.n_steps)

    @classmethod
    def from_retarget(cls, result: RetargetResult, model: mujoco.MjModel | None = None,
                      settings: DynamicsSettings = DEFAULT_DYNAMICS,
                      max_seconds: float = 20.0,
                      contact_height_m: float = 0.05,
                      feedforward: bool = True) -> TrackingReference:
        """Resample ``result`` to ``model``'s timestep.

        Args:
            result: the retargeted clip (T >= 2 frames, finite).
            model: the simulated model (default ``result.humanoid.model``); it
                must share the humanoid's joints and actuators.
            settings: the reference velocities' filter cutoff, and the floor
                the feed-forward torques assume
                (:func:`~simenv.control.feedforward.feedforward_torques`).
            max_seconds: keep at most this much of the clip, seconds (the
                default is the tracking metric's ``tracking_max_seconds``).
            contact_height_m: a foot keypoint below this height (above its
                rest height over the floor) counts as planted.
            feedforward: compute the feed-forward torques (else zeros).

        Raises:
            PhysicsError: qpos of the wrong shape, NaN/inf (naming the frame),
                fewer than 2 frames, a non-positive frame rate or length cap.
        """
        h: Humanoid = result.humanoid
        model = h.model if model is None else model
        q = check_qpos(model, result.qpos)
        if len(q) < 2:
            raise PhysicsError(f"tracking needs at least 2 frames; got {len(q)}", field="qpos")
        fps = float(result.fps)
        if not np.isfinite(fps) or fps <= 0:
            raise PhysicsError(f"frame rate must be positive; got {fps}", field="fps")
        limit = float(max_seconds)
        if not limit > 0:
            raise PhysicsError(f"max_seconds must be positive; got {limit}", field="max_seconds")
        n_frames = min(len(q), int(np.floor(limit * fps)) + 1)
        q = q[:n_frames]
        dt = float(model.opt.timestep)
        qvel, _ = finite_differences(model, q, fps, settings.cutoff_hz)
        kp = h.keypoints(q)
        com, trunk = _centre_of_mass_and_trunk(model, q)
        com_vel = np.gradient(com, 1.0 / fps, axis=0)
        act_q, act_v = actuated_indices(model)
        ctrl = q[:, act_q] + velocity_feedthrough(model) * qvel[:, act_v]
        torque = (feedforward_torques(replace(result, qpos=q), settings) if feedforward
                  else np.zeros_like(ctrl))

        frame_step = np.round(np.arange(n_frames) / fps / dt).astype(int)
        interp = step_interpolator(frame_step, fps, dt)

        names = list(h.keypoint_names)
        foot = np.array([names.index(k) for k in FOOT_KEYPOINTS])
        rest = h.keypoints(h.default_qpos()[None])[0, foot, 2]
        kps = interp(kp)
        planted = kps[:, foot, 2] - rest < contact_height_m
        trunk_steps = interp(trunk)
        trunk_steps /= np.linalg.norm(trunk_steps, axis=-1, keepdims=True)
        return cls(name=result.name, dt=dt, fps=fps, n_frames=n_frames, frame_step=frame_step,
                   qpos0=q[0].copy(), qvel0=qvel[0].copy(), ctrl=interp(ctrl),
                   torque=interp(torque), keypoints=kps, com=interp(com),
                   com_vel=interp(com_vel), qvel=interp(qvel), trunk=trunk_steps,
                   planted=planted,
                   frame_keypoints=kp, foot_sites=foot)


def _centre_of_mass_and_trunk(model: mujoco.MjModel,
                              q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The whole-body centre of mass and the upper trunk's orientation of each pose.

    Args:
        model: the humanoid's model.
        q: (T, nq) poses.

    Returns:
        ``com``: (T, 3) metres, world frame; ``trunk``: (T, 4) unit quaternions (w, x, y, z)
        of :data:`TRUNK_BODY`, each on the same hemisphere as the previous frame's.
    """
    data = mujoco.MjData(model)
    com = np.empty((len(q), 3))
    trunk_id = model.body(TRUNK_BODY).id
    trunk = np.empty((len(q), 4))
    for t in range(len(q)):
        data.qpos[:] = q[t]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        com[t] = data.subtree_com[1]
        trunk[t] = data.xquat[trunk_id]
    # q and -q are one rotation: keep each frame on the previous one's side.
    flip = np.cumprod(np.where(np.einsum("tc,tc->t", trunk[1:], trunk[:-1]) < 0, -1.0, 1.0))
    trunk[1:] *= flip[:, None]
    return com, trunk


def step_interpolator(frame_step: np.ndarray, fps: float,
                      dt: float) -> Callable[[np.ndarray], np.ndarray]:
    """Linear interpolation of per-frame arrays to every physics step.

    Args:
        frame_step: (T,) the physics step of each frame (T >= 2).
        fps: the clip's frame rate, Hz.
        dt: the physics timestep, seconds.

    Returns:
        A function taking a (T, ...) array to its (frame_step[-1] + 1, ...) values, step ``s``
        at clip time ``s dt`` (held at the last frame past the clip's end).
    """
    n_frames = len(frame_step)
    steps = np.arange(frame_step[-1] + 1)
    u = np.clip(steps * dt * fps, 0.0, n_frames - 1)
    i0 = np.minimum(np.floor(u).astype(int), n_frames - 2)
    a = u - i0

    def interp(x: np.ndarray) -> np.ndarray:
        w = a.reshape((-1,) + (1,) * (x.ndim - 1))
        return x[i0] + w * (x[i0 + 1] - x[i0])

    return interp

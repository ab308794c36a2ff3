"""``simenv/HumanoidTrack-v0``: track a reference motion with PD targets (DeepMimic-style).

The body is a :class:`~simenv.body.humanoid.Humanoid` fitted to the reference's subject; the
reference is the motion retargeted onto it (:func:`simenv.body.retarget.retarget`), sampled at
the control rate ``1 / (frame_skip * timestep)`` (33.3 Hz by default, DeepMimic's 30 Hz).

Action
    ``Box(nu,)``: the target angle (rad) of every hinge's position actuator, within the
    joint's range. Each actuator applies ``kp (target - q) - kv qd`` (gains of
    :data:`simenv.body.humanoid.JOINTS`), clipped to its force limit. No root forces: the body
    balances on its feet.

Observation
    ``Box(2 (nq - 2) + nv + 3,)`` float32, concatenating: the body's ``qpos[2:]`` (pelvis
    height, orientation quaternion, hinge angles) and ``qvel``; the reference's ``qpos[2:]``
    at the next control step; the reference pelvis's horizontal offset (x, y) from the body's
    pelvis at the next step, in the body's heading frame (m); the phase (fraction of the
    reference elapsed).

Reward (DeepMimic, Peng et al. 2018, eq. 5-9), each term in (0, 1]::

    r = w_p exp(-k_p sum_j |q^_j - q_j|^2)            pose: hinge angle errors (rad) plus
                                                       the pelvis orientation's angle
      + w_v exp(-k_v sum_j |qd^_j - qd_j|^2)          velocity: hinges and pelvis (rad/s)
      + w_e exp(-k_e sum_e |p^_e - p_e|^2)            end effectors: hands and toes (m)
      + w_c exp(-k_c |c^ - c|^2)                      centre of mass (m)

with DeepMimic's weights ``w = (0.65, 0.1, 0.15, 0.1)`` and scales
``k = (2, 0.1, 40, 10)`` (:class:`RewardWeights`); ``^`` marks the reference. Positions are
world-frame (global tracking), read after the step's last substep.

Episode
    Starts at a reference frame drawn uniformly from the clip (reference state
    initialization; ``reset(options={"start_frame": k})`` picks it) in the reference's pose
    and velocity. *Terminated* when the mean keypoint error exceeds
    ``termination_distance`` (0.5 m, PHC's failure rule, as in
    :mod:`simenv.plausibility.tracking`). *Truncated* at the end of the reference, or when
    the physics diverges or MuJoCo warns (:mod:`simenv.body.divergence`), with
    ``info["truncation_reason"]``. Stepping before ``reset``, after the episode ended, or
    with an action of the wrong shape raises :class:`~simenv.core.errors.SimenvError`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from simenv.assets import WALK, asset_path, list_assets
from simenv.body.divergence import physics_problem, warning_counts
from simenv.body.dynamics import finite_differences
from simenv.body.humanoid import Humanoid
from simenv.body.retarget import RetargetResult, retarget
from simenv.core.errors import SimenvError
from simenv.core.motion import Interaction, Motion
from simenv.io.loader import load

#: Keypoints whose positions enter the end-effector term (DeepMimic: hands and feet).
END_EFFECTORS = ("left_hand", "right_hand", "left_toe", "right_toe")


@dataclass(frozen=True)
class RewardWeights:
    """Weights ``w_*`` and error scales ``k_*`` of the DeepMimic reward (module docstring)."""

    pose: float = 0.65
    velocity: float = 0.1
    end_effector: float = 0.15
    com: float = 0.1
    k_pose: float = 2.0
    k_velocity: float = 0.1
    k_end_effector: float = 40.0
    k_com: float = 10.0


@dataclass(frozen=True)
class Reference:
    """A reference motion sampled at the control rate, on the env's humanoid.

    Attributes:
        qpos: (T, nq). qvel: (T, nv) (finite differences, low-pass filtered).
        keypoints: (T, K, 3) keypoint sites, m. com: (T, 3) whole-body centre of mass, m.
        fps: control rate, Hz. name: the motion's name.
    """

    qpos: np.ndarray
    qvel: np.ndarray
    keypoints: np.ndarray
    com: np.ndarray
    fps: float
    name: str


def _nlerp_qpos(qpos: np.ndarray, fps_in: float, fps_out: float) -> np.ndarray:
    """Resample a free-root qpos trajectory: linear in positions and hinges, normalised
    linear (with sign continuity) in the root quaternion."""
    T = len(qpos)
    t_out = np.arange(int(np.floor((T - 1) / fps_in * fps_out)) + 1) / fps_out
    x = t_out * fps_in
    i0 = np.minimum(np.floor(x).astype(int), T - 2)
    a = (x - i0)[:, None]
    q0, q1 = qpos[i0], qpos[i0 + 1].copy()
    flip = np.sum(q0[:, 3:7] * q1[:, 3:7], axis=1) < 0
    q1[flip, 3:7] *= -1
    out = (1 - a) * q0 + a * q1
    out[:, 3:7] /= np.linalg.norm(out[:, 3:7], axis=1, keepdims=True)
    return out


def _as_motion(motion: str | os.PathLike[str] | Motion | Interaction,
               person: int | None) -> Motion:
    if isinstance(motion, (str, os.PathLike)):
        name = os.fspath(motion)
        path = asset_path(name) if name in list_assets() else Path(name)
        if not path.exists():
            raise SimenvError(f"no motion file {name!r} and no bundled asset of that name; "
                              f"bundled: {', '.join(list_assets())}", source=name)
        motion = load(path)
    if isinstance(motion, Interaction):
        if person not in (0, 1):
            raise SimenvError(f"{motion.name!r} holds two people; pass person=0 or person=1",
                              field="person")
        motion = motion.people[person]
    if not isinstance(motion, Motion):
        raise SimenvError(f"expected a motion file, Motion, Interaction or RetargetResult; "
                          f"got {type(motion).__name__}", field="motion")
    return motion


def make_reference(motion: str | os.PathLike[str] | Motion | Interaction | RetargetResult,
                   fps: float, person: int | None = None) -> tuple[Humanoid, Reference]:
    """The humanoid and the reference of ``motion`` (a file path, a bundled asset name, a
    Motion, a person of an Interaction, or an already retargeted result) at ``fps``."""
    if isinstance(motion, RetargetResult):
        result = motion
        qpos = _nlerp_qpos(result.qpos, result.fps, fps) if result.fps != fps else result.qpos
    else:
        m = _as_motion(motion, person)
        result = retarget(m.resample(fps) if m.fps != fps else m)
        qpos = result.qpos
    if len(qpos) < 3:
        raise SimenvError(f"reference {result.name!r} is {len(qpos)} control steps long at "
                          f"{fps:.1f} Hz; at least 3 are needed", field="motion")
    h = result.humanoid
    qvel, _ = finite_differences(h.model, qpos, fps)
    data = mujoco.MjData(h.model)
    kp = np.empty((len(qpos), len(h.site_ids), 3))
    com = np.empty((len(qpos), 3))
    for t, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(h.model, data)
        mujoco.mj_comPos(h.model, data)
        kp[t] = data.site_xpos[h.site_ids]
        com[t] = data.subtree_com[1]
    return h, Reference(qpos, qvel, kp, com, fps, result.name)


class HumanoidTrackEnv(gym.Env[np.ndarray, np.ndarray]):
    """Track a reference motion with the PD targets of a subject-fitted humanoid.

    See the module docstring for the action, observation, reward and episode rules.

    Args:
        motion: a motion file, a bundled asset name (default: the CMU walk), a
            :class:`~simenv.core.motion.Motion`, an :class:`~simenv.core.motion.Interaction` with
            ``person``, or a :class:`~simenv.body.retarget.RetargetResult`.
        frame_skip: physics steps (2 ms) per control step.
        termination_distance: mean keypoint error (m) that ends the episode.
        random_start: draw the start frame uniformly (else frame 0).
        weights: reward weights and scales.
        render_mode: None or ``"rgb_array"``.
        width, height: rendered image size, pixels.
        person: which person of a two-person motion to track.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 30}

    def __init__(self, motion: str | os.PathLike[str] | Motion | Interaction | RetargetResult
                 = WALK, *, frame_skip: int = 15, termination_distance: float = 0.5,
                 random_start: bool = True, weights: RewardWeights | None = None,
                 render_mode: str | None = None, width: int = 320, height: int = 240,
                 person: int | None = None) -> None:
        if render_mode not in (None, "rgb_array"):
            raise SimenvError(f"render_mode {render_mode!r} is not supported; expected None "
                              "or 'rgb_array'", field="render_mode")
        if int(frame_skip) < 1:
            raise SimenvError(f"frame_skip must be >= 1; got {frame_skip}", field="frame_skip")
        self.frame_skip = int(frame_skip)
        self.weights = weights or RewardWeights()
        self.termination_distance = float(termination_distance)
        self.random_start = bool(random_start)
        self.render_mode = render_mode
        self._size = (int(width), int(height))
        timestep = 0.002  # simenv.body.humanoid's integrator step
        self.control_dt = self.frame_skip * timestep
        self.humanoid, self.reference = make_reference(motion, 1.0 / self.control_dt, person)
        self.model = self.humanoid.model
        self.data = mujoco.MjData(self.model)
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.control_dt)}
        m, h = self.model, self.humanoid
        self._act_qpos = m.jnt_qposadr[m.actuator_trnid[:, 0]]
        self._act_dof = m.jnt_dofadr[m.actuator_trnid[:, 0]]
        self._ee = np.array([h.keypoint_names.index(k) for k in END_EFFECTORS])
        lo, hi = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
        self.action_space = spaces.Box(lo.astype(np.float32), hi.astype(np.float32),
                                       dtype=np.float32)
        n_obs = 2 * (m.nq - 2) + m.nv + 3
        self.observation_space = spaces.Box(-np.inf, np.inf, (n_obs,), dtype=np.float32)
        self._frame: int | None = None  # None: reset needed
        self._obs: np.ndarray | None = None
        self._renderer: mujoco.Renderer | None = None

    # -- Gymnasium API ----------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        T = len(self.reference.qpos)
        options = options or {}
        if "start_frame" in options:
            k = int(options["start_frame"])
            if not 0 <= k <= T - 2:
                raise SimenvError(f"start_frame {k} is outside [0, {T - 2}]",
                                  field="start_frame")
        else:
            k = int(self.np_random.integers(0, T - 1)) if self.random_start else 0
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = self.reference.qpos[k]
        self.data.qvel[:] = self.reference.qvel[k]
        self.data.ctrl[:] = self.reference.qpos[k, self._act_qpos]
        mujoco.mj_forward(self.model, self.data)
        self._frame = k
        self._obs = self._observe()
        return self._obs, {"frame": k, "body_error_m": self._body_error()}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._frame is None:
            raise SimenvError("step() called before reset() (or after the episode ended); "
                              "call reset() first")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self.action_space.shape:
            raise SimenvError(f"action has shape {a.shape}; expected "
                              f"{self.action_space.shape} (one PD target per actuator)",
                              field="action")
        if not np.isfinite(a).all():
            raise SimenvError("action contains NaN/inf", field="action")
        m, d = self.model, self.data
        counts = warning_counts(d)
        d.ctrl[:] = a
        mujoco.mj_step(m, d, nstep=self.frame_skip)
        self._frame += 1
        problem = physics_problem(m, d, counts)
        if problem is not None:
            self._frame = None
            return self._obs, 0.0, False, True, {"truncation_reason": f"physics: {problem}"}
        # Positions of the state after the last substep (mj_step leaves them one substep old).
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        terms = self._reward_terms()
        w = self.weights
        reward = (w.pose * terms["pose"] + w.velocity * terms["velocity"]
                  + w.end_effector * terms["end_effector"] + w.com * terms["com"])
        error = self._body_error()
        terminated = error > self.termination_distance
        end = self._frame >= len(self.reference.qpos) - 1
        info: dict[str, Any] = {"frame": self._frame, "body_error_m": error,
                                "reward_terms": terms}
        if end and not terminated:
            info["truncation_reason"] = "end of the reference motion"
        self._obs = self._observe()
        if terminated or end:
            self._frame = None
        return self._obs, float(reward), bool(terminated), bool(end and not terminated), info

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            # The renderer's module loads OpenCV (video): only rgb_array rendering needs it.
            from simenv.body.render import make_renderer

            self._renderer = make_renderer(self.model, *self._size)
            self._camera = mujoco.MjvCamera()
            self._camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
            self._camera.trackbodyid = 1  # pelvis
            self._camera.distance, self._camera.elevation = 3.5, -15.0
            self._camera.azimuth = 90.0
        self._renderer.update_scene(self.data, self._camera)
        return self._renderer.render()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # -- internals -------------------------------------------------------------

    def _ref_index(self, offset: int = 0) -> int:
        return min(self._frame + offset, len(self.reference.qpos) - 1)

    def _observe(self) -> np.ndarray:
        d, ref = self.data, self.reference
        k = self._ref_index(1)
        yaw = _heading(d.qpos[3:7])
        c, s = np.cos(yaw), np.sin(yaw)
        dx, dy = ref.qpos[k, :2] - d.qpos[:2]
        offset = [c * dx + s * dy, -s * dx + c * dy]
        phase = self._frame / (len(ref.qpos) - 1)
        return np.concatenate([d.qpos[2:], d.qvel, ref.qpos[k, 2:], offset, [phase]]
                              ).astype(np.float32)

    def _body_error(self) -> float:
        kp = self.data.site_xpos[self.humanoid.site_ids]
        return float(np.linalg.norm(kp - self.reference.keypoints[self._frame], axis=-1).mean())

    def _reward_terms(self) -> dict[str, float]:
        d, ref, k, w = self.data, self.reference, self._frame, self.weights
        hinge = d.qpos[self._act_qpos] - ref.qpos[k, self._act_qpos]
        rel = np.empty(4)
        inv = np.empty(4)
        mujoco.mju_negQuat(inv, ref.qpos[k, 3:7])
        mujoco.mju_mulQuat(rel, inv, d.qpos[3:7])
        root_angle = 2.0 * np.arccos(min(1.0, abs(float(rel[0]))))
        pose_err = float(hinge @ hinge + root_angle**2)
        vel = d.qvel[3:] - ref.qvel[k, 3:]  # pelvis angular velocity and hinge velocities
        kp = d.site_xpos[self.humanoid.site_ids]
        ee_err = float(np.sum((kp[self._ee] - ref.keypoints[k, self._ee]) ** 2))
        com_err = float(np.sum((d.subtree_com[1] - ref.com[k]) ** 2))
        return {"pose": float(np.exp(-w.k_pose * pose_err)),
                "velocity": float(np.exp(-w.k_velocity * float(vel @ vel))),
                "end_effector": float(np.exp(-w.k_end_effector * ee_err)),
                "com": float(np.exp(-w.k_com * com_err))}


def _heading(quat: np.ndarray) -> float:
    """Yaw (rad) of the body's x axis projected on the floor."""
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat, dtype=float))
    return float(np.arctan2(mat[3], mat[0]))

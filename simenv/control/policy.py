"""A tracking policy learned from the planner's own solutions, with the planner as fallback.

The sampling planner (:class:`~simenv.control.mpc.TrackingMPC`) rolls out about 360
(``FAST``) to 1,400 (default) planning steps per simulated step. A policy maps the body's
state and the next reference frames straight to the servo targets the planner would choose,
at the cost of one network evaluation per physics step (PHC, Luo et al. 2023; MoCapAct,
Wagener et al. 2022). Here:

* :class:`Observer` turns the simulated state and the reference window into a feature
  vector, everything expressed in the root's *heading frame* (the world frame turned about
  Z to the pelvis' yaw, origin at the pelvis), so that a motion walked in any direction
  looks the same to the policy;
* :class:`TrackingPolicy` is a small multilayer perceptron (numpy at run time, trained
  with torch by ``benchmarks/train_tracking_policy.py``) giving the servo-target offsets of
  the planner's sampled actuators (lumbar and legs) on top of the reference servo targets
  ``u*`` (:class:`~simenv.control.mpc.TrackingMPC` ``ctrl_ref``), the planner's own action
  space; the other actuators follow ``u*`` as they do under the planner;
* :class:`ExpertRecorder` runs the planner as the expert on whatever states the body
  reaches (its own, or the policy's: DAgger, Ross et al. 2011) and records
  (features, planner offsets) per physics step;
* :class:`PolicyTracker` runs the policy and hands control to the planner when the body
  error passes :attr:`PolicyConfig.engage_m`, back to the policy once it is below
  :attr:`PolicyConfig.release_m` again (after at least :attr:`PolicyConfig.hold_s`).

Both controllers have :class:`~simenv.control.mpc.TrackingMPC`'s per-step interface
(``model``, ``config``, ``reset``, ``control``, ``snapshot``, ``restore``, ``close``,
``rollout_steps``), so the tracking simulation runs them unchanged
(:func:`simenv.plausibility.policy_tracking.track_policy`). Only servo targets change:
nothing acts on the root. The policy is deterministic, the fallback seeded: runs reproduce.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from simenv.body.humanoid import Humanoid
from simenv.control.mpc import FAST, MPCConfig, TrackingMPC
from simenv.control.reference import TrackingReference, actuated_indices
from simenv.core.errors import PhysicsError

#: Physics steps ahead (2 ms each) of the reference frames the policy sees: now, 20, 50,
#: 100 and 200 ms (the planner looks 0.45 s ahead; the nearest frames matter most).
LOOKAHEAD_STEPS: tuple[int, ...] = (0, 10, 25, 50, 100)


def sampled_actuators(model: mujoco.MjModel, parts: tuple[str, ...]) -> np.ndarray:
    """Indices of the actuators whose names contain one of ``parts`` (the planner's
    ``sampled_parts``; empty: every actuator), (n,) int."""
    if not parts:
        return np.arange(model.nu)
    names = [model.actuator(i).name for i in range(model.nu)]
    return np.array([i for i, n in enumerate(names) if any(p in n for p in parts)], dtype=int)


def body_error(data: mujoco.MjData, site_ids: np.ndarray, ref: TrackingReference,
               step: int) -> float:
    """Mean keypoint distance between the simulated body and the reference at physics step
    ``step``, metres (the tracking metric's body error, per step)."""
    s = min(step, ref.n_steps)
    return float(np.linalg.norm(data.site_xpos[site_ids] - ref.keypoints[s], axis=-1).mean())


class Observer:
    """The policy's input at a physics step (module docstring), a (``size``,) float vector.

    Features, all in the root's heading frame (rotation ``H`` about Z by the pelvis' yaw,
    origin at the pelvis): pelvis height (m); the pelvis' orientation (first two columns of
    ``H^T R``); its linear velocity (m/s, heading frame) and angular velocity (rad/s, body
    frame); hinge angles (rad) and velocities (rad/s, x 0.1); the simulated keypoints (m);
    per lookahead step of :data:`LOOKAHEAD_STEPS` the reference keypoints (m) and the
    reference servo targets minus the hinge angles (rad); the reference centre-of-mass
    velocity (m/s) and its centre of mass minus the simulated one (m); the reference's
    planted feet now and 100 ms ahead (0/1).

    Args:
        model: the simulated model (the planner's, sensors included).
        reference: the clip per physics step.
        ctrl_ref: (S, nu) reference servo targets (:class:`TrackingMPC` ``ctrl_ref``).
        site_ids: (K,) keypoint site ids.
    """

    def __init__(self, model: mujoco.MjModel, reference: TrackingReference,
                 ctrl_ref: np.ndarray, site_ids: np.ndarray) -> None:
        self.reference = reference
        self.ctrl_ref = ctrl_ref
        self.site_ids = np.asarray(site_ids)
        self.hinge_q, self.hinge_v = actuated_indices(model)
        K, nu = len(self.site_ids), model.nu
        self.size = 1 + 6 + 3 + 3 + 2 * nu + 3 * K + len(LOOKAHEAD_STEPS) * (3 * K + nu) + 6 \
            + 2 * len(reference.foot_sites)

    def __call__(self, data: mujoco.MjData, step: int) -> np.ndarray:
        """The features at physics step ``step`` of ``data``'s state."""
        ref = self.reference
        pos = data.qpos[:3]
        R = data.xmat[1].reshape(3, 3)
        yaw = np.arctan2(R[1, 0], R[0, 0])
        c, s = np.cos(yaw), np.sin(yaw)
        Ht = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # world -> heading
        q, v = data.qpos[self.hinge_q], data.qvel[self.hinge_v]
        steps = np.minimum(step + np.array(LOOKAHEAD_STEPS), ref.n_steps)
        ref_kp = (ref.keypoints[steps] - pos) @ Ht.T
        ref_u = self.ctrl_ref[steps] - q
        ahead = np.concatenate([ref_kp.reshape(len(steps), -1), ref_u], axis=1)
        s0, s1 = steps[0], min(step + 50, ref.n_steps)
        return np.concatenate([
            [pos[2]], (Ht @ R)[:, :2].ravel(), Ht @ data.qvel[:3], data.qvel[3:6],
            q, 0.1 * v, ((data.site_xpos[self.site_ids] - pos) @ Ht.T).ravel(),
            ahead.ravel(), Ht @ ref.com_vel[s0], Ht @ (ref.com[s0] - data.subtree_com[1]),
            ref.planted[s0], ref.planted[s1]]).astype(np.float64)


@dataclass(frozen=True)
class TrackingPolicy:
    """A multilayer perceptron from :class:`Observer` features to servo-target offsets.

    ``a = limit * tanh(W_n elu(... elu(W_1 (x - mean) / std + b_1) ...) + b_n)``, radians,
    added to the reference servo targets of ``actuators``.

    Attributes:
        weights: per layer a (in, out) matrix; biases: per layer an (out,) vector.
        mean, std: (D,) feature normalisation.
        actuators: (A,) actuator indices the offsets go to.
        limit_rad: largest offset, radians (the planner's ``limit_rad``).
        info: what it was trained on (JSON text).
    """

    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]
    mean: np.ndarray
    std: np.ndarray
    actuators: np.ndarray
    limit_rad: float = 0.8
    info: str = "{}"

    def __post_init__(self) -> None:
        dims = [w.shape for w in self.weights]
        ok = (len(self.weights) == len(self.biases) >= 1
              and all(a[1] == b[0] for a, b in zip(dims, dims[1:], strict=False))
              and all(w.shape[1] == b.shape[0]
                      for w, b in zip(self.weights, self.biases, strict=False))
              and self.mean.shape == self.std.shape == (dims[0][0],)
              and dims[-1][1] == len(self.actuators))
        if not ok:
            raise PhysicsError(f"inconsistent policy layers {dims} for {len(self.actuators)} "
                               f"actuators and {self.mean.shape} features", field="weights")

    @property
    def n_features(self) -> int:
        """D, the feature vector's length."""
        return int(self.mean.shape[0])

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """(A,) or (N, A) offsets, radians, of (D,) or (N, D) features."""
        h = (x - self.mean) / self.std
        for w, b in zip(self.weights[:-1], self.biases[:-1], strict=True):
            h = h @ w + b
            h = np.where(h > 0, h, np.expm1(np.minimum(h, 0.0)))  # ELU
        return self.limit_rad * np.tanh(h @ self.weights[-1] + self.biases[-1])

    def save(self, path: str | Path) -> None:
        """Write the policy to ``path`` (``.npz``, float32 weights)."""
        arrays = {f"w{i}": w.astype(np.float32) for i, w in enumerate(self.weights)}
        arrays |= {f"b{i}": b.astype(np.float32) for i, b in enumerate(self.biases)}
        np.savez_compressed(path, mean=self.mean, std=self.std, actuators=self.actuators,
                            limit_rad=self.limit_rad, info=np.array(self.info), **arrays)

    @classmethod
    def load(cls, path: str | Path) -> TrackingPolicy:
        """Read a policy written by :meth:`save`.

        Raises:
            PhysicsError: a missing array or inconsistent shapes (naming the file).
        """
        try:
            with np.load(path) as z:
                n = sum(k.startswith("w") for k in z.files)
                return cls(tuple(z[f"w{i}"].astype(np.float64) for i in range(n)),
                           tuple(z[f"b{i}"].astype(np.float64) for i in range(n)),
                           z["mean"], z["std"], z["actuators"], float(z["limit_rad"]),
                           str(z["info"]))
        except (KeyError, ValueError, OSError, PhysicsError) as e:
            raise PhysicsError(f"not a tracking policy file: {e}", field="policy",
                               source=str(path)) from e


@dataclass(frozen=True)
class PolicyConfig:
    """Settings of :class:`PolicyTracker`.

    Attributes:
        engage_m: body error (mean keypoint distance to the reference, metres) at which the
            planner takes over. 0.10 m: about twice the planner's own mean body error
            (default 45 mm, FAST 57 mm on the 20 clean CMU clips), fixed before any
            evaluation run.
        release_m: body error below which the policy takes back control, metres.
        hold_s: least time the planner keeps control once engaged, seconds.
        planner: the fallback planner's settings (``FAST`` by default; its ``retries`` and
            ``rewind_s`` are the tracking run's).
    """

    engage_m: float = 0.10
    release_m: float = 0.06
    hold_s: float = 0.2
    planner: MPCConfig = field(default_factory=lambda: FAST)

    def __post_init__(self) -> None:
        if not 0 < self.release_m <= self.engage_m:
            raise PhysicsError(f"need 0 < release_m <= engage_m; got {self.release_m}, "
                               f"{self.engage_m}", field="release_m")
        if self.hold_s < 0:
            raise PhysicsError(f"hold_s must be >= 0; got {self.hold_s}", field="hold_s")


class _Controller:
    """What :class:`PolicyTracker` and :class:`ExpertRecorder` share: the planner (fallback
    or expert), its simulated model, the reference servo targets and the observer."""

    def __init__(self, humanoid: Humanoid, reference: TrackingReference,
                 planner: MPCConfig) -> None:
        self.reference = reference
        self.planner = TrackingMPC(humanoid, reference, planner)
        self.model = self.planner.model
        self.config = planner
        self.ctrl_ref = self.planner.ctrl_ref
        self.site_ids = humanoid.site_ids
        self.observer = Observer(self.model, reference, self.ctrl_ref, humanoid.site_ids)
        self.actuators = sampled_actuators(self.model, planner.sampled_parts)
        limited = self.model.actuator_ctrllimited.astype(bool)
        rng = self.model.actuator_ctrlrange
        self._lo = np.where(limited, rng[:, 0], -np.inf)
        self._hi = np.where(limited, rng[:, 1], np.inf)

    @property
    def rollout_steps(self) -> int:
        """Planning-model steps the planner rolled out so far."""
        return self.planner.rollout_steps

    def __enter__(self) -> _Controller:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the planner's rollout threads (idempotent)."""
        self.planner.close()

    def reset(self, data: mujoco.MjData) -> None:
        """Put ``data`` in the reference's first state and clear the plan."""
        self.planner.reset(data)

    def snapshot(self) -> tuple[np.ndarray, int, int]:
        """The planner's plan (:meth:`TrackingMPC.snapshot`)."""
        return self.planner.snapshot()

    def restore(self, snapshot: tuple[np.ndarray, int, int]) -> None:
        """Go back to a plan taken by :meth:`snapshot`."""
        self.planner.restore(snapshot)

    def _policy_control(self, policy: TrackingPolicy, obs: np.ndarray, step: int) -> np.ndarray:
        u = self.ctrl_ref[min(step, self.reference.n_steps)].copy()
        u[self.actuators] += policy(obs)
        return np.clip(u, self._lo, self._hi)


class PolicyTracker(_Controller):
    """The policy at one evaluation per physics step, the planner where it fails (module
    docstring). Counts ``policy_steps`` and ``fallback_steps`` (physics steps each drove)
    and ``engagements`` (times the planner took over).

    Raises:
        PhysicsError: the policy's feature length or actuators do not match this body.
    """

    def __init__(self, humanoid: Humanoid, reference: TrackingReference,
                 policy: TrackingPolicy, config: PolicyConfig | None = None) -> None:
        self.settings = config = config or PolicyConfig()
        super().__init__(humanoid, reference, config.planner)
        if policy.n_features != self.observer.size or not np.array_equal(
                policy.actuators, self.actuators):
            raise PhysicsError(f"policy expects {policy.n_features} features and actuators "
                               f"{policy.actuators.tolist()}; this body gives "
                               f"{self.observer.size} and {self.actuators.tolist()}",
                               field="policy", source=reference.name)
        self.policy = policy
        self._hold = int(round(config.hold_s / reference.dt))
        self._engaged_at: int | None = None
        self.policy_steps = self.fallback_steps = self.engagements = 0

    def reset(self, data: mujoco.MjData) -> None:
        """Put ``data`` in the reference's first state; the policy drives."""
        super().reset(data)
        self._engaged_at = None

    def restore(self, snapshot: tuple[np.ndarray, int, int]) -> None:
        """Go back to a plan taken by :meth:`snapshot`; the policy drives."""
        super().restore(snapshot)
        self._engaged_at = None

    def control(self, data: mujoco.MjData, step: int) -> np.ndarray:
        """(nu,) servo targets for physics step ``step``."""
        err = body_error(data, self.site_ids, self.reference, step)
        if self._engaged_at is None and err > self.settings.engage_m:
            # The planner starts from the reference servo targets: its last plan, if any,
            # was about states left behind.
            self.planner.knots[:] = 0.0
            self.planner.replans = 0
            self._engaged_at = step
            self.engagements += 1
        elif (self._engaged_at is not None and step - self._engaged_at >= self._hold
              and err < self.settings.release_m):
            self._engaged_at = None
        if self._engaged_at is not None:
            self.fallback_steps += 1
            return self.planner.control(data, step)
        self.policy_steps += 1
        return self._policy_control(self.policy, self.observer(data, step), step)


class ExpertRecorder(_Controller):
    """The planner labelling every physics step (module docstring).

    Without a policy the planner drives (behaviour cloning data); with one the policy
    drives and the planner, run on the same states, only labels them (DAgger), except where
    the body error passes ``engage_m``, where the planner drives until it is below
    ``release_m`` so that the recorded states include recoveries and the run goes on.

    Attributes:
        features: recorded (D,) feature vectors; offsets: the planner's (A,) offsets of the
            sampled actuators, radians, one per physics step recorded.
        expert_steps: physics steps the planner drove.
    """

    def __init__(self, humanoid: Humanoid, reference: TrackingReference,
                 planner: MPCConfig, policy: TrackingPolicy | None = None,
                 engage_m: float = 0.10, release_m: float = 0.06) -> None:
        super().__init__(humanoid, reference, planner)
        self.policy = policy
        self.engage_m, self.release_m = engage_m, release_m
        self._expert_drives = policy is None
        self.features: list[np.ndarray] = []
        self.offsets: list[np.ndarray] = []
        self.expert_steps = 0

    def control(self, data: mujoco.MjData, step: int) -> np.ndarray:
        """(nu,) servo targets for physics step ``step``; records the step."""
        obs = self.observer(data, step)
        u = self.planner.control(data, step)
        self.features.append(obs)
        self.offsets.append(u[self.actuators] - self.ctrl_ref[min(step, self.reference.n_steps),
                                                              self.actuators])
        if self.policy is not None:
            err = body_error(data, self.site_ids, self.reference, step)
            if err > self.engage_m:
                self._expert_drives = True
            elif err < self.release_m:
                self._expert_drives = False
        if self._expert_drives:
            self.expert_steps += 1
            return u
        return self._policy_control(self.policy, obs, step)


__all__ = ["LOOKAHEAD_STEPS", "ExpertRecorder", "Observer", "PolicyConfig", "PolicyTracker",
           "TrackingPolicy", "body_error", "sampled_actuators"]

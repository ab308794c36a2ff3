"""Reaction-synthesis baselines: generate the reactor B from the actor A.

One interface (:class:`ReactionGenerator`)::

    generate(actor_window, reactor_first_frame) -> reactor_window

``actor_window`` is (T, J, 3) or (N, T, J, 3), ``reactor_first_frame`` (J, 3) or
(N, J, 3), the result (T, J, 3) or (N, T, J, 3) float32, positions in metres in one frame
shared by both people (the actor frame of :mod:`simenv.data.interaction_data` in our pipeline;
every baseline here is equivariant to rotations about Z and translations, so any Z-up
frame works). Joints are :data:`~simenv.data.interaction_data.INTER18_JOINTS` unless
``joint_names`` says otherwise. The reactor's first frame is given, as in InterFormer's
autoregressive inference, but a baseline's frame 0 need not reproduce it (the
evaluation scores frames 1..T-1, the generated ones).

Baselines (math)
----------------
Write ``F_t = (o_t, θ_t)`` for the actor's per-frame frame of
:func:`~simenv.data.interaction_data.actor_frame` (pelvis on the floor, facing heading) and
``N_F(x) = R_z(-θ)(x - o)`` for the map into it.

* **zero_velocity**: ``x̂_t = b_0`` (the reactor holds its first frame).
* **nearest_neighbour** (frame co-occurrence): every training frame ``s`` stores the pair
  ``(N_{F_s}(a_s), N_{F_s}(b_s))``, actor pose and co-occurring reactor pose, both in the
  actor's frame of that frame. For each query frame ``t``:
  ``s* = argmin_s ||N_{F_t}(a_t) - N_{F_s}(a_s)||`` (flattened ``J·3`` poses, KD-tree) and
  ``x̂_t = N_{F_t}^{-1}(N_{F_s*}(b_s*))``: the reactor pose that co-occurred with the
  nearest training actor pose, placed relative to the query actor as it was relative to
  the training one.
* **mirror**: the actor's motion reflected into the reactor's place. With ``G_A = F_0`` of
  the actor and ``G_B`` the same frame of the reactor's first frame,
  ``x̂_t = P N_{G_B}^{-1}(S N_{G_A}(a_t))``, where ``S = diag(1, -1, 1)`` reflects across the
  actor's sagittal plane and ``P`` swaps left and right joints (so the result is a body
  of the right handedness again). Face to face this is the reflection across the plane
  midway between the two people: the reactor raises its left hand when the actor
  raises its right, like a mirror image.
* **copy**: the same without the reflection, ``x̂_t = N_{G_B}^{-1}(N_{G_A}(a_t))``: the
  actor's motion turned and moved into the reactor's place (the reactor raises the same
  hand).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np
from scipy.spatial import cKDTree

from simenv.core.errors import MotionError
from simenv.data.interaction_data import INTER18_JOINTS, actor_frame, denormalise, normalise


@runtime_checkable
class ReactionGenerator(Protocol):
    """Anything that generates a reaction window from the actor and the reactor's first
    frame (module docstring)."""

    name: str

    def generate(self, actor_window: np.ndarray, reactor_first_frame: np.ndarray
                 ) -> np.ndarray:
        """(N, T, J, 3) / (T, J, 3) actor, (N, J, 3) / (J, 3) first reactor frame ->
        (N, T, J, 3) / (T, J, 3) reactor, metres."""
        ...


def check_inputs(actor_window: np.ndarray, reactor_first_frame: np.ndarray,
                 joints: int) -> tuple[np.ndarray, np.ndarray, bool]:
    """Validate and batch the inputs: ((N, T, J, 3) float64, (N, J, 3) float64, batched).

    Raises:
        MotionError: wrong shapes, joint counts that disagree with the layout, batch sizes
            that disagree, or a non-finite value.
    """
    a = np.asarray(actor_window, dtype=np.float64)
    b = np.asarray(reactor_first_frame, dtype=np.float64)
    batched = a.ndim == 4
    if a.ndim == 3:
        a = a[None]
    if b.ndim == 2:
        b = b[None]
    if a.ndim != 4 or a.shape[-1] != 3 or a.shape[2] != joints:
        raise MotionError(f"actor_window must have shape (N, T, {joints}, 3) or "
                          f"(T, {joints}, 3); got {np.shape(actor_window)}",
                          field="actor_window")
    if b.shape != (a.shape[0], joints, 3):
        raise MotionError(f"reactor_first_frame must have shape ({a.shape[0]}, {joints}, 3)"
                          f" or ({joints}, 3) to match the actor; got "
                          f"{np.shape(reactor_first_frame)}", field="reactor_first_frame")
    for name, x in (("actor_window", a), ("reactor_first_frame", b)):
        if not np.isfinite(x).all():
            raise MotionError(f"{name} has a non-finite value", field=name)
    return a, b, batched


def mirror_index(joint_names: Sequence[str]) -> list[int]:
    """Index permutation swapping every ``left_*`` joint with its ``right_*`` partner."""
    names = list(joint_names)

    def partner(n: str) -> str:
        for a, b in (("left_", "right_"), ("right_", "left_")):
            if n.startswith(a) and b + n[len(a):] in names:
                return b + n[len(a):]
        return n

    return [names.index(partner(n)) for n in names]


class ZeroVelocity:
    """The reactor holds its first frame: ``x̂_t = b_0``."""

    name = "zero_velocity"

    def __init__(self, joint_names: Sequence[str] = INTER18_JOINTS) -> None:
        self.joint_names = tuple(joint_names)

    def generate(self, actor_window: np.ndarray, reactor_first_frame: np.ndarray
                 ) -> np.ndarray:
        a, b, batched = check_inputs(actor_window, reactor_first_frame,
                                     len(self.joint_names))
        out = np.repeat(b[:, None], a.shape[1], axis=1).astype(np.float32)
        return out if batched else out[0]


class MirrorActor:
    """The actor's motion placed at the reactor's first-frame position and heading,
    reflected (``reflect=True``, "mirror") or not ("copy"); math in the module docstring."""

    def __init__(self, reflect: bool = True,
                 joint_names: Sequence[str] = INTER18_JOINTS) -> None:
        self.reflect = bool(reflect)
        self.joint_names = tuple(joint_names)
        self.name = "mirror" if self.reflect else "copy"
        self._swap = mirror_index(self.joint_names)

    def generate(self, actor_window: np.ndarray, reactor_first_frame: np.ndarray
                 ) -> np.ndarray:
        a, b, batched = check_inputs(actor_window, reactor_first_frame,
                                     len(self.joint_names))
        o_a, yaw_a = actor_frame(a[:, 0], self.joint_names)
        o_b, yaw_b = actor_frame(b, self.joint_names)
        local = normalise(a, o_a, yaw_a).astype(np.float64)
        if self.reflect:
            local = local[:, :, self._swap] * np.array([1.0, -1.0, 1.0])
        out = denormalise(local, o_b, yaw_b)
        return out if batched else out[0]


class NearestNeighbour:
    """Frame co-occurrence nearest neighbour (module docstring); :meth:`fit` first.

    Args:
        joint_names: the J joints of every pose.
    """

    name = "nearest_neighbour"

    def __init__(self, joint_names: Sequence[str] = INTER18_JOINTS) -> None:
        self.joint_names = tuple(joint_names)
        self._tree = None
        self._reactor: np.ndarray | None = None

    def _per_frame(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(M, J, 3) -> per-frame origins (M, 3) and headings (M,)."""
        return actor_frame(poses, self.joint_names)

    def fit(self, actor: np.ndarray, reactor: np.ndarray) -> NearestNeighbour:
        """Store the co-occurring frames of training data.

        Args:
            actor, reactor: (N, T, J, 3) windows or (M, J, 3) frames, same shape, metres,
                one frame shared by both people.
        """
        a = np.asarray(actor, dtype=np.float64)
        b = np.asarray(reactor, dtype=np.float64)
        joints = len(self.joint_names)
        if a.shape != b.shape or a.ndim not in (3, 4) or a.shape[-2:] != (joints, 3):
            raise MotionError(f"actor and reactor must both be (N, T, {joints}, 3) or "
                              f"(M, {joints}, 3); got {a.shape} and {b.shape}",
                              field="reactor")
        if not (np.isfinite(a).all() and np.isfinite(b).all()):
            raise MotionError("training poses have a non-finite value", field="actor")
        a, b = a.reshape(-1, joints, 3), b.reshape(-1, joints, 3)

        origin, yaw = self._per_frame(a)
        self._tree = cKDTree(normalise(a[:, None], origin, yaw)[:, 0].reshape(len(a), -1))
        self._reactor = normalise(b[:, None], origin, yaw)[:, 0]
        return self

    @property
    def num_frames(self) -> int:
        """Training frames stored."""
        return 0 if self._reactor is None else len(self._reactor)

    def generate(self, actor_window: np.ndarray, reactor_first_frame: np.ndarray
                 ) -> np.ndarray:
        if self._tree is None or self._reactor is None:
            raise MotionError("nearest_neighbour has no training frames; call fit() first")
        a, _, batched = check_inputs(actor_window, reactor_first_frame,
                                     len(self.joint_names))
        n, t, joints, _ = a.shape
        flat = a.reshape(n * t, joints, 3)
        origin, yaw = self._per_frame(flat)
        query = normalise(flat[:, None], origin, yaw)[:, 0].reshape(n * t, -1)
        _, idx = self._tree.query(query, k=1)
        out = denormalise(self._reactor[idx][:, None], origin, yaw)[:, 0]
        out = out.reshape(n, t, joints, 3)
        return out if batched else out[0]


#: Baseline names of the evaluation, in table order.
BASELINE_NAMES: tuple[str, ...] = ("nearest_neighbour", "mirror", "copy", "zero_velocity")


def make_baseline(name: str, train_actor: np.ndarray | None = None,
                  train_reactor: np.ndarray | None = None,
                  joint_names: Sequence[str] = INTER18_JOINTS) -> ReactionGenerator:
    """A baseline by name (:data:`BASELINE_NAMES`); ``nearest_neighbour`` is fitted on
    ``train_actor`` / ``train_reactor``.

    Raises:
        MotionError: unknown name, or nearest_neighbour without training data.
    """
    if name == "zero_velocity":
        return ZeroVelocity(joint_names)
    if name in ("mirror", "copy"):
        return MirrorActor(reflect=name == "mirror", joint_names=joint_names)
    if name == "nearest_neighbour":
        if train_actor is None or train_reactor is None:
            raise MotionError("nearest_neighbour needs train_actor and train_reactor",
                              field="train_actor")
        return NearestNeighbour(joint_names).fit(train_actor, train_reactor)
    raise MotionError(f"unknown reaction baseline {name!r}; expected one of "
                      f"{', '.join(BASELINE_NAMES)}", field="name")

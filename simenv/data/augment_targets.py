"""Training targets of interaction augmentation with skeleton priors (Li et al.),
built from real two-person windows.

Li et al. train their retargeting networks on the output of an optimiser. We have no such
output, so the targets are built here, honestly, from the real windows of
:mod:`simenv.data.interaction_data` (actor A and reactor B, (T, J, 3) metres in the actor
frame, joints :data:`~simenv.data.interaction_data.INTER18_JOINTS`):

Scale vectors
-------------
One scale per bone of :func:`~simenv.data.interaction_data.inter18_skeleton` (the J - 1 = 17
bones, ordered by their child joint, :data:`BONE_CHILDREN`), on the grid
:data:`SCALE_GRID` = 0.75, 0.80, ..., 1.25. :func:`sample_scales` draws each grid value
uniformly; with ``symmetric=True`` (our default) a left bone and its right partner share
one scale (:data:`SCALE_GROUPS`, 10 groups: hip, thigh, shin, shoulder, upper arm,
forearm, hand, spine, neck, head) because a body with a 25 % longer left than right shin
is not a plausible person, which is what a skeleton prior is for.

Reactor target B' (:func:`scale_skeleton`)
------------------------------------------
Forward kinematics from the pelvis keeping every bone direction and scaling its length:

    b'_root = b_root,    b'_j = b'_{p(j)} + s_j (b_j - b_{p(j)}),

then every frame is shifted vertically so that its lowest ankle stays at the height it had
(``Δz_t = min_{ankles} b_{t,z} - min_{ankles} b'_{t,z}``): a foot on the floor stays on
the floor, a jump stays a jump, and longer legs lift the pelvis.

Actor target A' (:func:`adapt_actor`)
-------------------------------------
The actor is adapted to the new reactor by a small least-squares optimisation over its
root positions ``r_t`` and bone directions ``u_{t,k}`` (unit vectors) with each frame's
bone lengths ``L_{t,k}`` fixed (so A' keeps A's own bone lengths exactly):
``a'_root = r_t``, ``a'_j = a'_{p(j)} + L_{t,k(j)} u_{t,k(j)}``. With the key pairs
``(i, j)`` of :data:`simenv.data.interaction_metrics.KEY_JOINT_PAIRS`, their real distances
``d_{t,p} = ||a_{t,i} - b_{t,j}||`` and the contact mask ``m_{t,p} = [d_{t,p} <`` 0.15 m
``]`` (:data:`~simenv.data.interaction_metrics.CONTACT_DISTANCE_M`), it minimises, per window,

    E = Σ_{t,p} m_{t,p} (||a'_{t,i} - b'_{t,j}|| - d_{t,p})²           (keep the contacts)
      + λ_dir  Σ_{t,k} L_{t,k}² ||u_{t,k} - u⁰_{t,k}||²                (stay in A's pose)
      + λ_root Σ_t ||r_t - a_{t,root}||²                                (stay in A's place)
      + λ_feet Σ_t Σ_{ankles} ||a'_{t,f} - a_{t,f}||²                   (no foot sliding)
      + λ_vel  Σ_t Σ_j ||(a'_{t+1,j} - a'_{t,j}) - (a_{t+1,j} - a_{t,j})||²   (A's velocities)

(:class:`AdaptWeights`; ``u⁰`` are A's own directions, so A' = A is the minimiser when no
pair is in contact, and those windows are not optimised at all). The directions are
parametrised as ``u = normalise(u⁰ + δ)`` and (δ, r) found by L-BFGS in float64.
:func:`contact_jpd_mm` measures how well the contact distances are kept
(``mean over contact frames of |d' - d|``) for A' and for the naive A' = A.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from simenv.core.errors import MotionError
from simenv.data.interaction_data import INTER18_JOINTS, InteractionWindows, inter18_skeleton
from simenv.data.interaction_metrics import CONTACT_DISTANCE_M, KEY_JOINT_PAIRS

#: The scale grid of Li et al.: 0.75 to 1.25 in steps of 0.05 (11 values).
SCALE_GRID: tuple[float, ...] = tuple(round(0.75 + 0.05 * k, 2) for k in range(11))
#: Parents of the 18-keypoint layout (topological order: a parent precedes its children).
PARENTS: tuple[int, ...] = tuple(inter18_skeleton().parents)
#: Child joint of each bone (bone k is ``PARENTS[BONE_CHILDREN[k]] -> BONE_CHILDREN[k]``).
BONE_CHILDREN: tuple[int, ...] = tuple(j for j, p in enumerate(PARENTS) if p >= 0)
NUM_BONES = len(BONE_CHILDREN)
#: Bone names (the child joint's name).
BONE_NAMES: tuple[str, ...] = tuple(INTER18_JOINTS[j] for j in BONE_CHILDREN)


def _groups() -> tuple[tuple[int, ...], ...]:
    """Bone indices sharing one scale in a symmetric body (left/right partners)."""
    out: dict[str, list[int]] = {}
    for k, name in enumerate(BONE_NAMES):
        out.setdefault(name.removeprefix("left_").removeprefix("right_"), []).append(k)
    return tuple(tuple(v) for v in out.values())


#: Symmetric scale groups: each tuple lists the bones (indices into :data:`BONE_NAMES`)
#: that share one scale.
SCALE_GROUPS: tuple[tuple[int, ...], ...] = _groups()
#: Ankle joint indices (the feet of the vertical shift and of λ_feet).
ANKLES: tuple[int, ...] = (INTER18_JOINTS.index("left_ankle"),
                           INTER18_JOINTS.index("right_ankle"))


def _positions(x: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim < 3 or a.shape[-2:] != (len(PARENTS), 3):
        raise MotionError(f"{name} must have shape (..., T, {len(PARENTS)}, 3), metres; "
                          f"got {np.shape(x)}", field=name)
    if not np.isfinite(a).all():
        raise MotionError(f"{name} has a non-finite value", field=name)
    return a


def check_scales(scales: np.ndarray, batch: int | None = None) -> np.ndarray:
    """Validate (B,) or (N, B) per-bone scales (B = 17): finite, within [0.75, 1.25]
    (a 1e-6 tolerance). Returns (N, B) float64 (N = 1 for a single vector, or ``batch``
    copies of it when given).

    Raises:
        MotionError: wrong shape or a scale outside the range.
    """
    s = np.asarray(scales, dtype=np.float64)
    if s.ndim == 1:
        s = s[None]
        if batch is not None:
            s = np.repeat(s, batch, axis=0)
    if s.ndim != 2 or s.shape[1] != NUM_BONES or (batch is not None and len(s) != batch):
        want = f"({batch}, {NUM_BONES})" if batch is not None else f"(N, {NUM_BONES})"
        raise MotionError(f"scales must have shape ({NUM_BONES},) or {want}, one per bone "
                          f"({', '.join(BONE_NAMES)}); got {np.shape(scales)}",
                          field="scales")
    lo, hi = SCALE_GRID[0], SCALE_GRID[-1]
    if not np.isfinite(s).all() or (s < lo - 1e-6).any() or (s > hi + 1e-6).any():
        raise MotionError(f"scales must be finite and within [{lo}, {hi}]; got values in "
                          f"[{np.nanmin(s):.3g}, {np.nanmax(s):.3g}]", field="scales")
    return s


def sample_scales(n: int, rng: np.random.Generator, *, symmetric: bool = True
                  ) -> np.ndarray:
    """(n, 17) per-bone scales, each grid value of :data:`SCALE_GRID` equally likely;
    shared by left/right partners when ``symmetric`` (module docstring)."""
    grid = np.asarray(SCALE_GRID)
    if not symmetric:
        return grid[rng.integers(0, len(grid), (n, NUM_BONES))]
    out = np.empty((n, NUM_BONES))
    for bones, pick in zip(SCALE_GROUPS, rng.integers(0, len(grid), (len(SCALE_GROUPS), n)),
                           strict=True):
        out[:, list(bones)] = grid[pick][:, None]
    return out


def bone_vectors(positions: np.ndarray) -> np.ndarray:
    """(..., 17, 3) bone vectors ``x_j - x_{p(j)}`` of (..., 18, 3) positions."""
    p = np.asarray(positions)
    return p[..., BONE_CHILDREN, :] - p[..., [PARENTS[j] for j in BONE_CHILDREN], :]


def forward_kinematics(root: np.ndarray, bones: np.ndarray) -> np.ndarray:
    """(..., 18, 3) positions from (..., 3) root positions and (..., 17, 3) bone vectors
    (works for numpy arrays and torch tensors)."""
    joints = [root]
    for j in range(1, len(PARENTS)):
        joints.append(joints[PARENTS[j]] + bones[..., j - 1, :])
    if isinstance(root, np.ndarray):
        return np.stack(joints, axis=-2)
    import torch  # heavy: only tensor callers (the augmentation model) get here, with it loaded

    return torch.stack(joints, dim=-2)


def scale_skeleton(positions: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """B': every bone scaled, directions kept, lowest ankle at its height (module docstring).

    Args:
        positions: (N, T, 18, 3) or (T, 18, 3) metres, Z-up.
        scales: (17,) or (N, 17) per-bone scales in [0.75, 1.25].

    Returns:
        float32 positions of the shape of ``positions``.
    """
    p = _positions(positions, "positions")
    single = p.ndim == 3
    p = p[None] if single else p
    s = check_scales(scales, len(p))
    out = forward_kinematics(p[:, :, 0], bone_vectors(p) * s[:, None, :, None])
    dz = p[:, :, ANKLES, 2].min(axis=-1) - out[:, :, ANKLES, 2].min(axis=-1)
    out[..., 2] += dz[..., None]
    out = out.astype(np.float32)
    return out[0] if single else out


def _pair_index(pairs: Sequence[tuple[str, str]]) -> tuple[list[int], list[int]]:
    names = list(INTER18_JOINTS)
    return [names.index(a) for a, _ in pairs], [names.index(b) for _, b in pairs]


def contact_distances(actor: np.ndarray, reactor: np.ndarray,
                      pairs: Sequence[tuple[str, str]] = KEY_JOINT_PAIRS) -> np.ndarray:
    """(N, T, P) key joint-pair distances ``||a_i - b_j||``, metres."""
    ia, ib = _pair_index(pairs)
    a, b = np.asarray(actor, np.float64), np.asarray(reactor, np.float64)
    return np.linalg.norm(a[..., ia, :] - b[..., ib, :], axis=-1)


def contact_jpd_mm(actor: np.ndarray, reactor: np.ndarray, real_distance: np.ndarray,
                   mask: np.ndarray, pairs: Sequence[tuple[str, str]] = KEY_JOINT_PAIRS
                   ) -> float | None:
    """JPD on contacts: ``mean over m of |d(a, b) - d_real|``, mm; None without contacts.

    Args:
        actor, reactor: (N, T, 18, 3) metres. real_distance, mask: (N, T, P) the real
            key-pair distances (metres) and the frames where they are contacts.
    """
    m = np.asarray(mask, bool)
    if not m.any():
        return None
    err = np.abs(contact_distances(actor, reactor, pairs) - real_distance)
    return float(1000.0 * err[m].mean())


@dataclass(frozen=True)
class AdaptWeights:
    """Weights of the actor-adaptation objective (module docstring) and L-BFGS budget.

    The contact term has weight 1; the others are relative to it (all terms in m²).
    """

    direction: float = 0.02
    root: float = 0.1
    feet: float = 1.0
    velocity: float = 0.5
    iterations: int = 60
    contact_distance: float = CONTACT_DISTANCE_M


def adapt_actor(actor: np.ndarray, reactor: np.ndarray, new_reactor: np.ndarray,
                weights: AdaptWeights = AdaptWeights(),
                pairs: Sequence[tuple[str, str]] = KEY_JOINT_PAIRS
                ) -> tuple[np.ndarray, dict[str, float | int | None]]:
    """A': the actor adapted to ``new_reactor`` keeping the real contact distances.

    Args:
        actor, reactor: (N, T, 18, 3) the real pair, metres.
        new_reactor: (N, T, 18, 3) the scaled reactor B'.

    Returns:
        ``(actor', info)``: (N, T, 18, 3) float32 (A itself for windows without contact)
        and ``{"optimised_windows", "contact_frames", "jpd_contact_mm",
        "jpd_contact_naive_mm", "energy_start", "energy_end"}`` (JPD over the contact
        frames of A' and of the naive A' = A against ``new_reactor``, mm; None without
        contacts).
    """
    import torch  # heavy, and the targets themselves are NumPy: only this optimiser needs it

    a = _positions(actor, "actor")
    b = _positions(reactor, "reactor")
    nb = _positions(new_reactor, "new_reactor")
    if not (a.ndim == 4 and a.shape == b.shape == nb.shape):
        raise MotionError(f"actor, reactor and new_reactor must share one (N, T, 18, 3) "
                          f"shape; got {a.shape}, {b.shape}, {nb.shape}", field="new_reactor")
    d_real = contact_distances(a, b, pairs)
    mask = d_real < weights.contact_distance
    out = a.copy()
    todo = np.flatnonzero(mask.any(axis=(1, 2)))
    info: dict[str, float | int | None] = {
        "optimised_windows": int(len(todo)), "contact_frames": int(mask.sum()),
        "jpd_contact_naive_mm": contact_jpd_mm(a, nb, d_real, mask, pairs),
        "energy_start": None, "energy_end": None}
    if len(todo):
        ia, ib = _pair_index(pairs)
        at = torch.as_tensor(a[todo])
        target_b = torch.as_tensor(nb[todo])[..., ib, :]
        d = torch.as_tensor(d_real[todo])
        m = torch.as_tensor(mask[todo], dtype=torch.float64)
        bones0 = at[..., BONE_CHILDREN, :] - at[..., [PARENTS[j] for j in BONE_CHILDREN], :]
        length = bones0.norm(dim=-1, keepdim=True)
        u0 = bones0 / length.clamp_min(1e-9)
        delta = torch.zeros_like(u0, requires_grad=True)
        root = at[..., 0, :].clone().requires_grad_(True)
        vel0 = at[:, 1:] - at[:, :-1]

        def pose() -> tuple[torch.Tensor, torch.Tensor]:
            u = u0 + delta
            u = u / u.norm(dim=-1, keepdim=True).clamp_min(1e-9)
            return forward_kinematics(root, length * u), u

        def energy() -> torch.Tensor:
            x, u = pose()
            dist = (x[..., ia, :] - target_b).norm(dim=-1)
            e = (m * (dist - d) ** 2).sum()
            e = e + weights.direction * ((length * (u - u0)) ** 2).sum()
            e = e + weights.root * ((root - at[..., 0, :]) ** 2).sum()
            e = e + weights.feet * ((x[..., ANKLES, :] - at[..., ANKLES, :]) ** 2).sum()
            return e + weights.velocity * ((x[:, 1:] - x[:, :-1] - vel0) ** 2).sum()

        opt = torch.optim.LBFGS([delta, root], lr=1.0, max_iter=weights.iterations,
                                history_size=20, line_search_fn="strong_wolfe")

        def closure() -> torch.Tensor:
            opt.zero_grad()
            e = energy()
            e.backward()
            return e

        with torch.no_grad():
            info["energy_start"] = float(energy())
        opt.step(closure)
        with torch.no_grad():
            info["energy_end"] = float(energy())
            out[todo] = pose()[0].numpy()
    info["jpd_contact_mm"] = contact_jpd_mm(out, nb, d_real, mask, pairs)
    return out.astype(np.float32), info


@dataclass(frozen=True, eq=False)
class AugmentTargets:
    """Augmentation samples: window ``window[m]`` of the source windows with scales
    ``scales[m]``.

    Attributes:
        window: (M,) int64 index into the source :class:`InteractionWindows`.
        scales: (M, 17) float64 per-bone scales of the reactor.
        actor, reactor: (M, T, 18, 3) float32 the real pair (copies of the source), metres.
        actor_target: (M, T, 18, 3) float32 A'. reactor_target: (M, T, 18, 3) float32 B'.
        real_distance: (M, T, P) float32 real key-pair distances, metres.
        contact: (M, T, P) bool real contacts (distance < 0.15 m).
        label, recording: (M,) int64 of the source windows.
        info: statistics of the actor adaptation (:func:`adapt_actor`).
    """

    window: np.ndarray
    scales: np.ndarray
    actor: np.ndarray
    reactor: np.ndarray
    actor_target: np.ndarray
    reactor_target: np.ndarray
    real_distance: np.ndarray
    contact: np.ndarray
    label: np.ndarray
    recording: np.ndarray
    info: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return int(len(self.window))

    def subset(self, index: np.ndarray | Sequence[int]) -> AugmentTargets:
        """Samples selected by an integer or boolean index (``info`` kept)."""
        i = np.asarray(index)
        return AugmentTargets(self.window[i], self.scales[i], self.actor[i], self.reactor[i],
                              self.actor_target[i], self.reactor_target[i],
                              self.real_distance[i], self.contact[i], self.label[i],
                              self.recording[i], dict(self.info))


def build_targets(windows: InteractionWindows, scales_per_window: int = 4, *, seed: int = 0,
                  symmetric: bool = True, weights: AdaptWeights = AdaptWeights()
                  ) -> AugmentTargets:
    """``scales_per_window`` augmentation samples of every window: scales drawn by
    :func:`sample_scales`, B' by :func:`scale_skeleton`, A' by :func:`adapt_actor`.

    Raises:
        MotionError: no windows, a window not on the 18-keypoint layout, or
            ``scales_per_window`` < 1.
    """
    if len(windows) == 0:
        raise MotionError("no windows to build augmentation targets from", field="windows")
    if tuple(windows.joint_names) != INTER18_JOINTS:
        raise MotionError("windows must be on the 18-keypoint layout", field="joint_names")
    if int(scales_per_window) != scales_per_window or scales_per_window < 1:
        raise MotionError(f"scales_per_window must be an integer >= 1; got "
                          f"{scales_per_window!r}", field="scales_per_window")
    rng = np.random.default_rng(seed)
    idx = np.repeat(np.arange(len(windows)), int(scales_per_window))
    scales = sample_scales(len(idx), rng, symmetric=symmetric)
    a, b = windows.actor[idx], windows.reactor[idx]
    nb = scale_skeleton(b, scales)
    na, info = adapt_actor(a, b, nb, weights)
    d = contact_distances(a, b)
    return AugmentTargets(idx, scales, a, b, na, nb, d.astype(np.float32),
                          d < weights.contact_distance, windows.label[idx],
                          windows.recording[idx], info)

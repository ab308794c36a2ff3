"""BiGraphDiff: a denoising diffusion model generating both people of an interaction
from a class label.

The model generates the actor's and the reactor's 40-frame windows together, in the actor
frame of :mod:`simenv.data.interaction_data` (metres, Z-up, the actor's pelvis on the floor at
the origin at frame 0, facing +x). It is not a reaction generator: nothing is given but
the class.

Diffusion (DDPM, Ho et al. 2020; :class:`DiffusionSchedule`)
------------------------------------------------------------
Linear schedule ``β_k = β_1 + (β_K - β_1)(k - 1)/(K - 1)``, ``α_k = 1 - β_k``,
``ᾱ_k = Π_{s≤k} α_s``. Forward process in closed form
``q(x_k | x_0) = N(√ᾱ_k x_0, (1 - ᾱ_k) I)``; the network predicts the noise ``ε`` of
``x_k = √ᾱ_k x_0 + √(1 - ᾱ_k) ε`` and is trained with ``L = E ||ε - ε_θ(x_k, k, c)||²``
(the "simple" loss). Sampling is ancestral through the posterior
``q(x_{k-1} | x_k, x_0) = N(μ̃_k, β̃_k I)``, ``μ̃_k = c^0_k x̂_0 + c^k_k x_k`` with
``c^0_k = √ᾱ_{k-1} β_k / (1 - ᾱ_k)``, ``c^k_k = √α_k (1 - ᾱ_{k-1}) / (1 - ᾱ_k)``,
``β̃_k = β_k (1 - ᾱ_{k-1}) / (1 - ᾱ_k)`` and
``x̂_0 = (x_k - √(1 - ᾱ_k) ε_θ) / √ᾱ_k``. With ``steps < K`` the sampler uses an evenly
spaced subsequence ``τ`` of the training steps with the respaced betas
``β'_i = 1 - ᾱ_{τ_i} / ᾱ_{τ_{i-1}}`` (Nichol & Dhariwal 2021), which keeps ``ᾱ`` at
every visited step.

We train with ``K = 100`` steps (the paper's 1000 do not fit a CPU budget) and scale the
usual ``[1e-4, 0.02]`` (for 1000 steps) by ``1000 / K``: ``β ∈ [1e-3, 0.2]``, so
``ᾱ_K ≈ 2e-5`` and ``x_K`` is pure noise as in the 1000-step schedule.

Classifier-free guidance (Ho & Salimans 2022): during training the label is replaced by a
learned "null" label with probability ``label_dropout``; at sampling
``ε = ε_∅ + w (ε_c - ε_∅)``. ``w = 1`` (default) is the plain conditional model and costs
one network pass per step.

Data representation
-------------------
``x_0`` is the pair (2, T, J, 3): person 0 the actor, 1 the reactor, each coordinate
standardised by the training set's mean and standard deviation per (person, joint,
coordinate) over windows and frames (std floored at ``std_floor`` metres so that nearly
constant coordinates are not blown up). Optional augmentation: left/right mirror
(``y -> -y`` in the actor frame with left and right joints swapped, which keeps the actor
frame's conventions); off by default because it changes which hand is used, which is part
of the classes (right-hand fist bump, the salsa hold).

Denoiser (:class:`Denoiser`)
----------------------------
One token per (person p, frame t, joint j): ``h = W_in x + e_p + e_j + PE(t)``. The
conditioning vector ``c = MLP(PE(k)) + e_label`` modulates every pre-norm LayerNorm
(adaptive LayerNorm, ``LN(h)(1 + γ(c)) + β(c)``, initialised to identity). Each of the
``blocks`` blocks applies, with residuals:

1. :class:`SkeletonGraphConv`, the intra-skeleton graph of
   :func:`~simenv.data.interaction_data.inter18_skeleton` within each person and frame:
   ``h_i <- W_s h_i + W_p h_{parent(i)} + W_c mean_{c ∈ children(i)} h_c`` (ST-GCN's
   spatial partition: self, centripetal, centrifugal).
2. :class:`BipartiteGraph`, the complete bipartite graph between the two skeletons at
   each frame: every joint ``i`` of one person aggregates from every joint ``j`` of the
   other, ``m_i = Σ_j softmax_j(q_i·k_j / √d_h + E_ij) v_j`` (multi-head), with ``E`` a
   learned (J, J) bipartite edge bias. The same weights serve A <- B and B <- A, so the
   module is equivariant to swapping the persons' roles.
3. :class:`EfficientAttention` over the T frames of each (person, joint), Shen et al.
   2021: ``E(Q, K, V) = ρ_q(Q) (ρ_k(K)ᵀ V)``, ``ρ_q`` a softmax over the features of each
   query and ``ρ_k`` a softmax over the frames of each key feature, O(T d²) instead of
   O(T² d).
4. A GELU feed-forward network.

The output layer ``LN -> Linear(d, 3)`` is zero-initialised (ε̂ = 0 at the start, loss 1).

Paper vs ours
-------------
``K = 100`` diffusion steps (paper: 1000); a small denoiser (``d_model`` 32, 3 blocks);
the paper's exact graph-convolution variant and loss extras are not reproduced: the
simple ε loss only; EMA of the weights (decay ``ema_decay``) is what is saved.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from simenv.core.errors import MotionError, SimenvError
from simenv.data import interaction_data as idata
from simenv.models.checkpoint import Checkpoint, CheckpointMixin
from simenv.models.training import CpuBudget, cosine_schedule, seeded

CHECKPOINT_FORMAT = "simenv-bigraphdiff-1"


@dataclass(frozen=True)
class BiGraphDiffConfig:
    """Hyperparameters (JSON-able); defaults train in about 10 CPU minutes.

    Attributes:
        diffusion_steps: K, steps of the training schedule.
        beta_start, beta_end: β_1 and β_K of the linear schedule.
        d_model: token width. blocks: denoiser blocks. heads: attention heads.
        ffn_mult: feed-forward width / d_model.
        label_dropout: probability of the null label in training (classifier-free
            guidance). guidance_scale: default w at sampling.
        epochs, batch_size, lr, weight_decay, grad_clip: optimisation (AdamW, cosine
            decay after ``warmup_steps``).
        ema_decay: decay of the weight average that is kept and saved.
        mirror: left/right mirror augmentation (module docstring).
        std_floor: smallest per-coordinate standard deviation, metres.
        x0_clip: |x̂_0| bound in standardised units while sampling.
        max_cpu_minutes: training stops after this much CPU time (None: no limit).
        bone_weight: λ_b of the bone-length term (:func:`bone_loss`) added to the ε MSE;
            0 trains with the ε MSE alone, as the paper.
    """

    diffusion_steps: int = 100
    beta_start: float = 1e-3
    beta_end: float = 0.2
    d_model: int = 32
    blocks: int = 3
    heads: int = 4
    ffn_mult: int = 2
    label_dropout: float = 0.1
    guidance_scale: float = 1.0
    epochs: int = 40
    batch_size: int = 16
    lr: float = 1e-3
    weight_decay: float = 0.0
    grad_clip: float = 1.0
    warmup_steps: int = 50
    ema_decay: float = 0.99
    mirror: bool = False
    std_floor: float = 0.02
    x0_clip: float = 5.0
    max_cpu_minutes: float | None = 15.0
    bone_weight: float = 0.0


# -- diffusion schedule --------------------------------------------------------------------


class DiffusionSchedule:
    """Closed forms of a DDPM noise schedule (module docstring), float64.

    Args:
        betas: (K,) β_1..β_K in (0, 1). Index ``k`` (0-based) is diffusion step k + 1.
    """

    def __init__(self, betas: np.ndarray) -> None:
        b = np.asarray(betas, dtype=np.float64)
        if b.ndim != 1 or len(b) == 0 or not ((b > 0) & (b < 1)).all():
            raise SimenvError(f"betas must be a non-empty 1-d array in (0, 1); got {b!r}",
                              field="betas")
        self.betas = b
        self.alphas = 1.0 - b
        self.alpha_bar = np.cumprod(self.alphas)
        self.alpha_bar_prev = np.concatenate([[1.0], self.alpha_bar[:-1]])
        self.posterior_variance = b * (1.0 - self.alpha_bar_prev) / (1.0 - self.alpha_bar)
        self.coef_x0 = np.sqrt(self.alpha_bar_prev) * b / (1.0 - self.alpha_bar)
        self.coef_xt = np.sqrt(self.alphas) * (1.0 - self.alpha_bar_prev) / (1.0 - self.alpha_bar)

    @classmethod
    def linear(cls, steps: int, beta_start: float, beta_end: float) -> DiffusionSchedule:
        """``β_k`` evenly spaced from ``beta_start`` to ``beta_end`` over ``steps``."""
        if int(steps) != steps or steps < 1:
            raise SimenvError(f"diffusion steps must be an integer >= 1; got {steps!r}",
                              field="diffusion_steps")
        return cls(np.linspace(beta_start, beta_end, int(steps)))

    def __len__(self) -> int:
        return len(self.betas)

    def q_mean_var(self, x0: np.ndarray, k: int) -> tuple[np.ndarray, float]:
        """Mean ``√ᾱ_k x_0`` and variance ``1 - ᾱ_k`` of ``q(x_k | x_0)``."""
        return np.sqrt(self.alpha_bar[k]) * np.asarray(x0), float(1.0 - self.alpha_bar[k])

    def q_sample(self, x0: torch.Tensor, k: torch.Tensor, noise: torch.Tensor
                 ) -> torch.Tensor:
        """``x_k = √ᾱ_k x_0 + √(1 - ᾱ_k) ε`` for a batch; ``k`` (B,) 0-based steps."""
        ab = torch.as_tensor(self.alpha_bar, dtype=x0.dtype)[k]
        shape = (-1,) + (1,) * (x0.ndim - 1)
        return ab.sqrt().reshape(shape) * x0 + (1 - ab).sqrt().reshape(shape) * noise

    def predict_x0(self, xk: np.ndarray, k: int, eps: np.ndarray) -> np.ndarray:
        """``x̂_0 = (x_k - √(1 - ᾱ_k) ε) / √ᾱ_k``."""
        return (xk - np.sqrt(1.0 - self.alpha_bar[k]) * eps) / np.sqrt(self.alpha_bar[k])

    def respaced(self, steps: int) -> tuple[DiffusionSchedule, np.ndarray]:
        """A ``steps``-step schedule visiting an evenly spaced subsequence ``τ`` of this
        one with the same ``ᾱ`` there, and ``τ`` (0-based indices into this schedule)."""
        if int(steps) != steps or not 1 <= steps <= len(self):
            raise SimenvError(f"sampling steps must be an integer in [1, {len(self)}]; got "
                              f"{steps!r}", field="steps")
        tau = np.unique(np.round(np.linspace(0, len(self) - 1, int(steps))).astype(int))
        ab = self.alpha_bar[tau]
        prev = np.concatenate([[1.0], ab[:-1]])
        return DiffusionSchedule(1.0 - ab / prev), tau


# -- denoiser ------------------------------------------------------------------------------


def sinusoidal(positions: torch.Tensor, dim: int) -> torch.Tensor:
    """(..., dim) sinusoidal encoding of positions (Vaswani et al.), ``dim`` even."""
    half = dim // 2
    freq = torch.exp(-math.log(10000.0) * torch.arange(half, dtype=torch.float32) / half)
    ang = positions.float()[..., None] * freq
    return torch.cat([ang.sin(), ang.cos()], dim=-1)


def skeleton_partitions(parents: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """(J, J) parent matrix ``P[i, parent(i)] = 1`` and children-mean matrix
    ``C[i, c] = 1 / |children(i)|`` (rows of a root / a leaf are zero), float32."""
    n = len(parents)
    p, c = np.zeros((n, n), np.float32), np.zeros((n, n), np.float32)
    for j, par in enumerate(parents):
        if par >= 0:
            p[j, par] = 1.0
            c[par, j] = 1.0
    deg = c.sum(axis=1, keepdims=True)
    return p, np.divide(c, deg, out=np.zeros_like(c), where=deg > 0)


class SkeletonGraphConv(nn.Module):
    """Intra-skeleton graph convolution on (..., J, d) tokens:
    ``W_s h_i + W_p h_{parent(i)} + W_c mean_{children(i)} h_c``."""

    def __init__(self, d: int, parents: Sequence[int]) -> None:
        super().__init__()
        p, c = skeleton_partitions(parents)
        self.register_buffer("parent_of", torch.as_tensor(p), persistent=False)
        self.register_buffer("child_mean", torch.as_tensor(c), persistent=False)
        self.w_self, self.w_parent, self.w_child = (nn.Linear(d, d) for _ in range(3))

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        return (self.w_self(h) + self.w_parent(torch.einsum("ij,...jd->...id", self.parent_of, h))
                + self.w_child(torch.einsum("ij,...jd->...id", self.child_mean, h)))


class BipartiteGraph(nn.Module):
    """Complete bipartite message passing between the two skeletons, per frame.

    Input (B, 2, T, J, d); person ``p`` receives from person ``1 - p``:
    ``m_{p,i} = W_o concat_h Σ_j softmax_j(q_{p,i}·k_{1-p,j} / √d_h + E_{h,i,j}) v_{1-p,j}``
    with one set of weights for both directions, so swapping the persons swaps the output.
    """

    def __init__(self, d: int, heads: int, joints: int) -> None:
        super().__init__()
        if d % heads:
            raise SimenvError(f"d_model {d} must be divisible by heads {heads}",
                              field="heads")
        self.heads = heads
        self.q, self.k, self.v, self.o = (nn.Linear(d, d) for _ in range(4))
        self.edge_bias = nn.Parameter(torch.zeros(heads, joints, joints))

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        b, p, t, j, d = h.shape
        other = h.flip(1)
        q = self.q(h).reshape(b, p, t, j, self.heads, -1)
        k = self.k(other).reshape(b, p, t, j, self.heads, -1)
        v = self.v(other).reshape(b, p, t, j, self.heads, -1)
        scores = torch.einsum("bptihe,bptjhe->bpthij", q, k) / math.sqrt(q.shape[-1])
        w = torch.softmax(scores + self.edge_bias, dim=-1)
        return self.o(torch.einsum("bpthij,bptjhe->bptihe", w, v).reshape(b, p, t, j, d))


class EfficientAttention(nn.Module):
    """Efficient attention (Shen et al. 2021) along the second-to-last axis of
    (..., T, d) tokens: ``ρ_q(Q) (ρ_k(K)ᵀ V)`` per head, ``ρ_q`` softmax over each
    query's features, ``ρ_k`` softmax over the T positions of each key feature."""

    def __init__(self, d: int, heads: int) -> None:
        super().__init__()
        if d % heads:
            raise SimenvError(f"d_model {d} must be divisible by heads {heads}",
                              field="heads")
        self.heads = heads
        self.q, self.k, self.v, self.o = (nn.Linear(d, d) for _ in range(4))

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        *lead, t, d = h.shape
        split = (*lead, t, self.heads, d // self.heads)
        q = torch.softmax(self.q(h).reshape(split), dim=-1)
        k = torch.softmax(self.k(h).reshape(split), dim=-3)
        v = self.v(h).reshape(split)
        context = torch.einsum("...the,...thf->...hef", k, v)
        return self.o(torch.einsum("...the,...hef->...thf", q, context).reshape(*lead, t, d))


class AdaNorm(nn.Module):
    """LayerNorm modulated by the conditioning: ``LN(h)(1 + γ(c)) + β(c)``."""

    def __init__(self, d: int) -> None:
        super().__init__()
        self.norm = nn.LayerNorm(d, elementwise_affine=False)
        self.mod = nn.Linear(d, 2 * d)
        nn.init.zeros_(self.mod.weight)
        nn.init.zeros_(self.mod.bias)

    def forward(self, h: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        gamma, beta = self.mod(c).reshape(c.shape[0], 1, 1, 1, 2, -1).unbind(-2)
        return self.norm(h) * (1 + gamma) + beta


class Block(nn.Module):
    """Skeleton graph, bipartite graph, temporal efficient attention, feed-forward; each
    a pre-norm residual sub-layer on (B, 2, T, J, d) tokens."""

    def __init__(self, d: int, heads: int, ffn_mult: int, parents: Sequence[int]) -> None:
        super().__init__()
        self.norms = nn.ModuleList(AdaNorm(d) for _ in range(4))
        self.graph = SkeletonGraphConv(d, parents)
        self.bipartite = BipartiteGraph(d, heads, len(parents))
        self.temporal = EfficientAttention(d, heads)
        self.ffn = nn.Sequential(nn.Linear(d, ffn_mult * d), nn.GELU(),
                                 nn.Linear(ffn_mult * d, d))

    def forward(self, h: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        h = h + self.graph(self.norms[0](h, c))
        h = h + self.bipartite(self.norms[1](h, c))
        # (B, 2, T, J, d) -> (B, 2, J, T, d): attend over the frames of each joint
        tmp = self.temporal(self.norms[2](h, c).transpose(2, 3)).transpose(2, 3)
        h = h + tmp
        return h + self.ffn(self.norms[3](h, c))


class Denoiser(nn.Module):
    """ε_θ(x_k, k, label): (B, 2, T, J, 3) standardised noisy pair, (B,) 0-based steps,
    (B,) labels (``num_labels`` is the null label) -> (B, 2, T, J, 3) predicted noise."""

    def __init__(self, config: BiGraphDiffConfig, num_labels: int, window: int,
                 parents: Sequence[int]) -> None:
        super().__init__()
        d = config.d_model
        self.d = d
        joints = len(parents)
        self.inp = nn.Linear(3, d)
        self.person = nn.Parameter(torch.randn(2, d) * 0.02)
        self.joint = nn.Parameter(torch.randn(joints, d) * 0.02)
        self.register_buffer("frame_pe", sinusoidal(torch.arange(window), d),
                             persistent=False)
        self.step_mlp = nn.Sequential(nn.Linear(d, d), nn.SiLU(), nn.Linear(d, d))
        self.label = nn.Embedding(num_labels + 1, d)
        self.blocks = nn.ModuleList(Block(d, config.heads, config.ffn_mult, parents)
                                    for _ in range(config.blocks))
        self.out_norm = AdaNorm(d)
        self.out = nn.Linear(d, 3)
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)

    def forward(self, x: torch.Tensor, k: torch.Tensor, label: torch.Tensor) -> torch.Tensor:
        h = (self.inp(x) + self.person[None, :, None, None] + self.joint
             + self.frame_pe[:, None])
        c = self.step_mlp(sinusoidal(k, self.d)) + self.label(label)
        for block in self.blocks:
            h = block(h, c)
        return self.out(self.out_norm(h, c))


# -- model ---------------------------------------------------------------------------------


def _mirror(x: np.ndarray) -> np.ndarray:
    """Left/right mirror of (..., J, 3) actor-frame positions on the 18-joint layout."""
    names = list(idata.INTER18_JOINTS)
    swap = [names.index(n.replace("left_", "right_") if n.startswith("left_")
                        else n.replace("right_", "left_")) for n in names]
    return x[..., swap, :] * np.array([1.0, -1.0, 1.0], dtype=x.dtype)


class BiGraphDiff(CheckpointMixin):
    """A trained BiGraphDiff: :meth:`sample` both people's windows from class labels.

    Attributes:
        name: registry name ``"bigraphdiff"``.
        config: hyperparameters. labels: the classes it was trained on (label ids of
            :meth:`sample` index this tuple). window: frames per window (40).
        mean, std: (2, J, 3) float32 standardisation of (actor, reactor) positions, m.
        schedule: the training :class:`DiffusionSchedule`. denoiser: ε_θ.
    """

    name = "bigraphdiff"

    def __init__(self, config: BiGraphDiffConfig, labels: Sequence[str], mean: np.ndarray,
                 std: np.ndarray, window: int = idata.WINDOW_FRAMES) -> None:
        self.config = config
        self.labels = tuple(labels)
        self.window = int(window)
        self.mean = np.asarray(mean, dtype=np.float32)
        self.std = np.asarray(std, dtype=np.float32)
        self.parents = idata.inter18_skeleton().parents
        self.schedule = DiffusionSchedule.linear(config.diffusion_steps, config.beta_start,
                                                 config.beta_end)
        self.denoiser = Denoiser(config, len(self.labels), self.window, self.parents)
        self.metadata: dict[str, Any] = {}

    @property
    def null_label(self) -> int:
        """Label id of the unconditional (classifier-free guidance) branch."""
        return len(self.labels)

    def standardise(self, actor: np.ndarray, reactor: np.ndarray) -> np.ndarray:
        """(N, T, J, 3) actor and reactor, metres -> (N, 2, T, J, 3) standardised float32."""
        x = np.stack([actor, reactor], axis=1)
        return ((x - self.mean[:, None]) / self.std[:, None]).astype(np.float32)

    def unstandardise(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 2, T, J, 3) standardised -> actor, reactor (N, T, J, 3) float32 metres."""
        m = (np.asarray(x) * self.std[:, None] + self.mean[:, None]).astype(np.float32)
        return m[:, 0], m[:, 1]

    def label_ids(self, labels: Sequence[str] | np.ndarray) -> np.ndarray:
        """(N,) int64 ids of class names or of ids into :attr:`labels`.

        Raises:
            SimenvError: an unknown name or an id out of range (the message lists the
                known labels), or an empty list.
        """
        arr = np.asarray(labels)
        known = ", ".join(f"{i}={n}" for i, n in enumerate(self.labels))
        if arr.ndim != 1 or arr.size == 0:
            raise SimenvError(f"labels must be a non-empty 1-d sequence; got shape "
                              f"{arr.shape}; known labels: {known}", field="labels")
        if np.issubdtype(arr.dtype, np.integer):
            bad = [int(v) for v in arr if not 0 <= v < len(self.labels)]
            if bad:
                raise SimenvError(f"label id(s) {bad} out of range; known labels: {known}",
                                  field="labels")
            return arr.astype(np.int64)
        unknown = sorted({str(v) for v in arr if str(v) not in self.labels})
        if unknown:
            raise SimenvError(f"unknown label(s) {', '.join(map(repr, unknown))}; this "
                              f"model knows: {known}", field="labels")
        return np.array([self.labels.index(str(v)) for v in arr], dtype=np.int64)

    def _eps(self, x: torch.Tensor, k: int, y: torch.Tensor, w: float) -> torch.Tensor:
        kk = torch.full((len(x),), k, dtype=torch.long)
        eps = self.denoiser(x, kk, y)
        if w == 1.0:
            return eps
        eps_null = self.denoiser(x, kk, torch.full_like(y, self.null_label))
        return eps_null + w * (eps - eps_null)

    @torch.no_grad()
    def sample(self, labels: Sequence[str] | np.ndarray, *, seed: int = 0,
               steps: int | None = None, guidance: float | None = None,
               batch_size: int = 64) -> tuple[np.ndarray, np.ndarray]:
        """Generate one interaction per label.

        Args:
            labels: (N,) class names of :attr:`labels`, or int ids into it.
            seed: seeds all sampling noise (same seed, same output).
            steps: sampling steps (None: all ``diffusion_steps``; fewer: respaced).
            guidance: classifier-free guidance scale w (None: ``config.guidance_scale``).
            batch_size: windows per network pass.

        Returns:
            ``(actor, reactor)``, each (N, T, J, 3) float32, metres, actor frame.

        Raises:
            SimenvError: unknown labels or a bad number of steps.
        """
        y_all = self.label_ids(labels)
        schedule, tau = ((self.schedule, np.arange(len(self.schedule))) if steps is None
                         else self.schedule.respaced(steps))
        w = float(self.config.guidance_scale if guidance is None else guidance)
        gen = torch.Generator().manual_seed(int(seed))
        self.denoiser.eval()
        shape = (2, self.window, len(self.parents), 3)
        out = []
        for start in range(0, len(y_all), batch_size):
            y = torch.as_tensor(y_all[start:start + batch_size])
            x = torch.randn((len(y), *shape), generator=gen)
            for i in range(len(tau) - 1, -1, -1):
                eps = self._eps(x, int(tau[i]), y, w)
                ab = schedule.alpha_bar[i]
                x0 = ((x - math.sqrt(1 - ab) * eps) / math.sqrt(ab)).clamp(
                    -self.config.x0_clip, self.config.x0_clip)
                x = schedule.coef_x0[i] * x0 + schedule.coef_xt[i] * x
                if i > 0:
                    x = x + math.sqrt(schedule.posterior_variance[i]) * torch.randn(
                        x.shape, generator=gen)
            out.append(x.numpy())
        return self.unstandardise(np.concatenate(out))

    def denoising_loss(self, windows: idata.InteractionWindows, *, seed: int = 0,
                       draws: int = 4) -> float:
        """Mean ``||ε - ε_θ||²`` per coordinate over ``draws`` seeded (step, noise)
        draws per window of ``windows`` (labels must be known to the model); a
        deterministic score of the training objective."""
        x0 = torch.as_tensor(self.standardise(windows.actor, windows.reactor))
        y = torch.as_tensor(self.label_ids(np.asarray(windows.labels)[windows.label]))
        gen = torch.Generator().manual_seed(int(seed))
        self.denoiser.eval()
        total = 0.0
        with torch.no_grad():
            for _ in range(draws):
                k = torch.randint(0, len(self.schedule), (len(x0),), generator=gen)
                noise = torch.randn(x0.shape, generator=gen)
                pred = self.denoiser(self.schedule.q_sample(x0, k, noise), k, y)
                total += float(((pred - noise) ** 2).mean())
        return total / draws

    # -- checkpoints ------------------------------------------------------------------------

    CHECKPOINT_FORMAT = CHECKPOINT_FORMAT

    def checkpoint_nets(self) -> dict[str, nn.Module]:
        return {"denoiser": self.denoiser}

    def checkpoint_arrays(self) -> dict[str, np.ndarray]:
        """Labels (JSON), window and the standardisation."""
        return {"labels": np.array(json.dumps(list(self.labels))),
                "window": np.array(self.window), "mean": self.mean, "std": self.std}

    @classmethod
    def from_checkpoint(cls, checkpoint: Checkpoint) -> BiGraphDiff:
        a = checkpoint.arrays
        return cls(BiGraphDiffConfig(**checkpoint.config), json.loads(str(a["labels"])),
                   a["mean"], a["std"], int(a["window"]))


# -- training ------------------------------------------------------------------------------


def bone_loss(x0_hat: torch.Tensor, x0: torch.Tensor, alpha_bar: torch.Tensor,
              scale: torch.Tensor, parents: Sequence[int]) -> torch.Tensor:
    """ᾱ-weighted bone-length error of the denoiser's clean estimate, metres.

    ``x̂_0 = (x_k - √(1-ᾱ_k) ε̂) / √ᾱ_k`` amplifies ε̂'s error by ``1/√ᾱ_k`` at noisy steps,
    so each window's term is weighted by ``ᾱ_k``:
    ``L_b = mean_n ᾱ_{k_n} mean_{p,t,j} | ||x̂_j - x̂_{π(j)}|| - ||x_j - x_{π(j)}|| |`` over
    the non-root joints ``j`` (parent ``π(j)``) of both people, positions in metres
    (standardised coordinates times ``scale``, the per-coordinate std; the mean cancels
    in bone vectors).

    Args:
        x0_hat, x0: (B, 2, T, J, 3) standardised estimates and targets.
        alpha_bar: (B,) ᾱ of each window's step. scale: (2, J, 3) std, metres.
        parents: (J,) parent indices, -1 for the root.
    """
    child = [j for j, par in enumerate(parents) if par >= 0]
    parent = [parents[j] for j in child]
    s = scale[:, None]

    def lengths(x: torch.Tensor) -> torch.Tensor:
        return (x[..., child, :] - x[..., parent, :]).norm(dim=-1)

    per_window = (lengths(x0_hat * s) - lengths(x0 * s)).abs().mean(dim=(1, 2, 3))
    return (alpha_bar * per_window).mean()


def fit_standardisation(actor: np.ndarray, reactor: np.ndarray, std_floor: float
                        ) -> tuple[np.ndarray, np.ndarray]:
    """(2, J, 3) mean and floored std per (person, joint, coordinate) over windows and
    frames of (N, T, J, 3) actor and reactor positions, metres."""
    x = np.stack([actor, reactor], axis=1).astype(np.float64)
    mean = x.mean(axis=(0, 2))
    std = np.maximum(x.std(axis=(0, 2)), std_floor)
    return mean.astype(np.float32), std.astype(np.float32)


def train(train: idata.InteractionWindows, config: BiGraphDiffConfig | None = None, *,
          seed: int = 0, progress: bool = True) -> tuple[BiGraphDiff, dict[str, Any]]:
    """Train BiGraphDiff on two-person windows (CPU, seeded).

    Args:
        train: training windows (actor frame, metres); the model's classes are the
            labels present in them.
        config: hyperparameters (default :class:`BiGraphDiffConfig`).
        seed: seeds initialisation, batching, steps and noise.
        progress: show a tqdm bar.

    Returns:
        ``(model, history)``: model holding the EMA weights, in eval mode; history with
        ``"loss"`` (per-epoch mean ε MSE of the online network, per coordinate, on the
        standardised data), ``"eps_mse"`` (the same), ``"cpu_seconds"``, ``"steps"``,
        ``"epochs_run"``, ``"stopped_early"``, ``"windows"``.

    Raises:
        MotionError: fewer than 2 windows, or windows not on the 18-joint layout.
    """
    config = config or BiGraphDiffConfig()
    if len(train) < 2:
        raise MotionError(f"need at least 2 training windows; got {len(train)}",
                          field="train")
    if tuple(train.joint_names) != idata.INTER18_JOINTS:
        raise MotionError("training windows must be on the 18-joint layout "
                          "(interaction_data.INTER18_JOINTS)", field="joint_names")
    rng = seeded(seed)
    labels, actor, reactor, y = _training_set(train, config.mirror)
    mean, std = fit_standardisation(actor, reactor, config.std_floor)
    model = BiGraphDiff(config, labels, mean, std, train.window)
    x0_all = torch.as_tensor(model.standardise(actor, reactor))
    y_all = torch.as_tensor(y)
    online = model.denoiser
    ema = Denoiser(config, len(labels), train.window, model.parents)
    ema.load_state_dict(online.state_dict())
    ema.requires_grad_(False)
    optimizer = torch.optim.AdamW(online.parameters(), lr=config.lr,
                                  weight_decay=config.weight_decay)
    per_epoch = math.ceil(len(x0_all) / config.batch_size)
    scheduler = cosine_schedule(optimizer, per_epoch * config.epochs,
                                warmup_steps=config.warmup_steps)
    gen = torch.Generator().manual_seed(seed)
    history: dict[str, Any] = {"loss": [], "eps_mse": [], "stopped_early": False,
                               "windows": len(x0_all)}
    steps = 0
    budget = CpuBudget(config.max_cpu_minutes)
    online.train()
    bar = tqdm(range(config.epochs), desc="train bigraphdiff", disable=not progress)
    for _ in bar:
        order = torch.as_tensor(rng.permutation(len(x0_all)))
        losses, eps_losses = [], []
        for b in range(per_epoch):
            idx = order[b * config.batch_size:(b + 1) * config.batch_size]
            loss, eps_mse = denoising_loss(model, online, x0_all[idx], y_all[idx], gen)
            optimizer.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(online.parameters(), config.grad_clip)
            optimizer.step()
            scheduler.step()
            with torch.no_grad():
                for pe, po in zip(ema.parameters(), online.parameters(), strict=True):
                    pe.lerp_(po, 1.0 - config.ema_decay)
            losses.append(loss.item())
            eps_losses.append(eps_mse.item())
            steps += 1
        history["loss"].append(round(float(np.mean(losses)), 5))
        history["eps_mse"].append(round(float(np.mean(eps_losses)), 5))
        bar.set_postfix(loss=history["loss"][-1])
        if budget.exceeded():
            history["stopped_early"] = True
            break
    history["steps"] = steps
    history["epochs_run"] = len(history["loss"])
    history["cpu_seconds"] = round(budget.seconds(), 1)
    model.denoiser = ema.eval()
    return model, history


def _training_set(train: idata.InteractionWindows, mirror: bool
                  ) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, np.ndarray]:
    """The classes present in ``train`` and its (N, T, J, 3) actor and reactor windows
    with their (N,) class indices, doubled by their mirror images when ``mirror``."""
    present = sorted(set(train.label.tolist()))
    labels = tuple(train.labels[i] for i in present)
    actor, reactor = train.actor, train.reactor
    y = np.array([labels.index(train.labels[i]) for i in train.label], dtype=np.int64)
    if mirror:
        actor, reactor = np.concatenate([actor, _mirror(actor)]), np.concatenate(
            [reactor, _mirror(reactor)])
        y = np.concatenate([y, y])
    return labels, actor, reactor, y


def denoising_loss(model: BiGraphDiff, denoiser: Denoiser, x0: torch.Tensor,
                   labels: torch.Tensor, gen: torch.Generator
                   ) -> tuple[torch.Tensor, torch.Tensor]:
    """Training loss of ``denoiser`` on a batch: the label dropped to the null label with
    probability ``label_dropout``, a random step k and noise ε, then the ε MSE plus, with
    ``bone_weight`` > 0, λ_b times :func:`bone_loss` of the implied x̂_0.

    Args:
        model: the model (schedule, config, standardisation, parents).
        denoiser: the network being trained (the model's online denoiser).
        x0: (B, 2, T, J, 3) standardised windows. labels: (B,) class indices.
        gen: generator of the dropout, steps and noise.

    Returns:
        (loss, ε MSE), scalars.
    """
    config = model.config
    yb = labels.clone()
    drop = torch.rand(len(yb), generator=gen) < config.label_dropout
    yb[drop] = model.null_label
    k = torch.randint(0, config.diffusion_steps, (len(x0),), generator=gen)
    noise = torch.randn(x0.shape, generator=gen)
    xk = model.schedule.q_sample(x0, k, noise)
    eps = denoiser(xk, k, yb)
    eps_mse = ((eps - noise) ** 2).mean()
    if config.bone_weight <= 0:
        return eps_mse, eps_mse
    ab = torch.as_tensor(model.schedule.alpha_bar, dtype=torch.float32)[k]
    shape = (-1,) + (1,) * (x0.ndim - 1)
    x0_hat = (xk - (1 - ab).sqrt().reshape(shape) * eps) / ab.sqrt().reshape(shape)
    scale = torch.as_tensor(model.std, dtype=torch.float32)
    bone = bone_loss(x0_hat, x0, ab, scale, model.parents)
    return eps_mse + config.bone_weight * bone, eps_mse

"""Gesture classifier: a spatio-temporal transformer with the skeleton-adjacency mask.

The recognition network of the thesis's virtual-agent application (Chopin 2023, ch. 5;
the spatial/temporal attention of InterFormer), on the windows of
:mod:`simenv.data.gestures` (T = 75 frames at 25 fps, J gesture joints, normalised).

Math
----
Input ``x`` (B, T, J, 3) and a validity mask ``m`` (B, T) (False on padded frames).
Each joint of each frame is a token with features ``[x_tj, 25 (x_tj - x_{t-1,j})]``
(position and velocity in m/s; velocity 0 at the first frame), embedded as

    h⁰_tj = W f_tj + e_j + PE(t)

(learned joint embedding ``e_j``, sinusoidal time encoding ``PE``). Then L pre-norm blocks:

* **spatial attention**, within each frame over the J joints, restricted by the
  adjacency mask ``M = I + A_in + A_out > 0``: ``A_in[i, j] = 1`` when ``i`` is the
  parent of ``j`` (the path inward, child -> parent: the parent attends to its
  children) and ``A_out = A_inᵀ`` (outward, parent -> child: a child attends to its
  parent). Attention weights are
  ``softmax_j(q_i·k_j / sqrt(d_h) + log M_ij)``, i.e. exactly 0 on non-adjacent pairs;
* **temporal attention**, per joint over the T frames, with padded frames masked out as
  keys (``softmax_s(q_t·k_s / sqrt(d_h) + log m_s)``);
* a two-layer GELU feed-forward network.

Each sub-layer is ``h <- h + Sublayer(LayerNorm(h))``. The final tokens are averaged over
joints and valid frames, and an MLP head maps the pooled vector ``z`` to logits:
``φ = GELU(W_1 LN(z) + b_1)`` (the penultimate features, :meth:`features`, used by
FID/FVD elsewhere) and ``logits = W_2 φ + b_2``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from torch import nn

from simenv.core.errors import MotionError
from simenv.data.gestures import normalise_windows
from simenv.models.checkpoint import Checkpoint, CheckpointError, CheckpointMixin

CHECKPOINT_FORMAT = "simenv-gesture-classifier"
CHECKPOINT_VERSION = 2


def adjacency_matrices(parents: Sequence[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Identity, inward and outward adjacency of a skeleton tree.

    Args:
        parents: (J,) parent index of each joint, -1 for a root.

    Returns:
        ``(I, A_in, A_out)``, each (J, J) float32: ``A_in[p, c] = 1`` for every bone
        (parent ``p``, child ``c``) and ``A_out = A_inᵀ``.
    """
    n = len(parents)
    inward = np.zeros((n, n), np.float32)
    for child, parent in enumerate(parents):
        if parent >= 0:
            inward[parent, child] = 1.0
    return np.eye(n, dtype=np.float32), inward, inward.T.copy()


def adjacency_mask(parents: Sequence[int]) -> torch.Tensor:
    """(J, J) bool spatial attention mask ``I + A_in + A_out > 0`` (True = may attend)."""
    eye, inward, outward = adjacency_matrices(parents)
    return torch.from_numpy((eye + inward + outward) > 0)


class MaskedAttention(nn.Module):
    """Multi-head self-attention with an optional pair mask and key-validity mask.

    ``Attn(X) = concat_h softmax(Q_h K_hᵀ / sqrt(d_h) + B) V_h W_o`` with ``B = 0`` on
    allowed (query, key) pairs and ``-inf`` elsewhere, so masked pairs get weight 0.
    """

    def __init__(self, dim: int, heads: int) -> None:
        super().__init__()
        if dim % heads:
            raise ValueError(f"dim {dim} is not divisible by heads {heads}")
        self.heads = heads
        self.qkv = nn.Linear(dim, 3 * dim)
        self.out = nn.Linear(dim, dim)

    def forward(self, x: torch.Tensor, allowed: torch.Tensor | None = None,
                key_valid: torch.Tensor | None = None, return_weights: bool = False
                ) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
        """Args: ``x`` (N, L, D); ``allowed`` (L, L) bool; ``key_valid`` (N, L) bool.
        Returns (N, L, D), and the (N, H, L, L) weights if ``return_weights``."""
        n, length, dim = x.shape
        q, k, v = (self.qkv(x).view(n, length, 3, self.heads, dim // self.heads)
                   .permute(2, 0, 3, 1, 4))
        mask = None
        if allowed is not None:
            mask = allowed[None, None]
        if key_valid is not None:
            kv = key_valid[:, None, None, :]
            mask = kv if mask is None else mask & kv
        if return_weights:
            scores = q @ k.transpose(-1, -2) / math.sqrt(dim // self.heads)
            if mask is not None:
                scores = scores.masked_fill(~mask, float("-inf"))
            weights = torch.softmax(scores, dim=-1)
            att = weights @ v
        else:
            # Same computation, fused (much faster on CPU); tests check both agree.
            att = nn.functional.scaled_dot_product_attention(q, k, v, attn_mask=mask)
        out = self.out(att.transpose(1, 2).reshape(n, length, dim))
        return (out, weights) if return_weights else out


class SpatioTemporalBlock(nn.Module):
    """Spatial (adjacency-masked) attention, temporal attention and a feed-forward
    network, each pre-norm with a residual connection (see the module docstring)."""

    def __init__(self, dim: int, heads: int, ffn: int) -> None:
        super().__init__()
        self.norm_s, self.norm_t, self.norm_f = nn.LayerNorm(dim), nn.LayerNorm(dim), \
            nn.LayerNorm(dim)
        self.spatial = MaskedAttention(dim, heads)
        self.temporal = MaskedAttention(dim, heads)
        self.ffn = nn.Sequential(nn.Linear(dim, ffn), nn.GELU(), nn.Linear(ffn, dim))

    def forward(self, h: torch.Tensor, adjacency: torch.Tensor, valid: torch.Tensor
                ) -> torch.Tensor:
        """``h`` (B, T, J, D), ``adjacency`` (J, J) bool, ``valid`` (B, T) bool."""
        b, t, j, d = h.shape
        s = self.spatial(self.norm_s(h).reshape(b * t, j, d), allowed=adjacency)
        h = h + s.view(b, t, j, d)
        ht = self.norm_t(h).transpose(1, 2).reshape(b * j, t, d)
        kv = valid[:, None, :].expand(b, j, t).reshape(b * j, t)
        h = h + self.temporal(ht, key_valid=kv).view(b, j, t, d).transpose(1, 2)
        return h + self.ffn(self.norm_f(h))


@dataclass
class SkeletonClasses:
    """The data contract of a skeleton classifier's config: input joints and classes.

    Attributes:
        joint_names: (J,) joint names of the input (e.g. a :mod:`simenv.data.gestures`
            joint set).
        parents: (J,) parent index of each joint (-1: a root).
        labels: class names, index = class id.

    Raises:
        ValueError: ``joint_names`` and ``parents`` of different lengths.
    """

    joint_names: tuple[str, ...]
    parents: tuple[int, ...]
    labels: tuple[str, ...]

    def __post_init__(self) -> None:
        self.joint_names = tuple(self.joint_names)
        self.parents = tuple(int(p) for p in self.parents)
        self.labels = tuple(self.labels)
        if len(self.joint_names) != len(self.parents):
            raise ValueError("joint_names and parents differ in length")


@dataclass
class ClassifierConfig(SkeletonClasses):
    """Architecture and data contract (:class:`SkeletonClasses`; the parents define the
    adjacency mask) of a :class:`GestureClassifier`.

    Attributes:
        window: frames per window (T).
        fps: frame rate of the windows, frames/s.
        dim, heads, layers, ffn: transformer width, heads, blocks, feed-forward width.
        feature_dim: width of the penultimate features.
        dropout: dropout probability before the last layer, in training. (None inside
            the blocks: on CPU it costs more than it regularises here.)
    """

    window: int = 75
    fps: float = 25.0
    dim: int = 64
    heads: int = 4
    layers: int = 3
    ffn: int = 128
    feature_dim: int = 128
    dropout: float = 0.1
    extra: dict[str, Any] = field(default_factory=dict)


def valid_mask(x: torch.Tensor, valid: torch.Tensor | None) -> torch.Tensor:
    """(B, T) bool mask of the real frames of windows ``x`` (B, T, ...): ``valid`` checked,
    or all frames when None.

    Raises:
        MotionError: ``valid`` of another shape, or a window without a valid frame.
    """
    if valid is None:
        return torch.ones(x.shape[:2], dtype=torch.bool, device=x.device)
    if valid.shape != x.shape[:2]:
        raise MotionError(f"valid must have shape {tuple(x.shape[:2])}; got "
                          f"{tuple(valid.shape)}", field="valid")
    valid = valid.bool()
    if not bool(valid.any(dim=1).all()):
        raise MotionError("every window needs at least one valid frame", field="valid")
    return valid


def time_encoding(length: int, dim: int) -> torch.Tensor:
    """(length, dim) sinusoidal encoding ``PE(t, 2i) = sin(t / 10000^(2i/dim))``,
    ``PE(t, 2i+1) = cos(...)``."""
    pos = torch.arange(length, dtype=torch.float32)[:, None]
    freq = torch.exp(torch.arange(0, dim, 2, dtype=torch.float32) * (-math.log(1e4) / dim))
    pe = torch.zeros(length, dim)
    pe[:, 0::2] = torch.sin(pos * freq)
    pe[:, 1::2] = torch.cos(pos * freq)
    return pe


class GestureClassifier(CheckpointMixin, nn.Module):
    """Transformer gesture classifier (math in the module docstring).

    ``forward(x, valid) -> logits`` with ``x`` (B, T, J, 3) normalised windows and
    ``valid`` (B, T) bool; ``features(x, valid) -> (B, feature_dim)``.
    """

    def __init__(self, config: ClassifierConfig) -> None:
        super().__init__()
        self.config = config
        self.metadata: dict[str, Any] = {}
        c = config
        joints = len(c.joint_names)
        self.register_buffer("adjacency", adjacency_mask(c.parents), persistent=False)
        self.register_buffer("time_pe", time_encoding(c.window, c.dim), persistent=False)
        self.embed = nn.Linear(6, c.dim)
        self.joint_embed = nn.Parameter(torch.randn(joints, c.dim) * 0.02)
        self.blocks = nn.ModuleList(SpatioTemporalBlock(c.dim, c.heads, c.ffn)
                                    for _ in range(c.layers))
        self.norm = nn.LayerNorm(c.dim)
        self.head_norm = nn.LayerNorm(c.dim)
        self.hidden = nn.Linear(c.dim, c.feature_dim)
        self.head_drop = nn.Dropout(c.dropout)
        self.classify = nn.Linear(c.feature_dim, len(c.labels))

    def _check(self, x: torch.Tensor, valid: torch.Tensor | None) -> torch.Tensor:
        c = self.config
        if x.ndim != 4 or x.shape[1:] != (c.window, len(c.joint_names), 3):
            raise MotionError(
                f"classifier input must have shape (B, {c.window}, {len(c.joint_names)}, 3) "
                f"(frames at {c.fps:g} fps, joints {', '.join(c.joint_names)}); "
                f"got {tuple(x.shape)}", field="x")
        return valid_mask(x, valid)

    def pooled(self, x: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
        """(B, dim) tokens averaged over joints and valid frames."""
        valid = self._check(x, valid)
        # Frames after the batch's last valid frame are neither keys nor pooled, so
        # dropping them is exact (and saves work on padded short clips).
        last = int(torch.nonzero(valid.any(dim=0)).max()) + 1
        x, valid = x[:, :last], valid[:, :last]
        vel = torch.zeros_like(x)
        vel[:, 1:] = (x[:, 1:] - x[:, :-1]) * self.config.fps
        h = self.embed(torch.cat([x, vel], dim=-1)) + self.joint_embed + self.time_pe[:last, None]
        for block in self.blocks:
            h = block(h, self.adjacency, valid)
        h = self.norm(h).mean(dim=2)  # (B, T, D)
        w = valid.to(h.dtype)[..., None]
        return (h * w).sum(dim=1) / w.sum(dim=1)

    def features(self, x: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
        """(B, feature_dim) penultimate features (FID/FVD embeddings)."""
        return nn.functional.gelu(self.hidden(self.head_norm(self.pooled(x, valid))))

    def forward(self, x: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
        """(B, C) class logits."""
        return self.classify(self.head_drop(self.features(x, valid)))

    # -- numpy convenience --------------------------------------------------------------

    @torch.no_grad()
    def predict_proba(self, x: np.ndarray, valid: np.ndarray | None = None,
                      batch_size: int = 256) -> np.ndarray:
        """(N, C) class probabilities of *normalised* windows (N, T, J, 3)."""
        self.eval()
        xt = torch.as_tensor(np.asarray(x, np.float32))
        vt = None if valid is None else torch.as_tensor(np.asarray(valid, bool))
        out = [torch.softmax(self(xt[i:i + batch_size],
                                  None if vt is None else vt[i:i + batch_size]), dim=-1)
               for i in range(0, len(xt), batch_size)]
        return torch.cat(out).numpy()

    def classify_world(self, windows: np.ndarray, valid: np.ndarray | None = None
                       ) -> np.ndarray:
        """Class probabilities of raw world-frame windows, metres, Z up, at ``fps``:
        (N, T, J, 3) or (T, J, 3) on ``config.joint_names``; normalised here with
        :func:`simenv.data.gestures.normalise_windows`. Returns (N, C) or (C,)."""
        single = np.ndim(windows) == 3
        x = normalise_windows(windows, valid, joints=self.config.joint_names)
        if single:
            x = x[None]
            valid = None if valid is None else np.asarray(valid)[None]
        p = self.predict_proba(x, valid)
        return p[0] if single else p

    # -- checkpoints --------------------------------------------------------------------

    CHECKPOINT_FORMAT = CHECKPOINT_FORMAT

    def checkpoint_nets(self) -> dict[str, nn.Module]:
        return {"weights": self}

    def checkpoint_arrays(self) -> dict[str, np.ndarray]:
        return {"version": np.array(CHECKPOINT_VERSION)}

    @classmethod
    def from_checkpoint(cls, checkpoint: Checkpoint) -> GestureClassifier:
        """Raises :class:`CheckpointError` (field ``version``) for another version."""
        stored = checkpoint.arrays.get("version")
        version = None if stored is None else int(stored)
        if version != CHECKPOINT_VERSION:
            raise CheckpointError(f"checkpoint version {version!r}; this simenv reads "
                                  f"version {CHECKPOINT_VERSION}", source=checkpoint.path,
                                  field="version")
        return cls(ClassifierConfig(**checkpoint.config))

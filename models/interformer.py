"""InterFormer: reaction synthesis with a spatio-temporal encoder-decoder transformer.

Chopin et al., "Interaction Transformer for Human Reaction Generation" (IEEE TMM 2023):
the actor's window ``a`` (T, J, 3) is translated into the reactor's window ``x``
(T, J, 3), generated autoregressively from the reactor's given first frame ``x_0``.
Joints are :data:`~simenv.data.interaction_data.INTER18_JOINTS`, positions in metres in the
actor frame of :mod:`simenv.data.interaction_data` (actor pelvis on the floor at the origin,
facing +x, Z up) at 25 fps.

Math
----
**Tokens.** Every joint of every frame is a token. A person's frame ``t`` gives features
``f_tj = [p_tj, fps (p_tj - p_{t-1,j})]`` (position, m, and velocity, m/s; 0 at the
window's first frame), embedded as ``h_tj = W f_tj + e_j + PE(t)`` (learned joint
embedding, sinusoidal time encoding). Actor and reactor have their own ``W`` and ``e``.

**Attention.** ``Attn(X, Y) = concat_h softmax(Q_h K_hᵀ / sqrt(d_h) + B) V_h W_o`` with
queries from ``X``, keys and values from ``Y`` and an additive logit bias ``B`` (``-inf``
where attention is forbidden). The sub-layers, each pre-norm with a residual
(``h <- h + Sublayer(LN(h))``):

* *spatial self-attention*, within one frame over the J joints of one person, with the
  skeleton-adjacency mask ``M = I + A_in + A_out > 0``
  (:func:`simenv.models.gesture_classifier.adjacency_mask`): ``B_ij = 0`` when ``M_ij``,
  else ``-inf``;
* *temporal self-attention*, per joint over the frames: full in the encoder, causal in the
  decoder (``B_ks = -inf`` for ``s > k``);
* *cross spatial attention* (decoder): the reactor's joints of decoder step ``k`` attend
  to all actor joints of frame ``k + 1`` (the frame being generated; the whole actor
  window is an input) with the **interaction-distance term**
  ``B_h,ij = γ_h · J² · softmax_(i,j)(-D_ij / σ)``, where
  ``D_ij = ||x_k,i - a_{k+1},j||`` (m) is the distance from reactor joint ``i`` to actor
  joint ``j``, the softmax runs over all ``J²`` pairs of the frame (as in the paper's code),
  ``σ`` = :attr:`InterFormerConfig.distance_sigma` and ``γ_h`` is a learned per-head
  scale (initialised to 1). ``J²`` makes the bias average 1 over the pairs, so it is of the
  order of the attention logits; nearby joint pairs get the largest bias;
* a two-layer GELU feed-forward network.

Encoder block: spatial, temporal, FFN. Decoder block: spatial, causal temporal, cross
spatial, FFN. The actor's other frames reach the decoder through the encoder's temporal
attention (every encoder token of frame ``k + 1`` has seen the whole actor window).

**Output.** The decoder's input at step ``k`` is the reactor frame ``x_k``; it predicts
the next frame as a displacement, ``x̂_{k+1} = x_k + Δ_k`` with
``Δ_k = 0.1 · W_out LN(h_k)`` (so an untrained output head is close to the zero-velocity
baseline, and the head works in decimetres).

**Loss** (positions in decimetres, ``LOSS_UNIT``):
``L = mean_{k,j} ||x̂_k,j - x_k,j||² + λ_v mean_j ||(x̂_2,j - x̂_1,j) - (x_2,j - x_1,j)||²``,
the sequence MSE over the generated frames 1..T-1 and the paper's first-frame velocity
loss (the velocity between the first two generated frames, as in the authors' code;
``λ_v`` = :attr:`InterFormerConfig.velocity_weight`).

**Training** uses teacher forcing: the decoder reads the true reactor frames
``x_0..x_{T-2}`` (plus Gaussian noise of :attr:`InterFormerConfig.input_noise` metres,
ours, see below) and predicts ``x_1..x_{T-1}`` in one pass. **Inference** is
autoregressive from the given ``x_0``: each generated frame is appended to the decoder's
input. A decoder step's tokens depend on earlier steps only through the causal temporal
attention, so generation decodes only the newest frame at each step
(:meth:`InterFormer.decode_steps`), keeping the earlier steps' temporal keys and values
per layer (:class:`DecoderCache`); the result equals re-decoding the whole sequence.
**Long generation** (T beyond the trained window W): the sequence is generated in
chunks of W frames; each new chunk starts ``chunk_context`` frames before the previous
chunk's end, is re-normalised in the actor frame of its own first frame
(:func:`~simenv.data.interaction_data.actor_frame`), takes those last generated frames as the
decoder's given prefix and generates the rest of the chunk autoregressively.

Paper vs ours
-------------
* Size: the authors' code defaults to 6 encoder + 6 decoder layers, 3 heads, batch 128,
  on GPU; ours is a small CPU configuration (d_model 64, 4 heads, 2 encoder + 2 decoder
  blocks, FFN 128, batch 16, 30 epochs; the defaults of :class:`InterFormerConfig`).
* Data: the paper trains on SBU, K3HI and DuetDance; ours on the real two-person windows
  of :mod:`simenv.data.interaction_data` (CMU pairs + NuiSI, 18 keypoints, 40-frame windows at
  25 fps, split by recording).
* Tokens: the authors' code uses the flattened pose itself (width 3J) as the token of a
  frame in temporal attention and splits it per joint in spatial attention; ours embeds
  every (frame, joint) token in d_model dimensions from its position and velocity and
  alternates spatial and temporal attention over those tokens (as our gesture
  classifier does).
* Interaction distance: the paper adds ``softmax(-D)`` over the J² pairs with D in its
  data's normalised units; ours divides by ``σ`` (metres) and multiplies by ``J²`` and a
  learned per-head ``γ_h`` (module math), because with D in metres the plain softmax is a
  near-constant ~1/J² and would have no effect. The paper computes D between the two
  people at the same frame; ours between the decoder's input reactor frame ``k`` (the last
  known one) and the actor frame ``k + 1`` being reacted to.
* Decoder cross attention: the paper's decoder attends to the encoded action both
  spatially and temporally; ours only spatially (per frame, with the distance term) and
  relies on the encoder's temporal attention to bring in the actor's other frames, to
  save CPU.
* Dropout: the paper 0.1; ours 0 by default (on CPU it costs ~10 % of a step).
* Output: the paper's decoder outputs the next pose; ours a displacement from the current
  input frame (module math).
* Loss units: the paper scales the MSE by 1e5 (its coordinates); ours measures in
  decimetres (a constant factor).
* Exposure bias: ours adds small Gaussian noise to the teacher-forced decoder inputs so
  that the model learns to correct its own small errors during autoregressive
  inference (the paper trains on clean inputs).
* Augmentation (ours): each training window is mirrored left/right with probability 1/2
  (``y -> -y`` in the actor frame and left/right joints swapped, for both people; the
  actor frame stays an actor frame). Rotations about Z are not used: every window is
  re-normalised in its actor's frame, so they would be undone.
* Chunked long generation re-normalises each chunk in its own actor frame (ours; the
  paper generates up to its maximum length).
* Optimiser: AdamW 1e-3 with a cosine learning-rate decay and gradient clipping (the
  authors' code: Adam 1e-4, betas (0.9, 0.98)), because our CPU budget allows only a few
  hundred steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from simenv.core.errors import MotionError
from simenv.data import interaction_data as idata
from simenv.models.checkpoint import CheckpointMixin
from simenv.models.gesture_classifier import adjacency_mask, time_encoding
from simenv.models.reaction_baselines import check_inputs, mirror_index
from simenv.models.training import CpuBudget, cosine_schedule, seeded

CHECKPOINT_FORMAT = "simenv-interformer-1"
#: Positions are multiplied by this inside the loss (metres -> decimetres).
LOSS_UNIT = 10.0
#: The output head predicts displacements in decimetres.
OUTPUT_SCALE = 0.1


@dataclass(frozen=True)
class InterFormerConfig:
    """Architecture, data contract and training of an :class:`InterFormer`.

    Attributes:
        window: trained window length W, frames (the positional encodings cover it).
        fps: frame rate, Hz (velocity features are in m/s).
        joint_names: (J,) joints; parents: (J,) parent indices (adjacency mask).
        d_model, heads, encoder_layers, decoder_layers, ffn: transformer sizes.
        dropout: dropout inside the attention outputs and the FFN, in training.
        distance_sigma: σ of the interaction-distance term, metres.
        velocity_weight: λ_v of the first-frame velocity loss.
        input_noise: std of the Gaussian noise on teacher-forced decoder inputs, metres.
        mirror: left/right mirror augmentation in training.
        epochs, batch_size, lr, weight_decay, grad_clip: optimisation (AdamW, cosine
            decay of ``lr`` to 5 % over all steps).
        chunk_context: generated frames carried into the next chunk in long generation
            (1 <= chunk_context < window).
    """

    window: int = idata.WINDOW_FRAMES
    fps: float = idata.TARGET_FPS
    joint_names: tuple[str, ...] = idata.INTER18_JOINTS
    parents: tuple[int, ...] = field(
        default_factory=lambda: tuple(int(p) for p in idata.inter18_skeleton().parents))
    d_model: int = 64
    heads: int = 4
    encoder_layers: int = 2
    decoder_layers: int = 2
    ffn: int = 128
    dropout: float = 0.0
    distance_sigma: float = 0.1
    velocity_weight: float = 1.0
    input_noise: float = 0.005
    mirror: bool = True
    epochs: int = 30
    batch_size: int = 16
    lr: float = 1e-3
    weight_decay: float = 1e-4
    grad_clip: float = 1.0
    chunk_context: int = 10

    def __post_init__(self) -> None:
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        object.__setattr__(self, "parents", tuple(int(p) for p in self.parents))
        if len(self.joint_names) != len(self.parents):
            raise MotionError(f"joint_names ({len(self.joint_names)}) and parents "
                              f"({len(self.parents)}) differ in length", field="parents")
        if int(self.window) != self.window or self.window < 3:
            raise MotionError(f"window must be an integer >= 3; got {self.window!r}",
                              field="window")
        if not 1 <= self.chunk_context < self.window:
            raise MotionError(f"chunk_context must be in [1, {self.window - 1}]; got "
                              f"{self.chunk_context!r}", field="chunk_context")
        if self.d_model % self.heads:
            raise MotionError(f"d_model {self.d_model} is not divisible by heads "
                              f"{self.heads}", field="heads")


def interaction_distance_bias(reactor: torch.Tensor, actor: torch.Tensor,
                              sigma: float) -> torch.Tensor:
    """The interaction-distance term before its per-head scale:
    ``J_r J_a · softmax_(i,j)(-||x_i - a_j|| / σ)`` over all joint pairs of each frame.

    Args:
        reactor: (..., J_r, 3) reactor joints, metres. actor: (..., J_a, 3), metres.
        sigma: distance scale, metres.

    Returns:
        (..., J_r, J_a) bias; it averages 1 over the pairs of a frame.
    """
    dist = torch.cdist(reactor, actor)
    shape = dist.shape
    flat = torch.softmax(-dist.flatten(-2) / sigma, dim=-1)
    return flat.view(shape) * (shape[-1] * shape[-2])


class Attention(nn.Module):
    """Multi-head attention with an additive logit bias:
    ``concat_h softmax(Q_h K_hᵀ / sqrt(d_h) + B) V_h W_o``."""

    def __init__(self, dim: int, heads: int, dropout: float) -> None:
        super().__init__()
        self.heads = heads
        self.q = nn.Linear(dim, dim)
        self.kv = nn.Linear(dim, 2 * dim)
        self.out = nn.Linear(dim, dim)
        self.drop = nn.Dropout(dropout)

    def forward(self, x: torch.Tensor, memory: torch.Tensor,
                bias: torch.Tensor | None = None) -> torch.Tensor:
        """``x`` (N, L, D) queries, ``memory`` (N, S, D) keys/values, ``bias``
        broadcastable to (N, H, L, S) (``-inf`` = forbidden). Returns (N, L, D)."""
        return self.attend(x, *self.keys_values(memory), bias)

    def keys_values(self, memory: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(N, S, D) memory -> per-head keys and values, each (N, H, S, D / H)."""
        n, length, dim = memory.shape
        k, v = (self.kv(memory).view(n, length, 2, self.heads, dim // self.heads)
                .permute(2, 0, 3, 1, 4))
        return k, v

    def attend(self, x: torch.Tensor, keys: torch.Tensor, values: torch.Tensor,
               bias: torch.Tensor | None = None) -> torch.Tensor:
        """``x`` (N, L, D) queries over ``keys``/``values`` (N, H, S, D / H) of
        :meth:`keys_values`; ``bias`` as in :meth:`forward`. Returns (N, L, D)."""
        n, length, dim = x.shape
        q = self.q(x).view(n, length, self.heads, dim // self.heads).transpose(1, 2)
        att = nn.functional.scaled_dot_product_attention(q, keys, values, attn_mask=bias)
        return self.drop(self.out(att.transpose(1, 2).reshape(n, length, dim)))


def _spatial(att: Attention, h: torch.Tensor, memory: torch.Tensor,
             bias: torch.Tensor | None) -> torch.Tensor:
    """Attention within each frame: (N, T, J, D) queries over (N, T, J', D) keys."""
    n, t, j, d = h.shape
    out = att(h.reshape(n * t, j, d), memory.reshape(n * t, memory.shape[2], d), bias)
    return out.view(n, t, j, d)


def _temporal(att: Attention, h: torch.Tensor, memory: torch.Tensor,
              bias: torch.Tensor | None) -> torch.Tensor:
    """Attention per joint over frames: (N, T, J, D) queries over (N, S, J, D) keys."""
    n, t, j, d = h.shape
    q = h.transpose(1, 2).reshape(n * j, t, d)
    kv = memory.transpose(1, 2).reshape(n * j, memory.shape[1], d)
    return att(q, kv, bias).view(n, j, t, d).transpose(1, 2)


class TemporalCache:
    """The keys and values of one decoder layer's causal temporal attention for the decoder
    steps computed so far, in a buffer of ``capacity`` steps filled step by step (a step's
    keys never change once computed: the decoder is causal and otherwise per frame)."""

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        self.steps = 0
        self._keys: torch.Tensor | None = None
        self._values: torch.Tensor | None = None

    def extend(self, keys: torch.Tensor, values: torch.Tensor
               ) -> tuple[torch.Tensor, torch.Tensor]:
        """Append the (N J, H, L, d_h) keys and values of L new steps; returns those of
        every step so far, each (N J, H, steps, d_h).

        Raises:
            MotionError: more steps than ``capacity``.
        """
        new = keys.shape[2]
        if self.steps + new > self.capacity:
            raise MotionError(f"decoder cache holds {self.capacity} steps; {self.steps} "
                              f"cached + {new} new", field="reactor_in")
        if self._keys is None or self._values is None:
            shape = (*keys.shape[:2], self.capacity, keys.shape[3])
            self._keys, self._values = keys.new_empty(shape), values.new_empty(shape)
        self._keys[:, :, self.steps:self.steps + new] = keys
        self._values[:, :, self.steps:self.steps + new] = values
        self.steps += new
        return self._keys[:, :, :self.steps], self._values[:, :, :self.steps]


class DecoderCache:
    """State of incremental decoding (:meth:`InterFormer.decode_steps`): the steps decoded
    so far, the last reactor input frame (N, J, 3) (metres, for the next step's velocity
    feature) and one :class:`TemporalCache` per decoder layer."""

    def __init__(self, layers: int, capacity: int) -> None:
        self.steps = 0
        self.last: torch.Tensor | None = None
        self.layers = [TemporalCache(capacity) for _ in range(layers)]


def _ffn(dim: int, hidden: int, dropout: float) -> nn.Sequential:
    return nn.Sequential(nn.Linear(dim, hidden), nn.GELU(), nn.Linear(hidden, dim),
                         nn.Dropout(dropout))


class EncoderBlock(nn.Module):
    """Spatial (adjacency-masked) and full temporal self-attention, then an FFN."""

    def __init__(self, dim: int, heads: int, ffn: int, dropout: float) -> None:
        super().__init__()
        self.norms = nn.ModuleList(nn.LayerNorm(dim) for _ in range(3))
        self.spatial = Attention(dim, heads, dropout)
        self.temporal = Attention(dim, heads, dropout)
        self.ffn = _ffn(dim, ffn, dropout)

    def forward(self, h: torch.Tensor, adjacency_bias: torch.Tensor) -> torch.Tensor:
        """``h`` (N, T, J, D); ``adjacency_bias`` (J, J) 0 / -inf."""
        x = self.norms[0](h)
        h = h + _spatial(self.spatial, x, x, adjacency_bias)
        x = self.norms[1](h)
        h = h + _temporal(self.temporal, x, x, None)
        return h + self.ffn(self.norms[2](h))


class DecoderBlock(nn.Module):
    """Spatial (adjacency-masked) and causal temporal self-attention, cross spatial
    attention with the interaction-distance term, FFN."""

    def __init__(self, dim: int, heads: int, ffn: int, dropout: float) -> None:
        super().__init__()
        self.norms = nn.ModuleList(nn.LayerNorm(dim) for _ in range(4))
        self.memory_norm = nn.LayerNorm(dim)
        self.spatial = Attention(dim, heads, dropout)
        self.temporal = Attention(dim, heads, dropout)
        self.cross_spatial = Attention(dim, heads, dropout)
        self.distance_scale = nn.Parameter(torch.ones(heads))
        self.ffn = _ffn(dim, ffn, dropout)

    def forward(self, h: torch.Tensor, memory: torch.Tensor, adjacency_bias: torch.Tensor,
                distance: torch.Tensor, cache: TemporalCache | None = None) -> torch.Tensor:
        """Decoder steps S..S+L-1.

        Args:
            h: (N, L, J, D) decoder tokens of the steps.
            memory: (N, L, J, D) encoder output of the actor frames S+1..S+L (step k
                reacts to actor frame k + 1).
            adjacency_bias: (J, J) 0 / -inf.
            distance: (N, L, J, J) the unscaled interaction-distance term of each step
                (reactor frame k, actor frame k + 1).
            cache: keys/values of steps 0..S-1, extended with the new steps' (S = 0 and
                nothing kept when None).

        Returns:
            (N, L, J, D) the steps' output tokens.
        """
        n, length, j, d = h.shape
        x = self.norms[0](h)
        h = h + _spatial(self.spatial, x, x, adjacency_bias)
        x = self.norms[1](h).transpose(1, 2).reshape(n * j, length, d)
        keys, values = self.temporal.keys_values(x)
        if cache is not None:
            keys, values = cache.extend(keys, values)
        steps = keys.shape[2]
        # Step S + i sees steps 0..S + i; one new step sees every cached one.
        causal = None if length == 1 else torch.full(
            (length, steps), float("-inf")).triu(steps - length + 1)
        h = h + (self.temporal.attend(x, keys, values, causal)
                 .view(n, j, length, d).transpose(1, 2))
        bias = (distance.reshape(n * length, 1, j, j)
                * self.distance_scale.view(1, -1, 1, 1))
        h = h + _spatial(self.cross_spatial, self.norms[2](h), self.memory_norm(memory),
                         bias)
        return h + self.ffn(self.norms[3](h))


def _features(p: torch.Tensor, fps: float, previous: torch.Tensor | None = None
              ) -> torch.Tensor:
    """(N, T, J, 3) positions -> (N, T, J, 6) ``[position, velocity]`` (m, m/s); the first
    frame's velocity is from ``previous`` (N, J, 3), the frame before, or 0 without it."""
    vel = torch.zeros_like(p)
    vel[:, 1:] = (p[:, 1:] - p[:, :-1]) * fps
    if previous is not None:
        vel[:, 0] = (p[:, 0] - previous) * fps
    return torch.cat([p, vel], dim=-1)


class InterFormer(CheckpointMixin, nn.Module):
    """Reaction generator (math in the module docstring); ``generate`` implements
    :class:`simenv.models.reaction_baselines.ReactionGenerator`."""

    name = "interformer"

    def __init__(self, config: InterFormerConfig | None = None) -> None:
        super().__init__()
        c = config or InterFormerConfig()
        self.config = c
        self.metadata: dict[str, Any] = {}
        joints = len(c.joint_names)
        adjacency = adjacency_mask(c.parents)
        self.register_buffer("adjacency_bias", torch.zeros(joints, joints).masked_fill(
            ~adjacency, float("-inf")), persistent=False)
        self.register_buffer("time_pe", time_encoding(c.window, c.d_model),
                             persistent=False)
        self.actor_embed = nn.Linear(6, c.d_model)
        self.reactor_embed = nn.Linear(6, c.d_model)
        self.actor_joints = nn.Parameter(torch.randn(joints, c.d_model) * 0.02)
        self.reactor_joints = nn.Parameter(torch.randn(joints, c.d_model) * 0.02)
        self.encoder = nn.ModuleList(EncoderBlock(c.d_model, c.heads, c.ffn, c.dropout)
                                     for _ in range(c.encoder_layers))
        self.decoder = nn.ModuleList(DecoderBlock(c.d_model, c.heads, c.ffn, c.dropout)
                                     for _ in range(c.decoder_layers))
        self.out_norm = nn.LayerNorm(c.d_model)
        self.head = nn.Linear(c.d_model, 3)
        self._swap = mirror_index(c.joint_names)

    # -- network ------------------------------------------------------------------------

    def encode(self, actor: torch.Tensor) -> torch.Tensor:
        """(N, T, J, 3) actor window (actor frame, m), T <= window -> (N, T, J, D)."""
        t = actor.shape[1]
        h = self.actor_embed(_features(actor, self.config.fps)) + self.actor_joints \
            + self.time_pe[:t, None]
        for block in self.encoder:
            h = block(h, self.adjacency_bias)
        return h

    def decode(self, reactor_in: torch.Tensor, memory: torch.Tensor,
               actor: torch.Tensor) -> torch.Tensor:
        """Next-frame predictions for every decoder step.

        Args:
            reactor_in: (N, L, J, 3) reactor frames 0..L-1 (actor frame, m).
            memory: (N, T, J, D) encoder output of the actor window, T >= L + 1.
            actor: (N, T, J, 3) the actor window (for the interaction distances).

        Returns:
            (N, L, J, 3) predicted reactor frames 1..L, metres.
        """
        return self.decode_steps(reactor_in, memory, actor)

    def decode_steps(self, reactor_in: torch.Tensor, memory: torch.Tensor,
                     actor: torch.Tensor, cache: DecoderCache | None = None
                     ) -> torch.Tensor:
        """Next-frame predictions of the decoder steps S..S+L-1 after the S steps that
        ``cache`` holds: equal to rows S..S+L-1 of :meth:`decode` of all L + S frames,
        computing only the new steps (their tokens depend on earlier steps only through
        the causal temporal attention, whose keys and values the cache keeps).

        Args:
            reactor_in: (N, L, J, 3) reactor frames S..S+L-1 (actor frame, m).
            memory: (N, T, J, D) encoder output of the actor window, T >= S + L + 1.
            actor: (N, T, J, 3) the actor window.
            cache: S = 0 without it; else extended with the new steps (from a fresh
                :class:`DecoderCache` for S = 0).

        Returns:
            (N, L, J, 3) predicted reactor frames S+1..S+L, metres.

        Raises:
            MotionError: the actor window ends before frame S + L.
        """
        start = 0 if cache is None else cache.steps
        stop = start + reactor_in.shape[1]
        if stop >= actor.shape[1] or stop >= memory.shape[1]:
            raise MotionError(f"decoder steps {start}..{stop - 1} need actor frames up to "
                              f"{stop}; the window has {min(actor.shape[1], memory.shape[1])}",
                              field="reactor_in")
        previous = None if cache is None else cache.last
        h = self.reactor_embed(_features(reactor_in, self.config.fps, previous)) \
            + self.reactor_joints + self.time_pe[start:stop, None]
        distance = interaction_distance_bias(reactor_in, actor[:, start + 1:stop + 1],
                                             self.config.distance_sigma)
        for k, block in enumerate(self.decoder):
            h = block(h, memory[:, start + 1:stop + 1], self.adjacency_bias, distance,
                      None if cache is None else cache.layers[k])
        if cache is not None:
            cache.steps, cache.last = stop, reactor_in[:, -1]
        return reactor_in + OUTPUT_SCALE * self.head(self.out_norm(h))

    def forward(self, actor: torch.Tensor, reactor_in: torch.Tensor) -> torch.Tensor:
        """Teacher-forced pass: (N, T, J, 3) actor, (N, T-1, J, 3) reactor frames
        0..T-2 -> (N, T-1, J, 3) predicted frames 1..T-1."""
        return self.decode(reactor_in, self.encode(actor), actor)

    # -- generation ---------------------------------------------------------------------

    @torch.no_grad()
    def _rollout(self, actor: np.ndarray, prefix: np.ndarray) -> np.ndarray:
        """Autoregressive generation within one chunk.

        Args:
            actor: (N, T, J, 3) actor chunk, T <= window, actor frame.
            prefix: (N, C, J, 3) given reactor frames 0..C-1, 1 <= C < T, same frame.

        Returns:
            (N, T - C, J, 3) generated reactor frames C..T-1.
        """
        a = torch.as_tensor(actor, dtype=torch.float32)
        memory = self.encode(a)
        # Each step decodes only the newest frame (the cache keeps the earlier ones').
        cache = DecoderCache(len(self.decoder), a.shape[1] - 1)
        nxt = self.decode_steps(torch.as_tensor(prefix, dtype=torch.float32), memory, a,
                                cache)[:, -1:]
        frames = [nxt]
        while cache.steps + 1 < a.shape[1]:
            nxt = self.decode_steps(nxt, memory, a, cache)
            frames.append(nxt)
        return torch.cat(frames, dim=1).numpy()

    def generate(self, actor_window: np.ndarray, reactor_first_frame: np.ndarray
                 ) -> np.ndarray:
        """The reactor's window from the actor's and the reactor's first frame.

        Args:
            actor_window: (N, T, J, 3) or (T, J, 3) actor positions, metres, T >= 2, any
                Z-up frame shared by both people (each chunk is re-normalised in its
                actor's frame and mapped back).
            reactor_first_frame: (N, J, 3) or (J, 3), the reactor's frame 0, same frame.

        Returns:
            (N, T, J, 3) / (T, J, 3) float32 reactor positions, metres, in the input's
            frame; frame 0 is the given one. T beyond the trained window is generated in
            chunks (module docstring).

        Raises:
            MotionError: bad shapes, fewer than 2 frames, non-finite values.
        """
        c = self.config
        a, b, batched = check_inputs(actor_window, reactor_first_frame,
                                     len(c.joint_names))
        total = a.shape[1]
        if total < 2:
            raise MotionError(f"actor_window needs at least 2 frames; got {total}",
                              field="actor_window")
        self.eval()
        out = np.empty(a.shape, dtype=np.float64)
        out[:, 0] = b
        start, context = 0, 1
        while True:
            stop = min(start + c.window, total)
            origin, yaw = idata.actor_frame(a[:, start], c.joint_names)
            actor = idata.normalise(a[:, start:stop], origin, yaw)
            prefix = idata.normalise(out[:, start:start + context], origin, yaw)
            gen = self._rollout(actor, prefix)
            out[:, start + context:stop] = idata.denormalise(gen, origin, yaw)
            if stop == total:
                break
            context = c.chunk_context
            start = stop - context
        out = out.astype(np.float32)
        return out if batched else out[0]

    # -- training pieces ----------------------------------------------------------------

    def mirror(self, x: torch.Tensor) -> torch.Tensor:
        """Left/right mirror in the actor frame: ``y -> -y`` and left/right joints
        swapped, (N, T, J, 3) -> (N, T, J, 3)."""
        return x[:, :, self._swap] * torch.tensor([1.0, -1.0, 1.0])

    def loss(self, actor: torch.Tensor, reactor: torch.Tensor,
             noise: float = 0.0) -> tuple[torch.Tensor, dict[str, float]]:
        """Teacher-forced loss of (N, T, J, 3) windows (module docstring), T >= 3.

        Returns:
            ``(total, {"mse": ..., "velocity": ...})``, in decimetres².
        """
        reactor_in = reactor[:, :-1]
        if noise > 0:
            reactor_in = reactor_in + noise * torch.randn_like(reactor_in)
        pred = self(actor, reactor_in) * LOSS_UNIT
        target = reactor[:, 1:] * LOSS_UNIT
        mse = ((pred - target) ** 2).sum(-1).mean()
        vel = (((pred[:, 1] - pred[:, 0]) - (target[:, 1] - target[:, 0])) ** 2
               ).sum(-1).mean()
        total = mse + self.config.velocity_weight * vel
        return total, {"mse": float(mse.detach()), "velocity": float(vel.detach())}

    # -- checkpoints --------------------------------------------------------------------

    CHECKPOINT_FORMAT = CHECKPOINT_FORMAT
    CONFIG = InterFormerConfig

    def checkpoint_nets(self) -> dict[str, nn.Module]:
        return {"weights": self}


def train(train: idata.InteractionWindows, config: InterFormerConfig | None = None, *,
          seed: int = 0, progress: bool = True) -> tuple[InterFormer, dict[str, Any]]:
    """Train an InterFormer on real windows with teacher forcing (CPU, seeded).

    Args:
        train: training windows (N, T, J, 3), actor frame; T becomes ``config.window``.
        config: architecture and optimisation (defaults: :class:`InterFormerConfig`).
        seed: seeds torch and the batch order / augmentation.
        progress: show a tqdm bar over epochs.

    Returns:
        ``(model, history)``: the model in eval mode, and per-epoch ``"loss"``, ``"mse"``,
        ``"velocity"`` (means over the epoch's batches, dm²), ``"cpu_seconds"`` and
        ``"steps"``.

    Raises:
        MotionError: fewer than 3 frames per window, joints that differ from the
            config's, or no windows.
    """
    c = config or InterFormerConfig()
    if len(train) == 0:
        raise MotionError("no training windows", field="train")
    if train.window < 3:
        raise MotionError(f"training windows need >= 3 frames; got {train.window}",
                          field="train")
    if tuple(train.joint_names) != c.joint_names:
        raise MotionError("training windows' joints differ from the config's joint_names",
                          field="train")
    c = replace(c, window=train.window, chunk_context=min(c.chunk_context,
                                                          train.window - 1))
    budget = CpuBudget()
    rng = seeded(seed)
    model = InterFormer(c)
    actor = torch.as_tensor(train.actor, dtype=torch.float32)
    reactor = torch.as_tensor(train.reactor, dtype=torch.float32)
    n = len(train)
    per_epoch = math.ceil(n / c.batch_size)
    steps = per_epoch * c.epochs
    opt = torch.optim.AdamW(model.parameters(), lr=c.lr, weight_decay=c.weight_decay)
    sched = cosine_schedule(opt, steps, floor=0.05)
    history: dict[str, Any] = {"loss": [], "mse": [], "velocity": []}
    model.train()
    for _ in tqdm(range(c.epochs), desc="interformer", disable=not progress):
        order = rng.permutation(n)
        sums = np.zeros(3)
        for i in range(per_epoch):
            idx = torch.as_tensor(order[i * c.batch_size:(i + 1) * c.batch_size])
            a, b = actor[idx], reactor[idx]
            if c.mirror:
                flip = torch.as_tensor(rng.random(len(idx)) < 0.5)
                a = torch.where(flip[:, None, None, None], model.mirror(a), a)
                b = torch.where(flip[:, None, None, None], model.mirror(b), b)
            total, terms = model.loss(a, b, noise=c.input_noise)
            opt.zero_grad()
            total.backward()
            nn.utils.clip_grad_norm_(model.parameters(), c.grad_clip)
            opt.step()
            sched.step()
            sums += (float(total.detach()), terms["mse"], terms["velocity"])
        for key, value in zip(("loss", "mse", "velocity"), sums / per_epoch, strict=True):
            history[key].append(float(value))
    history["cpu_seconds"] = budget.seconds()
    history["steps"] = steps
    model.metadata = {"train_windows": n, "seed": seed, "epochs": c.epochs,
                      "final_loss": history["loss"][-1],
                      "cpu_seconds": history["cpu_seconds"]}
    return model.eval(), history

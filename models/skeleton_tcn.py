"""Skeleton temporal convolutional network: the room's gesture recogniser.

A small 1-D convolutional network over time on three streams of a body-centred skeleton
(joints, bones, motion: what two-stream and multi-stream skeleton recognisers such as
2s-AGCN learned to feed a network), with masked pooling so that any number of valid
frames can be classified: a whole clip, 1 s of it, or 1 s real + a forecast.

Math
----
Input ``x`` (B, T, J, 3): windows normalised by :func:`simenv.data.gestures.normalise_windows`
(origin at the spine, facing +X, arm size scaled to the reference adult; metres of that
body, Z up), and a validity mask ``m`` (B, T). Per frame t the feature vector is

    f_t = [x_t - x_t,root ;  x_t - x_t,parent ;  s (x_t - x_{t-1}) ;  x_t,root]

(joint stream relative to the frame's root, bone stream, motion stream scaled by
``s = fps / 5`` so a 0.2 m/s limb reads 1; the root's own trajectory), of size 9J + 3.
Then

    h⁰ = W_in f                       (1x1 convolution, width D)
    hᵏ = (hᵏ⁻¹ + W₂ᵏ GELU(LN(W₁ᵏ * hᵏ⁻¹))) ⊙ m     k = 1..K

with ``W₁ᵏ *`` a temporal convolution of kernel 5 and dilation ``dᵏ`` (1, 2, 4, 1: a
receptive field of 33 frames, 1.3 s at 25 fps), LN a layer norm over channels (padded
frames must not enter batch statistics, so no batch norm), ⊙ m zeroing padded frames.
Pooling is the masked mean and max over valid frames,
``z = [Σ_t m_t hᵗ / Σ_t m_t ; max_{t: m_t} hᵗ]`` (2D), the penultimate features
(:meth:`SkeletonTCN.features`), and ``logits = W_out dropout(z)``.

Calibrated probabilities: ``p = softmax(logits / τ)`` with the temperature ``τ``
fitted after training (Guo et al. 2017, "On calibration of modern neural networks";
:func:`fit_temperature`), stored in the checkpoint, so that a decision threshold on
``p`` means a probability of being right.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import torch
from torch import nn

from simenv.core.errors import MotionError
from simenv.data.gestures import normalise_windows
from simenv.data.sensor_invariance import canonical_body
from simenv.models.checkpoint import CheckpointMixin
from simenv.models.gesture_classifier import SkeletonClasses, valid_mask

CHECKPOINT_FORMAT = "simenv-skeleton-tcn-1"
#: Key of ``TCNConfig.extra`` marking a network trained on canonical-body input
#: (:func:`simenv.data.sensor_invariance.canonical_body`), which :meth:`SkeletonTCN.model_input`
#: then gives it whoever calls it.
CANONICAL_BODY = "canonical_body"
#: Dilations of the residual blocks (receptive field 1 + 4 (1 + 2 + 4 + 1) = 33 frames).
DILATIONS: tuple[int, ...] = (1, 2, 4, 1)
KERNEL = 5


@dataclass
class TCNConfig(SkeletonClasses):
    """Architecture and data contract (:class:`SkeletonClasses`, with exactly one root)
    of a :class:`SkeletonTCN`.

    Attributes:
        fps: frame rate of the windows, frames/s.
        width: channels D of the blocks.
        dropout: dropout before the output layer and inside the blocks, in training.
        temperature: softmax temperature τ of :meth:`SkeletonTCN.predict_proba`.
        extra: JSON-able provenance (joint set, dataset, protocol); ``canonical_body``
            (:data:`CANONICAL_BODY`) true: the network reads canonical-body input.
    """

    fps: float = 25.0
    width: int = 128
    dropout: float = 0.2
    temperature: float = 1.0
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        super().__post_init__()
        if sum(p < 0 for p in self.parents) != 1:
            raise ValueError("the skeleton needs exactly one root (parent -1)")
        if not self.temperature > 0:
            raise ValueError(f"temperature must be > 0; got {self.temperature}")


def _trimmed(x: torch.Tensor, valid: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``x`` (B, T, ...) and ``valid`` (B, T) without the trailing frames that pad every
    window: padded frames are zeroed after every layer, exactly what the convolutions' own
    zero padding gives, so cutting them changes nothing."""
    last = int(torch.nonzero(valid.any(dim=0)).max()) + 1
    return x[:, :last], valid[:, :last]


def _pooled(h: torch.Tensor, mask: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor]:
    """Mean and max over time of ``h`` (B, C, T), over the frames where ``mask`` (B, 1, T)
    is 1 (None: every frame)."""
    if mask is None:
        return h.mean(-1), h.amax(-1)
    return h.sum(-1) / mask.sum(-1), h.masked_fill(mask == 0, float("-inf")).amax(-1)


class _Block(nn.Module):
    """``h + W₂ GELU(LN(W₁ * h))``, padded frames zeroed (module docstring)."""

    def __init__(self, width: int, dilation: int, dropout: float) -> None:
        super().__init__()
        self.conv = nn.Conv1d(width, width, KERNEL, padding=dilation * (KERNEL // 2),
                              dilation=dilation)
        self.norm = nn.GroupNorm(1, width)
        self.mix = nn.Conv1d(width, width, 1)
        self.drop = nn.Dropout(dropout)

    def forward(self, h: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        return (h + self.mix(self.drop(nn.functional.gelu(self.norm(self.conv(h)))))) * mask


class SkeletonTCN(CheckpointMixin, nn.Module):
    """Multi-stream temporal convolutional skeleton classifier (math in the module
    docstring). ``forward(x, valid) -> logits`` with ``x`` (B, T, J, 3) normalised
    windows and ``valid`` (B, T) bool; any T >= 1."""

    def __init__(self, config: TCNConfig) -> None:
        super().__init__()
        self.config = config
        self.metadata: dict[str, Any] = {}
        joints = len(config.joint_names)
        self.root = config.parents.index(-1)
        parents = [p if p >= 0 else self.root for p in config.parents]
        self.register_buffer("parent_index", torch.tensor(parents), persistent=False)
        self.inp = nn.Conv1d(9 * joints + 3, config.width, 1)
        self.blocks = nn.ModuleList(_Block(config.width, d, config.dropout)
                                    for d in DILATIONS)
        self.drop = nn.Dropout(config.dropout)
        self.out = nn.Linear(2 * config.width, len(config.labels))

    def _check(self, x: torch.Tensor, valid: torch.Tensor | None) -> torch.Tensor:
        joints = len(self.config.joint_names)
        if x.ndim != 4 or x.shape[2:] != (joints, 3) or x.shape[1] < 1:
            raise MotionError(
                f"classifier input must have shape (B, T, {joints}, 3) (joints "
                f"{', '.join(self.config.joint_names)}); got {tuple(x.shape)}", field="x")
        return valid_mask(x, valid)

    def streams(self, x: torch.Tensor) -> torch.Tensor:
        """(B, T, 9J + 3) per-frame joint, bone, motion and root features."""
        b, t = x.shape[:2]
        root = x[:, :, self.root:self.root + 1]
        motion = torch.zeros_like(x)
        motion[:, 1:] = (x[:, 1:] - x[:, :-1]) * (self.config.fps / 5.0)
        return torch.cat([(x - root).reshape(b, t, -1),
                          (x - x[:, :, self.parent_index]).reshape(b, t, -1),
                          motion.reshape(b, t, -1), root.reshape(b, t, -1)], dim=-1)

    def features(self, x: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
        """(B, 2D) masked mean and max of the last block over valid frames."""
        x, valid = _trimmed(x, self._check(x, valid))
        mask = valid[:, None, :].to(x.dtype)
        h = self.inp(self.streams(x).transpose(1, 2)) * mask
        for block in self.blocks:
            h = block(h, mask)
        return torch.cat(_pooled(h, mask), dim=-1)

    def forward(self, x: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
        """(B, C) class logits (before the temperature)."""
        return self.out(self.drop(self.features(x, valid)))

    def model_input(self, x: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
        """Normalised windows (N, T, J, 3) as this network was trained to read them: through
        :func:`~simenv.data.sensor_invariance.canonical_body` when ``config.extra`` marks it
        so (:data:`CANONICAL_BODY`), as given otherwise (e.g. the shipped ``gesture-tcn*``).
        :meth:`predict_proba` and :meth:`classify_world` apply it; a caller of
        :meth:`forward` passes its windows through it."""
        if not self.config.extra.get(CANONICAL_BODY):
            return x
        return canonical_body(x, valid, joints=self.config.joint_names)

    @torch.no_grad()
    def predict_proba(self, x: np.ndarray, valid: np.ndarray | None = None,
                      batch_size: int = 256) -> np.ndarray:
        """(N, C) calibrated probabilities ``softmax(logits / τ)`` of normalised windows
        (N, T, J, 3) (through :meth:`model_input`)."""
        if self.training:
            self.eval()
        xt = torch.as_tensor(np.asarray(self.model_input(x, valid), np.float32))
        vt = None if valid is None else torch.as_tensor(np.asarray(valid, bool))
        tau = self.config.temperature
        out = [torch.softmax(self(xt[i:i + batch_size],
                                  None if vt is None else vt[i:i + batch_size]) / tau, -1)
               for i in range(0, len(xt), batch_size)]
        return torch.cat(out).numpy()

    def classify_world(self, windows: np.ndarray, valid: np.ndarray | None = None
                       ) -> np.ndarray:
        """Probabilities of world-frame windows (metres, Z up, ``fps``): (N, T, J, 3) or
        (T, J, 3) on ``config.joint_names``, normalised here
        (:func:`simenv.data.gestures.normalise_windows`). Returns (N, C) or (C,)."""
        single = np.ndim(windows) == 3
        x = normalise_windows(windows, valid, joints=self.config.joint_names)
        v = None if valid is None else np.asarray(valid, bool)
        if single:
            x, v = x[None], None if v is None else v[None]
        p = self.predict_proba(x, v)
        return p[0] if single else p

    CHECKPOINT_FORMAT = CHECKPOINT_FORMAT
    CONFIG = TCNConfig

    def checkpoint_nets(self) -> dict[str, nn.Module]:
        return {"net": self}


ENSEMBLE_FORMAT = "simenv-skeleton-tcn-ensemble-1"


class SkeletonTCNEnsemble(CheckpointMixin, nn.Module):
    """Member :class:`SkeletonTCN` networks of one architecture, evaluated as one network.

    Math: member m (m = 1..M) gives logits ``z_m`` and has temperature ``τ_m``; the
    ensemble's probabilities average the members' temperature-scaled logits,

        p = softmax( (1/M) Σ_m z_m / τ_m ),

    (members sharing one temperature τ: ``softmax(mean_m z_m / τ)``, a τ fitted on the
    members' mean logits).

    Fused evaluation: the members read the same streams ``f``, so their input 1x1
    convolutions are stacked into one of ``M D`` output channels; each block's temporal and
    mixing convolutions become grouped convolutions (``groups = M``: member m's channels
    ``m D .. (m+1) D`` see only themselves); the layer norm ``GroupNorm(M, M D)`` is, per
    member, exactly its own ``GroupNorm(1, D)``; the output layers are one batched product.
    The logits are the members' own (float rounding aside) for one pass of Python and
    kernel overhead instead of M. Inference only: the fused weights are rebuilt whenever a
    member's parameters change.

    Args:
        members: the networks; same joints, labels, width and frame rate.

    Raises:
        ValueError: no member, or members whose config differs in more than weights,
            temperature and provenance.
    """

    def __init__(self, members: Sequence[SkeletonTCN]) -> None:
        super().__init__()
        if not members:
            raise ValueError("an ensemble needs at least one member network")
        first = members[0].config
        shape = (first.joint_names, first.parents, first.labels, first.width, first.fps)
        for k, m in enumerate(members[1:], start=1):
            c = m.config
            if (c.joint_names, c.parents, c.labels, c.width, c.fps) != shape:
                raise ValueError(f"ensemble member {k} differs from member 0 in its joints, "
                                 "labels, width or frame rate")
            if bool(c.extra.get(CANONICAL_BODY)) != bool(first.extra.get(CANONICAL_BODY)):
                raise ValueError(f"ensemble member {k} and member 0 read different input "
                                 "(canonical-body or normalised windows): the fused pass "
                                 "gives every member the same windows")
        self.members = nn.ModuleList(members)
        #: The shared contract, temperature 1: :meth:`forward` is already scaled.
        self.config = replace(first, temperature=1.0)
        self.metadata: dict[str, Any] = {}
        self._fused: dict[str, Any] | None = None
        self._versions: tuple[int, ...] = ()
        # Walking the module tree for every window costs more than a member's forward pass.
        self._params = tuple(self.parameters())

    @property
    def temperatures(self) -> tuple[float, ...]:
        """``τ_m`` of each member."""
        return tuple(float(m.config.temperature) for m in self.members)

    def _weights(self) -> dict[str, Any]:
        versions = tuple(p._version for p in self._params)
        if self._fused is None or versions != self._versions:
            ms = list(self.members)

            def cat(get: Any) -> torch.Tensor:
                return torch.cat([get(m).detach() for m in ms])

            blocks = [{"conv": cat(lambda m, k=k: m.blocks[k].conv.weight),
                       "conv_b": cat(lambda m, k=k: m.blocks[k].conv.bias),
                       "norm": cat(lambda m, k=k: m.blocks[k].norm.weight),
                       "norm_b": cat(lambda m, k=k: m.blocks[k].norm.bias),
                       "mix": cat(lambda m, k=k: m.blocks[k].mix.weight),
                       "mix_b": cat(lambda m, k=k: m.blocks[k].mix.bias),
                       "eps": ms[0].blocks[k].norm.eps, "dilation": d}
                      for k, d in enumerate(DILATIONS)]
            self._fused = {"inp": cat(lambda m: m.inp.weight), "inp_b": cat(lambda m: m.inp.bias),
                           "blocks": blocks,
                           "out": torch.stack([m.out.weight.detach() for m in ms]),
                           "out_b": torch.stack([m.out.bias.detach() for m in ms])}
            self._versions = versions
        return self._fused

    @torch.no_grad()
    def member_logits(self, x: torch.Tensor, valid: torch.Tensor | None = None
                      ) -> torch.Tensor:
        """(B, M, C) each member's logits (before its temperature) of normalised windows
        ``x`` (B, T, J, 3) with ``valid`` (B, T) bool, by the fused pass (class docstring)."""
        first: SkeletonTCN = self.members[0]
        x, valid = _trimmed(x, first._check(x, valid))
        # Every frame valid (the loop's windows): multiplying by a mask of ones is skipped.
        mask = None if bool(valid.all()) else valid[:, None, :].to(x.dtype)
        w, n = self._weights(), len(self.members)
        h = nn.functional.conv1d(first.streams(x).transpose(1, 2), w["inp"], w["inp_b"])
        h = h if mask is None else h * mask
        for b in w["blocks"]:
            y = nn.functional.conv1d(h, b["conv"], b["conv_b"], padding=b["dilation"] * (
                KERNEL // 2), dilation=b["dilation"], groups=n)
            y = nn.functional.gelu(nn.functional.group_norm(y, n, b["norm"], b["norm_b"],
                                                            b["eps"]))
            h = h + nn.functional.conv1d(y, b["mix"], b["mix_b"], groups=n)
            h = h if mask is None else h * mask
        mean, peak = _pooled(h, mask)
        z = torch.cat([mean.view(len(x), n, -1), peak.view(len(x), n, -1)], dim=-1)
        return torch.einsum("bmk,mck->bmc", z, w["out"]) + w["out_b"]

    def forward(self, x: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
        """(B, C) the ensemble's logits ``(1/M) Σ_m z_m / τ_m`` (its probabilities are
        their softmax: :attr:`config` has temperature 1)."""
        tau = torch.tensor(self.temperatures, dtype=x.dtype)[None, :, None]
        return (self.member_logits(x, valid) / tau).mean(1)

    def model_input(self, x: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
        """Normalised windows as the members read them (:meth:`SkeletonTCN.model_input`;
        every member reads the same input, checked when the ensemble is made)."""
        return self.members[0].model_input(x, valid)

    @torch.no_grad()
    def predict_proba(self, x: np.ndarray, valid: np.ndarray | None = None,
                      batch_size: int = 256) -> np.ndarray:
        """(N, C) ensemble probabilities (class docstring) of normalised windows
        (N, T, J, 3) (through :meth:`model_input`)."""
        xt = torch.as_tensor(np.asarray(self.model_input(x, valid), np.float32))
        vt = None if valid is None else torch.as_tensor(np.asarray(valid, bool))
        out = [torch.softmax(self(xt[i:i + batch_size],
                                  None if vt is None else vt[i:i + batch_size]), -1)
               for i in range(0, len(xt), batch_size)]
        return torch.cat(out).numpy()

    #: World-frame windows as :meth:`SkeletonTCN.classify_world` reads them.
    classify_world = SkeletonTCN.classify_world

    CHECKPOINT_FORMAT = ENSEMBLE_FORMAT
    CONFIG = TCNConfig

    def checkpoint_nets(self) -> dict[str, nn.Module]:
        return {f"member{k}": m for k, m in enumerate(self.members)}

    def checkpoint_arrays(self) -> dict[str, np.ndarray]:
        return {"temperatures": np.array(self.temperatures)}

    @classmethod
    def from_checkpoint(cls, checkpoint: Any) -> SkeletonTCNEnsemble:
        taus = np.asarray(checkpoint.arrays["temperatures"], float).reshape(-1)
        config = TCNConfig(**checkpoint.config)  # temperature 1: each member's is in taus
        return cls([SkeletonTCN(replace(config, temperature=float(t))) for t in taus])


def fit_temperature(logits: np.ndarray, y: np.ndarray,
                    grid: Sequence[float] = tuple(np.exp(np.linspace(np.log(0.25),
                                                                     np.log(8.0), 61)))
                    ) -> float:
    """Temperature minimising the negative log-likelihood of ``softmax(logits / τ)`` on
    held-out (logits (N, C), labels (N,)), over a log-spaced grid 0.25..8 (the NLL is
    convex in 1/τ, so a fine grid finds its minimum without an optimiser)."""
    z = torch.as_tensor(np.asarray(logits, np.float64))
    target = torch.as_tensor(np.asarray(y, np.int64))
    if z.ndim != 2 or len(z) != len(target) or len(z) == 0:
        raise ValueError(f"need (N, C) logits and (N,) labels; got {tuple(z.shape)} and "
                         f"{tuple(target.shape)}")
    nll = [float(nn.functional.cross_entropy(z / t, target)) for t in grid]
    return float(grid[int(np.argmin(nll))])


__all__ = ["CHECKPOINT_FORMAT", "ENSEMBLE_FORMAT", "SkeletonTCN", "SkeletonTCNEnsemble",
           "TCNConfig", "fit_temperature"]

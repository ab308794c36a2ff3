"""DCT-residual MLP motion predictor (siMLPe-like): a learned regression baseline.

A diagnostic of what the data allows, evaluated exactly like the PredictiveMA-WGAN
predictor (:mod:`simenv.models.predictor`): same windows, same heading normalisation,
same ``predict(history)`` interface. It follows siMLPe (Guo et al., "Back to MLP: a
simple baseline for human motion prediction", WACV 2023) scaled to our data:

Math (one window; H = 1 + P history frames, F future frames, D = 51)
--------------------------------------------------------------------
1. **Heading.** The window is rotated about Z so that the hip axis of the last observed
   pose points along +X (as in the WGAN model), and rotated back at the end.
2. **Residual to the last pose.** ``X = h - x_T`` (H, D): the history relative to the
   last observed pose ``x_T``, in decimetres (``LOSS_UNIT``). The pose itself enters
   as a second input ``x_T`` (D,) so the network can still use it (phase of a gait).
3. **DCT.** ``C = D_H X`` with the orthonormal DCT-II matrix ``D_H`` (H x H): low
   temporal frequencies first, which the temporal mixing below exploits.
4. **MLP.** ``C -> FC_space (D -> D) -> n blocks [C + LN(FC_time(C))] -> FC_time_out
   (H -> F) -> FC_space (D -> D)``: fully connected layers alternate along the
   feature axis (shared over time) and along the time axis (shared over features), as
   in siMLPe; LayerNorm over the feature axis. The pose ``x_T`` is added through a
   linear embedding to every coefficient before the blocks.
5. **Inverse DCT and residual.** ``x̂ = x_T + D_F^T C_out``: a zero output is the
   zero-velocity prediction, so the network learns only the change from the last pose.
6. **Root motion** (optional, ``root_input``; not in siMLPe, which predicts the root
   with the body). The pelvis velocity over the history in the heading frame,
   ``v_t = R_z(-θ)(r_t - r_{t-1}) · fps`` (H, 3) m/s (``v_0 = v_1``), enters as its DCT
   through a linear embedding added to the coefficients like the pose: walking or
   turning tells the network where the limbs are going. ``predict`` then needs the
   history's world pelvis positions (``root=``).
7. **Ensemble and test-time mirroring** (not in siMLPe; both reduce the variance that
   13 training clips leave). With ``members = K`` the prediction is the mean of K
   networks, each trained with its own seed (``DCTRegressionPredictor(config, seed)``:
   network i starts from ``seed + i``) and either selected on validation clips or
   refitted on all training clips for a schedule chosen on them
   (:func:`simenv.learning.train_predictor.run`); with ``mirror_average`` each network's
   prediction is ``½ (f(h) + M f(M h))``, ``M`` the left-right mirror
   (:func:`simenv.models.predictor.mirror`), which makes the predictor exactly
   mirror-equivariant, as the mirrored training data asks it to be.

Loss: mean per-joint Euclidean position error (decimetres) plus the same on the
frame-to-frame velocities (siMLPe's two terms), Adam with cosine decay, weight decay;
optionally weighted towards the late frames (:func:`regression_loss`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import torch
from torch import nn

from simenv.core.errors import MotionError
from simenv.models.baselines import check_history
from simenv.models.checkpoint import Checkpoint, CheckpointMixin
from simenv.models.predictor import (
    DIMS,
    LOSS_UNIT,
    NUM_JOINTS,
    heading,
    mirror,
    rotate_z,
)

#: Format tag of checkpoint files.
CHECKPOINT_FORMAT = "simenv-dct-mlp-1"


def dct_matrix(n: int) -> np.ndarray:
    """Orthonormal DCT-II matrix (n, n): ``C = M x`` transforms n samples, ``x = Mᵀ C``."""
    k = np.arange(n)[:, None]
    i = np.arange(n)[None, :]
    m = np.sqrt(2.0 / n) * np.cos(np.pi * (2 * i + 1) * k / (2 * n))
    m[0] /= np.sqrt(2.0)
    return m


@dataclass
class RegressionConfig:
    """Hyper-parameters (saved in checkpoints)."""

    past_len: int
    future_len: int
    fps: float = 25.0
    blocks: int = 4
    dropout: float = 0.0
    #: Networks averaged (an ensemble); 1 in checkpoints written before ensembles.
    members: int = 1
    #: Average each network with its mirrored prediction of the mirrored history.
    mirror_average: bool = False
    #: The history's root (pelvis) velocity is an input (``predict(history, root=...)``).
    root_input: bool = False
    info: dict = field(default_factory=dict)


class TemporalBlock(nn.Module):
    """``C + LN(FC_time(C))`` on (B, T, D) coefficients (FC over the time axis)."""

    def __init__(self, length: int, dropout: float) -> None:
        super().__init__()
        self.fc = nn.Linear(length, length)
        self.norm = nn.LayerNorm(DIMS)
        self.drop = nn.Dropout(dropout)
        nn.init.xavier_uniform_(self.fc.weight, gain=1e-3)
        nn.init.zeros_(self.fc.bias)

    def forward(self, c: torch.Tensor) -> torch.Tensor:
        return c + self.drop(self.norm(self.fc(c.transpose(1, 2)).transpose(1, 2)))


class DCTMLP(nn.Module):
    """(B, H, D) residual history, (B, D) last pose -> (B, F, D) residual future."""

    def __init__(self, history_len: int, future_len: int, blocks: int = 4,
                 dropout: float = 0.0, root_input: bool = False) -> None:
        super().__init__()
        self.register_buffer("dct_in", torch.as_tensor(dct_matrix(history_len),
                                                       dtype=torch.float32))
        self.register_buffer("idct_out", torch.as_tensor(dct_matrix(future_len).T,
                                                         dtype=torch.float32))
        self.fc_in = nn.Linear(DIMS, DIMS)
        self.pose = nn.Linear(DIMS, DIMS)
        self.root = nn.Linear(3, DIMS) if root_input else None
        self.blocks = nn.Sequential(*(TemporalBlock(history_len, dropout)
                                      for _ in range(blocks)))
        self.time_out = nn.Linear(history_len, future_len)
        self.fc_out = nn.Linear(DIMS, DIMS)
        # start at the zero-velocity prediction: a zero residual
        nn.init.zeros_(self.fc_out.weight)
        nn.init.zeros_(self.fc_out.bias)

    def forward(self, residual: torch.Tensor, last: torch.Tensor,
                root_velocity: torch.Tensor | None = None) -> torch.Tensor:
        c = self.dct_in @ residual
        c = self.fc_in(c) + self.pose(last)[:, None, :]
        if self.root is not None:
            c = c + self.root(self.dct_in @ root_velocity)
        c = self.blocks(c)
        c = self.time_out(c.transpose(1, 2)).transpose(1, 2)
        return self.idct_out @ self.fc_out(c)


class DCTRegressionPredictor(CheckpointMixin):
    """Trained DCT-residual MLP with the predictor interface of :mod:`simenv.models.baselines`.

    ``predict(history)``: (N, 1 + P, 17, 3) (or longer) root-relative pred17 positions,
    metres -> (N, F, 17, 3) float32 future.
    """

    def __init__(self, config: RegressionConfig, seed: int | None = None) -> None:
        """``seed``: network ``i`` starts from the weights ``torch.manual_seed(seed + i)``
        gives, whatever the process, the global generator or the ensemble size; None:
        from the global torch generator (which torch seeds *randomly* in every process,
        so a training run is then not reproducible across processes)."""
        if config.members < 1:
            raise MotionError(f"members must be >= 1; got {config.members}", field="members")
        self.config = config
        self.metadata: dict[str, Any] = {}
        self.past_len = config.past_len
        self.future_len = config.future_len
        self.fps = config.fps
        self.nets = nn.ModuleList(self._network(None if seed is None else seed + i)
                                  for i in range(config.members))

    def _network(self, seed: int | None) -> DCTMLP:
        c = self.config
        # A seeded network leaves the caller's generator alone.
        with torch.random.fork_rng(devices=[], enabled=seed is not None):
            if seed is not None:
                torch.manual_seed(seed)
            return DCTMLP(self.history_len, self.future_len, c.blocks, c.dropout,
                          c.root_input)

    @property
    def history_len(self) -> int:
        return self.past_len + 1

    @property
    def net(self) -> DCTMLP:
        """The first (for ``members = 1`` the only) network."""
        return self.nets[0]

    def member(self, index: int) -> DCTRegressionPredictor:
        """A one-network predictor that *shares* network ``index`` (training it trains
        this ensemble's member), with the same mirror averaging."""
        single = DCTRegressionPredictor(replace(self.config, members=1))
        single.nets[0] = self.nets[index]
        return single

    @staticmethod
    def inputs(history: np.ndarray, root: np.ndarray | None = None, fps: float = 25.0
               ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None, np.ndarray]:
        """(N, H, 17, 3) history, metres -> residual (N, H, 51) and last pose (N, 51) in
        heading-normalised decimetres, the root velocity (N, H, 3) in the heading frame,
        m/s (None without ``root`` (N, H, 3) world pelvis positions), and the heading
        angles (N,)."""
        angle = heading(history[:, -1])
        frames = rotate_z(np.asarray(history, dtype=np.float64), -angle) * LOSS_UNIT
        n, h = frames.shape[:2]
        flat = frames.reshape(n, h, DIMS)
        last = flat[:, -1]
        velocity = None
        if root is not None:
            step = np.diff(np.asarray(root, dtype=np.float64), axis=1) * fps
            step = np.concatenate([step[:, :1], step], axis=1)
            velocity = torch.as_tensor(rotate_z(step, -angle), dtype=torch.float32)
        return (torch.as_tensor(flat - last[:, None], dtype=torch.float32),
                torch.as_tensor(last, dtype=torch.float32), velocity, angle)

    def forward(self, residual: torch.Tensor, last: torch.Tensor,
                root_velocity: torch.Tensor | None = None) -> torch.Tensor:
        """Differentiable prediction of the first network in normalised decimetres:
        (B, F, 51) (what training fits; no ensemble, no mirroring)."""
        return last[:, None, :] + self.net(residual, last, root_velocity)

    def _predict_frames(self, history: np.ndarray, root: np.ndarray | None) -> np.ndarray:
        """(N, H, 17, 3) metres -> (N, F, 17, 3) float64 metres: mean of the networks."""
        residual, last, velocity, angle = self.inputs(history, root, self.fps)
        out = torch.stack([last[:, None, :] + net(residual, last, velocity)
                           for net in self.nets])
        out = out.mean(dim=0).double().numpy() / LOSS_UNIT
        return rotate_z(out.reshape(len(history), self.future_len, NUM_JOINTS, 3), angle)

    @torch.no_grad()
    def predict(self, history: np.ndarray, root: np.ndarray | None = None) -> np.ndarray:
        """Predict the F frames after a history.

        Args:
            history: (N, H, 17, 3) or (H, 17, 3) root-relative positions, metres,
                H >= 1 + P, ending at the last observed frame.
            root: (N, H, 3) or (H, 3) world pelvis positions of the same frames, metres
                (Z up); needed by (only) a model with ``config.root_input``.

        Returns:
            (N, F, 17, 3) or (F, 17, 3) float32 future positions, metres.

        Raises:
            MotionError: too short a history, wrong joint count, NaN frames, a missing
                or mis-shaped ``root``.
        """
        h, batched = check_history(history, self.history_len, joints=NUM_JOINTS)
        h = h[:, -self.history_len:]
        r = None
        if self.config.root_input:
            if root is None:
                raise MotionError("this model takes the root trajectory too: pass root "
                                  f"(N, >= {self.history_len}, 3) world pelvis positions",
                                  field="root")
            r = np.asarray(root, dtype=np.float64)
            r = r[None] if r.ndim == 2 else r
            if r.shape[0] != len(h) or r.shape[1] < self.history_len or r.shape[2:] != (3,) \
                    or not np.isfinite(r).all():
                raise MotionError(f"root must be finite (N, >= {self.history_len}, 3) with "
                                  f"N = {len(h)}; got shape {r.shape}", field="root")
            r = r[:, -self.history_len:]
        self.nets.eval()
        if self.config.mirror_average:  # one pass over the histories and their mirrors
            rr = None if r is None else np.concatenate([r, r * np.array([-1.0, 1.0, 1.0])])
            both = self._predict_frames(np.concatenate([h, mirror(h)]), rr)
            out = 0.5 * (both[: len(h)] + mirror(both[len(h):]))
        else:
            out = self._predict_frames(h, r)
        out = out.astype(np.float32)
        return out if batched else out[0]

    CHECKPOINT_FORMAT = CHECKPOINT_FORMAT

    def checkpoint_nets(self) -> dict[str, nn.Module]:
        return {"nets": self.nets}

    @classmethod
    def from_checkpoint(cls, checkpoint: Checkpoint) -> DCTRegressionPredictor:
        # Checkpoints from before ensembles hold their one network as "net.<k>": it is
        # member 0 of the ensemble.
        a = checkpoint.arrays
        for key in [k for k in a if k.startswith("net.")]:
            a[f"nets.0.{key[4:]}"] = a.pop(key)
        return cls(RegressionConfig(**checkpoint.config))


def horizon_weights(length: int, slope: float) -> torch.Tensor:
    """(length,) frame weights ``w_t ∝ 1 + slope · t / (length - 1)``, mean 1."""
    w = 1 + slope * torch.arange(length, dtype=torch.float32) / max(length - 1, 1)
    return w / w.mean()


def regression_loss(pred: torch.Tensor, target: torch.Tensor,
                    horizon_weight: float = 0.0) -> torch.Tensor:
    """Mean per-joint Euclidean error of positions plus that of frame-to-frame
    velocities, of (B, T, 51) tensors in decimetres (siMLPe's two terms).

    ``horizon_weight`` a >= 0 weights future frame t by ``1 + a t / (T - 1)`` (weights
    normalised to mean 1, :func:`horizon_weights`; velocities by the weights of their
    later frame's slot): a > 0 favours the long horizons, which the per-frame mean
    otherwise trades for the easy first frames.
    """
    p = pred.view(*pred.shape[:2], NUM_JOINTS, 3)
    t = target.view(*target.shape[:2], NUM_JOINTS, 3)
    pos = (p - t).norm(dim=-1).mean(dim=(0, 2))
    vel = ((p[:, 1:] - p[:, :-1]) - (t[:, 1:] - t[:, :-1])).norm(dim=-1).mean(dim=(0, 2))
    if not horizon_weight:
        return pos.mean() + vel.mean()
    w = horizon_weights(p.shape[1], horizon_weight)
    wv = w[1:] / w[1:].mean()
    return (pos * w).mean() + (vel * wv).mean()


def targets(history_len: int, frames: np.ndarray) -> tuple[torch.Tensor, ...]:
    """Training tensors of (N, H + F, 17, 3) windows (metres): residual history, last
    pose and heading-normalised future (N, F, 51), all in decimetres."""
    n = len(frames)
    angle = heading(frames[:, history_len - 1])
    f = rotate_z(np.asarray(frames, dtype=np.float64), -angle) * LOSS_UNIT
    f = f.reshape(n, f.shape[1], DIMS)
    last = f[:, history_len - 1]
    as_t = lambda a: torch.as_tensor(a, dtype=torch.float32)  # noqa: E731
    return as_t(f[:, :history_len] - last[:, None]), as_t(last), as_t(f[:, history_len:])


def root_targets(history_len: int, frames: np.ndarray, root: np.ndarray, fps: float
                 ) -> torch.Tensor:
    """(N, H, 3) root-velocity input (m/s, heading frame; see
    :meth:`DCTRegressionPredictor.inputs`) of (N, H + F, ...) windows."""
    return DCTRegressionPredictor.inputs(frames[:, :history_len], root[:, :history_len],
                                         fps)[2]


def check_lengths(model: DCTRegressionPredictor, past_len: int, future_len: int) -> None:
    """Raise a MotionError if windows of ``past_len -> future_len`` do not fit ``model``."""
    if (past_len, future_len) != (model.past_len, model.future_len):
        raise MotionError(f"windows are {past_len}->{future_len}; the model is "
                          f"{model.past_len}->{model.future_len}", field="windows")

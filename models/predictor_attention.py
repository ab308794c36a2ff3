"""Joint-attention transformer on DCT coefficients: a learned motion predictor.

A spatio-temporal network in the spirit of the graph/attention predictors on DCT
coefficients (Mao et al., "Learning trajectory dependencies", ICCV 2019; "History
repeats itself", ECCV 2020), with self-attention across joints in place of the learned
graph. Same windows, heading normalisation, residual form, losses and interface as the
DCT-residual MLP (:mod:`simenv.models.predictor_regression`), so the two differ only in
how they mix joints and time.

Math (one window; H = 1 + P history frames, F future frames, J = 17 joints)
---------------------------------------------------------------------------
1. **Heading and residual.** As the DCT-MLP: the window is rotated so the last observed
   hip axis is +X, and the history enters as ``X = h - x_T`` in decimetres
   (:func:`inputs`).
2. **Temporal: DCT per joint.** ``C_j = D_H X_j`` (H, 3) with the orthonormal DCT-II
   matrix; joint j's *token* is ``e_j = W_in [vec(C_j), x_{T,j}] + p_j`` (width d), its
   3H coefficients and its last position, plus a learned joint embedding ``p_j``.
3. **Spatial: attention across joints.** ``L`` pre-norm transformer encoder layers over
   the J tokens: ``e <- e + MHA(LN(e))``, ``e <- e + FFN(LN(e))`` (``heads`` heads, FFN
   width 2d, GELU). Every joint attends to every other; the coefficients of a joint are
   mixed with each other inside its token (the temporal part).
4. **Output.** ``Ĉ_j = W_out LN(e_j)`` (F, 3) future DCT coefficients (``W_out`` starts
   at zero, so the untrained network is zero-velocity), ``x̂_j = x_{T,j} + D_F^T Ĉ_j``;
   the pelvis output is held at 0 (its root-relative position is 0).
5. **Ensemble and mirroring**, as the DCT-MLP: ``members`` networks averaged, each
   averaged with its mirrored prediction of the mirrored history (``mirror_average``).

Loss: :func:`simenv.models.predictor_regression.regression_loss` (mean joint error plus
velocity error, decimetres); trained by :func:`simenv.train_predictor_families.train_attention`
(the DCT-MLP's optimiser, schedule and model selection).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import torch
from torch import nn

from simenv.errors import MotionError
from simenv.models.baselines import check_history
from simenv.models.checkpoint import CheckpointError
from simenv.models.predictor import DIMS, LOSS_UNIT, NUM_JOINTS, heading, mirror, rotate_z
from simenv.models.predictor_regression import dct_matrix

#: Format tag of checkpoint files.
CHECKPOINT_FORMAT = "simenv-joint-attention-dct-1"


@dataclass
class AttentionConfig:
    """Hyper-parameters (saved in checkpoints)."""

    past_len: int
    future_len: int
    fps: float = 25.0
    width: int = 64
    layers: int = 3
    heads: int = 4
    dropout: float = 0.1
    members: int = 1
    mirror_average: bool = True
    info: dict = field(default_factory=dict)


def inputs(history: np.ndarray) -> tuple[torch.Tensor, torch.Tensor, np.ndarray]:
    """(N, H, 17, 3) history, metres -> residual (N, H, 51) and last pose (N, 51) in
    heading-normalised decimetres, and the heading angles (N,) rad."""
    angle = heading(history[:, -1])
    frames = rotate_z(np.asarray(history, dtype=np.float64), -angle) * LOSS_UNIT
    flat = frames.reshape(*frames.shape[:2], DIMS)
    last = flat[:, -1]
    return (torch.as_tensor(flat - last[:, None], dtype=torch.float32),
            torch.as_tensor(last, dtype=torch.float32), angle)


class JointAttentionDCT(nn.Module):
    """(B, H, 51) residual history, (B, 51) last pose -> (B, F, 51) residual future."""

    def __init__(self, history_len: int, future_len: int, width: int = 64, layers: int = 3,
                 heads: int = 4, dropout: float = 0.1) -> None:
        super().__init__()
        self.history_len, self.future_len = history_len, future_len
        self.register_buffer("dct_in", torch.as_tensor(dct_matrix(history_len),
                                                       dtype=torch.float32))
        self.register_buffer("idct_out", torch.as_tensor(dct_matrix(future_len).T,
                                                         dtype=torch.float32))
        mask = torch.ones(NUM_JOINTS, 1, 1)
        mask[0] = 0.0  # the pelvis is the origin of root-relative positions
        self.register_buffer("joint_mask", mask)
        self.embed = nn.Linear(3 * history_len + 3, width)
        self.joint = nn.Parameter(0.02 * torch.randn(NUM_JOINTS, width))
        layer = nn.TransformerEncoderLayer(width, heads, 2 * width, dropout,
                                           activation="gelu", batch_first=True,
                                           norm_first=True)
        self.encoder = nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)
        self.norm = nn.LayerNorm(width)
        self.out = nn.Linear(width, 3 * future_len)
        nn.init.zeros_(self.out.weight)  # start at the zero-velocity prediction
        nn.init.zeros_(self.out.bias)

    def forward(self, residual: torch.Tensor, last: torch.Tensor) -> torch.Tensor:
        b = residual.shape[0]
        c = (self.dct_in @ residual).view(b, self.history_len, NUM_JOINTS, 3)
        c = c.permute(0, 2, 1, 3).reshape(b, NUM_JOINTS, 3 * self.history_len)
        tokens = self.embed(torch.cat([c, last.view(b, NUM_JOINTS, 3)], -1)) + self.joint
        out = self.out(self.norm(self.encoder(tokens)))
        out = out.view(b, NUM_JOINTS, self.future_len, 3) * self.joint_mask
        out = out.permute(0, 2, 1, 3).reshape(b, self.future_len, 3 * NUM_JOINTS)
        return self.idct_out @ out


class AttentionPredictor:
    """Trained joint-attention DCT network(s) with the predictor interface of
    :mod:`simenv.models.baselines`.

    ``predict(history)``: (N, 1 + P, 17, 3) (or longer) root-relative pred17 positions,
    metres -> (N, F, 17, 3) float32 future.
    """

    def __init__(self, config: AttentionConfig) -> None:
        if config.members < 1:
            raise MotionError(f"members must be >= 1; got {config.members}", field="members")
        if config.width % config.heads:
            raise MotionError(f"width {config.width} is not a multiple of heads "
                              f"{config.heads}", field="width")
        self.config = config
        self.past_len = config.past_len
        self.future_len = config.future_len
        self.fps = config.fps
        self.nets = nn.ModuleList(
            JointAttentionDCT(self.history_len, self.future_len, config.width,
                              config.layers, config.heads, config.dropout)
            for _ in range(config.members))

    @property
    def history_len(self) -> int:
        return self.past_len + 1

    @property
    def net(self) -> JointAttentionDCT:
        """The first (for ``members = 1`` the only) network (what training fits)."""
        return self.nets[0]

    def member(self, index: int) -> AttentionPredictor:
        """A one-network predictor that *shares* network ``index``."""
        single = AttentionPredictor(replace(self.config, members=1))
        single.nets[0] = self.nets[index]
        return single

    def forward(self, residual: torch.Tensor, last: torch.Tensor) -> torch.Tensor:
        """Differentiable prediction of the first network in normalised decimetres:
        (B, F, 51) (what :func:`simenv.train_predictor_families.train_attention` fits)."""
        return last[:, None, :] + self.net(residual, last)

    def _predict_frames(self, history: np.ndarray) -> np.ndarray:
        residual, last, angle = inputs(history)
        out = torch.stack([last[:, None, :] + net(residual, last) for net in self.nets])
        out = out.mean(dim=0).double().numpy() / LOSS_UNIT
        return rotate_z(out.reshape(len(history), self.future_len, NUM_JOINTS, 3), angle)

    @torch.no_grad()
    def predict(self, history: np.ndarray) -> np.ndarray:
        """Predict the F frames after a history.

        Args:
            history: (N, H, 17, 3) or (H, 17, 3) root-relative positions, metres,
                H >= 1 + P, ending at the last observed frame.

        Returns:
            (N, F, 17, 3) or (F, 17, 3) float32 future positions, metres.

        Raises:
            MotionError: too short a history, wrong joint count, NaN frames.
        """
        h, batched = check_history(history, self.history_len, joints=NUM_JOINTS)
        h = h[:, -self.history_len:]
        self.nets.eval()
        if self.config.mirror_average:
            both = self._predict_frames(np.concatenate([h, mirror(h)]))
            out = 0.5 * (both[: len(h)] + mirror(both[len(h):]))
        else:
            out = self._predict_frames(h)
        out = out.astype(np.float32)
        return out if batched else out[0]

    def save(self, path: str | Path) -> Path:
        """Write an ``.npz`` checkpoint (arrays only): config JSON and the weights."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {"format": np.array(CHECKPOINT_FORMAT),
                  "config": np.array(json.dumps(asdict(self.config)))}
        arrays |= {f"nets.{k}": v.detach().cpu().numpy()
                   for k, v in self.nets.state_dict().items()}
        with path.open("wb") as fh:
            np.savez_compressed(fh, **arrays)
        return path

    @classmethod
    def load(cls, path: str | Path) -> AttentionPredictor:
        """Read a checkpoint written by :meth:`save`.

        Raises:
            CheckpointError: missing file, not such a checkpoint, or mismatched arrays.
        """
        path = Path(path)
        try:
            data = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise CheckpointError(f"cannot read attention checkpoint: {exc}",
                                  source=path) from None
        with data:
            if "format" not in data or str(data["format"]) != CHECKPOINT_FORMAT:
                raise CheckpointError(f"not a {CHECKPOINT_FORMAT} checkpoint", source=path)
            model = cls(AttentionConfig(**json.loads(str(data["config"]))))
            state = {k[5:]: torch.as_tensor(data[k]) for k in data.files
                     if k.startswith("nets.")}
            try:
                model.nets.load_state_dict(state)
            except RuntimeError as exc:
                raise CheckpointError(f"weights do not fit the config: {exc}",
                                      source=path) from None
        return model

"""Gesture-domain motion forecaster: 1 s of a Kinect skeleton -> the next 2 s.

The room's perception loop classifies "1 s real + 2 s predicted" frames. The CMU-trained
predictors (:mod:`simenv.models.predictor`, :mod:`simenv.models.predictor_regression`)
work on the root-relative pred17 layout and were fitted on clean optical mocap; this one
works directly on the classifier's ``gesture15`` joints
(:data:`simenv.data.gestures.GESTURE15_JOINTS`) in the **world frame** and is trained on the
real Kinect recordings of the gesture corpus (:mod:`simenv.learning.train_gesture_predictor`).

``GesturePredictor.predict(history)``: (25, 15, 3) world positions, metres, Z up,
25 fps -> (50, 15, 3) world positions of the next 50 frames; with ``mirror_average``, the
mean of that forecast and the mirrored forecast of the left-right mirrored history.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from simenv.core.errors import MotionError
from simenv.data.gestures import GESTURE15_JOINTS, mirror_windows
from simenv.models.baselines import check_history
from simenv.models.checkpoint import Checkpoint, CheckpointMixin
from simenv.models.predictor_regression import dct_matrix

__all__ = ["CHECKPOINT_FORMAT", "GesturePredictor", "GesturePredictorConfig", "ROOT_MODES",
           "body_frame", "from_body", "observer_offset", "to_body"]

#: Format tag of checkpoint files.
CHECKPOINT_FORMAT = "simenv-gesture-predictor-1"
#: Joints of every history and forecast (order of axis J).
JOINTS: tuple[str, ...] = GESTURE15_JOINTS
NUM_JOINTS = len(JOINTS)
DIMS = 3 * NUM_JOINTS
_SPINE = JOINTS.index("spine")
_LS, _RS = JOINTS.index("left_shoulder"), JOINTS.index("right_shoulder")
#: Observer input of the network: its horizontal offset from the person in the body
#: frame (decimetres, 2) and whether it is known (1 or 0).
OBSERVER_DIMS = 3
#: Network unit: decimetres (positions of ~0.1-1 m become ~1-10, a good range for an MLP).
UNIT = 10.0
#: How the forecast's root (spine) moves: ``learned`` = as the network predicts it;
#: ``damped`` = the spine velocity of the last :attr:`GesturePredictorConfig.root_frames`
#: history frames, decaying with time constant ``root_tau_s``; ``still`` = the spine stays.
ROOT_MODES = ("learned", "damped", "still")


@dataclass
class GesturePredictorConfig:
    """Hyper-parameters (saved in checkpoints).

    Attributes:
        history_len: observed frames H (25 = 1 s). future_len: predicted frames F (50 = 2 s).
        fps: frame rate of both, frames/s.
        dct_in: DCT coefficients of the history kept (low frequencies first).
        dct_out: DCT coefficients of the future predicted (the forecast is band-limited
            to ``dct_out / (2 F / fps)`` Hz).
        hidden: width of the MLP. blocks: residual blocks. dropout: in each block.
        mirror_average: also forecast the left-right mirror of the history and average
            the mirrored-back forecast in (see :class:`GesturePredictor`, step 8).
        heading_frames: last history frames whose mean shoulder axis gives the heading
            (a few, to damp Kinect jitter of the shoulders).
        root_mode: one of :data:`ROOT_MODES`. root_frames: history frames the root
            velocity of ``damped`` is measured over. root_tau_s: its decay time, s.
        observer_input: the network also takes where the observer (the depth sensor
            of a recording, the agent for a live user) stands relative to the person
            (:class:`GesturePredictor`, step 4): people walk up to what they face and stop
            short of it, which one second of their own motion does not tell.
        info: free provenance (training command, data), JSON.
    """

    history_len: int = 25
    future_len: int = 50
    fps: float = 25.0
    dct_in: int = 10
    dct_out: int = 12
    hidden: int = 160
    blocks: int = 1
    dropout: float = 0.1
    mirror_average: bool = False
    heading_frames: int = 3
    root_mode: str = "learned"
    root_frames: int = 5
    root_tau_s: float = 0.5
    observer_input: bool = False
    info: dict[str, Any] = field(default_factory=dict)

    def check(self) -> None:
        """Raise a MotionError naming the first inconsistent field."""
        if self.root_mode not in ROOT_MODES:
            raise MotionError(f"root_mode must be one of {ROOT_MODES}; got {self.root_mode!r}",
                              field="root_mode")
        for name, hi in (("dct_in", self.history_len), ("dct_out", self.future_len),
                         ("heading_frames", self.history_len),
                         ("root_frames", self.history_len - 1)):
            value = getattr(self, name)
            if not 1 <= value <= hi:
                raise MotionError(f"{name} must be in [1, {hi}]; got {value}", field=name)
        if self.hidden < 1 or self.blocks < 0 or not self.fps > 0 or not self.root_tau_s > 0:
            raise MotionError("hidden >= 1, blocks >= 0, fps > 0 and root_tau_s > 0 are "
                              "required", field="config")


# -- body frame -----------------------------------------------------------------------


def body_frame(history: np.ndarray, heading_frames: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Origin and heading of the body frame of each history.

    Origin ``o`` = the spine of the last frame; heading ``θ`` such that ``R_z(-θ)`` turns
    the forward direction ``Z × (r_shoulder - l_shoulder)`` (mean over the last
    ``heading_frames`` frames) onto +X, as :func:`simenv.data.gestures.normalise_windows`
    defines facing.

    Args:
        history: (N, H, 15, 3) world positions, metres.

    Returns:
        origin (N, 3) metres, heading (N,) radians.

    Raises:
        MotionError: shoulders without horizontal separation (facing undefined).
    """
    origin = history[:, -1, _SPINE]
    across = (history[:, -heading_frames:, _RS] - history[:, -heading_frames:, _LS]).mean(1)
    flat = np.flatnonzero(np.hypot(across[:, 0], across[:, 1]) < 1e-4)
    if flat.size:
        raise MotionError(f"history {int(flat[0])}: the shoulders have no horizontal "
                          "separation in its last frames; cannot tell which way the person "
                          "faces", field="history")
    return origin, np.arctan2(across[:, 0], -across[:, 1])


def _rotation(angle: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations about Z by ``angle`` (N,) radians."""
    c, s = np.cos(angle), np.sin(angle)
    rot = np.zeros((len(angle), 3, 3))
    rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1], rot[:, 2, 2] = c, -s, s, c, 1.0
    return rot


def to_body(x: np.ndarray, origin: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(N, T, J, 3) world metres -> body frame ``R_z(-θ)(x - o)``, metres."""
    return np.einsum("nij,ntkj->ntki", _rotation(-angle), x - origin[:, None, None])


def from_body(x: np.ndarray, origin: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_body`: ``R_z(θ) x + o``, metres."""
    return np.einsum("nij,ntkj->ntki", _rotation(angle), x) + origin[:, None, None]


# -- network --------------------------------------------------------------------------


class _Block(nn.Module):
    """Pre-norm residual block ``h + Drop(GELU(W LN(h)))``."""

    def __init__(self, width: int, dropout: float) -> None:
        super().__init__()
        self.norm = nn.LayerNorm(width)
        self.fc = nn.Linear(width, width)
        self.drop = nn.Dropout(dropout)

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        return h + self.drop(nn.functional.gelu(self.fc(self.norm(h))))


class GestureDCTMLP(nn.Module):
    """(B, H, 45) residual history, (B, 45) last pose, decimetres, with ``observer_input``
    (B, 3) observer offset (decimetres) and known flag -> (B, F, 45) residual future,
    decimetres (see :class:`GesturePredictor` for the math)."""

    def __init__(self, config: GesturePredictorConfig) -> None:
        super().__init__()
        c = config
        self.register_buffer("dct_in", torch.as_tensor(
            dct_matrix(c.history_len)[: c.dct_in], dtype=torch.float32))
        self.register_buffer("idct_out", torch.as_tensor(
            dct_matrix(c.future_len)[: c.dct_out].T, dtype=torch.float32))
        self.dct_out = c.dct_out
        self.fc_in = nn.Linear(c.dct_in * DIMS + DIMS + (OBSERVER_DIMS if c.observer_input
                                                          else 0), c.hidden)
        self.blocks = nn.Sequential(*(_Block(c.hidden, c.dropout) for _ in range(c.blocks)))
        self.norm = nn.LayerNorm(c.hidden)
        self.fc_out = nn.Linear(c.hidden, c.dct_out * DIMS)
        # A zero output is the zero-velocity forecast: training starts from it.
        nn.init.zeros_(self.fc_out.weight)
        nn.init.zeros_(self.fc_out.bias)

    def forward(self, residual: torch.Tensor, last: torch.Tensor,
                observer: torch.Tensor | None = None) -> torch.Tensor:
        coeffs = (self.dct_in @ residual).flatten(1)  # (B, K_in * 45)
        parts = [coeffs, last] if observer is None else [coeffs, last, observer]
        h = nn.functional.gelu(self.fc_in(torch.cat(parts, dim=1)))
        out = self.fc_out(self.norm(self.blocks(h))).view(-1, self.dct_out, DIMS)
        return self.idct_out @ out  # (B, F, 45)


# -- predictor ------------------------------------------------------------------------


class GesturePredictor(CheckpointMixin):
    """DCT-residual MLP forecaster of world-frame ``gesture15`` skeletons.

    Math (one history ``x_1..x_H`` (H = 25), F = 50 future frames, J = 15, D = 3J = 45)
    -------------------------------------------------------------------------------
    1. **Body frame.** ``o = spine(x_H)``; ``θ`` = heading of the mean shoulder axis
       ``a = r_shoulder - l_shoulder`` over the last ``heading_frames`` frames,
       ``θ = atan2(a_x, -a_y)``, so that ``R_z(-θ)`` maps the forward direction
       ``Z × a`` onto +X (left = +Y; the convention of
       :func:`simenv.data.gestures.normalise_windows`). Every frame becomes
       ``b_t = U · R_z(-θ)(x_t - o)`` in decimetres (``U = 10``); the person stands at
       the origin facing +X at the last observed frame, height (Z) kept, no scaling.
    2. **Residual to the last pose.** ``r_t = b_t - b_H`` (H, D); ``b_H`` (D,) also
       enters on its own (posture: seated, bent, arm raised).
    3. **DCT.** ``C = (M_H r)[:K_in]`` with the orthonormal DCT-II matrix ``M_H``
       (H x H, :func:`simenv.models.predictor_regression.dct_matrix`), keeping the
       ``K_in`` lowest temporal frequencies (K_in x D).
    4. **MLP.** ``z = GELU(W_in [vec C; b_H])`` -- with ``observer_input``,
       ``z = GELU(W_in [vec C; b_H; U·[R_z(-θ)(p - o)]_xy; 1])`` for an observer standing
       at world ``p`` (the sensor of a recording, the agent for a live user), or
       ``[...; 0, 0; 0]`` when it is unknown (:func:`observer_offset`) -- then
       ``blocks`` residual blocks
       ``z + Drop(GELU(W LN(z)))``, then ``Ĉ = W_out LN(z)`` reshaped to (K_out, D).
    5. **Inverse DCT and residual.** ``b̂_{H+k} = b_H + (M_F[:K_out]ᵀ Ĉ)_k``: the forecast
       is the last pose plus a band-limited change, so ``W_out = 0`` (the initialisation)
       is the zero-velocity forecast.
    6. **Root.** The spine is a joint like the others, so the network predicts the root
       displacement (``root_mode="learned"``). Alternatives, chosen per model in the
       config: ``"damped"`` keeps the pose relative to the predicted spine and moves the
       spine by ``d_k = v τ (1 - e^{-k / (τ fps)})``, ``v`` the mean spine velocity over
       the last ``root_frames`` history frames (m/s), ``τ = root_tau_s``; ``"still"``
       keeps the spine where it was (``d_k = 0``).
    7. **Back to the world:** ``x̂ = R_z(θ) b̂ / U + o``.
    8. **Mirror average** (``mirror_average``): ``x̂ ← (x̂(x) + S x̂(S x)) / 2``, where
       ``S`` mirrors left and right (world Y negated, left/right joints swapped; the
       observer's Y negated too). Training
       sees mirrored motion as often as the original, so the ideal forecaster commutes
       with ``S``; the average removes the part of the trained network's error that does
       not, for a second forward pass. Like any average of forecasts it also moves a
       little less than either.

    Training (:mod:`simenv.learning.train_gesture_predictor`): per-joint Euclidean error of the
    positions plus that of the frame-to-frame velocities (siMLPe's two terms), in the
    body frame, decimetres.

    Attributes:
        config: :class:`GesturePredictorConfig`. net: the torch network.
        name: registry name (``predictor-gesture-25-50`` when shipped).
        history_len, future_len, fps: from the config.
        joint_names: :data:`simenv.data.gestures.GESTURE15_JOINTS`.
        metadata: provenance read from / written to the checkpoint (JSON).
    """

    joint_names: tuple[str, ...] = JOINTS

    def __init__(self, config: GesturePredictorConfig | None = None, seed: int | None = None,
                 name: str = "predictor-gesture-25-50") -> None:
        """``seed``: the network starts from the weights ``torch.manual_seed(seed)`` gives
        (the caller's generator is left alone); None: from the global generator."""
        self.config = config or GesturePredictorConfig()
        self.config.check()
        with torch.random.fork_rng(devices=[], enabled=seed is not None):
            if seed is not None:
                torch.manual_seed(seed)
            self.net = GestureDCTMLP(self.config)
        self.net.eval()
        self.name = name
        self.metadata: dict[str, Any] = {}

    @property
    def history_len(self) -> int:
        return self.config.history_len

    @property
    def future_len(self) -> int:
        return self.config.future_len

    @property
    def fps(self) -> float:
        return self.config.fps

    @property
    def uses_observer(self) -> bool:
        """Whether :meth:`predict` uses its ``observer`` (``observer_input``)."""
        return self.config.observer_input

    # -- tensors ------------------------------------------------------------------------

    def inputs(self, history: np.ndarray, observer: np.ndarray | None = None
               ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None, np.ndarray,
                          np.ndarray]:
        """Network inputs of validated (N, H, 15, 3) world histories, metres: residual
        (N, H, 45) and last pose (N, 45) in body-frame decimetres, the observer input
        (N, 3) (:func:`observer_offset`; None without ``observer_input``), origin (N, 3)
        metres and heading (N,) radians. ``observer``: (N, 3) world metres, NaN rows
        unknown, or None."""
        origin, angle = body_frame(history, self.config.heading_frames)
        b = to_body(history, origin, angle).reshape(len(history), history.shape[1], DIMS)
        b = b * UNIT
        last = b[:, -1]
        obs = (torch.as_tensor(observer_offset(observer, origin, angle), dtype=torch.float32)
               if self.config.observer_input else None)
        return (torch.as_tensor(b - last[:, None], dtype=torch.float32),
                torch.as_tensor(last, dtype=torch.float32), obs, origin, angle)

    def forward(self, residual: torch.Tensor, last: torch.Tensor,
                observer: torch.Tensor | None = None) -> torch.Tensor:
        """Differentiable body-frame forecast (B, F, 45), decimetres (what training fits;
        the root as the network predicts it). ``observer``: (B, 3) observer input
        (:func:`observer_offset`), used with ``observer_input`` (None: unknown)."""
        if not self.config.observer_input:
            observer = None
        elif observer is None:
            observer = torch.zeros(len(last), OBSERVER_DIMS)
        return last[:, None, :] + self.net(residual, last, observer)

    def _root_path(self, history: np.ndarray) -> np.ndarray:
        """(N, F, 3) world displacement of the spine after the last frame, metres, for the
        ``damped`` / ``still`` root modes."""
        c = self.config
        n = len(history)
        if c.root_mode == "still":
            return np.zeros((n, c.future_len, 3))
        spine = history[:, :, _SPINE]
        v = (spine[:, -1] - spine[:, -1 - c.root_frames]) / c.root_frames * c.fps  # m/s
        k = np.arange(1, c.future_len + 1) / c.fps  # s after the last frame
        gain = c.root_tau_s * (1.0 - np.exp(-k / c.root_tau_s))  # s
        return v[:, None, :] * gain[None, :, None]

    # -- prediction ---------------------------------------------------------------------

    def check(self, history: Any) -> tuple[np.ndarray, bool]:
        """Validated (N, H, 15, 3) float64 history (its last H frames) and whether the
        input was batched.

        Raises:
            MotionError: not numeric, wrong shape, fewer than H frames, not 15 joints,
                a non-finite value (window, frame and joint named).
        """
        h, batched = check_history(history, self.history_len)
        if h.shape[2] != NUM_JOINTS:
            raise MotionError(f"history has {h.shape[2]} joints; this predictor expects "
                              f"{NUM_JOINTS} (simenv.data.gestures.GESTURE15_JOINTS: "
                              f"{', '.join(JOINTS)})", field="history")
        if len(h) == 0:
            raise MotionError("history holds no window", field="history")
        return h[:, -self.history_len:], batched

    def check_observer(self, observer: Any, n: int) -> np.ndarray | None:
        """Validated (n, 3) float64 observer positions (one (3,) position is shared by the
        n histories), or None.

        Raises:
            MotionError: not numeric, or neither (3,) nor (n, 3).
        """
        if observer is None:
            return None
        try:
            obs = np.asarray(observer, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise MotionError(f"observer is not numeric: {exc}", field="observer") from None
        if obs.shape == (3,):
            obs = np.broadcast_to(obs, (n, 3))
        if obs.shape != (n, 3):
            raise MotionError(f"observer must be (3,) or ({n}, 3) world positions, metres; "
                              f"got shape {obs.shape}", field="observer")
        return obs

    @torch.no_grad()
    def predict_batch(self, history: np.ndarray, observer: np.ndarray | None = None
                      ) -> np.ndarray:
        """Forecast the F frames after each of N histories.

        Args:
            history: (N, H', 15, 3) world positions, metres, Z up, at :attr:`fps`,
                H' >= H (the last H frames are used), ending at the last observed frame.
            observer: where the observer stands, world metres, Z up: (3,) for every
                history or (N, 3), a non-finite row for unknown; None: unknown. Used by a
                model with ``observer_input`` (step 4), ignored by one without.

        Returns:
            (N, F, 15, 3) float32 world positions, metres.

        Raises:
            MotionError: see :meth:`check` and :meth:`check_observer`; shoulders on top
                of each other.
        """
        h, _ = self.check(history if np.ndim(history) == 4 else np.asarray(history)[None])
        return self._predict(h, self.check_observer(observer, len(h)))

    def predict(self, history: np.ndarray, observer: np.ndarray | None = None) -> np.ndarray:
        """Forecast one history (H', 15, 3) -> (F, 15, 3), or a batch (N, H', 15, 3) ->
        (N, F, 15, 3); float32 world positions, metres (see :meth:`predict_batch`)."""
        h, batched = self.check(history)
        out = self._predict(h, self.check_observer(observer, len(h)))
        return out if batched else out[0]

    @torch.no_grad()
    def _world_forecast(self, h: np.ndarray, observer: np.ndarray | None) -> np.ndarray:
        """Steps 1-7: (N, F, 15, 3) float64 world metres, the root as the network has it."""
        residual, last, obs, origin, angle = self.inputs(h, observer)
        self.net.eval()
        body = self.forward(residual, last, obs).double().numpy() / UNIT
        return from_body(body.reshape(len(h), self.future_len, NUM_JOINTS, 3), origin, angle)

    def _predict(self, h: np.ndarray, observer: np.ndarray | None) -> np.ndarray:
        if self.config.mirror_average:  # both histories in one batch: one network call
            both_obs = (None if observer is None or not self.config.observer_input
                        else np.concatenate([observer, observer * (1.0, -1.0, 1.0)]))
            both = self._world_forecast(np.concatenate([h, mirror_world(h)]), both_obs)
            out = 0.5 * (both[:len(h)] + mirror_world(both[len(h):]))
        else:
            out = self._world_forecast(h, observer)
        if self.config.root_mode != "learned":
            spine = h[:, -1, _SPINE][:, None] + self._root_path(h)  # (N, F, 3)
            out = out - out[:, :, _SPINE:_SPINE + 1] + spine[:, :, None]
        return out.astype(np.float32)

    def variant(self, *, root_mode: str | None = None, root_tau_s: float | None = None,
                mirror_average: bool | None = None) -> GesturePredictor:
        """A predictor sharing this network with other inference settings: another
        :data:`ROOT_MODES` root (and decay time, s), mirror averaging on or off (None: as
        this one).

        Raises:
            MotionError: an unknown root mode, a decay time <= 0.
        """
        changes = {k: v for k, v in (("root_mode", root_mode), ("root_tau_s", root_tau_s),
                                     ("mirror_average", mirror_average)) if v is not None}
        config = GesturePredictorConfig(**{**asdict(self.config), **changes})
        config.check()
        other = GesturePredictor.__new__(GesturePredictor)
        other.config, other.net, other.name = config, self.net, self.name
        other.metadata = dict(self.metadata)
        return other

    # -- checkpoints --------------------------------------------------------------------

    def num_parameters(self) -> int:
        return sum(p.numel() for p in self.net.parameters())

    CHECKPOINT_FORMAT = CHECKPOINT_FORMAT

    def save(self, path: str | Path, metadata: dict[str, Any] | None = None) -> Path:
        """The checkpoint (:class:`~simenv.models.checkpoint.CheckpointMixin`), with the
        predictor's ``name`` in its metadata."""
        own = self.metadata if metadata is None else metadata
        return super().save(path, {"name": self.name, **own})

    def checkpoint_nets(self) -> dict[str, nn.Module]:
        return {"net": self.net}

    @classmethod
    def from_checkpoint(cls, checkpoint: Checkpoint) -> GesturePredictor:
        config = GesturePredictorConfig(**checkpoint.config)
        config.check()
        return cls(config, seed=0,
                   name=str(checkpoint.metadata.get("name", "predictor-gesture-25-50")))


def observer_offset(observer: np.ndarray | None, origin: np.ndarray, angle: np.ndarray
                    ) -> np.ndarray:
    """The network's observer input (step 4 of :class:`GesturePredictor`).

    Args:
        observer: (N, 3) world positions of the observer, metres (a non-finite row:
            unknown), or None (all unknown).
        origin: (N, 3) body-frame origins, metres. angle: (N,) headings, radians
            (:func:`body_frame`).

    Returns:
        (N, 3) float64: ``U·[R_z(-θ)(p - o)]_xy`` (decimetres) and 1 where the observer is
        known; 0, 0, 0 where it is not.
    """
    out = np.zeros((len(origin), OBSERVER_DIMS))
    if observer is None:
        return out
    known = np.isfinite(observer).all(axis=1)
    body = to_body(observer[known, None, None], origin[known], angle[known])[:, 0, 0]
    out[known, :2] = body[:, :2] * UNIT
    out[known, 2] = 1.0
    return out


def mirror_world(windows: np.ndarray) -> np.ndarray:
    """Left-right mirror of (..., 15, 3) world windows (Y negated, left/right swapped):
    still a valid world-frame motion, of a left-handed twin (training augmentation)."""
    return mirror_windows(windows, JOINTS)


def position_velocity_loss(pred: torch.Tensor, target: torch.Tensor, *,
                           horizon_weight: float = 0.0, speed_weight: float = 0.0,
                           speed_step: int = 5) -> torch.Tensor:
    """siMLPe's two terms on (B, F, 45) body-frame tensors (decimetres): mean per-joint
    Euclidean error of the positions plus that of the frame-to-frame velocities.

    ``horizon_weight`` a >= 0 weighs frame t by ``1 + a t / (F - 1)`` (normalised to mean
    1): favours the long horizons the per-frame mean trades for the easy first frames.
    ``speed_weight`` adds ``|‖p_{t+s} - p_t‖ - ‖q_{t+s} - q_t‖|`` (s = ``speed_step``
    frames, joints and frames averaged): a penalty on moving too slowly *or* too fast that
    ignores the direction, against the mean-regression of a deterministic forecast; over
    ``s`` frames so that Kinect jitter of the target does not set the speed.
    """
    p = pred.view(*pred.shape[:2], NUM_JOINTS, 3)
    t = target.view(*target.shape[:2], NUM_JOINTS, 3)
    pos = (p - t).norm(dim=-1).mean(dim=(0, 2))  # (F,)
    vel = ((p[:, 1:] - p[:, :-1]) - (t[:, 1:] - t[:, :-1])).norm(dim=-1).mean(dim=(0, 2))
    w = 1 + horizon_weight * torch.linspace(0, 1, p.shape[1])
    w = w / w.mean()
    loss = (pos * w).mean() + (vel * w[1:] / w[1:].mean()).mean()
    if speed_weight:
        sp = (p[:, speed_step:] - p[:, :-speed_step]).norm(dim=-1)
        st = (t[:, speed_step:] - t[:, :-speed_step]).norm(dim=-1)
        loss = loss + speed_weight * (sp - st).abs().mean()
    return loss

"""Reactive GAN: the reactor B generated from the actor A by a part-based LSTM generator
and a class-aware BiLSTM discriminator (Men et al., "GAN-based reactive motion synthesis
with class-aware discriminators for human-human interaction", 2022).

Data: windows of :mod:`simenv.data.interaction_data` ((N, T, J, 3) metres in the actor's
first-frame frame, J = 18 keypoints :data:`~simenv.data.interaction_data.INTER18_JOINTS`,
25 fps). Interface: :class:`~simenv.models.reaction_baselines.ReactionGenerator`,
``generate(actor_window, reactor_first_frame) -> reactor_window``.

Generator
---------
* **Body-part encoders.** The actor's 18 keypoints are partitioned into five parts
  (:data:`BODY_PARTS`; every joint in exactly one part):

  ==========  =============================================
  torso       pelvis, spine, neck, head
  left arm    left shoulder, elbow, wrist, hand
  right arm   right shoulder, elbow, wrist, hand
  left leg    left hip, knee, ankle
  right leg   right hip, knee, ankle
  ==========  =============================================

  Part ``p`` at frame ``t`` has the features ``u^p_t = [x^p_t, v^p_t]`` (positions,
  metres, and velocities ``v_t = (x_t - x_{t-1}) · fps / 10``, i.e. in units of 10 m/s
  so that both are O(0.1-1); ``v_0 = 0``), read by its own LSTM:
  ``e^p_t = LSTM_p(u^p_{≤t})``. The actor encoding is ``e_t = [e^1_t, ..., e^5_t]``.
* **Global attention** (Luong et al. 2015, "general" score), queried by the decoder
  state ``h_t``: ``α_ts = softmax_s(h_tᵀ W_a e_s)`` over all T actor frames,
  ``c_t = Σ_s α_ts e_s``, ``h̃_t = tanh(W_c [c_t; h_t])``.
* **LSTM decoder** from the reactor's given first frame ``b_0``: initial state
  ``(h_0, m_0) = tanh(W_0 [b_0; mean_s e_s])``; step ``t = 1..T-1`` reads
  ``[x̂_{t-1}, e_t, h̃_{t-1}, z]`` (its own previous pose, the actor encoding of the
  same frame, the previous attentional state — Luong's input feeding — and a noise
  vector ``z ~ N(0, I)`` held for the whole sequence) and outputs a displacement:
  ``x̂_t = x̂_{t-1} + W_o h̃_t / 10`` (decimetres to metres), ``x̂_0 = b_0``. ``W_o`` starts
  at zero, so the untrained generator is the zero-velocity baseline.

Discriminator
-------------
A BiLSTM over the reactor only: features ``[x_t, v_t]`` (as above, all 18 joints),
outputs averaged over time, ``f = mean_t [→h_t; ←h_t]``, then two heads:
``D(x) = σ(w_rfᵀ f)`` (real/fake) and ``K(x) = softmax(W_cls f)`` over ``N + 1`` classes
(the N interaction classes of the training windows plus "fake").

Losses (:func:`train`)
----------------------
Write ``x`` for a real reaction of class ``y``, ``x̂ = G(a, b_0, z)`` for a generated one.

* **Unsupervised GAN** (:func:`unsupervised_d_loss`, :func:`unsupervised_g_loss`), with
  one-sided label smoothing (real target ``s = 0.9``, fake target 0):
  ``L^D_un = -s log D(x) - (1 - s) log(1 - D(x)) - log(1 - D(x̂))``;
  ``L^G_un = -log D(x̂)`` (the non-saturating generator loss).
* **Supervised** (class-aware; :func:`supervised_d_loss`, :func:`supervised_g_loss`):
  ``L^D_sup = -log K_y(x) - log K_fake(x̂)``; ``L^G_sup = -log K_y(x̂)``: the generated
  reaction must be recognised as the interaction class of its actor.
* **L1 reconstruction** (:func:`l1_loss`): ``mean |x̂ - x|`` (frames 1..T-1), weight 1.
* **Bone length to the reference** (:func:`bone_length_loss`): ``mean_{t,k} |b̂_{t,k} -
  b^ref_k|``, ``b^ref`` the bone lengths of the reactor's given first frame, weight 0.01.
* **Continuity hinge** (:func:`continuity_loss`), weight 0.01, with ``dt = 1``, ``k = 5``:
  ``L_c = mean_t max(0, ||x̂_{t+dt} - x̂_t|| - ||x̂_{t+k} - x̂_t||)`` (flattened pose
  norms): a frame must stay closer to its immediate successor than to the frame ``k``
  steps on, which a smooth motion satisfies and a jittering or jumping one (a pose that
  leaves and comes back) violates. With the paper's ``k = 1`` (= dt) the two distances
  are the same and the hinge is identically 0, a constant with no gradient; ``k = 5``
  (0.2 s at 25 fps) makes it a real term.

Generator total: ``L^G_un + L^G_sup + L1 + 0.01 L_bone + 0.01 L_c`` (the adversarial
terms weighted by ``adv_weight``, 1 by default); discriminator: ``L^D_un + L^D_sup``.
Position terms are computed in decimetres (:data:`LOSS_UNIT`) so that an error of a few
centimetres gives an L1 of ~0.5, the size of the GAN terms at the paper's weight 1.

Paper vs ours
-------------
* Data: the paper trains on SBU / HHOI / 2C (15-joint Kinect skeletons, normalised
  coordinates); we train on 256 40-frame windows of real CMU + NuiSI pairs
  (salsa, rocket fist bump) in metres in the actor frame, doubled by left/right
  mirroring (negate y, swap left/right joints of both people: the actor frame is kept
  exactly, and the mirrored window is a real motion of mirrored bodies with the same
  label).
* Body parts: our partition of the 18 keypoints (table above), disjoint.
* Reactor first frame: the decoder starts from the given first frame of the reactor
  (the contract of simenv's reaction generators; the paper decodes the whole reaction)
  and predicts per-frame displacements with a zero-initialised output layer.
* Decoder input: besides the global attention context (paper), the decoder reads the
  actor encoding of its own frame ``e_t``: with 256 windows the attention alone is slow to
  learn the frame alignment.
* Attention is over all T actor frames (offline, as in the paper), so a generated frame
  may depend on later actor frames; windows longer than the trained one are generated
  chunk by chunk (:meth:`ReactiveGAN.generate`).
* Continuity hinge: our reading of the paper's term (above), with k = 5.
* Noise ``z``: 8-D, used in training; :meth:`ReactiveGAN.generate` uses ``z = 0`` unless
  a seed is given (deterministic evaluation).
* The generator is given no class label (``generate`` has none); the class supervises
  it only through the discriminator's class head.
* Sizes (CPU): part LSTMs of 32 units, decoder LSTM 128, discriminator BiLSTM 2 x 64;
  Adam (lr 1e-3, betas 0.5 / 0.999), batch 32, one discriminator step per generator
  step, 80 epochs over the 512 (mirrored) training windows: about 9 CPU minutes on one
  thread (the shipped checkpoint's card has the measured time).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F
from tqdm import tqdm

from simenv.core.errors import MotionError
from simenv.data import interaction_data as idata
from simenv.models.checkpoint import Checkpoint, CheckpointMixin
from simenv.models.reaction_baselines import check_inputs, mirror_index
from simenv.models.training import CpuBudget, seeded

#: Checkpoint format tag.
CHECKPOINT_FORMAT = "simenv-reactive-gan-1"
#: Positions enter the losses and the decoder output in decimetres.
LOSS_UNIT = 10.0
#: Velocity features are divided by this (m/s -> units of 10 m/s).
VELOCITY_SCALE = 10.0
#: The five body parts of the generator's encoders: name -> joints of INTER18_JOINTS.
BODY_PARTS: dict[str, tuple[str, ...]] = {
    "torso": ("pelvis", "spine", "neck", "head"),
    "left_arm": ("left_shoulder", "left_elbow", "left_wrist", "left_hand"),
    "right_arm": ("right_shoulder", "right_elbow", "right_wrist", "right_hand"),
    "left_leg": ("left_hip", "left_knee", "left_ankle"),
    "right_leg": ("right_hip", "right_knee", "right_ankle"),
}
NUM_JOINTS = len(idata.INTER18_JOINTS)
#: Parent index of each joint of the layout (-1 for the root).
PARENTS: tuple[int, ...] = tuple(idata.inter18_skeleton().parents)


def _part_index() -> list[list[int]]:
    names = list(idata.INTER18_JOINTS)
    parts = [[names.index(j) for j in joints] for joints in BODY_PARTS.values()]
    flat = sorted(j for p in parts for j in p)
    if flat != list(range(NUM_JOINTS)):  # the table above must stay a partition
        raise AssertionError("BODY_PARTS is not a partition of INTER18_JOINTS")
    return parts


PART_INDEX: list[list[int]] = _part_index()


@dataclass(frozen=True)
class ReactiveGANConfig:
    """Hyper-parameters (JSON-able; saved in checkpoints).

    ``labels`` are the N interaction classes of the class head (filled in by
    :func:`train` from the training windows); ``window`` the training window length in
    frames (also the chunk length of long generation).
    """

    labels: tuple[str, ...] = ()
    window: int = idata.WINDOW_FRAMES
    fps: float = idata.TARGET_FPS
    part_hidden: int = 32
    decoder_hidden: int = 128
    disc_hidden: int = 64
    noise_dim: int = 8
    epochs: int = 80
    batch_size: int = 32
    lr_g: float = 1e-3
    lr_d: float = 1e-3
    adv_weight: float = 1.0
    l1_weight: float = 1.0
    bone_weight: float = 0.01
    continuity_weight: float = 0.01
    continuity_dt: int = 1
    continuity_k: int = 5
    real_label: float = 0.9
    mirror: bool = True
    max_minutes: float | None = None

    @property
    def num_classes(self) -> int:
        return len(self.labels)


# -- features --------------------------------------------------------------------------


def motion_features(x: torch.Tensor, fps: float) -> torch.Tensor:
    """(B, T, J, 3) positions, metres -> (B, T, J, 6) ``[x_t, v_t]`` with
    ``v_t = (x_t - x_{t-1}) fps / VELOCITY_SCALE`` and ``v_0 = 0``."""
    v = torch.zeros_like(x)
    v[:, 1:] = (x[:, 1:] - x[:, :-1]) * (fps / VELOCITY_SCALE)
    return torch.cat([x, v], dim=-1)


# -- networks --------------------------------------------------------------------------


class PartEncoder(nn.Module):
    """Five body-part LSTMs over the actor: (B, T, J, 3) -> e (B, T, 5 · part_hidden)."""

    def __init__(self, hidden: int, fps: float) -> None:
        super().__init__()
        self.fps = fps
        self.lstms = nn.ModuleList(nn.LSTM(6 * len(p), hidden, batch_first=True)
                                   for p in PART_INDEX)

    def forward(self, actor: torch.Tensor) -> torch.Tensor:
        u = motion_features(actor, self.fps)
        b, t = u.shape[:2]
        outs = [lstm(u[:, :, idx].reshape(b, t, -1))[0]
                for lstm, idx in zip(self.lstms, PART_INDEX, strict=True)]
        return torch.cat(outs, dim=-1)


class GlobalAttention(nn.Module):
    """Luong "general" attention: ``α_s = softmax(hᵀ W_a e_s)``, ``c = Σ α_s e_s``,
    ``h̃ = tanh(W_c [c; h])``."""

    def __init__(self, query: int, memory: int) -> None:
        super().__init__()
        self.w_a = nn.Linear(query, memory, bias=False)
        self.w_c = nn.Linear(query + memory, query)

    def forward(self, h: torch.Tensor, memory: torch.Tensor
                ) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, H) query, (B, T, E) memory -> h̃ (B, H), weights (B, T)."""
        scores = torch.einsum("be,bte->bt", self.w_a(h), memory)
        alpha = torch.softmax(scores, dim=-1)
        context = torch.einsum("bt,bte->be", alpha, memory)
        return torch.tanh(self.w_c(torch.cat([context, h], dim=-1))), alpha


class Generator(nn.Module):
    """Part encoders -> global attention -> LSTM decoder from ``b_0`` (module docstring)."""

    def __init__(self, config: ReactiveGANConfig) -> None:
        super().__init__()
        self.noise_dim = config.noise_dim
        self.hidden = config.decoder_hidden
        memory = 5 * config.part_hidden
        pose = 3 * NUM_JOINTS
        self.encoder = PartEncoder(config.part_hidden, config.fps)
        self.init = nn.Linear(pose + memory, 2 * self.hidden)
        self.cell = nn.LSTMCell(pose + memory + self.hidden + self.noise_dim, self.hidden)
        self.attention = GlobalAttention(self.hidden, memory)
        self.out = nn.Linear(self.hidden, pose)
        nn.init.zeros_(self.out.weight)  # start as the zero-velocity baseline
        nn.init.zeros_(self.out.bias)

    def forward(self, actor: torch.Tensor, first: torch.Tensor,
                z: torch.Tensor | None = None) -> torch.Tensor:
        """(B, T, J, 3) actor, (B, J, 3) reactor first frame, (B, noise_dim) noise (zeros
        if None) -> (B, T, J, 3) reactor, metres, frame 0 = ``first``."""
        b, t = actor.shape[:2]
        if z is None:
            z = actor.new_zeros(b, self.noise_dim)
        memory = self.encoder(actor)
        prev = first.reshape(b, -1)
        h, m = torch.tanh(self.init(torch.cat([prev, memory.mean(dim=1)], -1))).chunk(2, -1)
        h, m = h.contiguous(), m.contiguous()
        feed = actor.new_zeros(b, self.hidden)
        frames = [prev]
        for step in range(1, t):
            h, m = self.cell(torch.cat([prev, memory[:, step], feed, z], -1), (h, m))
            feed, _ = self.attention(h, memory)
            prev = prev + self.out(feed) / LOSS_UNIT
            frames.append(prev)
        return torch.stack(frames, dim=1).reshape(b, t, NUM_JOINTS, 3)


class Discriminator(nn.Module):
    """BiLSTM over the reactor, time-averaged, with a real/fake logit and N + 1 class
    logits: (B, T, J, 3) -> ((B,), (B, N + 1))."""

    def __init__(self, config: ReactiveGANConfig) -> None:
        super().__init__()
        self.fps = config.fps
        self.lstm = nn.LSTM(6 * NUM_JOINTS, config.disc_hidden, batch_first=True,
                            bidirectional=True)
        self.real_fake = nn.Linear(2 * config.disc_hidden, 1)
        self.classes = nn.Linear(2 * config.disc_hidden, config.num_classes + 1)

    def forward(self, reactor: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        u = motion_features(reactor, self.fps)
        f = self.lstm(u.reshape(u.shape[0], u.shape[1], -1))[0].mean(dim=1)
        return self.real_fake(f)[:, 0], self.classes(f)


# -- losses ----------------------------------------------------------------------------


def unsupervised_d_loss(real_logit: torch.Tensor, fake_logit: torch.Tensor,
                        real_label: float = 0.9) -> torch.Tensor:
    """``mean BCE(D(x), s) + mean BCE(D(x̂), 0)``: (B,) logits, one-sided smoothing ``s``."""
    return (F.binary_cross_entropy_with_logits(real_logit,
                                               torch.full_like(real_logit, real_label))
            + F.binary_cross_entropy_with_logits(fake_logit, torch.zeros_like(fake_logit)))


def unsupervised_g_loss(fake_logit: torch.Tensor) -> torch.Tensor:
    """Non-saturating ``mean -log D(x̂)`` of (B,) logits."""
    return F.binary_cross_entropy_with_logits(fake_logit, torch.ones_like(fake_logit))


def supervised_d_loss(real_classes: torch.Tensor, fake_classes: torch.Tensor,
                      labels: torch.Tensor) -> torch.Tensor:
    """``mean -log K_y(x) + mean -log K_fake(x̂)``: (B, N + 1) logits, (B,) labels in
    [0, N); the last class is "fake"."""
    fake = torch.full_like(labels, real_classes.shape[1] - 1)
    return F.cross_entropy(real_classes, labels) + F.cross_entropy(fake_classes, fake)


def supervised_g_loss(fake_classes: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
    """``mean -log K_y(x̂)``: the generated reaction classified as its actor's class."""
    return F.cross_entropy(fake_classes, labels)


def l1_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """``mean |x̂ - x|`` of (B, T, J, 3) positions (in the caller's unit)."""
    return (pred - target).abs().mean()


def bone_length_loss(pred: torch.Tensor, reference: torch.Tensor,
                     parents: Sequence[int] = PARENTS) -> torch.Tensor:
    """``mean_{b,t,k} |b̂_{b,t,k} - b^ref_{b,k}|``: bone lengths of (B, T, J, 3) frames
    against those of (B, J, 3) reference poses (the caller's unit)."""
    child = [j for j, p in enumerate(parents) if p >= 0]
    par = [parents[j] for j in child]
    bones = (pred[..., child, :] - pred[..., par, :]).norm(dim=-1)
    ref = (reference[..., child, :] - reference[..., par, :]).norm(dim=-1)
    return (bones - ref[:, None]).abs().mean()


def continuity_loss(pred: torch.Tensor, dt: int = 1, k: int = 5) -> torch.Tensor:
    """Continuity hinge ``mean_t max(0, ||x̂_{t+dt} - x̂_t|| - ||x̂_{t+k} - x̂_t||)`` over
    ``t = 0..T-1-max(dt, k)`` of (B, T, J, 3) frames (flattened pose norms); identically
    0 for ``k == dt`` (module docstring).

    Raises:
        MotionError: ``dt`` or ``k`` < 1, or the sequence is too short for them.
    """
    span = max(dt, k)
    if dt < 1 or k < 1 or pred.shape[1] <= span:
        raise MotionError(f"continuity hinge needs dt, k >= 1 and more than max(dt, k) "
                          f"frames; got dt={dt}, k={k}, {pred.shape[1]} frames",
                          field="continuity_k")
    x = pred.flatten(2)
    n = x.shape[1] - span
    near = (x[:, dt:dt + n] - x[:, :n]).norm(dim=-1)
    far = (x[:, k:k + n] - x[:, :n]).norm(dim=-1)
    return torch.relu(near - far).mean()


# -- the model -------------------------------------------------------------------------


def _chunks(length: int, window: int) -> list[tuple[int, int]]:
    """[start, stop) chunks of at most ``window`` frames, consecutive chunks sharing one
    frame (the last generated frame of one chunk is the first frame of the next)."""
    out, start = [], 0
    while True:
        stop = min(start + window, length)
        out.append((start, stop))
        if stop == length:
            return out
        start = stop - 1


class ReactiveGAN(CheckpointMixin):
    """The trained reactive GAN: generator, discriminator and config.

    ``generate(actor_window, reactor_first_frame)``: (N, T, J, 3) / (T, J, 3) actor and
    (N, J, 3) / (J, 3) reactor first frame, metres, one Z-up frame shared by both people ->
    float32 reactor of the actor's shape (frame 0 = the given first frame). Each chunk of
    at most ``config.window`` frames is mapped into the actor frame of its first actor
    frame (:func:`~simenv.data.interaction_data.actor_frame`, as the training windows are),
    generated there and mapped back; a chunk starts from the last generated frame of the
    previous one. Any ``T >= 2``.
    """

    name = "reactive-gan"

    def __init__(self, config: ReactiveGANConfig) -> None:
        if config.num_classes < 1:
            raise MotionError("ReactiveGANConfig.labels is empty; the class head needs the "
                              "interaction classes", field="labels")
        if config.window < 2:
            raise MotionError(f"window must be >= 2 frames; got {config.window}",
                              field="window")
        self.config = config
        self.metadata: dict[str, Any] = {}
        self.generator = Generator(config)
        self.discriminator = Discriminator(config)

    def _generate_chunk(self, actor: np.ndarray, first: np.ndarray,
                        z: torch.Tensor) -> np.ndarray:
        origin, yaw = idata.actor_frame(actor[:, 0])
        a = idata.normalise(actor, origin, yaw)
        b0 = idata.normalise(first[:, None], origin, yaw)[:, 0]
        with torch.no_grad():
            out = self.generator(torch.as_tensor(a), torch.as_tensor(b0), z).double().numpy()
        return idata.denormalise(out, origin, yaw).astype(np.float64)

    def generate(self, actor_window: np.ndarray, reactor_first_frame: np.ndarray, *,
                 seed: int | None = None) -> np.ndarray:
        """The reactor's window (class docstring); ``seed`` draws the noise ``z`` (one per
        window), else ``z = 0``.

        Raises:
            MotionError: bad shapes or non-finite input (``check_inputs``), fewer than 2
                frames, or an actor pose without a facing direction.
        """
        a, b, batched = check_inputs(actor_window, reactor_first_frame, NUM_JOINTS)
        if a.shape[1] < 2:
            raise MotionError(f"actor_window needs at least 2 frames; got {a.shape[1]}",
                              field="actor_window")
        self.generator.eval()
        if seed is None:
            z = torch.zeros(len(a), self.config.noise_dim)
        else:
            gen = torch.Generator().manual_seed(int(seed))
            z = torch.randn(len(a), self.config.noise_dim, generator=gen)
        out = np.empty_like(a)
        out[:, 0] = b
        for start, stop in _chunks(a.shape[1], self.config.window):
            out[:, start:stop] = self._generate_chunk(a[:, start:stop], out[:, start], z)
        out = out.astype(np.float32)
        return out if batched else out[0]

    # -- checkpoints -----------------------------------------------------------------------

    CHECKPOINT_FORMAT = CHECKPOINT_FORMAT

    def checkpoint_nets(self) -> dict[str, nn.Module]:
        return {"generator": self.generator, "discriminator": self.discriminator}

    @classmethod
    def from_checkpoint(cls, checkpoint: Checkpoint) -> ReactiveGAN:
        raw = dict(checkpoint.config)
        raw["labels"] = tuple(raw["labels"])
        return cls(ReactiveGANConfig(**raw))


# -- training --------------------------------------------------------------------------


def mirror_windows(x: np.ndarray) -> np.ndarray:
    """Left/right mirror image of (..., J, 3) actor-frame poses: negate y, swap the
    left and right joints (keeps the actor frame; module docstring)."""
    out = np.array(x[..., mirror_index(idata.INTER18_JOINTS), :], copy=True)
    out[..., 1] *= -1
    return out


#: The loss terms :func:`gan_step` returns, in the order of the training history.
LOSS_TERMS: tuple[str, ...] = ("loss", "d_loss", "l1", "bone", "continuity", "g_unsup",
                               "g_sup", "d_unsup", "d_sup")


def _check_windows(windows: idata.InteractionWindows, window: int) -> None:
    if len(windows) == 0:
        raise MotionError("no training windows", field="train")
    if tuple(windows.joint_names) != idata.INTER18_JOINTS:
        raise MotionError("training windows must be on INTER18_JOINTS", field="train")
    if windows.window < max(2, window):
        raise MotionError(f"training windows have {windows.window} frames; config.window "
                          f"is {window}", field="train")
    for name in ("actor", "reactor"):
        if not np.isfinite(getattr(windows, name)).all():
            raise MotionError(f"training {name} windows have a non-finite value",
                              field=name)


def train(train: idata.InteractionWindows, config: ReactiveGANConfig | None = None, *,
          seed: int = 0, progress: bool = True,
          validation: idata.InteractionWindows | None = None
          ) -> tuple[ReactiveGAN, dict[str, Any]]:
    """Train a reactive GAN on interaction windows (module docstring for the losses).

    Args:
        train: training windows (actor frame, metres); ``train.labels`` become the class
            head's N classes unless ``config.labels`` is set.
        config: hyper-parameters (defaults: the shipped CPU configuration).
        seed: seeds torch and numpy (batches, noise, initial weights).
        progress: show a tqdm bar.
        validation: windows to score after every epoch (for choosing the epoch count on
            recordings other than the test ones; never the test split).

    Returns:
        ``(model, history)``: per-epoch means ``"loss"`` (generator total), ``"d_loss"``,
        ``"l1"``, ``"bone"``, ``"continuity"``, ``"g_unsup"``, ``"g_sup"``, ``"d_unsup"``,
        ``"d_sup"`` (position terms in decimetres), ``"cpu_seconds"``, ``"epochs"``,
        ``"windows"`` (after augmentation); with ``validation`` also
        ``"val_joint_error_mm"``, the per-epoch mean joint error of frames 1..T-1 (z = 0).
    """
    config = config or ReactiveGANConfig()
    if not config.labels:
        config = ReactiveGANConfig(**{**asdict(config), "labels": tuple(train.labels)})
    if not set(train.labels) <= set(config.labels):
        raise MotionError(f"training labels {train.labels} are not among the config's "
                          f"{config.labels}", field="labels")
    _check_windows(train, config.window)
    rng = seeded(seed)
    a_all, b_all, y_all = _training_tensors(train, config)
    model = ReactiveGAN(config)
    g, d = model.generator, model.discriminator
    opt_g = torch.optim.Adam(g.parameters(), lr=config.lr_g, betas=(0.5, 0.999))
    opt_d = torch.optim.Adam(d.parameters(), lr=config.lr_d, betas=(0.5, 0.999))
    history: dict[str, Any] = {k: [] for k in LOSS_TERMS}
    if validation is not None:
        history["val_joint_error_mm"] = []
    budget = CpuBudget(config.max_minutes)
    bar = tqdm(range(config.epochs), desc="train reactive-gan", disable=not progress)
    for _ in bar:
        g.train()
        d.train()
        sums = dict.fromkeys(LOSS_TERMS, 0.0)
        order = rng.permutation(len(a_all))
        batches = [order[i:i + config.batch_size]
                   for i in range(0, len(order), config.batch_size)]
        for idx in batches:
            terms = gan_step(model, opt_g, opt_d, a_all[idx], b_all[idx], y_all[idx])
            for key, value in terms.items():
                sums[key] += float(value.detach()) * len(idx)
        for key in LOSS_TERMS:
            history[key].append(sums[key] / len(a_all))
        if validation is not None:
            pred = model.generate(validation.actor, validation.reactor[:, 0])
            err = np.linalg.norm(pred[:, 1:] - validation.reactor[:, 1:], axis=-1).mean()
            history["val_joint_error_mm"].append(float(1000.0 * err))
        bar.set_postfix(g=f"{history['loss'][-1]:.3f}", l1=f"{history['l1'][-1]:.3f}",
                        d=f"{history['d_loss'][-1]:.3f}")
        if budget.exceeded():
            break
    history["cpu_seconds"] = round(budget.seconds(), 1)
    history["epochs"] = len(history["loss"])
    history["windows"] = len(a_all)
    g.eval()
    d.eval()
    return model, history


def _training_tensors(train: idata.InteractionWindows, config: ReactiveGANConfig
                      ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(N, T, J, 3) actor and reactor windows cut to ``config.window`` frames and their
    (N,) class indices in ``config.labels``, doubled by the mirror images when
    ``config.mirror``."""
    label_map = np.array([config.labels.index(name) for name in train.labels])
    actor, reactor = train.actor[:, :config.window], train.reactor[:, :config.window]
    labels = label_map[train.label]
    if config.mirror:
        actor = np.concatenate([actor, mirror_windows(actor)])
        reactor = np.concatenate([reactor, mirror_windows(reactor)])
        labels = np.concatenate([labels, labels])
    return (torch.as_tensor(actor, dtype=torch.float32),
            torch.as_tensor(reactor, dtype=torch.float32),
            torch.as_tensor(labels, dtype=torch.int64))


def gan_step(model: ReactiveGAN, opt_g: torch.optim.Optimizer, opt_d: torch.optim.Optimizer,
             a: torch.Tensor, b: torch.Tensor, y: torch.Tensor) -> dict[str, torch.Tensor]:
    """One discriminator step, then one generator step, on a batch (module docstring).

    Args:
        model: the GAN being trained. opt_g, opt_d: the generator's and discriminator's
            optimisers.
        a, b: (B, T, J, 3) actor and reactor windows, metres. y: (B,) class indices.

    Returns:
        Every term of :data:`LOSS_TERMS` (``loss``: the generator's total; position terms
        in decimetres), scalars.
    """
    config = model.config
    g, d = model.generator, model.discriminator
    z = torch.randn(len(a), config.noise_dim)
    fake = g(a, b[:, 0], z)

    real_rf, real_cls = d(b)
    fake_rf, fake_cls = d(fake.detach())
    d_unsup = unsupervised_d_loss(real_rf, fake_rf, config.real_label)
    d_sup = supervised_d_loss(real_cls, fake_cls, y)
    opt_d.zero_grad()
    (d_unsup + d_sup).backward()
    opt_d.step()

    fake_rf, fake_cls = d(fake)
    g_unsup = unsupervised_g_loss(fake_rf)
    g_sup = supervised_g_loss(fake_cls, y)
    fake_u, real_u = LOSS_UNIT * fake, LOSS_UNIT * b
    l1 = l1_loss(fake_u[:, 1:], real_u[:, 1:])
    bone = bone_length_loss(fake_u[:, 1:], real_u[:, 0])
    cont = continuity_loss(fake_u, config.continuity_dt, config.continuity_k)
    g_loss = (config.adv_weight * (g_unsup + g_sup) + config.l1_weight * l1
              + config.bone_weight * bone + config.continuity_weight * cont)
    opt_g.zero_grad()
    g_loss.backward()
    opt_g.step()
    return {"loss": g_loss, "d_loss": d_unsup + d_sup, "l1": l1, "bone": bone,
            "continuity": cont, "g_unsup": g_unsup, "g_sup": g_sup, "d_unsup": d_unsup,
            "d_sup": d_sup}

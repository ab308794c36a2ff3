"""PredictiveMA-WGAN: history SRVF -> future SRVF through a WGAN-GP in the tangent space.

The model of the thesis (Chopin 2023, ch. 2) and the MA-GAN journal paper, on the
geometry of :mod:`simenv.core.srvf` and the windows of :mod:`simenv.data.prediction_data`.

Pipeline (one window; P observed frames, F to predict, 17 joints, D = 51)
-------------------------------------------------------------------------
1. **Heading.** Rotate the whole window about the vertical (Z) axis so that the hip
   axis (left hip - right hip) of the last observed pose points along +X. SRVFs commute
   with rotations, so this changes nothing geometric; it removes the facing direction,
   which is arbitrary in mocap and otherwise has to be learnt from very few clips.
   Predictions are rotated back.
2. **Curves to the sphere.** Past curve ``[lead_in, past]`` (P steps) and future curve
   ``[past[-1], future]`` (F steps) -> SRVFs ``q`` -> unit points ``p = q / ||q||`` and
   amplitudes ``a = ||q|| = sqrt(curve length)``.
3. **Tangent spaces.** Two Karcher means (step 0.9) over the *training* windows: ``μ_P``
   of the past points and ``μ_F`` of the future points (the paper leaves open whether
   one mean is shared; with P != F (25 -> 50) the spheres differ anyway, and the future
   distribution is not the past one). History ``v_P = log_{μ_P}(p_P)``; target
   ``v_F = log_{μ_F}(p_F)``. The generator maps ``T_{μ_P} -> T_{μ_F}`` directly, so no
   parallel transport is needed (the net learns the correspondence between the two
   tangent spaces; transport would only fix one arbitrary identification of them).
   Networks see tangent vectors in *isometric* coordinates (``v / sqrt(n)``, whose
   Euclidean norm is the sphere norm ``||v||``) multiplied by one scalar per side that
   makes the training data unit-RMS.
4. **Generator.** ``G(v_P, log a_P, x_T, z) -> ṽ``, then ``ṽ`` is projected onto
   ``T_{μ_F}`` (``ṽ - <ṽ, μ_F> μ_F``) and mapped to the sphere with ``exp_{μ_F}``.
5. **Amplitude.** A small head predicts ``log a_F - log a_P`` from the same condition
   (the colleague's measurement: carrying ``a_P`` correlates only 0.35 with ``a_F``).
   The alternative "carried" amplitude ``a_P sqrt(F / P)`` (same mean speed) is
   available for comparison (``amplitude="carried"``), and with a prior (item 7) the
   prior future's own amplitude ``ã`` (``amplitude="prior"``). By default the head is
   trained on its own (:func:`amplitude_loss`: the position error at the generator's
   direction, or with ``target="true"`` the L1 error of ``log a_F`` itself, which does
   not reward a shorter curve) and the generator at the true amplitude; with
   ``joint_amplitude`` (:func:`generator_loss`) both are trained together on the
   position losses at the predicted amplitude (measured in docs/prediction.md).
6. **Integration without a seam.** ``q̂ = â p̂`` is integrated from the last observed
   pose ``x_T`` with the exact inverse SRVF, ``x̂_k = x_T + (1/F) Σ_{i<k} q̂_i |q̂_i|``,
   so the predicted motion starts exactly where the history ends.
7. **Residual to a prior future** (optional, ``prior``; not in the papers). A cheap
   prior future ``x̃_k = x_T + Σ_t W[t, k] (x_t - x_T)`` (one temporal filter ``W``
   shared by all joint coordinates, fitted on the training windows by
   :func:`fit_prior`: the last velocity continued and damped, or a ridge least-squares
   filter) is mapped like a true future, ``[x_T, x̃]`` -> SRVF -> ``p̃``, ``ã``,
   ``ũ = log_{μ_F}(p̃)`` (scaled coordinates). The generator then outputs a
   *correction*, ``ṽ = ũ + G(·)``, and the head ``log â = log ã + h(·)`` (instead of
   ``log a_P + h(·)``); their last layers start at zero, so the untrained model predicts
   the prior. The tangent space stays the one at ``μ_F``; the critic judges the full
   ``ṽ``. Why: without it the generator's output correlated 0.026 with the true
   future tangent coordinates and the head shrank the curve to a median 0.18 of the
   true length (zero-velocity); the prior gives the nets a reference that already
   carries the history's motion.
8. **Test-time mirror averaging** (optional, ``mirror_average``): the prediction is
   ``½ (f(h) + M f(M h))``, ``M`` the left-right mirror (:func:`mirror`); it makes the
   predictor exactly mirror-equivariant, as the mirrored training data asks.
9. **Bone lengths restored** (optional, ``restore_bones``; not in the papers): every
   predicted frame, and the prior future of item 7 before it is mapped to the sphere,
   is rebuilt from the pelvis outwards with the bone lengths of the last observed pose
   along the predicted bone directions, ``x̂_j <- x̂_{parent(j)} + b_j d_j / |d_j|``
   (:func:`restore_bone_lengths`; in :meth:`PredictiveMAWGAN.decode` too, so the
   training losses see the frames that are predicted; at prediction after the mirror
   average of item 8, since the mean of two poses has shorter bones). Why: the drift enters at the
   prior (a linear filter blends poses, which shortens and lengthens bones: 20.5 mm
   mean drift on the 25-25 validation clips) and the tangent-space output inherits it
   (14.6 mm); nothing in the SRVF integration keeps a bone rigid, and the bone loss
   only discourages the drift. With the restoration the drift is zero by construction.

Networks (paper -> here, scaled for a 1-thread CPU budget of minutes)
---------------------------------------------------------------------
* Generator: paper FC to 36,864 then 5 upsampling conv blocks. Here: FC(cond -> 512) ->
  FC(512 -> 256 · L_0) -> reshape (256 channels, L_0 steps) -> 5 blocks of
  [linear upsampling in time to ``L_k = ceil(F / 2^(5-k))`` -> Conv1d(k=3) -> LeakyReLU
  0.2], the 5th conv giving the 51 channels of ``ṽ`` with no activation. Convolutions
  run over time with joints x coordinates as channels (1-D; the paper's 2-D image
  layout would treat adjacent coordinates of different joints as neighbours).
* Critic: 3 conv blocks (Conv1d k=3 stride 2 + LeakyReLU 0.2; 64, 128, 128 channels;
  no normalisation, as WGAN-GP requires) -> FC 1024 -> FC 1, as in the paper. It is
  conditional: its input is ``ṽ`` plus an embedding (FC 64) of the condition broadcast
  over time, so it judges whether the future fits the history.
* Condition: the paper's generator sees the history tangent vector only. We also give
  it ``log a_P`` and the last observed pose ``x_T`` (heading-normalised, decimetres):
  the SRVF forgets where the curve is, yet the next motion depends on the pose (the
  phase of a gait, a raised arm). With ``velocity_condition`` also the last velocity
  ``x_T - x_{T-1}`` (unit-RMS over the training windows): the tangent vector at ``μ_P``
  holds it only as one of P steps of a unit-norm function. Noise ``z`` (16-D, N(0, 1))
  in training; ``z = 0`` at prediction unless a seed is given.

Losses (weights 1, 1, 10, 10 as in the paper)
---------------------------------------------
``L_G = 1 · L_adv + 1 · L_rec + 10 · L_gram + 10 · L_bone`` with

* ``L_adv = -E[C(ṽ)]`` (WGAN); the critic minimises ``E[C(ṽ)] - E[C(v_F)] + λ GP``,
  ``GP = E[(||∇C(v̄)|| - 1)²]`` at random interpolates ``v̄``, λ = 10;
* ``L_rec``: L1 between predicted and true future joint positions (integrated with the
  true amplitude during training, so the generator learns the direction and the head
  the amplitude). The reference repo puts L1 on the SRVF/tangent vectors; we put it on
  the positions, which is what MPJPE measures;
* ``L_gram``: Gram/Procrustes skeleton integrity: per frame, the Gram matrix ``X Xᵀ``
  (J x J) of the centred pose is invariant to rotations, so comparing predicted and
  true Gram matrices penalises shape changes but not a rigid rotation;
  ``mean |Ĝ - G|``;
* ``L_bone``: ``mean |b̂ - b_T|``, predicted bone lengths against those of the last
  observed pose (the subject's skeleton does not change).

Positions enter the losses in decimetres so that, at the paper's weights, all four
terms have comparable size (errors of a few cm give L1 ~ 0.5). Optimiser: Adam lr
1e-4, betas (0.5, 0.9) (WGAN-GP's), batch 64; critic steps per generator step is a
training option (the WGAN-GP default 5; fewer fit a minutes-long CPU budget).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from simenv.core import srvf
from simenv.core.errors import MotionError
from simenv.data.prediction_data import PRED17_JOINTS, PRED17_LAYOUT, PredictionWindows
from simenv.models.baselines import check_history
from simenv.models.checkpoint import Checkpoint, CheckpointError, CheckpointMixin

NUM_JOINTS = 17
DIMS = 3 * NUM_JOINTS
#: Indices of the hips in the pred17 layout (heading from the hip axis).
RIGHT_HIP, LEFT_HIP = PRED17_JOINTS.index("right_hip"), PRED17_JOINTS.index("left_hip")
PARENTS: tuple[int, ...] = tuple(
    -1 if p is None else PRED17_JOINTS.index(p) for _, p in PRED17_LAYOUT
)
#: Positions are multiplied by this inside the losses (metres -> decimetres).
LOSS_UNIT = 10.0
#: Loss weights of the paper: adversarial, L1 reconstruction, Gram, bone length.
LOSS_WEIGHTS = {"adv": 1.0, "rec": 1.0, "gram": 10.0, "bone": 10.0}
GP_LAMBDA = 10.0
#: Format tag of checkpoint files.
CHECKPOINT_FORMAT = "simenv-predictive-ma-wgan-1"
#: Prior futures the networks can correct (:func:`fit_prior`).
PRIORS = ("none", "damped_velocity", "linear")
#: How the future amplitude is restored (:meth:`PredictiveMAWGAN.log_amplitude`).
AMPLITUDES = ("predicted", "carried", "prior")
#: What the amplitude head is trained against (:func:`amplitude_loss`).
AMPLITUDE_TARGETS = ("positions", "true")


# -- heading normalisation ------------------------------------------------------


def heading(pose: np.ndarray) -> np.ndarray:
    """Angle (rad) about Z of the hip axis (left hip - right hip) of (N, 17, 3) poses."""
    axis = pose[..., LEFT_HIP, :2] - pose[..., RIGHT_HIP, :2]
    return np.arctan2(axis[..., 1], axis[..., 0])


def rotate_z(points: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotate (N, ..., 3) points by ``angle`` (N,) radians about the Z axis."""
    c, s = np.cos(angle), np.sin(angle)
    shape = (-1,) + (1,) * (points.ndim - 2)
    c, s = c.reshape(shape), s.reshape(shape)
    x, y = points[..., 0], points[..., 1]
    return np.stack([c * x - s * y, s * x + c * y, points[..., 2]], axis=-1)


def _mirror_index() -> list[int]:
    swap = {n: n.replace("left_", "@").replace("right_", "left_").replace("@", "right_")
            for n in PRED17_JOINTS}
    return [PRED17_JOINTS.index(swap[n]) for n in PRED17_JOINTS]


#: Joint permutation that swaps left and right in the pred17 layout.
MIRROR: tuple[int, ...] = tuple(_mirror_index())


def mirror(frames: np.ndarray) -> np.ndarray:
    """Left-right mirror image of (..., 17, 3) poses: negate X, swap left/right joints
    (a real motion of the mirrored body; used to double the training data)."""
    out = np.array(frames[..., list(MIRROR), :], copy=True)
    out[..., 0] *= -1
    return out


# -- torch versions of the sphere maps (same inner product as simenv.core.srvf) ---------


def t_inner(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``<a, b> = (1/n) Σ_i a_i · b_i`` of (B, n, D) step functions; shape (B,)."""
    return (a * b).sum(dim=(-2, -1)) / a.shape[-2]


def t_project_tangent(mu: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """``v - <v, μ> μ``: projection of (B, n, D) ``v`` onto ``T_μ S`` (unit (n, D) μ)."""
    return v - t_inner(v, mu.expand_as(v))[:, None, None] * mu


def t_exp(mu: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """``exp_μ(v) = cos(||v||) μ + sin(||v||) v / ||v||`` for tangent (B, n, D) ``v``."""
    nv = torch.sqrt(t_inner(v, v) + 1e-12)[:, None, None]
    out = torch.cos(nv) * mu + torch.sin(nv) / nv * v
    return out / torch.sqrt(t_inner(out, out))[:, None, None]


def t_inverse_srvf(q: torch.Tensor, start: torch.Tensor) -> torch.Tensor:
    """Samples 1..n of the curve with SRVF (B, n, D) ``q`` from (B, D) ``start``:
    ``c_k = c_0 + (1/n) Σ_{i<k} q_i |q_i|``; shape (B, n, D) (``c_0`` excluded)."""
    speed = torch.sqrt((q * q).sum(dim=-1, keepdim=True) + 1e-12)
    return start[:, None, :] + torch.cumsum(q * speed, dim=1) / q.shape[1]


# -- networks -----------------------------------------------------------------------


def _schedule(length: int, blocks: int = 5) -> list[int]:
    """Time lengths ``ceil(F / 2^(blocks-k))``, k = 0..blocks, ending at F."""
    return [max(1, math.ceil(length / 2 ** (blocks - k))) for k in range(blocks + 1)]


class Generator(nn.Module):
    """FC -> reshape -> 5 upsampling Conv1d blocks: condition (+ noise) -> (B, F, 51)."""

    def __init__(self, cond_dim: int, future_len: int, noise_dim: int = 16,
                 hidden: int = 512, channels: Sequence[int] = (256, 128, 128, 64, 64),
                 dropout: float = 0.0) -> None:
        super().__init__()
        self.noise_dim = noise_dim
        self.lengths = _schedule(future_len)
        self.c0 = channels[0]
        self.fc = nn.Sequential(
            nn.Dropout(dropout), nn.Linear(cond_dim + noise_dim, hidden), nn.LeakyReLU(0.2),
            nn.Dropout(dropout), nn.Linear(hidden, channels[0] * self.lengths[0]),
            nn.LeakyReLU(0.2),
        )
        outs = list(channels[1:]) + [DIMS]
        self.convs = nn.ModuleList(
            nn.Conv1d(cin, cout, 3, padding=1)
            for cin, cout in zip(channels, outs, strict=True)
        )

    def forward(self, cond: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        h = self.fc(torch.cat([cond, z], dim=1)).view(-1, self.c0, self.lengths[0])
        for k, conv in enumerate(self.convs):
            h = nn.functional.interpolate(h, size=self.lengths[k + 1], mode="linear",
                                          align_corners=False)
            h = conv(h)
            if k < len(self.convs) - 1:
                h = nn.functional.leaky_relu(h, 0.2)
        return h.transpose(1, 2)


class Critic(nn.Module):
    """Conditional WGAN critic: 3 strided Conv1d blocks -> FC 1024 -> FC 1."""

    def __init__(self, cond_dim: int, future_len: int, embed: int = 64,
                 channels: Sequence[int] = (64, 128, 128)) -> None:
        super().__init__()
        self.embed = nn.Linear(cond_dim, embed)
        layers: list[nn.Module] = []
        cin = DIMS + embed
        length = future_len
        for c in channels:
            layers += [nn.Conv1d(cin, c, 3, stride=2, padding=1), nn.LeakyReLU(0.2)]
            cin, length = c, (length - 1) // 2 + 1
        self.convs = nn.Sequential(*layers)
        self.head = nn.Sequential(nn.Linear(cin * length, 1024), nn.LeakyReLU(0.2),
                                  nn.Linear(1024, 1))

    def forward(self, u: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """(B, F, 51) future tangent coordinates, (B, cond_dim) -> (B,) scores."""
        e = self.embed(cond)[:, :, None].expand(-1, -1, u.shape[1])
        h = self.convs(torch.cat([u.transpose(1, 2), e], dim=1))
        return self.head(h.flatten(1))[:, 0]


class AmplitudeHead(nn.Module):
    """MLP condition -> ``log a_F - log a_P``."""

    def __init__(self, cond_dim: int, hidden: int = 128, dropout: float = 0.0) -> None:
        super().__init__()
        self.net = nn.Sequential(nn.Dropout(dropout), nn.Linear(cond_dim, hidden),
                                 nn.LeakyReLU(0.2),
                                 nn.Linear(hidden, hidden), nn.LeakyReLU(0.2),
                                 nn.Linear(hidden, 1))

    def forward(self, cond: torch.Tensor) -> torch.Tensor:
        return self.net(cond)[:, 0]


# -- losses ---------------------------------------------------------------------------


def gradient_penalty(critic: nn.Module, real: torch.Tensor, fake: torch.Tensor,
                     cond: torch.Tensor, eps: torch.Tensor | None = None) -> torch.Tensor:
    """WGAN-GP penalty ``E[(||∇_x C(x, c)||_2 - 1)²]`` at ``x = ε real + (1 - ε) fake``.

    Args:
        real, fake: (B, F, 51) critic inputs; cond: (B, cond_dim) condition (not mixed).
        eps: (B,) mixing weights in [0, 1]; uniform random when None.
    """
    if eps is None:
        eps = torch.rand(real.shape[0], device=real.device)
    x = (eps[:, None, None] * real + (1 - eps[:, None, None]) * fake.detach())
    x.requires_grad_(True)
    grad, = torch.autograd.grad(critic(x, cond).sum(), x, create_graph=True)
    return ((grad.flatten(1).norm(dim=1) - 1) ** 2).mean()


#: Child joints of the 16 bones and their parents (pred17 layout).
BONE_CHILD: tuple[int, ...] = tuple(j for j, p in enumerate(PARENTS) if p >= 0)
BONE_PARENT: tuple[int, ...] = tuple(PARENTS[j] for j in BONE_CHILD)


def _ancestor_matrix() -> np.ndarray:
    """(17, 16) ``A[j, k] = 1`` when bone ``k`` lies on the path from the pelvis to
    joint ``j``, so that poses are ``x = x_pelvis + A b`` for bone vectors ``b``."""
    a = np.zeros((NUM_JOINTS, len(BONE_CHILD)))
    for j in range(NUM_JOINTS):
        k = j
        while PARENTS[k] >= 0:
            a[j, BONE_CHILD.index(k)] = 1.0
            k = PARENTS[k]
    return a


ANCESTORS = _ancestor_matrix()


def restore_bone_lengths(frames: np.ndarray | torch.Tensor, reference: np.ndarray | torch.Tensor
                         ) -> np.ndarray | torch.Tensor:
    """Frames with the bone lengths of a reference pose, along their own bone directions.

    Rebuilds each pose from the pelvis outwards, ``x_j = x_{parent(j)} + b_j d_j / |d_j|``
    with ``d_j`` the frame's own bone vector and ``b_j`` the reference's bone length, in
    one step: ``x = x_pelvis + A (b d / |d|)`` with the ancestor matrix ``A``
    (:data:`ANCESTORS`). The pelvis stays where it is; a bone of zero length in the
    frame (no direction) stays of zero length.

    Args:
        frames: (B, F, 17, 3) poses; reference: (B, 17, 3) poses, same unit; both numpy
            arrays or both torch tensors (then differentiable in ``frames``).

    Returns:
        (B, F, 17, 3) poses, of the input's kind.
    """
    def length(v):  # |v| over the last axis, kept; numpy and torch alike
        return ((v * v).sum(-1)[..., None] + 1e-18) ** 0.5

    child, par = list(BONE_CHILD), list(BONE_PARENT)
    bones = frames[..., child, :] - frames[..., par, :]
    ref = length(reference[:, child] - reference[:, par])[:, None]
    bones = bones * (ref / length(bones))
    anc = (torch.as_tensor(ANCESTORS, dtype=frames.dtype) if isinstance(frames, torch.Tensor)
           else ANCESTORS)
    return frames[..., :1, :] + anc @ bones


def gram_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Gram/Procrustes skeleton integrity: ``mean |Ĝ - G|`` of per-frame Gram matrices
    ``X Xᵀ`` of centred (..., J, 3) poses (invariant to rotations of either pose)."""
    p = pred - pred.mean(dim=-2, keepdim=True)
    t = target - target.mean(dim=-2, keepdim=True)
    return (p @ p.transpose(-1, -2) - t @ t.transpose(-1, -2)).abs().mean()


def bone_loss(pred: torch.Tensor, reference: torch.Tensor) -> torch.Tensor:
    """``mean |b̂ - b_ref|`` of bone lengths: (B, F, J, 3) frames vs (B, J, 3) poses."""
    child = [j for j, p in enumerate(PARENTS) if p >= 0]
    par = [PARENTS[j] for j in child]
    b = (pred[..., child, :] - pred[..., par, :]).norm(dim=-1)
    b_ref = (reference[..., child, :] - reference[..., par, :]).norm(dim=-1)
    return (b - b_ref[:, None]).abs().mean()


# -- the model -------------------------------------------------------------------------


@dataclass
class PredictorConfig:
    """Hyper-parameters and fitted constants (saved in checkpoints)."""

    past_len: int
    future_len: int
    fps: float = 25.0
    noise_dim: int = 16
    hidden: int = 512
    gen_channels: tuple[int, ...] = (256, 128, 128, 64, 64)
    critic_channels: tuple[int, ...] = (64, 128, 128)
    dropout: float = 0.0
    scale_past: float = 1.0
    scale_future: float = 1.0
    #: Prior future the generator and head correct: "none" (the paper's model),
    #: "damped_velocity" or "linear" (see :func:`fit_prior`).
    prior: str = "none"
    #: Add the last observed velocity (x_T - x_{T-1}, times ``scale_velocity``) to the
    #: condition.
    velocity_condition: bool = False
    scale_velocity: float = 1.0
    #: Average each prediction with the mirrored prediction of the mirrored history.
    mirror_average: bool = False
    #: Rebuild predicted frames and the prior future with the last observed pose's
    #: bone lengths (:func:`restore_bone_lengths`).
    restore_bones: bool = False
    info: dict = field(default_factory=dict)

    @property
    def cond_dim(self) -> int:
        return self.past_len * DIMS + 1 + DIMS + (DIMS if self.velocity_condition else 0)


@dataclass
class Batch:
    """Prepared tensors of windows in heading-normalised coordinates.

    Attributes:
        cond: (N, cond_dim) condition; u_future: (N, F, 51) scaled future tangent
            coordinates; log_amp_past/log_amp_future: (N,); last: (N, 51) last observed
            pose, metres; future: (N, F, 17, 3) true future frames, metres;
        u_base, log_amp_base: (N, F, 51) scaled tangent coordinates and (N,) log
            amplitude the generator and the head add to: the prior future's (zero and
            ``log a_P`` without a prior).
    """

    cond: torch.Tensor
    u_future: torch.Tensor
    log_amp_past: torch.Tensor
    log_amp_future: torch.Tensor
    last: torch.Tensor
    future: torch.Tensor
    u_base: torch.Tensor
    log_amp_base: torch.Tensor

    def __len__(self) -> int:
        return int(self.cond.shape[0])

    def take(self, idx: torch.Tensor) -> Batch:
        return Batch(*(getattr(self, f)[idx] for f in
                       ("cond", "u_future", "log_amp_past", "log_amp_future", "last",
                        "future", "u_base", "log_amp_base")))


def _sphere(curve: np.ndarray, fallback: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points and amplitudes of (N, T, D) curves; a curve that does not move at all gets
    the ``fallback`` point (its direction is undefined, its amplitude 0)."""
    q = srvf.srvf(curve)
    amp = srvf.norm(q)
    moving = amp > 0
    points = np.where(moving[:, None, None], q / np.where(moving, amp, 1.0)[:, None, None],
                      fallback)
    return points, amp


class PredictiveMAWGAN(CheckpointMixin):
    """The trained predictor: networks, Karcher means and the SRVF pipeline.

    ``predict(history)`` takes (N, 1 + P, 17, 3) (or longer; the last 1 + P frames are
    used) root-relative pred17 positions in metres, the lead-in frame followed by the P
    observed frames, and returns the (N, F, 17, 3) float32 future (see the module
    docstring for the math).
    """

    def __init__(self, config: PredictorConfig, mu_past: np.ndarray,
                 mu_future: np.ndarray, prior_filter: np.ndarray | None = None) -> None:
        if config.prior not in PRIORS:
            raise MotionError(f"prior must be one of {', '.join(PRIORS)}; got "
                              f"{config.prior!r}", field="prior")
        self.config = config
        self.metadata: dict[str, Any] = {}
        self.past_len = config.past_len
        self.future_len = config.future_len
        self.fps = config.fps
        self.mu_past = np.asarray(mu_past, dtype=np.float64)
        self.mu_future = np.asarray(mu_future, dtype=np.float64)
        if self.mu_past.shape != (config.past_len, DIMS) or \
                self.mu_future.shape != (config.future_len, DIMS):
            raise CheckpointError(
                f"Karcher means must be ({config.past_len}, {DIMS}) and "
                f"({config.future_len}, {DIMS}); got {self.mu_past.shape} and "
                f"{self.mu_future.shape}"
            )
        self.mu_future_t = torch.as_tensor(self.mu_future, dtype=torch.float32)
        self.generator = Generator(config.cond_dim, config.future_len, config.noise_dim,
                                   config.hidden, config.gen_channels, config.dropout)
        self.critic = Critic(config.cond_dim, config.future_len,
                             channels=config.critic_channels)
        self.amplitude = AmplitudeHead(config.cond_dim, dropout=config.dropout)
        self.prior_filter = None
        if config.prior != "none":
            shape = (self.history_len, config.future_len)
            if prior_filter is None or np.shape(prior_filter) != shape:
                raise CheckpointError(
                    f"prior {config.prior!r} needs a prior filter of shape {shape}; got "
                    f"{None if prior_filter is None else np.shape(prior_filter)}")
            self.prior_filter = np.asarray(prior_filter, dtype=np.float64)
            # a fresh model predicts the prior exactly: zero correction, zero log-ratio
            for layer in (self.generator.convs[-1], self.amplitude.net[-1]):
                nn.init.zeros_(layer.weight)
                nn.init.zeros_(layer.bias)

    @property
    def history_len(self) -> int:
        return self.past_len + 1

    # -- data ------------------------------------------------------------------------

    def prior_future(self, frames: np.ndarray) -> np.ndarray:
        """The prior future of (N, 1+P, 17, 3) heading-normalised histories (metres):
        ``x_T + Σ_t W[t, k] (x_t - x_T)``, (N, F, 51); ``x_T`` repeated without a prior."""
        flat = frames.reshape(len(frames), self.history_len, DIMS)
        last = flat[:, -1]
        if self.prior_filter is None:
            return np.repeat(last[:, None], self.future_len, axis=1)
        prior = last[:, None] + np.einsum("nhd,hf->nfd", flat - last[:, None],
                                          self.prior_filter)
        if self.config.restore_bones:
            prior = self._restore(prior, last)
        return prior

    def _restore(self, future: np.ndarray, last: np.ndarray) -> np.ndarray:
        """(N, F, 51) futures with the bone lengths of the (N, 51) last poses."""
        n = len(future)
        out = restore_bone_lengths(future.reshape(n, -1, NUM_JOINTS, 3),
                                   last.reshape(n, NUM_JOINTS, 3))
        return out.reshape(future.shape)

    def _condition(self, frames: np.ndarray) -> tuple[np.ndarray, ...]:
        """(N, 1+P, 17, 3) heading-normalised history -> condition, log a_P, last pose,
        base tangent coordinates and base log amplitude (:class:`Batch`)."""
        n = len(frames)
        flat = frames.reshape(n, self.history_len, DIMS)
        p_past, a_past = _sphere(flat, self.mu_past)
        v_past = srvf.log_map(self.mu_past, p_past) / math.sqrt(self.past_len)
        log_a = np.log(np.maximum(a_past, 1e-6))
        last = flat[:, -1]
        parts = [v_past.reshape(n, -1) * self.config.scale_past, log_a[:, None],
                 LOSS_UNIT * last]
        if self.config.velocity_condition:
            parts.append((last - flat[:, -2]) * self.config.scale_velocity)
        cond = np.concatenate(parts, axis=1)
        if self.prior_filter is None:
            return cond, log_a, last, np.zeros((n, self.future_len, DIMS)), log_a
        curve = np.concatenate([last[:, None], self.prior_future(frames)], axis=1)
        p_prior, a_prior = _sphere(curve, self.mu_future)
        u_base = (srvf.log_map(self.mu_future, p_prior) / math.sqrt(self.future_len)
                  * self.config.scale_future)
        return cond, log_a, last, u_base, np.log(np.maximum(a_prior, 1e-6))

    def prepare(self, windows: PredictionWindows) -> Batch:
        """Training/evaluation tensors of windows with this model's P and F."""
        if (windows.past_len, windows.future_len) != (self.past_len, self.future_len):
            raise MotionError(
                f"windows are {windows.past_len}->{windows.future_len}; the model is "
                f"{self.past_len}->{self.future_len}", field="windows"
            )
        frames = windows.frames.astype(np.float64)
        frames = rotate_z(frames, -heading(frames[:, self.past_len]))
        n = len(frames)
        cond, log_a, last, u_base, log_base = self._condition(frames[:, : self.past_len + 1])
        future_curve = frames[:, self.past_len:].reshape(n, self.future_len + 1, DIMS)
        p_f, a_f = _sphere(future_curve, self.mu_future)
        v_f = srvf.log_map(self.mu_future, p_f) / math.sqrt(self.future_len)
        f32 = torch.float32
        return Batch(
            torch.as_tensor(cond, dtype=f32),
            torch.as_tensor(v_f * self.config.scale_future, dtype=f32),
            torch.as_tensor(log_a, dtype=f32),
            torch.as_tensor(np.log(np.maximum(a_f, 1e-6)), dtype=f32),
            torch.as_tensor(last, dtype=f32),
            torch.as_tensor(frames[:, self.past_len + 1:], dtype=f32),
            torch.as_tensor(u_base, dtype=f32),
            torch.as_tensor(log_base, dtype=f32),
        )

    # -- differentiable decoding -------------------------------------------------------

    def decode(self, u: torch.Tensor, log_amp: torch.Tensor, last: torch.Tensor
               ) -> tuple[torch.Tensor, torch.Tensor]:
        """Generator output -> (future frames (B, F, 17, 3) metres, sphere points).

        ``u`` (B, F, 51) scaled coordinates are unscaled to a tangent vector at ``μ_F``,
        projected onto ``T_{μ_F}`` (the raw output is not exactly tangent), mapped with
        ``exp_{μ_F}``, scaled by ``exp(log_amp)`` and integrated from ``last`` (B, 51);
        with ``restore_bones`` the frames get the bone lengths of ``last``.
        """
        v = u * (math.sqrt(self.future_len) / self.config.scale_future)
        v = t_project_tangent(self.mu_future_t, v)
        p = t_exp(self.mu_future_t, v)
        frames = t_inverse_srvf(p * torch.exp(log_amp)[:, None, None], last)
        frames = frames.view(-1, self.future_len, NUM_JOINTS, 3)
        if self.config.restore_bones:
            frames = restore_bone_lengths(frames, last.view(-1, NUM_JOINTS, 3))
        return frames, p

    def sample_noise(self, n: int, generator: torch.Generator | None = None) -> torch.Tensor:
        return torch.randn(n, self.config.noise_dim, generator=generator)

    def direction(self, cond: torch.Tensor, u_base: torch.Tensor, z: torch.Tensor
                  ) -> torch.Tensor:
        """Scaled future tangent coordinates (B, F, 51): the base (the prior future's,
        or zero) plus the generator's output."""
        return u_base + self.generator(cond, z)

    def log_amplitude(self, cond: torch.Tensor, log_amp_past: torch.Tensor,
                      amplitude: str = "predicted", base: torch.Tensor | None = None
                      ) -> torch.Tensor:
        """log of the future amplitude: ``"predicted"``, the head's output added to
        ``base`` (the prior future's log amplitude; ``log_amp_past`` when None),
        ``"carried"`` from the past, ``a_P sqrt(F / P)`` (the same mean speed), or
        ``"prior"``, the prior future's own (``base``; a model with a prior only)."""
        if amplitude == "predicted":
            return (log_amp_past if base is None else base) + self.amplitude(cond)
        if amplitude == "carried":
            return log_amp_past + 0.5 * math.log(self.future_len / self.past_len)
        if amplitude == "prior":
            if self.prior_filter is None or base is None:
                raise MotionError("amplitude 'prior' needs a model with a prior future",
                                  field="amplitude")
            return base
        raise MotionError(f"amplitude must be one of {', '.join(AMPLITUDES)}; got "
                          f"{amplitude!r}", field="amplitude")

    # -- prediction ---------------------------------------------------------------------

    @torch.no_grad()
    def predict(self, history: np.ndarray, *, amplitude: str = "predicted",
                seed: int | None = None) -> np.ndarray:
        """Predict the F frames after a history.

        Args:
            history: (N, H, 17, 3) or (H, 17, 3) root-relative positions, metres,
                H >= 1 + P, ending at the last observed frame.
            amplitude: ``"predicted"`` (default), ``"carried"`` or ``"prior"``
                (:meth:`log_amplitude`).
            seed: sample the generator noise with this seed; None uses ``z = 0``.

        Returns:
            (N, F, 17, 3) or (F, 17, 3) float32 future positions, metres.

        Raises:
            MotionError: too short a history, wrong joint count, NaN frames.
        """
        h, batched = check_history(history, self.history_len, joints=NUM_JOINTS)
        h = h[:, -self.history_len:]
        if amplitude not in AMPLITUDES:
            raise MotionError(f"amplitude must be one of {', '.join(AMPLITUDES)}; got "
                              f"{amplitude!r}", field="amplitude")
        if self.config.mirror_average:  # one pass over the histories and their mirrors
            both = self._predict(np.concatenate([h, mirror(h)]), amplitude, seed)
            out = 0.5 * (both[: len(h)] + mirror(both[len(h):]))
        else:
            out = self._predict(h, amplitude, seed)
        if self.config.restore_bones:  # after the average: a mean of two poses is shorter
            last = h[:, -1].astype(np.float64).reshape(len(h), DIMS)
            out = self._restore(out.reshape(len(h), self.future_len, DIMS), last)
            out = out.reshape(len(h), self.future_len, NUM_JOINTS, 3)
        out = out.astype(np.float32)
        return out if batched else out[0]

    def _predict(self, h: np.ndarray, amplitude: str, seed: int | None) -> np.ndarray:
        """(N, 1+P, 17, 3) checked histories -> (N, F, 17, 3) float64 futures, metres."""
        angle = heading(h[:, -1])
        frames = rotate_z(h, -angle)
        cond, log_a, last, u_base, log_base = self._condition(frames)
        cond_t = torch.as_tensor(cond, dtype=torch.float32)
        if seed is None:
            z = torch.zeros(len(h), self.config.noise_dim)
        else:
            z = self.sample_noise(len(h), torch.Generator().manual_seed(seed))
        self.generator.eval()
        self.amplitude.eval()
        u = self.direction(cond_t, torch.as_tensor(u_base, dtype=torch.float32), z)
        log_amp = self.log_amplitude(cond_t, torch.as_tensor(log_a, dtype=torch.float32),
                                     amplitude, torch.as_tensor(log_base, dtype=torch.float32))
        _, p = self.decode(u, log_amp, torch.as_tensor(last, dtype=torch.float32))
        # integrate in float64 from the exact last observed pose: no seam
        q = p.double().numpy() * np.exp(log_amp.double().numpy())[:, None, None]
        out = srvf.inverse_srvf(q, last)[:, 1:].reshape(len(h), self.future_len, NUM_JOINTS, 3)
        return rotate_z(out, angle)

    # -- checkpoints ------------------------------------------------------------------------

    CHECKPOINT_FORMAT = CHECKPOINT_FORMAT
    OPTIONAL_NETS = ("critic",)

    def save(self, path: str | Path, metadata: dict[str, Any] | None = None, *,
             with_critic: bool = True) -> Path:
        """The checkpoint (:class:`~simenv.models.checkpoint.CheckpointMixin`): config,
        Karcher means, prior filter and the networks; the critic, needed only to train
        on, is left out when ``with_critic`` is False."""
        return super().save(path, metadata, leave_out=() if with_critic else ("critic",))

    def checkpoint_nets(self) -> dict[str, nn.Module]:
        return {"generator": self.generator, "amplitude": self.amplitude,
                "critic": self.critic}

    def checkpoint_arrays(self) -> dict[str, np.ndarray]:
        arrays = {"mu_past": self.mu_past, "mu_future": self.mu_future}
        if self.prior_filter is not None:
            arrays["prior_filter"] = self.prior_filter
        return arrays

    @classmethod
    def from_checkpoint(cls, checkpoint: Checkpoint) -> PredictiveMAWGAN:
        raw = dict(checkpoint.config)
        for key in ("gen_channels", "critic_channels"):
            raw[key] = tuple(raw[key])
        a = checkpoint.arrays
        return cls(PredictorConfig(**raw), a["mu_past"], a["mu_future"], a.get("prior_filter"))


def fit_geometry(windows: PredictionWindows, config: PredictorConfig,
                 *, max_iter: int = 1000, tol: float = 1e-6, max_points: int = 4000,
                 seed: int = 0) -> PredictiveMAWGAN:
    """A fresh model whose Karcher means and coordinate scales are fitted to ``windows``.

    The means are computed on heading-normalised training windows (a seeded random
    subset of at most ``max_points`` of them: overlapping stride-1 windows are highly
    redundant); ``config.info`` receives the Karcher iterations, convergence and
    Fréchet variances.
    """
    if len(windows) > max_points:
        pick = np.random.default_rng(seed).choice(len(windows), max_points, replace=False)
        windows = windows.subset(np.sort(pick))
    frames = windows.frames.astype(np.float64)
    frames = rotate_z(frames, -heading(frames[:, windows.past_len]))
    n = len(frames)
    past = frames[:, : windows.past_len + 1].reshape(n, -1, DIMS)
    future = frames[:, windows.past_len:].reshape(n, -1, DIMS)
    amp_p = srvf.norm(srvf.srvf(past))
    amp_f = srvf.norm(srvf.srvf(future))
    keep = (amp_p > 0) & (amp_f > 0)
    p_p, _ = srvf.curve_to_sphere(past[keep])
    p_f, _ = srvf.curve_to_sphere(future[keep])
    km_p = srvf.karcher_mean(p_p, max_iter=max_iter, tol=tol)
    km_f = srvf.karcher_mean(p_f, max_iter=max_iter, tol=tol)
    v_p = srvf.log_map(km_p.mean, p_p) / math.sqrt(windows.past_len)
    v_f = srvf.log_map(km_f.mean, p_f) / math.sqrt(windows.future_len)
    config.scale_past = float(1.0 / np.sqrt(np.mean(v_p**2)))
    config.scale_future = float(1.0 / np.sqrt(np.mean(v_f**2)))
    velocity = past[:, -1] - past[:, -2]
    config.scale_velocity = float(1.0 / max(np.sqrt(np.mean(velocity**2)), 1e-9))
    prior_filter = None
    if config.prior != "none":
        prior_filter, fit = fit_prior(frames, windows.past_len, config.prior)
        config.info["prior_fit"] = fit
    config.info.update({
        "karcher_past": {"iterations": km_p.iterations, "converged": km_p.converged,
                         "variance_rad2": km_p.variance},
        "karcher_future": {"iterations": km_f.iterations, "converged": km_f.converged,
                           "variance_rad2": km_f.variance},
    })
    return PredictiveMAWGAN(config, km_p.mean, km_f.mean, prior_filter)


#: Damping factors :func:`fit_prior` chooses from for the damped-velocity prior.
DAMPING_GRID = tuple(np.round(np.arange(0.0, 0.96, 0.05), 2))


def fit_prior(frames: np.ndarray, past_len: int, kind: str) -> tuple[np.ndarray, dict]:
    """The temporal filter ``W`` (1+P, F) of a prior future, fitted to training windows.

    The prior of a history ``x_0 .. x_T`` (T = P) is ``x̃_k = x_T + Σ_t W[t, k] (x_t - x_T)``,
    one filter shared by every joint coordinate (it is then left-right and heading
    equivariant). ``"damped_velocity"``: the last velocity ``v = x_T - x_{T-1}``
    continued and damped, ``x̃_k = x_T + v Σ_{i<=k} d^i``, with ``d`` of
    :data:`DAMPING_GRID` that minimises the mean per-joint error over the future frames
    (``d = 0`` is zero-velocity). ``"linear"``: ``W`` by ridge least squares of the
    future residuals on the history residuals (the history's DCT continued, in the
    limit of all coefficients; ridge λ = 1e-4 of the mean diagonal of the normal
    matrix).

    Args:
        frames: (N, 1+P+F, 17, 3) heading-normalised training windows, metres.

    Returns:
        ``(W, info)``, info stating the fitted damping or ridge and the training error.
    """
    n, length = frames.shape[:2]
    h, f = past_len + 1, length - past_len - 1
    flat = frames.reshape(n, length, DIMS)
    last = flat[:, past_len]
    hist, fut = flat[:, :h] - last[:, None], flat[:, h:] - last[:, None]

    def error(w: np.ndarray) -> float:
        pred = np.einsum("nhd,hf->nfd", hist, w).reshape(n, f, NUM_JOINTS, 3)
        return float(np.linalg.norm(pred - fut.reshape(n, f, NUM_JOINTS, 3), axis=-1).mean())

    if kind == "damped_velocity":
        def damped(d: float) -> np.ndarray:
            w = np.zeros((h, f))
            w[h - 2] = -np.cumsum(d ** np.arange(1, f + 1))
            return w

        errors = {float(d): error(damped(d)) for d in DAMPING_GRID}
        best = min(errors, key=errors.get)
        return damped(best), {"kind": kind, "damping": best,
                              "train_error_mm": round(1000 * errors[best], 2),
                              "zero_velocity_train_error_mm": round(1000 * errors[0.0], 2)}
    if kind == "linear":
        a = hist.transpose(0, 2, 1).reshape(-1, h)
        b = fut.transpose(0, 2, 1).reshape(-1, f)
        gram = a.T @ a
        ridge = 1e-4 * float(np.mean(np.diag(gram)))
        w = np.linalg.solve(gram + ridge * np.eye(h), a.T @ b)
        return w, {"kind": kind, "ridge": ridge, "train_error_mm": round(1000 * error(w), 2),
                   "zero_velocity_train_error_mm": round(1000 * error(np.zeros((h, f))), 2)}
    raise MotionError(f"prior must be one of {', '.join(PRIORS[1:])}; got {kind!r}",
                      field="prior")


def critic_loss(model: PredictiveMAWGAN, batch: Batch, z: torch.Tensor,
                eps: torch.Tensor | None = None) -> tuple[torch.Tensor, dict[str, float]]:
    """WGAN-GP critic objective ``E[C(fake)] - E[C(real)] + λ GP``."""
    with torch.no_grad():
        fake = model.direction(batch.cond, batch.u_base, z)
    real_score = model.critic(batch.u_future, batch.cond).mean()
    fake_score = model.critic(fake, batch.cond).mean()
    gp = gradient_penalty(model.critic, batch.u_future, fake, batch.cond, eps)
    loss = fake_score - real_score + GP_LAMBDA * gp
    return loss, {"critic": loss.item(), "wasserstein": (real_score - fake_score).item(),
                  "gp": gp.item()}


def generator_loss(model: PredictiveMAWGAN, batch: Batch, z: torch.Tensor,
                   weights: dict[str, float] | None = None, *, joint_amplitude: bool = False
                   ) -> tuple[torch.Tensor, dict[str, float], torch.Tensor]:
    """``1 L_adv + 1 L_rec + 10 L_gram + 10 L_bone`` (positions in decimetres).

    Args:
        joint_amplitude: integrate the predicted future with the amplitude head's output
            instead of the true amplitude, so that the position losses train direction
            and amplitude together (the gradient reaches the head too). With the true
            amplitude the generator must find the direction of a full-size future; with
            the predicted one it can learn the direction of the MPJPE-optimal, shorter
            motion.

    Returns:
        ``(loss, terms, u)`` with ``u`` the (B, F, 51) generator output.
    """
    w = LOSS_WEIGHTS if weights is None else weights
    u = model.direction(batch.cond, batch.u_base, z)
    log_amp = (model.log_amplitude(batch.cond, batch.log_amp_past, base=batch.log_amp_base)
               if joint_amplitude else batch.log_amp_future)
    frames, _ = model.decode(u, log_amp, batch.last)
    pred, true = LOSS_UNIT * frames, LOSS_UNIT * batch.future
    last = LOSS_UNIT * batch.last.view(-1, NUM_JOINTS, 3)
    terms = {
        "adv": -model.critic(u, batch.cond).mean() if w["adv"] else torch.zeros(()),
        "rec": (pred - true).abs().mean(),
        "gram": gram_loss(pred, true),
        "bone": bone_loss(pred, last),
    }
    loss = sum(w[k] * v for k, v in terms.items())
    info = {k: v.item() for k, v in terms.items()} | {"generator": loss.item()}
    return loss, info, u


def amplitude_loss(model: PredictiveMAWGAN, batch: Batch, u: torch.Tensor,
                   target: str = "positions") -> torch.Tensor:
    """Loss of the amplitude head.

    ``target="positions"``: L1 position error (decimetres) of the future integrated with
    the generator's direction ``u`` (held fixed) and the predicted amplitude. Training
    the head on the position error rather than on the true amplitude makes it the
    MPJPE-optimal length for the direction the generator actually predicts: where the
    direction is uncertain, a shorter curve errs less. ``target="true"``: ``mean |log â -
    log a_F|``, the true amplitude (median-unbiased; the curve is not shrunk).
    """
    log_amp = model.log_amplitude(batch.cond, batch.log_amp_past, base=batch.log_amp_base)
    if target == "true":
        return (log_amp - batch.log_amp_future).abs().mean()
    if target not in AMPLITUDE_TARGETS:
        raise MotionError(f"target must be one of {', '.join(AMPLITUDE_TARGETS)}; got "
                          f"{target!r}", field="target")
    frames, _ = model.decode(u.detach(), log_amp, batch.last)
    return LOSS_UNIT * (frames - batch.future).abs().mean()


def rollout(predictor: object, history: np.ndarray, num_frames: int) -> np.ndarray:
    """Recursive prediction beyond the trained horizon.

    Predicts ``future_len`` frames, appends them to the history and predicts again from
    the last ``history_len`` frames, until ``num_frames`` frames exist (the thesis's
    2-3 repeats). Works for any predictor with ``predict``/``history_len``/
    ``future_len``.

    Args:
        history: (N, H, 17, 3) metres; num_frames: frames to return.

    Returns:
        (N, num_frames, 17, 3) float32.
    """
    if num_frames < 1:
        raise MotionError(f"num_frames must be >= 1; got {num_frames}", field="num_frames")
    seq = np.asarray(history, dtype=np.float32)
    start = seq.shape[1]
    while seq.shape[1] - start < num_frames:
        nxt = predictor.predict(seq[:, -predictor.history_len:])
        seq = np.concatenate([seq, nxt], axis=1)
    return seq[:, start: start + num_frames]

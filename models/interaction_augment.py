"""Interaction augmentation with skeleton priors (Li et al.): three conditional VAEs that
give a real two-person window new body proportions while keeping its contacts.

``augment(actor_window, reactor_window, scales=None, seed=0) -> (actor', reactor',
scales)``: windows (T, 18, 3) or (N, T, 18, 3) metres in one Z-up frame (the actor frame
of :mod:`simenv.data.interaction_data`), scales (17,) / (N, 17) per bone of
:func:`~simenv.data.interaction_data.inter18_skeleton`
(:data:`~simenv.data.augment_targets.BONE_NAMES`),
drawn from the skeleton prior when None. Training targets: :mod:`simenv.data.augment_targets`.

Networks (math)
---------------
* **Skeleton prior** p(s) (:class:`ScalePriorVAE`): an MLP VAE over scale vectors,
  ``q(z|s) = N(μ(s), σ²(s))``, ``ŝ = 1 + 0.25 tanh(g(z))`` (inside [0.75, 1.25] by
  construction); sampling decodes ``z ~ N(0, I)`` and snaps to the 0.05 grid.
* **B-retargeting VAE** (:class:`GraphCVAE` on the reactor's 18-node skeleton graph):
  condition per node and frame ``c_{t,j} = [b_{t,j}, s_j, s_j (b_{t,j} - b_{t,p(j)})]``
  (s_root = 1, bone vector 0 at the root); posterior encoder ``q(z | B', c)``: ST-GCN
  blocks (graph convolution ``Â X W`` with ``Â = D^{-1/2}(A + I)D^{-1/2}`` over the
  skeleton, then a temporal convolution, residual, ReLU) pooled over frames and nodes to
  ``(μ, log σ²)``; decoder: a non-causal ST-GCN context of ``c`` and a **graph GRU**
  (the GRU's input and recurrent maps are graph convolutions,
  ``r = σ(Â x W_r + Â h U_r)``, ``u = σ(Â x W_u + Â h U_u)``,
  ``h̃ = tanh(Â x W_h + r ⊙ Â h U_h)``, ``h ← (1-u) ⊙ h + u ⊙ h̃``) run over the frames
  with input ``[context_t, z]``; its per-node output is a root displacement (root node)
  and bone-vector corrections (other nodes), and the pose is assembled by forward
  kinematics from the reactor's root and scaled bones:
  ``b̂'_root = b_root + o_root``, ``b̂'_j = b̂'_{p(j)} + s_j (b_j - b_{p(j)}) + o_j``.
* **A-adaptation VAE** (the same :class:`GraphCVAE` on a 36-node two-person graph: the
  actor's 18 nodes, the new reactor's 18, each skeleton's bones and one edge per key
  joint pair of :data:`~simenv.data.interaction_metrics.KEY_JOINT_PAIRS`), conditioned on the
  new reactor B': actor nodes carry ``[a_{t,j}, a_{t,j} - a_{t,p(j)}, 0]``, reactor nodes
  ``[b'_{t,j}, b'_{t,j} - b_{t,j}, 1]``; the output of the actor nodes builds
  ``â'`` by forward kinematics from A's root and bones as above (scale 1).

At inference ``z ~ N(0, I)`` (seeded); A is adapted to the *generated* B'.

Losses (weights 0.75 / 0.1 / 0.05 / 0.1)
-----------------------------------------
DESIGN.md and the issue give the four weights without naming the terms; our assignment
(every term in metres, so that the weights, not the units, set the balance):

* B-retargeting: ``0.75 · mean_{t,j} ||b̂'_{t,j} - b'_{t,j}||`` (reconstruction)
  ``+ 0.1 · mean |‖b̂'_j - b̂'_{p(j)}‖ - s_j L_j|`` (bone length to the target scale)
  ``+ 0.05 · KL`` (per sample, summed over latent dimensions)
  ``+ 0.1 · mean ||Δb̂'_t - Δb'_t||`` (frame-to-frame velocities, the temporal term).
* A-adaptation: ``0.75 · mean ||â' - a'|| + 0.1 · bone length to A's own + 0.05 · KL
  + 0.1 · JPD``, the last ``mean over real contact frames of |‖â'_i - b'_j‖ - d_real|``
  (the key joint-pair distances the augmentation must keep).
* Skeleton prior: ``0.75 · Σ_k |ŝ_k - s_k| / 0.25 + 0.05 · KL`` (the two terms that
  apply; summed over bones: with a per-bone mean the KL collapsed the posterior and the
  prior sampled only scales within ±0.05 of 1), trained in its own loop.

Paper vs ours
-------------
* Targets: the paper's optimiser outputs are replaced by :mod:`simenv.data.augment_targets`
  (FK scaling of B, least-squares contact-preserving adaptation of A).
* The prior is trained on the sampled scale vectors (uniform on the grid, left/right
  symmetric), not on a corpus of real body shapes (we have too few subjects).
* Small CPU sizes (hidden 24, latent 8, 2 ST-GCN blocks per encoder/context), 40-frame
  windows at 25 fps, 18 keypoints; positions, not joint rotations.
* The decoders' output layers start at zero, so the untrained model is the naive
  augmentation (B with scaled bones, A unchanged) and training learns corrections.

Generalisation splits (:func:`generalisation_splits`)
-----------------------------------------------------
Over augmentation samples (window, scale vector): **random** (windows split by recording,
scales from the same distribution on both sides), **cross-scale** (same window split;
train samples have a mean bone scale in the central band, test samples outside it),
**cross-interaction** (a held-out interaction class; recordings are disjoint since a
recording has one class), **both** (held-out class *and* outer scales on the test side,
other classes *and* central scales on the train side; the rest is unused).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from simenv.core.errors import MotionError
from simenv.data import augment_targets as at
from simenv.data import interaction_data as idata
from simenv.data.interaction_metrics import KEY_JOINT_PAIRS
from simenv.models.checkpoint import CheckpointMixin
from simenv.models.training import CpuBudget, seeded

CHECKPOINT_FORMAT = "simenv-interaction-augment-v1"
J = len(at.PARENTS)
_PARENT_OF_BONE = [at.PARENTS[j] for j in at.BONE_CHILDREN]


def normalised_adjacency(edges: Sequence[tuple[int, int]], nodes: int) -> np.ndarray:
    """(V, V) float32 ``D^{-1/2} (A + I) D^{-1/2}`` of an undirected graph."""
    a = np.eye(nodes, dtype=np.float64)
    for i, j in edges:
        a[i, j] = a[j, i] = 1.0
    d = 1.0 / np.sqrt(a.sum(axis=1))
    return (a * d[:, None] * d[None, :]).astype(np.float32)


def skeleton_edges(offset: int = 0) -> list[tuple[int, int]]:
    """Bones of the 18-keypoint skeleton as (parent, child) node pairs."""
    return [(p + offset, j + offset) for j, p in enumerate(at.PARENTS) if p >= 0]


def two_person_edges() -> list[tuple[int, int]]:
    """Edges of the 36-node graph: both skeletons and the key joint pairs (A i - B j)."""
    names = list(idata.INTER18_JOINTS)
    pairs = [(names.index(a), J + names.index(b)) for a, b in KEY_JOINT_PAIRS]
    return skeleton_edges() + skeleton_edges(J) + pairs


class STGCNBlock(nn.Module):
    """Spatial graph convolution ``Â X W`` then a temporal convolution (kernel k, same
    length), both followed by ReLU, with a residual (1x1 projection when widths differ).
    Input and output (B, C, T, V)."""

    def __init__(self, adjacency: torch.Tensor, c_in: int, c_out: int, kernel: int = 5
                 ) -> None:
        super().__init__()
        self.register_buffer("adj", adjacency)
        self.spatial = nn.Conv2d(c_in, c_out, 1)
        self.temporal = nn.Conv2d(c_out, c_out, (kernel, 1), padding=(kernel // 2, 0))
        self.residual = nn.Identity() if c_in == c_out else nn.Conv2d(c_in, c_out, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = torch.relu(torch.einsum("bctv,wv->bctw", self.spatial(x), self.adj))
        return torch.relu(self.temporal(h) + self.residual(x))


class GraphGRUCell(nn.Module):
    """GRU cell whose input and recurrent maps are graph convolutions (module docstring).
    x: (B, V, C_in), h: (B, V, H) -> h' (B, V, H)."""

    def __init__(self, adjacency: torch.Tensor, c_in: int, hidden: int) -> None:
        super().__init__()
        self.register_buffer("adj", adjacency)
        self.wx = nn.Linear(c_in, 3 * hidden)
        self.wh = nn.Linear(hidden, 3 * hidden, bias=False)

    def forward(self, x: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
        gx = self.adj @ self.wx(x)
        gh = self.adj @ self.wh(h)
        xr, xu, xn = gx.chunk(3, dim=-1)
        hr, hu, hn = gh.chunk(3, dim=-1)
        r, u = torch.sigmoid(xr + hr), torch.sigmoid(xu + hu)
        return (1 - u) * h + u * torch.tanh(xn + r * hn)


class GraphCVAE(nn.Module):
    """Conditional VAE over node trajectories: ST-GCN posterior encoder, ST-GCN context of
    the condition and a graph-GRU decoder emitting (B, T, V_out, 3) per-node offsets for
    the first ``out_nodes`` nodes (module docstring)."""

    def __init__(self, adjacency: np.ndarray, cond_channels: int, out_nodes: int,
                 hidden: int, latent: int) -> None:
        super().__init__()
        adj = torch.as_tensor(adjacency)
        self.latent, self.out_nodes = latent, out_nodes
        self.enc = nn.Sequential(STGCNBlock(adj, cond_channels + 3, hidden),
                                 STGCNBlock(adj, hidden, hidden))
        self.enc_head = nn.Linear(hidden, 2 * latent)
        self.ctx = nn.Sequential(STGCNBlock(adj, cond_channels, hidden),
                                 STGCNBlock(adj, hidden, hidden))
        self.cell = GraphGRUCell(adj, hidden + latent, hidden)
        self.out = nn.Linear(hidden, 3)
        # Zero offsets at initialisation: the untrained decoder is the naive augmentation
        # (B with scaled bones, A unchanged) and training learns the corrections.
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)

    def encode(self, cond: torch.Tensor, target: torch.Tensor
               ) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, T, V, C) condition, (B, T, V, 3) target (zero-padded nodes) -> μ, log σ²."""
        x = torch.cat([cond, target], dim=-1).permute(0, 3, 1, 2)
        h = self.enc(x).mean(dim=(2, 3))
        mu, logvar = self.enc_head(h).chunk(2, dim=-1)
        return mu, logvar.clamp(-8.0, 8.0)

    def decode(self, cond: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        """(B, T, V, C) condition, (B, latent) -> (B, T, out_nodes, 3) offsets."""
        ctx = self.ctx(cond.permute(0, 3, 1, 2)).permute(0, 2, 3, 1)  # (B, T, V, H)
        b, t, v, _ = ctx.shape
        zz = z[:, None, :].expand(b, v, self.latent)
        h = torch.zeros(b, v, ctx.shape[-1], dtype=ctx.dtype)
        outs = []
        for k in range(t):
            h = self.cell(torch.cat([ctx[:, k], zz], dim=-1), h)
            outs.append(self.out(h[:, :self.out_nodes]))
        return torch.stack(outs, dim=1)


class ScalePriorVAE(nn.Module):
    """MLP VAE over (B, 17) scale vectors; the decoder keeps ŝ in [0.75, 1.25]."""

    def __init__(self, hidden: int, latent: int) -> None:
        super().__init__()
        self.latent = latent
        self.enc = nn.Sequential(nn.Linear(at.NUM_BONES, hidden), nn.ReLU(),
                                 nn.Linear(hidden, 2 * latent))
        self.dec = nn.Sequential(nn.Linear(latent, hidden), nn.ReLU(),
                                 nn.Linear(hidden, at.NUM_BONES))

    def encode(self, s: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        mu, logvar = self.enc((s - 1.0) / 0.25).chunk(2, dim=-1)
        return mu, logvar.clamp(-8.0, 8.0)

    def decode(self, z: torch.Tensor) -> torch.Tensor:
        return 1.0 + 0.25 * torch.tanh(self.dec(z))


# -- conditions and forward kinematics -----------------------------------------------------


def _bones(x: torch.Tensor) -> torch.Tensor:
    """(..., 18, 3) -> (..., 18, 3) bone vectors per child node (0 at the root)."""
    par = x[..., [max(p, 0) for p in at.PARENTS], :]
    bones = x - par
    bones[..., 0, :] = 0.0
    return bones


def reactor_condition(b: torch.Tensor, s: torch.Tensor) -> torch.Tensor:
    """(N, T, 18, 3), (N, 17) -> (N, T, 18, 7) ``[b, s_j, s_j · bone_j]``."""
    s_node = torch.cat([torch.ones_like(s[:, :1]), s], dim=1)[:, None, :, None]
    s_node = s_node.expand(*b.shape[:3], 1)
    return torch.cat([b, s_node, s_node * _bones(b)], dim=-1)


def actor_condition(a: torch.Tensor, b: torch.Tensor, nb: torch.Tensor) -> torch.Tensor:
    """(N, T, 18, 3) A, B, B' -> (N, T, 36, 7) two-person node features."""
    zeros = torch.zeros_like(a[..., :1])
    actor = torch.cat([a, _bones(a), zeros], dim=-1)
    reactor = torch.cat([nb, nb - b, torch.ones_like(zeros)], dim=-1)
    return torch.cat([actor, reactor], dim=2)


def assemble(root: torch.Tensor, bones: torch.Tensor, offsets: torch.Tensor) -> torch.Tensor:
    """FK of (N, T, 3) root + offsets[..., 0] and (N, T, 17, 3) bones + offsets[..., 1:]."""
    return at.forward_kinematics(root + offsets[..., 0, :], bones + offsets[..., 1:, :])


def _kl(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    return (-0.5 * (1 + logvar - mu ** 2 - logvar.exp()).sum(dim=-1)).mean()


def _bone_length(x: torch.Tensor) -> torch.Tensor:
    return (x[..., at.BONE_CHILDREN, :] - x[..., _PARENT_OF_BONE, :]).norm(dim=-1)


@dataclass(frozen=True)
class InteractionAugmenterConfig:
    """Small CPU configuration (every field JSON-able).

    Attributes:
        hidden: channels of the ST-GCN blocks and the graph-GRU state. latent: latent size
            of both graph VAEs. prior_hidden / prior_latent: the skeleton-prior MLP
            (latent 10 = the number of symmetric scale groups). prior_steps: its Adam
            steps (:func:`fit_prior`, after the graph VAEs).
        epochs: passes over the training samples (the two graph VAEs train side by side).
        batch: samples per step. lr: Adam learning rate.
        scales_per_window: augmentation samples built per training window
            (:func:`simenv.data.augment_targets.build_targets`).
        symmetric_scales: left/right bones share a scale.
        rotate_augment: each epoch rotates every sample by a random angle about Z (both
            people, the same rigid motion: the task is rotation equivariant).
        w_rec / w_bone / w_kl / w_rel: the four loss weights (module docstring).
    """

    hidden: int = 24
    latent: int = 8
    prior_hidden: int = 64
    prior_latent: int = 10
    prior_steps: int = 3000
    epochs: int = 8
    batch: int = 16
    lr: float = 1e-3
    scales_per_window: int = 4
    symmetric_scales: bool = True
    rotate_augment: bool = True
    w_rec: float = 0.75
    w_bone: float = 0.1
    w_kl: float = 0.05
    w_rel: float = 0.1


class InteractionAugmenter(CheckpointMixin):
    """The three VAEs and :meth:`augment` (module docstring)."""

    name = "interaction-augment"

    def __init__(self, config: InteractionAugmenterConfig | None = None) -> None:
        self.config = config or InteractionAugmenterConfig()
        c = self.config
        self.prior = ScalePriorVAE(c.prior_hidden, c.prior_latent)
        self.retarget = GraphCVAE(normalised_adjacency(skeleton_edges(), J), 7, J,
                                  c.hidden, c.latent)
        self.adapt = GraphCVAE(normalised_adjacency(two_person_edges(), 2 * J), 7, J,
                               c.hidden, c.latent)
        self.metadata: dict[str, Any] = {}

    @property
    def nets(self) -> dict[str, nn.Module]:
        return {"prior": self.prior, "retarget": self.retarget, "adapt": self.adapt}

    # -- inference --------------------------------------------------------------------------

    def sample_scales(self, n: int, *, seed: int = 0) -> np.ndarray:
        """(n, 17) scale vectors from the skeleton prior, snapped to the 0.05 grid."""
        g = torch.Generator().manual_seed(seed)
        with torch.no_grad():
            s = self.prior.decode(torch.randn(n, self.config.prior_latent, generator=g))
        s = np.clip(np.round(s.double().numpy() / 0.05) * 0.05, at.SCALE_GRID[0],
                    at.SCALE_GRID[-1])
        return np.round(s, 2)

    def retarget_reactor(self, b: torch.Tensor, s: torch.Tensor, z: torch.Tensor
                         ) -> torch.Tensor:
        """B' (N, T, 18, 3) from B and (N, 17) scales with latent z."""
        offsets = self.retarget.decode(reactor_condition(b, s), z)
        scaled = (b[..., at.BONE_CHILDREN, :] - b[..., _PARENT_OF_BONE, :]) * s[:, None, :, None]
        return assemble(b[..., 0, :], scaled, offsets)

    def adapt_actor(self, a: torch.Tensor, b: torch.Tensor, nb: torch.Tensor,
                    z: torch.Tensor) -> torch.Tensor:
        """A' (N, T, 18, 3) from A, B and B' with latent z."""
        offsets = self.adapt.decode(actor_condition(a, b, nb), z)
        bones = a[..., at.BONE_CHILDREN, :] - a[..., _PARENT_OF_BONE, :]
        return assemble(a[..., 0, :], bones, offsets)

    def augment(self, actor_window: np.ndarray, reactor_window: np.ndarray,
                scales: np.ndarray | None = None, *, seed: int = 0
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A new body for the reactor and the actor adapted to it.

        Args:
            actor_window, reactor_window: (T, 18, 3) or (N, T, 18, 3), metres, one Z-up
                frame, T >= 2.
            scales: (17,) or (N, 17) per-bone scales in [0.75, 1.25]; None: drawn from
                the skeleton prior.
            seed: seeds the prior draw and the two latents.

        Returns:
            ``(actor', reactor', scales)``: float32 windows of the input shape and the
            (17,) / (N, 17) float64 scales used.

        Raises:
            MotionError: shapes that disagree, too few frames, non-finite values or
                scales outside the range.
        """
        a = np.asarray(actor_window, dtype=np.float64)
        b = np.asarray(reactor_window, dtype=np.float64)
        batched = a.ndim == 4
        for name, x in (("actor_window", a), ("reactor_window", b)):
            if x.ndim not in (3, 4) or x.shape[-2:] != (J, 3) or x.shape[-3] < 2:
                raise MotionError(f"{name} must have shape (N, T >= 2, {J}, 3) or "
                                  f"(T >= 2, {J}, 3), metres; got {x.shape}", field=name)
            if not np.isfinite(x).all():
                raise MotionError(f"{name} has a non-finite value", field=name)
        if a.shape != b.shape:
            raise MotionError(f"actor_window {a.shape} and reactor_window {b.shape} must "
                              "have one shape (same frames, same joints)",
                              field="reactor_window")
        if not batched:
            a, b = a[None], b[None]
        n = len(a)
        if scales is None:
            s = self.sample_scales(n, seed=seed)
        else:
            if not batched and np.ndim(scales) != 1:
                raise MotionError(f"scales of a single window must have shape "
                                  f"({at.NUM_BONES},); got {np.shape(scales)}",
                                  field="scales")
            s = at.check_scales(scales, n)
        g = torch.Generator().manual_seed(seed + 1)
        z_b = torch.randn(n, self.config.latent, generator=g)
        z_a = torch.randn(n, self.config.latent, generator=g)
        for net in self.nets.values():
            net.eval()
        with torch.no_grad():
            at_, bt = torch.as_tensor(a, dtype=torch.float32), torch.as_tensor(
                b, dtype=torch.float32)
            st = torch.as_tensor(s, dtype=torch.float32)
            nb = self.retarget_reactor(bt, st, z_b)
            na = self.adapt_actor(at_, bt, nb, z_a)
        na, nb = na.numpy().astype(np.float32), nb.numpy().astype(np.float32)
        if not batched:
            return na[0], nb[0], s[0]
        return na, nb, s

    # -- checkpoints ------------------------------------------------------------------------

    CHECKPOINT_FORMAT = CHECKPOINT_FORMAT
    CONFIG = InteractionAugmenterConfig

    def save(self, path: str | Path, metadata: dict[str, Any] | None = None) -> Path:
        """The checkpoint (:class:`~simenv.models.checkpoint.CheckpointMixin`) with the
        model's metadata updated with ``metadata``."""
        return super().save(path, {**self.metadata, **(metadata or {})})

    def checkpoint_nets(self) -> dict[str, nn.Module]:
        return dict(self.nets)


# -- training ------------------------------------------------------------------------------


def _rot_z(theta: torch.Tensor) -> torch.Tensor:
    c, s = torch.cos(theta), torch.sin(theta)
    z, o = torch.zeros_like(theta), torch.ones_like(theta)
    return torch.stack([torch.stack([c, -s, z], -1), torch.stack([s, c, z], -1),
                        torch.stack([z, z, o], -1)], -2)


def losses(model: InteractionAugmenter, batch: dict[str, torch.Tensor]
           ) -> dict[str, torch.Tensor]:
    """The named loss terms of one batch (module docstring) and their weighted sum
    ``"loss"``. ``batch``: actor, reactor, actor_target, reactor_target (B, T, 18, 3),
    scales (B, 17), real_distance, contact (B, T, P)."""
    c = model.config
    a, b, s = batch["actor"], batch["reactor"], batch["scales"]
    ta, tb = batch["actor_target"], batch["reactor_target"]
    # B-retargeting VAE
    cond_b = reactor_condition(b, s)
    mu, logvar = model.retarget.encode(cond_b, tb)
    z = mu + torch.randn_like(mu) * (0.5 * logvar).exp()
    scaled = (b[..., at.BONE_CHILDREN, :] - b[..., _PARENT_OF_BONE, :]) * s[:, None, :, None]
    pb = assemble(b[..., 0, :], scaled, model.retarget.decode(cond_b, z))
    out = {"b_rec": (pb - tb).norm(dim=-1).mean(),
           "b_bone": (_bone_length(pb) - _bone_length(tb)).abs().mean(),
           "b_kl": _kl(mu, logvar),
           "b_vel": (pb.diff(dim=1) - tb.diff(dim=1)).norm(dim=-1).mean()}
    # A-adaptation VAE, conditioned on the true B' (teacher forcing)
    cond_a = actor_condition(a, b, tb)
    pad = torch.cat([ta, torch.zeros_like(ta)], dim=2)
    mu, logvar = model.adapt.encode(cond_a, pad)
    z = mu + torch.randn_like(mu) * (0.5 * logvar).exp()
    bones = a[..., at.BONE_CHILDREN, :] - a[..., _PARENT_OF_BONE, :]
    pa = assemble(a[..., 0, :], bones, model.adapt.decode(cond_a, z))
    ia, ib = (list(x) for x in zip(*[(idata.INTER18_JOINTS.index(i),
                                      idata.INTER18_JOINTS.index(j))
                                     for i, j in KEY_JOINT_PAIRS], strict=True))
    dist = (pa[..., ia, :] - tb[..., ib, :]).norm(dim=-1)
    m = batch["contact"].float()
    out.update({"a_rec": (pa - ta).norm(dim=-1).mean(),
                "a_bone": (_bone_length(pa) - _bone_length(a)).abs().mean(),
                "a_kl": _kl(mu, logvar),
                "a_jpd": (m * (dist - batch["real_distance"]).abs()).sum() / m.sum().clamp_min(1)})
    out["loss"] = (c.w_rec * (out["b_rec"] + out["a_rec"])
                   + c.w_bone * (out["b_bone"] + out["a_bone"])
                   + c.w_kl * (out["b_kl"] + out["a_kl"])
                   + c.w_rel * (out["b_vel"] + out["a_jpd"]))
    return out


def prior_losses(model: InteractionAugmenter, scales: torch.Tensor) -> dict[str, torch.Tensor]:
    """Skeleton-prior terms of (B, 17) scales: ``s_rec`` = per-sample sum over bones of
    ``|ŝ - s| / 0.25`` (a Laplace log-likelihood in units of the range's half-width; a
    per-bone mean lets the KL collapse the posterior), ``s_kl``, and ``"loss"`` =
    ``0.75 · s_rec + 0.05 · s_kl``."""
    c = model.config
    mu, logvar = model.prior.encode(scales)
    z = mu + torch.randn_like(mu) * (0.5 * logvar).exp()
    rec = ((model.prior.decode(z) - scales).abs().sum(dim=-1) / 0.25).mean()
    kl = _kl(mu, logvar)
    return {"s_rec": rec, "s_kl": kl, "loss": c.w_rec * rec + c.w_kl * kl}


def fit_prior(model: InteractionAugmenter, scales: np.ndarray, *, seed: int = 0
              ) -> dict[str, list[float]]:
    """Train the skeleton prior on (M, 17) scale vectors for ``config.prior_steps`` Adam
    steps of ``config.batch`` · 4 vectors; returns the ``prior_loss`` every 100 steps."""
    c = model.config
    rng = np.random.default_rng(seed)
    data = torch.as_tensor(scales, dtype=torch.float32)
    opt = torch.optim.Adam(model.prior.parameters(), lr=2 * c.lr)
    model.prior.train()
    curve = []
    for step in range(c.prior_steps):
        terms = prior_losses(model, data[torch.as_tensor(rng.integers(0, len(data),
                                                                      4 * c.batch))])
        opt.zero_grad()
        terms["loss"].backward()
        opt.step()
        if step % 100 == 99:
            curve.append(float(terms["loss"].detach()))
    return {"prior_loss": curve}


def _tensors(targets: at.AugmentTargets) -> dict[str, torch.Tensor]:
    return {"actor": torch.as_tensor(targets.actor),
            "reactor": torch.as_tensor(targets.reactor),
            "actor_target": torch.as_tensor(targets.actor_target),
            "reactor_target": torch.as_tensor(targets.reactor_target),
            "scales": torch.as_tensor(targets.scales, dtype=torch.float32),
            "real_distance": torch.as_tensor(targets.real_distance),
            "contact": torch.as_tensor(targets.contact)}


def fit(targets: at.AugmentTargets, config: InteractionAugmenterConfig | None = None, *,
        seed: int = 0, progress: bool = True) -> tuple[InteractionAugmenter, dict]:
    """Train the three VAEs on prepared augmentation samples (see :func:`train`)."""
    config = config or InteractionAugmenterConfig()
    if len(targets) == 0:
        raise MotionError("no augmentation samples to train on", field="targets")
    rng = seeded(seed)
    model = InteractionAugmenter(config)
    params = [p for net in (model.retarget, model.adapt) for p in net.parameters()]
    opt = torch.optim.Adam(params, lr=config.lr)
    data = _tensors(targets)
    positions = ("actor", "reactor", "actor_target", "reactor_target")
    history: dict[str, Any] = {"loss": []}
    budget = CpuBudget()
    for _ in tqdm(range(config.epochs), desc="train interaction-augment",
                  disable=not progress):
        for net in model.nets.values():
            net.train()
        order = rng.permutation(len(targets))
        sums: dict[str, float] = {}
        for k in range(0, len(order), config.batch):
            idx = torch.as_tensor(order[k:k + config.batch])
            batch = {key: v[idx] for key, v in data.items()}
            if config.rotate_augment:
                rot = _rot_z(torch.as_tensor(rng.uniform(-np.pi, np.pi, len(idx)),
                                             dtype=torch.float32))
                for key in positions:
                    batch[key] = torch.einsum("ntjc,nkc->ntjk", batch[key], rot)
            terms = losses(model, batch)
            opt.zero_grad()
            terms["loss"].backward()
            opt.step()
            for key, v in terms.items():
                sums[key] = sums.get(key, 0.0) + float(v.detach()) * len(idx)
        for key, v in sums.items():
            history.setdefault(key, []).append(v / len(targets))
    history.update(fit_prior(model, targets.scales, seed=seed))
    history["cpu_seconds"] = round(budget.seconds(), 1)
    model.metadata = {"samples": len(targets), "target_info": targets.info}
    return model, history


def train(train: idata.InteractionWindows, config: InteractionAugmenterConfig | None = None,
          *, seed: int = 0, progress: bool = True) -> tuple[InteractionAugmenter, dict]:
    """Build the augmentation targets of ``train``
    (:func:`simenv.data.augment_targets.build_targets`,
    ``config.scales_per_window`` seeded scale vectors per window), train the two graph
    VAEs side by side (Adam, one summed loss, :func:`losses`), then the skeleton prior on
    the samples' scale vectors (:func:`fit_prior`).

    Returns:
        ``(model, history)``: per-epoch ``"loss"`` and every named term, ``"cpu_seconds"``
        (training and target building) and ``"target_seconds"``.
    """
    config = config or InteractionAugmenterConfig()
    torch.set_num_threads(1)
    budget = CpuBudget()
    targets = at.build_targets(train, config.scales_per_window, seed=seed,
                               symmetric=config.symmetric_scales)
    target_seconds = budget.seconds()
    model, history = fit(targets, config, seed=seed, progress=progress)
    history["target_seconds"] = round(target_seconds, 1)
    history["cpu_seconds"] = round(budget.seconds(), 1)
    return model, history


# -- generalisation splits and evaluation --------------------------------------------------


def generalisation_splits(targets: at.AugmentTargets, windows: idata.InteractionWindows, *,
                          held_out_label: str | None = None, scale_fraction: float = 0.25,
                          test_recordings: Sequence[str] | None = idata.DEFAULT_TEST_RECORDINGS
                          ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The four generalisation splits as (train, test) sample indices (module docstring).

    Args:
        targets: samples built from ``windows`` (``targets.window`` indexes them).
        windows: the source windows (recordings and labels).
        held_out_label: class of the cross-interaction test side; None: the class whose
            share of the samples is closest to ``scale_fraction``.
        scale_fraction: share of the samples with the most extreme mean bone scale
            ``|mean_k s_k - 1|`` that form the cross-scale test side.
        test_recordings: test recordings of the random split
            (:func:`simenv.data.interaction_data.split_by_recording`).

    Raises:
        MotionError: unknown held-out label or a split side left empty.
    """
    rec = windows.window_recording_names[targets.window].astype(str)
    labels = windows.window_labels[targets.window].astype(str)
    split = idata.split_by_recording(windows, test_recordings)
    test_win = np.isin(targets.window, split.test)
    dev = np.abs(targets.scales.mean(axis=1) - 1.0)
    outer = dev > np.quantile(dev, 1.0 - scale_fraction)
    present = sorted(set(labels))
    if held_out_label is None:
        share = {c: float(np.mean(labels == c)) for c in present}
        held_out_label = min(present, key=lambda c: (abs(share[c] - scale_fraction), c))
    if held_out_label not in present:
        raise MotionError(f"held_out_label {held_out_label!r} not among the samples' "
                          f"classes ({', '.join(present)})", field="held_out_label")
    held = labels == held_out_label
    sides = {"random": (~test_win, test_win),
             "cross-scale": (~test_win & ~outer, test_win & outer),
             "cross-interaction": (~held, held),
             "both": (~held & ~outer, held & outer)}
    out = {}
    for name, (tr, te) in sides.items():
        if not tr.any() or not te.any():
            raise MotionError(f"the {name} split leaves a side empty", field="targets")
        if set(rec[tr]) & set(rec[te]):
            raise MotionError(f"the {name} split shares recordings", field="targets")
        out[name] = (np.flatnonzero(tr), np.flatnonzero(te))
    return out


def evaluate(model: InteractionAugmenter, targets: at.AugmentTargets, *, seed: int = 0
             ) -> dict[str, dict[str, float | None]]:
    """Errors of the model and of the naive baseline (B scaled by FK, A unchanged) on
    ``targets`` with their own scales.

    Returns:
        ``{"model": {...}, "naive": {...}}`` with ``B_error_mm`` / ``A_error_mm`` (mean
        joint error against B' / A'), ``jpd_contact_mm`` (mean over real contact frames of
        ``| ||a'_i - b'_j|| - d_real |``), ``bone_error_mm`` (mean ``| |b̂'_k| - s_k L_k |``
        of B' against the target-scaled lengths) and ``samples``.
    """
    na, nb, _ = model.augment(targets.actor, targets.reactor, targets.scales, seed=seed)
    naive_b = targets.reactor_target
    out = {}
    target_len = np.linalg.norm(at.bone_vectors(targets.reactor_target), axis=-1)
    for name, (pa, pb) in (("model", (na, nb)), ("naive", (targets.actor, naive_b))):
        out[name] = {
            "B_error_mm": float(1000 * np.linalg.norm(pb - targets.reactor_target,
                                                      axis=-1).mean()),
            "A_error_mm": float(1000 * np.linalg.norm(pa - targets.actor_target,
                                                      axis=-1).mean()),
            "jpd_contact_mm": at.contact_jpd_mm(pa, pb, targets.real_distance,
                                                targets.contact),
            "bone_error_mm": float(1000 * np.abs(np.linalg.norm(at.bone_vectors(pb), axis=-1)
                                                 - target_len).mean()),
            "samples": float(len(targets)),
        }
    return out


def split_benchmark(windows: idata.InteractionWindows,
                    config: InteractionAugmenterConfig | None = None, *, seed: int = 0,
                    progress: bool = True, **split_options: Any) -> dict[str, Any]:
    """Train on the train side of each generalisation split and :func:`evaluate` on its
    test side. Targets are built once for all ``windows``
    (``config.scales_per_window`` per window).

    Returns:
        ``{split: {"train": n, "test": n, "model": {...}, "naive": {...},
        "target_jpd_contact_mm": mm, "cpu_seconds": s}}``.
    """
    config = config or InteractionAugmenterConfig()
    targets = at.build_targets(windows, config.scales_per_window, seed=seed,
                               symmetric=config.symmetric_scales)
    out: dict[str, Any] = {}
    for name, (tr, te) in generalisation_splits(targets, windows, **split_options).items():
        t0 = time.process_time()
        model, history = fit(targets.subset(tr), config, seed=seed, progress=progress)
        test = targets.subset(te)
        res = evaluate(model, test, seed=seed)
        out[name] = {"train": int(len(tr)), "test": int(len(te)), **res,
                     "target_jpd_contact_mm": at.contact_jpd_mm(
                         test.actor_target, test.reactor_target, test.real_distance,
                         test.contact),
                     "contact_frames": int(test.contact.sum()),
                     "final_loss": history["loss"][-1],
                     "cpu_seconds": round(time.process_time() - t0, 1)}
    return out

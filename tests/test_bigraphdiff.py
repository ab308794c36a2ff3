"""BiGraphDiff (models/bigraphdiff.py): diffusion closed forms, graph modules, training on
real windows, sampling and checkpoints."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch

from simenv.core.errors import MotionError, SimenvError
from simenv.data import interaction_data as idata
from simenv.models import bigraphdiff as bg
from simenv.models.predictor import CheckpointError

TINY = bg.BiGraphDiffConfig(d_model=16, blocks=1, heads=2, epochs=4, batch_size=16,
                            lr=3e-3, warmup_steps=1, ema_decay=0.0, max_cpu_minutes=None)


@pytest.fixture(scope="module")
def train_windows(shared_data) -> idata.InteractionWindows:
    """A small real training subset: every 4th train window (both train classes)."""
    windows = idata.make_windows(idata.load_recordings(shared_data))
    train = windows.subset(idata.split_by_recording(windows).train)
    return train.subset(np.arange(0, len(train), 4))


@pytest.fixture(scope="module")
def trained(train_windows) -> tuple[bg.BiGraphDiff, dict]:
    return bg.train(train_windows, TINY, seed=0, progress=False)


# -- schedule ------------------------------------------------------------------------------


def test_alpha_bar_and_q_marginal_closed_forms():
    s = bg.DiffusionSchedule(np.array([0.1, 0.2, 0.5]))
    np.testing.assert_allclose(s.alpha_bar, [0.9, 0.72, 0.36])
    mean, var = s.q_mean_var(np.array([2.0, -1.0]), 1)
    np.testing.assert_allclose(mean, [2 * math.sqrt(0.72), -math.sqrt(0.72)])
    assert var == pytest.approx(0.28)
    # q_sample draws from that Gaussian
    n = 200_000
    x0 = torch.full((n, 1), 2.0, dtype=torch.float64)
    xk = s.q_sample(x0, torch.full((n,), 1), torch.randn(n, 1, dtype=torch.float64,
                                                         generator=torch.Generator().manual_seed(0)))
    assert float(xk.mean()) == pytest.approx(2 * math.sqrt(0.72), abs=5e-3)
    assert float(xk.var()) == pytest.approx(0.28, abs=5e-3)
    # x̂_0 from the true noise inverts q_sample
    eps = np.array([0.3, -1.2])
    xk = math.sqrt(0.36) * np.array([1.0, 2.0]) + math.sqrt(0.64) * eps
    np.testing.assert_allclose(s.predict_x0(xk, 2, eps), [1.0, 2.0])


def test_posterior_matches_bayes_rule():
    """q(x_{k-1} | x_k, x_0) from the prior N(√ᾱ_{k-1} x0, 1 - ᾱ_{k-1}) and the step
    likelihood N(√α_k x_{k-1}, β_k), by completing the square."""
    s = bg.DiffusionSchedule(np.array([0.1, 0.2, 0.5]))
    x0, xk = 0.7, -0.4
    for k in (1, 2):
        ab_prev, a, b = s.alpha_bar[k - 1], s.alphas[k], s.betas[k]
        precision = 1 / (1 - ab_prev) + a / b
        mean = (math.sqrt(ab_prev) * x0 / (1 - ab_prev) + math.sqrt(a) * xk / b) / precision
        assert s.posterior_variance[k] == pytest.approx(1 / precision)
        assert s.coef_x0[k] * x0 + s.coef_xt[k] * xk == pytest.approx(mean)
    # the first step's posterior is the point x_0 (ᾱ_0 = 1)
    assert s.posterior_variance[0] == 0 and s.coef_x0[0] == pytest.approx(1.0)


def test_linear_schedule_and_respacing():
    cfg = bg.BiGraphDiffConfig()
    s = bg.DiffusionSchedule.linear(cfg.diffusion_steps, cfg.beta_start, cfg.beta_end)
    assert len(s) == 100 and s.betas[0] == cfg.beta_start and s.betas[-1] == cfg.beta_end
    np.testing.assert_allclose(np.diff(s.betas), np.diff(s.betas)[0])
    assert s.alpha_bar[-1] < 1e-4  # x_K is pure noise
    short, tau = s.respaced(10)
    assert len(short) == 10 and tau[0] == 0 and tau[-1] == 99
    np.testing.assert_allclose(short.alpha_bar, s.alpha_bar[tau])
    full, tau = s.respaced(100)
    np.testing.assert_allclose(full.betas, s.betas)
    for bad in (0, 101, 2.5):
        with pytest.raises(SimenvError, match="steps"):
            s.respaced(bad)
    with pytest.raises(SimenvError, match="betas"):
        bg.DiffusionSchedule(np.array([0.1, 1.0]))


# -- graph modules -------------------------------------------------------------------------


def _jacobian_mask(fn, x: torch.Tensor, out_index: tuple) -> np.ndarray:
    x = x.clone().requires_grad_(True)
    fn(x)[out_index].sum().backward()
    return (x.grad.abs().sum(-1) > 0).numpy()


def test_bipartite_graph_swaps_with_the_persons_and_connects_every_joint_pair():
    torch.manual_seed(0)
    j = len(idata.INTER18_JOINTS)
    module = bg.BipartiteGraph(8, 2, j).double()
    with torch.no_grad():
        module.edge_bias.normal_()
    h = torch.randn(2, 2, 5, j, 8, dtype=torch.float64)
    out = module(h)
    torch.testing.assert_close(module(h.flip(1)), out.flip(1))
    # actor joint 3 at frame 2 depends on its own token and on every reactor joint at
    # frame 2, nothing else
    mask = _jacobian_mask(module, h, (0, 0, 2, 3))  # (B, 2, T, J)
    expected = np.zeros_like(mask)
    expected[0, 1, 2, :] = True
    expected[0, 0, 2, 3] = True
    np.testing.assert_array_equal(mask, expected)


def test_skeleton_graph_conv_reaches_parent_and_children_only():
    parents = idata.inter18_skeleton().parents
    module = bg.SkeletonGraphConv(4, parents).double()
    h = torch.randn(1, len(parents), 4, dtype=torch.float64)
    spine = idata.INTER18_JOINTS.index("spine")
    mask = _jacobian_mask(module, h, (0, spine))[0]
    expected = {spine, parents[spine]} | {c for c, p in enumerate(parents) if p == spine}
    assert set(np.flatnonzero(mask)) == expected
    assert {idata.INTER18_JOINTS[i] for i in expected} == {
        "spine", "pelvis", "neck", "left_shoulder", "right_shoulder"}


def test_efficient_attention_of_constant_values_is_that_value():
    """ρ_q rows and ρ_k columns sum to 1, so equal values pass through unchanged."""
    torch.manual_seed(0)
    module = bg.EfficientAttention(6, 2).double()
    with torch.no_grad():
        for lin in (module.v, module.o):
            lin.weight.copy_(torch.eye(6))
            lin.bias.zero_()
    h = torch.randn(3, 7, 6, dtype=torch.float64)
    h_const = h.clone()
    h_const[..., :] = h[:, :1]  # every frame the same token -> equal values
    out = module(h_const)
    torch.testing.assert_close(out, h_const)
    # and it is the explicit formula ρ_q(Q) (ρ_k(K)ᵀ V) per head
    q = torch.softmax(module.q(h).reshape(3, 7, 2, 3), -1)
    k = torch.softmax(module.k(h).reshape(3, 7, 2, 3), 1)
    v = h.reshape(3, 7, 2, 3)
    ref = torch.stack([q[:, :, i] @ (k[:, :, i].transpose(1, 2) @ v[:, :, i])
                       for i in range(2)], 2).reshape(3, 7, 6)
    torch.testing.assert_close(module(h), ref)


def test_bone_loss_measures_stretched_bones_in_metres_weighted_by_alpha_bar():
    parents = [-1, 0, 1]  # a chain of three joints: two bones
    x0 = torch.zeros(2, 2, 3, 3, 3)
    x0[..., 1, 2] = 1.0
    x0[..., 2, 2] = 2.0
    scale = torch.full((2, 3, 3), 0.5)  # 1 standardised unit = 0.5 m: bones of 0.5 m
    assert bg.bone_loss(x0, x0, torch.ones(2), scale, parents).item() == 0.0
    stretched = x0.clone()
    stretched[..., 2, 2] = 2.4  # the second bone 0.4 units = 0.2 m longer
    ab = torch.tensor([1.0, 0.5])
    # Per window: 0.2 m on one bone of two -> 0.1 m; weighted by alpha_bar and averaged.
    expected = (1.0 * 0.1 + 0.5 * 0.1) / 2
    assert bg.bone_loss(stretched, x0, ab, scale, parents).item() == pytest.approx(expected)


def test_mirror_is_an_involution_that_keeps_the_actor_frame(train_windows):
    a = train_windows.actor[:8]
    np.testing.assert_allclose(bg._mirror(bg._mirror(a)), a)
    _, yaw = idata.actor_frame(bg._mirror(a)[:, 0])
    np.testing.assert_allclose(yaw, 0.0, atol=1e-5)


# -- training, sampling, checkpoints -------------------------------------------------------


def test_short_training_run_lowers_the_loss(train_windows, trained):
    model, history = trained
    assert model.labels == ("salsa", "rocket_fist_bump")
    assert len(history["loss"]) == TINY.epochs and history["cpu_seconds"] > 0
    untrained = bg.BiGraphDiff(TINY, model.labels, model.mean, model.std)
    before = untrained.denoising_loss(train_windows, seed=1)
    after = model.denoising_loss(train_windows, seed=1)
    assert before == pytest.approx(1.0, abs=0.05)  # zero-initialised output: ε̂ = 0
    assert after < before - 0.1, (before, after, history["loss"])
    assert history["loss"][-1] < history["loss"][0]


def test_bone_term_adds_to_the_eps_loss_in_training(train_windows, trained):
    from dataclasses import replace

    _, plain = trained
    assert plain["loss"] == plain["eps_mse"]  # bone_weight 0: the eps MSE alone
    _, boned = bg.train(train_windows, replace(TINY, epochs=1, bone_weight=1.0), seed=0,
                        progress=False)
    # Same seed, same first epoch: the total is the eps MSE plus a positive bone term.
    assert boned["loss"][0] > boned["eps_mse"][0] > 0


def test_sampling_shapes_determinism_and_labels(trained):
    model, _ = trained
    a, r = model.sample(["salsa", "rocket_fist_bump", "salsa"], seed=3, steps=5)
    assert a.shape == r.shape == (3, 40, 18, 3) and a.dtype == r.dtype == np.float32
    assert np.isfinite(a).all() and np.isfinite(r).all()
    a2, r2 = model.sample(np.array([0, 1, 0]), seed=3, steps=5)
    np.testing.assert_array_equal(a, a2)
    np.testing.assert_array_equal(r, r2)
    a3, _ = model.sample(["salsa", "rocket_fist_bump", "salsa"], seed=4, steps=5)
    assert not np.allclose(a, a3)
    ag, _ = model.sample(["salsa"], seed=3, steps=5, guidance=2.0)
    assert ag.shape == (1, 40, 18, 3) and not np.allclose(ag[0], a[0])
    with pytest.raises(SimenvError, match="shake_hands.*salsa, 1=rocket_fist_bump"):
        model.sample(["shake_hands"])
    with pytest.raises(SimenvError, match="out of range"):
        model.sample(np.array([2]))
    with pytest.raises(SimenvError, match="non-empty"):
        model.sample([])
    with pytest.raises(SimenvError, match="steps"):
        model.sample(["salsa"], steps=0)


def test_save_load_round_trip(tmp_path, trained):
    model, history = trained
    path = model.save(tmp_path / "bgd.npz", metadata={"history": history})
    loaded = bg.BiGraphDiff.load(path)
    assert loaded.config == model.config and loaded.labels == model.labels
    assert loaded.metadata["history"]["loss"] == history["loss"]
    for x, y in zip(model.sample(["salsa", "rocket_fist_bump"], seed=7, steps=4),
                    loaded.sample(["salsa", "rocket_fist_bump"], seed=7, steps=4),
                    strict=True):
        np.testing.assert_array_equal(x, y)


def test_bad_checkpoints_and_training_input(tmp_path, train_windows):
    text = tmp_path / "x.npz"
    text.write_text("not a checkpoint")
    with pytest.raises(CheckpointError, match="cannot read"):
        bg.BiGraphDiff.load(text)
    other = tmp_path / "other.npz"
    np.savez(other, format=np.array("something-else"))
    with pytest.raises(CheckpointError, match="not a simenv-bigraphdiff"):
        bg.BiGraphDiff.load(other)
    with pytest.raises(CheckpointError, match="cannot read"):
        bg.BiGraphDiff.load(tmp_path / "missing.npz")
    with pytest.raises(MotionError, match="at least 2"):
        bg.train(train_windows.subset([0]), TINY, progress=False)


def test_shipped_checkpoint_loads_and_generates():
    from importlib import resources

    path = Path(str(resources.files("simenv.assets"))) / "models" / "bigraphdiff.npz"
    model = bg.BiGraphDiff.load(path)
    assert model.name == "bigraphdiff" and model.labels == ("salsa", "rocket_fist_bump")
    assert path.stat().st_size < 8e6
    a, r = model.sample(["rocket_fist_bump"], seed=0, steps=3)
    assert a.shape == r.shape == (1, 40, 18, 3)
    assert np.isfinite(a).all() and np.isfinite(r).all()

"""Tests for simenv.models.predictor (PredictiveMA-WGAN) on real CMU windows."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import torch

from simenv.core import srvf
from simenv.core.errors import MotionError, SimenvError
from simenv.data import prediction_data as pdata
from simenv.io import bvh
from simenv.models import load
from simenv.models import predictor as P
from simenv.models.baselines import ZeroVelocity

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def windows(shared_data):
    clips = [bvh.read(shared_data / "cmu" / "bvh" / f"{n}.bvh") for n in ("02_01", "49_02")]
    return pdata.windows_from_motions(clips, 10, 10, stride=4)


@pytest.fixture(scope="module")
def fitted(windows):
    torch.manual_seed(0)
    return P.fit_geometry(windows, P.PredictorConfig(10, 10), tol=1e-5)


def _batch(model, windows, n=32):
    return model.prepare(windows.subset(np.arange(n)))


def test_karcher_means_are_unit_points_and_scales_standardise(fitted, windows):
    assert fitted.mu_past.shape == fitted.mu_future.shape == (10, 51)
    assert srvf.norm(fitted.mu_past) == pytest.approx(1.0)
    assert fitted.config.info["karcher_future"]["converged"]
    batch = fitted.prepare(windows)
    assert batch.cond.shape == (len(windows), fitted.config.cond_dim)
    assert batch.u_future.shape == (len(windows), 10, 51)
    assert batch.u_future.pow(2).mean().item() == pytest.approx(1.0, rel=1e-3)


def test_network_shapes(fitted):
    for f in (10, 25, 50):
        gen = P.Generator(fitted.config.cond_dim, f)
        critic = P.Critic(fitted.config.cond_dim, f)
        cond = torch.randn(3, fitted.config.cond_dim)
        u = gen(cond, torch.randn(3, 16))
        assert u.shape == (3, f, 51)
        assert gen.lengths[-1] == f and len(gen.lengths) == 6  # 5 upsampling blocks
        assert critic(u, cond).shape == (3,)


def test_torch_sphere_maps_match_simenv_srvf(fitted):
    rng = np.random.default_rng(0)
    mu = fitted.mu_future
    v = srvf.project_tangent(mu, rng.normal(size=(4, 10, 51)) * 0.2)
    mu_t = torch.as_tensor(mu)
    np.testing.assert_allclose(P.t_exp(mu_t, torch.as_tensor(v)).numpy(),
                               srvf.exp_map(mu, v), atol=1e-10)
    q = rng.normal(size=(4, 10, 51))
    start = rng.normal(size=(4, 51))
    np.testing.assert_allclose(P.t_inverse_srvf(torch.as_tensor(q), torch.as_tensor(start)),
                               srvf.inverse_srvf(q, start)[:, 1:], atol=1e-5)


def test_projection_makes_generator_output_tangent(fitted):
    raw = torch.randn(5, 10, 51, dtype=torch.float64) + 3 * torch.as_tensor(fitted.mu_future)
    mu = torch.as_tensor(fitted.mu_future)
    assert P.t_inner(raw, mu.expand_as(raw)).abs().min() > 1.0
    tangent = P.t_project_tangent(mu, raw)
    np.testing.assert_allclose(P.t_inner(tangent, mu.expand_as(raw)).numpy(), 0.0, atol=1e-12)
    # projecting twice changes nothing; the decoded points lie on the unit sphere
    np.testing.assert_allclose(P.t_project_tangent(mu, tangent), tangent, atol=1e-12)
    _, points = fitted.decode(raw.float(), torch.zeros(5), torch.zeros(5, 51))
    np.testing.assert_allclose(srvf.norm(points.double().numpy()), 1.0, atol=1e-5)


def test_gradient_penalty_matches_a_manual_computation():
    class Linear(torch.nn.Module):
        def __init__(self, w):
            super().__init__()
            self.w = w

        def forward(self, u, cond):
            return (u * self.w).sum(dim=(1, 2)) + cond[:, 0]

    class Quadratic(torch.nn.Module):
        def forward(self, u, cond):
            return 0.5 * (u**2).sum(dim=(1, 2)) * cond[:, 0]

    gen = torch.Generator().manual_seed(0)
    real, fake = torch.randn(4, 3, 2, generator=gen), torch.randn(4, 3, 2, generator=gen)
    cond = torch.rand(4, 1, generator=gen) + 0.5
    eps = torch.rand(4, generator=gen)
    w = torch.randn(3, 2, generator=gen)
    # linear critic: gradient w everywhere -> (||w|| - 1)^2
    gp = P.gradient_penalty(Linear(w), real, fake, cond, eps)
    assert gp.item() == pytest.approx((w.norm().item() - 1) ** 2, rel=1e-6)
    # quadratic critic: gradient c * x at the interpolate x
    x = eps[:, None, None] * real + (1 - eps[:, None, None]) * fake
    manual = ((cond[:, 0] * x.flatten(1).norm(dim=1) - 1) ** 2).mean()
    gp = P.gradient_penalty(Quadratic(), real, fake, cond, eps)
    assert gp.item() == pytest.approx(manual.item(), rel=1e-6)


def test_gram_and_bone_losses_see_shape_not_rotation(windows):
    future = torch.as_tensor(windows.future[:4], dtype=torch.float64)
    last = torch.as_tensor(windows.past[:4, -1], dtype=torch.float64)
    rot = torch.as_tensor(P.rotate_z(windows.future[:4].astype(np.float64), np.full(4, 0.7)))
    assert P.gram_loss(rot, future).item() < 1e-12
    assert P.bone_loss(rot, last).item() < 1e-3  # real bones: rigid to < 1 mm
    assert P.gram_loss(1.2 * future, future).item() > 0.01
    assert P.bone_loss(1.2 * future, last).item() > 0.01


def test_losses_decrease_on_a_tiny_real_batch(fitted, windows):
    model = P.PredictiveMAWGAN(fitted.config, fitted.mu_past, fitted.mu_future)
    torch.manual_seed(1)
    batch = _batch(model, windows)
    z = torch.zeros(len(batch), 16)
    opt_g = torch.optim.Adam(model.generator.parameters(), lr=1e-3)
    opt_c = torch.optim.Adam(model.critic.parameters(), lr=1e-3)
    opt_a = torch.optim.Adam(model.amplitude.parameters(), lr=1e-3)
    recs, critics, amps = [], [], []
    for _ in range(25):
        loss_c, info_c = P.critic_loss(model, batch, z)
        opt_c.zero_grad()
        loss_c.backward()
        opt_c.step()
        loss_g, info_g, u = P.generator_loss(model, batch, z)
        opt_g.zero_grad()
        loss_g.backward()
        opt_g.step()
        loss_a = P.amplitude_loss(model, batch, u)
        opt_a.zero_grad()
        loss_a.backward()
        opt_a.step()
        recs.append(info_g["rec"] + 10 * info_g["gram"] + 10 * info_g["bone"])
        critics.append(info_c["critic"])
        amps.append(loss_a.item())
    assert np.mean(recs[-5:]) < 0.7 * np.mean(recs[:3])
    assert np.mean(amps[-5:]) < np.mean(amps[:3])
    assert min(critics[-5:]) < critics[0]  # the critic learns to separate real from fake


def test_prediction_starts_at_the_last_observed_pose(fitted, windows):
    history = windows.frames[:6, :11]
    pred = fitted.predict(history)
    assert pred.shape == (6, 10, 17, 3) and pred.dtype == np.float32
    last = history[:, -1].astype(np.float64)
    # the future curve [last, pred] integrates the predicted SRVF from the last pose:
    # its first step is one SRVF step, as small as real frame-to-frame motion
    first_step = np.linalg.norm(pred[:, 0] - last, axis=-1).max()
    real_step = np.linalg.norm(np.diff(windows.frames[:6], axis=1), axis=-1).max()
    assert first_step < 2 * real_step
    # and rebuilding it from its own SRVF at the exact last pose gives it back
    curve = np.concatenate([last[:, None], pred.astype(np.float64)], 1).reshape(6, 11, 51)
    rebuilt = srvf.inverse_srvf(srvf.srvf(curve), last.reshape(6, 51))
    np.testing.assert_allclose(rebuilt, curve, atol=1e-9)
    # heading: rotating the history about Z rotates the prediction the same way
    turned = P.rotate_z(history.astype(np.float64), np.full(6, 1.1))
    np.testing.assert_allclose(fitted.predict(turned),
                               P.rotate_z(pred.astype(np.float64), np.full(6, 1.1)), atol=1e-4)
    # a single history, a longer history (last 11 frames used), carried amplitude, noise
    np.testing.assert_allclose(fitted.predict(history[0]), pred[0], atol=1e-6)
    np.testing.assert_allclose(fitted.predict(windows.frames[:6, :15])[0],
                               fitted.predict(windows.frames[:6, 4:15])[0], atol=1e-6)
    assert not np.allclose(fitted.predict(history, amplitude="carried"), pred)
    np.testing.assert_array_equal(fitted.predict(history, seed=3),
                                  fitted.predict(history, seed=3))


def test_bad_histories_are_clear_errors(fitted, windows):
    with pytest.raises(MotionError, match="needs at least 11"):
        fitted.predict(windows.frames[:2, :5])
    bad = windows.frames[:2, :11].copy()
    bad[1, 7, 3, 2] = np.nan
    with pytest.raises(MotionError, match=r"frame 7.*window 1, joint 3"):
        fitted.predict(bad)
    with pytest.raises(MotionError, match="expects 17"):
        fitted.predict(windows.frames[:2, :11, :15])
    with pytest.raises(MotionError, match="amplitude"):
        fitted.predict(windows.frames[:2, :11], amplitude="guess")


def test_checkpoint_round_trip(fitted, windows, tmp_path):
    path = fitted.save(tmp_path / "p.npz")
    again = P.PredictiveMAWGAN.load(path)
    assert again.config == fitted.config
    history = windows.frames[:4, :11]
    np.testing.assert_array_equal(again.predict(history), fitted.predict(history))
    for a, b in zip(again.critic.parameters(), fitted.critic.parameters(), strict=True):
        assert torch.equal(a, b)
    small = fitted.save(tmp_path / "g.npz", with_critic=False)
    assert small.stat().st_size < path.stat().st_size
    np.testing.assert_array_equal(P.PredictiveMAWGAN.load(small).predict(history),
                                  fitted.predict(history))
    (tmp_path / "junk.npz").write_bytes(b"not a checkpoint")
    with pytest.raises(P.CheckpointError, match="junk.npz"):
        P.PredictiveMAWGAN.load(tmp_path / "junk.npz")


def test_rollout_chains_predictions(fitted, windows):
    history = windows.frames[:3, :11]
    out = P.rollout(fitted, history, 25)
    assert out.shape == (3, 25, 17, 3)
    np.testing.assert_allclose(out[:, :10], fitted.predict(history), atol=1e-6)
    second = fitted.predict(np.concatenate([history, out[:, :10]], 1))
    np.testing.assert_allclose(out[:, 10:20], second, atol=1e-5)
    np.testing.assert_array_equal(P.rollout(ZeroVelocity(10), history, 25),
                                  np.repeat(history[:, -1:], 25, 1))


def test_models_load_by_name():
    zv = load("zero-velocity-25")
    assert zv.future_len == 25
    with pytest.raises(SimenvError, match="unknown model 'predictor-9-9'"):
        load("predictor-9-9")


@pytest.mark.parametrize("name", ["predictor-10-10", "predictor-25-25", "predictor-25-50"])
def test_shipped_checkpoints_load_and_predict(name, windows):
    from simenv.models import available

    if name not in available():
        pytest.skip(f"{name} is not shipped")
    model = load(name)
    p, f = (int(x) for x in name.split("-")[1:])
    assert (model.past_len, model.future_len, model.fps) == (p, f, 25.0)
    history = windows.frames[:2, :11]
    history = np.concatenate([np.repeat(history[:, :1], p + 1 - 11, 1), history], 1) \
        if p + 1 > 11 else history
    out = model.predict(history)
    assert out.shape == (2, f, 17, 3) and np.isfinite(out).all()
    assert math.isfinite(float(np.abs(out).max()))


def test_joint_amplitude_trains_the_head_through_the_position_losses(fitted, windows):
    batch = _batch(fitted, windows, 16)
    z = torch.zeros(len(batch), 16)
    for joint in (False, True):
        for net in (fitted.generator, fitted.amplitude):
            net.zero_grad()
        loss, terms, _ = P.generator_loss(fitted, batch, z, P.LOSS_WEIGHTS | {"adv": 0.0},
                                          joint_amplitude=joint)
        loss.backward()
        head = sum(p.grad.abs().sum().item() for p in fitted.amplitude.parameters()
                   if p.grad is not None)
        gen = sum(p.grad.abs().sum().item() for p in fitted.generator.parameters())
        assert gen > 0
        assert (head > 0) == joint
    fitted.generator.zero_grad()
    fitted.amplitude.zero_grad()


@pytest.fixture(scope="module")
def with_prior(windows):
    config = P.PredictorConfig(10, 10, prior="damped_velocity", velocity_condition=True)
    return P.fit_geometry(windows, config, tol=1e-5)


def _normalised(windows):
    frames = windows.frames.astype(np.float64)
    return P.rotate_z(frames, -P.heading(frames[:, windows.past_len]))


def test_fitted_priors_err_less_than_zero_velocity_on_their_windows(windows):
    frames = _normalised(windows)
    w_damped, fit = P.fit_prior(frames, 10, "damped_velocity")
    # the grid holds d = 0 (zero-velocity), so the chosen damping errs no more
    assert fit["damping"] in P.DAMPING_GRID
    assert fit["train_error_mm"] <= fit["zero_velocity_train_error_mm"]
    assert np.count_nonzero(w_damped.any(axis=1)) <= 1  # only the last velocity is used
    w_lin, fit_lin = P.fit_prior(frames, 10, "linear")
    assert w_lin.shape == (11, 10)
    # ridge least squares: its squared residual is below that of W = 0
    flat = frames.reshape(len(frames), 21, 51)
    hist, fut = flat[:, :11] - flat[:, 10:11], flat[:, 11:] - flat[:, 10:11]
    resid = np.einsum("nhd,hf->nfd", hist, w_lin) - fut
    assert (resid**2).sum() < (fut**2).sum()
    with pytest.raises(MotionError, match="prior"):
        P.fit_prior(frames, 10, "quadratic")


def test_a_fresh_model_with_a_prior_predicts_the_prior(with_prior, windows):
    model = with_prior
    assert model.config.cond_dim == 10 * 51 + 1 + 51 + 51
    history = windows.frames[:8, :11]
    pred = model.predict(history)
    angle = P.heading(history[:, -1])
    prior = model.prior_future(P.rotate_z(history.astype(np.float64), -angle))
    expected = P.rotate_z(prior.reshape(8, 10, 17, 3), angle)
    np.testing.assert_allclose(pred, expected, atol=1e-5)
    # the damped-velocity prior continues the last velocity, shrinking every step
    step = np.linalg.norm(np.diff(np.concatenate([history[:, -1:], pred], 1), axis=1),
                          axis=-1).mean(axis=(0, 2))
    assert np.all(np.diff(step) <= 1e-7)
    batch = _batch(model, windows, 8)
    assert batch.u_base.abs().max() > 0 and batch.u_base.shape == (8, 10, 51)


def test_training_with_a_prior_moves_away_from_it(with_prior, windows):
    model = P.PredictiveMAWGAN(with_prior.config, with_prior.mu_past, with_prior.mu_future,
                               with_prior.prior_filter)
    torch.manual_seed(0)
    batch = _batch(model, windows)
    z = torch.zeros(len(batch), 16)
    params = list(model.generator.parameters()) + list(model.amplitude.parameters())
    opt = torch.optim.Adam(params, lr=1e-3)
    recs = []
    for _ in range(20):
        loss, info, _ = P.generator_loss(model, batch, z, P.LOSS_WEIGHTS | {"adv": 0.0},
                                         joint_amplitude=True)
        opt.zero_grad()
        loss.backward()
        opt.step()
        recs.append(info["rec"])
    assert recs[-1] < recs[0]  # the correction lowers the error of the prior


def test_mirror_average_makes_the_predictor_mirror_equivariant(with_prior, windows):
    model = P.PredictiveMAWGAN(with_prior.config, with_prior.mu_past, with_prior.mu_future,
                               with_prior.prior_filter)
    torch.manual_seed(3)
    for layer in (model.generator.convs[-1], model.amplitude.net[-1]):
        torch.nn.init.normal_(layer.weight, std=0.05)  # a correction that is not mirrored
    history = windows.frames[:5, :11]
    plain = model.predict(history)
    assert not np.allclose(model.predict(P.mirror(history)), P.mirror(plain), atol=1e-3)
    model.config = P.PredictorConfig(**{**vars(with_prior.config), "mirror_average": True})
    averaged = model.predict(history)
    np.testing.assert_allclose(model.predict(P.mirror(history)), P.mirror(averaged),
                               atol=1e-5)


def test_checkpoint_with_a_prior_round_trips(with_prior, windows, tmp_path):
    path = with_prior.save(tmp_path / "prior.npz", with_critic=False)
    again = P.PredictiveMAWGAN.load(path)
    assert again.config == with_prior.config
    np.testing.assert_array_equal(again.prior_filter, with_prior.prior_filter)
    history = windows.frames[:3, :11]
    np.testing.assert_array_equal(again.predict(history), with_prior.predict(history))
    with pytest.raises(P.CheckpointError, match="prior filter"):
        P.PredictiveMAWGAN(with_prior.config, with_prior.mu_past, with_prior.mu_future)
    with pytest.raises(MotionError, match="prior must be one of"):
        P.PredictiveMAWGAN(P.PredictorConfig(10, 10, prior="spline"),
                           with_prior.mu_past, with_prior.mu_future)


def _bones(frames):
    child = list(range(1, 17))
    par = [P.PARENTS[j] for j in child]
    return np.linalg.norm(frames[..., child, :] - frames[..., par, :], axis=-1)


def test_restore_bone_lengths_keeps_directions_and_real_skeletons(windows):
    last = torch.as_tensor(windows.past[:6, -1], dtype=torch.float64)
    future = torch.as_tensor(windows.future[:6], dtype=torch.float64)
    # real mocap futures already have the last observed pose's bones: nothing moves
    np.testing.assert_allclose(P.restore_bone_lengths(future, last), future, atol=2e-3)
    # a blend of poses (as a linear prior makes) has other bone lengths; restored, it
    # has the reference's, and every bone keeps its direction
    blend = 0.5 * (future + future.flip(1)) + 0.02 * torch.sin(
        torch.arange(17 * 3, dtype=torch.float64)).view(17, 3)
    out = P.restore_bone_lengths(blend, last).numpy()
    assert np.abs(_bones(blend.numpy()) - _bones(last.numpy())[:, None]).max() > 0.02
    np.testing.assert_allclose(_bones(out), np.broadcast_to(
        _bones(last.numpy())[:, None], _bones(out).shape), atol=1e-9)
    np.testing.assert_allclose(out[..., 0, :], blend[..., 0, :].numpy(), atol=1e-12)
    for j in range(1, 17):
        d_in = blend[..., j, :] - blend[..., P.PARENTS[j], :]
        d_out = out[..., j, :] - out[..., P.PARENTS[j], :]
        cos = (d_in.numpy() * d_out).sum(-1) / (np.linalg.norm(d_out, axis=-1)
                                                 * d_in.norm(dim=-1).numpy())
        np.testing.assert_allclose(cos, 1.0, atol=1e-9)


def test_restore_bones_predicts_the_observed_skeleton(windows):
    config = P.PredictorConfig(10, 10, prior="linear", velocity_condition=True,
                               restore_bones=True)
    model = P.fit_geometry(windows, config, tol=1e-5)
    history = windows.frames[:8, :11]
    pred = model.predict(history)
    drift = np.abs(_bones(pred.astype(np.float64))
                   - _bones(history[:, -1].astype(np.float64))[:, None])
    assert drift.max() < 1e-5
    # also a trained (non-zero) correction, averaged with its mirror image
    torch.manual_seed(3)
    torch.nn.init.normal_(model.generator.convs[-1].weight, std=0.05)
    model.config = replace(config, mirror_average=True)
    pred = model.predict(history)
    drift = np.abs(_bones(pred.astype(np.float64))
                   - _bones(history[:, -1].astype(np.float64))[:, None])
    assert drift.max() < 1e-5
    model.config = config
    # without the restoration the same linear prior drifts (it blends poses)
    plain = P.PredictiveMAWGAN(replace(config, restore_bones=False),
                               model.mu_past, model.mu_future, model.prior_filter)
    raw = plain.predict(history)
    assert np.abs(_bones(raw.astype(np.float64))
                  - _bones(history[:, -1].astype(np.float64))[:, None]).mean() > 1e-3
    # training sees the restored frames: its bone loss is ~0
    batch = _batch(model, windows, 8)
    _, terms, _ = P.generator_loss(model, batch, torch.zeros(8, 16), joint_amplitude=True)
    assert terms["bone"] < 1e-4


def test_prior_amplitude_and_true_amplitude_target(with_prior, fitted, windows):
    model = P.PredictiveMAWGAN(with_prior.config, with_prior.mu_past, with_prior.mu_future,
                               with_prior.prior_filter)
    torch.manual_seed(2)
    torch.nn.init.normal_(model.amplitude.net[-1].weight, std=0.5)  # head != 0
    history = windows.frames[:4, :11]
    # amplitude "prior" ignores the head: a fresh model's prediction, the prior itself
    fresh = with_prior.predict(history)
    np.testing.assert_allclose(model.predict(history, amplitude="prior"), fresh, atol=1e-5)
    assert not np.allclose(model.predict(history), fresh, atol=1e-4)
    with pytest.raises(MotionError, match="prior future"):
        fitted.predict(history, amplitude="prior")
    # the "true" target is the log-amplitude error, 0 exactly at the true amplitude
    batch = _batch(model, windows, 16)
    u = model.direction(batch.cond, batch.u_base, torch.zeros(16, 16))
    log_amp = model.log_amplitude(batch.cond, batch.log_amp_past, base=batch.log_amp_base)
    expected = (log_amp - batch.log_amp_future).abs().mean()
    assert P.amplitude_loss(model, batch, u, "true").item() == pytest.approx(expected.item())
    with pytest.raises(MotionError, match="target"):
        P.amplitude_loss(model, batch, u, "speed")

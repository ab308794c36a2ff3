"""Tests for simenv.models.reactive_gan: every loss term on a toy input with a known
value, the attention and chunking math, the reaction-generator protocol, bad input,
checkpoint round trip and a short real training run on real two-person windows."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from simenv.core.errors import MotionError
from simenv.data import interaction_data as idata
from simenv.models import reactive_gan as rg
from simenv.models.predictor import CheckpointError
from simenv.models.reaction_baselines import ReactionGenerator, ZeroVelocity

torch.set_num_threads(1)

#: A tiny configuration for tests (seconds of CPU).
TINY = rg.ReactiveGANConfig(labels=("shake_hands", "salsa", "rocket_fist_bump"),
                            window=20, part_hidden=8, decoder_hidden=32, disc_hidden=16,
                            epochs=3, batch_size=32)


@pytest.fixture(scope="module")
def windows(shared_data: Path) -> tuple[idata.InteractionWindows, idata.InteractionWindows]:
    """Real train / test windows of the default split."""
    w = idata.make_windows(idata.load_recordings(shared_data))
    split = idata.split_by_recording(w)
    return w.subset(split.train), w.subset(split.test)


@pytest.fixture(scope="module")
def trained(windows) -> tuple[rg.ReactiveGAN, dict]:
    """A tiny model trained briefly on 48 real training windows."""
    train, _ = windows
    pick = np.random.default_rng(0).permutation(len(train))
    return rg.train(train.subset(pick[:48]), replace(TINY, epochs=4), seed=0,
                    progress=False, validation=train.subset(pick[48:56]))


# -- losses on toy inputs ----------------------------------------------------------------


def test_l1_loss_known_value():
    pred = torch.zeros(2, 3, 18, 3)
    target = torch.full((2, 3, 18, 3), 0.5)
    target[0] = -0.25
    assert rg.l1_loss(pred, target).item() == pytest.approx(0.375)


def test_bone_length_loss_of_a_doubled_skeleton_is_the_mean_bone_length():
    rng = np.random.default_rng(1)
    ref = torch.as_tensor(rng.normal(size=(2, 18, 3)))
    pred = (2.0 * ref)[:, None].repeat(1, 4, 1, 1)  # every bone twice as long
    child = [j for j, p in enumerate(rg.PARENTS) if p >= 0]
    par = [rg.PARENTS[j] for j in child]
    mean_bone = (ref[:, child] - ref[:, par]).norm(dim=-1).mean().item()
    assert rg.bone_length_loss(pred, ref).item() == pytest.approx(mean_bone)
    assert rg.bone_length_loss(ref[:, None].repeat(1, 4, 1, 1), ref).item() == 0.0


def test_continuity_hinge_known_values():
    # x_t = (t mod 5) m along x for one joint: with k = 5, x_{t+5} = x_t, so the hinge is
    # the step size ||x_{t+1} - x_t||: 1, 1, 1, 1 and 4 (the jump back), mean 8/5.
    x = torch.zeros(1, 10, 1, 3)
    x[0, :, 0, 0] = torch.arange(10) % 5
    assert rg.continuity_loss(x, dt=1, k=5).item() == pytest.approx(1.6)
    # Uniform motion moves away monotonically: the hinge is 0.
    line = torch.zeros(1, 12, 1, 3)
    line[0, :, 0, 2] = 0.1 * torch.arange(12)
    assert rg.continuity_loss(line, dt=1, k=5).item() == 0.0


def test_continuity_hinge_with_k_equal_dt_is_constant_zero():
    x = torch.randn(3, 10, 18, 3, requires_grad=True)
    loss = rg.continuity_loss(x, dt=1, k=1)
    loss.backward()
    assert loss.item() == 0.0
    assert torch.count_nonzero(x.grad) == 0
    with pytest.raises(MotionError, match="continuity hinge"):
        rg.continuity_loss(x, dt=1, k=10)


def test_unsupervised_losses_known_values():
    # sigma(log 9) = 0.9: the smoothed real target, where the real term is minimal and
    # equals the binary entropy H(0.9); the fake term at sigma = 0.1 is -log 0.9.
    logit = torch.tensor([math.log(9.0)])
    h09 = -(0.9 * math.log(0.9) + 0.1 * math.log(0.1))
    value = rg.unsupervised_d_loss(logit, -logit, real_label=0.9).item()
    assert value == pytest.approx(h09 - math.log(0.9))
    for other in (math.log(8.0), math.log(10.0)):  # one-sided smoothing: 0.9 is the optimum
        assert rg.unsupervised_d_loss(torch.tensor([other]), -logit).item() > value
    assert rg.unsupervised_g_loss(torch.zeros(5)).item() == pytest.approx(math.log(2.0))


def test_supervised_losses_known_values():
    labels = torch.tensor([0, 2, 1])
    uniform = torch.zeros(3, 4)  # N = 3 classes + fake
    assert rg.supervised_d_loss(uniform, uniform, labels).item() == pytest.approx(
        2 * math.log(4.0))
    assert rg.supervised_g_loss(uniform, labels).item() == pytest.approx(math.log(4.0))
    sure_real = 50.0 * torch.nn.functional.one_hot(labels, 4).float()
    sure_fake = 50.0 * torch.nn.functional.one_hot(torch.full((3,), 3), 4).float()
    assert rg.supervised_d_loss(sure_real, sure_fake, labels).item() < 1e-12
    assert rg.supervised_g_loss(sure_fake, labels).item() == pytest.approx(50.0)


def test_global_attention_selects_the_matching_memory_row():
    att = rg.GlobalAttention(query=3, memory=3)
    with torch.no_grad():
        att.w_a.weight.copy_(100.0 * torch.eye(3))
    memory = torch.eye(3)[None]  # three orthogonal encodings
    _, alpha = att(torch.tensor([[0.0, 1.0, 0.0]]), memory)
    assert alpha.sum().item() == pytest.approx(1.0)
    assert alpha[0, 1].item() > 0.999


# -- math helpers ------------------------------------------------------------------------


def test_body_parts_partition_the_layout():
    joints = [j for part in rg.BODY_PARTS.values() for j in part]
    assert sorted(joints) == sorted(idata.INTER18_JOINTS)
    assert len(rg.BODY_PARTS) == 5


def test_chunks_share_one_frame():
    assert rg._chunks(85, 40) == [(0, 40), (39, 79), (78, 85)]
    assert rg._chunks(40, 40) == [(0, 40)]
    assert rg._chunks(2, 40) == [(0, 2)]


def test_mirror_keeps_the_actor_frame(windows):
    train, _ = windows
    m = rg.mirror_windows(train.actor[:20, 0])
    origin, yaw = idata.actor_frame(m)
    np.testing.assert_allclose(yaw, 0.0, atol=1e-5)
    np.testing.assert_allclose(origin, 0.0, atol=1e-5)
    np.testing.assert_array_equal(rg.mirror_windows(m), train.actor[:20, 0])


# -- protocol and bad input --------------------------------------------------------------


def test_untrained_generator_is_zero_velocity(windows):
    _, test = windows
    model = rg.ReactiveGAN(TINY)
    out = model.generate(test.actor[:4], test.reactor[:4, 0])
    ref = ZeroVelocity().generate(test.actor[:4], test.reactor[:4, 0])
    np.testing.assert_allclose(out, ref, atol=1e-5)


def test_protocol_shapes_and_long_windows(trained, windows):
    model, _ = trained
    _, test = windows
    assert isinstance(model, ReactionGenerator) and model.name == "reactive-gan"
    batch = model.generate(test.actor[:3], test.reactor[:3, 0])
    assert batch.shape == (3, 40, 18, 3) and batch.dtype == np.float32
    np.testing.assert_allclose(batch[:, 0], test.reactor[:3, 0], atol=1e-6)
    single = model.generate(test.actor[0], test.reactor[0, 0])
    np.testing.assert_allclose(single, batch[0], atol=1e-5)
    short = model.generate(test.actor[0, :2], test.reactor[0, 0])
    assert short.shape == (2, 18, 3)
    # 40 frames with a 20-frame trained window: chunks (0, 20), (19, 39), (38, 40), each
    # starting from the last generated frame; the first chunk is a plain 20-frame run.
    long = model.generate(test.actor[:2], test.reactor[:2, 0])
    np.testing.assert_allclose(long[:, :20], model.generate(test.actor[:2, :20],
                                                            test.reactor[:2, 0]), atol=1e-5)
    assert np.isfinite(long).all() and not np.allclose(long[:, 20:], long[:, 19:20])


def test_generation_is_equivariant_to_rigid_motions_about_z(trained, windows):
    model, _ = trained
    _, test = windows
    a, b0 = test.actor[:2].astype(np.float64), test.reactor[:2, 0].astype(np.float64)
    c, s = math.cos(1.1), math.sin(1.1)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    shift = np.array([2.0, -1.5, 0.0])
    moved = model.generate(a @ rot.T + shift, b0 @ rot.T + shift)
    np.testing.assert_allclose(moved, model.generate(a, b0) @ rot.T + shift, atol=1e-4)


def test_noise_seed_changes_the_trained_reaction(trained, windows):
    model, _ = trained
    _, test = windows
    one = model.generate(test.actor[:2], test.reactor[:2, 0], seed=1)
    np.testing.assert_array_equal(one, model.generate(test.actor[:2], test.reactor[:2, 0],
                                                      seed=1))
    assert not np.allclose(one, model.generate(test.actor[:2], test.reactor[:2, 0], seed=2))


def test_bad_input_errors(trained, windows):
    model, _ = trained
    _, test = windows
    a, b0 = test.actor[:2], test.reactor[:2, 0]
    with pytest.raises(MotionError, match="actor_window"):
        model.generate(a[:, :, :17], b0)
    with pytest.raises(MotionError, match="reactor_first_frame"):
        model.generate(a, b0[:1])
    bad = a.copy()
    bad[0, 3, 2, 1] = np.nan
    with pytest.raises(MotionError, match="non-finite"):
        model.generate(bad, b0)
    with pytest.raises(MotionError, match="at least 2 frames"):
        model.generate(a[:, :1], b0)
    with pytest.raises(MotionError, match="labels"):
        rg.ReactiveGAN(replace(TINY, labels=()))


def test_train_rejects_bad_windows(windows):
    train, _ = windows
    with pytest.raises(MotionError, match="labels"):
        rg.train(train.subset(np.arange(4)), replace(TINY, labels=("wave",)),
                 progress=False)
    with pytest.raises(MotionError, match="config.window"):
        rg.train(train.subset(np.arange(4)), replace(TINY, window=60), progress=False)


# -- checkpoints -------------------------------------------------------------------------


def test_save_load_round_trip(trained, windows, tmp_path):
    model, history = trained
    _, test = windows
    path = model.save(tmp_path / "rgan.npz", metadata={"epochs": history["epochs"]})
    with np.load(path, allow_pickle=False) as data:  # arrays only, no pickle
        assert str(data["format"]) == rg.CHECKPOINT_FORMAT
    back = rg.ReactiveGAN.load(path)
    assert back.config == model.config and back.metadata == {"epochs": 4}
    for seed in (None, 3):
        np.testing.assert_array_equal(
            back.generate(test.actor[:3], test.reactor[:3, 0], seed=seed),
            model.generate(test.actor[:3], test.reactor[:3, 0], seed=seed))


def test_load_bad_files(tmp_path):
    with pytest.raises(CheckpointError, match="cannot read"):
        rg.ReactiveGAN.load(tmp_path / "missing.npz")
    other = tmp_path / "other.npz"
    np.savez(other, format=np.array("something-else"))
    with pytest.raises(CheckpointError, match="not a"):
        rg.ReactiveGAN.load(other)
    good = rg.ReactiveGAN(TINY).save(tmp_path / "good.npz")
    with np.load(good) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["config"] = np.array('{"labels": ["salsa"], "part_hidden": 5}')
    np.savez(tmp_path / "mismatch.npz", **arrays)
    with pytest.raises(CheckpointError, match="do not fit"):
        rg.ReactiveGAN.load(tmp_path / "mismatch.npz")


# -- real training -------------------------------------------------------------------------


def test_short_real_training_lowers_the_loss(trained):
    _, history = trained
    assert history["epochs"] == 4 and history["windows"] == 96  # 48 + their mirror images
    for key in ("loss", "d_loss", "l1", "bone", "continuity", "g_unsup", "g_sup"):
        assert len(history[key]) == 4 and np.isfinite(history[key]).all()
    assert history["l1"][-1] < history["l1"][0]
    assert history["loss"][-1] < history["loss"][0]
    assert history["cpu_seconds"] > 0
    assert len(history["val_joint_error_mm"]) == 4
    assert all(0 < e < 2000 for e in history["val_joint_error_mm"])


def test_shipped_checkpoint_loads_and_generates(windows):
    from importlib import resources

    path = Path(str(resources.files("simenv.assets"))) / "models" / "reactive-gan.npz"
    model = rg.ReactiveGAN.load(path)
    assert model.name == "reactive-gan" and model.config.window == idata.WINDOW_FRAMES
    assert model.metadata["train_windows"] > 0 and path.stat().st_size < 8_000_000
    _, test = windows
    out = model.generate(test.actor[:4], test.reactor[:4, 0])
    assert out.shape == test.reactor[:4].shape and np.isfinite(out).all()
    np.testing.assert_allclose(out[:, 0], test.reactor[:4, 0], atol=1e-6)
    assert not np.allclose(out[:, 1:], out[:, :1])  # trained: it moves

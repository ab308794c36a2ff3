"""Tests for simenv.models.predictor_attention (joint-attention DCT network) on real CMU
windows."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from simenv import prediction_data as pdata
from simenv import train_predictor as tp
from simenv import train_predictor_families as fam
from simenv.errors import MotionError
from simenv.io import bvh
from simenv.models import predictor as P
from simenv.models.baselines import ZeroVelocity
from simenv.models.checkpoint import CheckpointError
from simenv.models.predictor_attention import AttentionConfig, AttentionPredictor, inputs
from simenv.models.predictor_regression import regression_loss, targets

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def clips(shared_data):
    return [bvh.read(shared_data / "cmu" / "bvh" / f"{n}.bvh") for n in ("02_01", "49_02")]


@pytest.fixture(scope="module")
def windows(clips):
    return pdata.windows_from_motions(clips, 10, 10, stride=4)


def _perturbed(config: AttentionConfig, seed: int) -> AttentionPredictor:
    """A model whose output layers are random (not zero-velocity)."""
    model = AttentionPredictor(config)
    torch.manual_seed(seed)
    for net in model.nets:
        for p in net.out.parameters():
            torch.nn.init.normal_(p, std=0.05)
    return model


def test_untrained_model_is_zero_velocity_and_heading_and_mirror_equivariant(windows):
    history = windows.frames[:5, :11]
    fresh = AttentionPredictor(AttentionConfig(10, 10, width=32, layers=2))
    np.testing.assert_allclose(fresh.predict(history), ZeroVelocity(10).predict(history),
                               atol=1e-5)
    model = _perturbed(AttentionConfig(10, 10, width=32, layers=2), seed=0)
    pred = model.predict(history)
    assert np.abs(pred - ZeroVelocity(10).predict(history)).max() > 1e-3
    np.testing.assert_allclose(pred[:, :, 0], 0.0, atol=1e-6)  # the pelvis stays the origin
    turned = P.rotate_z(history.astype(np.float64), np.full(5, -0.7))
    np.testing.assert_allclose(model.predict(turned),
                               P.rotate_z(pred.astype(np.float64), np.full(5, -0.7)),
                               atol=1e-4)
    np.testing.assert_allclose(model.predict(P.mirror(history)), P.mirror(pred), atol=1e-4)
    np.testing.assert_allclose(model.predict(history[1]), pred[1], atol=1e-6)


def test_short_training_lowers_the_loss_and_keeps_the_best_validation_state(clips):
    train_w = pdata.windows_from_motions(clips[:1], 10, 10, stride=2)
    val_w = pdata.windows_from_motions(clips[1:], 10, 10, stride=4)
    config = AttentionConfig(10, 10, width=32, layers=2, dropout=0.0)
    model = AttentionPredictor(config)
    residual, last, future = targets(model.history_len, train_w.frames)

    def loss() -> float:
        with torch.no_grad():
            model.net.eval()
            return regression_loss(model.forward(residual, last), future).item()

    before = loss()
    fam.train_attention(model, train_w, iterations=150, lr=1e-3, progress=False)
    assert loss() < 0.8 * before
    model = AttentionPredictor(config)
    log = fam.train_attention(model, train_w, iterations=150, lr=1e-3, validation=val_w,
                              validate_every=50, progress=False)
    scores = [e["val_mpjpe_mm"] for e in log if "val_mpjpe_mm" in e]
    assert len(scores) >= 3
    # the restored state is the best one seen on the validation windows
    assert tp.validation_score(model, val_w) == pytest.approx(min(scores), rel=1e-5)


def test_checkpoint_round_trip_and_bad_input(windows, tmp_path):
    model = _perturbed(AttentionConfig(10, 10, width=32, layers=2, members=2), seed=1)
    again = AttentionPredictor.load(model.save(tmp_path / "a.npz"))
    history = windows.frames[:3, :11]
    np.testing.assert_array_equal(again.predict(history), model.predict(history))
    # the ensemble is the mean of its members (each mirror-averaged)
    members = np.mean([model.member(i).predict(history) for i in range(2)], axis=0)
    np.testing.assert_allclose(model.predict(history), members, atol=1e-5)
    with pytest.raises(MotionError, match="needs at least 11"):
        model.predict(history[:, :7])
    with pytest.raises(MotionError, match="expects 17"):
        model.predict(history[:, :, :16])
    with pytest.raises(MotionError, match="multiple of heads"):
        AttentionPredictor(AttentionConfig(10, 10, width=30, heads=4))
    gan = P.fit_geometry(windows, P.PredictorConfig(10, 10), max_iter=5)
    with pytest.raises(CheckpointError, match=r"simenv-joint-attention-dct-1"):
        AttentionPredictor.load(gan.save(tmp_path / "g.npz"))
    short = pdata.PredictionWindows(windows.frames[:, :11], windows.root[:, :11],
                                    windows.clip, windows.start, windows.clip_names, 5, 5,
                                    windows.fps)
    with pytest.raises(MotionError, match="the model is 10->10"):
        fam.train_attention(model, short, iterations=1, progress=False)


def test_inputs_are_the_residual_to_the_heading_normalised_last_pose(windows):
    history = windows.frames[:4, :11].astype(np.float64)
    residual, last, angle = inputs(history)
    np.testing.assert_allclose(residual[:, -1].numpy(), 0.0, atol=1e-6)
    # after normalisation the hip axis (left hip - right hip) of the last pose is +X
    pose = last.numpy().reshape(4, 17, 3)
    axis = pose[:, P.LEFT_HIP] - pose[:, P.RIGHT_HIP]
    np.testing.assert_allclose(axis[:, 1], 0.0, atol=1e-5)
    assert (axis[:, 0] > 0).all()
    np.testing.assert_allclose(angle, P.heading(history[:, -1]))

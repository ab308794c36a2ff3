"""Tests for simenv.models.predictor_regression (DCT-residual MLP) on real CMU windows."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from simenv import prediction_data as pdata
from simenv import train_predictor as tp
from simenv.errors import MotionError
from simenv.io import bvh
from simenv.models import predictor as P
from simenv.models import predictor_regression as R
from simenv.models.baselines import ZeroVelocity

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def clips(shared_data):
    return [bvh.read(shared_data / "cmu" / "bvh" / f"{n}.bvh") for n in ("02_01", "49_02")]


@pytest.fixture(scope="module")
def windows(clips):
    return pdata.windows_from_motions(clips, 10, 10, stride=4)


def test_dct_matrix_is_orthonormal_and_puts_a_constant_in_the_first_coefficient():
    for n in (1, 11, 26):
        m = R.dct_matrix(n)
        np.testing.assert_allclose(m @ m.T, np.eye(n), atol=1e-12)
        c = m @ np.full(n, 2.0)
        assert c[0] == pytest.approx(2.0 * np.sqrt(n))
        np.testing.assert_allclose(c[1:], 0.0, atol=1e-12)


def test_untrained_model_is_zero_velocity_and_heading_equivariant(windows):
    model = R.DCTRegressionPredictor(R.RegressionConfig(10, 10))
    history = windows.frames[:5, :11]
    np.testing.assert_allclose(model.predict(history), ZeroVelocity(10).predict(history),
                               atol=1e-5)
    torch.manual_seed(0)
    for p in model.net.fc_out.parameters():
        torch.nn.init.normal_(p, std=0.1)
    pred = model.predict(history)
    assert np.abs(pred - ZeroVelocity(10).predict(history)).max() > 1e-3
    turned = P.rotate_z(history.astype(np.float64), np.full(5, 0.8))
    np.testing.assert_allclose(model.predict(turned),
                               P.rotate_z(pred.astype(np.float64), np.full(5, 0.8)),
                               atol=1e-4)
    np.testing.assert_allclose(model.predict(history[0]), pred[0], atol=1e-6)


def test_short_training_lowers_the_loss_and_keeps_the_best_validation_state(clips):
    train_w = pdata.windows_from_motions(clips[:1], 10, 10, stride=2)
    val_w = pdata.windows_from_motions(clips[1:], 10, 10, stride=4)
    model = R.DCTRegressionPredictor(R.RegressionConfig(10, 10))
    residual, last, future = R.targets(model.history_len, train_w.frames)

    def loss() -> float:
        with torch.no_grad():
            return R.regression_loss(model.forward(residual, last), future).item()

    before = loss()
    tp.train_regression(model, train_w, iterations=150, lr=1e-3, progress=False)
    assert loss() < 0.8 * before
    model = R.DCTRegressionPredictor(R.RegressionConfig(10, 10))
    log = tp.train_regression(model, train_w, iterations=150, lr=1e-3,
                              validation=val_w, validate_every=50, progress=False)
    scores = [e["val_mpjpe_mm"] for e in log if "val_mpjpe_mm" in e]
    assert len(scores) >= 3
    # the restored state is the best one seen on the validation windows
    assert tp.validation_score(model, val_w) == pytest.approx(min(scores), rel=1e-5)


def test_checkpoint_round_trip_and_errors(windows, tmp_path):
    model = R.DCTRegressionPredictor(R.RegressionConfig(10, 10, blocks=2))
    torch.manual_seed(1)
    for p in model.net.fc_out.parameters():
        torch.nn.init.normal_(p, std=0.1)
    again = R.DCTRegressionPredictor.load(model.save(tmp_path / "r.npz"))
    history = windows.frames[:3, :11]
    np.testing.assert_array_equal(again.predict(history), model.predict(history))
    gan = P.fit_geometry(windows, P.PredictorConfig(10, 10), max_iter=5)
    with pytest.raises(P.CheckpointError, match="simenv-dct-mlp-1"):
        R.DCTRegressionPredictor.load(gan.save(tmp_path / "g.npz"))
    with pytest.raises(MotionError, match="needs at least 11"):
        model.predict(windows.frames[:2, :6])
    short = pdata.PredictionWindows(windows.frames[:, :11], windows.root[:, :11],
                                    windows.clip, windows.start, windows.clip_names, 5, 5,
                                    windows.fps)
    with pytest.raises(MotionError, match="the model is 10->10"):
        tp.train_regression(model, short, iterations=1, progress=False)


def test_evaluation_of_a_regression_model_has_no_carried_amplitude(windows):
    model = R.DCTRegressionPredictor(R.RegressionConfig(10, 10))
    preds = tp.predictions(model, windows.subset(np.arange(8)))
    assert set(preds) == {"model", "zero_velocity", "constant_velocity"}
    np.testing.assert_allclose(preds["model"], preds["zero_velocity"], atol=1e-5)

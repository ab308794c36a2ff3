"""Tests for simenv.models.predictor_blend (per-frame convex blend) on real CMU windows."""

from __future__ import annotations

from math import comb

import numpy as np
import pytest
import torch

from simenv import prediction_data as pdata
from simenv import train_predictor_families as fam
from simenv.errors import MotionError
from simenv.io import bvh
from simenv.models.baselines import ConstantVelocity, ZeroVelocity
from simenv.models.checkpoint import CheckpointError
from simenv.models.predictor_attention import AttentionConfig, AttentionPredictor
from simenv.models.predictor_blend import (
    ZERO_VELOCITY,
    BlendPredictor,
    convex_weights,
    simplex_grid,
)
from simenv.models.predictor_knn import KNNConfig, KNNPredictor

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def clips(shared_data):
    return [bvh.read(shared_data / "cmu" / "bvh" / f"{n}.bvh") for n in ("02_01", "49_02")]


@pytest.fixture(scope="module")
def windows(clips):
    return pdata.windows_from_motions(clips[1:], 10, 10, stride=5)


@pytest.fixture(scope="module")
def knn(clips):
    return KNNPredictor(KNNConfig(10, 10, k=8, shrinkage=0.7),
                        fam.sequences(clips[:1], [clips[0].name], speeds=(1.0,)))


def test_simplex_grid_covers_the_simplex():
    grid = simplex_grid(3, 0.1)
    assert len(grid) == comb(10 + 2, 2)
    np.testing.assert_allclose(grid.sum(1), 1.0)
    assert grid.min() >= 0 and len({tuple(r) for r in grid}) == len(grid)
    with pytest.raises(MotionError, match="1/step an integer"):
        simplex_grid(3, 0.3)


def test_convex_weights_find_the_member_that_is_the_truth(windows):
    history, truth = windows.frames[:, :11], windows.future
    zv = ZeroVelocity(10).predict(history)
    cv = ConstantVelocity(10).predict(history)
    w = convex_weights(np.stack([zv, truth, cv]), truth, joints=range(1, 17), step=0.1)
    np.testing.assert_allclose(w, np.repeat([[0.0], [1.0], [0.0]], 10, axis=1))
    # with only the baselines, the first frame leans on constant velocity (accurate one
    # frame ahead) and the weights stay on the simplex
    w = convex_weights(np.stack([zv, cv]), truth, step=0.05)
    np.testing.assert_allclose(w.sum(0), 1.0)
    assert w[1, 0] > 0.5 and w[1, 0] >= w[1, -1]
    with pytest.raises(MotionError, match="same windows"):
        convex_weights(np.stack([zv, cv]), truth[:3])


def test_blend_predicts_the_weighted_mean_of_its_members(windows, knn):
    history = windows.frames[:6, :11]
    zv = ZeroVelocity(10)
    weights = np.stack([np.linspace(0, 1, 10), np.linspace(1, 0, 10)])
    blend = BlendPredictor([knn, zv], ["knn", ZERO_VELOCITY], weights)
    expected = (weights[0][None, :, None, None] * knn.predict(history)
                + weights[1][None, :, None, None] * zv.predict(history))
    np.testing.assert_allclose(blend.predict(history), expected, atol=1e-6)
    np.testing.assert_allclose(blend.predict(history[2]), expected[2], atol=1e-6)
    assert blend.history_len == 11 and blend.future_len == 10
    with pytest.raises(MotionError, match="sum to 1"):
        BlendPredictor([knn, zv], ["knn", ZERO_VELOCITY], weights * 0.5)
    with pytest.raises(MotionError, match=r"\(2, 10\)"):
        BlendPredictor([knn, zv], ["knn", ZERO_VELOCITY], weights[:, :5])
    with pytest.raises(MotionError, match="different lengths"):
        BlendPredictor([knn, ZeroVelocity(5)], ["knn", ZERO_VELOCITY], weights)


def test_checkpoint_round_trip_with_every_member_kind_and_bad_input(windows, knn, tmp_path):
    attention = AttentionPredictor(AttentionConfig(10, 10, width=32, layers=2))
    torch.manual_seed(0)
    for p in attention.net.out.parameters():
        torch.nn.init.normal_(p, std=0.05)
    weights = np.full((3, 10), 1 / 3)
    blend = BlendPredictor([knn, attention, ZeroVelocity(10)],
                           ["knn", "attention", ZERO_VELOCITY], weights, {"note": "test"})
    again = BlendPredictor.load(blend.save(tmp_path / "blend.npz"))
    assert again.names == blend.names and again.info == {"note": "test"}
    assert isinstance(again.members[0], KNNPredictor)
    assert isinstance(again.members[1], AttentionPredictor)
    history = windows.frames[:4, :11]
    np.testing.assert_allclose(again.predict(history), blend.predict(history), atol=1e-6)
    with pytest.raises(MotionError, match="needs at least 11"):
        blend.predict(history[:, :4])
    bad = history.copy()
    bad[1, 5, 3, 2] = np.inf
    with pytest.raises(MotionError, match="non-finite value in window 1"):
        blend.predict(bad)
    with pytest.raises(MotionError, match="expects 17"):
        blend.predict(history[:, :, :12])
    with pytest.raises(CheckpointError, match="simenv-predictor-blend-1"):
        BlendPredictor.load(knn.save(tmp_path / "knn.npz"))

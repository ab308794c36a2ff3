"""Tests for simenv.models.predictor_knn (motion matching) on real CMU clips."""

from __future__ import annotations

import numpy as np
import pytest

from simenv import prediction_data as pdata
from simenv import train_predictor_families as fam
from simenv.errors import MotionError
from simenv.io import bvh
from simenv.models import predictor as P
from simenv.models.baselines import ZeroVelocity
from simenv.models.checkpoint import CheckpointError
from simenv.models.predictor_knn import KNNConfig, KNNPredictor


@pytest.fixture(scope="module")
def clips(shared_data):
    return [bvh.read(shared_data / "cmu" / "bvh" / f"{n}.bvh") for n in ("02_01", "49_02")]


@pytest.fixture(scope="module")
def seqs(clips):
    """Root-relative pred17 frames of the two clips at 25 fps (one speed)."""
    return fam.sequences(clips, [c.name for c in clips], speeds=(1.0,))


def test_a_database_window_is_its_own_nearest_neighbour_and_predicts_its_future(seqs):
    model = KNNPredictor(KNNConfig(10, 10, k=1, shrinkage=1.0, mirror=False), seqs)
    window = seqs[1][40:61]  # 11 history + 10 future frames of the jump
    pred = model.predict(window[:11])
    np.testing.assert_allclose(pred, window[11:], atol=1e-5)
    # shrinkage 0 is zero-velocity whatever the neighbours
    still = KNNPredictor(KNNConfig(10, 10, k=8, shrinkage=0.0), seqs)
    np.testing.assert_allclose(still.predict(window[:11]),
                               ZeroVelocity(10).predict(window[:11]), atol=1e-6)


def test_prediction_is_heading_and_mirror_equivariant(seqs):
    model = KNNPredictor(KNNConfig(10, 10, k=8, shrinkage=0.8), seqs)
    history = np.stack([seqs[0][i:i + 11] for i in (5, 30, 60)]).astype(np.float64)
    pred = model.predict(history)
    assert np.abs(pred - ZeroVelocity(10).predict(history)).max() > 1e-3
    turned = P.rotate_z(history, np.full(3, 1.1))
    np.testing.assert_allclose(model.predict(turned),
                               P.rotate_z(pred.astype(np.float64), np.full(3, 1.1)),
                               atol=1e-4)
    np.testing.assert_allclose(model.predict(P.mirror(history)), P.mirror(pred), atol=1e-4)


def test_checkpoint_round_trip_and_bad_input(seqs, tmp_path):
    model = KNNPredictor(KNNConfig(10, 10, k=4, velocity_weight=2.0, shrinkage=0.6), seqs)
    again = KNNPredictor.load(model.save(tmp_path / "knn.npz"))
    assert again.config == model.config and again.num_windows == model.num_windows
    history = seqs[0][:11]
    np.testing.assert_array_equal(again.predict(history), model.predict(history))
    with pytest.raises(MotionError, match="needs at least 11"):
        model.predict(history[:6])
    bad = history.copy()
    bad[3, 2, 0] = np.nan
    with pytest.raises(MotionError, match="non-finite"):
        model.predict(bad)
    with pytest.raises(MotionError, match="expects 17"):
        model.predict(history[:, :15])
    with pytest.raises(MotionError, match="no sequence gives a window"):
        KNNPredictor(KNNConfig(10, 10), [seqs[0][:15]])
    (tmp_path / "other.npz").write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match="cannot read"):
        KNNPredictor.load(tmp_path / "other.npz")


def test_validation_search_is_no_worse_than_zero_velocity(clips):
    """The grid contains shrinkage 0 (zero-velocity), so the chosen point scores at most
    zero-velocity's validation error; here the database is the walk and validation the
    jump."""
    val = pdata.windows_from_motions(clips[1:], 10, 10, stride=3)
    split = fam.Split(list(clips), (), (), (clips[0].name,), (clips[1].name,), val, val,
                      10, 10)
    config, rows = fam.select_knn(split, progress=False)
    zv = fam.score(ZeroVelocity(10).predict(val.frames[:, :11]), val)
    best = min(r["score_mm"] for r in rows)
    assert best <= zv + 1e-6
    assert len(rows) == (len(fam.KNN_K) * len(fam.KNN_VELOCITY) * len(fam.KNN_HISTORY)
                         * len(fam.KNN_SHRINKAGE))
    chosen = KNNPredictor(config, fam.sequences(clips[:1], [clips[0].name]))
    assert fam.score(chosen.predict(val.frames[:, :11]), val) == pytest.approx(best, rel=1e-4)

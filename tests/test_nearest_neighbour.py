"""The nearest-neighbour baseline on real UTKinect clips: resampling, distances, labels."""

from __future__ import annotations

import numpy as np
import pytest

from simenv.core.errors import SimenvError
from simenv.learning.nearest_neighbour import (
    distances,
    nearest_neighbour,
    resample_sequences,
)
from simenv.learning.recognition_protocols import whole_windows


@pytest.fixture(scope="module")
def utk_sequences(utkinect_clips):
    """Every UTKinect clip normalised and resampled, with labels and subjects."""
    x, valid = whole_windows(utkinect_clips)
    labels = sorted({c.label for c in utkinect_clips})
    y = np.array([labels.index(c.label) for c in utkinect_clips])
    subjects = np.array([c.subject for c in utkinect_clips])
    return resample_sequences(x, valid), y, subjects, x, valid


def test_resampling_keeps_the_real_frames_and_skips_padding(utk_sequences):
    _, _, _, x, valid = utk_sequences
    n = int(np.argmin(valid.sum(1)))  # the shortest clip: padded the most
    real = int(valid[n].sum())
    assert real < valid.shape[1]
    same = resample_sequences(x[n:n + 1], valid[n:n + 1], samples=real)[0]
    np.testing.assert_allclose(same, x[n][valid[n]], atol=1e-6)
    garbage = x[n:n + 1].copy()
    garbage[0, ~valid[n]] = 1e3
    np.testing.assert_array_equal(resample_sequences(garbage, valid[n:n + 1]),
                                  resample_sequences(x[n:n + 1], valid[n:n + 1]))


def test_dtw_forgives_timing_that_the_euclidean_distance_charges(utk_sequences):
    seqs, _, _, x, valid = utk_sequences
    n = 0
    real = x[n][valid[n]]
    # The same performance, its first half played twice as fast and its second half slower.
    half = len(real) // 2
    warped = np.concatenate([real[:half:2], real[half:].repeat(2, axis=0)])
    moved = resample_sequences(warped[None], np.ones((1, len(warped)), bool))
    eu = distances(moved, seqs[n:n + 1], "euclidean")[0, 0]
    dtw = distances(moved, seqs[n:n + 1], "dtw")[0, 0]
    assert distances(seqs[:1], seqs[:1], "dtw")[0, 0] == pytest.approx(0.0, abs=1e-6)
    # The diagonal is one warping path, so DTW is at most half the Euclidean distance;
    # re-timing is what it forgives, so it is well below that here.
    assert dtw < 0.5 * eu
    others = distances(moved, seqs[1:], "dtw")[0]
    assert dtw < others.min()


def test_nearest_neighbour_recognises_an_unseen_person(utk_sequences):
    seqs, y, subjects, _, _ = utk_sequences
    test, train = subjects == 10, subjects != 10
    for metric in ("euclidean", "dtw"):
        pred = nearest_neighbour(seqs[test], seqs[train], y[train], metric)
        assert pred.shape == (int(test.sum()),)
        assert (pred == y[test]).mean() > 0.5  # ten classes: chance is 0.1
    # A clip in the training set is its own nearest neighbour.
    pred = nearest_neighbour(seqs[:5], seqs, np.arange(len(seqs)), "euclidean")
    np.testing.assert_array_equal(pred, np.arange(5))


def test_bad_input_is_named(utk_sequences):
    seqs, y, _, x, valid = utk_sequences
    with pytest.raises(SimenvError, match="unknown distance"):
        distances(seqs[:1], seqs, "cosine")  # type: ignore[arg-type]
    with pytest.raises(SimenvError, match="training ones"):
        distances(seqs[:1, :10], seqs)
    with pytest.raises(SimenvError, match="one label each"):
        nearest_neighbour(seqs[:1], seqs, y[:-1])
    with pytest.raises(SimenvError, match="one label each"):
        nearest_neighbour(seqs[:1], seqs[:0], y[:0])
    empty = valid[:1].copy()
    empty[:] = False
    with pytest.raises(SimenvError, match="sequence 0 has no real frame"):
        resample_sequences(x[:1], empty)
    with pytest.raises(SimenvError, match="samples"):
        resample_sequences(x[:1], valid[:1], samples=0)

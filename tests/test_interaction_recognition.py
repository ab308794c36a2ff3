"""Tests for simenv.learning.interaction_recognition: a known separable toy problem, reactor-only
features, untrained and bad input, and real held-out windows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import MotionError
from simenv.data import interaction_data as idata
from simenv.learning.interaction_features import default_feature_extractor
from simenv.learning.interaction_recognition import InteractionRecognizer


def _mean_position(windows: np.ndarray) -> np.ndarray:
    """(N, T, J, 3) -> (N, 3) toy features: the mean position."""
    return np.asarray(windows).mean(axis=(1, 2))


def _toy(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Class c puts the reactor at x = 2c (actor always at the origin), with noise."""
    rng = np.random.default_rng(seed)
    labels = np.arange(n) % 3
    actor = rng.normal(0, 0.05, (n, 4, 2, 3))
    reactor = rng.normal(0, 0.05, (n, 4, 2, 3))
    reactor[..., 0] += 2.0 * labels[:, None, None]
    return actor, reactor, labels


def test_separable_toy_classes_are_recognised_exactly() -> None:
    rec = InteractionRecognizer(_mean_position).fit(*_toy(60, 0))
    acc, n = rec.accuracy(*_toy(30, 1))
    assert (acc, n) == (1.0, 30)
    assert rec.classes == (0, 1, 2)


def test_reactor_only_features_ignore_the_actor() -> None:
    a, b, y = _toy(60, 0)
    rec = InteractionRecognizer(_mean_position, use_actor=False).fit(a, b, y)
    # Moving the actor far away changes nothing when only the reactor is seen.
    np.testing.assert_array_equal(rec.predict(a + 10.0, b), rec.predict(a, b))


def test_classes_never_trained_are_left_out_of_the_accuracy() -> None:
    a, b, y = _toy(60, 0)
    keep = y < 2
    rec = InteractionRecognizer(_mean_position).fit(a[keep], b[keep], y[keep])
    acc, n = rec.accuracy(a, b, y)
    assert n == int(keep.sum()) and acc == 1.0
    assert np.isnan(rec.accuracy(a[~keep], b[~keep], y[~keep])[0])


def test_bad_input_is_named() -> None:
    a, b, y = _toy(10, 0)
    with pytest.raises(MotionError, match="not trained"):
        InteractionRecognizer(_mean_position).predict(a, b)
    with pytest.raises(MotionError, match="labels"):
        InteractionRecognizer(_mean_position).fit(a, b, y[:5])
    with pytest.raises(MotionError, match="reactor"):
        InteractionRecognizer(_mean_position).fit(a, b[:, :2], y)
    with pytest.raises(MotionError, match="ridge"):
        InteractionRecognizer(_mean_position, ridge=0.0)


def test_real_held_out_windows_are_recognised_above_chance(shared_data: Path) -> None:
    windows = idata.make_windows(idata.load_recordings(shared_data))
    split = idata.split_by_recording(windows)
    train, test = windows.subset(split.train), windows.subset(split.test)
    extractor, _ = default_feature_extractor()
    for use_actor in (True, False):
        rec = InteractionRecognizer(extractor, use_actor=use_actor)
        rec.fit(train.actor, train.reactor, train.label)
        acc, n = rec.accuracy(test.actor, test.reactor, test.label)
        # Held-out recordings of the trained classes, by the real motion: well above chance.
        assert n == int(np.isin(test.label, rec.classes).sum()) > 0
        assert acc > 1.0 / len(rec.classes) + 0.2

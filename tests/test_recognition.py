"""Training windows, Kinect-noise augmentation and training of the recogniser, on real clips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import SimenvError
from simenv.data.gestures import (
    GESTURE15_JOINTS,
    GESTURE_LABELS,
    gesture_skeleton,
)
from simenv.learning.recognition import (
    SHORT_FRAMES,
    RecognitionConfig,
    continue_windows,
    kinect_noise,
    logits_of,
    time_scale,
    train_recogniser,
    training_windows,
)


def test_config_validation(tmp_path: Path):
    with pytest.raises(SimenvError, match="partial_frames"):
        RecognitionConfig(partial_frames=(30, 10))
    with pytest.raises(SimenvError, match="speed"):
        RecognitionConfig(speed=(0.0, 1.0))
    with pytest.raises(SimenvError, match="forecast_prob"):
        RecognitionConfig(forecast_prob=1.5)
    (tmp_path / "c.toml").write_text("epochs = 3\nbogus = 1\n")
    with pytest.raises(SimenvError, match="bogus"):
        RecognitionConfig.from_file(tmp_path / "c.toml")


def test_time_scale_keeps_the_path(utkinect_clips):
    p = utkinect_clips[0].positions
    slow = time_scale(p, 1.5)
    assert len(slow) == round(1.5 * len(p))
    np.testing.assert_allclose(slow[[0, -1]], p[[0, -1]], atol=1e-6)


def test_training_windows_mix_partial_and_full(utkinect_clips):
    config = RecognitionConfig(partial_prob=0.5, speed=(1.0, 1.0))
    x, valid = training_windows(utkinect_clips, np.random.default_rng(0), config)
    n = valid.sum(1)
    assert x.shape == (len(utkinect_clips), 75, 15, 3) and np.isfinite(x).all()
    lo, hi = config.partial_frames
    partial = n <= hi
    assert 0.25 < partial.mean() < 0.75
    assert (n >= min(lo, min(c.num_frames for c in utkinect_clips))).all()
    # every window is prefix-valid: real frames first, padding after
    assert all(v[:k].all() and not v[k:].any() for v, k in zip(valid, n, strict=True))


def test_forecast_windows_are_real_second_plus_forecast(utkinect_clips):
    config = RecognitionConfig(forecast_prob=1.0, speed=(1.0, 1.0))
    calls = []

    def forecast(h):
        calls.append(h.shape)
        return np.repeat(h[:, -1:] + 0.1, 50, axis=1)

    x, valid = training_windows(utkinect_clips, np.random.default_rng(1), config, forecast)
    assert calls and calls[0][1:] == (SHORT_FRAMES, 15, 3)
    long = [i for i, c in enumerate(utkinect_clips) if c.num_frames >= SHORT_FRAMES]
    assert valid[long].all()
    # the continuation is the forecast: 0.1 above the last real frame
    i = long[0]
    np.testing.assert_allclose(x[i, SHORT_FRAMES], x[i, SHORT_FRAMES - 1] + 0.1, atol=1e-5)
    with pytest.raises(ValueError):
        continue_windows(x[:1], valid[:1], np.array([0]), lambda h: np.zeros((2, 3)))


def test_stream_windows_are_the_loops_ticks(utkinect_clips):
    config = RecognitionConfig(stream_prob=1.0, forecast_prob=0.0, speed=(1.0, 1.0))
    x, valid = training_windows(utkinect_clips, np.random.default_rng(2), config)
    n = valid.sum(1)
    lo, hi = config.stream_frames
    assert ((n >= lo) & (n <= hi)).all() and np.isfinite(x).all()
    assert all(v[:k].all() and not v[k:].any() for v, k in zip(valid, n, strict=True))
    # windows reaching before the clip's first frame hold its first pose there
    still = [i for i in range(len(x)) if np.allclose(x[i, 0], x[i, 1], atol=1e-6)]
    assert len(still) > len(x) // 4
    with pytest.raises(SimenvError, match="stream_frames"):
        RecognitionConfig(stream_frames=(25, 100))
    with pytest.raises(SimenvError, match="stream_prob"):
        RecognitionConfig(stream_prob=-0.1)


def test_kinect_noise_changes_but_keeps_the_body(utkinect_clips):
    skel = gesture_skeleton("gesture15")
    x, _ = training_windows(utkinect_clips[:20], np.random.default_rng(0), RecognitionConfig())
    y = kinect_noise(x, np.random.default_rng(0), RecognitionConfig(), GESTURE15_JOINTS,
                     skel.parents)
    assert y.shape == x.shape and np.isfinite(y).all()
    assert np.abs(y - x).mean() > 0.01
    size = np.linalg.norm(x[:, :, 1] - x[:, :, 0], axis=-1).mean()  # head - spine
    assert np.linalg.norm(y[:, :, 1] - y[:, :, 0], axis=-1).mean() == pytest.approx(size, rel=0.3)


def test_short_training_lowers_the_loss_and_beats_chance(utkinect_clips):
    labels = sorted({c.label for c in utkinect_clips})
    config = RecognitionConfig(epochs=8, width=32, seed=0)
    model, history = train_recogniser(utkinect_clips, labels, lambda c: c.label, config,
                                      progress=False)
    assert history["epoch_loss"][-1] < history["epoch_loss"][0]
    from simenv.data.gestures import make_windows

    w = make_windows(utkinect_clips, crop="centre")
    acc = (logits_of(model, w.x, w.valid).argmax(1) ==
           np.array([labels.index(c.label) for c in utkinect_clips])).mean()
    assert acc > 1.5 / len(labels)  # training clips: well above chance after 8 epochs
    with pytest.raises(SimenvError, match="not one of"):
        train_recogniser(utkinect_clips[:3], ["x"], lambda c: c.label, config, progress=False)
    with pytest.raises(SimenvError, match="no training clips"):
        train_recogniser([], list(GESTURE_LABELS), lambda c: c.label, config, progress=False)

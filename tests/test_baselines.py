"""Tests for simenv.models.baselines: exact toy predictions and real-clip behaviour."""

from __future__ import annotations

import numpy as np
import pytest

from simenv.core.errors import MotionError
from simenv.data import prediction_data as pdata
from simenv.data import prediction_metrics as pm
from simenv.io import bvh
from simenv.models.baselines import ConstantVelocity, Predictor, ZeroVelocity


def _linear_history(n: int = 2, h: int = 6) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    x0 = rng.normal(size=(n, 1, 17, 3))
    vel = rng.normal(size=(n, 1, 17, 3)) * 0.01
    k = np.arange(h)[None, :, None, None]
    return x0 + k * vel, vel


def test_zero_velocity_repeats_the_last_pose():
    hist, _ = _linear_history()
    out = ZeroVelocity(5).predict(hist)
    assert out.shape == (2, 5, 17, 3) and out.dtype == np.float32
    np.testing.assert_array_equal(out, np.repeat(hist[:, -1:], 5, axis=1).astype(np.float32))
    single = ZeroVelocity(3).predict(hist[0])
    assert single.shape == (3, 17, 3)


def test_constant_velocity_is_exact_on_linear_motion():
    hist, vel = _linear_history(h=4)
    out = ConstantVelocity(7).predict(hist)
    k = np.arange(1, 8)[None, :, None, None]
    np.testing.assert_allclose(out, hist[:, -1:] + k * vel, atol=1e-6)


def test_baselines_follow_the_predictor_protocol():
    for model in (ZeroVelocity(25), ConstantVelocity(25)):
        assert isinstance(model, Predictor) and model.future_len == 25 and model.fps == 25.0


def test_bad_histories_are_clear_errors():
    hist, _ = _linear_history()
    with pytest.raises(MotionError, match="needs at least 2"):
        ConstantVelocity(5).predict(hist[:, :1])
    bad = hist.copy()
    bad[0, 2, 5, 1] = np.inf
    with pytest.raises(MotionError, match=r"frame 2.*window 0, joint 5"):
        ZeroVelocity(5).predict(bad)
    with pytest.raises(MotionError, match=r"\(N, H, J, 3\)"):
        ZeroVelocity(5).predict(hist[..., :2])
    with pytest.raises(MotionError, match="future_len"):
        ZeroVelocity(0)


def test_on_a_real_walk_constant_velocity_wins_short_and_loses_long(shared_data):
    motion = bvh.read(shared_data / "cmu" / "bvh" / "16_15.bvh")
    w = pdata.windows_from_motions([motion], 25, 25, stride=3)
    history = w.frames[:, :26]
    joints = range(1, 17)
    zv = pm.mpjpe_at_horizons_mm(ZeroVelocity(25).predict(history), w.future, 25.0,
                                 joints=joints)
    cv = pm.mpjpe_at_horizons_mm(ConstantVelocity(25).predict(history), w.future, 25.0,
                                 joints=joints)
    assert cv[80] < zv[80]  # the next frames continue the current velocity
    assert cv[1000] > zv[1000]  # a gait reverses its limb velocities within a second
    assert zv[80] < zv[400]  # (at 1000 ms a gait of ~1 s period is back near the start)

"""Tests for simenv.data.prediction_metrics on toy inputs with known answers and real clips."""

from __future__ import annotations

import numpy as np
import pytest

from simenv.core.errors import MotionError
from simenv.data import prediction_data as pdata
from simenv.data import prediction_metrics as pm
from simenv.io import bvh

PARENTS = pdata.pred17_skeleton().parents


def _target(n: int = 3, f: int = 25, j: int = 17, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(n, f, j, 3)) * 0.3


def test_constant_offset_gives_mpjpe_equal_to_the_offset():
    target = _target()
    offset = np.array([0.03, -0.04, 0.0])  # 50 mm
    pred = target + offset
    per_frame = pm.mpjpe_at_horizons_mm(pred, target, 25.0)
    rms = pm.rms_mpjpe_up_to_horizons_mm(pred, target, 25.0)
    # 1000 ms is frame 25 of 25: every horizon is inside
    assert list(per_frame) == list(pm.HORIZONS_MS) == list(rms)
    np.testing.assert_allclose(list(per_frame.values()), 50.0, rtol=1e-9)
    np.testing.assert_allclose(list(rms.values()), 50.0, rtol=1e-9)
    np.testing.assert_allclose(pm.per_frame_mpjpe_mm(pred, target), 50.0, rtol=1e-9)


def test_per_frame_and_rms_forms_differ_on_growing_errors():
    target = np.zeros((1, 25, 2, 3))
    pred = target.copy()
    pred[0, :, :, 0] = 0.01 * np.arange(1, 26)[:, None]  # error k cm at frame k
    per_frame = pm.mpjpe_at_horizons_mm(pred, target, 25.0)
    rms = pm.rms_mpjpe_up_to_horizons_mm(pred, target, 25.0)
    # 80 ms = 2nd future frame -> 20 mm; 400 ms = frame 10 -> 100 mm
    assert per_frame[80] == pytest.approx(20.0) and per_frame[400] == pytest.approx(100.0)
    assert rms[80] == pytest.approx(10 * np.sqrt((1 + 4) / 2))
    assert rms[400] == pytest.approx(10 * np.sqrt(np.mean(np.arange(1, 11) ** 2)))
    assert all(rms[h] < per_frame[h] for h in pm.HORIZONS_MS)


def test_horizons_beyond_the_prediction_are_left_out_and_frames_are_rounded():
    target = _target(f=10)
    out = pm.mpjpe_at_horizons_mm(target, target, 25.0)
    assert list(out) == [80, 160, 320, 400] and all(v == 0 for v in out.values())
    assert pm.horizon_frames(pm.HORIZONS_MS, 25.0) == [2, 4, 8, 10, 25]
    assert pm.horizon_frames([80], 50.0) == [4]
    with pytest.raises(MotionError, match="shorter than one frame"):
        pm.horizon_frames([10], 25.0)


def test_joint_selection_excludes_joints():
    target = _target()
    pred = target.copy()
    pred[:, :, 0, 0] += 1.0  # only the root is wrong, by 1 m
    assert pm.mpjpe_at_horizons_mm(pred, target, 25.0, joints=range(1, 17))[400] == 0.0
    assert pm.mpjpe_at_horizons_mm(pred, target, 25.0)[400] == pytest.approx(1000 / 17)


def test_mpjs_of_uniform_motion_is_its_speed():
    t = np.arange(11) / 25.0
    frames = np.zeros((2, 11, 17, 3))
    frames[..., 1] = 1.5 * t[None, :, None]  # 1.5 m/s along Y
    assert pm.mean_per_joint_speed(frames, 25.0) == pytest.approx(1.5)
    with pytest.raises(MotionError, match="T >= 2"):
        pm.mean_per_joint_speed(frames[:, :1], 25.0)


def test_bone_drift_of_a_stretched_skeleton(shared_data):
    motion = pdata.to_pred17(bvh.read(shared_data / "cmu" / "bvh" / "02_01.bvh"))
    rel, _ = pdata.split_root(motion)
    ref = rel[None, 100].astype(np.float64)
    same = np.repeat(rel[None, 101:111], 1, axis=0)
    rigid = pm.bone_length_drift_mm(same, ref, PARENTS)
    assert rigid["max"] < 1.0  # real mocap: rigid bones, sub-millimetre drift
    stretched = pm.bone_length_drift_mm(1.1 * same, ref, PARENTS)
    mean_bone = 1000 * pm.bone_lengths(ref, PARENTS).mean()
    assert stretched["mean"] == pytest.approx(0.1 * mean_bone, rel=0.02)


def test_bad_inputs_name_what_was_expected():
    target = _target()
    with pytest.raises(MotionError, match="same shape"):
        pm.mpjpe_at_horizons_mm(target[:, :5], target, 25.0)
    bad = target.copy()
    bad[1, 3, 4, 0] = np.nan
    with pytest.raises(MotionError, match=r"frame 3.*window 1, joint 4"):
        pm.per_frame_mpjpe_mm(bad, target)
    with pytest.raises(MotionError, match=r"\(N, F, J, 3\)"):
        pm.per_frame_mpjpe_mm(target[0], target[0])

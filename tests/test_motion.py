"""Tests for simenv.core.motion: validation and explicit transformations."""

from __future__ import annotations

import numpy as np
import pytest

from simenv.core.errors import MotionError, SkeletonError, UnitsError
from simenv.core.motion import Interaction, Motion, interpolate_gaps
from simenv.core.skeletons import Skeleton, canonical_skeleton


def _walk(frames: int = 20, fps: float = 30.0) -> Motion:
    """A canonical-skeleton motion: a fixed 1.7 m pose translated along X."""
    skel = canonical_skeleton()
    rng = np.random.default_rng(0)
    pose = rng.uniform(-0.2, 0.2, size=(skel.num_joints, 3))
    pose[:, 2] = np.linspace(0.0, 1.7, skel.num_joints)
    t = np.arange(frames)[:, None, None] / fps
    return Motion(pose[None] + t * np.array([1.0, 0, 0]), fps, skel, "walk")


def test_skeleton_rejects_duplicate_names():
    with pytest.raises(SkeletonError, match="duplicate"):
        Skeleton("x", ("a", "a"), (-1, 0))


def test_skeleton_rejects_parent_after_child():
    with pytest.raises(SkeletonError, match="precede"):
        Skeleton("x", ("a", "b"), (1, -1))


def test_motion_rejects_nan_naming_frame_and_joint():
    m = _walk()
    pos = m.positions.copy()
    pos[7, 3, 1] = np.nan
    with pytest.raises(MotionError, match=r"frame 7.*left_ankle"):
        Motion(pos, 30, m.skeleton)


def test_motion_rejects_empty_and_wrong_joint_count():
    m = _walk()
    with pytest.raises(MotionError, match="no frames"):
        Motion(m.positions[:0], 30, m.skeleton)
    with pytest.raises(MotionError, match="20 joints"):
        Motion(m.positions[:, :20], 30, m.skeleton)


def test_motion_rejects_wrong_units():
    m = _walk()
    with pytest.raises(UnitsError, match="metres"):
        Motion(m.positions * 1000.0, 30, m.skeleton)


def test_resample_keeps_time_span_and_interpolates():
    m = _walk(frames=31, fps=30.0)
    r = m.resample(15.0)
    assert r.fps == 15.0
    assert r.num_frames == 16
    assert r.duration == pytest.approx(m.duration)
    np.testing.assert_allclose(r.positions[5], m.positions[10], atol=1e-6)
    assert m.num_frames == 31  # the original is unchanged


def test_slice_and_concatenate_round_trip():
    m = _walk(frames=20)
    joined = Motion.concatenate([m.slice(0, 8), m.slice(8)])
    np.testing.assert_array_equal(joined.positions, m.positions)
    with pytest.raises(MotionError, match="empty"):
        m.slice(30, 40)
    with pytest.raises(MotionError, match="fps"):
        Motion.concatenate([m, m.resample(15.0)])


def test_interaction_requires_common_clock():
    m = _walk(frames=20)
    with pytest.raises(MotionError, match="frames"):
        Interaction(m, m.slice(0, 10))
    with pytest.raises(MotionError, match="fps"):
        Interaction(m, m.resample(60.0).slice(0, 20))


def test_interpolate_gaps_fills_and_reports():
    m = _walk(frames=10)
    valid = np.ones(10, bool)
    valid[3:5] = False
    pos = m.positions.copy()
    pos[3:5] = 0.0
    filled, notes = interpolate_gaps(pos, valid)
    np.testing.assert_allclose(filled, m.positions, atol=1e-5)
    assert notes == ["interpolated frames 3-4 (2 invalid)"]
    with pytest.raises(MotionError, match="max_gap"):
        interpolate_gaps(pos, valid, max_gap=1)

"""Tests for simenv.data.prediction_data on real CMU clips: layout, windows, split by clip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simenv.core import srvf
from simenv.core.errors import MotionError, SkeletonError
from simenv.core.skeletons import canonical_skeleton, h36m_skeleton
from simenv.data import prediction_data as pdata
from simenv.io import asf_amc, bvh


def _clip(shared_data: Path, stem: str, **kw) -> object:
    return bvh.read(shared_data / "cmu" / "bvh" / f"{stem}.bvh", **kw)


def test_layout_has_the_h36m17_tree():
    skel = pdata.pred17_skeleton()
    assert skel.num_joints == 17
    assert skel.parents == h36m_skeleton().parents
    assert set(skel.joint_names) <= set(canonical_skeleton().joint_names)


def test_to_pred17_takes_the_canonical_keypoints(shared_data):
    motion = _clip(shared_data, "02_01")
    m17 = pdata.to_pred17(motion)
    assert m17.skeleton.name == "pred17" and m17.num_frames == motion.num_frames
    for joint in ("pelvis", "chest", "head", "left_wrist", "right_ankle"):
        np.testing.assert_array_equal(
            m17.joint(joint), motion.joint(motion.skeleton.canonical[joint])
        )


def test_to_pred17_names_missing_keypoints(shared_data):
    canon = _clip(shared_data, "02_01").to_canonical()
    keep = [j for j in canon.skeleton.joint_names if j not in ("chest", "left_elbow")]
    no_chest = canon.with_positions(
        canon.positions[:, [canon.skeleton.index(j) for j in keep]],
        skeleton=canon.skeleton.subset(keep, name="kinect_like"),
    )
    with pytest.raises(SkeletonError, match=r"kinect_like.*chest, left_elbow"):
        pdata.to_pred17(no_chest)


def test_windows_are_contiguous_resampled_frames_split_into_root_and_relative(shared_data):
    motion = _clip(shared_data, "02_06")
    windows = pdata.windows_from_motions([motion], 25, 25, stride=7)
    m25 = pdata.to_pred17(motion.resample(25.0))
    length = 51
    assert windows.fps == 25.0
    assert windows.frames.shape[1:] == (length, 17, 3)
    assert len(windows) == (m25.num_frames - length) // 7 + 1
    np.testing.assert_array_equal(windows.start, 7 * np.arange(len(windows)))
    for k in (0, len(windows) // 2, len(windows) - 1):
        s = windows.start[k]
        absolute = windows.frames[k] + windows.root[k][:, None]
        np.testing.assert_allclose(absolute, m25.positions[s : s + length], atol=1e-6)
    assert np.all(windows.frames[:, :, 0] == 0)  # pelvis is the origin
    # views: lead-in, P past, F future; the future curve starts at the last observed pose
    assert windows.past.shape == windows.future.shape == (len(windows), 25, 17, 3)
    np.testing.assert_array_equal(windows.past[:, 0], windows.frames[:, 1])
    np.testing.assert_array_equal(windows.future[:, -1], windows.frames[:, -1])
    np.testing.assert_array_equal(windows.future_root, windows.root[:, 26:])
    past_c, future_c = windows.past_curve(), windows.future_curve()
    assert past_c.shape == future_c.shape == (len(windows), 26, 51)
    np.testing.assert_array_equal(past_c[:, 0], windows.lead_in.reshape(-1, 51))
    np.testing.assert_array_equal(past_c[:, -1], future_c[:, 0])


def test_past_and_future_are_points_of_one_sphere_and_the_future_integrates_back(shared_data):
    windows = pdata.windows_from_motions([_clip(shared_data, "49_02")], 25, 25, stride=25)
    future_c = windows.future_curve()
    p_past, _ = srvf.curve_to_sphere(windows.past_curve())
    p_future, amp_future = srvf.curve_to_sphere(future_c)
    d = srvf.distance(p_past, p_future)
    assert d.shape == (len(windows),) and np.all((d >= 0) & (d <= np.pi))
    rebuilt = srvf.sphere_to_curve(p_future, amp_future, windows.past[:, -1].reshape(-1, 51))
    np.testing.assert_allclose(rebuilt[:, 1:], windows.future.reshape(len(windows), 25, 51),
                               atol=1e-9)


def test_clips_already_at_the_target_rate_are_not_resampled(shared_data):
    m25 = _clip(shared_data, "02_01").resample(25.0)
    windows = pdata.windows_from_motions([m25], 10, 10, stride=1)
    assert len(windows) == m25.num_frames - 21 + 1
    pelvis = pdata.to_pred17(m25).joint("pelvis")
    np.testing.assert_array_equal(windows.root[:, 0], pelvis[: len(windows)])


def test_short_clips_are_skipped_and_no_usable_clip_is_an_error(shared_data):
    long_clip, short_clip = _clip(shared_data, "02_01"), _clip(shared_data, "35_17")
    windows = pdata.windows_from_motions([long_clip, short_clip], 25, 25)
    assert windows.skipped == ("35_17",)
    assert windows.clip_names == ("02_01",)
    with pytest.raises(MotionError, match=r"needs 51 frames.*35_17 \(35 frames\)"):
        pdata.windows_from_motions([short_clip], 25, 25)
    with pytest.raises(MotionError, match="stride"):
        pdata.windows_from_motions([long_clip], 25, 25, stride=0)


def test_clips_with_the_same_name_are_one_clip(shared_data):
    a = _clip(shared_data, "02_01", name="trial")
    b = _clip(shared_data, "12_01", name="trial")
    c = _clip(shared_data, "16_15")
    windows = pdata.windows_from_motions([a, b, c], 10, 10, stride=5)
    assert windows.clip_names == ("trial", "16_15")
    split = pdata.split_by_clip(windows.window_clip_names, 0.5, seed=0)
    assert {split.train_clips, split.test_clips} == {("trial",), ("16_15",)}


def test_one_trial_read_from_bvh_and_amc_is_one_clip(shared_data):
    from_bvh = _clip(shared_data, "02_01")
    from_amc = asf_amc.read(shared_data / "cmu" / "asf_amc" / "02_01.amc")
    windows = pdata.windows_from_motions([from_bvh, from_amc, _clip(shared_data, "49_06")],
                                         10, 10, stride=4)
    assert windows.clip_names == ("02_01", "49_06")
    per_format = np.bincount(windows.clip)[0] // 2
    assert per_format == len(pdata.windows_from_motions([from_amc], 10, 10, stride=4))
    split = pdata.split_by_clip(windows.window_clip_names, 0.5, seed=1)
    assert set(split.test_clips) in ({"02_01"}, {"49_06"})


def test_split_by_clip_on_real_windows(shared_data):
    clips = [_clip(shared_data, n) for n in ("02_01", "02_06", "12_01", "16_15", "49_02", "49_06")]
    windows = pdata.windows_from_motions(clips, 10, 10, stride=2)
    split = pdata.split_by_clip(windows.window_clip_names, 0.25, seed=3)
    names = windows.window_clip_names
    assert not set(names[split.train]) & set(names[split.test])
    assert sorted(np.concatenate([split.train, split.test]).tolist()) == list(range(len(names)))
    assert set(names[split.test]) == set(split.test_clips)
    again = pdata.split_by_clip(windows.window_clip_names, 0.25, seed=3)
    np.testing.assert_array_equal(again.test, split.test)
    test_part = windows.subset(split.test)
    assert set(test_part.window_clip_names) == set(split.test_clips)


#: Window counts of 2-12 clips, and a seed, of the split properties.
CLIP_SIZES = st.lists(st.integers(1, 40), min_size=2, max_size=12)
SEEDS = st.integers(0, 2**32 - 1)


def _clip_names(sizes: list[int], seed: int) -> np.ndarray:
    """The clip name of each window, ``sizes[i]`` windows of clip i, in a seeded random
    order (windows need not be grouped by clip)."""
    names = np.concatenate([np.full(n, f"clip{i}") for i, n in enumerate(sizes)])
    return names[np.random.default_rng(seed).permutation(len(names))]


@settings(max_examples=200, deadline=None)
@given(CLIP_SIZES, st.floats(0.01, 0.99), SEEDS)
def test_split_by_clip_never_shares_a_clip_and_approaches_the_fraction(sizes, fraction, seed):
    names = _clip_names(sizes, seed)
    split = pdata.split_by_clip(names, fraction, seed)
    assert split.train.size and split.test.size
    assert not set(names[split.train]) & set(names[split.test])
    assert split.train.size + split.test.size == len(names)
    # greedy: within one clip (the largest) of the target, unless forced to keep a side
    assert abs(split.test.size - fraction * len(names)) <= max(sizes)


def test_split_by_clip_rejects_bad_input():
    with pytest.raises(MotionError, match="at least 2 distinct clips"):
        pdata.split_by_clip(["a", "a"], 0.5, 0)
    with pytest.raises(MotionError, match=r"\(0, 1\)"):
        pdata.split_by_clip(["a", "b"], 1.0, 0)


@settings(max_examples=200, deadline=None)
@given(CLIP_SIZES, st.integers(2, 6), SEEDS)
def test_clip_folds_hold_out_every_clip_once_and_balance_the_windows(sizes, folds, seed):
    folds = min(folds, len(sizes))
    names = _clip_names(sizes, seed)
    splits = pdata.clip_folds(names, folds, seed)
    assert len(splits) == folds
    held = [c for s in splits for c in s.test_clips]
    assert sorted(held) == sorted(set(names))  # each clip on the test side exactly once
    for s in splits:
        assert s.test.size and s.train.size + s.test.size == len(names)
        assert not set(names[s.train]) & set(names[s.test])
        assert set(names[s.test]) == set(s.test_clips)
    loads = [s.test.size for s in splits]
    # dealt largest first to the lightest fold: loads differ by at most the largest clip
    assert max(loads) - min(loads) <= max(sizes)


def test_clip_folds_on_real_windows_and_bad_input(shared_data):
    clips = [_clip(shared_data, n) for n in ("02_01", "02_06", "12_01", "16_15", "49_06")]
    windows = pdata.windows_from_motions(clips, 10, 10, stride=2)
    splits = pdata.clip_folds(windows.window_clip_names, 3, seed=0)
    assert sorted(c for s in splits for c in s.test_clips) == sorted(windows.clip_names)
    again = pdata.clip_folds(windows.window_clip_names, 3, seed=0)
    for a, b in zip(splits, again, strict=True):
        np.testing.assert_array_equal(a.test, b.test)
    with pytest.raises(MotionError, match=r"folds must be in \[2, 5\]"):
        pdata.clip_folds(windows.window_clip_names, 6, 0)
    with pytest.raises(MotionError, match="folds must be"):
        pdata.clip_folds(windows.window_clip_names, 1, 0)


def test_to_pred17_derives_the_chest_and_pelvis_of_kinect_skeletons_when_asked(shared_data):
    from simenv.io import florence3d, utkinect

    session = utkinect.read(shared_data / "gestures" / "utkinect" / "joints"
                            / "joints_s01_e01.txt")
    with pytest.raises(SkeletonError, match="chest"):
        pdata.to_pred17(session)
    m17 = pdata.to_pred17(session, derive=True)
    assert m17.skeleton.name == "pred17" and m17.num_frames == session.num_frames
    np.testing.assert_allclose(
        m17.joint("chest"), 0.5 * (session.joint("Spine") + session.joint("ShoulderCenter")),
        atol=1e-6)
    np.testing.assert_array_equal(m17.joint("pelvis"), session.joint("HipCenter"))
    assert m17.metadata["derived_keypoints"] == {"chest": ["spine", "neck"]}
    video = florence3d.read(shared_data / "gestures" / "florence3d" / "skeletal_data.mat")[0]
    f17 = pdata.to_pred17(video, derive=True)  # OpenNI: no pelvis either
    np.testing.assert_allclose(
        f17.joint("pelvis"), 0.5 * (video.joint("LeftHip") + video.joint("RightHip")), atol=1e-6)
    # a real body: the derived chest lies between the pelvis and the head
    z = f17.positions[..., 2]
    assert np.all((z[:, 0] < z[:, 8]) & (z[:, 8] < z[:, 10]))


def test_to_pred17_derive_still_names_what_cannot_be_derived(shared_data):
    canon = _clip(shared_data, "02_01").to_canonical()
    keep = [j for j in canon.skeleton.joint_names if j not in ("chest", "neck")]
    no_neck = canon.with_positions(
        canon.positions[:, [canon.skeleton.index(j) for j in keep]],
        skeleton=canon.skeleton.subset(keep, name="no_neck"))
    with pytest.raises(SkeletonError, match=r"no_neck.*chest, neck"):
        pdata.to_pred17(no_neck, derive=True)

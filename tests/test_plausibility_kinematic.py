"""Joint-level kinematic metrics on real CMU clips and corrupted copies."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import simenv
from simenv.core.errors import MotionError, SimenvError
from simenv.core.motion import Motion
from simenv.core.skeletons import Skeleton, kinect_v2_skeleton
from simenv.io import bvh
from simenv.plausibility import (
    Thresholds,
    bone_length,
    bone_length_error,
    bone_lengths,
    jitter,
    kinematic_metrics,
    reference_lengths,
    velocity,
)
from simenv.plausibility.clips import norm3
from simenv.plausibility.metrics.bone_length import bone_deviations, bone_names
from simenv.plausibility.metrics.jitter import windowed_normalized_jerk
from simenv.plausibility.metrics.velocity import speed_limits

HUMANML3D = Path(__file__).parent / "data" / "humanml3d" / "new_joints" / "012314.npy"


@pytest.fixture(scope="module")
def walk(shared_data) -> Motion:
    """Real CMU walk 02_01 (343 frames at 120 fps, T-pose dropped)."""
    return bvh.read(shared_data / "cmu/bvh/02_01.bvh")


def _canon(m: Motion) -> Motion:
    return m.to_canonical()


def test_clean_walk_passes_every_kinematic_metric(walk) -> None:
    results = kinematic_metrics(walk)
    assert list(results) == ["bone_length", "foot_skate", "ground_penetration", "floating",
                             "jitter", "velocity"]
    for name, r in results.items():
        assert r.available, (name, r.reason)
        assert r.passed, (name, r.value, r.threshold, r.violations[:3])
        assert r.timeline.shape == (walk.num_frames,)


def test_bone_stretched_over_time_fails(walk) -> None:
    c = _canon(walk)
    names = c.skeleton.joint_names
    knee, ankle, toe = (names.index(n) for n in ("left_knee", "left_ankle", "left_toe"))
    pos = c.positions.copy()
    shin = pos[:, ankle] - pos[:, knee]
    # The shin grows linearly to +20 % over the clip; the foot moves with it.
    grow = np.linspace(0.0, 0.2, c.num_frames, dtype=np.float32)[:, None] * shin
    pos[:, ankle] += grow
    pos[:, toe] += grow
    r = bone_length(c.with_positions(pos))
    assert r.passed is False
    assert r.details["max_rel_deviation"] > 0.08
    # Frames near the clip's median length are fine: the violation is at the ends.
    starts = [v[0] for v in r.violations]
    assert min(starts) == 0 and r.violations[-1][1] == c.num_frames - 1
    assert bone_length(walk).details["max_rel_deviation"] < 1e-3


def test_bone_length_error_against_reference(walk, shared_data) -> None:
    # The reference is keyed by canonical keypoint pairs, whatever the source's bones.
    ref = reference_lengths(walk)
    hip, knee = (walk.skeleton.index(n) for n in ("LeftUpLeg", "LeftLeg"))
    assert ref["left_knee"] == pytest.approx(float(np.median(
        norm3(walk.positions[:, knee].astype(np.float64) - walk.positions[:, hip]))))
    same = bone_length_error(walk, ref)
    assert same.passed and same.value < 1.0
    other = bvh.read(shared_data / "cmu/bvh/131_01.bvh").slice(0, 100)
    scaled = {k: 1.25 * v for k, v in ref.items() if v > 0.01}
    r = bone_length_error(walk, scaled)
    assert r.passed is False and r.value > 20.0
    assert bone_length_error(other, ref).value > same.value
    with pytest.raises(MotionError, match="not a canonical bone"):
        bone_length_error(walk, {"tail": 0.3})
    with pytest.raises(MotionError, match="positive bone length"):
        bone_length_error(walk, {"left_knee": -0.4})


@pytest.fixture(scope="module")
def humanml3d() -> Motion:
    """Real HumanML3D ``new_joints`` clip 012314 (AMASS tennis serve on the SMPL
    body, 170 frames at 20 fps; tests/data/humanml3d/SOURCES.md)."""
    return simenv.load(HUMANML3D, fps=20)


def test_real_smpl_clip_passes_on_its_own_bones(humanml3d) -> None:
    # Every SMPL bone is rigid; the canonical chest-to-shoulder pair spans the
    # collar joint, so its length changes (the canonical pairs failed this clip
    # at 2.8 tolerances).
    names, lengths = bone_lengths(humanml3d)
    assert len(names) == 21 and "left_collar->left_shoulder" in names
    assert "spine3->left_shoulder" not in names
    rel = np.abs(lengths / np.median(lengths, axis=0) - 1)
    assert rel.max() < 1e-4
    s = humanml3d.skeleton
    assert s.canonical["chest"] == "spine3"
    span = norm3(humanml3d.positions[:, s.index("left_shoulder")].astype(np.float64)
                 - humanml3d.positions[:, s.index("spine3")])
    assert np.abs(span / np.median(span) - 1).max() > 0.1
    r = bone_length(humanml3d)
    assert r.passed and r.value < 1e-3 and r.details["bones_checked"] == 21


def test_a_stretched_source_bone_fails_and_is_named(humanml3d) -> None:
    pos = humanml3d.positions.copy()
    s = humanml3d.skeleton
    collar, shoulder = s.index("left_collar"), s.index("left_shoulder")
    below = [shoulder, *(s.index(n) for n in ("left_elbow", "left_wrist"))]
    # The collar bone grows by 20 % over the last 40 % of the clip.
    grow = np.zeros(len(pos), dtype=np.float32)
    grow[-len(pos) * 2 // 5:] = 0.2
    pos[:, below] += (grow[:, None] * (pos[:, shoulder] - pos[:, collar]))[:, None]
    moved = humanml3d.with_positions(pos)
    r = bone_length(moved)
    assert r.passed is False and r.details["max_rel_deviation"] == pytest.approx(0.2, abs=1e-3)
    worst = max(bone_deviations(moved), key=lambda d: d["p95_tolerances"])
    assert worst["bone"] == "left_collar->left_shoulder" and worst["checked"]
    assert worst["p95_tolerances"] == pytest.approx(4.0, rel=1e-3)


def test_measured_bones_follow_the_tree_not_the_canonical_map(shared_data) -> None:
    # Extremity fans (two or more end joints on one parent) are left out: the
    # Poser head's eyes, Kinect v2's hand tip and thumb; a lone end joint (the
    # ASF thumb and fingers, a toe, the head) is measured.
    amc = simenv.load(shared_data / "cmu/asf_amc/02_01.amc").slice(0, 240)
    names = bone_names(amc.skeleton)
    assert len(names) == len(amc.skeleton.bones) == 30
    assert {"lowerneck->upperneck", "upperneck->head", "lwrist->lthumb"} <= set(names)
    salsa = simenv.load(shared_data / "cmu/two_person/60_61_salsa_10").actor
    assert {"head->leftEye", "head->rightEye"} & set(bone_names(salsa.skeleton)) == set()
    assert "lFoot->lFoot_end" in bone_names(salsa.skeleton)
    assert not [n for n in bone_names(kinect_v2_skeleton()) if "Tip" in n or "Thumb" in n]
    # The canonical map decides nothing but the head's tolerance: with three
    # keypoints mapped the same bones are checked, with the same values.
    full = bone_length(amc)
    keep = {k: amc.skeleton.canonical[k] for k in ("pelvis", "head", "left_toe")}
    sparse = Skeleton("sparse", amc.skeleton.joint_names, amc.skeleton.parents, keep)
    r = bone_length(Motion(amc.positions, amc.fps, sparse, "sparse"))
    assert r.details == full.details and r.value == full.value
    # Every real CMU bone is rigid, the neck included (the canonical neck-head pair
    # spans the upper neck, which CMU 02_04 nods by 6 %).
    nod = simenv.load(shared_data / "cmu/asf_amc/02_04.amc")
    assert bone_length(nod).details["max_rel_deviation"] < 1e-4


@pytest.mark.parametrize("sigma", [0.005, 0.01])
def test_added_noise_is_flagged_as_jitter(walk, sigma) -> None:
    rng = np.random.default_rng(7)
    noisy = walk.with_positions(walk.positions + rng.normal(0, sigma, walk.positions.shape)
                                .astype(np.float32))
    r = jitter(noisy)
    clean = jitter(walk)
    assert clean.passed and not r.passed
    assert r.details["mean_jerk_mps3"] > 3 * clean.details["mean_jerk_mps3"]
    assert r.violations and r.violations[0][2] > 6500


def test_jitter_is_evaluated_at_30_fps_whatever_the_input_rate(walk) -> None:
    a = jitter(walk)
    b = jitter(walk.resample(60.0))
    assert a.details["analysis_fps"] == b.details["analysis_fps"] == 30.0
    assert a.passed and b.passed
    assert b.details["normalized_jerk_mean"] == pytest.approx(
        a.details["normalized_jerk_mean"], rel=0.3)


def test_teleported_joint_is_caught(walk) -> None:
    pos = walk.positions.copy()
    j = walk.skeleton.index("LeftHand")
    pos[150:153, j] += np.array([0.3, 0.0, 0.0], dtype=np.float32)
    r = velocity(walk.with_positions(pos))
    assert r.passed is False
    assert r.details["teleport_frames"] >= 2
    assert any(s <= 150 <= e or s <= 153 <= e for s, e, _ in r.violations)


def test_skipped_frames_at_30_fps_are_a_teleport(walk) -> None:
    low = walk.resample(30.0)
    assert velocity(low).passed
    # Drop 12 frames (0.4 s) in the middle: the whole body jumps ahead.
    skipped = Motion.concatenate([low.slice(0, 40), low.slice(52)])
    r = velocity(skipped)
    assert r.passed is False
    assert any(s <= 40 <= e + 1 for s, e, _ in r.violations)


def test_speed_limit_is_per_keypoint_group(walk) -> None:
    # A pelvis moving at 15 m/s is beyond any human; a hand at 15 m/s is not.
    c = _canon(walk).slice(0, 50)
    t = c.times.astype(np.float32)
    pel = c.skeleton.index("pelvis")
    pos = c.positions.copy()
    pos[:, pel, 0] += 15.0 * t
    assert velocity(c.with_positions(pos)).passed is False
    pos = c.positions.copy()
    hand = c.skeleton.index("right_hand")
    pos[:, hand, 0] += 15.0 * t
    r = velocity(c.with_positions(pos))
    assert r.passed and r.details["max_speed_mps"] > 15.0


def test_short_clips_are_not_available_with_a_reason(walk) -> None:
    one, two = walk.slice(0, 1), walk.slice(0, 2)
    assert bone_length(one).passed is True
    v1, v2 = velocity(one), velocity(two)
    assert v1.passed is None and "2 frames" in v1.reason
    assert v2.available and v2.details["teleport_frames"] == 0
    j = jitter(walk.slice(0, 20))
    assert j.passed is None and "frames" in j.reason and j.timeline.shape == (20,)
    for r in kinematic_metrics(one).values():
        assert r.timeline.shape == (1,)


def test_missing_keypoints_use_what_is_there(walk) -> None:
    c = _canon(walk)
    keep = [n for n in c.skeleton.joint_names if not n.endswith(("_toe", "_hand", "head"))]
    sub = Motion(c.positions[:, [c.skeleton.index(n) for n in keep]], c.fps,
                 c.skeleton.subset(keep), "no-extremities")
    assert bone_length(sub).passed and velocity(sub).passed and jitter(sub).passed
    bare = Motion(c.positions[:, :1], c.fps,
                  c.skeleton.subset(["pelvis"]), "pelvis-only")
    r = bone_length(bare)
    assert r.passed is None and "bone" in r.reason


def test_thresholds_are_validated_and_configurable(walk) -> None:
    with pytest.raises(SimenvError, match="speed_limit_trunk_mps"):
        Thresholds(speed_limit_trunk_mps=-1)
    strict = replace(Thresholds(), speed_limit_trunk_mps=0.5)
    assert velocity(walk, strict).passed is False


def test_normalized_jerk_matches_the_published_formula() -> None:
    # ProtoMotions' definition on x(t) = t^3 sampled at dt = 1 with a 4-frame
    # window: path length 1 + 7 + 19 = 27, one jerk sample of 6, T = 3.
    t = np.arange(4, dtype=np.float64)
    pos = np.zeros((4, 1, 3))
    pos[:, 0, 0] = t**3
    nj = windowed_normalized_jerk(pos, fps=1.0, window_frames=4)
    assert nj.shape == (1, 1)
    assert nj[0, 0] == pytest.approx(3.0**5 * 36.0 / (27.0**2 + 0.1))
    assert windowed_normalized_jerk(pos[:3], fps=1.0, window_frames=4).shape == (0, 1)


@pytest.mark.parametrize("fps", [60.0, 30.0, 24.0])
def test_real_walk_passes_at_other_frame_rates(walk, fps) -> None:
    low = walk.resample(fps)
    base = kinematic_metrics(walk)
    for name, r in kinematic_metrics(low).items():
        assert r.passed, (fps, name, r.value)
        assert r.timeline.shape == (low.num_frames,)
    assert kinematic_metrics(low)["velocity"].details["max_speed_mps"] == pytest.approx(
        base["velocity"].details["max_speed_mps"], rel=0.25)


@pytest.mark.parametrize("limb_mps", [None, 12.0])
def test_velocity_is_the_numpy_formula(walk, limb_mps) -> None:
    # The kernel takes one square root per frame and speed limit (the root of
    # the largest squared step); the per-keypoint numpy formula must give the
    # same bits, also when two keypoint groups share a limit.
    th = Thresholds() if limb_mps is None else replace(
        Thresholds(), speed_limit_limb_mps=limb_mps, speed_limit_trunk_mps=limb_mps)
    c = _canon(walk)
    pos = c.positions.astype(np.float64)
    speed = norm3(np.diff(pos, axis=0)) * c.fps
    ratio = speed / speed_limits(c, th)
    jump = norm3(np.diff(pos, 2, axis=0))
    limit = max(th.teleport_distance_m, th.teleport_accel_mps2 / c.fps**2)
    timeline = np.full(c.num_frames, np.nan)
    timeline[1:] = ratio.max(axis=1)
    timeline[1:-1] = np.maximum(timeline[1:-1], jump.max(axis=1) / limit)
    r = velocity(walk, th)
    np.testing.assert_array_equal(r.timeline, timeline.astype(np.float32))
    assert r.value == np.nanmax(timeline)
    assert r.details["max_speed_mps"] == speed.max()
    assert r.details["max_speed_ratio"] == ratio.max()
    assert r.details["max_jump_m"] == jump.max()


def test_violation_runs_beyond_the_room_made_for_them_are_all_kept(walk, monkeypatch) -> None:
    # clips.score makes room for a few runs per clip and scores again when a
    # batch has more; a joint teleported every 20 frames gives many runs.
    from simenv.plausibility import clips

    pos = walk.positions.copy()
    pos[10::20, 5] += np.float32(0.5)
    jumpy = walk.with_positions(pos)
    expected = kinematic_metrics(jumpy)
    assert len(expected["velocity"].violations) > 10
    monkeypatch.setattr(clips, "_RUNS_PER_CLIP", 1)
    got = kinematic_metrics(jumpy)
    for name, r in expected.items():
        assert got[name].violations == r.violations, name
        assert got[name].value == r.value or np.isnan(r.value), name
        assert got[name].details == r.details, name
        np.testing.assert_array_equal(got[name].timeline, r.timeline, err_msg=name)


@pytest.mark.parametrize("n", [1, 2, 3, 8, 15, 16, 21, 22, 31, 33])
def test_median_network_gives_numpy_median_and_max(n) -> None:
    # Jitter's median over keypoints (a pruned Batcher network), on columns
    # with and without ties: numpy's median is the answer.
    from simenv.plausibility import kernels

    rng = np.random.default_rng(n)
    a = rng.standard_normal((n, 40))
    a[:, 20:] = np.round(a[:, 20:])
    med, top = np.empty(40), np.empty(40)
    kernels._column_medians(a.copy(), kernels.median_network(n), med, top)
    np.testing.assert_array_equal(med, np.median(a, axis=0))
    np.testing.assert_array_equal(top, a.max(axis=0))
    assert len(kernels.median_network(21)) < 21 * 20


def _same_result(a, b, where: str) -> None:
    assert (a.name, a.unit, a.threshold, a.passed, a.frame_threshold, a.timeline_unit,
            a.reason) == (b.name, b.unit, b.threshold, b.passed, b.frame_threshold,
                          b.timeline_unit, b.reason), where
    assert repr(a.value) == repr(b.value), where  # NaN equals NaN
    assert a.violations == b.violations and a.details.keys() == b.details.keys(), where
    assert [repr(v) for v in a.details.values()] == [repr(v) for v in b.details.values()], where
    assert a.timeline.dtype == b.timeline.dtype and a.timeline.tobytes() == b.timeline.tobytes()


def test_batch_of_windows_equals_scoring_each_window_alone(shared_data) -> None:
    # The shape of a generator's output: equal-length windows (views into
    # real clips, so they share each clip's memory), plus windows too short
    # for jitter, batched together; each must score exactly as alone.
    from simenv.plausibility import KINEMATIC_METRICS, kinematic_metrics_batch

    clips = [bvh.read(shared_data / f"cmu/bvh/{n}.bvh") for n in ("02_01", "05_02", "49_02")]
    wins = [c.slice(s, s + f) for f in (240, 37) for c in clips
            for s in range(0, c.num_frames - f + 1, 3 * f)]
    assert len(wins) > 20
    batched = kinematic_metrics_batch(wins)
    assert len(batched) == len(wins)
    for i, (motion, got) in enumerate(zip(wins, batched, strict=True)):
        assert list(got) == list(KINEMATIC_METRICS)
        for name, fn in KINEMATIC_METRICS.items():
            _same_result(got[name], fn(motion), f"window {i}: {name}")


def test_batch_results_are_a_sequence_built_on_reading(shared_data, walk) -> None:
    from simenv.plausibility import KINEMATIC_METRICS, KinematicResults, kinematic_metrics_batch

    wins = [walk.slice(s, s + 60) for s in range(0, 300, 60)] + [walk.slice(0, 2)]
    res = kinematic_metrics_batch(wins)
    assert isinstance(res, KinematicResults) and len(res) == 6
    # Reading a clip again gives the same objects, by any index form.
    first = res[0]
    assert res[0] is first and res[-6] is first and res[:1][0] is first
    assert [r is s for r, s in zip(res, list(res), strict=True)] == [True] * 6
    with pytest.raises(IndexError, match="out of range"):
        res[6]
    # values() gives the results' values without building them (NaN where
    # not available: jitter on the 2-frame clip).
    fresh = kinematic_metrics_batch(wins)
    for name in KINEMATIC_METRICS:
        v = fresh.values(name)
        assert v.shape == (6,)
        expected = np.array([r[name].value for r in res])
        np.testing.assert_array_equal(v, expected)
    assert np.isnan(fresh.values("jitter")[-1]) and not np.isnan(fresh.values("jitter")[0])
    with pytest.raises(SimenvError, match="not a kinematic metric"):
        fresh.values("tracking")
    assert kinematic_metrics_batch([]) == [] and kinematic_metrics_batch([]) != [{}]

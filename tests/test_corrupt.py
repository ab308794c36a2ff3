"""Corruption generators on real motion capture: each one at its moderate
strength is caught by the metric it targets, the real clip is not; the
generators are seeded, pure, keep length and fps, and reject bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import simenv
from simenv.assets import WALK, asset_path
from simenv.core.errors import MotionError, SimenvError
from simenv.core.motion import Motion
from simenv.plausibility import KINEMATIC_METRICS, bone_length, bone_lengths, floating, foot_skate
from simenv.plausibility.corrupt import (
    CORRUPTIONS,
    MIN_FRAMES,
    STRENGTH_UNITS,
    STRETCH_BONES,
    bone_stretch,
    float_,
)

#: Real HumanML3D ``new_joints`` clip (AMASS on the SMPL body; tests/data/humanml3d/SOURCES.md).
HUMANML3D = Path(__file__).parent / "data" / "humanml3d" / "new_joints" / "012314.npy"

#: Real clips (path under shared/data/cmu, frames kept): a walk, jumps and
#: hops, a karate kata, a dance with pirouettes, a run. A few seconds each.
REAL_CLIPS = {
    "jumps": ("bvh/49_02.bvh", 600),
    "kata": ("asf_amc/135_06.amc", 600),
    "dance": ("bvh/05_02.bvh", 600),
    "run": ("asf_amc/09_06.amc", None),
}

_CACHE: dict[str, Motion] = {}


def _clip(key: str, shared_data: Path | None) -> Motion:
    if key not in _CACHE:
        if key == "walk_asset":
            _CACHE[key] = simenv.load(asset_path(WALK))
        else:
            path, frames = REAL_CLIPS[key]
            motion = simenv.load(shared_data / "cmu" / path)
            _CACHE[key] = motion if frames is None else motion.slice(0, frames)
    return _CACHE[key]


@pytest.fixture(params=["walk_asset", *REAL_CLIPS])
def clip(request: pytest.FixtureRequest) -> Motion:
    """A real clip: the bundled walk, or a corpus clip (skipped when absent)."""
    if request.param == "walk_asset":
        return _clip("walk_asset", None)
    return _clip(request.param, request.getfixturevalue("shared_data"))


@pytest.fixture
def walk() -> Motion:
    return _clip("walk_asset", None)


@pytest.mark.parametrize("name", list(CORRUPTIONS))
def test_moderate_corruption_is_caught_by_its_target(clip: Motion, name: str) -> None:
    fn, targets, moderate = CORRUPTIONS[name]
    for target in targets:
        clean = KINEMATIC_METRICS[target](clip)
        assert clean.passed, f"real clip {clip.name} already fails {target}: {clean.value}"
    corrupted = fn(clip, moderate, seed=0)
    results = {t: KINEMATIC_METRICS[t](corrupted) for t in targets}
    assert any(r.passed is False for r in results.values()), (
        f"{name} at {moderate:g} {STRENGTH_UNITS[name]} on {clip.name} not caught: "
        + ", ".join(f"{t}={r.value:.3g} (threshold {r.threshold:g})" for t, r in results.items())
    )


def test_freeze_the_fall_of_a_jump_is_floating(shared_data: Path) -> None:
    jumps = _clip("jumps", shared_data)
    assert floating(jumps).passed
    frozen = float_(jumps, 15.0, seed=0, mode="freeze")
    result = floating(frozen)
    assert not result.passed
    apex = frozen.metadata["corruptions"][-1]["apex_frame"]
    assert any(s <= apex + 1 <= e for s, e, _ in result.violations)


@pytest.mark.parametrize("name", list(CORRUPTIONS))
def test_seeded_pure_and_same_shape(walk: Motion, name: str) -> None:
    fn, targets, moderate = CORRUPTIONS[name]
    before = walk.positions.copy()
    a = fn(walk, moderate, seed=3)
    b = fn(walk, moderate, seed=3)
    c = fn(walk, moderate, seed=4)
    np.testing.assert_array_equal(a.positions, b.positions)
    assert not np.array_equal(a.positions, c.positions)
    np.testing.assert_array_equal(walk.positions, before)  # input untouched
    assert "corruptions" not in walk.metadata
    assert (a.num_frames, a.fps, a.skeleton) == (walk.num_frames, walk.fps, walk.skeleton)
    assert a.positions.dtype == np.float32
    record = a.metadata["corruptions"][-1]
    assert record["corruption"] == name
    assert record["strength"] == moderate
    assert record["unit"] == STRENGTH_UNITS[name]
    assert record["seed"] == 3
    assert record["targets"] == list(targets)
    assert record["frames"], "no affected frames recorded"
    for start, end in record["frames"]:
        assert 0 <= start <= end < walk.num_frames
    if name == "foot_slide":
        return  # records the sliding frames; the drift reached is held after them
    # Only recorded frames change (time_warp records the slowed rest too).
    changed = np.abs(a.positions - walk.positions).max(axis=(1, 2)) > 1e-6
    affected = np.zeros(walk.num_frames, dtype=bool)
    for start, end in record["frames"]:
        affected[start : end + 1] = True
    assert not (changed & ~affected).any()


def test_corruptions_chain_in_metadata(walk: Motion) -> None:
    twice = CORRUPTIONS["sink"].fn(CORRUPTIONS["jitter"].fn(walk, 0.5, seed=1), 5.0, seed=2)
    assert [r["corruption"] for r in twice.metadata["corruptions"]] == ["jitter", "sink"]


def test_time_warp_keeps_the_ends_and_speeds_up(walk: Motion) -> None:
    warped = CORRUPTIONS["time_warp"].fn(walk, 4.0, seed=0)
    np.testing.assert_allclose(warped.positions[0], walk.positions[0], atol=1e-5)
    np.testing.assert_allclose(warped.positions[-1], walk.positions[-1], atol=1e-4)
    record = warped.metadata["corruptions"][-1]
    assert record["fast_rate"] == 4.0 and 0.0 < record["slow_rate"] < 1.0
    speed = np.linalg.norm(np.diff(walk.positions, axis=0), axis=-1).max()
    assert np.linalg.norm(np.diff(warped.positions, axis=0), axis=-1).max() > 2.5 * speed


def test_bone_stretch_lengthens_exactly_the_chosen_bone(walk: Motion) -> None:
    out = bone_stretch(walk, 0.2, seed=0, bone="left_knee")
    # It is the source skeleton's thigh bone, which bone_length measures; every
    # other measured bone keeps its length.
    assert out.metadata["corruptions"][-1]["source_bone"] == "LeftUpLeg->LeftLeg"
    names, before = bone_lengths(walk)
    after = bone_lengths(out)[1]
    k = names.index("LeftUpLeg->LeftLeg")
    assert (after[:, k] / before[:, k]).max() == pytest.approx(1.2, abs=1e-3)
    np.testing.assert_allclose(np.delete(after, k, axis=1), np.delete(before, k, axis=1),
                               atol=2e-5)
    canon_in, canon_out = walk.to_canonical(), out.to_canonical()
    hip, knee = (canon_in.skeleton.index(n) for n in ("left_hip", "left_knee"))
    ratio = (np.linalg.norm(canon_out.positions[:, knee] - canon_out.positions[:, hip], axis=-1)
             / np.linalg.norm(canon_in.positions[:, knee] - canon_in.positions[:, hip], axis=-1))
    assert ratio.max() == pytest.approx(1.2, abs=1e-3)
    assert ratio.min() == pytest.approx(1.0, abs=1e-5)
    shin = canon_in.skeleton.index("left_ankle")
    np.testing.assert_allclose(  # the shin below is moved rigidly, not stretched
        np.linalg.norm(canon_out.positions[:, shin] - canon_out.positions[:, knee], axis=-1),
        np.linalg.norm(canon_in.positions[:, shin] - canon_in.positions[:, knee], axis=-1),
        atol=1e-5,
    )


@pytest.mark.parametrize("bone", STRETCH_BONES)
def test_bone_stretch_of_a_real_smpl_clip_is_caught(bone: str) -> None:
    """Each limb bone of the real HumanML3D clip 012314 (SMPL joints), stretched
    at the moderate 10 %, fails bone_length; the clip itself passes."""
    smpl = simenv.load(HUMANML3D, fps=20)
    assert bone_length(smpl).passed
    out = bone_stretch(smpl, CORRUPTIONS["bone_stretch"].moderate, seed=0, bone=bone)
    record = out.metadata["corruptions"][-1]
    assert record["source_bone"] == f"{smpl.skeleton.canonical[record['parent']]}->" \
        f"{smpl.skeleton.canonical[bone]}"
    r = bone_length(out)
    assert r.passed is False and r.details["max_rel_deviation"] == pytest.approx(0.1, abs=1e-3)


def test_foot_slide_is_flagged_at_skating_speed_only(walk: Motion) -> None:
    assert foot_skate(CORRUPTIONS["foot_slide"].fn(walk, 0.25, seed=0)).passed
    assert not foot_skate(CORRUPTIONS["foot_slide"].fn(walk, 1.0, seed=0)).passed


@pytest.mark.parametrize("name", list(CORRUPTIONS))
@pytest.mark.parametrize("strength", [0.0, -1.0, float("nan"), float("inf"), 1e6, "strong"])
def test_bad_strength_raises(walk: Motion, name: str, strength: object) -> None:
    with pytest.raises(SimenvError, match="strength"):
        CORRUPTIONS[name].fn(walk, strength)


@pytest.mark.parametrize("name", list(CORRUPTIONS))
def test_too_short_or_not_a_motion_raises(walk: Motion, name: str) -> None:
    fn, _, moderate = CORRUPTIONS[name]
    with pytest.raises(MotionError, match=f"at least {MIN_FRAMES} frames"):
        fn(walk.slice(0, MIN_FRAMES - 1), moderate)
    with pytest.raises(MotionError, match="expected a simenv.Motion"):
        fn(walk.positions, moderate)
    with pytest.raises(SimenvError, match="seed"):
        fn(walk, moderate, seed=-1)


def test_specific_bad_arguments(walk: Motion) -> None:
    with pytest.raises(MotionError, match="bone 'nose' not available"):
        bone_stretch(walk, 0.1, bone="nose")
    with pytest.raises(SimenvError, match="mode 'hover' unknown"):
        float_(walk, 15.0, mode="hover")  # type: ignore[arg-type]
    with pytest.raises(MotionError, match="too short for a 20x segment"):
        CORRUPTIONS["time_warp"].fn(walk.slice(0, 12), 20.0)
    canon = walk.to_canonical()
    upper = ["pelvis", "spine", "chest", "neck", "head"]
    torso = Motion(canon.positions[:, [canon.skeleton.index(n) for n in upper]], canon.fps,
                   canon.skeleton.subset(upper))
    with pytest.raises(MotionError, match="no frame with a planted foot"):
        CORRUPTIONS["foot_slide"].fn(torso, 1.0)
    with pytest.raises(MotionError, match="none of the limb bones"):
        bone_stretch(torso, 0.1)


def test_registry_is_consistent() -> None:
    assert set(CORRUPTIONS) == set(STRENGTH_UNITS)
    for name, (fn, targets, moderate) in CORRUPTIONS.items():
        assert callable(fn) and fn.__doc__ and "Targets" in fn.__doc__, name
        assert targets and all(t in KINEMATIC_METRICS for t in targets), name
        assert moderate > 0

"""Joint-level ground metrics on real CMU clips and corrupted copies."""

from __future__ import annotations

import inspect
from pathlib import Path

import numpy as np
import pytest

from simenv.body.foot_contact import foot_contacts, foot_keypoints
from simenv.core.motion import Motion
from simenv.io import bvh
from simenv.plausibility import floating, foot_skate, ground_penetration
from simenv.plausibility.metrics.floating import ballistic_residual
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS


@pytest.fixture(scope="module")
def walk(shared_data) -> Motion:
    """Real CMU walk 02_01 (343 frames at 120 fps)."""
    return bvh.read(shared_data / "cmu/bvh/02_01.bvh")


@pytest.fixture(scope="module")
def jumps(shared_data) -> Motion:
    """Real CMU 01_01 forward jumps: the first 600 frames hold three hops."""
    return bvh.read(shared_data / "cmu/bvh/01_01.bvh").slice(0, 600)


def _shift(m: Motion, dz: float) -> Motion:
    return m.with_positions(m.positions + np.array([0, 0, dz], dtype=np.float32))


def test_foot_contact_defaults_are_the_joint_level_thresholds() -> None:
    contacts = inspect.signature(foot_contacts).parameters
    feet = inspect.signature(foot_keypoints).parameters
    for name, field in (("toe_height_m", "contact_height_m"),
                        ("ankle_height_m", "contact_height_ankle_m")):
        assert contacts[name].default == feet[name].default == getattr(DEFAULT_THRESHOLDS, field)
    assert contacts["speed_mps"].default == DEFAULT_THRESHOLDS.contact_speed_mps


def test_clean_walk_has_planted_feet_and_no_ground_violation(walk) -> None:
    feet, contacts = foot_contacts(walk)
    assert feet == ["left_toe", "right_toe"]
    # Walking: each foot is planted for a good part of the gait cycle, and
    # some foot is planted most of the time.
    assert 0.2 < contacts[:, 0].mean() < 0.8 and contacts.any(axis=1).mean() > 0.6
    for metric in (foot_skate, ground_penetration, floating):
        r = metric(walk)
        assert r.passed, (r.name, r.value, r.violations[:3])


def test_real_jumps_are_ballistic_not_floating(jumps) -> None:
    r = floating(jumps)
    assert r.passed and r.details["jumps"] >= 2 and r.details["airborne_fraction"] > 0.05
    assert r.details["worst_residual_m"] < 0.03


def test_lifted_walk_floats(walk) -> None:
    r = floating(_shift(walk, 0.30))
    assert r.passed is False
    assert r.details["floating_fraction"] > 0.95
    (start, end, worst), = r.violations
    assert start == 0 and end == walk.num_frames - 1 and worst > 300.0


def test_a_skeleton_without_toes_stands_on_the_soles_below_its_ankles(walk) -> None:
    """The real walk with its toe keypoints dropped (an OpenNI / H36M-style layout): its
    lower ankle, 5-12 cm up, is its lowest point; counted a sole lower it is on the floor,
    so the walk does not float (it did: 120 mm), and lifted 20 cm it still does."""
    canon = walk.to_canonical()
    keep = [n for n in canon.skeleton.joint_names if not n.endswith("_toe")]
    toeless = Motion(canon.positions[:, [canon.skeleton.index(n) for n in keep]], canon.fps,
                     canon.skeleton.subset(keep), "no_toes")
    assert floating(toeless).passed
    assert floating(_shift(toeless, 0.20)).passed is False


def test_lifted_jumps_still_jump_but_the_ground_phases_float(jumps) -> None:
    r = floating(_shift(jumps, 0.30))
    assert r.passed is False and r.details["floating_fraction"] > 0.5


def test_sunk_walk_penetrates(walk) -> None:
    clean = ground_penetration(walk)
    r = ground_penetration(_shift(walk, -0.10))
    assert clean.passed and clean.value == 0.0
    assert r.passed is False
    lowest = walk.to_canonical().positions[..., 2].min()
    assert r.value == pytest.approx((0.10 - lowest) * 1000, abs=1.0)
    assert r.details["frames_below_floor"] > 0.5


def test_sliding_planted_feet_skate_at_any_frame_rate(walk) -> None:
    t = walk.times.astype(np.float32)[:, None]
    drift = np.zeros(walk.positions.shape, dtype=np.float32)
    drift[..., 1] = 1.0 * t  # the whole body drifts sideways at 1 m/s
    slid = walk.with_positions(walk.positions + drift)
    clean, r = foot_skate(walk), foot_skate(slid)
    assert clean.passed and clean.value < 0.02
    assert r.passed is False and r.value > 0.2
    assert r.details["physdiff_skate_mm"] > 2 * clean.details["physdiff_skate_mm"]
    assert r.violations and max(w for *_, w in r.violations) > 50.0
    low = foot_skate(slid.resample(30.0))
    assert low.passed is False and low.value > 0.2
    assert foot_skate(walk.resample(30.0)).passed


def test_a_low_swing_beside_a_still_foot_is_not_skating() -> None:
    """The real HumanML3D walk 000612 (AMASS, pushing by hand) swings each SMPL toe joint
    1-2 cm above its stance height at 1.5-2.5 m/s while the other foot stands still;
    the planted toes sit 1-3 cm apart in height, so the lower-foot test alone called
    15 % of it skating. Drifting the whole body still is skating."""
    from dataclasses import replace

    from simenv.io import humanml3d_features
    from simenv.plausibility.corrupt import foot_slide

    clip = Path(__file__).parent / "data" / "humanml3d" / "new_joint_vecs" / "000612.npy"
    motion = humanml3d_features.read(clip)
    assert foot_skate(motion).value == 0.0
    heights_only = replace(DEFAULT_THRESHOLDS, skate_stance_speed_mps=1e-9)
    assert foot_skate(motion, heights_only).passed is False
    assert foot_skate(foot_slide(motion, 1.0, seed=0)).passed is False


def test_published_gmd_ratio_is_reported(walk) -> None:
    d = foot_skate(walk).details
    assert 0.0 <= d["gmd_skating_ratio"] <= 1.0
    assert 0.0 < d["contact_fraction"] <= 1.0


def test_ankles_stand_in_for_missing_toes(walk) -> None:
    c = walk.to_canonical()
    keep = [n for n in c.skeleton.joint_names if not n.endswith("_toe")]
    sub = Motion(c.positions[:, [c.skeleton.index(n) for n in keep]], c.fps,
                 c.skeleton.subset(keep), "no-toes")
    feet, contacts = foot_contacts(sub)
    assert feet == ["left_ankle", "right_ankle"] and 0.2 < contacts.any(axis=1).mean() < 1.0
    clean = foot_skate(sub)
    assert clean.passed and clean.details["ankle_fallback"] == 1.0
    drift = np.zeros(sub.positions.shape, dtype=np.float32)
    drift[..., 1] = sub.times.astype(np.float32)[:, None]
    assert foot_skate(sub.with_positions(sub.positions + drift)).passed is False


def test_short_clips(walk) -> None:
    one, two = walk.slice(0, 1), walk.slice(0, 2)
    assert ground_penetration(one).passed is True
    assert foot_skate(one).passed is None and "2 frames" in foot_skate(one).reason
    assert floating(two).passed is None and "3 frames" in floating(two).reason
    assert foot_skate(two).available


def test_ballistic_residual_of_a_measured_jump_vs_a_hover(jumps) -> None:
    # The trunk of a real hop fits free fall; the same track without its
    # vertical motion (hovering) does not.
    r = floating(jumps)
    assert r.passed
    z = jumps.to_canonical().positions[:, 0, 2].astype(float)
    fps = jumps.fps
    assert ballistic_residual(np.full(60, 1.2), fps, 9.81) > 0.05
    assert ballistic_residual(z[:2], fps, 9.81) == 0.0


def test_a_frozen_fall_floats_while_the_other_jumps_stay_jumps(jumps) -> None:
    # Hold the body at the apex of the first hop for 0.2 s: nothing supports
    # it and it does not fall.
    c = jumps.to_canonical()
    air = np.flatnonzero(c.positions[..., 2].min(axis=1) > 0.1)
    first = air[: np.argmax(np.diff(air) > 1)]
    apex = first[0] + int(np.argmax(c.positions[first, 0, 2]))
    hold = round(0.2 * jumps.fps)
    frozen = np.repeat(jumps.positions[apex : apex + 1], hold, axis=0)
    pos = np.concatenate([jumps.positions[:apex], frozen, jumps.positions[apex:]])
    r = floating(jumps.with_positions(pos))
    assert r.passed is False
    (start, end, _), = r.violations
    assert start <= apex <= apex + hold <= end
    assert r.details["jumps"] >= 1 and r.details["worst_residual_m"] > 0.03

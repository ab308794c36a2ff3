"""Tests for simenv.data.interaction_data: real two-person recordings, windows, split by
recording, the reactive-GAN normalisation and its inverse, bad input."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import MotionError, SimenvError, SkeletonError
from simenv.core.motion import Motion
from simenv.data import interaction_data as idata

J = list(idata.INTER18_JOINTS)


@pytest.fixture(scope="module")
def recordings(shared_data: Path) -> list:
    return idata.load_recordings(shared_data)


@pytest.fixture(scope="module")
def windows(recordings: list) -> idata.InteractionWindows:
    return idata.make_windows(recordings)


def test_layout_is_the_canonical_subset_both_datasets_measure():
    skel = idata.inter18_skeleton()
    assert skel.joint_names == idata.INTER18_JOINTS and skel.num_joints == 18
    # chest is absent in NuiSI: shoulders and neck hang from the spine
    assert skel.parents[J.index("left_shoulder")] == J.index("spine")
    assert skel.parents[J.index("neck")] == J.index("spine")


def test_recordings_labels_roles_and_fps(recordings):
    names = [r.name for r in recordings]
    assert names[:3] == [f"cmu/{p}" for p in idata.CMU_PAIRS]
    assert names[3:] == [f"nuisi/Rocket/rep{k:02d}" for k in range(1, 13)]
    by = {r.name: r for r in recordings}
    assert by["cmu/18_19_walk_shake_hands"].label == "shake_hands"
    assert by["cmu/60_61_salsa_05"].label == "salsa"
    assert by["nuisi/Rocket/rep01"].label == "rocket_fist_bump"
    # CMU roles from the descriptions: subject A / lead acts
    assert by["cmu/18_19_walk_shake_hands"].actor.name == "18_01"
    assert by["cmu/60_61_salsa_10"].actor.name == "60_10_scaled"
    assert by["nuisi/Rocket/rep05"].actor.name == "Rocket_p1"
    assert "p1 is the actor" in by["nuisi/Rocket/rep05"].metadata["roles_source"]
    for r in recordings:
        assert r.fps == idata.TARGET_FPS and r.roles_known
        assert r.actor.skeleton.joint_names == idata.INTER18_JOINTS
        assert r.actor.num_frames == r.reactor.num_frames
    # 120 Hz CMU -> 25 fps keeps the duration (303 frames = 2.517 s -> 63 frames)
    assert by["cmu/18_19_walk_shake_hands"].num_frames == 63


def test_nuisi_repetitions_follow_the_annotated_lines(recordings, shared_data):
    times = idata._nuisi_line_times(shared_data / "other" / "nuisi" / "Rocket_p1.txt")
    for k, rec in enumerate(recordings[3:]):
        a, b = idata.NUISI_ROCKET_REPETITIONS[k]
        assert rec.metadata["lines"] == [a, b]
        # duration of the slice = time between the annotated lines, within one frame
        assert rec.num_frames / 25.0 == pytest.approx(times[b] - times[a], abs=0.081)
    # repetitions do not overlap in the session
    spans = [r.metadata["frames_in_session"] for r in recordings[3:]]
    assert all(s1[1] < s2[0] for s1, s2 in zip(spans, spans[1:], strict=False))


def test_windows_protocol(windows, recordings):
    assert windows.window == idata.WINDOW_FRAMES and windows.stride == idata.WINDOW_STRIDE
    assert windows.labels == ("shake_hands", "salsa", "rocket_fist_bump")
    expected = sum((r.num_frames - 40) // 5 + 1 for r in recordings)
    assert len(windows) == expected
    assert windows.actor.shape == windows.reactor.shape == (expected, 40, 18, 3)
    assert windows.actor.dtype == np.float32


def test_normalisation_puts_the_actor_at_the_origin_facing_x(windows):
    first = windows.actor[:, 0]
    np.testing.assert_allclose(first[:, J.index("pelvis"), :2], 0.0, atol=1e-5)
    across = (first[:, J.index("right_shoulder")] - first[:, J.index("left_shoulder")]
              + first[:, J.index("right_hip")] - first[:, J.index("left_hip")])
    # facing +x means "across" (left -> right) points along -y
    assert (across[:, 1] < 0).all()
    np.testing.assert_allclose(across[:, 0], 0.0, atol=1e-5)
    # heights are untouched: the pelvis stays above the floor
    assert (first[:, J.index("pelvis"), 2] > 0.5).all()


def test_inverse_places_windows_back_in_the_world(windows, recordings):
    world_a = windows.to_world(windows.actor)
    world_b = windows.to_world(windows.reactor)
    for n in (0, len(windows) // 2, len(windows) - 1):
        rec = recordings[windows.recording[n]]
        s = int(windows.start[n])
        np.testing.assert_allclose(world_a[n], rec.actor.positions[s:s + 40], atol=2e-5)
        np.testing.assert_allclose(world_b[n], rec.reactor.positions[s:s + 40], atol=2e-5)
    inter = windows.interaction(3)
    rec = recordings[windows.recording[3]]
    s = int(windows.start[3])
    np.testing.assert_allclose(inter.reactor.positions, rec.reactor.positions[s:s + 40],
                               atol=2e-5)


def test_normalise_roundtrip_on_random_frames():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(7, 5, 18, 3))
    origin = rng.normal(size=(7, 3))
    yaw = rng.uniform(-np.pi, np.pi, 7)
    back = idata.denormalise(idata.normalise(x, origin, yaw), origin, yaw)
    np.testing.assert_allclose(back, x, atol=1e-5)
    # a known case: origin (1, 2, 0), facing +y (yaw pi/2): world (1, 3, 1) is 1 m ahead
    np.testing.assert_allclose(
        idata.normalise(np.array([[[1.0, 3.0, 1.0]]]), np.array([[1.0, 2.0, 0.0]]),
                        np.array([np.pi / 2])), [[[1.0, 0.0, 1.0]]], atol=1e-6)


def test_split_is_by_recording(windows):
    split = idata.split_by_recording(windows)
    names = windows.window_recording_names
    train, test = set(names[split.train]), set(names[split.test])
    assert not train & test
    assert test == set(idata.DEFAULT_TEST_RECORDINGS)
    assert len(split.train) + len(split.test) == len(windows)
    seeded = idata.split_by_recording(windows, None, test_fraction=0.3, seed=1)
    assert not set(names[seeded.train]) & set(names[seeded.test])
    with pytest.raises(MotionError, match="not among"):
        idata.split_by_recording(windows, ["cmu/nope"])


def test_bad_input_is_a_clear_error(recordings):
    rec = recordings[3]
    a, b = rec.actor, rec.reactor
    kw = dict(label="Rocket", name="x", roles_source="test")
    with pytest.raises(MotionError, match="reactor is missing"):
        idata.make_interaction(a, None, **kw)
    with pytest.raises(MotionError, match="frames"):
        idata.make_interaction(a, b.slice(0, 50), **kw)
    with pytest.raises(MotionError, match="fps"):
        idata.make_interaction(a, replace(b, fps=30.0), **kw)
    with pytest.raises(SimenvError, match="unknown interaction label 'tango'"):
        idata.make_interaction(a, b, label="tango", name="x", roles_source="test")
    with pytest.raises(SimenvError, match="no class label"):
        idata.make_interaction(a, b, label=None, name="x", roles_source="test")
    no_pelvis = a.skeleton.subset([n for n in J if n != "pelvis"], name="nopelvis")
    m = Motion(a.positions[:, 1:], a.fps, no_pelvis, "np")
    with pytest.raises(SkeletonError, match="pelvis"):
        idata.make_interaction(m, m, **kw)
    with pytest.raises(MotionError, match="single 400-frame window"):
        idata.make_windows(recordings[:1], window=400)
    with pytest.raises(MotionError, match="unique"):
        idata.make_windows([rec, rec])


def test_load_interaction_refuses_one_person(shared_data):
    folder = shared_data / "cmu" / "two_person" / "18_19_walk_shake_hands"
    with pytest.raises(MotionError, match="one person only"):
        idata.load_interaction(folder / "18_01.bvh")
    inter = idata.load_interaction(folder)
    assert inter.label == "shake_hands" and inter.actor.name == "18_01"
    # the SBU sample has no pelvis: it cannot go on the layout
    with pytest.raises(SimenvError):
        idata.load_interaction(shared_data / "other" / "sbu_kinect_sample" / "skeleton_pos.txt",
                               label="shake_hands")

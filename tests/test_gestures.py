"""Gesture vocabulary and dataset builder, on the real gesture recordings."""

from __future__ import annotations

import csv
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import MotionError, SimenvError, SkeletonError
from simenv.core.motion import Motion
from simenv.core.skeletons import Skeleton
from simenv.data import gestures as g


@pytest.fixture(scope="module")
def clips(gesture_root: Path) -> tuple[list[g.GestureClip], g.LoadReport]:
    report = g.LoadReport()
    return g.load_gesture_clips(gesture_root, report=report), report


def _index_rows(root: Path) -> list[dict[str, str]]:
    with open(root / "index.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_vocabulary_covers_every_indexed_class(gesture_root: Path) -> None:
    rows = _index_rows(gesture_root)
    classes = {(r["dataset"], r["class_name"]) for r in rows}
    assert len(classes) == 20 + 10 + 9
    labels = {key: g.gesture_label(*key) for key in classes}
    # Every label but idle (no dataset class; cut from unlabelled frames) has a class.
    assert set(labels.values()) == set(g.GESTURE_LABELS) - {g.IDLE_LABEL}
    waves = {k for k, v in labels.items() if v == "wave"}
    assert waves == {("msr_action3d", "high arm wave"), ("msr_action3d", "horizontal arm wave"),
                     ("msr_action3d", "two hand wave"), ("utkinect", "waveHands"),
                     ("florence3d", "wave")}
    assert labels[("florence3d", "answer phone")] == "answer_phone"
    assert labels[("florence3d", "bow")] == "bow"
    assert {g.room_reaction(lab) for lab in g.GESTURE_LABELS} == {
        "greet", "hifi_down", "bow_back", "keep"}
    assert g.room_reaction("wave") == "greet" and g.room_reaction("clap") == "keep"
    assert g.room_reaction(g.IDLE_LABEL) == "keep"  # no reaction to standing still


def test_unknown_class_and_label_are_clear_errors() -> None:
    with pytest.raises(SimenvError, match="known classes of 'florence3d'.*answer phone"):
        g.gesture_label("florence3d", "juggle")
    with pytest.raises(SimenvError, match="unknown gesture label"):
        g.room_reaction("hello")


def test_loaded_clips_match_the_index(gesture_root: Path, clips) -> None:
    loaded, report = clips
    rows = _index_rows(gesture_root)
    # Every indexed sample except the all-zero MSR file and the NaN UTKinect segment.
    assert len(loaded) == len(rows) - 2
    assert any("a13_s09_e02" in s for s in report.skipped)
    assert any("carry" in s and "NaN" in s for s in report.skipped)
    per_dataset = Counter(c.dataset for c in loaded)
    assert per_dataset == {"msr_action3d": 506, "utkinect": 199, "florence3d": 215}
    counts = Counter((c.dataset, c.source_label) for c in loaded)
    expected = Counter((r["dataset"], r["class_name"]) for r in rows)
    expected[("msr_action3d", "bend")] -= 1
    expected[("utkinect", "carry")] -= 1
    assert counts == expected
    # 25 fps: an MSR clip of n frames at 15 fps spans (n - 1) / 15 s.
    clip = next(c for c in loaded if c.name == "a01_s01_e01_skeleton3D")
    assert clip.num_frames == int(np.floor((54 - 1) / 15 * 25 + 1e-9)) + 1
    assert all(c.positions.shape[1:] == (15, 3) for c in loaded)
    assert all(np.isfinite(c.positions).all() for c in loaded)


def test_windows_shapes_padding_and_cropping(clips) -> None:
    loaded, _ = clips
    w = g.make_windows(loaded)
    assert w.x.shape == (len(loaded), 75, 15, 3) and w.x.dtype == np.float32
    assert w.valid.shape == (len(loaded), 75) and w.y.shape == (len(loaded),)
    n_valid = w.valid.sum(1)
    lengths = np.array([c.num_frames for c in loaded])
    assert (n_valid == np.minimum(lengths, 75)).all()
    # Valid frames are a prefix; padded frames hold the last real pose.
    assert (w.valid == (np.arange(75) < n_valid[:, None])).all()
    i = int(np.argmin(n_valid))
    assert (w.x[i, n_valid[i]:] == w.x[i, n_valid[i] - 1]).all()
    # Centre crop of a long clip; the 1-s condition keeps the first 25 real frames.
    long_clip = next(c for c in loaded if c.num_frames > 150)
    win, valid = g.cut_window(long_clip.positions, offset=(long_clip.num_frames - 75) // 2)
    assert valid.all() and np.array_equal(win[0], long_clip.positions[
        (long_clip.num_frames - 75) // 2])
    short = g.make_windows(loaded, real_frames=g.SHORT_FRAMES)
    assert (short.valid.sum(1) == np.minimum(n_valid, 25)).all()
    rng_a, rng_b = np.random.default_rng(3), np.random.default_rng(3)
    a = g.make_windows(loaded[:40], crop="random", rng=rng_a)
    b = g.make_windows(loaded[:40], crop="random", rng=rng_b)
    assert np.array_equal(a.x, b.x)  # seeded


def test_cross_subject_split_has_no_leak(clips) -> None:
    loaded, _ = clips
    train, test = g.split_cross_subject(loaded)
    assert len(train) + len(test) == len(loaded)
    train_subjects = {c.subject_key for c in train}
    test_subjects = {c.subject_key for c in test}
    assert not train_subjects & test_subjects
    assert {c.dataset for c in train} == {c.dataset for c in test} == set(g.DATASETS)
    assert {s for s in test_subjects if s.startswith("msr")} == {
        "msr_action3d/s02", "msr_action3d/s04", "msr_action3d/s06", "msr_action3d/s08"}
    # Every labelled class is on both sides (idle comes with idle=True).
    labelled = set(g.GESTURE_LABELS) - {g.IDLE_LABEL}
    assert {c.label for c in test} == labelled == {c.label for c in train}


def test_normalisation_is_invariant_to_pose_placement(clips) -> None:
    loaded, _ = clips
    wave = next(c for c in loaded if c.label == "wave" and c.dataset == "utkinect")
    raw, valid = g.cut_window(wave.positions)
    ref = g.normalise_windows(raw, valid)
    names = list(g.GESTURE15_JOINTS)
    head = ref[: g.NORM_FRAMES]
    assert np.allclose(head[:, names.index("spine")].mean(0), 0, atol=1e-5)
    assert head[:, names.index("left_shoulder"), 1].mean() > 0.1  # left = +Y: faces +X
    # Yaw, translation and scale of the input change nothing.
    a = np.deg2rad(130.0)
    rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    moved = 1.3 * raw @ rot.T + np.array([4.0, -2.0, 0.5])
    assert np.allclose(g.normalise_windows(moved, valid), ref, atol=1e-4)
    # The size measure equals the reference size after normalisation.
    ls, rs = names.index("left_shoulder"), names.index("right_shoulder")
    width = np.linalg.norm(head[:, ls] - head[:, rs], axis=-1).mean()
    assert 0.5 * g.REFERENCE_SIZE_M < width < 2 * g.REFERENCE_SIZE_M


def test_mirror_swaps_sides(clips) -> None:
    loaded, _ = clips
    w = g.make_windows(loaded[:5])
    m = g.mirror_windows(w.x)
    names = list(g.GESTURE15_JOINTS)
    lw, rw = names.index("left_wrist"), names.index("right_wrist")
    assert np.allclose(m[..., lw, 0], w.x[..., rw, 0])
    assert np.allclose(m[..., lw, 1], -w.x[..., rw, 1])
    assert np.allclose(g.mirror_windows(m), w.x)


def test_gesture9_joint_set(gesture_root: Path) -> None:
    nine = g.load_gesture_clips(gesture_root, datasets=["florence3d"], joints="gesture9")
    assert nine[0].positions.shape[1] == 9
    w = g.make_windows(nine[:8], joints=g.gesture_skeleton("gesture9").joint_names)
    assert w.x.shape == (8, 75, 9, 3)


def test_bad_input_is_a_clear_error(tmp_path: Path, clips) -> None:
    loaded, _ = clips
    raw, valid = g.cut_window(loaded[0].positions)
    bad = raw.copy()
    bad[3, 2, 0] = np.nan
    with pytest.raises(MotionError, match="non-finite") as exc:
        g.normalise_windows(bad, valid)
    assert exc.value.frame == 3
    with pytest.raises(MotionError, match="no valid frame"):
        g.normalise_windows(raw, np.zeros(75, bool))
    with pytest.raises(MotionError, match="shape"):
        g.normalise_windows(raw[:, :9], valid)
    with pytest.raises(SimenvError, match="no gesture recording"):
        g.load_gesture_clips(tmp_path)
    with pytest.raises(SimenvError, match="unknown gesture dataset"):
        g.load_gesture_clips(tmp_path, datasets=["ntu"])
    skel = g.gesture_skeleton("gesture9")
    partial = Skeleton("partial", skel.joint_names, skel.parents,
                       {k: k for k in skel.joint_names if "elbow" not in k})
    motion = Motion(raw[:, :9], 25.0, partial)
    with pytest.raises(SkeletonError, match="left_elbow, right_elbow"):
        g.to_gesture_joints(motion, "gesture9")


# -- idle --------------------------------------------------------------------------------


def _still_pose(T: int, fps: float, jitter_m: float, seed: int = 0) -> np.ndarray:
    """(T, 15, 3) a standing gesture15 pose plus Gaussian jitter (Kinect-like noise)."""
    base = {"spine": (0, 0, 1.1), "neck": (0, 0, 1.45), "head": (0, 0, 1.6),
            "left_shoulder": (0, 0.18, 1.42), "left_elbow": (0, 0.2, 1.15),
            "left_wrist": (0, 0.2, 0.9), "right_shoulder": (0, -0.18, 1.42),
            "right_elbow": (0, -0.2, 1.15), "right_wrist": (0, -0.2, 0.9),
            "left_hip": (0, 0.1, 0.95), "left_knee": (0, 0.1, 0.5), "left_ankle": (0, 0.1, 0.08),
            "right_hip": (0, -0.1, 0.95), "right_knee": (0, -0.1, 0.5),
            "right_ankle": (0, -0.1, 0.08)}
    pose = np.array([base[j] for j in g.GESTURE15_JOINTS])
    rng = np.random.default_rng(seed)
    return np.repeat(pose[None], T, axis=0) + rng.normal(0, jitter_m, (T, 15, 3))


def test_still_mask_on_known_speeds() -> None:
    """Analytic cases: a pose with 3 mm jitter is still; a wrist sweeping side to side, or
    the whole body gliding at 0.5 m/s, is not; the threshold is in m/s (any fps)."""
    fps = 15.0
    still = _still_pose(60, fps, 0.003)
    assert g.still_mask(still, fps).all()
    wrist = g.GESTURE15_JOINTS.index("right_wrist")
    sweep = still.copy()
    t = np.arange(60) / fps
    sweep[:, wrist, 1] += 0.45 * np.sin(t / 0.3)  # 1.5 m/s peak, 0.48 m/s at the turns
    assert not g.still_mask(sweep, fps)[10:50].any()
    glide = still + (0.5 * t)[:, None, None] * np.array([1.0, 0.0, 0.0])
    assert not g.still_mask(glide, fps).any()
    slow = still + (0.1 * t)[:, None, None] * np.array([1.0, 0.0, 0.0])  # 0.1 m/s drift
    assert g.still_mask(slow, fps).all()
    # The same motion sampled at 25 fps gives the same verdicts.
    t25 = np.arange(100) / 25.0
    glide25 = _still_pose(100, 25.0, 0.003) + (0.5 * t25)[:, None, None] * np.array(
        [1.0, 0.0, 0.0])
    assert not g.still_mask(glide25, 25.0).any()
    with pytest.raises(MotionError, match="positions"):
        g.still_mask(still[:1], fps)


@pytest.fixture(scope="module")
def idle_clips(gesture_root: Path) -> list[g.GestureClip]:
    clips = g.load_gesture_clips(gesture_root, idle=True)
    return [c for c in clips if c.label == g.IDLE_LABEL]


def test_idle_clips_come_from_unlabelled_still_frames(gesture_root: Path, idle_clips) -> None:
    """Every UTKinect idle range of a training session lies outside its labelled segments
    and is still throughout; MSR idle clips are a clip's lead-in or lead-out; lengths are
    within the documented bounds; both datasets give idle clips on both sides of the
    split, and Florence (clips of 0.4-1.8 s, moving from the first frame) almost none."""
    from simenv.io import utkinect

    session = utkinect.read(gesture_root / "utkinect" / "joints" / "joints_s03_e01.txt")
    labelled = g._session_labelled(session)
    ranges = g.idle_ranges(session, labelled=labelled)
    assert ranges
    still = g.still_mask(g.to_gesture_joints(session), session.fps)
    for a, b in ranges:
        assert not labelled[a:b].any() and still[a:b].all()
        assert g.IDLE_SESSION_MIN_S * session.fps <= b - a <= g.IDLE_MAX_S * session.fps
    kinds = Counter((c.dataset, c.source_label) for c in idle_clips)
    assert kinds[("utkinect", "unlabelled still")] > 0
    assert kinds[("msr_action3d", "still lead-in/out")] > 0
    assert kinds[("florence3d", "still lead-in/out")] <= 2
    train, test = g.split_cross_subject(idle_clips)
    assert train and test and all(c.subject % 2 == 1 for c in train)
    for c in idle_clips:
        assert c.source is not None and c.name.rsplit("_idle", 1)[0] == c.source.name
        assert c.num_frames <= g.IDLE_MAX_S * g.GESTURE_FPS + 1
    msr = next(c for c in idle_clips if c.dataset == "msr_action3d")
    from simenv.io import msr_action3d

    whole = msr_action3d.read(gesture_root / "msr_action3d" / f"{msr.source.name}.txt")
    n = msr.source.num_frames
    at_start = np.array_equal(msr.source.positions, whole.positions[:n])
    at_end = np.array_equal(msr.source.positions, whole.positions[-n:])
    assert at_start or at_end
    # The UTKinect session with a missing (NaN) segment: its gap is excluded too.
    s10 = utkinect.read(gesture_root / "utkinect" / "joints" / "joints_s10_e02.txt")
    segs = sorted(s10.metadata["segments"], key=lambda d: int(d["start"]))
    pick = next(d for d in segs if d["label"].strip() == "pickUp")
    throw = next(d for d in segs if d["label"].strip() == "throw")
    assert g._session_labelled(s10)[int(pick["end"]):int(throw["start"])].all()

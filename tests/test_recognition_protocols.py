"""Protocols of the recogniser: folds, conditions, the room protocol end to end (short)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import SimenvError, SkeletonError
from simenv.data.gestures import (
    GESTURE15_JOINTS,
    load_gesture_clips,
    split_subject_folds,
    subject_fold,
)
from simenv.learning.recognition import (
    RecognitionConfig,
    clip_skeleton,
    logits_of,
    train_recogniser,
)
from simenv.learning.recognition_protocols import (
    benchmark_folds,
    classification_scores,
    condition_windows,
    mirror_clip,
    native_clips,
    room_descriptors,
    room_nearest_neighbour,
    run_benchmark,
    run_room_protocol,
    whole_windows,
    window_mirror_complete,
)
from simenv.perception.train_recogniser import benchmark_table


@pytest.fixture(scope="module")
def utk(gesture_root: Path):
    return load_gesture_clips(gesture_root, datasets=("utkinect",), idle=True)


def test_subject_folds_are_disjoint_and_cover_every_clip(utk):
    folds = split_subject_folds(utk)
    assert len(folds) == 5
    tested = []
    for train, test in folds:
        assert not {c.subject_key for c in train} & {c.subject_key for c in test}
        tested += [c.name for c in test]
    assert sorted(tested) == sorted(c.name for c in utk)
    assert subject_fold("msr_action3d/s06") == subject_fold("utkinect/s01") == 0
    with pytest.raises(SimenvError, match="subject key"):
        subject_fold("s06")
    with pytest.raises(SimenvError, match="folds"):
        split_subject_folds(utk, folds=1)


def test_benchmark_folds_follow_each_protocol(utk):
    msr_like = benchmark_folds("msr_action3d", utk)
    assert len(msr_like) == 1 and all(c.subject % 2 for c in msr_like[0][1])
    loso = benchmark_folds("utkinect", utk)
    assert len(loso) == 10 and all({c.subject for c in test} == {int(name[1:])}
                                   for name, _, test in loso)


def test_msr_action_sets_are_li_et_al_s_eight_actions_each_cross_subject(gesture_root: Path):
    msr = load_gesture_clips(gesture_root, datasets=("msr_action3d",))
    folds = benchmark_folds("msr_action3d_sets", msr)
    assert [name for name, _, _ in folds] == ["AS1", "AS2", "AS3"]
    for _, train, test in folds:
        assert len({c.source_label for c in train}) == 8
        assert {c.source_label for c in test} <= {c.source_label for c in train}
        assert all(c.subject % 2 == 1 for c in train) and all(c.subject % 2 == 0 for c in test)
    as1 = {c.source_label for c in folds[0][1]}
    assert {"horizontal arm wave", "hand clap", "bend"} <= as1 and "high arm wave" not in as1
    assert "side-boxing" in {c.source_label for c in folds[1][1]}
    # High throw, tennis serve and pick up & throw are in two sets (AS1 and AS3).
    assert len([f for f in folds if "tennis serve" in {c.source_label for c in f[1]}]) == 2


def test_conditions_share_the_real_second(utk):
    clips = [c for c in utk if c.num_frames >= 40][:12]
    conds = condition_windows(clips, lambda h: np.repeat(h[:, -1:] + 0.05, 50, axis=1))
    assert set(conds) == {"real_3s", "real_1s", "real_1s_pred_2s", "real_1s_pred_2s_zv",
                          "real_1s_pred_2s_cv"}
    x1, v1 = conds["real_1s"]
    assert (v1.sum(1) == 25).all()
    for name in ("real_1s_pred_2s", "real_1s_pred_2s_zv", "real_1s_pred_2s_cv"):
        x, v = conds[name]
        np.testing.assert_allclose(x[:, :25], x1[:, :25])
        assert v.all()
    zv = conds["real_1s_pred_2s_zv"][0]
    np.testing.assert_allclose(zv[:, 60], zv[:, 24])
    x, valid = whole_windows(clips)
    assert valid.sum(1).tolist() == [c.num_frames for c in clips]


def test_scores():
    s = classification_scores(np.array([0, 0, 1, 2]), np.array([0, 1, 1, 1]), ["a", "b", "c"],
                              ["x", "x", "y", "y"])
    assert s["accuracy"] == 0.5 and s["balanced_accuracy"] == pytest.approx(0.5)
    assert s["per_dataset_accuracy"] == {"x": 0.5, "y": 0.5}
    assert s["confusion"][2] == [0, 1, 0]


def test_room_protocol_runs_every_fold_on_unseen_subjects(utk):
    """Two folds, two epochs, a thin network: every clip is tested once by a network that
    never saw its subject; the temperature is cross-fitted; the forecast condition exists
    when a forecaster is given."""
    config = RecognitionConfig(epochs=2, width=16, forecast_prob=0.5)
    out = run_room_protocol(utk, config, folds=2, progress=False,
                            forecaster_for_fold=lambda k: (lambda h: np.repeat(h[:, -1:], 50, 1)))
    assert out["clips"] == len(utk)
    assert {"real_3s", "real_1s", "real_1s_pred_2s"} <= set(out["conditions"])
    for row in out["folds"]:
        assert 0.25 <= row["temperature"] <= 8.0
    oof = out["oof"]
    assert len(oof["y"]) == len(utk) and sorted(oof["names"]) == sorted(c.name for c in utk)
    assert 0.0 <= out["conditions"]["real_3s"]["accuracy"] <= 1.0


def test_benchmark_rejects_unknown_datasets(gesture_root: Path):
    with pytest.raises(SimenvError, match="unknown benchmark"):
        run_benchmark("ntu", gesture_root)
    with pytest.raises(SimenvError, match="unknown joint set"):
        run_benchmark("msr_action3d", gesture_root, joints="kinect")  # type: ignore[arg-type]
    with pytest.raises(SimenvError, match="unknown distance"):
        run_benchmark("utkinect", gesture_root, neighbour="cosine")  # type: ignore[arg-type]


def test_an_ensemble_benchmark_reports_its_first_networks_alone(gesture_root: Path):
    # A thin network: the assertions are about which networks are reported, not accuracy.
    config = RecognitionConfig(partial_prob=0.0, max_frames=75, epochs=1, width=16)
    pair = run_benchmark("msr_action3d", gesture_root, config, members=2, progress=False)
    one = run_benchmark("msr_action3d", gesture_root, config, members=1, progress=False)
    assert one["smaller_ensembles"] == []
    (first,) = pair["smaller_ensembles"]
    assert first["members"] == 1 and pair["members"] == 2
    # The pair's first network is the single run's network (same seed), bit for bit.
    assert first["scores"] == one["scores"]
    assert first["mean_fold_accuracy"] == one["mean_fold_accuracy"]
    assert 0 < first["train_cpu_s"] < pair["train_cpu_s"]
    assert [f["fold"] for f in first["folds"]] == [f["fold"] for f in pair["folds"]]
    # The same network judging each test clip and its mirror image (test-time augmentation).
    both = run_benchmark("msr_action3d", gesture_root, config, mirror_test=True,
                         progress=False)
    assert both["mirror_test"] and not one["mirror_test"]
    assert both["train_cpu_s"] > 0 and both["scores"]["n"] == one["scores"]["n"]
    assert "test clip + its mirror" in benchmark_table([both])


def test_room_nearest_neighbour_keeps_subjects_apart(utk):
    r = room_nearest_neighbour(utk, "euclidean", progress=False)
    assert r["room"] and r["clips"] == len(utk) == sum(f["clips"] for f in r["folds"])
    # The folds of the room protocol: every subject tested once, by a fold without it.
    tested = [s for f in r["folds"] for s in f["test_subjects"]]
    assert sorted(tested) == sorted({c.subject_key for c in utk})
    for name in ("real_3s", "real_1s"):
        assert 0.3 < r["conditions"][name]["accuracy"] < 1.0  # chance: about 0.1
    with pytest.raises(SimenvError, match="unknown distance"):
        room_nearest_neighbour(utk, "cosine")  # type: ignore[arg-type]


def test_room_descriptors_choose_on_training_subjects_only(utk):
    # Two folds (a documented option): the same per-fold choice on training subjects as
    # the default five, with fewer fits.
    r = room_descriptors(utk, lie_group=True, folds=2, progress=False)
    assert len(r["folds"]) == 2
    assert r["method"] == "covariance and Lie-group descriptors"
    assert r["descriptors"] == ["covariance", "lie group"]
    tested = [s for f in r["folds"] for s in f["test_subjects"]]
    assert sorted(tested) == sorted({c.subject_key for c in utk})
    for fold in r["folds"]:
        for name in ("real_3s", "real_1s"):
            chosen = fold["chosen"][name]
            assert chosen["variant"].startswith(("gesture15", "lie:gesture15"))
            assert 0.0 < chosen["held_out_accuracy"] <= 1.0
    for name in ("real_3s", "real_1s"):
        assert 0.3 < r["conditions"][name]["accuracy"] < 1.0  # chance: about 0.1


def test_nearest_neighbour_baseline_runs_the_benchmark_protocol(gesture_root: Path):
    r = run_benchmark("utkinect", gesture_root, neighbour="euclidean", progress=False)
    assert r["method"] == "nearest neighbour (euclidean)" and r["mirror"] == "none"
    assert [f["fold"] for f in r["folds"]] == [f"s{s:02d}" for s in range(1, 11)]
    assert sum(f["n"] for f in r["folds"]) == r["clips"] == r["scores"]["n"]
    # Ten classes: chance is 10 %; unseen people's actions are far above it, not perfect.
    assert 0.5 < r["scores"]["accuracy"] < 1.0


def test_native_msr_clips_carry_the_20_kinect_joints(gesture_root: Path):
    """MSR on its own skeleton: 20 joints renamed to canonical keypoints, the gesture15
    joints equal to the gesture clips', the clip mirror equal to the training mirror of
    normalised windows, and a thin network trains and classifies on them."""
    if not (gesture_root / "msr_action3d").is_dir():
        pytest.skip("MSR Action3D not in the corpus")
    gesture = load_gesture_clips(gesture_root, datasets=("msr_action3d",))[:24]
    clips = native_clips(gesture)
    skel = clip_skeleton(clips)
    assert len(skel.joint_names) == 20 and skel.parents[skel.joint_names.index("pelvis")] == -1
    assert {"left_hand", "right_toe", "pelvis"} <= set(skel.joint_names)
    idx = [skel.joint_names.index(j) for j in GESTURE15_JOINTS]
    for g, n in zip(gesture, clips, strict=True):
        np.testing.assert_array_equal(n.positions[:, idx], g.positions)
    assert clip_skeleton(gesture).name == "gesture15"  # the default is unchanged
    with pytest.raises(SkeletonError, match="carry"):
        clip_skeleton(clips[:2] + gesture[:2])
    # kinect_noise's mirror does not swap the Kinect hands and feet: the benchmark
    # mirrors clips, which normalise to the same image.
    assert not window_mirror_complete(skel)
    x, valid = whole_windows(clips)
    xm, _ = whole_windows([mirror_clip(c, skel) for c in clips])
    swap = [skel.joint_names.index(j.replace("left_", "@").replace("right_", "left_")
                                   .replace("@", "right_")) for j in skel.joint_names]
    ideal = x[:, :, swap] * np.array([1, -1, 1], np.float32)
    np.testing.assert_allclose(xm[valid], ideal[valid], atol=1e-4)
    labels = sorted({c.source_label for c in clips})
    model, _ = train_recogniser(clips, labels, lambda c: c.source_label,
                                RecognitionConfig(epochs=1, width=8, mirror=False),
                                progress=False)
    assert model.config.joint_names == skel.joint_names
    assert logits_of(model, x, valid).shape == (len(clips), len(labels))

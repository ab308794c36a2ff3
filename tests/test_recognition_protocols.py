"""Protocols of the recogniser: folds, conditions, the room protocol end to end (short)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simenv.errors import SimenvError
from simenv.gestures import load_gesture_clips, split_subject_folds, subject_fold
from simenv.recognition import RecognitionConfig
from simenv.recognition_protocols import (
    benchmark_folds,
    classification_scores,
    condition_windows,
    run_benchmark,
    run_room_protocol,
    whole_windows,
)


@pytest.fixture(scope="module")
def root(shared_data: Path) -> Path:
    root = shared_data / "gestures"
    if not (root / "utkinect").is_dir():
        pytest.skip(f"gesture corpus not found at {root}")
    return root


@pytest.fixture(scope="module")
def utk(root: Path):
    return load_gesture_clips(root, datasets=("utkinect",), idle=True)


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


def test_benchmark_rejects_unknown_datasets(root: Path):
    with pytest.raises(SimenvError, match="unknown benchmark"):
        run_benchmark("ntu", root)

"""The recogniser's command line: eval on any labelled folder (--json), errors, tables."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import simenv.models
from simenv.cli import main as cli
from simenv.perception.train_recogniser import benchmark_table

shipped = pytest.mark.skipif(
    not {"gesture-tcn-ensemble", "predictor-gesture-25-50"} <= set(simenv.models.available()),
    reason="shipped gesture-tcn-ensemble / predictor-gesture-25-50 absent")


@shipped
def test_eval_classifier_json_on_a_folder_of_msr_files(tmp_path: Path, capsys,
                                                       shared_data: Path) -> None:
    """A folder holding only some MSR Action3D files (labels from their names) gives one
    JSON object with the three conditions."""
    src = shared_data / "gestures" / "msr_action3d"
    files = sorted(src.glob("a0[1-3]_s02_e0*_skeleton3D.txt"))
    if not files:
        pytest.skip(f"MSR Action3D not found under {src}")
    folder = tmp_path / "mine"
    folder.mkdir()
    for f in files:
        (folder / f.name).symlink_to(f)
    assert cli.main(["eval", "classifier", "--data", str(folder), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["clips"] == len(files)
    assert set(out["conditions"]) == {"real_3s", "real_1s", "real_1s_pred_2s"}
    # the default is the room's recogniser; one network is asked for by name
    assert cli.main(["eval", "classifier", "gesture-tcn", "--data", str(folder), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["clips"] == len(files)
    for v in out["conditions"].values():
        assert set(v) == {"accuracy", "balanced_accuracy"} and 0 <= v["accuracy"] <= 1


@shipped
def test_eval_classifier_names_a_folder_without_recordings(tmp_path: Path, capsys) -> None:
    (tmp_path / "notes.txt").write_text("nothing here")
    assert cli.main(["eval", "classifier", "--data", str(tmp_path), "--json"]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path) in err and "skeleton3D.txt" in err


def test_benchmark_table_lists_published_figures() -> None:
    row = {"dataset": "florence3d", "protocol": "leave-one-subject-out", "classes": list("ab"),
           "clips": 10, "scores": {"accuracy": 0.9}, "mean_fold_accuracy": 0.91,
           "published": {"Lie group": 90.88}, "train_cpu_s": 12.0, "members": 1,
           "whole_sequences": True, "config": {"max_frames": 43}}
    table = benchmark_table([row])
    assert "| florence3d |" in table and "90.0 %" in table
    assert "Lie group (Vemulapalli et al. 2014) 90.9 %" in table  # today's figures
    assert "whole sequences, 1 network(s)" in table
    old = benchmark_table([{**row, "dataset": "msr_action3d",
                            "published": {"Lie group": 89.48, "HBRNN": 94.49}}])
    assert "HBRNN" not in old  # its 94.49 % is the action-set mean, not a 20-class figure
    gone = benchmark_table([{**row, "dataset": "ntu"}])
    assert "Lie group 90.9 %" in gone
    sets = benchmark_table([{**row, "dataset": "msr_action3d_sets", "classes": list("abcd"),
                             "folds": [{"fold": "AS1", "accuracy": 0.8, "classes": 2},
                                       {"fold": "AS2", "accuracy": 0.9, "classes": 2}]}])
    assert "| 2 per fold (4 in all) |" in sets and "(AS1 80.0, AS2 90.0)" in sets


def test_room_baseline_needs_a_distance(tmp_path: Path, capsys, gesture_root: Path) -> None:
    out = tmp_path / "bench"
    args = ["eval", "classifier", "--benchmark", "room", "--data", str(gesture_root),
            "--out", str(out)]
    assert cli.main(args) == 2
    assert "give --neighbour" in capsys.readouterr().err
    assert not out.exists()

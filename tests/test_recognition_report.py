"""``simenv eval classifier`` shows which gestures fail: per-class accuracy on the terminal,
confusion matrices as JSON and PNG, on real MSR Action3D recordings of the shared corpus."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import simenv.models
from simenv.cli import main as cli
from simenv.data.gestures import GESTURE_LABELS

pytestmark = pytest.mark.skipif(
    not {"gesture-tcn-ensemble", "predictor-gesture-25-50"} <= set(simenv.models.available()),
    reason="shipped gesture-tcn-ensemble / predictor-gesture-25-50 absent")


def test_eval_classifier_per_class_and_confusion(gesture_root: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "mine"
    folder.mkdir()
    files = sorted((gesture_root / "msr_action3d").glob("a0[15]_s0[24]_e01_skeleton3D.txt")) \
        + sorted((gesture_root / "msr_action3d").glob("a10_s0[24]_e01_skeleton3D.txt"))
    for f in files:
        (folder / f.name).symlink_to(f)
    out = tmp_path / "out"
    assert cli.main(["eval", "classifier", "--data", str(folder), "--predictor", "none",
                     "--out", str(out)]) == 0
    text = capsys.readouterr().out
    saved = json.loads((out / "confusion.json").read_text())
    assert saved["labels"] == list(GESTURE_LABELS)
    assert set(saved["conditions"]) == {"real_3s", "real_1s"}
    for cond in saved["conditions"].values():
        confusion = np.array(cond["confusion"])
        assert confusion.shape == (len(GESTURE_LABELS),) * 2
        assert confusion.sum() == len(files)
        # wave (a01), other (a05: forward punch), clap (a10).
        assert {k for k, v in zip(GESTURE_LABELS, confusion.sum(1), strict=True) if v} == {
            "wave", "other", "clap"}
        assert np.trace(confusion) / len(files) == pytest.approx(cond["accuracy"], abs=1e-4)
    assert (out / "confusion.png").stat().st_size > 0
    table = text[text.index("per class"):].splitlines()
    rows = {line.split()[0]: line.split() for line in table[2:] if line.strip()
            and not line.startswith("confusion matrices")}
    assert set(rows) == {"wave", "other", "clap", "all"}
    support = np.array(saved["conditions"]["real_3s"]["confusion"]).sum(1)
    for label in ("wave", "other", "clap"):
        assert int(rows[label][1]) == support[GESTURE_LABELS.index(label)]
        assert float(rows[label][2]) == pytest.approx(
            saved["conditions"]["real_3s"]["per_class_recall"][label], abs=1e-3)

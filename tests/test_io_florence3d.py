"""Florence 3D Actions reader (skeletal_data.mat)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from simenv.core.errors import FormatError
from simenv.io import florence3d

MAT = "gestures/florence3d/skeletal_data.mat"


def test_all_215_videos_with_labels(shared_data: Path) -> None:
    with open(shared_data / "gestures" / "index.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["dataset"] == "florence3d"]
    motions = florence3d.read(shared_data / MAT)
    assert len(motions) == len(rows) == 215
    assert sum(m.num_frames for m in motions) == 4016
    for m, r in zip(motions, rows, strict=True):
        assert m.num_frames == int(r["frames"])
        assert m.metadata["label"] == r["class_name"]
        assert m.metadata["class_id"] == int(r["class_id"])
        assert m.metadata["subject"] == int(r["subject"])
        assert m.metadata["repetition"] == int(r["repetition"])
        assert m.fps == 20.0
    heights = [np.median(m.joint("Head")[:, 2] - m.positions[:, [11, 14], 2].min(1))
               for m in motions if m.metadata["label"] not in ("sit down", "stand up")]
    widths = [np.median(np.linalg.norm(m.joint("LeftShoulder") - m.joint("RightShoulder"),
                                       axis=1)) for m in motions]
    # SOURCES.md: median head-to-ankle 1.49 m, shoulder width 0.32 m.
    assert np.median(heights) == pytest.approx(1.49, abs=0.05)
    assert np.median(widths) == pytest.approx(0.32, abs=0.02)
    # One floor per subject: ankles near their 7 cm clearance, head up.
    ankles = np.concatenate([m.positions[:, [11, 14], 2].min(1) for m in motions])
    assert abs(np.median(ankles) - 0.07) < 0.04
    head_up = np.concatenate([m.joint("Head")[:, 2] > m.joint("Spine")[:, 2] for m in motions])
    assert head_up.mean() > 0.99


def test_rows_are_x_z_y(shared_data: Path) -> None:
    """Height (the .mat's third row) becomes world Z: a waving right wrist
    rises well above the shoulder."""
    m = florence3d.read(shared_data / MAT)[0]
    assert m.metadata["label"] == "wave"
    assert (m.joint("RightWrist")[:, 2] > m.joint("RightShoulder")[:, 2]).any()
    per_video = florence3d.read(shared_data / MAT, level="video")[0]
    assert per_video.metadata["camera_frame"]["level"] == "video"


def test_sniff(shared_data: Path) -> None:
    f = shared_data / MAT
    assert florence3d.sniff(f, f.read_bytes()[:4096])
    names = shared_data / "gestures/florence3d/action_names.mat"
    assert not florence3d.sniff(names, names.read_bytes()[:4096])


def test_bad_input(shared_data: Path, tmp_path: Path) -> None:
    empty = tmp_path / "skeletal_data.mat"
    scipy.io.savemat(empty, {"other": np.zeros(3)})
    with pytest.raises(FormatError, match="no 'skeletal_data'"):
        florence3d.read(empty)
    shape = tmp_path / "shape.mat"
    cell = np.empty((1,), dtype=object)
    cell[0] = {"original_skeletal_data": np.zeros((3, 14, 5)), "subject": 1, "action": 1}
    scipy.io.savemat(shape, {"skeletal_data": cell})
    with pytest.raises(FormatError, match=r"expected \(3, 15, T>=1\)") as err:
        florence3d.read(shape)
    assert err.value.field == "skeletal_data[0]"
    broken = tmp_path / "broken.mat"
    broken.write_bytes((shared_data / MAT).read_bytes()[:3000])
    with pytest.raises(FormatError, match="cannot read MATLAB file"):
        florence3d.read(broken)

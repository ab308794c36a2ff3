"""UTKinect-Action3D sessions: segments, duplicates, timing, bad input."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import FormatError
from simenv.io import utkinect

UTK = "gestures/utkinect/joints"


def _index(root: Path) -> list[dict[str, str]]:
    with open(root / "gestures" / "index.csv") as f:
        return [r for r in csv.DictReader(f) if r["dataset"] == "utkinect"]


@pytest.mark.parametrize("timing", ["resample", "rows"])
def test_every_session_and_segment(shared_data: Path, timing: str) -> None:
    index = _index(shared_data)
    files = sorted((shared_data / UTK).glob("joints_*.txt"))
    assert len(files) == 20
    n_segments = 0
    for f in files:
        raw = np.loadtxt(f)
        frames = raw[:, 0]
        m = utkinect.read(f, timing=timing)
        unique = np.unique(frames)
        dups = len(frames) - len(unique)
        assert any(f"dropped {dups} rows" in r for r in m.metadata["repairs"]) == (dups > 0)
        assert m.metadata["frame_numbers"] == unique.astype(int).tolist()
        if timing == "rows":
            assert m.num_frames == len(unique)
            # The kept row of each frame number is the first one of the file.
            first = np.array([np.flatnonzero(frames == u)[0] for u in unique[:50]])
            cam_rows = raw[first, 1:].reshape(-1, 20, 3)
            # Rigid transform: head-to-right-hand distances are those of the first rows.
            dist = np.linalg.norm(m.positions[:50, 3] - m.positions[:50, 11], axis=1)
            np.testing.assert_allclose(dist, np.linalg.norm(cam_rows[:, 3] - cam_rows[:, 11],
                                                            axis=1), atol=1e-5)
        else:
            assert m.fps == 15.0
            assert m.duration == pytest.approx((unique[-1] - unique[0]) / 60.0, abs=1 / 15)
        rows = [r for r in index if r["file"].endswith(f.name)]
        segs = m.metadata["segments"]
        expected = [r for r in rows if r["start_frame"] != "NaN"]
        assert [s["label"] for s in segs] == [r["class_name"] for r in expected]
        for s, r in zip(segs, expected, strict=True):
            assert (s["start_frame"], s["end_frame"]) == (int(r["start_frame"]),
                                                          int(r["end_frame"]))
            assert 0 <= s["start"] < s["end"] <= m.num_frames
            if timing == "rows":
                fn = np.array(m.metadata["frame_numbers"])
                inside = fn[s["start"]:s["end"]]
                assert inside.min() >= s["start_frame"] and inside.max() <= s["end_frame"]
                # index.csv counts rows in range *including* duplicates
                assert len(inside) <= int(r["frames"])
            else:
                t0 = (s["start_frame"] - unique[0]) / 60.0
                assert s["start"] / 15.0 == pytest.approx(t0, abs=1 / 15 + 1e-9)
        n_segments += len(segs)
        if f.name == "joints_s10_e02.txt":
            assert any("NaN" in q for q in m.metadata["quirks"])
    assert n_segments == 199


def test_walk_speed_supports_the_60hz_clock(shared_data: Path) -> None:
    speeds = []
    for f in sorted((shared_data / UTK).glob("joints_*.txt")):
        m = utkinect.read(f)
        seg = next(s for s in m.metadata["segments"] if s["label"] == "walk")
        pelvis = m.joint("HipCenter")[seg["start"]:seg["end"], :2]
        speeds.append(np.median(np.linalg.norm(np.diff(pelvis, axis=0), axis=1)) * m.fps)
    # A 30 Hz clock would halve these to ~0.3 m/s, too slow for walking.
    assert 0.45 < np.median(speeds) < 1.2


def test_label_override_and_no_labels(shared_data: Path) -> None:
    f = shared_data / UTK / "joints_s01_e02.txt"
    mod = utkinect.read(f, labels=shared_data / UTK / "actionLabel_modified.txt")
    walk = next(s for s in mod.metadata["segments"] if s["label"] == "walk")
    assert walk["end_frame"] == 270  # the corrected bound (original file: 192)
    assert utkinect.read(f, labels=False).metadata["segments"] == []
    with pytest.raises(FormatError, match="not found"):
        utkinect.read(f, labels=shared_data / UTK / "missing.txt")


def test_sniff(shared_data: Path) -> None:
    f = shared_data / UTK / "joints_s01_e01.txt"
    assert utkinect.sniff(f, f.read_bytes()[:4096])
    g = shared_data / "gestures/msr_action3d/a01_s01_e01_skeleton3D.txt"
    assert not utkinect.sniff(g, g.read_bytes()[:4096])


def _mutated(shared_data: Path, tmp_path: Path, edit) -> Path:
    lines = (shared_data / UTK / "joints_s01_e01.txt").read_text().splitlines()[:60]
    out = tmp_path / "joints_s01_e01.txt"
    out.write_text("\n".join(edit(lines)) + "\n")
    return out


@pytest.mark.parametrize("edit, message, line", [
    (lambda ls: ls[:10] + [" ".join(ls[10].split()[:60])] + ls[11:], "expected 61 values", 11),
    (lambda ls: ls[:4] + ["5 " + " ".join(ls[4].split()[1:])] + ls[5:], "decreases", 5),
    (lambda ls: ls[:3] + ["250.5 " + " ".join(ls[3].split()[1:])] + ls[4:], "integer", 4),
    (lambda ls: ls[:2] + [ls[2].replace(ls[2].split()[7], "x1", 1)] + ls[3:],
     "expected a finite number", 3),
])
def test_bad_input(shared_data: Path, tmp_path: Path, edit, message: str, line: int) -> None:
    bad = _mutated(shared_data, tmp_path, edit)
    with pytest.raises(FormatError, match=message) as err:
        utkinect.read(bad, labels=False)
    assert err.value.line == line and err.value.source == str(bad)


def test_bad_label_file(shared_data: Path, tmp_path: Path) -> None:
    labels = tmp_path / "actionLabel.txt"
    labels.write_text("s01_e01\nwalk: 252\n")
    with pytest.raises(FormatError, match="label: start end") as err:
        utkinect.read(shared_data / UTK / "joints_s01_e01.txt", labels=labels)
    assert err.value.line == 2

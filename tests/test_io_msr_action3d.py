"""MSR Action3D reader on every real file of the corpus."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import FormatError, MotionError
from simenv.io import msr_action3d, nuisi, sbu, utkinect

MSR = "gestures/msr_action3d"


def _index(root: Path) -> dict[str, dict[str, str]]:
    with open(root / "gestures" / "index.csv") as f:
        return {r["file"]: r for r in csv.DictReader(f) if r["dataset"] == "msr_action3d"}


def test_every_file_loads_with_labels(shared_data: Path) -> None:
    index = _index(shared_data)
    files = sorted((shared_data / MSR).glob("a*_skeleton3D.txt"))
    assert len(files) == 507
    heights, widths, loaded = [], [], 0
    for f in files:
        row = index[f"msr_action3d/{f.name}"]
        raw = np.loadtxt(f).reshape(-1, 20, 4)
        zero = (raw == 0).all(axis=(1, 2))
        if zero.all():
            with pytest.raises(MotionError, match="all 38 frames are zero"):
                msr_action3d.read(f)
            continue
        m = msr_action3d.read(f)
        loaded += 1
        tracked = np.flatnonzero(~zero)
        assert int(row["frames"]) == len(raw)
        assert m.num_frames == tracked[-1] - tracked[0] + 1
        assert m.metadata["trimmed"] == [tracked[0], len(raw) - 1 - tracked[-1]]
        assert m.fps == 15.0
        assert m.metadata["label"] == row["class_name"]
        assert m.metadata["subject"] == int(row["subject"])
        assert m.metadata["repetition"] == int(row["repetition"])
        assert m.metadata["dropout_frames"] == int(zero.sum())
        assert bool(m.metadata["repairs"]) == bool(zero.any())
        heights.append(np.median(m.joint("Head")[:, 2] - m.positions[:, [14, 18], 2].min(1)))
        widths.append(np.median(np.linalg.norm(m.joint("ShoulderLeft")
                                               - m.joint("ShoulderRight"), axis=1)))
    assert loaded == 506
    # SOURCES.md: median head-to-lowest-foot 1.59 m, shoulder width 0.36 m.
    assert np.median(heights) == pytest.approx(1.59, abs=0.06)
    assert np.median(widths) == pytest.approx(0.36, abs=0.03)


def test_joint_reordering_matches_the_file(shared_data: Path) -> None:
    f = shared_data / MSR / "a01_s01_e01_skeleton3D.txt"
    raw = np.loadtxt(f).reshape(-1, 20, 4)[..., :3]
    m = msr_action3d.read(f)
    rot = np.array(m.metadata["camera_frame"]["rotation"])
    cam = (m.positions - [0, 0, m.metadata["camera_frame"]["sensor_height_m"]]) @ rot
    # MSR line 13 is the right hand, line 20 the head (1-based).
    np.testing.assert_allclose(cam[:, m.skeleton.index("HandRight")], raw[:, 12], atol=2e-3)
    np.testing.assert_allclose(cam[:, m.skeleton.index("Head")], raw[:, 19], atol=2e-3)
    # High arm wave is done with the right hand.
    travel = {s: np.linalg.norm(np.ptp(m.joint(f"Hand{s}"), axis=0)) for s in ("Left", "Right")}
    assert travel["Right"] > 3 * travel["Left"]


def test_dropouts_are_interpolated(shared_data: Path) -> None:
    edge = msr_action3d.read(shared_data / MSR / "a13_s09_e03_skeleton3D.txt")
    assert edge.num_frames == 936 - 740  # dropouts only before/after: trimmed, not frozen
    f = shared_data / MSR / "a20_s02_e02_skeleton3D.txt"
    raw = np.loadtxt(f).reshape(-1, 20, 4)
    zero = (raw == 0).all(axis=(1, 2))
    assert zero.sum() == 29
    m = msr_action3d.read(f)
    assert m.num_frames == len(raw)
    assert any("interpolated" in r for r in m.metadata["repairs"])
    # Filled frames are convex combinations of the tracked neighbours.
    good = np.flatnonzero(~zero)
    t = int(np.flatnonzero(zero & (np.arange(len(zero)) > good[0]))[0])
    lo, hi = good[good < t].max(), good[good > t].min()
    w = (t - lo) / (hi - lo)
    np.testing.assert_allclose(m.positions[t], (1 - w) * m.positions[lo] + w * m.positions[hi],
                               atol=1e-5)


def test_sniff(shared_data: Path) -> None:
    f = shared_data / MSR / "a02_s01_e01_skeleton3D.txt"
    assert msr_action3d.sniff(f, f.read_bytes()[:4096])
    for other in (shared_data / "gestures/utkinect/joints/joints_s01_e01.txt",
                  shared_data / "other/sbu_kinect_sample/skeleton_pos.txt",
                  shared_data / "other/nuisi/Rocket_p1.txt"):
        head = other.read_bytes()[:4096]
        assert not msr_action3d.sniff(other, head)
        assert sum(mod.sniff(other, head) for mod in (utkinect, sbu, nuisi)) == 1


@pytest.mark.parametrize("mutate, message, line", [
    (lambda ls: ls[:-1], "not a multiple of 20", 799),
    (lambda ls: ls[:5] + ["0.1 0.2 0.3"] + ls[6:], "expected 4 values", 6),
    (lambda ls: ls[:7] + ["0.1 0.2 abc 1"] + ls[8:], "expected a finite number", 8),
    (lambda ls: ls[:3] + ["0.1 nan 0.3 1"] + ls[4:], "expected a finite number", 4),
    (lambda ls: [], "empty", None),
])
def test_bad_input(shared_data: Path, tmp_path: Path, mutate, message: str, line) -> None:
    lines = (shared_data / MSR / "a01_s01_e02_skeleton3D.txt").read_text().splitlines()
    assert len(lines) == 43 * 20
    bad = tmp_path / "a01_s01_e02_skeleton3D.txt"
    out = mutate(lines[:800])
    bad.write_text("\n".join(out) + ("\n" if out else ""))
    with pytest.raises(FormatError, match=message) as err:
        msr_action3d.read(bad)
    assert err.value.source == str(bad)
    assert err.value.line == line

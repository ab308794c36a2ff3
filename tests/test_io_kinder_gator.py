"""Kinder-Gator ``POSE-*.csv`` recordings. Kinder-Gator's files come with no licence that
allows redistribution (tests/data/kinder_gator/SOURCES.md), so the tests write a real Kinect v1
session of the shared corpus (UTKinect s01_e01: SDK joint order, metres, camera frame, uneven
frame times) into the Kinder-Gator layout."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import FormatError, MotionError
from simenv.core.skeletons import KINECT_V1_JOINTS
from simenv.io import kinder_gator, utkinect

#: Milliseconds of the fixture's clock at its first row (Kinder-Gator clocks start far from 0).
T0_MS = 36_831_130.1807
HEADER = ",".join(["Timestamp"] + [f"{j}{c}" for j in KINECT_V1_JOINTS for c in "XYZ"]
                  + ["User-ID", "Action", ""])


def write_kinder_gator(path: Path, t_s: np.ndarray, xyz: np.ndarray, pid: int = 901,
                       action: str = "Wave-your-hand") -> Path:
    """``xyz`` (R, 20, 3) camera positions at times ``t_s`` (s) as a Kinder-Gator csv."""
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = [",".join([f"{T0_MS + t * 1e3:.4f}"] + [f"{v:.7g}" for v in p.ravel()]
                     + [str(pid), action, ""]) for t, p in zip(t_s, xyz, strict=True)]
    path.write_text(HEADER + "\n" + "\n".join(rows) + "\n")
    return path


def utk_session(gesture_root: Path) -> tuple[Path, np.ndarray, np.ndarray]:
    """UTKinect s01_e01: the file, (R,) times in s of its unique frames, (R, 20, 3)
    camera positions."""
    path = gesture_root / "utkinect" / "joints" / "joints_s01_e01.txt"
    raw = np.loadtxt(path)
    _, first = np.unique(raw[:, 0], return_index=True)
    frames = raw[first, 0]
    return path, (frames - frames[0]) / utkinect.FRAME_CLOCK_HZ, raw[first, 1:].reshape(-1, 20, 3)


def test_reads_the_kinect_rows(gesture_root: Path, tmp_path: Path) -> None:
    src, t_s, xyz = utk_session(gesture_root)
    path = write_kinder_gator(tmp_path / "Children" / "POSE-p103_17-Wave-your-hand-1.csv",
                              t_s, xyz)
    rows = kinder_gator.read(path, fps=None)
    ref = utkinect.read(src, timing="rows")
    np.testing.assert_allclose(rows.positions, ref.positions, atol=1e-4)
    assert rows.skeleton.joint_names == KINECT_V1_JOINTS
    m = rows.metadata
    assert (m["subject"], m["order"], m["motion"], m["group"]) == (103, 17, "Wave your hand",
                                                                    "child")
    assert m["repairs"] == [] and m["timing"]["rows"] == len(t_s)
    grid = kinder_gator.read(path)
    assert grid.fps == kinder_gator.KINDER_GATOR_FPS
    assert grid.num_frames == int(np.floor(t_s[-1] * grid.fps + 1e-9)) + 1


def test_repeated_stamps_and_untracked_rows_are_dropped(gesture_root: Path,
                                                        tmp_path: Path) -> None:
    _, t_s, xyz = utk_session(gesture_root)
    t_s, xyz = t_s[:60].copy(), xyz[:60].copy()
    t_s[10] = t_s[9]  # two rows stamped alike, as in 55 of the dataset's files
    xyz[20] = 0.0  # no skeleton tracked
    path = write_kinder_gator(tmp_path / "POSE-p565_05-Bow-2.csv", t_s, xyz)
    m = kinder_gator.read(path, fps=None)
    assert m.num_frames == 58
    assert m.metadata["repairs"] == [
        "dropped 1 rows whose time stamp the next row repeats (first at line 11)",
        "dropped 1 untracked (all-zero) frames"]
    assert "group" not in m.metadata and m.metadata["motion"] == "Bow"


@pytest.mark.parametrize(("edit", "where", "message"), [
    (lambda lines: ["Time,HipX"] + lines[1:], "line 1", "expected the Kinder-Gator header"),
    (lambda lines: lines[:3] + [lines[3].rsplit(",", 4)[0]] + lines[4:], "line 4",
     "expected 63 comma-separated fields"),
    (lambda lines: lines[:5] + [lines[5].replace(",", ",x", 1)] + lines[6:], "line 6",
     "HipCenterX"),
    (lambda lines: lines[:7] + [lines[8], lines[7]] + lines[9:], "line 9",
     "goes back"),
])
def test_bad_files_name_the_line(gesture_root: Path, tmp_path: Path, edit, where: str,
                                 message: str) -> None:
    _, t_s, xyz = utk_session(gesture_root)
    good = write_kinder_gator(tmp_path / "POSE-p565_03-Wave-your-hand-3.csv", t_s[:20],
                              xyz[:20])
    bad = tmp_path / "bad" / good.name
    bad.parent.mkdir()
    bad.write_text("\n".join(edit(good.read_text().splitlines())) + "\n")
    with pytest.raises(FormatError) as err:
        kinder_gator.read(bad)
    assert where in str(err.value) and message in str(err.value)


def test_nothing_tracked_is_a_motion_error(gesture_root: Path, tmp_path: Path) -> None:
    _, t_s, xyz = utk_session(gesture_root)
    path = write_kinder_gator(tmp_path / "POSE-p565_03-Wave-your-hand-4.csv", t_s[:5],
                              np.zeros_like(xyz[:5]))
    with pytest.raises(MotionError, match="no skeleton tracked"):
        kinder_gator.read(path)


def test_labels_from_name() -> None:
    name = Path("Adults/POSE-p577_44-Swipe-across-an-imaginary-screen-in-front-of-you-"
                "from-right-to-left-1469183193341.csv")
    assert kinder_gator.labels_from_name(name) == {
        "subject": 577, "order": 44, "group": "adult",
        "motion": "Swipe across an imaginary screen in front of you from right to left"}
    assert kinder_gator.labels_from_name(Path("POSE-p565_53-Throw-a-ball--1.csv"))[
        "motion"] == "Throw a ball"
    assert kinder_gator.labels_from_name(Path("joints_s01_e01.csv")) == {}

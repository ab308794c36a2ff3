"""MSRC-12 ``.csv`` + ``.tagstream`` recordings. MSRC-12's licence does not state that its
files may be redistributed (tests/data/msrc12/SOURCES.md), so the tests write a real Kinect v1
session of the shared corpus (UTKinect s01_e01: SDK joint order, metres, camera frame, uneven
frame times) into the MSRC-12 layout, with its labelled segments as gesture tags."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import simenv
from simenv.core.errors import FormatError, MotionError
from simenv.io import msrc12, utkinect
from simenv.io.loader import detect

#: Microseconds of the fixture's clock at its first row (MSRC-12 clocks start far from 0).
T0_US = 303_293_455


def _session(gesture_root: Path) -> tuple[Path, np.ndarray, np.ndarray]:
    """UTKinect s01_e01: the file, (R,) unique frame numbers, (R, 20, 3) camera positions."""
    path = gesture_root / "utkinect" / "joints" / "joints_s01_e01.txt"
    raw = np.loadtxt(path)
    _, first = np.unique(raw[:, 0], return_index=True)
    return path, raw[first, 0], raw[first, 1:].reshape(-1, 20, 3)


def _write(folder: Path, name: str, frames: np.ndarray, xyz: np.ndarray,
           tags: list[tuple[float, int]] | None) -> Path:
    """``xyz`` (R, 20, 3) as an MSRC-12 csv (time in microseconds from the UTKinect frame
    clock, 60 units/s; w = 1 on tracked rows, 0 on all-zero ones) and, with ``tags``
    ((time s from the first row, gesture id)), its tagstream."""
    t_us = np.round(T0_US + (frames - frames[0]) / utkinect.FRAME_CLOCK_HZ * 1e6)
    w = (~(xyz == 0).all(axis=(1, 2))).astype(float)
    rows = np.concatenate([xyz, np.broadcast_to(w[:, None, None], (len(xyz), 20, 1))], axis=2)
    table = np.concatenate([t_us[:, None], rows.reshape(len(xyz), 80)], axis=1)
    csv = folder / f"{name}.csv"
    np.savetxt(csv, table, fmt=["%d"] + ["%.6g"] * 80, delimiter=" ")
    if tags is not None:
        lines = ["XQPCTick;Tag"] + [
            f"{round(((T0_US + s * 1e6) * msrc12.TICKS_PER_MS - msrc12.TICKS_PER_MS / 2) / 1000)}"
            f";G{k}  {msrc12.MSRC12_GESTURES[k - 1]}" for s, k in tags]
        csv.with_suffix(".tagstream").write_text("\n".join(lines) + "\n")
    return csv


def test_reads_the_kinect_rows_and_tags(gesture_root: Path, tmp_path: Path) -> None:
    src, frames, xyz = _session(gesture_root)
    segments = utkinect.read(src, timing="rows").metadata["segments"]
    times = (frames - frames[0]) / 60.0
    # A tag on the stored row nearest each segment's middle (the action point).
    rows_at = [int(np.argmin(np.abs(frames - (s["start_frame"] + s["end_frame"]) / 2)))
               for s in segments]
    tags = [(float(times[k]), 7) for k in rows_at]
    path = _write(tmp_path, "P3_2_7A_p17", frames, xyz, tags)
    rows = msrc12.read(path, fps=None)
    ref = utkinect.read(src, timing="rows")
    np.testing.assert_allclose(rows.positions, ref.positions, atol=1e-4)
    assert (rows.metadata["instruction"], rows.metadata["gesture_id"], rows.metadata["take"],
            rows.metadata["subject"], rows.metadata["label"]) == ([3, 2], 7, 2, 17, "bow")
    gestures = rows.metadata["gestures"]
    assert [g["label"] for g in gestures] == ["bow"] * len(segments)
    for g, (s, _), k in zip(gestures, tags, rows_at, strict=True):
        assert g["time_s"] == pytest.approx(s, abs=1e-4)
        assert g["frame"] == k
    grid = simenv.load(path)  # the loader finds it and its tags; the default 30 fps grid
    assert detect(path)[0] == "msrc12" and grid.fps == msrc12.MSRC12_FPS
    assert grid.duration == pytest.approx(times[-1], abs=1 / 30)
    assert [g["frame"] for g in grid.metadata["gestures"]] == [
        round(s * 30) for s, _ in tags]


def test_untracked_frames(gesture_root: Path, tmp_path: Path) -> None:
    _, frames, xyz = _session(gesture_root)
    frames, xyz = frames[:200], xyz[:200].copy()
    xyz[:6] = 0.0  # MSRC-12 recordings start untracked
    xyz[50:53] = 0.0
    m = msrc12.read(_write(tmp_path, "P1_1_1_p19", frames, xyz, None), fps=None)
    assert m.num_frames == 200 - 6 - 3 and m.metadata["trimmed"] == [6, 0]
    assert "gestures" not in m.metadata
    assert any("dropped 3 untracked" in r for r in m.metadata["repairs"])
    with pytest.raises(MotionError, match="all 200 frames are zero"):
        msrc12.read(_write(tmp_path, "P1_1_1_p20", frames, np.zeros_like(xyz), None))


def test_bad_files_name_line_and_field(gesture_root: Path, tmp_path: Path) -> None:
    _, frames, xyz = _session(gesture_root)
    path = _write(tmp_path, "P1_1_2_p01", frames[:20], xyz[:20], [(0.1, 2)])
    lines = path.read_text().splitlines()
    short = tmp_path / "short.csv"
    short.write_text("\n".join(lines[:4] + [lines[4].rsplit(" ", 1)[0]] + lines[5:]))
    with pytest.raises(FormatError, match="expected 81 values per line") as e:
        msrc12.read(short)
    assert e.value.line == 5
    back = tmp_path / "back.csv"
    back.write_text("\n".join(lines[:3] + [lines[1]] + lines[4:]))
    with pytest.raises(FormatError, match="does not increase") as e:
        msrc12.read(back)
    assert (e.value.line, e.value.field) == (4, "time")
    word = tmp_path / "word.csv"
    word.write_text("\n".join(lines[:2] + [lines[2].replace(" ", " x ", 1).rsplit(" ", 1)[0]]
                              + lines[3:]))
    with pytest.raises(FormatError) as e:
        msrc12.read(word)
    assert e.value.line == 3
    tags = path.with_suffix(".tagstream")
    tags.write_text("XQPCTick;Tag\n15398506943;G13 nothing\n")
    with pytest.raises(FormatError, match="G13 is not one of G1-G12") as e:
        msrc12.read(path)
    assert (e.value.line, e.value.field) == (2, "Tag")
    tags.write_text("Tick,Tag\n")
    with pytest.raises(FormatError, match="XQPCTick;Tag"):
        msrc12.read(path)
    with pytest.raises(FormatError, match="not found"):
        msrc12.read(path, tags=tmp_path / "none.tagstream")

"""The cross-dataset protocol on a small real subset of the shared corpus (one-epoch networks:
the test checks what the protocol computes and writes, not how well it recognises), and the
MSRC-12 clips, cut from a real UTKinect session written in the MSRC-12 layout (MSRC-12's own
files are not redistributable here: tests/data/msrc12/SOURCES.md), and the Berkeley MHAD clips,
cut from a real CMU BVH written as an MHAD file (nor are MHAD's: tests/data/berkeley_mhad/
SOURCES.md; the released files are read when ``SIMENV_BERKELEY_MHAD`` names a folder of them)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from test_io_berkeley_mhad import CMU_WALK, _in_cm
from test_io_kinder_gator import utk_session, write_kinder_gator

from simenv.cli import main as cli
from simenv.core.errors import SimenvError
from simenv.data.gestures import GESTURE_FPS, LoadReport, still_mask
from simenv.io import berkeley_mhad, msrc12, utkinect
from simenv.learning.cross_dataset import (
    KINDER_GATOR_ROOM_LABELS,
    MSRC12_AFTER_S,
    MSRC12_BEFORE_S,
    kinder_gator_clips,
    kinder_gator_label,
    mhad_clips,
    mhad_label,
    msrc12_clips,
    run_cross_dataset,
)
from simenv.learning.recognition import RecognitionConfig


def _msrc12_file(folder: Path, stem: str, session: Path, gesture: int) -> list[float]:
    """A UTKinect session as an MSRC-12 recording (rows -> microseconds at 60 frame-number
    units/s, w = 1), tagged with ``gesture`` at the middle of each labelled segment; returns
    the tags' times from the first row, s."""
    raw = np.loadtxt(session)
    _, first = np.unique(raw[:, 0], return_index=True)
    frames, xyz = raw[first, 0], raw[first, 1:].reshape(-1, 20, 3)
    t_s = (frames - frames[0]) / utkinect.FRAME_CLOCK_HZ
    rows = np.concatenate([xyz, np.ones((len(xyz), 20, 1))], axis=2).reshape(len(xyz), 80)
    np.savetxt(folder / f"{stem}.csv", np.concatenate([(t_s * 1e6 + 5e7)[:, None], rows], 1),
               fmt=["%d"] + ["%.6g"] * 80)
    segments = utkinect.read(session, timing="rows").metadata["segments"]
    tags = [float(t_s[np.argmin(np.abs(frames - (s["start_frame"] + s["end_frame"]) / 2))])
            for s in segments]
    ticks = [round(((5e7 + s * 1e6) * msrc12.TICKS_PER_MS - msrc12.TICKS_PER_MS / 2) / 1000)
             for s in tags]
    (folder / f"{stem}.tagstream").write_text("XQPCTick;Tag\n" + "".join(
        f"{t};G{gesture}  {msrc12.MSRC12_GESTURES[gesture - 1]}\n" for t in ticks))
    return tags


def test_msrc12_clips_around_tags_without_p06(gesture_root: Path, tmp_path: Path) -> None:
    session = gesture_root / "utkinect" / "joints" / "joints_s02_e01.txt"
    tags = _msrc12_file(tmp_path, "P1_1_7_p17", session, 7)
    _msrc12_file(tmp_path, "P1_1_8_p17", session, 8)
    _msrc12_file(tmp_path, "P1_1_7_p06", session, 7)  # reserved: never read
    (tmp_path / "P1_1_9_p18.csv").write_text((tmp_path / "P1_1_8_p17.csv").read_text())
    report = LoadReport()
    clips = msrc12_clips(tmp_path, per_file=3, report=report)
    assert report.skipped == ["P1_1_9_p18.csv: no .tagstream beside it"]
    assert {c.subject for c in clips} == {17} and {c.dataset for c in clips} == {"msrc12"}
    assert [c.label for c in clips] == ["bow"] * 3 + ["other"] * 3
    assert [c.source_label for c in clips] == ["bow"] * 3 + ["throw"] * 3
    longest = (MSRC12_BEFORE_S + MSRC12_AFTER_S) * GESTURE_FPS + 1
    for c in clips:
        k = int(c.name.rsplit("_tag", 1)[1])
        assert c.name.startswith("P1_1_") and 0 < k < len(tags) - 1  # spread, not the ends
        # The clip spans its tag: the source slice's first frame is at most 2 s before it.
        assert c.source is not None and c.num_frames <= longest
        assert c.positions.shape[1:] == (15, 3)


def test_cross_dataset_command(gesture_root: Path, tmp_path: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:
    data = tmp_path / "gestures"
    (data / "msr_action3d").mkdir(parents=True)
    (data / "utkinect" / "joints").mkdir(parents=True)
    for s in range(1, 5):
        for a in (1, 5, 10, 13):  # wave, forward punch (other), clap, bend
            name = f"a{a:02d}_s{s:02d}_e01_skeleton3D.txt"
            (data / "msr_action3d" / name).symlink_to(gesture_root / "msr_action3d" / name)
        name = f"joints_s{s:02d}_e01.txt"
        (data / "utkinect" / "joints" / name).symlink_to(
            gesture_root / "utkinect" / "joints" / name)
    (data / "utkinect" / "joints" / "actionLabel.txt").symlink_to(
        gesture_root / "utkinect" / "joints" / "actionLabel.txt")
    config = tmp_path / "config.json"
    config.write_text('{"epochs": 1, "width": 16}')
    with pytest.raises(SystemExit):
        cli.main(["eval", "classifier", "--msrc12", str(tmp_path)])
    assert "--msrc12: only with --protocol" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["eval", "classifier", "--kindergator", str(tmp_path), "--cross-only"])
    assert "--kindergator, --cross-only: only with --protocol" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["eval", "classifier", "--mhad", str(tmp_path)])
    assert "--mhad: only with --protocol" in capsys.readouterr().err
    out = tmp_path / "out"
    assert cli.main(["eval", "classifier", "--protocol", "cross-dataset", "--data", str(data),
                     "--config", str(config), "--folds", "2", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    result = json.loads((out / "cross_dataset.json").read_text())
    assert set(result["datasets"]) == {"msr_action3d", "utkinect"}
    utk = result["datasets"]["utkinect"]
    # MSR Action3D has no walking, sitting down or standing up: not asked of its network.
    assert set(utk["excluded"]) == {"walk", "sit_down", "stand_up"}
    assert utk["shared_clips"] == utk["test_clips"] - sum(utk["excluded"].values())
    for name, d in result["datasets"].items():
        for cond in ("real_3s", "real_1s"):
            c = d["conditions"][cond]
            assert c["cross_dataset"]["n"] == c["within_dataset"]["n"] == d["shared_clips"]
            confusion = np.array(c["cross_dataset"]["confusion"])
            assert confusion.sum() == d["shared_clips"]
            by_source = c["by_source_label"].values()
            assert sum(r["n"] for r in by_source) == d["test_clips"]
            assert all(sum(r["read_as"].values()) == r["n"] >= r["right"] for r in by_source)
            assert f"| {name} |" in text
        saved = json.loads((out / f"confusion_{name}.json").read_text())
        assert saved["labels"] == result["labels"] and saved["rows"] == "true label"
        assert (out / f"confusion_{name}.png").stat().st_size > 0
    assert "utkinect left out, per class" in text and "most confused with" in text


def test_kinder_gator_room_labels() -> None:
    assert kinder_gator_label("Wave your hand") == kinder_gator_label(
        "Wave your other hand") == "wave"
    assert kinder_gator_label("Bow") == "bow"
    assert kinder_gator_label("Touch your toes") == "bend_down"
    # A raised hand without waving, beckoning and walking in place are no room gesture.
    for motion in ("Raise your hand", "Signal someone to come here", "Walk in place",
                   "Throw a ball"):
        assert kinder_gator_label(motion) == "other"
    assert set(KINDER_GATOR_ROOM_LABELS.values()) == {"wave", "bow", "bend_down"}


def test_kinder_gator_clips_cut_the_moving_part(gesture_root: Path, tmp_path: Path) -> None:
    _, t_s, xyz = utk_session(gesture_root)
    session = utkinect.read(gesture_root / "utkinect" / "joints" / "joints_s01_e01.txt",
                            timing="rows")
    seg = next(g for g in session.metadata["segments"] if g["label"] == "waveHands")
    # The wave segment (row indices of the session) with 2 s of the session on each side.
    rows = (t_s >= t_s[int(seg["start"])] - 2.0) & (t_s <= t_s[int(seg["end"]) - 1] + 2.0)
    for motion, pid in (("Wave-your-other-hand", 934), ("Bow", 934), ("Punch", 103),
                        ("Throw-a-ball", 103), ("Wave-your-hand", 103)):
        write_kinder_gator(tmp_path / ("Children" if pid == 103 else "Adults")
                           / f"POSE-p{pid}_01-{motion}-1.csv", t_s[rows], xyz[rows], pid,
                           motion)
    report = LoadReport()
    clips = kinder_gator_clips(tmp_path, report=report)
    assert report.skipped == []
    moving = [c for c in clips if c.label != "idle"]
    # Of the 'other' motions (sorted: Punch, Throw a ball), the first person (p103) uses
    # every fifth from the first.
    assert sorted((c.subject, c.source_label, c.label) for c in moving) == [
        (103, "Punch", "other"), (103, "Wave your hand", "wave"), (934, "Bow", "bow"),
        (934, "Wave your other hand", "wave")]
    assert {c.dataset for c in clips} == {"kindergator"}
    for c in moving:
        still = still_mask(c.positions, GESTURE_FPS)
        assert not still[0] and not still[-1]  # trimmed to the moving part
        assert c.positions.shape[1:] == (15, 3) and c.source is not None
    with pytest.raises(SimenvError, match="no Kinder-Gator recording"):
        kinder_gator_clips(tmp_path / "Adults" / "none")


def test_train_only_datasets_must_be_in_the_corpus(gesture_root: Path, tmp_path: Path
                                                   ) -> None:
    from simenv.data.gestures import load_labelled

    clips = load_labelled([gesture_root / "utkinect" / "joints" / "joints_s01_e01.txt"])
    with pytest.raises(SimenvError, match="train_only names kindergator"):
        run_cross_dataset(clips, RecognitionConfig(epochs=1), train_only=("kindergator",))
    with pytest.raises(SimenvError, match="at least two datasets to leave out"):
        run_cross_dataset(clips, RecognitionConfig(epochs=1))
    with pytest.raises(SimenvError, match="left_out names mhad"):
        run_cross_dataset(clips, RecognitionConfig(epochs=1), left_out=("mhad",))


def test_mhad_room_labels() -> None:
    by_name = {name: mhad_label(k) for k, name in enumerate(berkeley_mhad.MHAD_ACTIONS, 1)}
    assert by_name == {
        "jumping in place": "other", "jumping jacks": "other",
        "bending (hands up all the way down)": "bend_down", "punching (boxing)": "other",
        "waving (two hands)": "wave", "waving (one hand, right)": "wave",
        "clapping hands": "clap", "throwing a ball": "other",  # no throw in the vocabulary
        "sit down then stand up": "other", "sit down": "sit_down", "stand up": "stand_up"}


def _still_padded(bvh_cm: Path, seconds: float) -> int:
    """Hold the first and the last pose of a BVH ``seconds`` before and after its motion
    (a still lead-in and lead-out, as MHAD's recordings have); returns the frames added at
    each end."""
    lines = bvh_cm.read_text().splitlines()
    top = next(i for i, line in enumerate(lines) if line.strip().upper().startswith("FRAME TIME"))
    fps = 1.0 / float(lines[top].split(":")[1])
    frames = [line for line in lines[top + 1:] if line.strip()]
    n = int(round(seconds * fps))
    lines[top - 1] = f"Frames: {len(frames) + 2 * n}"
    bvh_cm.write_text("\n".join(lines[:top + 1] + [frames[0]] * n + frames
                                + [frames[-1]] * n) + "\n")
    return n


def test_mhad_clips_cut_the_moving_part(shared_data: Path, tmp_path: Path) -> None:
    folder = tmp_path / "BerkeleyMHAD" / "SkeletalData"
    folder.mkdir(parents=True)
    src = shared_data / CMU_WALK  # a real walk; the file names give MHAD's labels
    for name in ("skl_s03_a06_r01", "skl_s07_a08_r02", "skl_s07_t-pose", "skl_s03_a12_r01"):
        _in_cm(src, folder / f"{name}.bvh")
    _still_padded(folder / "skl_s03_a06_r01.bvh", 1.0)
    walk = berkeley_mhad.read(folder / "skl_s07_a08_r02.bvh")
    report = LoadReport()
    clips = mhad_clips(tmp_path / "BerkeleyMHAD", report=report)  # finds SkeletalData/
    assert report.skipped == []  # the T-pose and the unknown action 12 are not read
    assert {c.dataset for c in clips} == {"mhad"}
    moving = sorted((c for c in clips if c.label != "idle"), key=lambda c: c.subject)
    assert [(c.subject, c.source_label, c.label) for c in moving] == [
        (3, "waving (one hand, right)", "wave"), (7, "throwing a ball", "other")]
    for c in moving:
        assert c.source is not None and c.source.fps == GESTURE_FPS  # read at the room's rate
        still = still_mask(c.positions, GESTURE_FPS)
        assert not still[0] and not still[-1] and c.positions.shape[1:] == (15, 3)
        # The walk moves throughout: the moving part holds it, and at most the still test's
        # 0.4-s moving average (10 frames) of the still edges.
        walk_frames = walk.num_frames / walk.fps * GESTURE_FPS
        assert walk_frames - 1 <= c.num_frames <= walk_frames + 0.4 * GESTURE_FPS + 1
    idle = [c for c in clips if c.label == "idle"]
    # Only the padded recording has still edges: 1 s each, less what the speed's 0.4-s
    # moving average smears into them.
    assert sorted(c.name for c in idle) == ["skl_s03_a06_r01_idle0", "skl_s03_a06_r01_idle1"]
    for c in idle:
        assert c.subject == 3 and 0.7 * GESTURE_FPS <= c.num_frames <= 1.0 * GESTURE_FPS + 1
    with pytest.raises(SimenvError, match="no Berkeley MHAD recording"):
        mhad_clips(tmp_path)


def _released_mhad() -> list[Path]:
    """One released file per action present in ``SIMENV_BERKELEY_MHAD`` (the first)."""
    folder = Path(os.environ.get("SIMENV_BERKELEY_MHAD", "/nonexistent"))
    first: dict[int, Path] = {}
    for path in sorted(folder.glob("skl_s*_a*_r*.bvh")):
        labels = berkeley_mhad.labels_from_name(path)
        if "action_id" in labels:
            first.setdefault(int(labels["action_id"]), path)
    return list(first.values())


@pytest.mark.skipif(not _released_mhad(),
                    reason="set SIMENV_BERKELEY_MHAD to a folder of released skl_*.bvh files")
def test_mhad_released_files(tmp_path: Path) -> None:
    for path in _released_mhad():
        (tmp_path / path.name).symlink_to(path)
    clips = mhad_clips(tmp_path)
    for path in _released_mhad():
        recording = berkeley_mhad.read(path)
        label = mhad_label(int(berkeley_mhad.labels_from_name(path)["action_id"]))
        mine = [c for c in clips if c.name.startswith(path.stem)]
        moving = [c for c in mine if c.label != "idle"]
        assert [c.label for c in moving] == [label], path.name
        # The action is at least half a second and no longer than its recording.
        seconds = moving[0].num_frames / GESTURE_FPS
        assert 0.5 <= seconds <= recording.num_frames / recording.fps + 0.04, path.name
        assert all(c.num_frames >= 0.5 * GESTURE_FPS - 1 for c in mine if c.label == "idle")

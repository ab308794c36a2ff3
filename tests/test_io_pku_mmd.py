"""PKU-MMD skeleton sequences and labels. PKU-MMD's terms do not say its files may be
redistributed (tests/data/pku_mmd/SOURCES.md), so the tests write a real Kinect v2 recording
(the NTU RGB+D sample in tests/data/ntu: SDK joint order, metres, camera frame) into PKU-MMD's
line layout, with label files beside it. A released PKU-MMD file is checked when
``SIMENV_PKU_MMD`` names one (``A10N08-L.txt`` was, see the SOURCES.md)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from expect import raises_at, rejects_lines

import simenv
from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Interaction, Motion
from simenv.io import ntu, pku_mmd
from simenv.io.loader import detect

NTU_SAMPLE = Path(__file__).parent / "data" / "ntu" / "S001C001P001R001A001.skeleton"


def _ntu_body() -> np.ndarray:
    """(103, 25, 3) camera-frame metres, Kinect v2 SDK order, of the NTU sample's body."""
    n, bodies = ntu.parse(NTU_SAMPLE)
    (frames,) = bodies.values()
    return np.stack([frames[f] for f in range(n)])


def _write(path: Path, body1: np.ndarray, body2: np.ndarray | None = None) -> Path:
    """Both bodies ((T, 25, 3), SDK order; None or NaN frames: all zeros) as PKU-MMD lines."""
    two = np.zeros((len(body1), 2, 25, 3))
    two[:, 0] = body1
    if body2 is not None:
        two[:, 1] = body2
    two = np.nan_to_num(two, nan=0.0)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, two.reshape(len(body1), 150), fmt="%.6f")
    return path


def _sequence(root: Path, labels: list[str] | None, name: str = "0291-M") -> Path:
    """The NTU body as ``<root>/PKU_Skeleton_Renew/<name>.txt`` with ``labels`` lines in
    ``<root>/Train_Label_PKU_final/<name>.txt``."""
    path = _write(root / "PKU_Skeleton_Renew" / f"{name}.txt", _ntu_body())
    if labels is not None:
        lab = root / "Train_Label_PKU_final" / f"{name}.txt"
        lab.parent.mkdir(parents=True, exist_ok=True)
        lab.write_text("\n".join(labels) + "\n")
    return path


def test_one_body_and_its_labels(tmp_path: Path) -> None:
    path = _sequence(tmp_path, ["8,5,60,2", "13,61,102,1"])
    m = pku_mmd.read(path)
    ref = ntu.read(NTU_SAMPLE)  # same joints, same floor estimate -> same world frame
    assert isinstance(m, Motion) and m.skeleton.name == "kinect_v2_25" and m.fps == 30.0
    np.testing.assert_allclose(m.positions, ref.positions, atol=1e-4)
    assert (m.metadata["sequence"], m.metadata["phase"], m.metadata["view"],
            m.metadata["units"], m.metadata["body"]) == ("0291", 1, "middle", "m", 1)
    assert m.metadata["labels_file"].endswith("Train_Label_PKU_final/0291-M.txt")
    assert [(a["action_id"], a["label"], a["start_frame"], a["end_frame"], a["confidence"])
            for a in m.metadata["actions"]] == [(8, "drink water", 5, 60, 2),
                                                (13, "hand waving", 61, 102, 1)]
    assert m.metadata["actions"][1]["end_s"] == pytest.approx(102 / 30, abs=1e-4)
    clips = pku_mmd.action_clips(m)
    assert [c.num_frames for _, c in clips] == [56, 42]
    np.testing.assert_array_equal(clips[1][1].positions, m.positions[61:103])
    assert detect(path)[0] == "pku_mmd"
    loaded = simenv.load(path)  # the loader finds it and its labels
    assert loaded.metadata["format"] == "pku_mmd" and len(loaded.metadata["actions"]) == 2


def test_second_body_millimetres_and_gaps(tmp_path: Path) -> None:
    body = _ntu_body()
    other = body + np.array([0.9, 0.0, 0.4])  # a second person beside the first
    other[:40] = np.nan  # enters at frame 40: tracked on 61 % of the frames
    pair = pku_mmd.read(_write(tmp_path / "A01N02-R.txt", body, other))
    assert isinstance(pair, Interaction) and pair.metadata["phase"] == 2
    assert pair.actor.metadata["view"] == "right" and pair.reactor.metadata["body"] == 2
    assert pair.reactor.metadata["tracked_fraction"] == pytest.approx(63 / 103, abs=1e-4)
    assert any("frames 0-39" in r for r in pair.reactor.metadata["repairs"])
    d = pair.reactor.positions[50:] - pair.actor.positions[50:]  # one rigid world frame
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), np.linalg.norm([0.9, 0.0, 0.4]),
                               atol=1e-4)
    other[:70] = np.nan  # 32 %: not a second person, ignored with a note
    alone = pku_mmd.read(_write(tmp_path / "A01N03-L.txt", body, other))
    assert isinstance(alone, Motion)
    assert any("ignored body 2" in q for q in alone.metadata["quirks"])
    gappy = body.copy()
    gappy[20:23] = np.nan  # body 1 lost for three frames
    mm = pku_mmd.read(_write(tmp_path / "0002-L.txt", gappy * 1000.0))
    assert mm.metadata["units"] == "mm" and mm.num_frames == 103
    assert any("frames 20-22" in r for r in mm.metadata["repairs"])
    np.testing.assert_allclose(mm.positions[30:], pku_mmd.read(
        _write(tmp_path / "0003-L.txt", gappy)).positions[30:], atol=1e-4)


def test_a_folded_second_body_does_not_tilt_the_floor(tmp_path: Path) -> None:
    body = _ntu_body()
    hips = body[:, :1, 1:2]
    folded = body + np.array([0.9, 0.0, 0.4])
    folded[..., 1:2] = 2 * hips - body[..., 1:2]  # upside down about its hips
    pair = pku_mmd.read(_write(tmp_path / "0005-L.txt", body, folded))
    alone = pku_mmd.read(_write(tmp_path / "0006-L.txt", body))
    assert isinstance(pair, Interaction)
    assert pair.actor.metadata["camera_frame"]["from_bodies"] == [1]
    assert any("body 2: hips above the ankles on only 0%" in q
               for q in pair.actor.metadata["quirks"])
    np.testing.assert_allclose(pair.actor.positions, alone.positions, atol=1e-5)
    upright = pku_mmd.read(_write(tmp_path / "0007-L.txt", body, body + [0.9, 0.0, 0.4]))
    assert upright.actor.metadata["camera_frame"]["from_bodies"] == [1, 2]


def test_bad_lines_name_file_line_frame_and_field(tmp_path: Path) -> None:
    path = _write(tmp_path / "0004-L.txt", _ntu_body()[:12])
    lines = path.read_text().splitlines()
    bad = tmp_path / "bad.txt"
    e = rejects_lines(pku_mmd.read, bad, lines[:3] + [lines[3].rsplit(" ", 1)[0]] + lines[4:],
                      "expected 150 values per line", line=4)
    assert e.frame == 3
    tokens = lines[5].split()
    for token in ("nan", "0.5a"):  # SpineMid y of body 1
        tokens[4] = token
        e = rejects_lines(pku_mmd.read, bad, lines[:5] + [" ".join(tokens)] + lines[6:],
                          f"expected a finite number, found '{token}'", line=6)
        assert (e.frame, e.field) == (5, "body1.SpineMid.y")
    empty = tmp_path / "empty.txt"
    empty.write_text("\n")
    raises_at(FormatError, "empty", lambda: pku_mmd.read(empty))
    raises_at(MotionError, "one frame", lambda: pku_mmd.read(
        _write(tmp_path / "one.txt", _ntu_body()[:1])))
    raises_at(MotionError, "all zeros on all 5 frames", lambda: pku_mmd.read(
        _write(tmp_path / "zero.txt", np.zeros((5, 25, 3)))))


def test_bad_labels_name_file_line_and_field(tmp_path: Path) -> None:
    cases = [(["8,5,60,2", "52,61,70,1"], "not one of 1-51", 2, "action_id"),
             (["8,5,103,2"], "past the skeleton file's last frame 102", 1, "end_frame"),
             (["8,60,5,2"], "after the end frame", 1, "start_frame"),
             (["8,5,60,3"], "confidence 3", 1, "confidence"),
             (["8,5,x,2"], "expected an integer", 1, "end_frame"),
             (["8,5,60"], "expected 4 comma-separated", 1, None)]
    for k, (labels, match, line, field) in enumerate(cases):
        path = _sequence(tmp_path / str(k), labels)
        e = raises_at(FormatError, match, lambda p=path: pku_mmd.read(p), line=line,
                      field=field)
        assert Path(str(e.source)).parent.name == "Train_Label_PKU_final"
    path = _sequence(tmp_path / "given", None)
    raises_at(FormatError, "not found", lambda: pku_mmd.read(path, labels=tmp_path / "no.txt"))
    assert "actions" not in pku_mmd.read(path).metadata


@pytest.mark.skipif(not os.environ.get("SIMENV_PKU_MMD"),
                    reason="set SIMENV_PKU_MMD to a released PKU-MMD skeleton .txt")
def test_released_file() -> None:
    path = Path(os.environ["SIMENV_PKU_MMD"])
    loaded = simenv.load(path)
    first = loaded.people[0] if isinstance(loaded, Interaction) else loaded
    assert first.fps == 30.0 and first.skeleton.num_joints == 25
    assert first.metadata["units"] == "m"
    cam = first.metadata["camera_frame"]
    assert cam["tilt_deg"] < 30 and 0.3 < cam["sensor_height_m"] < 2.5
    canon = first.to_canonical()
    toes = canon.positions[:, [canon.skeleton.index(f"{s}_toe") for s in ("left", "right")],
                           2].min(axis=1)
    assert abs(float(np.median(toes))) < 0.1  # the levelled floor is under the feet

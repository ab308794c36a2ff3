"""UTD-MHAD ``d_skel`` MAT-files. UTD-MHAD is reserved for evaluation, so every test writes
real Kinect v1 recordings of MSR Action3D (shared corpus) into UTD-MHAD's layout with
``scipy.io.savemat`` and checks the reader gives back what the MSR reader gives."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.io

import simenv
from simenv.cli import main as cli
from simenv.core.errors import FormatError, MotionError
from simenv.io import msr_action3d, utd_mhad
from simenv.io.loader import detect

MSR_WAVE = "a01_s01_e01_skeleton3D.txt"


def _camera_sdk(path: Path) -> np.ndarray:
    """(T, 20, 3) camera-frame positions of an MSR file, Kinect SDK joint order."""
    return np.loadtxt(path).reshape(-1, 20, 4)[:, list(msr_action3d.MSR_TO_SDK), :3]


def _write_utd(path: Path, sdk: np.ndarray) -> Path:
    """``sdk`` (T, 20, 3) written as UTD-MHAD's ``d_skel`` (20, 3, T), UTD joint order."""
    d_skel = np.zeros((20, 3, len(sdk)))
    for k, row in enumerate(utd_mhad.UTD_TO_SDK):
        d_skel[row] = sdk[:, k].T
    scipy.io.savemat(path, {"d_skel": d_skel})
    return path


@pytest.fixture(scope="module")
def msr_wave(gesture_root: Path) -> Path:
    return gesture_root / "msr_action3d" / MSR_WAVE


def test_reads_the_kinect_recording_back(msr_wave: Path, tmp_path: Path) -> None:
    path = _write_utd(tmp_path / "a03_s02_t04_skeleton.mat", _camera_sdk(msr_wave))
    m = utd_mhad.read(path)
    ref = msr_action3d.read(msr_wave, fps=utd_mhad.UTD_FPS)
    assert m.fps == 30.0 and m.skeleton.name == "kinect_v1_20"
    np.testing.assert_allclose(m.positions, ref.positions, atol=1e-6)
    assert (m.metadata["label"], m.metadata["class_id"], m.metadata["subject"],
            m.metadata["trial"]) == ("right hand wave", 3, 2, 4)
    # The joint order: the head is the highest joint, the waving right hand moves most.
    names = m.skeleton.joint_names
    assert names[int(np.argmax(np.median(m.positions[..., 2], axis=0)))] in ("Head",
                                                                             "HandRight")
    travel = np.abs(np.diff(m.positions, axis=0)).sum(axis=(0, 2))
    assert names[int(np.argmax(travel))] in ("HandRight", "WristRight")


def test_loader_and_info_detect_it(msr_wave: Path, tmp_path: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    path = _write_utd(tmp_path / "a27_s01_t01_skeleton.mat", _camera_sdk(msr_wave))
    assert detect(path)[0] == "utd_mhad"
    m = simenv.load(path)
    assert m.metadata["format"] == "utd_mhad" and m.metadata["label"].startswith("squat")
    assert cli.main(["info", str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["persons"][0]["frames"] == len(_camera_sdk(msr_wave))


def test_untracked_frames_are_trimmed_and_bridged(msr_wave: Path, tmp_path: Path) -> None:
    sdk = _camera_sdk(msr_wave)
    sdk[:3] = 0.0
    sdk[10] = 0.0
    m = utd_mhad.read(_write_utd(tmp_path / "a03_s01_t01_skeleton.mat", sdk))
    assert m.num_frames == len(sdk) - 3
    assert m.metadata["trimmed"] == [3, 0]
    assert any("untracked" in r for r in m.metadata["repairs"][1:])


def test_bad_files_name_file_and_field(msr_wave: Path, tmp_path: Path) -> None:
    sdk = _camera_sdk(msr_wave)
    other = tmp_path / "other.mat"
    scipy.io.savemat(other, {"skel": np.zeros((20, 3, 4))})
    with pytest.raises(FormatError, match="no 'd_skel' variable .found skel.") as e:
        utd_mhad.read(other)
    assert e.value.source == str(other) and e.value.field == "d_skel"
    wrong = tmp_path / "wrong.mat"
    scipy.io.savemat(wrong, {"d_skel": np.zeros((25, 3, 4))})
    with pytest.raises(FormatError, match=r"shape \(25, 3, 4\); expected \(20, 3, T"):
        utd_mhad.read(wrong)
    nan = sdk.copy()
    nan[5, 11, 0] = np.nan
    with pytest.raises(MotionError, match="HandRight") as e:
        utd_mhad.read(_write_utd(tmp_path / "nan.mat", nan))
    assert e.value.frame == 5
    with pytest.raises(MotionError, match="all 4 frames are zero"):
        utd_mhad.read(_write_utd(tmp_path / "zero.mat", np.zeros((4, 20, 3))))
    text = tmp_path / "x_skeleton.mat"
    text.write_text("not a MAT-file")
    with pytest.raises(FormatError, match="cannot read MATLAB file"):
        utd_mhad.read(text)

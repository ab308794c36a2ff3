"""Azure Kinect Body Tracking reader, on a real recording (tests/data/conventions/azure_kinect,
SOURCES.md there): a bodyweight squat tracked by an Azure Kinect, written by the C# SDK
application that captured it (``x y z`` cells under the SDK's ``JointId`` names). The
offline processor's JSON is tested on the same real positions written in its layout."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import simenv
from simenv.core.errors import FormatError, MotionError
from simenv.io import azure_kinect
from simenv.io.joint_csv import AZURE_KINECT_JOINTS
from simenv.io.loader import detect

DATA = Path(__file__).parent / "data" / "conventions" / "azure_kinect"
SQUAT = DATA / "gymtrainer_bodyweight_squat_side_view.csv"
#: The capturing application's camera rate (its CameraFPS setting when the file was written).
SQUAT_FPS = 15.0
#: The 1.0 SDK's names, as the offline processor writes them.
SDK_NAMES = [j.replace("NAVAL", "NAVEL") for j in AZURE_KINECT_JOINTS]


def _table_positions(path: Path) -> np.ndarray:
    """(T, 32, 3) the table's own numbers, header order (the SDK's)."""
    rows = path.read_text(encoding="utf-8-sig").splitlines()[1:]
    return np.array([[c.split() for c in r.split(",")] for r in rows], dtype=np.float64)


def _write_offline_json(path: Path, frames: list[tuple[int, list[tuple[int, np.ndarray]]]]
                        ) -> Path:
    """An offline-processor JSON: frames of (timestamp_usec, [(body_id, (32, 3) mm)])."""
    out = {"bone_list": [], "joint_names": SDK_NAMES, "k4abt_sdk_version": "1.1.2",
           "source_file": "recording.mkv", "frames": [
               {"frame_id": n, "timestamp_usec": t, "num_bodies": len(bodies),
                "bodies": [{"body_id": b, "joint_positions": xyz.tolist(),
                            "joint_orientations": [[1.0, 0.0, 0.0, 0.0]] * len(xyz)}
                           for b, xyz in bodies]}
               for n, (t, bodies) in enumerate(frames)]}
    path.write_text(json.dumps(out))
    return path


def _frames_mm(raw: np.ndarray, step_us: int) -> list[tuple[int, list[tuple[int, np.ndarray]]]]:
    return [(1_000_000 + k * step_us, [(1, xyz * 1000.0)]) for k, xyz in enumerate(raw)]


def test_real_squat_table_is_detected_and_maps_automatically() -> None:
    """The table is this reader's (not joint_csv's), and every canonical keypoint maps by
    the Azure Kinect names; the rate is assumed and says so."""
    assert detect(SQUAT)[0] == "azure_kinect"
    motion = simenv.load(SQUAT)
    record = motion.metadata["joint_map"]
    assert record["convention"] == "azure_kinect"
    assert record["missing"] == []
    for key in ("pelvis", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle",
                "right_ankle"):
        assert record["how"][key] == "name (azure_kinect)", key
    assert motion.fps == azure_kinect.DEFAULT_FPS
    assert "assumed" in motion.metadata["fps_reason"]
    assert motion.metadata["units"] == "m"


def test_real_squat_stands_on_the_floor_and_squats() -> None:
    """In the world frame the person stands upright on the floor (ankles low, head above
    the pelvis, a plausible stature), and the pelvis drops by a squat's depth."""
    motion = simenv.load(SQUAT, fps=SQUAT_FPS)
    assert motion.positions.shape == (150, 32, 3)
    assert motion.fps == SQUAT_FPS
    c = motion.to_canonical()
    z = {k: c.positions[:, i, 2] for i, k in enumerate(c.skeleton.joint_names)}
    ankles = np.median(np.concatenate([z["left_ankle"], z["right_ankle"]]))
    assert 0.0 < ankles < 0.2
    assert np.all(z["head"] > z["pelvis"])
    standing = np.percentile(z["head"], 95) - ankles
    assert 1.2 < standing < 2.0
    assert np.percentile(z["pelvis"], 95) - z["pelvis"].min() > 0.3


def test_offline_json_gives_the_table_motion(tmp_path: Path) -> None:
    """The same real positions in the offline processor's JSON (millimetres, 1.0 SDK names,
    a 15 Hz clock) read as the same world motion, at the clock's rate."""
    raw = _table_positions(SQUAT)
    path = _write_offline_json(tmp_path / "squat.json", _frames_mm(raw, 66_667))
    assert detect(path)[0] == "azure_kinect"
    got = simenv.load(path)
    want = simenv.load(SQUAT, fps=SQUAT_FPS)
    assert got.fps == SQUAT_FPS and got.metadata["units"] == "mm"
    assert got.metadata["body_id"] == 1 and got.metadata["repairs"] == []
    assert np.abs(got.positions - want.positions).max() < 1e-4


def test_offline_json_dropped_frames_resampled_and_body_chosen(tmp_path: Path) -> None:
    """Frames where the body is missing are resampled onto the sensor's grid (logged); of
    two bodies the one in most frames is read unless ``body_id=`` names the other."""
    raw = _table_positions(SQUAT)
    frames = _frames_mm(raw, 66_667)
    for k in (40, 41, 90):
        frames[k] = (frames[k][0], [])
    for k in range(10, 30):  # a second person, 2 m to the side, in 20 frames
        frames[k][1].append((7, raw[k] * 1000.0 + [2000.0, 0.0, 0.0]))
    path = _write_offline_json(tmp_path / "two.json", frames)
    got = simenv.load(path)
    assert got.metadata["body_id"] == 1 and got.fps == SQUAT_FPS
    assert len(got.positions) == len(raw)
    assert "resampled" in got.metadata["repairs"][0]
    want = simenv.load(SQUAT, fps=SQUAT_FPS).positions
    # A kept frame far from the gaps is the table's, up to the floor fit of fewer frames.
    assert np.abs(got.positions[60] - want[60]).max() < 0.02
    other = azure_kinect.read(path, body_id=7)
    assert other.metadata["body_id"] == 7 and len(other.positions) == 20


def test_errors_name_file_line_frame_and_field(tmp_path: Path) -> None:
    lines = SQUAT.read_text(encoding="utf-8-sig").splitlines()
    cells = lines[3].split(",")
    cells[5] = "0.1 0.2"
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([*lines[:3], ",".join(cells), *lines[4:]]) + "\n")
    with pytest.raises(FormatError) as err:
        azure_kinect.read(bad)
    assert err.value.line == 4 and err.value.field == "ShoulderLeft"
    assert "bad.csv" in str(err.value)

    raw = _table_positions(SQUAT)[:5]
    path = _write_offline_json(tmp_path / "one.json", _frames_mm(raw, 33_333))
    with pytest.raises(MotionError, match="body_id 3"):
        azure_kinect.read(path, body_id=3)
    data = json.loads(path.read_text())
    data["frames"][2]["bodies"][0]["joint_positions"] = data["frames"][2]["bodies"][0][
        "joint_positions"][:31]
    path.write_text(json.dumps(data))
    with pytest.raises(FormatError) as err:
        azure_kinect.read(path)
    assert err.value.frame == 2 and err.value.field == "joint_positions"
    data["joint_names"] = SDK_NAMES[:31]
    path.write_text(json.dumps(data))
    with pytest.raises(FormatError, match="joint_names"):
        azure_kinect.read(path)

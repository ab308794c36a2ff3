"""simenv.io.joint_csv on a real Xsens MVN segment-position table (EmoKine, see
tests/data/conventions/SOURCES.md) and on tables computed from it: the same real motion written
as other exporters write it (MVN Excel names, other axes, units, clocks and delimiters, other
joint names), and broken copies for the errors."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import simenv
from simenv.body.retarget import retarget
from simenv.core.errors import FormatError, MotionError, SkeletonError
from simenv.core.motion import Motion
from simenv.io import joint_csv, loader
from simenv.io.camera_frame import FOOT_NOISE_M, KINECT_TO_ZUP

MVN_CSV = (Path(__file__).parent / "data" / "conventions" / "xsens_mvn"
           / "emokine_mvn_segment_positions.csv")
pytestmark = pytest.mark.skipif(not MVN_CSV.exists(), reason=f"{MVN_CSV} absent")

#: The keypoints MVN's 23 segments give (no hand ends: MVN's hand segment starts at the wrist).
MVN_KEYPOINTS = (
    "pelvis", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
    "left_toe", "right_toe", "spine", "chest", "neck", "head", "left_shoulder",
    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
)


def _table() -> tuple[list[str], list[list[str]]]:
    with MVN_CSV.open(newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def _file_positions() -> tuple[np.ndarray, np.ndarray]:
    """(T,) ms clock and (T, 23, 3) positions as written in the file."""
    header, rows = _table()
    data = np.array(rows, dtype=np.float64)
    return data[:, header.index("ms")], data[:, 2:].reshape(len(rows), 23, 3)


def _write(path: Path, header: list[str], rows: list[list[str]], delimiter: str = ",") -> Path:
    with path.open("w", newline="") as fh:
        csv.writer(fh, delimiter=delimiter).writerows([header, *rows])
    return path


@pytest.fixture(scope="module")
def mvn() -> Motion:
    loaded = simenv.load(MVN_CSV)
    assert isinstance(loaded, Motion)
    return loaded


def test_real_mvn_table_loads_with_its_tree_clock_units_and_axes(mvn: Motion) -> None:
    ms, pos = _file_positions()
    assert loader.detect(MVN_CSV)[0] == "joint_csv"
    assert mvn.num_joints == 23 and mvn.skeleton.name == "xsens_mvn23"
    assert mvn.num_frames == len(ms)
    measured = 1000.0 * (len(ms) - 1) / (ms[-1] - ms[0])
    assert mvn.fps == pytest.approx(measured, rel=2e-3)  # 239.96 Hz by the clock -> 240
    assert "'ms'" in mvn.metadata["fps_reason"]
    assert mvn.metadata["units"] == "m" and mvn.metadata["up_axis_in_file"] == "Z"
    # Metres and Z up already: the positions are the file's, joint for joint.
    order = [joint_csv.MVN_SEGMENTS.index(n) for n in mvn.skeleton.joint_names]
    np.testing.assert_allclose(mvn.positions, pos[:, order], atol=1e-6)
    sk = mvn.skeleton
    parent = {n: (sk.joint_names[p] if p >= 0 else None)
              for n, p in zip(sk.joint_names, sk.parents, strict=True)}
    assert parent["Head"] == "Neck" and parent["Neck"] == "T8" and parent["L5"] == "Pelvis"
    assert parent["RightShoulder"] == "T8" and parent["RightHand"] == "RightForeArm"
    assert parent["LeftUpperLeg"] == "Pelvis" and parent["LeftToe"] == "LeftFoot"
    assert set(MVN_KEYPOINTS) <= set(sk.canonical)
    assert sk.canonical["left_hip"] == "LeftUpperLeg" and sk.canonical["chest"] == "T8"
    assert 1.4 < mvn.height() < 2.1  # joint centres, ankle/toe to head segment origin
    lowest = mvn.positions[..., 2].min(axis=1)
    assert -0.05 < float(np.median(lowest)) < 0.1  # toes on MVN's floor


def test_retargets_every_mvn_keypoint(mvn: Motion) -> None:
    result = retarget(mvn)
    assert set(result.keypoint_names) == set(MVN_KEYPOINTS)
    assert np.isfinite(result.residuals).all()
    assert float(np.percentile(result.residuals, 95)) < 0.02


def test_mvn_excel_names_without_clock_need_fps(tmp_path: Path) -> None:
    header, rows = _table()
    spaced = {s: " ".join(_words(s)) for s in joint_csv.MVN_SEGMENTS}
    excel = ["Frame"] + [f"{spaced[c.rsplit('_', 1)[0]]} {c[-1]}" for c in header[2:]]
    path = _write(tmp_path / "segment_position.csv", excel, [[r[0], *r[2:]] for r in rows])
    assert "Right Upper Arm x" in excel
    with pytest.raises(FormatError, match="fps="):
        simenv.load(path)
    m = simenv.load(path, fps=240)
    assert m.fps == 240 and m.skeleton.name == "xsens_mvn23"
    assert set(MVN_KEYPOINTS) <= set(m.skeleton.canonical)


def _words(segment: str) -> list[str]:
    return re.findall(r"[A-Z][a-z]+|[A-Z]\d+|[A-Z]+", segment)


@pytest.mark.parametrize(("up", "unit", "scale"), [("y", "mm", 1000.0), ("-y", "cm", 100.0),
                                                   ("x", "m", 1.0)])
def test_other_axes_units_clock_and_delimiter(tmp_path: Path, up: str, unit: str,
                                              scale: float, mvn: Motion) -> None:
    ms, pos = _file_positions()
    header, _ = _table()
    # The real motion written in another file frame: world = file @ R.T, so file = world @ R.
    file_pos = pos @ joint_csv.UP_TO_Z_UP[up] * scale
    rows = [[f"{(t - ms[0]) / 1000:.6f}", *(f"{v:.6f}" for v in p.ravel())]
            for t, p in zip(ms, file_pos, strict=True)]
    cols = ["Time (Seconds)"] + [c.replace("_", ".") for c in header[2:]]
    m = simenv.load(_write(tmp_path / "t.csv", cols, rows, delimiter=";"))
    assert m.metadata["up_axis_in_file"] == up.upper() and m.metadata["units"] == unit
    assert m.fps == 240
    np.testing.assert_allclose(m.positions, mvn.positions, atol=2e-5 * scale + 1e-5)


def test_names_of_another_convention_get_a_tree_from_their_keypoints(tmp_path: Path,
                                                                     mvn: Motion) -> None:
    # The real motion under SMPL-style joint names (no declared layout): the tree comes from
    # the keypoints the names give; L3/T12 and the clavicles, which name none, hang from the
    # nearest named joint.
    smpl = {"Pelvis": "Pelvis", "L5": "Spine1", "L3": "lumbar_mid", "T12": "thorax_low",
            "T8": "Spine3", "Neck": "Neck", "Head": "Head"}
    for side, s in (("Left", "L"), ("Right", "R")):
        smpl |= {f"{side}UpperLeg": f"{s}_Hip", f"{side}LowerLeg": f"{s}_Knee",
                 f"{side}Foot": f"{s}_Ankle", f"{side}Toe": f"{s}_Foot",
                 f"{side}Shoulder": f"{s}_Collar", f"{side}UpperArm": f"{s}_Shoulder",
                 f"{side}ForeArm": f"{s}_Elbow", f"{side}Hand": f"{s}_Wrist"}
    header, rows = _table()
    cols = header[:2] + [f"{smpl[c.rsplit('_', 1)[0]]}_{c[-1]}" for c in header[2:]]
    m = simenv.load(_write(tmp_path / "smpl_names.csv", cols, rows))
    assert m.metadata["layout"] == "tree from the joint names"
    sk = m.skeleton
    parent = {n: (sk.joint_names[p] if p >= 0 else None)
              for n, p in zip(sk.joint_names, sk.parents, strict=True)}
    assert parent["L_Knee"] == "L_Hip" and parent["L_Hip"] == "Pelvis"
    assert parent["R_Elbow"] == "R_Shoulder" and parent["Head"] == "Neck"
    back = {v: k for k, v in smpl.items()}
    for key in ("pelvis", "left_hip", "right_knee", "left_ankle", "right_toe", "left_shoulder",
                "right_elbow", "left_wrist", "neck", "head"):
        assert back[sk.canonical[key]] == mvn.skeleton.canonical[key], key
        np.testing.assert_allclose(m.joint(sk.canonical[key]),
                                   mvn.joint(mvn.skeleton.canonical[key]), atol=1e-6)


def test_unknown_names_are_an_error_listing_the_columns_and_a_map_reads_them(
        tmp_path: Path) -> None:
    header, rows = _table()
    segs = list(dict.fromkeys(c.rsplit("_", 1)[0] for c in header[2:]))
    alias = {s: f"p{k:02d}" for k, s in enumerate(segs)}
    cols = header[:2] + [f"{alias[c.rsplit('_', 1)[0]]}_{c[-1]}" for c in header[2:]]
    path = _write(tmp_path / "numbered.csv", cols, rows)
    with pytest.raises(SkeletonError, match="p00_x") as err:
        simenv.load(path)
    assert "pelvis" in str(err.value) and "joint_map" in str(err.value)
    user = {"pelvis": alias["Pelvis"], "left_hip": alias["LeftUpperLeg"],
            "right_hip": alias["RightUpperLeg"], "left_knee": alias["LeftLowerLeg"],
            "right_knee": alias["RightLowerLeg"]}
    m = simenv.load(path, joint_map=user)
    assert m.skeleton.canonical == user
    assert m.skeleton.parents[m.skeleton.index(alias["LeftLowerLeg"])] == m.skeleton.index(
        alias["LeftUpperLeg"])


def test_headerless_tables_are_not_claimed(tmp_path: Path) -> None:
    _, rows = _table()
    path = tmp_path / "numbers.csv"
    path.write_text("\n".join(" ".join(r) for r in rows) + "\n")
    assert not joint_csv.sniff(path, path.read_bytes()[:4096])
    with pytest.raises(FormatError, match="header row"):
        simenv.load(path)


def test_missing_axis_column(tmp_path: Path) -> None:
    header, rows = _table()
    drop = header.index("LeftToe_z")
    path = _write(tmp_path / "t.csv", [c for i, c in enumerate(header) if i != drop],
                  [[v for i, v in enumerate(r) if i != drop] for r in rows])
    with pytest.raises(FormatError, match="LeftToe_x.*no z column") as err:
        simenv.load(path)
    assert err.value.field == "LeftToe" and err.value.line == 1


def test_nan_cells_name_row_and_column_or_are_interpolated(tmp_path: Path, mvn: Motion) -> None:
    header, rows = _table()
    col = header.index("RightHand_y")
    for k in (40, 41, 42):
        rows[k][col] = "NaN"
    rows[43][col] = ""
    path = _write(tmp_path / "t.csv", header, rows)
    with pytest.raises(MotionError, match="RightHand") as err:
        simenv.load(path)
    assert (err.value.line, err.value.frame, err.value.field) == (42, 40, "RightHand")
    m = simenv.load(path, gaps="interpolate")
    assert any("RightHand" in r for r in m.metadata["repairs"])
    j = m.skeleton.index("RightHand")
    good = [39, 44]
    np.testing.assert_allclose(m.positions[good, j], mvn.positions[good, j], atol=1e-6)
    assert np.isfinite(m.positions).all()


def test_one_row(tmp_path: Path) -> None:
    header, rows = _table()
    with pytest.raises(MotionError, match="at least 2 frames"):
        simenv.load(_write(tmp_path / "t.csv", header, rows[:1]))


def test_non_numeric_cell(tmp_path: Path) -> None:
    header, rows = _table()
    rows[10][header.index("Head_z")] = "1,58a"
    with pytest.raises(FormatError, match="expected a number") as err:
        simenv.load(_write(tmp_path / "t.csv", header, rows))
    assert (err.value.line, err.value.field) == (12, "Head_z")


def test_time_going_backwards(tmp_path: Path) -> None:
    header, rows = _table()
    t = header.index("ms")
    rows[100][t], rows[101][t] = rows[101][t], rows[100][t]
    with pytest.raises(FormatError, match="goes backwards") as err:
        simenv.load(_write(tmp_path / "t.csv", header, rows))
    assert (err.value.line, err.value.field) == (103, "ms")


def test_dropped_frames_are_an_error_or_a_logged_resampling(tmp_path: Path,
                                                            mvn: Motion) -> None:
    header, rows = _table()
    kept = rows[:120] + rows[123:]  # three frames lost
    path = _write(tmp_path / "t.csv", header, kept)
    with pytest.raises(FormatError, match="irregular time") as err:
        simenv.load(path)
    assert err.value.line == 122
    m = simenv.load(path, irregular_time="resample")
    assert m.fps == 240 and any("resampled" in r for r in m.metadata["repairs"])
    assert abs(m.num_frames - mvn.num_frames) <= 1
    # Away from the hole the grid meets the real frames within one clock tick of motion.
    np.testing.assert_allclose(m.positions[:100], mvn.positions[:100], atol=5e-3)


def test_depth_camera_coordinates_are_levelled_onto_the_floor(tmp_path: Path,
                                                               mvn: Motion) -> None:
    # The real motion as a depth camera would see it: sensor 2.5 m in front, 1.1 m high,
    # pitched 12 deg down, y down (Azure Kinect / OpenCV), millimetres.
    ms, pos = _file_positions()
    header, _ = _table()
    sensor = (Rotation.from_euler("z", 180, degrees=True)
              * Rotation.from_euler("y", 12, degrees=True)).as_matrix()
    cam = ((pos - [2.5, 0.1, 1.1]) @ sensor @ KINECT_TO_ZUP @ joint_csv.Y_DOWN_TO_Y_UP) * 1000
    rows = [[f"{t:.0f}", *(f"{v:.3f}" for v in c.ravel())] for t, c in zip(ms, cam, strict=True)]
    path = _write(tmp_path / "camera.csv", ["ms", *header[2:]], rows)
    m = simenv.load(path, frame="camera")
    assert m.metadata["up_axis_in_file"] == "-Y" and m.metadata["units"] == "mm"
    assert "camera_frame" in m.metadata and m.fps == 240
    w = m.positions.astype(np.float64)
    dist = np.linalg.norm(w[:, :, None] - w[:, None], axis=-1)
    ref = np.linalg.norm(mvn.positions[:, :, None] - mvn.positions[:, None], axis=-1)
    np.testing.assert_allclose(dist, ref, atol=1e-4)  # a rigid motion of the real clip
    # Levelled onto the floor from the feet: heights as captured, within the foot noise.
    assert np.abs(w[..., 2] - mvn.positions[..., 2]).max() < FOOT_NOISE_M


def test_a_preamble_above_the_header_is_skipped(tmp_path: Path, mvn: Motion) -> None:
    # LSL Kinect writes "Software : LSL_Kinect,Version : ...,Stream nominal rate : 15" and a
    # blank line above its header.
    path = tmp_path / "preamble.csv"
    path.write_text("Software : recorder,Version : 1.0,Stream nominal rate : 240\n\n"
                    + MVN_CSV.read_text())
    assert joint_csv.sniff(path, b"")
    m = simenv.load(path)
    np.testing.assert_array_equal(m.positions, mvn.positions)


AZURE_SQUAT = (Path(__file__).parent / "data" / "conventions" / "azure_kinect"
               / "gymtrainer_bodyweight_squat_side_view.csv")


def test_azure_kinect_1_0_spelling_is_still_the_declared_layout(tmp_path: Path) -> None:
    """Body Tracking 1.0 renamed ``SPINE_NAVAL`` to ``SPINE_NAVEL``: a real Azure Kinect
    squat (tests/data/conventions/azure_kinect) written as ``<joint>.x`` columns in mm with
    the new name is still the Azure layout in camera coordinates, read as the Azure reader
    reads the recording (not as a world frame with the feet 0.8 m below z = 0)."""
    lines = AZURE_SQUAT.read_text(encoding="utf-8-sig").splitlines()[1:]
    raw = np.array([[c.split() for c in r.split(",")] for r in lines], dtype=np.float64)
    names = [j.replace("SPINE_NAVAL", "SPINE_NAVEL") for j in joint_csv.AZURE_KINECT_JOINTS]
    rows = [[str(round(k * 1e6 / 15)), *(f"{v:.3f}" for v in xyz.ravel() * 1000)]
            for k, xyz in enumerate(raw)]
    path = _write(tmp_path / "azure.csv",
                  ["timestamp_us", *(f"{n}.{a}" for n in names for a in "xyz")], rows)
    m = simenv.load(path)
    assert m.metadata["layout"] == "azure_kinect32" and "camera_frame" in m.metadata
    assert m.skeleton.canonical["spine"] == "SPINE_NAVEL" and m.fps == 15
    want = simenv.load(AZURE_SQUAT, fps=15)
    assert np.abs(m.positions - want.positions).max() < 1e-3

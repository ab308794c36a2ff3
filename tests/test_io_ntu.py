"""NTU RGB+D ``.skeleton`` reader. No NTU file is in the corpus (its licence
forbids redistribution), so files are written in the documented format from
real Kinect v1 recordings (MSR Action3D) mapped onto the 25 Kinect v2 joints,
and read back."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from expect import rejects_lines

from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Interaction, Motion
from simenv.core.skeletons import kinect_v1_skeleton, kinect_v2_skeleton
from simenv.io import msr_action3d, ntu

MSR = "gestures/msr_action3d"


def v2_from_msr(path: Path) -> np.ndarray:
    """(T, 25, 3) camera-frame metres on the Kinect v2 skeleton from a raw MSR
    file. Joints v1 lacks are computed from measured ones: Neck halfway
    between ShoulderCenter and Head, HandTip one wrist-hand length past the
    hand, Thumb at the hand."""
    raw = np.loadtxt(path).reshape(-1, 20, 4)[:, msr_action3d.MSR_TO_SDK, :3]
    v1 = kinect_v1_skeleton()
    j = {n: raw[:, v1.index(n)] for n in v1.joint_names}
    rename = {"SpineBase": "HipCenter", "SpineMid": "Spine", "SpineShoulder": "ShoulderCenter"}
    out = []
    for name in kinect_v2_skeleton().joint_names:
        if name in j or name in rename:
            out.append(j[rename.get(name, name)])
        elif name == "Neck":
            out.append((j["ShoulderCenter"] + j["Head"]) / 2)
        elif name.startswith("HandTip"):
            side = name[len("HandTip"):]
            out.append(2 * j[f"Hand{side}"] - j[f"Wrist{side}"])
        else:  # Thumb
            out.append(j[f"Hand{name[len('Thumb'):]}"])
    return np.stack(out, axis=1)


def test_round_trip_one_body(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / MSR / "a05_s03_e01_skeleton3D.txt"
    cam = v2_from_msr(src)
    f = tmp_path / "S001C001P003R001A005.skeleton"
    ntu.write(f, [cam])
    assert ntu.sniff(f, f.read_bytes()[:4096])
    m = ntu.read(f)
    assert isinstance(m, Motion) and m.skeleton.name == "kinect_v2_25" and m.fps == 30.0
    ref = msr_action3d.read(src)  # same joints drive the floor estimate -> same world frame
    for v2, v1 in (("SpineBase", "HipCenter"), ("Head", "Head"), ("HandRight", "HandRight"),
                   ("FootLeft", "FootLeft")):
        np.testing.assert_allclose(m.joint(v2), ref.joint(v1), atol=1e-4)
    assert m.metadata["camera_frame"]["tilt_deg"] == pytest.approx(
        ref.metadata["camera_frame"]["tilt_deg"], abs=1e-3)


def test_two_bodies_and_missing_frames(shared_data: Path, tmp_path: Path) -> None:
    a = v2_from_msr(shared_data / MSR / "a06_s01_e01_skeleton3D.txt")
    b = v2_from_msr(shared_data / MSR / "a06_s02_e01_skeleton3D.txt")
    n = min(len(a), len(b))
    a, b = a[:n], b[:n] + [1.2, 0.0, 0.3]  # second person 1.2 m to the sensor's left
    b[5:8] = np.nan  # not seen in three frames
    f = tmp_path / "pair.skeleton"
    ntu.write(f, [a, b])
    inter = ntu.read(f)
    assert isinstance(inter, Interaction) and inter.num_frames == n
    assert any("missing" in r for r in inter.reactor.metadata["repairs"])
    gap = np.linalg.norm(inter.actor.joint("SpineBase") - inter.reactor.joint("SpineBase"), axis=1)
    assert np.median(gap) == pytest.approx(np.hypot(1.2, 0.3), abs=0.25)
    # A body seen in too few frames is ignored.
    b[: n - 3] = np.nan
    ntu.write(f, [a, b])
    single = ntu.read(f)
    assert isinstance(single, Motion) and single.metadata["quirks"]


def _written(shared_data: Path, tmp_path: Path) -> list[str]:
    f = tmp_path / "ok.skeleton"
    ntu.write(f, [v2_from_msr(shared_data / MSR / "a05_s03_e01_skeleton3D.txt")[:3]])
    return f.read_text().splitlines()


@pytest.mark.parametrize("edit, message, line", [
    (lambda ls: ls[:-5], "file ends early", 81),
    (lambda ls: ls[:3] + ["24"] + ls[4:], "joint count 24", 4),
    (lambda ls: ls[:6] + [ls[6].replace("0 0 0 0", "0 0 zz 0", 1)] + ls[7:], "expected numbers",
     7),
    (lambda ls: ls[:6] + [ls[6] + " 1"] + ls[7:], "expected 12 values", 7),
    (lambda ls: ls + ["1"], "unexpected data", 86),
    (lambda ls: ["x"] + ls[1:], "expected an integer", 1),
])
def test_bad_input(shared_data: Path, tmp_path: Path, edit, message: str, line: int) -> None:
    lines = _written(shared_data, tmp_path)
    assert len(lines) == 1 + 3 * 28
    rejects_lines(ntu.read, tmp_path / "bad.skeleton", edit(lines), message, line)


def test_empty_and_bodiless(tmp_path: Path) -> None:
    f = tmp_path / "empty.skeleton"
    f.write_text("")
    with pytest.raises(FormatError, match="empty"):
        ntu.read(f)
    f.write_text("2\n0\n0\n")
    with pytest.raises(MotionError, match="no body"):
        ntu.read(f)

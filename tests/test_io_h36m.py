"""H36M-17 arrays, computed from a real Kinect recording's canonical keypoints."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Motion
from simenv.core.skeletons import H36M_JOINTS, h36m_skeleton
from simenv.io import h36m, utkinect
from simenv.io.camera_frame import KINECT_TO_ZUP

UTK = "gestures/utkinect/joints/joints_s02_e01.txt"
# H36M joint -> canonical keypoint of the Kinect clip (Head = head top, computed).
FROM_CANONICAL = {
    "Hip": "pelvis", "RHip": "right_hip", "RKnee": "right_knee", "RFoot": "right_ankle",
    "LHip": "left_hip", "LKnee": "left_knee", "LFoot": "left_ankle", "Spine": "spine",
    "Thorax": "neck", "Neck/Nose": "head", "LShoulder": "left_shoulder",
    "LElbow": "left_elbow", "LWrist": "left_wrist", "RShoulder": "right_shoulder",
    "RElbow": "right_elbow", "RWrist": "right_wrist",
}


def h36m_array(m: Motion) -> np.ndarray:
    """(T, 17, 3) world metres; the head top is 10 cm above the head joint."""
    c = m.to_canonical()
    cols = []
    for name in H36M_JOINTS:
        if name == "Head":
            cols.append(c.joint("head") + [0.0, 0.0, 0.10])
        else:
            cols.append(c.joint(FROM_CANONICAL[name]))
    return np.stack(cols, axis=1)


@pytest.fixture(scope="module")
def clip(shared_data: Path) -> tuple[Motion, np.ndarray]:
    m = utkinect.read(shared_data / UTK)
    return m, h36m_array(m)


def test_npy_in_mm_round_trip(clip, tmp_path: Path) -> None:
    m, arr = clip
    f = tmp_path / "S1_walk.npy"
    np.save(f, (arr * 1000).astype(np.float32))
    assert h36m.sniff(f, f.read_bytes()[:4096])
    h = h36m.read(f, fps=m.fps)
    assert h.metadata["units"] == "mm" and h.skeleton == h36m_skeleton()
    np.testing.assert_allclose(h.positions, arr, atol=1e-4)
    # The canonical view agrees with the source's canonical keypoints.
    src, got = m.to_canonical(), h.to_canonical()
    for key in got.skeleton.joint_names:
        np.testing.assert_allclose(got.joint(key), src.joint(key), atol=1e-4)
    flat = h36m.from_array(arr.reshape(len(arr), 51), fps=50)
    np.testing.assert_allclose(flat.positions, arr, atol=1e-6)
    assert flat.metadata["units"] == "m"


def test_camera_frame_is_levelled(clip) -> None:
    m, arr = clip
    # An OpenCV camera (x right, y down, z forward), level, 1.3 m above the floor.
    kinect = (arr - [0.0, 0.0, 1.3]) @ KINECT_TO_ZUP
    opencv = kinect * [-1.0, -1.0, 1.0]
    h = h36m.from_array(opencv, frame="camera", fps=m.fps)
    assert h.metadata["camera_frame"]["sensor_height_m"] == pytest.approx(1.3, abs=0.08)
    np.testing.assert_allclose(h.positions[..., 2], arr[..., 2], atol=0.08)


def test_npz(clip, tmp_path: Path) -> None:
    _, arr = clip
    one = tmp_path / "one.npz"
    np.savez(one, positions_3d=arr)
    assert h36m.sniff(one, one.read_bytes()[:4096])
    assert h36m.read(one).num_frames == len(arr)
    two = tmp_path / "two.npz"
    np.savez(two, a=arr, b=arr[:10])
    with pytest.raises(FormatError, match="exactly one"):
        h36m.read(two)
    assert h36m.read(two, key="b").num_frames == 10
    ours = tmp_path / "simenv.npz"
    np.savez(ours, positions=arr, joint_names=np.array(H36M_JOINTS))
    assert not h36m.sniff(ours, ours.read_bytes()[:4096])
    pickled = tmp_path / "videopose.npz"
    np.savez(pickled, positions_3d=np.array([{"S1": arr}], dtype=object))
    with pytest.raises(FormatError, match="without pickle"):
        h36m.read(pickled)


def test_bad_arrays(clip, tmp_path: Path) -> None:
    _, arr = clip
    with pytest.raises(MotionError, match=r"expected \(T, 17, 3\)"):
        h36m.from_array(arr[:, :16])
    bad = arr.copy()
    bad[4, 13, 1] = np.nan
    with pytest.raises(MotionError, match="non-finite") as err:
        h36m.from_array(bad)
    assert err.value.frame == 4 and err.value.field == "LWrist"
    junk = tmp_path / "junk.npy"
    junk.write_bytes(b"\x93NUMPY garbage")
    with pytest.raises(FormatError):
        h36m.read(junk)

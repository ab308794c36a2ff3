"""Camera frame -> Z-up world with the floor from the feet, on real Kinect
recordings and on real recordings put back into synthetic sensor poses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from simenv.core.errors import MotionError
from simenv.core.skeletons import florence_skeleton, gesture9_skeleton, get_skeleton
from simenv.io import camera_frame, msr_action3d, utkinect
from simenv.io.camera_frame import (
    KINECT_TO_ZUP,
    camera_to_world,
    centre_of_mass,
    estimate_floor,
    standing_up,
)

UTK = "gestures/utkinect/joints"


def _low_foot(m) -> np.ndarray:
    sk = m.skeleton
    idx = [sk.index(sk.canonical[k]) for k in ("left_toe", "right_toe") if k in sk.canonical]
    return m.positions[:, idx, 2].min(axis=1)


def test_axes_are_a_proper_rotation() -> None:
    assert np.linalg.det(KINECT_TO_ZUP) == pytest.approx(1.0)
    # camera z (depth) -> world X, camera x (sensor left) -> world Y, camera y -> Z
    np.testing.assert_array_equal(KINECT_TO_ZUP @ [0, 0, 1], [1, 0, 0])
    np.testing.assert_array_equal(KINECT_TO_ZUP @ [1, 0, 0], [0, 1, 0])
    np.testing.assert_array_equal(KINECT_TO_ZUP @ [0, 1, 0], [0, 0, 1])


def test_real_sessions_upright_feet_on_floor(shared_data: Path) -> None:
    files = sorted((shared_data / UTK).glob("joints_*.txt"))
    heights = []
    for f in files:
        m = utkinect.read(f)
        sk = m.skeleton
        head = m.joint("Head")[:, 2]
        pelvis = m.joint("HipCenter")[:, 2]
        assert (head > pelvis).mean() > 0.95, f.name
        low = _low_foot(m)
        # Kinect forefoot joints sit ~3 cm above the sole: lowest foot near the floor.
        assert abs(np.median(low) - 0.03) < 0.06, (f.name, np.median(low))
        assert np.percentile(low, 5) > -0.12, f.name
        # The person faces the sensor (sensor at the origin looking along +X).
        left = m.joint(sk.canonical["left_shoulder"])
        right = m.joint(sk.canonical["right_shoulder"])
        facing = np.median(np.cross(left - right, [0, 0, 1]), axis=0)
        assert facing[0] < 0, f.name
        cf = m.metadata["camera_frame"]
        assert 0.5 < cf["sensor_height_m"] < 2.2
        assert cf["tilt_deg"] < 20
        heights.append(cf["sensor_height_m"])
    assert len(heights) == 20


@pytest.mark.parametrize("pitch_down, roll_deg, height", [(12.0, 0.0, 1.1), (-8.0, 5.0, 0.7),
                                                         (25.0, -3.0, 1.8)])
def test_recovers_a_known_sensor_pose(shared_data: Path, pitch_down: float, roll_deg: float,
                                      height: float) -> None:
    """A levelled real walk, seen from a synthetic sensor with known pitch,
    roll and height, must come back level with that pose estimated."""
    m = utkinect.read(shared_data / UTK / "joints_s04_e01.txt")
    world = m.positions.astype(np.float64)
    # world -> camera: undo the axis permutation of a level sensor at `height`,
    # then express it in a sensor pitched down (a rotation of the coordinates
    # by -pitch about x: what is ahead appears higher) and rolled about z.
    level_cam = (world - [0, 0, height]) @ KINECT_TO_ZUP  # rows: inverse permutation
    tilt = Rotation.from_euler("xz", [-pitch_down, roll_deg], degrees=True).as_matrix()
    cam = level_cam @ tilt.T
    back, est = camera_to_world(cam, m.skeleton)
    assert est.sensor_height_m == pytest.approx(height, abs=0.1)
    assert est.pitch_down_deg == pytest.approx(pitch_down, abs=2.0)
    assert est.roll_deg == pytest.approx(-roll_deg, abs=2.0)
    # Same heights as the original levelling (yaw may differ): compare z only.
    np.testing.assert_allclose(back[..., 2], world[..., 2], atol=0.1)


def test_shared_floor_for_two_people(shared_data: Path) -> None:
    a = msr_action3d.read(shared_data / "gestures/msr_action3d/a06_s01_e01_skeleton3D.txt")
    b = msr_action3d.read(shared_data / "gestures/msr_action3d/a06_s02_e01_skeleton3D.txt")
    # Back to (level) camera coordinates: both clips are already levelled.
    cam_a, cam_b = a.positions @ KINECT_TO_ZUP, b.positions @ KINECT_TO_ZUP
    est = estimate_floor([(cam_a, a.skeleton), (cam_b, b.skeleton)])
    assert est.floor_points > len(a) and est.tilt_deg < 3
    assert abs(est.sensor_height_m) < 0.05


def test_errors_for_unusable_input(shared_data: Path) -> None:
    m = utkinect.read(shared_data / UTK / "joints_s01_e01.txt")
    upside_down = m.positions * np.array([1, 1, -1])
    cam = upside_down @ KINECT_TO_ZUP
    with pytest.raises(MotionError, match="y-up"):
        camera_to_world(cam, m.skeleton)
    g9 = gesture9_skeleton()
    with pytest.raises(MotionError, match="no ankle or toe"):
        camera_to_world(np.zeros((3, 9, 3)), g9)
    assert get_skeleton("kinect_v1_20") == m.skeleton


#: OpenNI / NiTE joint names (as NiTE-to-BVH tools write them) of the Kinect v1 joints that
#: have one, and the parent of each in the tree those tools write (rooted at the torso).
OPENNI_BVH = {"Spine": ("TORSO", None), "ShoulderCenter": ("NECK", "Spine"),
              "Head": ("HEAD", "ShoulderCenter"),
              **{f"{k}{s}": (f"{s.upper()}_{n}", p.format(s)) for s in ("Left", "Right")
                 for k, n, p in (("Shoulder", "SHOULDER", "ShoulderCenter"),
                                 ("Elbow", "ELBOW", "Shoulder{}"), ("Wrist", "HAND", "Elbow{}"),
                                 ("Hip", "HIP", "Spine"), ("Knee", "KNEE", "Hip{}"),
                                 ("Ankle", "FOOT", "Knee{}"))}}


def _write_position_bvh(path: Path, names: list[str], parents: list[int], pos: np.ndarray,
                        fps: float) -> None:
    """A BVH whose every joint carries its position channels (the layout NiTE exporters and
    Trinity's rig use): local translations from ``pos`` (T, J, 3) in file units, Y up, no
    rotation."""
    local = pos - np.where(np.array(parents)[None, :, None] >= 0,
                           pos[:, [max(p, 0) for p in parents]], 0.0)
    lines = ["HIERARCHY"]

    def joint(j: int, depth: int) -> None:
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if parents[j] < 0 else 'JOINT'} {names[j]}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {' '.join(f'{v:.3f}' for v in local[0, j])}")
        lines.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation "
                     "Yrotation")
        children = [c for c, p in enumerate(parents) if p == j]
        for c in children:
            joint(c, depth + 1)
        if not children:
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0 0 0",
                          f"{pad}  }}"])
        lines.append(f"{pad}}}")

    joint(parents.index(-1), 0)
    order: list[int] = []

    def walk(j: int) -> None:
        order.append(j)
        for c in (c for c, p in enumerate(parents) if p == j):
            walk(c)

    walk(parents.index(-1))
    lines += ["MOTION", f"Frames: {len(pos)}", f"Frame Time: {1 / fps:.6f}"]
    lines += [" ".join(f"{v:.3f} {w:.3f} {u:.3f} 0 0 0" for v, w, u in local[t, order])
              for t in range(len(pos))]
    path.write_text("\n".join(lines) + "\n")


def test_depth_camera_skeleton_written_as_bvh_is_levelled_and_judged_as_one(
        shared_data: Path, tmp_path: Path) -> None:
    """A real Kinect v1 walk seen from a sensor 1.1 m up, pitched 12 deg down, written as a
    NiTE-style BVH (OpenNI names, millimetres, the camera's y up): the file's zero is the
    sensor, not the floor. ``simenv.load`` maps it by the OpenNI names, levels it onto the floor
    its feet give (the sensor's height recovered) and the scorer judges it by the Kinect v1
    profile."""
    import simenv
    from simenv.plausibility.profiles import detect_source

    m = utkinect.read(shared_data / UTK / "joints_s04_e01.txt")
    world = m.positions.astype(np.float64)
    level_cam = (world - [0, 0, 1.1]) @ KINECT_TO_ZUP
    cam = level_cam @ Rotation.from_euler("x", -12.0, degrees=True).as_matrix().T
    keys = list(OPENNI_BVH)
    names = [OPENNI_BVH[k][0] for k in keys]
    parents = [-1 if OPENNI_BVH[k][1] is None else keys.index(OPENNI_BVH[k][1]) for k in keys]
    idx = [m.skeleton.index(k) for k in keys]
    path = tmp_path / "nite_walk.bvh"
    _write_position_bvh(path, names, parents, 1000.0 * cam[:, idx], m.fps)

    loaded = simenv.load(path)
    assert loaded.metadata["joint_map"]["convention"] == "openni"
    cf = loaded.metadata["camera_frame"]
    assert cf["sensor_height_m"] == pytest.approx(1.1, abs=0.1)
    assert cf["pitch_down_deg"] == pytest.approx(12.0, abs=2.0)
    ankles = loaded.to_canonical()
    low = np.minimum(ankles.joint("left_ankle")[:, 2], ankles.joint("right_ankle")[:, 2])
    reference = np.minimum(world[:, m.skeleton.index("AnkleLeft"), 2],
                           world[:, m.skeleton.index("AnkleRight"), 2])
    np.testing.assert_allclose(low, reference, atol=0.1)
    kind = detect_source(loaded)
    assert (kind.kind, kind.profile, kind.how) == ("kinect_v1", "kinect_v1",
                                                    "joint names openni")


def _openni_keypoints(path: Path, seconds: tuple[float, float]) -> np.ndarray:
    """Real CMU motion capture (Z up, metres) from ``seconds[0]`` to ``seconds[1]`` at 30 fps
    as an OpenNI / NiTE-like 15-joint skeleton (no toes: each joint at its canonical
    keypoint), the way a depth camera's tracker would give it."""
    import simenv

    m = simenv.load(path)
    c = m.to_canonical()
    step = int(round(m.fps / 30.0))
    a, b = (int(round(s * m.fps)) for s in seconds)
    sk = florence_skeleton()
    inverse = {v: k for k, v in sk.canonical.items()}
    return np.stack([c.joint(inverse[n])[a:b:step] for n in sk.joint_names], axis=1).astype(
        np.float64)


def _seen_by(world: np.ndarray, pitch_down: float, roll_deg: float, height: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """World positions in the camera frame of a sensor with that pose, and the true world
    up in camera coordinates."""
    tilt = Rotation.from_euler("xz", [-pitch_down, roll_deg], degrees=True).as_matrix()
    return ((world - [0, 0, height]) @ KINECT_TO_ZUP) @ tilt.T, tilt @ [0.0, 1.0, 0.0]


def _error_deg(est, up: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(est.up_camera @ up, -1.0, 1.0))))


def test_in_place_gesture_levelled_by_its_centre_of_mass(
        shared_data: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A real boxer punching in place (CMU 02_05, knees bent, shanks leaning 17-25 deg) seen
    by a sensor pitched 15 deg down and rolled 4: the feet stay in one floor cell, so the
    prior decides the tilt. The centre of mass over the feet recovers the vertical within
    3 deg; the body axis (shanks and trunk) misses it by more than 10."""
    world = _openni_keypoints(shared_data / "cmu/asf_amc/02_05.amc", (0.0, 4.0))
    cam, up = _seen_by(world, 15.0, 4.0, 1.0)
    sk = florence_skeleton()
    est = estimate_floor([(cam, sk)])
    assert est.prior == "centre of mass over feet"
    assert _error_deg(est, up) < 3.0
    assert est.sensor_height_m == pytest.approx(1.0, abs=0.1)
    monkeypatch.setattr(camera_frame, "IN_PLACE_SPREAD_M", -1.0)  # nobody in place: old prior
    old = estimate_floor([(cam, sk)])
    assert old.prior == "body axis"
    assert _error_deg(old, up) > 10.0


def test_walk_keeps_the_body_axis_prior(shared_data: Path,
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """A real walk (CMU 16_15) as OpenNI keypoints in a tilted sensor: the feet spread over
    the floor, nobody is in place, and the estimate is the one the body-axis prior gave."""
    world = _openni_keypoints(shared_data / "cmu/bvh/16_15.bvh", (0.0, 8.0))
    cam, up = _seen_by(world, 20.0, -5.0, 1.2)
    sk = florence_skeleton()
    assert standing_up(world, sk) is None
    est = estimate_floor([(cam, sk)])
    monkeypatch.setattr(camera_frame, "IN_PLACE_SPREAD_M", -1.0)
    old = estimate_floor([(cam, sk)])
    assert est.prior == old.prior == "body axis"
    assert float(np.degrees(np.arccos(np.clip(est.up_camera @ old.up_camera, -1, 1)))) < 0.01
    assert _error_deg(est, up) < 2.0


def test_centre_of_mass_of_a_standing_person(shared_data: Path) -> None:
    """de Leva's keypoint model on real motion capture of a person standing in place (CMU
    18_01, waiting to shake hands): the centre of mass sits 0.85-1.05 m up, at 60-70 % of
    the head keypoint's height (about 56 % of stature over a skull base at about 87 %), and
    over the feet (within 15 cm of the ankles' midpoint)."""
    world = _openni_keypoints(shared_data / "cmu/two_person/18_19_walk_shake_hands/18_01.bvh",
                              (1.5, 5.5))
    sk = florence_skeleton()
    com = centre_of_mass(world, sk)
    assert com is not None and com.shape == (len(world), 3)
    head = world[:, sk.index("Head"), 2]
    assert 0.85 < np.median(com[:, 2]) < 1.05
    assert 0.60 < np.median(com[:, 2] / head) < 0.70
    ankles = world[:, [sk.index("LeftAnkle"), sk.index("RightAnkle")]].mean(axis=1)
    assert np.percentile(np.linalg.norm((com - ankles)[:, :2], axis=1), 90) < 0.15
    assert centre_of_mass(world[:, :9], gesture9_skeleton()) is None  # no legs: no estimate

"""Mapping skeletons never seen onto the canonical keypoints (:mod:`simenv.core.joint_map`),
on real motion capture: the library's own skeletons, real CMU clips re-exported under each
naming convention's joint names (and with no names at all), and real files of other labs
(tests/data/conventions, see its SOURCES.md)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import simenv
from simenv.core import skeletons
from simenv.core.errors import RetargetError, SkeletonError
from simenv.core.joint_map import (
    CONVENTIONS,
    HOW_REST_POSE,
    HOW_TOPOLOGY,
    HOW_USER,
    infer_joint_map,
    joint_map_template,
    normalise,
    read_joint_map,
)
from simenv.io import bvh
from simenv.io._kinematics import rest_extent
from simenv.io.joint_csv import azure_kinect_skeleton

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
CONVENTIONS_DIR = Path(__file__).parent / "data" / "conventions"
WALK = DATA / "cmu" / "bvh" / "02_01.bvh"

needs_data = pytest.mark.skipif(not WALK.exists(), reason=f"shared CMU data absent ({WALK})")


@pytest.mark.parametrize(("name", "side", "stem"), [
    ("mixamorig:LeftUpLeg", "left", "upleg"),
    ("mixamorig7:RightHand", "right", "hand"),
    ("Bip01 L Thigh", "left", "thigh"),
    ("Bip01 Pelvis", None, "pelvis"),
    ("thigh_l", "left", "thigh"),
    ("UpperLeg_L", "left", "upperleg"),
    ("LThigh", "left", "thigh"),
    ("LUArm", "left", "uarm"),
    ("lShldr", "left", "shldr"),
    ("L_Hip", "left", "hip"),
    ("HipRight", "right", "hip"),
    ("HIP_LEFT", "left", "hip"),
    ("thigh.R", "right", "thigh"),
    ("spine_01", None, "spine1"),
    ("L5", None, "l5"),
    ("LowerBack", None, "lowerback"),
    ("Character1_LeftArm", "left", "arm"),
])
def test_normalise(name: str, side: str | None, stem: str) -> None:
    n = normalise(name)
    assert (n.side, n.stem) == (side, stem)


@pytest.mark.parametrize("make", [skeletons.smpl22_skeleton, skeletons.kinect_v1_skeleton,
                                  skeletons.kinect_v2_skeleton, skeletons.nuitrack_skeleton,
                                  skeletons.sbu_skeleton, skeletons.florence_skeleton])
def test_names_alone_give_the_library_maps(make) -> None:
    """The library's hand-written maps of real sensor and body-model skeletons are what the
    conventions table finds from their names and hierarchy (Nuitrack's neck aside: its
    reader uses the collar point, the name says JOINT_NECK)."""
    sk = make()
    found = infer_joint_map(sk.joint_names, sk.parents).canonical
    expected = dict(sk.canonical)
    if sk.name == "nuitrack":
        expected["neck"] = "JOINT_NECK"
    assert found == expected


@pytest.mark.parametrize("spine", ["SPINE_NAVEL", "SpineNavel", "SPINE_NAVAL"])
def test_azure_kinect_spine_in_every_sdk_spelling(spine: str) -> None:
    """The Body Tracking SDK 1.0 renamed ``SPINE_NAVAL`` to ``SPINE_NAVEL`` (the C# SDK's
    ``JointId.SpineNavel``): every spelling is the spine by name, not only by topology."""
    sk = azure_kinect_skeleton()
    names = [spine if n == "SPINE_NAVAL" else n for n in sk.joint_names]
    mapping = infer_joint_map(names, sk.parents)
    assert mapping.canonical["spine"] == spine
    assert mapping.how["spine"] == "name (azure_kinect)"


# Real CMU clips re-exported under each convention's joint names. Keys are the cgspeed
# MotionBuilder names of CMU-31 with {s} for the side (Left/Right) and {c} for L/R; values
# the convention's name for the same joint, same placeholders.
_CMU31 = ["Hips", "{c}HipJoint", "{s}UpLeg", "{s}Leg", "{s}Foot", "{s}ToeBase", "LowerBack",
          "Spine", "Spine1", "Neck", "Neck1", "Head", "{s}Shoulder", "{s}Arm", "{s}ForeArm",
          "{s}Hand", "{s}FingerBase", "{s}HandIndex1", "{c}Thumb"]
RENAMES: dict[str, list[str]] = {
    "mixamo": ["mixamorig:Hips", "mixamorig:{s}HipBone", "mixamorig:{s}UpLeg", "mixamorig:{s}Leg",
               "mixamorig:{s}Foot", "mixamorig:{s}ToeBase", "mixamorig:Spine",
               "mixamorig:Spine1", "mixamorig:Spine2", "mixamorig:Neck", "mixamorig:Neck1",
               "mixamorig:Head", "mixamorig:{s}Shoulder", "mixamorig:{s}Arm",
               "mixamorig:{s}ForeArm", "mixamorig:{s}Hand", "mixamorig:{s}HandMiddle1",
               "mixamorig:{s}HandIndex1", "mixamorig:{s}HandThumb1"],
    "unity_suffix": ["Hips", "HipBone_{c}", "UpperLeg_{c}", "LowerLeg_{c}", "Foot_{c}",
                     "Toes_{c}", "Spine", "Chest", "UpperChest", "Neck", "Neck2", "Head",
                     "Shoulder_{c}", "UpperArm_{c}", "LowerArm_{c}", "Hand_{c}",
                     "MiddleProximal_{c}", "IndexProximal_{c}", "ThumbProximal_{c}"],
    "unreal": ["pelvis", "hipbone_{l}", "thigh_{l}", "calf_{l}", "foot_{l}", "ball_{l}",
               "spine_01", "spine_02", "spine_03", "neck_01", "neck_02", "head", "clavicle_{l}",
               "upperarm_{l}", "lowerarm_{l}", "hand_{l}", "middle_01_{l}", "index_01_{l}",
               "thumb_01_{l}"],
    "smpl": ["Pelvis", "{c}_HipBone", "{c}_Hip", "{c}_Knee", "{c}_Ankle", "{c}_Foot", "Spine1",
             "Spine2", "Spine3", "Neck", "Neck_Upper", "Head", "{c}_Collar", "{c}_Shoulder",
             "{c}_Elbow", "{c}_Wrist", "{c}_Middle1", "{c}_Index1", "{c}_Thumb1"],
    "biped": ["Bip01 Pelvis", "Bip01 {c} HipBone", "Bip01 {c} Thigh", "Bip01 {c} Calf",
              "Bip01 {c} Foot", "Bip01 {c} Toe0", "Bip01 Spine", "Bip01 Spine1", "Bip01 Spine2",
              "Bip01 Neck", "Bip01 Neck1", "Bip01 Head", "Bip01 {c} Clavicle",
              "Bip01 {c} UpperArm", "Bip01 {c} Forearm", "Bip01 {c} Hand", "Bip01 {c} Finger2",
              "Bip01 {c} Finger1", "Bip01 {c} Finger0"],
    "xsens": ["Pelvis", "{s}HipBone", "{s}UpperLeg", "{s}LowerLeg", "{s}Foot", "{s}Toe", "L5",
              "L3", "T8", "Neck", "Neck2", "Head", "{s}Shoulder", "{s}UpperArm", "{s}ForeArm",
              "{s}Hand", "{s}HandMiddle1", "{s}HandIndex1", "{s}HandThumb1"],
    "optitrack": ["Actor01_Hip", "Actor01_{c}HipBone", "Actor01_{c}Thigh", "Actor01_{c}Shin",
                  "Actor01_{c}Foot", "Actor01_{c}Toe", "Actor01_Ab", "Actor01_Ab2",
                  "Actor01_Chest", "Actor01_Neck", "Actor01_Neck2", "Actor01_Head",
                  "Actor01_{c}Shoulder", "Actor01_{c}UArm", "Actor01_{c}FArm", "Actor01_{c}Hand",
                  "Actor01_{c}Middle1", "Actor01_{c}Index1", "Actor01_{c}Thumb1"],
    "rokoko": ["Hips", "{s}HipBone", "{s}Thigh", "{s}Shin", "{s}Foot", "{s}Toe", "Spine",
               "Spine1", "Spine2", "Neck", "Neck2", "Head", "{s}Shoulder", "{s}Arm",
               "{s}ForeArm", "{s}Hand", "{s}FingerMiddle1", "{s}FingerIndex1",
               "{s}FingerThumb1"],
    "mocopi": ["root", "{l}_hip_bone", "{l}_up_leg", "{l}_low_leg", "{l}_foot", "{l}_toes",
               "torso_1", "torso_4", "torso_7", "neck_1", "neck_2", "head", "{l}_shoulder",
               "{l}_up_arm", "{l}_low_arm", "{l}_hand", "{l}_finger_base", "{l}_index_1",
               "{l}_thumb_1"],
    "azure_kinect": ["PELVIS", "HIPBONE_{S}", "HIP_{S}", "KNEE_{S}", "ANKLE_{S}", "FOOT_{S}",
                     "SPINE_NAVAL", "SPINE_MID", "SPINE_CHEST", "NECK", "NECK_UPPER", "HEAD",
                     "CLAVICLE_{S}", "SHOULDER_{S}", "ELBOW_{S}", "WRIST_{S}", "HAND_{S}",
                     "HANDTIP_{S}", "THUMB_{S}"],
}


def _table(target: list[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    for side, c in (("Left", "L"), ("Right", "R")):
        fill = {"s": side, "c": c, "l": c.lower(), "S": side.upper()}
        for src, dst in zip(_CMU31, target, strict=True):
            out[src.format(s=side, c=c)] = dst.format(**fill)
    return out


def reexport(src: Path, dst: Path, rename: dict[str, str], root_offset: str | None = None
             ) -> Path:
    """``src`` with every ROOT/JOINT renamed; with ``root_offset``, wrapped in a
    ``joint_Root`` (no channels) and the hips' OFFSET replaced by it (an actor start
    position, as some exporters write)."""
    lines = src.read_text().splitlines()
    out = []
    for line in lines:
        m = re.match(r"^(\s*)(ROOT|JOINT)\s+(\S+)\s*$", line)
        out.append(f"{m.group(1)}{m.group(2)} {rename.get(m.group(3), m.group(3))}" if m
                   else line)
    if root_offset is not None:
        k = next(i for i, line in enumerate(out) if line.strip().startswith("ROOT"))
        hips = out[k].split(None, 1)[1]
        offset = next(i for i in range(k, len(out)) if out[i].strip().startswith("OFFSET"))
        out[offset] = f"  OFFSET {root_offset}"
        out[k] = f"  JOINT {hips}"
        motion = next(i for i, line in enumerate(out) if line.strip() == "MOTION")
        out = out[:k] + ["ROOT joint_Root", "{", "  OFFSET 0 0 0", "  CHANNELS 0"] + \
            out[k:motion] + ["}"] + out[motion:]
    dst.write_text("\n".join(out) + "\n")
    return dst


def _canonical_positions(motion) -> dict[str, np.ndarray]:
    c = motion.to_canonical()
    return {k: c.positions[:, i] for i, k in enumerate(c.skeleton.joint_names)}


@needs_data
@pytest.mark.parametrize("convention", sorted(RENAMES))
def test_cmu_clip_reexported_under_convention_maps_like_cmu(tmp_path: Path,
                                                             convention: str) -> None:
    """A real CMU walk with its joints renamed to a convention's names maps every keypoint
    onto the same points as the CMU reader's own table (21 of 21). A hand no name gives is
    found beyond the wrist (CMU's hand joints are 3.5 cm long, the topology rule walks at
    least 5 cm): within 6 cm of CMU's."""
    reference = simenv.load(WALK)
    path = reexport(WALK, tmp_path / f"{convention}.bvh", _table(RENAMES[convention]))
    motion = simenv.load(path)
    record = motion.metadata["joint_map"]
    assert record["missing"] == []
    want, got = _canonical_positions(reference), _canonical_positions(motion)
    assert sorted(got) == sorted(want)
    for key in want:
        loose = key.endswith("_hand") and record["how"][key] == "topology"
        error = np.linalg.norm(got[key] - want[key], axis=-1).max()
        assert error < (0.06 if loose else 1e-5), (convention, key, error)


@needs_data
def test_every_declared_convention_is_exercised() -> None:
    """Each declared convention (bar the sensor ones whose layouts have their own readers and
    the generic fallback) is the best match of one re-export above or of a real file."""
    best = set()
    for target in RENAMES.values():
        names = list(dict.fromkeys(_table(target).values()))
        best.add(infer_joint_map(names, list(range(-1, len(names) - 1))).convention)
    declared = {c.name for c in CONVENTIONS} - {"generic", "kinect_v1", "kinect_v2", "poser",
                                                "openni"}  # NiTE BVH: test_io_camera_frame
    assert declared - best <= {"motionbuilder", "unity_humanoid"}  # real files and tables


@needs_data
def test_hip_offset_holding_the_start_position_is_not_body_size(tmp_path: Path) -> None:
    """An exporter that writes the actor's start position (4.5 m away) into the hips' OFFSET
    below a ``joint_Root``: units are still read from the body (CMU units), and the
    Unity-style names map."""
    path = reexport(WALK, tmp_path / "unity_root.bvh", _table(RENAMES["unity_suffix"]),
                    root_offset="80.0 0.0 -20.0")
    parsed = bvh.parse(path)
    assert rest_extent(parsed.parents, parsed.offsets) < 40.0
    motion = simenv.load(path)
    assert motion.metadata["units"] == simenv.load(WALK).metadata["units"]
    assert motion.metadata["joint_map"]["missing"] == []


@needs_data
@pytest.mark.parametrize("clip", ["02_01.bvh", "05_02.bvh", "01_01.bvh"])
def test_unnamed_skeleton_mapped_from_hierarchy_and_pose(tmp_path: Path, clip: str) -> None:
    """Real CMU clips with every joint renamed ``j0``..``j30``: legs, arms, spine and head are
    found from the hierarchy and the motion, left and right from the body's own frame."""
    src = DATA / "cmu" / "bvh" / clip
    reference = simenv.load(src)
    names = {n: f"j{i}" for i, n in enumerate(reference.skeleton.joint_names)}
    motion = simenv.load(reexport(src, tmp_path / clip, names))
    how = motion.metadata["joint_map"]["how"]
    assert set(how.values()) <= {HOW_REST_POSE, "topology"}
    want, got = _canonical_positions(reference), _canonical_positions(motion)
    for key in ("pelvis", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle",
                "right_ankle", "left_toe", "right_toe", "chest", "left_shoulder",
                "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
                "spine", "neck", "head"):
        assert np.allclose(got[key], want[key], atol=1e-5), key


def _knee_flexion(motion: simenv.Motion, side: str) -> np.ndarray:
    """(T,) angle between thigh and shin, degrees (0 = straight), from the reader's map."""
    sk = motion.skeleton
    hip, knee, ankle = (motion.positions[:, sk.index(sk.canonical[f"{side}_{k}"])]
                        for k in ("hip", "knee", "ankle"))
    thigh, shin = knee - hip, ankle - knee
    cos = np.einsum("ti,ti->t", thigh, shin) / (np.linalg.norm(thigh, axis=-1)
                                                * np.linalg.norm(shin, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


@pytest.mark.parametrize(("path", "seconds"), [
    (CONVENTIONS_DIR / "cmu_motionbuilder" / "xia_depressed_18_000.bvh", None),
    (CONVENTIONS_DIR / "xsens_mvn" / "emokine_mvn_segment_positions.csv", None),
    pytest.param(DATA / "cmu" / "bvh" / "05_02.bvh", (7.0, 8.0), marks=needs_data),
], ids=["xia_depressed_walk", "emokine_mvn_stand", "cmu_05_02_pirouette_stance"])
def test_unnamed_straight_knee_is_the_knee(path: Path, seconds: tuple[float, float] | None
                                           ) -> None:
    """Real clips with a straight knee (median flexion under the 5 degrees at which the
    rest-pose step merges bones into one segment): Xia's upright depressed walk, EmoKine's
    standing MVN take, one second of CMU 05_02 on a straight left leg. With every joint
    renamed ``J0``.. the legs are found by bone lengths: hip, knee, ankle and toe are the
    reader's own, and so left and right (told from the feet)."""
    motion = simenv.load(path)
    if seconds is not None:
        motion = motion.slice(*(round(t * motion.fps) for t in seconds))
    assert min(np.median(_knee_flexion(motion, s)) for s in ("left", "right")) < 5.0
    sk = motion.skeleton
    anonymous = [f"J{i}" for i in range(len(sk.joint_names))]
    mapping = infer_joint_map(anonymous, sk.parents, motion.positions)
    assert mapping.how["left_knee"] == HOW_REST_POSE
    for side in ("left", "right"):
        for key in ("hip", "knee", "ankle", "toe"):
            found = mapping.canonical.get(f"{side}_{key}")
            want = f"J{sk.index(sk.canonical[f'{side}_{key}'])}"
            assert found == want, (f"{side}_{key}", found, want)


@pytest.mark.parametrize("path", [
    CONVENTIONS_DIR / "cmu_motionbuilder" / "xia_angry_13_000.bvh",
    pytest.param(DATA / "cmu" / "bvh" / "35_17.bvh", marks=needs_data),
    CONVENTIONS_DIR / "snu_mass" / "mass_kick.bvh",
], ids=["xia_angry_walk", "cmu_35_17_run", "snu_mass_kick"])
def test_unnamed_bent_arm_ends_at_the_hand(path: Path) -> None:
    """Real clips whose hands stay in front of the chest (an angry walk, a jog: the elbow
    lies farther from the chest than the hand; a kick, where a 0.5 m mesh helper hanging
    from the upper arm also reaches farther than the hand): with every joint renamed
    ``J0``.. the arm chain runs to the hand, so shoulder, elbow and wrist are the reader's
    own, not the clavicle, shoulder and elbow (or the helper)."""
    motion = simenv.load(path)
    sk = motion.skeleton
    mapping = infer_joint_map([f"J{i}" for i in range(len(sk.joint_names))], sk.parents,
                              motion.positions)
    assert mapping.how["left_elbow"] == HOW_REST_POSE
    for side in ("left", "right"):
        for key in ("shoulder", "elbow", "wrist"):
            found = mapping.canonical.get(f"{side}_{key}")
            want = f"J{sk.index(sk.canonical[f'{side}_{key}'])}"
            assert found == want, (f"{side}_{key}", found, want)


def zero_rotation_rest(src: Path, dst: Path, frames: int = 2) -> Path:
    """``src``'s skeleton with every channel zero on ``frames`` frames: the skeleton's own
    rest pose (a T-pose, arms straight out, for CMU's and most rigs' skeletons)."""
    head, _, motion = src.read_text().partition("MOTION")
    channels = sum(int(n) for n in re.findall(r"CHANNELS\s+(\d+)", head))
    frame_time = re.search(r"Frame Time:\s*(\S+)", motion)
    assert frame_time is not None, src
    row = " ".join(["0"] * channels)
    dst.write_text(f"{head}MOTION\nFrames: {frames}\nFrame Time: {frame_time.group(1)}\n"
                   + f"{row}\n" * frames)
    return dst


@pytest.mark.parametrize("path", [
    CONVENTIONS_DIR / "other" / "fair1_dab_zup.bvh",
    CONVENTIONS_DIR / "snu_mass" / "mass_walk.bvh",
    pytest.param(WALK, marks=needs_data),
    pytest.param(DATA / "cmu" / "bvh" / "131_01.bvh", marks=needs_data),
], ids=["fair_dab", "snu_mass_walk", "cmu_02_01", "cmu_131_01"])
def test_unnamed_straight_arm_rest_pose_is_the_arm(tmp_path: Path, path: Path) -> None:
    """Real skeletons in their rest pose (every channel zero: arms straight out), every
    joint renamed ``J0``..: the straight elbow's segment (upper arm and forearm, and the
    hand in CMU's, the clavicle too in FAIR's) is cut at the elbow by bone lengths, so
    shoulder, elbow, wrist and hand are the reader's own, not clavicle, shoulder and
    fingertip."""
    motion = simenv.load(zero_rotation_rest(path, tmp_path / path.name))
    sk = motion.skeleton
    mapping = infer_joint_map([f"J{i}" for i in range(len(sk.joint_names))], sk.parents,
                              motion.positions)
    assert mapping.how["left_elbow"] == HOW_REST_POSE
    for side in ("left", "right"):
        for key in ("shoulder", "elbow", "wrist", "hand"):
            if f"{side}_{key}" not in sk.canonical:
                continue  # MASS's hands: stub and stray End Sites, dropped by the reader
            found = mapping.canonical.get(f"{side}_{key}")
            want = f"J{sk.index(sk.canonical[f'{side}_{key}'])}"
            assert found == want, (f"{side}_{key}", found, want)


@pytest.mark.parametrize("path", [
    pytest.param(DATA / "cmu" / "two_person" / "60_61_salsa_10" / "61_10_scaled.bvh",
                 marks=needs_data),
    CONVENTIONS_DIR / "azure_kinect" / "gymtrainer_bodyweight_squat_side_view.csv",
], ids=["cmu_61_10_salsa_poser", "azure_kinect_squat"])
def test_unnamed_head_branch_is_not_an_arm(path: Path) -> None:
    """Real clips whose chest has a head branch with eyes (and ears, a nose): a salsa
    dancer in hold (Poser names; the hands stay near the chest, so the eyes reach farther
    from it than a hand) and an Azure Kinect squat. With every joint renamed ``J0``.. the
    arms are the two mirror-image branches and the head is the joint the eyes hang from:
    shoulder, elbow, wrist, neck and head are the reader's own."""
    motion = simenv.load(path)
    sk = motion.skeleton
    mapping = infer_joint_map([f"J{i}" for i in range(len(sk.joint_names))], sk.parents,
                              motion.positions)
    assert mapping.how["head"] == HOW_REST_POSE
    keys = [f"{s}_{k}" for s in ("left", "right") for k in ("shoulder", "elbow", "wrist")]
    for key in [*keys, "neck", "head"]:
        found = mapping.canonical.get(key)
        want = f"J{sk.index(sk.canonical[key])}"
        assert found == want, (key, found, want)


@pytest.mark.skipif(not CONVENTIONS_DIR.exists(), reason="tests/data/conventions absent")
@pytest.mark.parametrize("path", sorted(CONVENTIONS_DIR.glob("*/*.bvh")), ids=lambda p: p.name)
def test_real_files_of_other_labs_map_every_keypoint(path: Path) -> None:
    """Every keypoint, except a hand the file does not have (its end on the wrist, or a
    stray end), which the reader must say it dropped."""
    motion = simenv.load(path)
    missing = set(skeletons.CANONICAL_KEYPOINTS) - set(motion.skeleton.canonical)
    assert missing <= {"left_hand", "right_hand"}, motion.skeleton.canonical
    said = " ".join([*motion.metadata.get("quirks", []),
                     *(motion.metadata.get("joint_map") or {}).get("notes", [])])
    for key in missing:
        assert f"{key} dropped" in said or f"{key} -> " in said, (key, said)


MASS = CONVENTIONS_DIR / "snu_mass"


def test_helper_joint_named_like_its_bone_is_not_ambiguous() -> None:
    """SNU MRL's kick hangs mesh helpers named like the bones below them (``Neck`` under
    ``Character1_Neck``, ``L_Foot`` under ``Character1_LeftFoot``): the name means the
    joint above, not nothing."""
    canonical = simenv.load(MASS / "mass_kick.bvh").skeleton.canonical
    assert canonical["neck"] == "Character1_Neck"
    assert canonical["spine"] == "Character1_Spine"
    assert canonical["left_ankle"] == "Character1_LeftFoot"
    assert canonical["right_ankle"] == "Character1_RightFoot"


def test_stray_or_stub_end_of_the_wrist_is_not_a_hand() -> None:
    """SNU MRL's walk: the right hand's End Site is 1.6 m off the wrist, the left one 9 mm:
    neither says where a hand is, so neither is a hand keypoint (one across the room, one a
    stub the fit would take for an observed hand); the feet's ends stay."""
    motion = simenv.load(MASS / "mass_walk.bvh")
    canonical = motion.skeleton.canonical
    assert "right_hand" not in canonical and "left_hand" not in canonical
    assert canonical["left_toe"] == "Character1_LeftToeBase"
    notes = motion.metadata["joint_map"]["notes"]
    assert any(n.startswith("right_hand -> Character1_RightHand_end dropped: 1.618 m")
               for n in notes)
    assert any(n.startswith("left_hand -> Character1_LeftHand_end dropped: 0.009 m")
               for n in notes)


def test_arms_crossing_over_are_noted_not_remapped() -> None:
    """A real walk (Xia et al., tests/data/conventions) maps with no crossing note; the same
    frames with the two arm chains' positions exchanged (each arm hanging from the other
    shoulder, as a capture solve that flips both clavicles leaves them: FAIR's
    ``5yr_old/skipping``) keep their names' map and get the note that the arms cross."""
    motion = simenv.load(CONVENTIONS_DIR / "cmu_motionbuilder" / "xia_angry_13_000.bvh")
    names, parents = list(motion.skeleton.joint_names), motion.skeleton.parents
    plain = infer_joint_map(names, parents, motion.positions)
    assert not any("cross over" in n for n in plain.notes)

    def arm(side: str) -> list[int]:
        """The shoulder joint and every joint below it, in file order."""
        below = [names.index(plain.canonical[f"{side}_shoulder"])]
        for j, parent in enumerate(parents):
            if parent in below:
                below.append(j)
        return below

    crossed = motion.positions.copy()
    left, right = arm("left"), arm("right")
    assert len(left) == len(right)
    crossed[:, left + right] = crossed[:, right + left]
    mapping = infer_joint_map(names, parents, crossed)
    assert mapping.canonical == plain.canonical
    note = next(n for n in mapping.notes if "cross over" in n)
    assert "on 100 % of frames" in note


def test_minimal_rig_whose_spine_carries_the_arms_maps_it_as_the_chest() -> None:
    """A minimal rig (PyMO's demo walk: ``Hips -> Spine``, the head and both arms on
    ``Spine``) has one trunk joint, and it is where the arms leave the trunk: the chest, not
    the lumbar. Built from a real walk (Xia et al.): its chest hub's positions under the name
    ``Spine``, the head, arms and legs hung from it and from ``Hips``."""
    motion = simenv.load(CONVENTIONS_DIR / "cmu_motionbuilder" / "xia_angry_13_000.bvh")
    full = infer_joint_map(motion.skeleton.joint_names, motion.skeleton.parents,
                           motion.positions).canonical
    rig = [("Hips", None, "pelvis"), ("Spine", "Hips", "chest"), ("Head", "Spine", "head")]
    for side in ("Left", "Right"):
        s = side.lower()
        rig += [(f"{side}Arm", "Spine", f"{s}_shoulder"),
                (f"{side}ForeArm", f"{side}Arm", f"{s}_elbow"),
                (f"{side}Hand", f"{side}ForeArm", f"{s}_wrist"),
                (f"{side}UpLeg", "Hips", f"{s}_hip"), (f"{side}Leg", f"{side}UpLeg", f"{s}_knee"),
                (f"{side}Foot", f"{side}Leg", f"{s}_ankle"),
                (f"{side}ToeBase", f"{side}Foot", f"{s}_toe")]
    names = [name for name, _, _ in rig]
    parents = [-1 if parent is None else names.index(parent) for _, parent, _ in rig]
    idx = [motion.skeleton.index(full[key]) for _, _, key in rig]
    mapping = infer_joint_map(names, parents, motion.positions[:, idx])
    assert mapping.canonical["chest"] == "Spine"
    assert mapping.how["chest"] == HOW_TOPOLOGY
    assert "spine" not in mapping.canonical


@pytest.mark.parametrize("asset", ["763", "Skeleton_001"])
def test_motive3_hip_bone_named_after_the_asset_is_the_pelvis(asset: str) -> None:
    """OptiTrack Motive 3 names a skeleton's hip bone after the asset (a real Gaga dance
    export: ``763:763``, parent of ``763:Ab`` and ``763:LThigh``; SOURCES.md), a name no
    convention can hold: the pelvis is where the named hips meet, the rest comes from
    Motive's names. Built from a real walk (Xia et al.): each Motive bone at the joint the
    walk's own map gives (the clavicle is the shoulder's parent)."""
    motion = simenv.load(CONVENTIONS_DIR / "cmu_motionbuilder" / "xia_angry_13_000.bvh")
    sk = motion.skeleton
    full = infer_joint_map(sk.joint_names, sk.parents, motion.positions).canonical
    root = f"{asset}:{asset}"
    rig = [(root, None, "pelvis"), (f"{asset}:Ab", root, "spine"),
           (f"{asset}:Chest", f"{asset}:Ab", "chest"), (f"{asset}:Neck", f"{asset}:Chest", "neck"),
           (f"{asset}:Head", f"{asset}:Neck", "head")]
    for c in ("L", "R"):
        s = "left" if c == "L" else "right"
        rig += [(f"{asset}:{c}Shoulder", f"{asset}:Chest", f"{s}_clavicle"),
                (f"{asset}:{c}UArm", f"{asset}:{c}Shoulder", f"{s}_shoulder"),
                (f"{asset}:{c}FArm", f"{asset}:{c}UArm", f"{s}_elbow"),
                (f"{asset}:{c}Hand", f"{asset}:{c}FArm", f"{s}_wrist"),
                (f"{asset}:{c}Thigh", root, f"{s}_hip"),
                (f"{asset}:{c}Shin", f"{asset}:{c}Thigh", f"{s}_knee"),
                (f"{asset}:{c}Foot", f"{asset}:{c}Shin", f"{s}_ankle"),
                (f"{asset}:{c}Toe", f"{asset}:{c}Foot", f"{s}_toe")]
    names = [name for name, _, _ in rig]
    parents = [-1 if parent is None else names.index(parent) for _, parent, _ in rig]

    def joint(key: str) -> int:
        if key.endswith("_clavicle"):
            return sk.parents[sk.index(full[key.replace("_clavicle", "_shoulder")])]
        return sk.index(full[key])

    mapping = infer_joint_map(names, parents, motion.positions[:, [joint(k) for _, _, k in rig]])
    assert mapping.convention == "optitrack_motive"
    assert mapping.canonical["pelvis"] == root
    assert mapping.how["pelvis"] == HOW_TOPOLOGY
    for name, _, key in rig[1:]:
        if not key.endswith(("_clavicle", "chest")):
            assert mapping.canonical[key] == name, key
            assert mapping.how[key] == "name (optitrack_motive)", key


@needs_data
def test_user_map_round_trip_through_template(tmp_path: Path) -> None:
    """The template of an unnamed skeleton, edited, maps it: the user's word stands."""
    names = {n: f"j{i}" for i, n in enumerate(simenv.load(WALK).skeleton.joint_names)}
    path = reexport(WALK, tmp_path / "anon.bvh", names)
    motion = simenv.load(path)
    mapping = motion.metadata["joint_map"]
    text = joint_map_template(motion.skeleton.joint_names)
    assert "# pelvis" in text and "j30" in text
    filled = text.replace('# pelvis = ""', f'pelvis = "{mapping["canonical"]["pelvis"]}"')
    for side in ("left", "right"):
        joint = mapping["canonical"][f"{side}_hip"]
        filled = filled.replace(f'# {side}_hip = ""', f'{side}_hip = "{joint}"')
    user = tmp_path / "map.toml"
    user.write_text(filled)
    assert read_joint_map(user) == {k: mapping["canonical"][k]
                                    for k in ("pelvis", "left_hip", "right_hip")}
    mapped = simenv.load(path, joint_map=user)
    assert dict(mapped.skeleton.canonical) == read_joint_map(user)
    assert set(mapped.metadata["joint_map"]["how"].values()) == {HOW_USER}


@needs_data
@pytest.mark.parametrize(("text", "message"), [
    ('[canonical]\nleft_hipp = "j1"\n', "unknown canonical keypoint 'left_hipp'"),
    ('[canonical]\npelvis = "nosuch"\n', "has no such joint"),
    ('pelvis = "j0"\n', "expected a [canonical] table"),
    ('[canonical\n', "not a TOML joint map"),
    ('[canonical]\npelvis = 3\n', "expected a joint name"),
])
def test_bad_user_map_is_a_clear_error(tmp_path: Path, text: str, message: str) -> None:
    user = tmp_path / "map.toml"
    user.write_text(text)
    with pytest.raises(SkeletonError, match=re.escape(message)) as err:
        simenv.load(WALK, joint_map=user)
    assert "map.toml" in str(err.value)


@needs_data
def test_unmappable_skeleton_error_lists_joints_and_the_way_out(tmp_path: Path) -> None:
    """A real clip cut down to its upper body cannot give a pelvis and hips: retargeting says
    which joints there are and how to write a map."""
    from simenv.body.retarget import retarget

    motion = simenv.load(WALK)
    keep = [n for n in motion.skeleton.joint_names if "Leg" not in n and "Foot" not in n
            and "Toe" not in n and "Hip" not in n]
    upper = motion.skeleton.subset(keep, name="upper")
    canonical = {k: v for k, v in upper.canonical.items() if k != "pelvis"}
    sk = skeletons.Skeleton("upper", upper.joint_names, upper.parents, canonical)
    cut = simenv.Motion(motion.positions[:, [motion.skeleton.index(n) for n in keep]],
                        motion.fps, sk, "upper", dict(motion.metadata))
    with pytest.raises(RetargetError, match="--write-joint-map") as err:
        retarget(cut)
    assert "LeftForeArm" in str(err.value) and "pelvis" in str(err.value)

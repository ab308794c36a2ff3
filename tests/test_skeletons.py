"""Skeleton library: structure, canonical maps and the registry, checked
against real Kinect recordings where geometry matters."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import SkeletonError
from simenv.core.skeletons import (
    CANONICAL_KEYPOINTS,
    CANONICAL_TREE,
    KINECT_V2_SDK_JOINTS,
    KINECT_V2_SDK_ORDER,
    get_skeleton,
    skeleton_names,
)
from simenv.io import florence3d, msr_action3d, nuisi, sbu, utkinect

EXPECTED = {
    "canonical": 21, "kinect_v1_20": 20, "kinect_v2_25": 25, "sbu15": 15, "florence15": 15,
    "nuitrack": 24, "h36m17": 17, "gesture9": 9,
}
# Keypoints each skeleton must NOT claim (declared missing, never guessed).
MISSING = {
    "kinect_v1_20": {"chest"},
    "kinect_v2_25": {"chest"},
    "sbu15": {"pelvis", "chest", "left_hand", "right_hand", "left_toe", "right_toe"},
    "florence15": {"pelvis", "chest", "left_hand", "right_hand", "left_toe", "right_toe"},
    "nuitrack": {"chest"},
    "h36m17": {"chest", "left_hand", "right_hand", "left_toe", "right_toe"},
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_registry_structure(name: str) -> None:
    s = get_skeleton(name)
    assert s.num_joints == EXPECTED[name]
    assert s.name == name
    assert all(k in CANONICAL_KEYPOINTS for k in s.canonical)
    assert len(set(s.canonical.values())) == len(s.canonical)  # one joint per keypoint
    assert MISSING.get(name, set()).isdisjoint(s.canonical)
    # Every canonical bone whose two ends are mapped joins joints linked in the
    # skeleton's tree (possibly through unmapped joints), never across limbs.
    for child, parent in CANONICAL_TREE.items():
        if parent is None or child not in s.canonical or parent not in s.canonical:
            continue
        a, b = s.index(s.canonical[child]), s.index(s.canonical[parent])
        chain_a = _ancestors(s.parents, a)
        chain_b = _ancestors(s.parents, b)
        assert b in chain_a or a in chain_b, (name, child, parent)


def _ancestors(parents: tuple[int, ...], j: int) -> list[int]:
    out = [j]
    while parents[j] >= 0:
        j = parents[j]
        out.append(j)
    return out


def test_registry_names_and_aliases() -> None:
    assert set(EXPECTED) <= set(skeleton_names())
    assert get_skeleton("Kinect-v1-20") is get_skeleton("kinect_v1_20")
    assert get_skeleton("NTU").name == "kinect_v2_25"
    assert get_skeleton("H36M").name == "h36m17"
    with pytest.raises(SkeletonError, match="known skeletons: .*sbu15"):
        get_skeleton("openpose25")


def test_cmu31_matches_the_cmu_bvh_release(shared_data: Path) -> None:
    import simenv

    motion = simenv.load(shared_data / "cmu" / "bvh" / "02_01.bvh")
    cmu = get_skeleton("CMU-31")
    assert cmu.num_joints == 31
    assert cmu.joint_names == motion.skeleton.joint_names
    assert cmu.parents == motion.skeleton.parents
    assert dict(cmu.canonical) == dict(motion.skeleton.canonical)


def test_kinect_v2_order_is_a_permutation_of_the_sdk() -> None:
    s = get_skeleton("kinect_v2_25")
    assert sorted(KINECT_V2_SDK_ORDER) == list(range(25))
    assert s.joint_names == tuple(KINECT_V2_SDK_JOINTS[i] for i in KINECT_V2_SDK_ORDER)
    assert s.joint_names[s.parents[s.index("Neck")]] == "SpineShoulder"


def _bone(m, a: str, b: str) -> float:
    sk = m.skeleton
    ja, jb = sk.index(sk.canonical[a]), sk.index(sk.canonical[b])
    return float(np.median(np.linalg.norm(m.positions[:, ja] - m.positions[:, jb], axis=1)))


def test_canonical_maps_give_anatomical_lengths(shared_data: Path) -> None:
    """The mapping decisions (SBU 'hand' = wrist, 'foot' = ankle, Kinect 'foot'
    = toe...) give adult segment lengths on real recordings."""
    g = shared_data / "gestures"
    msr = msr_action3d.read(g / "msr_action3d" / "a01_s01_e01_skeleton3D.txt")
    utk = utkinect.read(g / "utkinect" / "joints" / "joints_s01_e01.txt")
    flo = florence3d.read(g / "florence3d" / "skeletal_data.mat")[0]
    s = sbu.read(shared_data / "other" / "sbu_kinect_sample" / "skeleton_pos.txt")
    nui = nuisi.read(shared_data / "other" / "nuisi" / "Rocket_p1.txt")
    for m in (msr, utk, flo, s.actor, s.reactor, nui):
        assert 0.20 <= _bone(m, "left_elbow", "left_wrist") <= 0.33, m.name
        assert 0.30 <= _bone(m, "left_knee", "left_ankle") <= 0.50, m.name
        assert 0.26 <= _bone(m, "left_shoulder", "right_shoulder") <= 0.45, m.name
    for m in (msr, utk):  # Kinect v1 foot is the forefoot, forward of the ankle
        assert 0.05 <= _bone(m, "left_ankle", "left_toe") <= 0.20
        assert 0.03 <= _bone(m, "left_wrist", "left_hand") <= 0.15

"""HumanML3D ``new_joint_vecs`` (T, 263) and KIT-ML (T, 251) features, read by
recovering joint positions. Real data: HumanML3D's sample clip 012314 (features
and its ``new_joints``), MoMask's HumanML3D test clip 000612, the dataset's
Mean/Std, and KIT-ML's feature statistics (tests/data/humanml3d/SOURCES.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import simenv
from simenv.core import skeletons
from simenv.core.errors import FormatError, MotionError, UnitsError
from simenv.core.motion import Motion
from simenv.core.skeletons import CANONICAL_KEYPOINTS, SMPL22_JOINTS, SMPL22_PARENTS
from simenv.io import humanml3d_features as hf
from simenv.io import loader

DATA = Path(__file__).parent / "data" / "humanml3d"
VECS = DATA / "new_joint_vecs" / "012314.npy"
JOINTS = DATA / "new_joints" / "012314.npy"
VECS_612 = DATA / "new_joint_vecs" / "000612.npy"
MEAN, STD = DATA / "Mean.npy", DATA / "Std.npy"
KIT_MEAN = DATA / "kitml" / "kit_mean.npy"

# HumanML3D's paramUtil.kit_kinematic_chain.
KIT_CHAIN = [[0, 11, 12, 13, 14, 15], [0, 16, 17, 18, 19, 20], [0, 1, 2, 3, 4], [3, 5, 6, 7],
             [3, 8, 9, 10]]


def save(path: Path, arr: np.ndarray) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as fh:
        np.save(fh, arr)
    return path


def bone_lengths(m: Motion) -> np.ndarray:
    """(T, bones) parent-child distances in metres."""
    p = m.positions.astype(np.float64)
    return np.stack([np.linalg.norm(p[:, j] - p[:, i], axis=1) for i, j in m.skeleton.bones], 1)


def handedness(m: Motion, left_hip: str, right_hip: str, left_toe: str, right_toe: str,
               left_ankle: str, right_ankle: str) -> float:
    """Mean cosine between the toes' direction and up x (right hip - left hip), Z up:
    +1 for a right-handed body whose left joints are on its left, -1 if mirrored."""
    p, ix = m.positions.astype(np.float64), m.skeleton.index
    fwd = np.cross([0.0, 0.0, 1.0], p[:, ix(right_hip)] - p[:, ix(left_hip)])
    toe = (p[:, ix(left_toe)] - p[:, ix(left_ankle)]) + (p[:, ix(right_toe)]
                                                         - p[:, ix(right_ankle)])
    fwd[:, 2] = toe[:, 2] = 0.0
    cos = (fwd * toe).sum(1) / np.linalg.norm(fwd, axis=1) / np.linalg.norm(toe, axis=1)
    return float(cos.mean())


# -- layout and skeleton ----------------------------------------------------------------


def test_feature_widths_and_columns() -> None:
    assert hf.feature_width(22) == 263 and hf.feature_width(21) == 251
    for fs in (hf.HUMANML3D, hf.KITML):
        cols = dict(hf.feature_columns(fs.n_joints))
        assert cols["ric"] == slice(4, 4 + 3 * (fs.n_joints - 1))
        assert cols["foot_contact"].stop == fs.width
    assert set(hf.BY_WIDTH) == {263, 251}


def test_kit21_skeleton_follows_kit_chain() -> None:
    parents = [-1] + [0] * 20
    for chain in KIT_CHAIN:
        for prev, j in zip(chain, chain[1:], strict=False):
            parents[j] = prev
    skel = skeletons.kit21_skeleton()
    assert skel.parents == skeletons.KIT21_PARENTS == tuple(parents) and skel.num_joints == 21
    # Everything retargeting uses except the hand ends, which KIT-ML lacks.
    assert set(skel.canonical) == set(CANONICAL_KEYPOINTS) - {"left_hand", "right_hand"}


# -- HumanML3D: recovery checked against new_joints ---------------------------------------


def test_recovery_matches_new_joints_of_the_same_clip() -> None:
    feats = np.load(VECS)
    ref = np.load(JOINTS).astype(np.float64)
    pos = hf.recover_positions(feats, 22)
    err = np.linalg.norm(pos - ref, axis=-1)
    # new_joints was written by HumanML3D's float32 recover_from_ric from these rows.
    assert err.max() < 1e-6, f"max {err.max() * 1e3:.2g} mm"


def test_load_features_equals_load_new_joints() -> None:
    assert loader.detect(VECS)[0] == "humanml3d_features"
    m, ref = simenv.load(VECS), simenv.load(JOINTS)
    assert isinstance(m, Motion) and m.skeleton == ref.skeleton
    assert m.skeleton.name == "smpl22" and m.fps == 20.0 and m.name == "012314"
    assert m.metadata["format"] == "humanml3d_vecs" and m.metadata["units"] == "m"
    assert m.metadata["quirks"] == [] and not m.metadata["denormalised"]
    np.testing.assert_allclose(m.positions, ref.positions, atol=1e-6)
    assert simenv.load(VECS, fps=30).fps == 30.0


def test_second_real_clip_recovers_a_rigid_body() -> None:
    m = simenv.load(VECS_612)
    assert m.skeleton.name == "smpl22" and m.num_frames == 199
    lengths = bone_lengths(m)
    # AMASS bodies are rigid: each SMPL bone keeps its length to float precision.
    assert lengths.std(axis=0).max() < 1e-5
    assert 1.3 < m.height() < 2.0
    p = m.positions
    i = SMPL22_JOINTS.index
    assert np.all(p[:, i("head"), 2] > p[:, i("pelvis"), 2])  # Z is up
    assert handedness(m, "left_hip", "right_hip", "left_foot", "right_foot", "left_ankle",
                      "right_ankle") > 0.8
    assert SMPL22_PARENTS == m.skeleton.parents


# -- normalised arrays ----------------------------------------------------------------


@pytest.mark.parametrize("clip", [VECS, VECS_612])
def test_normalised_array_is_refused_then_read_with_statistics(tmp_path: Path, clip: Path
                                                               ) -> None:
    raw = np.load(clip).astype(np.float64)
    mean, std = np.load(MEAN).astype(np.float64), np.load(STD).astype(np.float64)
    f = save(tmp_path / "normalised.npy", ((raw - mean) / std).astype(np.float32))
    with pytest.raises(FormatError, match=r"look normalised.*mean='Mean.npy'") as err:
        simenv.load(f)
    assert err.value.source == str(f)
    # Read as raw anyway, it is no body either (about 4 m across).
    with pytest.raises(UnitsError, match=r"spans [34]\.\d+ m.*normalised"):
        simenv.load(f, check_raw=False)
    m = simenv.load(f, mean=MEAN, std=STD)
    assert m.metadata["denormalised"]
    np.testing.assert_allclose(m.positions, simenv.load(clip).positions, atol=1e-5)


@pytest.mark.parametrize("clip", [VECS, VECS_612])
def test_every_second_of_a_normalised_clip_shows_it(clip: Path) -> None:
    raw = np.load(clip).astype(np.float64)
    z = (raw - np.load(MEAN)) / np.load(STD)
    assert hf.normalised_evidence(raw) is None
    assert all(hf.normalised_evidence(z[s: s + 20]) for s in range(len(z) - 19))


def test_statistics_errors(tmp_path: Path) -> None:
    with pytest.raises(FormatError, match="both mean= and std=") as err:
        simenv.load(VECS, std=STD)
    assert err.value.field == "mean"
    with pytest.raises(FormatError, match=r"shape \(251,\); expected \(263,\)"):
        simenv.load(VECS, mean=KIT_MEAN, std=STD)
    zero = np.load(STD).copy()
    zero[7] = 0.0
    with pytest.raises(FormatError, match=r"std\[7\] = 0.0; expected finite positive"):
        simenv.load(VECS, mean=MEAN, std=zero)


# -- bad input ------------------------------------------------------------------------


def test_nan_row_names_frame_and_group(tmp_path: Path) -> None:
    feats = np.load(VECS).copy()
    feats[37, 100] = np.nan  # a rot6d column
    feats[90, 2] = np.inf
    with pytest.raises(MotionError, match=r"column 100 \(rot6d\) and in 2 of 170 rows") as err:
        simenv.load(save(tmp_path / "nan.npy", feats))
    assert err.value.frame == 37 and err.value.field == "rot6d"


@pytest.mark.parametrize("frames", [0, 1])
def test_fewer_than_two_frames(tmp_path: Path, frames: int) -> None:
    f = save(tmp_path / "short.npy", np.load(VECS)[:frames])
    with pytest.raises(MotionError, match=rf"{frames} frame\(s\); expected at least 2"):
        simenv.load(f)


def test_wrong_widths_are_named() -> None:
    feats = np.load(VECS)
    with pytest.raises(FormatError, match=r"\(T, 263\) HumanML3D or \(T, 251\) KIT-ML.*InterGen"):
        hf.from_features(feats[:, :262])
    with pytest.raises(FormatError, match=r"shape \(170, 264\)"):
        hf.from_features(np.concatenate([feats, feats[:, :1]], axis=1))
    with pytest.raises(FormatError, match="real numeric"):
        hf.from_features(feats.astype(np.complex64))


def test_intergen_person_folders_are_left_to_intergen(tmp_path: Path) -> None:
    f = save(tmp_path / "person1" / "1.npy", np.load(VECS))
    assert loader.detect(f)[0] != "humanml3d_features"


def test_all_zero_rows_are_not_a_body(tmp_path: Path) -> None:
    with pytest.raises(UnitsError, match=r"spans 0 m.*normalised"):
        simenv.load(save(tmp_path / "zeros.npy", np.zeros((20, 263), np.float32)))


# -- KIT-ML ---------------------------------------------------------------------------


def kit_rows_from_humanml3d(feats: np.ndarray) -> tuple[np.ndarray, dict[str, str]]:
    """KIT-ML (T, 251) rows carrying the real clip 012314 on 20 of its joints, written
    the way KIT-ML stores bodies (KIT units, mirrored in x), and the SMPL joint each KIT
    joint carries. Mirroring negates x and the yaw; rotations, velocities and contacts
    stay zero (recovery does not read them)."""
    smpl = {"BP": "spine1", "BT": "spine3", "BLN": "neck", "BUN": "head"}
    for s, side in (("L", "left"), ("R", "right")):
        smpl |= {f"{s}S": f"{side}_shoulder", f"{s}E": f"{side}_elbow", f"{s}W": f"{side}_wrist",
                 f"{s}H": f"{side}_hip", f"{s}K": f"{side}_knee", f"{s}A": f"{side}_ankle",
                 f"{s}Mrot": f"{side}_ankle", f"{s}F": f"{side}_foot"}
    unit = hf.KIT_METRES_PER_UNIT
    ric = feats[:, 4:67].reshape(len(feats), 21, 3) * [-1.0, 1.0, 1.0] / unit
    kit = np.zeros((len(feats), 251))
    kit[:, 0] = -feats[:, 0]
    kit[:, 1] = -feats[:, 1] / unit
    kit[:, 2:4] = feats[:, 2:4] / unit
    for j, name in enumerate(skeletons.KIT21_JOINTS[1:]):
        kit[:, 4 + 3 * j: 7 + 3 * j] = ric[:, SMPL22_JOINTS.index(smpl[name]) - 1]
    return kit, smpl


def test_kit_rows_read_back_the_real_motion(tmp_path: Path) -> None:
    feats = np.load(VECS).astype(np.float64)
    kit, smpl = kit_rows_from_humanml3d(feats)
    f = save(tmp_path / "03950.npy", kit)
    assert loader.detect(f)[0] == "humanml3d_features"
    m, ref = simenv.load(f), simenv.load(VECS)
    assert m.skeleton.name == "kit21" and m.fps == 12.5
    assert m.metadata["format"] == "kitml_vecs" and "mirrored" in m.metadata["quirks"][0]
    assert m.metadata["units"] == "0.0015625 m"
    for kit_joint, smpl_joint in smpl.items():
        np.testing.assert_allclose(m.joint(kit_joint), ref.joint(smpl_joint), atol=1e-5,
                                   err_msg=kit_joint)
    np.testing.assert_allclose(m.joint("root"), ref.joint("pelvis"), atol=1e-5)
    mm = simenv.load(f, units="mm")  # a declared unit replaces KIT-ML's own
    np.testing.assert_allclose(mm.positions, m.positions * (1e-3 / hf.KIT_METRES_PER_UNIT),
                               rtol=1e-5, atol=1e-6)
    assert simenv.load(f, units=0.0017).metadata["units"] == "0.0017 m"


def test_kit_mean_pose_is_a_person_with_left_on_the_left() -> None:
    mean = np.load(KIT_MEAN)  # KIT-ML's mean feature row: its mean pose, standing still
    rows = np.repeat(mean[None], 3, axis=0)
    rows[:, :3] = 0.0
    m = hf.from_features(rows, name="kit_mean")
    p, ix = m.positions[0].astype(np.float64), m.skeleton.index
    # KIT-ML units read as 0.75/480 m: pelvis 0.87 m up, upper neck to toes 1.1-1.3 m.
    assert 0.8 < p[ix("root"), 2] < 1.0
    assert 1.0 < p[ix("BUN"), 2] - min(p[ix("LF"), 2], p[ix("RF"), 2]) < 1.4
    # Read with MMM's names and mirrored back, the body is right-handed: the toes point
    # along up x (right hip - left hip), as in HumanML3D's SMPL bodies.
    assert handedness(m, "LH", "RH", "LF", "RF", "LA", "RA") > 0.8
    assert handedness(m, "LS", "RS", "LF", "RF", "LA", "RA") > 0.8

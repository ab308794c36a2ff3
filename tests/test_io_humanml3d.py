"""HumanML3D ``new_joints``, MDM ``results.npy`` and InterGen/InterHuman pairs, built
from real CMU motion capture (the bundled walk and handshake pair): files are made
both by hand from the documented array layouts (independently of the writers) and
by the writers, then read back through :func:`simenv.load`."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

import simenv
from simenv.assets import HANDSHAKE_PAIR, WALK, asset_path
from simenv.cli import main as cli
from simenv.core.errors import FormatError, MotionError, SkeletonError, UnitsError
from simenv.core.motion import Interaction, Motion
from simenv.core.skeletons import SMPL22_JOINTS, SMPL22_PARENTS, get_skeleton
from simenv.io import bvh, humanml3d, intergen, loader
from simenv.io.humanml3d import to_smpl22, write_humanml3d, write_mdm_results
from simenv.io.intergen import write_intergen

# HumanML3D's t2m_kinematic_chain (github.com/EricGuo5513/HumanML3D, paramUtil.py).
T2M_KINEMATIC_CHAIN = [[0, 2, 5, 8, 11], [0, 1, 4, 7, 10], [0, 3, 6, 9, 12, 15],
                       [9, 14, 17, 19, 21], [9, 13, 16, 18, 20]]


def y_up(z_up: np.ndarray) -> np.ndarray:
    """Z-up simenv positions in a Y-up frame, written out by hand: simenv reads
    Y-up (x, y, z) as Z-up (x, -z, y), so Y-up = (X, Z, -Y)."""
    return np.stack([z_up[..., 0], z_up[..., 2], -z_up[..., 1]], axis=-1)


def chirality(p: np.ndarray, up: int) -> float:
    """Mean cosine between the toe direction and up x (right hip - left hip): +1
    for a right-handed, unmirrored body, -1 for a mirrored one."""
    upv = np.zeros(3)
    upv[up] = 1.0
    i = SMPL22_JOINTS.index
    fwd = np.cross(upv, p[:, i("right_hip")] - p[:, i("left_hip")])
    toe = (p[:, i("left_foot")] - p[:, i("left_ankle")]
           + p[:, i("right_foot")] - p[:, i("right_ankle")])
    fwd[:, up] = toe[:, up] = 0.0
    cos = (fwd * toe).sum(1) / np.linalg.norm(fwd, axis=1) / np.linalg.norm(toe, axis=1)
    return float(cos.mean())


@pytest.fixture(scope="module")
def walk20() -> Motion:
    """The bundled real CMU 02_01 walk at 20 fps on SMPL-22 (58 frames)."""
    return to_smpl22(bvh.read(asset_path(WALK)).resample(20.0))


@pytest.fixture(scope="module")
def handshake30() -> Interaction:
    """The bundled real CMU 18_01 + 19_01 handshake pair at 30 fps on SMPL-22."""
    pair = simenv.load(asset_path(HANDSHAKE_PAIR))
    a, b = (to_smpl22(m.resample(30.0)) for m in pair.people)
    return Interaction(a, b, name="handshake")


def save(path: Path, arr: object) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as fh:
        np.save(fh, arr, allow_pickle=not isinstance(arr, np.ndarray))
    return path


# -- skeleton ------------------------------------------------------------------------


def test_smpl22_skeleton_follows_t2m_chain() -> None:
    parents = [0] * 22
    parents[0] = -1
    for chain in T2M_KINEMATIC_CHAIN:  # HumanML3D's own rule: parent = previous in chain
        for prev, j in zip(chain, chain[1:], strict=False):
            parents[j] = prev
    skel = get_skeleton("smpl22")
    assert skel.parents == SMPL22_PARENTS == tuple(parents)
    assert skel.joint_names[:4] == ("pelvis", "left_hip", "right_hip", "spine1")
    assert get_skeleton("HumanML3D") is skel and get_skeleton("smpl-22") is skel
    # Everything retargeting uses except the hand ends, which SMPL-22 lacks.
    assert set(skel.canonical) == set(simenv.core.skeletons.CANONICAL_KEYPOINTS) - {
        "left_hand", "right_hand"}


def test_cmu_maps_onto_smpl22(walk20: Motion) -> None:
    cmu = bvh.read(asset_path(WALK)).resample(20.0)
    smpl = to_smpl22(cmu)
    for key, joint in smpl.skeleton.canonical.items():
        np.testing.assert_array_equal(smpl.joint(joint), cmu.joint(cmu.skeleton.canonical[key]))
    assert smpl.metadata["derived_joints"] == ["spine2", "left_collar", "right_collar"]
    # The derived joints sit where SMPL puts them: spine2 between spine1 and spine3,
    # collars between the neck base and the shoulders.
    i = SMPL22_JOINTS.index
    p = smpl.positions
    assert np.all(p[:, i("spine2"), 2] > p[:, i("spine1"), 2])
    assert np.all(p[:, i("spine2"), 2] < p[:, i("spine3"), 2])
    for side in ("left", "right"):
        d_collar = np.linalg.norm(p[:, i(f"{side}_collar")] - p[:, i(f"{side}_shoulder")], axis=1)
        assert np.all((d_collar > 0.05) & (d_collar < 0.25))
    with pytest.raises(SkeletonError, match="spine2, left_collar, right_collar"):
        to_smpl22(cmu, derive_missing=False)


def test_skeleton_without_toes_is_refused_naming_them() -> None:
    canon = bvh.read(asset_path(WALK)).slice(0, 40).to_canonical()
    keep = [k for k in canon.skeleton.joint_names if not k.endswith("_toe")]
    no_toes = Motion(canon.positions[:, [canon.skeleton.index(k) for k in keep]], canon.fps,
                     canon.skeleton.subset(keep, name="no_toes"), "walk_no_toes")
    with pytest.raises(SkeletonError) as err:
        to_smpl22(no_toes)
    assert "left_toe (SMPL left_foot)" in str(err.value)
    assert "right_toe (SMPL right_foot)" in str(err.value)
    assert "no_toes" in str(err.value)


# -- HumanML3D new_joints -------------------------------------------------------------


def test_hand_built_humanml3d_file(tmp_path: Path, walk20: Motion) -> None:
    arr = y_up(walk20.positions).astype(np.float32)  # documented: (T, 22, 3), Y up, metres
    assert arr[:, :, 1].min() < 0.2 and np.ptp(arr[:, :, 1]) > 1.4  # Y really is up here
    f = save(tmp_path / "000001.npy", arr)
    assert loader.detect(f)[0] == "humanml3d"
    m = simenv.load(f)
    assert isinstance(m, Motion) and m.skeleton.name == "smpl22"
    assert m.fps == 20.0 and m.num_frames == len(arr) and m.name == "000001"
    assert m.metadata["format"] == "humanml3d" and m.metadata["quirks"] == []
    np.testing.assert_allclose(m.positions, walk20.positions, atol=1e-6)
    np.testing.assert_allclose(m.positions[..., 2], arr[..., 1], atol=0)  # file Y -> Z up
    assert 1.2 < m.height() < 2.0  # joint span (toe to skull base) of CMU subject 02
    # A proper rotation: the body is neither mirrored nor turned over.
    assert chirality(arr, up=1) > 0.8 and chirality(m.positions, up=2) > 0.8
    assert simenv.load(f, fps=30).fps == 30.0


def test_humanml3d_round_trip(tmp_path: Path, walk20: Motion) -> None:
    f = write_humanml3d(walk20, tmp_path / "walk.npy")
    raw = np.load(f, allow_pickle=False)  # no pickle in the file
    assert raw.shape == (walk20.num_frames, 22, 3) and raw.dtype == np.float32
    np.testing.assert_allclose(raw, y_up(walk20.positions), atol=1e-6)
    back = simenv.load(f)
    assert back.fps == walk20.fps and back.skeleton == walk20.skeleton
    np.testing.assert_allclose(back.positions, walk20.positions, atol=1e-6)
    # Any skeleton: the CMU motion itself is mapped on the way out.
    cmu = bvh.read(asset_path(WALK)).resample(20.0)
    again = simenv.load(write_humanml3d(cmu, tmp_path / "cmu.npy"))
    np.testing.assert_allclose(again.positions, walk20.positions, atol=1e-6)


def test_writer_keeps_the_format_rate(tmp_path: Path) -> None:
    cmu = bvh.read(asset_path(WALK))
    with pytest.raises(MotionError, match=r"20 fps.*120 fps.*resample=True"):
        write_humanml3d(cmu, tmp_path / "x.npy")
    m = simenv.load(write_humanml3d(cmu, tmp_path / "x.npy", resample=True))
    assert m.fps == 20.0 and m.duration == pytest.approx(cmu.duration, abs=0.05)


def test_retarget_and_score_a_read_clip(tmp_path: Path, walk20: Motion) -> None:
    from simenv.body.retarget import retarget

    m = simenv.load(write_humanml3d(walk20.slice(0, 40), tmp_path / "walk40.npy"))
    result = retarget(m)
    assert result.qpos.shape[0] == 40 and np.isfinite(result.qpos).all()
    assert float(np.median(result.residuals)) < 0.05
    report = simenv.score(m, physics=False)
    assert report.people[0].verdict


def test_cli_info_on_a_humanml3d_file(tmp_path: Path, walk20: Motion, capsys) -> None:
    f = write_humanml3d(walk20, tmp_path / "walk.npy")
    assert cli.main(["info", str(f), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["format"] == "humanml3d" and info["fps"] == 20 and info["people"] == 1
    assert info["persons"][0]["joints"] == 22


# -- errors --------------------------------------------------------------------------


def test_wrong_joint_count(tmp_path: Path, walk20: Motion) -> None:
    arr = y_up(walk20.positions)
    f = save(tmp_path / "j23.npy", np.concatenate([arr, arr[:, :1]], axis=1))
    with pytest.raises(MotionError, match=r"23 joints per frame.*\(T, 22, 3\)") as err:
        simenv.load(f)
    assert err.value.source == str(f) and err.value.field == "positions"
    f21 = save(tmp_path / "kit.npy", arr[:, :21])
    with pytest.raises(MotionError, match="KIT-ML"):
        simenv.load(f21)


def test_nan_frame_is_located(tmp_path: Path, walk20: Motion) -> None:
    arr = y_up(walk20.positions)
    arr[17, 20, 1] = np.nan
    arr[30, 3, 0] = np.nan
    with pytest.raises(MotionError, match="2 of 58 frames") as err:
        simenv.load(save(tmp_path / "nan.npy", arr))
    assert err.value.frame == 17 and err.value.field == "left_wrist"
    assert "nan.npy" in str(err.value)


@pytest.mark.parametrize("frames", [0, 1])
def test_empty_and_one_frame_clips(tmp_path: Path, walk20: Motion, frames: int) -> None:
    f = save(tmp_path / "short.npy", y_up(walk20.positions)[:frames])
    with pytest.raises(MotionError, match=rf"{frames} frame\(s\); expected at least 2"):
        simenv.load(f)


def test_centimetres_are_named(tmp_path: Path, walk20: Motion) -> None:
    f = save(tmp_path / "cm.npy", y_up(walk20.positions) * 100.0)
    with pytest.raises(UnitsError, match=r"centimetres.*units='cm'") as err:
        simenv.load(f)
    assert err.value.source == str(f)
    m = simenv.load(f, units="cm")
    np.testing.assert_allclose(m.positions, walk20.positions, atol=1e-5)
    assert m.metadata["units"] == "cm"


@pytest.mark.parametrize(("axes", "match"), [
    ((0, 2, 1), r"\(T, 3, 22\).*transpose\(0, 2, 1\)"),
    ((1, 2, 0), r"\(22, 3, T\).*transpose\(2, 0, 1\)"),
])
def test_axis_layouts_are_named(tmp_path: Path, walk20: Motion, axes, match) -> None:
    f = save(tmp_path / "axes.npy", y_up(walk20.positions).transpose(axes))
    with pytest.raises(FormatError, match=match):
        simenv.load(f)


def test_feature_vectors_go_to_their_reader_and_pickles_are_refused(
        tmp_path: Path, walk20: Motion) -> None:
    # (T, 263) rows are features, read by humanml3d_features (tests/test_io_humanml3d_features.py);
    # handed to the positions reader they are named as such.
    vecs = save(tmp_path / "vecs.npy", np.zeros((walk20.num_frames, 263), np.float32))
    assert loader.detect(vecs)[0] == "humanml3d_features"
    with pytest.raises(FormatError, match="new_joint_vecs features"):
        humanml3d.from_array(np.load(vecs))
    # A pickled dict under another name is never unpickled.
    data = {"motion": y_up(walk20.positions).transpose(1, 2, 0)[None]}
    with pytest.raises(FormatError, match=r"results\*\.npy"):
        simenv.load(save(tmp_path / "generated.npy", data))


# -- MDM results.npy ------------------------------------------------------------------


def _mdm_dict(walk20: Motion) -> tuple[dict, list[int], list[int]]:
    """MDM's documented layout by hand: 2 prompts x 2 repetitions, entry
    rep * num_samples + sample, motion (N, 22, 3, T), shorter samples padded."""
    full = y_up(walk20.positions).astype(np.float32)  # (T, 22, 3)
    starts, lengths = [0, 5, 10, 15], [58, 40, 48, 30]
    motion = np.zeros((4, 22, 3, 58), np.float32)
    for k, (s, n) in enumerate(zip(starts, lengths, strict=True)):
        clip = full[s: s + n]
        motion[k, :, :, :n] = clip.transpose(1, 2, 0)
        motion[k, :, :, n:] = 1e3  # garbage past the length must be dropped
    texts = ["a person walks forward", "a person walks slowly"] * 2
    return {"motion": motion, "text": texts, "lengths": np.array(lengths),
            "num_samples": 2, "num_repetitions": 2}, starts, lengths


def test_hand_built_mdm_results(tmp_path: Path, walk20: Motion) -> None:
    data, starts, lengths = _mdm_dict(walk20)
    f = save(tmp_path / "results.npy", data)
    assert loader.detect(f)[0] == "humanml3d"
    motions = simenv.load(f)
    assert [m.name for m in motions] == ["results_sample00_rep00", "results_sample01_rep00",
                                         "results_sample00_rep01", "results_sample01_rep01"]
    for k, m in enumerate(motions):
        assert m.fps == 20.0 and m.num_frames == lengths[k]
        assert m.metadata["text"] == data["text"][k] and m.metadata["format"] == "mdm"
        assert (m.metadata["sample"], m.metadata["repetition"]) == (k % 2, k // 2)
        np.testing.assert_allclose(
            m.positions, walk20.positions[starts[k]: starts[k] + lengths[k]], atol=1e-6)


def test_mdm_round_trip(tmp_path: Path, walk20: Motion) -> None:
    clips = [walk20, walk20.slice(10, 40)]
    f = write_mdm_results(clips, tmp_path / "results.npy", texts=["walk", "walk, part"])
    back = simenv.load(f)
    assert [m.metadata["text"] for m in back] == ["walk", "walk, part"]
    for m, ref in zip(back, clips, strict=True):
        assert m.fps == ref.fps and m.num_frames == ref.num_frames
        np.testing.assert_allclose(m.positions, ref.positions, atol=1e-6)
    with pytest.raises(ValueError, match=r"results\*\.npy"):
        write_mdm_results(clips, tmp_path / "samples.npy")


def test_mdm_errors(tmp_path: Path, walk20: Motion) -> None:
    data, _, _ = _mdm_dict(walk20)
    wrong = dict(data, motion=data["motion"].transpose(0, 3, 1, 2))  # (N, T, 22, 3)
    with pytest.raises(FormatError, match=r"\(N, T, 22, 3\).*transpose\(0, 2, 3, 1\)") as err:
        simenv.load(save(tmp_path / "results.npy", wrong))
    assert err.value.field == "motion"
    bad_len = dict(data, lengths=np.array([58, 40, 99, 30]))
    with pytest.raises(FormatError, match=r"lengths\[2\] = 99") as err:
        simenv.load(save(tmp_path / "results_a.npy", bad_len))
    assert err.value.field == "lengths"
    one = dict(data, lengths=np.array([58, 1, 48, 30]))
    with pytest.raises(MotionError, match=r"sample 1 \(prompt 1, repetition 0, 'a person walks"):
        simenv.load(save(tmp_path / "results_b.npy", one))
    nan = {**data, "motion": data["motion"].copy()}
    nan["motion"][2, 7, 1, 12] = np.nan
    with pytest.raises(MotionError, match="sample 2") as err:
        simenv.load(save(tmp_path / "results_c.npy", nan))
    assert err.value.frame == 12 and err.value.field == "left_ankle"


class _Exploit:
    """Unpickling this would call os.mkdir: a stand-in for a malicious results.npy."""

    def __init__(self, target: str) -> None:
        self.target = target

    def __reduce__(self):
        return (os.mkdir, (self.target,))


def test_mdm_pickle_admits_only_numpy_and_builtins(tmp_path: Path, walk20: Motion) -> None:
    data, _, _ = _mdm_dict(walk20)
    target = tmp_path / "pwned"
    f = save(tmp_path / "results.npy", dict(data, extra=_Exploit(str(target))))
    with pytest.raises(FormatError, match="refusing to unpickle"):
        simenv.load(f)
    assert not target.exists()


# -- InterGen / InterHuman pairs ------------------------------------------------------


def test_hand_built_interhuman_raw_pair(tmp_path: Path, handshake30: Interaction) -> None:
    """Raw InterHuman rows: 22 joint positions (Z up) first, then more columns."""
    root = tmp_path / "interhuman"
    for person, m in zip(("person1", "person2"), handshake30.people, strict=True):
        rows = np.zeros((m.num_frames, 492), np.float32)  # width >= 62*3 + 21*6
        rows[:, :66] = m.positions.reshape(m.num_frames, 66)
        save(root / "motions_processed" / person / "1234.npy", rows)
    (root / "annots").mkdir()
    (root / "annots" / "1234.txt").write_text("two people shake hands.\nthey greet.\n")
    pair = simenv.load(root / "motions_processed" / "person2" / "1234.npy")
    assert isinstance(pair, Interaction) and pair.name == "1234" and not pair.roles_known
    assert pair.fps == 30.0 and pair.metadata["texts"] == ["two people shake hands.",
                                                           "they greet."]
    assert pair.actor.name == "1234_person1" and pair.actor.metadata["layout"] == "interhuman"
    for got, ref in zip(pair.people, handshake30.people, strict=True):
        np.testing.assert_allclose(got.positions, ref.positions, atol=1e-6)


def test_hand_built_intergen_262_pair(tmp_path: Path, handshake30: Interaction) -> None:
    """InterGen's representation: positions (Y up) | velocities | 6D rotations | contacts."""
    for person, m in zip(("person1", "person2"), handshake30.people, strict=True):
        pos = y_up(m.positions).reshape(m.num_frames, 66)
        vel = np.diff(pos, axis=0, append=pos[-1:])
        rows = np.concatenate([pos, vel, np.zeros((m.num_frames, 126 + 4))], axis=1)
        assert rows.shape[1] == 262
        save(tmp_path / person / "7.npy", rows.astype(np.float32))
    pair = simenv.load([tmp_path / "person1" / "7.npy", tmp_path / "person2" / "7.npy"])
    assert pair.actor.metadata["layout"] == "intergen262"
    for got, ref in zip(pair.people, handshake30.people, strict=True):
        np.testing.assert_allclose(got.positions, ref.positions, atol=1e-6)
        assert chirality(got.positions, up=2) > 0.5


def test_intergen_round_trip(tmp_path: Path, handshake30: Interaction) -> None:
    p1, p2 = write_intergen(handshake30, tmp_path / "out", "42")
    assert (p1.parent.name, p2.parent.name) == ("person1", "person2")
    assert np.load(p1, allow_pickle=False).shape == (handshake30.num_frames, 22, 3)
    assert loader.detect(p1)[0] == "intergen"
    pair = simenv.load([p2, p1])  # either order: person1 is the actor
    assert isinstance(pair, Interaction) and pair.fps == 30.0
    for got, ref in zip(pair.people, handshake30.people, strict=True):
        np.testing.assert_allclose(got.positions, ref.positions, atol=1e-6)
    # The two people keep their real distance (one world frame).
    gap = np.linalg.norm(pair.actor.positions[:, 0] - pair.reactor.positions[:, 0], axis=1)
    ref_gap = np.linalg.norm(handshake30.actor.positions[:, 0]
                             - handshake30.reactor.positions[:, 0], axis=1)
    np.testing.assert_allclose(gap, ref_gap, atol=1e-5)
    with pytest.raises(MotionError, match=r"30 fps.*resample=True"):
        write_intergen(simenv.load(asset_path(HANDSHAKE_PAIR)), tmp_path / "x")


def test_intergen_errors(tmp_path: Path, handshake30: Interaction) -> None:
    a, b = handshake30.people
    p1 = save(tmp_path / "person1" / "3.npy", y_up(a.positions))
    save(tmp_path / "person2" / "3.npy", y_up(b.positions)[:-5])
    n = a.num_frames
    with pytest.raises(MotionError, match=f"person1 has {n} frames and person2 {n - 5}"):
        simenv.load(p1)
    odd = save(tmp_path / "person1" / "4.npy", np.zeros((10, 100), np.float32))
    with pytest.raises(FormatError, match=r"\(T, 262\)"):
        intergen.read(odd)
    # A lone person reads as one Motion, with a note.
    lone = save(tmp_path / "person1" / "5.npy", y_up(a.positions))
    m = simenv.load(lone)
    assert isinstance(m, Motion) and "not found" in m.metadata["quirks"][0]


# -- real corpus ----------------------------------------------------------------------


def test_shared_cmu_clip_through_humanml3d(shared_data: Path, tmp_path: Path) -> None:
    src = simenv.load(shared_data / "cmu" / "bvh" / "49_02.bvh")
    f = write_humanml3d(src, tmp_path / "49_02.npy", resample=True)
    back = humanml3d.read(f)
    ref = to_smpl22(src.resample(20.0))
    np.testing.assert_allclose(back.positions, ref.positions, atol=1e-6)
    assert chirality(back.positions, up=2) > 0.5

"""Source kinds and depth-camera profiles (simenv.plausibility.profiles), on real clips: a real
NTU RGB+D (Kinect v2) clip, real Kinect v1 clips (MSR Action3D, Florence 3D), real CMU motion
capture. Physics off: the metrics under test are joint-level."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from simenv.cli import score as score_cli
from simenv.core.errors import SimenvError
from simenv.io.loader import load
from simenv.plausibility.corrupt import CORRUPTIONS
from simenv.plausibility.metric import ScoreConfig
from simenv.plausibility.profiles import (
    DECLARABLE_SOURCES,
    apply_profile,
    at_profile_rate,
    detect_source,
    load_profiles,
    profile_for,
    profile_path,
)
from simenv.plausibility.report import score
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS

NTU = Path(__file__).parent / "data" / "ntu" / "S001C001P001R001A001.skeleton"
MSR = "gestures/msr_action3d/a01_s01_e01_skeleton3D.txt"


def test_bundled_profiles_name_their_calibration() -> None:
    profiles = load_profiles()
    assert set(profiles) == {"kinect_v1", "kinect_v1@30", "kinect_v2"}
    assert {n: p.fps for n, p in profiles.items()} == {"kinect_v1": 15.0, "kinect_v1@30": 30.0,
                                                      "kinect_v2": 30.0}
    for p in profiles.values():
        assert p.thresholds["bone_length_rel_max"] > DEFAULT_THRESHOLDS.bone_length_rel_max
        assert p.provenance["script"] == "benchmarks/depth_camera_profiles.py"
        assert p.provenance["calibration_sources"]
    # The held-out sources never enter a calibration.
    assert "ntu" not in profiles["kinect_v2"].provenance["calibration_sources"]
    assert not {"florence3d", "sbu"} & set(profiles["kinect_v1"].provenance["calibration_sources"])
    assert set(profiles["kinect_v1@30"].provenance["calibration_sources"]) == {"msrc12",
                                                                              "kindergator"}


def test_a_clip_is_judged_by_its_familys_profile_at_its_rate(shared_data: Path) -> None:
    """A real Kinect v1 clip (MSR Action3D, 15 fps) is judged by the 15-fps profile; the same
    clip at 20 fps (Florence 3D's rate) too, as it is; at 30 fps (the sensor's rate) by the
    30-fps one; at 60 fps by the 30-fps one on every second frame, which the record says."""
    msr = load(shared_data / MSR)
    kind = detect_source(msr)
    assert profile_for(kind).name == "kinect_v1"
    assert [profile_for(kind, f).name for f in (10.0, 15.0, 20.0, 25.0, 30.0, 60.0)] == [
        "kinect_v1", "kinect_v1", "kinect_v1", "kinect_v1@30", "kinect_v1@30", "kinect_v1@30"]
    rec = score(msr, physics=False).to_records()[0]
    assert rec["profile"] == "kinect_v1" and "judged_fps" not in rec["source_kind"]
    mid = score(msr.resample(20.0), physics=False).to_records()[0]
    assert mid["profile"] == "kinect_v1" and "judged_fps" not in mid["source_kind"]
    fast = msr.resample(60.0)
    thin = at_profile_rate(fast, profile_for(kind, 60.0))
    assert thin.fps == 30.0 and thin.num_frames == (fast.num_frames + 1) // 2
    np.testing.assert_array_equal(thin.positions, fast.positions[::2])
    rec = score(fast, physics=False).to_records()[0]
    assert rec["profile"] == "kinect_v1@30" and rec["source_kind"]["judged_fps"] == 30.0
    assert rec["frames"] == thin.num_frames


def test_real_kinect_v2_clip_is_judged_by_its_profile_by_default() -> None:
    clip = load(NTU)
    kind = detect_source(clip)
    assert kind.record() == {"kind": "kinect_v2", "profile": "kinect_v2",
                             "how": "skeleton kinect_v2_25"}
    before = score(clip, physics=False, source="mocap").to_records()[0]
    after = score(clip, physics=False).to_records()[0]
    assert before["profile"] == "mocap" and before["verdict"] == "implausible"
    assert before["metrics"]["bone_length"]["passed"] is False
    assert after["profile"] == "kinect_v2"
    assert after["source_kind"] == {"kind": "kinect_v2", "profile": "kinect_v2",
                                    "how": "skeleton kinect_v2_25"}
    assert after["verdict"] == "plausible"
    assert after["metrics"]["bone_length"]["value"] == pytest.approx(
        before["metrics"]["bone_length"]["value"] * DEFAULT_THRESHOLDS.bone_length_rel_max
        / load_profiles()["kinect_v2"].thresholds["bone_length_rel_max"], rel=1e-6)


def test_corrupted_kinect_clip_fails_its_profile() -> None:
    clip = load(NTU)
    bad = CORRUPTIONS["jitter"].fn(clip, CORRUPTIONS["jitter"].moderate, seed=0)
    rec = score(bad, physics=False).to_records()[0]
    assert rec["profile"] == "kinect_v2"
    assert rec["verdict"] == "implausible" and rec["metrics"]["jitter"]["passed"] is False


def test_real_kinect_v1_clips_pick_the_kinect_v1_profile(shared_data: Path) -> None:
    msr = load(shared_data / MSR)
    assert detect_source(msr).profile == "kinect_v1"
    florence = load(shared_data / "gestures/florence3d/skeletal_data.mat")[0]
    assert detect_source(florence).how == "skeleton florence15"
    rec = score(msr, physics=False).to_records()[0]
    assert rec["profile"] == "kinect_v1"


def test_cmu_clip_keeps_the_mocap_thresholds(shared_data: Path) -> None:
    clip = load(shared_data / "cmu/bvh/02_01.bvh")
    kind = detect_source(clip)
    assert (kind.kind, kind.profile) == ("mocap", "mocap")
    assert profile_for(kind) is None
    report = score(clip, physics=False)
    rec = report.to_records()[0]
    assert rec["profile"] == "mocap"
    assert rec["metrics"]["bone_length"]["threshold"] == 1.0
    declared = score(clip, physics=False, source="mocap").to_records()[0]
    assert rec["metrics"] == declared["metrics"]


def test_a_rigid_file_keeps_the_mocap_bone_tolerance_under_a_depth_profile(
        shared_data: Path) -> None:
    """A file that stores rotations on fixed bones (here a real CMU BVH judged as a Kinect v1
    clip, as a NiTE recording exported to rotation-channel BVH is) cannot carry the sensor's
    bone-length noise: its bones keep the motion-capture tolerance under the family's profile,
    so a 10 % stretched bone fails, while the profile's other fields judge it. The same
    stretch on a real Kinect v1 clip of per-joint positions hides in the profile's tolerance."""
    clip = load(shared_data / "cmu/bvh/02_01.bvh").slice(0, 240)
    assert clip.metadata["rigid_bones"] is True
    kinect = load(shared_data / MSR)
    assert "rigid_bones" not in kinect.metadata
    stretch = CORRUPTIONS["bone_stretch"]
    clean = score(clip, physics=False, source="kinect_v1").to_records()[0]
    bad = score(stretch.fn(clip, stretch.moderate, seed=0), physics=False,
                source="kinect_v1").to_records()[0]
    assert clean["source_kind"]["rigid_bones"] is True and clean["profile"] == "kinect_v1@30"
    assert clean["metrics"]["bone_length"]["passed"] is True
    assert bad["metrics"]["bone_length"]["passed"] is False
    assert bad["metrics"]["bone_length"]["value"] > 1.5
    profile = load_profiles()["kinect_v1@30"]
    assert clean["metrics"]["velocity"]["details"] == score(
        replace(clip, metadata={**clip.metadata, "rigid_bones": False}), physics=False,
        source="kinect_v1").to_records()[0]["metrics"]["velocity"]["details"]
    assert profile.thresholds["bone_length_rel_max"] > 10 * DEFAULT_THRESHOLDS.bone_length_rel_max
    loose = score(stretch.fn(kinect, stretch.moderate, seed=0), physics=False).to_records()[0]
    assert "rigid_bones" not in loose["source_kind"]
    assert loose["metrics"]["bone_length"]["passed"] is True


@pytest.mark.parametrize(("path", "kind"), [
    ("conventions/xsens_mvn/emokine_mvn_segment_positions.csv", "mocap"),
    ("humanml3d/new_joints/012314.npy", "body_model"),
    ("humanml3d/new_joint_vecs/000612.npy", "body_model"),
    ("conventions/rokoko/rokoko_video_mixamo_preset_jesse_dance.bvh", "mocap"),
])
def test_sources_of_other_labs_and_models(path: str, kind: str) -> None:
    """Real files of other readers: an Xsens suit's segments are rigid like optical mocap,
    HumanML3D joints and features are a body model's."""
    clip = load(Path(__file__).parent / "data" / path)
    assert detect_source(clip).kind == kind


def test_declared_kinds() -> None:
    clip = load(NTU)
    assert detect_source(clip, "mocap").profile == "mocap"
    assert detect_source(clip, "mocap").how == "declared"
    # A generated clip on a depth camera's skeleton: that family's profile.
    gen = detect_source(clip, "generated")
    assert (gen.kind, gen.profile) == ("generated", "kinect_v2")
    assert detect_source(clip, "kinect_v1").profile == "kinect_v1"
    with pytest.raises(SimenvError, match="unknown source kind 'kinect3'"):
        detect_source(clip, "kinect3")
    assert score_cli.SOURCE_CHOICES == DECLARABLE_SOURCES


def test_explicit_thresholds_stay_the_users() -> None:
    profile = load_profiles()["kinect_v2"]
    mine = replace(DEFAULT_THRESHOLDS, bone_length_rel_max=0.5)
    config = apply_profile(ScoreConfig(thresholds=mine), profile)
    assert config.thresholds.bone_length_rel_max == 0.5
    assert config.thresholds.speed_limit_trunk_mps == profile.thresholds["speed_limit_trunk_mps"]


def test_bad_profiles_file(tmp_path: Path) -> None:
    bad = tmp_path / "p.json"
    bad.write_text(json.dumps({"profiles": {"x": {"thresholds": {"bone_length_rel_max": -1}}}}))
    with pytest.raises(SimenvError, match="x.thresholds.bone_length_rel_max"):
        load_profiles(bad)
    with pytest.raises(SimenvError, match="missing"):
        load_profiles(tmp_path / "none.json")
    assert profile_path().is_file()


def test_cli_records_the_profile(capsys: pytest.CaptureFixture[str]) -> None:
    from simenv.cli.main import main

    assert main(["score", str(NTU), "--no-physics", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out.strip().splitlines()[0])
    assert rec["profile"] == "kinect_v2" and rec["verdict"] == "plausible"
    assert main(["score", str(NTU), "--no-physics", "--json", "--source", "mocap"]) == 0
    rec = json.loads(capsys.readouterr().out.strip().splitlines()[0])
    assert rec["profile"] == "mocap" and rec["verdict"] == "implausible"


def test_html_report_says_which_profile_judged(tmp_path: Path) -> None:
    from simenv.plausibility.html_report import write_report

    page = write_report(score(load(NTU), physics=False), tmp_path / "ntu").read_text()
    assert "judged by" in page and "kinect_v2 depth-camera profile" in page

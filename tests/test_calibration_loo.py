"""The leave-clips-out calibration of benchmarks/calibrate_loo.py on hand-made records."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import calibrate_loo  # noqa: E402

from simenv.core.errors import SimenvError  # noqa: E402
from simenv.plausibility.metric import ScoreConfig  # noqa: E402
from simenv.plausibility.metric_registry import PERSON_METRICS  # noqa: E402


def test_threshold_rule() -> None:
    rule = calibrate_loo.fold_threshold
    # Every real value below the prior: the prior stays (no loosening).
    assert rule([1.0, 2.0, 3.0, 80.0, 89.0], 100.0) == 100.0
    # Real clips above the prior raise it to the largest non-outlier ...
    assert rule([30.0, 32.0, 35.0, 38.0, 39.0, 41.0], 30.0) == 41.0
    # ... but a far-out value (Q3 + 3 IQR) cannot drag it up.
    assert rule([0.0] * 20 + [36.8, 32.3, 60.0], 10.0) == 10.0
    assert rule([1.0, 1.1, 1.2, 1.3, 1.4, 9.0], 1.0) == pytest.approx(1.4)
    # Too few values, or none finite: the prior.
    assert rule([50.0, 60.0, None], 30.0) == 30.0
    assert rule([float("inf")] * 5, 0.5) == 0.5


def _record(file: str, values: dict[str, float], person: int = 0) -> dict[str, Any]:
    metrics = {n: {"value": 0.0, "threshold": 10.0, "passed": True, "unit": "u"}
               for n in PERSON_METRICS}
    for n, v in values.items():
        metrics[n]["value"] = v
    return {"file": file, "person": person, "metrics": metrics}


def test_no_clip_judges_itself(tmp_path: Path) -> None:
    """A clip's own value never enters the threshold it is judged with: the one
    clip far above its prior fails in its fold, while the subjects whose values
    sit just above the prior pass on the others' values."""
    (tmp_path / "gestures").mkdir()
    (tmp_path / "gestures" / "index.csv").write_text("dataset,file,subject\n")
    base = tmp_path / "cmu" / "bvh"
    real = [_record(str(base / f"{s}_01.bvh"), {"ground_penetration": v})
            for s, v in ((1, 12.0), (2, 14.0), (3, 16.0), (4, 18.0), (5, 20.0))]
    real.append(_record(str(base / "6_01.bvh"), {"ground_penetration": 400.0}))
    real.append(_record(str(base / "7_01.bvh"), {"ground_penetration": 11.0}))
    # Subjects 1-5 each exceed the prior (10); subject 7 only just.
    th = calibrate_loo.judge(real, [], tmp_path)
    verdicts = {Path(r["file"]).stem: r["_fail_loo"] for r in real}
    assert verdicts["6_01"] == ["ground_penetration"]
    assert th["folds"]["cmu/6"]["ground_penetration"] == 20.0
    assert th["folds"]["cmu/5"]["ground_penetration"] == 18.0  # 400 is far out, 20 is its own
    assert verdicts["5_01"] == ["ground_penetration"]  # the largest real value, held out
    assert all(not verdicts[f"{s}_01"] for s in (1, 2, 3, 4, 7))
    # Against the default threshold (10) every one of them fails.
    assert all(r["_fail_default"] for r in real)
    # A run without corrupted copies says so instead of an empty table.
    text = calibrate_loo.markdown(real, [], th, tmp_path, "mpc-segments-seeds",
                                  calibrate_loo.mpc_settings("mpc-segments-seeds"))
    assert "No corrupted copies were scored" in text and "| source | corruption |" not in text
    assert calibrate_loo.TRACKERS["mpc-segments-seeds"] in text
    assert f"{ScoreConfig().mpc.n_samples} samples per replan" in text


def test_depth_camera_profile_passes_a_real_kinect_clip_and_catches_a_slide(
        shared_data: Path) -> None:
    """MSR Action3D a01_s03_e02 (a real Kinect wave) fails five metrics at the motion
    capture defaults; with its source's own calibration it is plausible, and its
    feet slid 1 m/s are still caught."""
    from simenv.io.loader import load
    from simenv.plausibility.body_thresholds import SOURCE_BODY_THRESHOLDS
    from simenv.plausibility.corrupt import foot_slide
    from simenv.plausibility.metric import ScoreConfig
    from simenv.plausibility.report import score
    from simenv.plausibility.thresholds import SOURCE_THRESHOLDS

    path = shared_data / "gestures" / "msr_action3d" / "a01_s03_e02_skeleton3D.txt"
    if not path.exists():
        pytest.skip(f"{path} not in the shared data")
    clip = load(path)
    clip = clip[0] if isinstance(clip, list) else clip
    default = score(clip, config=ScoreConfig(tracking=False), source="mocap").people[0]
    assert {"bone_length", "foot_skate"} <= set(default.failed), default.failed
    own = ScoreConfig(thresholds=SOURCE_THRESHOLDS["msr_action3d"],
                      body=SOURCE_BODY_THRESHOLDS["msr_action3d"], tracking=False)
    assert score(clip, config=own).people[0].verdict == "plausible"
    slid = score(foot_slide(clip, 1.0, seed=0), config=own).people[0]
    assert "foot_skate" in slid.failed, slid.failed


def test_one_tracker_per_run_folder(tmp_path: Path) -> None:
    """The scorer's MPC or the assisted PD servos judge tracking; a folder keeps the tracker
    its first stage recorded, and a second tracker is refused rather than mixed in."""
    assert calibrate_loo.score_config("mpc").tracking_controller == "mpc"
    assert not calibrate_loo.score_config("mpc").tracking_assist
    pd = calibrate_loo.score_config("pd-assisted")
    assert pd.tracking_controller == "pd" and pd.tracking_assist
    segmented = calibrate_loo.score_config("mpc-segments")
    assert segmented.tracking_controller == "mpc" and not segmented.tracking_assist
    assert segmented.body.tracking_segment_s == 4.0 and segmented.mpc.attempts == 1
    seeds = calibrate_loo.score_config("mpc-segments-seeds")
    assert seeds.body.tracking_segment_s == 4.0 and seeds.mpc.attempts == 3
    assert calibrate_loo.score_config("mpc").body.tracking_segment_s == float("inf")
    assert calibrate_loo.score_config("mpc").mpc.attempts == 1
    # The scorer's default is the last of them.
    default = ScoreConfig()
    assert (seeds.body.tracking_segment_s, seeds.mpc.attempts) == (
        default.body.tracking_segment_s, default.mpc.attempts)
    assert calibrate_loo.run_tracker(tmp_path, None) == ("pd-assisted", None)  # an old folder
    settings = calibrate_loo.mpc_settings("mpc")
    assert settings == {"n_samples": default.mpc.n_samples, "horizon_s": default.mpc.horizon_s,
                        "retry_horizon_s": default.mpc.retry_horizon_s, "attempts": 1}
    assert calibrate_loo.run_tracker(tmp_path, "mpc") == ("mpc", settings)
    assert calibrate_loo.run_tracker(tmp_path, None) == ("mpc", settings)
    with pytest.raises(SimenvError, match="tracker 'mpc'"):
        calibrate_loo.run_tracker(tmp_path, "pd-assisted")
    # A run scored with other planner settings is not resumed with the current ones.
    record = tmp_path / "tracker.json"
    record.write_text(json.dumps({"tracker": "mpc", "mpc": {**settings, "n_samples": 2}}))
    with pytest.raises(SimenvError, match="the scorer now plans with"):
        calibrate_loo.run_tracker(tmp_path, "mpc")
    assert calibrate_loo.run_tracker(tmp_path, None)[1]["n_samples"] == 2
    assert calibrate_loo.mpc_settings("pd-assisted") is None
    with pytest.raises(SimenvError, match="unknown tracker"):
        calibrate_loo.score_config("assisted")

"""simenv.score / PlausibilityReport on real motion capture (bundled CMU clips)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import simenv
from simenv.assets import HANDSHAKE_PAIR, WALK, asset_path
from simenv.core.errors import SimenvError
from simenv.core.motion import Interaction
from simenv.plausibility.metric import ScoreConfig
from simenv.plausibility.metric_registry import PAIR_METRICS, PERSON_METRICS
from simenv.plausibility.report import metric_score, score
from simenv.plausibility.timeline import MetricResult

RECORD_KEYS = {"file", "person", "name", "frames", "fps", "verdict", "score", "physics",
               "metrics", "violations"}
METRIC_KEYS = {"value", "unit", "threshold", "passed", "basis", "details", "reason"}


@pytest.fixture(scope="module")
def walk():
    # Two seconds of the bundled CMU 02_01 walk keep the physics quick.
    return simenv.load(asset_path(WALK)).slice(0, 240)


@pytest.fixture(scope="module")
def walk_report(walk_1s_report):
    # The shipped planner's run on the walk's first second, shared with the HTML-page tests.
    return walk_1s_report


def _lowered(motion, metres):
    return motion.with_positions(motion.positions - np.float32([0, 0, metres]))


def test_real_walk_is_plausible_with_every_metric(walk_report):
    person = walk_report.people[0]
    assert list(person.metrics) == list(PERSON_METRICS)
    assert all(m.passed is not None for m in person.metrics.values()), {
        n: m.reason for n, m in person.metrics.items() if m.passed is None}
    assert person.verdict == "plausible", person.failed
    assert walk_report.verdict == "plausible"
    assert 50.0 <= person.score <= 100.0
    assert person.violations == []
    assert person.basis["ground_penetration"] == "geoms"
    assert person.basis["tracking"] == "simulation"
    assert person.metrics["tracking"].details["success"] == 1.0
    assert "unassisted_time_to_failure_s" in person.metrics["tracking"].details
    # Judged unassisted by the MPC (no help at the root); the assisted PD run is a detail.
    tracked = person.metrics["tracking"].details
    assert tracked["mpc"] == 1.0 and tracked["assist_force_mean"] == 0.0
    assert tracked["assisted_success"] == 1.0 and tracked["assisted_force_mean"] > 0.0
    assert tracked["work_j"] > 0.0 and tracked["work_j_per_kg"] > 0.0
    for m in person.metrics.values():
        assert m.timeline.shape == (person.frames,)


def test_json_records_follow_the_contract(walk_report):
    (rec,) = walk_report.to_records()
    assert RECORD_KEYS <= set(rec)
    assert rec["verdict"] in ("plausible", "implausible")
    assert set(rec["metrics"]) == set(PERSON_METRICS)
    for m in rec["metrics"].values():
        assert METRIC_KEYS <= set(m)
    text = json.dumps(rec, allow_nan=False)  # strict JSON: no NaN or inf sneaks in
    assert json.loads(text)["frames"] == walk_report.people[0].frames == 120


def test_sunken_walk_fails_ground_penetration_with_its_frames(walk):
    report = score(_lowered(walk, 0.10), config=ScoreConfig(tracking=False,
                                                            joint_limits=False))
    person = report.people[0]
    gp = person.metrics["ground_penetration"]
    assert gp.passed is False and gp.value > 60.0  # mm below the floor
    assert person.verdict == "implausible" and person.score < 50.0
    (rec,) = report.to_records()
    runs = [v for v in rec["violations"] if v["metric"] == "ground_penetration"]
    assert runs and all(0 <= v["start_frame"] <= v["end_frame"] < 240 for v in runs)
    assert person.metrics["tracking"].passed is None
    assert "disabled" in person.metrics["tracking"].reason


def test_raised_walk_fails_floating_and_root_residual(walk):
    raised = walk.with_positions(walk.positions + np.float32([0, 0, 0.3]))
    person = score(raised, config=ScoreConfig(tracking=False, joint_limits=False)).people[0]
    assert person.metrics["floating"].passed is False
    assert person.metrics["root_residual"].passed is False
    assert person.metrics["root_residual"].value > 0.5  # body weights of help from nowhere


def test_raised_walk_needs_help_the_unassisted_controller_measures(walk):
    """With the unassisted controller judging, root_residual counts help only on the
    frames the simulated body could not follow: a walk 30 cm up falls to the floor,
    so nearly every frame keeps its inferred ~1 body weight."""
    raised = walk.slice(0, 60).with_positions(walk.positions[:60] + np.float32([0, 0, 0.3]))
    config = ScoreConfig(joint_limits=False, tracking_assisted_detail=False)
    root = score(raised, config=config).people[0].metrics["root_residual"]
    assert root.passed is False and root.value > 0.5, root.details
    assert root.details["measured_fraction"] < 0.5
    assert root.value <= root.details["inferred_mean"]


def test_track_if_plausible_skips_the_tracking_of_a_failing_person_only(walk):
    """``track_if_plausible``: the walk sunk 10 cm fails ground penetration before any
    tracking, so it is not tracked (its tracking says why); the real walk passes everything
    else, so it is tracked as without the option."""
    from dataclasses import replace

    from simenv.control import FAST

    config = ScoreConfig(joint_limits=False, tracking_assisted_detail=False,
                         mpc=replace(FAST, attempts=1), track_if_plausible=True)
    sunk = score(_lowered(walk.slice(0, 24), 0.10), config=config).people[0]
    assert sunk.verdict == "implausible"
    tracking = sunk.metrics["tracking"]
    assert tracking.passed is None and tracking.reason.startswith("skipped: ")
    assert "ground_penetration" in tracking.reason
    assert sunk.metrics["root_residual"].passed is not None  # the inferred residual
    clean = score(walk.slice(0, 12), config=config).people[0]
    assert clean.metrics["tracking"].reason is None
    assert clean.metrics["tracking"].passed is not None


def test_no_physics_reports_what_it_cannot_compute(walk):
    person = score(walk, physics=False).people[0]
    assert person.basis["ground_penetration"] == "keypoints"
    for name in ("joint_limits", "self_penetration", "root_residual", "balance", "tracking"):
        m = person.metrics[name]
        assert m.passed is None and m.reason == "physics=False"
    assert person.verdict == "plausible"


def test_one_frame_motion_computes_what_it_can(walk):
    person = score(walk.slice(0, 1), physics=False).people[0]
    assert person.metrics["bone_length"].passed is not None
    assert person.metrics["ground_penetration"].passed is not None
    for name in ("foot_skate", "jitter", "velocity"):
        assert person.metrics[name].passed is None
        assert "frame" in person.metrics[name].reason


def test_skeleton_without_legs_names_the_missing_keypoints(walk):
    canon = walk.to_canonical()
    upper = [n for n in canon.skeleton.joint_names
             if not any(k in n for k in ("hip", "knee", "ankle", "toe", "pelvis"))]
    idx = [canon.skeleton.index(n) for n in upper]
    motion = type(canon)(canon.positions[:, idx], canon.fps, canon.skeleton.subset(upper),
                         name="upper body")
    person = score(motion).people[0]
    assert person.metrics["foot_skate"].passed is None
    assert person.metrics["tracking"].passed is None
    assert "no body could be fitted" in person.metrics["tracking"].reason
    assert person.metrics["velocity"].passed is not None  # the rest is still computed


def test_two_people_get_pairwise_metrics():
    pair = simenv.load(asset_path(HANDSHAKE_PAIR))
    assert isinstance(pair, Interaction)
    report = score(pair.slice(0, 120), config=ScoreConfig(tracking=False, joint_limits=False))
    assert len(report.people) == 2
    assert set(report.interaction) == set(PAIR_METRICS)
    assert report.interaction["inter_penetration"].passed is True
    recs = report.to_records()
    assert [r["person"] for r in recs] == [0, 1]
    assert all(set(r["interaction"]["metrics"]) == set(PAIR_METRICS) for r in recs)


def test_people_on_top_of_each_other_fail_inter_penetration(walk):
    clip = walk.slice(0, 60)
    pair = Interaction(clip, clip.with_positions(clip.positions + np.float32([0.05, 0, 0])))
    report = score(pair, config=ScoreConfig(tracking=False, joint_limits=False))
    assert report.interaction["inter_penetration"].passed is False
    assert report.verdict == "implausible"


def test_score_reads_paths_and_rejects_other_things(tmp_path):
    report = score(asset_path(WALK), physics=False)
    assert report.source.endswith(WALK)
    with pytest.raises(SimenvError, match="no such file|not exist|No such"):
        score(tmp_path / "missing.bvh", physics=False)
    with pytest.raises(SimenvError, match="expects a Motion"):
        score(42)  # type: ignore[arg-type]


def _result(value: float, threshold: float) -> MetricResult:
    return MetricResult.from_timeline("x", np.zeros(3), value, "u", threshold)


@pytest.mark.parametrize(("value", "expected"), [
    (0.0, 100.0), (0.5, 75.0), (1.0, 50.0), (2.0, 25.0), (4.0, 12.5), (math.inf, 0.0),
])
def test_metric_score_mapping(value, expected):
    assert metric_score(_result(value, 1.0)) == pytest.approx(expected)


def test_metric_score_of_unavailable_metric_is_none():
    assert metric_score(MetricResult.not_available("x", 3, "u", 1.0, "why")) is None


def test_score_is_at_least_50_exactly_when_plausible(walk):
    for motion in (walk, _lowered(walk, 0.08)):
        person = score(motion, physics=False).people[0]
        assert (person.score >= 50.0) == (person.verdict == "plausible")


def test_standing_body_leaning_off_its_feet_fails_balance(shared_data):
    # CMU 131_01 frames 820-940: standing still (quasi-static, judged by balance).
    stand = simenv.load(shared_data / "cmu/bvh/131_01.bvh").slice(820, 940).to_canonical()
    fixed = [i for i, n in enumerate(stand.skeleton.joint_names) if "toe" in n or "ankle" in n]
    lean = stand.positions.copy()
    moved = np.ones(stand.num_joints, dtype=bool)
    moved[fixed] = False
    lean[:, moved, 0] += 0.2  # everything above the ankles 20 cm forward, feet planted
    config = ScoreConfig(tracking=False, joint_limits=False)
    real = score(stand, config=config).people[0].metrics["balance"]
    leaning = score(stand.with_positions(lean), config=config).people[0].metrics["balance"]
    assert real.passed is True
    assert leaning.passed is False and leaning.value > 100.0


def test_forearm_through_the_torso_fails_self_penetration(walk):
    clip = walk.slice(0, 120).to_canonical()
    names = clip.skeleton.joint_names
    pos = clip.positions.copy()
    chest, spine = pos[:, names.index("chest")], pos[:, names.index("spine")]
    pos[:, names.index("right_hand")] = chest
    pos[:, names.index("right_wrist")] = 0.5 * (chest + spine)
    config = ScoreConfig(tracking=False, joint_limits=False)
    real = score(clip, config=config).people[0].metrics["self_penetration"]
    through = score(clip.with_positions(pos), config=config).people[0].metrics["self_penetration"]
    assert real.passed is True and real.value < 30.0
    assert through.passed is False

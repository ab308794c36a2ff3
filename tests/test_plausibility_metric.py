"""The metric registry and the scorer's shared inputs (simenv.plausibility.metric*)."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from collections import Counter

import numpy as np

import simenv
import simenv.plausibility.metric as metric_module
import simenv.plausibility.metrics as metrics_package
import simenv.plausibility.metrics.balance as balance_module
import simenv.plausibility.metrics.contact as contact_module
import simenv.plausibility.metrics.ground_penetration as ground_module
import simenv.plausibility.metrics.joint_limits as joint_limits_module
import simenv.plausibility.metrics.tracking as tracking_module
import simenv.plausibility.report as report_module
from simenv.assets import HANDSHAKE_PAIR, asset_path
from simenv.body import dynamics as body_dynamics
from simenv.body import geometry
from simenv.plausibility.keypoints import KINEMATIC_METRICS
from simenv.plausibility.metric import DEFAULT_SCORE_CONFIG, Metric, Needs, ScoreConfig
from simenv.plausibility.metric_registry import (
    KEYPOINT_REGISTRY,
    METRICS,
    PAIR_METRICS,
    PAIR_REGISTRY,
    PERSON_METRICS,
    PERSON_REGISTRY,
    alternatives,
)
from simenv.plausibility.report import score
from simenv.plausibility.timeline import MetricResult

#: The report's names in order: the JSON contract.
CONTRACT_PERSON = ("bone_length", "foot_skate", "ground_penetration", "floating", "jitter",
                   "velocity", "joint_limits", "self_penetration", "root_residual", "balance",
                   "tracking")
CONTRACT_PAIR = ("inter_penetration", "contact", "pair_root_residual")
FAMILIES = {"kinematic", "contact", "body", "dynamics", "tracking"}
BASES = {"keypoints", "geoms", "dynamics", "simulation"}
QUICK = ScoreConfig(tracking=False)


def test_every_metric_is_registered_once_in_report_order():
    everything = PERSON_REGISTRY + PAIR_REGISTRY
    assert len({id(m) for m in everything}) == len(everything)
    assert len({type(m) for m in everything}) == len(everything)
    # A name has at most one metric per input (the geom and the keypoint versions).
    assert len({(m.name, m.needs) for m in everything}) == len(everything)
    assert PERSON_METRICS == CONTRACT_PERSON
    assert PAIR_METRICS == CONTRACT_PAIR
    options = alternatives(PERSON_REGISTRY)
    assert [m.basis for m in options["ground_penetration"]] == ["geoms", "keypoints"]
    assert [m.basis for m in options["floating"]] == ["geoms", "keypoints"]
    assert all(len(v) == 1 for k, v in options.items() if k not in ("ground_penetration",
                                                                    "floating"))


def test_registered_metrics_follow_the_protocol():
    for m in PERSON_REGISTRY + PAIR_REGISTRY:
        assert isinstance(m, Metric), m
        assert m.family in FAMILIES and m.basis in BASES, m
        assert isinstance(m.unit, str) and m.unit
        assert m.__doc__ and len(m.__doc__.splitlines()) >= 3, f"{m.name}: document the math"
        threshold, frame_threshold = m.thresholds(QUICK)
        assert np.isfinite(threshold) and np.isfinite(frame_threshold)
    assert {m.needs for m in PERSON_REGISTRY} == {Needs.MOTION, Needs.BODY}
    assert {m.needs for m in PAIR_REGISTRY} == {Needs.PAIR}


def test_the_registry_is_one_list_of_metrics_each_in_its_own_module():
    # One plain list; every other registry view is read off it, in its order.
    assert isinstance(METRICS, list)
    assert PERSON_REGISTRY + PAIR_REGISTRY == tuple(METRICS)
    assert KEYPOINT_REGISTRY == tuple(m for m in METRICS if m.needs is Needs.MOTION)
    assert list(KINEMATIC_METRICS) == [m.name for m in KEYPOINT_REGISTRY]
    # A name is unique per input (the geom and keypoint versions share one).
    assert len({(m.name, m.needs) for m in METRICS}) == len(METRICS)
    modules = {name for _, name, _ in pkgutil.iter_modules(metrics_package.__path__)}
    for m in METRICS:
        # The metric's class lives in the module named after the metric, which
        # also holds the math its docstring cites.
        module = type(m).__module__
        assert module == f"simenv.plausibility.metrics.{m.name}", (m.name, module)
        doc = inspect.getdoc(type(m))
        assert doc and len(doc.splitlines()) >= 3, f"{m.name}: document the math"
        assert "value" in doc and "passes" in doc, f"{m.name}: say what is judged and when"
        assert isinstance(m.unit, str) and m.unit, m.name
        for config in (QUICK, DEFAULT_SCORE_CONFIG):
            threshold, frame_threshold = m.thresholds(config)
            assert np.isfinite(threshold) and threshold > 0, m.name
            assert np.isfinite(frame_threshold) and frame_threshold > 0, m.name
        if m.needs is Needs.MOTION:
            # A joint-level metric brings its kernel spec and its one-motion function.
            assert callable(m.spec) and callable(m.function), m.name
            assert importlib.import_module(module).__dict__.get(m.function.__name__) \
                is m.function, m.name
    # No module of the package without a registered metric.
    assert modules == {m.name for m in METRICS}


def test_the_scorer_runs_exactly_the_registry(walk_2s, monkeypatch):
    # Every metric of the list whose input is there is computed once; nothing else is.
    calls: Counter = Counter()
    for m in METRICS:
        compute = m.compute

        def counted(inputs, m=m, compute=compute):
            calls[id(m)] += 1
            return compute(inputs)

        monkeypatch.setattr(m, "compute", counted, raising=False)
    person = score(walk_2s.slice(0, 60), config=QUICK).people[0]
    chosen = [m for m in PERSON_REGISTRY if person.basis[m.name] == m.basis]
    assert [m.name for m in chosen] == list(person.metrics) == list(PERSON_METRICS)
    # Tracking too: with tracking off it reports itself not available.
    assert calls == Counter({id(m): 1 for m in chosen})


def test_joint_level_metrics_score_the_same_alone_as_in_the_scorers_one_pass(walk_2s):
    # The scorer hands a person the registry's joint-level metrics to run in one compiled
    # pass; a metric asked alone (benchmarks build inputs without them) gives the same.
    motion = walk_2s.slice(0, 90)
    together = metric_module.PersonInputs(motion, None, "physics=False", QUICK,
                                          keypoint_metrics=KEYPOINT_REGISTRY)
    alone = metric_module.PersonInputs(motion, None, "physics=False", QUICK)
    for m in KEYPOINT_REGISTRY:
        a, b = m.compute(together), m.compute(alone)
        assert a is together.keypoint_results[m.name]
        assert a.to_dict() == b.to_dict() and repr(a.value) == repr(b.value), m.name
        np.testing.assert_array_equal(a.timeline, b.timeline)


class _Reach:
    """Test metric: the highest keypoint above the floor.

    Per frame ``max_j z_j(t)`` in metres; value: its maximum; passes at <= 3 m.
    """

    name, family, unit, needs, basis = "reach", "kinematic", "m", Needs.MOTION, "keypoints"

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        return 3.0, 3.0

    def compute(self, inputs) -> MetricResult:
        top = inputs.motion.positions[..., 2].max(axis=1).astype(np.float64)
        return MetricResult.from_timeline(self.name, top, float(top.max()), self.unit, 3.0)


def test_a_metric_appended_to_the_list_is_scored_and_reported(walk_2s, monkeypatch):
    # Adding a metric is its module and one list entry: the scorer, the verdict and the
    # JSON record need nothing else.
    monkeypatch.setattr(report_module, "PERSON_REGISTRY", (*PERSON_REGISTRY, _Reach()))
    report = score(walk_2s.slice(0, 60), physics=False)
    record = report.to_records()[0]
    assert list(record["metrics"])[-1] == "reach"
    reach = record["metrics"]["reach"]
    height = float(walk_2s.positions[:60, :, 2].max())
    assert reach["value"] == height and reach["unit"] == "m" and reach["passed"]
    assert reach["basis"] == "keypoints"


def test_declared_units_and_thresholds_are_those_of_the_results(walk_2s):
    report = score(walk_2s.slice(0, 120), config=QUICK)
    person = report.people[0]
    chosen = {m.name: m for m in PERSON_REGISTRY if m.basis == person.basis[m.name]}
    assert list(chosen) == list(PERSON_METRICS)
    for name, result in person.metrics.items():
        m = chosen[name]
        assert result.unit == m.unit, name
        assert (result.threshold, result.frame_threshold) == m.thresholds(QUICK), name
    no_body = score(walk_2s.slice(0, 120), physics=False).people[0]
    for m in PERSON_REGISTRY:
        if m.needs is Needs.BODY and no_body.basis[m.name] == m.basis:
            result = no_body.metrics[m.name]
            assert result.reason == "physics=False"
            assert (result.unit, result.threshold) == (m.unit, m.thresholds(QUICK)[0])


def _count(monkeypatch, module, name, counts: Counter, key=None):
    """Wrap ``module.name`` so that each call adds one to ``counts[key or name]``."""
    original = getattr(module, name)

    def counted(*args, **kwargs):
        counts[key or name] += 1
        return original(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)


def test_a_person_is_retargeted_once_and_posed_once(walk_2s, monkeypatch):
    counts: Counter = Counter()
    _count(monkeypatch, report_module, "retarget", counts, "fit")
    # The joint-limit probe refits onto a body with widened ranges only.
    original_refit = joint_limits_module.retarget

    def refit(motion, humanoid=None, **kwargs):
        counts["refit" if humanoid is None else "probe"] += 1
        return original_refit(motion, humanoid=humanoid, **kwargs)

    monkeypatch.setattr(joint_limits_module, "retarget", refit)
    # Forward kinematics of the fitted trajectory, wherever the metrics ask for it.
    fk = geometry.body_poses
    frames = 120

    def poses(model, qpos):
        counts["poses" if len(qpos) == frames else "poses_of_some_frames"] += 1
        return fk(model, qpos)

    for module in (metric_module, ground_module, balance_module, contact_module, body_dynamics):
        monkeypatch.setattr(module, "body_poses", poses)
    person = score(walk_2s.slice(0, frames), config=QUICK).people[0]
    assert all(m.passed is not None for n, m in person.metrics.items() if n != "tracking")
    assert counts["fit"] == 1 and counts["refit"] == 0 and counts["probe"] == 1
    assert counts["poses"] == 1, counts


def test_two_people_are_retargeted_once_together_and_each_body_posed_once(monkeypatch):
    counts: Counter = Counter()
    _count(monkeypatch, report_module, "retarget", counts)
    _count(monkeypatch, metric_module, "pair_root_residual", counts)
    fk, posed = geometry.body_poses, Counter()

    def poses(model, qpos):
        posed[id(model)] += 1
        return fk(model, qpos)

    for module in (metric_module, ground_module, balance_module, contact_module, body_dynamics):
        monkeypatch.setattr(module, "body_poses", poses)
    pair = simenv.load(asset_path(HANDSHAKE_PAIR)).slice(0, 60)
    report = score(pair, config=ScoreConfig(tracking=False, joint_limits=False))
    assert counts == {"retarget": 1, "pair_root_residual": 1}
    # Each person's model, and the two-person scene's (the contact metric's key joints).
    assert len(posed) == 3 and set(posed.values()) == {1}, posed
    # Each person's root residual is the pair's partner-explained one.
    assert all("single_person_value" in p.metrics["root_residual"].details
               for p in report.people)


def test_root_residual_reads_the_tracking_run_instead_of_running_it_again(walk_2s,
                                                                          monkeypatch):
    counts: Counter = Counter()
    _count(monkeypatch, tracking_module, "tracking", counts)
    config = ScoreConfig(tracking_controller="pd", tracking_assisted_detail=False,
                         joint_limits=False)
    person = score(walk_2s.slice(0, 30), config=config).people[0]
    assert counts["tracking"] == 1
    tracked = person.metrics["tracking"]
    assert tracked.available and tracked.details["mpc"] == 0.0
    assert "measured_fraction" in person.metrics["root_residual"].details

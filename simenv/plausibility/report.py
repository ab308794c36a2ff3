"""The plausibility scorer: every metric of a motion, a verdict and a score.

:func:`score` takes a :class:`~simenv.core.motion.Motion`, an
:class:`~simenv.core.motion.Interaction` or a path, and returns a
:class:`PlausibilityReport`: per person the metrics under their stable names
(:data:`~simenv.plausibility.metric_registry.PERSON_METRICS`), for two
people also the pairwise ones
(:data:`~simenv.plausibility.metric_registry.PAIR_METRICS`). Each name is one
:class:`~simenv.plausibility.metric.Metric` of the registry
(:mod:`simenv.plausibility.metric_registry`), whose docstring gives its math.

Which computation stands behind each name
    =================== ============================== ==========================
    name                physics=True                   physics=False
    =================== ============================== ==========================
    bone_length         keypoints                      keypoints
    foot_skate          keypoints                      keypoints
    ground_penetration  body geoms (retargeted body)   keypoints
    floating            body geoms + true COM          keypoints + pelvis arc
    jitter              keypoints                      keypoints
    velocity            keypoints                      keypoints
    joint_limits        relaxed refit vs fitted body   not available
    self_penetration    body geoms (``mj_collision``)  not available
    root_residual       ``mj_inverse`` + floor NNLS,   not available
                        0 where the unassisted
                        tracker followed (two people:
                        + hand contacts)
    balance             COM vs support polygon         not available
    tracking            unassisted MPC in ``mj_step``  not available
    inter_penetration   geoms of the two bodies        not available
    contact             key joint pairs on the bodies  not available
    pair_root_residual  both ``mj_inverse`` + floor    not available
                        and hand-contact forces
    =================== ============================== ==========================

    In a two-person file each person's ``root_residual`` is the
    partner-explained residual of
    :func:`simenv.plausibility.pair_dynamics.pair_root_residual` (help the
    floor and the partner's hands together cannot give); the single-person
    value is in its details (``single_person_value``).

    ``basis`` in each metric's record says which one ran (``keypoints``,
    ``geoms``, ``dynamics``, ``simulation``). A metric that cannot run
    (physics off, too few frames, a skeleton without the keypoints it needs,
    a body that cannot be fitted) is reported with ``passed = None`` and the
    reason; the others are still computed.

Verdict
    A person is ``"plausible"`` when every available metric passes
    (``value <= threshold``), ``"implausible"`` otherwise. An interaction's
    verdict also needs every pairwise metric to pass.

Score (0-100)
    Per metric the normalised severity ``b = value / threshold`` maps to::

        q(b) = 100 (1 - b / 2)   for b <= 1   (100 at 0, 50 at the threshold)
        q(b) = 50 / b            for b > 1    (25 at twice the threshold)

    and the score is the minimum of ``q`` over the available metrics: the
    worst metric decides, so ``score >= 50`` exactly when the verdict is
    plausible, and the distance from 50 says how close the motion came to
    the limit of its worst metric. A diverged simulation (value ``inf``)
    scores 0.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from simenv.body.retarget import InteractionRetargetResult, RetargetResult, retarget
from simenv.core.errors import SimenvError
from simenv.core.motion import Interaction, Motion
from simenv.io.loader import load
from simenv.plausibility.metric import (
    DEFAULT_SCORE_CONFIG,
    Metric,
    PairInputs,
    PersonInputs,
    ScoreConfig,
    not_available,
)
from simenv.plausibility.metric_registry import (
    KEYPOINT_REGISTRY,
    PAIR_REGISTRY,
    PERSON_REGISTRY,
    alternatives,
)
from simenv.plausibility.profiles import (
    SourceKind,
    apply_profile,
    at_profile_rate,
    detect_source,
    for_clip,
    profile_for,
)
from simenv.plausibility.published import published_record
from simenv.plausibility.timeline import MetricResult

VERDICT_PLAUSIBLE = "plausible"
VERDICT_IMPLAUSIBLE = "implausible"


def metric_score(result: MetricResult) -> float | None:
    """``q(value / threshold)`` in [0, 100] (module docstring); None when the
    metric is not available."""
    if result.passed is None or not np.isfinite(result.threshold):
        return None
    value = result.value
    if np.isnan(value):
        return None
    b = value / result.threshold if result.threshold > 0 else (0.0 if value <= 0 else np.inf)
    b = max(float(b), 0.0)
    return 100.0 * (1.0 - b / 2.0) if b <= 1.0 else 50.0 / b


def _metric_record(result: MetricResult, basis: str) -> dict[str, Any]:
    rec = result.to_dict()
    del rec["name"], rec["violations"]
    value = result.value
    # JSON has no inf: a diverged simulation reports its value as the string "inf".
    if np.isinf(value):
        rec["value"] = "inf"
    rec["basis"] = basis
    rec["details"] = {k: (v if np.isfinite(v) else None) for k, v in rec["details"].items()}
    return rec


def violation_ranges(metrics: Mapping[str, MetricResult]) -> list[dict[str, Any]]:
    """Every failing metric's violating frame ranges, ``{metric, start_frame, end_frame,
    worst_value}``, sorted by start frame: what the JSON, the page and the video show."""
    out = []
    for name, m in metrics.items():
        if m.passed is None:
            continue
        runs = m.violations
        if not m.passed and not runs:
            # A clip-level failure with no single frame over the per-frame limit (e.g. a mean
            # over frames): the whole clip is the violating range.
            worst = float(np.nanmax(m.timeline)) if np.isfinite(m.timeline).any() else m.value
            runs = [(0, len(m.timeline) - 1, worst)]
        for s, e, w in runs:
            out.append({"metric": name, "start_frame": s, "end_frame": e,
                        "worst_value": w if np.isfinite(w) else "inf"})
    return sorted(out, key=lambda v: (v["start_frame"], v["metric"]))


def _verdict(metrics: Mapping[str, MetricResult]) -> str:
    failed = any(m.passed is False for m in metrics.values())
    return VERDICT_IMPLAUSIBLE if failed else VERDICT_PLAUSIBLE


@dataclass(frozen=True)
class PersonReport:
    """The metrics of one person.

    Attributes:
        person: index of the person in the scored clip (0, or 0/1 for two).
        name: the motion's name.
        frames: number of frames T; fps: frames per second.
        metrics: name -> :class:`MetricResult` for every name of
            :data:`~simenv.plausibility.metric_registry.PERSON_METRICS`; each
            timeline has T values.
        basis: name -> which computation produced it (module docstring).
        retargeted: the retargeting used by the body metrics, or None when
            physics was off or the body could not be fitted.
        published: the papers' metrics in their published definitions
            (:func:`simenv.plausibility.published.published_record`); they
            do not enter the verdict or the score.
    """

    person: int
    name: str
    frames: int
    fps: float
    metrics: dict[str, MetricResult]
    basis: dict[str, str]
    retargeted: RetargetResult | None = None
    published: dict[str, Any] = field(default_factory=dict)

    @property
    def verdict(self) -> str:
        return _verdict(self.metrics)

    @property
    def score(self) -> float:
        """Minimum metric score (module docstring); 100 when nothing is available."""
        scores = [s for s in map(metric_score, self.metrics.values()) if s is not None]
        return float(min(scores)) if scores else 100.0

    @property
    def violations(self) -> list[dict[str, Any]]:
        """``[{metric, start_frame, end_frame, worst_value}]`` of every failing metric,
        frames inclusive, sorted by start frame."""
        return violation_ranges(self.metrics)

    @property
    def failed(self) -> list[str]:
        return [n for n, m in self.metrics.items() if m.passed is False]


@dataclass(frozen=True)
class PlausibilityReport:
    """Result of :func:`score` on one clip.

    Attributes:
        source: the file scored, or the motion's name.
        people: one :class:`PersonReport` per person.
        interaction: pairwise metrics (name -> result) for two people, else None.
        physics: whether the body-level metrics were requested.
        seconds: wall time of the scoring.
        source_kind: what the clip is and which profile judged it
            (:func:`simenv.plausibility.profiles.detect_source`); None: not recorded.
    """

    source: str
    people: list[PersonReport]
    interaction: dict[str, MetricResult] | None
    physics: bool
    seconds: float
    interaction_basis: dict[str, str] = field(default_factory=dict)
    source_kind: SourceKind | None = None

    @property
    def profile(self) -> str | None:
        """Name of the profile whose thresholds judged the clip (``"mocap"``: the
        defaults; ``"kinect_v1"``, ``"kinect_v2"``: a depth-camera family's)."""
        return None if self.source_kind is None else self.source_kind.profile

    @property
    def verdict(self) -> str:
        """Plausible when every person and every pairwise metric passes."""
        verdicts = [p.verdict for p in self.people]
        if self.interaction is not None:
            verdicts.append(_verdict(self.interaction))
        return VERDICT_IMPLAUSIBLE if VERDICT_IMPLAUSIBLE in verdicts else VERDICT_PLAUSIBLE

    def to_records(self) -> list[dict[str, Any]]:
        """One JSON-ready dict per person (the ``simenv score --json`` contract):
        ``file``, ``person``, ``name``, ``frames``, ``fps``, ``verdict``, ``score``,
        ``physics``, ``metrics`` {name: {``value``, ``unit``, ``threshold``, ``passed``,
        ``basis``, ``details``, ``reason``}}, ``violations`` [{``metric``,
        ``start_frame``, ``end_frame``, ``worst_value``}], ``published`` (the
        papers' metrics: {name: {``value``, ``unit``}}, ``feet``, ``fps``,
        ``floor``, or {``reason``}); ``profile`` (the thresholds' profile: ``mocap``,
        ``kinect_v1``, ``kinect_v2``) and ``source_kind`` {``kind``, ``profile``, ``how``};
        for two people also ``interaction`` {``verdict``, ``metrics``, ``violations``}."""
        pair = None
        if self.interaction is not None:
            pair = {
                "verdict": _verdict(self.interaction),
                "metrics": {n: _metric_record(m, self.interaction_basis.get(n, "geoms"))
                            for n, m in self.interaction.items()},
                "violations": violation_ranges(self.interaction),
            }
        records = []
        for p in self.people:
            rec: dict[str, Any] = {
                "file": self.source, "person": p.person, "name": p.name,
                "frames": p.frames, "fps": p.fps, "verdict": p.verdict,
                "score": round(p.score, 2), "physics": self.physics,
                "metrics": {n: _metric_record(m, p.basis[n]) for n, m in p.metrics.items()},
                "violations": p.violations,
                "published": p.published,
            }
            if self.source_kind is not None:
                rec["profile"] = self.source_kind.profile
                rec["source_kind"] = self.source_kind.record()
            if pair is not None:
                rec["interaction"] = pair
            records.append(rec)
        return records


# -- scoring ---------------------------------------------------------------------


def _measure(registry: Sequence[Metric], inputs: PersonInputs | PairInputs
             ) -> tuple[dict[str, MetricResult], dict[str, str]]:
    """Every metric of ``registry`` on ``inputs``, keyed by report name in
    registry order, and the basis each ran on: per name the first metric
    whose input is there, or the first one reported not available with the
    reason the input is missing."""
    metrics: dict[str, MetricResult] = {}
    basis: dict[str, str] = {}
    for name, options in alternatives(registry).items():
        metric = next((m for m in options if inputs.has(m.needs)), None)
        if metric is None:
            metric = options[0]
            metrics[name] = not_available(metric, inputs.frames, inputs.config,
                                          inputs.missing or "physics off")
        else:
            metrics[name] = inputs.measure(metric)
        basis[name] = metric.basis
    return metrics, basis


#: Metrics that read the tracking run (``ScoreConfig.track_if_plausible`` decides without them).
READS_TRACKING: frozenset[str] = frozenset({"tracking", "root_residual"})


def _score_person(inputs: PersonInputs) -> PersonReport:
    config = inputs.config
    metrics: dict[str, MetricResult] | None = None
    if config.tracking and config.track_if_plausible and inputs.pair is None:
        untracked = PersonInputs(inputs.motion, inputs.fitted, inputs.missing,
                                 replace(config, tracking=False),
                                 keypoint_metrics=inputs.keypoint_metrics)
        metrics, basis = _measure(PERSON_REGISTRY, untracked)
        failing = [n for n, r in metrics.items() if r.passed is False and n not in READS_TRACKING]
        if failing:
            why = f"skipped: the person already fails {', '.join(failing)} (track_if_plausible)"
            metrics["tracking"] = replace(metrics["tracking"], reason=why)
        else:  # track it; what the untracked pass measured stands
            inputs.reuse(untracked, [m for m in PERSON_REGISTRY if m.name not in READS_TRACKING])
            metrics = None
    if metrics is None:
        metrics, basis = _measure(PERSON_REGISTRY, inputs)
    motion = inputs.motion
    return PersonReport(person=inputs.person, name=motion.name, frames=motion.num_frames,
                        fps=motion.fps, metrics=metrics, basis=basis,
                        retargeted=inputs.fitted, published=published_record(motion))


def _fit(clip: Motion | Interaction
         ) -> tuple[RetargetResult | InteractionRetargetResult | None, str | None]:
    """Retarget for the body metrics; a motion that cannot be fitted (no pelvis/hips,
    too few frames) gets the reason instead, and the joint-level metrics still run."""
    try:
        return retarget(clip), None
    except SimenvError as exc:
        return None, f"no body could be fitted: {exc}"


def _load_clip(path: str | Path) -> Motion | Interaction:
    loaded = load(path)
    if isinstance(loaded, list):
        if len(loaded) != 1:
            raise SimenvError(f"holds {len(loaded)} clips; score them one by one "
                              "(or with `simenv score`, which walks folders)", source=path)
        loaded = loaded[0]
    return loaded


def score(motion_or_path: Motion | Interaction | str | Path, physics: bool = True,
          config: ScoreConfig | None = None, source: str = "auto") -> PlausibilityReport:
    """Score a motion's physical plausibility: load, retarget once, every metric.

    The clip is retargeted once (both people into one scene for two); each
    person's metrics (:data:`~simenv.plausibility.metric_registry.PERSON_REGISTRY`)
    then share that fit and the intermediates computed from it once
    (:class:`~simenv.plausibility.metric.PersonInputs`: the keypoint pass, the
    body's forward kinematics, the tracking run), and the pairwise metrics
    share the pair's (:class:`~simenv.plausibility.metric.PairInputs`).

    Args:
        motion_or_path: a :class:`Motion` (positions (T, J, 3) metres, Z-up), an
            :class:`Interaction` of two, or a file / two-person folder that
            :func:`simenv.load` reads as one clip.
        physics: also retarget onto a fitted MuJoCo humanoid and run the
            body-level, inverse-dynamics and physics-tracking metrics.
        config: thresholds and switches (:class:`ScoreConfig`).
        source: the source kind (:data:`simenv.plausibility.profiles.DECLARABLE_SOURCES`):
            ``"auto"`` detects it from the skeleton; a depth-camera clip is judged by its
            sensor family's profile (:func:`simenv.plausibility.profiles.apply_profile`: the
            profile's fields replace those ``config`` leaves at their defaults).

    Returns:
        :class:`PlausibilityReport` (see the module docstring for verdict and score).

    Raises:
        SimenvError: the path cannot be read, or holds several clips, or ``source`` is not a
            known kind.
    """
    config = config or DEFAULT_SCORE_CONFIG
    declared = source  # ``source`` names the scored file below
    t0 = time.perf_counter()
    if isinstance(motion_or_path, (str, Path)):
        source = str(motion_or_path)
        clip = _load_clip(motion_or_path)
    elif isinstance(motion_or_path, (Motion, Interaction)):
        clip = motion_or_path
        source = str(clip.people[0].metadata.get("source", clip.name)
                     if isinstance(clip, Interaction)
                     else clip.metadata.get("source", clip.name))
    else:
        raise SimenvError(f"score expects a Motion, an Interaction or a path; got "
                          f"{type(motion_or_path).__name__}")
    kind = detect_source(clip, declared)
    profile = profile_for(kind, clip.fps)
    if profile is not None and profile.name != kind.profile:
        kind = replace(kind, profile=profile.name)  # the family's profile for this rate
    rigid = for_clip(profile, clip)
    if rigid is not profile:
        profile, kind = rigid, replace(kind, rigid_bones=True)
    config = apply_profile(config, profile)
    judged = at_profile_rate(clip, profile)
    if judged is not clip:
        clip, kind = judged, replace(kind, judged_fps=judged.fps)
    fitted, missing = _fit(clip) if physics else (None, "physics=False")
    if isinstance(clip, Interaction):
        scene = fitted if isinstance(fitted, InteractionRetargetResult) else None
        pair = PairInputs(clip, scene, missing, config)
        bodies = scene.people if scene is not None else (None, None)
        people = [_score_person(PersonInputs(m, r, missing, config, pair=pair, person=i,
                                             keypoint_metrics=KEYPOINT_REGISTRY))
                  for i, (m, r) in enumerate(zip(clip.people, bodies, strict=True))]
        interaction, pair_basis = _measure(PAIR_REGISTRY, pair)
    else:
        body = fitted if isinstance(fitted, RetargetResult) else None
        people = [_score_person(PersonInputs(clip, body, missing, config,
                                             keypoint_metrics=KEYPOINT_REGISTRY))]
        interaction, pair_basis = None, {}
    return PlausibilityReport(source=source, people=people, interaction=interaction,
                              physics=physics, seconds=time.perf_counter() - t0,
                              interaction_basis=pair_basis, source_kind=kind)

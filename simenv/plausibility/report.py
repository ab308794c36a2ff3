"""The plausibility scorer: every metric of a motion, a verdict and a score.

:func:`score` takes a :class:`~simenv.core.motion.Motion`, an
:class:`~simenv.core.motion.Interaction` or a path, and returns a
:class:`PlausibilityReport`: per person the metrics under their stable names
(:data:`PERSON_METRICS`), for two people also the pairwise ones
(:data:`PAIR_METRICS`).

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
from simenv.control.mpc import MPCConfig
from simenv.core.errors import SimenvError
from simenv.core.motion import Interaction, Motion
from simenv.plausibility.body import (
    DEFAULT_CONTACT_PAIRS,
    body_floating,
    body_penetration,
    contact,
    inter_penetration,
    joint_limits,
    self_penetration,
)
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.contact import floating, foot_skate, ground_penetration
from simenv.plausibility.dynamics import balance, root_residual
from simenv.plausibility.kinematic import bone_length, jitter, velocity
from simenv.plausibility.pair_dynamics import pair_root_residual
from simenv.plausibility.published import published_record
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult
from simenv.plausibility.tracking import tracking

#: Per-person metric names, in report order (stable: part of the JSON contract).
PERSON_METRICS: tuple[str, ...] = (
    "bone_length", "foot_skate", "ground_penetration", "floating", "jitter", "velocity",
    "joint_limits", "self_penetration", "root_residual", "balance", "tracking",
)
#: Pairwise metric names of a two-person motion.
PAIR_METRICS: tuple[str, ...] = ("inter_penetration", "contact", "pair_root_residual")

VERDICT_PLAUSIBLE = "plausible"
VERDICT_IMPLAUSIBLE = "implausible"


@dataclass(frozen=True)
class ScoreConfig:
    """What :func:`score` runs and against which limits.

    Attributes:
        thresholds: joint-level thresholds (:class:`Thresholds`).
        body: body-level thresholds (:class:`BodyThresholds`).
        tracking: run the PD physics-tracking simulation (up to
            ``body.tracking_max_seconds`` of simulated time per person).
        tracking_assist: judge tracking with the PD servos and the root
            assistance on (:func:`simenv.plausibility.tracking.track`,
            ``assist=True``; the unassisted ``tracking_controller`` run is then
            reported in the details as ``unassisted_*``). Default False: the
            verdict asks whether the body can perform the motion with its own
            muscles -- the unassisted model-predictive controller
            (:mod:`simenv.control`) tracks it, nothing acts on the root. A PD
            controller alone cannot balance real locomotion (on the bundled
            CMU walk 02_01 the unassisted PD body falls after 0.87 s, on 01_01
            jumps after 1.19 s, on the 49_06 cartwheel after 1.5 s).
        tracking_controller: ``"mpc"`` (default) or ``"pd"``: the controller
            of the unassisted run.
        tracking_assisted_detail: also run the assisted PD tracker (about 1x
            real time) and report it in the details (``assisted_success``,
            ``assisted_time_to_failure_s``, ``assisted_mpjpe_mm``,
            ``assisted_force_mean``) when the judged run is unassisted.
        mpc: settings of the MPC (:class:`simenv.control.MPCConfig`).
        joint_limits: run the joint-limit probe (one extra retargeting onto a
            body with widened ranges).
        contact_pairs: key joint pairs (person A keypoint, person B keypoint)
            of the pairwise ``contact`` metric, canonical names.
    """

    thresholds: Thresholds = DEFAULT_THRESHOLDS
    body: BodyThresholds = DEFAULT_BODY_THRESHOLDS
    tracking: bool = True
    tracking_assist: bool = False
    tracking_controller: str = "mpc"
    tracking_assisted_detail: bool = True
    mpc: MPCConfig = field(default_factory=MPCConfig)
    joint_limits: bool = True
    contact_pairs: tuple[tuple[str, str], ...] = DEFAULT_CONTACT_PAIRS


DEFAULT_SCORE_CONFIG = ScoreConfig()


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
            :data:`PERSON_METRICS`; each timeline has T values.
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
    """

    source: str
    people: list[PersonReport]
    interaction: dict[str, MetricResult] | None
    physics: bool
    seconds: float
    interaction_basis: dict[str, str] = field(default_factory=dict)

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
        ``floor``, or {``reason``}); for two people also
        ``interaction`` {``verdict``, ``metrics``, ``violations``}."""
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
            if pair is not None:
                rec["interaction"] = pair
            records.append(rec)
        return records


# -- scoring ---------------------------------------------------------------------


_BODY_UNITS = {
    "joint_limits": ("deg", "joint_limit_max_deg"),
    "self_penetration": ("mm", "self_penetration_max_mm"),
    "root_residual": ("body weight", "root_force_mean_max"),
    "balance": ("mm", "balance_margin_mm"),
    "tracking": ("m", "tracking_fail_m"),
}


def _unavailable_body(names: Sequence[str], frames: int, body: BodyThresholds,
                      reason: str) -> dict[str, MetricResult]:
    return {n: MetricResult.not_available(n, frames, _BODY_UNITS[n][0],
                                          getattr(body, _BODY_UNITS[n][1]), reason)
            for n in names}


def _score_person(motion: Motion, fitted: RetargetResult | None, physics_reason: str | None,
                  config: ScoreConfig, person: int,
                  root: MetricResult | None = None) -> PersonReport:
    th, body = config.thresholds, config.body
    T = motion.num_frames
    metrics: dict[str, MetricResult] = {}
    basis: dict[str, str] = {}
    for name, fn in (("bone_length", bone_length), ("foot_skate", foot_skate)):
        metrics[name], basis[name] = fn(motion, th), "keypoints"
    if fitted is not None:
        # The geom versions keep their module names; the report uses the stable ones.
        metrics["ground_penetration"] = replace(body_penetration(fitted, body),
                                                name="ground_penetration")
        metrics["floating"] = replace(body_floating(fitted, body), name="floating")
        basis["ground_penetration"] = basis["floating"] = "geoms"
    else:
        metrics["ground_penetration"] = ground_penetration(motion, th)
        metrics["floating"] = floating(motion, th)
        basis["ground_penetration"] = basis["floating"] = "keypoints"
    for name, fn in (("jitter", jitter), ("velocity", velocity)):
        metrics[name], basis[name] = fn(motion, th), "keypoints"

    body_names = ("joint_limits", "self_penetration", "root_residual", "balance", "tracking")
    if fitted is None:
        metrics.update(_unavailable_body(body_names, T, body, physics_reason or "physics off"))
    else:
        if config.joint_limits:
            metrics["joint_limits"] = joint_limits(motion, body, fitted=fitted)
        else:
            metrics.update(_unavailable_body(["joint_limits"], T, body,
                                             "joint-limit probe disabled in the config"))
        metrics["self_penetration"] = self_penetration(fitted, body)
        metrics["balance"] = balance(fitted, body)
        if config.tracking and T >= 2:
            metrics["tracking"] = _tracking(fitted, config)
        else:
            why = ("physics tracking disabled in the config" if not config.tracking
                   else f"needs at least 2 frames; the motion has {T}")
            metrics.update(_unavailable_body(["tracking"], T, body, why))
        # Measured by the unassisted controller where it ran (no help on the frames it
        # followed), inferred elsewhere; two people: the partner-explained residual.
        free = metrics["tracking"]
        tracked = free.timeline if free.available and not config.tracking_assist else None
        metrics["root_residual"] = root if root is not None else root_residual(
            fitted, body, tracked_error=tracked)
    basis.update({"joint_limits": "geoms", "self_penetration": "geoms",
                  "root_residual": "dynamics", "balance": "dynamics",
                  "tracking": "simulation"})
    ordered = {n: metrics[n] for n in PERSON_METRICS}
    return PersonReport(person=person, name=motion.name, frames=T, fps=motion.fps,
                        metrics=ordered, basis={n: basis[n] for n in PERSON_METRICS},
                        retargeted=fitted, published=published_record(motion))


def _tracking(fitted: RetargetResult, config: ScoreConfig) -> MetricResult:
    """Tracking judged as configured, with the other run's outcome in the details."""
    body = config.body

    def run(assist: bool) -> MetricResult:
        return tracking(fitted, body, assist=assist,
                        max_seconds=body.tracking_max_seconds,
                        controller="pd" if assist else config.tracking_controller,
                        mpc=config.mpc)

    judged = run(config.tracking_assist)
    if config.tracking_assist:
        free = run(False)
    else:
        free = judged
    details = {**judged.details,
               "unassisted_success": free.details["success"],
               "unassisted_time_to_failure_s": free.details["time_to_failure_s"],
               "unassisted_mpjpe_mm": free.details["mpjpe_mm"]}
    if not config.tracking_assist and config.tracking_assisted_detail:
        helped = run(True)
        details.update({"assisted_success": helped.details["success"],
                        "assisted_time_to_failure_s": helped.details["time_to_failure_s"],
                        "assisted_mpjpe_mm": helped.details["mpjpe_mm"],
                        "assisted_force_mean": helped.details["assist_force_mean"]})
    return replace(judged, details=details)


def _fit(clip: Motion | Interaction) -> tuple[Any, str | None]:
    """Retarget for the body metrics; a motion that cannot be fitted (no pelvis/hips,
    too few frames) gets the reason instead, and the joint-level metrics still run."""
    try:
        return retarget(clip), None
    except SimenvError as exc:
        return None, f"no body could be fitted: {exc}"


def _load_clip(path: str | Path) -> Motion | Interaction:
    from simenv.io.loader import load

    loaded = load(path)
    if isinstance(loaded, list):
        if len(loaded) != 1:
            raise SimenvError(f"holds {len(loaded)} clips; score them one by one "
                              "(or with `simenv score`, which walks folders)", source=path)
        loaded = loaded[0]
    return loaded


def score(motion_or_path: Motion | Interaction | str | Path, physics: bool = True,
          config: ScoreConfig | None = None) -> PlausibilityReport:
    """Score a motion's physical plausibility.

    Args:
        motion_or_path: a :class:`Motion` (positions (T, J, 3) metres, Z-up), an
            :class:`Interaction` of two, or a file / two-person folder that
            :func:`simenv.load` reads as one clip.
        physics: also retarget onto a fitted MuJoCo humanoid and run the
            body-level, inverse-dynamics and physics-tracking metrics.
        config: thresholds and switches (:class:`ScoreConfig`).

    Returns:
        :class:`PlausibilityReport` (see the module docstring for verdict and score).

    Raises:
        SimenvError: the path cannot be read, or holds several clips.
    """
    config = config or DEFAULT_SCORE_CONFIG
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
    fitted, reason = _fit(clip) if physics else (None, "physics=False")
    if isinstance(clip, Interaction):
        results = fitted.people if fitted is not None else (None, None)
        pair_rr = pair_root_residual(fitted, config.body) if fitted is not None else None
        people = [_score_person(m, r, reason, config, i,
                                root=None if pair_rr is None else pair_rr[1][i])
                  for i, (m, r) in enumerate(zip(clip.people, results, strict=True))]
        interaction, pair_basis = _pair_metrics(clip, fitted, reason, config,
                                                None if pair_rr is None else pair_rr[0])
    else:
        people = [_score_person(clip, fitted, reason, config, 0)]
        interaction, pair_basis = None, {}
    return PlausibilityReport(source=source, people=people, interaction=interaction,
                              physics=physics, seconds=time.perf_counter() - t0,
                              interaction_basis=pair_basis)


def _pair_metrics(clip: Interaction, fitted: InteractionRetargetResult | None,
                  reason: str | None, config: ScoreConfig,
                  pair_rr: MetricResult | None = None
                  ) -> tuple[dict[str, MetricResult], dict[str, str]]:
    body, T = config.body, clip.num_frames
    basis = {"inter_penetration": "geoms", "contact": "geoms", "pair_root_residual": "dynamics"}
    if fitted is None or pair_rr is None:
        why = reason or "physics off"
        return {
            "inter_penetration": MetricResult.not_available(
                "inter_penetration", T, "mm", body.inter_penetration_max_mm, why),
            "contact": MetricResult.not_available("contact", T, "mm", body.jpd_max_mm, why),
            "pair_root_residual": MetricResult.not_available(
                "pair_root_residual", T, "body weight", body.root_force_mean_max, why,
                frame_threshold=body.root_force_frame_max),
        }, basis
    return {
        "inter_penetration": inter_penetration(fitted, body),
        "contact": contact(fitted, pairs=config.contact_pairs, thresholds=body),
        "pair_root_residual": pair_rr,
    }, basis

"""What a plausibility metric is, what it reads, and under which settings.

Every metric of the scorer (:func:`simenv.plausibility.report.score`) is one
object of the :class:`Metric` protocol: its stable ``name`` in the report,
its ``family`` (the kind of computation), the input it ``needs``
(:class:`Needs`), the ``basis`` its record names, its ``unit``, its
``thresholds`` under a :class:`ScoreConfig`, and ``compute``. Each metric is one
module of :mod:`simenv.plausibility.metrics` (its class, whose docstring gives
the math, and the code of that math); the scorer runs the plain list of
:mod:`simenv.plausibility.metric_registry`, in report order. The bases here
hold what the metrics of one input share: :class:`KeypointMetric` (a
compiled joint-level kernel on the canonical keypoints), :class:`BodyMetric`
and :class:`PairMetric` (one limit of
:class:`~simenv.plausibility.body_thresholds.BodyThresholds` on one body or a
pair).

``compute`` reads shared inputs (:class:`PersonInputs`, :class:`PairInputs`)
that hold each intermediate the metrics have in common and compute it on
first use, once: the joint-level metrics' one compiled pass over the
keypoints, the body's forward kinematics (geom, site and centre-of-mass
poses of every frame), the tracking simulation, and for two people the
partner-explained inverse dynamics. The retargeting itself is done before,
once per clip, by the caller that builds the inputs.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from enum import Enum
from functools import cached_property
from typing import Protocol, TypeVar, runtime_checkable

from simenv.body.geometry import BodyPoses, body_poses
from simenv.body.retarget import InteractionRetargetResult, RetargetResult
from simenv.control.mpc import MPCConfig
from simenv.core.motion import Interaction, Motion
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.clips import ClipBatch, MetricSpec, cached_plan, run, score_clip
from simenv.plausibility.pair_dynamics import pair_root_residual
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult

#: Planner seeds the scorer's tracking may try per run or segment (``MPCConfig.attempts``).
SCORER_ATTEMPTS = 3

#: Key joint pairs (person A keypoint, person B keypoint) of an interaction:
#: the handshake pair and the interaction-augmentation seed's A right hand -
#: B spine, plus its mirror.
DEFAULT_CONTACT_PAIRS: tuple[tuple[str, str], ...] = (
    ("right_hand", "right_hand"),
    ("right_hand", "spine"),
    ("spine", "right_hand"),
)


@dataclass(frozen=True)
class ScoreConfig:
    """What :func:`~simenv.plausibility.report.score` runs and against which limits.

    Attributes:
        thresholds: joint-level thresholds (:class:`Thresholds`).
        body: body-level thresholds (:class:`BodyThresholds`).
        tracking: run the physics-tracking simulation (up to
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
        mpc: settings of the MPC (:class:`simenv.control.MPCConfig`); the scorer's
            default tries a failed run (each failed segment) with up to
            :data:`SCORER_ATTEMPTS` planner seeds, the further ones planning over the longer
            ``retry_horizon_s``, before the motion is blamed: a tracked run shows the body
            can do it, a failed one only that one search found no way (on real CMU clips
            single seeds disagree: docs/plausibility.md).
        joint_limits: run the joint-limit probe (one extra retargeting onto a
            body with widened ranges).
        contact_pairs: key joint pairs (person A keypoint, person B keypoint)
            of the pairwise ``contact`` metric, canonical names.
        progress: show a progress bar on stderr for the physics tracking (frames
            tracked of the total, time left), the step that takes minutes.
        track_if_plausible: run the physics tracking (nearly all of the scorer's time)
            only for a person whose other metrics all pass; one that already fails one is
            implausible whatever the tracking finds, so its ``tracking`` is reported not
            available ("skipped: ...") and its ``root_residual`` is the inferred one alone
            (the tracking run would refine it). For scoring many clips, e.g. a generated
            test set. Two-person clips are always tracked.
    """

    thresholds: Thresholds = DEFAULT_THRESHOLDS
    body: BodyThresholds = DEFAULT_BODY_THRESHOLDS
    tracking: bool = True
    tracking_assist: bool = False
    tracking_controller: str = "mpc"
    tracking_assisted_detail: bool = True
    mpc: MPCConfig = field(default_factory=lambda: MPCConfig(attempts=SCORER_ATTEMPTS))
    joint_limits: bool = True
    contact_pairs: tuple[tuple[str, str], ...] = DEFAULT_CONTACT_PAIRS
    progress: bool = False
    track_if_plausible: bool = False


DEFAULT_SCORE_CONFIG = ScoreConfig()


class Needs(Enum):
    """The input a metric reads."""

    #: The motion's joint positions (canonical keypoints, metres).
    MOTION = "motion"
    #: One person's body retargeted onto a fitted MuJoCo humanoid.
    BODY = "body"
    #: Two people's bodies retargeted into one scene.
    PAIR = "pair"


class _Memo:
    """Results of the metrics computed on one set of inputs, each once."""

    def __init__(self) -> None:
        self._results: dict[int, MetricResult] = {}

    def measure(self, metric: Metric) -> MetricResult:
        """``metric.compute(self)``, computed on the first call only: a metric
        may read another's result (the root residual reads the tracking run)."""
        key = id(metric)
        if key not in self._results:
            self._results[key] = metric.compute(self)
        return self._results[key]

    def reuse(self, other: _Memo, metrics: Iterable[Metric]) -> None:
        """Take ``other``'s results of ``metrics``, computed on the same inputs under a
        configuration that does not change them (only the tracking switch differs)."""
        for metric in metrics:
            if id(metric) in other._results:
                self._results[id(metric)] = other._results[id(metric)]


class PairInputs(_Memo):
    """What the pairwise metrics of a two-person clip read.

    Attributes:
        clip: the two people.
        fitted: both retargeted into one scene, or None when physics is off
            or no body could be fitted.
        missing: why ``fitted`` is None (None when it is not).
        config: the scorer's settings.
    """

    def __init__(self, clip: Interaction, fitted: InteractionRetargetResult | None,
                 missing: str | None, config: ScoreConfig) -> None:
        super().__init__()
        self.clip, self.fitted, self.missing, self.config = clip, fitted, missing, config

    @property
    def frames(self) -> int:
        return self.clip.num_frames

    def has(self, needs: Needs) -> bool:
        """Whether the input ``needs`` names is there."""
        return needs is Needs.PAIR and self.fitted is not None

    @cached_property
    def poses(self) -> tuple[BodyPoses, BodyPoses]:
        """Forward kinematics of every frame of each fitted body
        (:func:`simenv.body.geometry.body_poses`), each person's model apart."""
        assert self.fitted is not None
        a, b = self.fitted.people
        return (body_poses(a.humanoid.model, a.qpos), body_poses(b.humanoid.model, b.qpos))

    @cached_property
    def partner_explained(self) -> tuple[MetricResult, tuple[MetricResult, MetricResult]]:
        """The pairwise ``pair_root_residual`` and each person's partner-explained
        ``root_residual`` (:func:`simenv.plausibility.pair_dynamics.pair_root_residual`),
        solved once for both."""
        assert self.fitted is not None
        return pair_root_residual(self.fitted, self.config.body, poses=self.poses)


class PersonInputs(_Memo):
    """What the metrics of one person read.

    Attributes:
        motion: the person's motion (positions (T, J, 3) metres, Z-up).
        fitted: the motion retargeted onto its fitted humanoid, or None when
            physics is off or no body could be fitted.
        missing: why ``fitted`` is None (None when it is not).
        config: the scorer's settings.
        pair: the pair's inputs when the person is one of two, else None.
        person: index of the person in the clip (0, or 0/1 for two).
        keypoint_metrics: the joint-level metrics computed together in one compiled
            pass when the first of them is asked for (the scorer's: the registry's);
            any other :class:`KeypointMetric` runs alone, with the same result.
    """

    def __init__(self, motion: Motion, fitted: RetargetResult | None, missing: str | None,
                 config: ScoreConfig, pair: PairInputs | None = None, person: int = 0,
                 keypoint_metrics: Sequence[KeypointMetric] = ()) -> None:
        super().__init__()
        self.motion, self.fitted, self.missing, self.config = motion, fitted, missing, config
        self.pair, self.person = pair, person
        self.keypoint_metrics = tuple(keypoint_metrics)

    @cached_property
    def keypoint_results(self) -> dict[str, MetricResult]:
        """The results of ``keypoint_metrics`` on the motion, by name, from one compiled
        pass over its keypoints (:func:`simenv.plausibility.clips.run`)."""
        batch = ClipBatch([self.motion])
        plan = cached_plan(batch, self.config.thresholds,
                           tuple(m.spec for m in self.keypoint_metrics))
        return dict(zip((m.name for m in self.keypoint_metrics), run(batch, plan).clip(0),
                        strict=True))

    @property
    def frames(self) -> int:
        return self.motion.num_frames

    def has(self, needs: Needs) -> bool:
        """Whether the input ``needs`` names is there."""
        return needs is Needs.MOTION or (needs is Needs.BODY and self.fitted is not None)

    @cached_property
    def poses(self) -> BodyPoses:
        """Forward kinematics of every frame of the fitted body
        (:func:`simenv.body.geometry.body_poses`; the pair's, one of two)."""
        assert self.fitted is not None
        if self.pair is not None:
            return self.pair.poses[self.person]
        return body_poses(self.fitted.humanoid.model, self.fitted.qpos)


Inputs = TypeVar("Inputs", PersonInputs, PairInputs, contravariant=True)


@runtime_checkable
class Metric(Protocol[Inputs]):
    """One plausibility metric.

    Attributes:
        name: stable name in the report (part of the JSON contract).
        family: the kind of computation: ``kinematic`` (keypoint motion),
            ``contact`` (keypoints against the floor), ``body`` (the fitted
            body's geoms and joints), ``dynamics`` (inverse dynamics) or
            ``tracking`` (forward simulation).
        needs: the input it reads (:class:`Needs`).
        basis: what its record says it ran on: ``keypoints``, ``geoms``,
            ``dynamics`` or ``simulation``.
        unit: unit of its value and threshold.
    """

    name: str
    family: str
    needs: Needs
    basis: str
    unit: str

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        """(limit on the value, per-frame limit on the timeline) under ``config``."""
        ...

    def compute(self, inputs: Inputs) -> MetricResult:
        """The metric on ``inputs``, whose ``needs`` input is there."""
        ...


def not_available(metric: Metric, frames: int, config: ScoreConfig,
                  reason: str) -> MetricResult:
    """``metric``'s result when it cannot run: NaN value and timeline of
    ``frames`` frames, its thresholds under ``config``, and ``reason``."""
    threshold, frame_threshold = metric.thresholds(config)
    return MetricResult.not_available(metric.name, frames, metric.unit, threshold, reason,
                                      frame_threshold=frame_threshold)


# -- bases of the metrics of one input -----------------------------------------------------


class KeypointMetric:
    """A joint-level metric: one compiled kernel
    (:mod:`simenv.plausibility.kernels`) on the motion's canonical keypoints.

    Attributes:
        spec: ``spec(batch, thresholds) -> MetricSpec``: the metric as
            :func:`simenv.plausibility.clips.run` runs it on a batch of clips
            (its kernel slot, arguments, details). Every metric with a ``spec``
            joins the one compiled pass of
            :func:`simenv.plausibility.keypoints.kinematic_metrics_batch`.
        function: ``function(motion, thresholds) -> MetricResult``, the metric
            on one motion.
    """

    name: str
    family: str
    unit: str
    needs = Needs.MOTION
    basis = "keypoints"
    spec: Callable[[ClipBatch, Thresholds], MetricSpec]
    function: Callable[[Motion, Thresholds], MetricResult]

    def compute(self, inputs: PersonInputs) -> MetricResult:
        # A clip scores the same alone or with the other kernels (clips.py).
        if self in inputs.keypoint_metrics:
            return inputs.keypoint_results[self.name]
        return score_clip(inputs.motion, self.spec, inputs.config.thresholds)


class BodyMetric:
    """A metric of one retargeted body whose ``limit`` (a
    :class:`~simenv.plausibility.body_thresholds.BodyThresholds` field) bounds
    both its value and its timeline."""

    name: str
    family = "body"
    needs = Needs.BODY
    basis = "geoms"
    unit = "mm"
    limit: Callable[[BodyThresholds], float]

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        value = self.limit(config.body)
        return value, value


class PairMetric(BodyMetric):
    """A metric of the two bodies of a pair with one ``limit``."""

    needs = Needs.PAIR


def fitted_body(inputs: PersonInputs) -> RetargetResult:
    """The fitted body of inputs whose metric needs it (the scorer checks)."""
    assert inputs.fitted is not None
    return inputs.fitted


def fitted_pair(inputs: PairInputs) -> InteractionRetargetResult:
    """The fitted pair of inputs whose metric needs it (the scorer checks)."""
    assert inputs.fitted is not None
    return inputs.fitted


def root_force_limits(config: ScoreConfig) -> tuple[float, float]:
    """Mean and per-frame limits of a root residual force, body weights."""
    return config.body.root_force_mean_max, config.body.root_force_frame_max

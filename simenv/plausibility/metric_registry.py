"""Every metric of the plausibility report, once, in report order.

:data:`PERSON_REGISTRY` lists the per-person metrics (kinematic, contact,
body, dynamics and tracking families), :data:`PAIR_REGISTRY` the pairwise
ones of a two-person clip; each entry is a :class:`~simenv.plausibility.metric.Metric`
whose docstring gives its math and units, and whose function in the family
module (named in the docstring) holds the computation. A report name served
on two inputs has two entries, the preferred first: ``ground_penetration``
and ``floating`` run on the body's geoms when a body was fitted, on the
keypoints otherwise (:func:`alternatives`). :data:`PERSON_METRICS` and
:data:`PAIR_METRICS` are the report names in order (the JSON contract).

Units: metres and seconds in, millimetres, degrees, body weights or
fractions out as each metric says; floor plane z = 0, Z up.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from operator import attrgetter

from simenv.body.retarget import InteractionRetargetResult, RetargetResult
from simenv.plausibility.body import (
    body_floating,
    body_penetration,
    contact,
    inter_penetration,
    joint_limits,
    self_penetration,
)
from simenv.plausibility.body_thresholds import BodyThresholds
from simenv.plausibility.dynamics import balance, root_residual
from simenv.plausibility.metric import (
    Metric,
    Needs,
    PairInputs,
    PersonInputs,
    ScoreConfig,
    not_available,
)
from simenv.plausibility.timeline import MetricResult
from simenv.plausibility.tracking import tracking

# -- families: what the metrics of one input and one kind share ---------------------------


class _Keypoints:
    """A joint-level metric: its result comes from the one compiled pass that
    computes all of them on the motion's canonical keypoints
    (:attr:`PersonInputs.keypoint_metrics`)."""

    name: str
    family: str
    unit: str
    needs = Needs.MOTION
    basis = "keypoints"

    def compute(self, inputs: PersonInputs) -> MetricResult:
        return inputs.keypoint_metrics[self.name]


class _OnBody:
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


class _GroundOnBody(_OnBody):
    """The geom version of a keypoint ground metric: its family function
    (``measure``) names the result after itself; the report uses the stable
    name the keypoint version shares."""

    measure: Callable[..., MetricResult]

    def compute(self, inputs: PersonInputs) -> MetricResult:
        result = self.measure(_fitted(inputs), inputs.config.body, poses=inputs.poses)
        return replace(result, name=self.name)


class _OnPair(_OnBody):
    """A metric of the two bodies of a pair with one ``limit``."""

    needs = Needs.PAIR


def _fitted(inputs: PersonInputs) -> RetargetResult:
    """The fitted body of inputs whose metric needs it (the scorer checks)."""
    assert inputs.fitted is not None
    return inputs.fitted


def _scene(inputs: PairInputs) -> InteractionRetargetResult:
    """The fitted pair of inputs whose metric needs it (the scorer checks)."""
    assert inputs.fitted is not None
    return inputs.fitted


def _root_force(config: ScoreConfig) -> tuple[float, float]:
    """Mean and per-frame limits of a root residual force, body weights."""
    return config.body.root_force_mean_max, config.body.root_force_frame_max


# -- joint level -----------------------------------------------------------------------


class BoneLength(_Keypoints):
    """Bone-length consistency (:func:`simenv.plausibility.kinematic.bone_length`).

    Per frame ``max_b |L_b(t) / median_t L_b - 1| / tol_b`` over the source
    skeleton's own parent-child bones (fraction of the bone's tolerance: 5 %,
    15 % for the bone ending at the head); value: its 95th percentile over
    frames; passes at <= 1.
    """

    name, family, unit = "bone_length", "kinematic", "fraction of tolerance"

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        return 1.0, 1.0


class FootSkate(_Keypoints):
    """Foot skating (:func:`simenv.plausibility.contact.foot_skate`).

    A low foot (within its contact height of the floor) sliding faster than
    ``skate_speed_mps`` for at least ``skate_min_duration_s``, unless the
    other, lower foot carries the weight; timeline: the skating foot's speed
    in mm per frame at ``skate_reference_fps``; value: fraction of frame pairs
    with a skating foot; passes at <= ``skate_ratio_max``.
    """

    name, family, unit = "foot_skate", "contact", "fraction"

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        th = config.thresholds
        return th.skate_ratio_max, th.skate_speed_mps * 1000.0 / th.skate_reference_fps


class KeypointPenetration(_Keypoints):
    """Lowest keypoint below the floor
    (:func:`simenv.plausibility.contact.ground_penetration`).

    Per frame ``max(0, -min_j z_j(t))`` in mm; value: the maximum; passes at
    <= ``penetration_max_mm``.
    """

    name, family, unit = "ground_penetration", "contact", "mm"

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        return (config.thresholds.penetration_max_mm,) * 2


class KeypointFloating(_Keypoints):
    """Airborne keypoints without a free-fall arc (:func:`simenv.plausibility.contact.floating`).

    A frame is airborne when the lowest keypoint (hands ``float_hand_reach_m``
    lower) is above ``float_height_m``; an airborne run whose trunk-keypoint
    centre fits ``z0 + v0 t - g t^2 / 2`` within ``ballistic_tolerance_m`` RMS
    is a jump. Timeline: height (mm) on floating frames, 0 elsewhere; value:
    its maximum; passes at <= ``float_height_m`` (in mm).
    """

    name, family, unit = "floating", "contact", "mm"

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        return (config.thresholds.float_height_m * 1000.0,) * 2


class Jitter(_Keypoints):
    """High-frequency jitter (:func:`simenv.plausibility.kinematic.jitter`).

    ProtoMotions' normalized jerk ``T^5 sum |j|^2 dt / (max(L, eps)^2 + eps)``
    per 0.4 s window and keypoint at <= 30 fps; timeline: the median
    keypoint's NJ of the window centred on each frame; value: percentage of
    windows whose median keypoint exceeds ``normalized_jerk_max``; passes at
    <= ``high_jerk_percent_max``.
    """

    name, family, unit = "jitter", "kinematic", "%"

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        return config.thresholds.high_jerk_percent_max, config.thresholds.normalized_jerk_max


class Velocity(_Keypoints):
    """Speeds beyond human limits and teleports (:func:`simenv.plausibility.kinematic.velocity`).

    Per frame ``max_j max(|p_j(t) - p_j(t-1)| fps / S_j, |p_j(t+1) - 2 p_j(t)
    + p_j(t-1)| / E)`` (fraction of the keypoint group's speed limit ``S_j``
    and of the teleport distance ``E``); value: its maximum; passes at <= 1.
    """

    name, family, unit = "velocity", "kinematic", "fraction of limit"

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        return 1.0, 1.0


# -- body: the retargeted humanoid's geoms ---------------------------------------------


class GeomPenetration(_GroundOnBody):
    """Lowest body geom point below the floor (:func:`simenv.plausibility.body.body_penetration`).

    Per frame ``max(0, -min_g z_low,g(t))`` in mm over every body geom (exact
    lowest points of capsules and boxes); value: the maximum; passes at <=
    ``geom_penetration_max_mm``.
    """

    name, limit = "ground_penetration", attrgetter("geom_penetration_max_mm")
    measure = staticmethod(body_penetration)


class GeomFloating(_GroundOnBody):
    """Airborne geoms without a free-fall centre of mass
    (:func:`simenv.plausibility.body.body_floating`).

    A frame is airborne when every body geom is more than
    ``geom_float_clearance_m`` above the floor; an airborne run whose true
    centre of mass fits a free-fall parabola within ``ballistic_tolerance_m``
    RMS is a jump. Timeline: lowest geom's clearance (mm) on floating frames,
    0 elsewhere; value: its maximum; passes when no frame floats.
    """

    name = "floating"
    measure = staticmethod(body_floating)

    def limit(self, body: BodyThresholds) -> float:
        return body.geom_float_clearance_m * 1000.0


class JointLimits(_OnBody):
    """Hinge angles beyond their anatomical ranges that the motion demands
    (:func:`simenv.plausibility.body.joint_limits`).

    The motion is refitted onto a body with ranges widened by
    ``joint_limit_probe_deg``; per frame ``max_h excess_h(t)`` degrees over the
    hinges whose limits cost more than ``joint_limit_cost_m`` of keypoint
    accuracy; value: the largest excess held for ``joint_limit_min_duration_s``;
    passes at <= ``joint_limit_max_deg``. Off when ``ScoreConfig.joint_limits``
    is False.
    """

    name, unit, limit = "joint_limits", "deg", attrgetter("joint_limit_max_deg")

    def compute(self, inputs: PersonInputs) -> MetricResult:
        if not inputs.config.joint_limits:
            return not_available(self, inputs.frames, inputs.config,
                                 "joint-limit probe disabled in the config")
        return joint_limits(inputs.motion, inputs.config.body, fitted=inputs.fitted)


class SelfPenetration(_OnBody):
    """Penetration between non-neighbouring geoms of one body
    (:func:`simenv.plausibility.body.self_penetration`).

    Per frame the deepest ``mj_collision`` penetration (mm) between geoms of
    bodies more than two joints apart; value: the maximum; passes at <=
    ``self_penetration_max_mm``.
    """

    name, limit = "self_penetration", attrgetter("self_penetration_max_mm")

    def compute(self, inputs: PersonInputs) -> MetricResult:
        return self_penetration(_fitted(inputs), inputs.config.body)


# -- dynamics and simulation -------------------------------------------------------------


class RootResidual(_OnBody):
    """Help from nowhere: the root force no floor contact explains
    (:func:`simenv.plausibility.dynamics.root_residual`).

    ``mj_inverse`` of the retargeted trajectory gives the root wrench; the best
    friction-cone floor forces (NNLS) explain what they can. Per frame the
    residual force in body weights ``m g``, 0 on the frames the unassisted
    tracker followed (:class:`Tracking`); value: its mean; passes at <=
    ``root_force_mean_max``; per-frame limit ``root_force_frame_max``. Of two
    people, the partner-explained residual (hand contacts may help,
    :func:`simenv.plausibility.pair_dynamics.pair_root_residual`).
    """

    name, family, basis, unit = "root_residual", "dynamics", "dynamics", "body weight"
    thresholds = staticmethod(_root_force)

    def compute(self, inputs: PersonInputs) -> MetricResult:
        if inputs.pair is not None:
            return inputs.pair.partner_explained[1][inputs.person]
        # Measured by the unassisted controller where it ran (no help on the frames it
        # followed), inferred elsewhere.
        free = inputs.measure(TRACKING)
        tracked = free.timeline if free.available and not inputs.config.tracking_assist \
            else None
        return root_residual(_fitted(inputs), inputs.config.body, tracked_error=tracked,
                             poses=inputs.poses)


class Balance(_OnBody):
    """Centre of mass over the support polygon when quasi-static
    (:func:`simenv.plausibility.dynamics.balance`).

    On frames whose 6 Hz filtered centre of mass moves slower than
    ``balance_speed_mps`` and accelerates less than ``balance_accel_mps2``,
    the distance (mm) of its ground projection outside the convex hull of the
    geom points near the floor (NaN elsewhere); value: the maximum; passes
    at <= ``balance_margin_mm``.
    """

    name, family, basis = "balance", "dynamics", "dynamics"
    limit = attrgetter("balance_margin_mm")

    def compute(self, inputs: PersonInputs) -> MetricResult:
        return balance(_fitted(inputs), inputs.config.body, poses=inputs.poses)


class Tracking(_OnBody):
    """Can a simulated body perform the motion (:func:`simenv.plausibility.tracking.tracking`)?

    The unassisted controller (``ScoreConfig.tracking_controller``, MPC by
    default; the assisted PD servos with ``tracking_assist``) follows the
    retargeted trajectory in ``mj_step``; per frame the mean keypoint distance
    ``e_t`` (m) between the simulated and the reference body, NaN after a
    failure; value: the largest ``e_t``; passes at <= ``tracking_fail_m``
    (PHC). The other runs' outcomes go in the details (``unassisted_*``,
    ``assisted_*``). Off when ``ScoreConfig.tracking`` is False; needs 2 frames.
    """

    name, family, basis, unit = "tracking", "tracking", "simulation", "m"
    limit = attrgetter("tracking_fail_m")

    def compute(self, inputs: PersonInputs) -> MetricResult:
        config, T = inputs.config, inputs.frames
        if not config.tracking or T < 2:
            why = ("physics tracking disabled in the config" if not config.tracking
                   else f"needs at least 2 frames; the motion has {T}")
            return not_available(self, T, config, why)
        fitted, body = _fitted(inputs), config.body

        def run(assist: bool) -> MetricResult:
            return tracking(fitted, body, assist=assist, max_seconds=body.tracking_max_seconds,
                            controller="pd" if assist else config.tracking_controller,
                            mpc=config.mpc, progress=config.progress)

        judged = run(config.tracking_assist)
        free = run(False) if config.tracking_assist else judged
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


# -- pairwise ---------------------------------------------------------------------------


class InterPenetration(_OnPair):
    """Penetration between the geoms of two people
    (:func:`simenv.plausibility.body.inter_penetration`).

    Per frame the deepest ``mj_collision`` penetration (mm) between geoms of
    different people; value: the maximum; passes at <= ``inter_penetration_max_mm``.
    """

    name, limit = "inter_penetration", attrgetter("inter_penetration_max_mm")

    def compute(self, inputs: PairInputs) -> MetricResult:
        return inter_penetration(_scene(inputs), inputs.config.body)


class Contact(_OnPair):
    """Key joint-pair distance error (JPD) (:func:`simenv.plausibility.body.contact`).

    For each pair of ``ScoreConfig.contact_pairs`` the distance ``d_p(t)`` on
    the bodies against the fitted keypoints' ``r_p(t)``; per frame
    ``mean_p |d_p(t) - r_p(t)|`` in mm; value: its mean; passes at <=
    ``jpd_max_mm``.
    """

    name, limit = "contact", attrgetter("jpd_max_mm")

    def compute(self, inputs: PairInputs) -> MetricResult:
        return contact(_scene(inputs), pairs=inputs.config.contact_pairs,
                       thresholds=inputs.config.body)


class PairRootResidual(_OnPair):
    """Root help the floor and the partner's hands together cannot give
    (:func:`simenv.plausibility.pair_dynamics.pair_root_residual`).

    Per frame the larger of the two people's partner-explained residual
    forces (body weights; hand-contact forces bounded by
    ``grip_force_max_bw``); value: the larger of their means; passes at <=
    ``root_force_mean_max``; per-frame limit ``root_force_frame_max``.
    """

    name, family, basis, unit = "pair_root_residual", "dynamics", "dynamics", "body weight"
    thresholds = staticmethod(_root_force)

    def compute(self, inputs: PairInputs) -> MetricResult:
        return inputs.partner_explained[0]


TRACKING = Tracking()

#: Per-person metrics in report order; of two entries with one name the first
#: whose input is there runs.
PERSON_REGISTRY: tuple[Metric[PersonInputs], ...] = (
    BoneLength(), FootSkate(), GeomPenetration(), KeypointPenetration(), GeomFloating(),
    KeypointFloating(), Jitter(), Velocity(), JointLimits(), SelfPenetration(),
    RootResidual(), Balance(), TRACKING,
)
#: Pairwise metrics of a two-person clip, in report order.
PAIR_REGISTRY: tuple[Metric[PairInputs], ...] = (
    InterPenetration(), Contact(), PairRootResidual(),
)


def alternatives(registry: Sequence[Metric]) -> dict[str, tuple[Metric, ...]]:
    """Report name -> its metrics in ``registry`` order (the preferred first),
    names in order of first appearance."""
    out: dict[str, tuple[Metric, ...]] = {}
    for m in registry:
        out[m.name] = (*out.get(m.name, ()), m)
    return out


#: Per-person metric names, in report order (stable: part of the JSON contract).
PERSON_METRICS: tuple[str, ...] = tuple(alternatives(PERSON_REGISTRY))
#: Pairwise metric names of a two-person motion.
PAIR_METRICS: tuple[str, ...] = tuple(alternatives(PAIR_REGISTRY))

"""Floating: airborne frames that are not a jump (no free-fall arc).

Two versions under one report name, the preferred first: on the retargeted
body's geoms and its true centre of mass when a body was fitted
(:class:`GeomFloating`, :func:`body_floating`), on the keypoints otherwise
(:class:`KeypointFloating`, :func:`floating`, kernel
:func:`simenv.plausibility.kernels.floating`). Both test each airborne run for
a ballistic flight (:func:`ballistic_residual`) and assume the floor (z = 0)
is the only support. Thresholds: ``float_*``, ``ballistic_tolerance_m`` and
``gravity_mps2`` of :class:`~simenv.plausibility.thresholds.Thresholds`,
``geom_float_clearance_m`` and ``ballistic_tolerance_m`` of
:class:`~simenv.plausibility.body_thresholds.BodyThresholds`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from simenv.body.geometry import BodyPoses
from simenv.body.retarget import RetargetResult
from simenv.core.motion import Motion
from simenv.plausibility import kernels
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.clips import ClipBatch, MetricSpec, score_clip
from simenv.plausibility.metric import (
    BodyMetric,
    KeypointMetric,
    PersonInputs,
    ScoreConfig,
    fitted_body,
)
from simenv.plausibility.metrics.ground_penetration import lowest_geom_z
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult

#: Keypoints whose mean is the centre-of-mass proxy of the floating test.
COM_KEYPOINTS: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine", "chest", "neck",
    "left_shoulder", "right_shoulder",
)


#: Keypoints that may rest on the palm and fingers below them.
HAND_KEYPOINTS: tuple[str, ...] = ("left_wrist", "right_wrist", "left_hand", "right_hand")
#: A skeleton's toes; without them its ankles count ``float_ankle_sole_m`` lower.
TOE_KEYPOINTS: tuple[str, ...] = ("left_toe", "right_toe")
ANKLE_KEYPOINTS: tuple[str, ...] = ("left_ankle", "right_ankle")


def ballistic_residual(height: np.ndarray, fps: float, gravity: float) -> float:
    """RMS residual (metres) of the best free-fall fit to a height track.

    Fits ``z(t) = z0 + v0 t - g t^2 / 2`` (only z0 and v0 free) by least
    squares to ``height`` (N,) sampled at ``fps``; a body with nothing
    supporting it follows such an arc exactly (its centre of mass does).
    Returns 0 for fewer than three samples (two parameters fit them exactly).
    """
    n = len(height)
    if n < 3:
        return 0.0
    t = np.arange(n) / fps
    target = np.asarray(height, dtype=np.float64) + 0.5 * gravity * t**2
    design = np.stack([np.ones(n), t], axis=1)
    coef, *_ = np.linalg.lstsq(design, target, rcond=None)
    return float(np.sqrt(np.mean((target - design @ coef) ** 2)))


def floating(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricResult:
    """Floating: airborne frames that are not a jump.

    A frame is airborne when its lowest keypoint is more than
    ``float_height_m`` above the floor (z = 0); wrist and hand keypoints
    count ``float_hand_reach_m`` lower (the palm and fingers can carry the
    body), and on a skeleton without toe keypoints the ankles count
    ``float_ankle_sole_m`` lower (the sole below the ankle joint). Each
    maximal airborne run is tested for a ballistic flight: the
    centre-of-mass proxy (mean of the trunk keypoints :data:`COM_KEYPOINTS`
    present) must follow a free-fall parabola, i.e. vertical acceleration
    -g, within an RMS residual of ``ballistic_tolerance_m``
    (:func:`ballistic_residual`). Jumps pass; a body hovering, rising or
    sinking slowly without support fails.

    Timeline: height in mm of the lowest (support-adjusted) keypoint on
    frames of non-ballistic airborne runs, 0 elsewhere; value: its maximum;
    passes when no frame floats (value at most ``float_height_m`` in mm).
    Details: ``airborne_fraction``, ``floating_fraction``,
    ``worst_residual_m``, ``jumps`` (ballistic runs).

    Assumes the floor is the only support (no chairs, props or partners:
    those need the body-level metrics). Needs three frames.
    """
    return score_clip(motion, floating_spec, thresholds)


def floating_spec(batch: ClipBatch, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricSpec:
    """:func:`floating` as :func:`~simenv.plausibility.clips.score` runs it."""
    com_idx = batch.indices(COM_KEYPOINTS)
    frames = batch.num_frames
    args, reason = None, ""
    if batch.skeleton is None:
        pass
    elif not com_idx:
        reason = ("needs a trunk keypoint (pelvis, hips, spine, chest, neck or shoulders) for "
                  "the centre-of-mass proxy")
    elif frames < 3:
        reason = (f"needs at least 3 frames to tell a jump from floating; the motion has "
                  f"{frames}")
    else:
        toeless = not batch.indices(TOE_KEYPOINTS)
        args = (np.array(com_idx, dtype=np.int64),
                np.array(batch.indices(HAND_KEYPOINTS), dtype=np.int64),
                float(thresholds.float_hand_reach_m),
                np.array(batch.indices(ANKLE_KEYPOINTS) if toeless else [], dtype=np.int64),
                float(thresholds.float_ankle_sole_m), float(thresholds.float_height_m),
                float(batch.fps), float(thresholds.gravity_mps2),
                float(thresholds.ballistic_tolerance_m))
    return MetricSpec(
        kernels.FLOAT, "floating", "mm", thresholds.float_height_m * 1000.0, args,
        ("airborne_fraction", "floating_fraction", "worst_residual_m", "jumps"),
        reason=reason)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True in a 1-D mask."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def body_floating(result: RetargetResult,
                  thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS, *,
                  poses: BodyPoses | None = None) -> MetricResult:
    """Floating on geoms: airborne frames whose centre of mass does not fall.

    A frame is airborne when every body geom is more than
    ``geom_float_clearance_m`` above the floor (hands, knees and the back all
    count as support: the geoms are the skin). Each maximal airborne run is
    a jump when the true centre of mass (body masses of the model) follows a
    free-fall parabola within ``ballistic_tolerance_m`` RMS
    (:func:`ballistic_residual`), and floating
    otherwise. Timeline: clearance (mm) of the lowest geom on floating frames,
    0 elsewhere; value: its maximum; passes when no frame floats. Details:
    ``airborne_fraction``, ``floating_fraction``, ``worst_residual_m``,
    ``jumps``. Assumes the floor is the only support. ``poses``: ``result``'s
    forward kinematics when the caller has them.
    """
    thr = thresholds.geom_float_clearance_m * 1000.0
    T = result.num_frames
    if T < 3:
        return MetricResult.not_available(
            "body_floating", T, "mm", thr,
            f"needs at least 3 frames to tell a jump from floating; the motion has {T}")
    lowest, poses = lowest_geom_z(result, poses)
    airborne = lowest > thresholds.geom_float_clearance_m
    floating_mask = np.zeros(T, dtype=bool)
    worst, jumps = 0.0, 0
    for start, stop in _runs(airborne):
        residual = ballistic_residual(poses.com[start:stop, 2], result.fps,
                                      thresholds.gravity_mps2)
        worst = max(worst, residual)
        if residual > thresholds.ballistic_tolerance_m:
            floating_mask[start:stop] = True
        else:
            jumps += 1
    timeline = np.where(floating_mask, lowest * 1000.0, 0.0)
    return MetricResult.from_timeline(
        "body_floating", timeline, float(timeline.max()), "mm", thr,
        details={"airborne_fraction": float(airborne.mean()),
                 "floating_fraction": float(floating_mask.mean()),
                 "worst_residual_m": worst, "jumps": float(jumps)},
    )


class GeomFloating(BodyMetric):
    """Airborne geoms without a free-fall centre of mass
    (:func:`body_floating`).

    A frame is airborne when every body geom is more than
    ``geom_float_clearance_m`` above the floor; an airborne run whose true
    centre of mass fits a free-fall parabola within ``ballistic_tolerance_m``
    RMS is a jump. Timeline: lowest geom's clearance (mm) on floating frames,
    0 elsewhere; value: its maximum; passes when no frame floats.
    """

    name = "floating"

    def limit(self, body: BodyThresholds) -> float:
        return body.geom_float_clearance_m * 1000.0

    def compute(self, inputs: PersonInputs) -> MetricResult:
        result = body_floating(fitted_body(inputs), inputs.config.body, poses=inputs.poses)
        return replace(result, name=self.name)


class KeypointFloating(KeypointMetric):
    """Airborne keypoints without a free-fall arc (:func:`floating`).

    A frame is airborne when the lowest keypoint (hands ``float_hand_reach_m``
    lower) is above ``float_height_m``; an airborne run whose trunk-keypoint
    centre fits ``z0 + v0 t - g t^2 / 2`` within ``ballistic_tolerance_m`` RMS
    is a jump. Timeline: height (mm) on floating frames, 0 elsewhere; value:
    its maximum; passes at <= ``float_height_m`` (in mm).
    """

    name, family, unit = "floating", "contact", "mm"

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        return (config.thresholds.float_height_m * 1000.0,) * 2

    spec = staticmethod(floating_spec)
    function = staticmethod(floating)

"""Ground penetration: the lowest point below the floor (plane z = 0).

Two versions under one report name, the preferred first: on the retargeted
body's geoms when a body was fitted (:class:`GeomPenetration`,
:func:`body_penetration`), on the keypoints otherwise
(:class:`KeypointPenetration`, :func:`ground_penetration`, kernel
:func:`simenv.plausibility.kernels.ground_penetration`). Thresholds:
``penetration_max_mm`` of :class:`~simenv.plausibility.thresholds.Thresholds`,
``geom_penetration_max_mm`` of
:class:`~simenv.plausibility.body_thresholds.BodyThresholds`. Metres in,
millimetres out.
"""

from __future__ import annotations

from dataclasses import replace
from operator import attrgetter

import numpy as np

from simenv.body.geometry import BodyPoses, body_geoms, body_poses, geom_lowest_z
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
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult


def ground_penetration(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS
                       ) -> MetricResult:
    """Depth of the lowest keypoint below the floor (PhysDiff "penetrate" at
    keypoint level).

    Timeline: ``max(0, -min_j z_j(t)) * 1000`` mm over all canonical keypoints
    (feet, but also hands or knees on the floor). Value: the maximum over
    frames; passes when at most ``penetration_max_mm``. Details:
    ``mean_mm`` (PhysDiff's per-clip mean over frames) and
    ``frames_below_floor`` (fraction). Works on a single frame.
    """
    return score_clip(motion, ground_penetration_spec, thresholds)


def ground_penetration_spec(batch: ClipBatch, thresholds: Thresholds = DEFAULT_THRESHOLDS
                            ) -> MetricSpec:
    """:func:`ground_penetration` as :func:`~simenv.plausibility.clips.score`
    runs it."""
    return MetricSpec(kernels.GROUND, "ground_penetration", "mm",
                      thresholds.penetration_max_mm,
                      None if batch.skeleton is None else (),
                      ("mean_mm", "frames_below_floor"))


def lowest_geom_z(result: RetargetResult, poses: BodyPoses | None,
                  geoms: np.ndarray | None = None) -> tuple[np.ndarray, BodyPoses]:
    """(T,) height of the lowest point of ``geoms`` (default: every body geom), metres, and
    the poses used (``poses`` when given, else computed)."""
    model = result.humanoid.model
    if poses is None:
        poses = body_poses(model, result.qpos)
    geoms = body_geoms(model) if geoms is None else geoms
    return geom_lowest_z(model, poses, geoms).min(axis=1), poses


def observed_geoms(result: RetargetResult, motion: Motion) -> np.ndarray:
    """The body geoms whose pose the source places: every body geom but a hand's when the
    source has no hand keypoint (e.g. SMPL's 22 joints end at the wrists). The fit then
    only guesses the hand's angle at the wrist (along the forearm), so where such a hand
    meets the floor the source shows nothing of it."""
    model = result.humanoid.model
    geoms = body_geoms(model)
    seen = set(motion.to_canonical().skeleton.joint_names)
    unseen = {b for b in range(model.nbody) for side in ("left", "right")
              if f"{side}_hand" not in seen and model.body(b).name.endswith(f"{side}_hand")}
    return geoms[~np.isin(model.geom_bodyid[geoms], list(unseen))]


def body_penetration(result: RetargetResult,
                     thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS, *,
                     poses: BodyPoses | None = None,
                     geoms: np.ndarray | None = None) -> MetricResult:
    """Depth of the body's lowest geom point below the floor.

    Timeline: ``max(0, -min_g z_low,g(t)) * 1000`` mm over every body geom
    (:func:`~simenv.body.geometry.geom_lowest_z`: exact for capsules and boxes), so a sinking foot,
    knee or hand counts. Value: the maximum over frames; passes when at most
    ``geom_penetration_max_mm``. Details: ``mean_mm`` (PhysDiff's
    "penetrate", here on geoms instead of mesh vertices) and
    ``frames_below_floor`` (fraction of frames deeper than 1 mm). ``poses``:
    ``result``'s forward kinematics when the caller has them; ``geoms``: the geoms
    judged (default every body geom; the scorer passes :func:`observed_geoms`).
    """
    lowest, _ = lowest_geom_z(result, poses, geoms)
    depth = np.maximum(-lowest, 0.0) * 1000.0
    return MetricResult.from_timeline(
        "body_penetration", depth, float(depth.max()), "mm",
        thresholds.geom_penetration_max_mm,
        details={"mean_mm": float(depth.mean()), "frames_below_floor": float((depth > 1).mean())},
    )


class GeomPenetration(BodyMetric):
    """Lowest body geom point below the floor (:func:`body_penetration`).

    Per frame ``max(0, -min_g z_low,g(t))`` in mm over the body geoms the source places
    (:func:`observed_geoms`: exact lowest points of capsules and boxes); value: the
    maximum; passes at <= ``geom_penetration_max_mm``.
    """

    name, limit = "ground_penetration", attrgetter("geom_penetration_max_mm")

    def compute(self, inputs: PersonInputs) -> MetricResult:
        body = fitted_body(inputs)
        result = body_penetration(body, inputs.config.body, poses=inputs.poses,
                                  geoms=observed_geoms(body, inputs.motion))
        return replace(result, name=self.name)


class KeypointPenetration(KeypointMetric):
    """Lowest keypoint below the floor
    (:func:`ground_penetration`).

    Per frame ``max(0, -min_j z_j(t))`` in mm; value: the maximum; passes at
    <= ``penetration_max_mm``.
    """

    name, family, unit = "ground_penetration", "contact", "mm"

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        return (config.thresholds.penetration_max_mm,) * 2

    spec = staticmethod(ground_penetration_spec)
    function = staticmethod(ground_penetration)

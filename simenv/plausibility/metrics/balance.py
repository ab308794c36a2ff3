"""Static balance: the centre of mass over the support polygon when quasi-static.

The metric (:class:`Balance`, :func:`balance`) on the retargeted body's
forward kinematics. Thresholds: ``balance_*``, ``support_height_m`` and
``filter_cutoff_hz`` of
:class:`~simenv.plausibility.body_thresholds.BodyThresholds`. Metres in,
millimetres out.
"""

from __future__ import annotations

from operator import attrgetter

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from simenv.body.dynamics import lowpass
from simenv.body.geometry import BodyPoses, body_geoms, body_poses, geom_support_points
from simenv.body.retarget import RetargetResult
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.metric import BodyMetric, PersonInputs, fitted_body
from simenv.plausibility.timeline import MetricResult


def distance_outside(point: np.ndarray, support: np.ndarray) -> float:
    """Distance (same unit) of a 2-D ``point`` outside the convex hull of
    ``support`` (N, 2); 0 inside. Degenerate hulls (1 point, collinear
    points) are a point or a segment."""
    pts = np.unique(np.round(support, 6), axis=0)
    if len(pts) >= 3:
        try:
            hull = ConvexHull(pts)
        except QhullError:
            hull = None
        if hull is not None:
            if np.all(hull.equations[:, :2] @ point + hull.equations[:, 2] <= 1e-9):
                return 0.0
            poly = pts[hull.vertices]
            segs = zip(poly, np.roll(poly, -1, axis=0), strict=True)
            return min(_point_segment(point, a, b) for a, b in segs)
    if len(pts) == 1:
        return float(np.linalg.norm(point - pts[0]))
    # Collinear: the segment between the two extreme points.
    d = pts - pts.mean(axis=0)
    axis = np.linalg.svd(d, full_matrices=False)[2][0]
    s = d @ axis
    return _point_segment(point, pts[np.argmin(s)], pts[np.argmax(s)])


def _point_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    s = np.clip(np.dot(p - a, ab) / max(np.dot(ab, ab), 1e-18), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + s * ab)))


def balance(result: RetargetResult,
            thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS, *,
            poses: BodyPoses | None = None) -> MetricResult:
    """Static balance: centre of mass over the support polygon when quasi-static.

    A frame is judged when it is quasi-static -- the centre of mass (6 Hz
    filtered) moves horizontally slower than ``balance_speed_mps`` and
    accelerates less than ``balance_accel_mps2`` -- and some geom point is
    within ``support_height_m`` of the floor. The support points are the geom
    points within ``support_height_m`` of the floor or within
    ``balance_support_band_m`` of the frame's lowest point (a foot standing a
    few centimetres higher than the other, on data whose floor is uneven, still
    carries weight). Timeline: distance (mm) of the centre of mass ground
    projection outside the convex hull of those points
    (:func:`distance_outside`), NaN on frames not judged; value: its
    maximum over judged frames (0 when none); passes when at most
    ``balance_margin_mm``. Details: ``judged_fraction``, ``outside_fraction``
    (judged frames with the centre of mass outside by more than the margin).
    ``poses``: ``result``'s forward kinematics when the caller has them.
    """
    thr = thresholds.balance_margin_mm
    T = result.num_frames
    if T < 3:
        return MetricResult.not_available(
            "balance", T, "mm", thr, f"needs at least 3 frames for accelerations; got {T}")
    model = result.humanoid.model
    if poses is None:
        poses = body_poses(model, result.qpos)
    com = lowpass(poses.com, result.fps, thresholds.filter_cutoff_hz)
    dt = 1.0 / result.fps
    vel = np.gradient(com, dt, axis=0)
    acc = np.linalg.norm(np.gradient(vel, dt, axis=0), axis=1)
    speed = np.linalg.norm(vel[:, :2], axis=1)
    points = geom_support_points(model, poses, body_geoms(model))
    lowest = points[..., 2].min(axis=1)
    timeline = np.full(T, np.nan)
    static = (acc < thresholds.balance_accel_mps2) & (speed < thresholds.balance_speed_mps)
    for t in np.flatnonzero(static & (lowest < thresholds.support_height_m)):
        z = points[t, :, 2]
        p = points[t][(z < thresholds.support_height_m)
                      | (z < lowest[t] + thresholds.balance_support_band_m)]
        if len(p):
            timeline[t] = distance_outside(poses.com[t, :2], p[:, :2]) * 1000.0
    judged = ~np.isnan(timeline)
    value = float(np.nanmax(timeline)) if judged.any() else 0.0
    return MetricResult.from_timeline(
        "balance", timeline, value, "mm", thr,
        details={"judged_fraction": float(judged.mean()),
                 "outside_fraction": float((timeline[judged] > thr).mean())
                 if judged.any() else 0.0},
    )


class Balance(BodyMetric):
    """Centre of mass over the support polygon when quasi-static
    (:func:`balance`).

    On frames whose 6 Hz filtered centre of mass moves slower than
    ``balance_speed_mps`` and accelerates less than ``balance_accel_mps2``,
    the distance (mm) of its ground projection outside the convex hull of the
    geom points near the floor (NaN elsewhere); value: the maximum; passes
    at <= ``balance_margin_mm``.
    """

    name, family, basis = "balance", "dynamics", "dynamics"
    limit = attrgetter("balance_margin_mm")

    def compute(self, inputs: PersonInputs) -> MetricResult:
        return balance(fitted_body(inputs), inputs.config.body, poses=inputs.poses)

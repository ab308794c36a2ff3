"""Dynamic plausibility of a retargeted trajectory: inverse dynamics and balance.

Root residual ("invisible help")
    The retargeted qpos trajectory's inverse dynamics give the net external
    wrench the body needs at its root, and the best floor contact forces
    (friction pyramids at the geom points near the floor) explain what they
    can of it (:mod:`simenv.body.dynamics`: :func:`~simenv.body.dynamics.root_wrench`,
    :func:`~simenv.body.dynamics.floor_residual`). What remains is the
    residual wrench no floor contact can explain; its force, divided by the
    body weight ``m g``, is the timeline. A real walk needs almost none; a
    walk lifted 30 cm needs about one body weight all the time (nothing
    touches the floor), which is the "residual force" of residual-force
    control (Yuan & Kitani 2020) that a simulated character would need to
    perform the motion. :mod:`simenv.plausibility.pair_dynamics` adds a
    partner's hand forces to the same per-frame problem.

    The derivatives are one-sided at a clip's ends; a trajectory cut mid-stride
    needs no help on its last frames (the real walk cut at 1, 1.3 or 1.7 s:
    at most 0.03 body weight), while a motion that stops dead -- CMU 49_04,
    whose last 6 frames are frozen copies -- does (up to 2.5 body weights).

Balance
    On quasi-static frames (centre-of-mass acceleration below
    ``balance_accel_mps2``) the ground projection of the centre of mass must
    lie inside the support polygon (convex hull of the support points); the
    timeline is its distance outside the polygon in millimetres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from simenv.body.dynamics import (
    DynamicsSettings,
    RootWrench,
    floor_residual,
    lowpass,
    root_wrench,
)
from simenv.body.geometry import BodyPoses, body_geoms, body_poses, geom_support_points
from simenv.body.retarget import RetargetResult
from simenv.core.errors import PhysicsError
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.timeline import MetricResult


def dynamics_settings(thresholds: BodyThresholds) -> DynamicsSettings:
    """The inverse-dynamics settings of ``thresholds`` (filter cutoff, floor
    friction, support height, gravity)."""
    return DynamicsSettings(cutoff_hz=thresholds.filter_cutoff_hz,
                            friction=thresholds.friction,
                            support_height_m=thresholds.support_height_m,
                            gravity_mps2=thresholds.gravity_mps2)


@dataclass(frozen=True)
class RootResidual:
    """Per-frame residual root wrench after the best floor contact forces.

    Attributes:
        force: (T,) residual force, fraction of body weight ``m g``.
        torque: (T,) residual torque about the root, N m divided by ``m g``
            (metres: the lever arm at which body weight makes that torque).
        required: (T,) the whole external force the motion needs, fraction of
            body weight (1 when standing still).
        support_points: (T,) number of geom points near enough to the floor
            to carry load.
        com_accel: (T, 3) centre-of-mass acceleration, m/s^2 (filtered).
        poses: the forward kinematics used.
        residual: (T, 6) residual wrench ``[F; N / L]``, N (see
            :class:`~simenv.body.dynamics.RootWrench`).
    """

    force: np.ndarray
    torque: np.ndarray
    required: np.ndarray
    support_points: np.ndarray
    com_accel: np.ndarray
    poses: BodyPoses
    residual: np.ndarray


def root_residual_wrench(result: RetargetResult,
                         thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS, *,
                         poses: BodyPoses | None = None) -> RootResidual:
    """The root's residual wrench per frame (see the module docstring);
    ``poses``: ``result``'s forward kinematics when the caller has them."""
    return residual_of(root_wrench(result, dynamics_settings(thresholds), poses=poses))


def residual_of(rw: RootWrench) -> RootResidual:
    """:class:`RootResidual` of a :class:`~simenv.body.dynamics.RootWrench`
    (floor forces only)."""
    T = len(rw.wrench)
    res = np.stack([floor_residual(rw, t) for t in range(T)]) if T else np.zeros((0, 6))
    norms = np.array([rw.residual_norms(r) for r in res]).reshape(T, 2)
    return RootResidual(norms[:, 0], norms[:, 1],
                        np.linalg.norm(rw.wrench[:, :3], axis=1) / rw.weight,
                        np.array([len(p) for p in rw.support], dtype=int),
                        rw.com_accel, rw.poses, res)


def root_residual(result: RetargetResult,
                  thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS, *,
                  tracked_error: np.ndarray | None = None,
                  poses: BodyPoses | None = None) -> MetricResult:
    """Residual root force: the help from nowhere the motion needs.

    Inferred (``tracked_error`` None): per frame, the residual force of the
    reference trajectory after the best floor contact forces, as a fraction
    of body weight (:func:`root_residual_wrench`, ``f_t``).

    Measured (``tracked_error`` given): ``tracked_error`` is the (T,) body
    error (metres, mean keypoint distance; NaN where not simulated) of an
    *unassisted* tracking controller that ran the motion in forward
    simulation (:func:`simenv.plausibility.tracking.tracking`, the MPC). On
    a frame it followed within ``root_residual_tracked_m`` the simulated body
    did the motion with its own actuators and the floor, so no help was
    needed; elsewhere (where it fell behind, after it failed, beyond the
    simulated stretch) the reference's inferred residual stands::

        r_t = 0          if e_t <= root_residual_tracked_m
        r_t = f_t        otherwise (e_t > limit or NaN)

    The inference's weak spot is what the measurement replaces: around
    flight phases and impacts the 6 Hz filtered accelerations spread landing
    forces into frames no geom supports, which reads as help (a real run
    outside the corpus needed 0.19 BW); a body that actually ran it needed
    none. A hover or a slow-motion flight cannot be tracked by a body under
    gravity, so those frames keep their inferred ~1 BW.

    Timeline: ``r_t``; value: its mean over frames; passes when at most
    ``root_force_mean_max``; violation runs above ``root_force_frame_max``.
    Details: ``p95``, ``max``, ``torque_mean_m`` and ``torque_p95_m``
    (inferred residual torque / body weight, metres), ``required_mean``
    (mean total external force needed, body weights),
    ``unsupported_fraction`` (frames without any geom near the floor),
    ``inferred_mean`` (the inferred value) and ``measured_fraction`` (frames
    the controller tracked; 0 when inferred). Needs 3 frames. ``poses``:
    ``result``'s forward kinematics when the caller has them.
    """
    thr = thresholds.root_force_mean_max
    T = result.num_frames
    if T < 3:
        return MetricResult.not_available(
            "root_residual", T, "body weight", thr,
            f"needs at least 3 frames for accelerations; the motion has {T}",
            frame_threshold=thresholds.root_force_frame_max)
    rr = root_residual_wrench(result, thresholds, poses=poses)
    f = rr.force
    tracked = np.zeros(T, dtype=bool)
    if tracked_error is not None:
        e = np.asarray(tracked_error, dtype=float)
        if e.shape != (T,):
            raise PhysicsError(f"tracked_error has shape {e.shape}; expected ({T},), one body "
                               "error per frame", field="tracked_error")
        with np.errstate(invalid="ignore"):
            tracked = e <= thresholds.root_residual_tracked_m
    r = np.where(tracked, 0.0, f)
    return MetricResult.from_timeline(
        "root_residual", r, float(r.mean()), "body weight", thr,
        frame_threshold=thresholds.root_force_frame_max,
        details={"p95": float(np.percentile(r, 95)), "max": float(r.max()),
                 "torque_mean_m": float(rr.torque.mean()),
                 "torque_p95_m": float(np.percentile(rr.torque, 95)),
                 "required_mean": float(rr.required.mean()),
                 "unsupported_fraction": float((rr.support_points == 0).mean()),
                 "inferred_mean": float(f.mean()),
                 "measured_fraction": float(tracked.mean())},
    )


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

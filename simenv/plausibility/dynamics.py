"""Dynamic plausibility of a retargeted trajectory: the inverse-dynamics root residual.

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

The root residual is the ``root_residual`` metric's math
(:mod:`simenv.plausibility.metrics.root_residual`); the wrench and the
settings here are shared with the two-person residual
(:mod:`simenv.plausibility.pair_dynamics`) and the tracker.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simenv.body.dynamics import (
    DynamicsSettings,
    RootWrench,
    floor_residual,
    root_wrench,
)
from simenv.body.geometry import BodyPoses
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

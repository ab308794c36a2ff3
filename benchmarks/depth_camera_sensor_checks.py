"""Sensor checks of the depth-camera profiles: measured, not shipped.

A family profile's thresholds sit on its sensor's worst real clips, so a moderate defect
hides under them. Two checks judge what the sensor's noise is not, each against the
family's own calibrated limit and reported under the metric that owns the defect:
:func:`limb_persistence` (a limb bone's persistent length change over the clip's own
frame-to-frame noise) for ``bone_length``, and :func:`body_jump` (the whole body leaving its
path in one frame, where joint-independent noise averages out) for ``velocity``.

Judged once on sources the calibration never saw, the checks put more real clips outside
than they caught defects (docs/plausibility.md, "Source kinds and depth-camera profiles"),
so the library does not run them: ``benchmarks/depth_camera_profiles.py`` writes their
measured limits to each profile's ``provenance["sensor_measured"]`` and reports the
held-out sources with and without them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from scipy.ndimage import median_filter

from simenv.core.motion import Motion
from simenv.plausibility.metrics.bone_length import bone_lengths, measured_bones
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds

#: Canonical keypoints at the lower end of the limb bones (thighs, shins, upper arms,
#: forearms): bones between two joints a depth camera localises on their own, unlike the
#: trunk, hand and foot bones, whose ends it guesses (their lengths wander several times
#: more on real Kinect clips: docs/plausibility.md, "Source kinds and depth-camera profiles").
LIMB_ENDS: tuple[str, ...] = (
    "left_knee", "left_ankle", "right_knee", "right_ankle",
    "left_elbow", "left_wrist", "right_elbow", "right_wrist",
)
#: Relative length noise (fraction) below which a limb bone counts as still: the floor of
#: :func:`limb_persistence`'s noise scale, so that a bone a sensor keeps rigid (MSR
#: Action3D's shins) does not turn a sub-millimetre change into a large multiple.
LIMB_NOISE_FLOOR = 0.01

#: Sensor-check settings: the limits (``*_max``: a check fails above) and the
#: running-median window (frames) of ``limb_persistence``.
SENSOR_FIELDS: tuple[str, ...] = ("limb_window_frames", "limb_persistence_max",
                                  "body_jump_max_m")
#: Sensor check -> (its limit field, the metric whose verdict it joins).
SENSOR_CHECKS: dict[str, tuple[str, str]] = {
    "limb_persistence": ("limb_persistence_max", "bone_length"),
    "body_jump": ("body_jump_max_m", "velocity"),
}


def limb_persistence(motion: Motion, window: int,
                     thresholds: Thresholds = DEFAULT_THRESHOLDS) -> tuple[float, str]:
    """The most persistent limb-bone length change of a clip, in units of the clip's own
    frame-to-frame length noise (the self-referenced bone check).

    For each source bone ending at a canonical :data:`LIMB_ENDS` keypoint whose median
    length is at least ``bone_min_length_m``: ``d(t) = L(t) / median_t L - 1``; its
    running median over ``window`` frames ``s(t)`` (edges repeat the end frames) is the
    persistent part, ``d - s`` the frame-to-frame noise with RMS ``n``. The bone's value
    is the 95th percentile over frames of ``|s(t) - median_t s|`` divided by
    ``n + LIMB_NOISE_FLOOR``. A depth camera's length errors come and go from frame to
    frame, so they sit in ``n``; a bone that keeps another length for a stretch of
    frames (a stretched bone, a limb the generator grew) moves ``s``.

    Args:
        motion: any skeleton with canonical limb keypoints; positions (T, J, 3) metres.
        window: running-median length in frames (odd, >= 3).

    Returns:
        (largest value over the limb bones, dimensionless; the bone ``"parent->child"``),
        ``(0.0, "")`` without a limb bone or with fewer frames than ``window``.
    """
    skel = motion.skeleton
    role = {v: k for k, v in skel.canonical.items()}
    names, lengths = bone_lengths(motion)
    keep = [k for k, (_, c) in enumerate(measured_bones(skel))
            if role.get(skel.joint_names[c]) in LIMB_ENDS]
    if not keep or motion.num_frames < window:
        return 0.0, ""
    length = lengths[:, keep]
    med = np.median(length, axis=0)
    ok = med >= thresholds.bone_min_length_m
    if not ok.any():
        return 0.0, ""
    d = length[:, ok] / med[ok] - 1.0
    smooth = median_filter(d, size=(window, 1), mode="nearest")
    noise = np.sqrt(np.mean((d - smooth) ** 2, axis=0))
    shift = np.percentile(np.abs(smooth - np.median(smooth, axis=0)), 95, axis=0)
    z = shift / (noise + LIMB_NOISE_FLOOR)
    k = int(np.argmax(z))
    return float(z[k]), [names[i] for i, o in zip(keep, ok, strict=True) if o][k]


def body_jump(motion: Motion) -> float:
    """Largest departure (metres) of the keypoints' centroid from its constant-velocity
    path: ``max_t |c(t+1) - 2 c(t) + c(t-1)|``, ``c`` the mean of the canonical keypoints
    (the whole-body teleport check). A depth camera's joint errors are independent from
    joint to joint, so they average out in ``c``; a body that jumps as a whole (a tracker
    that swaps people, a bad generated frame) moves ``c`` by the full jump. 0.0 for fewer
    than 3 frames.
    """
    if motion.num_frames < 3:
        return 0.0
    c = motion.to_canonical().positions.astype(np.float64).mean(axis=1)
    return float(np.max(np.linalg.norm(c[2:] - 2.0 * c[1:-1] + c[:-2], axis=-1)))


def sensor_values(motion: Motion, window: int) -> dict[str, float]:
    """The sensor checks' values of one person: ``limb_persistence`` (dimensionless, with a
    ``window``-frame running median) and ``body_jump`` (metres)."""
    return {"limb_persistence": limb_persistence(motion, window)[0],
            "body_jump": body_jump(motion)}


def sensor_limits(people: Sequence[Mapping[int, Mapping[str, float]]], window: int,
                  percentile: float) -> dict[str, float]:
    """Each sensor check's limit (:data:`SENSOR_FIELDS`): ``percentile`` of the people's
    values at ``window``, each person given as window (frames) -> :func:`sensor_values`."""
    out = {"limb_window_frames": float(window)}
    for check, (limit, _) in SENSOR_CHECKS.items():
        v = np.array([p[window][check] for p in people])
        out[limit] = round(float(np.percentile(v, percentile)), 4)
    return out


def sensor_failures(motion: Motion, sensor: Mapping[str, float] | None
                    ) -> dict[str, dict[str, float | str]]:
    """The sensor checks ``motion`` fails under the limits ``sensor`` (:data:`SENSOR_FIELDS`),
    keyed by the metric whose verdict each joins (``bone_length``, ``velocity``):
    ``{"check", "value", "limit"}``. Empty for None and for limits without a window."""
    if not sensor or "limb_window_frames" not in sensor:
        return {}
    values = sensor_values(motion, int(sensor["limb_window_frames"]))
    out: dict[str, dict[str, float | str]] = {}
    for check, (limit, metric) in SENSOR_CHECKS.items():
        if limit in sensor and values[check] > sensor[limit]:
            out[metric] = {"check": check, "value": values[check], "limit": sensor[limit]}
    return out

"""Keypoint speeds beyond human limits, and teleports between frames.

The metric (:class:`Velocity`, its kernel
:func:`simenv.plausibility.kernels.velocity`) and the keypoint groups of its
speed limits. Thresholds: ``speed_limit_*`` and ``teleport_*`` of
:class:`~simenv.plausibility.thresholds.Thresholds`. Metres, seconds.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from simenv.core.motion import Motion
from simenv.plausibility import kernels
from simenv.plausibility.clips import ClipBatch, MetricSpec, score_clip
from simenv.plausibility.metric import KeypointMetric, ScoreConfig
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult

#: Keypoint groups for the speed limits (see :class:`Thresholds`).
TRUNK_KEYPOINTS: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine", "chest", "neck", "head",
    "left_shoulder", "right_shoulder",
)


LIMB_KEYPOINTS: tuple[str, ...] = ("left_knee", "right_knee", "left_elbow", "right_elbow")


DISTAL_KEYPOINTS: tuple[str, ...] = (
    "left_ankle", "right_ankle", "left_toe", "right_toe",
    "left_wrist", "right_wrist", "left_hand", "right_hand",
)


def speed_limits(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> np.ndarray:
    """(J,) speed limit in m/s of each keypoint of a canonical ``motion``
    (trunk, mid-limb or distal limit; unknown names get the distal limit)."""
    return _speed_limits(tuple(motion.skeleton.joint_names), thresholds).copy()


@lru_cache(maxsize=64)
def _speed_limits(names: tuple[str, ...], thresholds: Thresholds) -> np.ndarray:
    """(J,) float64 limits, m/s, once per layout and thresholds (shared:
    never modified)."""
    group_limit = {
        **{n: thresholds.speed_limit_trunk_mps for n in TRUNK_KEYPOINTS},
        **{n: thresholds.speed_limit_limb_mps for n in LIMB_KEYPOINTS},
        **{n: thresholds.speed_limit_distal_mps for n in DISTAL_KEYPOINTS},
    }
    limits = [group_limit.get(n, thresholds.speed_limit_distal_mps)
              for n in names]
    return np.array(limits, dtype=np.float64)


def velocity(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricResult:
    """Keypoint speeds beyond human limits, and teleports between frames.

    Speed of keypoint j at frame t >= 1: ``s_j(t) = |p_j(t) - p_j(t-1)| * fps``
    against its group limit ``S_j`` (trunk / mid-limb / distal, see
    :class:`Thresholds`). Teleport: the departure from the constant-velocity
    path ``e_j(t) = |p_j(t+1) - 2 p_j(t) + p_j(t-1)|`` (metres) against
    ``E = max(teleport_distance_m, teleport_accel_mps2 / fps^2)``.
    Timeline (fraction of the limit):
    ``max_j max(s_j(t) / S_j, e_j(t) / E)``, NaN on frame 0; value: its
    maximum; passes when at most 1. Details: ``max_speed_mps``,
    ``max_speed_ratio``, ``max_jump_m``, ``teleport_frames``. Needs two frames
    (teleports need three; with two only speeds are checked).
    """
    return score_clip(motion, velocity_spec, thresholds)


def velocity_spec(batch: ClipBatch, thresholds: Thresholds = DEFAULT_THRESHOLDS
                  ) -> MetricSpec:
    """:func:`velocity` as :func:`~simenv.plausibility.clips.score` runs it."""
    frames, fps = batch.num_frames, batch.fps
    jump_limit = max(thresholds.teleport_distance_m, thresholds.teleport_accel_mps2 / fps**2)
    args, reason = None, ""
    if batch.skeleton is not None and frames < 2:
        reason = f"needs at least 2 frames for a speed; the motion has {frames}"
    elif batch.skeleton is not None:
        args = (_speed_limits(tuple(batch.names), thresholds), float(fps), float(jump_limit))
    return MetricSpec(
        kernels.VELOCITY, "velocity", "fraction of limit", 1.0, args,
        ("max_speed_mps", "max_speed_ratio", "max_jump_m", ("jump_limit_m", jump_limit),
         "teleport_frames"),
        reason=reason)


class Velocity(KeypointMetric):
    """Speeds beyond human limits and teleports (:func:`velocity`).

    Per frame ``max_j max(|p_j(t) - p_j(t-1)| fps / S_j, |p_j(t+1) - 2 p_j(t)
    + p_j(t-1)| / E)`` (fraction of the keypoint group's speed limit ``S_j``
    and of the teleport distance ``E``); value: its maximum; passes at <= 1.
    """

    name, family, unit = "velocity", "kinematic", "fraction of limit"

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        return 1.0, 1.0

    spec = staticmethod(velocity_spec)
    function = staticmethod(velocity)

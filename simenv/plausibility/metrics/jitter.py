"""High-frequency jitter: ProtoMotions' windowed normalized jerk.

The metric (:class:`Jitter`, its kernel :func:`simenv.plausibility.kernels.jitter`)
and the numpy form of its statistic (:func:`windowed_normalized_jerk`).
Thresholds: ``jerk_*``, ``normalized_jerk_max`` and ``high_jerk_percent_max`` of
:class:`~simenv.plausibility.thresholds.Thresholds`. Metres, seconds.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from simenv.core.motion import Motion, resample_weights
from simenv.plausibility import kernels
from simenv.plausibility.clips import ClipBatch, MetricSpec, norm3, score_clip
from simenv.plausibility.metric import KeypointMetric, ScoreConfig
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult

#: Path-length floor (metres) of the normalized jerk (ProtoMotions' value).
NJ_EPS = 0.1


def windowed_normalized_jerk(
    positions: np.ndarray, fps: float, window_frames: int, eps: float = NJ_EPS
) -> np.ndarray:
    """ProtoMotions' normalized jerk per sliding window and keypoint.

    For a window of ``w`` frames (duration ``T = (w - 1) / fps``) and one
    keypoint, with finite-difference velocity ``v``, jerk ``j`` and
    ``dt = 1 / fps``:
    ``NJ = T^5 * sum |j|^2 dt / (max(L, eps)^2 + eps)`` with path length
    ``L = sum |v| dt``. Dimensionless; windows advance one frame.

    Args:
        positions: (..., T, J, 3) metres; leading axes (e.g. clips) are
            batch axes.
        fps: frame rate of ``positions``.
        window_frames: ``w >= 4``.

    Returns:
        (..., T - w + 1, J) float64; empty along the window axis when ``T < w``.
    """
    pos = np.asarray(positions, dtype=np.float64)
    *lead, t_count, j_count, _ = pos.shape
    w = int(window_frames)
    if t_count < w or w < 4:
        return np.zeros((*lead, 0, j_count))
    dt = 1.0 / fps
    vel = np.diff(pos, axis=-3) / dt
    jerk = np.diff(pos, 3, axis=-3) / dt**3
    step = norm3(vel) * dt  # (..., T-1, J)
    jx, jy, jz = jerk[..., 0], jerk[..., 1], jerk[..., 2]
    jerk_sq = ((jx * jx + jy * jy) + jz * jz) * dt  # (..., T-3, J)
    # Window sums from cumulative sums: O(T) whatever the window length.
    zero = np.zeros((*lead, 1, j_count))
    cs_step = np.concatenate([zero, np.cumsum(step, axis=-2)], axis=-2)
    cs_jerk = np.concatenate([zero, np.cumsum(jerk_sq, axis=-2)], axis=-2)
    n = t_count - w + 1
    path = cs_step[..., w - 1 : w - 1 + n, :] - cs_step[..., :n, :]
    integrated = cs_jerk[..., w - 3 : w - 3 + n, :] - cs_jerk[..., :n, :]
    duration = (w - 1) * dt
    return duration**5 * integrated / (np.maximum(path, eps) ** 2 + eps)


def jitter(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricResult:
    """High-frequency jitter from ProtoMotions' windowed normalized jerk.

    The motion is first brought to at most ``thresholds.jerk_fps`` (30 Hz,
    ProtoMotions' rate; see :class:`Thresholds`). With windows of
    ``w = max(4, round(jerk_window_s * fps))`` frames (0.4 s),
    :func:`windowed_normalized_jerk` gives NJ per window and keypoint.

    Value: percentage of windows in which the *median* keypoint's NJ exceeds
    ``normalized_jerk_max`` (6500); passes when at most
    ``high_jerk_percent_max``. Capture or generation noise shakes every
    keypoint, whereas real jerky moments (landings, strikes, kicks) are
    local: ProtoMotions' published statistic, where *any* keypoint over 6500
    makes a window high-jerk, scores real CMU dance and athletics at 20-78 %,
    so it is reported in ``details["protomotions_high_jerk_percent"]`` for
    comparison but not used for the verdict. Timeline: the median keypoint's
    NJ of the window centred on each frame (NaN where no window is centred),
    against 6500. Details also: ``mean_jerk_mps3`` (mean over frames and
    keypoints of |jerk| at the analysis rate), ``normalized_jerk_mean``
    (ProtoMotions' ``normalized_jerk_mean``: mean over keypoints and windows)
    and ``analysis_fps``. Not available for clips shorter than one window.
    """
    return score_clip(motion, jitter_spec, thresholds)


def jitter_spec(batch: ClipBatch, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricSpec:
    """:func:`jitter` as :func:`~simenv.plausibility.clips.score` runs it."""
    fps = batch.fps
    fa, w, src, weight, reason = _jitter_setup(fps, batch.num_frames, thresholds)
    args = None
    if batch.skeleton is None:
        reason = ""
    elif reason is None:
        resample = src is not None
        if src is None:
            src, weight = _NO_RESAMPLE
        dt = 1.0 / fa
        args = (resample, src, weight, float(fps), float(fa), int(w), NJ_EPS,
                float(thresholds.normalized_jerk_max), dt**3, ((w - 1) * dt) ** 5, fa**3,
                _median_network(len(batch.names)))
    return MetricSpec(
        kernels.JITTER, "jitter", "%", thresholds.high_jerk_percent_max, args,
        ("protomotions_high_jerk_percent", "mean_jerk_mps3", "normalized_jerk_mean",
         ("analysis_fps", fa)),
        frame_threshold=thresholds.normalized_jerk_max, timeline_unit="normalized jerk",
        reason=reason or "")


@lru_cache(maxsize=64)
def _median_network(keypoints: int) -> np.ndarray:
    """:func:`simenv.plausibility.kernels.median_network` of a keypoint
    count, built once (shared: never modified)."""
    return kernels.median_network(keypoints)


#: Unused resampling arrays of a clip analysed at its own rate.
_NO_RESAMPLE = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.float32))


@lru_cache(maxsize=256)
def _jitter_setup(fps: float, frames: int, thresholds: Thresholds
                  ) -> tuple[float, int, np.ndarray | None, np.ndarray | None, str | None]:
    """Analysis rate, window (frames), resampling indices (N,) int64 and
    weights (N,) float32 (None without resampling), and why the metric is not
    available (None when it is), once per frame rate, length and thresholds."""
    fa = min(fps, thresholds.jerk_fps)
    w = max(4, round(thresholds.jerk_window_s * fa))
    needed = max(int(np.ceil((w - 1) * fps / fa)) + 1, 4)
    if frames < needed:
        return fa, w, None, None, (
            f"needs at least {needed} frames ({thresholds.jerk_window_s:g} s window at "
            f"{fa:g} fps); the motion has {frames}")
    # Down to the analysis rate (never up: interpolating up would add jerk
    # at every original sample), in float32 as Motion.resample.
    if not fps > fa * (1 + 1e-9):
        reason = None if frames >= w else f"resampled clip is shorter than one {w}-frame window"
        return fa, w, None, None, reason
    src, weight = resample_weights(frames, fps, fa)
    if len(src) < w:
        return fa, w, None, None, f"resampled clip is shorter than one {w}-frame window"
    return fa, w, src.astype(np.int64), weight.astype(np.float32), None


class Jitter(KeypointMetric):
    """High-frequency jitter (:func:`jitter`).

    ProtoMotions' normalized jerk ``T^5 sum |j|^2 dt / (max(L, eps)^2 + eps)``
    per 0.4 s window and keypoint at <= 30 fps; timeline: the median
    keypoint's NJ of the window centred on each frame; value: percentage of
    windows whose median keypoint exceeds ``normalized_jerk_max``; passes at
    <= ``high_jerk_percent_max``.
    """

    name, family, unit = "jitter", "kinematic", "%"

    def thresholds(self, config: ScoreConfig) -> tuple[float, float]:
        return config.thresholds.high_jerk_percent_max, config.thresholds.normalized_jerk_max

    spec = staticmethod(jitter_spec)
    function = staticmethod(jitter)

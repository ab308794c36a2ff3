"""Training the skeleton recogniser (:class:`simenv.models.skeleton_tcn.SkeletonTCN`) the way
the field learned to: body-centred, scale-normalised input, partial windows for early
recognition, Kinect-noise augmentation, and a calibrated temperature.

Training windows (:func:`training_windows`), one fresh window per clip and epoch:

1. **Speed**: the clip is resampled in time by a factor in ``speed`` (a person waving
   faster or slower; linear interpolation).
2. **Crop**: with probability ``partial_prob`` a random ``partial_frames`` span of the clip
   (early recognition: the perception loop classifies 1 s of a gesture that may have just
   begun, or be half-way), otherwise a random crop of at most ``max_frames``; padding is
   masked out (the network pools over valid frames only).
3. **Forecast** (only with a ``predictor``): with probability ``forecast_prob`` a 1 s
   partial window is continued by the predictor's forecast, all frames valid -- the
   window "1 s real + 2 s predicted" the loop's anticipation stage classifies, so the
   network learns to read forecasts instead of meeting them first at test time. The
   forecaster runs on the normalised window (a similarity transform of the world frame,
   scale near 1; the gesture forecaster body-centres its input itself).
   **Stream** (``stream_prob``, off by default): otherwise, with this probability, the
   window the perception loop reads at a tick: the last ``stream_frames`` frames (a
   length drawn in that range) ending at a random frame of the clip, frames before the
   clip's first holding its first pose (the loop's stream, where a person stands still
   before the gesture); every frame valid.
4. **Normalise** (:func:`simenv.data.gestures.normalise_windows`); with
   ``canonical_body`` (default) the body is read alike from every sensor
   (:func:`simenv.data.sensor_invariance.canonical_body`: trunk joints redefined from the
   shoulders and hips, every bone at a reference length), as a network trained so reads
   every window (:meth:`SkeletonTCN.model_input`); then **Kinect noise**
   (:func:`kinect_noise`): mirror image, rotation (yaw, and pitch/roll of a tilted
   sensor), isotropic and per-axis scale, Gaussian jitter, and dropped joints (a joint
   pulled toward its parent for the whole window, as a Kinect does with an occluded hand).

Optimisation: AdamW, one-cycle learning rate, cross-entropy with label smoothing and class
weights ``(N / (C n_c))^(1/2)``; seeded; one CPU thread; a tqdm bar.

Calibration (:func:`simenv.models.skeleton_tcn.fit_temperature`): the temperature is fitted
on logits of subjects the network did not train on (out-of-fold in the protocols of
:mod:`simenv.learning.recognition_protocols`), never on the clips it is evaluated on.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from simenv.core.config import dataclass_from_file
from simenv.core.errors import SimenvError, SkeletonError
from simenv.core.skeletons import Skeleton
from simenv.data.gestures import (
    GESTURE_FPS,
    GestureClip,
    cut_window,
    gesture_skeleton,
    mirror_windows,
    normalise_windows,
)
from simenv.data.sensor_invariance import canonical_body, has_canonical_joints
from simenv.models.skeleton_tcn import CANONICAL_BODY, SkeletonTCN, TCNConfig
from simenv.models.training import CpuBudget, seeded

#: Frames of real motion in the short condition and the loop's tick (1 s at 25 fps).
SHORT_FRAMES = 25


@dataclass
class RecognitionConfig:
    """Training options of the recogniser (overridable from a TOML/JSON file).

    Attributes:
        seed: seed of every random draw. epochs: passes over the clips.
        batch_size, lr, weight_decay, label_smoothing: optimisation.
        width, dropout: network (:class:`~simenv.models.skeleton_tcn.TCNConfig`).
        max_frames: longest training window, frames at 25 fps (75 = 3 s).
        partial_prob: probability of a partial window; partial_frames: its length range
            [lo, hi] in frames.
        forecast_prob: probability that a window is 1 s real + a forecast (needs a
            predictor; otherwise ignored).
        speed: time-scale range of the speed augmentation.
        mirror: mirror half the windows.
        yaw_deg, tilt_deg: rotation noise (uniform within ±).
        scale, axis_scale: isotropic and per-axis scale noise (± fraction).
        jitter_m: standard deviation of per-joint Gaussian jitter, m.
        drop_prob: probability of a window with one dropped joint.
        stream_prob: probability of a loop-tick window (module docstring, step 3);
            stream_frames: its length range [lo, hi] in frames (at most max_frames).
        canonical_body: read windows through
            :func:`~simenv.data.sensor_invariance.canonical_body` (the network is marked
            so, and :meth:`SkeletonTCN.model_input` gives it its input the same way); on a
            joint set
            without the joints it redefines (gesture9, a dataset's native skeleton) the
            windows are read as normalised and the network is not marked.
        max_minutes: CPU-time budget; training stops after the epoch that exceeds it.
    """

    seed: int = 0
    epochs: int = 40
    batch_size: int = 32
    lr: float = 2e-3
    weight_decay: float = 0.05
    label_smoothing: float = 0.1
    width: int = 128
    dropout: float = 0.2
    max_frames: int = 75
    partial_prob: float = 0.5
    partial_frames: tuple[int, int] = (10, 40)
    forecast_prob: float = 0.25
    speed: tuple[float, float] = (0.75, 1.33)
    mirror: bool = True
    yaw_deg: float = 30.0
    tilt_deg: float = 8.0
    scale: float = 0.15
    axis_scale: float = 0.07
    jitter_m: float = 0.01
    drop_prob: float = 0.3
    stream_prob: float = 0.0
    stream_frames: tuple[int, int] = (25, 75)
    canonical_body: bool = True
    max_minutes: float = 20.0

    def __post_init__(self) -> None:
        self.partial_frames = tuple(int(v) for v in self.partial_frames)  # type: ignore
        self.stream_frames = tuple(int(v) for v in self.stream_frames)  # type: ignore
        self.speed = tuple(float(v) for v in self.speed)  # type: ignore[assignment]
        lo, hi = self.partial_frames
        if not 1 <= lo <= hi:
            raise SimenvError(f"partial_frames must be 1 <= lo <= hi; got {self.partial_frames}",
                              field="partial_frames")
        if not 0 < self.speed[0] <= self.speed[1]:
            raise SimenvError(f"speed must be 0 < lo <= hi; got {self.speed}", field="speed")
        lo, hi = self.stream_frames
        if not 1 <= lo <= hi <= self.max_frames:
            raise SimenvError(f"stream_frames must be 1 <= lo <= hi <= max_frames; got "
                              f"{self.stream_frames}", field="stream_frames")
        for name in ("partial_prob", "forecast_prob", "drop_prob", "stream_prob"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise SimenvError(f"{name} must be in [0, 1]; got {getattr(self, name)}",
                                  field=name)
        if self.epochs < 1 or self.max_frames < 2:
            raise SimenvError(f"epochs >= 1 and max_frames >= 2 needed; got {self.epochs}, "
                              f"{self.max_frames}", field="epochs")

    @classmethod
    def from_file(cls, path: str | Path, **overrides: Any) -> RecognitionConfig:
        """Config from a TOML or JSON file (unknown keys are an error)."""
        return dataclass_from_file(cls, path, **overrides)


def time_scale(positions: np.ndarray, factor: float) -> np.ndarray:
    """(T, J, 3) clip played ``factor`` times slower (> 1) or faster (< 1): resampled to
    ``round(T factor)`` frames (at least 2) by linear interpolation."""
    n = len(positions)
    if n < 2:
        return positions.copy()
    m = max(2, int(round(n * factor)))
    s = np.linspace(0.0, n - 1, m)
    i0 = np.minimum(np.floor(s).astype(int), n - 2)
    a = (s - i0)[:, None, None]
    return ((1 - a) * positions[i0] + a * positions[i0 + 1]).astype(np.float32)


def _rotations(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """(N, 3, 3) ``R_z(yaw) R_y(pitch) R_x(roll)``."""
    cy, sy, cp, sp, cr, sr = (np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch),
                              np.cos(roll), np.sin(roll))
    return np.stack([
        np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
        np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
        np.stack([-sp, cp * sr, cp * cr], -1)], axis=1)


def kinect_noise(x: np.ndarray, rng: np.random.Generator, config: RecognitionConfig,
                 joints: Sequence[str], parents: Sequence[int]) -> np.ndarray:
    """Augmented copies of normalised windows (N, T, J, 3) (module docstring, step 4)."""
    x = np.array(x, dtype=np.float32)
    n = len(x)
    if config.mirror:
        flip = rng.random(n) < 0.5
        x[flip] = mirror_windows(x[flip], joints)
    tilt = np.deg2rad(config.tilt_deg)
    rot = _rotations(rng.uniform(-1, 1, n) * np.deg2rad(config.yaw_deg),
                     rng.uniform(-tilt, tilt, n), rng.uniform(-tilt, tilt, n))
    x = np.einsum("nij,ntkj->ntki", rot, x)
    x *= rng.uniform(1 - config.scale, 1 + config.scale, (n, 1, 1, 1))
    x *= rng.uniform(1 - config.axis_scale, 1 + config.axis_scale, (n, 1, 1, 3))
    x += rng.normal(0.0, config.jitter_m, x.shape)
    movable = [j for j, p in enumerate(parents) if p >= 0]
    for i in np.flatnonzero(rng.random(n) < config.drop_prob):
        j = int(rng.choice(movable))
        p = parents[j]
        # An untracked joint: stuck at a shortened mean offset from its parent.
        offset = (x[i, :, j] - x[i, :, p]).mean(axis=0) * rng.uniform(0.3, 1.0)
        x[i, :, j] = x[i, :, p] + offset
    return x.astype(np.float32)


def clip_skeleton(clips: Sequence[GestureClip], skeleton: Skeleton | None = None) -> Skeleton:
    """The joint set all ``clips`` are on.

    ``skeleton`` when given; else the skeleton the clips carry, when they have a
    ``skeleton`` attribute (e.g. the benchmarks' native-skeleton clips,
    :class:`simenv.learning.recognition_protocols.NativeClip`); else ``gesture15`` or ``gesture9``,
    told apart by the joint count. Any skeleton works that names the joints
    :func:`~simenv.data.gestures.normalise_windows` measures a window by (``spine``, left/right
    ``shoulder``, ``elbow``, ``wrist``); its parents give the network's bone stream.

    Raises:
        SkeletonError: clips on different or unknown joint counts, clips carrying different
            skeletons (or only some of them one), a skeleton whose joint count is not the
            clips', or one lacking a joint the normalisation needs.
    """
    counts = {c.positions.shape[1] for c in clips}
    carried = [getattr(c, "skeleton", None) for c in clips]
    if skeleton is None and any(s is not None for s in carried):
        if any(s is None or s != carried[0] for s in carried):
            raise SkeletonError("clips carry different skeletons (or only some carry one); "
                                "train and test one skeleton at a time", field="joints")
        skeleton = carried[0]
    if skeleton is not None:
        needed = ("spine", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
                  "left_wrist", "right_wrist")
        missing = [j for j in needed if j not in skeleton.joint_names]
        if missing:
            raise SkeletonError(f"skeleton {skeleton.name!r} lacks joint(s) "
                                f"{', '.join(missing)} that the window normalisation needs",
                                field="joints")
        if counts != {len(skeleton.joint_names)}:
            raise SkeletonError(f"clips must all be on the {len(skeleton.joint_names)} joints "
                                f"of {skeleton.name!r}; joint counts {sorted(counts)}",
                                field="joints")
        return skeleton
    sets = {len(s.joint_names): s for s in (gesture_skeleton("gesture15"),
                                            gesture_skeleton("gesture9"))}
    if len(counts) != 1 or next(iter(counts)) not in sets:
        raise SkeletonError(f"clips must all be on gesture15 or gesture9; joint counts "
                            f"{sorted(counts)}", field="joints")
    return sets[next(iter(counts))]


#: A forecaster for training windows: (N, 25, J, 3) normalised histories -> (N, F, J, 3).
Forecaster = Callable[[np.ndarray], np.ndarray]


def training_windows(clips: Sequence[GestureClip], rng: np.random.Generator,
                     config: RecognitionConfig, forecast: Forecaster | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """One fresh, normalised, un-augmented window per clip (module docstring, steps 1-3):
    ((N, max_frames, J, 3) float32, (N, max_frames) bool valid)."""
    length = config.max_frames
    lo, hi = config.partial_frames
    xs, vs, fc = [], [], []
    for clip in clips:
        p = time_scale(clip.positions, rng.uniform(*config.speed))
        to_forecast = forecast is not None and rng.random() < config.forecast_prob
        if not to_forecast and config.stream_prob > 0 and rng.random() < config.stream_prob:
            # The loop's window at a tick: the person held the first pose before the clip.
            span = int(rng.integers(config.stream_frames[0], config.stream_frames[1] + 1))
            end = int(rng.integers(1, len(p) + 1)) + length
            lead = np.concatenate([np.repeat(p[:1], length, axis=0), p])
            w, v = cut_window(lead[end - span:end], length=length)
        else:
            if to_forecast:
                span = SHORT_FRAMES
            elif rng.random() < config.partial_prob:
                span = int(rng.integers(lo, hi + 1))
            else:
                span = length
            span = min(span, len(p), length)
            offset = int(rng.integers(0, len(p) - span + 1))
            w, v = cut_window(p, length=length, offset=offset, real_frames=span)
        xs.append(w)
        vs.append(v)
        fc.append(to_forecast)
    x, valid = np.stack(xs), np.stack(vs)
    joints = clip_skeleton(clips).joint_names
    x = normalise_windows(x, valid, joints=joints)
    rows = np.flatnonzero(fc)
    if rows.size:
        x, valid = continue_windows(x, valid, rows, forecast)
    if config.canonical_body and has_canonical_joints(joints):
        # After the forecast: the network reads the whole window as logits_of gives it.
        x = canonical_body(x, valid, joints=joints)
    return x, valid


def continue_windows(x: np.ndarray, valid: np.ndarray, rows: np.ndarray,
                     forecast: Forecaster) -> tuple[np.ndarray, np.ndarray]:
    """Windows ``rows`` continued after their last :data:`SHORT_FRAMES` real frames by
    ``forecast`` (frames missing before a shorter real part repeat its first), the
    continuation marked valid; the window length is kept."""
    x, valid = x.copy(), valid.copy()
    hist = np.empty((len(rows), SHORT_FRAMES) + x.shape[2:], np.float32)
    for k, i in enumerate(rows):
        n = int(valid[i].sum())
        real = x[i, :n][-SHORT_FRAMES:]
        hist[k] = np.concatenate([np.repeat(real[:1], SHORT_FRAMES - len(real), 0), real])
    future = np.asarray(forecast(hist), np.float32)
    for k, i in enumerate(rows):
        n = int(valid[i].sum())
        room = min(x.shape[1] - n, future.shape[1])
        x[i, n:n + room] = future[k, :room]
        x[i, n + room:] = future[k, room - 1] if room else x[i, n - 1]
        valid[i, :n + room] = True
    return x, valid


def class_weights(y: np.ndarray, num_classes: int) -> torch.Tensor:
    """(C,) loss weights ``(N / (C n_c))^(1/2)`` (1 for absent classes)."""
    counts = np.bincount(y, minlength=num_classes).astype(np.float64)
    w = np.where(counts > 0, np.sqrt(len(y) / (num_classes * np.maximum(counts, 1))), 1.0)
    return torch.tensor(w, dtype=torch.float32)


def train_recogniser(clips: Sequence[GestureClip], labels: Sequence[str],
                     label_of: Callable[[GestureClip], str], config: RecognitionConfig, *,
                     forecast: Forecaster | None = None, progress: bool = True,
                     extra: dict[str, Any] | None = None) -> tuple[SkeletonTCN, dict[str, Any]]:
    """Train a :class:`SkeletonTCN` on ``clips`` (module docstring).

    Args:
        clips: training clips, all on one gesture joint set.
        labels: the class names (index = class id).
        label_of: a clip's class name (one of ``labels``).
        config: training options.
        forecast: optional forecaster for the "1 s real + forecast" windows.
        progress: show a progress bar.
        extra: provenance stored in the network's config.

    Returns:
        (network in eval mode, temperature 1; history with per-epoch loss and CPU seconds).

    Raises:
        SimenvError: no clips, or a clip whose label is not in ``labels``.
    """
    if not clips:
        raise SimenvError("no training clips")
    y = []
    for c in clips:
        name = label_of(c)
        if name not in labels:
            raise SimenvError(f"clip {c.name!r} has label {name!r}, not one of {list(labels)}",
                              field="labels")
        y.append(labels.index(name))
    y_all = np.array(y)
    skel = clip_skeleton(clips)
    rng = seeded(config.seed)
    extra = dict(extra or {})
    if config.canonical_body and has_canonical_joints(skel.joint_names):
        extra[CANONICAL_BODY] = True
    model = SkeletonTCN(TCNConfig(skel.joint_names, skel.parents, tuple(labels),
                                  fps=GESTURE_FPS, width=config.width, dropout=config.dropout,
                                  extra=extra))
    weights = class_weights(y_all, len(labels))
    steps = config.epochs * math.ceil(len(clips) / config.batch_size)
    optimizer = torch.optim.AdamW(model.parameters(), lr=config.lr,
                                  weight_decay=config.weight_decay)
    schedule = torch.optim.lr_scheduler.OneCycleLR(optimizer, config.lr, total_steps=steps)
    history: dict[str, Any] = {"epoch_loss": [], "stopped_early": False}
    budget = CpuBudget(config.max_minutes)
    bar = tqdm(range(config.epochs), desc="train recogniser", disable=not progress,
               leave=False)
    for _ in bar:
        x, valid = training_windows(clips, rng, config, forecast)
        x = kinect_noise(x, rng, config, skel.joint_names, skel.parents)
        order = rng.permutation(len(x))
        model.train()
        losses = []
        for i in range(0, len(order), config.batch_size):
            idx = order[i:i + config.batch_size]
            logits = model(torch.from_numpy(x[idx]), torch.from_numpy(valid[idx]))
            loss = torch.nn.functional.cross_entropy(
                logits, torch.from_numpy(y_all[idx]), weight=weights,
                label_smoothing=config.label_smoothing)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            schedule.step()
            losses.append(loss.item())
        history["epoch_loss"].append(round(float(np.mean(losses)), 4))
        bar.set_postfix(loss=history["epoch_loss"][-1])
        if budget.exceeded():
            history["stopped_early"] = True
            break
    history["epochs_run"] = len(history["epoch_loss"])
    history["train_cpu_s"] = round(budget.seconds(), 1)
    return model.eval(), history


@torch.no_grad()
def logits_of(model: SkeletonTCN, x: np.ndarray, valid: np.ndarray,
              batch_size: int = 256) -> np.ndarray:
    """(N, C) raw logits (before the temperature) of normalised windows (through
    :meth:`SkeletonTCN.model_input`)."""
    model.eval()
    x = model.model_input(x, valid)
    out = [model(torch.from_numpy(np.ascontiguousarray(x[i:i + batch_size], np.float32)),
                 torch.from_numpy(np.asarray(valid[i:i + batch_size], bool))).numpy()
           for i in range(0, len(x), batch_size)]
    return np.concatenate(out)


__all__ = ["SHORT_FRAMES", "Forecaster", "RecognitionConfig", "class_weights", "clip_skeleton",
           "continue_windows", "kinect_noise", "logits_of", "time_scale", "train_recogniser",
           "training_windows"]

"""A hand-written wave detector on the avatar keypoints the room's agent sees (issue 34).

The simplest baseline beside the learned recogniser: no training, a few parameters
(:class:`WaveRule`). At a tick it reads the last :attr:`WaveRule.window_s` seconds of the
user's keypoints on the ``gesture15`` joints (:data:`simenv.data.gestures.GESTURE15_JOINTS`,
(T, 15, 3) m, Z up, 25 fps: what :func:`simenv.perception.protocol.avatar_clips` gives) and
fires when one hand swings side to side above its shoulder.

The math, per window of T frames:

* **Body size** s (m): the median over the window of the distance between the shoulders.
  Every length below is divided by it, so one rule reads children and adults alike.
* **The body's own sideways axis** u: the window's mean of the shoulder line (left shoulder
  minus right shoulder) projected on the floor (Z dropped), unit length. Height is the
  world's Z (the room's avatar stands upright; the trunk's tilt is not the body's frame
  for "above the shoulder").
* Per hand (left, right): its height ``h_t = (z_wrist - z_shoulder) / s`` and its sideways
  position ``x_t = ((p_wrist - p_neck) . u) / s`` (shoulder widths), ``x`` smoothed by a
  centred moving average of :attr:`WaveRule.smooth_frames` frames (the sensor's jitter is
  not a swing).
* **Half-swings** (:func:`half_swings`): the zig-zag of ``x`` with hysteresis
  :attr:`WaveRule.swing` -- a turning point counts once ``x`` has come back from it by at
  least ``swing`` shoulder widths, and the leg into it (from the previous turning point,
  or from the window's lowest / highest ``x`` before the first) travelled at least
  ``swing`` too. Each leg ending in a turning point is a half-swing: its duration, its
  sideways travel ``|dx|``, the range of ``h`` over it and the lowest ``h`` on it.
* A half-swing's reversal is **kept** (:meth:`WaveRule.kept`) when the wrist stays at or
  above :attr:`WaveRule.raise_height` throughout it, its vertical range is at most
  :attr:`WaveRule.max_rise` times ``|dx|`` (sideways, not up and down or round), and it
  lasted between ``1 / (2 max_hz)`` and ``1 / (2 min_hz)`` seconds (a swing of
  ``min_hz`` .. ``max_hz``).
* The rule **fires** when either hand has at least :attr:`WaveRule.reversals` kept
  reversals in the window.

Streaming (:func:`stream_fires`) reads each clip exactly as
:func:`simenv.perception.protocol.stream_readings` does: the person holds the first pose
before the clip, a tick every :data:`simenv.perception.protocol.TICK_FRAMES` frames with
the same seeded phases, ticks until the one at or after the clip's last frame (which sees
the clip's last frames). :func:`rule_outcomes` counts what the loop's rule would count
(:func:`simenv.perception.protocol.loop_outcomes`): a clip is greeted when any of its
ticks fires.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from simenv.core.errors import SimenvError
from simenv.data.gestures import GESTURE15_JOINTS, GestureClip
from simenv.perception.protocol import (
    GREET_LABEL,
    TICK_FRAMES,
    greeting_rates,
    outcome_group,
    tick_frames,
)

_J = {name: k for k, name in enumerate(GESTURE15_JOINTS)}
#: (shoulder, wrist) joint indices of each hand in ``gesture15``.
HANDS: dict[str, tuple[int, int]] = {
    "left": (_J["left_shoulder"], _J["left_wrist"]),
    "right": (_J["right_shoulder"], _J["right_wrist"]),
}


@dataclass(frozen=True)
class WaveRule:
    """The detector's parameters (module docstring). The defaults are the rule that
    ``benchmarks/wave_rule_cross_dataset.py`` chooses on every subject of the room's own
    corpus (MSR Action3D and UTKinect as the avatar reads them; its criterion: the most
    waves greeted with at most 2 % of the other and idle clips greeted).

    Attributes:
        window_s: seconds of motion read at a tick, ending at it.
        raise_height: lowest wrist height over its shoulder during a half-swing, shoulder
            widths (0: level with the shoulder; negative: below it).
        swing: least sideways travel of a half-swing, shoulder widths.
        max_rise: largest vertical travel of a half-swing per unit of its sideways travel
            (a wave swings sideways; a drawn circle or an up-and-down beat does not).
        reversals: least number of kept reversals of one hand in the window.
        min_hz, max_hz: swing frequencies counted, Hz (a half-swing lasts
            ``1 / (2 max_hz)`` .. ``1 / (2 min_hz)`` s).
        smooth_frames: width of the moving average on the sideways position, frames.
        fps: frame rate of the keypoints, Hz.

    Raises:
        SimenvError: a parameter out of its range.
    """

    window_s: float = 2.0
    raise_height: float = -0.25
    swing: float = 0.5
    max_rise: float = 1.0
    reversals: int = 2
    min_hz: float = 0.4
    max_hz: float = 3.0
    smooth_frames: int = 3
    fps: float = 25.0

    def __post_init__(self) -> None:
        checks = {"window_s": self.window_s > 0, "swing": self.swing > 0,
                  "max_rise": self.max_rise > 0, "reversals": self.reversals >= 1,
                  "min_hz": 0 < self.min_hz < self.max_hz,
                  "smooth_frames": self.smooth_frames >= 1, "fps": self.fps > 0,
                  "raise_height": np.isfinite(self.raise_height)}
        for name, ok in checks.items():
            if not ok:
                raise SimenvError(f"WaveRule.{name} out of range: {getattr(self, name)} "
                                  f"(window_s, swing, max_rise, fps > 0; reversals, "
                                  f"smooth_frames >= 1; 0 < min_hz < max_hz)", field=name)

    @property
    def window_frames(self) -> int:
        """Frames read at a tick."""
        return max(int(round(self.window_s * self.fps)), 2)

    @property
    def min_frames(self) -> int:
        """Fewest frames a window may have: the moving average plus two frames."""
        return self.smooth_frames + 2

    def kept(self, legs: HalfSwings) -> np.ndarray:
        """(2,) kept reversals of the left and the right hand among ``legs``."""
        frames = legs.frames / self.fps
        ok = ((frames >= 1 / (2 * self.max_hz)) & (frames <= 1 / (2 * self.min_hz))
              & (legs.low >= self.raise_height)
              & (legs.vertical <= self.max_rise * legs.sideways))
        return np.bincount(legs.hand[ok], minlength=2)


@dataclass(frozen=True)
class HalfSwings:
    """The half-swings of one window (zig-zag legs of each hand's sideways position that
    end in a reversal; module docstring), N of them.

    Attributes:
        hand: (N,) 0 left, 1 right (the order of :data:`HANDS`).
        frames: (N,) duration, frames.
        sideways: (N,) sideways travel, shoulder widths (>= the zig-zag's ``swing``).
        vertical: (N,) range of the wrist's height over the leg, shoulder widths.
        low: (N,) lowest wrist height over its shoulder during the leg, shoulder widths.
        body_size_m: the shoulder width the window was scaled by, m.
    """

    hand: np.ndarray
    frames: np.ndarray
    sideways: np.ndarray
    vertical: np.ndarray
    low: np.ndarray
    body_size_m: float


@dataclass(frozen=True)
class WaveReading:
    """What the rule read on one window.

    Attributes:
        fired: at least :attr:`WaveRule.reversals` kept reversals on one hand.
        reversals: kept reversals per hand, ``{"left": n, "right": n}``.
        body_size_m: the shoulder width the window was scaled by, m.
    """

    fired: bool
    reversals: dict[str, int]
    body_size_m: float


def _check(keypoints: np.ndarray, min_frames: int) -> np.ndarray:
    """``keypoints`` as float64 (T, 15, 3), or a clear error."""
    k = np.asarray(keypoints, dtype=np.float64)
    if k.ndim != 3 or k.shape[1:] != (len(GESTURE15_JOINTS), 3):
        raise SimenvError(f"keypoints must be (T, {len(GESTURE15_JOINTS)}, 3) on the "
                          f"gesture15 joints; got shape {k.shape}", field="keypoints")
    if len(k) < min_frames:
        raise SimenvError(f"a window needs at least {min_frames} frames; got {len(k)}",
                          field="keypoints")
    bad = ~np.isfinite(k).all(axis=(1, 2))
    if bad.any():
        raise SimenvError("keypoints hold NaN or infinite values (untracked frames must be "
                          "filled before the rule reads them)", frame=int(np.argmax(bad)),
                          field="keypoints")
    return k


def _turns(x: np.ndarray, swing: float) -> tuple[list[int], list[int]]:
    """Zig-zag of ``x`` (T,) with hysteresis ``swing``: (turning frames, the frame each
    half-swing into them started from). Only local extrema can be turning points, so the
    zig-zag runs over them (and the first frame) rather than every frame."""
    d = np.sign(np.diff(x))
    nz = np.flatnonzero(d)
    change = nz[1:][d[nz[1:]] != d[nz[:-1]]]
    candidates = np.concatenate([[0], change, [len(x) - 1]])
    v = x[candidates]
    turns, starts = [], []
    lo = hi = 0  # running extrema while no direction is set
    trend, ext, start = 0, 0, 0
    for i in range(1, len(v)):
        if trend == 0:
            lo = i if v[i] < v[lo] else lo
            hi = i if v[i] > v[hi] else hi
            if v[i] - v[lo] >= swing:
                trend, ext, start = 1, i, lo
            elif v[hi] - v[i] >= swing:
                trend, ext, start = -1, i, hi
        elif trend * (v[i] - v[ext]) > 0:
            ext = i
        elif trend * (v[ext] - v[i]) >= swing:
            turns.append(int(candidates[ext]))
            starts.append(int(candidates[start]))
            trend, start, ext = -trend, ext, i
    return turns, starts


def half_swings(keypoints: np.ndarray, swing: float, smooth_frames: int = 3) -> HalfSwings:
    """The half-swings of both hands on one window (module docstring): all of
    ``keypoints``, (T, 15, 3) m on the gesture15 joints, Z up.

    Args:
        keypoints: the window.
        swing: the zig-zag's hysteresis, shoulder widths.
        smooth_frames: width of the moving average on the sideways position, frames.

    Raises:
        SimenvError: a wrong shape, fewer than ``smooth_frames + 2`` frames, NaN or
            infinite values, or shoulders that coincide or stand one above the other.
    """
    k = _check(keypoints, smooth_frames + 2)
    shoulders = k[:, _J["left_shoulder"]] - k[:, _J["right_shoulder"]]
    size = float(np.median(np.linalg.norm(shoulders, axis=1)))
    axis = shoulders[:, :2].mean(axis=0)
    if size < 1e-3 or np.linalg.norm(axis) < 1e-3:
        raise SimenvError(f"the shoulders coincide or stand one above the other (shoulder "
                          f"width {size:.4f} m): no body frame", field="keypoints")
    u = axis / np.linalg.norm(axis)
    kernel = np.ones(smooth_frames) / smooth_frames
    # 'valid' smoothing drops (w - 1) // 2 frames at the start: indices shift by it.
    shift = (smooth_frames - 1) // 2
    rows = []
    for h, (shoulder, wrist) in enumerate(HANDS.values()):
        height = (k[:, wrist, 2] - k[:, shoulder, 2]) / size
        x = np.convolve((k[:, wrist, :2] - k[:, _J["neck"], :2]) @ u / size, kernel,
                        mode="valid")
        turns, starts = _turns(x, swing)
        for t, s in zip(turns, starts, strict=True):
            leg = height[s + shift:t + shift + 1]
            rows.append((h, t - s, abs(x[t] - x[s]), np.ptp(leg), leg.min()))
    cols = np.array(rows, dtype=np.float64).reshape(-1, 5).T
    return HalfSwings(cols[0].astype(int), cols[1], cols[2], cols[3], cols[4], size)


def read_window(keypoints: np.ndarray, rule: WaveRule = WaveRule()) -> WaveReading:
    """The rule on one window (module docstring): all of ``keypoints``, (T, 15, 3) m on the
    gesture15 joints, Z up, at ``rule.fps``; callers pass the last ``rule.window_frames``.

    Raises:
        SimenvError: as :func:`half_swings`.
    """
    legs = half_swings(keypoints, rule.swing, rule.smooth_frames)
    kept = rule.kept(legs)
    return WaveReading(bool(kept.max() >= rule.reversals), dict(zip(HANDS, kept.tolist(),
                                                                    strict=True)),
                       legs.body_size_m)


def stream_fires(clips: Sequence[GestureClip], rules: Sequence[WaveRule], *,
                 seed: int = 0) -> list[list[tuple[np.ndarray, np.ndarray]]]:
    """Each rule at every loop tick of every clip (module docstring: the ticks and phases
    of :func:`simenv.perception.protocol.stream_readings` with the same ``seed``). Rules
    sharing window, swing and smoothing share the half-swings, read once per tick.

    Args:
        clips: gesture15 clips at 25 fps (e.g. :func:`simenv.perception.protocol.avatar_clips`).
        rules: the detectors' parameters (``fps`` must be 25, the clips' rate).
        seed: seed of the ticks' phases.

    Returns:
        Per rule, per clip: (ticks_s (K,) s after the clip's first frame, fired (K,) bool).
    """
    if any(r.fps != 1.0 * TICK_FRAMES for r in rules):
        raise SimenvError(f"the loop's clips are at {TICK_FRAMES} fps; got rules at "
                          f"{sorted({r.fps for r in rules})} fps", field="fps")
    rng = np.random.default_rng(seed)
    phases = [int(rng.integers(0, TICK_FRAMES)) for _ in clips]
    groups: dict[tuple[int, float, int], list[int]] = {}
    for i, r in enumerate(rules):
        groups.setdefault((r.window_frames, r.swing, r.smooth_frames), []).append(i)
    out: list[list[tuple[np.ndarray, np.ndarray]]] = [[] for _ in rules]
    for clip, phase in zip(clips, phases, strict=True):
        p = clip.positions
        ends = tick_frames(len(p), phase)
        ticks_s = ends / TICK_FRAMES
        for (w, swing, smooth), members in groups.items():
            lead = np.concatenate([np.repeat(p[:1], w, axis=0), p])
            # A tick after the clip's end reads its last frames (stream_readings').
            legs = [half_swings(lead[min(int(e), len(p)):min(int(e), len(p)) + w], swing,
                                smooth) for e in ends]
            for i in members:
                fired = np.array([rules[i].kept(g).max() >= rules[i].reversals
                                  for g in legs])
                out[i].append((ticks_s, fired))
    return out


def rule_outcomes(clips: Sequence[GestureClip], fires: Sequence[tuple[np.ndarray, np.ndarray]],
                  greet: str = GREET_LABEL) -> dict[str, Any]:
    """What the room would do if it greeted at the rule's ticks: the counts of
    :func:`simenv.perception.protocol.loop_outcomes`.

    Args:
        clips: the clips (their labels and lengths).
        fires: :func:`stream_fires` of ``clips``.
        greet: the label that should be greeted.

    Returns:
        ``greet_clips`` / ``other_clips`` / ``idle_clips``: [greeted, clips];
        ``greeted_rate``, ``other_greet_rate``, ``idle_greet_rate``, ``false_greet_rate``
        (other + idle); ``decision_after_onset_s`` (median, p90 of the first firing tick
        over greeted waves, s after the clip's start); ``decided_before_end`` (share of
        greeted waves decided before the clip ended).
    """
    groups = {"greet_clips": [0, 0], "other_clips": [0, 0], "idle_clips": [0, 0]}
    delays, before_end = [], 0
    for clip, (ticks_s, fired) in zip(clips, fires, strict=True):
        group = outcome_group(clip.label, greet)
        groups[group][1] += 1
        if fired.any():
            groups[group][0] += 1
            if group == "greet_clips":
                t = float(ticks_s[np.argmax(fired)])
                delays.append(t)
                before_end += t < clip.num_frames / TICK_FRAMES
    return greeting_rates(groups, delays, before_end)


__all__ = ["HANDS", "HalfSwings", "WaveReading", "WaveRule", "half_swings", "read_window",
           "rule_outcomes", "stream_fires"]

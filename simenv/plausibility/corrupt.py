"""Seeded corruptions of real motion, to prove that the plausibility metrics
catch what they claim to catch.

Each generator is a pure function ``fn(motion, strength, *, seed=0, ...) ->
Motion``: it never modifies its input, returns a new :class:`Motion` with
the same number of frames and the same fps (:func:`time_warp` too: it
re-times the clip inside its own length), and appends one record to
``metadata["corruptions"]`` (a list, so corruptions can be chained)::

    {"corruption": "sink", "strength": 10.0, "unit": "cm", "seed": 0,
     "targets": ["ground_penetration"], "frames": [[120, 311]], ...}

``frames`` lists the affected frames as inclusive ``[start, end]`` runs (the
convention of :class:`~simenv.plausibility.timeline.MetricResult`
violations): the frames the corruption changes, except for
:func:`foot_slide`, which records the frames where the feet slide (the drift
reached is held afterwards). Generator-specific choices (bone, direction, offsets) are
recorded too. The same ``seed`` gives the same output; the seed chooses the
affected segment, the direction or the noise.

Strength has a unit per generator (cm, m/s, fraction, metres, speed-up
factor; see each docstring and :data:`STRENGTH_UNITS`). :data:`CORRUPTIONS`
maps each name to ``(function, target metric names, moderate strength)``:
the moderate strength is one every real CMU clip of the shared corpus should
fail its target metric at (``tests/test_corrupt.py`` checks it,
``benchmarks/detection_table.py`` maps the detection rate over strengths).

Positions are edited on the motion's own skeleton (all joints, not only the
canonical keypoints); source rotations are dropped since they no longer
match (:meth:`Motion.with_positions`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Literal, NamedTuple

import numpy as np

from simenv.body.foot_contact import foot_contacts
from simenv.core.errors import MotionError, SimenvError
from simenv.core.motion import Motion
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS

#: Fewest frames a corruption accepts: its segment, ramps and finite
#: differences need a few frames to be meaningful.
MIN_FRAMES = 10

#: Duration (s) of the raised-cosine ramps that blend a segment corruption in
#: and out, so that the seam itself is not a teleport.
RAMP_S = 0.2

#: Shortest hover (s) of :func:`float_` in raise mode. A lift lasting
#: ~0.5 s, ramps included, is close to a free-fall arc (a real 0.5 s jump
#: rises 30 cm), so it would be a jump, not floating.
HOVER_MIN_S = 1.0

#: Shortest source bone :func:`bone_stretch` stretches (metres): the bones
#: :func:`~simenv.plausibility.metrics.bone_length.bone_length` skips are shorter.
BONE_MIN_LENGTH_M = DEFAULT_THRESHOLDS.bone_min_length_m

#: Limb bones :func:`bone_stretch` chooses from, by the canonical keypoint at
#: their lower end: thighs, shins, upper arms and forearms.
STRETCH_BONES: tuple[str, ...] = (
    "left_knee", "left_ankle", "right_knee", "right_ankle",
    "left_elbow", "left_wrist", "right_elbow", "right_wrist",
)


# -- shared helpers ------------------------------------------------------------


def _check(name: str, motion: Motion, strength: float, low: float, high: float, unit: str,
           seed: int) -> float:
    """Validate the common arguments; returns ``strength`` as a float.

    ``strength`` must lie in ``(low, high]``.
    """
    if not isinstance(motion, Motion):
        raise MotionError(f"{name}: expected a simenv.Motion; got {type(motion).__name__}")
    motion.require_frames(MIN_FRAMES, f"corruption {name}")
    try:
        value = float(strength)
    except (TypeError, ValueError):
        raise SimenvError(f"{name}: strength must be a number in {unit}; got {strength!r}",
                          field="strength") from None
    if not (math.isfinite(value) and low < value <= high):
        raise SimenvError(
            f"{name}: strength {strength!r} out of range; expected {low:g} < strength <= "
            f"{high:g} ({unit})", field="strength",
        )
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise SimenvError(f"{name}: seed must be a non-negative integer; got {seed!r}",
                          field="seed")
    return value


def _segment(rng: np.random.Generator, num_frames: int, low: float, high: float
             ) -> tuple[int, int]:
    """Random ``[start, stop)`` covering a fraction in ``[low, high]`` of the clip."""
    length = max(3, round(rng.uniform(low, high) * num_frames))
    length = min(length, num_frames)
    start = int(rng.integers(0, num_frames - length + 1))
    return start, start + length


def _bump(num_frames: int, start: int, stop: int, ramp: int) -> np.ndarray:
    """(T,) weights: 0 outside ``[start, stop)``, 1 inside, with raised-cosine
    ramps of ``ramp`` frames at both ends of the segment (inside it)."""
    w = np.zeros(num_frames)
    length = stop - start
    ramp = max(0, min(ramp, (length - 1) // 2))
    w[start:stop] = 1.0
    if ramp:
        rise = 0.5 - 0.5 * np.cos(np.pi * np.arange(1, ramp + 1) / (ramp + 1))
        w[start : start + ramp] = rise
        w[stop - ramp : stop] = rise[::-1]
    return w


def _runs(mask: np.ndarray) -> list[list[int]]:
    """Inclusive ``[start, end]`` runs of True in a (T,) mask."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [[int(s), int(e) - 1] for s, e in zip(starts, stops, strict=True)]


def _ramp_frames(motion: Motion) -> int:
    return max(1, round(RAMP_S * motion.fps))


def _finish(motion: Motion, positions: np.ndarray, name: str, strength: float, seed: int,
            affected: np.ndarray, **extra: Any) -> Motion:
    """New motion with ``positions`` and the corruption record appended."""
    record = {
        "corruption": name,
        "strength": strength,
        "unit": STRENGTH_UNITS[name],
        "seed": int(seed),
        "targets": list(CORRUPTIONS[name].targets),
        "frames": _runs(np.asarray(affected, dtype=bool)),
        **extra,
    }
    meta = dict(motion.metadata)
    meta["corruptions"] = [*motion.metadata.get("corruptions", []), record]
    return motion.with_positions(positions.astype(np.float32), metadata=meta)


def _lowest(motion: Motion) -> np.ndarray:
    """(T,) height (m) of the lowest joint of each frame."""
    return motion.positions[..., 2].astype(np.float64).min(axis=1)


def _horizontal_direction(rng: np.random.Generator) -> np.ndarray:
    angle = rng.uniform(0.0, 2.0 * np.pi)
    return np.array([np.cos(angle), np.sin(angle), 0.0])


# -- generators ----------------------------------------------------------------


def foot_slide(motion: Motion, strength: float, *, seed: int = 0) -> Motion:
    """Drift the whole body horizontally while a foot is planted.

    On every frame where a foot is in contact (:func:`~simenv.body.foot_contact.
    foot_contacts` on the input: low and slow), the root and with it every
    joint advances by ``strength / fps`` metres in one seeded horizontal
    direction; the offset is held (not undone) while airborne. Planted feet
    therefore slide at ``strength`` m/s: the classic generated-motion skate.

    Args:
        strength: drift speed in **m/s**, ``0 < strength <= 10``. Moderate:
            1.0 (twice the GMD skating speed of 0.5 m/s).
        seed: chooses the drift direction.

    Targets ``foot_skate``. Raises :class:`MotionError` when the clip has no
    planted foot (nothing to slide).
    """
    name = "foot_slide"
    value = _check(name, motion, strength, 0.0, 10.0, "m/s", seed)
    _, contacts = foot_contacts(motion)
    planted = contacts.any(axis=1) if contacts.size else np.zeros(motion.num_frames, bool)
    if not planted.any():
        raise MotionError(
            f"{name}: motion {motion.name!r} has no frame with a planted foot (needs toe or "
            "ankle keypoints low and slow); expected a clip with foot contact",
            source=motion.metadata.get("source"),
        )
    rng = np.random.default_rng(seed)
    direction = _horizontal_direction(rng)
    # The step at frame t moves the body from t-1 to t, so frame 0 stays put.
    steps = np.concatenate([[0.0], planted[1:].astype(np.float64)]) * value / motion.fps
    offset = np.cumsum(steps)[:, None] * direction  # (T, 3)
    pos = motion.positions.astype(np.float64) + offset[:, None, :]
    return _finish(motion, pos, name, value, seed, planted,
                   direction=direction[:2].tolist())


def bone_stretch(motion: Motion, strength: float, *, seed: int = 0,
                 bone: str | None = None) -> Motion:
    """Lengthen one limb bone of the source skeleton over part of the clip.

    The bone is the source bone (``motion.skeleton.parents``) that ends at the
    joint of canonical keypoint ``bone``: the thigh ``LeftUpLeg->LeftLeg`` of
    a CMU BVH for ``"left_knee"``, ``left_hip->left_knee`` of SMPL. When that
    bone is shorter than ``bone_min_length_m`` (a converter's collapsed joint
    at the child end) the one above it is taken. It grows by ``strength`` of
    its length, ``L' = (1 + strength) L``, by translating its child joint and
    everything below it along the bone, so it is one of the bones
    :func:`~simenv.plausibility.metrics.bone_length.bone_length` measures and every
    other bone keeps its length. The stretch ramps in and out
    (:data:`RAMP_S`) over a seeded segment covering 25-40 % of the clip, so
    that the stretch itself is smooth (no teleport).

    Args:
        strength: relative lengthening as a **fraction**,
            ``0 < strength <= 1``. Moderate: 0.10 (twice the 5 % tolerance).
        seed: chooses the segment and, unless ``bone`` is given, the bone
            among :data:`STRETCH_BONES`.
        bone: canonical keypoint at the bone's lower end (``"left_knee"`` is
            the thigh).

    The record names the bone (``bone``, canonical), its canonical ``parent``
    and ``source_bone`` (``"parent->child"`` in the source's joint names).
    Targets ``bone_length``. Raises :class:`MotionError` when the skeleton
    lacks the bone.
    """
    name = "bone_stretch"
    value = _check(name, motion, strength, 0.0, 1.0, "fraction", seed)
    canon = motion.to_canonical().skeleton
    skel = motion.skeleton
    available = [b for b in STRETCH_BONES
                 if b in canon.joint_names and canon.parents[canon.index(b)] >= 0
                 and skel.parents[skel.index(skel.canonical[b])] >= 0]
    rng = np.random.default_rng(seed)
    if bone is None:
        if not available:
            raise MotionError(
                f"{name}: skeleton {motion.skeleton.name!r} has none of the limb bones "
                f"{', '.join(STRETCH_BONES)}", source=motion.metadata.get("source"),
            )
        bone = available[int(rng.integers(len(available)))]
    elif bone not in available:
        raise MotionError(
            f"{name}: bone {bone!r} not available; expected one of {', '.join(available)}",
            field="bone",
        )
    parent_name = canon.joint_names[canon.parents[canon.index(bone)]]
    pos = motion.positions.astype(np.float64)
    child = skel.index(skel.canonical[bone])
    parent = skel.parents[child]
    while skel.parents[parent] >= 0 and not np.median(
            np.linalg.norm(pos[:, child] - pos[:, parent], axis=-1)) >= BONE_MIN_LENGTH_M:
        child, parent = parent, skel.parents[parent]
    subtree = np.zeros(skel.num_joints, dtype=bool)
    subtree[child] = True
    for j in range(child + 1, skel.num_joints):  # parents precede children
        subtree[j] = skel.parents[j] >= 0 and subtree[skel.parents[j]]
    start, stop = _segment(rng, motion.num_frames, 0.25, 0.40)
    w = _bump(motion.num_frames, start, stop, _ramp_frames(motion))
    shift = (value * w)[:, None] * (pos[:, child] - pos[:, parent])  # (T, 3)
    pos[:, subtree] += shift[:, None, :]
    return _finish(motion, pos, name, value, seed, w > 0, bone=bone, parent=parent_name,
                   source_bone=f"{skel.joint_names[parent]}->{skel.joint_names[child]}")


def sink(motion: Motion, strength: float, *, seed: int = 0) -> Motion:
    """Lower the whole body into the floor over part of the clip.

    Every joint goes down by ``strength`` cm over a seeded segment covering
    30-60 % of the clip, ramped in and out (:data:`RAMP_S`).

    Args:
        strength: depth in **cm**, ``0 < strength <= 100``. Moderate: 10.
            The keypoint-level metric sees the *joint centres*: CMU toe
            keypoints stand 1-7 cm above the floor, and the metric allows
            3 cm, so sinks under ~10 cm are not visible at keypoint level on
            every subject (the body-level metric on geoms is finer).
        seed: chooses the segment.

    Targets ``ground_penetration``.
    """
    name = "sink"
    value = _check(name, motion, strength, 0.0, 100.0, "cm", seed)
    rng = np.random.default_rng(seed)
    start, stop = _segment(rng, motion.num_frames, 0.30, 0.60)
    w = _bump(motion.num_frames, start, stop, _ramp_frames(motion))
    pos = motion.positions.astype(np.float64)
    pos[..., 2] -= (value / 100.0 * w)[:, None]
    return _finish(motion, pos, name, value, seed, w > 0)


def float_(motion: Motion, strength: float, *, seed: int = 0,
           mode: Literal["raise", "freeze"] = "raise") -> Motion:
    """Make the body hover: raise it, or freeze the fall of a jump.

    ``mode="raise"``: every joint goes up by ``strength`` cm over a seeded
    segment covering 30-50 % of the clip but at least :data:`HOVER_MIN_S`
    (the whole clip if shorter), ramped in and out (:data:`RAMP_S`); the legs
    keep walking in the air.

    ``mode="freeze"``: from the apex of the clip's highest moment (the frame
    whose lowest joint is highest: the top of the highest jump), the body's
    lowest joint is held at ``max(apex height, strength cm)`` for a seeded
    0.4-0.8 s instead of falling, then released over :data:`RAMP_S`.

    Args:
        strength: height in **cm**, ``0 < strength <= 100`` (raise: lift;
            freeze: least hover height of the lowest joint). Moderate: 15
            (the airborne test starts at 10 cm).
        seed: chooses the segment (raise) or the hover duration (freeze).
        mode: ``"raise"`` or ``"freeze"``.

    Targets ``floating``.
    """
    name = "float"
    value = _check(name, motion, strength, 0.0, 100.0, "cm", seed)
    rng = np.random.default_rng(seed)
    num = motion.num_frames
    pos = motion.positions.astype(np.float64)
    if mode == "raise":
        # At least HOVER_MIN_S: a short lift with its ramps is a jump-like arc.
        floor_share = min(1.0, HOVER_MIN_S * motion.fps / num)
        start, stop = _segment(rng, num, max(0.30, floor_share), max(0.50, floor_share))
        lift = value / 100.0 * _bump(num, start, stop, _ramp_frames(motion))
        extra: dict[str, Any] = {"mode": mode}
    elif mode == "freeze":
        hold = max(3, round(rng.uniform(0.4, 0.8) * motion.fps))
        hold = min(hold, num - 1)
        lowest = _lowest(motion)
        apex = int(np.argmax(lowest[: num - hold]))
        level = max(float(lowest[apex]), value / 100.0)
        ramp = _ramp_frames(motion)
        lift = np.zeros(num)
        lift[apex : apex + hold] = np.maximum(level - lowest[apex : apex + hold], 0.0)
        # Release: blend the held offset of the last hover frame back to 0.
        release = np.arange(apex + hold, min(num, apex + hold + ramp))
        if release.size:
            fade = 0.5 + 0.5 * np.cos(np.pi * np.arange(1, release.size + 1) / (ramp + 1))
            lift[release] = lift[apex + hold - 1] * fade
        extra = {"mode": mode, "apex_frame": apex, "hover_height_m": level}
    else:
        raise SimenvError(f"{name}: mode {mode!r} unknown; expected 'raise' or 'freeze'",
                          field="mode")
    pos[..., 2] += lift[:, None]
    return _finish(motion, pos, name, value, seed, lift > 0, **extra)


def jitter(motion: Motion, strength: float, *, seed: int = 0) -> Motion:
    """Add high-frequency noise: i.i.d. Gaussian offsets on every joint,
    axis and frame (white noise, the highest frequencies the frame rate
    carries), over the whole clip.

    Args:
        strength: noise standard deviation per coordinate in **cm**,
            ``0 < strength <= 10``. Moderate: 2.0. The jitter metric's
            normalized jerk divides by the path length in each window, so
            5 mm already fails walks and dances, but runs and leaps (long
            paths) need 1-2 cm.
        seed: seeds the noise.

    Targets ``jitter``.
    """
    name = "jitter"
    value = _check(name, motion, strength, 0.0, 10.0, "cm", seed)
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, value / 100.0, size=motion.positions.shape)
    pos = motion.positions.astype(np.float64) + noise
    return _finish(motion, pos, name, value, seed, np.ones(motion.num_frames, bool))


def teleport(motion: Motion, strength: float, *, seed: int = 0) -> Motion:
    """Jump the whole body away for a few frames and back.

    A seeded run of 1-4 frames is displaced by ``strength`` metres in a
    seeded horizontal direction (what a tracking swap or a bad generated
    frame looks like).

    Args:
        strength: jump distance in **metres**, ``0 < strength <= 10``.
            Moderate: 0.3 (at 120 fps: 36 m/s and twice the 0.15 m teleport
            distance; at 30 fps a jump must exceed ~0.33 m).
        seed: chooses the frames and the direction.

    Targets ``velocity``.
    """
    name = "teleport"
    value = _check(name, motion, strength, 0.0, 10.0, "m", seed)
    rng = np.random.default_rng(seed)
    length = int(rng.integers(1, 5))
    start = int(rng.integers(1, motion.num_frames - length))  # never the first/last frame
    direction = _horizontal_direction(rng)
    affected = np.zeros(motion.num_frames, dtype=bool)
    affected[start : start + length] = True
    pos = motion.positions.astype(np.float64)
    pos[affected] += value * direction
    return _finish(motion, pos, name, value, seed, affected, direction=direction[:2].tolist())


def time_warp(motion: Motion, strength: float, *, seed: int = 0) -> Motion:
    """Non-uniform re-timing: one segment plays ``strength`` times faster.

    The playback rate ``r(t) = ds/dt`` (source seconds per output second)
    rises smoothly from ``c`` to ``strength`` over half of :data:`RAMP_S`,
    holds, and falls back. The fast part consumes a seeded 30-50 % of the
    source clip, centred on a frame drawn in proportion to the body's mean
    joint speed (a sped-up still stand is no corruption); the rest plays at
    the constant rate ``c < 1`` that keeps the clip's first and last frames
    and its length, so frame count and fps are unchanged. Positions are
    linearly interpolated at the source times. Speeds in the fast part
    scale by ``strength``, accelerations by its square: beyond a factor of a
    few, no human could move that way. The slowed rest also turns jumps
    into slow-motion (non-ballistic) flights.

    Args:
        strength: peak speed-up **factor** (x), ``1 < strength <= 20``.
            Moderate: 10. Speeds only exceed the human limits of
            ``velocity`` when the clip was fast already: real CMU clips peak
            at 0.17 (walks) to 0.6 (dance) of the limits, so a 2x segment is
            a plausible faster performance, and slow clips (bending, slow
            dances) stay under the limits even at 10x; their accelerations
            (x strength^2) are left to the dynamics metrics.
        seed: chooses where the fast segment lies and how much it covers.

    Targets ``velocity``. Records the rates (``fast_rate``, ``slow_rate``).
    """
    name = "time_warp"
    value = _check(name, motion, strength, 1.0, 20.0, "x (speed-up factor)", seed)
    rng = np.random.default_rng(seed)
    num, fps = motion.num_frames, motion.fps
    duration = (num - 1) / fps
    share = rng.uniform(0.30, 0.50)  # fraction of the source played fast
    # The two raised-cosine ramps of r frames weigh r frames together, so a
    # segment of core + r frames weighs ``core`` frames of fast playback.
    core = max(2, round(share * (num - 1) / value))
    ramp = min(round(0.5 * RAMP_S * fps), core // 2)
    length = min(num - 2, core + ramp)

    def slow_rate(start: int) -> tuple[np.ndarray, float]:
        # c such that the integral of r = c + (k - c) w is the clip's
        # duration D: c = (D - k W) / (D - W), W the integral of w.
        w = _bump(num, start, start + length, ramp)
        weight = float(np.sum(w[1:] + w[:-1]) / (2.0 * fps))
        return w, (duration - value * weight) / (duration - weight)

    _, slow = slow_rate(0)
    if not slow > 0.05:
        raise MotionError(
            f"{name}: motion {motion.name!r} ({num} frames) is too short for a {value:g}x "
            "segment; expected a longer clip or a smaller strength",
            source=motion.metadata.get("source"),
        )
    # Speeding up stillness changes nothing, so the fast source span is
    # centred on a frame drawn in proportion to the body's speed there.
    pos = motion.positions.astype(np.float64)
    speed = np.linalg.norm(np.diff(pos, axis=0), axis=-1).mean(axis=1) + 1e-9
    centre = rng.choice(num - 1, p=speed / speed.sum())
    span = share * (num - 1)
    first = float(np.clip(centre - span / 2.0, 0.0, num - 1 - span))
    # Before the segment the clip plays at the slow rate c: output frame
    # first / c shows source frame ``first``.
    w, slow = slow_rate(int(np.clip(round(first / slow), 0, num - length)))
    rate = slow + (value - slow) * w
    source_t = np.concatenate([[0.0], np.cumsum((rate[1:] + rate[:-1]) / (2.0 * fps))])
    source_t = np.clip(source_t, 0.0, duration)
    f = source_t * fps
    i = np.clip(np.floor(f).astype(int), 0, num - 2)
    a = (f - i)[:, None, None]
    pos = (1.0 - a) * pos[i] + a * pos[i + 1]
    return _finish(motion, pos, name, value, seed, np.abs(rate - 1.0) > 1e-9,
                   fast_rate=value, slow_rate=float(slow),
                   fast_frames=_runs(w > 0))


# -- registry ------------------------------------------------------------------


class Corruption(NamedTuple):
    """A registered corruption: generator, metrics it targets, moderate strength."""

    fn: Callable[..., Motion]
    targets: tuple[str, ...]
    moderate: float


#: name -> (function, target metric names, moderate strength).
CORRUPTIONS: dict[str, Corruption] = {
    "foot_slide": Corruption(foot_slide, ("foot_skate",), 1.0),
    "bone_stretch": Corruption(bone_stretch, ("bone_length",), 0.10),
    "sink": Corruption(sink, ("ground_penetration",), 10.0),
    "float": Corruption(float_, ("floating",), 15.0),
    "jitter": Corruption(jitter, ("jitter",), 2.0),
    "teleport": Corruption(teleport, ("velocity",), 0.3),
    "time_warp": Corruption(time_warp, ("velocity",), 10.0),
}

#: name -> unit of ``strength``.
STRENGTH_UNITS: dict[str, str] = {
    "foot_slide": "m/s",
    "bone_stretch": "fraction",
    "sink": "cm",
    "float": "cm",
    "jitter": "cm",
    "teleport": "m",
    "time_warp": "x",
}

__all__ = [
    "CORRUPTIONS",
    "HOVER_MIN_S",
    "MIN_FRAMES",
    "RAMP_S",
    "STRENGTH_UNITS",
    "STRETCH_BONES",
    "Corruption",
    "bone_stretch",
    "float_",
    "foot_slide",
    "jitter",
    "sink",
    "teleport",
    "time_warp",
]

"""Core data model: :class:`Motion` and :class:`Interaction` (joint layouts are
:class:`simenv.core.skeletons.Skeleton`).

Conventions (see DESIGN.md): positions in metres, world frame Z-up, time in
seconds. A Motion never silently changes length or frame rate; resampling,
slicing and concatenation are explicit methods that return new objects.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from simenv.core.errors import MotionError, SkeletonError, UnitsError
from simenv.core.skeletons import Skeleton, canonical_skeleton

#: Plausible range of a person's per-frame extent (largest bounding-box side),
#: metres. Anything outside almost always means wrong units (mm, cm, inches,
#: CMU units) or normalised coordinates, so it is an error, not a repair.
MIN_PERSON_EXTENT_M = 0.1
MAX_PERSON_EXTENT_M = 3.5


def resample_weights(num_frames: int, fps: float, new_fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Linear-interpolation weights of :meth:`Motion.resample`.

    New frame ``k`` (at time ``k / new_fps``, up to the last original time)
    is ``(1 - w[k]) * p[i[k]] + w[k] * p[i[k] + 1]`` of the original frames.

    Args:
        num_frames: original frame count, at least 2.
        fps: original frame rate. new_fps: target frame rate.

    Returns:
        i: (N,) int64 indices in ``[0, num_frames - 2]``; w: (N,) float32.
    """
    n = int(np.floor((num_frames - 1) / fps * new_fps + 1e-9)) + 1
    t_new = np.arange(n) / new_fps
    t_old = np.arange(num_frames, dtype=np.float64) / fps
    i = np.clip(np.searchsorted(t_old, t_new, side="right") - 1, 0, num_frames - 2)
    return i, ((t_new - t_old[i]) * fps).astype(np.float32)


def resample_linear(x: np.ndarray, n: int) -> np.ndarray:
    """``(T, ...)`` -> ``(n, ...)`` by linear interpolation over normalised time (first and
    last frames kept; a single frame is repeated)."""
    if len(x) == 1:
        return np.repeat(x, n, axis=0)
    s = np.linspace(0.0, len(x) - 1, n)
    i0 = np.minimum(np.floor(s).astype(int), len(x) - 2)
    a = (s - i0).reshape(-1, *([1] * (x.ndim - 1)))
    return (1 - a) * x[i0] + a * x[i0 + 1]


@dataclass(frozen=True, eq=False)
class Motion:
    """One person's skeleton motion.

    Attributes:
        positions: (T, J, 3) float32, metres, world frame Z-up. T >= 1.
        fps: frames per second (> 0).
        skeleton: joint layout; ``skeleton.num_joints == J``.
        name: human-readable clip name (file stem by default).
        metadata: free-form provenance, e.g. ``source`` (file), ``subject``,
            ``units`` (what the file used), ``repairs`` (list of logged fixes),
            ``quirks`` (list of notes about the source).
        rotations: optional (T, J, 4) float32 unit quaternions (w, x, y, z),
            each joint's rotation relative to its parent, when the source has
            them (BVH, AMC). Not used by retargeting.
    """

    positions: np.ndarray
    fps: float
    skeleton: Skeleton
    name: str = "motion"
    metadata: dict[str, Any] = field(default_factory=dict)
    rotations: np.ndarray | None = None

    def __post_init__(self) -> None:
        source = self.metadata.get("source")
        pos = np.asarray(self.positions)
        if pos.ndim != 3 or pos.shape[-1] != 3:
            raise MotionError(
                f"positions must have shape (T, J, 3); got {pos.shape}", source=source
            )
        if pos.shape[0] == 0:
            raise MotionError("motion has no frames; expected at least 1", source=source)
        if pos.shape[1] != self.skeleton.num_joints:
            raise MotionError(
                f"positions have {pos.shape[1]} joints but skeleton {self.skeleton.name!r} "
                f"has {self.skeleton.num_joints}",
                source=source,
            )
        if not np.issubdtype(pos.dtype, np.number):
            raise MotionError(f"positions must be numeric; got dtype {pos.dtype}", source=source)
        pos = pos.astype(np.float32, copy=False)
        bad = ~np.isfinite(pos)
        if bad.any():
            t, j, _ = np.argwhere(bad)[0]
            raise MotionError(
                f"non-finite position ({pos[t, j].tolist()}) in {int(bad.any(axis=(1, 2)).sum())} "
                "frame(s); expected finite metres (repair gaps explicitly, e.g. "
                "simenv.core.motion.interpolate_gaps)",
                source=source,
                frame=int(t),
                field=self.skeleton.joint_names[j],
            )
        fps = float(self.fps)
        if not np.isfinite(fps) or fps <= 0:
            raise MotionError(f"fps must be a positive number; got {self.fps!r}", source=source)
        extent = float(np.median(np.ptp(pos, axis=1).max(axis=1)))
        if pos.shape[1] > 1 and not MIN_PERSON_EXTENT_M <= extent <= MAX_PERSON_EXTENT_M:
            raise UnitsError(
                f"median person extent is {extent:.4g} m; expected "
                f"{MIN_PERSON_EXTENT_M}-{MAX_PERSON_EXTENT_M} m. The data is probably not in "
                "metres (mm, cm, inches or CMU units?): convert it when reading",
                source=source,
            )
        if self.rotations is not None:
            rot = np.asarray(self.rotations, dtype=np.float32)
            if rot.shape != (pos.shape[0], pos.shape[1], 4):
                raise MotionError(
                    f"rotations must have shape (T, J, 4) = {(pos.shape[0], pos.shape[1], 4)}; "
                    f"got {rot.shape}",
                    source=source,
                )
            object.__setattr__(self, "rotations", rot)
        pos.setflags(write=False)
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "fps", fps)

    # -- basic properties -------------------------------------------------

    @property
    def num_frames(self) -> int:
        return int(self.positions.shape[0])

    @property
    def num_joints(self) -> int:
        return int(self.positions.shape[1])

    @property
    def duration(self) -> float:
        """Seconds between the first and the last frame."""
        return (self.num_frames - 1) / self.fps

    @property
    def times(self) -> np.ndarray:
        """(T,) float64 seconds of each frame, starting at 0."""
        return np.arange(self.num_frames, dtype=np.float64) / self.fps

    def __len__(self) -> int:
        return self.num_frames

    def __repr__(self) -> str:
        return (
            f"Motion(name={self.name!r}, frames={self.num_frames}, joints={self.num_joints}, "
            f"fps={self.fps:g}, skeleton={self.skeleton.name!r})"
        )

    def joint(self, name: str) -> np.ndarray:
        """(T, 3) positions of joint ``name``, metres."""
        return self.positions[:, self.skeleton.index(name)]

    def require_frames(self, n: int, purpose: str) -> None:
        """Raise :class:`MotionError` unless the clip has at least ``n`` frames."""
        if self.num_frames < n:
            raise MotionError(
                f"{purpose} needs at least {n} frames; motion {self.name!r} has "
                f"{self.num_frames}",
                source=self.metadata.get("source"),
            )

    def height(self) -> float:
        """Robust standing-height estimate, metres: the 95th percentile over
        frames of (highest joint - lowest joint) along Z."""
        span = self.positions[..., 2].max(axis=1) - self.positions[..., 2].min(axis=1)
        return float(np.percentile(span, 95))

    # -- explicit transformations -----------------------------------------

    def with_positions(self, positions: np.ndarray, **changes: Any) -> Motion:
        """Copy with new positions (same skeleton); rotations are dropped
        because they would no longer match."""
        return replace(self, positions=positions, rotations=None, **changes)

    def slice(self, start: int, stop: int | None = None) -> Motion:
        """Frames ``[start, stop)``. Raises if the range is empty."""
        stop = self.num_frames if stop is None else stop
        idx = range(self.num_frames)[start:stop]
        if len(idx) == 0:
            raise MotionError(
                f"slice [{start}:{stop}] of motion {self.name!r} ({self.num_frames} frames) "
                "is empty",
                source=self.metadata.get("source"),
            )
        sl = slice(idx.start, idx.stop)
        rot = None if self.rotations is None else self.rotations[sl]
        return replace(self, positions=self.positions[sl], rotations=rot)

    def resample(self, fps: float) -> Motion:
        """Linear interpolation of positions to ``fps``, keeping the same time
        span (the last frame is at or before the original last time).
        Rotations are dropped (positions are the ground truth)."""
        if not np.isfinite(fps) or fps <= 0:
            raise MotionError(f"target fps must be positive; got {fps!r}")
        self.require_frames(2, "resampling")
        i, w = resample_weights(self.num_frames, self.fps, fps)
        w = w[:, None, None]
        pos = (1 - w) * self.positions[i] + w * self.positions[i + 1]
        meta = dict(self.metadata)
        meta["resampled_from_fps"] = self.fps
        return replace(self, positions=pos, fps=float(fps), rotations=None, metadata=meta)

    @staticmethod
    def concatenate(motions: Iterable[Motion], name: str | None = None) -> Motion:
        """Join clips end to end. All must share skeleton and fps."""
        motions = list(motions)
        if not motions:
            raise MotionError("nothing to concatenate")
        first = motions[0]
        for m in motions[1:]:
            if m.skeleton != first.skeleton:
                raise MotionError(
                    f"cannot concatenate {m.name!r} (skeleton {m.skeleton.name!r}) with "
                    f"{first.name!r} (skeleton {first.skeleton.name!r})"
                )
            if m.fps != first.fps:
                raise MotionError(
                    f"cannot concatenate {m.name!r} at {m.fps:g} fps with {first.name!r} at "
                    f"{first.fps:g} fps; resample explicitly first"
                )
        rot = None
        if all(m.rotations is not None for m in motions):
            rot = np.concatenate([m.rotations for m in motions])
        return replace(
            first,
            positions=np.concatenate([m.positions for m in motions]),
            rotations=rot,
            name=name or first.name,
        )

    def on_layout(self, layout: Skeleton, purpose: str) -> Motion:
        """Motion on ``layout``, a skeleton whose joints are canonical keypoint names
        (same frames, fps and metadata).

        Args:
            purpose: what needs the layout, for the error (e.g. "the 17-joint
                prediction layout").

        Raises:
            SkeletonError: this skeleton lacks some of the keypoints (all named).
        """
        canonical = self.skeleton.canonical
        missing = [k for k in layout.joint_names if k not in canonical]
        if missing:
            raise self.missing_keypoints(missing, layout.joint_names, purpose)
        idx = [self.skeleton.index(canonical[k]) for k in layout.joint_names]
        return Motion(self.positions[:, idx], self.fps, layout, self.name, dict(self.metadata))

    def missing_keypoints(self, missing: Sequence[str], needed: Sequence[str], purpose: str,
                          note: str = "") -> SkeletonError:
        """The error for canonical keypoints ``missing`` from this motion's skeleton that
        ``purpose`` needs (it needs all of ``needed``); ``note`` follows the missing names."""
        return SkeletonError(
            f"skeleton {self.skeleton.name!r} of motion {self.name!r} lacks canonical "
            f"keypoint(s) {', '.join(missing)}{note}; {purpose} needs {', '.join(needed)}",
            source=self.metadata.get("source"),
        )

    def to_canonical(self) -> Motion:
        """Motion on the canonical keypoint skeleton (only the keypoints this
        skeleton provides; see :func:`simenv.core.skeletons.canonical_skeleton`)."""
        keys = [k for k in canonical_skeleton().joint_names if k in self.skeleton.canonical]
        if not keys:
            raise MotionError(
                f"skeleton {self.skeleton.name!r} maps no canonical keypoints",
                source=self.metadata.get("source"),
            )
        skel = canonical_skeleton().subset(keys, name="canonical")
        idx = [self.skeleton.index(self.skeleton.canonical[k]) for k in skel.joint_names]
        return Motion(
            self.positions[:, idx], self.fps, skel, self.name, dict(self.metadata)
        )


@dataclass(frozen=True, eq=False)
class Interaction:
    """Two people recorded together, on one clock and in one world frame.

    Attributes:
        actor: person A (the one who acts, when roles are known).
        reactor: person B.
        label: interaction class (e.g. ``"shake_hands"``), if known.
        roles_known: whether actor/reactor roles come from the source; when
            False they are just first/second person.
        name: clip name.
        metadata: provenance and quirks.
    """

    actor: Motion
    reactor: Motion
    label: str | None = None
    roles_known: bool = False
    name: str = "interaction"
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        a, b = self.actor, self.reactor
        if a.fps != b.fps:
            raise MotionError(
                f"interaction {self.name!r}: actor at {a.fps:g} fps, reactor at {b.fps:g} fps; "
                "resample one explicitly"
            )
        if a.num_frames != b.num_frames:
            raise MotionError(
                f"interaction {self.name!r}: actor has {a.num_frames} frames, reactor "
                f"{b.num_frames}; align them explicitly (slice)"
            )

    @property
    def people(self) -> tuple[Motion, Motion]:
        return (self.actor, self.reactor)

    @property
    def fps(self) -> float:
        return self.actor.fps

    @property
    def num_frames(self) -> int:
        return self.actor.num_frames

    def slice(self, start: int, stop: int | None = None) -> Interaction:
        return replace(self, actor=self.actor.slice(start, stop),
                       reactor=self.reactor.slice(start, stop))

    def resample(self, fps: float) -> Interaction:
        return replace(self, actor=self.actor.resample(fps), reactor=self.reactor.resample(fps))


def interpolate_gaps(
    positions: np.ndarray, valid: np.ndarray, *, max_gap: int | None = None
) -> tuple[np.ndarray, list[str]]:
    """Fill invalid frames by linear interpolation between valid neighbours
    (held constant before the first / after the last valid frame).

    Args:
        positions: (T, J, 3) array; values at invalid frames are ignored.
        valid: (T,) bool, True where the frame holds a real measurement.
        max_gap: if given, a run of more than ``max_gap`` invalid frames
            raises :class:`MotionError` instead of being filled.

    Returns:
        (filled positions as float32, list of human-readable repair notes).
    """
    positions = np.array(positions, dtype=np.float32)
    valid = np.asarray(valid, dtype=bool)
    if positions.shape[0] != valid.shape[0]:
        raise MotionError(f"valid mask has {valid.shape[0]} frames, positions {positions.shape[0]}")
    if not valid.any():
        raise MotionError("no valid frame to interpolate from")
    notes: list[str] = []
    bad = np.flatnonzero(~valid)
    if bad.size == 0:
        return positions, notes
    runs = np.split(bad, np.flatnonzero(np.diff(bad) > 1) + 1)
    for run in runs:
        if max_gap is not None and len(run) > max_gap:
            raise MotionError(
                f"gap of {len(run)} invalid frames ({run[0]}-{run[-1]}) exceeds max_gap={max_gap}",
                frame=int(run[0]),
            )
        notes.append(f"interpolated frames {run[0]}-{run[-1]} ({len(run)} invalid)")
    t = np.arange(len(valid))
    good = np.flatnonzero(valid)
    flat = positions.reshape(len(valid), -1)
    for c in range(flat.shape[1]):
        flat[~valid, c] = np.interp(t[~valid], good, flat[good, c])
    return flat.reshape(positions.shape), notes

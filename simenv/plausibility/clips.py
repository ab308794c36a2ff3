"""Clips prepared once for the compiled joint-level metrics.

A :class:`ClipBatch` holds B clips of equal length and frame rate on one
canonical keypoint layout as keypoint-major float64 coordinate planes
(3, J, B, T) plus the lowest keypoint height per frame, built in one compiled
pass (:func:`simenv.plausibility.kernels.planes`), so every joint-level
metric is one kernel call over all B clips whose inner loops run along
contiguous frames. :func:`batches` groups any list of motions into such
batches (clips of other lengths or skeletons go to other batches), small
enough to stay in the CPU cache. :func:`results` turns the kernels' per-clip
arrays back into one :class:`~simenv.plausibility.timeline.MetricResult`
per clip.

Numerics are those of the per-clip formulas: each operation is the same
IEEE operation on the same numbers (e.g. a Euclidean norm is
``sqrt((x*x + y*y) + z*z)``, the summation order of ``np.linalg.norm``), and
every operation is independent per clip, so a clip scores exactly the same
alone or in any batch (see :mod:`simenv.plausibility.kernels` for the one
documented last-bits exception, and
``tests/test_plausibility_kinematic_golden.py``).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from functools import lru_cache

import numpy as np

from simenv.errors import MotionError
from simenv.motion import MIN_PERSON_EXTENT_M, Motion, Skeleton
from simenv.plausibility import kernels
from simenv.plausibility.timeline import MetricResult
from simenv.skeletons import canonical_skeleton

#: Frames per batch (clips x frames): keeps the (3, J, B, T) float64 planes
#: and their temporaries within a few MB of cache.
BATCH_FRAMES = 8192


@lru_cache(maxsize=256)
def _layout(key: tuple) -> tuple[Skeleton, tuple[int, ...]] | None:
    """Canonical skeleton and source joint indices of a skeleton, by
    :func:`_layout_key`; None when it maps no canonical keypoint."""
    _, joint_names, _, canonical = key
    mapping = dict(canonical)
    keys = [k for k in canonical_skeleton().joint_names if k in mapping]
    if not keys:
        return None
    skel = canonical_skeleton().subset(keys, name="canonical")
    return skel, tuple(joint_names.index(mapping[k]) for k in skel.joint_names)


def _layout_key(skeleton: Skeleton) -> tuple:
    # The canonical map is part of the key: Skeleton's hash ignores it.
    return (skeleton.name, skeleton.joint_names, skeleton.parents,
            tuple(sorted(skeleton.canonical.items())))


def norm3(v: np.ndarray) -> np.ndarray:
    """Euclidean norm over the last axis (length 3) with the summation order
    of ``np.linalg.norm`` (bit-identical, several times faster)."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.sqrt((x * x + y * y) + z * z)


class ClipBatch:
    """B clips of T frames at one frame rate on one canonical layout.

    Attributes:
        motions: the B source motions.
        num_frames: T. fps: frames per second.
        skeleton: the canonical skeleton (J keypoints), or None when the
            source skeleton maps no canonical keypoint.
        names: canonical keypoint names (J).
        reasons: per clip, why the canonical keypoints cannot be used (the
            message of :meth:`Motion.to_canonical`'s error), or None.
        p: (3, J, B, T) float64 canonical keypoint coordinates, metres
            (Z-up); x, y, z: its three (J, B, T) planes.
        zmin: (B, T) height of the lowest keypoint, metres.
    """

    def __init__(self, motions: Sequence[Motion]) -> None:
        first = motions[0]
        self.motions = list(motions)
        self.num_frames = first.num_frames
        self.fps = first.fps
        layout = _layout(_layout_key(first.skeleton))
        self.reasons: list[str | None] = [None] * len(motions)
        if layout is None:
            self.skeleton, self.names = None, ()
            self.reasons = [_canonical_reason(m) for m in motions]
            return
        self.skeleton, idx = layout
        self.names = self.skeleton.joint_names
        # One clip is passed as a view; several are stacked once (their
        # source joints, the canonical gather happens in the kernel).
        stack = (first.positions[None] if len(motions) == 1
                 else np.stack([m.positions for m in motions]))
        self.p, self.zmin, span = kernels.planes(stack, np.asarray(idx, dtype=np.int64))
        self.x, self.y, self.z = self.p
        self._check_extent(span)

    def _check_extent(self, span: np.ndarray) -> None:
        """:meth:`Motion.to_canonical` rejects a canonical subset whose median
        extent is below ``MIN_PERSON_EXTENT_M`` (the full skeleton's upper
        bound holds for any subset); test the cheap sufficient condition
        (every frame's height span, ``span`` (B,) metres at its smallest, is
        above it) and fall back to the exact check for the rare clips that
        fail it."""
        if len(self.names) < 2:
            return
        for b in np.flatnonzero(~(span > MIN_PERSON_EXTENT_M * 1.1)):
            self.reasons[b] = _canonical_reason(self.motions[b])

    @property
    def size(self) -> int:
        return len(self.motions)

    def indices(self, names: Sequence[str]) -> list[int]:
        """Indices of those of ``names`` that the layout has, in order."""
        return [self.names.index(n) for n in names if n in self.names]

    def not_available(self, name: str, unit: str, threshold: float, reason: str,
                      **kwargs: object) -> list[MetricResult]:
        """One not-available result per clip (a clip's own canonical-keypoint
        reason takes precedence)."""
        return [MetricResult.not_available(name, self.num_frames, unit, threshold, r or reason,
                                           **kwargs) for r in self.reasons]


def _canonical_reason(motion: Motion) -> str | None:
    try:
        motion.to_canonical()
    except MotionError as exc:
        return f"no canonical keypoints: {exc.detail}"
    return None


def batches(motions: Sequence[Motion], max_frames: int | None = None
            ) -> Iterator[tuple[list[int], ClipBatch]]:
    """Group ``motions`` into :class:`ClipBatch` es.

    Clips share a batch when they have the same skeleton (and canonical
    map), frame rate and length; a batch holds at most ``max_frames``
    frames in total (default :data:`BATCH_FRAMES`; at least one clip).

    Yields:
        (positions of the batch's clips in ``motions``, the batch).
    """
    max_frames = BATCH_FRAMES if max_frames is None else max_frames
    groups: dict[tuple, list[int]] = {}
    for i, m in enumerate(motions):
        groups.setdefault((_layout_key(m.skeleton), m.fps, m.num_frames), []).append(i)
    for (_, _, frames), members in groups.items():
        per = max(1, max_frames // frames)
        for start in range(0, len(members), per):
            chunk = members[start:start + per]
            yield chunk, ClipBatch([motions[i] for i in chunk])


def results(batch: ClipBatch, name: str, timeline: np.ndarray, value: np.ndarray, unit: str,
            threshold: float, *, frame_threshold: float | None = None,
            timeline_unit: str | None = None,
            details: Mapping[str, np.ndarray | float] | None = None,
            available: np.ndarray | None = None, reason: str = "") -> list[MetricResult]:
    """Per-clip results, as :meth:`MetricResult.from_timeline` builds them.

    Args:
        batch: the clips.
        timeline: (B, T) per-frame values. value: (B,) clip values.
        details: name -> (B,) per-clip or scalar values.
        available: (B,) bool, clips the metric could be computed on
            (default all); the others get ``reason``.
    """
    ft = threshold if frame_threshold is None else frame_threshold
    # The comparison happens in float32 exactly when numpy's ``tl > ft`` on
    # the float32 timeline would: a Python number is cast to float32.
    in_float32 = (not isinstance(ft, np.generic)
                  or bool(np.result_type(np.float32, ft) == np.float32))
    tl, runs, offsets = kernels.violations(
        np.asarray(timeline, dtype=np.float64), float(ft), in_float32)
    size = batch.size
    keys = list(details or {})
    # Python floats per detail at once (a scalar detail is the same for every
    # clip), then one row per clip: per-clip numpy calls would cost more than
    # the kernels on short clips.
    columns = []
    for v in (details or {}).values():
        col = np.asarray(v, dtype=np.float64)
        columns.append([float(col)] * size if col.ndim == 0 else col.tolist())
    rows = list(zip(*columns, strict=True)) if columns else [()] * size
    values = np.asarray(value, dtype=np.float64).tolist()
    spans = [(int(s), int(e), w) for s, e, w in runs.tolist()]
    bounds = offsets.tolist()
    unit_tl, thr, ft = timeline_unit or unit, float(threshold), float(ft)
    ok = [True] * size if available is None else np.asarray(available).tolist()
    out = []
    for b in range(size):
        r = batch.reasons[b] or (None if ok[b] else reason)
        if r is not None:
            out.append(MetricResult.not_available(name, batch.num_frames, unit, threshold, r,
                                                  frame_threshold=frame_threshold,
                                                  timeline_unit=timeline_unit))
            continue
        v = values[b]
        out.append(MetricResult(
            name=name, value=v, unit=unit, threshold=thr, passed=v <= threshold,
            timeline=tl[b], violations=spans[bounds[b]:bounds[b + 1]], frame_threshold=ft,
            timeline_unit=unit_tl, details=dict(zip(keys, rows[b], strict=True)),
        ))
    return out

"""Clips prepared once for the compiled joint-level metrics.

A :class:`ClipBatch` holds B clips of equal length and frame rate on one
canonical keypoint layout: their source joint positions (B, T, S, 3) and the
source joint of each canonical keypoint. :func:`run` runs any set of
joint-level metrics, each described by a :class:`MetricSpec`, on all B clips
in one compiled call (:func:`simenv.plausibility.kernels.score`), which reads
each clip's keypoints once for all metrics, and keeps the per-clip arrays in
a :class:`Scores`, which builds the
:class:`~simenv.plausibility.timeline.MetricResult` s of a clip or of a
metric when asked; :func:`score` builds them all. :func:`batches` groups any
list of motions into such batches (clips of other lengths or skeletons go to
other batches).

Numerics are those of the per-clip formulas: each operation is the same
IEEE operation on the same numbers (e.g. a Euclidean norm is
``sqrt((x*x + y*y) + z*z)``, the summation order of ``np.linalg.norm``), and
every operation is independent per clip, so a clip scores exactly the same
alone or in any batch (see :mod:`simenv.plausibility.kernels` for the one
documented last-bits exception, and
``tests/test_plausibility_kinematic_golden.py``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from functools import lru_cache
from operator import itemgetter
from typing import NamedTuple, TypeVar

import numpy as np
from numba import types
from numba.typed import List

from simenv.core.errors import MotionError
from simenv.core.motion import MIN_PERSON_EXTENT_M, Motion
from simenv.core.skeletons import Skeleton, canonical_skeleton
from simenv.plausibility import kernels
from simenv.plausibility.timeline import MetricResult

#: numba type of one clip of a several-clip batch (any strides: windows cut
#: from a longer clip are views).
_CLIP = types.Array(types.float32, 3, "A", readonly=True)
#: Frames per batch (clips x frames): bounds the result arrays of one call.
BATCH_FRAMES = 8192
#: Violation runs per clip that :func:`score` makes room for (more cost a
#: second kernel call).
_RUNS_PER_CLIP = 16
#: The thresholds a metric's spec reads (:class:`~simenv.plausibility.thresholds.Thresholds`).
Settings = TypeVar("Settings")


@lru_cache(maxsize=256)
def _layout(key: tuple) -> tuple[Skeleton, np.ndarray] | None:
    """Canonical skeleton and (J,) int64 source joint of each canonical
    keypoint (shared: never modified) of a skeleton, by :func:`_layout_key`;
    None when it maps no canonical keypoint."""
    _, joint_names, _, canonical = key
    mapping = dict(canonical)
    keys = [k for k in canonical_skeleton().joint_names if k in mapping]
    if not keys:
        return None
    skel = canonical_skeleton().subset(keys, name="canonical")
    idx = np.array([joint_names.index(mapping[k]) for k in skel.joint_names], dtype=np.int64)
    return skel, idx


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
            message of :meth:`Motion.to_canonical`'s error), or None; set
            for the extent check by :func:`score`.
        positions: the B clips' (T, S, 3) float32 read-only source joints,
            metres: a (1, T, S, 3) array for one clip, a typed list of
            arrays for several (None without a canonical layout).
        idx: (J,) int64 source joint of each canonical keypoint.
    """

    def __init__(self, motions: Sequence[Motion], layout_key: tuple | None = None) -> None:
        """``layout_key``: :func:`_layout_key` of the clips' skeleton when
        the caller has it (:func:`batches`), which spares hashing it again."""
        first = motions[0]
        self.motions = list(motions)
        self.num_frames = first.num_frames
        self.fps = first.fps
        layout = _layout(_layout_key(first.skeleton) if layout_key is None else layout_key)
        self.reasons: list[str | None] = [None] * len(motions)
        self.positions: np.ndarray | List | None = None
        if layout is None:
            self.skeleton, self.names, self.idx = None, (), np.zeros(0, dtype=np.int64)
            self.reasons = [_canonical_reason(m) for m in motions]
            return
        self.skeleton, self.idx = layout
        self.names = self.skeleton.joint_names
        # One clip is passed as a view, several as a typed list of their
        # arrays (a third of the time of stacking them; the canonical gather
        # happens in the kernel).
        if len(motions) == 1:
            self.positions = first.positions[None]
        else:
            self.positions = List.empty_list(_CLIP)
            for m in motions:
                self.positions.append(m.positions)

    def _check_extent(self, span: np.ndarray) -> None:
        """:meth:`Motion.to_canonical` rejects a canonical subset whose median
        extent is below ``MIN_PERSON_EXTENT_M`` (the full skeleton's upper
        bound holds for any subset); test the cheap sufficient condition
        (every frame's height span, ``span`` (B,) metres at its smallest, is
        above it) and fall back to the exact check for the rare clips that
        fail it."""
        if len(self.names) < 2:
            return
        limit = MIN_PERSON_EXTENT_M * 1.1
        for b, s in enumerate(span.tolist()):
            if not s > limit:
                self.reasons[b] = _canonical_reason(self.motions[b])

    @property
    def size(self) -> int:
        return len(self.motions)

    def indices(self, names: Sequence[str]) -> list[int]:
        """Indices of those of ``names`` that the layout has, in order."""
        return [self.names.index(n) for n in names if n in self.names]


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
    # Clips cut from one motion share its skeleton object: one layout key
    # each, numbered, so that grouping hashes a small tuple per clip instead
    # of the key's names and parents (3 us a clip, as much as its kernels on
    # a 2 s window).
    layouts: dict[tuple, int] = {}
    numbers: dict[int, int] = {}
    for i, m in enumerate(motions):
        number = numbers.get(id(m.skeleton))
        if number is None:
            number = numbers[id(m.skeleton)] = layouts.setdefault(
                _layout_key(m.skeleton), len(layouts))
        groups.setdefault((number, m.fps, m.num_frames), []).append(i)
    keys = list(layouts)
    for (number, _, frames), members in groups.items():
        per = max(1, max_frames // frames)
        for start in range(0, len(members), per):
            chunk = members[start:start + per]
            yield chunk, ClipBatch([motions[i] for i in chunk], keys[number])


@dataclass(frozen=True)
class MetricSpec:
    """One joint-level metric as :func:`score` runs it on a batch.

    Attributes:
        slot: the metric's kernel (:data:`simenv.plausibility.kernels.BONE`
            ... ``VELOCITY``).
        name, unit, threshold: as in the results.
        args: the kernel's arguments after its planes (see
            :func:`simenv.plausibility.kernels.score`), or None when the
            metric cannot be computed on the batch (then every clip gets
            ``reason``).
        details: the result's details in order: a name takes the kernel's
            next detail column (per clip), a (name, value) pair is the same
            for every clip.
        frame_threshold, timeline_unit: as in the results (default: the
            threshold and the unit).
        reason: why the metric is not available, for the whole batch
            (``args`` None) or for the clips the kernel marks unavailable.
    """

    slot: int
    name: str
    unit: str
    threshold: float
    args: tuple | None
    details: tuple[str | tuple[str, float], ...] = ()
    frame_threshold: float | None = None
    timeline_unit: str | None = None
    reason: str = ""

    def not_available(self, batch: ClipBatch) -> list[MetricResult]:
        """One not-available result per clip (a clip's own canonical-keypoint
        reason takes precedence)."""
        return [MetricResult.not_available(self.name, batch.num_frames, self.unit,
                                           self.threshold, r or self.reason,
                                           frame_threshold=self.frame_threshold,
                                           timeline_unit=self.timeline_unit)
                for r in batch.reasons]


class _Layout(NamedTuple):
    """What the results of one spec share: how its details are read (their
    ``keys`` in order, the ``constants`` appended to the kernel's detail
    columns, and ``pick``, which takes the keys' values from that
    (columns + constants) row) and ``template``, an available result's field
    dict in field order with the fields that are the same for every clip set
    (copying it and setting the five fields that differ costs about half of
    building the dict)."""

    keys: tuple[str, ...]
    constants: list[float]
    pick: Callable[[list[float]], tuple[float, ...]]
    template: dict


def _picker(order: list[int]) -> Callable[[list[float]], tuple[float, ...]]:
    """``row -> tuple(row[i] for i in order)``, in C for two or more
    indices (``itemgetter`` returns a bare item for one)."""
    if len(order) > 1:
        return itemgetter(*order)
    return lambda row: tuple(row[i] for i in order)


class Plan:
    """Metric specs prepared once for :func:`score`: which kernel slots run,
    their arguments, per-frame thresholds and comparison precision, and per
    spec the layout of its details (:class:`_Layout`).

    A plan depends only on the layout, frame rate, length and thresholds of
    a batch, so callers may keep one for every batch of that shape.
    """

    def __init__(self, specs: Sequence[MetricSpec]) -> None:
        self.specs = tuple(specs)
        self.enabled = np.zeros(kernels.N_METRICS, dtype=np.bool_)
        self.frame_thresholds = np.zeros(kernels.N_METRICS)
        self.in_float32 = np.zeros(kernels.N_METRICS, dtype=np.bool_)
        args = dict(kernels.IDLE_ARGS)
        self.layouts: list[_Layout] = []
        for s in self.specs:
            # A result's details are picked from its clip's row: the
            # kernel's detail columns, then the spec's constants.
            keys, constants, order = [], [], []
            for d in s.details:
                if isinstance(d, str):
                    order.append(len(order) - len(constants))
                    keys.append(d)
                else:
                    order.append(kernels.N_DETAILS + len(constants))
                    constants.append(float(d[1]))
                    keys.append(d[0])
            thr = float(s.threshold)
            ft = thr if s.frame_threshold is None else float(s.frame_threshold)
            template = {"name": s.name, "value": None, "unit": s.unit, "threshold": thr,
                        "passed": None, "timeline": None, "violations": None,
                        "frame_threshold": ft, "timeline_unit": s.timeline_unit or s.unit,
                        "details": None, "reason": None}
            self.layouts.append(_Layout(tuple(keys), constants, _picker(order), template))
            if s.args is None:
                continue
            self.enabled[s.slot] = True
            args[s.slot] = s.args
            ft = s.threshold if s.frame_threshold is None else s.frame_threshold
            self.frame_thresholds[s.slot] = ft
            # The comparison happens in float32 exactly when numpy's
            # ``tl > ft`` on the float32 timeline would: a Python number is
            # cast to float32.
            self.in_float32[s.slot] = (not isinstance(ft, np.generic)
                                       or bool(np.result_type(np.float32, ft) == np.float32))
        self.args = tuple(args[slot] for slot in range(kernels.N_METRICS))


#: Whether results may be built from their field dicts (as ``copy`` and
#: ``pickle`` do), which skips the frozen dataclass's per-field
#: ``object.__setattr__`` (about 3 us per result: more than the kernels
#: spend on a 2 s window); only while MetricResult has no ``__post_init__``
#: or slots.
_FROM_FIELDS = not hasattr(MetricResult, "__post_init__") and not hasattr(
    MetricResult, "__slots__")


class Scores:
    """The kernel's outputs for one batch and plan, turned into
    :class:`~simenv.plausibility.timeline.MetricResult` s on demand.

    The compiled call computes every metric of every clip (:func:`run`);
    building the Python result objects costs about 1.5 us each, more than
    the kernels spend on a short clip per metric, so they are built only
    for the clips and metrics asked for (:meth:`clip`, :meth:`metric`), from
    the arrays kept here. Each call builds new results; timelines are rows
    of the one (6, B, T) float32 array of the batch.
    """

    def __init__(self, batch: ClipBatch, plan: Plan, tl: np.ndarray, value: np.ndarray,
                 details: np.ndarray, available: np.ndarray, runs: np.ndarray,
                 offsets: np.ndarray) -> None:
        self.batch, self.plan = batch, plan
        self.tl, self.value = tl, value
        self._arrays = (details, available, runs, offsets)
        self._lists: tuple | None = None

    def _python(self) -> tuple:
        """Python numbers of the outputs, converted once, in one conversion
        per array (per-clip or per-metric numpy calls would cost more than
        the kernels on short clips): violation runs, their bounds, values,
        detail columns, and per spec why each clip has no result."""
        if self._lists is None:
            details, available, runs, offsets = self._arrays
            bounds = offsets.tolist()
            spans = [(int(s), int(e), w) for s, e, w in runs[:bounds[-1]].tolist()]
            ok = available.tolist()
            missing = []
            for s in self.plan.specs:
                # Per clip, why it has no result (None for most): its own
                # reason, or for bone_length no bone checked.
                reasons = self.batch.reasons
                if s.args is not None and s.slot == kernels.BONE and not all(ok):
                    reasons = [r or (None if a else s.reason)
                               for r, a in zip(reasons, ok, strict=True)]
                missing.append(reasons)
            self._lists = (spans, bounds, self.value.tolist(), details.tolist(), missing)
        return self._lists

    def values(self, i: int) -> np.ndarray:
        """(B,) float64 values of spec ``i`` of the plan, NaN for the clips
        without a result, without building results."""
        s = self.plan.specs[i]
        if s.args is None:
            return np.full(self.batch.size, np.nan)
        out = self.value[s.slot].copy()
        missing = np.array([r is not None for r in self.batch.reasons], dtype=np.bool_)
        if s.slot == kernels.BONE:
            missing |= ~self._arrays[1]
        out[missing] = np.nan
        return out

    def metric(self, i: int) -> list[MetricResult]:
        """The results of spec ``i`` of the plan, one per clip."""
        s, layout = self.plan.specs[i], self.plan.layouts[i]
        if s.args is None:
            return s.not_available(self.batch)
        spans, bounds, values, columns, missing = self._python()
        return _results(self.batch, s, layout, self.tl[s.slot], values[s.slot],
                        columns[s.slot], spans, bounds, missing[i])

    def clip(self, k: int) -> list[MetricResult]:
        """The results of clip ``k`` of the batch, one per spec."""
        spans, bounds, values, columns, missing = self._python()
        out = []
        n = self.batch.num_frames
        # The plan's sequences have equal lengths by construction (zip's
        # strict keyword costs about 1 us a call).
        for s, layout, reasons in zip(self.plan.specs, self.plan.layouts, missing):  # noqa: B905
            reason = reasons[k] if s.args is not None else reasons[k] or s.reason
            if reason is not None:
                out.append(MetricResult.not_available(
                    s.name, n, s.unit, s.threshold, reason,
                    frame_threshold=s.frame_threshold, timeline_unit=s.timeline_unit))
                continue
            m = s.slot
            b = k * kernels.N_METRICS + m
            out.append(_result(s, layout, values[m][k], columns[m][k], self.tl[m, k],
                               spans[bounds[b]:bounds[b + 1]]))
        return out


#: Plans by spec builders and batch shape (a plan depends on nothing else).
_PLANS: dict[tuple, Plan] = {}


def cached_plan(batch: ClipBatch, thresholds: Settings,
                specs: tuple[Callable[[ClipBatch, Settings], MetricSpec], ...]) -> Plan:
    """The plan of the metrics ``spec(batch, thresholds)`` of ``specs`` for batches of
    this layout, rate, length and thresholds, prepared once (the specs' lookups cost as
    much as the kernels on a short clip)."""
    # The source skeleton too: bone_length measures its bones, and skeletons
    # with other bones share a canonical layout.
    key = (specs, batch.skeleton, batch.motions[0].skeleton, batch.fps, batch.num_frames,
           thresholds)
    plan = _PLANS.get(key)
    if plan is None:
        if len(_PLANS) >= 256:
            _PLANS.clear()
        plan = _PLANS[key] = Plan([spec(batch, thresholds) for spec in specs])
    return plan


def run(batch: ClipBatch, specs: Sequence[MetricSpec] | Plan) -> Scores:
    """Every metric of ``specs`` on every clip of ``batch``, in one compiled
    call; the results are built on demand from the returned
    :class:`Scores`."""
    plan = specs if isinstance(specs, Plan) else Plan(specs)
    b_count, t_count = batch.size, batch.num_frames
    tl = np.empty((kernels.N_METRICS, b_count, t_count), dtype=np.float32)
    value = np.zeros((kernels.N_METRICS, b_count))
    details = np.zeros((kernels.N_METRICS, b_count, kernels.N_DETAILS))
    available = np.zeros(b_count, dtype=np.bool_)
    offsets = np.zeros(b_count * kernels.N_METRICS + 1, dtype=np.int64)
    runs = np.empty((_RUNS_PER_CLIP * b_count, 3))
    if batch.positions is None:
        return Scores(batch, plan, tl, value, details, available, runs, offsets)
    span = np.empty(b_count)
    while True:
        count = kernels.score(batch.positions, batch.idx, plan.enabled, plan.args,
                              plan.frame_thresholds, plan.in_float32, tl, value, details,
                              available, span, runs, offsets)
        if count <= len(runs):
            break
        # Rare (many separate violations): score again with room for all.
        runs = np.empty((count, 3))
        value[:], details[:], available[:] = 0.0, 0.0, False
    batch._check_extent(span)
    return Scores(batch, plan, tl, value, details, available, runs, offsets)


def score(batch: ClipBatch, specs: Sequence[MetricSpec] | Plan) -> list[list[MetricResult]]:
    """Every metric of ``specs`` on every clip of ``batch``, in one compiled
    call (:func:`run`).

    Returns:
        Per spec, one result per clip, as :meth:`MetricResult.from_timeline`
        builds them.
    """
    scores = run(batch, specs)
    return [scores.metric(i) for i in range(len(scores.plan.specs))]


def score_clip(motion: Motion, spec: Callable[[ClipBatch, Settings], MetricSpec],
               thresholds: Settings) -> MetricResult:
    """One joint-level metric of one motion: ``spec(batch, thresholds)`` of the
    motion's one-clip batch, run by :func:`score` (the per-metric functions of
    :mod:`simenv.plausibility.metrics`)."""
    batch = ClipBatch([motion])
    return score(batch, [spec(batch, thresholds)])[0][0]


def _result(spec: MetricSpec, layout: _Layout, v: float, row: list[float],
            timeline: np.ndarray, violations: list[tuple[int, int, float]]) -> MetricResult:
    """One available result: value ``v``, detail columns ``row`` (4,),
    (T,) float32 ``timeline`` and its violation runs."""
    keys, constants, pick, template = layout
    fields = template.copy()
    fields["value"] = v
    fields["passed"] = v <= spec.threshold
    fields["timeline"] = timeline
    fields["violations"] = violations
    # keys and pick have equal lengths by construction (Plan); zip's strict
    # keyword would double the cost of the details.
    fields["details"] = dict(zip(keys, pick(row + constants)))  # noqa: B905
    if not _FROM_FIELDS:
        return MetricResult(**fields)
    result = object.__new__(MetricResult)
    object.__setattr__(result, "__dict__", fields)
    return result


def _results(batch: ClipBatch, spec: MetricSpec, layout: _Layout, tl: np.ndarray,
             values: list[float], columns: list[list[float]],
             spans: list[tuple[int, int, float]], bounds: list[int],
             missing: list[str | None]) -> list[MetricResult]:
    """The results of one metric: ``layout`` how its details are read,
    ``tl`` (B, T) float32 timelines, ``values`` (B,), ``columns`` (B, 4)
    detail columns, the violation runs and their bounds (see
    :func:`simenv.plausibility.kernels.score`), ``missing`` (B,) why a clip
    has no result (None: it has one)."""
    out = []
    # Per clip only what differs (about 1.5 us a result); a row view per
    # clip from iterating tl; k walks the clip's runs bounds.
    k = spec.slot
    for v, row, timeline, reason in zip(values, columns, tl, missing, strict=True):
        if reason is not None:
            out.append(MetricResult.not_available(
                spec.name, batch.num_frames, spec.unit, spec.threshold, reason,
                frame_threshold=spec.frame_threshold, timeline_unit=spec.timeline_unit))
        else:
            out.append(_result(spec, layout, v, row, timeline, spans[bounds[k]:bounds[k + 1]]))
        k += kernels.N_METRICS
    return out

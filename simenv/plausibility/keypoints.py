"""The joint-level metrics of many motions in one compiled pass.

:func:`kinematic_metrics` runs every joint-level metric of the registry
(:data:`~simenv.plausibility.metric_registry.KEYPOINT_REGISTRY`: the metrics
with a kernel spec) on one motion, :func:`kinematic_metrics_batch` on many at
once (vectorised over clips of equal length; same values), each clip's
keypoints read once for all of them
(:func:`simenv.plausibility.clips.run`). :data:`KINEMATIC_METRICS` maps their
names to the per-metric functions. Thresholds:
:class:`~simenv.plausibility.thresholds.Thresholds`.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Iterator, Sequence

import numpy as np

from simenv.core.errors import SimenvError
from simenv.core.motion import Motion
from simenv.plausibility.clips import Scores, batches, cached_plan, run
from simenv.plausibility.metric_registry import KEYPOINT_REGISTRY
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult

#: The joint-level metrics in report order, by stable name: name -> ``function(motion,
#: thresholds) -> MetricResult``.
KINEMATIC_METRICS: dict[str, Callable[[Motion, Thresholds], MetricResult]] = {
    m.name: m.function for m in KEYPOINT_REGISTRY}

#: The kernel specs of the joint-level metrics, in report order.
_SPECS = tuple(m.spec for m in KEYPOINT_REGISTRY)


def kinematic_metrics(
    motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS
) -> dict[str, MetricResult]:
    """Every joint-level metric of ``motion``, keyed by metric name."""
    return kinematic_metrics_batch([motion], thresholds)[0]


class KinematicResults(Sequence[dict[str, MetricResult]]):
    """The joint-level metrics of a list of motions, in input order: item i
    is the ``{metric name: MetricResult}`` dict of motion i.

    A read-only sequence backed by the compiled kernels' output arrays
    (:class:`simenv.plausibility.clips.Scores`): every metric of every clip
    is computed when :func:`kinematic_metrics_batch` returns, but a clip's
    dict of result objects (about 1.5 us per result, more than the kernels
    spend per metric on a short clip) is built the first time the clip is
    read and then kept, so reading it again gives the same objects.
    :meth:`values` reads one metric's values of all clips without building
    any. Equal to a list (or any sequence) holding equal dicts.
    """

    def __init__(self, size: int) -> None:
        #: Per clip: (scores of its batch, its index in the batch).
        self._where: list[tuple[Scores, int]] = [None] * size  # type: ignore[list-item]
        self._built: list[dict[str, MetricResult] | None] = [None] * size
        #: Per batch: its scores and the positions of its clips.
        self._batches: list[tuple[Scores, list[int]]] = []

    def __len__(self) -> int:
        return len(self._where)

    def _clip(self, i: int) -> dict[str, MetricResult]:
        built = self._built[i]
        if built is None:
            scores, k = self._where[i]
            built = self._built[i] = dict(zip(KINEMATIC_METRICS, scores.clip(k)))  # noqa: B905
        return built

    def __getitem__(self, i):  # type: ignore[override]
        if isinstance(i, slice):
            return [self._clip(j) for j in range(*i.indices(len(self)))]
        n = len(self)
        j = operator.index(i)
        if not -n <= j < n:
            raise IndexError(f"motion index {i} out of range for {n} motions")
        return self._clip(j % n)

    def __iter__(self) -> Iterator[dict[str, MetricResult]]:
        return (self._clip(i) for i in range(len(self)))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Sequence) or isinstance(other, str | bytes):
            return NotImplemented
        return len(self) == len(other) and all(a == b for a, b in zip(self, other, strict=True))

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"KinematicResults({len(self)} motions)"

    def values(self, name: str) -> np.ndarray:
        """(N,) float64 ``value`` of metric ``name`` of every motion, NaN
        where it is not available: ``[r[name].value for r in self]``
        without building the results."""
        if name not in KINEMATIC_METRICS:
            raise SimenvError(f"metric name {name!r} is not a kinematic metric; expected one "
                              f"of {', '.join(KINEMATIC_METRICS)}")
        m = list(KINEMATIC_METRICS).index(name)
        out = np.empty(len(self))
        for scores, members in self._batches:
            out[members] = scores.values(m)
        return out


def kinematic_metrics_batch(
    motions: Sequence[Motion], thresholds: Thresholds = DEFAULT_THRESHOLDS
) -> KinematicResults:
    """Every joint-level metric of every motion, in input order.

    Results equal :func:`kinematic_metrics` of each motion. Clips of equal
    skeleton, frame rate and length (e.g. a batch of generated motions) are
    scored together, vectorised over clips
    (:func:`simenv.plausibility.clips.batches`), every joint-level metric in one
    compiled call per batch (:func:`simenv.plausibility.clips.run`), which
    removes the per-call overhead that dominates short clips; any mix of
    clips is accepted. The metrics are computed here; the result objects of
    a clip are built when it is first read (:class:`KinematicResults`).
    """
    out = KinematicResults(len(motions))
    where = out._where
    for members, batch in batches(motions):
        scores = run(batch, cached_plan(batch, thresholds, _SPECS))
        out._batches.append((scores, members))
        for k, i in enumerate(members):
            where[i] = (scores, k)
    return out

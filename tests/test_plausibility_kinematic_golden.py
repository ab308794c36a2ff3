"""The joint-level metrics give the same results as the unoptimised code.

``tests/data/kinematic_golden.npz`` holds every result (value, verdict,
details, violations, timeline) of the straightforward implementation on the
bundled walk, seeded corruptions of it, its edge cases, and every real CMU
clip of the shared corpus (see ``tests/kinematic_cases.py``). Values must be
equal; float tolerances are at rounding level only, so that a different
numpy SIMD path cannot fail the test while any change of formula does.

The compiled kernels (``simenv/plausibility/kernels.py``) reproduce the
numpy operations in order and are bit-identical on every pinned value but
one: ``floating``'s ``worst_residual_m`` comes from a closed-form
least-squares fit instead of LAPACK's, measured at most 5.3e-14 relative
off (within the 1e-12 below).
"""

from __future__ import annotations

import json
from dataclasses import FrozenInstanceError, fields, replace

import numpy as np
import pytest
from kinematic_cases import GOLDEN, cases, summary

from simenv.core.motion import Motion
from simenv.plausibility import (
    KINEMATIC_METRICS,
    MetricResult,
    kinematic_metrics,
    kinematic_metrics_batch,
)


@pytest.fixture(scope="module")
def golden() -> tuple[dict, dict[str, np.ndarray]]:
    with np.load(GOLDEN) as npz:
        return json.loads(str(npz["_meta"])), {k: npz[k] for k in npz.files if k != "_meta"}


def _same(a: object, b: object, where: str) -> None:
    """Recursive equality of summaries: floats to 1e-12 relative."""
    if isinstance(b, dict):
        assert isinstance(a, dict) and a.keys() == b.keys(), where
        for k in b:
            _same(a[k], b[k], f"{where}.{k}")
    elif isinstance(b, list):
        assert isinstance(a, list) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(b, float) and not isinstance(a, bool):
        assert a == pytest.approx(b, rel=1e-12, abs=1e-300), where
    else:
        assert a == b, where


def _check(name: str, results: dict[str, MetricResult], golden) -> None:
    meta, timelines = golden
    assert list(results) == list(KINEMATIC_METRICS)
    for metric, r in results.items():
        where = f"{name}:{metric}"
        _same(summary(r), meta[name][metric], where)
        np.testing.assert_allclose(r.timeline, timelines[where], rtol=1e-6, atol=0,
                                   equal_nan=True, err_msg=where)


@pytest.fixture(scope="module")
def bundled() -> list[tuple[str, Motion]]:
    """The bundled walk, its corruptions and edge cases."""
    return list(cases(None))


@pytest.fixture(scope="module")
def corpus(shared_data) -> list[tuple[str, Motion]]:
    """The real CMU clips of the shared corpus (BVH and AMC)."""
    return list(cases(shared_data))[len(list(cases(None))):]


def test_golden_pins_every_verdict(golden) -> None:
    # Every metric has passing, failing and not-available cases pinned.
    for metric in KINEMATIC_METRICS:
        verdicts = {golden[0][n][metric]["passed"] for n in golden[0]}
        assert verdicts == {True, False, None}, metric


@pytest.mark.parametrize("source", ["bundled", "corpus"])
def test_each_metric_matches_the_golden_results(source, request, golden) -> None:
    for name, motion in request.getfixturevalue(source):
        _check(name, {m: fn(motion) for m, fn in KINEMATIC_METRICS.items()}, golden)


@pytest.mark.parametrize("source", ["bundled", "corpus"])
def test_kinematic_metrics_matches_the_golden_results(source, request, golden) -> None:
    for name, motion in request.getfixturevalue(source):
        _check(name, kinematic_metrics(motion), golden)


def _identical(a: MetricResult, b: MetricResult) -> None:
    assert summary(a) == summary(b), a.name  # NaN is compared as its repr
    np.testing.assert_array_equal(a.timeline, b.timeline, err_msg=a.name)


@pytest.mark.parametrize("source", ["bundled", "corpus"])
def test_batch_equals_one_clip_at_a_time(source, request) -> None:
    motions = [m for _, m in request.getfixturevalue(source)]
    # Equal-length copies form real multi-clip batches; mixed lengths, rates
    # and skeletons are grouped apart; order is kept.
    walk = motions[0]
    shifted = [walk.with_positions(walk.positions + np.float32(dz)) for dz in (0.02, -0.04, 0.3)]
    mixed = motions + shifted + motions[:3]
    batched = kinematic_metrics_batch(mixed)
    assert len(batched) == len(mixed)
    for motion, got in zip(mixed, batched, strict=True):
        for name, fn in KINEMATIC_METRICS.items():
            _identical(got[name], fn(motion))


def test_batch_of_nothing_is_empty() -> None:
    assert kinematic_metrics_batch([]) == []


def test_results_are_ordinary_metric_results(bundled) -> None:
    # The compiled path builds results from their field dicts: they must be
    # indistinguishable from results built by the dataclass constructor.
    names = {f.name for f in fields(MetricResult)}
    for _, motion in bundled[:4]:
        for r in kinematic_metrics(motion).values():
            assert type(r) is MetricResult and set(vars(r)) == names
            built = replace(r)
            assert summary(built) == summary(r) and repr(built) == repr(r)
            with pytest.raises(FrozenInstanceError):
                r.value = 0.0  # type: ignore[misc]

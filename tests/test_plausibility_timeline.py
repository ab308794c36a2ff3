"""MetricResult and violation runs (simenv.plausibility.timeline)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from simenv.core.errors import MotionError
from simenv.io import bvh
from simenv.plausibility import velocity
from simenv.plausibility.timeline import MetricResult, find_violations


def test_violation_runs_are_maximal_inclusive_and_carry_the_worst_value() -> None:
    timeline = np.array([0.0, 2.0, 3.0, 0.5, np.nan, 4.0, 1.5, 1.0, 7.0], dtype=np.float32)
    assert find_violations(timeline, 1.0) == [(1, 2, 3.0), (5, 6, 4.0), (8, 8, 7.0)]
    assert find_violations(timeline, 10.0) == []
    # NaN never violates, even when everything else does.
    assert find_violations(np.array([np.nan, 5.0, np.nan]), 1.0) == [(1, 1, 5.0)]


def test_find_violations_rejects_non_1d() -> None:
    with pytest.raises(MotionError, match=r"shape \(T,\)"):
        find_violations(np.zeros((3, 2)), 1.0)


def test_from_timeline_verdict_and_frame_threshold() -> None:
    tl = np.array([0.0, 30.0, 40.0, 0.0])
    r = MetricResult.from_timeline("foot_skate", tl, 0.5, "fraction", 0.08,
                                   frame_threshold=25.0, timeline_unit="mm/frame")
    assert r.passed is False and r.available
    assert r.violations == [(1, 2, 40.0)]
    assert r.timeline.dtype == np.float32 and r.timeline.shape == (4,)
    d = r.to_dict()
    assert json.loads(json.dumps(d))["violations"][0] == {
        "start_frame": 1, "end_frame": 2, "worst_value": 40.0}


def test_not_available_has_reason_nan_value_and_null_verdict() -> None:
    r = MetricResult.not_available("jitter", 3, "%", 10.0, "needs 13 frames")
    assert r.passed is None and not r.available and r.reason == "needs 13 frames"
    assert np.isnan(r.value) and np.isnan(r.timeline).all() and r.violations == []
    d = r.to_dict()
    assert d["value"] is None and d["passed"] is None
    json.dumps(d)


def test_real_glitch_frame_is_reported_as_a_violation(shared_data) -> None:
    # CMU 16_15 (cgspeed BVH): the left arm jumps ~0.7 m for one frame right
    # after the T-pose (frames 1-2 once the T-pose is dropped).
    motion = bvh.read(shared_data / "cmu/bvh/16_15.bvh").slice(0, 200)
    r = velocity(motion)
    assert r.passed is False
    assert len(r.violations) == 1
    start, end, worst = r.violations[0]
    assert start <= 2 and end <= 3 and worst > 3.0
    assert np.isnan(r.timeline[0]) and r.timeline.shape == (200,)


@given(
    st.lists(st.one_of(st.floats(-10, 10), st.just(float("nan"))), min_size=0, max_size=60),
    st.floats(-5, 5),
)
def test_violation_runs_cover_exactly_the_frames_over_threshold(values, threshold) -> None:
    timeline = np.array(values, dtype=np.float64)
    runs = find_violations(timeline, threshold)
    covered = [t for s, e, _ in runs for t in range(s, e + 1)]
    expected = [t for t, v in enumerate(values) if v > threshold]
    assert covered == expected
    for s, e, worst in runs:
        assert worst == max(values[s : e + 1])
    for (_, end, _), (start, _, _) in zip(runs, runs[1:], strict=False):
        assert start > end + 1  # maximal: runs never touch

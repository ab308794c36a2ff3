"""Tests for simenv.core.srvf: exact discrete SRVF, hypersphere maps, Karcher mean.

Property tests (hypothesis) check the identities the module documents; the real-data
tests run the same identities on CMU motion capture.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from simenv.core import srvf
from simenv.core.errors import MotionError
from simenv.core.srvf import GeometryError
from simenv.io import bvh

SETTINGS = settings(max_examples=150, deadline=None)

seeds = st.integers(0, 2**32 - 1)
steps = st.integers(1, 30)
dims = st.integers(1, 9)


def _sphere_points(seed: int, n: int, d: int, k: int) -> np.ndarray:
    """(k, n, d) random unit SRVFs."""
    x = np.random.default_rng(seed).normal(size=(k, n, d))
    return x / srvf.norm(x)[:, None, None]


def _tangent(p: np.ndarray, seed: int, length: float) -> np.ndarray:
    """A random tangent vector at p of the given norm."""
    v = srvf.project_tangent(p, np.random.default_rng(seed + 1).normal(size=p.shape))
    return v * (length / srvf.norm(v))


@st.composite
def curves(draw: st.DrawFn) -> np.ndarray:
    """(T, D) curves; some samples repeated so that parts of the curve stand still."""
    t, d = draw(st.integers(2, 30)), draw(dims)
    c = draw(hnp.arrays(np.float64, (t, d), elements=st.floats(-1e3, 1e3)))
    repeat = draw(hnp.arrays(np.bool_, (t,)))
    repeat[0] = False
    idx = np.maximum.accumulate(np.where(repeat, 0, np.arange(t)))
    return c[idx]


# -- SRVF of curves ----------------------------------------------------------------


@SETTINGS
@given(curves())
def test_inverse_srvf_reconstructs_the_curve(c):
    q = srvf.srvf(c)
    assert q.shape == (c.shape[0] - 1, c.shape[1])
    back = srvf.inverse_srvf(q, c[0])
    scale = 1.0 + np.abs(c).max()
    np.testing.assert_allclose(back, c, rtol=0, atol=1e-13 * scale * c.shape[0])


@SETTINGS
@given(curves())
def test_squared_norm_is_curve_length(c):
    q = srvf.srvf(c)
    length = srvf.curve_length(c)
    assert srvf.norm(q) ** 2 == pytest.approx(length, rel=1e-12, abs=1e-12)


@SETTINGS
@given(curves())
def test_inner_product_is_exact_l2_of_the_piecewise_linear_curve(c):
    """Inserting midpoints does not change the piecewise-linear curve, so its SRVF is the
    same function: every inner product and the norm must be unchanged (a quadrature
    inconsistency between srvf and inner would show here)."""
    mid = (c[:-1] + c[1:]) / 2
    fine = np.empty((2 * len(c) - 1, c.shape[1]))
    fine[0::2], fine[1::2] = c, mid
    q, qf = srvf.srvf(c), srvf.srvf(fine)
    # A midpoint is rounded to the float grid (up to eps * |c| off), and v -> v / sqrt|v| is
    # Hölder-1/2, so near-still steps of a far-from-origin curve differ by sqrt(rounding).
    rounding = 2 * (len(fine) - 1) * np.finfo(float).eps * (1.0 + np.abs(c).max())
    atol = 1e-9 + 4 * np.sqrt(rounding)
    np.testing.assert_allclose(np.repeat(q, 2, axis=0), qf, rtol=1e-9, atol=atol)
    other = np.sin(np.arange(q.size, dtype=float)).reshape(q.shape)
    assert srvf.inner(q, other) == pytest.approx(
        srvf.inner(qf, np.repeat(other, 2, axis=0)), rel=1e-9, abs=c.shape[1] * atol
    )


def test_still_steps_have_zero_srvf_and_are_reconstructed():
    c = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 2.0]])
    q = srvf.srvf(c)
    assert np.all(q[1] == 0)
    np.testing.assert_allclose(srvf.inverse_srvf(q, c[0]), c, atol=1e-15)


def test_batched_curves_match_one_by_one():
    c = np.random.default_rng(3).normal(size=(4, 2, 12, 5))
    q = srvf.srvf(c)
    assert q.shape == (4, 2, 11, 5)
    np.testing.assert_array_equal(q[2, 1], srvf.srvf(c[2, 1]))
    np.testing.assert_allclose(srvf.inverse_srvf(q, c[..., 0, :]), c, atol=1e-13)


def test_sphere_round_trip_restores_curve_from_amplitude_and_start():
    c = np.random.default_rng(4).normal(size=(3, 20, 6)).cumsum(axis=1)
    points, amplitude = srvf.curve_to_sphere(c)
    np.testing.assert_allclose(srvf.norm(points), 1.0, atol=1e-14)
    np.testing.assert_allclose(amplitude**2, srvf.curve_length(c), rtol=1e-12)
    np.testing.assert_allclose(srvf.sphere_to_curve(points, amplitude, c[:, 0]), c, atol=1e-12)


def test_bad_curves_raise_motion_error():
    with pytest.raises(MotionError, match="at least 2 samples"):
        srvf.srvf(np.zeros((1, 3)))
    with pytest.raises(MotionError, match=r"non-finite value at index \(2, 1\)"):
        srvf.srvf(np.where(np.arange(12).reshape(4, 3) == 7, np.nan, 1.0))
    with pytest.raises(MotionError, match=r"shape \(\.\.\., n, D\)"):
        srvf.srvf(np.zeros(5))


def test_still_curve_has_no_point_on_the_sphere():
    c = np.ones((3, 10, 4))
    c[0] += np.linspace(0, 1, 10)[:, None]
    with pytest.raises(GeometryError, match=r"zero length.*batch index \(1,\)"):
        srvf.curve_to_sphere(c)


def test_inverse_rejects_start_of_wrong_dimension():
    with pytest.raises(GeometryError, match="D = 4"):
        srvf.inverse_srvf(np.ones((5, 4)), np.zeros(3))
    with pytest.raises(GeometryError, match="do not broadcast"):
        srvf.inverse_srvf(np.ones((2, 5, 4)), np.zeros((3, 4)))


def test_one_srvf_integrated_from_many_start_poses():
    c = np.random.default_rng(8).normal(size=(9, 4))
    starts = np.random.default_rng(9).normal(size=(3, 4))
    curves_ = srvf.inverse_srvf(srvf.srvf(c), starts)
    assert curves_.shape == (3, 9, 4)
    np.testing.assert_allclose(curves_ - curves_[:, :1], np.broadcast_to(c - c[0], (3, 9, 4)),
                               atol=1e-13)


# -- the sphere -------------------------------------------------------------------------


@SETTINGS
@given(seeds, steps, dims, st.floats(0.0, 3.1))
def test_log_of_exp_is_identity_inside_injectivity_radius(seed, n, d, length):
    p = _sphere_points(seed, n, d, 1)[0]
    if n * d == 1:  # the 0-sphere {±1} has no non-zero tangent vector
        length = 0.0
    v = _tangent(p, seed, length) if length > 0 else np.zeros_like(p)
    q = srvf.exp_map(p, v)
    assert srvf.norm(q) == pytest.approx(1.0, abs=1e-12)
    assert srvf.distance(p, q) == pytest.approx(length, abs=1e-9)
    np.testing.assert_allclose(srvf.log_map(p, q), v, atol=1e-9)


@SETTINGS
@given(seeds, steps, dims)
def test_exp_of_log_is_identity(seed, n, d):
    p, q = _sphere_points(seed, n, d, 2)
    if srvf.inner(p, q) < -1 + 1e-6:  # (near-)antipodal: tested separately
        return
    v = srvf.log_map(p, q)
    assert abs(srvf.inner(v, p)) < 1e-12
    assert srvf.norm(v) == pytest.approx(srvf.distance(p, q), abs=1e-9)
    np.testing.assert_allclose(srvf.exp_map(p, v), q, atol=1e-9)


@SETTINGS
@given(seeds, steps, dims)
def test_distance_is_a_metric_bounded_by_pi(seed, n, d):
    p, q, r = _sphere_points(seed, n, d, 3)
    dpq, dqp = srvf.distance(p, q), srvf.distance(q, p)
    assert dpq == dqp
    assert 0.0 <= dpq <= np.pi
    assert srvf.distance(p, p) == 0.0
    assert srvf.distance(p, -p) == pytest.approx(np.pi, abs=1e-12)
    assert srvf.distance(p, r) <= dpq + srvf.distance(q, r) + 1e-12
    assert dpq == pytest.approx(np.arccos(np.clip(srvf.inner(p, q), -1, 1)), abs=1e-7)


def test_distance_keeps_precision_for_nearby_points():
    p = _sphere_points(0, 10, 3, 1)[0]
    v = _tangent(p, 0, 1e-9)
    q = srvf.exp_map(p, v)
    assert srvf.distance(p, q) == pytest.approx(1e-9, rel=1e-6)
    np.testing.assert_allclose(srvf.log_map(p, q), v, rtol=0, atol=1e-15)


@SETTINGS
@given(seeds, steps, dims)
def test_tangent_projection_is_orthogonal_and_idempotent(seed, n, d):
    p = _sphere_points(seed, n, d, 1)[0]
    x = np.random.default_rng(seed + 7).normal(size=p.shape) * 5
    v = srvf.project_tangent(p, x)
    assert abs(srvf.inner(v, p)) < 1e-12
    np.testing.assert_allclose(srvf.project_tangent(p, v), v, atol=1e-12)
    np.testing.assert_allclose(v + srvf.inner(x, p) * p, x, atol=1e-12)


@SETTINGS
@given(seeds, st.integers(1, 12), st.integers(2, 6))
def test_parallel_transport_is_an_isometry_between_tangent_spaces(seed, n, d):
    p, q = _sphere_points(seed, n, d, 2)
    if srvf.inner(p, q) < -1 + 1e-6:
        return
    u = _tangent(p, seed, 0.7)
    w = _tangent(p, seed + 11, 1.3)
    tu, tw = srvf.parallel_transport(u, p, q), srvf.parallel_transport(w, p, q)
    assert abs(srvf.inner(tu, q)) < 1e-10
    assert srvf.inner(tu, tw) == pytest.approx(srvf.inner(u, w), abs=1e-10)
    np.testing.assert_allclose(srvf.parallel_transport(tu, q, p), u, atol=1e-10)
    np.testing.assert_allclose(
        srvf.parallel_transport(srvf.log_map(p, q), p, q), -srvf.log_map(q, p), atol=1e-9
    )


def test_sphere_maps_broadcast_over_batches():
    p = _sphere_points(5, 8, 3, 1)[0]
    qs = _sphere_points(6, 8, 3, 7)
    logs = srvf.log_map(p, qs)
    assert logs.shape == qs.shape
    np.testing.assert_allclose(logs[4], srvf.log_map(p, qs[4]), atol=1e-15)
    np.testing.assert_allclose(srvf.exp_map(p, logs), qs, atol=1e-12)
    assert srvf.distance(p, qs).shape == (7,)


def test_domain_errors_are_clear():
    p, q = _sphere_points(1, 6, 3, 2)
    with pytest.raises(GeometryError, match="unit sphere.*norm 2"):
        srvf.log_map(2 * p, q)
    with pytest.raises(GeometryError, match="tangent"):
        srvf.exp_map(p, q)
    with pytest.raises(GeometryError, match="antipode"):
        srvf.log_map(p, -p)
    with pytest.raises(GeometryError, match="antipode"):
        srvf.parallel_transport(_tangent(p, 1, 1.0), p, -p)
    with pytest.raises(GeometryError, match="different spaces"):
        srvf.distance(p, q[:5])
    with pytest.raises(GeometryError, match=r"batch index \(2,\)"):
        srvf.distance(p, np.stack([q, q, 3 * q]))
    with pytest.raises(GeometryError, match="do not broadcast"):
        srvf.inner(np.stack([p, q]), np.stack([p, q, p]))


# -- Karcher mean ---------------------------------------------------------------------------


@SETTINGS
@given(seeds, steps, dims, st.integers(1, 6))
def test_karcher_mean_of_copies_is_the_point(seed, n, d, k):
    p = _sphere_points(seed, n, d, 1)[0]
    result = srvf.karcher_mean(np.repeat(p[None], k, axis=0))
    assert result.converged
    np.testing.assert_allclose(result.mean, p, atol=1e-12)
    assert result.variance == pytest.approx(0.0, abs=1e-20)


@SETTINGS
@given(seeds, st.integers(1, 12), st.integers(2, 6), st.integers(1, 4), st.floats(0.05, 1.2))
def test_karcher_mean_of_points_symmetric_about_p_is_p(seed, n, d, pairs, spread):
    """Points exp_p(±v_i): every log at p cancels in pairs, so p is the mean. Start the
    iteration elsewhere so the algorithm has to find it."""
    p = _sphere_points(seed, n, d, 1)[0]
    vs = [_tangent(p, seed + 3 * i, spread * (1 + i) / pairs) for i in range(pairs)]
    pts = np.stack([srvf.exp_map(p, s * v) for v in vs for s in (1.0, -1.0)])
    start = srvf.exp_map(p, _tangent(p, seed + 99, 0.3))
    result = srvf.karcher_mean(pts, init=start, tol=1e-10, max_iter=500)
    assert result.converged
    assert srvf.distance(result.mean, p) < 1e-8
    assert result.history[-1] < result.history[0]


def test_karcher_mean_reports_non_convergence():
    pts = _sphere_points(2, 10, 3, 20)
    result = srvf.karcher_mean(pts, max_iter=2, tol=1e-14)
    assert not result.converged
    assert result.iterations == 2
    assert len(result.history) == 3


def test_karcher_mean_rejects_bad_input():
    pts = _sphere_points(2, 10, 3, 4)
    with pytest.raises(GeometryError, match=r"\(N, n, D\)"):
        srvf.karcher_mean(pts[0])
    with pytest.raises(GeometryError, match="step"):
        srvf.karcher_mean(pts, step=1.5)
    with pytest.raises(GeometryError, match="unit sphere"):
        srvf.karcher_mean(pts * 1.1)


# -- real motion capture ------------------------------------------------------------------


def _real_segments(shared_data: Path, length: int) -> np.ndarray:
    """(N, length, 3J) root-relative canonical-keypoint curves of CMU 02_06 at 25 fps."""
    motion = bvh.read(shared_data / "cmu" / "bvh" / "02_06.bvh").to_canonical().resample(25.0)
    pos = motion.positions - motion.joint("pelvis")[:, None]
    flat = pos.reshape(len(pos), -1)
    starts = range(0, len(flat) - length + 1, 5)
    return np.stack([flat[s : s + length] for s in starts])


def test_real_motion_reconstructs_exactly_and_amplitude_is_length(shared_data):
    curves_ = _real_segments(shared_data, 26)
    q = srvf.srvf(curves_)
    assert q.shape == (len(curves_), 25, curves_.shape[-1])
    np.testing.assert_allclose(srvf.inverse_srvf(q, curves_[:, 0]), curves_, atol=1e-12)
    points, amplitude = srvf.to_sphere(q)
    np.testing.assert_allclose(amplitude**2, srvf.curve_length(curves_), rtol=1e-10)
    # a 1 s segment of a person moving about: total joint-path length of metres, not mm or km
    assert 0.05 < np.median(amplitude**2) < 50


def test_real_karcher_mean_is_a_critical_point_and_a_minimum(shared_data):
    points, _ = srvf.curve_to_sphere(_real_segments(shared_data, 26))
    # real windows are spread far apart (distances ~ π/2), so convergence is slow
    result = srvf.karcher_mean(points, tol=1e-8, max_iter=1000)
    assert result.converged
    assert all(b < a for a, b in zip(result.history, result.history[1:], strict=False))
    # first-order condition: the mean of the logs vanishes
    assert srvf.norm(srvf.log_map(result.mean, points).mean(axis=0)) < 1e-8

    def frechet(mu: np.ndarray) -> float:
        return float(np.mean(srvf.distance(mu, points) ** 2))

    assert frechet(result.mean) == pytest.approx(result.variance, rel=1e-9)
    assert all(frechet(p) > result.variance for p in points)
    for seed in range(5):
        nudged = srvf.exp_map(result.mean, _tangent(result.mean, seed, 0.05))
        assert frechet(nudged) > result.variance

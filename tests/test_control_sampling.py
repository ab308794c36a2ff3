"""Spline offsets and the predictive-sampling / MPPI update (simenv.control.sampling)."""

from __future__ import annotations

import numpy as np
import pytest

from simenv.control.sampling import Sampler, Spline
from simenv.core.errors import PhysicsError


def test_spline_passes_through_its_knots_and_interpolates_linearly() -> None:
    sp = Spline(horizon=31, n_knots=4)
    knots = np.array([[0.0, 1.0], [3.0, -1.0], [6.0, 2.0], [0.0, 0.0]])
    curve = sp.evaluate(knots)
    assert curve.shape == (31, 2)
    np.testing.assert_allclose(curve[[0, 10, 20, 30]], knots)
    np.testing.assert_allclose(curve[5], (knots[0] + knots[1]) / 2)
    # Batched knots evaluate sample by sample.
    batch = np.stack([knots, 2 * knots])
    np.testing.assert_allclose(sp.evaluate(batch)[1], 2 * curve)


def test_spline_shift_rereads_the_curve_later_and_holds_its_end() -> None:
    sp = Spline(horizon=31, n_knots=4)
    knots = np.array([[0.0], [3.0], [6.0], [9.0]])  # a ramp of 0.3 per step
    shifted = sp.shift(knots, 10)
    np.testing.assert_allclose(shifted[:, 0], [3.0, 6.0, 9.0, 9.0])
    np.testing.assert_allclose(sp.shift(knots, 5)[:, 0], [1.5, 4.5, 7.5, 9.0])


def test_sampler_keeps_the_nominal_clips_and_is_seeded() -> None:
    nominal = np.full((3, 4), 0.5)
    a = Sampler(16, sigma=1.0, limit=0.6, seed=3).sample(nominal)
    b = Sampler(16, sigma=1.0, limit=0.6, seed=3).sample(nominal)
    c = Sampler(16, sigma=1.0, limit=0.6, seed=4).sample(nominal)
    assert a.shape == (16, 3, 4)
    np.testing.assert_array_equal(a[0], nominal)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert np.abs(a).max() <= 0.6 and (np.abs(a[1:]) == 0.6).any()
    # A zero sigma (an actuator left out of the search) never moves.
    frozen = Sampler(8, sigma=np.array([0.0, 1.0, 1.0, 1.0]), limit=5.0).sample(nominal)
    np.testing.assert_array_equal(frozen[:, :, 0], 0.5)


def test_constant_samples_shift_every_knot_alike() -> None:
    nominal = np.zeros((4, 3))
    out = Sampler(9, sigma=0.1, limit=1.0, seed=0, constant_fraction=0.5).sample(nominal)
    steady = out[1:5]  # round(0.5 * 8) = 4 constant offsets, then 4 free ones
    np.testing.assert_array_equal(steady, np.repeat(steady[:, :1], 4, axis=1))
    assert (np.abs(np.diff(out[5:], axis=1)) > 0).all()


def test_update_keeps_the_best_or_the_mppi_average() -> None:
    samples = np.arange(4.0)[:, None, None] * np.ones((4, 2, 3))
    costs = np.array([3.0, 1.0, np.nan, 2.0])
    best = Sampler(4, 1.0, 10.0).update(samples, costs)
    np.testing.assert_array_equal(best, samples[1])  # the NaN rollout (index 2) never wins
    avg = Sampler(4, 1.0, 10.0, temperature=0.5).update(samples, costs)
    # Weights exp(-(c - 1) / (0.5 * (2 - 1))) over the finite costs 3, 1, 2.
    w = np.exp(-np.array([2.0, 0.0, 1.0]) / 0.5)
    np.testing.assert_allclose(avg, (w @ np.array([0.0, 1.0, 3.0])) / w.sum() * np.ones((2, 3)))
    # Every rollout blew up: keep the nominal's slot instead of averaging NaN.
    assert np.isfinite(Sampler(4, 1.0, 10.0, 0.5).update(samples, np.full(4, np.nan))).all()


@pytest.mark.parametrize(("make", "field"), [
    (lambda: Spline(1, 2), "n_knots"),
    (lambda: Spline(10, 11), "n_knots"),
    (lambda: Sampler(1, 1.0, 1.0), "n_samples"),
    (lambda: Sampler(4, 1.0, 1.0, temperature=-1.0), "temperature"),
    (lambda: Sampler(4, 1.0, 1.0, constant_fraction=1.5), "constant_fraction"),
])
def test_bad_settings_raise_physics_errors_naming_the_field(make, field) -> None:
    with pytest.raises(PhysicsError) as err:
        make()
    assert err.value.field == field


def test_antithetic_samples_come_in_mirrored_pairs_and_cancel_in_the_average() -> None:
    nominal = np.full((4, 3), 0.1)
    s = Sampler(9, sigma=0.2, limit=5.0, seed=0, constant_fraction=0.5, antithetic=True)
    out = s.sample(nominal)
    eps = out[1:] - nominal
    np.testing.assert_allclose(eps[:4], -eps[4:])  # 8 noisy samples: 4 pairs
    # round(4 * 4 / 8) = 2 constant offsets in each half, mirrored with their pair.
    np.testing.assert_array_equal(eps[:2], np.repeat(eps[:2, :1], 4, axis=1))
    assert (np.abs(np.diff(eps[2:4], axis=1)) > 0).all()
    # Costs alike on both sides of the nominal: the MPPI average stays on it.
    costs = np.concatenate([[0.5], np.tile([1.0, 2.0, 1.5, 3.0], 2)])
    mppi = Sampler(9, sigma=0.2, limit=5.0, temperature=0.1, antithetic=True)
    np.testing.assert_allclose(mppi.update(out, costs), nominal, atol=1e-12)
    # An odd number of noisy samples leaves the last one without its mirror.
    odd = Sampler(10, sigma=0.2, limit=5.0, seed=0, antithetic=True).sample(nominal)
    np.testing.assert_allclose(odd[1:5] - nominal, nominal - odd[6:10])

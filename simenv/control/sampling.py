"""Sampled control offsets on a piecewise-linear spline, and their update rule.

The planner searches over offsets ``delta(j)`` (radians, added to the
reference servo targets) for the ``H`` physics steps of its horizon. They are
parameterised by ``n`` knots ``theta_k`` (n, nu) at steps ``t_k = k (H - 1) /
(n - 1)`` and interpolated linearly,

    delta(j) = sum_k B_jk theta_k,   B (H, n) the hat functions at the knots,

so a sample is ``n x nu`` numbers instead of ``H x nu`` (smooth, low-dimensional;
MuJoCo MPC's predictive sampling uses the same representation).

:class:`Sampler` implements predictive sampling (Howell et al. 2022) and its
MPPI variant (Williams et al. 2017): around the nominal knots
``theta_0`` draw ``theta_i = clip(theta_0 + sigma * eps_i)``, ``eps_i ~ N(0,
I)``, i = 1 .. N-1 (sample 0 is the nominal itself, so a plan never gets
worse than the previous one by sampling), roll them out, and keep

A fraction ``constant_fraction`` of the samples draws one ``eps`` per
actuator for all knots (a constant offset over the horizon): balance
corrections are mostly such sustained shifts (lean the ankles, bend the
hips), and a search over ``nu`` constant offsets finds them far more often
than one over ``n x nu`` independent knots.

The next nominal is

* the cheapest sample (``temperature = 0``: predictive sampling), or
* the weighted mean ``sum_i w_i theta_i`` with ``w_i ~ exp(-(c_i - c_min) /
  (lambda (c_mean - c_min)))`` (MPPI with the temperature ``lambda``
  normalised by the spread of the costs, so it is unitless).

With ``antithetic`` the noise comes in mirrored pairs, ``eps_i`` and ``-eps_i`` (the
constant ones with their mirror): where the cost is locally flat the two weigh alike and
their contributions to the MPPI average cancel, so the update moves only along directions
where one side is cheaper -- a less noisy step for as many rollouts (on the walks 02_01 and
12_01 with 64 samples and an 8 ms planning step: 84 -> 45 and 71 -> 38 mm body error;
docs/tracking_speed.md).
"""

from __future__ import annotations

import numpy as np

from simenv.core.errors import PhysicsError


class Spline:
    """Piecewise-linear interpolation of ``n_knots`` knots over ``horizon`` steps.

    Args:
        horizon: H, steps covered (>= 2).
        n_knots: n, knots (2 <= n <= H), the first at step 0 and the last at H - 1.
    """

    def __init__(self, horizon: int, n_knots: int) -> None:
        if horizon < 2 or not 2 <= n_knots <= horizon:
            raise PhysicsError(f"a spline needs 2 <= n_knots <= horizon and horizon >= 2; "
                               f"got n_knots={n_knots}, horizon={horizon}", field="n_knots")
        self.horizon = int(horizon)
        self.n_knots = int(n_knots)
        self.knot_steps = np.linspace(0.0, horizon - 1, n_knots)
        self.basis = self.weights(np.arange(horizon, dtype=np.float64))

    def weights(self, steps: np.ndarray) -> np.ndarray:
        """(len(steps), n) interpolation weights at ``steps``, held constant past the ends."""
        s = np.clip(steps, 0.0, self.horizon - 1)
        return np.stack([np.interp(s, self.knot_steps, np.eye(self.n_knots)[k])
                         for k in range(self.n_knots)], axis=1)

    def evaluate(self, knots: np.ndarray) -> np.ndarray:
        """Offsets per step: (..., n, nu) knots -> (..., H, nu)."""
        return np.einsum("hk,...ku->...hu", self.basis, knots)

    def shift(self, knots: np.ndarray, steps: int) -> np.ndarray:
        """The same curve started ``steps`` later: knots re-read at ``t_k + steps``,
        the last value held past the horizon. (n, nu) -> (n, nu)."""
        return self.weights(self.knot_steps + steps) @ knots


class Sampler:
    """Draws knot samples around a nominal and folds their costs into the next nominal.

    Args:
        n_samples: N >= 2, including the nominal.
        sigma: (nu,) or scalar, standard deviation of the knot noise, radians.
        limit: (nu,) or scalar, largest offset magnitude of any knot, radians.
        temperature: 0 keeps the cheapest sample (predictive sampling); > 0
            the MPPI average (module docstring).
        constant_fraction: share of the noisy samples whose offset is the same
            on every knot.
        seed: seed of the noise generator (numpy PCG64).
        antithetic: draw the noise in mirrored pairs ``+eps``, ``-eps`` (module
            docstring).
    """

    def __init__(self, n_samples: int, sigma: np.ndarray | float, limit: np.ndarray | float,
                 temperature: float = 0.0, seed: int = 0,
                 constant_fraction: float = 0.0, antithetic: bool = False) -> None:
        if n_samples < 2:
            raise PhysicsError(f"n_samples must be >= 2; got {n_samples}", field="n_samples")
        if temperature < 0:
            raise PhysicsError(f"temperature must be >= 0; got {temperature}",
                               field="temperature")
        if not 0.0 <= constant_fraction <= 1.0:
            raise PhysicsError(f"constant_fraction must be in [0, 1]; got {constant_fraction}",
                               field="constant_fraction")
        self.n_samples = int(n_samples)
        self.n_constant = int(round(constant_fraction * (n_samples - 1)))
        self.sigma = np.asarray(sigma, dtype=np.float64)
        self.limit = np.asarray(limit, dtype=np.float64)
        self.temperature = float(temperature)
        self.rng = np.random.default_rng(seed)
        self.antithetic = bool(antithetic)

    def sample(self, nominal: np.ndarray) -> np.ndarray:
        """(n, nu) nominal -> (N, n, nu) samples, sample 0 the nominal."""
        n_noisy = self.n_samples - 1
        if self.antithetic:
            half = (n_noisy + 1) // 2
            eps = self.rng.standard_normal((half,) + nominal.shape)
            k = int(round(self.n_constant * half / max(n_noisy, 1)))
            eps[:k] = eps[:k, :1]
            eps = np.concatenate([eps, -eps])[:n_noisy]
        else:
            eps = self.rng.standard_normal((n_noisy,) + nominal.shape)
            eps[:self.n_constant] = eps[:self.n_constant, :1]
        out = np.empty((self.n_samples,) + nominal.shape)
        out[0] = nominal
        out[1:] = np.clip(nominal + self.sigma * eps, -self.limit, self.limit)
        return out

    def update(self, samples: np.ndarray, costs: np.ndarray) -> np.ndarray:
        """The next nominal from (N, n, nu) samples and their (N,) costs; a
        sample with a non-finite cost (a blown-up rollout) never wins."""
        c = np.where(np.isfinite(costs), costs, np.inf)
        best = int(np.argmin(c))
        if self.temperature == 0.0 or not np.isfinite(c[best]):
            return samples[best].copy()
        finite = np.isfinite(c)
        spread = max(float(c[finite].mean() - c[best]), 1e-12)
        w = np.zeros(len(c))
        w[finite] = np.exp(-(c[finite] - c[best]) / (self.temperature * spread))
        return np.tensordot(w / w.sum(), samples, axes=1)

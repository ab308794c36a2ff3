"""Recognition accuracy of generated interactions: a classifier trained on real two-person
windows, asked to name the class of (real actor, generated reactor) windows.

The papers measure how recognisable a generated reaction is with an action classifier
trained on real data. Ours is an L2-regularised multinomial logistic regression on window
features of both people, which trains in well under a second and is deterministic (a
convex problem solved by L-BFGS):

* features ``φ(a, b) = [f(a), f(b)]`` (or ``f(b)`` alone with ``use_actor=False``: is
  the class recognisable from the reaction by itself?), ``f`` the window feature
  extractor of FVD (:func:`simenv.learning.interaction_features.default_feature_extractor`:
  the gesture classifier's penultimate features), standardised with the training mean and
  deviation;
* class scores ``s = x W + c``; ``W, c`` minimise the mean cross-entropy of
  ``softmax(s)`` plus ``λ/2 ||W||²`` (the bias is not regularised), ``λ`` = :data:`RIDGE`.
  (Least-squares one-vs-rest was tried first and fails on classes that lie between two
  others along one feature: the linear "masking" problem; softmax does not.)
* prediction ``argmax_c s_c``.

Only classes with training windows can be recognised; :meth:`InteractionRecognizer.accuracy`
scores the windows of those classes and says how many it left out.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from simenv.core.errors import MotionError
from simenv.data.interaction_metrics import FeatureExtractor

#: L2 strength λ of the weights (features are standardised).
RIDGE = 1e-2


class InteractionRecognizer:
    """Multinomial logistic regression of two-person windows (module docstring).

    Args:
        extractor: window features, ``(N, T, J, 3) -> (N, D)``.
        ridge: λ.
        use_actor: features of both people (True) or of the reactor only.
    """

    def __init__(self, extractor: FeatureExtractor, ridge: float = RIDGE,
                 use_actor: bool = True) -> None:
        if not ridge > 0:
            raise MotionError(f"ridge must be > 0; got {ridge!r}", field="ridge")
        self.extractor = extractor
        self.ridge = float(ridge)
        self.use_actor = bool(use_actor)
        self.classes: tuple[int, ...] = ()
        self._mean = self._std = self._w = None

    def _features(self, actor: np.ndarray, reactor: np.ndarray) -> np.ndarray:
        a, b = np.asarray(actor, np.float64), np.asarray(reactor, np.float64)
        if a.shape != b.shape or a.ndim != 4 or a.shape[-1] != 3:
            raise MotionError(f"actor and reactor must both be (N, T, J, 3); got {a.shape} "
                              f"and {b.shape}", field="reactor")
        if not self.use_actor:
            return self.extractor(b)
        return np.concatenate([self.extractor(a), self.extractor(b)], axis=1)

    def fit(self, actor: np.ndarray, reactor: np.ndarray, labels: Sequence[int]
            ) -> InteractionRecognizer:
        """Train on real windows: (N, T, J, 3) actor and reactor, (N,) integer labels."""
        y = np.asarray(labels, dtype=np.int64)
        x = self._features(actor, reactor)
        if len(y) != len(x) or len(x) == 0:
            raise MotionError(f"{len(x)} windows but {len(y)} labels", field="labels")
        self.classes = tuple(int(c) for c in np.unique(y))
        self._mean, self._std = x.mean(0), x.std(0) + 1e-8
        z = np.hstack([(x - self._mean) / self._std, np.ones((len(x), 1))])
        onehot = (y[:, None] == np.asarray(self.classes)[None]).astype(np.float64)
        shape = (z.shape[1], len(self.classes))
        decay = np.ones(shape)
        decay[-1] = 0.0

        def loss(flat: np.ndarray) -> tuple[float, np.ndarray]:
            w = flat.reshape(shape)
            s = z @ w
            s -= s.max(axis=1, keepdims=True)
            logp = s - np.log(np.exp(s).sum(axis=1, keepdims=True))
            grad = z.T @ (np.exp(logp) - onehot) / len(z) + self.ridge * decay * w
            value = -(onehot * logp).sum() / len(z) + 0.5 * self.ridge * (decay * w * w).sum()
            return float(value), grad.ravel()

        # scipy.optimize takes ~1 s to import; only fitting needs it.
        from scipy.optimize import minimize

        res = minimize(loss, np.zeros(np.prod(shape)), jac=True, method="L-BFGS-B",
                       options={"maxiter": 500})
        self._w = res.x.reshape(shape)
        return self

    def predict(self, actor: np.ndarray, reactor: np.ndarray) -> np.ndarray:
        """(N,) predicted labels of (N, T, J, 3) actor and reactor windows."""
        if self._w is None:
            raise MotionError("the recognizer is not trained; call fit() first")
        z = (self._features(actor, reactor) - self._mean) / self._std
        scores = np.hstack([z, np.ones((len(z), 1))]) @ self._w
        return np.asarray(self.classes)[np.argmax(scores, axis=1)]

    def accuracy(self, actor: np.ndarray, reactor: np.ndarray, labels: Sequence[int]
                 ) -> tuple[float, int]:
        """(accuracy over windows of trained classes, how many windows that is); the
        accuracy is NaN when no window has a trained class."""
        y = np.asarray(labels, dtype=np.int64)
        keep = np.isin(y, self.classes)
        if not keep.any():
            return float("nan"), 0
        pred = self.predict(np.asarray(actor)[keep], np.asarray(reactor)[keep])
        return float(np.mean(pred == y[keep])), int(keep.sum())

"""Covariance descriptors of skeleton sequences and a ridge classifier on them.

A second model family for the recognition benchmarks, beside the networks: the covariance
of the joint coordinates over time (Hussein et al. 2013, "Cov3DJ"), which sees how the
joints move *together* (a hand against the other, the hands against the head) whatever
the speed, and errs where a network errs differently (measured: docs/recognition.md).

**Descriptor.** A clip's real frames, normalised as the networks see them (body-centred,
scale-normalised: :func:`simenv.data.gestures.normalise_windows`), give per frame the
stacked joint coordinates ``s_t`` (3J) and, with ``velocity``, their frame difference
``s_t - s_{t-1}`` (6J in all). Over a window of frames the descriptor is the upper triangle
of the sample covariance ``C = 1/(n-1) sum_t (s_t - m)(s_t - m)^T``. A temporal pyramid
keeps the order of the movement: level ``l`` = 0 .. L-1 has windows of ``T / 2^l`` frames
starting every ``T / 2^(l+1)`` (overlapping by half): 1 + 3 + 7 windows for L = 3, the
paper's best. The clip's descriptor is their concatenation, ``W D (D + 1) / 2`` numbers.

**Classifier.** Ridge regression of one-versus-rest targets (+1 for the class, -1 for the
others) on the standardised descriptors (each dimension to zero mean, unit variance over
the training clips), solved in the dual because clips are far fewer than dimensions:
``(K + lambda I) alpha = Y``, ``K = A A^T``, scores ``B A^T alpha``. A descriptor may be
given as blocks (e.g. covariance and Lie-group descriptors of the same clips,
:mod:`simenv.learning.lie_group`): each block ``b`` of ``F_b`` of the ``F`` dimensions is
standardised and scaled by ``sqrt(F / (n_blocks F_b))``, so that every block weighs the same
in ``K`` whatever its size (one block is left as it is). The regulariser
``lambda`` and the descriptor variant (which joints, with or without velocities) are chosen
by leave-one-training-subject-out accuracy, never on test clips (the standardisation is
computed once on all training clips, labels unused, so the held-out subject's Gram rows are
read from one matrix); the held-out scores of the
chosen setting then fit a softmax temperature (least negative log-likelihood), so that
:meth:`CovarianceClassifier.predict_proba` gives probabilities calibrated on subjects the
fit did not see, and can be multiplied with another model's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from simenv.core.errors import SimenvError

#: A descriptor variant of N clips: one (N, F) array, or blocks of the same N clips.
Descriptor = np.ndarray | tuple[np.ndarray, ...]

#: Temporal pyramid levels (L): 1 + 3 + 7 windows.
PYRAMID_LEVELS = 3
#: Ridge regularisers tried by the leave-one-subject-out selection.
RIDGE_LAMBDAS: tuple[float, ...] = (1e2, 1e3, 1e4, 1e5, 1e6)
#: Softmax temperatures tried for the held-out scores (log-spaced).
TEMPERATURES = np.geomspace(0.01, 10.0, 61)


def pyramid_windows(length: int, levels: int = PYRAMID_LEVELS) -> list[tuple[int, int]]:
    """``[start, stop)`` frame windows of the temporal pyramid (module docstring) of a
    ``length``-frame clip; every window spans at least 2 frames (a short clip repeats
    them)."""
    if length < 2:
        raise SimenvError(f"a covariance needs at least 2 frames; got {length}",
                          field="frames")
    out = []
    for level in range(levels):
        span = length / 2 ** level
        for k in range(2 ** (level + 1) - 1):
            start = min(int(round(k * span / 2)), length - 2)
            out.append((start, max(int(round(k * span / 2 + span)), start + 2)))
    return out


def covariance_descriptor(frames: np.ndarray, velocity: bool = True,
                          levels: int = PYRAMID_LEVELS) -> np.ndarray:
    """The descriptor of one clip (module docstring).

    Args:
        frames: (T, J, 3) real frames, normalised; T >= 2.
        velocity: stack the frame differences with the coordinates.

    Returns:
        (W D (D + 1) / 2,) float64, D = 3J (6J with ``velocity``), W the pyramid's windows.

    Raises:
        SimenvError: fewer than 2 frames or non-finite coordinates.
    """
    frames = np.asarray(frames, np.float64)
    if frames.ndim != 3 or frames.shape[-1] != 3:
        raise SimenvError(f"frames must be (T, J, 3); got {frames.shape}", field="frames")
    if not np.isfinite(frames).all():
        raise SimenvError("frames hold non-finite coordinates", field="frames")
    s = frames.reshape(len(frames), -1)
    if velocity:
        s = np.concatenate([s, np.diff(s, axis=0, prepend=s[:1])], axis=1)
    upper = np.triu_indices(s.shape[1])
    return np.concatenate([np.cov(s[a:b], rowvar=False)[upper]
                           for a, b in pyramid_windows(len(s), levels)])


def descriptors(x: np.ndarray, valid: np.ndarray, velocity: bool = True) -> np.ndarray:
    """(N, F) descriptors of normalised windows ``x`` (N, T, J, 3), each over its real
    frames (``valid`` (N, T) bool)."""
    return np.stack([covariance_descriptor(seq[np.asarray(v, bool)], velocity)
                     for seq, v in zip(x, valid, strict=True)])


def _softmax(z: np.ndarray) -> np.ndarray:
    z = z - z.max(1, keepdims=True)
    e = np.exp(z)
    return e / e.sum(1, keepdims=True)


def _fit_temperature(scores: np.ndarray, y: np.ndarray) -> float:
    """The softmax temperature of :data:`TEMPERATURES` with the least mean NLL of ``y``."""
    nll = [-np.log(_softmax(scores / t)[np.arange(len(y)), y] + 1e-300).mean()
           for t in TEMPERATURES]
    return float(TEMPERATURES[int(np.argmin(nll))])


def _blocks(descriptor: Descriptor) -> tuple[np.ndarray, ...]:
    return descriptor if isinstance(descriptor, tuple) else (descriptor,)


def _block_weights(blocks: Sequence[np.ndarray]) -> list[float]:
    """``sqrt(F / (n_blocks F_b))`` of each block (module docstring)."""
    total = sum(b.shape[1] for b in blocks)
    return [float(np.sqrt(total / (len(blocks) * b.shape[1]))) for b in blocks]


class _Standardised:
    """One block's training statistics and the Gram matrix of its standardised training
    rows (a fit computes it once per block, since variants share blocks)."""

    def __init__(self, block: np.ndarray) -> None:
        block = np.asarray(block, np.float64)
        self.mean, self.scale = block.mean(0), block.std(0) + 1e-12
        z = self.apply(block)
        self.gram = z @ z.T

    def apply(self, block: np.ndarray) -> np.ndarray:
        return (np.asarray(block, np.float64) - self.mean) / self.scale


class CovarianceClassifier:
    """Ridge classifier on covariance descriptors, or any descriptors of the same clips given
    as blocks beside or instead of them (module docstring).

    Args:
        num_classes: C, labels are 0 .. C-1.
        lambdas: regularisers the leave-one-subject-out selection tries.

    After :meth:`fit`: ``variant`` (the descriptor variant chosen), ``lam``, ``temperature``
    and ``selection`` ({variant: {lambda: held-out accuracy}}).
    """

    def __init__(self, num_classes: int, lambdas: Sequence[float] = RIDGE_LAMBDAS) -> None:
        if num_classes < 2:
            raise SimenvError(f"num_classes must be >= 2; got {num_classes}",
                              field="num_classes")
        if not lambdas or min(lambdas) <= 0:
            raise SimenvError(f"lambdas must be positive; got {tuple(lambdas)}",
                              field="lambdas")
        self.num_classes = int(num_classes)
        self.lambdas = tuple(float(v) for v in lambdas)
        self.variant = ""
        self.lam = 0.0
        self.temperature = 1.0
        self.selection: dict[str, dict[float, float]] = {}
        # Per block of the chosen variant (statistics, weight, standardised training rows)
        # and the dual weights, once fitted.
        self._fitted: tuple[list[tuple[_Standardised, float, np.ndarray]], np.ndarray] | None
        self._fitted = None

    def _targets(self, y: np.ndarray) -> np.ndarray:
        t = -np.ones((len(y), self.num_classes))
        t[np.arange(len(y)), y] = 1.0
        return t

    def fit(self, variants: Mapping[str, Descriptor], y: np.ndarray,
            groups: np.ndarray) -> CovarianceClassifier:
        """Choose the variant and ``lambda``, fit the temperature and the final weights.

        Args:
            variants: name -> (N, F_v) descriptors of the same N training clips, or a tuple
                of such blocks (module docstring).
            y: (N,) int labels in 0 .. C-1.
            groups: (N,) subject of each clip (held out one at a time; at least 2).

        Raises:
            SimenvError: no variant, mismatched lengths, labels out of range, fewer than two
                subjects or non-finite descriptors.
        """
        y, groups = np.asarray(y, int), np.asarray(groups)
        if not variants:
            raise SimenvError("no descriptor variant to fit", field="variants")
        for name, d in variants.items():
            for a in _blocks(d):
                if a.ndim != 2 or len(a) != len(y) or len(groups) != len(y):
                    raise SimenvError(f"variant {name!r}: {len(a)} descriptors, {len(y)} "
                                      f"labels, {len(groups)} groups (descriptors must be "
                                      f"(N, F); got {a.shape})", field="variants")
                if not np.isfinite(a).all():
                    raise SimenvError(f"variant {name!r} holds non-finite descriptors",
                                      field="variants")
        if y.min() < 0 or y.max() >= self.num_classes:
            raise SimenvError(f"labels must be in 0..{self.num_classes - 1}", field="y")
        subjects = np.unique(groups)
        if len(subjects) < 2:
            raise SimenvError("the selection holds out one subject at a time: needs at "
                              f"least 2; got {len(subjects)}", field="groups")
        targets = self._targets(y)
        best: tuple[float, str, float, np.ndarray] | None = None
        cache: dict[int, _Standardised] = {}

        def gram_of(blocks: tuple[np.ndarray, ...]) -> np.ndarray:
            for a in blocks:
                if id(a) not in cache:
                    cache[id(a)] = _Standardised(a)
            return sum(w * w * cache[id(a)].gram
                       for a, w in zip(blocks, _block_weights(blocks), strict=True))

        for name, d in variants.items():
            gram = gram_of(_blocks(d))
            self.selection[name] = {}
            for lam in self.lambdas:
                held = np.zeros_like(targets)
                for s in subjects:
                    out = groups == s
                    k = gram[np.ix_(~out, ~out)]
                    alpha = np.linalg.solve(k + lam * np.eye(len(k)), targets[~out])
                    held[out] = gram[np.ix_(out, ~out)] @ alpha
                acc = float((held.argmax(1) == y).mean())
                self.selection[name][lam] = acc
                if best is None or acc > best[0]:
                    best = (acc, name, lam, held)
        assert best is not None
        _, self.variant, self.lam, held = best
        self.temperature = _fit_temperature(held, y)
        blocks = _blocks(variants[self.variant])
        fitted = [(cache[id(a)], w, w * cache[id(a)].apply(a))
                  for a, w in zip(blocks, _block_weights(blocks), strict=True)]
        self._fitted = (fitted, np.linalg.solve(gram_of(blocks) + self.lam * np.eye(len(y)),
                                                targets))
        return self

    def predict_proba(self, variants: Mapping[str, Descriptor]) -> np.ndarray:
        """(N, C) class probabilities of clips given by their descriptors (the fitted
        ``variant`` must be among ``variants``, in the same blocks).

        Raises:
            SimenvError: not fitted, the variant missing, or the wrong descriptor size.
        """
        if self._fitted is None:
            raise SimenvError("fit the classifier first", field="variant")
        if self.variant not in variants:
            raise SimenvError(f"descriptor variant {self.variant!r} missing; got "
                              f"{sorted(variants)}", field="variants")
        fitted, alpha = self._fitted
        blocks = _blocks(variants[self.variant])
        widths = [len(st.mean) for st, _, _ in fitted]
        if (len(blocks) != len(fitted)
                or any(b.ndim != 2 or b.shape[1] != f for b, f in zip(blocks, widths,
                                                                      strict=True))
                or len({len(b) for b in blocks}) != 1):
            raise SimenvError(f"descriptors must be blocks of (N, F) with F = {widths}; got "
                              f"{[b.shape for b in blocks]}", field="variants")
        scores = sum((w * st.apply(b)) @ z.T @ alpha
                     for b, (st, w, z) in zip(blocks, fitted, strict=True))
        return _softmax(scores / self.temperature)

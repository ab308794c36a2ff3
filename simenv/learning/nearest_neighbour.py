"""The simplest recogniser: one nearest neighbour on normalised skeleton sequences.

The baseline a learned recogniser has to beat to earn its keep (the recognition benchmarks
report it beside the networks). Each clip is taken as the networks see it, body-centred and
scale-normalised (:func:`simenv.data.gestures.normalise_windows`), and resampled to ``L``
samples evenly spaced in time over its real frames, ``a_t`` (J, 3) for t = 1..L. The frame
cost is the mean joint distance ``c(a_t, b_s) = (1/J) sum_j ||a_tj - b_sj||`` (normalised
units: a reference body's size is 1 m). A test clip takes the label of the training clip at
the smallest distance:

* ``euclidean``: frames matched by their time fraction, ``d(a, b) = (1/L) sum_t c(a_t, b_t)``;
* ``dtw``: dynamic time warping over the same samples,
  ``D(t, s) = c(a_t, b_s) + min(D(t-1, s), D(t, s-1), D(t-1, s-1))``, ``d(a, b) = D(L, L) / (2L)``,
  so that one performer may run ahead of the other within the clip.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from simenv.core.errors import SimenvError

NeighbourDistance = Literal["euclidean", "dtw"]
#: Distances of :func:`nearest_neighbour`.
NEIGHBOUR_DISTANCES: tuple[str, ...] = ("euclidean", "dtw")
#: Samples per clip (``L``): 40 spans a 1.6 s clip at 25 fps frame by frame.
NEIGHBOUR_SAMPLES = 40


def resample_sequences(x: np.ndarray, valid: np.ndarray,
                       samples: int = NEIGHBOUR_SAMPLES) -> np.ndarray:
    """Each sequence's real frames resampled (linear in time) to ``samples`` frames.

    Args:
        x: (N, T, J, 3) normalised windows.
        valid: (N, T) bool, True for real frames; the real frames of a row need not be
            contiguous (the padding is skipped).

    Returns:
        (N, samples, J, 3) float32.

    Raises:
        SimenvError: a sequence without a real frame, or ``samples`` < 1.
    """
    if samples < 1:
        raise SimenvError(f"samples must be >= 1; got {samples}", field="samples")
    out = np.empty((len(x), samples, *x.shape[2:]), np.float32)
    for n, (seq, v) in enumerate(zip(x, valid, strict=True)):
        real = seq[np.asarray(v, bool)]
        if not len(real):
            raise SimenvError(f"sequence {n} has no real frame", field="valid")
        at = np.linspace(0.0, len(real) - 1, samples)
        lo = np.floor(at).astype(int)
        hi = np.minimum(lo + 1, len(real) - 1)
        w = (at - lo)[:, None, None].astype(np.float32)
        out[n] = (1 - w) * real[lo] + w * real[hi]
    return out


def _frame_costs(a: np.ndarray, train: np.ndarray) -> np.ndarray:
    """c(a_t, b_s) for every training sequence b: (N, L, L) from a (L, J, 3), train (N, L, J, 3)."""
    diff = a[None, :, None] - train[:, None, :]  # (N, L, L, J, 3)
    return np.linalg.norm(diff, axis=-1).mean(-1)


def _dtw(cost: np.ndarray) -> np.ndarray:
    """D(L, L) / (2L) of the module docstring for a batch of cost matrices (N, L, L)."""
    n, length, _ = cost.shape
    acc = np.full((n, length + 1, length + 1), np.inf)
    acc[:, 0, 0] = 0.0
    for t in range(1, length + 1):
        for s in range(1, length + 1):
            acc[:, t, s] = cost[:, t - 1, s - 1] + np.minimum(
                np.minimum(acc[:, t - 1, s], acc[:, t, s - 1]), acc[:, t - 1, s - 1])
    return acc[:, length, length] / (2 * length)


def distances(test: np.ndarray, train: np.ndarray,
              distance: NeighbourDistance = "euclidean") -> np.ndarray:
    """Distance of every test sequence to every training sequence (module docstring).

    Args:
        test: (M, L, J, 3) resampled normalised sequences (:func:`resample_sequences`).
        train: (N, L, J, 3) likewise.
        distance: ``euclidean`` or ``dtw``.

    Returns:
        (M, N) float64, normalised units.

    Raises:
        SimenvError: unknown distance, or the two sets differ in samples or joints.
    """
    if distance not in NEIGHBOUR_DISTANCES:
        raise SimenvError(f"unknown distance {distance!r}; expected one of "
                          f"{', '.join(NEIGHBOUR_DISTANCES)}", field="distance")
    if test.shape[1:] != train.shape[1:]:
        raise SimenvError(f"test sequences are {test.shape[1:]} (samples, joints, 3), "
                          f"training ones {train.shape[1:]}", field="shape")
    out = np.empty((len(test), len(train)))
    for m, a in enumerate(test):
        if distance == "euclidean":
            out[m] = np.linalg.norm(a[None] - train, axis=-1).mean(axis=(1, 2))
        else:
            out[m] = _dtw(_frame_costs(a, train))
    return out


def nearest_neighbour(test: np.ndarray, train: np.ndarray, train_labels: np.ndarray,
                      distance: NeighbourDistance = "euclidean") -> np.ndarray:
    """The label of each test sequence's nearest training sequence.

    Args:
        test, train: resampled normalised sequences, as for :func:`distances`.
        train_labels: (N,) int class of each training sequence.

    Returns:
        (M,) int labels.

    Raises:
        SimenvError: as :func:`distances`; no training sequence, or labels of another length.
    """
    labels = np.asarray(train_labels)
    if not len(train) or len(labels) != len(train):
        raise SimenvError(f"{len(train)} training sequences and {len(labels)} labels; "
                          "expected one label each and at least one sequence",
                          field="train_labels")
    return labels[distances(test, train, distance).argmin(axis=1)]

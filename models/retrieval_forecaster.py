"""The nearest-neighbour forecaster: continue a motion as the most similar recorded one went on.

The simplest data-driven forecasting baseline (motion retrieval), beside zero- and
constant-velocity, for the gesture-domain forecaster of :mod:`simenv.models.gesture_predictor`.

Bank: every window of H + F frames of the training recordings. Each window is expressed
in the body frame of its last history frame (:func:`~simenv.models.gesture_predictor.body_frame`:
origin the spine, heading from the shoulders; ``b = R_z(-θ)(x - o)``), so a wave recorded
facing north matches one performed facing east. A history ``h`` (H, 15, 3) is turned into
its own body frame, and its distance to bank window ``i`` is

    d_i = || b(h) - b(h_i) ||_2   over all H x 15 x 3 coordinates, metres;

the forecast is the mean body-frame future of the ``k`` nearest windows, turned back into
the world by the history's frame: ``x̂ = R_z(θ) mean_{i in kNN} b(f_i) + o``.
"""

from __future__ import annotations

import numpy as np

from simenv.core.errors import MotionError
from simenv.models.baselines import check_history
from simenv.models.gesture_predictor import body_frame, from_body, to_body

#: Histories compared per block (bounds the (block, bank) distance matrix in memory).
_BLOCK = 512


class NearestNeighbourForecaster:
    """Forecast ``future_len`` frames by retrieval (module docstring); a
    :class:`~simenv.models.baselines.Predictor`.

    Args:
        windows: (M, H + F, 15, 3) world positions, metres, Z up: the bank (training
            windows of ``history_len + future_len`` frames).
        history_len: H, frames compared.
        k: neighbours averaged (1: the nearest window's future as it was).
        fps: frame rate of the windows.
        heading_frames: frames whose shoulders give the heading (as the learned forecaster).

    Raises:
        MotionError: an empty bank, windows of another shape or with non-finite values,
            ``k`` not in 1..M, or no frame left to forecast.
    """

    def __init__(self, windows: np.ndarray, history_len: int, *, k: int = 1,
                 fps: float = 25.0, heading_frames: int = 3) -> None:
        w = np.asarray(windows, np.float64)
        if w.ndim != 4 or w.shape[2:] != (15, 3) or not len(w):
            raise MotionError(f"bank windows must be (M >= 1, T, 15, 3); got {w.shape}",
                              field="windows")
        if not 1 <= history_len < w.shape[1]:
            raise MotionError(f"history_len must be in 1..{w.shape[1] - 1} for windows of "
                              f"{w.shape[1]} frames; got {history_len}", field="history_len")
        if not 1 <= k <= len(w):
            raise MotionError(f"k must be in 1..{len(w)} (the bank's windows); got {k}",
                              field="k")
        bad = np.argwhere(~np.isfinite(w))
        if len(bad):
            raise MotionError(f"bank window {int(bad[0, 0])} has a non-finite value",
                              frame=int(bad[0, 1]), field="windows")
        self.history_len = int(history_len)
        self.future_len = w.shape[1] - self.history_len
        self.fps = float(fps)
        self.k = int(k)
        self.heading_frames = int(heading_frames)
        origin, angle = body_frame(w[:, :history_len], heading_frames)
        body = to_body(w, origin, angle)
        # float64: the distance's expansion |q|^2 + |k|^2 - 2 q.k cancels to millimetres
        # between near neighbours, which float32 would blur.
        self._keys = body[:, :history_len].reshape(len(w), -1)
        self._key_sq = (self._keys ** 2).sum(1)
        self._futures = body[:, history_len:].astype(np.float32)

    @property
    def bank_size(self) -> int:
        """Windows in the bank (M)."""
        return len(self._keys)

    def _history(self, history: np.ndarray) -> tuple[np.ndarray, bool]:
        """The last H frames of a checked history, batched, and whether it came batched."""
        h, batched = check_history(history, self.history_len)
        if h.shape[2] != 15:
            raise MotionError(f"history has {h.shape[2]} joints; this forecaster expects "
                              "the 15 of gesture15 (simenv.data.gestures.GESTURE15_JOINTS)",
                              field="history")
        return h[:, -self.history_len:], batched

    def neighbours(self, history: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The ``k`` nearest bank windows of each history: (N, k) indices, nearest first,
        and (N, k) distances, metres (module docstring). ``history`` as for :meth:`predict`."""
        h, _ = self._history(history)
        return self._search(h, *body_frame(h, self.heading_frames))

    def _search(self, h: np.ndarray, origin: np.ndarray, angle: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`neighbours` of checked histories ``h`` (N, H, 15, 3) in their body frames."""
        query = to_body(h, origin, angle).reshape(len(h), -1)
        index = np.empty((len(h), self.k), np.int64)
        dist = np.empty((len(h), self.k))
        for s in range(0, len(h), _BLOCK):
            q = query[s:s + _BLOCK]
            d2 = ((q ** 2).sum(1)[:, None] + self._key_sq[None]
                  - 2.0 * (q @ self._keys.T))
            near = np.argpartition(d2, self.k - 1, axis=1)[:, :self.k]
            order = np.argsort(np.take_along_axis(d2, near, 1), axis=1)
            index[s:s + _BLOCK] = np.take_along_axis(near, order, 1)
            dist[s:s + _BLOCK] = np.sqrt(np.maximum(
                np.take_along_axis(d2, index[s:s + _BLOCK], 1), 0.0))
        return index, dist

    def predict(self, history: np.ndarray) -> np.ndarray:
        """(N, H', 15, 3) or (H', 15, 3) world history, metres (H' >= H; the last H frames
        are used) -> (N, F, 15, 3) or (F, 15, 3) float32 world forecast, metres.

        Raises:
            MotionError: a wrong shape, too few frames, a non-finite value, or shoulders
                with no horizontal separation (no heading).
        """
        h, batched = self._history(history)
        origin, angle = body_frame(h, self.heading_frames)
        index, _ = self._search(h, origin, angle)
        future = self._futures[index].astype(np.float64).mean(axis=1)
        out = from_body(future, origin, angle).astype(np.float32)
        return out if batched else out[0]

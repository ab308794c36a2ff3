"""Baseline motion predictors with the interface of the PredictiveMA-WGAN predictor.

Interface (:class:`Predictor`): ``predict(history) -> future`` where ``history`` is an
(N, H, J, 3) array of root-relative positions in metres ending at the last observed
frame (for the learned model H = 1 + P: the lead-in frame and the P observed frames,
see :mod:`simenv.data.prediction_data`) and ``future`` is the (N, F, J, 3) float32 array of
the F frames that follow it. A single (H, J, 3) history gives a single (F, J, 3) future.

* zero-velocity: ``x̂_{T+k} = x_T`` (repeat the last observed pose);
* constant-velocity: ``x̂_{T+k} = x_T + k (x_T - x_{T-1})`` (extrapolate the last
  frame-to-frame displacement linearly).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from simenv.core.errors import MotionError


@runtime_checkable
class Predictor(Protocol):
    """Anything that predicts ``future_len`` frames at ``fps`` from a history."""

    future_len: int
    fps: float

    @property
    def history_len(self) -> int:
        """Frames of history needed (the last ``history_len`` frames are used)."""
        ...

    def predict(self, history: np.ndarray) -> np.ndarray:
        """(N, H, J, 3) or (H, J, 3) history, metres -> (N, F, J, 3) or (F, J, 3)."""
        ...


def check_history(history: np.ndarray, need: int, *, joints: int | None = None
                  ) -> tuple[np.ndarray, bool]:
    """Validate a history and add a batch axis: returns ((N, H, J, 3) float64, batched).

    Raises:
        MotionError: wrong shape, fewer than ``need`` frames, wrong joint count, or a
            non-finite value (the message names window and frame).
    """
    try:
        h = np.asarray(history, dtype=np.float64)
    except (TypeError, ValueError):
        raise MotionError("history must be a numeric (N, H, J, 3) array",
                          field="history") from None
    batched = h.ndim == 4
    if h.ndim == 3:
        h = h[None]
    if h.ndim != 4 or h.shape[-1] != 3:
        raise MotionError(
            f"history must have shape (N, H, J, 3) or (H, J, 3); got {np.shape(history)}",
            field="history",
        )
    if h.shape[1] < need:
        raise MotionError(
            f"history has {h.shape[1]} frames; this predictor needs at least {need} "
            "(ending at the last observed frame)",
            field="history",
        )
    if joints is not None and h.shape[2] != joints:
        raise MotionError(
            f"history has {h.shape[2]} joints; this predictor expects {joints} "
            "(the pred17 layout of simenv.data.prediction_data)",
            field="history",
        )
    bad = ~np.isfinite(h)
    if bad.any():
        n, f, j, _ = (int(i) for i in np.argwhere(bad)[0])
        raise MotionError(f"history has a non-finite value in window {n}, joint {j}",
                          frame=f, field="history")
    return h, batched


class Extrapolator:
    """Base of the closed-form baselines: ``future_len`` frames at ``fps`` from the last
    ``history_len`` observed frames (a :class:`Predictor`).

    Raises:
        MotionError: ``future_len`` not a positive integer.
    """

    history_len: int

    def __init__(self, future_len: int, fps: float = 25.0) -> None:
        if int(future_len) != future_len or future_len < 1:
            raise MotionError(f"future_len must be a positive integer; got {future_len!r}",
                              field="future_len")
        self.future_len = int(future_len)
        self.fps = float(fps)


class ZeroVelocity(Extrapolator):
    """Repeat the last observed pose for ``future_len`` frames."""

    history_len = 1

    def predict(self, history: np.ndarray) -> np.ndarray:
        h, batched = check_history(history, self.history_len)
        out = np.repeat(h[:, -1:], self.future_len, axis=1).astype(np.float32)
        return out if batched else out[0]


class ConstantVelocity(Extrapolator):
    """Continue the last frame-to-frame displacement: ``x_T + k (x_T - x_{T-1})``."""

    history_len = 2

    def predict(self, history: np.ndarray) -> np.ndarray:
        h, batched = check_history(history, self.history_len)
        k = np.arange(1, self.future_len + 1, dtype=np.float64)[None, :, None, None]
        out = (h[:, -1:] + k * (h[:, -1:] - h[:, -2:-1])).astype(np.float32)
        return out if batched else out[0]

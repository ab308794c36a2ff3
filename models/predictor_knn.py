"""Motion-matching (k-nearest-neighbour) motion predictor: a nonparametric baseline.

Predicts the future of a history by finding the training windows whose recent past looks
most like it and averaging what happened next. It has no trained weights, so its errors
are unlike those of the learned regressors (:mod:`simenv.models.predictor_regression`),
which is what a blend of predictors (:mod:`simenv.models.predictor_blend`) needs.
Same ``predict(history)`` interface and pred17 layout as the other predictors.

Math (one query; H = 1 + P history frames, F future frames)
-------------------------------------------------------------
1. **Heading.** Every window (database and query) is rotated about Z so that the hip
   axis of its last observed pose ``x_T`` points along +X
   (:func:`simenv.models.predictor.heading`).
2. **Feature** (metres): ``φ(h) = [x_T, w_v · (5 / l)(x_T - x_{T-l}) for l in
   VELOCITY_LAGS, w_h · (x_{T-l} - x_T) for l in HISTORY_LAGS]``: the last pose, its
   velocities (scaled to the displacement over 5 frames = 0.2 s) and the history
   relative to the last pose, with weights ``w_v``, ``w_h`` (``velocity_weight``,
   ``history_weight``).
3. **Neighbours.** The k windows ``i`` with the smallest ``d_i = ||φ(h) - φ(h_i)||``
   among the database windows and, with ``mirror``, their left-right mirror images
   (:func:`simenv.models.predictor.mirror`; searched by mirroring the query, which is
   the same search since mirroring keeps a heading-normalised pose normalised).
4. **Future.** ``x̂_{T+j} = x_T + α Σ_i w_i (y_{i,j} - y_{i,T})``, the neighbours'
   future displacements from *their* last pose added to the query's last pose, with
   inverse-distance weights ``w_i ∝ 1 / (d_i + ε)`` and a shrinkage ``α`` toward
   zero-velocity (``α = 0`` is zero-velocity); then rotated back to the query's heading.

``k``, ``w_v``, ``w_h`` and ``α`` are chosen on validation clips
(:mod:`simenv.train_predictor_families`). The database is stored as the training
sequences themselves (root-relative frames), from which windows, features and futures
are rebuilt at load time, so a checkpoint is a few MB.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from simenv.errors import MotionError
from simenv.models.baselines import check_history
from simenv.models.checkpoint import CheckpointError
from simenv.models.predictor import NUM_JOINTS, heading, mirror, rotate_z

#: Format tag of checkpoint files.
CHECKPOINT_FORMAT = "simenv-knn-predictor-1"

#: Frame lags of the velocity features (x_T - x_{T-l}).
VELOCITY_LAGS: tuple[int, ...] = (1, 2)
#: Frame lags of the history features (x_{T-l} - x_T); lags beyond P are dropped.
HISTORY_LAGS: tuple[int, ...] = (5, 10, 15, 25)
#: Queries per distance block (bounds the memory of the distance matrix).
CHUNK = 256
#: Queries per block of gathered neighbour futures.
SUM_CHUNK = 32
_EPS = 1e-6


@dataclass
class KNNConfig:
    """Hyper-parameters (saved in checkpoints)."""

    past_len: int
    future_len: int
    fps: float = 25.0
    k: int = 16
    velocity_weight: float = 1.0
    history_weight: float = 0.5
    #: α: 0 is zero-velocity, 1 the neighbours' mean displacement.
    shrinkage: float = 1.0
    #: Search the mirror images of the database windows too.
    mirror: bool = True
    info: dict = field(default_factory=dict)


def _lags(past_len: int, lags: Sequence[int]) -> tuple[int, ...]:
    return tuple(lag for lag in lags if lag <= past_len)


def normalised(frames: np.ndarray, last: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """(N, T, 17, 3) metres -> the frames rotated to the heading of frame ``last`` (the
    last observed pose; -1 for a history) and the heading angles (N,) rad."""
    angle = heading(frames[:, last])
    return rotate_z(np.asarray(frames, dtype=np.float64), -angle), angle


def features(history: np.ndarray, config: KNNConfig) -> np.ndarray:
    """(N, H, 17, 3) heading-normalised history, metres -> (N, D) float64 features φ
    (parts with weight 0 are left out)."""
    last = history[:, -1]
    parts = [last]
    if config.velocity_weight:
        parts += [config.velocity_weight * (5.0 / lag) * (last - history[:, -1 - lag])
                  for lag in _lags(config.past_len, VELOCITY_LAGS)]
    if config.history_weight:
        parts += [config.history_weight * (history[:, -1 - lag] - last)
                  for lag in _lags(config.past_len, HISTORY_LAGS)]
    n = len(history)
    return np.concatenate([p.reshape(n, -1) for p in parts], axis=1)


class KNNPredictor:
    """Motion matching over a database of training sequences (module docstring).

    ``predict(history)``: (N, 1 + P, 17, 3) (or longer) root-relative pred17 positions,
    metres -> (N, F, 17, 3) float32 future.
    """

    def __init__(self, config: KNNConfig, sequences: Sequence[np.ndarray]) -> None:
        if config.k < 1:
            raise MotionError(f"k must be >= 1; got {config.k}", field="k")
        self.config = config
        self.past_len = config.past_len
        self.future_len = config.future_len
        self.fps = config.fps
        self.sequences = [np.asarray(s, dtype=np.float32) for s in sequences]
        length = self.history_len + self.future_len
        for i, s in enumerate(self.sequences):
            if s.ndim != 3 or s.shape[1:] != (NUM_JOINTS, 3):
                raise MotionError(f"sequence {i} must have shape (T, 17, 3); got {s.shape}",
                                  field="sequences")
        starts = [(i, o) for i, s in enumerate(self.sequences)
                  for o in range(len(s) - length + 1)]
        if not starts:
            raise MotionError(f"no sequence gives a window of {length} frames "
                              f"({self.history_len} history + {self.future_len} future)",
                              field="sequences")
        feats, futures = [], []
        h = self.history_len
        for a in range(0, len(starts), CHUNK):  # blocks: all windows at once is ~0.2 GB
            frames, _ = normalised(np.stack([self.sequences[i][o : o + length]
                                             for i, o in starts[a : a + CHUNK]]), h - 1)
            feats.append(features(frames[:, :h], config))
            futures.append((frames[:, h:] - frames[:, h - 1 : h]).astype(np.float32))
        feats = np.concatenate(feats)
        # centred float32: a fast product, and centring keeps the squared distances
        # (differences of large terms) accurate in float32
        self.db_mean = feats.mean(0)
        self.db_features = (feats - self.db_mean).astype(np.float32)
        self.db_sqnorm = (self.db_features.astype(np.float64) ** 2).sum(1)
        self.db_future = np.concatenate(futures)

    @property
    def history_len(self) -> int:
        return self.past_len + 1

    @property
    def num_windows(self) -> int:
        """Windows in the database (mirror images not counted)."""
        return len(self.db_features)

    def reweighted(self, velocity_weight: float, history_weight: float) -> KNNPredictor:
        """A predictor on the same database with other feature weights (the features
        are rebuilt; ``k`` and ``shrinkage`` are kept)."""
        config = KNNConfig(**{**asdict(self.config), "velocity_weight": velocity_weight,
                              "history_weight": history_weight})
        return KNNPredictor(config, self.sequences)

    def neighbours(self, history: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The k nearest database windows of heading-normalised histories.

        Args:
            history: (N, H, 17, 3) heading-normalised, metres.
            k: neighbours per query.

        Returns:
            ``(index, distance)``: (N, k) int64 and float64, nearest first; an index
            ``i >= num_windows`` is the mirror image of window ``i - num_windows``.
        """
        queries = [features(history, self.config)]
        if self.config.mirror:
            queries.append(features(mirror(history), self.config))
        queries = [(q - self.db_mean).astype(np.float32) for q in queries]
        n, size = len(history), self.num_windows
        k = min(k, size * len(queries))
        index = np.empty((n, k), np.int64)
        dist = np.empty((n, k))
        for a in range(0, n, CHUNK):
            # database @ query (not query @ database.T): a contiguous BLAS product
            d2 = np.concatenate([
                (q[a : a + CHUNK].astype(np.float64) ** 2).sum(1)[:, None] + self.db_sqnorm
                - 2.0 * (self.db_features @ q[a : a + CHUNK].T).T for q in queries], axis=1)
            part = np.argpartition(d2, k - 1, axis=1)[:, :k]
            pd = np.take_along_axis(d2, part, 1)
            order = np.argsort(pd, axis=1)
            index[a : a + CHUNK] = np.take_along_axis(part, order, 1)
            dist[a : a + CHUNK] = np.sqrt(np.maximum(np.take_along_axis(pd, order, 1), 0))
        return index, dist

    def displacement(self, index: np.ndarray, dist: np.ndarray) -> np.ndarray:
        """Inverse-distance weighted mean future displacement (N, F, 17, 3) of the
        neighbours ``(index, dist)`` of :meth:`neighbours` (heading-normalised frame)."""
        w = 1.0 / (dist + _EPS)
        w /= w.sum(1, keepdims=True)
        size = self.num_windows
        flipped = index >= size
        out = np.empty((len(index), self.future_len, NUM_JOINTS, 3))
        for a in range(0, len(index), SUM_CHUNK):
            y = self.db_future[index[a : a + SUM_CHUNK] % size]  # (n, k, F, 17, 3)
            wa, fa = w[a : a + SUM_CHUNK], flipped[a : a + SUM_CHUNK]
            # mirroring is linear: mirror the weighted sum of the mirrored neighbours
            out[a : a + SUM_CHUNK] = (np.einsum("nk,nk...->n...", wa * ~fa, y)
                                      + mirror(np.einsum("nk,nk...->n...", wa * fa, y)))
        return out

    @staticmethod
    def compose(history: np.ndarray, displacement: np.ndarray, shrinkage: float,
                angle: np.ndarray) -> np.ndarray:
        """``x_T + α · displacement`` rotated back by ``angle``: (N, F, 17, 3) metres."""
        out = history[:, -1:] + shrinkage * displacement
        return rotate_z(out, angle)

    def predict(self, history: np.ndarray) -> np.ndarray:
        """Predict the F frames after a history.

        Args:
            history: (N, H, 17, 3) or (H, 17, 3) root-relative positions, metres,
                H >= 1 + P, ending at the last observed frame.

        Returns:
            (N, F, 17, 3) or (F, 17, 3) float32 future positions, metres.

        Raises:
            MotionError: too short a history, wrong joint count, NaN frames.
        """
        h, batched = check_history(history, self.history_len, joints=NUM_JOINTS)
        h, angle = normalised(h[:, -self.history_len :])
        index, dist = self.neighbours(h, self.config.k)
        out = self.compose(h, self.displacement(index, dist), self.config.shrinkage, angle)
        out = out.astype(np.float32)
        return out if batched else out[0]

    def save(self, path: str | Path) -> Path:
        """Write an ``.npz`` checkpoint (arrays only): config JSON, the concatenated
        sequences (float32) and their lengths."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("wb") as fh:
            np.savez_compressed(
                fh, format=np.array(CHECKPOINT_FORMAT),
                config=np.array(json.dumps(asdict(self.config))),
                frames=np.concatenate(self.sequences),
                lengths=np.array([len(s) for s in self.sequences], np.int64))
        return path

    @classmethod
    def load(cls, path: str | Path) -> KNNPredictor:
        """Read a checkpoint written by :meth:`save`.

        Raises:
            CheckpointError: missing file, not such a checkpoint, or inconsistent arrays.
        """
        path = Path(path)
        try:
            data = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise CheckpointError(f"cannot read kNN checkpoint: {exc}", source=path) from None
        with data:
            if "format" not in data or str(data["format"]) != CHECKPOINT_FORMAT:
                raise CheckpointError(f"not a {CHECKPOINT_FORMAT} checkpoint", source=path)
            config = KNNConfig(**json.loads(str(data["config"])))
            frames, lengths = data["frames"], data["lengths"]
        if lengths.sum() != len(frames):
            raise CheckpointError(f"sequence lengths sum to {lengths.sum()}, but there are "
                                  f"{len(frames)} frames", source=path)
        return cls(config, np.split(frames, np.cumsum(lengths)[:-1]))

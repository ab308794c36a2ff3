"""Convex blend of motion predictors, with one set of weights per predicted frame.

Predictors of different families err differently (a nonparametric motion matcher, a
DCT-MLP, an attention network, zero-velocity), so a weighted mean of their futures can
err less than each. Same ``predict(history)`` interface and pred17 layout as its members.

Math
----
With members ``m = 1..M`` predicting ``x̂^m_{T+j}`` (j = 1..F) from the same history,
``x̂_{T+j} = Σ_m w_{m,j} x̂^m_{T+j}`` with ``w_{m,j} >= 0`` and ``Σ_m w_{m,j} = 1`` for
every frame j (a convex combination, so a blend of zero-velocity and one model is a
shrinkage of that model toward the last pose). :func:`convex_weights` chooses every
frame's weights on a simplex grid by the mean per-joint Euclidean error on validation
windows (the metric being reported, which a least-squares fit would not minimise).

A checkpoint stores each member's own checkpoint file verbatim (read back by that
member's loader, told apart by its format tag) and the (M, F) weights; zero-velocity is
stored by name.
"""

from __future__ import annotations

import io
import json
import tempfile
from collections.abc import Sequence
from itertools import combinations
from pathlib import Path
from typing import Any

import numpy as np

from simenv.errors import MotionError
from simenv.models.baselines import ZeroVelocity, check_history
from simenv.models.checkpoint import CheckpointError
from simenv.models.predictor import NUM_JOINTS

#: Format tag of checkpoint files.
CHECKPOINT_FORMAT = "simenv-predictor-blend-1"
#: Name of the zero-velocity member (stored without a checkpoint).
ZERO_VELOCITY = "zero-velocity"


def member_loaders() -> dict[str, Any]:
    """Member checkpoint format tag -> predictor class (imported on demand)."""
    from simenv.models import predictor_attention, predictor_knn, predictor_regression

    return {m.CHECKPOINT_FORMAT: cls for m, cls in (
        (predictor_regression, predictor_regression.DCTRegressionPredictor),
        (predictor_knn, predictor_knn.KNNPredictor),
        (predictor_attention, predictor_attention.AttentionPredictor))}


def simplex_grid(members: int, step: float) -> np.ndarray:
    """(G, members) every weight vector with entries in multiples of ``step`` (1/step
    an integer) summing to 1 ("stars and bars")."""
    n = round(1.0 / step)
    if members < 1 or n < 1 or abs(n * step - 1.0) > 1e-9:
        raise MotionError(f"need members >= 1 and 1/step an integer; got {members}, {step}",
                          field="step")
    rows = []
    for bars in combinations(range(n + members - 1), members - 1):
        edges = (-1, *bars, n + members - 1)
        rows.append([edges[i + 1] - edges[i] - 1 for i in range(members)])
    return np.asarray(rows, dtype=np.float64) / n


def convex_weights(predictions: np.ndarray, target: np.ndarray, *,
                   joints: Sequence[int] | None = None, step: float = 0.05,
                   chunk: int = 64) -> np.ndarray:
    """Per-frame convex weights minimising the mean per-joint Euclidean error.

    Args:
        predictions: (M, N, F, J, 3) the members' predictions of N windows, metres.
        target: (N, F, J, 3) the true futures, metres.
        joints: joints counted in the error (all without).
        step: resolution of the simplex grid (:func:`simplex_grid`).
        chunk: grid points evaluated at once (bounds memory).

    Returns:
        (M, F) weights, each column on the simplex.
    """
    p = np.asarray(predictions, dtype=np.float64)
    t = np.asarray(target, dtype=np.float64)
    if p.ndim != 5 or p.shape[1:] != t.shape:
        raise MotionError(f"predictions must be (M, N, F, J, 3) and target (N, F, J, 3) "
                          f"of the same windows; got {p.shape} and {t.shape}",
                          field="predictions")
    if joints is not None:
        p, t = p[..., list(joints), :], t[..., list(joints), :]
    grid = simplex_grid(p.shape[0], step)
    weights = np.zeros((p.shape[0], p.shape[2]))
    for f in range(p.shape[2]):
        errors = np.concatenate([
            np.linalg.norm(np.einsum("gm,mnjc->gnjc", grid[a : a + chunk], p[:, :, f])
                           - t[None, :, f], axis=-1).mean(axis=(1, 2))
            for a in range(0, len(grid), chunk)])
        weights[:, f] = grid[np.argmin(errors)]
    return weights


class BlendPredictor:
    """Per-frame convex combination of predictors (module docstring).

    ``predict(history)``: (N, H, 17, 3) root-relative pred17 positions, metres, H at
    least the longest member history -> (N, F, 17, 3) float32.
    """

    def __init__(self, members: Sequence[Any], names: Sequence[str], weights: np.ndarray,
                 info: dict | None = None) -> None:
        w = np.asarray(weights, dtype=np.float64)
        if not members or len(names) != len(members):
            raise MotionError(f"need one name per member; got {len(names)} names for "
                              f"{len(members)} members", field="names")
        futures = {m.future_len for m in members}
        if len(futures) != 1:
            raise MotionError(f"members predict different lengths {sorted(futures)}",
                              field="members")
        future_len = futures.pop()
        if w.shape != (len(members), future_len):
            raise MotionError(f"weights must be ({len(members)}, {future_len}) (member, "
                              f"frame); got {w.shape}", field="weights")
        if (w < -1e-9).any() or not np.allclose(w.sum(0), 1.0, atol=1e-6):
            raise MotionError("weights must be >= 0 and sum to 1 over the members of every "
                              "frame", field="weights")
        self.members, self.names, self.weights = list(members), list(names), w
        self.future_len = future_len
        self.fps = float(members[0].fps)
        self.info = dict(info or {})

    @property
    def history_len(self) -> int:
        return max(m.history_len for m in self.members)

    @property
    def past_len(self) -> int:
        return self.history_len - 1

    def member_predictions(self, history: np.ndarray) -> np.ndarray:
        """(M, N, F, 17, 3) float64 every member's prediction of validated (N, H, 17, 3)
        histories."""
        return np.stack([np.asarray(m.predict(history[:, -m.history_len:]), np.float64)
                         for m in self.members])

    def predict(self, history: np.ndarray) -> np.ndarray:
        """Predict the F frames after a history.

        Args:
            history: (N, H, 17, 3) or (H, 17, 3) root-relative positions, metres,
                H >= :attr:`history_len`, ending at the last observed frame.

        Returns:
            (N, F, 17, 3) or (F, 17, 3) float32 future positions, metres.

        Raises:
            MotionError: too short a history, wrong joint count, NaN frames.
        """
        h, batched = check_history(history, self.history_len, joints=NUM_JOINTS)
        preds = self.member_predictions(h)
        out = np.einsum("mf,mnfjc->nfjc", self.weights, preds).astype(np.float32)
        return out if batched else out[0]

    def save(self, path: str | Path) -> Path:
        """Write an ``.npz`` checkpoint (arrays only): config JSON, the weights and each
        member's checkpoint bytes (``member<i>``; none for zero-velocity)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {"format": np.array(CHECKPOINT_FORMAT), "weights": self.weights,
                  "config": np.array(json.dumps({"names": self.names, "info": self.info,
                                                 "future_len": self.future_len,
                                                 "fps": self.fps}))}
        with tempfile.TemporaryDirectory() as tmp:
            for i, m in enumerate(self.members):
                if isinstance(m, ZeroVelocity):
                    continue
                member_path = m.save(Path(tmp) / f"member{i}.npz")
                arrays[f"member{i}"] = np.frombuffer(member_path.read_bytes(), np.uint8)
        with path.open("wb") as fh:
            np.savez(fh, **arrays)  # members are compressed already
        return path

    @classmethod
    def load(cls, path: str | Path) -> BlendPredictor:
        """Read a checkpoint written by :meth:`save`.

        Raises:
            CheckpointError: missing file, not such a checkpoint, or a member that no
                known loader reads.
        """
        path = Path(path)
        try:
            data = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise CheckpointError(f"cannot read blend checkpoint: {exc}", source=path) from None
        loaders = member_loaders()
        with data:
            if "format" not in data or str(data["format"]) != CHECKPOINT_FORMAT:
                raise CheckpointError(f"not a {CHECKPOINT_FORMAT} checkpoint", source=path)
            config = json.loads(str(data["config"]))
            weights = data["weights"]
            members = []
            with tempfile.TemporaryDirectory() as tmp:
                for i, name in enumerate(config["names"]):
                    key = f"member{i}"
                    if key not in data.files:
                        if name != ZERO_VELOCITY:
                            raise CheckpointError(f"member {i} ({name}) has no checkpoint",
                                                  source=path)
                        members.append(ZeroVelocity(config["future_len"], config["fps"]))
                        continue
                    blob = data[key].tobytes()
                    with np.load(io.BytesIO(blob), allow_pickle=False) as member:
                        tag = str(member["format"]) if "format" in member else "?"
                    if tag not in loaders:
                        raise CheckpointError(f"member {i} ({name}) has format {tag!r}; "
                                              f"known: {', '.join(loaders)}", source=path)
                    member_path = Path(tmp) / f"{key}.npz"
                    member_path.write_bytes(blob)
                    members.append(loaders[tag].load(member_path))
        return cls(members, config["names"], weights, config.get("info"))

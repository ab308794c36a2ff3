"""Other predictor families for the 20 % goal of issue 5: selection, training, evaluation.

``python -m simenv.train_predictor_families knn|attention|blend|all [--out out/families]``

Every family is fitted on the training clips of ``predictor-25-25``'s split
(:func:`simenv.train_predictor.make_split`, test fraction 0.25, seed 0) and tuned only on
the validation clips inside them (``make_split`` of the training windows with fraction
0.2 and the same seed: 05_02, 135_06, 49_04, as the shipped DCT-MLP). The held-out
windows are exactly the shipped model card's (1 + 25 + 25 frames, stride 1).

* ``knn`` (:mod:`simenv.models.predictor_knn`): the database is the fit clips (training
  minus validation) at speeds 0.8, 1, 1.25 with mirror search; ``k``, the feature
  weights and the shrinkage are chosen on a grid by the validation score of
  :func:`simenv.train_predictor.validation_score` (mean per-frame MPJPE over the
  horizons). The final model searches all training clips with the chosen values.
* ``attention`` (:mod:`simenv.models.predictor_attention`): trained with
  :func:`simenv.train_predictor.train_regression` (same loss, optimiser and model
  selection on the validation clips as the DCT-MLP) on the fit clips' windows with the
  speed and mirror augmentation.
* ``blend`` (:mod:`simenv.models.predictor_blend`): convex weights per horizon frame
  over the shipped DCT-MLP (a copy in ``out/families/base``), the kNN and attention
  predictors *as fitted without the validation clips*, and zero-velocity, chosen on the
  validation windows (:func:`simenv.models.predictor_blend.convex_weights`).

Each run writes ``<out>/<family>/metrics.json`` (validation search, held-out metrics of
the final candidate in the format of :func:`simenv.train_predictor.evaluate`), the model
(``model.npz``) and its card (``model.md``, :func:`simenv.train_predictor.results_lines`).
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from simenv import prediction_data as pdata
from simenv import prediction_metrics as pm
from simenv import train_predictor as tp
from simenv.errors import MotionError
from simenv.models.baselines import ZeroVelocity
from simenv.models.predictor_attention import AttentionConfig, AttentionPredictor
from simenv.models.predictor_knn import KNNConfig, KNNPredictor, normalised
from simenv.models.predictor_regression import (
    check_lengths,
    cosine_lr,
    regression_loss,
    targets,
)
from simenv.motion import Motion

#: Speed factors of the training clips (as the shipped DCT-MLP).
SPEEDS: tuple[float, ...] = (0.8, 1.0, 1.25)
#: kNN search grid (validation): neighbours, velocity and history feature weights.
KNN_K: tuple[int, ...] = (4, 8, 16, 32, 64)
KNN_VELOCITY: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0)
KNN_HISTORY: tuple[float, ...] = (0.0, 0.25, 0.5, 1.0)
#: Shrinkage grid α (0 = zero-velocity).
KNN_SHRINKAGE: tuple[float, ...] = tuple(np.round(np.arange(0.0, 1.51, 0.05), 2))


@dataclass
class Split:
    """``predictor-25-25``'s split and the validation clips inside its training side.

    Attributes:
        motions: every usable clip of the corpus.
        train_clips, test_clips: groups of the two sides (as the shipped cards).
        fit_clips: training groups minus the validation groups.
        validation_clips: groups held out of fitting for selection.
        validation: (1 + P + F)-frame windows of the validation clips, stride 1.
        test: the held-out windows, stride 1.
    """

    motions: list[Motion]
    train_clips: tuple[str, ...]
    test_clips: tuple[str, ...]
    fit_clips: tuple[str, ...]
    validation_clips: tuple[str, ...]
    validation: pdata.PredictionWindows
    test: pdata.PredictionWindows
    past_len: int
    future_len: int


def load_split(paths: Sequence[str | Path], past_len: int = 25, future_len: int = 25,
               *, test_fraction: float = 0.25, validation: float = 0.2, seed: int = 0
               ) -> Split:
    """The clips under ``paths`` split as :func:`simenv.train_predictor.run` splits them
    with ``--validation`` (same functions, same seed).

    Raises:
        SimenvError: no usable clip.
    """
    motions, _ = tp.collect_motions(paths)
    windows = pdata.windows_from_motions(motions, past_len, future_len, stride=1)
    split = tp.make_split(windows, test_fraction, seed)
    base = windows.subset(split.train)
    vsplit = tp.make_split(base, validation, seed)
    return Split(motions, split.train_clips, split.test_clips, vsplit.train_clips,
                 vsplit.test_clips, base.subset(vsplit.test), windows.subset(split.test),
                 past_len, future_len)


def sequences(motions: Sequence[Motion], clips: Sequence[str],
              speeds: Sequence[float] = SPEEDS) -> list[np.ndarray]:
    """Root-relative pred17 frames (T, 17, 3) float32, metres, at 25 fps of every motion
    whose group is in ``clips``, once per speed factor."""
    keep = [m for m in motions if tp.group_of(m.name) in set(clips)]
    out = []
    for m in tp.speed_variants(keep, speeds):
        if m.fps != pdata.TARGET_FPS:
            m = m.resample(pdata.TARGET_FPS)
        out.append(pdata.split_root(pdata.to_pred17(m))[0])
    return out


def score(pred: np.ndarray, windows: pdata.PredictionWindows) -> float:
    """Validation score of predictions (N, F, 17, 3): the mean per-frame MPJPE (mm) over
    the horizons, as :func:`simenv.train_predictor.validation_score`."""
    errors = pm.mpjpe_at_horizons_mm(pred, windows.future, windows.fps,
                                     joints=tp.EVAL_JOINTS)
    return float(np.mean(list(errors.values())))


def horizon_row(pred: np.ndarray, windows: pdata.PredictionWindows) -> dict:
    """Per-frame MPJPE at 400 / 1000 ms and the gain over zero-velocity (%) there."""
    zv = ZeroVelocity(windows.future_len).predict(windows.frames[:, : windows.past_len + 1])
    m = pm.mpjpe_at_horizons_mm(pred, windows.future, windows.fps, joints=tp.EVAL_JOINTS)
    z = pm.mpjpe_at_horizons_mm(zv, windows.future, windows.fps, joints=tp.EVAL_JOINTS)
    return {str(h): {"mm": round(m[h], 1), "zero_velocity_mm": round(z[h], 1),
                     "gain_pct": round(100 * (1 - m[h] / z[h]), 1)}
            for h in (400, 1000) if h in m}


def select_knn(split: Split, *, progress: bool = True) -> tuple[KNNConfig, list[dict]]:
    """Grid search of the kNN predictor on the validation clips (database: fit clips).

    For each feature weighting the neighbours of every validation history are found
    once (the largest k); each k and shrinkage α are then scored on them.

    Returns:
        The best config (lowest :func:`score`) and every grid point's score.
    """
    db = sequences(split.motions, split.fit_clips)
    val = split.validation
    history, angle = normalised(val.frames[:, : split.past_len + 1].astype(np.float64))
    config = KNNConfig(split.past_len, split.future_len)
    base = KNNPredictor(config, db)
    rows: list[dict] = []
    for wv, wh in itertools.product(KNN_VELOCITY, KNN_HISTORY):
        t0 = time.process_time()
        model = base.reweighted(wv, wh)
        index, dist = model.neighbours(history, max(KNN_K))
        for k in KNN_K:
            disp = model.displacement(index[:, :k], dist[:, :k])
            for a in KNN_SHRINKAGE:
                rows.append({"k": k, "velocity_weight": wv, "history_weight": wh,
                             "shrinkage": float(a),
                             "score_mm": score(model.compose(history, disp, a, angle), val)})
        if progress:
            best = min(r["score_mm"] for r in rows if r["velocity_weight"] == wv
                       and r["history_weight"] == wh)
            print(f"knn w_v={wv} w_h={wh}: best {best:.1f} mm "
                  f"({time.process_time() - t0:.1f} CPU s)", file=sys.stderr)
    best = min(rows, key=lambda r: r["score_mm"])
    chosen = KNNConfig(split.past_len, split.future_len, k=best["k"],
                       velocity_weight=best["velocity_weight"],
                       history_weight=best["history_weight"], shrinkage=best["shrinkage"])
    return chosen, rows


def train_attention(model: AttentionPredictor, windows: pdata.PredictionWindows, *,
                    iterations: int = 3000, minutes: float | None = None,
                    batch_size: int = 128, lr: float = 3e-4, weight_decay: float = 1e-4,
                    validation: pdata.PredictionWindows | None = None,
                    validate_every: int = 100, seed: int = 0, progress: bool = True
                    ) -> list[dict[str, float]]:
    """Supervised training of the first network of ``model``: the DCT-MLP's recipe
    (:func:`simenv.train_predictor.train_regression`: AdamW, cosine decay over
    ``iterations``, :func:`simenv.models.predictor_regression.regression_loss`, batches
    without replacement), keeping the state with the best
    :func:`simenv.train_predictor.validation_score` on ``validation`` (checked every
    ``validate_every`` iterations). ``minutes`` budgets process CPU time.

    Returns:
        A log: one dict every 50 iterations (and the last).

    Raises:
        MotionError: windows of another configuration, or fewer than 2 windows.
    """
    from tqdm import tqdm

    check_lengths(model, windows.past_len, windows.future_len)
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    residual, last, future = targets(model.history_len, windows.frames)
    if len(residual) < 2:
        raise MotionError(f"training needs at least 2 windows; got {len(residual)}")
    opt = torch.optim.AdamW(model.net.parameters(), lr=lr, weight_decay=weight_decay)
    bs = min(batch_size, len(residual))
    log: list[dict[str, float]] = []
    best_score, best_state = float("inf"), None
    t0 = time.process_time()
    for it in tqdm(range(iterations), disable=not progress, desc="train", unit="it"):
        for group in opt.param_groups:
            group["lr"] = cosine_lr(lr, it, iterations)
        idx = torch.as_tensor(rng.choice(len(residual), bs, replace=False))
        model.net.train()
        loss = regression_loss(model.forward(residual[idx], last[idx]), future[idx])
        opt.zero_grad()
        loss.backward()
        opt.step()
        done = minutes is not None and time.process_time() - t0 > 60 * minutes
        if it % 50 == 0 or it == iterations - 1 or done:
            entry = {"iteration": it, "loss": loss.item(),
                     "seconds": time.process_time() - t0}
            if validation is not None and (it % validate_every == 0 or it == iterations - 1
                                           or done):
                entry["val_mpjpe_mm"] = tp.validation_score(model, validation)
                if entry["val_mpjpe_mm"] < best_score:
                    best_score = entry["val_mpjpe_mm"]
                    best_state = {k: v.detach().clone()
                                  for k, v in model.net.state_dict().items()}
            log.append(entry)
        if done:
            break
    if best_state is not None:
        model.net.load_state_dict(best_state)
    return log


def training_windows(split: Split, clips: Sequence[str]) -> pdata.PredictionWindows:
    """Windows of ``clips`` with the speed variants and mirror images of the shipped
    DCT-MLP's training (:func:`simenv.train_predictor.training_windows`)."""
    args = argparse.Namespace(speeds=list(SPEEDS), past=split.past_len,
                              future=split.future_len, mirror=True)
    return tp.training_windows(split.motions, set(clips), args)


def fit_attention(split: Split, config: AttentionConfig, *, iterations: int = 3000,
                  lr: float = 3e-4, seed: int = 0, progress: bool = True
                  ) -> tuple[AttentionPredictor, dict]:
    """Train ``config.members`` attention networks (seed + i) on the fit clips, each
    selected on the validation clips; returns the model and what its card records."""
    windows = training_windows(split, split.fit_clips)
    model = AttentionPredictor(config)
    members = []
    for i in range(config.members):
        log = train_attention(model.member(i), windows, iterations=iterations, lr=lr,
                              validation=split.validation, seed=seed + i, progress=progress)
        scored = [e for e in log if "val_mpjpe_mm" in e]
        pick = min(scored, key=lambda e: e["val_mpjpe_mm"])
        members.append({"iterations": log[-1]["iteration"] + 1,
                        "train_seconds": round(log[-1]["seconds"], 1),
                        "selected_iteration": pick["iteration"],
                        "val_mpjpe_mm": round(pick["val_mpjpe_mm"], 2),
                        "log": log})
    return model, {"train_windows": len(windows), "lr": lr, "seed": seed,
                   "members": members}

"""Other predictor families for the 20 % goal of issue 5: selection, training, evaluation.

``OMP_NUM_THREADS=1 python -m simenv.train_predictor_families knn attention blend
[--out out/families]`` (stages in that order; the blend needs the other two and a copy of
the shipped ``predictor-dctmlp-25-25.*`` in ``<out>/base``). ``OMP_NUM_THREADS=1`` puts
numpy's BLAS on one thread: the speeds recorded (:func:`speed`) are one-thread speeds,
and on a shared machine a multi-threaded BLAS makes the kNN's single predictions several
times slower in CPU time.

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
* ``attention`` (:mod:`simenv.models.predictor_attention`): trained by
  :func:`train_attention` (the loss, optimiser, schedule and model selection on the
  validation clips of :func:`simenv.train_predictor.train_regression`) on the fit clips'
  windows with the speed and mirror augmentation; ``--members K`` trains K networks
  with seeds 0 .. K-1. An existing ``<out>/attention/model.npz`` with its
  ``training.json`` is evaluated again instead of retrained (``--retrain``).
* ``blend`` (:mod:`simenv.models.predictor_blend`): convex weights per horizon frame
  over the shipped DCT-MLP (a copy in ``out/families/base``), the kNN and attention
  predictors *as fitted without the validation clips*, and zero-velocity, chosen on the
  validation windows (:func:`simenv.models.predictor_blend.convex_weights`); the final
  blend keeps the weights and swaps in the kNN searching all training clips.

Each run writes ``<out>/<family>/metrics.json`` (validation search, held-out metrics of
the final candidate in the format of :func:`simenv.train_predictor.evaluate`), the model
(``model.npz``) and its card (``model.md``, :func:`simenv.train_predictor.results_lines`).
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from simenv import prediction_data as pdata
from simenv import prediction_metrics as pm
from simenv import train_predictor as tp
from simenv.errors import MotionError, SimenvError
from simenv.models.baselines import ZeroVelocity
from simenv.models.predictor_attention import AttentionConfig, AttentionPredictor
from simenv.models.predictor_blend import (
    ZERO_VELOCITY,
    BlendPredictor,
    convex_weights,
    member_loaders,
)
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
KNN_HISTORY: tuple[float, ...] = (0.0, 0.25)
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


def per_action(pred: np.ndarray, windows: pdata.PredictionWindows) -> dict:
    """Per action type (:func:`simenv.train_predictor.action_of`) of the windows' clips:
    window count and :func:`horizon_row` of the predictions."""
    actions = np.array([tp.action_of(c) for c in windows.window_clip_names], dtype=object)
    out = {}
    for action in sorted(set(actions)):
        sel = np.flatnonzero(actions == action)
        out[action] = {"windows": len(sel)} | horizon_row(pred[sel], windows.subset(sel))
    return out


def validation_report(model: object, split: Split) -> dict:
    """Validation score, 400 / 1000 ms rows and per-action rows of ``model``."""
    pred = model.predict(split.validation.frames[:, : split.past_len + 1])
    return {"score_mm": round(score(pred, split.validation), 2),
            "overall": horizon_row(pred, split.validation),
            "per_action": per_action(pred, split.validation)}


def rate(fn: Callable[[], object], seconds: float) -> float:
    """Calls per CPU second of ``fn`` after one warm-up call (as
    ``benchmarks/bench_models.py`` measures the shipped models)."""
    fn()
    calls, start = 0, time.process_time()
    while time.process_time() - start < seconds:
        fn()
        calls += 1
    return calls / (time.process_time() - start)


def speed(model: object, seconds: float = 3.0) -> dict[str, float]:
    """Single-sample and batch-of-64 predictions per CPU second on one thread, on
    histories of the bundled CMU walk 02_01 (``benchmarks/bench_models.py``'s inputs)."""
    from simenv.assets import WALK, asset_path
    from simenv.io import bvh

    torch.set_num_threads(1)
    walk = bvh.read(asset_path(WALK))
    w = pdata.windows_from_motions([walk], model.past_len, 1, stride=1)
    batch = w.frames[:64, : model.history_len]
    return {"single_predictions_per_s": round(rate(lambda: model.predict(batch[0]),
                                                   seconds), 1),
            "batched_predictions_per_s": round(len(batch) * rate(
                lambda: model.predict(batch), seconds), 1), "batch": len(batch)}


def held_out(model: object, split: Split) -> dict:
    """Held-out metrics of ``model`` in the format of
    :func:`simenv.train_predictor.evaluate` (plus recursive prediction)."""
    metrics = tp.evaluate(model, split.test)
    metrics["recursive"] = tp.evaluate_recursive(model, split.motions, split.test_clips)
    return metrics


def card(name: str, title: str, module: str, metrics: dict, training: Sequence[str]
         ) -> str:
    """Markdown model card in the format of :func:`simenv.train_predictor.model_card`
    (same header, data and split, held-out results), with ``training`` lines."""
    cfg = metrics["config"]
    lines = [
        f"# {name}: {title} ({cfg['past_len']} -> {cfg['future_len']} frames at 25 fps)",
        "",
        f"Predicts the next {cfg['future_len']} frames "
        f"({1000 * cfg['future_len'] / 25:.0f} ms) of a 17-joint root-relative skeleton "
        "(simenv.prediction_data pred17 layout, metres, Z-up) from the last "
        f"{cfg['past_len'] + 1} frames (lead-in + {cfg['past_len']} observed). Method: "
        f"docstring of `{module}`. Not shipped: `{module}.{cfg['class']}.load(path)`, "
        "then `.predict(history)`.",
        "",
        "## Data and split",
        "",
        "Real CMU motion capture from the shared corpus (BVH, ASF/AMC and both people of "
        "the two-person trials), resampled to 25 fps, sliding windows with stride 1. "
        "Split by clip group with `prediction_data.split_by_clip` (test fraction 0.25, "
        "seed 0; partners of one two-person trial are one group): the held-out windows "
        "of `predictor-25-25` and `predictor-dctmlp-25-25`.",
        "",
        f"* train clips ({len(cfg['train_clips'])}): {', '.join(cfg['train_clips'])}",
        f"* held-out clips ({len(cfg['test_clips'])}): {', '.join(cfg['test_clips'])}",
        f"* validation clips (inside the training clips, for every choice): "
        f"{', '.join(cfg['validation_clips'])}; held-out windows: {cfg['test_windows']}",
        *training,
        "",
        "## Held-out results",
        "",
        *tp.results_lines(metrics),
        "",
        "Licence of the training data: CMU Graphics Lab Motion Capture Database. The data "
        "used in this project was obtained from mocap.cs.cmu.edu. The database was created "
        "with funding from NSF EIA-0196217.",
        "",
    ]
    return "\n".join(lines)


def _split_info(split: Split) -> dict:
    return {"past_len": split.past_len, "future_len": split.future_len,
            "train_clips": list(split.train_clips), "test_clips": list(split.test_clips),
            "validation_clips": list(split.validation_clips),
            "fit_clips": list(split.fit_clips), "test_windows": len(split.test),
            "validation_windows": len(split.validation), "speeds": list(SPEEDS),
            "mirror": True, "seed": 0}


def _write(out: Path, name: str, title: str, module: str, model: object, metrics: dict,
           training: Sequence[str]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    model.save(out / "model.npz")
    metrics["checkpoint_bytes"] = (out / "model.npz").stat().st_size
    (out / "metrics.json").write_text(json.dumps(metrics, indent=1, default=float))
    (out / "model.md").write_text(card(name, title, module, metrics, training))


def run_knn(split: Split, out: Path, progress: bool = True) -> dict:
    """Select the kNN predictor on validation, refit its database on all training
    clips, evaluate on the held-out windows; writes ``out/knn``."""
    t0 = time.process_time()
    config, rows = select_knn(split, progress=progress)
    fit = KNNPredictor(config, sequences(split.motions, split.fit_clips))
    folder = out / "knn"
    folder.mkdir(parents=True, exist_ok=True)
    fit.save(folder / "model-fit.npz")
    config.info = _split_info(split) | {"class": "KNNPredictor", "database_clips":
                                        list(split.train_clips)}
    model = KNNPredictor(config, sequences(split.motions, split.train_clips))
    seconds = time.process_time() - t0
    metrics = held_out(model, split)
    metrics |= {"config": config.info, "validation": validation_report(fit, split),
                "search": rows, "select_seconds": round(seconds, 1),
                "speed": speed(model), "knn": asdict(config) | {"info": None}}
    training = [
        f"* selection: grid over k {list(KNN_K)}, velocity weight {list(KNN_VELOCITY)}, "
        f"history weight {list(KNN_HISTORY)} and shrinkage 0 .. 1.5 (step 0.05), "
        "database = the training clips minus the validation clips, scored on the "
        "validation clips by the mean per-frame MPJPE over the horizons "
        f"({seconds:.0f} CPU s): k = {config.k}, velocity weight "
        f"{config.velocity_weight}, history weight {config.history_weight}, shrinkage "
        f"{config.shrinkage}, validation {metrics['validation']['score_mm']} mm; then "
        f"the database is all {len(split.train_clips)} training clips at speeds "
        f"{list(SPEEDS)} ({model.num_windows} windows, mirror images searched too)"]
    _write(folder, "knn-25-25", "motion-matching kNN predictor", "simenv.models."
           "predictor_knn", model, metrics, training)
    return metrics


#: Size of the attention network (about 0.45 MB of float32 weights per member).
ATTENTION_WIDTH, ATTENTION_LAYERS = 64, 3


def run_attention(split: Split, out: Path, *, iterations: int = 1500, members: int = 1,
                  retrain: bool = False, progress: bool = True) -> dict:
    """Train (or, unless ``retrain``, reuse ``out/attention/model.npz`` and its
    ``training.json``) the attention predictor, evaluate it; writes ``out/attention``."""
    folder = out / "attention"
    path, info_path = folder / "model.npz", folder / "training.json"
    if path.is_file() and info_path.is_file() and not retrain:
        model = AttentionPredictor.load(path)
        info = json.loads(info_path.read_text())
    else:
        config = AttentionConfig(split.past_len, split.future_len, width=ATTENTION_WIDTH,
                                 layers=ATTENTION_LAYERS, members=members)
        model, info = fit_attention(split, config, iterations=iterations,
                                    progress=progress)
        folder.mkdir(parents=True, exist_ok=True)
        info_path.write_text(json.dumps(info))
    cfg = model.config
    cfg.info = _split_info(split) | {"class": "AttentionPredictor"}
    params = sum(p.numel() for p in model.nets.parameters())
    metrics = held_out(model, split)
    metrics |= {"config": cfg.info, "validation": validation_report(model, split),
                "training": info, "speed": speed(model), "parameters": params}
    selected = "; ".join(f"member {i}: iteration {m['selected_iteration']} of "
                         f"{m['iterations']}, validation {m['val_mpjpe_mm']} mm, "
                         f"{m['train_seconds']} CPU s" for i, m in enumerate(info["members"]))
    training = [
        f"* training windows: {info['train_windows']} (training clips minus the validation "
        f"clips, speeds {list(SPEEDS)}, mirrored)",
        f"* network: width {cfg.width}, {cfg.layers} layers, {cfg.heads} heads, dropout "
        f"{cfg.dropout}, {params} parameters, {cfg.members} member(s), mirror-averaged: "
        f"{cfg.mirror_average}; AdamW lr {info['lr']}, weight decay 1e-4, batch 128, "
        f"cosine decay, one thread; iteration selected on the validation clips ({selected})"]
    _write(folder, "attention-25-25", "joint-attention transformer on DCT coefficients",
           "simenv.models.predictor_attention", model, metrics, training)
    return metrics


#: Members of the blend: name -> checkpoint under the output folder (validation fit,
#: final); the DCT-MLP is the copy of the shipped model, the same in both.
BLEND_MEMBERS: dict[str, tuple[str, str]] = {
    "dct-mlp": ("base/predictor-dctmlp-25-25.npz", "base/predictor-dctmlp-25-25.npz"),
    "knn": ("knn/model-fit.npz", "knn/model.npz"),
    "attention": ("attention/model.npz", "attention/model.npz"),
}


def _load_member(path: Path) -> object:
    if not path.is_file():
        raise SimenvError(f"blend member {path} is missing (run the knn and attention "
                          "stages first; copy the shipped predictor-dctmlp-25-25.* to "
                          "base/)", source=path)
    with np.load(path, allow_pickle=False) as data:
        tag = str(data["format"])
    return member_loaders()[tag].load(path)


def run_blend(split: Split, out: Path, step: float = 0.05) -> dict:
    """Per-frame convex weights over :data:`BLEND_MEMBERS` and zero-velocity chosen on
    the validation windows with the members as fitted without the validation clips;
    the blend of the final members is evaluated on the held-out windows; writes
    ``out/blend``."""
    names = [*BLEND_MEMBERS, ZERO_VELOCITY]
    zv = ZeroVelocity(split.future_len)
    fitted = [_load_member(out / a) for a, _ in BLEND_MEMBERS.values()] + [zv]
    final = [_load_member(out / b) for _, b in BLEND_MEMBERS.values()] + [zv]
    history = split.validation.frames[:, : split.past_len + 1]
    t0 = time.process_time()
    preds = np.stack([m.predict(history) for m in fitted])
    weights = convex_weights(preds, split.validation.future, joints=tp.EVAL_JOINTS,
                             step=step)
    seconds = time.process_time() - t0
    info = _split_info(split) | {"class": "BlendPredictor", "members": names,
                                 "step": step}
    blend = BlendPredictor(final, names, weights, info)
    members_val = {n: validation_report(m, split) for n, m in zip(names, fitted,
                                                                  strict=True)}
    metrics = held_out(blend, split)
    metrics |= {"config": info, "weights": weights.round(4).tolist(),
                "validation": validation_report(BlendPredictor(fitted, names, weights),
                                                split),
                "validation_members": members_val, "weights_seconds": round(seconds, 1),
                "speed": speed(blend)}
    mean_w = ", ".join(f"{n} {w:.2f}" for n, w in zip(names, weights.mean(1), strict=True))
    at = {h: ", ".join(f"{n} {w:.2f}" for n, w in zip(names, weights[:, h // 40 - 1],
                                                      strict=True)) for h in (400, 1000)}
    training = [
        f"* members: {', '.join(names)}; per-frame convex weights on a simplex grid (step "
        f"{step}) minimising the mean joint error on the validation windows, with the "
        "members as fitted without the validation clips (the shipped DCT-MLP; the kNN "
        "database of the training clips minus the validation clips; the attention "
        "network); the final blend uses the same weights with the kNN database of all "
        "training clips",
        f"* weights averaged over the 25 frames: {mean_w}; at 400 ms: {at[400]}; at 1000 "
        f"ms: {at[1000]}",
        f"* validation (in-sample for the weights): {metrics['validation']['score_mm']} mm "
        "mean over the horizons; members: " + ", ".join(
            f"{n} {r['score_mm']} mm" for n, r in members_val.items())]
    _write(out / "blend", "blend-25-25", "per-frame convex blend of predictors",
           "simenv.models.predictor_blend", blend, metrics, training)
    return metrics

def main(argv: Sequence[str] | None = None) -> int:
    """Run the named stages; returns the exit status (2 on a user error)."""
    ap = argparse.ArgumentParser(prog="python -m simenv.train_predictor_families",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("stages", nargs="+", choices=("knn", "attention", "blend"))
    ap.add_argument("--shared", default=str(tp.SHARED), help="shared corpus root")
    ap.add_argument("--out", default="out/families", help="output folder")
    ap.add_argument("--iterations", type=int, default=1500,
                    help="attention: iterations per member")
    ap.add_argument("--members", type=int, default=1, help="attention: networks")
    ap.add_argument("--retrain", action="store_true",
                    help="attention: train even if <out>/attention/model.npz exists")
    ap.add_argument("--quiet", action="store_true", help="no progress output")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    out = Path(args.out)
    try:
        split = load_split(tp.default_data(Path(args.shared)))
        for stage in args.stages:
            if stage == "knn":
                metrics = run_knn(split, out, progress=not args.quiet)
            elif stage == "attention":
                metrics = run_attention(split, out, iterations=args.iterations,
                                        members=args.members, retrain=args.retrain,
                                        progress=not args.quiet)
            else:
                metrics = run_blend(split, out)
            row = {h: metrics["overall"]["model"]["mpjpe_mm"][h] for h in (400, 1000)}
            zv = {h: metrics["overall"]["zero_velocity"]["mpjpe_mm"][h] for h in (400, 1000)}
            print(f"{stage}: held-out " + ", ".join(
                f"{h} ms {row[h]:.1f} mm ({100 * (1 - row[h] / zv[h]):+.1f} % vs "
                f"zero-velocity)" for h in row) + f"; outputs in {out / stage}")
    except SimenvError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

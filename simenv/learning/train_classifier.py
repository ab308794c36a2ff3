"""Train and evaluate the gesture classifier on the real gesture recordings.

Data: every recording of ``shared/data/gestures`` (MSR Action3D, UTKinect, Florence 3D),
built by :mod:`simenv.data.gestures` (vocabulary, joint set, 25 fps, 3 s windows, normalisation),
plus the ``idle`` clips cut from their near-still unlabelled frames
(``load_gesture_clips(idle=True)``, module docstring of :mod:`simenv.data.gestures`), and split
cross-subject (:func:`simenv.data.gestures.split_cross_subject`: odd subject ids
train, even ids test; no subject on both sides). No validation split is carved out: the
schedule is fixed in advance and the test split is only read after training.

Training (seeded; CPU, one thread): AdamW, cosine learning rate with a linear warm-up,
cross-entropy with label smoothing and class weights ``(N / (C n_c))^(1/2)`` (the pooled
``other`` class is ~half the data); batches group windows of similar length
(:func:`length_buckets`). Each epoch draws a fresh window of every clip
(:func:`training_windows`): a random 3-s crop, or (with ``short_prob``) a random 1 s of
the clip with the rest masked -- the ``real_1s`` condition and the perception loop's real
stage --, or (with ``hold_prob``) a random 1 s followed by its last pose held *as valid
frames* -- the zero-velocity ``1 s + 2 s`` condition, and the loop's predicted stage when
the forecast hardly moves (the shipped WGAN's does not: without these windows the network
read "1 s of anything, then a held pose" as a wave). Then it augments them: mirror image
(p = 0.5; a left-handed wave is still a wave), a yaw of up to ±15° and a scale of ±10 %
(noise of the facing and size normalisation).

Evaluation, the thesis's way, on the test subjects (windows centre-cropped):

* ``real_3s``: 3 s of real motion (75 frames; shorter clips padded, see gestures);
* ``real_1s``: only the first 25 frames are real (the rest padded and masked);
* ``real_1s_pred_2s_model``: the thesis's "1 s real + 2 s predicted": the 1 s of real
  motion continued by the shipped learned predictor ``predictor-25-50`` (the room's
  configuration; :func:`extrapolate_with_predictor`; skipped when it is not shipped).
  It runs on the normalised windows (a similarity transform with a scale close to 1),
  not re-fitted to them;
* ``real_1s_pred_2s_cv``: the 1 s of real motion continued by a **constant-velocity**
  extrapolation (``x_{n-1+k} = x_{n-1} + k (x_{n-1} - x_{n-2})``) up to 75 frames, all
  frames treated as valid — the same condition with the simplest predictor;
  ``real_1s_pred_2s_zv``: the same with zero velocity (the last pose held,
  unmasked). The extrapolation is done on normalised windows: the normalisation is a
  similarity transform fixed by the first 10 (real) frames, so this equals extrapolating
  in the world frame and normalising afterwards.

The test windows include the test subjects' ``idle`` clips. Per condition: accuracy,
the accuracy on the labelled clips alone (``accuracy_labelled``: the test set of a model
without the idle class), balanced accuracy (mean per-class recall), per-class recall,
confusion matrix (rows = true, columns = predicted), accuracy per dataset, and the room's
reaction accuracy (true and predicted labels mapped through
:func:`simenv.data.gestures.room_reaction`). Outputs: ``metrics.json``, ``confusion.png``,
``gesture-classifier.npz`` and a model card ``gesture-classifier.md``.

Command line: ``python -m simenv.learning.train_classifier train --out DIR [--config FILE]``,
``python -m simenv.learning.train_classifier eval [--model NAME | --checkpoint FILE] --out DIR``
(also ``simenv train classifier`` / ``simenv eval classifier [NAME]``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from simenv.core.config import dataclass_from_file, shared_data_root
from simenv.core.errors import MotionError, SimenvError
from simenv.data.gestures import (
    GESTURE15_JOINTS,
    GESTURE_FPS,
    GESTURE_LABELS,
    IDLE_LABEL,
    SHORT_FRAMES,
    WINDOW_FRAMES,
    GestureClip,
    GestureWindows,
    LoadReport,
    cut_window,
    gesture_skeleton,
    load_gesture_clips,
    make_windows,
    mirror_windows,
    pack_windows,
    room_reaction,
    split_cross_subject,
)
from simenv.data.prediction_data import DERIVED_KEYPOINTS, PRED17_JOINTS
from simenv.learning.recognition import class_weights
from simenv.models import available, checkpoint_path, load
from simenv.models.gesture_classifier import ClassifierConfig, GestureClassifier
from simenv.models.predictor import rollout
from simenv.models.training import CpuBudget, cosine_schedule, seeded

#: Default location of the gesture corpus (``SIMENV_SHARED_DATA`` overrides the root).
DEFAULT_DATA = shared_data_root() / "gestures"

CONDITIONS: tuple[str, ...] = ("real_3s", "real_1s", "real_1s_pred_2s_model",
                               "real_1s_pred_2s_cv", "real_1s_pred_2s_zv")
#: The shipped predictor of the "1 s real + 2 s predicted" condition (the room's 25 -> 50).
PREDICTOR = "predictor-25-50"


@dataclass
class TrainConfig:
    """Training options (all overridable from a TOML/JSON ``--config`` file).

    Attributes:
        data: the ``gestures`` folder.
        joints: gesture joint set (``gesture15`` or ``gesture9``).
        seed: seed of every random draw (crops, augmentation, init, batches).
        epochs: passes over the training clips.
        batch_size: windows per step.
        lr, weight_decay, warmup_steps: AdamW and schedule.
        label_smoothing: cross-entropy label smoothing.
        dim, heads, layers, ffn, feature_dim, dropout: architecture.
        mirror, max_yaw_deg, max_scale: augmentation (see the module docstring).
        short_prob, hold_prob: probability of a 1-s window with the rest masked / held
            as valid frames (:func:`training_windows`).
        idle: train with the ``idle`` clips (and test on the test subjects' ones).
        max_minutes: CPU-time budget of this process (reproducible on a shared machine,
            unlike wall time); training stops after the epoch that exceeds it
            (recorded in the metrics as ``stopped_early``).
    """

    data: str = str(DEFAULT_DATA)
    joints: str = "gesture15"
    seed: int = 0
    epochs: int = 20
    batch_size: int = 32
    lr: float = 1e-3
    weight_decay: float = 0.05
    warmup_steps: int = 30
    label_smoothing: float = 0.1
    dim: int = 48
    heads: int = 4
    layers: int = 2
    ffn: int = 96
    feature_dim: int = 128
    dropout: float = 0.2
    mirror: bool = True
    max_yaw_deg: float = 15.0
    max_scale: float = 0.1
    short_prob: float = 0.25
    hold_prob: float = 0.25
    idle: bool = True
    max_minutes: float = 8.0

    @classmethod
    def from_file(cls, path: str | Path, **overrides: Any) -> TrainConfig:
        """Config from a TOML or JSON file (unknown keys are an error)."""
        return dataclass_from_file(cls, path, **overrides)


def augment(x: np.ndarray, rng: np.random.Generator, config: TrainConfig,
            joints: Sequence[str]) -> np.ndarray:
    """Mirror / yaw / scale augmentation of normalised windows (N, T, J, 3)."""
    x = x.copy()
    if config.mirror:
        flip = rng.random(len(x)) < 0.5
        x[flip] = mirror_windows(x[flip], joints)
    yaw = np.deg2rad(rng.uniform(-config.max_yaw_deg, config.max_yaw_deg, len(x)))
    c, s = np.cos(yaw)[:, None, None], np.sin(yaw)[:, None, None]
    x0, x1 = x[..., 0].copy(), x[..., 1].copy()
    x[..., 0], x[..., 1] = c * x0 - s * x1, s * x0 + c * x1
    scale = rng.uniform(1 - config.max_scale, 1 + config.max_scale, len(x))
    return (x * scale[:, None, None, None]).astype(np.float32)


def training_windows(clips: Sequence[GestureClip], rng: np.random.Generator,
                     config: TrainConfig, joints: Sequence[str]) -> GestureWindows:
    """One fresh, normalised training window per clip (see the module docstring).

    Each window is, independently: with probability ``config.short_prob`` a random
    :data:`~simenv.data.gestures.SHORT_FRAMES` (1 s) of the clip, padded to 75 frames by holding
    its last pose and the padding masked; with ``config.hold_prob`` the same 1 s with the
    held frames *valid*; otherwise a random 75-frame (3 s) crop (a shorter clip whole,
    padding masked). Clips shorter than 1 s are taken whole in every case.
    """
    kinds = rng.choice(3, size=len(clips), p=[1.0 - config.short_prob - config.hold_prob,
                                              config.short_prob, config.hold_prob])
    xs, vs = [], []
    for clip, kind in zip(clips, kinds, strict=True):
        span = WINDOW_FRAMES if kind == 0 else SHORT_FRAMES
        offset = int(rng.integers(0, max(clip.num_frames - span, 0) + 1))
        w, v = cut_window(clip.positions, offset=offset,
                          real_frames=None if kind == 0 else SHORT_FRAMES)
        xs.append(w)
        vs.append(np.ones_like(v) if kind == 2 else v)
    return pack_windows(clips, xs, vs, joints)


def length_buckets(lengths: np.ndarray, batch_size: int, rng: np.random.Generator,
                   pool: int = 8) -> list[np.ndarray]:
    """Shuffled batches of indices whose windows have similar valid lengths: a random
    permutation is cut into pools of ``pool`` batches, each pool sorted by length and cut
    into batches, and the batches are shuffled. The model skips trailing padding of a
    batch, so this saves work without changing what a window contributes."""
    order = rng.permutation(len(lengths))
    batches: list[np.ndarray] = []
    for i in range(0, len(order), pool * batch_size):
        chunk = order[i:i + pool * batch_size]
        chunk = chunk[np.argsort(lengths[chunk], kind="stable")]
        batches += [chunk[j:j + batch_size] for j in range(0, len(chunk), batch_size)]
    return [batches[k] for k in rng.permutation(len(batches))]


def build_model(config: TrainConfig) -> GestureClassifier:
    """Untrained classifier for ``config`` (weights from ``torch.manual_seed(seed)``)."""
    skel = gesture_skeleton(config.joints)  # type: ignore[arg-type]
    torch.manual_seed(config.seed)
    return GestureClassifier(ClassifierConfig(
        skel.joint_names, skel.parents, GESTURE_LABELS, window=WINDOW_FRAMES, dim=config.dim,
        heads=config.heads, layers=config.layers, ffn=config.ffn,
        feature_dim=config.feature_dim, dropout=config.dropout,
        extra={"joint_set": config.joints}))


def train_step(model: GestureClassifier, optimizer: torch.optim.Optimizer,
               batch: GestureWindows, weights: torch.Tensor, label_smoothing: float
               ) -> tuple[float, int]:
    """One optimisation step on a batch; returns (loss, correctly classified windows)."""
    model.train()
    logits = model(torch.from_numpy(batch.x), torch.from_numpy(batch.valid))
    y = torch.from_numpy(batch.y)
    loss = torch.nn.functional.cross_entropy(logits, y, weight=weights,
                                             label_smoothing=label_smoothing)
    optimizer.zero_grad()
    loss.backward()
    torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
    optimizer.step()
    return loss.item(), int((logits.argmax(1) == y).sum())


def train(config: TrainConfig, train_clips: Sequence[GestureClip], *, progress: bool = True
          ) -> tuple[GestureClassifier, dict[str, Any]]:
    """Train a classifier on ``train_clips``; returns (model in eval mode, history)."""
    if not train_clips:
        raise SimenvError("no training clips: the data folder gave no usable recording")
    rng = seeded(config.seed)
    model = build_model(config)
    joints = model.config.joint_names
    y_all = np.array([GESTURE_LABELS.index(c.label) for c in train_clips])
    weights = class_weights(y_all, len(GESTURE_LABELS))
    steps_per_epoch = math.ceil(len(train_clips) / config.batch_size)
    optimizer = torch.optim.AdamW(model.parameters(), lr=config.lr,
                                  weight_decay=config.weight_decay)
    scheduler = cosine_schedule(optimizer, steps_per_epoch * config.epochs,
                                warmup_steps=config.warmup_steps)
    # epoch_train_acc: on the augmented crops, in training mode (dropout on).
    history: dict[str, Any] = {"epoch_loss": [], "epoch_train_acc": [], "stopped_early": False}
    budget = CpuBudget(config.max_minutes)
    bar = tqdm(range(config.epochs), desc="train gesture classifier", disable=not progress)
    for _ in bar:
        windows = training_windows(train_clips, rng, config, joints)
        x = augment(windows.x, rng, config, joints)
        batches = length_buckets(windows.valid.sum(1), config.batch_size, rng)
        losses, correct = [], 0
        for idx in batches:
            batch = GestureWindows(x[idx], windows.valid[idx], windows.y[idx], (), (), (), joints)
            loss, ok = train_step(model, optimizer, batch, weights, config.label_smoothing)
            losses.append(loss)
            correct += ok
            scheduler.step()
        history["epoch_loss"].append(round(float(np.mean(losses)), 4))
        history["epoch_train_acc"].append(round(correct / len(x), 4))
        bar.set_postfix(loss=history["epoch_loss"][-1], acc=history["epoch_train_acc"][-1])
        if budget.exceeded():
            history["stopped_early"] = True
            break
    history["epochs_run"] = len(history["epoch_loss"])
    history["train_seconds"] = round(budget.seconds(), 1)
    return model.eval(), history


def extrapolate(windows: GestureWindows, mode: str) -> GestureWindows:
    """Continue each window after its last valid frame to the full length, all frames
    valid: ``mode="cv"`` constant velocity (last displacement), ``"zv"`` zero velocity."""
    x = windows.x.copy()
    for i, v in enumerate(windows.valid):
        n = int(v.sum())
        if n == len(v):
            continue
        vel = x[i, n - 1] - x[i, n - 2] if (mode == "cv" and n >= 2) else 0.0
        k = np.arange(1, len(v) - n + 1, dtype=np.float32)[:, None, None]
        x[i, n:] = x[i, n - 1] + k * vel
    return GestureWindows(x, np.ones_like(windows.valid), windows.y, windows.subjects,
                          windows.datasets, windows.names, windows.joints)


def extrapolate_with_predictor(windows: GestureWindows, predictor: Any) -> GestureWindows:
    """Continue each window after its last valid frame with a learned motion predictor
    (``predict`` on pred17 root-relative histories of ``1 + P`` frames, see
    :mod:`simenv.models.predictor`), all frames valid.

    gesture15 -> pred17: the pelvis and the chest (gesture15 has neither) are derived as
    :func:`simenv.data.prediction_data.to_pred17` derives them
    (:data:`~simenv.data.prediction_data.DERIVED_KEYPOINTS`: mid-hip, spine-neck midpoint);
    the other 15 joints map by name. The lead-in
    frame repeats the first real frame when the window has only P real frames. The
    predicted root-relative poses are put on a constant-velocity root (the predictor
    does not predict the root); repeated predictions (P -> F steps) fill the window.

    Raises:
        MotionError: the windows are not on the gesture15 joints.
    """
    names = list(windows.joints)
    if set(names) != set(GESTURE15_JOINTS):
        raise MotionError("the predicted condition needs gesture15 windows (legs for the "
                          f"pelvis); got joints {', '.join(names)}", field="joints")
    col = {j: names.index(j) for j in names}
    x = windows.x.copy()
    need = predictor.history_len
    for i, v in enumerate(windows.valid):
        n = int(v.sum())
        if n == len(v):
            continue
        real = x[i, :n].astype(np.float64)
        extra = {k: 0.5 * (real[:, col[a]] + real[:, col[b]])
                 for k, (a, b) in DERIVED_KEYPOINTS.items()}
        pelvis = extra["pelvis"]
        pose = np.stack([extra[j] if j in extra else real[:, col[j]] for j in PRED17_JOINTS],
                        axis=1) - pelvis[:, None]
        if n < need:
            pose = np.concatenate([np.repeat(pose[:1], need - n, axis=0), pose])
        future = rollout(predictor, pose[None], len(v) - n)[0]
        vel = pelvis[-1] - pelvis[-2] if n >= 2 else np.zeros(3)
        root = pelvis[-1] + np.arange(1, len(v) - n + 1)[:, None] * vel
        world = future + root[:, None].astype(np.float32)
        x[i, n:] = world[:, [PRED17_JOINTS.index(j) for j in names]]
    return GestureWindows(x, np.ones_like(windows.valid), windows.y, windows.subjects,
                          windows.datasets, windows.names, windows.joints)


def condition_windows(clips: Sequence[GestureClip], joints: Sequence[str],
                      predictor: Any | None = None) -> dict[str, GestureWindows]:
    """The evaluation conditions (see the module docstring) for ``clips``;
    ``real_1s_pred_2s_model`` only when a ``predictor`` is given."""
    short = make_windows(clips, crop="centre", real_frames=SHORT_FRAMES, joints=joints)
    out = {"real_3s": make_windows(clips, crop="centre", joints=joints), "real_1s": short}
    if predictor is not None:
        out["real_1s_pred_2s_model"] = extrapolate_with_predictor(short, predictor)
    out["real_1s_pred_2s_cv"] = extrapolate(short, "cv")
    out["real_1s_pred_2s_zv"] = extrapolate(short, "zv")
    return out


def shipped_predictor() -> Any | None:
    """The shipped :data:`PREDICTOR`, or None when it is not shipped."""
    return load(PREDICTOR) if PREDICTOR in available() else None


def score(y_true: np.ndarray, y_pred: np.ndarray, datasets: Sequence[str]) -> dict[str, Any]:
    """Accuracy, balanced accuracy, per-class recall, confusion matrix, per-dataset
    accuracy and room-reaction accuracy of predictions."""
    c = len(GESTURE_LABELS)
    confusion = np.zeros((c, c), dtype=np.int64)
    np.add.at(confusion, (y_true, y_pred), 1)
    support = confusion.sum(1)
    recall = {GESTURE_LABELS[k]: round(float(confusion[k, k] / support[k]), 4)
              for k in range(c) if support[k]}
    ds = np.asarray(datasets)
    react = np.array([room_reaction(GESTURE_LABELS[k]) for k in range(c)])
    labelled = y_true != GESTURE_LABELS.index(IDLE_LABEL)
    return {
        "n": int(len(y_true)),
        "accuracy": round(float((y_true == y_pred).mean()), 4),
        "accuracy_labelled": round(float((y_true == y_pred)[labelled].mean()), 4),
        "balanced_accuracy": round(float(np.mean(list(recall.values()))), 4),
        "per_class_recall": recall,
        "support": {GESTURE_LABELS[k]: int(support[k]) for k in range(c)},
        "per_dataset_accuracy": {d: round(float((y_true[ds == d] == y_pred[ds == d]).mean()), 4)
                                 for d in sorted(set(datasets))},
        "room_reaction_accuracy": round(float((react[y_true] == react[y_pred]).mean()), 4),
        "confusion": confusion.tolist(),
    }


def evaluate(model: GestureClassifier, clips: Sequence[GestureClip],
             predictor: Any | None = None) -> dict[str, Any]:
    """Scores of every condition of :data:`CONDITIONS` on ``clips`` (the learned-predictor
    condition only with a ``predictor``)."""
    out: dict[str, Any] = {}
    conditions = condition_windows(clips, model.config.joint_names, predictor)
    for name, w in tqdm(conditions.items(), desc="evaluate", leave=False):
        pred = model.predict_proba(w.x, w.valid).argmax(1)
        out[name] = score(w.y, pred, w.datasets)
    return out


def plot_confusions(results: dict[str, Any], path: Path) -> Path:
    """One row-normalised confusion matrix per condition, as a PNG."""
    import matplotlib  # heavy, and only the report's figure needs it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(results)
    fig, axes = plt.subplots(1, len(names), figsize=(6.2 * len(names), 6.0))
    for ax, name in zip(np.atleast_1d(axes), names, strict=True):
        cm = np.asarray(results[name]["confusion"], dtype=float)
        norm = cm / np.maximum(cm.sum(1, keepdims=True), 1)
        ax.imshow(norm, cmap="Blues", vmin=0, vmax=1)
        for i, j in zip(*np.nonzero(cm), strict=True):
            ax.text(j, i, int(cm[i, j]), ha="center", va="center", fontsize=7,
                    color="white" if norm[i, j] > 0.5 else "black")
        ax.set_xticks(range(len(GESTURE_LABELS)), GESTURE_LABELS, rotation=60, ha="right",
                      fontsize=8)
        ax.set_yticks(range(len(GESTURE_LABELS)), GESTURE_LABELS, fontsize=8)
        ax.set_xlabel("predicted")
        ax.set_ylabel("true")
        r = results[name]
        ax.set_title(f"{name}: acc {r['accuracy']:.3f}, bal. {r['balanced_accuracy']:.3f}",
                     fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def split_summary(train_clips: Sequence[GestureClip], test_clips: Sequence[GestureClip]
                  ) -> dict[str, Any]:
    """Subjects and clip counts of each side of the split (``*_idle``: of them, the
    ``idle`` clips per dataset and source, with their seconds of motion)."""
    def idle(clips: Sequence[GestureClip]) -> dict[str, Any]:
        rows: dict[str, Any] = {}
        for c in clips:
            if c.label == IDLE_LABEL:
                row = rows.setdefault(f"{c.dataset}: {c.source_label}", {"clips": 0, "s": 0.0})
                row["clips"] += 1
                row["s"] = round(row["s"] + c.num_frames / GESTURE_FPS, 2)
        return rows

    return {
        "rule": "odd subject ids train, even ids test, per dataset (subject = dataset/sNN)",
        "train_subjects": sorted({c.subject_key for c in train_clips}),
        "test_subjects": sorted({c.subject_key for c in test_clips}),
        "train_clips": len(train_clips),
        "test_clips": len(test_clips),
        "train_idle": idle(train_clips),
        "test_idle": idle(test_clips),
    }


def results_markdown(metrics: dict[str, Any]) -> str:
    """The test-results tables of a model card (per condition; per-class recall) from
    the metrics of a training run or of :func:`run_evaluation`;
    ``benchmarks/model_docs.py`` puts the same text into docs/recognition_transformer.md."""
    ev = metrics["test"]
    per_ds = " / ".join(sorted(ev["real_3s"]["per_dataset_accuracy"]))
    rows = "\n".join(
        f"| {c} | {ev[c]['accuracy']:.3f} | {ev[c].get('accuracy_labelled', ev[c]['accuracy']):.3f}"
        f" | {ev[c]['balanced_accuracy']:.3f} | {ev[c]['room_reaction_accuracy']:.3f} | "
        + " / ".join(f"{ev[c]['per_dataset_accuracy'][d]:.3f}"
                     for d in sorted(ev[c]['per_dataset_accuracy'])) + " |"
        for c in ev)
    recall = "\n".join(
        f"| {k} | {ev['real_3s']['support'][k]} | {ev['real_3s']['per_class_recall'].get(k, 0):.3f}"
        f" | {ev['real_1s']['per_class_recall'].get(k, 0):.3f} |" for k in GESTURE_LABELS)
    head = ("| condition | accuracy | labelled clips only | balanced acc. | "
            f"room-reaction acc. | per dataset ({per_ds}) |")
    return f"""{head}
|---|---|---|---|---|---|
{rows}

"labelled clips only": the accuracy without the `idle` test windows (the test set of the
classifier before it had an idle class).

`real_1s_pred_2s_model`: 1 s real + 2 s predicted by the shipped
`{metrics.get('predictor') or 'predictor-25-50 (not shipped: condition skipped)'}`;
`real_1s_pred_2s_cv` / `_zv`: 1 s real + 2 s from a constant-velocity / zero-velocity
extrapolation. Thesis (its own 7-gesture data): 63.6 % (3 s),
47.7 % (1 s), 60.2 % (1 s + 2 s predicted).

Per-class recall (test):

| label | test windows | 3 s real | 1 s real |
|---|---|---|---|
{recall}
"""


def _idle_text(rows: dict[str, Any] | None) -> str:
    """``split_summary``'s idle counts as a phrase."""
    if not rows:
        return "none"
    return ", ".join(f"{k} {v['clips']} clips ({v['s']:.1f} s)" for k, v in rows.items())


def model_card(metrics: dict[str, Any]) -> str:
    """Markdown model card of a trained classifier from its metrics."""
    cfg, split = metrics["config"], metrics["split"]
    return f"""# gesture-classifier

Spatio-temporal transformer gesture classifier (skeleton-adjacency spatial mask
I + inward + outward, temporal attention, MLP head): `simenv.models.gesture_classifier`.
Input: 3-s windows (75 frames at 25 fps) on the `{cfg['joints']}` joints, built and
normalised by `simenv.data.gestures` (root-relative at the window start, facing +X, arm-size
scale); padded frames masked. Output: the {len(GESTURE_LABELS)} labels of the room's
gesture vocabulary ({', '.join(GESTURE_LABELS)}). `features()` gives the
{cfg['feature_dim']}-d penultimate features for FID/FVD.

Load: `simenv.models.load("gesture-classifier")` (or `GestureClassifier.load(path)`); raw
world-frame windows: `model.classify_world(x)`.

## Data
Real Kinect-era recordings in `shared/data/gestures` (research use; see its SOURCES.md):
MSR Action3D (s01-s09), UTKinect-Action3D (segments of the 20 sessions), Florence 3D.
{metrics['clips']} clips; skipped: {'; '.join(metrics['skipped']) or 'none'}.
`idle` (no gesture) clips, cut from real near-still frames that carry no label (criterion
and sources: `simenv.data.gestures`, section *Idle*): train {_idle_text(split.get('train_idle'))};
test {_idle_text(split.get('test_idle'))}.

## Split (cross-subject)
{split['rule']}. Train: {split['train_clips']} clips, {len(split['train_subjects'])} subjects;
test: {split['test_clips']} clips, {len(split['test_subjects'])} subjects. No subject on both
sides. No model selection on the test split (fixed schedule).

## Training
Seed {cfg['seed']}, {metrics['history']['epochs_run']} epochs in
{metrics['history']['train_seconds']:.0f} CPU s on one thread; AdamW lr {cfg['lr']}, batch
{cfg['batch_size']}, dim {cfg['dim']}, {cfg['layers']} blocks, {cfg['heads']} heads;
windows: random 3-s crop, or a random 1 s with the rest masked (p {cfg.get('short_prob', 0)})
or held as valid frames (p {cfg.get('hold_prob', 0)}); augmentation: mirror, yaw
±{cfg['max_yaw_deg']}°, scale ±{cfg['max_scale']}.
Parameters: {metrics['parameters']}.

## Test results (cross-subject)

{results_markdown(metrics)}
Confusion matrices: `confusion.png` next to the metrics of the training run.
"""


def run_training(config: TrainConfig, out: Path, *, progress: bool = True) -> dict[str, Any]:
    """Load data, train, evaluate, write ``metrics.json``, ``confusion.png``, the
    checkpoint and its card into ``out``; returns the metrics."""
    out = Path(out)
    report = LoadReport()
    clips = load_gesture_clips(config.data, joints=config.joints,  # type: ignore[arg-type]
                               report=report, idle=config.idle)
    train_clips, test_clips = split_cross_subject(clips)
    if not test_clips:
        raise SimenvError("the cross-subject split left no test clip (no even subject id)",
                          source=config.data)
    model, history = train(config, train_clips, progress=progress)
    predictor = shipped_predictor()
    results = evaluate(model, test_clips, predictor)
    metrics: dict[str, Any] = {
        "config": asdict(config),
        "clips": len(clips),
        "skipped": report.skipped,
        "split": split_summary(train_clips, test_clips),
        "labels": list(GESTURE_LABELS),
        "parameters": sum(p.numel() for p in model.parameters()),
        "history": history,
        "predictor": PREDICTOR if predictor is not None else None,
        "test": results,
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=1))
    plot_confusions(results, out / "confusion.png")
    model.save(out / "gesture-classifier.npz", metadata={
        "labels": list(GESTURE_LABELS), "split": metrics["split"]["rule"],
        "test_accuracy": {c: results[c]["accuracy"] for c in results},
        "seed": config.seed})
    (out / "gesture-classifier.md").write_text(model_card(metrics))
    return metrics


def run_evaluation(checkpoint: Path, data: Path, out: Path) -> dict[str, Any]:
    """Evaluate a saved classifier on the test subjects of ``data``; writes
    ``metrics.json`` and ``confusion.png`` into ``out``.

    Besides the scores, the metrics record what the data section of the docs states
    (clip count, skipped recordings, split, parameter count), so that
    ``benchmarks/model_docs.py`` can write docs/recognition_transformer.md from them alone."""
    model = GestureClassifier.load(checkpoint)
    joints = model.config.extra.get("joint_set", "gesture15")
    report = LoadReport()
    clips = load_gesture_clips(data, joints=joints, report=report,
                               idle=IDLE_LABEL in model.config.labels)
    train_clips, test_clips = split_cross_subject(clips)
    predictor = shipped_predictor()
    results = evaluate(model, test_clips, predictor)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    metrics = {"checkpoint": str(checkpoint), "test": results,
               "predictor": PREDICTOR if predictor is not None else None,
               "clips": len(clips), "skipped": report.skipped,
               "parameters": sum(p.numel() for p in model.parameters()),
               "split": split_summary(train_clips, test_clips)}
    (out / "metrics.json").write_text(json.dumps(metrics, indent=1))
    plot_confusions(results, out / "confusion.png")
    return metrics


def _print_summary(results: dict[str, Any]) -> None:
    for name, r in results.items():
        print(f"{name:>20}: accuracy {r['accuracy']:.3f}  balanced {r['balanced_accuracy']:.3f}"
              f"  room {r['room_reaction_accuracy']:.3f}  (n={r['n']})")


def add_train_arguments(parser: argparse.ArgumentParser) -> None:
    """The training options (``simenv train classifier``), on ``parser``."""
    parser.add_argument("--config", help="TOML or JSON file with TrainConfig options")
    parser.add_argument("--data", help=f"gestures folder (default {DEFAULT_DATA})")
    parser.add_argument("--out", default="out/gesture-classifier", help="output folder")
    parser.add_argument("--epochs", type=int,
                        help=f"training epochs (default: --config's, else {TrainConfig.epochs})")
    parser.add_argument("--seed", type=int,
                        help=f"seed (default: --config's, else {TrainConfig.seed})")
    parser.add_argument("--max-minutes", type=float, help="CPU-time budget (default: "
                        f"--config's, else {TrainConfig.max_minutes})")


def add_eval_arguments(parser: argparse.ArgumentParser) -> None:
    """The evaluation options of ``python -m simenv.learning.train_classifier eval``."""
    parser.add_argument("--model", default="gesture-classifier",
                        help="shipped classifier name")
    parser.add_argument("--checkpoint", help="a checkpoint file instead of a shipped model")
    parser.add_argument("--data", default=str(DEFAULT_DATA), help="gestures folder")
    parser.add_argument("--out", default="out/gesture-classifier-eval", help="output folder")


def _run_and_report(job: Callable[[], dict[str, Any]], out: str | Path) -> int:
    """Run ``job`` (training or evaluation), print its test summary and where its outputs
    are; 2 on a user error."""
    try:
        metrics = job()
    except SimenvError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    _print_summary(metrics["test"])
    print(f"outputs in {out}")
    return 0


def train_command(args: argparse.Namespace) -> int:
    """Train with the options of :func:`add_train_arguments`; 2 on a user error."""
    overrides = {k: v for k, v in (("data", args.data), ("epochs", args.epochs),
                                   ("seed", args.seed), ("max_minutes", args.max_minutes))
                 if v is not None}

    def job() -> dict[str, Any]:
        config = (TrainConfig.from_file(args.config, **overrides) if args.config
                  else TrainConfig(**overrides))
        return run_training(config, Path(args.out))

    return _run_and_report(job, args.out)


def eval_command(checkpoint: Path, data: Path, out: Path) -> int:
    """Evaluate ``checkpoint`` on the test subjects of ``data``, write to ``out`` and print
    the summary; 2 on a user error."""
    return _run_and_report(lambda: run_evaluation(checkpoint, data, out), out)


def main(argv: Sequence[str] | None = None) -> int:
    """``train`` / ``eval`` entry point (see the module docstring)."""
    parser = argparse.ArgumentParser(prog="python -m simenv.learning.train_classifier",
                                     description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    add_train_arguments(sub.add_parser("train", help="train on the gesture corpus and evaluate"))
    add_eval_arguments(sub.add_parser("eval", help="evaluate a checkpoint on the test subjects"))
    args = parser.parse_args(argv)
    if args.command == "train":
        return train_command(args)
    try:
        checkpoint = Path(args.checkpoint) if args.checkpoint else checkpoint_path(args.model)
    except SimenvError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return eval_command(checkpoint, Path(args.data), Path(args.out))


if __name__ == "__main__":
    raise SystemExit(main())

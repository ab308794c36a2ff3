"""What a user reads of a recogniser's evaluation: per-class accuracy on the terminal and the
confusion matrices as JSON and PNG, so the failing gestures are visible, not only the mean.

:func:`evaluate_recogniser` scores a shipped recogniser (or a checkpoint) on labelled
recordings in the conditions of ``simenv eval classifier``; :func:`per_class_table` and
:func:`write_confusions` present any result whose conditions carry
:func:`simenv.learning.recognition_protocols.classification_scores` (the cross-dataset
protocol's too).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

import simenv.models
from simenv.core.errors import SimenvError
from simenv.data.gestures import LoadReport, load_labelled
from simenv.learning.recognition import logits_of
from simenv.learning.recognition_protocols import classification_scores, condition_windows
from simenv.learning.train_classifier import plot_confusions
from simenv.models.skeleton_tcn import SkeletonTCN

#: Conditions ``simenv eval classifier`` reports (of the room protocol's).
EVAL_CONDITIONS: tuple[str, ...] = ("real_3s", "real_1s", "real_1s_pred_2s")


def evaluate_recogniser(paths: Sequence[str], *, model_name: str,
                        checkpoint: str | None = None, predictor: str | None = None
                        ) -> dict[str, Any]:
    """Scores of a recogniser on the labelled recordings under ``paths``.

    Args:
        paths: corpus roots, dataset folders or recording files
            (:func:`simenv.data.gestures.load_labelled`).
        model_name: shipped recogniser (used when ``checkpoint`` is None).
        checkpoint: a :class:`SkeletonTCN` checkpoint file instead.
        predictor: shipped forecaster of ``real_1s_pred_2s`` (None: condition skipped).

    Returns:
        ``clips``, ``labels``, ``subjects``, ``skipped``, ``model``, ``predictor`` and
        ``conditions``: per condition of :data:`EVAL_CONDITIONS` the scores of
        :func:`~simenv.learning.recognition_protocols.classification_scores` (accuracy,
        balanced accuracy, per-class recall, confusion with rows true, per dataset).

    Raises:
        SimenvError: no usable recording, or a label outside the recogniser's vocabulary.
    """
    model = SkeletonTCN.load(checkpoint) if checkpoint else simenv.models.load(model_name)
    report = LoadReport()
    clips = load_labelled(paths, report=report)
    labels = list(model.config.labels)
    unknown = sorted({c.label for c in clips} - set(labels))
    if unknown:
        raise SimenvError(f"labels {unknown} are not in the recogniser's vocabulary "
                          f"{labels}", field="data")
    forecast = simenv.models.load(predictor).predict_batch if predictor else None
    y = np.array([labels.index(c.label) for c in clips])
    datasets = [c.dataset for c in clips]
    conditions = {}
    for name, (x, valid) in condition_windows(clips, forecast).items():
        if name in EVAL_CONDITIONS:
            pred = logits_of(model, x, valid).argmax(1)
            conditions[name] = classification_scores(y, pred, labels, datasets)
    return {"clips": len(clips), "labels": labels, "conditions": conditions,
            "skipped": report.skipped, "model": checkpoint or model_name,
            "predictor": predictor, "subjects": sorted({c.subject_key for c in clips})}


def per_class_table(conditions: dict[str, dict[str, Any]], labels: Sequence[str]) -> str:
    """Plain-text table: one row per class present in any condition, its test clips and
    its recall (the fraction of its clips classified as it) per condition, and the most
    frequent wrong answer of the first condition; a row of the overall accuracies."""
    names = list(conditions)
    first = np.asarray(conditions[names[0]]["confusion"])
    support = first.sum(1)
    width = max(12, *(len(n) for n in names))
    head = f"{'class':<14}{'clips':>6}" + "".join(f"{n:>{width + 2}}" for n in names)
    lines = [head + "  most confused with (" + names[0] + ")"]
    for k, label in enumerate(labels):
        if not support[k]:
            continue
        row = f"{label:<14}{int(support[k]):>6}"
        for n in names:
            recall = conditions[n]["per_class_recall"].get(label)
            row += f"{'-' if recall is None else f'{recall:.3f}':>{width + 2}}"
        wrong = first[k].copy()
        wrong[k] = 0
        if wrong.any():
            j = int(np.argmax(wrong))
            row += f"  {labels[j]} ({int(wrong[j])})"
        lines.append(row)
    lines.append(f"{'all':<14}{int(support.sum()):>6}"
                 + "".join(f"{conditions[n]['accuracy']:>{width + 2}.3f}" for n in names))
    return "\n".join(lines)


def write_confusions(conditions: dict[str, dict[str, Any]], labels: Sequence[str],
                     out: Path, stem: str = "confusion") -> tuple[Path, Path]:
    """``out/<stem>.json`` (per condition: labels, confusion with rows true and columns
    predicted, per-class recall, accuracy) and ``out/<stem>.png`` (row-normalised
    matrices, one panel per condition); returns both paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    keep = ("n", "accuracy", "balanced_accuracy", "per_class_recall", "confusion")
    json_path = out / f"{stem}.json"
    json_path.write_text(json.dumps(
        {"labels": list(labels), "rows": "true label", "columns": "predicted label",
         "conditions": {n: {k: c[k] for k in keep if k in c}
                        for n, c in conditions.items()}}, indent=1))
    return json_path, plot_confusions(conditions, out / f"{stem}.png")


__all__ = ["EVAL_CONDITIONS", "evaluate_recogniser", "per_class_table", "write_confusions"]

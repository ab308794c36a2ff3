"""Train, measure and ship the room's gesture recogniser; evaluate it on any labelled data.

``python -m simenv.perception.train_recogniser train --out DIR`` (also ``simenv train recogniser``):

1. the room vocabulary, leave-subjects-out over every subject of the gesture corpus
   (:func:`simenv.learning.recognition_protocols.run_room_protocol`), each fold's network trained
   with "1 s real + forecast" windows from that fold's forecaster (``--forecasters DIR``:
   ``DIR/fold<k>/model.npz``, gesture predictors trained without the fold's subjects by
   :mod:`simenv.learning.train_gesture_predictor`);
2. the perception loop on the held-out subjects as the room runs it
   (:mod:`simenv.perception.protocol`: avatar keypoints, ticks every second), with and
   without the forecast stage, thresholds cross-fitted;
3. the shipped network: trained on every subject with the shipped forecaster
   ``predictor-gesture-25-50``, its temperature fitted on all out-of-fold logits and its
   loop threshold chosen on all out-of-fold loop readings; written as
   ``gesture-tcn.npz`` with its card ``gesture-tcn.md`` and ``metrics.json``.

``eval --data PATH... [--json]``: the room's recogniser (``--model``, default
:data:`simenv.perception.loop.DEFAULT_CLASSIFIER`; or a ``--checkpoint`` file) on any
labelled recordings (:func:`simenv.data.gestures.load_labelled`) in the conditions ``real_3s``,
``real_1s`` and ``real_1s_pred_2s`` (the forecaster: ``--predictor``, default the shipped
gesture predictor). ``--json`` prints one object ``{"clips": N, "conditions": {name:
{"accuracy": a, "balanced_accuracy": b}}}``. Clips of subjects the shipped network trained
on are in-sample; the protocol's numbers are the unseen-subject ones.

``benchmark [--dataset NAME] [--joints {gesture15,native}] [--epochs N]``:
:func:`simenv.learning.recognition_protocols.run_benchmark` on MSR Action3D, UTKinect and Florence
3D, printed next to the published figures, each network trained for ``--epochs`` (default
:data:`BENCHMARK_EPOCHS`; 1 runs every step quickly, its numbers thrown away); ``--joints
native`` trains and tests on each dataset's own skeleton (results
``<dataset>_m<members>_w<whole>_native.json``);
``--neighbour {euclidean,dtw}`` runs the nearest-neighbour baseline instead of the networks
(:mod:`simenv.learning.nearest_neighbour`; results ``<dataset>_nn-<distance>.json``);
``--mirror-test`` averages each network over the test clip and its mirror image (results
``..._mirror-test.json``); ``--covariance alone`` runs the covariance-descriptor classifier
instead of the networks (:mod:`simenv.learning.covariance`; ``<dataset>_cov.json``),
``--covariance fused`` multiplies the networks' probabilities with its (``..._cov.json``),
``--covariance weighted`` weighs the two by a weight chosen on each fold's training subjects
(a network per training subject more; ``..._covw.json``); with ``--lie-group`` the
covariance classifier also chooses among Lie-group descriptors
(:mod:`simenv.learning.lie_group`; the result's name ends in ``_lie``).
``--dataset room --neighbour D`` runs the nearest neighbour on the room vocabulary's
leave-subjects-out folds (:func:`simenv.learning.recognition_protocols.room_nearest_neighbour`;
``room_nn-<distance>.json``), ``--dataset room --covariance alone [--lie-group]`` the
covariance classifier (:func:`~simenv.learning.recognition_protocols.room_descriptors`;
``room_cov[_lie].json``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np

import simenv.models
from simenv.core.config import shared_data_root
from simenv.core.errors import SimenvError
from simenv.data.gestures import (
    GESTURE_LABELS,
    LoadReport,
    load_gesture_clips,
    subject_fold,
)
from simenv.learning.nearest_neighbour import NEIGHBOUR_DISTANCES
from simenv.learning.recognition import Forecaster, RecognitionConfig, train_recogniser
from simenv.learning.recognition_protocols import (
    BENCHMARK_EPOCHS,
    BENCHMARK_JOINTS,
    COVARIANCE_MODES,
    PUBLISHED,
    ROOM_CONDITIONS,
    benchmark_config,
    calibrated,
    room_descriptors,
    room_nearest_neighbour,
    run_benchmark,
    run_room_protocol,
)
from simenv.learning.recognition_report import evaluate_recogniser
from simenv.models.gesture_predictor import GesturePredictor
from simenv.perception.loop import DEFAULT_CLASSIFIER
from simenv.perception.protocol import (
    avatar_clips,
    choose_threshold,
    cross_fitted_outcomes,
    stream_readings,
)

#: Registry name of the shipped recogniser and of its forecaster.
MODEL_NAME = "gesture-tcn"
FORECASTER = "predictor-gesture-25-50"
#: Real windows (frames) the shipped loop classifies at each tick: the thesis's 1 s and
#: the last 2 and 3 s (3 s of real motion is read far better than 1 s; fixed before the
#: loop was measured with them). The 1-s-only loop is reported beside it.
LOOP_WINDOWS: tuple[int, ...] = (25, 50, 75)


def _default_data() -> Path:
    return shared_data_root(None) / "gestures"


def shipped_forecaster() -> Forecaster | None:
    """``predict_batch`` of the shipped :data:`FORECASTER`, or None when not shipped."""
    if FORECASTER not in simenv.models.available():
        return None
    return simenv.models.load(FORECASTER).predict_batch


def fold_forecasters(folder: Path | None, folds: int) -> list[Forecaster] | None:
    """The per-fold forecasters ``folder/fold<k>/model.npz`` (None without a folder).

    Raises:
        SimenvError: a fold's checkpoint is missing.
    """
    if folder is None:
        return None
    out = []
    for k in range(folds):
        path = Path(folder) / f"fold{k}" / "model.npz"
        if not path.is_file():
            raise SimenvError(f"no forecaster for fold {k} (train the five folds' with python -m "
                              "simenv.learning.train_gesture_predictor --evaluate, or this one "
                              f"with --fold {k})", source=path)
        out.append(GesturePredictor.load(path).predict_batch)
    return out


def plot_confusions(conditions: dict[str, Any], labels: Sequence[str], path: Path) -> Path:
    """Row-normalised confusion matrix of each condition, one PNG."""
    import matplotlib  # heavy, and only the report's figure needs it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(conditions)
    fig, axes = plt.subplots(1, len(names), figsize=(4.2 * len(names), 4.4))
    for ax, name in zip(np.atleast_1d(axes), names, strict=True):
        c = np.asarray(conditions[name]["confusion"], float)
        ax.imshow(c / np.maximum(c.sum(1, keepdims=True), 1), vmin=0, vmax=1, cmap="Blues")
        ax.set_title(f"{name}: {conditions[name]['accuracy']:.3f}", fontsize=9)
        ax.set_xticks(range(len(labels)), labels, rotation=90, fontsize=6)
        ax.set_yticks(range(len(labels)), labels, fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _loop(protocol: dict[str, Any], clips: Sequence[Any], forecasters: list[Forecaster] | None,
          progress: bool) -> dict[str, Any]:
    """Step 2 of ``train``: the loop on held-out avatar clips with the shipped windows
    (:data:`LOOP_WINDOWS`) and with the thesis's 1 s alone, each with and without the
    forecast stage; ``readings`` are the shipped windows' (for the shipped threshold)."""
    avatars, skipped = avatar_clips(clips, progress=progress)
    readings = []
    for k, model in enumerate(protocol["models"]):
        held = [c for c in avatars if subject_fold(c.subject_key) == k]
        readings += stream_readings(held, model, forecasters[k] if forecasters else None,
                                    seed=k, real_windows=LOOP_WINDOWS)
    one_second = [replace(r, logits_real=r.logits_real[:, :1]) for r in readings]
    temps = [row["temperature"] for row in protocol["folds"]]
    out: dict[str, Any] = {"clips": len(readings), "skipped": skipped,
                           "windows_s": [w / 25.0 for w in LOOP_WINDOWS]}
    for tag, rows in (("", readings), ("1s_", one_second)):
        out[f"{tag}real_only"] = cross_fitted_outcomes(rows, subject_fold, GESTURE_LABELS,
                                                       temps, use_forecast=False)
        if forecasters:
            out[f"{tag}with_forecast"] = cross_fitted_outcomes(
                rows, subject_fold, GESTURE_LABELS, temps, use_forecast=True)
    out["readings"] = readings
    return out


def run_train(config: RecognitionConfig, out: Path, *, data: Path,
              forecasters_dir: Path | None, progress: bool = True) -> dict[str, Any]:
    """``train`` (module docstring); writes into ``out`` and returns the metrics."""
    start = time.process_time()
    report = LoadReport()
    clips = load_gesture_clips(data, idle=True, report=report)
    forecasters = fold_forecasters(forecasters_dir, 5)
    protocol = run_room_protocol(
        clips, config, forecaster_for_fold=(lambda k: forecasters[k]) if forecasters else None,
        progress=progress, keep_models=True)
    loop = _loop(protocol, [c for c in clips if c.dataset != "florence3d"], forecasters,
                 progress)
    use_forecast = bool(forecasters) and _better(loop.get("with_forecast"), loop["real_only"])
    temperature = protocol["temperature_all"]
    threshold = choose_threshold(loop.pop("readings"), GESTURE_LABELS, temperature,
                                 use_forecast=use_forecast)
    forecast = shipped_forecaster()
    model, history = train_recogniser(clips, GESTURE_LABELS, lambda c: c.label, config,
                                      forecast=forecast, progress=progress,
                                      extra={"joint_set": "gesture15",
                                             "trained_on": "every subject of the corpus"})
    calibrated(model, temperature)
    for k, fold_model in enumerate(protocol.pop("models")):
        # Kept for later analysis of the loop on held-out subjects (not shipped).
        calibrated(fold_model, protocol["folds"][k]["temperature"])
        fold_model.save(out / "folds" / f"fold{k}.npz")
    metrics = {"config": asdict(config), "clips": len(clips), "skipped": report.skipped,
               "protocol": {k: v for k, v in protocol.items() if k != "oof"},
               "loop": loop, "loop_uses_forecast": use_forecast,
               "loop_threshold": threshold, "temperature": temperature,
               "history": history, "forecaster": FORECASTER if forecast else None,
               "parameters": sum(p.numel() for p in model.parameters()),
               "cpu_s": round(time.process_time() - start, 1)}
    out.mkdir(parents=True, exist_ok=True)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=1, default=float))
    (out / "oof.json").write_text(json.dumps(protocol["oof"]))
    plot_confusions(protocol["conditions"], GESTURE_LABELS, out / "confusion.png")
    model.save(out / f"{MODEL_NAME}.npz", metadata={
        "loop_threshold": threshold, "loop_uses_forecast": use_forecast,
        "loop_windows": list(LOOP_WINDOWS),
        "temperature": temperature, "seed": config.seed,
        "protocol_accuracy": {c: protocol["conditions"][c]["accuracy"]
                              for c in protocol["conditions"]}})
    (out / f"{MODEL_NAME}.md").write_text(model_card(metrics))
    return metrics


def _better(with_forecast: dict[str, Any] | None, real_only: dict[str, Any]) -> bool:
    """Whether the loop with the forecast stage greets more waves at no more false
    greetings than without (on the cross-fitted held-out outcomes)."""
    if with_forecast is None:
        return False
    false = [(r["other_clips"][0] + r["idle_clips"][0]) for r in (with_forecast, real_only)]
    return (with_forecast["greet_clips"][0] > real_only["greet_clips"][0]
            and false[0] <= false[1])


def _loop_row(name: str, r: dict[str, Any]) -> str:
    (a, n), (b, m), (c, q) = r["greet_clips"], r["other_clips"], r["idle_clips"]
    d = r["decision_after_onset_s"]
    return (f"| {name} | {a}/{n} ({a / max(n, 1):.1%}) | {b}/{m} ({b / max(m, 1):.1%}) | "
            f"{c}/{q} ({c / max(q, 1):.1%}) | {d['median']} / {d['p90']} | "
            f"{r['decided_before_end']:.1%} | "
            f"{', '.join(str(f['threshold']) for f in r['folds'])} |")


def protocol_table(metrics: dict[str, Any]) -> str:
    """Markdown tables of the protocol's conditions and the loop (card and docs)."""
    cond = metrics["protocol"]["conditions"]
    lines = ["| condition | accuracy | balanced acc. | room-reaction acc. | wave recall | "
             "per dataset (florence3d / msr_action3d / utkinect) |", "|---|---|---|---|---|---|"]
    for name in ROOM_CONDITIONS:
        if name in cond:
            s = cond[name]
            per = " / ".join(f"{s['per_dataset_accuracy'][d]:.3f}"
                             for d in sorted(s["per_dataset_accuracy"]))
            lines.append(f"| {name} | {s['accuracy']:.3f} | {s['balanced_accuracy']:.3f} | "
                         f"{s['room_reaction_accuracy']:.3f} | "
                         f"{s['per_class_recall'].get('wave', float('nan')):.3f} | {per} |")
    loop = metrics["loop"]
    lines += ["", "| loop stages | waves greeted | other actions greeted | idle greeted | "
              "decision after onset, s (median / p90) | greeted waves decided before the "
              "end | threshold per fold |", "|---|---|---|---|---|---|---|"]
    windows = " / ".join(f"{w:g}" for w in loop.get("windows_s", [1.0]))
    for key, name in (("1s_real_only", "1 s real (the thesis's tick)"),
                      ("1s_with_forecast", "1 s real, then 1 s real + 2 s forecast"),
                      ("real_only", f"last {windows} s real"),
                      ("with_forecast", f"last {windows} s real, then 1 s real + 2 s "
                                        "forecast")):
        if key in loop:
            lines.append(_loop_row(name, loop[key]))
    return "\n".join(lines)


def model_card(metrics: dict[str, Any]) -> str:
    """The shipped checkpoint's model card (markdown)."""
    folds = metrics["protocol"]["folds"]
    uses = metrics["loop_uses_forecast"]
    why = ("greets more waves at no more false greetings" if uses else
           "did not greet more waves at no more false greetings")
    return f"""# {MODEL_NAME}

The room's gesture recogniser: a multi-stream skeleton TCN
(`simenv.models.skeleton_tcn.SkeletonTCN`, {metrics['parameters']} parameters) on the 15
gesture joints at 25 fps, the room's vocabulary ({', '.join(GESTURE_LABELS)}). Trained by
`python -m simenv.perception.train_recogniser train` on every subject of the gesture corpus
({metrics['clips']} clips, idle included; {metrics['history']['train_cpu_s']} CPU s), with
"1 s real + 2 s forecast" windows from `{metrics['forecaster']}`.
Temperature {metrics['temperature']:.3f} (fitted on out-of-fold logits); loop threshold
{metrics['loop_threshold']} (chosen on out-of-fold loop readings: greetings on at most
2 % of non-wave clips); the loop {'uses' if uses else 'does not use'} the forecast stage
(with it the loop {why} on held-out subjects).

## On subjects it never saw (leave-subjects-out, {len(folds)} folds)

{protocol_table(metrics)}

Per fold (accuracy, real_3s / real_1s): {'; '.join(f"fold {f['fold']} "
f"({', '.join(f['test_subjects'])}): {f['real_3s']:.3f} / {f['real_1s']:.3f}" for f in folds)}.

Training options: `{json.dumps(metrics['config'])}`.
"""


def run_eval(paths: Sequence[str], *, checkpoint: str | None = None,
             model_name: str = DEFAULT_CLASSIFIER, predictor: str | None = FORECASTER
             ) -> dict[str, Any]:
    """``eval`` (module docstring): scores of each condition on the clips of ``paths``
    (:func:`simenv.learning.recognition_report.evaluate_recogniser`, without the
    confusion matrices)."""
    result = evaluate_recogniser(paths, model_name=model_name, checkpoint=checkpoint,
                                 predictor=predictor)
    del result["labels"]
    keep = ("accuracy", "balanced_accuracy", "n", "per_class_recall", "per_dataset_accuracy")
    result["conditions"] = {name: {k: scores[k] for k in keep}
                            for name, scores in result["conditions"].items()}
    return result


def benchmark_rows(results: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per ensemble size: an ensemble's result carries its smaller ensembles (its
    first k networks, ``smaller_ensembles``), each a copy of the result with its numbers;
    the result itself comes last."""
    return [r | smaller for r in results for smaller in [*r.get("smaller_ensembles", []), {}]]


def benchmark_table(results: Sequence[dict[str, Any]]) -> str:
    """Markdown: each benchmark's accuracy next to the published figures (today's
    :data:`PUBLISHED`, so a result written before a figure was corrected shows the
    correction; the result's own copy for a benchmark no longer listed)."""
    lines = ["| dataset | protocol | classes | clips | training windows | simenv accuracy "
             "(pooled) | mean of folds | published | training CPU s |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in benchmark_rows(results):
        figures = PUBLISHED.get(r["dataset"], r["published"])
        pub = "; ".join(f"{k} {v:.1f} %" for k, v in figures.items())
        method = r.get("method", "network")
        family = ("covariance and Lie-group" if "lie group" in r.get("descriptors", [])
                  else "covariance")
        if method == "covariance":  # its descriptor's joints are its own choice
            windows = f"none: {family} descriptors (ridge), whole sequences"
        elif not method.startswith("network"):  # no training windows
            windows = f"none: {method}, whole sequences, {r.get('joints', 'gesture15')}"
        else:
            windows = ("whole sequences" if r.get("whole_sequences") else
                       f"crops <= {r['config']['max_frames']} frames")
            windows += f", {r.get('members', 1)} network(s), {r.get('joints', 'gesture15')}"
            if r.get("mirror_test"):
                windows += ", test clip + its mirror"
            if method == "network + covariance":
                windows += f", fused with the {family} classifier"
            elif method == "network + covariance, weighted":
                weights = sorted({f["covariance"]["fusion"]["weight"] for f in r["folds"]})
                windows += (f", fused with the {family} classifier, weight from the "
                            f"training subjects ({', '.join(f'{w:g}' for w in weights)})")
        if r.get("joints", "gesture15") != "gesture15":
            windows += f" ({len(r['skeleton']['joint_names'])} joints)"
        classes = f"{len(r['classes'])}"
        per_fold = {f.get("classes", len(r["classes"])) for f in r.get("folds", [])}
        if per_fold and max(per_fold) < len(r["classes"]):
            classes = f"{max(per_fold)} per fold ({classes} in all)"
        mean = f"{100 * r['mean_fold_accuracy']:.1f} %"
        if 1 < len(r.get("folds", [])) <= 3:  # a few named folds (action sets): each one
            mean += " (" + ", ".join(f"{f['fold']} {100 * f['accuracy']:.1f}"
                                     for f in r["folds"]) + ")"
        lines.append(f"| {r['dataset']} | {r['protocol']} | {classes} | "
                     f"{r['clips']} | {windows} | {100 * r['scores']['accuracy']:.1f} % | "
                     f"{mean} | {pub} | {r['train_cpu_s']} |")
    return "\n".join(lines)


def add_train_arguments(p: argparse.ArgumentParser) -> None:
    """The training options (``simenv train recogniser``), on ``p``."""
    p.add_argument("--data", help="gestures folder (default: the shared corpus)")
    p.add_argument("--out", default="out/gesture-tcn", help="output folder")
    p.add_argument("--config", help="TOML or JSON file of RecognitionConfig options")
    p.add_argument("--epochs", type=int, help="training epochs (default: --config's, else "
                   f"{RecognitionConfig.epochs})")
    p.add_argument("--seed", type=int,
                   help=f"seed (default: --config's, else {RecognitionConfig.seed})")
    p.add_argument("--forecasters", help="folder of per-fold gesture predictors "
                   "(fold<k>/model.npz; default: none, the protocol's folds and the loop "
                   "run without a forecast)")


def add_eval_options(p: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """The evaluation options besides the data, model, output and ``--json``."""
    p.add_argument("--checkpoint", help="a SkeletonTCN checkpoint file instead of a "
                   "shipped recogniser")
    p.add_argument("--predictor", default=FORECASTER,
                   help="forecaster of real_1s_pred_2s ('none' to skip)")


def add_benchmark_options(p: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """The benchmark options besides the dataset, data, output and ``--json``."""
    p.add_argument("--members", type=int, default=1,
                   help="networks of consecutive seeds averaged per fold")
    p.add_argument("--epochs", type=int, default=BENCHMARK_EPOCHS,
                   help="training epochs of each network (default %(default)s; 1: a quick "
                   "run with throw-away numbers)")
    p.add_argument("--whole-sequences", action="store_true",
                   help="train on whole sequences instead of 5-s crops")
    p.add_argument("--joints", choices=BENCHMARK_JOINTS, default="gesture15",
                   help="joint set: the room's gesture15, or each dataset's own skeleton "
                   "(native)")
    p.add_argument("--neighbour", choices=NEIGHBOUR_DISTANCES,
                   help="the nearest-neighbour baseline (this distance) instead of the "
                   "networks")
    p.add_argument("--covariance", choices=COVARIANCE_MODES,
                   help="the covariance-descriptor classifier alone, fused with the networks "
                   "at equal weights, or weighted by the training subjects "
                   "(simenv.learning.covariance)")
    p.add_argument("--lie-group", action="store_true",
                   help="with --covariance: the classifier also chooses among Lie-group "
                   "descriptors (simenv.learning.lie_group)")
    p.add_argument("--mirror-test", action="store_true",
                   help="average each network over the test clip and its mirror image")


#: ``benchmark``'s datasets: a benchmark, all of them, or the room vocabulary's folds.
BENCHMARK_DATASETS: tuple[str, ...] = ("all", "room", *PUBLISHED)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m simenv.perception.train_recogniser",
                                     description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    add_train_arguments(sub.add_parser("train", help="protocol, loop and the shipped network"))
    p_eval = sub.add_parser("eval", help="evaluate on labelled recordings")
    p_eval.add_argument("--data", nargs="+", help="corpus roots, dataset folders or files "
                        "(default: the shared corpus; in-sample for the shipped model)")
    p_eval.add_argument("--model", default=DEFAULT_CLASSIFIER,
                        help=f"shipped recogniser (default {DEFAULT_CLASSIFIER}, the room's)")
    add_eval_options(p_eval)
    p_eval.add_argument("--json", action="store_true", help="print one JSON object")
    p_eval.add_argument("--out", help="also write metrics.json here")
    p_bench = sub.add_parser("benchmark", help="per-dataset protocols vs published figures")
    p_bench.add_argument("--dataset", choices=BENCHMARK_DATASETS, default="all",
                         help="a benchmark, all of them, or 'room': the room vocabulary's "
                         "leave-subjects-out folds (with --neighbour or --covariance alone only)")
    p_bench.add_argument("--data", help="gestures folder (default: the shared corpus)")
    p_bench.add_argument("--out", default="out/recognition-benchmark")
    add_benchmark_options(p_bench)
    p_bench.add_argument("--json", action="store_true")
    return parser


def train_command(args: argparse.Namespace) -> None:
    """The ``train`` command on parsed options (its parser: :func:`_parser`).

    Raises:
        SimenvError: bad data or options.
    """
    overrides = {k: v for k, v in (("epochs", args.epochs), ("seed", args.seed))
                 if v is not None}
    config = (RecognitionConfig.from_file(args.config, **overrides) if args.config
              else RecognitionConfig(**overrides))
    metrics = run_train(config, Path(args.out),
                        data=Path(args.data) if args.data else _default_data(),
                        forecasters_dir=Path(args.forecasters) if args.forecasters else None)
    print(protocol_table(metrics))
    print(f"outputs in {args.out}")


def eval_command(args: argparse.Namespace) -> None:
    """The ``eval`` command on parsed options (its parser: :func:`_parser`).

    Raises:
        SimenvError: bad data or options.
    """
    result = run_eval(args.data or [str(_default_data())], checkpoint=args.checkpoint,
                      model_name=args.model,
                      predictor=None if args.predictor == "none" else args.predictor)
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / "metrics.json").write_text(json.dumps(result, indent=1))
    if args.json:
        print(json.dumps({"clips": result["clips"], "conditions": {
            k: {"accuracy": v["accuracy"], "balanced_accuracy": v["balanced_accuracy"]}
            for k, v in result["conditions"].items()}}))
    else:
        for name, v in result["conditions"].items():
            print(f"{name:>16}: accuracy {v['accuracy']:.3f}  balanced "
                  f"{v['balanced_accuracy']:.3f}  (n={v['n']})")


def benchmark_command(args: argparse.Namespace) -> None:
    """The ``benchmark`` command on parsed options (its parser: :func:`_parser`).

    Raises:
        SimenvError: bad data or options.
    """
    data = Path(args.data) if args.data else _default_data()
    out = Path(args.out)
    if args.dataset == "room":
        if not args.neighbour and args.covariance != "alone":
            raise SimenvError("--dataset room runs the models with no network only; give "
                              "--neighbour or --covariance alone (the networks: the train "
                              "command)", field="neighbour")
        clips = load_gesture_clips(data, idle=True)
        if args.neighbour:
            result, name = (room_nearest_neighbour(clips, args.neighbour),
                            f"room_nn-{args.neighbour}")
        else:
            result = room_descriptors(clips, lie_group=args.lie_group)
            name = "room_cov_lie" if args.lie_group else "room_cov"
        out.mkdir(parents=True, exist_ok=True)
        (out / f"{name}.json").write_text(json.dumps(result, indent=1))
        print(json.dumps({k: {m: v[m] for m in ("accuracy", "balanced_accuracy")}
                          for k, v in result["conditions"].items()}))
        return
    names = list(PUBLISHED) if args.dataset == "all" else [args.dataset]
    out.mkdir(parents=True, exist_ok=True)
    results = []
    for name in names:
        results.append(run_benchmark(name, data, benchmark_config(args.epochs),
                                     members=args.members,
                                     whole_sequences=args.whole_sequences, joints=args.joints,
                                     neighbour=args.neighbour, mirror_test=args.mirror_test,
                                     covariance=args.covariance,
                                     lie_group=args.lie_group))
        alone = args.neighbour or args.covariance == "alone"
        tag = (f"{name}_nn-{args.neighbour}" if args.neighbour else f"{name}_cov"
               if args.covariance == "alone" else
               f"{name}_m{args.members}_w{int(args.whole_sequences)}")
        if args.joints != "gesture15":
            tag += f"_{args.joints}"
        if args.mirror_test and not alone:
            tag += "_mirror-test"
        tag += {"fused": "_cov", "weighted": "_covw"}.get(args.covariance, "")
        if args.lie_group:
            tag += "_lie"
        (out / f"{tag}.json").write_text(json.dumps(results[-1], indent=1, default=str))
    print(json.dumps([{k: r[k] for k in ("dataset", "mean_fold_accuracy")}
                      | {"accuracy": r["scores"]["accuracy"]} for r in results])
          if args.json else benchmark_table(results))


def main(argv: Sequence[str] | None = None) -> int:
    """Command line (module docstring)."""
    args = _parser().parse_args(argv)
    commands = {"train": train_command, "eval": eval_command,
                "benchmark": benchmark_command}
    try:
        commands[args.command](args)
    except SimenvError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0

if __name__ == "__main__":
    raise SystemExit(main())

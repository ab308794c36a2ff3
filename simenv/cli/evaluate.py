"""``simenv eval KIND [NAME] ...``: evaluate a shipped model on its held-out split or on given
data; the options after KIND are parsed by that kind's parser, built here."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from simenv.cli.common import add_model_command, command_parser, positive_int

#: Description of ``simenv eval`` (its help is the text up to the first parenthesis).
DESCRIPTION = (
    "evaluate a shipped model [NAME] (default predictor-25-25 / "
    "gesture-tcn-ensemble, the room's recogniser; gesture-tcn: one of its networks; "
    "gesture-classifier: the thesis's transformer) "
    "on its held-out split, or on --data PATH... (--json prints one object); writes "
    "metrics.json and plots (--out DIR). `eval classifier --benchmark [DATASET]` runs "
    "the MSR Action3D / UTKinect / Florence 3D protocols against published figures; "
    "`eval classifier --protocol cross-dataset` trains on all datasets but one and tests "
    "on the one left out. "
    "`eval interaction` scores the two-person reaction baselines on the held-out "
    "recordings with the papers' metrics and physics (docs/interaction.md).")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add ``simenv eval``."""
    add_model_command(subparsers, "eval", DESCRIPTION, run)


#: What each ``simenv eval KIND`` does (the description of its ``--help``).
KIND_DESCRIPTIONS = {
    "predictor": "Evaluate a shipped motion predictor against zero- and constant-velocity: "
                 "per-frame MPJPE at 80-1000 ms on its own held-out CMU clips or on --data; "
                 "writes metrics.json and error_curve.png.",
    "classifier": "Evaluate a shipped gesture recogniser on labelled recordings (3 s real, "
                  "1 s real, 1 s real + 2 s predicted; per-class accuracy, confusion "
                  "matrices as JSON and PNG), or, with --benchmark, run a dataset's "
                  "own protocol (MSR Action3D, UTKinect, Florence 3D) against published "
                  "figures, or, with --protocol cross-dataset, train on all datasets but "
                  "one and test on the one left out, each in turn.",
    "interaction": "Score the two-person reaction models and baselines on the held-out "
                   "recordings (or --data) with the papers' metrics and physics; writes "
                   "interaction.md/.json/.png (docs/interaction.md).",
}
KIND_DESCRIPTIONS["recogniser"] = KIND_DESCRIPTIONS["classifier"]

#: ``eval classifier``'s options that only --benchmark uses: option -> its dest.
BENCHMARK_ONLY = {"--members": "members", "--epochs": "epochs",
                  "--whole-sequences": "whole_sequences",
                  "--joints": "joints", "--neighbour": "neighbour",
                  "--covariance": "covariance", "--lie-group": "lie_group",
                  "--mirror-test": "mirror_test"}
#: ``eval classifier``'s options that only --protocol uses: option -> its dest.
PROTOCOL_ONLY = {"--msrc12": "msrc12", "--kindergator": "kindergator", "--mhad": "mhad",
                 "--config": "config",
                 "--folds": "folds", "--jobs": "jobs", "--cross-only": "cross_only"}
#: Protocols of ``eval classifier --protocol``.
PROTOCOLS: tuple[str, ...] = ("cross-dataset",)


def classifier_parser(prog: str) -> argparse.ArgumentParser:
    """The parser of ``simenv eval classifier`` (and ``eval recogniser``): the shipped
    recogniser's evaluation, the transformer's, and the benchmarks."""
    from simenv.perception import train_recogniser as tr
    from simenv.perception.loop import DEFAULT_CLASSIFIER

    parser = command_parser(prog, KIND_DESCRIPTIONS["classifier"])
    parser.add_argument("name", nargs="?", metavar="NAME", help=(
        f"shipped model (default {DEFAULT_CLASSIFIER}, the room's recogniser; gesture-tcn: "
        "one of its networks; gesture-classifier: the thesis's transformer, on its "
        "cross-subject test split)"))
    parser.add_argument("--data", nargs="+", metavar="PATH", help=(
        "labelled recordings: corpus roots, dataset folders (MSR Action3D, UTKinect, "
        "Florence 3D) or files (default: the shared corpus, in-sample for the shipped "
        "recogniser); one gestures folder for gesture-classifier and --benchmark"))
    tr.add_eval_options(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--out", help=(
        "output folder (default: out/classifier-eval for a recogniser: confusion.json and "
        "confusion.png; out/gesture-classifier-eval for the transformer, "
        "out/recognition-benchmark with --benchmark, out/cross-dataset with --protocol)"))
    bench = parser.add_argument_group(
        "benchmarks", "a dataset's own protocol against published figures "
        "(docs/recognition.md)")
    bench.add_argument("--benchmark", nargs="?", const="all", choices=tr.BENCHMARK_DATASETS,
                       metavar="DATASET", help=(
        f"one of {', '.join(tr.BENCHMARK_DATASETS)} (default when given alone: all); "
        "room: the room vocabulary's leave-subjects-out folds (with --neighbour or "
        "--covariance alone only)"))
    tr.add_benchmark_options(bench)
    proto = parser.add_argument_group(
        "protocols", "train networks on the corpus (--data: one gestures folder, default "
        "the shared corpus) and test them on data they never saw (docs/recognition.md)")
    proto.add_argument("--protocol", choices=PROTOCOLS, help=(
        "cross-dataset: per dataset, one network trained on the others, tested on its clips "
        "of the labels the others have (3 s and 1 s real), beside the leave-subjects-out "
        "figure of the same clips"))
    proto.add_argument("--msrc12", metavar="DIR", help=(
        "also the MSRC-12 recordings in DIR (.csv + .tagstream; person p06 left out)"))
    proto.add_argument("--kindergator", metavar="DIR", help=(
        "also the Kinder-Gator recordings in DIR (Kinect v1 .csv), as training data of every "
        "network only: never a left-out dataset"))
    proto.add_argument("--mhad", metavar="DIR", help=(
        "also the Berkeley MHAD skeletons in DIR (skl_s<SS>_a<AA>_r<RR>.bvh, or a folder "
        "holding SkeletalData/): a left-out dataset and training data of the others"))
    proto.add_argument("--config", metavar="FILE", help=(
        "TOML or JSON file of RecognitionConfig options for the protocol's networks"))
    proto.add_argument("--folds", type=positive_int, help=(
        "folds of the leave-subjects-out figures (default 5)"))
    proto.add_argument("--jobs", type=positive_int, help=(
        "networks trained at once, one process of one thread each (default 1)"))
    proto.add_argument("--cross-only", action="store_true", default=None, help=(
        "train the cross-dataset networks only, not the leave-subjects-out ones (about half "
        "the CPU; the within-dataset column then reads n/a)"))
    return parser


def _eval_classifier(parser: argparse.ArgumentParser, options: list[str]) -> int:
    """Parse ``eval classifier``'s options and run the evaluation they ask for."""
    from simenv.perception import train_recogniser as tr
    from simenv.perception.loop import DEFAULT_CLASSIFIER

    args = parser.parse_args(options)
    if args.protocol is None:
        given = [o for o, dest in PROTOCOL_ONLY.items() if getattr(args, dest) is not None]
        if given:
            parser.error(f"{', '.join(given)}: only with --protocol")
    else:
        if args.name is not None or args.checkpoint is not None or args.benchmark is not None:
            parser.error("--protocol trains its own networks: no NAME, --checkpoint or "
                         "--benchmark")
        if args.data is not None and len(args.data) > 1:
            parser.error("--data: one gestures folder here")
        return _cross_dataset(args, options)
    if args.benchmark is None:
        given = [o for o, dest in BENCHMARK_ONLY.items()
                 if getattr(args, dest) != parser.get_default(dest)]
        if given:
            parser.error(f"{', '.join(given)}: only with --benchmark")
    elif args.name is not None or args.checkpoint is not None:
        parser.error("--benchmark trains its own networks: no NAME or --checkpoint")
    single = args.benchmark is not None or (args.name or "").startswith("gesture-classifier")
    if single and args.data is not None and len(args.data) > 1:
        parser.error("--data: one gestures folder here")
    if args.benchmark is not None:
        return _ran(tr.benchmark_command, argparse.Namespace(**{
            **vars(args), "dataset": args.benchmark, "data": args.data and args.data[0],
            "out": args.out or "out/recognition-benchmark"}))
    if single:
        if args.json or args.predictor != parser.get_default("predictor"):
            parser.error("--json and --predictor apply to the recognisers, not to "
                         "gesture-classifier")
        from simenv.learning import train_classifier as tc
        from simenv.models import checkpoint_path

        checkpoint = Path(args.checkpoint) if args.checkpoint else checkpoint_path(args.name)
        return tc.eval_command(checkpoint, Path(args.data[0]) if args.data else tc.DEFAULT_DATA,
                               Path(args.out or "out/gesture-classifier-eval"))
    return _eval_recogniser(args, args.name or DEFAULT_CLASSIFIER)


def _eval_recogniser(args: argparse.Namespace, model: str) -> int:
    """A recogniser on labelled recordings: the conditions' accuracies (one JSON object
    with --json), per-class accuracy, and the confusion matrices written to --out."""
    import json

    from simenv.core.config import shared_data_root
    from simenv.learning.recognition_report import (
        evaluate_recogniser,
        per_class_table,
        write_confusions,
    )

    result = evaluate_recogniser(
        args.data or [str(shared_data_root(None) / "gestures")], model_name=model,
        checkpoint=args.checkpoint,
        predictor=None if args.predictor == "none" else args.predictor)
    out = Path(args.out or "out/classifier-eval")
    out.mkdir(parents=True, exist_ok=True)
    (out / "metrics.json").write_text(json.dumps(result, indent=1))
    paths = write_confusions(result["conditions"], result["labels"], out)
    if args.json:
        print(json.dumps({"clips": result["clips"], "conditions": {
            k: {"accuracy": v["accuracy"], "balanced_accuracy": v["balanced_accuracy"]}
            for k, v in result["conditions"].items()}}))
        return 0
    for name, v in result["conditions"].items():
        print(f"{name:>16}: accuracy {v['accuracy']:.3f}  balanced "
              f"{v['balanced_accuracy']:.3f}  (n={v['n']})")
    print("\nper class (recall: the fraction of its clips given its label)")
    print(per_class_table(result["conditions"], result["labels"]))
    print(f"confusion matrices: {paths[0]}, {paths[1]}")
    return 0


def _cross_dataset(args: argparse.Namespace, options: list[str]) -> int:
    """``--protocol cross-dataset``: run it, print its table and each left-out dataset's
    per-class accuracy, write ``cross_dataset.json`` and a confusion matrix per left-out
    dataset (``confusion_<dataset>.json/.png``, the cross-dataset figures) to --out."""
    import json

    import torch

    from simenv.core.config import shared_data_root
    from simenv.learning.cross_dataset import (
        KINDER_GATOR,
        load_corpus,
        run_cross_dataset,
        summary_table,
    )
    from simenv.learning.recognition import RecognitionConfig
    from simenv.learning.recognition_report import per_class_table, write_confusions

    torch.set_num_threads(1)  # the networks' CPU budgets are one thread's
    config = (RecognitionConfig.from_file(args.config) if args.config
              else RecognitionConfig())
    data = Path(args.data[0]) if args.data else shared_data_root(None) / "gestures"
    clips = load_corpus(data, msrc12_folder=args.msrc12, kinder_gator_folder=args.kindergator,
                        mhad_folder=args.mhad)
    result = run_cross_dataset(clips, config, **({"folds": args.folds} if args.folds else {}),
                               jobs=args.jobs or 1, cross_only=bool(args.cross_only),
                               train_only=(KINDER_GATOR,) if args.kindergator else ())
    result["command"] = "simenv eval classifier " + " ".join(options)
    out = Path(args.out or "out/cross-dataset")
    out.mkdir(parents=True, exist_ok=True)
    (out / "cross_dataset.json").write_text(json.dumps(result, indent=1))
    if args.json:
        print(json.dumps({name: {cond: {k: c[k]["accuracy"] for k in ("cross_dataset",
                                                                         "within_dataset")
                                        if k in c}
                                 for cond, c in d["conditions"].items()}
                          for name, d in result["datasets"].items()}))
        return 0
    print(summary_table(result))
    for name, d in result["datasets"].items():
        cross = {cond: c["cross_dataset"] for cond, c in d["conditions"].items()}
        print(f"\n{name} left out, per class (cross-dataset recall)")
        print(per_class_table(cross, result["labels"]))
        write_confusions(cross, result["labels"], out, f"confusion_{name}")
    print(f"\noutputs in {out}")
    return 0


def _ran(command: Callable[[argparse.Namespace], None], args: argparse.Namespace) -> int:
    """Run a command that prints its results and raises on a user error; 0."""
    command(args)
    return 0


def run(args: argparse.Namespace) -> int:
    """Parse the options after KIND with that kind's parser (named ``simenv eval KIND``)
    and evaluate."""
    prog = f"simenv eval {args.kind}"
    # Each evaluation script loads PyTorch: only the one asked for is imported.
    if args.kind == "predictor":
        from simenv.learning.train_predictor import evaluate_main

        return evaluate_main(args.options, command_parser(prog, KIND_DESCRIPTIONS["predictor"]))
    if args.kind == "interaction":
        from simenv.learning.eval_interaction import main as interaction_main

        return interaction_main(args.options,
                                command_parser(prog, KIND_DESCRIPTIONS["interaction"]))
    return _eval_classifier(classifier_parser(prog), list(args.options))

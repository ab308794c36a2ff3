"""``simenv eval KIND [NAME] ...``: evaluate a shipped model on its held-out split or on given
data; the options after KIND are parsed by that kind's parser, built here."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from simenv.cli.common import add_model_command, command_parser

#: Description of ``simenv eval`` (its help is the text up to the first parenthesis).
DESCRIPTION = (
    "evaluate a shipped model [NAME] (default predictor-25-25 / "
    "gesture-tcn-ensemble, the room's recogniser; gesture-tcn: one of its networks; "
    "gesture-classifier: the thesis's transformer) "
    "on its held-out split, or on --data PATH... (--json prints one object); writes "
    "metrics.json and plots (--out DIR). `eval classifier --benchmark [DATASET]` runs "
    "the MSR Action3D / UTKinect / Florence 3D protocols against published figures. "
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
                  "1 s real, 1 s real + 2 s predicted), or, with --benchmark, run a dataset's "
                  "own protocol (MSR Action3D, UTKinect, Florence 3D) against published "
                  "figures.",
    "interaction": "Score the two-person reaction models and baselines on the held-out "
                   "recordings (or --data) with the papers' metrics and physics; writes "
                   "interaction.md/.json/.png (docs/interaction.md).",
}
KIND_DESCRIPTIONS["recogniser"] = KIND_DESCRIPTIONS["classifier"]

#: ``eval classifier``'s options that only --benchmark uses: option -> its dest.
BENCHMARK_ONLY = {"--members": "members", "--whole-sequences": "whole_sequences",
                  "--joints": "joints", "--neighbour": "neighbour",
                  "--covariance": "covariance", "--lie-group": "lie_group",
                  "--mirror-test": "mirror_test"}


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
        "output folder (default: none for a recogniser, out/gesture-classifier-eval for "
        "the transformer, out/recognition-benchmark with --benchmark)"))
    bench = parser.add_argument_group(
        "benchmarks", "a dataset's own protocol against published figures "
        "(docs/recognition.md)")
    bench.add_argument("--benchmark", nargs="?", const="all", choices=tr.BENCHMARK_DATASETS,
                       metavar="DATASET", help=(
        f"one of {', '.join(tr.BENCHMARK_DATASETS)} (default when given alone: all); "
        "room: the room vocabulary's leave-subjects-out folds (with --neighbour or "
        "--covariance alone only)"))
    tr.add_benchmark_options(bench)
    return parser


def _eval_classifier(parser: argparse.ArgumentParser, options: list[str]) -> int:
    """Parse ``eval classifier``'s options and run the evaluation they ask for."""
    from simenv.perception import train_recogniser as tr
    from simenv.perception.loop import DEFAULT_CLASSIFIER

    args = parser.parse_args(options)
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
    return _ran(tr.eval_command, argparse.Namespace(**{
        **vars(args), "model": args.name or DEFAULT_CLASSIFIER}))


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

"""``simenv eval KIND [NAME] ...``: evaluate a shipped model on its held-out split or on given
data; the options after KIND (and NAME) go to that kind's evaluation script."""

from __future__ import annotations

import argparse

from simenv.cli.common import add_model_command

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


def run(args: argparse.Namespace) -> int:
    """Evaluate a shipped model: an optional NAME, then the script's own options."""
    # Each evaluation script loads PyTorch: only the one asked for is imported.
    options = list(args.options)
    name = options.pop(0) if options and not options[0].startswith("-") else None
    if args.kind == "predictor":
        from simenv.learning.train_predictor import main as predictor_main

        return predictor_main(["--evaluate", name or "predictor-25-25", *options])
    if args.kind == "interaction":
        from simenv.learning.eval_interaction import main as interaction_main

        return interaction_main(list(args.options))
    if name is not None and name.startswith("gesture-classifier"):
        from simenv.learning.train_classifier import main as classifier_main

        return classifier_main(["eval", "--model", name, *options])
    from simenv.perception.loop import DEFAULT_CLASSIFIER
    from simenv.perception.train_recogniser import main as recogniser_main

    if "--benchmark" in options:
        i = options.index("--benchmark")
        has_value = i + 1 < len(options) and not options[i + 1].startswith("-")
        dataset = options[i + 1] if has_value else "all"
        rest = options[:i] + options[i + 1 + has_value:]
        return recogniser_main(["benchmark", "--dataset", dataset, *rest])
    return recogniser_main(["eval", "--model", name or DEFAULT_CLASSIFIER, *options])

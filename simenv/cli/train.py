"""``simenv train KIND ...``: train the motion predictor, the gesture classifier, the room's
recogniser or a two-person model; the options after KIND go to that kind's training script."""

from __future__ import annotations

import argparse

from simenv.cli.common import add_model_command

#: Description of ``simenv train`` (its help is the text up to the first parenthesis).
DESCRIPTION = (
    "train the motion predictor, the gesture classifier, the room's "
    "recogniser (`train recogniser`: leave-subjects-out protocol, loop, shipped network) or a "
    "two-person model (`train interaction --model NAME`) on the real mocap of the shared "
    "corpus (CPU, seeded, progress bar): checkpoint, model card, metrics and plots. "
    "Options after KIND go to its training script (see `simenv train KIND --help`); "
    "--config FILE reads them from a TOML or JSON file.")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add ``simenv train``."""
    add_model_command(subparsers, "train", DESCRIPTION, run)


def run(args: argparse.Namespace) -> int:
    """Forward the options after KIND to the training script of the predictor, the
    classifier or the two-person models."""
    # Each training script loads PyTorch: only the one asked for is imported.
    if args.kind == "predictor":
        from simenv.learning.train_predictor import main as predictor_main

        return predictor_main(args.options)
    if args.kind == "interaction":
        from simenv.learning.train_interaction import main as interaction_main

        return interaction_main(args.options)
    if args.kind == "recogniser":
        from simenv.perception.train_recogniser import main as recogniser_main

        return recogniser_main(["train", *args.options])
    from simenv.learning.train_classifier import main as classifier_main

    return classifier_main(["train", *args.options])

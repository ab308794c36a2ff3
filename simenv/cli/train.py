"""``simenv train KIND ...``: train the motion predictor, the gesture classifier, the room's
recogniser or a two-person model; the options after KIND go to that kind's training script."""

from __future__ import annotations

import argparse

from simenv.cli.common import add_model_command, command_parser

#: Description of ``simenv train`` (its help is the text up to the first parenthesis).
DESCRIPTION = (
    "train the motion predictor, the gesture classifier, the room's "
    "recogniser (`train recogniser`: leave-subjects-out protocol, loop, shipped network) or a "
    "two-person model (`train interaction --model NAME`) on the real mocap of the shared "
    "corpus (CPU, seeded, progress bar): checkpoint, model card, metrics and plots. "
    "Options after KIND are that kind's (see `simenv train KIND --help`); "
    "--config FILE reads them from a TOML or JSON file.")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add ``simenv train``."""
    add_model_command(subparsers, "train", DESCRIPTION, run)


#: What each ``simenv train KIND`` does (the description of its ``--help``).
KIND_DESCRIPTIONS = {
    "predictor": "Train the PredictiveMA-WGAN motion predictor (or, --model regression, the "
                 "DCT-residual MLP) on the CMU clips of the shared corpus, split by clip group; "
                 "writes the checkpoint, its model card, metrics.json and error_curve.png.",
    "classifier": "Train the thesis's gesture transformer (gesture-classifier) on the gesture "
                  "corpus and evaluate it on its cross-subject test split.",
    "recogniser": "Train the room's recogniser: the leave-subjects-out protocol, the "
                  "perception loop on held-out people and the shipped network (gesture-tcn).",
    "interaction": "Train a two-person model (reaction generator, interaction generator or "
                   "augmenter) on the real two-person recordings, split by recording.",
}


def run(args: argparse.Namespace) -> int:
    """Parse the options after KIND with that kind's parser (named ``simenv train KIND``)
    and train."""
    parser = command_parser(f"simenv train {args.kind}", KIND_DESCRIPTIONS[args.kind])
    # Each training script loads PyTorch: only the one asked for is imported.
    if args.kind == "predictor":
        from simenv.learning.train_predictor import main as predictor_main

        return predictor_main(args.options, parser)
    if args.kind == "interaction":
        from simenv.learning.train_interaction import main as interaction_main

        return interaction_main(args.options, parser)
    if args.kind == "recogniser":
        from simenv.perception import train_recogniser

        train_recogniser.add_train_arguments(parser)
        train_recogniser.train_command(parser.parse_args(args.options))
        return 0
    from simenv.learning import train_classifier

    train_classifier.add_train_arguments(parser)
    return train_classifier.train_command(parser.parse_args(args.options))

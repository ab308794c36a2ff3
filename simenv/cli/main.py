"""The ``simenv`` command line: ``info``, ``retarget``, ``render``, ``score``, ``export``,
``demo``, ``train``, ``eval`` and ``rehearse``, one module of :mod:`simenv.cli` each (its
``add_parser`` and ``run``).

Every command that takes a motion file also takes a folder holding a two-person recording (one
file per person, e.g. the CMU pairs), which loads as one interaction. User errors
(:class:`~simenv.core.errors.SimenvError`) print one line on stderr and exit with status 2; anything
else is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from simenv.cli import demo, evaluate, export, info, rehearse, render, retarget, score, train
from simenv.cli.common import EXIT_USER_ERROR, HelpFormatter
from simenv.core.errors import SimenvError

#: Exit status when stdout's reader closed the pipe (128 + SIGPIPE, as a shell reports it).
EXIT_BROKEN_PIPE = 141

#: The commands in the order ``simenv --help`` lists them.
COMMANDS = (info, retarget, render, score, export, demo, train, evaluate, rehearse)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``simenv`` command (one sub-command per job)."""
    parser = argparse.ArgumentParser(
        prog="simenv",
        description="Physics-backed simulation and evaluation of 3D human skeleton motion.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.add_parser(sub)
    for cmd in sub.choices.values():
        # Every option's default in its help; usage errors name the subcommand's usage.
        cmd.formatter_class = HelpFormatter
        cmd.set_defaults(command_parser=cmd)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``simenv`` command; returns the exit status (2 on a user error)."""
    parser = build_parser()
    # `rehearse` forwards everything, its --help included, to the rehearsal's parser
    # (simenv.cli.rehearse builds it); `train`/`eval` forward what follows KIND likewise.
    args, extra = parser.parse_known_args(argv)
    if args.command == "rehearse":
        args.options = [*extra, *args.options]
    elif extra:
        args.command_parser.error(f"unrecognized arguments: {' '.join(extra)}")
    try:
        return args.func(args)
    except BrokenPipeError:
        # The reader went away (`simenv info ... | head`): stop quietly, as Unix tools do,
        # and keep the interpreter's final flush from raising again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except SimenvError as err:
        print(f"simenv {args.command}: error: {err}", file=sys.stderr)
        return EXIT_USER_ERROR

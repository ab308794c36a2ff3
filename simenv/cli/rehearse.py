"""``simenv rehearse SESSION --out DIR ...``: the offline interaction rehearsal in the room,
or a two-person model's generated reaction rehearsed on simulated bodies. The options, after
the room (MuJoCo) and the models are imported, are parsed by :func:`rehearsal_parser`: the
room rehearsal's (:func:`simenv.envs.rehearsal.add_arguments`) with the reaction generators
among the agents."""

from __future__ import annotations

import argparse

from simenv.cli.common import command_parser

#: ``simenv rehearse --help``'s description.
DESCRIPTION = (
    "Replay a recorded session (any single-person motion file, bundled asset or session "
    "recipe) in the virtual room: perception every second, the agent's reactions simulated; "
    "writes rehearsal.mp4, log.jsonl, summary.json and report.html to --out, and prints how "
    "many reactions started and succeeded, and why any that failed did. With --agent "
    "interformer or reactive-gan, a reaction generator answers the session instead: the "
    "generated reaction is retargeted, tracked physically and scored (summary.json, "
    "reaction.npz, report/).")

#: Room-rehearsal options a reaction generator does not use: option -> its dest.
ROOM_ONLY = {"--joint-map": "joint_map", "--scenario": "scenario", "--gesture": "gesture",
             "--predictor": "predictor", "--classifier": "classifier",
             "--templates": "templates", "--width": "width", "--height": "height"}
#: Reaction-generator options the room rehearsal does not use: option -> its dest.
GENERATOR_ONLY = {"--seconds": "seconds", "--shared": "shared", "--planner": "planner"}


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add ``simenv rehearse``: its options and ``--help`` go to :func:`rehearsal_parser`
    (built when the command runs, so that ``simenv`` starts without the room)."""
    reh = subparsers.add_parser("rehearse", help="offline interaction rehearsal in the room",
                                add_help=False, description=DESCRIPTION)
    reh.add_argument("options", nargs=argparse.REMAINDER, metavar="SESSION --out DIR ...",
                     help="see simenv rehearse --help")
    reh.set_defaults(func=run)


def rehearsal_parser() -> tuple[argparse.ArgumentParser, list[str]]:
    """The parser of ``simenv rehearse`` and the reaction generators among its agents."""
    from simenv.envs import rehearsal
    from simenv.envs.reaction_rehearsal import PLANNER_HELP
    from simenv.models import interaction_model_names
    from simenv.plausibility.planner import PLANNERS

    generators = interaction_model_names("reaction")
    parser = command_parser("simenv rehearse", DESCRIPTION)
    rehearsal.add_arguments(parser, generators)
    group = parser.add_argument_group(
        "reaction generators", f"with --agent {' or '.join(generators)} only")
    group.add_argument("--seconds", type=float, help="rehearse only the first SECONDS of "
                       "the session (default: all of it)")
    group.add_argument("--shared", help="corpus root of the training windows that give the "
                       "agent's start pose (default: --data, else $SIMENV_SHARED_DATA or "
                       "../shared/data)")
    group.add_argument("--planner", choices=PLANNERS, default="default", help=PLANNER_HELP)
    return parser, generators


def run(args: argparse.Namespace) -> int:
    """Parse the options and run the offline interaction rehearsal in the room
    (:mod:`simenv.envs.rehearsal`), or, when ``--agent`` names a reaction generator, the
    rehearsal of its generated reaction on simulated bodies
    (:mod:`simenv.envs.reaction_rehearsal`)."""
    parser, generators = rehearsal_parser()
    options = parser.parse_args(args.options)
    generated = options.agent in generators
    unused = ROOM_ONLY if generated else GENERATOR_ONLY
    given = [o for o, dest in unused.items()
             if getattr(options, dest) != parser.get_default(dest)]
    if given:
        parser.error(f"{', '.join(given)}: not used with --agent {options.agent}")
    if generated:
        from simenv.envs.reaction_rehearsal import run_args as reaction_run

        options.shared = options.shared or options.data
        return reaction_run(options)
    from simenv.envs.rehearsal import run_args as rehearsal_run

    return rehearsal_run(options)

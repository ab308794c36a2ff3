"""``simenv rehearse SESSION --out DIR ...``: the offline interaction rehearsal in the room,
or a two-person model's generated reaction rehearsed on simulated bodies. Every option,
``--help`` included, goes to the rehearsal's own parser."""

from __future__ import annotations

import argparse

from simenv.models import INTERACTION_MODELS


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add ``simenv rehearse`` (no help of its own: ``--help`` is forwarded)."""
    reh = subparsers.add_parser("rehearse", help="offline interaction rehearsal in the room",
                                add_help=False, description=(
        "Replay a recorded session (any single-person motion file or bundled asset) in the "
        "virtual room: perception every second, the agent's reactions simulated, outputs "
        "rehearsal.mp4, log.jsonl, summary.json and report.html in --out. Usage: simenv "
        "rehearse SESSION --out DIR [--agent AGENT] [--scenario NAME|FILE] "
        "[--gesture LABEL:ONSET_S:END_S] [--templates DIR] [--no-render]. With --agent "
        "interformer or reactive-gan, a reaction generator answers the session instead: the "
        "generated reaction is retargeted, tracked physically and scored "
        "(python -m simenv.envs.reaction_rehearsal --help)."))
    reh.add_argument("options", nargs=argparse.REMAINDER, metavar="SESSION --out DIR ...",
                     help="options of the rehearsal (python -m simenv.envs.rehearsal --help)")
    reh.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Forward to the offline interaction rehearsal in the room (:mod:`simenv.envs.rehearsal`),
    or, when ``--agent`` names a two-person model, to the rehearsal of its generated
    reaction on simulated bodies (:mod:`simenv.envs.reaction_rehearsal`)."""
    options = list(args.options)
    agent = next((options[i + 1] for i, o in enumerate(options[:-1]) if o == "--agent"),
                 next((o.split("=", 1)[1] for o in options if o.startswith("--agent=")),
                      None))
    # The room (MuJoCo, the perception loop) loads only when a rehearsal runs.
    if agent in INTERACTION_MODELS:
        from simenv.envs.reaction_rehearsal import main as reaction_main

        return reaction_main(options)
    from simenv.envs.rehearsal import main as rehearsal_main

    return rehearsal_main(options)

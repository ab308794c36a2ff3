"""``simenv demo``: the main job on bundled real CMU data (:mod:`simenv.cli.demo_job`) and
the check of its page (:mod:`simenv.cli.demo_page`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from simenv.cli.common import positive_int


def _seconds(text: str) -> float:
    """argparse type: a finite number of seconds > 0."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected seconds > 0, got {text!r}")
    return value


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add ``simenv demo``."""
    demo = subparsers.add_parser("demo", help="the main job on bundled real CMU data",
                                 description=(
        "Retarget the bundled CMU walk (02_01) and two-person handshake (18_01 + 19_01), write "
        "videos, NPZ trajectories, glTF files, plausibility reports, a room rehearsal and a "
        "JSON summary into the output folder, and index.html, the page that shows them."))
    demo.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    demo.add_argument("--stride", type=positive_int, default=None,
                      help="render every S-th frame (default: chosen to keep the demo short)")
    demo.add_argument("--reaction-seconds", type=_seconds, metavar="S", help=(
        "seconds of the handshake's person A the reaction generator answers (default: 2.5, "
        "simenv.cli.demo_job.REACTION_SECONDS; tracking both people is most of the demo's "
        "CPU)"))
    demo.add_argument("--check", action="store_true", help=(
        "then check the page: every link resolves, and a headless Chromium screenshot "
        "(index.png) is not blank and shows every video's poster"))
    demo.add_argument("--check-only", action="store_true",
                      help="check the page of an earlier run in --out without running")
    demo.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the demo into ``--out`` and/or check its page."""
    # The job and the page checks (MuJoCo, rendering, the room) load only for the demo.
    from simenv.cli.demo_job import run_demo
    from simenv.cli.demo_page import PAGE, check_page

    if not args.check_only:
        run_demo(Path(args.out), stride=args.stride, reaction_seconds=args.reaction_seconds)
    if args.check or args.check_only:
        result = check_page(Path(args.out) / PAGE)
        print(f"checked {Path(args.out) / PAGE}: {result['links']} links resolve in "
              f"{result['pages']} pages; Chromium plays its {len(result['videos'])} videos ("
              + ", ".join(f"{v['src']} {v['duration']:.1f} s" for v in result["videos"])
              + f"); screenshot {result['screenshot']} has "
              f"{100 * result['content_fraction']:.0f} % content and shows "
              f"{len(result['posters'])} video posters (match >= "
              f"{min((p['match'] for p in result['posters']), default=1):.2f})")
    return 0

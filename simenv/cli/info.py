"""``simenv info``: describe motion files (format, people, joints, frames, fps, duration,
heights, and the quirks found and repairs made while reading)."""

from __future__ import annotations

import argparse
import json
from typing import Any

from simenv.cli.common import PATH_HELP, describe
from simenv.io.loader import load_any


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add ``simenv info``."""
    info = subparsers.add_parser("info", help="describe a motion file", description=(
        "Format, people, joints, frames, fps, duration, height estimate per person, and the "
        "quirks found and repairs made while reading."))
    info.add_argument("paths", nargs="+", metavar="FILE|FOLDER", help=PATH_HELP)
    info.add_argument("--json", action="store_true", help="print one JSON object")
    info.set_defaults(func=run)


def _print_info(info: dict[str, Any]) -> None:
    print(f"{info['name']}  ({info['format']}, {info['source']})")
    print(
        f"  people {info['people']}, frames {info['frames']}, fps {info['fps']:g}, "
        f"duration {info['duration_s']:.2f} s"
    )
    if info.get("label"):
        print(f"  label {info['label']}")
    for note in info.get("quirks", []):
        print(f"  quirk: {note}")
    for i, person in enumerate(info["persons"]):
        stature = person["stature_m"]
        print(
            f"  person {i} {person['name']}: {person['joints']} joints, joint span "
            f"{person['height_m']:.2f} m, "
            + (f"stature ~{stature:.2f} m (fitted body), " if stature else "")
            + f"units in file {person['units_in_file']}"
        )
        for note in person["quirks"]:
            print(f"    quirk: {note}")
        for note in person["repairs"]:
            print(f"    repair: {note}")


def run(args: argparse.Namespace) -> int:
    """Print each clip's description (``--json``: one object, or ``{"clips": [...]}``)."""
    infos = [describe(clip) for clip in load_any(args.paths)]
    if args.json:
        print(json.dumps(infos[0] if len(infos) == 1 else {"clips": infos}))
    else:
        for info in infos:
            _print_info(info)
    return 0

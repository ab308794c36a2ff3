"""``simenv info``: describe motion files (format, people, joints, frames, fps, duration,
heights, how the joints map onto the canonical keypoints, and the quirks found and repairs
made while reading)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from simenv.cli.common import (
    PATH_HELP,
    add_joint_map_option,
    add_units_options,
    describe,
    read_options,
)
from simenv.core.errors import SimenvError
from simenv.core.joint_map import JointMapping, joint_map_template
from simenv.core.motion import Interaction
from simenv.io.loader import load_any


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add ``simenv info``."""
    info = subparsers.add_parser("info", help="describe a motion file", description=(
        "Format, people, joints, frames, fps, duration, height estimate per person, how the "
        "joints map onto the canonical keypoints (and how each was found), and the quirks "
        "found and repairs made while reading."))
    info.add_argument("paths", nargs="+", metavar="FILE|FOLDER", help=PATH_HELP)
    info.add_argument("--json", action="store_true", help="print one JSON object")
    info.add_argument("--write-joint-map", metavar="MAP.toml", help=(
        "write the first person's joint map as a TOML file to edit and pass back with "
        "--joint-map (every keypoint listed, the unmapped ones commented out)"))
    add_joint_map_option(info)
    add_units_options(info)
    info.set_defaults(func=run)


def _print_mapping(record: dict[str, Any]) -> None:
    canonical, how = record["canonical"], record["how"]
    by_how: dict[str, list[str]] = {}
    for key, joint in canonical.items():
        by_how.setdefault(how.get(key, ""), []).append(f"{key}={joint}")
    print(f"    joint map ({len(canonical)} of {len(canonical) + len(record['missing'])} "
          f"keypoints; convention {record['convention'] or 'none'}):")
    for found, entries in by_how.items():
        print(f"      by {found}: {', '.join(entries)}")
    if record["missing"]:
        print(f"      unmapped: {', '.join(record['missing'])}")
    for note in record["notes"]:
        print(f"      note: {note}")


#: Shortest text (characters) several quirks must share for ``info`` to print it once.
MIN_SHARED_QUIRK = 60


def _grouped(notes: list[str]) -> list[tuple[str, list[str]]]:
    """Quirks that end in the same explanation (one per joint, such as the collapsed bones of
    a CMU BVH conversion) as ``(", " + shared text, [each one's own beginning])``, in order
    of first appearance; any other quirk is ``("", [quirk])``. The shared text starts after
    a ", " and is at least :data:`MIN_SHARED_QUIRK` characters long."""
    tails = [[n[i:] for i in range(len(n)) if n.startswith(", ", i)
              and len(n) - i - 2 >= MIN_SHARED_QUIRK] for n in notes]
    counts: dict[str, int] = {}
    for own in tails:
        for tail in set(own):
            counts[tail] = counts.get(tail, 0) + 1
    groups: dict[str, list[str]] = {}
    for note, own in zip(notes, tails, strict=True):
        # The longest tail: the earliest ", " after which the notes agree.
        shared = next((t for t in own if counts[t] > 1), "")
        groups.setdefault(shared or note, []).append(note[:len(note) - len(shared)])
    return [(key if heads[0] != key else "", heads) for key, heads in groups.items()]


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
        _print_mapping(person["joint_map"])
        # The clip's quirks already name the person's share of the pair's repairs.
        shown = set(info.get("quirks", []))
        notes = [q for q in person["quirks"]
                 if q not in shown and f"{person['name']}: {q}" not in shown]
        for shared, heads in _grouped(notes):
            if len(heads) == 1:
                print(f"    quirk: {heads[0]}{shared}")
            else:
                print(f"    quirk, {len(heads)} alike: {shared.lstrip(', ')}")
                for head in heads:
                    print(f"      {head}")
        for note in person["repairs"]:
            print(f"    repair: {note}")


def _write_template(clip: Any, path: Path) -> None:
    person = clip.people[0] if isinstance(clip, Interaction) else clip
    record = describe(clip)["persons"][0]["joint_map"]
    mapping = JointMapping(record["canonical"], record["how"], record["convention"])
    if path.suffix.lower() != ".toml":
        raise SimenvError(f"--write-joint-map must end with .toml; got {path.name!r}",
                          field="--write-joint-map")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(joint_map_template(person.skeleton.joint_names, mapping,
                                       source=str(person.metadata.get("source", ""))),
                    encoding="utf-8")
    print(f"wrote {path}: edit it and pass it with --joint-map")


def run(args: argparse.Namespace) -> int:
    """Print each clip's description (``--json``: one object, or ``{"clips": [...]}``)."""
    clips = load_any(args.paths, **read_options(args))
    infos = [describe(clip) for clip in clips]
    if args.json:
        print(json.dumps(infos[0] if len(infos) == 1 else {"clips": infos}))
    else:
        for info in infos:
            _print_info(info)
    if args.write_joint_map:
        _write_template(clips[0], Path(args.write_joint_map))
    return 0

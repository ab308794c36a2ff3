"""``simenv export``: a motion, a room scenario, or the room with the motion played by its
user, as a glTF 2.0 file (.glb or .gltf)."""

from __future__ import annotations

import argparse

from simenv.cli.common import (
    PATH_HELP,
    add_joint_map_option,
    add_units_options,
    positive_int,
    read_options,
)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add ``simenv export``."""
    exp = subparsers.add_parser("export", help="export a motion or a room to glTF/GLB",
                                description=(
        "Write a 3D file any viewer opens (glTF 2.0: .glb binary or .gltf): a motion file "
        "retargeted onto fitted humanoids, animated at its frame rate; a room scenario "
        "(bundled name or TOML, user furniture meshes included); or, with --scenario, the "
        "room with the motion played by its user."))
    exp.add_argument("paths", nargs="*", metavar="FILE|FOLDER", help=PATH_HELP
                     + "; or a scenario .toml")
    exp.add_argument("--to", required=True, metavar="OUT.glb", help="output .glb or .gltf")
    exp.add_argument("--scenario", metavar="NAME|FILE",
                     help="export this room (bundled name or TOML); with FILE, as its user")
    exp.add_argument("--stride", type=positive_int, default=1,
                     help="keep every S-th frame of the animation (default 1)")
    add_joint_map_option(exp)
    add_units_options(exp)
    exp.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write ``--to`` and print what it holds."""
    # MuJoCo (retargeting, the room's model): only when something is exported.
    from simenv.io.gltf import check_gltf
    from simenv.room.export import export

    path = export(args.paths, args.to, scenario=args.scenario, stride=args.stride,
                  **read_options(args))
    info = check_gltf(path)
    print(f"wrote {path}: {info['meshes']} meshes, {info['vertices']} vertices"
          + (f", animation of {info['frames']} frames ({info['duration_s']:.2f} s, "
             f"{info['channels']} channels)" if info["animations"] else ", static"))
    return 0

"""``simenv render``: retarget a clip and render it offscreen to MP4."""

from __future__ import annotations

import argparse

from simenv.cli.common import (
    PATH_HELP,
    add_joint_map_option,
    add_units_options,
    check_suffix,
    positive_int,
    read_options,
    retarget_clip,
)
from simenv.io.loader import load_one


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add ``simenv render``."""
    ren = subparsers.add_parser("render", help="render the retargeted motion to MP4",
                                description=(
        "Retarget and render offscreen (MUJOCO_GL=osmesa on a CPU): the humanoid, the source "
        "joints as a ghost, camera following the subject. About 5-10 frames/s on a CPU, so "
        "use --stride/--max-frames for long clips."))
    ren.add_argument("paths", nargs="+", metavar="FILE|FOLDER", help=PATH_HELP)
    ren.add_argument("--out", required=True, help="output .mp4")
    ren.add_argument("--max-frames", type=positive_int, help="render at most N frames")
    ren.add_argument("--stride", type=positive_int, default=1,
                     help="render every S-th frame (default 1)")
    ren.add_argument("--width", type=positive_int, default=320, help="pixels (default 320)")
    ren.add_argument("--height", type=positive_int, default=240, help="pixels (default 240)")
    add_joint_map_option(ren)
    add_units_options(ren)
    ren.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Retarget the frames shown and write the video ``--out``."""
    from simenv.body.render import render_result  # MuJoCo and OpenCV: only to render

    out = check_suffix(args.out, ".mp4", "--out")
    clip = load_one(args.paths, **read_options(args))
    if args.max_frames is not None:
        # Only the frames that will be shown need retargeting.
        clip = clip.slice(0, args.max_frames * args.stride)
    result = retarget_clip(clip)
    render_result(result, out, stride=args.stride, max_frames=args.max_frames,
                  width=args.width, height=args.height, progress=True)
    print(f"wrote {out}")
    return 0

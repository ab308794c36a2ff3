"""``simenv retarget``: fit a humanoid to each person's bone lengths, solve its joint
trajectory, save it to NPZ and optionally render it."""

from __future__ import annotations

import argparse
import json

from simenv.cli.common import (
    PATH_HELP,
    add_joint_map_option,
    add_units_options,
    check_suffix,
    positive_int,
    read_options,
    retarget_clip,
    save_npz,
    summary,
)
from simenv.io.loader import load_one


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add ``simenv retarget``."""
    ret = subparsers.add_parser("retarget", help="retarget onto a fitted MuJoCo humanoid",
                                description=(
        "Fit a humanoid to each person's bone lengths, solve its joint trajectory, and save "
        "qpos (T, nq), fps and the humanoid's dimensions to an NPZ file."))
    ret.add_argument("paths", nargs="+", metavar="FILE|FOLDER", help=PATH_HELP)
    ret.add_argument("--out", required=True, help="output .npz")
    ret.add_argument("--video", help="also render an .mp4 (humanoid + source joints)")
    ret.add_argument("--stride", type=positive_int, default=1,
                     help="video: render every S-th frame (default 1)")
    ret.add_argument("--max-frames", type=positive_int, help="video: at most N frames")
    ret.add_argument("--json", action="store_true", help=(
        "print one JSON object: frames, fps, people, mean_residual_m, p95_residual_m, "
        "max_residual_m, seconds"))
    add_joint_map_option(ret)
    add_units_options(ret)
    ret.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Retarget, write ``--out`` (and ``--video``), print the residuals."""
    out = check_suffix(args.out, ".npz", "--out")
    video = check_suffix(args.video, ".mp4", "--video") if args.video else None
    result = retarget_clip(load_one(args.paths, **read_options(args)))
    save_npz(result, out)
    if video is not None:
        from simenv.body.render import render_result  # MuJoCo and OpenCV: only to render

        render_result(result, video, stride=args.stride, max_frames=args.max_frames, progress=True)
    info = summary(result)
    if args.json:
        print(json.dumps(info))
    else:
        print(
            f"retargeted {info['frames']} frames ({info['people']} people) in "
            f"{info['seconds']:.2f} s; keypoint residual mean {info['mean_residual_m'] * 100:.2f}"
            f" cm, p95 {info['p95_residual_m'] * 100:.2f} cm, max "
            f"{info['max_residual_m'] * 100:.2f} cm"
        )
        print(f"wrote {out}" + (f" and {video}" if video else ""))
    return 0

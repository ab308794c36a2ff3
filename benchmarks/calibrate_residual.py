"""Root residual inferred around flight phases versus measured by the unassisted controller.

For each real CMU clip (and, with ``--corrupt``, its ``float`` and ``time_warp``
corrupted copies at the registry's moderate strength): retarget, run the
unassisted model-predictive tracker (:func:`simenv.plausibility.tracking.track`,
``controller="mpc"``, nothing acting on the root) over at most
``--seconds`` of the clip, and compute :func:`simenv.plausibility.dynamics.root_residual`
twice: inferred (inverse dynamics of the reference and the best floor forces)
and measured (``tracked_error`` = the controller's per-frame body error: no
help on the frames it followed within ``root_residual_tracked_m``). One JSON
line per clip in ``--out`` as it finishes (a rerun skips the clips there);
``--table`` prints the Markdown table docs/calibration.md quotes.

The MPC costs tens of times real time: the default clips are the short ones
(runs, jumps, a walk, the Charleston); ``--clips all`` takes every
single-person CMU clip.

Usage::

    nohup nice .venv/bin/python benchmarks/calibrate_residual.py --corrupt &
    .venv/bin/python benchmarks/calibrate_residual.py --table
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from calibrate_body import DEFAULT_DATA, load, single_person_clips

from simenv.body.retarget import retarget
from simenv.control.mpc import MPCConfig
from simenv.core.motion import Motion
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS
from simenv.plausibility.corrupt import CORRUPTIONS
from simenv.plausibility.dynamics import root_residual
from simenv.plausibility.tracking import track

REPO = Path(__file__).resolve().parents[1]
#: The short real clips (seconds at 120 fps): runs 09_06 / 35_17 / 49_04 (its
#: frozen last frames), hops 02_03, walks 02_01 / 16_15, the Charleston, the
#: cartwheel 49_06.
SHORT_CLIPS = ("09_06.amc", "35_17.bvh", "02_03.amc", "49_04.bvh", "02_01.bvh", "16_15.bvh",
               "103_charleston1.amc", "49_06.bvh")
#: Corruptions applied with ``--corrupt`` (a body under gravity cannot perform them).
CORRUPT_KINDS = ("float", "time_warp")


def measure(motion: Motion, seconds: float) -> dict[str, Any]:
    """Inferred and measured root residual of one motion (module docstring)."""
    t0 = time.perf_counter()
    fitted = retarget(motion)
    tr = track(fitted, DEFAULT_BODY_THRESHOLDS, controller="mpc", max_seconds=seconds,
               mpc=MPCConfig(nthread=1))
    inferred = root_residual(fitted)
    measured = root_residual(fitted, tracked_error=tr.body_error)
    thr = DEFAULT_BODY_THRESHOLDS.root_force_mean_max
    return {"frames": motion.num_frames, "simulated_s": tr.simulated_s,
            "mpc_success": tr.success, "time_to_failure_s": tr.time_to_failure_s,
            "mpjpe_mm": tr.mpjpe_mm, "inferred": inferred.value, "measured": measured.value,
            "measured_fraction": measured.details["measured_fraction"],
            "inferred_passes": inferred.value <= thr, "measured_passes": measured.value <= thr,
            "wall_s": round(time.perf_counter() - t0, 1)}


def table(records: list[dict[str, Any]]) -> str:
    """Markdown of the records."""
    lines = ["| clip | MPC tracked | time to failure (s) | body error (mm) | frames measured "
             "| inferred (BW) | measured (BW) |", "|---|---|---|---|---|---|---|"]
    for r in records:
        lines.append(
            f"| {r['clip']} | {'yes' if r['mpc_success'] else 'no'} "
            f"| {r['time_to_failure_s']:.2f} / {r['simulated_s']:.2f} | {r['mpjpe_mm']:.0f} "
            f"| {100 * r['measured_fraction']:.0f} % | {r['inferred']:.3f} "
            f"| {r['measured']:.3f} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--out", type=Path, default=REPO / "out" / "calibration_loo" / "residual.jsonl")
    ap.add_argument("--clips", default="short", choices=("short", "all"))
    ap.add_argument("--seconds", type=float, default=5.0,
                    help="simulate at most this much of each clip")
    ap.add_argument("--corrupt", action="store_true",
                    help="also the float and time_warp copies of each clip")
    ap.add_argument("--table", action="store_true", help="print the table of --out and exit")
    args = ap.parse_args()
    done = [json.loads(line) for line in args.out.read_text().splitlines()] \
        if args.out.exists() else []
    if args.table:
        print(table(done))
        return
    names = {r["clip"] for r in done}
    paths = single_person_clips(args.data)
    if args.clips == "short":
        paths = [p for p in paths if p.name in SHORT_CLIPS]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with args.out.open("a", encoding="utf-8") as fh:
        for path in paths:
            motion = load(path, None)
            jobs = [(path.name, motion)]
            if args.corrupt:
                for kind in CORRUPT_KINDS:
                    spec = CORRUPTIONS[kind]
                    jobs.append((f"{path.name} {kind}", spec.fn(motion, spec.moderate, seed=0)))
            for name, m in jobs:
                if name in names:
                    continue
                rec = {"clip": name, **measure(m, args.seconds)}
                fh.write(json.dumps(rec) + "\n")
                fh.flush()
                print(json.dumps({k: (round(v, 3) if isinstance(v, float) else v)
                                  for k, v in rec.items()}), flush=True)


if __name__ == "__main__":
    main()

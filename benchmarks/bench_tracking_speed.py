"""The unassisted tracker before and after issue 35, side by side on the same real clips.

For each CMU clip of the shared corpus (its first ``--seconds``; by default the 20
non-acrobatic clips of ``benchmarks/eval_tracking.py``), retargeted once, in one process
and alternating which runs first so both see the same load:

* the raw ``mj_step`` loop of the fitted humanoid on the reference servo targets (the
  physical floor of any tracker);
* the previous default planner (:data:`PREVIOUS`: 128 samples over 0.45 s, a 4 ms planning
  step, a replan every 20 ms) and a new one (``--new``: :data:`simenv.control.FAST` by
  default, the shipped default :class:`simenv.control.MPCConfig`, or ``screen``: the
  default with ``screen_fraction`` a third), both through
  :func:`simenv.plausibility.tracking.track` with the scorer's attempts (``--attempts``,
  3 by default: the further ones plan over ``retry_horizon_s``).

Printed per clip and in total: cost as wall time per simulated second (x real time, every
attempt included; the reference's set-up excluded, as in the tracking metric's
``realtime_ratio``), the same over the raw ``mj_step`` loop, rolled-out planning steps per
simulated step (the cost without the machine's load), tracked or not and the mean body
error; then the ratios new / previous. ``--corrupt`` adds the corrupted copies of
``eval_tracking.py`` (:data:`eval_tracking.CORRUPT_RUNS` on its ``CORRUPT_CLIPS``), which
should fail.

Results go to a JSONL file line by line as each clip finishes (a rerun skips the clips
already there), so the run can go in the background; ``--summary`` prints the table of a
results file without running anything::

    nohup nice .venv/bin/python benchmarks/bench_tracking_speed.py --out /tmp/speed.jsonl &
    .venv/bin/python benchmarks/bench_tracking_speed.py --out /tmp/speed.jsonl --summary

The machine may be shared: the load average is recorded with every clip.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from bench_tracking import raw_step_ratio  # noqa: E402
from eval_tracking import ACROBATICS, CORRUPT_CLIPS, CORRUPT_RUNS, clip_motion, clips  # noqa: E402

from simenv.body.retarget import retarget  # noqa: E402
from simenv.control import FAST, MPCConfig  # noqa: E402
from simenv.core.config import shared_data_root  # noqa: E402
from simenv.plausibility.corrupt import CORRUPTIONS  # noqa: E402
from simenv.plausibility.tracking import TrackingResult, track  # noqa: E402

#: The planner shipped before issue 35 (2026-12-04 to 12-07): every setting it changed.
PREVIOUS = replace(MPCConfig(), n_samples=128, timestep_factor=2, antithetic=False)
#: The planners ``--new`` names: the shipped default and the quarter-cost preset.
NEW = {"default": MPCConfig(), "fast": FAST, "screen": MPCConfig(screen_fraction=1 / 3)}


def _record(tr: TrackingResult, dt: float) -> dict[str, float | bool]:
    sim = tr.steps * dt
    return {"success": tr.success, "mpjpe_mm": tr.mpjpe_mm,
            "time_to_failure_s": tr.time_to_failure_s, "simulated_s": tr.simulated_s,
            "x_real_time": tr.wall_s / sim, "rollout_per_step": tr.rollout_steps / tr.steps,
            "runs": tr.runs}


def run(args: argparse.Namespace) -> None:
    out: Path = args.out
    done = set()
    if out.is_file():
        done = {(r["clip"], r["corruption"], r["strength"])
                for r in map(json.loads, filter(str.strip, out.read_text().splitlines()))}
    paths = [p for p in clips(args.data) if p.stem not in ACROBATICS]
    if args.clips:
        paths = [p for p in paths if p.name in args.clips]
    jobs = [(p, "none", 0.0) for p in paths]
    if args.corrupt:
        jobs += [(p, c, s) for p in paths if p.name in CORRUPT_CLIPS for c, s in CORRUPT_RUNS]
    planners = {"previous": replace(PREVIOUS, attempts=args.attempts, nthread=args.threads),
                "new": replace(NEW[args.new], attempts=args.attempts, nthread=args.threads)}
    for i, (path, corruption, strength) in enumerate(jobs):
        if (path.name, corruption, strength) in done:
            continue
        motion = clip_motion(path, args.seconds)
        if corruption != "none":
            motion = CORRUPTIONS[corruption].fn(motion, strength, seed=0)
        fitted = retarget(motion)
        dt = fitted.humanoid.model.opt.timestep
        rec: dict[str, object] = {"clip": path.name, "corruption": corruption,
                                  "strength": strength, "seconds": args.seconds,
                                  "threads": args.threads, "attempts": args.attempts,
                                  "load_before": os.getloadavg()[0],
                                  "raw_x_real_time": raw_step_ratio(fitted, args.seconds, 3)}
        order = ("previous", "new") if i % 2 == 0 else ("new", "previous")
        for name in order:
            rec[name] = _record(track(fitted, controller="mpc", mpc=planners[name],
                                      max_seconds=args.seconds), dt)
        rec["load_after"] = os.getloadavg()[0]
        with out.open("a") as f:
            f.write(json.dumps(rec) + "\n")
        print(_line(rec), flush=True)


def _line(r: dict) -> str:
    p, n = r["previous"], r["new"]

    def cell(m: dict) -> str:
        return (f"{'tracked' if m['success'] else 'FAILED':7s} {m['mpjpe_mm']:5.0f} mm "
                f"{m['x_real_time']:6.2f}x {m['rollout_per_step']:6.0f}")

    name = r["clip"] + ("" if r["corruption"] == "none"
                        else f" {r['corruption']} {r['strength']:g}")
    return (f"{name:30s} {r['raw_x_real_time']:6.3f}x | {cell(p)} | {cell(n)} | "
            f"{p['x_real_time'] / n['x_real_time']:5.1f}  load {r['load_before']:.1f}")


def summary(records: list[dict]) -> str:
    """The per-clip lines and the totals of the clean clips and the corrupted copies."""
    head = (f"{'clip':30s} {'raw':>7s} | {'previous: verdict, error, x RT, rollout/step':45s}"
            f" | {'new: verdict, error, x RT, rollout/step':45s} | speed-up")
    lines = [head] + [_line(r) for r in records]
    clean = [r for r in records if r["corruption"] == "none"]
    bad = [r for r in records if r["corruption"] != "none"]
    if clean:
        lines.append("")
        raw = float(np.mean([r["raw_x_real_time"] for r in clean]))
        sim = sum(r["new"]["simulated_s"] for r in clean)
        for name in ("previous", "new"):
            ms = [r[name] for r in clean]
            ok = [m for m in ms if m["success"]]
            # Over all clips: total wall time over total simulated time.
            cost = sum(m["x_real_time"] * m["simulated_s"] for m in ms) / sim
            roll = float(np.mean([m["rollout_per_step"] for m in ms]))
            lines.append(
                f"{name:9s}: {len(ok)} of {len(ms)} clean clips tracked, mean body error "
                f"{np.mean([m['mpjpe_mm'] for m in ok]):.1f} mm; {cost:.2f}x real time "
                f"(median {np.median([m['x_real_time'] for m in ms]):.2f}x), "
                f"{cost / raw:.0f}x the raw mj_step loop ({raw:.3f}x real time); "
                f"{roll:.0f} rolled-out steps per simulated step")
        prev = sum(r["previous"]["x_real_time"] * r["previous"]["simulated_s"] for r in clean)
        new = sum(r["new"]["x_real_time"] * r["new"]["simulated_s"] for r in clean)
        lines.append(f"new / previous: cost {new / prev:.3f} (speed-up {prev / new:.1f}x); "
                     "rolled-out steps "
                     f"{np.mean([r['new']['rollout_per_step'] for r in clean]) / np.mean([r['previous']['rollout_per_step'] for r in clean]):.3f}")  # noqa: E501
        lines.append("load average over the runs: "
                     f"{min(r['load_before'] for r in clean):.1f}-"
                     f"{max(r['load_after'] for r in clean):.1f} (2 cores)")
    if bad:
        lines.append("")
        for name in ("previous", "new"):
            failed = sum(not r[name]["success"] for r in bad)
            lines.append(f"{name:9s}: {failed} of {len(bad)} corrupted copies failed tracking")
        both = sum(not r["previous"]["success"] and not r["new"]["success"] for r in bad)
        lost = [f"{r['clip']} {r['corruption']} {r['strength']:g}" for r in bad
                if not r["previous"]["success"] and r["new"]["success"]]
        lines.append(f"failed by both: {both}; failed before, tracked now: "
                     f"{', '.join(lost) or 'none'}")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=shared_data_root())
    ap.add_argument("--out", type=Path, default=Path("out/bench_tracking_speed.jsonl"))
    ap.add_argument("--summary", action="store_true", help="print the results file's table")
    ap.add_argument("--seconds", type=float, default=4.0, help="simulated seconds per clip")
    ap.add_argument("--threads", type=int, default=2, help="rollout threads of both planners")
    ap.add_argument("--attempts", type=int, default=3,
                    help="planner seeds per clip (the scorer's: 3)")
    ap.add_argument("--clips", nargs="*", default=[], help="only these clip files")
    ap.add_argument("--corrupt", action="store_true", help="also the corrupted copies")
    ap.add_argument("--new", choices=sorted(NEW), default="fast",
                    help="the planner set against the previous one")
    args = ap.parse_args()
    if not args.summary:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        run(args)
    records = [json.loads(line) for line in args.out.read_text().splitlines() if line.strip()]
    print(summary(records))


if __name__ == "__main__":
    main()

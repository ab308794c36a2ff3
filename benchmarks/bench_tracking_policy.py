"""The learned tracking policy against the sampling planners, side by side on the same clips.

For each evaluation clip of ``train_tracking_policy.py`` (``EVAL_CLIPS``: clips the policy
never saw; its first ``--seconds``), retargeted once, in one process:

* ``policy``: :func:`simenv.plausibility.policy_tracking.track_policy`, the policy with the
  planner (``FAST``, one thread) as fallback past :class:`simenv.control.policy.PolicyConfig`
  ``engage_m``;
* ``alone``: the policy with no fallback (what it does by itself);
* ``fast`` and, with ``--default``, ``default``: :func:`simenv.plausibility.tracking.track`
  with :data:`simenv.control.FAST` / :class:`simenv.control.MPCConfig` (one attempt, one
  thread, seed 0).

Printed per clip and in total: CPU seconds per simulated second (``time.process_time``; x
real time on one core), tracked or not, mean body error, the share of physics steps the
fallback drove; then the ratios against FAST and the default. ``--corrupt`` runs the
policy tracker on the corrupted copies of ``eval_tracking.py`` (its ``CORRUPT_RUNS``) of the
evaluation clips among its ``CORRUPT_CLIPS``, which should fail.

Lines go to ``--out`` (JSONL, one per run: the ``TrackingResult`` fields of
``eval_tracking.py`` (:func:`result_record`) plus the CPU time and the fallback share) as
they finish; a rerun skips runs already there; ``--summary`` prints the table of a results file::

    nohup nice -n 10 .venv/bin/python benchmarks/bench_tracking_policy.py \
        --policy assets/models/tracking-policy.npz --out out/bench_policy.jsonl &
    .venv/bin/python benchmarks/bench_tracking_policy.py --out out/bench_policy.jsonl --summary

``--trackers`` runs some of them only (a planner baseline can run before the policy exists).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from eval_tracking import CORRUPT_CLIPS, CORRUPT_RUNS  # noqa: E402
from train_tracking_policy import EVAL_CLIPS, clip_motion, clip_path  # noqa: E402

from simenv.body.retarget import retarget  # noqa: E402
from simenv.control import FAST, MPCConfig  # noqa: E402
from simenv.control.policy import PolicyConfig, TrackingPolicy  # noqa: E402
from simenv.plausibility.corrupt import CORRUPTIONS  # noqa: E402
from simenv.plausibility.policy_tracking import track_policy  # noqa: E402
from simenv.plausibility.tracking import TrackingResult, track  # noqa: E402

PLANNERS = {"fast": replace(FAST, nthread=1), "default": replace(MPCConfig(), nthread=1)}
#: The fallback and its thresholds: PolicyConfig's defaults, the planner on one thread.
FALLBACK = PolicyConfig(planner=PLANNERS["fast"])
#: No fallback: the planner never engages.
ALONE = replace(FALLBACK, engage_m=float("inf"))


def result_record(tr: TrackingResult) -> dict[str, float | bool | str | None]:
    """A run's :class:`TrackingResult` as ``eval_tracking.py`` records it (fewer fields)."""
    return {"success": tr.success, "time_to_failure_s": tr.time_to_failure_s,
            "simulated_s": tr.simulated_s, "mpjpe_mm": tr.mpjpe_mm,
            "max_error_mm": float(np.nanmax(tr.body_error)) * 1000.0,
            "work_j_per_kg": tr.work_j_per_kg, "wall_s": tr.wall_s, "runs": tr.runs,
            "rollout_per_step": tr.rollout_steps / max(tr.steps, 1),
            "realtime_ratio": tr.wall_s / max(tr.steps * 0.002, 1e-9), "error": tr.error}


def _done(out: Path) -> set[tuple[str, str, float, str]]:
    if not out.is_file():
        return set()
    return {(r["clip"], r["corruption"], r["strength"], r["tracker"])
            for r in map(json.loads, filter(str.strip, out.read_text().splitlines()))}


def run(args: argparse.Namespace) -> None:
    trackers = args.trackers + (["default"] if args.default else [])
    policy = (TrackingPolicy.load(args.policy)
              if {"policy", "alone"} & set(trackers) else None)
    jobs = [(c, "none", 0.0) for c in args.clips]
    if args.corrupt:
        jobs += [(c, k, s) for c in args.clips if c in CORRUPT_CLIPS for k, s in CORRUPT_RUNS]
    for clip, corruption, strength in jobs:
        names = trackers if corruption == "none" else ["policy"]
        todo = [t for t in names if (clip, corruption, strength, t) not in _done(args.out)]
        if not todo:
            continue
        motion = clip_motion(clip_path(clip), args.seconds)
        if corruption != "none":
            motion = CORRUPTIONS[corruption].fn(motion, strength, seed=0)
        fitted = retarget(motion)
        for name in todo:
            cpu = time.process_time()
            fallback = None
            if name in ("policy", "alone"):
                pr = track_policy(fitted, policy, FALLBACK if name == "policy" else ALONE,
                                  max_seconds=args.seconds)
                tr, fallback = pr.result, pr.fallback_fraction
            else:
                tr = track(fitted, controller="mpc", mpc=PLANNERS[name],
                           max_seconds=args.seconds)
            cpu = time.process_time() - cpu
            sim_s = tr.steps * fitted.humanoid.model.opt.timestep
            rec = {"clip": clip, "corruption": corruption, "strength": strength,
                   "tracker": name, "seconds": args.seconds,
                   "policy": args.policy if name in ("policy", "alone") else None,
                   "cpu_s": cpu, "cpu_ratio": cpu / max(sim_s, 1e-9),
                   "fallback_fraction": fallback, "load_average": os.getloadavg()[0],
                   **result_record(tr)}
            with args.out.open("a") as f:
                f.write(json.dumps(rec) + "\n")
            print(f"{clip:22s} {corruption:10s} {strength:5.1f} {name:8s} "
                  f"ok={int(tr.success)} ttf={tr.time_to_failure_s:.2f} "
                  f"err={tr.mpjpe_mm:.0f} mm cpu x{rec['cpu_ratio']:.2f} "
                  f"fallback={'-' if fallback is None else f'{fallback:.2f}'}", flush=True)


def _verdict(r: dict, ok: str, failed: str) -> str:
    return ok if r["success"] else f"{failed} {r['time_to_failure_s']:.2f}"


def summary(args: argparse.Namespace) -> None:
    recs = [json.loads(x) for x in args.out.read_text().splitlines() if x.strip()]
    clean = [r for r in recs if r["corruption"] == "none"]
    by = {(r["clip"], r["tracker"]): r for r in clean}
    trackers = [t for t in ("policy", "alone", "fast", "default")
                if any(r["tracker"] == t for r in clean)]
    clips = list(dict.fromkeys(r["clip"] for r in clean))
    print(f"{'clip':22s}" + "".join(f" | {t}: ok, mm, xRT" + (", fb" if t == "policy" else "")
                                    for t in trackers))
    for c in clips:
        row = f"{c:22s}"
        for t in trackers:
            r = by.get((c, t))
            if r is None:
                row += " | -"
                continue
            row += (f" | {_verdict(r, 'ok', 'FAIL')} "
                     f"{r['mpjpe_mm']:.0f} x{r['cpu_ratio']:.2f}")
            if t == "policy":
                row += f" {r['fallback_fraction']:.2f}"
        print(row)
    totals = {}
    for t in trackers:
        rs = [by[(c, t)] for c in clips if (c, t) in by]
        # Per simulated second actually stepped (a failed run stops early).
        cpu = sum(r["cpu_s"] for r in rs) / sum(r["cpu_s"] / r["cpu_ratio"] for r in rs)
        totals[t] = cpu
        extra = (f", fallback {np.mean([r['fallback_fraction'] for r in rs]):.2f} of the steps"
                 if t == "policy" else "")
        print(f"{t:8s}: {sum(r['success'] for r in rs)} of {len(rs)} tracked, mean body error "
              f"{np.mean([r['mpjpe_mm'] for r in rs]):.1f} mm, {cpu:.2f}x real time (CPU, "
              f"one core){extra}")
    for base in ("fast", "default"):
        if base in totals and "policy" in totals:
            print(f"policy / {base}: cost {totals['policy'] / totals[base]:.3f}")
    bad = [r for r in recs if r["corruption"] != "none"]
    for r in bad:
        print(f"corrupt {r['clip']:20s} {r['corruption']:10s} {r['strength']:5.1f} "
              f"{_verdict(r, 'tracked', 'failed')} "
              f"{r['mpjpe_mm']:.0f} mm fallback {r['fallback_fraction']:.2f}")
    loads = [r["load_average"] for r in recs]
    print(f"load average over the runs: {min(loads):.1f}-{max(loads):.1f} (2 cores)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--policy", default="assets/models/tracking-policy.npz")
    ap.add_argument("--out", type=Path, default=Path("out/bench_policy.jsonl"))
    ap.add_argument("--clips", nargs="*", default=list(EVAL_CLIPS))
    ap.add_argument("--seconds", type=float, default=4.0)
    ap.add_argument("--trackers", nargs="*", default=["policy", "alone", "fast"],
                    choices=["policy", "alone", "fast", "default"])
    ap.add_argument("--default", action="store_true", help="also the default planner")
    ap.add_argument("--corrupt", action="store_true", help="also the corrupted copies")
    ap.add_argument("--summary", action="store_true", help="print the table of --out only")
    args = ap.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    summary(args) if args.summary else run(args)


if __name__ == "__main__":
    main()

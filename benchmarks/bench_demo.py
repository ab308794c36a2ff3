"""The demo's physics verdicts and their cost under planner settings (``make demo``).

Scores the demo's three physics jobs -- the bundled CMU walk 02_01, the handshake pair
18_01 + 19_01 and the generated reaction (:func:`simenv.cli.demo_job.reaction_clip`) -- with
the demo's scoring (:func:`simenv.cli.demo_job.demo_score_config`: the scorer's settings
planning with :data:`simenv.control.FAST`, no assisted PD detail), with the scorer's default
planner at each ``--samples`` count (up to
:data:`~simenv.plausibility.metric.SCORER_ATTEMPTS` seeds; no assisted detail) and, with
``--shipped``, with ``simenv score``'s default
(:data:`~simenv.plausibility.metric.DEFAULT_SCORE_CONFIG`: 128 samples and the assisted
detail). Prints per job and setting: the verdict, each person's score, failed metrics,
tracking (tracked or not, mean body error, simulations run), wall and CPU seconds (this
process, every thread). The machine may be shared: the load average is printed before
and after; CPU seconds are the comparable number.

Usage::

    MUJOCO_GL=osmesa .venv/bin/python benchmarks/bench_demo.py [--samples 32 64] \\
        [--shipped] [--jobs walk handshake reaction]

Measured 2026-12-07 (load average 6-20: wall times are upper bounds), walk 02_01: 16
samples plausible 79, tracked at 96 mm mean body error, 16 s CPU; 32 samples plausible 66,
106 mm, 20 s; 64 samples plausible 87, 71 mm, 40 s; the shipped default plausible 88, 41
mm, 92 s CPU (with its assisted detail).
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

from simenv.assets import HANDSHAKE_PAIR, WALK, asset_path
from simenv.cli.demo_job import demo_score_config, reaction_clip
from simenv.control import MPCConfig
from simenv.io.loader import load
from simenv.plausibility.metric import DEFAULT_SCORE_CONFIG, SCORER_ATTEMPTS, ScoreConfig
from simenv.plausibility.report import score

JOBS = ("walk", "handshake", "reaction")


def job_clip(job: str) -> Any:
    """The clip the demo scores for ``job`` (one of :data:`JOBS`)."""
    if job == "walk":
        return load(asset_path(WALK))
    if job == "handshake":
        return load(asset_path(HANDSHAKE_PAIR))
    return reaction_clip()[0]


def measure(job: str, clip: Any, label: str, config: ScoreConfig) -> str:
    """One markdown row: ``job``'s clip scored with ``config``."""
    wall, cpu = time.perf_counter(), time.process_time()
    report = score(clip, config=config)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    people = []
    for p in report.people:
        t = p.metrics.get("tracking")
        d = {} if t is None else t.details
        tracked = "tracked" if d.get("success") else "fell"
        people.append(f"{p.name}: {p.verdict} {p.score:.0f} [{', '.join(p.failed) or '-'}] "
                      f"{tracked} {d.get('mpjpe_mm', float('nan')):.0f} mm, "
                      f"{d.get('runs', 0):.0f} runs")
    return (f"| {job} | {label} | {report.verdict} | {'; '.join(people)} | {wall:.0f} | "
            f"{cpu:.0f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, nargs="*", default=[],
                    help="also the scorer's planner with these samples per replan")
    ap.add_argument("--shipped", action="store_true",
                    help="also score with simenv score's default (128 samples, slow)")
    ap.add_argument("--jobs", nargs="+", choices=JOBS, default=list(JOBS))
    args = ap.parse_args()
    settings = [("demo", demo_score_config())]
    settings += [(f"{n} samples", ScoreConfig(mpc=MPCConfig(n_samples=n, attempts=SCORER_ATTEMPTS),
                                             tracking_assisted_detail=False))
                for n in args.samples]
    if args.shipped:
        settings.append(("shipped (128, assisted detail)", DEFAULT_SCORE_CONFIG))
    print(f"load average before: {os.getloadavg()}")
    print("| job | planner | verdict | people: verdict score [failed] tracking | wall s | "
          "CPU s |\n|---|---|---|---|---|---|", flush=True)
    for job in args.jobs:
        clip = job_clip(job)
        for label, config in settings:
            print(measure(job, clip, label, config), flush=True)
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()

"""What ``track_if_plausible`` saves when scoring a set where some clips already fail.

The physics tracking is nearly all of ``simenv score``'s time. With
``ScoreConfig(track_if_plausible=True)`` (``simenv score --track-if-plausible``) a person whose
other metrics already fail is not tracked: the verdict cannot change. This script scores the
same set both ways, side by side in one process: the first ``--seconds`` of real CMU clips of
the shared corpus and their seeded corruptions (``simenv.plausibility.corrupt``, seed 0, the
registry's moderate strength), physics on, the shipped planner. It prints per clip the verdict
both ways (they must agree), the tracking verdict or why it was skipped, the CPU seconds both
ways, and the overall ratio with the fraction of clips skipped: the saving depends on how
many clips of a set fail before tracking, so it is a property of the set, not a constant.

Usage::

    nice -n 10 .venv/bin/python benchmarks/bench_track_if_plausible.py \\
        --clips 02_01.bvh 05_02.bvh --corruptions teleport sink foot_slide --seconds 1
"""

from __future__ import annotations

import argparse
import time

import simenv  # noqa: F401  (MUJOCO_GL before mujoco)
from simenv.core.config import shared_data_root
from simenv.io.loader import load
from simenv.plausibility.corrupt import CORRUPTIONS
from simenv.plausibility.metric import ScoreConfig
from simenv.plausibility.report import score


def _scored(motion, config: ScoreConfig) -> tuple[str, str, float]:
    """(verdict, tracking verdict or why it did not run, CPU seconds)."""
    t0 = time.process_time()
    person = score(motion, config=config).people[0]
    tracking = person.metrics["tracking"]
    how = tracking.reason if tracking.reason else ("tracked" if tracking.passed else "fell")
    return person.verdict, how, time.process_time() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clips", nargs="+", default=["02_01.bvh", "05_02.bvh"])
    ap.add_argument("--corruptions", nargs="+", default=["teleport", "sink", "foot_slide"])
    ap.add_argument("--seconds", type=float, default=1.0)
    args = ap.parse_args()
    every, skipping = ScoreConfig(), ScoreConfig(track_if_plausible=True)
    rows, totals, skipped, agree = [], [0.0, 0.0], 0, 0
    for name in args.clips:
        clip = load(shared_data_root() / "cmu" / "bvh" / name)
        clip = clip.slice(0, min(clip.num_frames, int(round(args.seconds * clip.fps))))
        copies = [("clean", clip)] + [
            (c, CORRUPTIONS[c].fn(clip, CORRUPTIONS[c].moderate, seed=0))
            for c in args.corruptions]
        for label, motion in copies:
            v_all, how_all, t_all = _scored(motion, every)
            v_skip, how_skip, t_skip = _scored(motion, skipping)
            totals[0] += t_all
            totals[1] += t_skip
            skipped += how_skip.startswith("skipped")
            agree += v_all == v_skip
            rows.append(f"{name:12s} {label:11s} {v_all:12s} {v_skip:12s} {t_all:7.1f} "
                        f"{t_skip:7.1f}  {how_all} | {how_skip}")
            print(rows[-1], flush=True)
    n = len(rows)
    print(f"\n{n} clips: verdicts agree on {agree}; tracking skipped on {skipped} "
          f"({100 * skipped / n:.0f} %); CPU every clip tracked {totals[0]:.0f} s, "
          f"track_if_plausible {totals[1]:.0f} s: ratio {totals[1] / totals[0]:.2f} "
          f"({totals[0] / totals[1]:.1f}x faster)")


if __name__ == "__main__":
    main()

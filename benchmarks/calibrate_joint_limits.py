"""Calibrate the joint-limit metric on real motion capture.

Runs :func:`simenv.plausibility.body.joint_limit_demand` (limited + relaxed
retargeting, per-hinge attribution, least excess on the flagged frames) on
every real single-person CMU clip of the shared corpus and prints, per clip,
the value (degrees beyond the anatomical range the motion demands), the
worst hinge and frame, the relaxed fit's signed angle of that hinge there
(before the least-excess re-split) and its range, and the number of frames
above the threshold. ``--restore-collapsed-bones`` reads the BVH files with
the reader's repair of the converter's collapsed thorax and wrist bones
(:func:`simenv.io.bvh.read`), to tell the file's damage from the motion.
About a minute on one core (``OMP_NUM_THREADS=1``).

Usage::

    .venv/bin/python benchmarks/calibrate_joint_limits.py [--data DIR] [--frames N]
        [--restore-collapsed-bones]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from calibrate_body import DEFAULT_DATA, load, single_person_clips

from simenv.io import bvh
from simenv.plausibility.body import joint_limit_demand
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--frames", type=int, default=None)
    ap.add_argument("--restore-collapsed-bones", action="store_true",
                    help="read BVH files with restore_collapsed_bones=True")
    args = ap.parse_args()
    thr = DEFAULT_BODY_THRESHOLDS.joint_limit_max_deg
    print(f"{'clip':27s} {'frames':>6s} {'value':>6s}  {'worst hinge':20s} {'frame':>5s} "
          f"{'relax':>6s} {'range':>11s} {'frames>thr':>10s} {'s':>5s}")
    for path in single_person_clips(args.data):
        t0 = time.perf_counter()
        motion = load(path, args.frames)
        if args.restore_collapsed_bones and path.suffix == ".bvh":
            motion = bvh.read(path, restore_collapsed_bones=True)
            if args.frames and motion.num_frames > args.frames:
                motion = motion.slice(0, args.frames)
        demand, limited, relaxed = joint_limit_demand(motion)
        h = limited.humanoid
        line = demand.max(axis=1)
        value = float(line.max())
        if value > 0:
            t, j = np.unravel_index(int(demand.argmax()), demand.shape)
            angle = np.rad2deg(relaxed.qpos[t, h.hinge_qpos[j]])
            lo, hi = np.rad2deg(h.joint_limits[j])
            worst = f"{h.joint_names[j]:20s} {t:5d} {angle:6.1f} [{lo:4.0f},{hi:4.0f}]"
        else:
            worst = f"{'-':20s} {'':5s} {'':6s} {'':11s}"
        mark = "!" if value > thr else " "
        clip = f"{path.parent.name}/{path.name}"
        print(f"{clip:27s} {motion.num_frames:6d} {value:5.1f}{mark}  "
              f"{worst} {int((line > thr).sum()):10d} {time.perf_counter() - t0:5.1f}", flush=True)


if __name__ == "__main__":
    main()

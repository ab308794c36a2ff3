"""Speed of the recognition benchmarks' descriptors, one core: the Lie-group descriptor
(:mod:`simenv.learning.lie_group`) against the covariance descriptor it sits beside
(:mod:`simenv.learning.covariance`), on the same real clips, as a ratio.

Each clip of a dataset (whole, normalised as the benchmarks see it) is described on the
room's gesture15 joints and on the dataset's own skeleton, with and without velocities for
the covariance, at every fraction of :data:`simenv.learning.lie_group.FOURIER_FRACTIONS` for
the Lie group (one relative-geometry curve, one pyramid per fraction). Timings are the best
of ``--repeats`` CPU-time measurements of describing every clip; numpy threads are pinned to
1 before numpy is imported.

Usage::

    .venv/bin/python benchmarks/bench_descriptors.py [--dataset msr_action3d] [--repeats 3]
        [--data GESTURES]
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

from simenv.core.config import shared_data_root  # noqa: E402
from simenv.data.gestures import load_gesture_clips  # noqa: E402
from simenv.learning.covariance import descriptors  # noqa: E402
from simenv.learning.lie_group import lie_group_descriptors  # noqa: E402
from simenv.learning.recognition import clip_skeleton  # noqa: E402
from simenv.learning.recognition_protocols import native_clips, whole_windows  # noqa: E402


def best_cpu_s(fn: Callable[[], object], repeats: int) -> float:
    """The least CPU seconds of ``repeats`` calls of ``fn``."""
    best = float("inf")
    for _ in range(repeats):
        start = time.process_time()
        fn()
        best = min(best, time.process_time() - start)
    return best


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="msr_action3d",
                        choices=("msr_action3d", "utkinect", "florence3d"))
    parser.add_argument("--data", type=Path, help="gestures folder (default: the shared "
                        "corpus)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    root = args.data or shared_data_root(None) / "gestures"
    clips = load_gesture_clips(root, datasets=(args.dataset,))
    print(f"{args.dataset}: {len(clips)} clips, "
          f"{sum(c.num_frames for c in clips)} frames at 25 fps")
    for name, group in (("gesture15", clips), ("native", native_clips(clips))):
        x, valid = whole_windows(group)
        parents = clip_skeleton(group).parents
        cov = best_cpu_s(lambda x=x, valid=valid: [descriptors(x, valid, v)
                                                   for v in (False, True)], args.repeats)
        lie = best_cpu_s(lambda x=x, valid=valid, parents=parents: lie_group_descriptors(
            x, valid, parents), args.repeats)
        per_clip = 1000.0 / len(group)
        print(f"{name:>9} ({x.shape[2]} joints): covariance {cov * per_clip:6.2f} ms/clip, "
              f"Lie group {lie * per_clip:6.2f} ms/clip, ratio Lie/covariance "
              f"{lie / cov:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Speed of the plausibility scorer, one core.

1. Joint-level (kinematic) metrics: frames per second of all six metrics
   (:func:`simenv.plausibility.kinematic_metrics`) on real 31-joint CMU BVH
   clips -- one call on the bundled walk (343 frames), one call per whole
   corpus clip, and :func:`simenv.plausibility.kinematic_metrics_batch` on a
   batch of equal-length windows cut from the corpus clips (the shape of a
   generator's output; computed in the call, their result objects built
   when read, so that case is timed also with every clip's results read).
   Goal: 2M frames/s. A "frame" is one frame of one
   31-joint clip with all six kinematic metrics computed on it (21
   canonical keypoints). The metrics are numba kernels
   (:mod:`simenv.plausibility.kernels`); their one-off compile time is
   reported apart from the warm rates: in a fresh process with an empty
   numba cache (compiling), and with the on-disk cache (loading).
2. Physics tracking: simulator steps per second of
   :func:`simenv.plausibility.tracking.track` on the retargeted walk
   (unassisted, and with the root assistance the scorer uses) against a raw
   ``mujoco.mj_step`` loop on the same model from the same state, in the
   same run, as a ratio (goal: 0.5). Both the whole ``track`` call and its
   stepping loop alone are reported.
3. The whole scorer: wall and CPU seconds of one :func:`simenv.score` call
   on the bundled walk (load excluded): physics off, physics without the
   tracking run, and the default (retargeting, every body metric, MPC
   tracking with the assisted PD run as a detail).

Every timing is the best of a few repeats (the machine may be shared); the
load average is printed for context, and the kinematic rates are also given
in CPU time of this process (``time.process_time``), which other jobs on a
shared machine inflate less than wall time: per call over rounds of at least
0.3 s, and as the least CPU time of single calls (closest to a core of
one's own, as ``timeit`` advises taking the minimum). numpy/BLAS/torch threads are pinned
to 1 before anything is imported.

Usage::

    .venv/bin/python benchmarks/bench_score.py [--data DIR] [--window-s 2] [--repeats 5]
        [--kinematic-only | --scorer-only] [--baseline DIR [--rounds 3]]

``--baseline DIR`` compares before and after in the same run: DIR holds an
older ``simenv`` package (``git archive REV simenv | tar -x -C DIR``); the
two trees' kinematic cases (unless ``--scorer-only``) and scorer cases
(unless ``--kinematic-only``) are timed in fresh processes that alternate
for ``--rounds`` rounds, best per case.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import copy  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import mujoco  # noqa: E402

import simenv  # noqa: E402
from simenv.assets import WALK, asset_path  # noqa: E402
from simenv.body.retarget import RetargetResult, retarget  # noqa: E402
from simenv.core.config import shared_data_root  # noqa: E402
from simenv.core.motion import Motion  # noqa: E402
from simenv.io import bvh  # noqa: E402
from simenv.plausibility import kinematic_metrics, kinematic_metrics_batch  # noqa: E402
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS  # noqa: E402
from simenv.plausibility.tracking import assisted_model, track  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
DEFAULT_DATA = shared_data_root()
GOAL_FRAMES_PER_S = 2e6
GOAL_RATIO = 0.5
#: CPU seconds of single calls behind the ``cpu_call`` rates (a few hundred
#: calls at least: fewer miss the quiet moments of a loaded machine).
SINGLE_CALLS_S = 1.5


def best_seconds(fn: Callable[[], object], repeats: int, min_s: float = 0.3,
                 clock: Callable[[], float] = time.perf_counter) -> float:
    """Best time (s, of ``clock``: wall by default) of one call of ``fn`` over
    ``repeats`` rounds, each round timing as many calls as fit in ``min_s``."""
    fn()
    best = float("inf")
    for _ in range(repeats):
        calls, start = 0, clock()
        while True:
            fn()
            calls += 1
            elapsed = clock() - start
            if elapsed >= min_s:
                break
        best = min(best, elapsed / calls)
    return best


def least_call_seconds(fn: Callable[[], object], total_s: float) -> float:
    """Least CPU time (s) of one call of ``fn`` over single calls that take
    ``total_s`` CPU seconds together (at least 100 calls)."""
    fn()
    best, spent, calls = float("inf"), 0.0, 0
    while spent < total_s or calls < 100:
        start = time.process_time()
        fn()
        elapsed = time.process_time() - start
        best, spent, calls = min(best, elapsed), spent + elapsed, calls + 1
    return best


def windows(clips: list[Motion], frames: int) -> list[Motion]:
    """Non-overlapping windows of ``frames`` frames of every clip."""
    return [c.slice(s, s + frames) for c in clips for s in range(0, c.num_frames - frames + 1,
                                                                  frames)]


#: Run in a fresh interpreter: seconds of the first and of a second
#: kinematic_metrics call on the bundled walk.
_FIRST_CALL = """
import time
from simenv.assets import WALK, asset_path
from simenv.io import bvh
from simenv.plausibility import kinematic_metrics
walk = bvh.read(asset_path(WALK))
t0 = time.perf_counter(); kinematic_metrics(walk); t1 = time.perf_counter()
kinematic_metrics(walk); t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
"""


def first_call_seconds(cache_dir: str | None) -> tuple[float, float]:
    """(first, second) call seconds of the kinematic metrics in a fresh
    process, with numba's cache in ``cache_dir`` (None: its default, next to
    the kernels module)."""
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    out = subprocess.run([sys.executable, "-c", _FIRST_CALL], env=env, check=True,
                         capture_output=True, text=True).stdout.split()
    return float(out[-2]), float(out[-1])


def bench_compile() -> None:
    with tempfile.TemporaryDirectory() as empty:
        cold, _ = first_call_seconds(empty)
    cached, warm = first_call_seconds(None)
    print(f"numba kernels: first call {cold:.1f} s compiling (empty cache), {cached:.2f} s "
          f"loading the cache; warm call on the walk {warm * 1e3:.2f} ms")


def kinematic_cases(clips: list[Motion], walk: Motion, window_s: float
                    ) -> list[tuple[str, int, int, Callable[[], object]]]:
    """(label, frames, clips, call) of each kinematic case."""
    batch = windows(clips, round(window_s * clips[0].fps))
    return [
        ("one call, bundled walk", walk.num_frames, 1, lambda: kinematic_metrics(walk)),
        ("one call per whole clip", sum(c.num_frames for c in clips), len(clips),
         lambda: [kinematic_metrics(c) for c in clips]),
        (f"batch of {window_s:g} s windows", sum(b.num_frames for b in batch), len(batch),
         lambda: kinematic_metrics_batch(batch)),
        # The batch's result objects are built when read: also time reading
        # every clip's (the cost a caller that reads them all pays).
        (f"{window_s:g} s windows, results read", sum(b.num_frames for b in batch), len(batch),
         lambda: list(kinematic_metrics_batch(batch))),
    ]


def time_kinematic(clips: list[Motion], walk: Motion, window_s: float, repeats: int
                   ) -> list[dict]:
    """Best wall and CPU seconds of each case of :func:`kinematic_cases`: per
    call in rounds of at least 0.3 s (``wall``, ``cpu``), and the least CPU
    time of single calls (``cpu_call``, over :data:`SINGLE_CALLS_S`), which
    on a shared machine comes closest to a core of one's own: a 0.3 s round
    always includes other jobs' cache and core sharing."""
    return [{"label": label, "frames": frames, "clips": n,
             "wall": best_seconds(fn, repeats),
             "cpu": best_seconds(fn, repeats, clock=time.process_time),
             "cpu_call": least_call_seconds(fn, SINGLE_CALLS_S)}
            for label, frames, n, fn in kinematic_cases(clips, walk, window_s)]


def _rates(case: dict) -> str:
    rate, cpu_rate = case["frames"] / case["wall"], case["frames"] / case["cpu"]
    call_rate = case["frames"] / case["cpu_call"]
    return (f"{case['wall'] * 1e3:8.2f} ms  {rate:12,.0f} frames/s"
            f"  ({rate / GOAL_FRAMES_PER_S:.2f} x goal) | CPU {case['cpu'] * 1e3:8.2f} ms"
            f"  {cpu_rate:12,.0f} frames/s  ({cpu_rate / GOAL_FRAMES_PER_S:.2f} x goal)"
            f" | CPU single call {case['cpu_call'] * 1e3:8.2f} ms  {call_rate:12,.0f} frames/s"
            f"  ({call_rate / GOAL_FRAMES_PER_S:.2f} x goal)")


_HEADER = ("kinematic metrics (6 joint-level metrics, 31-joint CMU BVH, one core; frame = one"
           " frame of one clip with all six metrics; wall time, and CPU time of this process,"
           " which other jobs on a shared machine inflate less)")


def bench_kinematic(clips: list[Motion], walk: Motion, window_s: float, repeats: int) -> None:
    print(_HEADER)
    for case in time_kinematic(clips, walk, window_s, repeats):
        print(f"  {case['label']:28s} {case['clips']:4d} clip(s) {case['frames']:7d} frames"
              f"  {_rates(case)}")


def alternating(baseline: Path, args: argparse.Namespace, part: str) -> dict[str, list[dict]]:
    """The cases of ``part`` (``kinematic`` or ``scorer``) of this tree and of the
    ``simenv`` package in ``baseline`` (e.g. ``git archive REV simenv | tar -x -C
    DIR``), each timed in a fresh process, the two alternating for
    ``args.rounds`` rounds so that both see the same machine load: per tree,
    the best of every timing key of each case."""
    if not (baseline / "simenv" / "__init__.py").is_file():
        raise SystemExit(f"--baseline {baseline}: expected a directory holding simenv/")
    best: dict[str, list[dict]] = {}
    for _ in range(args.rounds):
        for name, root in (("baseline", baseline), ("current", REPO)):
            env = dict(os.environ, PYTHONPATH=os.pathsep.join(
                [str(root), os.environ.get("PYTHONPATH", "")]))
            out = subprocess.run(
                [sys.executable, __file__, f"--{part}-json", "--data", str(args.data),
                 "--window-s", str(args.window_s), "--repeats", str(args.repeats)],
                env=env, check=True, capture_output=True, text=True).stdout
            cases = json.loads(out.splitlines()[-1])
            if name not in best:
                best[name] = cases
            for old, new in zip(best[name], cases, strict=True):
                for key in ("wall", "cpu", "cpu_call"):
                    if key in old:
                        old[key] = min(old[key], new[key])
    return best


#: Speed-up lines: timing key -> its name.
_SPEEDUPS = {"wall": "wall", "cpu": "CPU", "cpu_call": "CPU single call"}


def compare(baseline: Path, args: argparse.Namespace, part: str) -> None:
    """This tree's ``part`` cases (``kinematic`` or ``scorer``) against those
    of ``baseline`` (:func:`alternating`)."""
    best = alternating(baseline, args, part)
    header, line = (_HEADER, _rates) if part == "kinematic" else (_SCORER_HEADER, _scorer_line)
    print(f"{header}; best of {args.rounds} alternating rounds, load average now "
          f"{os.getloadavg()[0]:.1f}; baseline: {baseline}")
    for base, cur in zip(best["baseline"], best["current"], strict=True):
        print(f"  {cur['label']:28s} {cur.get('clips', 1):4d} clip(s) {cur['frames']:7d} frames")
        print(f"    baseline {line(base)}")
        print(f"    current  {line(cur)}")
        print("    speed-up " + ", ".join(f"{name} {base[k] / cur[k]:.2f} x"
                                          for k, name in _SPEEDUPS.items() if k in cur))


def raw_steps_per_s(model: mujoco.MjModel, result: RetargetResult, steps: int,
                    repeats: int) -> float:
    """mj_step loop on ``model`` from the first reference pose, ``steps`` steps."""
    data = mujoco.MjData(model)
    act_qpos = model.jnt_qposadr[model.actuator_trnid[:, 0]]

    def run() -> None:
        mujoco.mj_resetData(model, data)
        data.qpos[:] = result.qpos[0]
        data.ctrl[:] = result.qpos[0, act_qpos]
        mujoco.mj_forward(model, data)
        for _ in range(steps):
            mujoco.mj_step(model, data)

    return steps / best_seconds(run, repeats, min_s=0.0)


def bench_tracking(walk: Motion, repeats: int) -> None:
    result = retarget(walk)
    h = result.humanoid
    print(f"physics tracking (retargeted walk, {walk.num_frames} frames, "
          f"timestep {h.model.opt.timestep * 1000:g} ms)")
    for assist in (False, True):
        tr = track(result, assist=assist)
        call_s = best_seconds(lambda a=assist: track(result, assist=a), repeats, min_s=0.0)
        loop_s = min(track(result, assist=assist).wall_s for _ in range(repeats))
        model = assisted_model(h, DEFAULT_BODY_THRESHOLDS) if assist else copy.deepcopy(h.model)
        raw = raw_steps_per_s(model, result, tr.steps, repeats)
        call, loop = tr.steps / call_s, tr.steps / loop_s
        outcome = "tracked" if tr.success else f"fell at {tr.time_to_failure_s:.2f} s"
        print(f"  {'assisted' if assist else 'unassisted':10s} {tr.steps:5d} steps ({outcome})"
              f"  raw mj_step {raw:8,.0f} steps/s | track() {call:8,.0f} steps/s,"
              f" ratio {call / raw:.2f} | stepping loop {loop:8,.0f} steps/s,"
              f" ratio {loop / raw:.2f}  (goal {GOAL_RATIO})")


#: The scorer's cases on the bundled walk: label, physics, ScoreConfig keywords.
SCORER_CASES: tuple[tuple[str, bool, dict], ...] = (
    ("physics off", False, {}),
    ("physics, no tracking run", True, {"tracking": False}),
    ("default (MPC + assisted PD)", True, {}),
)


def time_scorer(walk: Motion, repeats: int) -> list[dict]:
    """Least wall and CPU seconds of one :func:`simenv.score` call on ``walk``
    per case of :data:`SCORER_CASES` over ``repeats`` calls (one for a case
    that runs the tracking simulation: a minute of CPU), after a warm-up
    (the kernels' cache and the retargeting's first call)."""
    simenv.score(walk.slice(0, 30), config=simenv.ScoreConfig(tracking=False))
    out = []
    for label, physics, options in SCORER_CASES:
        config = simenv.ScoreConfig(**options)
        wall = cpu = float("inf")
        simulates = physics and config.tracking
        for _ in range(1 if simulates else repeats):
            w, c = time.perf_counter(), time.process_time()
            simenv.score(walk, physics=physics, config=config)
            wall = min(wall, time.perf_counter() - w)
            cpu = min(cpu, time.process_time() - c)
        out.append({"label": label, "frames": walk.num_frames, "wall": wall, "cpu": cpu})
    return out


_SCORER_HEADER = "whole scorer, simenv.score on the bundled walk"


def _scorer_line(case: dict) -> str:
    return f"wall {case['wall'] * 1e3:10.1f} ms | CPU {case['cpu'] * 1e3:10.1f} ms"


def bench_scorer(walk: Motion, repeats: int) -> None:
    print(f"{_SCORER_HEADER} ({walk.num_frames} frames)")
    for case in time_scorer(walk, repeats):
        print(f"  {case['label']:28s} {_scorer_line(case)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--window-s", type=float, default=2.0,
                        help="length of the batched windows, seconds")
    parser.add_argument("--repeats", type=int, default=5)
    parts = parser.add_mutually_exclusive_group()
    parts.add_argument("--kinematic-only", action="store_true",
                       help="skip the compile-time, physics-tracking and scorer parts")
    parts.add_argument("--scorer-only", action="store_true",
                       help="time the whole scorer only")
    parser.add_argument("--baseline", type=Path,
                        help="also time the kinematic metrics and the scorer of the simenv "
                             "package in this directory (an older revision), alternating "
                             "with this tree's")
    parser.add_argument("--rounds", type=int, default=3,
                        help="alternating rounds of --baseline")
    parser.add_argument("--kinematic-json", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--scorer-json", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if "torch" in sys.modules:
        import torch  # only to limit its threads when something already loaded it

        torch.set_num_threads(1)
    walk = bvh.read(asset_path(WALK))
    if args.scorer_json:
        print(json.dumps(time_scorer(walk, args.repeats)))
        return
    if args.scorer_only:
        if args.baseline is not None:
            compare(args.baseline, args, "scorer")
        else:
            bench_scorer(walk, args.repeats)
        return
    clips = [bvh.read(p) for p in sorted((args.data / "cmu" / "bvh").glob("*.bvh"))]
    clips = [c for c in clips if c.num_joints == 31 and c.fps == walk.fps] or [walk]
    if args.kinematic_json:
        print(json.dumps(time_kinematic(clips, walk, args.window_s, args.repeats)))
        return
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; "
          f"{len(clips)} real clip(s) from {args.data if len(clips) > 1 else 'the bundled walk'}")
    if not args.kinematic_only:
        bench_compile()
    if args.baseline is not None:
        compare(args.baseline, args, "kinematic")
    else:
        bench_kinematic(clips, walk, args.window_s, args.repeats)
    if not args.kinematic_only:
        bench_tracking(walk, args.repeats)
        if args.baseline is not None:
            compare(args.baseline, args, "scorer")
        else:
            bench_scorer(walk, args.repeats)


if __name__ == "__main__":
    main()

"""Time-varying LQR feedback between replans (issue 35): tracking closeness and cost.

Two measurements on real CMU clips of the shared corpus (docs/tracking_speed.md):

* ``run``: each planner variant of :data:`VARIANTS` (FAST's search with a longer replan
  interval and/or :class:`simenv.control.MPCConfig` ``feedback``) tracks each clip's first
  ``--seconds`` with one thread and one attempt; per clip the mean body error, whether it
  tracked, rolled-out planning steps per simulated step (a linearisation counted as its
  stepped states) and CPU seconds per simulated second (``time.process_time``: the
  machine's load does not change it the way it changes wall time). One JSON line per run
  to ``--out``; a rerun skips the (variant, clip, seed) already there.
* ``drift``: how far the simulated body departs from the plan's prediction when a FAST
  nominal is played open loop for 40 ms, 80 ms and the 0.44 s horizon from four states the
  tracker reached, with and without the feedback (the drift feedback could correct).

::

    nice -n 10 .venv/bin/python benchmarks/bench_tracking_feedback.py run --out out/fb.jsonl
    .venv/bin/python benchmarks/bench_tracking_feedback.py table --out out/fb.jsonl
    nice -n 10 .venv/bin/python benchmarks/bench_tracking_feedback.py drift
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from eval_tracking import ACROBATICS, clip_motion, clips  # noqa: E402

from simenv.body.retarget import retarget  # noqa: E402
from simenv.control import FAST, TrackingMPC, TrackingReference  # noqa: E402
from simenv.core.config import shared_data_root  # noqa: E402
from simenv.plausibility.corrupt import CORRUPTIONS  # noqa: E402
from simenv.plausibility.tracking import track  # noqa: E402

#: The variants of docs/tracking_speed.md: MPCConfig fields over FAST's. replan_steps are
#: 2 ms physics steps (10: every 20 ms); feedback_knots None: one per planning step.
VARIANTS: dict[str, dict] = {
    "fast": {},
    "fast_fb3": {"feedback": True, "feedback_knots": 3},
    "fast_fb_every": {"feedback": True},
    "40ms": {"replan_steps": 20},
    "40ms_fb1": {"replan_steps": 20, "feedback": True, "feedback_knots": 1},
    "40ms_fb3": {"replan_steps": 20, "feedback": True, "feedback_knots": 3},
    "40ms_fb12": {"replan_steps": 20, "feedback": True, "feedback_knots": 12},
    "40ms_fb_every": {"replan_steps": 20, "feedback": True},
    "80ms": {"replan_steps": 40},
    "80ms_fb1": {"replan_steps": 40, "feedback": True, "feedback_knots": 1},
    "80ms_fb3": {"replan_steps": 40, "feedback": True, "feedback_knots": 3},
    "80ms_fb12": {"replan_steps": 40, "feedback": True, "feedback_knots": 12},
    "80ms_fb_every": {"replan_steps": 40, "feedback": True},
    "16ms_step": {"timestep_factor": 8},
    "16ms_step_fb3": {"timestep_factor": 8, "feedback": True, "feedback_knots": 3},
    "16ms_step_fb10": {"timestep_factor": 8, "feedback": True, "feedback_knots": 10},
    "16ms_step_fb_every": {"timestep_factor": 8, "feedback": True},
    "32_samples": {"n_samples": 32},
    "32_samples_fb1": {"n_samples": 32, "feedback": True, "feedback_knots": 1},
}
CLIPS = ("bvh/02_01.bvh", "bvh/12_01.bvh", "bvh/35_17.bvh")
#: The corrupted copies (clip, corruption, strength; seed 0) the previous default planner
#: fails (docs/plausibility.md, docs/tracking_speed.md): a tracker must fail them too.
DEFAULT_FAILS = tuple((c, k, s) for k, s, cs in (
    ("teleport", 1.0, ("bvh/02_01.bvh", "bvh/35_17.bvh", "bvh/49_04.bvh",
                       "asf_amc/103_charleston1.amc")),
    ("time_warp", 10.0, ("bvh/02_01.bvh", "bvh/35_17.bvh", "bvh/49_04.bvh")),
    ("float", 50.0, ("bvh/02_01.bvh", "bvh/35_17.bvh", "bvh/49_04.bvh"))) for c in cs)
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


def run(args: argparse.Namespace) -> None:
    done = set()
    if args.out.is_file():
        done = {(r["variant"], r["clip"], r["seed"])
                for r in map(json.loads, filter(str.strip, args.out.read_text().splitlines()))}
    cmu = args.data / "cmu"
    jobs = [(c, "none", 0.0) for c in args.clips]
    if args.clips == ["clean20"]:   # eval_tracking.py's 20 non-acrobatic clean clips
        jobs = [(str(p.relative_to(cmu)), "none", 0.0) for p in clips(args.data)
                if p.stem not in ACROBATICS]
    elif args.clips == ["corrupt"]:
        jobs = list(DEFAULT_FAILS)
    for clip, corruption, strength in jobs:
        key = clip if corruption == "none" else f"{clip} {corruption} {strength:g}"
        fitted = None
        for seed in args.seeds:
            for name in args.variants:
                if (name, key, seed) in done:
                    continue
                if fitted is None:
                    motion = clip_motion(cmu / clip, args.seconds)
                    if corruption != "none":
                        motion = CORRUPTIONS[corruption].fn(motion, strength, seed=0)
                    fitted = retarget(motion)
                cfg = replace(FAST, nthread=1, attempts=args.attempts, seed=seed,
                              **VARIANTS[name])
                cpu = time.process_time()
                tr = track(fitted, controller="mpc", mpc=cfg, max_seconds=args.seconds)
                cpu = time.process_time() - cpu
                sim = tr.steps * fitted.humanoid.model.opt.timestep
                rec = {"variant": name, "clip": key, "seed": seed, "success": tr.success,
                       "mpjpe_mm": tr.mpjpe_mm, "time_to_failure_s": tr.time_to_failure_s,
                       "steps_per_step": tr.rollout_steps / tr.steps,
                       "cpu_per_sim_s": cpu / sim, "runs": tr.runs,
                       "attempts": args.attempts, "seconds": args.seconds,
                       "load": os.getloadavg()[0]}
                with args.out.open("a") as f:
                    f.write(json.dumps(rec) + "\n")
                print(json.dumps(rec), flush=True)


def table(args: argparse.Namespace) -> None:
    rows = defaultdict(list)
    for r in map(json.loads, filter(str.strip, args.out.read_text().splitlines())):
        rows[(r["variant"], r["seed"])].append(r)
    for (name, seed), rs in rows.items():
        cells = " | ".join(f"{Path(r['clip']).name} {r['mpjpe_mm']:.0f}"
                           + ("" if r["success"] else f" (fell {r['time_to_failure_s']:.2f})")
                           for r in rs)
        steps = [r["steps_per_step"] for r in rs]
        cpu = [r["cpu_per_sim_s"] for r in rs]
        print(f"{name:20s} seed {seed} | steps {min(steps):.0f}-{max(steps):.0f} | CPU "
              f"{min(cpu):.1f}-{max(cpu):.1f} s/s | {cells} | mean "
              f"{np.mean([r['mpjpe_mm'] for r in rs]):.1f} mm")


def _gap_mm(mpc: TrackingMPC, data: mujoco.MjData, x0: np.ndarray, start: int, n: int,
            feedback: bool) -> float:
    """Mean keypoint distance (mm) from the plan's prediction after playing the nominal
    ``n`` physics steps from ``x0`` (planned at step ``start``)."""
    m, fb = mpc.model, mpc.feedback
    mujoco.mj_setState(m, data, x0, _FULL)
    for s in range(n):
        u = mpc.ctrl_ref[start + s] + mpc._offsets(start + s)
        if feedback:
            u[fb.actuators] += fb.correction(m, data, s)
        data.ctrl[:] = u
        mujoco.mj_step(m, data)
    mujoco.mj_kinematics(m, data)
    predicted = mujoco.MjData(m)
    predicted.qpos[:] = fb.qpos[n // mpc.config.timestep_factor]
    mujoco.mj_kinematics(m, predicted)
    gap = data.site_xpos[fb.site_ids] - predicted.site_xpos[fb.site_ids]
    return 1000.0 * float(np.linalg.norm(gap, axis=1).mean())


def drift(args: argparse.Namespace) -> None:
    spans = (20, 40, 220)   # physics steps: 40 ms, 80 ms, 0.44 s
    for clip in args.clips:
        fitted = retarget(clip_motion(args.data / "cmu" / clip, 1.6))
        ref = TrackingReference.from_retarget(fitted, max_seconds=1.6)
        gaps = {(n, fb): [] for n in spans for fb in (False, True)}
        for start in (0, 150, 300, 450):   # 0, 0.3, 0.6, 0.9 s
            with TrackingMPC(fitted.humanoid, ref, replace(FAST, nthread=1, feedback=True)
                             ) as mpc:
                data = mujoco.MjData(mpc.model)
                mpc.reset(data)
                for s in range(start):
                    data.ctrl[:] = mpc.control(data, s)
                    mujoco.mj_step(mpc.model, data)
                mpc.plan(data, start)
                x0 = np.empty(mujoco.mj_stateSize(mpc.model, _FULL))
                mujoco.mj_getState(mpc.model, data, x0, _FULL)
                for n, fb in gaps:
                    gaps[(n, fb)].append(_gap_mm(mpc, data, x0, start, n, fb))
        print(clip, "  ".join(f"{2 * n} ms: {np.mean(gaps[(n, False)]):.1f} / "
                              f"{np.mean(gaps[(n, True)]):.1f} mm" for n in spans), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("command", choices=("run", "table", "drift"))
    ap.add_argument("--out", type=Path, default=Path("out/bench_tracking_feedback.jsonl"))
    ap.add_argument("--data", type=Path, default=shared_data_root())
    ap.add_argument("--clips", nargs="+", default=list(CLIPS),
                    help="run: paths under cmu/ (never the reserved trials); 'clean20': the "
                         "20 clean clips of eval_tracking.py; 'corrupt': DEFAULT_FAILS")
    ap.add_argument("--variants", nargs="+", choices=sorted(VARIANTS), default=list(VARIANTS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--attempts", type=int, default=1,
                    help="run: planner seeds a run may try (the scorer's: 3)")
    args = ap.parse_args()
    if args.command == "run":
        args.out.parent.mkdir(parents=True, exist_ok=True)
    {"run": run, "table": table, "drift": drift}[args.command](args)


if __name__ == "__main__":
    main()

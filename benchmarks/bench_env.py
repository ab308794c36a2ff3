"""Environment throughput: env steps/s against a raw ``mj_step`` loop on the same model.

For each environment the raw loop runs ``mujoco.mj_step(model, data, nstep=frame_skip)``
on the env's own model and data from its reset state, with the controls left at the reset
values; the env loop calls ``env.step`` with a constant action (the no-op of
``InteractionRoom``, the reset PD targets of ``HumanoidTrack``) and resets whenever an
episode ends (reset time included). The ratio env/raw is the fraction of the simulator's
speed the environment keeps (goal >= 0.5). Also the rehearsal pipeline's real-time factor
with rendering off (simulated seconds per wall second of :func:`simenv.envs.rehearsal.rehearse`
after a warm-up run, whole and for its simulation loop alone; goal >= 3): the
bundled walk in the discomfort scenario with a labelled "smell" gesture, so the agent's
cigarette_out plan runs. Single process, one core. Usage::

    .venv/bin/python benchmarks/bench_env.py [--steps N] [--json]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time

import mujoco
import numpy as np

import simenv  # noqa: F401  (MUJOCO_GL before mujoco renders)
from simenv.assets import WALK
from simenv.envs.humanoid_track import HumanoidTrackEnv
from simenv.envs.interaction_room import InteractionRoomEnv
from simenv.envs.rehearsal import rehearse
from simenv.room.session import GestureEvent, Session


def _raw(model: mujoco.MjModel, data: mujoco.MjData, frame_skip: int, steps: int) -> float:
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(model, data, nstep=frame_skip)
    return steps / (time.perf_counter() - t0)


def _env(env, action, steps: int) -> float:  # noqa: ANN001  (any Gymnasium env)
    env.reset(seed=0)
    t0 = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - t0)


def bench(steps: int) -> dict[str, dict[str, float]]:
    out = {}
    track = HumanoidTrackEnv(random_start=False)
    track.reset(seed=0)
    hold = track.data.ctrl.astype(np.float32).copy()
    room = InteractionRoomEnv()
    for name, env, action in (("HumanoidTrack-v0", track, hold),
                              ("InteractionRoom-v0", room, 0)):
        env.reset(seed=0)
        raw = _raw(env.model, env.data, env.frame_skip, steps)
        stepped = _env(env, action, steps)
        out[name] = {"frame_skip": env.frame_skip, "env_steps_per_s": stepped,
                     "raw_steps_per_s": raw, "ratio": stepped / raw}
    session = Session.load(WALK, [GestureEvent("smell", 0.2, 1.0)])
    with tempfile.TemporaryDirectory() as tmp:
        rehearse(session, tmp, scenario="discomfort", agent="labels", render=False)  # warm-up
        t0 = time.perf_counter()
        summary = rehearse(session, tmp, scenario="discomfort", agent="labels", render=False)
        wall = time.perf_counter() - t0
    sim = summary["duration_s"]
    out["rehearsal"] = {"simulated_s": sim, "wall_s": wall, **summary["timing_s"],
                        "real_time_factor": sim / wall}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    result = bench(args.steps)
    if args.json:
        print(json.dumps(result, indent=2))
        return
    rehearsal = result.pop("rehearsal")
    for name, r in result.items():
        print(f"{name:20s} frame_skip {r['frame_skip']:2d}: env {r['env_steps_per_s']:7.1f} "
              f"steps/s, raw mj_step {r['raw_steps_per_s']:7.1f} steps/s, "
              f"ratio {r['ratio']:.2f}")
    r = rehearsal
    print(f"rehearsal (no rendering): {r['simulated_s']:.2f} s simulated in {r['wall_s']:.2f} s "
          f"(preparation {r['preparation']:.2f}, loop {r['loop']:.2f}, outputs "
          f"{r['outputs']:.2f}): real-time factor {r['real_time_factor']:.2f}, simulation "
          f"loop alone {r['loop_real_time_factor']:.2f}")


if __name__ == "__main__":
    main()

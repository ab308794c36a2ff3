"""Measure the room agent's walk from motion-capture primitives
(:mod:`simenv.agents.mocap_walk`) side by side with the stepping gait
(:mod:`simenv.agents.walk`) on the same walks, on one core.

Walks (``discomfort`` room, the agent standing in its rest pose, balanced 1 s, no
rendering; nothing but its servos and contacts acts on it):

* ``straight``: from (-0.3, -1.4) facing east to (2.0, -1.4), along the south wall, east of
  the user (standing closer to the wall, the rest pose's hand touches it);
* ``bend``: from (-0.3, -1.4) facing east to (2.0, -0.9) (the primitives bend on the way,
  the stepping gait turns on the spot);
* ``to the window``: from (-0.2, 0.6), beside the desk, facing the spot in front of the
  window's handle, (-1.12, 1.59), 1.35 m away.

Per walk and gait: simulated seconds, wall seconds (1 thread) and their ratio, the mean
speeds, whether it fell, the
lowest pelvis height, the pelvis's distance from the goal at the end, the largest external
help on any physics step (N), when it fell and, for the primitives, the sequence
planned and played (and the piece it fell in). Speeds: the
pelvis's path length on the floor (it sways) and its net displacement, each over the
simulated time.

Usage::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/bench_mocap_walk.py \\
        [--out out/bench_mocap_walk] [--gaits mocap stepping] [--walks NAME ...]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from simenv.agents.gait import standing_agent
from simenv.agents.mocap_walk import plan_mocap_walk
from simenv.agents.walk import plan_walk
from simenv.room.room import Room

#: name -> (start (x, y), heading rad, goal (x, y)).
WALKS: dict[str, tuple[tuple[float, float], float, tuple[float, float]]] = {
    "straight": ((-0.3, -1.4), 0.0, (2.0, -1.4)),
    "bend": ((-0.3, -1.4), 0.0, (2.0, -0.9)),
    "to the window": ((-0.2, 0.6), float(np.arctan2(0.99, -0.92)), (-1.12, 1.59)),
}


#: Pelvis height below which the body has fallen (when it first did), m.
FALLEN_M = 0.6


def _run(gait: str, start: tuple[float, float], yaw: float, goal: tuple[float, float]
         ) -> dict[str, Any]:
    room = Room("discomfort")
    data = standing_agent(room, np.array(start), yaw)
    goal_a = np.array(goal)
    if gait == "mocap":
        plan = plan_mocap_walk(room, data, goal_a)
        extra = {"planned": list(plan.names)}
    else:
        heading = float(np.arctan2(*(goal_a - start)[::-1]))
        plan = plan_walk(room, data, goal_a, heading)
        extra = {"steps": len(plan.steps)}
    path = []
    dt = room.model.opt.timestep
    fell_at = None
    t0 = time.perf_counter()
    for i in range(int(round(plan.duration / dt))):
        data.ctrl[room.agent_ctrl] = plan.control(i * dt, data)
        mujoco.mj_step(room.model, data)
        if i % 50 == 0:
            path.append(data.qpos[room.agent_qpos][:2].copy())
            if fell_at is None and data.qpos[room.agent_qpos][2] < FALLEN_M:
                fell_at = i * dt
    wall = time.perf_counter() - t0
    path_a = np.array([*path, data.qpos[room.agent_qpos][:2].copy()])
    dist = float(np.linalg.norm(np.diff(path_a, axis=0), axis=1).sum())
    net = float(np.linalg.norm(path_a[-1] - path_a[0]))
    out = plan.feedback.outcome(data)
    help_ = plan.feedback.summary()
    if gait == "mocap":
        extra["seams"] = [[round(float(x), 3) if isinstance(x, float) else x for x in s]
                          for s in plan.seams]
        extra["played"] = plan.names  # the bends re-picked at the seams
        if fell_at is not None:
            extra["fell_in"] = [s[1] for s in plan.seams if s[0] <= fell_at][-1]
    return {"gait": gait, "simulated_s": plan.duration, "wall_s": wall,
            "cost_x_real_time": wall / plan.duration, "distance_m": dist,
            "path_speed_mps": dist / plan.duration, "net_m": net,
            "net_speed_mps": net / plan.duration, **out, "fell_at_s": fell_at,
            "help_max_n": help_["max_n"], **extra}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/bench_mocap_walk"))
    parser.add_argument("--gaits", nargs="*", default=["mocap", "stepping"],
                        choices=["mocap", "stepping"],
                        help="which gaits (the stepping gait takes minutes a walk)")
    parser.add_argument("--walks", nargs="*", default=list(WALKS))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in args.walks:
        start, yaw, goal = WALKS[name]
        for gait in args.gaits:
            row = {"walk": name, **_run(gait, start, yaw, goal)}
            rows.append(row)
            print(json.dumps(row, default=str), flush=True)
            (args.out / f"bench_mocap_walk_{'_'.join(args.gaits)}.json").write_text(
                json.dumps(rows, indent=1, default=str))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

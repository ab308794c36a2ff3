"""Measure the room agent's walk from motion-capture primitives
(:mod:`simenv.agents.mocap_walk`) side by side with the stepping gait
(:mod:`simenv.agents.walk`) on the same walks, on one core.

Walks (the agent standing in its rest pose, balanced 1 s, no rendering; nothing but its
servos and contacts acts on it):

* in the ``discomfort`` room (:data:`WALKS`):

  * ``straight``: from (-0.3, -1.4) facing east to (2.0, -1.4), along the south wall,
    east of the user (standing closer to the wall, the rest pose's hand touches it);
  * ``bend``: from (-0.3, -1.4) facing east to (2.0, -0.9) (the primitives bend on the
    way, the stepping gait turns on the spot);
  * ``to the window``: from (-0.2, 0.6), beside the desk, facing the spot in front of
    the window's handle, (-1.12, 1.59), 1.35 m away;

* on open floor (:data:`OPEN_GOALS`: the same room 16 m square, the agent at (-6, -4)
  facing east, far from the furniture): eight goals 2.5-5 m ahead and up to 1.5 m aside.

The primitives' walk is measured alone (``mocap``: it heads where the body faces), after
the stepping gait's turn on the spot to face the goal when it is more than
:data:`simenv.agents.walk.ALIGN_DEG` off (``turn+mocap``), and followed by the stepping gait's
walk onto the goal when it ends more than 0.15 m off and standing (``mocap+step``: the
stop that corrects the remaining offset, :func:`simenv.agents.walk.plan_walk`, facing the
walk's heading).
``person`` is :class:`simenv.agents.mocap_walk.PersonWalk` (a stepping turn when needed,
the primitives' walk where it gains without passing the goal, the stepping gait onto the
goal); ``person+close`` the same ending in the closing stops (a ``--library`` built with
``build_mocap_walk.py --close``).

Per walk and gait: simulated seconds, wall and CPU seconds (1 thread) and their ratios to
it (CPU: the cost on one core, whatever else the machine runs), the mean
speeds, whether it fell, the lowest pelvis height, the pelvis's distance from the goal at
the end, the largest external help on any physics step (N), when it fell and, for the
primitives, the sequence planned and played (and the piece it fell in). Speeds: the
pelvis's path length on the floor (it sways) and its net displacement, each over the
simulated time.

Usage::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/bench_mocap_walk.py \\
        [--out out/bench_mocap_walk] [--gaits mocap turn+mocap mocap+step person stepping] \\
        [--walks NAME ... open] [--library FILE] [--rows EARLIER.json ...] [--docs docs/room.md]

The table in docs/room.md: the primitives' gaits in one run, the stepping gait's rows (it
takes 1-2 min of simulation a walk) from a ``--gaits stepping`` run merged with ``--rows``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from simenv.agents.gait import standing_agent, wrap_angle
from simenv.agents.mocap_walk import (
    CLOSE_STOP,
    Library,
    load_library,
    plan_mocap_walk,
    plan_person_walk,
)
from simenv.agents.walk import ALIGN_DEG, plan_walk
from simenv.core.errors import SimenvError
from simenv.room.room import Room
from simenv.room.scenario import Scenario, load_scenario

#: name -> (start (x, y), heading rad, goal (x, y)).
WALKS: dict[str, tuple[tuple[float, float], float, tuple[float, float]]] = {
    "straight": ((-0.3, -1.4), 0.0, (2.0, -1.4)),
    "bend": ((-0.3, -1.4), 0.0, (2.0, -0.9)),
    "to the window": ((-0.2, 0.6), float(np.arctan2(0.99, -0.92)), (-1.12, 1.59)),
}


#: Open floor: the agent's start (x, y) and heading (rad), and the goals relative to it.
OPEN_START, OPEN_YAW = (-6.0, -4.0), 0.0
OPEN_GOALS = ((2.5, 0.0), (3.5, 0.0), (4.5, 0.0), (3.0, 1.0), (3.0, -1.0), (4.0, 1.5),
              (4.0, -1.5), (5.0, 0.5))
#: Pelvis height below which the body has fallen (when it first did), m.
FALLEN_M = 0.6
#: A walk ending farther than this from its goal gets the stepping gait's correction, m.
CORRECT_M = 0.15


def open_floor() -> Scenario:
    """The ``discomfort`` scenario in a 16 m square room (its furniture near the middle)."""
    s = load_scenario("discomfort")
    return replace(s, name="open_floor", room=replace(s.room, size=(16.0, 16.0)))


def _play(room: Room, data: mujoco.MjData, plan: Any, path: list, t_off: float
          ) -> tuple[float, float | None]:
    """Play ``plan`` to its end (its duration read every step: the primitives' walk may
    re-choose its tail at a seam); the pelvis every 0.1 s into ``path``; returns the
    simulated seconds and when the pelvis first went below :data:`FALLEN_M` (s from
    ``t_off``)."""
    dt = room.model.opt.timestep
    fell_at, i = None, 0
    while i * dt < plan.duration:
        data.ctrl[room.agent_ctrl] = plan.control(i * dt, data)
        mujoco.mj_step(room.model, data)
        if i % 50 == 0:
            path.append(data.qpos[room.agent_qpos][:2].copy())
            if fell_at is None and data.qpos[room.agent_qpos][2] < FALLEN_M:
                fell_at = t_off + i * dt
        i += 1
    return i * dt, fell_at


def _run(gait: str, start: tuple[float, float], yaw: float, goal: tuple[float, float],
         scenario: Scenario | str = "discomfort", lib: Library | None = None
         ) -> dict[str, Any]:
    room = Room(scenario)
    data = standing_agent(room, np.array(start), yaw)
    goal_a = np.array(goal)
    heading = float(np.arctan2(*(goal_a - start)[::-1]))
    path: list = []
    extra: dict[str, Any] = {}
    t0, c0 = time.perf_counter(), time.process_time()
    sim, fell_at, turn = 0.0, None, None
    if gait == "turn+mocap" and abs(wrap_angle(heading - yaw)) > np.deg2rad(ALIGN_DEG):
        turn = plan_walk(room, data, np.array(start), heading)  # on the spot
        sim, fell_at = _play(room, data, turn, path, 0.0)
        extra["turn_s"] = sim
        if turn.feedback.fallen():
            extra["fell_in"] = "turn"
            plan: Any = turn
    if gait.startswith("person"):
        plan = plan_person_walk(room, data, goal_a, heading, lib,
                                stop=CLOSE_STOP if gait == "person+close" else None)
        more, fell_at = _play(room, data, plan, path, 0.0)
        sim = more
        extra["stages"] = [[n, round(t0, 2), round(p.duration, 2)] for n, t0, p in plan.stages]
        extra["played"] = [x for n, _, p in plan.stages
                           for x in (p.names if n == "mocap" else [f"{n} {p.duration:.1f} s"])]
        if plan.refused:
            extra["correction_refused"] = plan.refused
    elif extra.get("fell_in") == "turn":
        more = 0.0
    elif "mocap" in gait:
        plan = plan_mocap_walk(room, data, goal_a, lib)
        extra["planned"] = list(plan.names)
    else:
        plan = plan_walk(room, data, goal_a, heading)
        extra["steps"] = len(plan.steps)
    if "fell_in" not in extra and not gait.startswith("person"):
        more, fell1 = _play(room, data, plan, path, sim)
        sim += more
        fell_at = fell_at if fell_at is not None else fell1
    out = plan.feedback.outcome(data)
    help_max = plan.feedback.summary()["max_n"]
    if turn is not None:
        help_max = max(help_max, turn.feedback.summary()["max_n"])
    if "mocap" in gait and "planned" in extra:
        extra["seams"] = [[round(float(x), 3) if isinstance(x, float) else x for x in s]
                          for s in plan.seams]
        extra["played"] = plan.names  # the tail re-chosen at the seams
        if fell_at is not None:
            extra["fell_in"] = [s[1] for s in plan.seams if s[0] <= fell_at - (sim - more)
                                ][-1]
        extra["walk_s"], extra["walk_goal_error_m"] = more, out["goal_error_m"]
    if gait == "mocap+step" and not out["fell"] and out["goal_error_m"] > CORRECT_M:
        try:
            fix = plan_walk(room, data, goal_a, heading)
        except SimenvError as exc:  # the walk's stance in stride: out of the gait's reach
            fix, extra["correction_refused"] = None, str(exc)
    else:
        fix = None
    if fix is not None:
        more, fell2 = _play(room, data, fix, path, sim)
        sim += more
        fell_at = fell_at if fell_at is not None else fell2
        out = fix.feedback.outcome(data)
        out["fell"] = out["fell"] or plan.feedback.fallen()
        out["lowest_pelvis_m"] = min(out["lowest_pelvis_m"], plan.feedback.lowest_m)
        help_max = max(help_max, fix.feedback.summary()["max_n"])
        extra["correction_s"], extra["correction_steps"] = more, len(fix.steps)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    path_a = np.array([*path, data.qpos[room.agent_qpos][:2].copy()])
    dist = float(np.linalg.norm(np.diff(path_a, axis=0), axis=1).sum())
    net = float(np.linalg.norm(path_a[-1] - path_a[0]))
    return {"gait": gait, "simulated_s": sim, "wall_s": wall,
            "cost_x_real_time": wall / sim, "cpu_s": cpu, "cpu_x_real_time": cpu / sim,
            "distance_m": dist,
            "path_speed_mps": dist / sim, "net_m": net,
            "net_speed_mps": net / sim, **out, "fell_at_s": fell_at,
            "help_max_n": help_max, **extra}


def _walks(names: list[str]) -> list[tuple[str, tuple, float, tuple, Scenario | str]]:
    out: list[tuple[str, tuple, float, tuple, Scenario | str]] = []
    for name in names:
        if name == "open":
            sc = open_floor()
            out += [(f"open {dx:+.1f} {dy:+.1f}", OPEN_START, OPEN_YAW,
                     (OPEN_START[0] + dx, OPEN_START[1] + dy), sc) for dx, dy in OPEN_GOALS]
        else:
            out.append((name, *WALKS[name], "discomfort"))
    return out


#: The generated table's markers in docs/room.md.
BEGIN, END = "<!-- mocap-walk:begin (benchmarks/bench_mocap_walk.py) -->", "<!-- mocap-walk:end -->"


def table(rows: list[dict[str, Any]]) -> str:
    """The rows as a markdown table (one line per walk and gait)."""
    head = ("| walk | gait | simulated s | CPU / simulated | fell | from the goal m | net m/s | "
            "path m/s | help max N | pieces played |")
    lines = [head, "| " + " | ".join(["---"] * 10) + " |"]
    for r in rows:
        played = " ".join(r.get("played", [])) or f"{r.get('steps', '')} steps"
        if r.get("correction_s"):
            played += f"; stepping correction {r['correction_s']:.1f} s"
        if r.get("correction_refused"):
            why = r["correction_refused"].split("): ", 1)[-1].split(": ", 1)[-1]
            played += f"; correction refused ({why})"
        if r.get("fell_in"):
            played += f"; fell in {r['fell_in']}"
        lines.append(f"| {r['walk']} | {r['gait']} | {r['simulated_s']:.1f} | "
                     f"{r.get('cpu_x_real_time', r['cost_x_real_time']):.2f} | {r['fell']} | "
                     f"{r['goal_error_m']:.2f} | "
                     f"{r['net_speed_mps']:.2f} | {r['path_speed_mps']:.2f} | "
                     f"{r['help_max_n']:.0f} | {played} |")
    return "\n".join(lines)


def write_docs(path: Path, rows: list[dict[str, Any]], command: str) -> None:
    """Replace the text between :data:`BEGIN` and :data:`END` in ``path`` with the table."""
    text = path.read_text()
    a, b = text.index(BEGIN) + len(BEGIN), text.index(END)
    body = (f"\n\nGenerated by `{command}` (1 thread, shared machine under load; CPU "
            f"seconds of the walk's process per simulated second).\n\n{table(rows)}\n\n")
    path.write_text(text[:a] + body + text[b:])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/bench_mocap_walk"))
    parser.add_argument("--gaits", nargs="*",
                        default=["mocap", "turn+mocap", "mocap+step", "stepping"],
                        choices=["mocap", "turn+mocap", "mocap+step", "person", "person+close",
                                 "stepping"],
                        help="which gaits (the stepping gait takes minutes a walk)")
    parser.add_argument("--walks", nargs="*", default=[*WALKS, "open"],
                        help=f"names among {list(WALKS)} and 'open' (the open-floor goals)")
    parser.add_argument("--library", type=Path, default=None,
                        help="the primitives' file (default: the bundled one)")
    parser.add_argument("--rows", nargs="*", type=Path, default=[],
                        help="earlier runs' JSON rows to table with this run's")
    parser.add_argument("--docs", type=Path, default=None,
                        help="write the table into this file (docs/room.md) between its "
                        "markers")
    args = parser.parse_args()
    lib = None if args.library is None else load_library(str(args.library))
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name, start, yaw, goal, scenario in _walks(args.walks):
        for gait in args.gaits:
            row = {"walk": name, **_run(gait, start, yaw, goal, scenario, lib)}
            rows.append(row)
            print(json.dumps(row, default=str), flush=True)
            (args.out / f"bench_mocap_walk_{'_'.join(args.gaits)}.json").write_text(
                json.dumps(rows, indent=1, default=str))
    if args.docs is not None:
        for f in args.rows:
            rows += json.loads(f.read_text())
        order = {w[0]: i for i, w in enumerate(_walks([*WALKS, "open"]))}
        rows.sort(key=lambda r: (order.get(r["walk"], len(order)), r["gait"]))
        write_docs(args.docs, rows, "python " + " ".join(sys.argv))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

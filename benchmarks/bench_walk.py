"""Measure the room's agent walking on its own legs and write the walking section of
docs/room.md.

Runs (no rendering, 1 thread):

* open-floor walks in the discomfort room from a standing rest pose at (-0.4, 0.3) facing
  north (:mod:`simenv.agents.walk`): straight 0.4 m and 1.2 m, and a quarter turn on the
  spot followed by 0.6 m;
* the rehearsals of ``cold`` (``close_window``) and ``bright`` (``close_curtain``) on the
  bundled CMU walk's first 0.5 s (:func:`simenv.rehearsal.rehearse`, the ``labels``
  agent): every stage's record (duration, outcome: fell / lowest pelvis / distance from
  the goal / success, external help), the help on every ``log.jsonl`` line, and the cost
  as wall time over simulated time.

Usage::

    python benchmarks/bench_walk.py --out out/bench_walk [--docs docs/room.md]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

BEGIN = "<!-- walking:begin (benchmarks/bench_walk.py) -->"
END = "<!-- walking:end -->"
OPEN = np.array([-0.4, 0.3])
#: The room's physics step, s (``Room.model.opt.timestep``).
TIMESTEP_S = 0.002
NORTH = np.pi / 2


def _standing_in_the_open() -> tuple[Any, mujoco.MjData]:
    from simenv.agents.gait import stand_balance
    from simenv.agents.reach import PDPlan, PDTrajectory, pd_targets, upper_body_joints
    from simenv.room import Room

    room = Room("discomfort")
    h = room.agent
    data = room.make_data()
    q = h.default_qpos()
    q[:2] = OPEN
    q[3:7] = [np.cos(NORTH / 2), 0.0, 0.0, np.sin(NORTH / 2)]
    data.qpos[room.agent_qpos] = q
    targets = pd_targets(h, q, upper_body_joints(h))
    data.ctrl[room.agent_ctrl] = targets
    mujoco.mj_forward(room.model, data)
    _play(room, data, PDPlan([PDTrajectory(targets, targets, 1.0)],
                             feedback=stand_balance(room, data, 1.0)))
    return room, data


def _play(room: Any, data: mujoco.MjData, plan: Any) -> float:
    """Play ``plan``; wall seconds."""
    t0 = time.perf_counter()
    dt = room.model.opt.timestep
    for i in range(int(round(plan.duration / dt))):
        data.ctrl[room.agent_ctrl] = plan.control(i * dt, data)
        mujoco.mj_step(room.model, data)
    return time.perf_counter() - t0


def open_floor() -> list[dict[str, Any]]:
    """The open-floor walks (module docstring)."""
    from simenv.agents.walk import plan_walk

    rows = []
    for name, goal, yaw, start in (("straight 0.4 m", OPEN + [0.0, 0.4], NORTH, None),
                                   ("straight 1.2 m", OPEN + [0.0, 1.2], NORTH, None),
                                   ("quarter turn, then 0.6 m west", OPEN + [-0.6, 0.0],
                                    np.pi, np.pi)):
        room, data = _standing_in_the_open()
        plan = plan_walk(room, data, goal, yaw, start_yaw=start)
        wall = _play(room, data, plan)
        a = plan.feedback.summary()
        rows.append({"walk": name, "steps": len(plan.steps), "duration_s": plan.duration,
                     "wall_s": wall, **plan.feedback.outcome(data), "help_max_n": a["max_n"]})
        print(json.dumps(rows[-1]), flush=True)
    return rows


def chains(out: Path) -> list[dict[str, Any]]:
    """The ``cold`` and ``bright`` rehearsals (module docstring)."""
    import simenv
    from simenv.assets import WALK, asset_path
    from simenv.rehearsal import rehearse
    from simenv.session import GestureEvent, Session

    short = simenv.load(asset_path(WALK)).slice(0, 60)
    rows = []
    for label in ("cold", "bright"):
        session = Session(short, (GestureEvent(label, 0.2, 0.5),))
        t0 = time.perf_counter()
        summary = rehearse(session, out / label, scenario="discomfort", agent="labels",
                           render=False)
        wall = time.perf_counter() - t0
        lines = [json.loads(x) for x in (out / label / "log.jsonl").read_text().splitlines()]
        (reaction,) = summary["reactions"]
        rows.append({
            "label": label, "reaction": reaction["reaction"], "success": reaction["success"],
            "fell": reaction.get("fell", False), "failed_stage": reaction.get("failed_stage"),
            "returned": reaction.get("returned"),
            "stages": [{k: s.get(k) for k in ("stage", "duration_s", "pelvis_end", "outcome")}
                       | {"help_max_n": (s.get("assistance") or {}).get("max_n"),
                          "grasp_max_n": (s.get("assistance") or {}).get("grasp_max_n"),
                          # measured stages run until they end or their body falls
                          "ran_s": (s["assistance"]["steps"] * TIMESTEP_S
                                    if "assistance" in s else s["duration_s"])}
                       for s in reaction["stages"]],
            "log_lines": len(lines),
            "log_assistance_bw_max": max(x["assistance_bw"] for x in lines),
            "simulated_s": summary["duration_s"], "wall_s": wall,
            "loop_s": summary["timing_s"]["loop"]})
        print(json.dumps(rows[-1], default=str), flush=True)
    return rows


def _section(walks: list[dict[str, Any]], runs: list[dict[str, Any]], command: str) -> str:
    lines = [BEGIN, "", "### Walking on its own legs: measured", "",
             f"Generated by `{command}` (1 thread, shared machine; wall times are noisy).",
             "", "Open floor (discomfort room, standing rest pose at (-0.4, 0.3) facing north):",
             "", "| walk | steps | simulated s | wall s | fell | lowest pelvis m | "
             "from the goal m | help max N |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for w in walks:
        err = "-" if w["goal_error_m"] is None else f"{w['goal_error_m']:.3f}"
        lines.append(f"| {w['walk']} | {w['steps']} | {w['duration_s']:.1f} | "
                     f"{w['wall_s']:.1f} | {w['fell']} | {w['lowest_pelvis_m']:.3f} | {err} | "
                     f"{w['help_max_n']:.1f} |")
    lines += ["", "Rehearsals (bundled CMU 02_01 walk's first 0.5 s, labelled 0.2-0.5 s, "
              "`labels` agent):", "",
              "| label | reaction | stage | planned s | ran s | fell | lowest pelvis m | "
              "from the goal m | help max N | grasp max N |",
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    def num(v: Any) -> str:
        return "-" if v is None else f"{v:.3f}" if isinstance(v, float) else str(v)

    for r in runs:
        for s in r["stages"]:
            o = s["outcome"] or {}
            lines.append(f"| {r['label']} | {r['reaction']} | {s['stage']} | "
                         f"{s['duration_s']:.1f} | {s['ran_s']:.1f} | {num(o.get('fell'))} | "
                         f"{num(o.get('lowest_pelvis_m'))} | {num(o.get('goal_error_m'))} | "
                         f"{num(s['help_max_n'])} | {num(s.get('grasp_max_n'))} |")
    lines += ["", "(grasp: the largest force of a closed proximity grasp on the hand, N -- holding "
              "a handle, not help; with every grasp refused the standing acts keep their "
              "balance the same, measured.)", "",
              "| label | object changed (success) | fell | failed stage | returned | "
              "log.jsonl lines | max assistance_bw | simulated s | loop wall s | cost "
              "(wall / simulated) |",
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in runs:
        lines.append(f"| {r['label']} | {r['success']} | {r['fell']} | "
                     f"{r['failed_stage'] or '-'} | {r['returned']} | {r['log_lines']} | "
                     f"{r['log_assistance_bw_max']:.3g} | {r['simulated_s']:.1f} | "
                     f"{r['loop_s']:.1f} | {r['loop_s'] / r['simulated_s']:.2f}x |")
    lines += ["", END]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/bench_walk"))
    parser.add_argument("--docs", type=Path, default=Path("docs/room.md"))
    parser.add_argument("--skip-open", action="store_true",
                        help="only the rehearsals (the open-floor rows of the last run kept)")
    parser.add_argument("--from-json", action="store_true",
                        help="rewrite the section from OUT/bench_walk.json, running nothing")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    stored = args.out / "bench_walk.json"
    if args.from_json:
        measured = json.loads(stored.read_text())
        walks, runs = measured["open_floor"], measured["rehearsals"]
    else:
        # --skip-open keeps the open-floor rows of the last run
        walks = (json.loads(stored.read_text())["open_floor"] if stored.exists() else []) \
            if args.skip_open else open_floor()
        runs = chains(args.out)
        stored.write_text(json.dumps({"open_floor": walks, "rehearsals": runs}, indent=1,
                                     default=str))
    section = _section(walks, runs, "python benchmarks/bench_walk.py --out "
                       f"{args.out}" + (" --skip-open" if args.skip_open else ""))
    doc = args.docs.read_text()
    if BEGIN in doc:
        head, rest = doc.split(BEGIN, 1)
        doc = head + section + rest.split(END, 1)[1]
    else:
        anchor = "## Back to the chair"
        doc = doc.replace(anchor, section + "\n\n" + anchor, 1)
    args.docs.write_text(doc)
    print(f"wrote {args.out / 'bench_walk.json'} and the walking section of {args.docs}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The shared CMU corpus's joint-level verdicts before and after a body-fit change.

Scores every real CMU clip of the shared corpus (single-person BVH and ASF/AMC, and both
people of the two-person trials) with ``simenv.score`` on the fitted body without the
physics-tracking simulation (``ScoreConfig(tracking=False)``: every retarget-based metric --
``joint_limits``, ground penetration, floating, self penetration, the inferred root residual,
balance -- and the kinematic ones) and writes one JSON line per person to
``--out`` (a rerun skips the clips already there). ``--compare BEFORE AFTER`` prints, per
person, the verdict and every metric value that moved, and the largest change of each metric.

Run the "before" side on a copy of the unchanged code (``git archive HEAD`` into a folder,
``PYTHONPATH=that folder``) and the "after" side on the changed one::

    nice -n 10 .venv/bin/python benchmarks/rest_geometry_check.py \\
        --out out/rest_geometry/after.jsonl
    .venv/bin/python benchmarks/rest_geometry_check.py --compare out/rest_geometry/before.jsonl \\
        out/rest_geometry/after.jsonl
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import simenv
from simenv.core.config import shared_data_root
from simenv.io.loader import load
from simenv.plausibility.metric import ScoreConfig

#: The scorer's body metrics on the fitted body, without the tracking simulation.
NO_TRACKING = ScoreConfig(tracking=False)


def clips(data: Path) -> list[Path]:
    """The shared CMU files: single-person BVH and AMC, then the two-person folders."""
    cmu = data / "cmu"
    return (sorted((cmu / "bvh").glob("*.bvh")) + sorted((cmu / "asf_amc").glob("*.amc"))
            + sorted(p for p in (cmu / "two_person").iterdir() if p.is_dir()))


def score_rows(path: Path) -> list[dict[str, Any]]:
    """One row per person of ``path``: verdict, score and every metric's value and pass."""
    t0 = time.process_time()
    report = simenv.score(load(path), physics=True, config=NO_TRACKING)
    rows = []
    for rec in report.to_records():
        rows.append({"clip": f"{path.parent.name}/{path.name}", "person": rec["person"],
                     "frames": rec["frames"], "verdict": rec["verdict"], "score": rec["score"],
                     "metrics": {n: {"value": m["value"], "passed": m["passed"],
                                     "details": m.get("details")}
                                 for n, m in rec["metrics"].items()},
                     "cpu_s": round(time.process_time() - t0, 1)})
    return rows


def compare(before: Path, after: Path) -> None:
    """Print what moved between two runs, and each metric's largest change."""
    def rows(p: Path) -> dict[tuple[str, Any], dict[str, Any]]:
        return {(r["clip"], r["person"]): r for r in map(json.loads, p.read_text().splitlines())}

    b, a = rows(before), rows(after)
    largest: dict[str, tuple[float, str]] = {}
    verdicts_moved = 0
    for key in sorted(b.keys() & a.keys(), key=str):
        rb, ra = b[key], a[key]
        moved = []
        for name, mb in rb["metrics"].items():
            ma = ra["metrics"].get(name, {})
            vb, va = mb.get("value"), ma.get("value")
            if isinstance(vb, float) and isinstance(va, float):
                d = va - vb
                if abs(d) > abs(largest.get(name, (0.0, ""))[0]):
                    largest[name] = (d, f"{key[0]} p{key[1]}")
                if abs(d) > 1e-6 or mb.get("passed") != ma.get("passed"):
                    moved.append(f"{name} {vb:.4g} -> {va:.4g}"
                                 + ("" if mb.get("passed") == ma.get("passed")
                                    else f" (passed {mb.get('passed')} -> {ma.get('passed')})"))
        verdicts_moved += rb["verdict"] != ra["verdict"]
        print(f"{key[0]} p{key[1]}: {rb['verdict']} {rb['score']} -> {ra['verdict']} "
              f"{ra['score']}; " + ("; ".join(moved) or "no metric moved"))
    print(f"\n{len(b.keys() & a.keys())} people compared, verdicts moved: {verdicts_moved}")
    for name, (d, where) in sorted(largest.items()):
        print(f"largest change of {name}: {d:+.4g} ({where})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=shared_data_root())
    ap.add_argument("--out", type=Path, default=Path("out/rest_geometry/after.jsonl"))
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("BEFORE", "AFTER"))
    args = ap.parse_args()
    if args.compare:
        compare(*args.compare)
        return
    args.out.parent.mkdir(parents=True, exist_ok=True)
    done = ({json.loads(line)["clip"] for line in args.out.read_text().splitlines()}
            if args.out.exists() else set())
    for path in clips(args.data):
        if f"{path.parent.name}/{path.name}" in done:
            continue
        rows = score_rows(path)
        with args.out.open("a") as fh:
            for row in rows:
                fh.write(json.dumps(row) + "\n")
        for row in rows:
            print(row["clip"], row["person"], row["frames"], row["verdict"], row["score"],
                  row["metrics"]["joint_limits"]["value"], row["cpu_s"], flush=True)


if __name__ == "__main__":
    main()

"""Detection table: which plausibility metric catches which corruption, how often.

Applies every corruption of :data:`simenv.plausibility.corrupt.CORRUPTIONS` at several
strengths and seeds to every real single-person CMU clip of the shared
corpus (``cmu/bvh/*.bvh`` and ``cmu/asf_amc/*.amc``, full length), scores
each result and the uncorrupted clips, and prints and writes a Markdown
table (default ``docs/detection.md``):

* per corruption and strength: the detection rate of its target metric(s)
  (over the clips whose *uncorrupted* version passes the target, so a clip
  that already fails it does not count as a detection), the rate at which
  any metric flags the clip, and each metric's flag rate;
* per metric: the false-positive rate on the uncorrupted clips.

A second, smaller table scores a few clips (first 3 s) at the moderate
strength and the one below it with ``physics=True``: body-level ground and
floating on the retargeted humanoid's geoms, joint limits, self-penetration,
inverse-dynamics root residual and balance, and PD physics tracking.

Scoring uses ``simenv.score(motion, physics=False)`` (verdict = flagged)
when it exists, else the joint-level metrics of
:func:`simenv.plausibility.kinematic_metrics` (flagged = a metric fails).
Nothing in the output is edited by hand.

Usage::

    .venv/bin/python benchmarks/detection_table.py [--data DIR] [--seeds N]
        [--physics-clips N] [--out FILE.md]
"""

from __future__ import annotations

import argparse
import platform
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
from tqdm import tqdm

import simenv
from simenv.core.config import shared_data_root
from simenv.core.motion import Motion
from simenv.io import asf_amc, bvh
from simenv.plausibility import kinematic_metrics
from simenv.plausibility.corrupt import CORRUPTIONS, STRENGTH_UNITS

REPO = Path(__file__).resolve().parent.parent
DEFAULT_DATA = shared_data_root()

#: Strengths per corruption (unit: STRENGTH_UNITS), weakest first; each
#: list contains the registry's moderate strength.
STRENGTHS: dict[str, tuple[float, ...]] = {
    "foot_slide": (0.25, 0.5, 1.0, 2.0),
    "bone_stretch": (0.03, 0.06, 0.10, 0.20),
    "sink": (3.0, 6.0, 10.0, 15.0),
    "float": (5.0, 10.0, 15.0, 30.0),
    "jitter": (0.2, 0.5, 1.0, 2.0),
    "teleport": (0.05, 0.1, 0.3, 0.6),
    "time_warp": (2.0, 4.0, 10.0, 16.0),
}

#: Clips of the smaller physics=True table (diverse: walk, jumps, kata,
#: dance, run) and the frames kept of each.
PHYSICS_CLIPS = ("bvh/02_01.bvh", "bvh/49_02.bvh", "asf_amc/135_06.amc", "bvh/05_02.bvh",
                 "asf_amc/09_06.amc")
PHYSICS_FRAMES = 360

#: (metric name -> passed or None when not available).
Verdicts = dict[str, bool | None]


def single_person_clips(data: Path) -> list[Path]:
    """The real single-person CMU clips of the corpus, BVH then AMC."""
    cmu = data / "cmu"
    return sorted((cmu / "bvh").glob("*.bvh")) + sorted((cmu / "asf_amc").glob("*.amc"))


def load(path: Path) -> Motion:
    return bvh.read(path) if path.suffix == ".bvh" else asf_amc.read(path)


def scorer(physics: bool) -> tuple[str, Callable[[Motion], tuple[bool, Verdicts]]]:
    """The scoring function and its description: ``simenv.score`` when it
    exists, else (kinematic table only) the joint-level metrics."""
    score = getattr(simenv, "score", None)
    if score is not None:
        def by_report(motion: Motion) -> tuple[bool, Verdicts]:
            person = score(motion, physics=physics).people[0]
            verdicts = {n: r.passed for n, r in person.metrics.items()}
            return person.verdict == "implausible", verdicts
        return (f"`simenv.score(motion, physics={physics})` (flagged = verdict "
                "`implausible`)"), by_report
    if physics:
        raise SystemExit("simenv.score is not available: cannot run the physics table")

    def by_metrics(motion: Motion) -> tuple[bool, Verdicts]:
        verdicts = {n: r.passed for n, r in kinematic_metrics(motion).items()}
        return any(v is False for v in verdicts.values()), verdicts
    return ("`simenv.plausibility.kinematic_metrics(motion)` (flagged = any metric fails; "
            "`simenv.score` had not landed)"), by_metrics


@dataclass
class Cell:
    """Outcomes of one corruption at one strength over clips and seeds."""

    runs: int = 0
    flagged: int = 0
    target_runs: int = 0  # runs on clips whose clean version passes the target
    target_hits: int = 0
    by_metric: dict[str, int] = field(default_factory=dict)
    misses: list[str] = field(default_factory=list)  # "clip#seed" the target missed
    errors: list[str] = field(default_factory=list)


def run(motions: dict[str, Motion], strengths: dict[str, tuple[float, ...]], seeds: int,
        score: Callable[[Motion], tuple[bool, Verdicts]], desc: str
        ) -> tuple[dict, dict, list[str]]:
    """Score the clean and the corrupted clips.

    Returns:
        (clean: clip -> (flagged, verdicts), cells: (corruption, strength) ->
        Cell, metric names in first-seen order).
    """
    clean = {}
    for clip, motion in tqdm(motions.items(), desc=f"{desc}: clean", unit="clip"):
        clean[clip] = score(motion)
    metrics = list(next(iter(clean.values()))[1])
    jobs = [(name, s, clip, seed) for name in CORRUPTIONS for s in strengths[name]
            for clip in motions for seed in range(seeds)]
    cells: dict[tuple[str, float], Cell] = {}
    with tqdm(total=len(jobs), desc=f"{desc}: corrupted", unit="clip") as bar:
        for name, strength, clip, seed in jobs:
            bar.set_postfix_str(f"{name} {strength:g}", refresh=False)
            cell = cells.setdefault((name, strength), Cell())
            entry = CORRUPTIONS[name]
            try:
                corrupted = entry.fn(motions[clip], strength, seed=seed)
            except simenv.SimenvError as exc:  # e.g. a clip too short for the warp
                cell.errors.append(f"{clip} seed {seed}: {exc.detail}")
                bar.update()
                continue
            flagged, verdicts = score(corrupted)
            cell.runs += 1
            cell.flagged += flagged
            for metric, passed in verdicts.items():
                if metric not in metrics:
                    metrics.append(metric)
                cell.by_metric[metric] = cell.by_metric.get(metric, 0) + (passed is False)
            if all(clean[clip][1].get(t) is not False for t in entry.targets):
                cell.target_runs += 1
                hit = any(verdicts.get(t) is False for t in entry.targets)
                cell.target_hits += hit
                if not hit:
                    cell.misses.append(f"{clip}#{seed}")
            bar.update()
    return clean, cells, metrics


def pct(num: int, den: int) -> str:
    return "n/a" if den == 0 else f"{100.0 * num / den:.0f} %"


def below_and_moderate(name: str) -> tuple[float, ...]:
    """The moderate strength of ``name`` and the next weaker one of STRENGTHS."""
    moderate = CORRUPTIONS[name].moderate
    weaker = [s for s in STRENGTHS[name] if s < moderate]
    return (*weaker[-1:], moderate)


def tables(clean: dict, cells: dict, metrics: list[str],
           strengths: dict[str, tuple[float, ...]]) -> list[str]:
    """Markdown lines: the detection table, then the false positives."""
    lines = [
        "| corruption | strength | target metric | target detected | flagged (any) "
        "| failing metrics |",
        "|---|---|---|---|---|---|",
    ]
    for name, entry in CORRUPTIONS.items():
        for strength in strengths[name]:
            cell = cells[(name, strength)]
            failing = sorted(((m, k) for m, k in cell.by_metric.items() if k), key=lambda x: -x[1])
            cause = ", ".join(f"{m} {pct(k, cell.runs)}" for m, k in failing) or "none"
            mark = " (moderate)" if np.isclose(strength, entry.moderate) else ""
            lines.append(
                f"| {name} | {strength:g} {STRENGTH_UNITS[name]}{mark} | "
                f"{', '.join(entry.targets)} | {pct(cell.target_hits, cell.target_runs)} "
                f"({cell.target_hits}/{cell.target_runs}) | {pct(cell.flagged, cell.runs)} | "
                f"{cause} |"
            )
    missed = [(name, s, c.misses) for (name, s), c in cells.items()
              if c.misses and np.isclose(s, CORRUPTIONS[name].moderate)]
    lines += ["", "Not caught by the target metric at the moderate strength (clip#seed): "
              + ("; ".join(f"{name} {s:g} {STRENGTH_UNITS[name]}: {', '.join(m)}"
                           for name, s, m in missed) or "none") + "."]
    errors = [(k, e) for k, c in cells.items() for e in c.errors]
    if errors:
        lines += ["", "Runs that could not be corrupted (not counted):", ""]
        lines += [f"* {name} {s:g}: {e}" for (name, s), e in errors]
    lines += [
        "",
        "False positives on the uncorrupted clips:",
        "",
        "| metric | clips failing | rate | which |",
        "|---|---|---|---|",
    ]
    never = [m for m in metrics if all(v.get(m) is None for _, v in clean.values())]
    for metric in metrics:
        if metric in never:
            continue
        failing = [c for c, (_, v) in clean.items() if v.get(metric) is False]
        na = sum(v.get(metric) is None for _, v in clean.values())
        which = ", ".join(failing) or "-"
        if na:
            which += f" (not available on {na})"
        lines.append(f"| {metric} | {len(failing)}/{len(clean)} | "
                     f"{pct(len(failing), len(clean))} | {which} |")
    flagged = [c for c, (f, _) in clean.items() if f]
    lines.append(f"| **any (verdict)** | {len(flagged)}/{len(clean)} | "
                 f"{pct(len(flagged), len(clean))} | {', '.join(flagged) or '-'} |")
    if never:
        lines += ["", f"Not available in this mode (no verdict): {', '.join(never)}."]
    return lines


def header(seconds: float) -> list[str]:
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, cwd=REPO).stdout.strip() or "unknown"
    now = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    command = " ".join([".venv/bin/python", "benchmarks/detection_table.py", *sys.argv[1:]])
    return [
        "# Corruption detection table",
        "",
        f"Generated by `{command}` on {now} at commit `{commit}` (Python "
        f"{platform.python_version()}, {seconds:.0f} s). Do not edit by hand: rerun the "
        "script. Corruptions: `simenv/plausibility/corrupt.py` (units and targets in the "
        "docstrings).",
        "",
        "* **target detected**: share of runs in which a target metric of the corruption fails, "
        "over the clips whose uncorrupted version passes that metric (a clip that already "
        "fails it cannot show a detection).",
        "* **flagged (any)**: share of all runs flagged by the verdict (includes clips flagged "
        "uncorrupted, see the false positives).",
        "* **failing metrics**: every metric that fails in at least one run, with its rate over "
        "all runs.",
        "* **(moderate)** marks the registry's moderate strength, which `tests/test_corrupt.py` "
        "requires to be caught.",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--seeds", type=int, default=3, help="seeds per clip and strength")
    parser.add_argument("--physics-clips", type=int, default=len(PHYSICS_CLIPS),
                        help="clips of the physics=True table (0: skip it)")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "detection.md")
    args = parser.parse_args()
    paths = single_person_clips(args.data)
    if not paths:
        raise SystemExit(f"no CMU clips under {args.data}/cmu")
    start = time.perf_counter()
    motions = {f"{p.parent.name}/{p.name}": load(p) for p in paths}
    frames = sum(m.num_frames for m in motions.values())
    how, score = scorer(physics=False)
    kinematic = run(motions, STRENGTHS, args.seeds, score, "kinematic")
    body = [
        "",
        "## Joint-level metrics, all clips",
        "",
        f"The {len(motions)} real single-person CMU clips of the shared corpus "
        f"(`cmu/bvh/*.bvh`, `cmu/asf_amc/*.amc`, full length, {frames} frames at 120 fps); "
        f"every corruption at every strength with seeds 0-{args.seeds - 1} on every clip; "
        f"scoring: {how}.",
        "",
        *tables(*kinematic, STRENGTHS),
    ]
    if args.physics_clips > 0:
        chosen = {c: motions[c].slice(0, PHYSICS_FRAMES)
                  for c in PHYSICS_CLIPS[: args.physics_clips]}
        how, score = scorer(physics=True)
        strengths = {n: below_and_moderate(n) for n in CORRUPTIONS}
        physics = run(chosen, strengths, 1, score, "physics")
        body += [
            "",
            "## With the body-level metrics (physics=True), a subset",
            "",
            f"{len(chosen)} clips ({', '.join(chosen)}), first {PHYSICS_FRAMES} frames "
            f"({PHYSICS_FRAMES / 120:g} s) each, seed 0, the moderate strength and the one "
            "below it; scoring: "
            f"{how}. Here `ground_penetration` and `floating` are measured on the retargeted "
            "body's geoms, and the retargeting, inverse-dynamics and physics-tracking metrics "
            "are added.",
            "",
            *tables(*physics, strengths),
        ]
    text = "\n".join([*header(time.perf_counter() - start), *body, ""])
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

"""Real HumanML3D clips (AMASS motion) judged by the default command (physics on).

Issue 33's goal: "real HumanML3D / AMASS clips: >= 95 % plausible" with physics on, by the
default command, and their seeded corruptions still caught. Every clip of :data:`CLIPS` (the
real clips of ``tests/data/humanml3d``, see its SOURCES.md; none generated) is read by
:func:`simenv.io.loader.load`, cut to its first ``--max-seconds`` and scored by
:func:`simenv.score` with the settings of ``simenv score FILE`` (``physics=True``, default
planner and thresholds, ``source="auto"``). Then :data:`CORRUPTED` seeded corruptions of it
(:data:`simenv.plausibility.corrupt.CORRUPTIONS` at their moderate strength, seed = the
clip's position in :data:`CLIPS`) are scored joint-level only (``physics=False``: each targets
a joint-level metric) and counted as caught when their target metric fails.

One JSON line per clip or corrupted copy goes to ``out/humanml3d/results.jsonl`` as it
finishes (a rerun skips the keys already there); the markdown table is written between the
markers of docs/plausibility.md.

``--before FILE`` (a JSONL of an earlier run, e.g. before a change to the body fit) adds the
earlier count and the real clips whose verdict or score moved. ``--carry FILE`` fills in the
rows of clips this run has not rescored from an earlier run, and the docs name them.

Roles. :data:`CLIPS` is the **development** set: every one of its clips has been diagnosed
on. :data:`HELD_OUT` is the **held-out** set, fixed (and committed) before any of its clips
was loaded or scored, and scored once, after the fixes (``--role heldout``); its table
reports that first scoring. Its files are read from fetched GitHub snapshots under
``/work/.mirror`` (``git show COMMIT:PATH`` into ``--extract-to``, /tmp by default): AMASS
motion is not redistributable, so they are never copied into the repository.

Usage (about 1-3 min of CPU per 6-s clip; niced, one process)::

    nice -n 10 .venv/bin/python benchmarks/humanml3d_survey.py
    nice -n 10 .venv/bin/python benchmarks/humanml3d_survey.py --role heldout
    .venv/bin/python benchmarks/humanml3d_survey.py --docs-only \\
        --before out/humanml3d/results_before.jsonl
"""

from __future__ import annotations

import argparse
import json
import subprocess
import time
from pathlib import Path
from typing import Any

from doc_sections import replace_section
from result_rows import read_rows

import simenv  # noqa: F401  (MUJOCO_GL before mujoco)
from simenv.core.errors import SimenvError
from simenv.core.motion import Motion
from simenv.io.loader import load
from simenv.plausibility.corrupt import CORRUPTIONS, STRENGTH_UNITS

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "humanml3d"
OUT = ROOT / "out" / "humanml3d"
DOC = ROOT / "docs" / "plausibility.md"
BEGIN, END = "<!-- humanml3d-survey:begin -->", "<!-- humanml3d-survey:end -->"

#: key -> (path under tests/data/humanml3d, AMASS source and frames per HumanML3D index.csv).
CLIPS: dict[str, tuple[str, str]] = {
    "012314": ("new_joints/012314.npy",
               "Eyes_Japan_Dataset/yamaoka/tennis-15-first service, 149-320"),
    "000612": ("new_joint_vecs/000612.npy",
               "Eyes_Japan_Dataset/hamada/walk-16-push by hand, 12-212"),
    "007005": ("new_joints/007005.npy", "KIT/424/step_stones04, 3-203"),
    "009548": ("new_joints/009548.npy",
               "Eyes_Japan_Dataset/hamada/turn-02-look around, 110-310"),
    "011673": ("new_joints/011673.npy",
               "Eyes_Japan_Dataset/aita/sitdown_standup-08-long sitting, 162-362"),
    "M010655": ("new_joints/M010655.npy",
                "BioMotionLab_NTroje/rub051/0017_lifting_light1, 0-129 (mirrored)"),
    "M010968": ("new_joints/M010968.npy",
                "BMLmovi/Subject_88_F_MoSh/Subject_88_F_14, 0-71 (mirrored)"),
    "000021": ("joints22/000021.npy", "KIT/4/WalkInCounterClockwiseCircle02, 0-180 (raw joints)"),
}

#: Held-out real clips: key -> (snapshot folder under /work/.mirror, commit, path in the
#: repository, AMASS source and frames per HumanML3D's index.csv). Chosen before any was read.
#: The search (stored-code index: every HumanML3D fork's and MDM / MoMask / priorMDM fork's
#: ``.npy`` files, ``new_joints`` / ``new_joint_vecs`` paths; snapshots of the forks the
#: index lists) found one real clip not in :data:`CLIPS`: the official ``000000`` of the
#: HumanML3D author's second repository (``syeon-yoo/priorMDM``'s ``000000`` / ``000002``
#: features have no snapshot here). Its ``new_joint_vecs`` twin is the same motion.
HELD_OUT: dict[str, tuple[str, str, str, str]] = {
    "000000": ("EricGuoICT+HumanML3D", "46853f48a8dc00e0c98e57a3ccd6f9128c9124d0",
               "HumanML3D/new_joints/000000.npy", "KIT/3/kick_high_left02, 0-117"),
}

#: Corruptions scored per clip: one per joint-level family the issue names.
CORRUPTED = ("foot_slide", "jitter", "sink")


MIRROR = Path("/work/.mirror")


def clip_path(key: str, extract_to: Path) -> Path:
    """The file of clip ``key``: under tests/data/humanml3d for the development set, or
    read from its snapshot by ``git show`` into ``extract_to`` for the held-out set.

    Raises:
        SimenvError: the snapshot is not fetched or lacks the file.
    """
    if key in CLIPS:
        return DATA / CLIPS[key][0]
    repo, commit, blob, _ = HELD_OUT[key]
    dest = extract_to / repo / blob
    if not dest.exists():
        git_dir = MIRROR / repo / "repo"
        if not git_dir.is_dir():
            raise SimenvError(f"snapshot {repo} not under {MIRROR} (fetch github:"
                              f"{repo.replace('+', '/')})")
        out = subprocess.run(["git", "--git-dir", str(git_dir), "show", f"{commit}:{blob}"],
                             capture_output=True, check=False)
        if out.returncode:
            raise SimenvError(f"{repo} @ {commit[:7]} has no {blob}: "
                              f"{out.stderr.decode().strip()}")
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_bytes(out.stdout)
    return dest


def trimmed(motion: Motion, max_seconds: float) -> Motion:
    """The first ``max_seconds`` seconds of ``motion`` (all of it when shorter)."""
    return motion.slice(0, min(motion.num_frames, int(round(max_seconds * motion.fps))))


def _record(motion: Motion, physics: bool) -> dict[str, Any]:
    """Verdict, score, failing metrics, every metric and the violating frame runs."""
    rec = simenv.score(motion, physics=physics).to_records()[0]
    return {
        "verdict": rec["verdict"], "score": rec["score"],
        "failing": {n: {"value": m["value"], "threshold": m["threshold"], "unit": m["unit"]}
                    for n, m in rec["metrics"].items() if m["passed"] is False},
        "metrics": {n: {"value": m["value"], "threshold": m["threshold"],
                        "passed": m["passed"], "details": m.get("details")}
                    for n, m in rec["metrics"].items()},
        "violations": rec.get("violations", []),
    }


def _role(key: str) -> str:
    return "dev" if key in CLIPS else "heldout"


def _source(key: str) -> tuple[str, str]:
    """(file as the docs name it, AMASS source and frames) of clip ``key``."""
    if key in CLIPS:
        return CLIPS[key]
    repo, commit, blob, source = HELD_OUT[key]
    return f"{repo.replace('+', '/')} @ {commit[:7]} : {blob}", source


def score_clip(key: str, max_seconds: float, extract_to: Path) -> dict[str, Any]:
    """Load, trim and score one real clip (physics on, default settings).

    Returns:
        A JSON-ready row: ``key``, ``kind`` "real", ``role``, ``source``, ``seconds``
        (scored), ``source_seconds``, ``verdict``, ``score``, ``failing``, ``metrics``,
        ``violations``, ``cpu_s``; or ``error`` when the file does not load or score.
    """
    rel, source = _source(key)
    row: dict[str, Any] = {"key": key, "kind": "real", "role": _role(key), "file": rel,
                           "source": source}
    t0 = time.process_time()
    try:
        clip = load(clip_path(key, extract_to))
        motion = trimmed(clip, max_seconds)
        row |= {"seconds": round(motion.duration, 2), "source_seconds": round(clip.duration, 2)}
        row |= _record(motion, physics=True)
    except SimenvError as exc:
        row |= {"error": str(exc), "error_type": type(exc).__name__}
    row["cpu_s"] = round(time.process_time() - t0, 1)
    return row


def score_corruption(key: str, name: str, seed: int, max_seconds: float, extract_to: Path
                     ) -> dict[str, Any]:
    """One seeded corruption of clip ``key`` at its moderate strength, physics off.

    Returns:
        A JSON-ready row with ``caught`` (every target metric failed) besides the record.
    """
    spec = CORRUPTIONS[name]
    row: dict[str, Any] = {"key": f"{key}/{name}", "kind": "corrupt", "role": _role(key),
                           "clip": key, "corruption": name, "strength": spec.moderate,
                           "unit": STRENGTH_UNITS[name], "seed": seed,
                           "targets": list(spec.targets)}
    t0 = time.process_time()
    try:
        motion = trimmed(load(clip_path(key, extract_to)), max_seconds)
        row |= _record(spec.fn(motion, spec.moderate, seed=seed), physics=False)
        row["caught"] = all(row["metrics"].get(t, {}).get("passed") is False
                            for t in spec.targets)
    except SimenvError as exc:
        row |= {"error": str(exc), "error_type": type(exc).__name__, "caught": False}
    row["cpu_s"] = round(time.process_time() - t0, 1)
    return row


def _fmt(x: Any) -> str:
    return f"{x:.3g}" if isinstance(x, float) else str(x)


def _failing(row: dict[str, Any]) -> str:
    if "error" in row:
        return f"error: {row['error'][:120]}"
    return "; ".join(f"`{n}` {_fmt(f['value'])} / {_fmt(f['threshold'])} {f['unit'] or ''}"
                     .rstrip() for n, f in row["failing"].items()) or "-"


def _moved(rows: dict[str, dict[str, Any]], before: dict[str, dict[str, Any]]) -> list[str]:
    """The earlier run's plausible count and the real clips whose verdict or score moved."""
    old = [r for r in before.values() if r["kind"] == "real"]
    ok = sum(r.get("verdict") == "plausible" for r in old)
    moved = [f"`{k}` {b.get('verdict')} {_fmt(b.get('score'))} ({_failing(b)}) -> "
             f"{rows[k].get('verdict')} {_fmt(rows[k].get('score'))} ({_failing(rows[k])})"
             for k, b in sorted(before.items())
             if b["kind"] == "real" and k in rows
             and (b.get("verdict"), b.get("score")) != (rows[k].get("verdict"),
                                                        rows[k].get("score"))]
    missing = [f"`{k}` ({b.get('verdict')} {_fmt(b.get('score'))} then)"
               for k, b in sorted(before.items()) if b["kind"] == "real" and k not in rows]
    return ["", f"**Before** (`--before`, an earlier run): {ok} of {len(old)} plausible; "
            f"moved: {'; '.join(moved) or 'none'}."
            + (f" Not rescored: {', '.join(missing)}." if missing else "")]


def _clip_table(real: list[dict[str, Any]]) -> list[str]:
    """The plausible count and one table row per real clip."""
    ok = sum(r.get("verdict") == "plausible" for r in real)
    lines = [f"{ok} of {len(real)} plausible ({100 * ok / max(len(real), 1):.0f} %).", "",
             "| clip | AMASS source, frames | seconds | verdict | score | "
             "failing metrics (value / threshold) | CPU s |", "|---" * 7 + "|"]
    for r in sorted(real, key=lambda r: r["key"]):
        if "error" in r:
            lines.append(f"| {r['key']} | {r['source']} | | error | | {_failing(r)} | "
                         f"{r['cpu_s']} |")
            continue
        lines.append(f"| {r['key']} | {r['source']} | {r['seconds']} of {r['source_seconds']}"
                     f" | {r['verdict']} | {r['score']:.1f} | {_failing(r)} | "
                     f"{r['cpu_s']:.0f} |")
    return lines


def markdown(rows: dict[str, dict[str, Any]], max_seconds: float,
             before: dict[str, dict[str, Any]] | None = None) -> str:
    """The generated section: per role, the real clips' table with the plausible count
    (and, given ``before``, the earlier run's count and the development clips that moved),
    then the corruptions caught by their target metric."""
    real = [r for r in rows.values() if r["kind"] == "real"]
    bad = [r for r in rows.values() if r["kind"] == "corrupt"]
    dev = [r for r in real if r.get("role", "dev") == "dev"]
    held = [r for r in real if r.get("role") == "heldout"]
    lines = [f"Generated by `benchmarks/humanml3d_survey.py`: each real clip's first "
             f"{max_seconds:g} s, `simenv.score(..., physics=True)` (default planner, default "
             "thresholds, `source=\"auto\"`). AMASS source and frames per HumanML3D's "
             "`index.csv`; development files and licences in "
             "`tests/data/humanml3d/SOURCES.md`, held-out files named by repository, commit "
             "and path (read from the snapshot, not copied).", "",
             "**Development set** (every clip diagnosed on): " + _clip_table(dev)[0],
             *_clip_table(dev)[1:]]
    carried = sorted(r["key"] for r in dev if r.get("carried"))
    if carried:
        lines += ["", f"Rows of {', '.join(f'`{k}`' for k in carried)} (and their corruptions) "
                  "are carried from an earlier run (`--carry`), not rescored by this one."]
    if before:
        lines += _moved(rows, before)
    if held:
        table = _clip_table(held)
        lines += ["", "**Held-out set** (fixed and committed before any clip was read; scored "
                  "once, after the fixes; first scored): " + table[0], *table[1:]]
    if bad:
        caught = sum(r["caught"] for r in bad)
        lines += ["", f"**Seeded corruptions** of both sets (moderate strength, seed = clip's "
                  f"position in development then held-out order, "
                  f"physics off): {caught} of {len(bad)} caught by their target metric "
                  f"({100 * caught / len(bad):.0f} %).", "",
                  "| corruption | strength | target | caught | clips missed (target value / "
                  "threshold) |", "|---" * 5 + "|"]
        for name in CORRUPTED:
            sel = [r for r in bad if r["corruption"] == name]
            if not sel:
                continue
            missed = []
            for r in sel:
                if r["caught"]:
                    continue
                t = r["targets"][0]
                m = r.get("metrics", {}).get(t)
                missed.append(f"{r['clip']} ({_fmt(m['value'])} / {_fmt(m['threshold'])})"
                              if m else f"{r['clip']} ({r.get('error', 'n/a')[:60]})")
            lines.append(f"| {name} | {sel[0]['strength']:g} {sel[0]['unit']} | "
                         f"`{', '.join(sel[0]['targets'])}` | {sum(r['caught'] for r in sel)}"
                         f" of {len(sel)} | {'; '.join(missed) or '-'} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", nargs="*", default=None, help="clip keys to score")
    ap.add_argument("--max-seconds", type=float, default=6.0,
                    help="score each clip's first SECONDS (default 6)")
    ap.add_argument("--no-corrupt", action="store_true", help="skip the corrupted copies")
    ap.add_argument("--docs-only", action="store_true", help="only rewrite the docs table")
    ap.add_argument("--out", type=Path, default=OUT / "results.jsonl", help="results JSONL")
    ap.add_argument("--before", type=Path, default=None,
                    help="JSONL of an earlier run: list its count and the clips that moved")
    ap.add_argument("--carry", type=Path, default=None,
                    help="JSONL of an earlier run whose rows stand in for clips --out lacks "
                         "(docs only; the table says which)")
    ap.add_argument("--role", choices=("dev", "heldout"), default="dev",
                    help="the set to score (default: the development set)")
    ap.add_argument("--extract-to", type=Path, default=Path("/tmp/simenv_humanml3d_heldout"),
                    help="where held-out files are written from their snapshots")
    args = ap.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    rows = read_rows(args.out)
    if not args.docs_only:
        keys = args.only or list(CLIPS if args.role == "dev" else HELD_OUT)
        order = list(CLIPS) + list(HELD_OUT)
        jobs: list[tuple[str, Any]] = []
        for key in keys:
            jobs.append((key, lambda k=key: score_clip(k, args.max_seconds, args.extract_to)))
            if not args.no_corrupt:
                seed = order.index(key)
                jobs += [(f"{key}/{n}", lambda k=key, n=n, s=seed:
                          score_corruption(k, n, s, args.max_seconds, args.extract_to))
                         for n in CORRUPTED]
        for key, job in jobs:
            if key in rows:
                continue
            row = job()
            rows[key] = row
            with args.out.open("a") as fh:
                fh.write(json.dumps(row) + "\n")
            print(key, row.get("verdict"), row.get("score"), row.get("caught", ""),
                  _failing(row), row["cpu_s"], flush=True)
    if args.carry:
        rows |= {k: r | {"carried": True} for k, r in read_rows(args.carry).items()
                 if k not in rows}
    before = read_rows(args.before) if args.before else None
    replace_section(DOC, BEGIN, END, markdown(rows, args.max_seconds, before))


if __name__ == "__main__":
    main()

"""Unassisted tracking of every real CMU clip of the shared corpus, clean and corrupted.

For each single-person CMU clip (``cmu/bvh/*.bvh``, ``cmu/asf_amc/*.amc``;
its first ``--seconds``), retargeted onto its fitted humanoid:

* the unassisted MPC tracker (:mod:`simenv.control`, the scorer's default):
  success (PHC rule: mean body error never above 0.5 m), time to failure,
  mean and largest body error, largest 0.5 s mean of the body error, and the
  positive work of the hinge actuators (J, J/kg);
* for comparison the unassisted PD servos and the assisted PD tracker (time
  to failure, error, mean assistance force);

and, on ``--corrupt-clips`` of them, the same MPC run on corrupted copies
(:mod:`simenv.plausibility.corrupt`: float, foot slide, teleport, time warp at their
moderate strengths and a strong one), which should fail.

``--samples N`` sets the MPC's rollouts per replan (recorded in every line;
lines without it ran with 32) and ``--trunk-weight W`` the weight of its
upper-trunk orientation cost (:class:`simenv.control.CostWeights` ``trunk``,
per rad^2; recorded as ``trunk_weight``, lines without it ran with 0) and
``--retries R`` the rewinds a run may use after a failure (:class:`simenv.control.MPCConfig`
``retries``; recorded as ``retries``, lines without it ran with 0) and ``--attempts A``
the planner seeds a run may try (``attempts``; recorded as ``attempts``, lines without it
ran with 1; the further ones plan over ``MPCConfig.retry_horizon_s``, recorded as
``retry_horizon_s``, lines without it over 0.45 s) and ``--temperature T`` the MPPI
temperature (``temperature``; recorded as ``temperature``, lines without it ran with 0:
predictive sampling) and ``--planner fast`` starts from :data:`simenv.control.FAST` instead
of the default (its planning step and antithetic noise recorded as ``timestep_factor`` and
``antithetic``, lines without them ran with 2 and false; ``rollout_per_step`` is the
planner's rolled-out steps per simulated step); a *setting* is the eight of them (the
retry horizon 0 for one attempt).
``docs`` tabulates each setting apart and puts the settings side by side clip by clip.

Results go to a JSONL file one line per run as each finishes (a rerun skips
runs already there with the same setting), so the long run can go in the
background::

    nohup nice .venv/bin/python benchmarks/eval_tracking.py run --runs clean &
    nohup nice .venv/bin/python benchmarks/eval_tracking.py run --runs corrupt \
        --out out/eval_tracking_corrupt.jsonl &
    nohup nice .venv/bin/python benchmarks/eval_tracking.py run --runs clean --samples 64 \
        --out out/eval_tracking_64.jsonl &
    .venv/bin/python benchmarks/eval_tracking.py docs   # tables -> docs/plausibility.md

``docs`` writes the tables between the ``unassisted-tracking`` markers of
``docs/plausibility.md`` (``--section NAME``: the ``NAME`` markers) and leaves the rest of
the file alone. The MPPI runs of 2026-12-04 have a section of their own, as the earlier
settings' result files did not survive::

    .venv/bin/python benchmarks/eval_tracking.py run --runs clean --out out/eval_tracking_mppi.jsonl
    .venv/bin/python benchmarks/eval_tracking.py run --runs corrupt \
        --out out/eval_tracking_corrupt_mppi.jsonl
    .venv/bin/python benchmarks/eval_tracking.py docs --section unassisted-tracking-mppi \
        --results out/eval_tracking_mppi.jsonl out/eval_tracking_corrupt_mppi.jsonl
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from doc_sections import replace_section  # noqa: E402

from simenv.body.retarget import retarget  # noqa: E402
from simenv.control import FAST, CostWeights, MPCConfig  # noqa: E402
from simenv.core.config import shared_data_root  # noqa: E402
from simenv.core.motion import Motion  # noqa: E402
from simenv.io.loader import load  # noqa: E402
from simenv.plausibility.corrupt import CORRUPTIONS  # noqa: E402
from simenv.plausibility.tracking import TrackingResult, track  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATA = shared_data_root()
DEFAULT_OUT = REPO / "out" / "eval_tracking.jsonl"
DEFAULT_RESULTS = (DEFAULT_OUT, REPO / "out" / "eval_tracking_corrupt.jsonl",
                   REPO / "out" / "eval_tracking_64.jsonl",
                   REPO / "out" / "eval_tracking_corrupt_64.jsonl",
                   REPO / "out" / "eval_tracking_64_r3.jsonl",
                   REPO / "out" / "eval_tracking_corrupt_64_r3.jsonl",
                   REPO / "out" / "eval_tracking_corrupt_64_a3.jsonl")
DOCS = REPO / "docs" / "plausibility.md"
SECTION = "unassisted-tracking"

#: Clips reported apart from the success rate (the issue's "acrobatics").
ACROBATICS = ("49_06",)
#: (corruption, strength): the moderate strength of :data:`simenv.plausibility.corrupt.CORRUPTIONS`
#: and a strong one.
CORRUPT_RUNS: tuple[tuple[str, float], ...] = (
    ("float", 15.0), ("float", 50.0), ("foot_slide", 1.0), ("teleport", 0.3),
    ("teleport", 1.0), ("time_warp", 10.0),
)
#: Clips corrupted (walk, runs, dance): a subset keeps the run within an hour.
CORRUPT_CLIPS = ("02_01.bvh", "35_17.bvh", "49_04.bvh", "103_charleston1.amc")
WINDOW_S = 0.5


def clips(data: Path) -> list[Path]:
    cmu = data / "cmu"
    return sorted((cmu / "bvh").glob("*.bvh")) + sorted((cmu / "asf_amc").glob("*.amc"))


def descriptions(data: Path) -> dict[str, str]:
    out = {}
    path = data / "cmu" / "cmu_trial_descriptions.tsv"
    if path.is_file():
        for line in path.read_text().splitlines():
            parts = line.split("\t")
            if len(parts) >= 2:
                out[parts[0]] = parts[1]
    return out


def clip_motion(path: Path, seconds: float) -> Motion:
    """The clip's first ``seconds`` (its first person when it holds several)."""
    m = load(path)
    m = m[0] if isinstance(m, list) else m
    return m.slice(0, min(m.num_frames, int(round(seconds * m.fps)) + 1))


def _window_max(err: np.ndarray, fps: float) -> float:
    """Largest mean body error over WINDOW_S windows of the tracked frames, metres."""
    e = err[np.isfinite(err)]
    w = max(1, int(round(WINDOW_S * fps)))
    if len(e) < w:
        return float(e.mean()) if len(e) else float("nan")
    c = np.cumsum(np.insert(e, 0, 0.0))
    return float(((c[w:] - c[:-w]) / w).max())


def _record(tr: TrackingResult, fps: float) -> dict[str, float | bool | str | None]:
    return {"success": tr.success, "time_to_failure_s": tr.time_to_failure_s,
            "simulated_s": tr.simulated_s, "mpjpe_mm": tr.mpjpe_mm,
            "max_error_mm": float(np.nanmax(tr.body_error)) * 1000.0,
            "window_max_mm": _window_max(tr.body_error, fps) * 1000.0,
            "work_j": tr.work_j, "work_j_per_kg": tr.work_j_per_kg, "wall_s": tr.wall_s,
            "retries_used": tr.retries, "runs": tr.runs,
            "rollout_per_step": tr.rollout_steps / max(tr.steps, 1),
            "realtime_ratio": tr.wall_s / max(tr.steps * 0.002, 1e-9), "error": tr.error}


#: An MPC setting of a run: (samples per replan, trunk cost weight per rad^2, retries,
#: attempts, MPPI temperature, horizon of the further attempts in s (0: one attempt),
#: planning step as a multiple of the physics step, antithetic noise).
Setting = tuple[int, float, int, int, float, float, int, bool]


def setting_of_config(cfg: MPCConfig) -> Setting:
    """The setting an :class:`MPCConfig` runs with."""
    retry = cfg.attempt(1).horizon_s if cfg.attempts > 1 else 0.0
    return (cfg.n_samples, cfg.weights.trunk, cfg.retries, cfg.attempts, cfg.temperature, retry,
            cfg.timestep_factor, cfg.antithetic)


def setting_of(record: dict) -> Setting:
    """The MPC setting of a run (lines written before a setting was recorded
    ran with 32 samples, no trunk term, no retries, one attempt and predictive sampling;
    before the retry horizon was, further attempts planned over the 0.45 s of the first;
    before issue 35, every run planned with a 4 ms step and independent noise)."""
    attempts = int(record.get("attempts", 1))
    return (int(record.get("samples", 32)), float(record.get("trunk_weight", 0.0)),
            int(record.get("retries", 0)), attempts, float(record.get("temperature", 0.0)),
            float(record.get("retry_horizon_s", 0.45)) if attempts > 1 else 0.0,
            int(record.get("timestep_factor", 2)), bool(record.get("antithetic", False)))


def setting_label(setting: Setting) -> str:
    """``"64 samples"``, with ``", trunk weight W"`` when the trunk term is on and
    ``", R retries"`` when rewinds are allowed and ``", A seeds (the further ones over H
    s)"`` with more than one attempt and ``", MPPI temperature T"`` unless it keeps the best
    sample, and ``", antithetic"`` and ``", F ms planning step"`` where they are not the
    previous planner's (independent noise, 4 ms)."""
    n, w, r, a, t, h, f, anti = setting
    return f"{n} samples" + (", antithetic" if anti else "") + (
        f", {2 * f} ms planning step" if f != 2 else "") + (
        f", trunk weight {w:g}" if w else "") + (
        f", {r} retries" if r else "") + (
        f", {a} seeds (the further ones over {h:g} s)" if a > 1 else "") + (
        f", MPPI temperature {t:g}" if t else ", predictive sampling")


def _done(out: Path) -> set[tuple[str, str, float, Setting]]:
    """(clip, corruption, strength, setting) of the runs already in ``out``."""
    if not out.is_file():
        return set()
    return {(r["clip"], r["corruption"], r["strength"], setting_of(r))
            for r in map(json.loads, filter(str.strip, out.read_text().splitlines()))}


def run(args: argparse.Namespace) -> None:
    out: Path = args.out
    out.parent.mkdir(parents=True, exist_ok=True)
    desc = descriptions(args.data)
    base = FAST if args.planner == "fast" else MPCConfig()
    cfg = replace(base, nthread=args.threads, seed=args.seed,
                  weights=CostWeights(trunk=args.trunk_weight), retries=args.retries,
                  attempts=args.attempts, temperature=args.temperature,
                  **({} if args.samples is None else {"n_samples": args.samples}))
    setting = setting_of_config(cfg)
    paths = clips(args.data)
    if args.clips:
        # The named clips first, in the order given; the others follow with --all-clips.
        first = [p for name in args.clips for p in paths if p.name == name]
        paths = first + ([p for p in paths if p not in first] if args.all_clips else [])
    jobs: list[tuple[Path, str, float]] = []
    if args.runs in ("clean", "all"):
        jobs += [(p, "none", 0.0) for p in paths]
    if args.runs in ("corrupt", "all"):
        jobs += [(p, c, s) for p in paths if p.name in args.corrupt_clips
                 for c, s in CORRUPT_RUNS]
    if args.reverse:
        jobs.reverse()
    for path, corruption, strength in jobs:
        # Read before every job: a second process may share the file (--reverse).
        if (path.name, corruption, strength, setting) in _done(out):
            continue
        t0 = time.perf_counter()
        motion = clip_motion(path, args.seconds)
        if corruption != "none":
            motion = CORRUPTIONS[corruption].fn(motion, strength, seed=args.seed)
        fitted = retarget(motion)
        mpc = track(fitted, controller="mpc", mpc=cfg, max_seconds=args.seconds,
                    progress=args.progress)
        rec: dict[str, object] = {
            "clip": path.name, "trial": path.stem, "description": desc.get(path.stem, ""),
            "corruption": corruption, "strength": strength, "seconds": args.seconds,
            "acrobatics": path.stem in ACROBATICS, "mass_kg": fitted.humanoid.total_mass,
            "mpc": _record(mpc, motion.fps), "samples": cfg.n_samples,
            "trunk_weight": cfg.weights.trunk, "retries": cfg.retries,
            "attempts": cfg.attempts, "temperature": cfg.temperature,
            "retry_horizon_s": setting[5], "timestep_factor": cfg.timestep_factor,
            "antithetic": cfg.antithetic,
            "threads": args.threads, "seed": args.seed,
            "load_average": os.getloadavg()[0],
        }
        if corruption == "none":
            rec["pd"] = _record(track(fitted, max_seconds=args.seconds), motion.fps)
            assisted = track(fitted, assist=True, max_seconds=args.seconds)
            rec["pd_assisted"] = {**_record(assisted, motion.fps),
                                  "assist_force_mean": float(np.nanmean(assisted.assist_force))}
        rec["total_s"] = time.perf_counter() - t0
        with out.open("a") as f:
            f.write(json.dumps(rec) + "\n")
        m = rec["mpc"]
        print(f"{path.name:22s} {corruption:10s} {strength:5.1f} ok={int(m['success'])} "
              f"ttf={m['time_to_failure_s']:.2f}/{m['simulated_s']:.2f} err={m['mpjpe_mm']:.0f} mm "
              f"work={m['work_j_per_kg']:.1f} J/kg x{m['realtime_ratio']:.0f} real time",
              flush=True)


def _fmt(x: float, spec: str = ".0f") -> str:
    return "-" if x is None or not np.isfinite(x) else format(x, spec)


def corrupted_span(data: Path, record: dict) -> tuple[float, float]:
    """(first, last) corrupted second of a corrupted run's copy, re-made from its seed."""
    name = record["clip"]
    path = next(p for p in clips(data) if p.name == name)
    motion = clip_motion(path, record["seconds"])
    bad = CORRUPTIONS[record["corruption"]].fn(motion, record["strength"], seed=record["seed"])
    runs = bad.metadata["corruptions"][-1]["frames"]
    return runs[0][0] / motion.fps, runs[-1][1] / motion.fps


def _clean_table(clean: list[dict], setting: Setting, expected: list[str] | None) -> list[str]:
    """Markdown lines of the clean runs of one MPC setting."""
    seconds = clean[0]["seconds"]
    lines = [
        f"**MPC: {setting_label(setting)}.** "
        "Generated by `benchmarks/eval_tracking.py` "
        f"(first {seconds:g} s of each clip; MPC seed {clean[0]['seed']}, "
        f"{clean[0]['threads']} rollout threads). Error = mean body-point (keypoint) error over "
        "the tracked frames; work = positive work of the hinge actuators; x RT = wall time per "
        "simulated second on this shared 2-core machine (load average at the run in the last "
        "column).", "",
        "| clip | motion | MPC | time to failure s | error mm | max 0.5 s error mm | "
        "work J | J/kg | PD unassisted: fails at s | PD assisted error mm | x RT | load |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in clean:
        m, p, a = r["mpc"], r["pd"], r["pd_assisted"]
        name = r["clip"] + (" (acrobatics)" if r["acrobatics"] else "")
        lines.append(
            f"| {name} | {r['description']} | {'tracked' if m['success'] else 'FELL'} | "
            f"{m['time_to_failure_s']:.2f} / {m['simulated_s']:.2f} | {_fmt(m['mpjpe_mm'])} "
            f"| {_fmt(m['window_max_mm'])} | {_fmt(m['work_j'])} | "
            f"{_fmt(m['work_j_per_kg'], '.1f')} | "
            f"{'-' if p['success'] else format(p['time_to_failure_s'], '.2f')} | "
            f"{_fmt(a['mpjpe_mm'])} | {_fmt(m['realtime_ratio'])} | "
            f"{r['load_average']:.1f} |")
    judged = [r for r in clean if not r["acrobatics"]]
    ok = [r for r in judged if r["mpc"]["success"]]
    err = [r["mpc"]["mpjpe_mm"] for r in ok]
    mean_err = float(np.mean(err)) if err else None
    pd_ok = sum(r["pd"]["success"] for r in judged)
    lines += ["", f"Unassisted MPC, {setting_label(setting)}: **{len(ok)} of {len(judged)} clips "
              f"tracked** ({100 * len(ok) / max(len(judged), 1):.0f} %; goal 90 %), acrobatics "
              f"apart; mean body error of the tracked clips {_fmt(mean_err)}"
              f" mm (goal 50 mm). Unassisted PD servos: {pd_ok} of {len(judged)}. Median "
              f"cost {np.median([r['mpc']['realtime_ratio'] for r in clean]):.0f}x real time."]
    missing = sorted(set(expected or []) - {r["clip"] for r in clean})
    if missing:
        lines += ["", f"Not evaluated (the run was stopped for time): {', '.join(missing)}."]
    return lines


def _corrupt_table(bad: list[dict], clean: list[dict], setting: Setting,
                   data: Path) -> list[str]:
    """Markdown lines of the corrupted runs of one MPC setting, beside its clean runs."""
    clean_by_clip = {r["clip"]: r["mpc"] for r in clean}
    lines = [f"Corrupted copies (the same MPC, {setting_label(setting)}; a copy fails when the "
             "body error exceeds 0.5 m; *corrupted s* is the span the corruption edits, and a "
             "failure long after it, or where the clean clip also fell, is not the "
             "corruption's doing):",
             "", "| clip | corruption | strength | corrupted s | MPC | time to failure s | "
             "error mm | max 0.5 s error mm | clean clip |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in bad:
        m = r["mpc"]
        a, b = corrupted_span(data, r)
        c = clean_by_clip.get(r["clip"])
        ref = ("-" if c is None else "tracked" if c["success"]
               else f"fell at {c['time_to_failure_s']:.2f}")
        lines.append(f"| {r['clip']} | {r['corruption']} | {r['strength']:g} | "
                     f"{a:.2f}-{b:.2f} | {'tracked' if m['success'] else 'failed'} | "
                     f"{m['time_to_failure_s']:.2f} / {m['simulated_s']:.2f} | "
                     f"{_fmt(m['mpjpe_mm'])} | {_fmt(m['window_max_mm'])} | {ref} |")
    lines.append("")
    for c, s in CORRUPT_RUNS:
        rs = [r for r in bad if r["corruption"] == c and r["strength"] == s]
        if rs:
            caught = sum(not r["mpc"]["success"] for r in rs)
            lines.append(f"- {c} {s:g}: failed on {caught} of {len(rs)} clips")
    return lines


def _comparison_table(clean: list[dict], settings: list[Setting]) -> list[str]:
    """Markdown lines comparing the MPC settings clip by clip (clean runs of
    the clips every setting ran)."""
    by = {(r["clip"], setting_of(r)): r["mpc"] for r in clean}
    names = [c for c in dict.fromkeys(r["clip"] for r in clean)
             if all((c, n) in by for n in settings)]
    head = " | ".join(f"{setting_label(n)}: MPC, time to failure s, error mm, x RT"
                      for n in settings)
    lines = ["MPC settings side by side (clean clips run at every setting):", "",
             f"| clip | {head} |", "|---|" + "---|" * len(settings)]
    for c in names:
        cells = [f"{'tracked' if m['success'] else 'FELL'}, {m['time_to_failure_s']:.2f}, "
                 f"{_fmt(m['mpjpe_mm'])}, {_fmt(m['realtime_ratio'])}"
                 for m in (by[(c, n)] for n in settings)]
        lines.append(f"| {c} | " + " | ".join(cells) + " |")
    return lines


def tables(records: list[dict], expected: list[str] | None = None,
           data: Path = DEFAULT_DATA) -> str:
    """Markdown tables of the runs, one set per MPC setting (the default
    :class:`MPCConfig`'s first) so settings never mix; ``expected`` clip names
    missing from a setting's clean runs are listed as not evaluated."""
    order = {p: i for i, p in enumerate(expected or [])}
    records = sorted(records, key=lambda r: (order.get(r["clip"], len(order)), r["clip"],
                                             r["corruption"], r["strength"]))
    default = setting_of_config(MPCConfig())
    settings = sorted({setting_of(r) for r in records}, key=lambda n: (n != default, n))
    clean_all = [r for r in records if r["corruption"] == "none"]
    # Side by side: the settings that ran clean clips (some ran corrupted copies only).
    compared = [n for n in settings if any(setting_of(r) == n for r in clean_all)]
    lines = _comparison_table(clean_all, compared) if len(compared) > 1 else []
    for n in settings:
        mine = [r for r in records if setting_of(r) == n]
        clean = [r for r in mine if r["corruption"] == "none"]
        bad = [r for r in mine if r["corruption"] != "none"]
        if lines:
            lines.append("")
        if clean:
            lines += _clean_table(clean, n, expected)
        if bad:
            lines += ([""] if clean else []) + _corrupt_table(bad, clean, n, data)
    return "\n".join(lines)


def write_docs(records: list[dict], expected: list[str], data: Path, path: Path = DOCS,
               section: str = SECTION) -> None:
    """The tables into ``path`` between the markers ``<!-- SECTION:begin -->`` and
    ``<!-- SECTION:end -->``."""
    replace_section(path, f"<!-- {section}:begin -->", f"<!-- {section}:end -->",
                    tables(records, expected, data))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("command", choices=("run", "docs"))
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="run: results JSONL")
    ap.add_argument("--results", type=Path, nargs="+", default=list(DEFAULT_RESULTS),
                    help="docs: the results JSONL files to tabulate")
    ap.add_argument("--section", default=SECTION,
                    help="docs: the marked section of docs/plausibility.md to write")
    ap.add_argument("--seconds", type=float, default=4.0, help="simulated seconds per clip")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--planner", choices=("default", "fast"), default="default",
                    help="run: the MPC's settings to start from: MPCConfig() or "
                         "simenv.control.FAST (issue 35)")
    ap.add_argument("--samples", type=int, default=None,
                    help="run: MPC rollouts per replan (default MPCConfig's)")
    ap.add_argument("--trunk-weight", type=float, default=CostWeights().trunk,
                    help="run: MPC upper-trunk orientation cost weight, per rad^2")
    ap.add_argument("--retries", type=int, default=MPCConfig().retries,
                    help="run: rewinds the MPC may use after a failure")
    ap.add_argument("--attempts", type=int, default=MPCConfig().attempts,
                    help="run: planner seeds a run may try (the first that tracks is kept)")
    ap.add_argument("--temperature", type=float, default=MPCConfig().temperature,
                    help="run: MPPI temperature of the MPC (0: keep the best sample)")
    ap.add_argument("--clips", nargs="*", default=[],
                    help="run: only these clip files (e.g. 05_02.bvh), in this order")
    ap.add_argument("--all-clips", action="store_true",
                    help="run: with --clips, the other clips after the named ones")
    ap.add_argument("--corrupt-clips", nargs="*", default=list(CORRUPT_CLIPS))
    ap.add_argument("--runs", choices=("clean", "corrupt", "all"), default="all",
                    help="which runs (two processes can share the work)")
    ap.add_argument("--reverse", action="store_true",
                    help="take the runs last to first (a second process on the same file)")
    ap.add_argument("--progress", action="store_true")
    args = ap.parse_args()
    if args.command == "run":
        run(args)
    else:
        records: dict[tuple[str, str, float, Setting], dict] = {}
        for path in args.results:
            if path.is_file():
                for line in filter(str.strip, path.read_text().splitlines()):
                    r = json.loads(line)
                    # A run repeated by a second process: the first one counts.
                    records.setdefault((r["clip"], r["corruption"], r["strength"],
                                        setting_of(r)), r)
        write_docs(list(records.values()), [p.name for p in clips(args.data)], args.data,
                   section=args.section)


if __name__ == "__main__":
    main()

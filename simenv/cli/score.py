"""``simenv score``: judge the physical plausibility of motion files and folders, optionally
relative to real data of the same source (``--reference``)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from simenv.cli.common import EXIT_USER_ERROR, add_joint_map_option, add_units_options, positive_int
from simenv.core.errors import SimenvError

if TYPE_CHECKING:  # the scorer's settings load MuJoCo
    from simenv.plausibility.metric import ScoreConfig

#: ``--source`` choices: simenv.plausibility.profiles.DECLARABLE_SOURCES, written out so that
#: parsing the command line does not load the scorer (tests/test_profiles.py checks they agree).
SOURCE_CHOICES = ("auto", "mocap", "body_model", "kinect_v1", "kinect_v2", "generated")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add ``simenv score``."""
    sco = subparsers.add_parser("score", help="judge physical plausibility", description=(
        "Score each motion: joint-level metrics (bone length, foot skate, jitter, velocity, "
        "...), and with --physics (default) the retargeted body's ground penetration, "
        "floating, joint limits, self-penetration, inverse-dynamics root residual, balance "
        "and unassisted physics tracking (model-predictive control); two-person clips add "
        "inter-person penetration and contact. "
        "Folders are walked (a folder with one two-person recording is one clip). Prints a "
        "verdict per person, or with --json one JSON object per person."))
    sco.add_argument("paths", nargs="+", metavar="PATH", help="motion files or folders")
    sco.add_argument("--json", action="store_true", help=(
        "print one JSON object per person scored: file, person, frames, fps, verdict, score, "
        "metrics, violations (and interaction for two people)"))
    sco.add_argument("--physics", action=argparse.BooleanOptionalAction, default=True,
                     help="run the body-level and simulation metrics (default: on)")
    sco.add_argument("--jobs", type=positive_int, default=1,
                     help="parallel worker processes / Ray tasks (default 1)")
    sco.add_argument("--backend", choices=("local", "ray"), default="local",
                     help="where the jobs run (default local)")
    sco.add_argument("--ray-address", default=None,
                     help="with --backend ray: cluster address (default: start a local Ray)")
    sco.add_argument("--out", metavar="RESULTS.jsonl", help=(
        "append one JSON line per person as each file finishes; a rerun skips files "
        "already there"))
    sco.add_argument("--report", metavar="DIR",
                     help="write an HTML report (timelines, violation video) per file")
    sco.add_argument("--progress", action="store_true",
                     help="show the progress bar even when stderr is not a terminal")
    sco.add_argument("--restore-collapsed-bones", action="store_true", help=(
        "read BVH files with the thorax and wrist bones that the CMU conversions collapse "
        "put back (reader's repair; listed in each record's repairs); default: as written"))
    sco.add_argument("--tracking-segments", type=float, metavar="SECONDS", help=(
        "judge physics tracking of clips longer than this in segments of this many "
        "seconds, each simulated from the captured state 1 s before it (default 4; inf: "
        "the whole clip in one run; docs/plausibility.md)"))
    sco.add_argument("--tracking-attempts", type=int, metavar="N", help=(
        "planner seeds a failed tracking run (segment) may try before the motion is blamed, "
        "the further ones planning 0.6 s ahead (default 3; 1: one seed)"))
    sco.add_argument("--planner", choices=("default", "fast"), default="default", help=(
        "the physics tracking's planner: default (128 samples, 4 ms planning step), or fast "
        "(simenv.control.FAST: a quarter of the rolled-out steps, 3-4x quicker; on 20 clean "
        "CMU clips 20 tracked at 57 mm mean body error against 45, and a walk lifted 50 cm "
        "that the default fails it follows: docs/tracking_speed.md)"))
    sco.add_argument("--track-if-plausible", action="store_true", help=(
        "run the physics tracking (nearly all of the time) only for people whose other "
        "metrics all pass: one already failing is implausible whatever the tracking finds, "
        "so its tracking reads 'skipped' and its root residual is the inferred one; for "
        "scoring many clips (two-person clips are always tracked)"))
    sco.add_argument("--reference", nargs="+", action="extend", metavar="REAL_PATH", help=(
        "judge the clips relative to real data of the same source: score these real files or "
        "folders (or read their earlier --out .jsonl results), calibrate every metric on them "
        "(percentiles) and report per clip and for the set where the scored clips fall "
        "(records get 'reference'; a summary line, REPORT/reference.html and "
        "OUT.reference.json). Put it after the scored PATHs"))
    sco.add_argument("--source", default="auto", choices=SOURCE_CHOICES, help=(
        "what the clips are, which picks the thresholds' profile: auto (default: from the "
        "skeleton; depth-camera clips are judged by their sensor family's real data), mocap "
        "and body_model (the motion-capture thresholds), kinect_v1, kinect_v2, generated (by "
        "the profile of the family its skeleton comes from); records name it in 'profile'. "
        "With --reference on depth-camera clips, --source mocap measures the values the "
        "reference compares at the default thresholds, where they are not cut to 0"))
    add_joint_map_option(sco)
    add_units_options(sco)
    sco.set_defaults(func=run)


def _print_score(rec: dict[str, Any]) -> None:
    if "error" in rec:
        print(f"{rec['file']}: error: {rec['error']}")
        return
    failed = [n for n, m in rec["metrics"].items() if m["passed"] is False]
    na = [n for n, m in rec["metrics"].items() if m["passed"] is None]
    where = f"clip {rec['clip']}, person {rec['person']}" if "clip" in rec \
        else f"person {rec['person']}"
    line = (f"{rec['file']} [{where}]: {rec['verdict']} (score "
            f"{rec['score']:.1f}, {rec['frames']} frames at {rec['fps']:g} fps, "
            f"{rec.get('profile', 'mocap')} thresholds)")
    if failed:
        line += "; failed: " + ", ".join(failed)
    if na:
        line += "; not available: " + ", ".join(na)
    pair = rec.get("interaction")
    if pair is not None and rec["person"] == 0:
        line += f"; interaction: {pair['verdict']}"
    ref = rec.get("reference")
    if ref is not None:
        line += (f"; against the reference: {ref['verdict']} (worst: {ref['worst_metric']} at "
                 f"percentile {ref['worst_percentile']:.1f})")
    print(line)


def score_config(args: argparse.Namespace, progress: bool = False) -> ScoreConfig | None:
    """The scorer's :class:`~simenv.plausibility.metric.ScoreConfig` of the options, or None
    for the defaults. ``progress``: the tracking shows its frames as it goes (one local job
    with physics: several jobs' bars would interleave).

    Raises:
        SimenvError: ``--tracking-segments`` not a positive number of seconds, or
            ``--tracking-attempts`` below 1.
    """
    progress = progress and args.physics and args.jobs == 1 and args.backend == "local"
    if (args.tracking_segments is None and args.tracking_attempts is None
            and args.planner == "default" and not progress and not args.track_if_plausible):
        return None
    # The scorer's settings load MuJoCo: only when an option asks for them.
    from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS
    from simenv.plausibility.metric import ScoreConfig

    config = ScoreConfig(progress=progress, track_if_plausible=args.track_if_plausible)
    if args.tracking_segments is not None:
        config = dataclasses.replace(config, body=dataclasses.replace(
            DEFAULT_BODY_THRESHOLDS, tracking_segment_s=args.tracking_segments))
    if args.tracking_attempts is not None:
        config = dataclasses.replace(config, mpc=dataclasses.replace(
            config.mpc, attempts=args.tracking_attempts))
    from simenv.plausibility.planner import with_planner

    return with_planner(config, args.planner)


def run(args: argparse.Namespace) -> int:
    """Score every target, print a line (or a JSON object) per person as it finishes; exit
    status 2 when some input could not be scored."""
    # The scorer (MuJoCo, numba kernels) loads only when something is scored.
    from simenv.plausibility.batch import (
        ScoreJob,
        calibrate_reference,
        done_files,
        find_targets,
        index_entries,
        score_batch,
    )

    targets = find_targets(args.paths)
    if not targets:
        raise SimenvError("found no motion file to score", source=args.paths[0])
    report_dir = None
    if args.report:
        report_dir = Path(args.report)
        report_dir.mkdir(parents=True, exist_ok=True)
    progress = sys.stderr.isatty() or args.progress
    job = ScoreJob(physics=args.physics, report_dir=None if report_dir is None
                   else str(report_dir), config=score_config(args, progress),
                   restore_collapsed_bones=args.restore_collapsed_bones,
                   joint_map=args.joint_map, source=args.source, units=args.units,
                   scale=args.scale)
    if args.reference:
        reference = calibrate_reference(args.reference, job, exclude=targets, jobs=args.jobs,
                                        backend=args.backend, ray_address=args.ray_address,
                                        progress=progress)
        job = dataclasses.replace(job, reference=reference)

    def show(_target: Path, records: list[dict[str, Any]]) -> None:
        for rec in records:
            if args.json:
                print(json.dumps(rec), flush=True)
            else:
                _print_score(rec)

    # Files already in --out are skipped by score_batch (a rerun resumes): counted here.
    done = done_files(args.out) if args.out else set()
    skipped = sum(str(t) in done for t in targets)
    records = score_batch(targets, job, jobs=args.jobs, backend=args.backend,
                          ray_address=args.ray_address, out=args.out,
                          progress=progress, on_result=show)
    if report_dir is not None:
        from simenv.plausibility.html_report import write_index  # rendering: with --report

        index = write_index(index_entries(records), report_dir)
        if not args.json:
            print(f"wrote {index}")
    if job.reference is not None:
        _reference_summary(args, job.reference, records, report_dir)
    if args.out:
        failed = len({r.get("file") for r in records if "error" in r})
        print(f"results in {args.out}: {len(targets) - skipped - failed} file(s) scored, "
              f"{skipped} skipped (already there), {failed} failed",
              file=sys.stderr if args.json else sys.stdout)
    # Every file was attempted and recorded; the status still says some input was bad.
    return EXIT_USER_ERROR if any("error" in r for r in records) else 0


def _reference_summary(args: argparse.Namespace, reference: Any,
                       records: list[dict[str, Any]], report_dir: Path | None) -> None:
    """Compare the generated set with the reference; print (JSON: one
    ``{"reference_summary": ...}`` line), write it next to ``--out`` and into
    ``--report``."""
    # The report writers (MuJoCo, rendering) load only with --reference.
    from simenv.plausibility.reference import compare, read_records, write_reference_page

    # With --out, the set is every record of the results file (a rerun skips files already in it),
    # judged against this reference.
    if args.out:
        records = [rec if "error" in rec else {**rec, "reference": reference.judge(rec)}
                   for rec in read_records(args.out)]
    summary = compare(reference, records)
    if args.out:
        Path(args.out).with_suffix(".reference.json").write_text(
            json.dumps(summary, indent=1), encoding="utf-8")
    if report_dir is not None:
        page = write_reference_page(summary, records, report_dir)
        if not args.json:
            print(f"wrote {page}")
    if args.json:
        print(json.dumps({"reference_summary": summary}), flush=True)
        return
    o = summary["overall"]
    print(f"reference: {summary['reference']['people']} real people; generated: "
          f"{summary['generated']['people']}: {summary['verdict']} "
          f"({100 * o['share_beyond_p99']:.1f} % beyond the real 99th percentile of the worst "
          f"metric, expected {100 * o['expected_share_beyond_p99']:.1f} %; p = "
          f"{o['p_value']:.3g})")
    for name, m in summary["metrics"].items():
        g = m.get("generated")
        if g is not None:
            print(f"  {name}: median percentile {g['median_percentile']:.1f}, "
                  f"{100 * g['share_beyond_p99']:.1f} % beyond real p99 ({g['verdict']})")

"""The ``simenv`` command line: ``info``, ``retarget``, ``render``, ``score``, ``export`` and
``demo``.

Every command that takes a motion file also takes a folder holding a two-person recording (one
file per person, e.g. the CMU pairs), which loads as one interaction. User errors
(:class:`~simenv.core.errors.SimenvError`) print one line on stderr and exit with status 2; anything
else is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import SimenvError
from simenv.core.motion import Interaction, Motion
from simenv.io.loader import load_any, load_one

EXIT_USER_ERROR = 2


def _stature(motion: Motion) -> float | None:
    """Standing height (m, sole to top of head) of the body fitted to the bone lengths."""
    from simenv.body.humanoid import fit_dimensions

    try:
        return round(fit_dimensions(motion).height, 3)
    except SimenvError:  # e.g. no pelvis/hips to measure a body from
        return None


def _person_info(motion: Motion) -> dict[str, Any]:
    """``height_m`` is the joint span (highest minus lowest joint, 95th percentile over
    frames); ``stature_m`` the standing height of the fitted body, when one can be fitted."""
    meta = motion.metadata
    return {
        "name": motion.name,
        "joints": motion.num_joints,
        "frames": motion.num_frames,
        "fps": motion.fps,
        "duration_s": round(motion.duration, 4),
        "height_m": round(motion.height(), 3),
        "stature_m": _stature(motion),
        "units_in_file": meta.get("units"),
        "quirks": list(meta.get("quirks", [])),
        "repairs": list(meta.get("repairs", [])),
    }


def describe(clip: Motion | Interaction) -> dict[str, Any]:
    """JSON-ready summary of a clip: format, people, joints, frames, fps, duration, heights."""
    people = clip.people if isinstance(clip, Interaction) else (clip,)
    first = people[0]
    info: dict[str, Any] = {
        "name": clip.name,
        "source": str(clip.metadata.get("source", first.metadata.get("source", ""))),
        "format": clip.metadata.get("format", first.metadata.get("format")),
        "people": len(people),
        "frames": first.num_frames,
        "fps": first.fps,
        "duration_s": round(first.duration, 4),
        "persons": [_person_info(m) for m in people],
    }
    if isinstance(clip, Interaction):
        info["label"] = clip.label
        info["quirks"] = list(clip.metadata.get("quirks", []))
    return info


def _print_info(info: dict[str, Any]) -> None:
    print(f"{info['name']}  ({info['format']}, {info['source']})")
    print(
        f"  people {info['people']}, frames {info['frames']}, fps {info['fps']:g}, "
        f"duration {info['duration_s']:.2f} s"
    )
    if info.get("label"):
        print(f"  label {info['label']}")
    for note in info.get("quirks", []):
        print(f"  quirk: {note}")
    for i, person in enumerate(info["persons"]):
        stature = person["stature_m"]
        print(
            f"  person {i} {person['name']}: {person['joints']} joints, joint span "
            f"{person['height_m']:.2f} m, "
            + (f"stature ~{stature:.2f} m (fitted body), " if stature else "")
            + f"units in file {person['units_in_file']}"
        )
        for note in person["quirks"]:
            print(f"    quirk: {note}")
        for note in person["repairs"]:
            print(f"    repair: {note}")


def cmd_info(args: argparse.Namespace) -> int:
    infos = [describe(clip) for clip in load_any(args.paths)]
    if args.json:
        print(json.dumps(infos[0] if len(infos) == 1 else {"clips": infos}))
    else:
        for info in infos:
            _print_info(info)
    return 0


def retarget_clip(clip: Motion | Interaction) -> Any:
    """Retarget one clip (each person on their own fitted humanoid); see
    :mod:`simenv.body.retarget`."""
    from simenv.body.retarget import retarget

    return retarget(clip)


def summary(result: Any) -> dict[str, Any]:
    """The one-object JSON summary of a retargeting result (residuals in metres)."""
    qpos = np.asarray(result.qpos)
    return {
        "frames": int(qpos.shape[0]),
        "fps": float(result.fps),
        "people": len(_people_results(result)),
        "mean_residual_m": float(result.mean_residual),
        "p95_residual_m": float(result.p95_residual),
        "max_residual_m": float(result.max_residual),
        "seconds": float(result.seconds),
    }


def _people_results(result: Any) -> list[Any]:
    for attr in ("people", "results", "persons"):
        people = getattr(result, attr, None)
        if people is not None:
            return list(people)
    return [result]


def _humanoid_arrays(humanoid: Any, suffix: str) -> dict[str, np.ndarray]:
    """The humanoid's dimensions as NPZ arrays: ``dim_names``/``dim_values`` (metres; 3-vector
    offsets split into ``_x``/``_y``/``_z``), ``height`` (m) and ``mass`` (kg)."""
    names: list[str] = []
    values: list[float] = []
    dims = getattr(humanoid, "dims", None)
    if dims is not None and dataclasses.is_dataclass(dims):
        for f in dataclasses.fields(dims):
            value = getattr(dims, f.name)
            if isinstance(value, (int, float)):
                names.append(f.name)
                values.append(float(value))
            elif isinstance(value, tuple) and len(value) == 3 and all(
                isinstance(v, (int, float)) for v in value
            ):
                names += [f"{f.name}_{axis}" for axis in "xyz"]
                values += [float(v) for v in value]
    arrays = {
        f"dim_names{suffix}": np.array(names, dtype=str),
        f"dim_values{suffix}": np.array(values, dtype=np.float64),
    }
    height = getattr(dims, "height", None)
    if isinstance(height, (int, float)):
        arrays[f"height{suffix}"] = np.float64(height)
    mass = getattr(humanoid, "total_mass", None)
    if isinstance(mass, (int, float)):
        arrays[f"mass{suffix}"] = np.float64(mass)
    return arrays


def save_npz(result: Any, path: str | Path) -> Path:
    """Write ``qpos`` (T, nq), ``fps``, per-person ``qpos_i`` and humanoid dimensions to NPZ."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, np.ndarray] = {
        "qpos": np.asarray(result.qpos, dtype=np.float64),
        "fps": np.float64(result.fps),
        "residuals": np.asarray(_residuals(result), dtype=np.float32),
    }
    people = _people_results(result)
    if len(people) == 1:
        arrays.update(_humanoid_arrays(people[0].humanoid, ""))
    else:
        for i, person in enumerate(people):
            arrays[f"qpos_{i}"] = np.asarray(person.qpos, dtype=np.float64)
            arrays.update(_humanoid_arrays(person.humanoid, f"_{i}"))
    np.savez(path, **arrays)
    return path


def _residuals(result: Any) -> np.ndarray:
    people = _people_results(result)
    if len(people) == 1:
        return np.asarray(people[0].residuals)
    return np.concatenate([np.asarray(p.residuals) for p in people], axis=1)


def _check_suffix(path: str, suffix: str, option: str) -> Path:
    out = Path(path)
    if out.suffix.lower() != suffix:
        raise SimenvError(f"{option} must end with {suffix}; got {out.name!r}", field=option)
    return out


def cmd_retarget(args: argparse.Namespace) -> int:
    out = _check_suffix(args.out, ".npz", "--out")
    video = _check_suffix(args.video, ".mp4", "--video") if args.video else None
    result = retarget_clip(load_one(args.paths))
    save_npz(result, out)
    if video is not None:
        from simenv.body.render import render_result

        render_result(result, video, stride=args.stride, max_frames=args.max_frames, progress=True)
    info = summary(result)
    if args.json:
        print(json.dumps(info))
    else:
        print(
            f"retargeted {info['frames']} frames ({info['people']} people) in "
            f"{info['seconds']:.2f} s; keypoint residual mean {info['mean_residual_m'] * 100:.2f}"
            f" cm, p95 {info['p95_residual_m'] * 100:.2f} cm, max "
            f"{info['max_residual_m'] * 100:.2f} cm"
        )
        print(f"wrote {out}" + (f" and {video}" if video else ""))
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from simenv.body.render import render_result

    out = _check_suffix(args.out, ".mp4", "--out")
    clip = load_one(args.paths)
    if args.max_frames is not None:
        # Only the frames that will be shown need retargeting.
        clip = clip.slice(0, args.max_frames * args.stride)
    result = retarget_clip(clip)
    render_result(result, out, stride=args.stride, max_frames=args.max_frames,
                  width=args.width, height=args.height, progress=True)
    print(f"wrote {out}")
    return 0


def _print_score(rec: dict[str, Any]) -> None:
    if "error" in rec:
        print(f"{rec['file']}: error: {rec['error']}")
        return
    failed = [n for n, m in rec["metrics"].items() if m["passed"] is False]
    na = [n for n, m in rec["metrics"].items() if m["passed"] is None]
    where = f"clip {rec['clip']}, person {rec['person']}" if "clip" in rec \
        else f"person {rec['person']}"
    line = (f"{rec['file']} [{where}]: {rec['verdict']} (score "
            f"{rec['score']:.1f}, {rec['frames']} frames at {rec['fps']:g} fps)")
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


def cmd_score(args: argparse.Namespace) -> int:
    from simenv.plausibility.batch import ScoreJob, find_targets, index_entries, score_batch

    targets = find_targets(args.paths)
    if not targets:
        raise SimenvError("found no motion file to score", source=args.paths[0])
    report_dir = None
    if args.report:
        report_dir = Path(args.report)
        report_dir.mkdir(parents=True, exist_ok=True)
    job = ScoreJob(physics=args.physics, report_dir=None if report_dir is None
                   else str(report_dir), restore_collapsed_bones=args.restore_collapsed_bones)
    progress = sys.stderr.isatty() or args.progress
    if args.reference:
        from simenv.plausibility.batch import calibrate_reference

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

    records = score_batch(targets, job, jobs=args.jobs, backend=args.backend,
                          ray_address=args.ray_address, out=args.out,
                          progress=progress, on_result=show)
    if report_dir is not None:
        from simenv.plausibility.html_report import write_index

        index = write_index(index_entries(records), report_dir)
        if not args.json:
            print(f"wrote {index}")
    if job.reference is not None:
        _reference_summary(args, job.reference, records, report_dir)
    if args.out and not args.json:
        print(f"results in {args.out}")
    # Every file was attempted and recorded; the status still says some input was bad.
    return EXIT_USER_ERROR if any("error" in r for r in records) else 0


def _reference_summary(args: argparse.Namespace, reference: Any,
                       records: list[dict[str, Any]], report_dir: Path | None) -> None:
    """Compare the generated set with the reference; print (JSON: one
    ``{"reference_summary": ...}`` line), write it next to ``--out`` and into
    ``--report``."""
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


def cmd_export(args: argparse.Namespace) -> int:
    from simenv.io.gltf import check_gltf
    from simenv.room.export import export

    path = export(args.paths, args.to, scenario=args.scenario, stride=args.stride)
    info = check_gltf(path)
    print(f"wrote {path}: {info['meshes']} meshes, {info['vertices']} vertices"
          + (f", animation of {info['frames']} frames ({info['duration_s']:.2f} s, "
             f"{info['channels']} channels)" if info["animations"] else ", static"))
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from simenv.cli.demo import PAGE, check_page, run_demo

    if not args.check_only:
        run_demo(Path(args.out), stride=args.stride)
    if args.check or args.check_only:
        result = check_page(Path(args.out) / PAGE)
        print(f"checked {Path(args.out) / PAGE}: {result['links']} links resolve in "
              f"{result['pages']} pages; Chromium plays its {len(result['videos'])} videos ("
              + ", ".join(f"{v['src']} {v['duration']:.1f} s" for v in result["videos"])
              + f"); screenshot {result['screenshot']} has "
              f"{100 * result['content_fraction']:.0f} % content and shows "
              f"{len(result['posters'])} video posters (match >= "
              f"{min((p['match'] for p in result['posters']), default=1):.2f})")
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    """Forward the options after KIND to the training script of the predictor, the
    classifier or the two-person models."""
    if args.kind == "predictor":
        from simenv.learning.train_predictor import main as predictor_main

        return predictor_main(args.options)
    if args.kind == "interaction":
        from simenv.learning.train_interaction import main as interaction_main

        return interaction_main(args.options)
    if args.kind == "recogniser":
        from simenv.perception.train_recogniser import main as recogniser_main

        return recogniser_main(["train", *args.options])
    from simenv.learning.train_classifier import main as classifier_main

    return classifier_main(["train", *args.options])


def cmd_eval(args: argparse.Namespace) -> int:
    """Evaluate a shipped model: an optional NAME, then the script's own options."""
    options = list(args.options)
    name = options.pop(0) if options and not options[0].startswith("-") else None
    if args.kind == "predictor":
        from simenv.learning.train_predictor import main as predictor_main

        return predictor_main(["--evaluate", name or "predictor-25-25", *options])
    if args.kind == "interaction":
        from simenv.learning.eval_interaction import main as interaction_main

        return interaction_main(list(args.options))
    if name is not None and name.startswith("gesture-classifier"):
        from simenv.learning.train_classifier import main as classifier_main

        return classifier_main(["eval", "--model", name, *options])
    from simenv.perception.train_recogniser import MODEL_NAME
    from simenv.perception.train_recogniser import main as recogniser_main

    if "--benchmark" in options:
        i = options.index("--benchmark")
        has_value = i + 1 < len(options) and not options[i + 1].startswith("-")
        dataset = options[i + 1] if has_value else "all"
        rest = options[:i] + options[i + 1 + has_value:]
        return recogniser_main(["benchmark", "--dataset", dataset, *rest])
    return recogniser_main(["eval", "--model", name or MODEL_NAME, *options])


def cmd_rehearse(args: argparse.Namespace) -> int:
    """Forward to the offline interaction rehearsal in the room (:mod:`simenv.envs.rehearsal`),
    or, when ``--agent`` names a two-person model, to the rehearsal of its generated
    reaction on simulated bodies (:mod:`simenv.envs.reaction_rehearsal`)."""
    from simenv.models import INTERACTION_MODELS

    options = list(args.options)
    agent = next((options[i + 1] for i, o in enumerate(options[:-1]) if o == "--agent"),
                 next((o.split("=", 1)[1] for o in options if o.startswith("--agent=")),
                      None))
    if agent in INTERACTION_MODELS:
        from simenv.envs.reaction_rehearsal import main as reaction_main

        return reaction_main(options)
    from simenv.envs.rehearsal import main as rehearsal_main

    return rehearsal_main(options)


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``simenv`` command (one sub-command per job)."""
    parser = argparse.ArgumentParser(
        prog="simenv",
        description="Physics-backed simulation and evaluation of 3D human skeleton motion.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    path_help = (
        "a motion file (BVH, ASF/AMC, Kinect text, NPZ), a folder with a two-person recording, "
        "or the two files of one"
    )

    info = sub.add_parser("info", help="describe a motion file", description=(
        "Format, people, joints, frames, fps, duration, height estimate per person, and the "
        "quirks found and repairs made while reading."))
    info.add_argument("paths", nargs="+", metavar="FILE|FOLDER", help=path_help)
    info.add_argument("--json", action="store_true", help="print one JSON object")
    info.set_defaults(func=cmd_info)

    ret = sub.add_parser("retarget", help="retarget onto a fitted MuJoCo humanoid", description=(
        "Fit a humanoid to each person's bone lengths, solve its joint trajectory, and save "
        "qpos (T, nq), fps and the humanoid's dimensions to an NPZ file."))
    ret.add_argument("paths", nargs="+", metavar="FILE|FOLDER", help=path_help)
    ret.add_argument("--out", required=True, help="output .npz")
    ret.add_argument("--video", help="also render an .mp4 (humanoid + source joints)")
    ret.add_argument("--stride", type=_positive_int, default=1,
                     help="video: render every S-th frame (default 1)")
    ret.add_argument("--max-frames", type=_positive_int, help="video: at most N frames")
    ret.add_argument("--json", action="store_true", help=(
        "print one JSON object: frames, fps, people, mean_residual_m, p95_residual_m, "
        "max_residual_m, seconds"))
    ret.set_defaults(func=cmd_retarget)

    ren = sub.add_parser("render", help="render the retargeted motion to MP4", description=(
        "Retarget and render offscreen (MUJOCO_GL=osmesa on a CPU): the humanoid, the source "
        "joints as a ghost, camera following the subject. About 5-10 frames/s on a CPU, so "
        "use --stride/--max-frames for long clips."))
    ren.add_argument("paths", nargs="+", metavar="FILE|FOLDER", help=path_help)
    ren.add_argument("--out", required=True, help="output .mp4")
    ren.add_argument("--max-frames", type=_positive_int, help="render at most N frames")
    ren.add_argument("--stride", type=_positive_int, default=1,
                     help="render every S-th frame (default 1)")
    ren.add_argument("--width", type=_positive_int, default=320, help="pixels (default 320)")
    ren.add_argument("--height", type=_positive_int, default=240, help="pixels (default 240)")
    ren.set_defaults(func=cmd_render)

    sco = sub.add_parser("score", help="judge physical plausibility", description=(
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
    sco.add_argument("--jobs", type=_positive_int, default=1,
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
    sco.add_argument("--reference", nargs="+", action="extend", metavar="REAL_PATH", help=(
        "judge the clips relative to real data of the same source: score these real files or "
        "folders (or read their earlier --out .jsonl results), calibrate every metric on them "
        "(percentiles) and report per clip and for the set where the scored clips fall "
        "(records get 'reference'; a summary line, REPORT/reference.html and "
        "OUT.reference.json). Put it after the scored PATHs"))
    sco.set_defaults(func=cmd_score)

    exp = sub.add_parser("export", help="export a motion or a room to glTF/GLB", description=(
        "Write a 3D file any viewer opens (glTF 2.0: .glb binary or .gltf): a motion file "
        "retargeted onto fitted humanoids, animated at its frame rate; a room scenario "
        "(bundled name or TOML, user furniture meshes included); or, with --scenario, the "
        "room with the motion played by its user."))
    exp.add_argument("paths", nargs="*", metavar="FILE|FOLDER", help=path_help
                     + "; or a scenario .toml")
    exp.add_argument("--to", required=True, metavar="OUT.glb", help="output .glb or .gltf")
    exp.add_argument("--scenario", metavar="NAME|FILE",
                     help="export this room (bundled name or TOML); with FILE, as its user")
    exp.add_argument("--stride", type=_positive_int, default=1,
                     help="keep every S-th frame of the animation (default 1)")
    exp.set_defaults(func=cmd_export)

    demo = sub.add_parser("demo", help="the main job on bundled real CMU data", description=(
        "Retarget the bundled CMU walk (02_01) and two-person handshake (18_01 + 19_01), write "
        "videos, NPZ trajectories, glTF files, plausibility reports, a room rehearsal and a "
        "JSON summary into the output folder, and index.html, the page that shows them."))
    demo.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    demo.add_argument("--stride", type=_positive_int, default=None,
                      help="render every S-th frame (default: chosen to keep the demo short)")
    demo.add_argument("--check", action="store_true", help=(
        "then check the page: every link resolves, and a headless Chromium screenshot "
        "(index.png) is not blank and shows every video's poster"))
    demo.add_argument("--check-only", action="store_true",
                      help="check the page of an earlier run in --out without running")
    demo.set_defaults(func=cmd_demo)

    for verb, func, text in (
        ("train", cmd_train, "train the motion predictor, the gesture classifier, the room's "
         "recogniser (`train recogniser`: leave-subjects-out protocol, loop, shipped network) or a "
         "two-person model (`train interaction --model NAME`) on the real mocap of the shared "
         "corpus (CPU, seeded, progress bar): checkpoint, model card, metrics and plots. "
         "Options after KIND go to its training script (see `simenv train KIND --help`); "
         "--config FILE reads them from a TOML or JSON file."),
        ("eval", cmd_eval, "evaluate a shipped model [NAME] (default predictor-25-25 / "
         "gesture-tcn, the room's recogniser; gesture-classifier: the thesis's transformer) "
         "on its held-out split, or on --data PATH... (--json prints one object); writes "
         "metrics.json and plots (--out DIR). `eval classifier --benchmark [DATASET]` runs "
         "the MSR Action3D / UTKinect / Florence 3D protocols against published figures. "
         "`eval interaction` scores the two-person reaction baselines on the held-out "
         "recordings with the papers' metrics and physics (docs/interaction.md)."),
    ):
        kinds = ("predictor", "classifier", "recogniser", "interaction")
        cmd = sub.add_parser(verb, help=text.split(" (")[0].split(":")[0], description=text)
        cmd.add_argument("kind", choices=kinds, metavar="KIND", help=" or ".join(kinds))
        cmd.add_argument("options", nargs=argparse.REMAINDER, metavar="...",
                         help="options of the training/evaluation script")
        cmd.set_defaults(func=func)
    reh = sub.add_parser("rehearse", help="offline interaction rehearsal in the room",
                         add_help=False, description=(
        "Replay a recorded session (any single-person motion file or bundled asset) in the "
        "virtual room: perception every second, the agent's reactions simulated, outputs "
        "rehearsal.mp4, log.jsonl, summary.json and report.html in --out. Usage: simenv "
        "rehearse SESSION --out DIR [--agent AGENT] [--scenario NAME|FILE] "
        "[--gesture LABEL:ONSET_S:END_S] [--templates DIR] [--no-render]. With --agent "
        "interformer or reactive-gan, a reaction generator answers the session instead: the "
        "generated reaction is retargeted, tracked physically and scored "
        "(python -m simenv.envs.reaction_rehearsal --help)."))
    reh.add_argument("options", nargs=argparse.REMAINDER, metavar="SESSION --out DIR ...",
                     help="options of the rehearsal (python -m simenv.envs.rehearsal --help)")
    reh.set_defaults(func=cmd_rehearse)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``simenv`` command; returns the exit status (2 on a user error)."""
    parser = build_parser()
    # `rehearse` forwards everything, its --help included, to the rehearsal's own parser.
    args, extra = parser.parse_known_args(argv)
    if args.command == "rehearse":
        args.options = [*extra, *args.options]
    elif extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    try:
        return args.func(args)
    except SimenvError as err:
        print(f"simenv {args.command}: error: {err}", file=sys.stderr)
        return EXIT_USER_ERROR

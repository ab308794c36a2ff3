"""Batch scoring: walk files and folders, score each clip, append results as they finish.

This is what ``simenv score PATH...`` runs. The unit of work is a *target*: a
motion file, or a folder that loads as one two-person recording (the CMU
pairs). :func:`find_targets` walks the given paths into targets;
:func:`score_target` scores one into JSON records (one per person, the
:meth:`~simenv.plausibility.report.PlausibilityReport.to_records` contract,
or one ``error`` record naming what was wrong with the input);
:func:`score_batch` runs them locally (``jobs`` worker processes) or on a
Ray cluster (:mod:`simenv.plausibility.distributed`), appending each target's records to
a JSON-lines file and flushing as soon as the target finishes, so a killed
run loses at most the targets in flight and a rerun skips every file already
in the file.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tqdm import tqdm

from simenv.core.errors import ReferenceDataError, SimenvError
from simenv.core.motion import Interaction
from simenv.io.loader import is_laid_out_recording, load, motion_files
from simenv.plausibility.distributed import ray_map
from simenv.plausibility.reference import Reference, calibrate, read_records

if TYPE_CHECKING:  # the scorer pulls in MuJoCo; workers import it when they score
    from simenv.plausibility.metric import ScoreConfig

BACKENDS = ("local", "ray")


def _pair_folder(folder: Path) -> bool:
    """Whether ``folder`` loads as one two-person recording."""
    if len(motion_files(folder)) != 2:
        return False
    try:
        return isinstance(load(folder), Interaction)
    except SimenvError:
        return False


def _walk(folder: Path) -> Iterator[Path]:
    if _pair_folder(folder) or is_laid_out_recording(folder):
        yield folder
        return
    for path, _ in motion_files(folder):
        yield path
    for sub in sorted(p for p in folder.iterdir() if p.is_dir() and not p.name.startswith(".")):
        yield from _walk(sub)


def find_targets(paths: Iterable[str | Path]) -> list[Path]:
    """Scoring targets under ``paths``, in walk order, without duplicates.

    A file is a target as given (an unreadable one fails when scored, with
    its error recorded). A folder is walked recursively: a folder holding one
    two-person recording (two partner files) is one target; otherwise every
    file a reader recognises is one (ASF skeletons are read through their
    AMC motions), then the sub-folders in name order.

    Raises:
        SimenvError: a path does not exist.
    """
    out: list[Path] = []
    seen: set[Path] = set()
    for p in map(Path, paths):
        if not p.exists():
            raise SimenvError("no such file or folder", source=p)
        for target in (_walk(p) if p.is_dir() else [p]):
            key = target.resolve()
            if key not in seen:
                seen.add(key)
                out.append(target)
    return out


@dataclass(frozen=True)
class ScoreJob:
    """What to do with each target (picklable: sent to worker processes).

    Attributes:
        physics: run the body-level metrics (see :func:`simenv.score`).
        report_dir: write an HTML report per target under this folder, or None.
        config: a :class:`~simenv.plausibility.metric.ScoreConfig`, or None for
            the defaults.
        restore_collapsed_bones: read BVH targets (files, and folders of BVH
            pairs) with the reader's repair of the CMU conversions' collapsed
            thorax and wrist bones (:func:`simenv.io.bvh.read`); other
            formats are read as they are, since only BVH conversions drop them.
        reference: a real corpus calibrated by :func:`calibrate_reference`;
            each record then also says where it falls in it (``reference``,
            :meth:`~simenv.plausibility.reference.Reference.judge`).
        joint_map: a TOML joint map applied to every target (see
            :func:`simenv.core.joint_map.read_joint_map`), or None for the
            automatic mapping.
        source: the source kind of every target (``"auto"``: detected per clip;
            :data:`simenv.plausibility.profiles.DECLARABLE_SOURCES`), which picks the
            thresholds' profile.
        units, scale: the targets' length unit or metres per file unit, for readers that
            take them (:func:`simenv.io.load`); None: detected per file.
    """

    physics: bool = True
    report_dir: str | None = None
    config: ScoreConfig | None = None
    restore_collapsed_bones: bool = False
    reference: Reference | None = None
    joint_map: str | None = None
    source: str = "auto"
    units: str | None = None
    scale: float | None = None


def _read_options(target: Path, job: ScoreJob) -> dict[str, Any]:
    """Reader options of ``job`` that apply to ``target`` (BVH-only ones to BVH only)."""
    options: dict[str, Any] = {name: value for name in ("joint_map", "units", "scale")
                               if (value := getattr(job, name)) is not None}
    if not job.restore_collapsed_bones:
        return options
    files = sorted(target.iterdir()) if target.is_dir() else [target]
    files = [f for f in files if f.is_file() and not f.name.startswith(".")]
    bvh_only = bool(files) and all(f.suffix.lower() == ".bvh" for f in files)
    return options | ({"restore_collapsed_bones": True} if bvh_only else {})


def _report_name(target: Path) -> str:
    """A file-system-safe, unique-enough folder name for a target's report."""
    parts = [p for p in target.resolve().parts[-3:] if p not in ("/", "")]
    return "__".join(parts).replace(" ", "_")


def score_target(target: str | Path, job: ScoreJob = ScoreJob()) -> list[dict[str, Any]]:
    """Score one target into JSON-ready records.

    Returns:
        One record per person (``file``, ``person``, ``verdict``, ``score``,
        ``metrics``, ``violations``, ... see
        :meth:`PlausibilityReport.to_records`), plus ``seconds``, ``repairs``
        (the reader's repairs and the retargeting's, e.g. a pelvis derived at the hips'
        midpoint, when they made any), and ``clip``
        (0, 1, ...) when the file holds several clips (e.g. an SBU file with
        two segments, a gesture session), and ``reference`` (where the person
        falls in ``job.reference``) when a reference is given; or, when the
        input is bad (a :class:`SimenvError`, e.g. a clip at another frame
        rate than the reference), a single record ``{"file", "error"}`` with
        the message, so one bad file never stops a batch. Other exceptions
        are bugs and propagate.
    """
    # The scorer pulls in MuJoCo: a batch that only walks, reads or calibrates does not.
    from simenv.plausibility.report import score

    target = Path(target)
    try:
        loaded = load(target, **_read_options(target, job))
        clips = loaded if isinstance(loaded, list) else [loaded]
        reports = [score(clip, physics=job.physics, config=job.config,
                         source=job.source) for clip in clips]
    except SimenvError as exc:
        return [{"file": str(target), "error": str(exc),
                 "error_type": type(exc).__name__}]
    records = []
    for i, (clip, report) in enumerate(zip(clips, reports, strict=True)):
        recs = report.to_records()
        repairs = clip.metadata.get("repairs", [])
        if job.report_dir is not None:
            from simenv.plausibility.html_report import write_report  # MuJoCo, OpenCV

            name = _report_name(target) + (f"__clip{i}" if len(reports) > 1 else "")
            page = write_report(report, Path(job.report_dir) / name)
            for rec in recs:
                # Absolute: the index links it relative to its own folder, whatever the
                # working directory (a relative report folder would otherwise be doubled).
                rec["report"] = str(page.absolute())
        for rec, person in zip(recs, report.people, strict=True):
            rec["file"] = str(target)
            rec["seconds"] = round(report.seconds, 3)
            # The reader's repairs, then what retargeting changed to fit the body.
            body = person.retargeted.repairs if person.retargeted is not None else []
            if repairs or body:
                rec["repairs"] = [*repairs, *body]
            if len(reports) > 1:
                rec["clip"] = i
        records.extend(recs)
    if job.reference is not None:
        try:
            for rec in records:
                rec["reference"] = job.reference.judge(rec)
        except SimenvError as exc:
            return [{"file": str(target), "error": str(exc),
                     "error_type": type(exc).__name__}]
    return records


def index_entries(records: Sequence[dict[str, Any]]
                  ) -> list[tuple[str, str | None, float | None, str]]:
    """Rows of the report index (:func:`simenv.plausibility.html_report.write_index`),
    one per file in first-seen order: ``(file, report page, score, verdict)``, the score
    and verdict of the clip's worst person (and pairwise verdict); ``(file, None, None,
    error message)`` for a file that could not be scored."""
    rows: dict[str, list[dict[str, Any]]] = {}
    for rec in records:
        rows.setdefault(rec["file"], []).append(rec)
    out = []
    for file, recs in rows.items():
        if "error" in recs[0]:
            out.append((file, None, None, recs[0]["error"]))
            continue
        verdicts = [r["verdict"] for r in recs] + [r["interaction"]["verdict"] for r in recs
                                                    if "interaction" in r]
        verdict = "implausible" if "implausible" in verdicts else "plausible"
        out.append((file, recs[0].get("report"), min(r["score"] for r in recs), verdict))
    return out


def done_files(path: str | Path) -> set[str]:
    """Files already recorded in a results JSON-lines file (missing file: none).

    A torn last line (the run was killed mid-write) is ignored, so that file
    is scored again.
    """
    path = Path(path)
    if not path.exists():
        return set()
    done = set()
    with path.open(encoding="utf-8") as fh:
        for line in fh:
            try:
                done.add(json.loads(line)["file"])
            except (json.JSONDecodeError, KeyError, TypeError):
                continue
    return done


def _local(targets: Sequence[Path], job: ScoreJob, jobs: int
           ) -> Iterator[tuple[Path, list[dict[str, Any]]]]:
    if jobs <= 1:
        for t in targets:
            yield t, score_target(t, job)
        return
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(score_target, t, job): t for t in targets}
        for fut in as_completed(futures):
            yield futures[fut], fut.result()


def score_batch(
    targets: Sequence[str | Path],
    job: ScoreJob = ScoreJob(),
    *,
    jobs: int = 1,
    backend: str = "local",
    ray_address: str | None = None,
    out: str | Path | None = None,
    progress: bool = True,
    on_result: Callable[[Path, list[dict[str, Any]]], None] | None = None,
) -> list[dict[str, Any]]:
    """Score many targets; results in completion order.

    Args:
        targets: from :func:`find_targets`.
        job: what to compute per target.
        jobs: worker processes (local backend) or concurrent tasks (Ray).
        backend: ``"local"`` or ``"ray"`` (:func:`simenv.plausibility.distributed.ray_map`).
        ray_address: Ray cluster address (``ray.init(address=...)``); None
            starts a local Ray instance.
        out: JSON-lines file; each target's records are appended and flushed
            as it finishes, and targets whose file is already there are skipped.
        progress: show a progress bar (files, with frames scored so far).
        on_result: called with (target, records) as each target finishes.

    Returns:
        The records of the targets scored in this call (skipped ones excluded).

    Raises:
        SimenvError: unknown backend, or ``jobs < 1``.
    """
    if backend not in BACKENDS:
        raise SimenvError(f"unknown backend {backend!r}; expected one of {', '.join(BACKENDS)}",
                          field="backend")
    if jobs < 1:
        raise SimenvError(f"jobs must be at least 1; got {jobs}", field="jobs")
    paths = [Path(t) for t in targets]
    if out is not None:
        done = done_files(out)
        paths = [p for p in paths if str(p) not in done]
    if backend == "ray":
        results: Iterable[tuple[Path, list[dict[str, Any]]]] = ray_map(
            score_target, paths, job, concurrency=jobs, address=ray_address)
    else:
        results = _local(paths, job, jobs)
    collected: list[dict[str, Any]] = []
    frames = 0
    bar = tqdm(total=len(paths), disable=not progress, desc="score", unit="file")
    if out is not None:
        Path(out).parent.mkdir(parents=True, exist_ok=True)
    fh = None if out is None else Path(out).open("a", encoding="utf-8")
    try:
        for target, records in results:
            if fh is not None:
                for rec in records:
                    fh.write(json.dumps(rec) + "\n")
                fh.flush()
                os.fsync(fh.fileno())
            frames += sum(r.get("frames", 0) for r in records if r.get("person", 0) == 0)
            bar.update(1)
            bar.set_postfix(frames=frames)
            collected.extend(records)
            if on_result is not None:
                on_result(target, records)
    finally:
        bar.close()
        if fh is not None:
            fh.close()
    return collected


def calibrate_reference(paths: Sequence[str | Path], job: ScoreJob = ScoreJob(), *,
                        exclude: Iterable[str | Path] = (), **batch: Any) -> Reference:
    """Score a real corpus and calibrate every metric on it
    (:func:`simenv.plausibility.reference.calibrate`).

    Args:
        paths: real motion files or folders (walked as :func:`find_targets`),
            or ``.jsonl`` results files of an earlier ``simenv score --out``
            run on them (read, not scored again).
        job: how to score them (physics on or off: the same as the generated
            set, so that the same metrics are calibrated); its report folder
            and reference are not used.
        exclude: the generated targets; none may also be in the reference.
        **batch: :func:`score_batch` options (``jobs``, ``backend``, ``progress``...).

    Raises:
        ReferenceDataError: no reference file, a generated target is also a
            reference file, or the reference cannot calibrate (nothing scored,
            too small, bad values).
        SimenvError: a path does not exist.
    """
    results = [Path(p) for p in paths if str(p).endswith(".jsonl") and Path(p).is_file()]
    targets = find_targets([p for p in paths if Path(p) not in results])
    generated = {Path(t).resolve() for t in exclude}
    for t in targets:
        if t.resolve() in generated:
            raise ReferenceDataError("is both a reference (real) and a generated clip: a clip "
                                     "cannot be judged against itself", source=t)
    if not targets and not results:
        raise ReferenceDataError("found no real motion file or results file for the reference",
                                 source=", ".join(map(str, paths)), field="reference")
    records = [rec for r in results for rec in read_records(r)]
    if targets:
        records += score_batch(targets, replace(job, report_dir=None, reference=None), **batch)
    return calibrate(records)


__all__ = ["BACKENDS", "ScoreJob", "calibrate_reference", "done_files", "find_targets",
           "index_entries", "score_batch", "score_target"]

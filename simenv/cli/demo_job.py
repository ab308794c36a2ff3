"""The main job on bundled real data (``simenv demo`` / ``make demo``).

Reads the bundled CMU clips (a walk, 02_01, and the two-person "walk, shake hands" pair,
18_01 + 19_01), retargets each person onto a humanoid fitted to their bone lengths, and writes
per clip an MP4 (humanoid + source joints as a ghost) and an NPZ trajectory, scores each
clip's physical plausibility (:func:`simenv.score`, physics on) into an HTML report
(``report/index.html``), rehearses the virtual room on person B of the handshake
(:data:`REHEARSAL_GESTURE`, ``rehearsal/``), lets the shipped reaction generator
(:data:`REACTION_MODEL`) answer person A of the handshake on simulated bodies
(``reaction/``: generated, retargeted, PD-tracked and scored), plus one ``summary.json``
with residuals, verdicts, the rehearsal's reactions, timings and which frames were
rendered. Offscreen rendering
on a CPU manages a few frames per second, so each video shows every ``stride``-th frame
(playing at ``fps / stride``, i.e. real time); retargeting always covers every frame.

What a person opens: ``index.html`` (:mod:`simenv.cli.demo_page`), which plays every video
and links the plausibility reports, the rehearsal's and the reaction's reports, the
trajectories and the glTF files (``<clip>.glb``: the retargeted bodies animated;
``room.glb``: the rehearsal's room), all by relative links.
"""

from __future__ import annotations

import json
import math
import resource
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import replace
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import cv2

from simenv.assets import HANDSHAKE_PAIR, WALK, asset_path
from simenv.body.render import render_result
from simenv.cli.common import describe, retarget_clip, save_npz, summary
from simenv.cli.demo_page import write_page
from simenv.control import fast_planner
from simenv.core.errors import SimenvError
from simenv.core.motion import Interaction
from simenv.data import interaction_data as idata
from simenv.envs.reaction_rehearsal import (
    generate_reaction,
    rehearse_reaction,
    user_motion,
)
from simenv.envs.rehearsal import rehearse
from simenv.io.loader import load
from simenv.learning.eval_interaction import SHARED
from simenv.models import available
from simenv.models import load as load_model
from simenv.plausibility import report as report_module
from simenv.plausibility.html_report import IndexEntry, report_score, write_index, write_report
from simenv.plausibility.metric import ScoreConfig
from simenv.plausibility.planner import planner_record, planning_cost
from simenv.plausibility.report import score
from simenv.room.export import export_result, export_room
from simenv.room.session import GestureEvent, Session

#: Rendered frames per clip when no stride is given: every 3rd frame of the bundled 120-fps
#: clips (videos at 40 fps, real time). Rendering is a third of the demo's CPU (OSMesa, about
#: 120 ms per frame with shadows); 180 (every 2nd) cost 16 s more of CPU.
RENDER_BUDGET = 120
#: The acknowledgement CMU asks for, repeated verbatim in every summary.
CMU_ACKNOWLEDGEMENT = (
    "The data used in this project was obtained from mocap.cs.cmu.edu. "
    "The database was created with funding from NSF EIA-0196217."
)
#: (output name, bundled asset) of each demo clip.
DEMO_CLIPS = (("walk", WALK), ("handshake", HANDSHAKE_PAIR))
#: The rehearsal's session: person B of the handshake pair, one real recording.
REHEARSAL_SESSION = f"{HANDSHAKE_PAIR}/19_01.bvh"
#: Its labelled gesture (label, onset s, end s). No public recording of the thesis's
#: discomfort gestures exists, so the demo labels a stretch of the real session "smell" to
#: show the mechanism: the agent must press the cigarette out with its own simulated hand.
REHEARSAL_GESTURE = ("smell", 0.5, 1.5)
#: The reaction generator of ``reaction/`` and the session it answers (person A of the
#: handshake pair, who walks up and offers a hand), cut to its first seconds to keep the
#: demo short: tracking both people is most of the demo's CPU (4 s: 117 s of the 244), so
#: the reaction covers as long as the pair's clip shows (2.5 s; ``simenv demo
#: --reaction-seconds``).
REACTION_MODEL = "interformer"
REACTION_FILE = "18_01.bvh"
REACTION_SECONDS = 2.5


def demo_score_config(base: ScoreConfig | None = None) -> ScoreConfig:
    """The demo's scoring: ``base`` (default: ``simenv score``'s,
    :data:`simenv.plausibility.report.DEFAULT_SCORE_CONFIG`, read at the call) planning with
    :data:`simenv.control.FAST` (fewer rolled-out steps than the default planner, less close
    tracking: docs/tracking_speed.md) with ``base``'s seeds, attempts and retry horizon, or
    with ``base``'s own planner where that is the cheaper, and without the assisted PD run
    ``simenv score`` reports beside the verdict as a detail. A smaller search can only fail
    to find a way a larger one finds: a clip it tracks is one the body can perform on its
    own; a failure it reports may be the search's."""
    base = base or report_module.DEFAULT_SCORE_CONFIG
    own = base.mpc
    mpc = min((fast_planner(own), own), key=planning_cost)
    return replace(base, mpc=mpc, tracking_assisted_detail=False)


#: Wall and CPU seconds of each stage of a run, by stage name.
Stages = dict[str, dict[str, float]]


@contextmanager
def stage(stages: Stages, name: str) -> Iterator[None]:
    """Record the block's wall time and CPU time (this process, every thread), seconds, as
    ``stages[name] = {"wall_s", "cpu_s"}``."""
    wall, cpu = time.perf_counter(), time.process_time()
    try:
        yield
    finally:
        stages[name] = {"wall_s": round(time.perf_counter() - wall, 2),
                        "cpu_s": round(time.process_time() - cpu, 2)}


def run_demo(
    out_dir: str | Path, *, stride: int | None = None, width: int = 320, height: int = 240,
    config: ScoreConfig | None = None, reaction_seconds: float | None = None,
) -> dict[str, Any]:
    """Run the demo, write its files into ``out_dir`` and print where they are.

    Args:
        out_dir: output folder (created).
        stride: render every ``stride``-th frame; default chosen per clip so that at most
            :data:`RENDER_BUDGET` frames are rendered.
        width, height: video size in pixels.
        config: the scoring of the clips and of the reaction (default
            :func:`demo_score_config`).
        reaction_seconds: seconds of :data:`REACTION_FILE` the reaction generator answers
            (default :data:`REACTION_SECONDS`).

    Returns:
        The summary written to ``out_dir/summary.json``; ``stages`` holds each stage's wall
        and CPU seconds, ``scoring`` the planner of the verdicts (:func:`planner_record`).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    config = config or demo_score_config()
    reaction_seconds = REACTION_SECONDS if reaction_seconds is None else reaction_seconds
    started, cpu = time.perf_counter(), _cpu_seconds()
    stages: Stages = {}
    clips: dict[str, Any] = {}
    print(f"[physics] scoring in two more processes ({planner_record(config)['text']})",
          flush=True)
    # The physics runs in two more processes beside the rendering (one thread): the
    # reaction (generating it reads the shared corpus on one thread, then both people are
    # tracked) and the clips' scoring, so that the cores stay busy to the end. "spawn": a
    # fresh interpreter, not a fork of one holding an OpenGL context and threads.
    with ProcessPoolExecutor(max_workers=2, mp_context=get_context("spawn")) as physics:
        answer = physics.submit(react, out_dir / "reaction", config, reaction_seconds)
        scoring = {name: physics.submit(score_clip, name, asset, out_dir, config)
                   for name, asset in DEMO_CLIPS}
        for name, asset in DEMO_CLIPS:
            clips[name] = _demo_clip(name, asset, out_dir, stages, stride=stride,
                                     width=width, height=height)
        with stage(stages, "rehearsal"):
            rehearsal = _rehearsal(out_dir / "rehearsal", width=width, height=height)
        index_rows: list[IndexEntry] = []
        for name, job in scoring.items():
            clips[name]["plausibility"], row, stages[f"{name}: score"] = job.result()
            index_rows.append(row)
        reaction, stages["reaction"] = answer.result()
    report = {
        "clips": clips,
        "rehearsal": rehearsal,
        "reaction": reaction,
        "scoring": planner_record(config),
        "stages": stages,
        "total_seconds": round(time.perf_counter() - started, 3),
        "cpu_seconds": round(_cpu_seconds() - cpu, 3),
        "data_acknowledgement": CMU_ACKNOWLEDGEMENT,
    }
    summary_path = out_dir / "summary.json"
    summary_path.write_text(json.dumps(report, indent=2) + "\n")
    index = write_index(index_rows, out_dir / "report")
    page = write_page(out_dir, report)
    print("[time] " + "; ".join(f"{k} {v['wall_s']:.1f} s ({v['cpu_s']:.1f} s CPU)"
                                for k, v in stages.items()))
    print(f"[time] total {report['total_seconds']:.0f} s ({report['cpu_seconds']:.0f} s CPU)")
    print(f"wrote {summary_path}")
    print(f"wrote {index}")
    for name in ("rehearsal.mp4", "report.html", "summary.json", "log.jsonl"):
        print(f"wrote {out_dir / 'rehearsal' / name}")
    if reaction.get("report"):
        print(f"wrote {reaction['report']}")
    for entry in clips.values():
        print(f"wrote {entry['video']}")
        print(f"wrote {entry['npz']}")
        if entry["glb"]:
            print(f"wrote {entry['glb']}")
    print(f"wrote {page}  <- open this page")
    return report


def _cpu_seconds() -> float:
    """CPU seconds of this process (every thread) and of its children that have ended."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), \
        resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _demo_clip(name: str, asset: str, out_dir: Path, stages: Stages, *, stride: int | None,
               width: int, height: int) -> dict[str, Any]:
    """One bundled clip retargeted (NPZ, GLB) and rendered (MP4, WebM, poster); returns its
    summary entry (:func:`score_clip` adds its ``plausibility``)."""
    print(f"[{name}] loading bundled {asset}")
    with stage(stages, f"{name}: retarget"):
        clip = load(asset_path(asset))
        info = describe(clip)
        print(f"[{name}] retargeting {info['frames']} frames ({info['people']} people)")
        result = retarget_clip(clip)
        entry = summary(result)
        npz = save_npz(result, out_dir / f"{name}.npz")
        glb = export_glb(result, out_dir / f"{name}.glb")
    clip_stride = stride or max(1, math.ceil(entry["frames"] / RENDER_BUDGET))
    with stage(stages, f"{name}: render"):
        video = render_result(result, out_dir / f"{name}.mp4", stride=clip_stride,
                              width=width, height=height, progress=True, web=True)
        poster = write_poster(video)
    entry.update(
        asset=asset,
        info=info,
        npz=str(npz),
        glb=None if glb is None else str(glb),
        video=str(video),
        poster=poster,
        render_stride=clip_stride,
        rendered_frames=len(range(0, entry["frames"], clip_stride)),
        video_fps=entry["fps"] / clip_stride,
        render_seconds=stages[f"{name}: render"]["wall_s"],
    )
    print(
        f"[{name}] residual mean {entry['mean_residual_m'] * 100:.2f} cm, p95 "
        f"{entry['p95_residual_m'] * 100:.2f} cm; retarget {entry['seconds']:.2f} s, "
        f"render {entry['render_seconds']:.1f} s ({entry['rendered_frames']} frames, "
        f"every {clip_stride})", flush=True)
    return entry


def score_clip(name: str, asset: str, out_dir: Path, config: ScoreConfig
               ) -> tuple[dict[str, Any], IndexEntry, dict[str, float]]:
    """Score the bundled ``asset``'s physical plausibility with ``config`` into
    ``out_dir/report/<name>/``. Returns the clip's ``plausibility`` summary entry, its row of
    the reports' index and the stage's wall and CPU seconds."""
    stages: Stages = {}
    source = asset_path(asset)
    with stage(stages, name):
        scored = score(load(source), config=config)
        page = write_report(scored, out_dir / "report" / name, video=False)
    entry = {
        "verdict": scored.verdict,
        "report": str(page),
        "people": [{"name": p.name, "verdict": p.verdict, "score": round(p.score, 1),
                    "failed": p.failed} for p in scored.people],
    }
    print(f"[{name}] plausibility: {scored.verdict} (" + ", ".join(
        f"{p.name} {p.score:.0f}" for p in scored.people)
        + f"); scored in {stages[name]['wall_s']:.1f} s", flush=True)
    return entry, (str(source), page, report_score(scored), scored.verdict), stages[name]


def _rehearsal(out_dir: Path, *, width: int, height: int) -> dict[str, Any]:
    """Rehearse the discomfort scenario on :data:`REHEARSAL_SESSION`; returns its reactions."""
    label, onset, end = REHEARSAL_GESTURE
    print(f"[rehearsal] room, discomfort scenario; session {REHEARSAL_SESSION} labelled "
          f"{label!r} at {onset}-{end} s")
    session = Session.load(asset_path(HANDSHAKE_PAIR) / "19_01.bvh",
                           [GestureEvent(label, onset, end)])
    summary = rehearse(session, out_dir, scenario="discomfort", agent="labels",
                       width=width, height=height)
    room = export_room_glb("discomfort", out_dir / "room.glb")
    for r in summary["reactions"]:
        print(f"[rehearsal] {r['gesture']} -> {r['reaction']}: "
              f"{'done' if r['success'] else 'not done: ' + str(r.get('failure'))} "
              f"(decided at {r['t_decision']:.2f} s, "
              f"object changed at {r['t_object_changed']} s)")
    video = out_dir / "rehearsal.mp4"
    return {"session": REHEARSAL_SESSION, "gesture": list(REHEARSAL_GESTURE),
            "reactions": summary["reactions"], "folder": str(out_dir),
            "report": str(out_dir / "report.html"),
            "video": str(video) if video.is_file() else None,
            "poster": write_poster(video) if video.is_file() else None,
            "glb": None if room is None else str(room)}


def reaction_clip(seconds: float = REACTION_SECONDS) -> tuple[Interaction, dict[str, Any]]:
    """Person A of the handshake pair (:data:`REACTION_FILE`, first ``seconds``) and
    :data:`REACTION_MODEL`'s answer, as ``simenv rehearse --agent`` generates it
    (:func:`simenv.envs.reaction_rehearsal.generate_reaction`: 18 keypoints at 25 fps, the
    agent starting where the nearest training window's partner stood; without the shared
    corpus, the mirrored user). Returns the pair and where the agent started."""
    user = user_motion(asset_path(HANDSHAKE_PAIR) / REACTION_FILE)
    user = user.slice(0, max(2, int(round(seconds * user.fps))))
    windows = None
    if SHARED.is_dir():
        every = idata.make_windows(idata.load_recordings(SHARED))
        windows = every.subset(idata.split_by_recording(every).train)
    return generate_reaction(user, load_model(REACTION_MODEL), windows)


def react(out_dir: Path, config: ScoreConfig, seconds: float = REACTION_SECONDS
          ) -> tuple[dict[str, Any], dict[str, float]]:
    """:func:`_reaction`, and its wall and CPU seconds."""
    stages: Stages = {}
    with stage(stages, "reaction"):
        answer = _reaction(out_dir, config, seconds)
    return answer, stages["reaction"]


def _reaction(out_dir: Path, config: ScoreConfig, seconds: float) -> dict[str, Any]:
    """:data:`REACTION_MODEL` answers :data:`REACTION_FILE` of the handshake pair (its first
    ``seconds``), tracked and scored with ``config``: ``simenv rehearse
    --agent`` (:func:`simenv.envs.reaction_rehearsal.rehearse_reaction`) writes
    ``reaction.npz``, ``report/report.html`` and ``summary.json``. Returns the demo's
    record."""
    if REACTION_MODEL not in available():
        print(f"[reaction] {REACTION_MODEL} is not shipped in assets/models; skipped",
              flush=True)
        return {"skipped": f"{REACTION_MODEL} not shipped"}
    session = f"{HANDSHAKE_PAIR}/{REACTION_FILE}"
    print(f"[reaction] {REACTION_MODEL} answers {session} (first "
          f"{seconds:g} s): generate, retarget, track, score", flush=True)
    s = rehearse_reaction(asset_path(HANDSHAKE_PAIR) / REACTION_FILE, REACTION_MODEL,
                          out_dir, seconds=seconds, video=False, config=config,
                          shared=SHARED)
    agent = s["agent"]
    print(f"[reaction] agent {agent['verdict']} (score {agent['score']:.0f}; failed: "
          f"{', '.join(agent['failed']) or 'none'}); interaction {s['interaction']['verdict']}",
          flush=True)
    return {"model": s["model"], "session": session, "frames": s["frames"],
            "agent": {k: agent[k] for k in ("verdict", "score", "failed")},
            "interaction": s["interaction"]["verdict"], "start": s["start"],
            "report": s["report"], "folder": str(out_dir)}


def export_glb(result: Any, path: Path) -> Path | None:
    """The retargeted bodies as an animated GLB (:mod:`simenv.room.export`); None (with the
    reason printed) when it cannot be written."""
    try:
        return export_result(result, path)
    except SimenvError as exc:
        print(f"no {path.name}: {exc}")
        return None


def export_room_glb(scenario: str, path: Path) -> Path | None:
    """The scenario's room as a static GLB; None (reason printed) when it cannot be."""
    try:
        return export_room(scenario, path)
    except SimenvError as exc:
        print(f"no {path.name}: {exc}")
        return None


def write_poster(video: Path) -> str | None:
    """Write the middle frame of ``video`` as ``<video stem>.png`` (the page shows it until
    the video plays); its path, or None when the video cannot be read."""
    cap = cv2.VideoCapture(str(video))
    try:
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        cap.set(cv2.CAP_PROP_POS_FRAMES, max(count // 2, 0))
        ok, frame = cap.read()
    finally:
        cap.release()
    if not ok:
        return None
    path = video.with_suffix(".png")
    cv2.imwrite(str(path), frame)
    return str(path)

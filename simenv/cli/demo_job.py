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
import time
from pathlib import Path
from typing import Any

import cv2

from simenv.assets import HANDSHAKE_PAIR, WALK, asset_path
from simenv.body.render import render_result
from simenv.cli.common import describe, retarget_clip, save_npz, summary
from simenv.cli.demo_page import write_page
from simenv.core.errors import SimenvError
from simenv.envs.reaction_rehearsal import rehearse_reaction
from simenv.envs.rehearsal import rehearse
from simenv.io.loader import load
from simenv.models import available
from simenv.plausibility.html_report import IndexEntry, report_score, write_index, write_report
from simenv.plausibility.report import score
from simenv.room.export import export_result, export_room
from simenv.room.session import GestureEvent, Session

#: Rendered frames per clip when no stride is given (keeps ``make demo`` to a minute or two).
RENDER_BUDGET = 180
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
#: demo short.
REACTION_MODEL = "interformer"
REACTION_FILE = "18_01.bvh"
REACTION_SECONDS = 4.0


def run_demo(
    out_dir: str | Path, *, stride: int | None = None, width: int = 320, height: int = 240
) -> dict[str, Any]:
    """Run the demo, write its files into ``out_dir`` and print where they are.

    Args:
        out_dir: output folder (created).
        stride: render every ``stride``-th frame; default chosen per clip so that at most
            :data:`RENDER_BUDGET` frames are rendered.
        width, height: video size in pixels.

    Returns:
        The summary written to ``out_dir/summary.json``.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    clips: dict[str, Any] = {}
    index_rows: list[IndexEntry] = []
    for name, asset in DEMO_CLIPS:
        clips[name], row = _demo_clip(name, asset, out_dir, stride=stride, width=width,
                                      height=height)
        index_rows.append(row)
    rehearsal = _rehearsal(out_dir / "rehearsal", width=width, height=height)
    reaction = _reaction(out_dir / "reaction")
    report = {
        "clips": clips,
        "rehearsal": rehearsal,
        "reaction": reaction,
        "total_seconds": round(time.perf_counter() - started, 3),
        "data_acknowledgement": CMU_ACKNOWLEDGEMENT,
    }
    summary_path = out_dir / "summary.json"
    summary_path.write_text(json.dumps(report, indent=2) + "\n")
    index = write_index(index_rows, out_dir / "report")
    page = write_page(out_dir, report)
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


def _demo_clip(name: str, asset: str, out_dir: Path, *, stride: int | None, width: int,
               height: int) -> tuple[dict[str, Any], IndexEntry]:
    """One bundled clip: retargeted (NPZ, GLB), rendered (MP4, WebM, poster) and scored
    (report). Returns its summary entry and its row of the reports' index."""
    source = asset_path(asset)
    print(f"[{name}] loading bundled {asset}")
    clip = load(source)
    info = describe(clip)
    print(f"[{name}] retargeting {info['frames']} frames ({info['people']} people)")
    result = retarget_clip(clip)
    entry = summary(result)
    npz = save_npz(result, out_dir / f"{name}.npz")
    glb = export_glb(result, out_dir / f"{name}.glb")
    clip_stride = stride or max(1, math.ceil(entry["frames"] / RENDER_BUDGET))
    render_start = time.perf_counter()
    video = render_result(result, out_dir / f"{name}.mp4", stride=clip_stride,
                          width=width, height=height, progress=True, web=True)
    entry.update(
        asset=asset,
        info=info,
        npz=str(npz),
        glb=None if glb is None else str(glb),
        video=str(video),
        poster=write_poster(video),
        render_stride=clip_stride,
        rendered_frames=len(range(0, entry["frames"], clip_stride)),
        video_fps=entry["fps"] / clip_stride,
        render_seconds=round(time.perf_counter() - render_start, 3),
    )
    print(f"[{name}] scoring physical plausibility")
    scored = score(clip)
    page = write_report(scored, out_dir / "report" / name, video=False)
    row = (str(source), page, report_score(scored), scored.verdict)
    entry["plausibility"] = {
        "verdict": scored.verdict,
        "report": str(page),
        "people": [{"name": p.name, "verdict": p.verdict, "score": round(p.score, 1),
                    "failed": p.failed} for p in scored.people],
    }
    print(f"[{name}] plausibility: {scored.verdict} (" + ", ".join(
        f"{p.name} {p.score:.0f}" for p in scored.people) + ")")
    print(
        f"[{name}] residual mean {entry['mean_residual_m'] * 100:.2f} cm, p95 "
        f"{entry['p95_residual_m'] * 100:.2f} cm; retarget {entry['seconds']:.2f} s, "
        f"render {entry['render_seconds']:.1f} s ({entry['rendered_frames']} frames, "
        f"every {clip_stride})"
    )
    return entry, row


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


def _reaction(out_dir: Path) -> dict[str, Any]:
    """:data:`REACTION_MODEL` answers :data:`REACTION_FILE` of the handshake pair
    (tracked and scored)."""
    if REACTION_MODEL not in available():
        print(f"[reaction] {REACTION_MODEL} is not shipped in assets/models; skipped")
        return {"skipped": f"{REACTION_MODEL} not shipped"}
    session = f"{HANDSHAKE_PAIR}/{REACTION_FILE}"
    print(f"[reaction] {REACTION_MODEL} answers {session} (first "
          f"{REACTION_SECONDS:g} s): generate, retarget, track, score")
    s = rehearse_reaction(asset_path(HANDSHAKE_PAIR) / REACTION_FILE, REACTION_MODEL, out_dir,
                          seconds=REACTION_SECONDS, video=False)
    agent = s["agent"]
    print(f"[reaction] agent {agent['verdict']} (score {agent['score']:.0f}; failed: "
          f"{', '.join(agent['failed']) or 'none'}); interaction {s['interaction']['verdict']}")
    return {"model": s["model"], "session": session, "frames": s["frames"],
            "agent": {k: agent[k] for k in ("verdict", "score", "failed")},
            "interaction": s["interaction"]["verdict"], "start": s["start"],
            "report": s.get("report"), "folder": str(out_dir)}


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

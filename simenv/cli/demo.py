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

What a person opens: ``index.html``, one page in the plausibility reports' style that plays
every video (the VP8 WebM copies browsers decode, a poster frame each), and links the
plausibility reports, the rehearsal's and the reaction's reports, the trajectories and the
glTF files (``<clip>.glb``: the retargeted bodies animated; ``room.glb``: the rehearsal's
room), all by relative links, so the folder can be moved, zipped or served as is.
:func:`check_page` verifies such a page: every link resolves, and a headless Chromium
screenshot (``index.png``) is not blank and shows every video's poster
(``simenv demo --check``, ``make demo-check``).
"""

from __future__ import annotations

import html
import json
import math
import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any
from urllib.parse import quote, unquote, urlsplit

import numpy as np

from simenv.assets import HANDSHAKE_PAIR, WALK, asset_path
from simenv.body.render import render_result
from simenv.cli.main import describe, retarget_clip, save_npz, summary
from simenv.core.errors import SimenvError
from simenv.plausibility.html_report import html_page, report_score, write_index, write_report
from simenv.plausibility.report import score

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
#: File name of the demo's page, and of its screenshot (:func:`check_page`).
PAGE = "index.html"
SCREENSHOT = "index.png"
#: Browser window (pixels) of the screenshot: wide enough for the page, tall enough for
#: every video on it.
SCREENSHOT_SIZE = (1100, 3000)
#: Fraction of a poster's height (from the top) matched in the screenshot: the browser
#: draws the video controls over the rest.
POSTER_MATCH_FRACTION = 0.6
#: Chromium's command names (Debian: ``chromium``).
CHROMIUM = ("chromium", "chromium-browser", "google-chrome")


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
    from simenv.io.loader import load

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    clips: dict[str, Any] = {}
    index_rows = []
    for name, asset in DEMO_CLIPS:
        source = asset_path(asset)
        print(f"[{name}] loading bundled {asset}")
        clip = load(source)
        info = describe(clip)
        print(f"[{name}] retargeting {info['frames']} frames ({info['people']} people)")
        result = retarget_clip(clip)
        entry = summary(result)
        npz = save_npz(result, out_dir / f"{name}.npz")
        glb = _export(result, out_dir / f"{name}.glb")
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
            poster=_poster(video),
            render_stride=clip_stride,
            rendered_frames=len(range(0, entry["frames"], clip_stride)),
            video_fps=entry["fps"] / clip_stride,
            render_seconds=round(time.perf_counter() - render_start, 3),
        )
        print(f"[{name}] scoring physical plausibility")
        scored = score(clip)
        page = write_report(scored, out_dir / "report" / name, video=False)
        index_rows.append((str(source), page, report_score(scored), scored.verdict))
        entry["plausibility"] = {
            "verdict": scored.verdict,
            "report": str(page),
            "people": [{"name": p.name, "verdict": p.verdict, "score": round(p.score, 1),
                        "failed": p.failed} for p in scored.people],
        }
        clips[name] = entry
        print(f"[{name}] plausibility: {scored.verdict} (" + ", ".join(
            f"{p.name} {p.score:.0f}" for p in scored.people) + ")")
        print(
            f"[{name}] residual mean {entry['mean_residual_m'] * 100:.2f} cm, p95 "
            f"{entry['p95_residual_m'] * 100:.2f} cm; retarget {entry['seconds']:.2f} s, "
            f"render {entry['render_seconds']:.1f} s ({entry['rendered_frames']} frames, "
            f"every {clip_stride})"
        )
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


def _rehearsal(out_dir: Path, *, width: int, height: int) -> dict[str, Any]:
    """Rehearse the discomfort scenario on :data:`REHEARSAL_SESSION`; returns its reactions."""
    from simenv.envs.rehearsal import rehearse
    from simenv.room.session import GestureEvent, Session

    label, onset, end = REHEARSAL_GESTURE
    print(f"[rehearsal] room, discomfort scenario; session {REHEARSAL_SESSION} labelled "
          f"{label!r} at {onset}-{end} s")
    session = Session.load(asset_path(HANDSHAKE_PAIR) / "19_01.bvh",
                           [GestureEvent(label, onset, end)])
    summary = rehearse(session, out_dir, scenario="discomfort", agent="labels",
                       width=width, height=height)
    room = _export_room("discomfort", out_dir / "room.glb")
    for r in summary["reactions"]:
        print(f"[rehearsal] {r['gesture']} -> {r['reaction']}: "
              f"{'done' if r['success'] else 'not done'} (decided at {r['t_decision']:.2f} s, "
              f"object changed at {r['t_object_changed']} s)")
    video = out_dir / "rehearsal.mp4"
    return {"session": REHEARSAL_SESSION, "gesture": list(REHEARSAL_GESTURE),
            "reactions": summary["reactions"], "folder": str(out_dir),
            "report": str(out_dir / "report.html"),
            "video": str(video) if video.is_file() else None,
            "poster": _poster(video) if video.is_file() else None,
            "glb": None if room is None else str(room)}


def _reaction(out_dir: Path) -> dict[str, Any]:
    """:data:`REACTION_MODEL` answers :data:`REACTION_FILE` of the handshake pair
    (tracked and scored)."""
    from simenv.envs.reaction_rehearsal import rehearse_reaction
    from simenv.models import available

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


def _export(result: Any, path: Path) -> Path | None:
    """The retargeted bodies as an animated GLB (:mod:`simenv.room.export`); None (with the
    reason printed) when it cannot be written."""
    from simenv.room.export import export_result

    try:
        return export_result(result, path)
    except SimenvError as exc:
        print(f"no {path.name}: {exc}")
        return None


def _export_room(scenario: str, path: Path) -> Path | None:
    """The scenario's room as a static GLB; None (reason printed) when it cannot be."""
    from simenv.room.export import export_room

    try:
        return export_room(scenario, path)
    except SimenvError as exc:
        print(f"no {path.name}: {exc}")
        return None


def _poster(video: Path) -> str | None:
    """Write the middle frame of ``video`` as ``<video stem>.png`` (the page shows it until
    the video plays); its path, or None when the video cannot be read."""
    import cv2

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


# -- the page ---------------------------------------------------------------------------


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _seconds(t: float | None) -> str:
    """A time cell, s; a dash for a time that never came."""
    return "&ndash;" if t is None else f"{t:.2f}"


def write_page(out_dir: str | os.PathLike[str], report: dict[str, Any]) -> Path:
    """Write ``out_dir/index.html``: the demo's videos and links to everything it wrote.

    Args:
        out_dir: the demo's folder (every file linked must lie inside it).
        report: the summary :func:`run_demo` returns (paths absolute or relative to the
            working directory, as written to ``summary.json``); missing parts (no
            rehearsal, a skipped reaction, no glTF) are left out of the page.

    Returns:
        The page's path. Its links and sources are relative to ``out_dir``.
    """
    out = Path(out_dir)

    def rel(path: str | os.PathLike[str] | None) -> str | None:
        if not path or not Path(path).exists():
            return None
        return quote(Path(os.path.relpath(Path(path).absolute(), out.absolute())).as_posix())

    def link(path: str | os.PathLike[str] | None, text: str) -> str:
        href = rel(path)
        return "" if href is None else f"<a href='{_e(href)}'>{_e(text)}</a>"

    def film(mp4: str | None, poster: str | None, caption: str) -> str:
        if mp4 is None or rel(mp4) is None:
            return "<p class='na'>No video.</p>"
        webm = Path(mp4).with_suffix(".webm")
        # The browser plays the first source it can: VP8 WebM (it cannot decode mp4v).
        sources = "".join(f"<source src='{_e(rel(src))}' type='{kind}'>" for src, kind in
                          ((webm, "video/webm"), (mp4, "video/mp4")) if rel(src))
        size = ""
        if poster and rel(poster):
            import cv2

            h, w = cv2.imread(str(poster)).shape[:2]
            size = f" poster='{_e(rel(poster))}' width='{w}' height='{h}'"
        return (f"<video class='demo' controls loop muted preload='metadata'{size}>{sources}"
                f"</video><p class='small'>{_e(caption)} {link(mp4, 'download the MP4')}</p>")

    parts = ["<h1>simenv demo</h1>",
             "<p>Real motion capture retargeted onto simulated bodies fitted to each "
             "person, judged for physical plausibility, and a virtual room rehearsed on a "
             "recorded person. Every file of the run is in this folder; links are relative, "
             "so the folder can be moved or shared as it is. 3D files (.glb) open in any "
             "glTF viewer (Blender, Windows 3D Viewer, online glTF viewers).</p>"]
    rows = []
    for name, clip in report.get("clips", {}).items():
        plaus = clip.get("plausibility", {})
        people = "; ".join(f"{p['name']}: <span class='{_e(p['verdict'])}'>{_e(p['verdict'])}"
                           f"</span> ({p['score']:.0f})" for p in plaus.get("people", []))
        rows.append(
            f"<tr><td><a href='#{_e(name)}'>{_e(name)}</a></td><td>{_e(clip.get('asset'))}</td>"
            f"<td class='num'>{clip['frames']}</td><td class='num'>{clip['fps']:g}</td>"
            f"<td class='num'>{1000 * clip['mean_residual_m']:.2f}</td>"
            f"<td class='num'>{1000 * clip['p95_residual_m']:.2f}</td><td>{people}</td>"
            f"<td>{link(plaus.get('report'), 'report')}</td></tr>")
    if rows:
        parts.append("<h2>Clips</h2><table><tr><th>clip</th><th>bundled file</th>"
                     "<th>frames</th><th>fps</th><th>keypoint residual mean (mm)</th>"
                     "<th>p95 (mm)</th><th>plausibility (score)</th><th></th></tr>"
                     + "".join(rows) + "</table>"
                     + f"<p>{link(Path(out) / 'report' / 'index.html', 'All plausibility reports')}"
                     "</p>")
    for name, clip in report.get("clips", {}).items():
        files = " &middot; ".join(x for x in (
            link(clip.get("plausibility", {}).get("report"), "plausibility report"),
            link(clip.get("glb"), f"{name}.glb (3D, animated)"),
            link(clip.get("npz"), f"{name}.npz (qpos trajectory)")) if x)
        parts.append(
            f"<h2 id='{_e(name)}'>{_e(name)}</h2>"
            + film(clip.get("video"), clip.get("poster"),
                   f"Retargeted humanoid(s), source joints as a ghost; one frame in "
                   f"{clip.get('render_stride', 1)} rendered, played in real time.")
            + f"<p>{files}</p>")
    reh = report.get("rehearsal")
    if reh:
        reactions = "".join(
            f"<tr><td>{_e(r['gesture'])}</td><td>{_e(r['reaction'])}</td>"
            f"<td class='{'pass' if r['success'] else 'fail'}'>"
            f"{'done' if r['success'] else 'not done'}</td>"
            f"<td class='num'>{_seconds(r['t_decision'])}</td>"
            f"<td class='num'>{_seconds(r['t_object_changed'])}</td></tr>"
            for r in reh.get("reactions", []))
        files = " &middot; ".join(x for x in (
            link(reh.get("report"), "rehearsal report"),
            link(Path(reh["folder"]) / "summary.json", "summary.json"),
            link(Path(reh["folder"]) / "log.jsonl", "log.jsonl"),
            link(reh.get("glb"), "room.glb (3D)")) if x)
        parts.append(
            f"<h2 id='rehearsal'>Rehearsal in the room</h2><p>Session {_e(reh['session'])}, "
            f"labelled gesture {_e(reh['gesture'][0])} at {reh['gesture'][1]:g}-"
            f"{reh['gesture'][2]:g} s.</p>"
            + film(reh.get("video"), reh.get("poster"), "The room as the agent sees it.")
            + "<table><tr><th>gesture</th><th>reaction</th><th>result</th>"
            "<th>decided (s)</th><th>object changed (s)</th></tr>" + reactions + "</table>"
            + f"<p>{files}</p>")
    answer = report.get("reaction")
    if answer and "skipped" not in answer:
        agent = answer["agent"]
        parts.append(
            f"<h2 id='reaction'>Generated reaction</h2><p>{_e(answer['model'])} answers "
            f"{_e(answer['session'])} ({answer['frames']} frames): agent "
            f"<span class='{_e(agent['verdict'])}'>{_e(agent['verdict'])}</span> "
            f"(score {agent['score']:.0f}; failed: {_e(', '.join(agent['failed']) or 'none')}"
            f"), interaction {_e(answer['interaction'])}. "
            f"{link(answer.get('report'), 'reaction report')}</p>")
    parts.append(f"<p class='small'>{link(Path(out) / 'summary.json', 'summary.json')} "
                 f"&middot; ran in {report.get('total_seconds', 0):.0f} s &middot; "
                 f"{_e(report.get('data_acknowledgement', ''))}</p>")
    page = out / PAGE
    page.write_text(html_page("simenv demo", "\n".join(parts)), encoding="utf-8")
    return page


# -- checking the page ---------------------------------------------------------------------

_LINK = re.compile(r"""\b(?:href|src|poster)\s*=\s*(?:'([^']*)'|"([^"]*)")""")


def page_links(page: str | os.PathLike[str]) -> list[str]:
    """Every ``href``, ``src`` and ``poster`` of an HTML page, as written."""
    text = Path(page).read_text(encoding="utf-8")
    return [html.unescape(a or b) for a, b in _LINK.findall(text)]


def check_links(page: str | os.PathLike[str]) -> dict[str, int]:
    """Check that the links of ``page`` and of the HTML pages it links, recursively,
    are relative and resolve to existing files (in-page anchors and ``data:`` images
    aside).

    Returns:
        ``{"pages": pages checked, "links": links resolved}``.

    Raises:
        SimenvError: an absolute link (it breaks when the folder moves) or a missing
            target, naming the page and the link.
    """
    todo, seen, links = [Path(page).resolve()], set(), 0
    while todo:
        current = todo.pop()
        if current in seen:
            continue
        seen.add(current)
        for href in page_links(current):
            parts = urlsplit(href)
            if href.startswith("#") or parts.scheme == "data":
                continue
            if parts.scheme or parts.netloc or href.startswith("/"):
                raise SimenvError(f"link {href!r} is not relative: it breaks when the "
                                  "folder moves", source=current)
            target = (current.parent / unquote(parts.path)).resolve()
            if not target.is_file():
                raise SimenvError(f"link {href!r} points to a missing file", source=current)
            links += 1
            if target.suffix == ".html":
                todo.append(target)
    return {"pages": len(seen), "links": links}


def find_chromium() -> str | None:
    """Path of a Chromium (or Chrome) executable, or None."""
    return next((p for p in map(shutil.which, CHROMIUM) if p), None)


def screenshot(page: str | os.PathLike[str], png: str | os.PathLike[str], *,
               size: tuple[int, int] = SCREENSHOT_SIZE, chromium: str | None = None) -> Path:
    """Screenshot ``page`` with headless Chromium into ``png`` (``size`` pixels).

    Raises:
        SimenvError: no Chromium, or it failed.
    """
    exe = chromium or find_chromium()
    if exe is None:
        raise SimenvError("no chromium to take the screenshot (Debian: apt-get install "
                          "chromium; or `make demo-check`, which installs it)")
    png = Path(png).absolute()
    with tempfile.TemporaryDirectory(prefix="simenv-chromium-") as profile:
        cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
               "--mute-audio", "--force-device-scale-factor=1", f"--user-data-dir={profile}",
               f"--window-size={size[0]},{size[1]}", "--virtual-time-budget=5000",
               f"--screenshot={png}", Path(page).absolute().as_uri()]
        try:
            done = subprocess.run(cmd, capture_output=True, text=True, timeout=180,
                                  check=False)
        except subprocess.TimeoutExpired:
            raise SimenvError("chromium took over 180 s for the screenshot",
                              source=page) from None
    if not png.is_file():
        raise SimenvError(f"chromium wrote no screenshot (exit {done.returncode}): "
                          f"{done.stderr.strip()[-500:]}", source=page)
    return png


_PROBE = """<!DOCTYPE html><html><body>{videos}<pre id='result'>[]</pre><script>
const vids = [...document.querySelectorAll('video')];
const out = vids.map(() => null);
vids.forEach((v, i) => {{
  const done = (ok) => {{
    out[i] = {{src: v.currentSrc, ok: ok, width: v.videoWidth, height: v.videoHeight,
              duration: v.duration}};
    document.getElementById('result').textContent = JSON.stringify(out);
  }};
  v.addEventListener('loadeddata', () => done(true));
  v.addEventListener('error', () => done(false), true);  // a <source>'s error: capture it
  v.preload = 'auto';
  v.load();
}});
</script></body></html>
"""


def check_videos(page: str | os.PathLike[str], *, chromium: str | None = None
                 ) -> list[dict[str, Any]]:
    """Load every ``<video>`` of ``page`` in headless Chromium, as the page declares it
    (same sources, same folder), and check that the browser decodes its first frame.

    Returns:
        Per video: the ``src`` the browser picked, ``width``/``height`` (pixels) and
        ``duration`` (s).

    Raises:
        SimenvError: no Chromium, or a video the browser cannot play.
    """
    exe = chromium or find_chromium()
    if exe is None:
        raise SimenvError("no chromium to load the videos (Debian: apt-get install chromium)")
    page = Path(page)
    videos = re.findall(r"<video\b.*?</video>", page.read_text(encoding="utf-8"), re.S)
    if not videos:
        return []
    probe = page.with_name(".simenv-video-probe.html")
    probe.write_text(_PROBE.format(videos="".join(videos)), encoding="utf-8")
    try:
        with tempfile.TemporaryDirectory(prefix="simenv-chromium-") as profile:
            done = subprocess.run(
                [exe, "--headless", "--no-sandbox", "--disable-gpu", "--mute-audio",
                 f"--user-data-dir={profile}", "--virtual-time-budget=10000", "--dump-dom",
                 probe.absolute().as_uri()], capture_output=True, text=True, timeout=180,
                check=False)
    finally:
        probe.unlink()
    found = re.search(r"<pre id=\"result\">(.*?)</pre>", done.stdout, re.S)
    results = json.loads(html.unescape(found.group(1))) if found else []
    if len(results) != len(videos) or not all(results):
        raise SimenvError(f"chromium reported {sum(map(bool, results))} of {len(videos)} "
                          f"videos loaded (exit {done.returncode})", source=page)
    for r in results:
        if not (r["ok"] and r["width"] > 0 and r["duration"] > 0):
            raise SimenvError(f"chromium cannot play the video {r['src'] or '(no source)'}: "
                              f"{r}", source=page)
        r["src"] = unquote(Path(urlsplit(r["src"]).path).name)
    return results


def check_screenshot(png: str | os.PathLike[str], posters: list[str | os.PathLike[str]],
                     *, min_match: float = 0.9) -> dict[str, Any]:
    """Check a page's screenshot: it is not blank, and each poster image is visible in it
    (normalised cross-correlation of the poster's top :data:`POSTER_MATCH_FRACTION`, above
    the video controls, with the screenshot >= ``min_match``, at a place with image
    content, not background).

    Returns:
        ``{"content_fraction"}`` (pixels unlike the white background) and ``"posters"``:
        per poster its file, best match and top-left pixel (x, y).

    Raises:
        SimenvError: a blank screenshot, or a poster not found.
    """
    import cv2

    shot = cv2.imread(str(png))
    if shot is None:
        raise SimenvError("cannot read the screenshot", source=png)
    content = float((np.abs(shot.astype(int) - 255).sum(axis=2) > 30).mean())
    if content < 0.01 or shot.std() < 5:
        raise SimenvError(f"the screenshot is blank ({100 * content:.2f} % non-background "
                          "pixels)", source=png)
    found = []
    for poster in posters:
        image = cv2.imread(str(poster))
        # The browser draws the video's controls over the bottom of the poster.
        top = image[:max(1, int(POSTER_MATCH_FRACTION * image.shape[0]))]
        scores = cv2.matchTemplate(shot, top, cv2.TM_CCOEFF_NORMED)
        _, best, _, (x, y) = cv2.minMaxLoc(scores)
        region = shot[y:y + image.shape[0], x:x + image.shape[1]]
        if best < min_match or region.std() < 5:
            raise SimenvError(f"the video poster {Path(poster).name} is not visible in the "
                              f"screenshot (best match {best:.2f} at {x}, {y})", source=png)
        found.append({"file": str(poster), "match": round(float(best), 4), "at": [x, y]})
    return {"content_fraction": round(content, 4), "posters": found}


def check_page(page: str | os.PathLike[str], *, shot: bool = True,
               chromium: str | None = None) -> dict[str, Any]:
    """Check a demo page: its links (:func:`check_links`) and, with ``shot``, in headless
    Chromium: every video plays (:func:`check_videos`), and a screenshot next to the page
    (:data:`SCREENSHOT`, :func:`check_screenshot` with every video poster of the page).

    Raises:
        SimenvError: the first check that fails.
    """
    page = Path(page)
    result: dict[str, Any] = check_links(page)
    if shot:
        result["videos"] = check_videos(page, chromium=chromium)
        png = screenshot(page, page.with_name(SCREENSHOT), chromium=chromium)
        text = page.read_text(encoding="utf-8")
        posters = [page.parent / unquote(html.unescape(p))
                   for p in re.findall(r"poster='([^']*)'", text)]
        result.update(check_screenshot(png, posters), screenshot=str(png))
    return result

"""The demo's page (``index.html``): writing it, and checking it the way a person's browser
would.

:func:`write_page` shows every video of a demo run (the VP8 WebM copies browsers decode, a
poster frame each) and links the plausibility reports, the rehearsal's and the reaction's
reports, the trajectories and the glTF files, all by relative links, so the folder can be
moved, zipped or served as is. :func:`check_page` verifies such a page: every link resolves,
and a headless Chromium screenshot (:data:`SCREENSHOT`) is not blank and shows every video's
poster (``simenv demo --check``, ``make demo-check``).
"""

from __future__ import annotations

import html
import json
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any
from urllib.parse import quote, unquote, urlsplit

import cv2
import numpy as np

from simenv.core.errors import SimenvError
from simenv.plausibility.html_report import html_page

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


# -- writing the page -----------------------------------------------------------------------


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _seconds(t: float | None) -> str:
    """A time cell, s; a dash for a time that never came."""
    return "&ndash;" if t is None else f"{t:.2f}"


def _rel(out: Path, path: str | os.PathLike[str] | None) -> str | None:
    """``path`` relative to the page's folder ``out``, URL-quoted; None when it is not there."""
    if not path or not Path(path).exists():
        return None
    return quote(Path(os.path.relpath(Path(path).absolute(), out.absolute())).as_posix())


def _link(out: Path, path: str | os.PathLike[str] | None, text: str) -> str:
    """A relative link to ``path``; empty when the file is not there."""
    href = _rel(out, path)
    return "" if href is None else f"<a href='{_e(href)}'>{_e(text)}</a>"


def _film(out: Path, mp4: str | None, poster: str | None, caption: str) -> str:
    """The video ``mp4`` (its WebM copy first) with its poster, caption and download link."""
    if mp4 is None or _rel(out, mp4) is None:
        return "<p class='na'>No video.</p>"
    webm = Path(mp4).with_suffix(".webm")
    # The browser plays the first source it can: VP8 WebM (it cannot decode mp4v).
    sources = "".join(f"<source src='{_e(_rel(out, src))}' type='{kind}'>" for src, kind in
                      ((webm, "video/webm"), (mp4, "video/mp4")) if _rel(out, src))
    size = ""
    if poster and _rel(out, poster):
        h, w = cv2.imread(str(poster)).shape[:2]
        size = f" poster='{_e(_rel(out, poster))}' width='{w}' height='{h}'"
    return (f"<video class='demo' controls loop muted preload='metadata'{size}>{sources}"
            f"</video><p class='small'>{_e(caption)} {_link(out, mp4, 'download the MP4')}</p>")


def _clip_table(out: Path, clips: dict[str, Any]) -> list[str]:
    """The table of clips (residuals, plausibility per person); nothing without clips."""
    rows = []
    for name, clip in clips.items():
        plaus = clip.get("plausibility", {})
        people = "; ".join(f"{p['name']}: <span class='{_e(p['verdict'])}'>{_e(p['verdict'])}"
                           f"</span> ({p['score']:.0f})" for p in plaus.get("people", []))
        rows.append(
            f"<tr><td><a href='#{_e(name)}'>{_e(name)}</a></td><td>{_e(clip.get('asset'))}</td>"
            f"<td class='num'>{clip['frames']}</td><td class='num'>{clip['fps']:g}</td>"
            f"<td class='num'>{1000 * clip['mean_residual_m']:.2f}</td>"
            f"<td class='num'>{1000 * clip['p95_residual_m']:.2f}</td><td>{people}</td>"
            f"<td>{_link(out, plaus.get('report'), 'report')}</td></tr>")
    if not rows:
        return []
    reports = _link(out, Path(out) / "report" / "index.html", "All plausibility reports")
    return ["<h2>Clips</h2><table><tr><th>clip</th><th>bundled file</th>"
            "<th>frames</th><th>fps</th><th>keypoint residual mean (mm)</th>"
            "<th>p95 (mm)</th><th>plausibility (score)</th><th></th></tr>"
            + "".join(rows) + "</table>" + f"<p>{reports}</p>"]


def _clip_section(out: Path, name: str, clip: dict[str, Any]) -> str:
    """One clip: its video and its files."""
    files = " &middot; ".join(x for x in (
        _link(out, clip.get("plausibility", {}).get("report"), "plausibility report"),
        _link(out, clip.get("glb"), f"{name}.glb (3D, animated)"),
        _link(out, clip.get("npz"), f"{name}.npz (qpos trajectory)")) if x)
    return (f"<h2 id='{_e(name)}'>{_e(name)}</h2>"
            + _film(out, clip.get("video"), clip.get("poster"),
                    f"Retargeted humanoid(s), source joints as a ghost; one frame in "
                    f"{clip.get('render_stride', 1)} rendered, played in real time.")
            + f"<p>{files}</p>")


def _rehearsal_section(out: Path, reh: dict[str, Any]) -> str:
    """The room rehearsal: its video, the reactions and their times, its files."""
    reactions = "".join(
        f"<tr><td>{_e(r['gesture'])}</td><td>{_e(r['reaction'])}</td>"
        f"<td class='{'pass' if r['success'] else 'fail'}'>"
        f"{'done' if r['success'] else 'not done'}</td>"
        f"<td class='num'>{_seconds(r['t_decision'])}</td>"
        f"<td class='num'>{_seconds(r['t_object_changed'])}</td></tr>"
        for r in reh.get("reactions", []))
    files = " &middot; ".join(x for x in (
        _link(out, reh.get("report"), "rehearsal report"),
        _link(out, Path(reh["folder"]) / "summary.json", "summary.json"),
        _link(out, Path(reh["folder"]) / "log.jsonl", "log.jsonl"),
        _link(out, reh.get("glb"), "room.glb (3D)")) if x)
    return (f"<h2 id='rehearsal'>Rehearsal in the room</h2><p>Session {_e(reh['session'])}, "
            f"labelled gesture {_e(reh['gesture'][0])} at {reh['gesture'][1]:g}-"
            f"{reh['gesture'][2]:g} s.</p>"
            + _film(out, reh.get("video"), reh.get("poster"), "The room as the agent sees it.")
            + "<table><tr><th>gesture</th><th>reaction</th><th>result</th>"
            "<th>decided (s)</th><th>object changed (s)</th></tr>" + reactions + "</table>"
            + f"<p>{files}</p>")


def _reaction_section(out: Path, answer: dict[str, Any]) -> str:
    """The generated reaction: the agent's and the interaction's verdicts, its report."""
    agent = answer["agent"]
    return (f"<h2 id='reaction'>Generated reaction</h2><p>{_e(answer['model'])} answers "
            f"{_e(answer['session'])} ({answer['frames']} frames): agent "
            f"<span class='{_e(agent['verdict'])}'>{_e(agent['verdict'])}</span> "
            f"(score {agent['score']:.0f}; failed: {_e(', '.join(agent['failed']) or 'none')}"
            f"), interaction {_e(answer['interaction'])}. "
            f"{_link(out, answer.get('report'), 'reaction report')}</p>")


def _cpu(report: dict[str, Any]) -> str:
    """`` (N s of CPU)`` of a run that recorded it, else nothing."""
    cpu = report.get("cpu_seconds")
    return "" if cpu is None else f" ({cpu:.0f} s of CPU)"


def write_page(out_dir: str | os.PathLike[str], report: dict[str, Any]) -> Path:
    """Write ``out_dir/index.html``: the demo's videos and links to everything it wrote.

    Args:
        out_dir: the demo's folder (every file linked must lie inside it).
        report: the summary :func:`simenv.cli.demo_job.run_demo` returns (paths absolute
            or relative to the working directory, as written to ``summary.json``); missing
            parts (no rehearsal, a skipped reaction, no glTF) are left out of the page.

    Returns:
        The page's path. Its links and sources are relative to ``out_dir``.
    """
    out = Path(out_dir)
    parts = ["<h1>simenv demo</h1>",
             "<p>Real motion capture retargeted onto simulated bodies fitted to each "
             "person, judged for physical plausibility, and a virtual room rehearsed on a "
             "recorded person. Every file of the run is in this folder; links are relative, "
             "so the folder can be moved or shared as it is. 3D files (.glb) open in any "
             "glTF viewer (Blender, Windows 3D Viewer, online glTF viewers).</p>"]
    clips = report.get("clips", {})
    parts += _clip_table(out, clips)
    scoring = report.get("scoring")
    if scoring:
        parts.append(f"<p>Physics verdicts (clips and generated reaction): {_e(scoring['text'])}"
                     ". A clip this planner tracks is one the body can perform on its own "
                     "muscles; a tracking failure may be its smaller search's.</p>")
    parts += [_clip_section(out, name, clip) for name, clip in clips.items()]
    reh = report.get("rehearsal")
    if reh:
        parts.append(_rehearsal_section(out, reh))
    answer = report.get("reaction")
    if answer and "skipped" not in answer:
        parts.append(_reaction_section(out, answer))
    parts.append(f"<p class='small'>{_link(out, Path(out) / 'summary.json', 'summary.json')} "
                 f"&middot; ran in {report.get('total_seconds', 0):.0f} s{_cpu(report)} "
                 "&middot; "
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

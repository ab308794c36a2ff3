"""HTML pages of plausibility reports: one page per scored clip, and a batch index.

API (stable; used by ``simenv score --report DIR``)
    ``write_report(report, out_dir, *, video=True, max_video_frames=150) -> Path``
        Writes one clip's page into ``out_dir`` (created) and returns the path of
        ``out_dir/report.html``. Give every clip its own directory (the CLI uses
        ``DIR/<safe stem>``): the file names below are fixed, so a second report
        written into the same directory replaces the first.
    ``write_index(entries, out_dir) -> Path``
        Writes ``out_dir/index.html``, a table of scored files linking to their
        pages. ``entries`` is a sequence of :data:`IndexEntry` tuples
        ``(file, page, score, status)``:

        * ``file``: the file scored (shown as given);
        * ``page``: path of the clip's page as returned by :func:`write_report`
          (absolute, or relative to the working directory like any path), or None
          for a file that could not be scored; the index links it relative to
          ``out_dir``, so the folder can be moved;
        * ``score``: 0-100 (e.g. :func:`report_score`), or None;
        * ``status``: the verdict (``"plausible"`` / ``"implausible"``) or, for a
          row whose ``page`` is None, the error message.

        The page names (``report.html`` per clip, ``index.html`` for the batch)
        differ, so the index may share a directory with a clip's page.
    ``report_score(report) -> float``
        The clip's score for the index: the minimum over its people's scores and
        its pairwise metrics' scores (same scale as
        :attr:`~simenv.plausibility.report.PersonReport.score`).
    ``html_page(title, body) -> str``
        A whole page around ``body`` (HTML) with these pages' inline style (tables,
        ``pass`` / ``fail`` / ``na`` / ``small`` / ``num`` classes); the rehearsal
        report uses it too.

Files of one clip's page, all next to ``report.html``
    ``p<i>_<metric>.png``
        Timeline of person ``i``'s metric: the per-frame values (``timeline``,
        in ``timeline_unit``) against ``frame_threshold`` (dashed), violation
        runs shaded red (the same frame ranges as the report's ``violations``,
        so a clip-level failure without one frame over the per-frame limit
        shades the whole clip). Only metrics that are available and have at
        least one finite per-frame value get a plot.
    ``pair_<metric>.png``
        The same for the pairwise metrics of a two-person clip.
    ``video.mp4`` and ``video.webm``
        With ``video=True`` and a retargeted body: the fitted humanoid(s) (both
        people in one scene for a two-person clip, else person 0) with the
        source keypoints as a ghost. Frames inside a violation run get a red
        border and the failing metric names. The MP4 (``mp4v``) is the
        download; the page plays the WebM (VP8), because browsers do not decode
        ``mp4v``. At most ``max_video_frames`` frames, at most
        :data:`VIDEO_MAX_FPS` frames per simulated second, played in real
        time. When rendering is impossible (no OpenGL) the page says why
        instead.

All text from the report (file and motion names, reasons, details) is
HTML-escaped. The page has no external resources (inline CSS, relative links
to its PNGs and videos), so the directory can be copied or served as is.

Cost (1-s, 120-fps walk, 2 shared CPU cores under load): scoring 1.6 s; the page
with its 11 plots 4.7 s (0.2-0.4 s a plot, plus ~3 s for the first matplotlib
import); the 30-frame video another ~25 s. Rendering dominates (~8-14 frames/s
at 320x240 on an idle CPU core, far less on a loaded one), so the video costs
up to ``max_video_frames`` renders whatever the clip length.
"""

from __future__ import annotations

import html
import logging
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from urllib.parse import quote

import numpy as np

from simenv.body.humanoid import build_scene
from simenv.core.errors import SimenvError
from simenv.plausibility.report import (
    VERDICT_IMPLAUSIBLE,
    VERDICT_PLAUSIBLE,
    PersonReport,
    PlausibilityReport,
    metric_score,
    violation_ranges,  # the report's own violation ranges: page, video and JSON agree
)
from simenv.plausibility.timeline import MetricResult

log = logging.getLogger(__name__)

#: File name of a clip's page inside its ``out_dir``.
REPORT_PAGE = "report.html"
#: File name of the batch index inside its ``out_dir``.
INDEX_PAGE = "index.html"
#: Highest frame rate of the video (frames per simulated second): more frames would
#: cost rendering time without showing anything new.
VIDEO_MAX_FPS = 30.0
#: Video frame size in pixels (width, height).
VIDEO_SIZE = (320, 240)
#: Thickness (px) of the red border on video frames inside a violation run.
BORDER_PX = 5
#: At most this many failing metric names are written on one video frame.
MAX_LABEL_LINES = 4

#: One row of the batch index: (file, page or None, score or None, verdict or error message).
IndexEntry = tuple[str, str | os.PathLike[str] | None, float | None, str]

_RED_RGB = (230, 30, 30)

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:1.5em;
color:#222;max-width:1100px}
h1{font-size:1.4em;word-break:break-all}h2{font-size:1.2em;margin-top:1.6em}
h3{font-size:1.05em}
table{border-collapse:collapse;margin:.5em 0}th,td{border:1px solid #ccc;padding:3px 8px;
text-align:left;vertical-align:top}th{background:#f3f3f3}td.num{text-align:right;
font-variant-numeric:tabular-nums}
.plausible,.pass{color:#187a2f;font-weight:600}.implausible,.fail,.error{color:#c0202a;
font-weight:600}.na{color:#777}.small{font-size:.85em;color:#555}
img.timeline{display:block;max-width:100%;margin:.4em 0}
"""


# -- public API -------------------------------------------------------------------


def report_score(report: PlausibilityReport) -> float:
    """Score (0-100) of a whole clip: the minimum over the people's scores and the
    pairwise metrics' scores; 100 when nothing is available."""
    scores = [p.score for p in report.people]
    if report.interaction is not None:
        scores += [s for s in map(metric_score, report.interaction.values()) if s is not None]
    return float(min(scores)) if scores else 100.0


def write_report(report: PlausibilityReport, out_dir: str | os.PathLike[str], *,
                 video: bool = True, max_video_frames: int = 150) -> Path:
    """Write the HTML page of one scored clip (module docstring: files and layout).

    Args:
        report: the result of :func:`simenv.score`.
        out_dir: directory of this clip's page (created); give each clip its own.
        video: render the retargeted body with violations highlighted (needs a
            report scored with ``physics=True`` and OpenGL).
        max_video_frames: cap on the number of rendered video frames (>= 1).

    Returns:
        Path of ``out_dir/report.html``.

    Raises:
        SimenvError: ``report`` is not a :class:`PlausibilityReport`, or bad
            ``max_video_frames``.
    """
    if not isinstance(report, PlausibilityReport):
        raise SimenvError(f"write_report expects a PlausibilityReport; got "
                          f"{type(report).__name__}")
    if max_video_frames < 1:
        raise SimenvError(f"max_video_frames={max_video_frames}; expected >= 1")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    parts = [_header(report)]
    for p in report.people:
        parts.append(_person_section(p, report, out))
    if report.interaction is not None:
        parts.append(_pair_section(report, out))
    if video:
        parts.append(_video_section(report, out, max_video_frames))

    title = f"simenv plausibility: {Path(report.source).name}"
    page = out / REPORT_PAGE
    page.write_text(html_page(title, "\n".join(parts)), encoding="utf-8")
    return page


def write_index(entries: Iterable[IndexEntry], out_dir: str | os.PathLike[str]) -> Path:
    """Write the batch index page ``out_dir/index.html``.

    Args:
        entries: one :data:`IndexEntry` ``(file, page, score, status)`` per file,
            in display order (module docstring). A row with ``page`` None is an
            error row and ``status`` is its message.
        out_dir: directory of the index (created); links to the pages are
            relative to it.

    Returns:
        Path of ``out_dir/index.html``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows, counts = [], {VERDICT_PLAUSIBLE: 0, VERDICT_IMPLAUSIBLE: 0, "error": 0}
    for file, page, score, status in entries:
        if page is None:
            counts["error"] += 1
            rows.append(f"<tr><td>{_e(file)}</td><td class='error'>error</td><td></td>"
                        f"<td class='small'>{_e(status)}</td></tr>")
            continue
        counts[status] = counts.get(status, 0) + 1
        # Both absolute: a page named relative to the working directory is linked from
        # the index's own folder, wherever that is.
        href = quote(Path(os.path.relpath(Path(page).absolute(), out.absolute())).as_posix())
        shown = "" if score is None else f"{score:.1f}"
        rows.append(f"<tr><td><a href='{_e(href)}'>{_e(file)}</a></td>"
                    f"<td class='{_e(status)}'>{_e(status)}</td><td class='num'>{shown}</td>"
                    f"<td></td></tr>")
    total = sum(counts.values())
    summary = (f"<p>{total} file(s): {counts[VERDICT_PLAUSIBLE]} plausible, "
               f"{counts[VERDICT_IMPLAUSIBLE]} implausible, {counts['error']} not scored.</p>")
    table = ("<table><tr><th>file</th><th>verdict</th><th>score</th><th>error</th></tr>"
             + "".join(rows) + "</table>")
    page_path = out / INDEX_PAGE
    page_path.write_text(html_page("simenv plausibility: batch",
                                   f"<h1>Plausibility scores</h1>{summary}{table}"),
                         encoding="utf-8")
    return page_path


# -- HTML pieces --------------------------------------------------------------------


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def html_page(title: str, body: str) -> str:
    """A complete HTML page with the reports' inline style (no external resources): its
    ``title`` (escaped) and ``body`` (HTML, inserted as is)."""
    return (f"<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            f"<title>{_e(title)}</title><style>{_CSS}</style></head>\n<body>\n{body}\n"
            f"</body></html>\n")


def _fmt(x: float) -> str:
    """Number for a table cell: 4 significant digits; NaN (not computed) as a dash."""
    if math.isnan(x):
        return "&ndash;"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.4g}"


def _verdict_span(verdict: str) -> str:
    return f"<span class='{_e(verdict)}'>{_e(verdict)}</span>"


def _profile_row(report: PlausibilityReport) -> list[tuple[str, str]]:
    """The "judged by" row: the thresholds' profile and the source kind behind it."""
    kind = report.source_kind
    if kind is None:
        return []
    what = ("the motion-capture thresholds (defaults)" if kind.profile == "mocap" else
            f"the {kind.profile} depth-camera profile (thresholds from that sensor family's "
            "real clips)")
    if kind.rigid_bones:
        what += ("; bone lengths at the motion-capture tolerance, since the file's bones are "
                 "fixed offsets")
    return [("judged by", f"{_e(what)}; source kind {_e(kind.kind)} ({_e(kind.how)})")]


def _header(report: PlausibilityReport) -> str:
    p0 = report.people[0]
    names = ", ".join(p.name for p in report.people)
    rows = [
        ("file", _e(report.source)),
        ("motion", _e(names)),
        ("people", str(len(report.people))),
        ("frames", f"{p0.frames} ({p0.frames / p0.fps:.2f} s)" if p0.fps else str(p0.frames)),
        ("fps", _fmt(p0.fps)),
        ("physics", "on" if report.physics else "off (joint-level metrics only)"),
        *_profile_row(report),
        ("verdict", _verdict_span(report.verdict)),
        ("score", f"{report_score(report):.1f} / 100"),
        ("scored in", f"{report.seconds:.1f} s"),
    ]
    table = "".join(f"<tr><th>{k}</th><td>{v}</td></tr>" for k, v in rows)
    failing = []
    for p in report.people:
        failing += [f"person {p.person}: {v['metric']} (frames {v['start_frame']}-"
                    f"{v['end_frame']})" for v in p.violations]
    if report.interaction is not None:
        failing += [f"pair: {v['metric']} (frames {v['start_frame']}-{v['end_frame']})"
                    for v in violation_ranges(report.interaction)]
    fail_html = ("<p><b>Violations:</b> " + "; ".join(_e(f) for f in failing) + "</p>"
                 if failing else "<p>No violations.</p>")
    return (f"<h1>Plausibility report: {_e(Path(report.source).name)}</h1>"
            f"<table>{table}</table>{fail_html}")


def _metrics_table(metrics: dict[str, MetricResult], basis: dict[str, str]) -> str:
    head = ("<tr><th>metric</th><th>value</th><th>unit</th><th>threshold</th>"
            "<th>per-frame limit</th><th>status</th><th>basis</th><th>details / reason</th></tr>")
    rows = []
    for name, m in metrics.items():
        if m.passed is None:
            status = "<span class='na'>not available</span>"
            note = f"<span class='na'>{_e(m.reason)}</span>"
        else:
            status = "<span class='pass'>pass</span>" if m.passed else \
                "<span class='fail'>FAIL</span>"
            note = ", ".join(f"{_e(k)}={_fmt(v)}" for k, v in m.details.items())
            note = f"<span class='small'>{note}</span>"
        rows.append(f"<tr><td>{_e(name)}</td><td class='num'>{_fmt(m.value)}</td>"
                    f"<td>{_e(m.unit)}</td><td class='num'>{_fmt(m.threshold)}</td>"
                    f"<td>{_fmt(m.frame_threshold)} {_e(m.timeline_unit)}</td>"
                    f"<td>{status}</td><td>{_e(basis.get(name, ''))}</td><td>{note}</td></tr>")
    return f"<table>{head}{''.join(rows)}</table>"


def _violations_table(violations: list[dict], fps: float) -> str:
    if not violations:
        return ""
    rows = "".join(
        f"<tr><td>{_e(v['metric'])}</td><td class='num'>{v['start_frame']}</td>"
        f"<td class='num'>{v['end_frame']}</td><td class='num'>"
        f"{v['start_frame'] / fps:.2f}-{(v['end_frame'] + 1) / fps:.2f}</td>"
        f"<td class='num'>{_fmt(float(v['worst_value']))}</td></tr>"
        for v in violations)
    return ("<h3>Violations</h3><table><tr><th>metric</th><th>first frame</th>"
            "<th>last frame</th><th>time (s)</th><th>worst per-frame value</th></tr>"
            f"{rows}</table>")


def _plots(metrics: dict[str, MetricResult], violations: list[dict], fps: float,
           prefix: str, out: Path) -> str:
    """Write one timeline PNG per plottable metric; returns their <img> tags."""
    tags = []
    for name, m in metrics.items():
        if m.passed is None or not np.isfinite(m.timeline).any():
            continue
        runs = [(v["start_frame"], v["end_frame"]) for v in violations if v["metric"] == name]
        file = f"{prefix}_{name}.png"
        _plot_timeline(m, runs, fps, out / file)
        tags.append(f"<img class='timeline' src='{_e(quote(file))}' "
                    f"alt='{_e(name)} timeline'>")
    return "".join(tags)


def _person_section(p: PersonReport, report: PlausibilityReport, out: Path) -> str:
    title = f"Person {p.person}: {p.name}"
    info = f"verdict {_verdict_span(p.verdict)}, score {p.score:.1f}"
    if p.retargeted is not None:
        info += (f"; retargeted body {p.retargeted.humanoid.dims.height:.2f} m, "
                 f"{p.retargeted.humanoid.total_mass:.1f} kg, mean keypoint residual "
                 f"{1000 * p.retargeted.mean_residual:.1f} mm")
    elif report.physics:
        info += "; no retargeted body"
    violations = p.violations
    return (f"<h2>{_e(title)}</h2><p>{info}</p>"
            f"{_metrics_table(p.metrics, p.basis)}"
            f"{_violations_table(violations, p.fps)}"
            f"<h3>Timelines</h3>"
            f"{_plots(p.metrics, violations, p.fps, f'p{p.person}', out) or '<p>none</p>'}")


def _pair_section(report: PlausibilityReport, out: Path) -> str:
    pair = report.interaction
    assert pair is not None
    fps = report.people[0].fps
    violations = violation_ranges(pair)
    failed = any(m.passed is False for m in pair.values())
    verdict = VERDICT_IMPLAUSIBLE if failed else VERDICT_PLAUSIBLE
    return (f"<h2>Interaction (pairwise metrics)</h2><p>verdict {_verdict_span(verdict)}</p>"
            f"{_metrics_table(pair, report.interaction_basis)}"
            f"{_violations_table(violations, fps)}"
            f"{_plots(pair, violations, fps, 'pair', out)}")


# -- timeline plots ------------------------------------------------------------------


def _plot_timeline(m: MetricResult, runs: Sequence[tuple[int, int]], fps: float,
                   path: Path) -> None:
    """PNG of ``m.timeline`` (T,) against ``m.frame_threshold``, ``runs`` shaded."""
    # Figure + Agg canvas directly: no pyplot global state, no GUI backend.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    values = np.asarray(m.timeline, dtype=np.float64)
    finite = np.isfinite(values)
    fig = Figure(figsize=(8.0, 2.3), dpi=90)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    frames = np.arange(len(values))
    ax.plot(frames, np.where(finite, values, np.nan), color="#1f5fa8", lw=1.2)
    ax.axhline(m.frame_threshold, color="#c0202a", ls="--", lw=1.0)
    for s, e in runs:
        ax.axvspan(s - 0.5, e + 0.5, color="#e33", alpha=0.18, lw=0)
    diverged = np.isposinf(values)
    if diverged.any():
        # Diverged frames (inf) cannot be drawn as a line: mark them on the top edge.
        top = max(m.frame_threshold, np.nanmax(values[finite], initial=0.0))
        ax.plot(frames[diverged], np.full(diverged.sum(), top), "v", color="#c0202a", ms=4)
    status = "not available" if m.passed is None else ("pass" if m.passed else "FAIL")
    title = f"{m.name}: {m.value:.4g} {m.unit} (threshold {m.threshold:.4g}) {status}"
    title += f"   dashed: per-frame limit {m.frame_threshold:.4g} {m.timeline_unit}"
    if runs:
        title += "; shaded: violations"
    if diverged.any():
        title += "; v: diverged (inf)"
    ax.set_title(title, fontsize=8.5, loc="left")
    ax.set_xlim(-0.5, max(len(values) - 0.5, 0.5))
    ax.set_xlabel("frame (top axis: seconds)", fontsize=8)
    ax.set_ylabel(m.timeline_unit, fontsize=8)
    ax.tick_params(labelsize=7)
    if fps > 0:
        sec = ax.secondary_xaxis("top", functions=(lambda f: f / fps, lambda t: t * fps))
        sec.tick_params(labelsize=7)
    # Fixed margins: tight_layout would draw the figure twice (half the plotting time).
    fig.subplots_adjust(left=0.09, right=0.985, bottom=0.2, top=0.76)
    fig.savefig(path, format="png")


# -- video ---------------------------------------------------------------------------


def _frame_labels(report: PlausibilityReport, n_frames: int) -> list[list[str]]:
    """Per frame (T lists) the failing metrics whose violation run covers it, labelled
    with the person (``P0 foot_skate``) when there are two people."""
    labels: list[list[str]] = [[] for _ in range(n_frames)]
    two = len(report.people) > 1
    groups = [(f"P{p.person} " if two else "", p.violations) for p in report.people]
    if report.interaction is not None:
        groups.append(("pair ", violation_ranges(report.interaction)))
    for prefix, violations in groups:
        for v in violations:
            for t in range(v["start_frame"], min(v["end_frame"], n_frames - 1) + 1):
                if prefix + v["metric"] not in labels[t]:
                    labels[t].append(prefix + v["metric"])
    return labels


def _highlight(frame: np.ndarray, labels: Sequence[str]) -> np.ndarray:
    """Red border and the failing metric names (bottom banner) on an RGB frame."""
    import cv2  # only when a video is rendered

    frame = np.ascontiguousarray(frame)
    h, w = frame.shape[:2]
    cv2.rectangle(frame, (0, 0), (w - 1, h - 1), _RED_RGB, BORDER_PX * 2)
    lines = list(labels[:MAX_LABEL_LINES])
    if len(labels) > MAX_LABEL_LINES:
        lines.append(f"+{len(labels) - MAX_LABEL_LINES} more")
    # White names on a red banner along the bottom edge: readable on floor and sky alike.
    line_h = 14
    top = h - BORDER_PX - 4 - line_h * len(lines)
    cv2.rectangle(frame, (0, top), (w - 1, h - 1), _RED_RGB, -1)
    for i, line in enumerate(lines):
        cv2.putText(frame, line, (BORDER_PX + 4, top + line_h * (i + 1) - 2),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.42, (255, 255, 255), 1, cv2.LINE_AA)
    return frame


def _video_scene(report: PlausibilityReport
                 ) -> tuple[object, np.ndarray, list[np.ndarray], list[str]] | None:
    """(MjModel, qpos (T, nq), ghost keypoints [(T, K, 3)] per person, the K keypoint
    names) of the video, or None when no person has a retargeted body. Two fitted
    people share one scene; if it cannot be built the video shows person 0."""
    fitted = [p.retargeted for p in report.people if p.retargeted is not None]
    if not fitted:
        return None
    if len(fitted) == 2:
        try:
            scene = build_scene([r.humanoid for r in fitted], ["actor", "reactor"])
        except SimenvError as exc:
            log.warning("two-person scene failed (%s); video shows person 0", exc)
        else:
            # render_frames draws one edge list for every ghost: keep the keypoints both have.
            a, b = (list(r.keypoint_names) for r in fitted)
            common = [k for k in a if k in b]
            ghosts = [r.targets[:, [n.index(k) for k in common]]
                      for r, n in zip(fitted, (a, b), strict=True)]
            return scene.model, scene.combine_qpos([r.qpos for r in fitted]), ghosts, common
    r = fitted[0]
    return r.humanoid.model, r.qpos, [r.targets], list(r.keypoint_names)


def _video_section(report: PlausibilityReport, out: Path, max_frames: int) -> str:
    """Render the videos and return their HTML (or a note saying why there is none)."""
    # OpenCV and the GL backend load only when a video is rendered.
    from simenv.body.render import keypoint_edges, render_frames, write_video

    scene = _video_scene(report)
    if scene is None:
        why = "physics was off" if not report.physics else "no body could be fitted"
        return f"<h2>Video</h2><p class='na'>No video: {_e(why)}.</p>"
    model, qpos, ghosts, names = scene
    T = len(qpos)
    fps = float(report.people[0].fps)
    stride = max(math.ceil(fps / VIDEO_MAX_FPS), math.ceil(T / max_frames), 1)
    labels = _frame_labels(report, T)
    try:
        frames = []
        raw = render_frames(model, qpos, width=VIDEO_SIZE[0], height=VIDEO_SIZE[1],
                            ghost=ghosts, ghost_edges=keypoint_edges(names), fps=fps,
                            stride=stride, max_frames=max_frames)
        for k, frame in enumerate(raw):
            t = k * stride
            # A frame stands for the `stride` frames up to the next rendered one, so a
            # violation shorter than the stride still shows.
            shown: list[str] = []
            for lab in labels[t:t + stride]:
                shown += [x for x in lab if x not in shown]
            frames.append(_highlight(frame, shown) if shown else frame)
        mp4 = write_video(frames, out / "video.mp4", fps=fps / stride)
        webm = _write_webm(frames, out / "video.webm", fps=fps / stride)
    except SimenvError as exc:
        log.warning("no video for %s: %s", report.source, exc)
        return f"<h2>Video</h2><p class='na'>No video: {_e(exc)}</p>"
    who = "both people" if len(ghosts) == 2 else f"person 0 ({report.people[0].name})"
    sources = (f"<source src='{quote(webm.name)}' type='video/webm'>" if webm else "")
    sources += f"<source src='{quote(mp4.name)}' type='video/mp4'>"
    return (f"<h2>Video</h2><p class='small'>Retargeted body of {_e(who)} (ghost: source "
            f"keypoints); every {stride}th frame, real time; red border: frame inside a "
            f"violation run, with the failing metrics. "
            f"<a href='{quote(mp4.name)}'>download MP4</a></p>"
            f"<video controls loop muted width='{VIDEO_SIZE[0] * 2}'>{sources}</video>")


def _write_webm(frames: Sequence[np.ndarray], path: Path, fps: float) -> Path | None:
    """VP8 WebM of RGB frames (browsers play it, unlike OpenCV's ``mp4v``); None when
    this OpenCV build cannot encode VP8."""
    # The video writer of every render: it opens the encoder without printing.
    from simenv.body.render import WEBM_CODECS, VideoFile

    try:
        with VideoFile(path, fps, WEBM_CODECS) as video:
            for frame in frames:
                video.write(frame)
    except SimenvError as exc:
        log.warning("no VP8 WebM (%s); the page links the MP4 only", exc)
        return None
    return path

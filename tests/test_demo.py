"""The demo's page (simenv.cli.demo_page.write_page) and the report writers' links: every link is
relative and resolves after the folder is moved; a headless Chromium screenshot of the page
is not blank and shows the video's poster (skipped when Chromium is absent: `make
demo-check` installs it and checks the full demo's page)."""

from __future__ import annotations

import os
import shutil
from dataclasses import replace
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import cv2
import numpy as np
import pytest

from simenv.assets import WALK, asset_path
from simenv.body.render import render_result
from simenv.body.retarget import retarget
from simenv.cli.common import save_npz, summary
from simenv.cli.demo_job import (
    demo_score_config,
    export_glb,
    stage,
    write_poster,
)
from simenv.cli.demo_page import (
    check_links,
    check_page,
    check_screenshot,
    check_videos,
    find_chromium,
    page_links,
    write_page,
)
from simenv.cli.main import main
from simenv.control import FAST, MPCConfig
from simenv.core.errors import SimenvError
from simenv.envs.rehearsal import rehearse
from simenv.io.loader import load
from simenv.plausibility.html_report import report_score, write_index, write_report
from simenv.plausibility.metric import DEFAULT_SCORE_CONFIG, ScoreConfig
from simenv.plausibility.planner import planner_record, planning_cost
from simenv.plausibility.report import score
from simenv.room.session import GestureEvent, Session

needs_chromium = pytest.mark.skipif(find_chromium() is None, reason=(
    "no chromium (Debian: apt-get install chromium; `make demo-check` installs it)"))


#: The demo folder as `make demo DEMO_OUT=out/walk/demo` names it: nested, and relative to
#: the working directory (the report index once linked its pages relative to the latter).
NESTED_OUT = Path("out", "walk", "demo")


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small demo folder written as run_demo writes it, into :data:`NESTED_OUT` under the
    working directory, then moved elsewhere: 0.5 s of the bundled walk retargeted, 3 frames
    rendered (MP4 + WebM + poster), scored without physics into a report and the reports'
    index, exported to GLB, and the same 0.5 s rehearsed in the room (labelled "smell")
    with its report and video."""
    root = tmp_path_factory.mktemp("demo")
    cwd = os.getcwd()
    os.chdir(root)  # paths as run_demo gets them: relative to the working directory
    try:
        out = NESTED_OUT
        clip = load(asset_path(WALK)).slice(0, 60)
        result = retarget(clip)
        entry = summary(result)
        video = render_result(result, out / "walk.mp4", stride=20, web=True)
        scored = score(clip, physics=False)
        page = write_report(scored, out / "report" / "walk", video=False)
        write_index([(WALK, page, report_score(scored), scored.verdict)], out / "report")
        entry.update(asset=WALK, npz=str(save_npz(result, out / "walk.npz")),
                     glb=str(export_glb(result, out / "walk.glb")), video=str(video),
                     poster=write_poster(video), render_stride=20,
                     plausibility={"verdict": scored.verdict, "report": str(page), "people": [
                         {"name": p.name, "verdict": p.verdict, "score": p.score, "failed": []}
                         for p in scored.people]})
        gesture = ("smell", 0.2, 0.5)
        folder = out / "rehearsal"
        reh = rehearse(Session(clip, (GestureEvent(*gesture),)), folder,
                       scenario="discomfort", agent="labels", width=320, height=240)
        rehearsal = {"session": WALK, "gesture": list(gesture), "reactions": reh["reactions"],
                     "folder": str(folder), "report": str(folder / "report.html"),
                     "video": str(folder / "rehearsal.mp4"),
                     "poster": write_poster(folder / "rehearsal.mp4"), "glb": None}
        write_page(out, {"clips": {"walk": entry}, "rehearsal": rehearsal,
                         "scoring": planner_record(demo_score_config()),
                         "total_seconds": 1.0, "cpu_seconds": 1.5,
                         "data_acknowledgement": "mocap.cs.cmu.edu"})
    finally:
        os.chdir(cwd)
    moved = root / "moved" / "elsewhere"
    shutil.move(str(root / out), str(moved))
    return moved


class _Links(HTMLParser):
    """Every ``href``, ``src`` and ``poster`` attribute of a page, as the browser reads it
    (entities decoded)."""

    def __init__(self) -> None:
        super().__init__()
        self.links: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.links += [v for k, v in attrs if k in ("href", "src", "poster") and v]


def test_every_page_links_relative_to_its_own_folder(demo_dir: Path):
    pages = sorted(demo_dir.rglob("*.html"))
    # The demo page, the clip's report, the reports' index and the rehearsal's report.
    assert [p.relative_to(demo_dir).as_posix() for p in pages] == [
        "index.html", "rehearsal/report.html", "report/index.html", "report/walk/report.html"]
    resolved = 0
    for page in pages:
        parser = _Links()
        parser.feed(page.read_text(encoding="utf-8"))
        for link in parser.links:
            parts = urlsplit(link)
            if link.startswith("#") or parts.scheme == "data":
                continue
            assert not (parts.scheme or parts.netloc or link.startswith("/")), (page, link)
            assert (page.parent / unquote(parts.path)).is_file(), (page, link)
            resolved += 1
    assert resolved > 20


def test_page_links_are_relative_and_survive_a_move(demo_dir: Path):
    page = demo_dir / "index.html"
    links = page_links(page)
    for name in ("walk.webm", "walk.mp4", "walk.png", "walk.glb", "walk.npz",
                 "report/walk/report.html"):
        assert name in links
    assert not any(str(demo_dir.parent.parent) in link for link in links)
    checked = check_links(page)
    # The page, the clip's plausibility report with its timeline PNGs, the reports' index
    # and the rehearsal's report.
    assert checked["pages"] == 4 and checked["links"] > 10
    text = page.read_text()
    assert "<video" in text and "type='video/webm'" in text
    assert text.index("walk.webm") < text.index("walk.mp4'")  # browsers play VP8, not mp4v


def test_page_states_the_planner_of_its_verdicts(demo_dir: Path):
    text = (demo_dir / "index.html").read_text()
    demo, shipped = demo_score_config().mpc, DEFAULT_SCORE_CONFIG.mpc
    assert (f"{demo.n_samples} samples per replan" in text
            and f"simenv score plans with {shipped.n_samples} samples" in text)
    assert "ran in 1 s (2 s of CPU)" in text


def test_demo_scores_as_simenv_score_with_the_fast_planner():
    config, shipped = demo_score_config(), DEFAULT_SCORE_CONFIG
    # FAST's search, the scorer's seeds and retries; every threshold is the scorer's.
    assert config.mpc == replace(FAST, seed=shipped.mpc.seed, attempts=shipped.mpc.attempts,
                                 retry_horizon_s=shipped.mpc.retry_horizon_s,
                                 nthread=shipped.mpc.nthread)
    assert planning_cost(config.mpc) < planning_cost(shipped.mpc)
    assert replace(config, mpc=shipped.mpc, tracking_assisted_detail=True) == shipped
    assert not config.tracking_assisted_detail
    # A cheaper base (the suite's quick planner) is kept as it is.
    quick = ScoreConfig(mpc=MPCConfig(n_samples=16, horizon_s=0.25))
    assert demo_score_config(quick).mpc == quick.mpc
    record = planner_record(config)
    mpc = shipped.mpc
    assert record["n_samples"] == config.mpc.n_samples and record["attempts"] == mpc.attempts
    assert (f"up to {mpc.attempts} seeds (the further ones over {mpc.retry_horizon_s:g} s)"
            in record["text"])


def test_stage_records_wall_and_cpu_seconds():
    stages: dict[str, dict[str, float]] = {}
    with stage(stages, "busy"):
        sum(i * i for i in range(1_000_000))
    assert set(stages["busy"]) == {"wall_s", "cpu_s"} and stages["busy"]["cpu_s"] > 0


def test_check_links_catches_absolute_and_missing_links(tmp_path: Path):
    (tmp_path / "a.html").write_text(f"<a href='{tmp_path / 'b.txt'}'>x</a>")
    (tmp_path / "b.txt").write_text("b")
    with pytest.raises(SimenvError, match="not relative"):
        check_links(tmp_path / "a.html")
    (tmp_path / "a.html").write_text("<img src='gone.png'><a href='#top'>top</a>")
    with pytest.raises(SimenvError, match="missing file"):
        check_links(tmp_path / "a.html")


def test_score_report_index_links_resolve_from_a_relative_folder(tmp_path: Path, capsys,
                                                                 monkeypatch):
    # `simenv score --report rep` run inside the folder: the index once linked
    # rep/<clip>/report.html from inside rep/.
    monkeypatch.chdir(tmp_path)
    assert main(["score", str(asset_path(WALK)), "--no-physics", "--report", "rep"]) == 0
    capsys.readouterr()
    shutil.move("rep", "moved")
    checked = check_links(tmp_path / "moved" / "index.html")
    assert checked["pages"] == 2


@needs_chromium
def test_screenshot_shows_the_page_and_its_video(demo_dir: Path):
    result = check_page(demo_dir / "index.html")
    # Chromium decodes each WebM's first frame (the walk's: 3 frames at 120 / 20 fps).
    video, room = result["videos"]
    assert video["src"] == "walk.webm" and (video["width"], video["height"]) == (320, 240)
    assert video["duration"] == pytest.approx(0.5, abs=0.01)
    assert room["src"] == "rehearsal.webm" and (room["width"], room["height"]) == (320, 240)
    assert result["content_fraction"] > 0.02
    poster, room_poster = result["posters"]
    assert poster["match"] > 0.9 and Path(poster["file"]).name == "walk.png"
    assert room_poster["match"] > 0.9 and Path(room_poster["file"]).name == "rehearsal.png"
    shot = cv2.imread(result["screenshot"])
    x, y = poster["at"]
    region = shot[y:y + 240, x:x + 320]
    # The humanoid and the floor, not page background.
    assert region.std() > 10 and (np.abs(region.astype(int) - 255).sum(axis=2) > 30).mean() > 0.5
    # An image that is not on the page is not found.
    other = demo_dir / "other.png"
    cv2.imwrite(str(other), np.random.default_rng(0).integers(0, 255, (240, 320, 3), np.uint8))
    with pytest.raises(SimenvError, match="not visible"):
        check_screenshot(result["screenshot"], [other])


@needs_chromium
def test_browser_cannot_play_an_mp4v_only_video(demo_dir: Path):
    # Why the page leads with the WebM: OpenCV's pip build writes MPEG-4 part 2 (mp4v).
    page = demo_dir / "mp4_only.html"
    page.write_text("<video controls><source src='walk.mp4' type='video/mp4'></video>")
    try:
        with pytest.raises(SimenvError, match="cannot play"):
            check_videos(page)
    finally:
        page.unlink()

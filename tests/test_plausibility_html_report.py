"""HTML plausibility report and batch index, on the bundled real CMU walk (02_01) and
the bundled handshake pair (18_01 + 19_01), each sliced short to keep scoring and
rendering quick."""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np
import pytest

import simenv
from simenv.assets import HANDSHAKE_PAIR, WALK, asset_path
from simenv.core.errors import SimenvError
from simenv.plausibility.html_report import (
    INDEX_PAGE,
    REPORT_PAGE,
    report_score,
    write_index,
    write_report,
)
from simenv.plausibility.metric import ScoreConfig
from simenv.plausibility.metric_registry import PAIR_METRICS, PERSON_METRICS

FRAMES = 120  # 1 s of the 120-fps walk
VIDEO_FRAMES = 6  # rendering costs ~0.1-0.8 s a frame on a shared CPU
BODY_METRICS = ("joint_limits", "self_penetration", "root_residual", "balance", "tracking")


@pytest.fixture(scope="module")
def walk() -> simenv.Motion:
    return simenv.load(asset_path(WALK)).slice(0, FRAMES)


@pytest.fixture(scope="module")
def clean(walk, walk_1s_report, tmp_path_factory):
    """(report, page) of the real walk, scored with physics (the session's shared run of
    these FRAMES)."""
    report = walk_1s_report
    assert report.people[0].frames == len(walk)
    return report, write_report(report, tmp_path_factory.mktemp("clean"),
                                max_video_frames=VIDEO_FRAMES)


@pytest.fixture(scope="module")
def sunk(walk, tmp_path_factory):
    """(report, page) of the walk lowered by 10 cm: the feet are in the floor. Physics
    fits and renders the body; tracking is off, as the page's violation comes from the
    ground contact, not the controller (whose verdicts the clean walk tests)."""
    lowered = walk.with_positions(walk.positions - np.array([0.0, 0.0, 0.10], np.float32))
    report = simenv.score(lowered, config=ScoreConfig(tracking=False))
    return report, write_report(report, tmp_path_factory.mktemp("sunk"),
                                max_video_frames=VIDEO_FRAMES)


def _row(page_html: str, metric: str) -> str:
    """The metrics-table row of ``metric``."""
    match = re.search(rf"<tr><td>{metric}</td>.*?</tr>", page_html)
    assert match, f"no table row for {metric}"
    return match.group(0)


def _images(page: Path) -> list[Path]:
    return [page.parent / src for src in re.findall(r"<img[^>]*src='([^']+)'", page.read_text())]


def _video_frames(path: Path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(frame)
    cap.release()
    return frames


def _red_border(frame_bgr: np.ndarray) -> bool:
    """Whether the outer 3-pixel ring of a decoded frame is red (lossy codec: medians)."""
    ring = np.concatenate([frame_bgr[:3].reshape(-1, 3), frame_bgr[-3:].reshape(-1, 3),
                           frame_bgr[:, :3].reshape(-1, 3), frame_bgr[:, -3:].reshape(-1, 3)])
    b, g, r = np.median(ring, axis=0)
    return r > 170 and g < 90 and b < 90


def test_page_of_real_clip(clean):
    report, page = clean
    assert page.name == REPORT_PAGE and page.is_file()
    text = page.read_text()
    assert report.verdict == "plausible"
    assert "<span class='plausible'>plausible</span>" in text
    assert f"{report_score(report):.1f} / 100" in text
    assert "cmu_02_01_walk" in text and f"{FRAMES} (1.00 s)" in text
    for name in PERSON_METRICS:
        row = _row(text, name)
        assert "pass" in row, row  # the real walk passes everything
        assert report.people[0].basis[name] in row
    assert "No violations." in text


def test_timeline_pngs_are_valid_images(clean):
    report, page = clean
    images = _images(page)
    # every metric is available on the real walk with physics; each one that judged some
    # frame has a timeline plot (balance judges only frames at rest: none in a walk)
    plotted = [n for n, m in report.people[0].metrics.items() if np.isfinite(m.timeline).any()]
    assert len(plotted) >= len(PERSON_METRICS) - 1
    assert sorted(p.name for p in images) == sorted(f"p0_{n}.png" for n in plotted)
    for path in images:
        img = cv2.imread(str(path))
        assert img is not None, path
        assert img.shape[0] > 100 and img.shape[1] > 400 and img.std() > 5


def test_video_of_real_clip_has_frames_and_no_highlight(clean):
    _, page = clean
    text = page.read_text()
    assert "<video" in text and "video.webm" in text and "video.mp4" in text
    for name in ("video.mp4", "video.webm"):
        frames = _video_frames(page.parent / name)
        assert len(frames) == VIDEO_FRAMES
        assert frames[0].shape == (240, 320, 3) and frames[0].std() > 5
        assert not any(_red_border(f) for f in frames)


def test_corrupted_clip_names_the_violation(sunk):
    report, page = sunk
    assert "ground_penetration" in report.people[0].failed
    text = page.read_text()
    assert "<span class='implausible'>implausible</span>" in text
    assert "FAIL" in _row(text, "ground_penetration")
    assert "person 0: ground_penetration (frames" in text  # header summary
    assert "<h3>Violations</h3>" in text
    assert (page.parent / "p0_ground_penetration.png").is_file()
    frames = _video_frames(page.parent / "video.mp4")
    assert len(frames) == VIDEO_FRAMES
    # the sink spans the whole clip: every frame is inside the violation run
    assert all(_red_border(f) for f in frames)


def test_metric_and_source_names_are_escaped(walk, tmp_path):
    evil = "<script>alert('x')</script>"
    motion = walk.slice(0, 30).with_positions(walk.positions[:30], name=evil,
                                              metadata={"source": f"{evil}.bvh"})
    report = simenv.score(motion, physics=False)
    page = write_report(report, tmp_path)
    text = page.read_text()
    assert "<script>" not in text and "alert('x')" not in text
    assert "&lt;script&gt;alert(&#x27;x&#x27;)&lt;/script&gt;" in text


def test_physics_off_lists_unavailable_metrics_with_reasons(walk, tmp_path):
    report = simenv.score(walk, physics=False)
    page = write_report(report, tmp_path, video=True)
    text = page.read_text()
    assert "physics</th><td>off" in text
    for name in BODY_METRICS:
        row = _row(text, name)
        assert "not available" in row and "physics=False" in row
        assert not (tmp_path / f"p0_{name}.png").exists()
    for name in ("bone_length", "foot_skate", "ground_penetration", "jitter"):
        assert (tmp_path / f"p0_{name}.png").is_file()
    assert "No video: physics was off." in text
    assert not (tmp_path / "video.mp4").exists()


@pytest.mark.usefixtures("quick_physics")  # the page's rows and files, not its verdicts
def test_two_people_pair_metrics_and_scene_video(tmp_path):
    pair = simenv.load(asset_path(HANDSHAKE_PAIR)).slice(0, 60)
    report = simenv.score(pair)
    page = write_report(report, tmp_path, max_video_frames=3)
    text = page.read_text()
    assert "Person 0: 18_01" in text and "Person 1: 19_01" in text
    assert "Interaction (pairwise metrics)" in text
    for name in PAIR_METRICS:
        _row(text, name)
        assert (tmp_path / f"pair_{name}.png").is_file()
    assert (tmp_path / "p1_bone_length.png").is_file()
    assert "Retargeted body of both people" in text
    assert len(_video_frames(tmp_path / "video.mp4")) == 3


def test_index_links_scores_and_error_rows(clean, sunk, tmp_path):
    (clean_report, clean_page), (sunk_report, sunk_page) = clean, sunk
    entries = [
        ("walk.bvh", clean_page, report_score(clean_report), clean_report.verdict),
        ("sunk walk.bvh", sunk_page, report_score(sunk_report), sunk_report.verdict),
        ("broken<1>.bvh", None, None, "MotionError: frame 3 is NaN <b>"),
    ]
    index = write_index(entries, tmp_path)
    assert index == tmp_path / INDEX_PAGE
    text = index.read_text()
    assert "3 file(s): 1 plausible, 1 implausible, 1 not scored." in text
    hrefs = re.findall(r"<a href='([^']+)'>", text)
    assert len(hrefs) == 2
    # links are relative to the index and resolve to the pages
    for href, page in zip(hrefs, (clean_page, sunk_page), strict=True):
        assert (tmp_path / href).resolve() == page.resolve()
    assert f"{report_score(sunk_report):.1f}" in text and "implausible" in text
    assert "broken&lt;1&gt;.bvh" in text and "NaN &lt;b&gt;" in text and "<b>" not in text


def test_report_score_and_bad_arguments(clean, tmp_path):
    report, _ = clean
    assert report_score(report) == pytest.approx(report.people[0].score)
    with pytest.raises(SimenvError, match="PlausibilityReport"):
        write_report(report.to_records(), tmp_path)
    with pytest.raises(SimenvError, match="max_video_frames"):
        write_report(report, tmp_path, max_video_frames=0)

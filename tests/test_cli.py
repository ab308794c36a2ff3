"""The ``simenv`` command line on real motion capture (bundled assets and ../shared/data)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from simenv.assets import HANDSHAKE_PAIR, WALK, asset_path
from simenv.cli import info as info_command
from simenv.cli import main as cli
from simenv.cli import score as score_command
from simenv.cli.demo_page import check_links
from simenv.data.interaction_data import TARGET_FPS

SUMMARY_KEYS = {
    "frames", "fps", "people", "mean_residual_m", "p95_residual_m", "max_residual_m", "seconds"
}


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    """Run the CLI in-process; returns (exit status, stdout, stderr)."""
    status = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def test_help_on_every_command(capsys):
    for argv in ([], ["info"], ["retarget"], ["render"], ["score"], ["demo"]):
        with pytest.raises(SystemExit) as exc:
            cli.main([*argv, "--help"])
        assert exc.value.code == 0
        assert "usage: simenv" in capsys.readouterr().out
    done = subprocess.run([sys.executable, "-m", "simenv", "--help"], capture_output=True,
                          text=True)
    assert done.returncode == 0 and "retarget" in done.stdout


def test_info_single_bvh(capsys):
    status, out, _ = run(capsys, "info", asset_path(WALK), "--json")
    assert status == 0
    info = json.loads(out)
    assert info["people"] == 1 and info["format"] == "bvh"
    assert info["fps"] == 120 and info["frames"] == 343  # 344 in the file minus the T-pose
    (person,) = info["persons"]
    assert person["joints"] >= 21 and 1.0 < person["height_m"] < person["stature_m"] < 2.1
    assert person["stature_m"] > 1.4
    assert any("pose" in q.lower() for q in person["quirks"])  # the dropped T-pose is reported
    status, text, _ = run(capsys, "info", asset_path(WALK))
    assert status == 0 and "people 1" in text and "343" in text


def test_info_two_person_folder(capsys, shared_data: Path):
    status, out, _ = run(
        capsys, "info", shared_data / "cmu/two_person/18_19_walk_shake_hands", "--json"
    )
    assert status == 0
    info = json.loads(out)
    assert info["people"] == 2 and len(info["persons"]) == 2
    # 18_01's header claims 30 fps; the pair is 120 Hz and the reader must say so.
    assert info["fps"] == 120 and all(p["fps"] == 120 for p in info["persons"])
    notes = " ".join(info.get("quirks", []) + info["persons"][0]["quirks"]).lower()
    assert "30" in notes or "frame time" in notes
    for person in info["persons"]:
        assert 1.0 < person["height_m"] < person["stature_m"] < 2.1 and person["stature_m"] > 1.4


def test_info_gives_a_stature_to_a_skeleton_without_pelvis(capsys, shared_data: Path):
    """A real SBU pair (OpenNI: both hips, no pelvis joint): each person's stature is the
    body retargeting fits, its pelvis at the hips' midpoint."""
    path = shared_data / "other/sbu_kinect_sample/skeleton_pos.txt"
    status, out, _ = run(capsys, "info", path, "--json")
    assert status == 0
    info = json.loads(out)
    assert info["people"] == 2
    for person in info["persons"]:
        assert "pelvis" in person["joint_map"]["missing"]
        assert 1.0 < person["height_m"] < person["stature_m"] < 2.1


def test_bad_input_exits_2_without_traceback(tmp_path: Path, capsys):
    text = asset_path(WALK).read_text()
    truncated = tmp_path / "truncated.bvh"
    truncated.write_text(text[: len(text) // 2].rsplit("\n", 1)[0] + "\n1.0 2.0\n")
    status, _, err = run(capsys, "info", truncated)
    assert status == 2 and "truncated.bvh" in err and "Traceback" not in err
    status, _, err = run(capsys, "info", tmp_path / "missing.bvh")
    assert status == 2 and "missing.bvh" in err
    status, _, err = run(capsys, "retarget", asset_path(WALK), "--out", tmp_path / "x.txt")
    assert status == 2 and ".npz" in err
    done = subprocess.run([sys.executable, "-m", "simenv", "info", str(truncated)],
                          capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 2
    assert "Traceback" not in done.stderr and len(done.stderr.strip().splitlines()) == 1


def test_a_closed_pipe_ends_quietly(tmp_path: Path):
    """`simenv info FILE | head`: the reader closes before simenv writes."""
    proc = subprocess.Popen([sys.executable, "-m", "simenv", "info", str(asset_path(WALK))],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait() == cli.EXIT_BROKEN_PIPE
    assert err == ""


def test_unexpected_errors_keep_their_traceback(monkeypatch):
    def broken(path):
        raise RuntimeError("a bug, not bad input")

    monkeypatch.setattr(info_command, "load_any", broken)
    with pytest.raises(RuntimeError, match="a bug"):
        cli.main(["info", str(asset_path(WALK))])


def test_retarget_json_and_npz(tmp_path: Path, capsys, shared_data: Path):
    out = tmp_path / "run.npz"
    status, stdout, _ = run(
        capsys, "retarget", shared_data / "cmu/bvh/35_17.bvh", "--out", out, "--json"
    )
    assert status == 0
    summary = json.loads(stdout)  # exactly one JSON object on stdout
    assert set(summary) == SUMMARY_KEYS
    assert summary["people"] == 1 and summary["fps"] == 120 and summary["frames"] == 167
    # (a heavy tail can put the mean above the 95th percentile; both stay below the max)
    assert 0 < summary["p95_residual_m"] <= summary["max_residual_m"]
    assert 0 < summary["mean_residual_m"] <= summary["max_residual_m"]
    assert summary["mean_residual_m"] < 0.05 and summary["seconds"] > 0
    with np.load(out) as npz:
        qpos = npz["qpos"]
        assert qpos.shape[0] == 167 and qpos.shape[1] >= 7 and np.isfinite(qpos).all()
        assert float(npz["fps"]) == 120
        dims = dict(zip(npz["dim_names"], npz["dim_values"], strict=True))
        assert 0.3 < dims["left_thigh"] < 0.6 and 1.4 < float(npz["height"]) < 2.1


def test_retarget_two_people_with_video(tmp_path: Path, capsys):
    out, video = tmp_path / "pair.npz", tmp_path / "pair.mp4"
    status, stdout, _ = run(
        capsys, "retarget", asset_path(HANDSHAKE_PAIR), "--out", out, "--json",
        "--video", video, "--stride", 100,
    )
    assert status == 0
    summary = json.loads(stdout)
    assert set(summary) == SUMMARY_KEYS and summary["people"] == 2
    with np.load(out) as npz:
        q0, q1, q = npz["qpos_0"], npz["qpos_1"], npz["qpos"]
        assert q0.shape[0] == q1.shape[0] == q.shape[0] == summary["frames"]
        assert q.shape[1] == q0.shape[1] + q1.shape[1]
        # The two people stand apart: their pelvis paths differ by decimetres at least.
        assert np.linalg.norm(q0[:, :2] - q1[:, :2], axis=1).min() > 0.3
    cap = cv2.VideoCapture(str(video))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == len(range(0, summary["frames"], 100))
    cap.release()


def test_render_a_few_frames(tmp_path: Path, capsys):
    video = tmp_path / "walk.mp4"
    status, stdout, _ = run(
        capsys, "render", asset_path(WALK), "--out", video, "--max-frames", 3, "--stride", 20
    )
    assert status == 0 and str(video) in stdout
    cap = cv2.VideoCapture(str(video))
    try:
        assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 3
        assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(120 / 20)
        ok, frame = cap.read()
        assert ok and frame.shape == (240, 320, 3) and frame.std() > 5
    finally:
        cap.release()


@pytest.mark.usefixtures("quick_physics")  # what the demo writes, not its verdicts
def test_demo_writes_videos_npz_and_summary(tmp_path: Path, capsys):
    # The reaction's first 0.6 s: what it writes and records, not how long it can track.
    status, stdout, _ = run(capsys, "demo", "--out", tmp_path / "demo", "--stride", 60,
                            "--reaction-seconds", 0.6)
    assert status == 0
    summary_path = tmp_path / "demo" / "summary.json"
    assert f"wrote {summary_path}" in stdout
    report = json.loads(summary_path.read_text())
    assert "mocap.cs.cmu.edu" in report["data_acknowledgement"]
    assert set(report["clips"]) == {"walk", "handshake"}
    for name, people in (("walk", 1), ("handshake", 2)):
        clip = report["clips"][name]
        assert SUMMARY_KEYS <= set(clip) and clip["people"] == people
        assert clip["mean_residual_m"] < 0.05 and clip["render_stride"] == 60
        assert clip["rendered_frames"] == len(range(0, clip["frames"], 60))
        assert f"wrote {clip['video']}" in stdout
        cap = cv2.VideoCapture(clip["video"])
        assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == clip["rendered_frames"]
        cap.release()
        with np.load(clip["npz"]) as npz:
            assert npz["qpos"].shape[0] == clip["frames"]
        plaus = clip["plausibility"]
        assert plaus["verdict"] in ("plausible", "implausible")
        assert len(plaus["people"]) == people and Path(plaus["report"]).is_file()
    assert (tmp_path / "demo" / "report" / "index.html").is_file()
    # The page a person opens: every link relative and resolving (tests/test_demo.py checks
    # such a page in a browser).
    assert check_links(tmp_path / "demo" / "index.html")["pages"] >= 5
    (reaction,) = report["rehearsal"]["reactions"]
    assert reaction["object"] == "cigarette" and reaction["success"] is True
    assert reaction["t_object_changed"] > reaction["t_decision"] >= reaction["t_onset"]
    assert (tmp_path / "demo" / "rehearsal" / "rehearsal.mp4").stat().st_size > 0
    answer = report["reaction"]
    if "skipped" not in answer:
        assert answer["model"] == "interformer"
        assert answer["frames"] == round(0.6 * TARGET_FPS)  # the seconds asked for
        assert answer["agent"]["verdict"] in ("plausible", "implausible")
        assert Path(answer["report"]).is_file()


def test_score_json_prints_one_object_per_person(capsys, tmp_path):
    out = tmp_path / "results.jsonl"
    status, text, _ = run(capsys, "score", asset_path(WALK), asset_path(HANDSHAKE_PAIR),
                          "--no-physics", "--json", "--out", out)
    assert status == 0
    records = [json.loads(line) for line in text.splitlines()]
    assert [(Path(r["file"]).name, r["person"]) for r in records] == [
        (WALK, 0), (HANDSHAKE_PAIR, 0), (HANDSHAKE_PAIR, 1)]
    for r in records:
        assert r["verdict"] in ("plausible", "implausible") and 0 <= r["score"] <= 100
        assert {"value", "unit", "threshold", "passed"} <= set(r["metrics"]["foot_skate"])
    assert "interaction" in records[1] and "interaction" not in records[0]
    assert len(out.read_text().splitlines()) == 3
    # A rerun with the same results file has nothing left to do.
    status, text, _ = run(capsys, "score", asset_path(WALK), "--no-physics", "--json",
                          "--out", out)
    assert status == 0 and text == ""


def test_score_text_output_and_bad_path(capsys, tmp_path):
    status, text, _ = run(capsys, "score", asset_path(WALK), "--no-physics")
    assert status == 0 and "plausible" in text and "not available: joint_limits" in text
    status, _, err = run(capsys, "score", tmp_path / "nothing.bvh")
    assert status == 2 and "no such file" in err
    # A bad file among good ones: every file is scored, the bad one is named, status 2.
    broken = tmp_path / "broken.bvh"
    broken.write_text(Path(asset_path(WALK)).read_text()[:5000])
    status, text, _ = run(capsys, "score", asset_path(WALK), broken, "--no-physics")
    assert status == 2
    assert "plausible" in text and f"{broken}: error:" in text and "line" in text


def test_score_tracking_segments_option(capsys):
    parser = cli.build_parser()
    args = parser.parse_args(["score", "clip.bvh", "--tracking-segments", "4"])
    assert score_command.score_config(args).body.tracking_segment_s == 4.0
    assert score_command.score_config(parser.parse_args(["score", "clip.bvh"])) is None
    status, _, err = run(capsys, "score", asset_path(WALK), "--tracking-segments", "0")
    assert status == 2 and "tracking_segment_s must be a positive number" in err
    whole = score_command.score_config(parser.parse_args(
        ["score", "clip.bvh", "--tracking-segments", "inf", "--tracking-attempts", "1"]))
    assert whole.body.tracking_segment_s == float("inf") and whole.mpc.attempts == 1
    assert whole.mpc.n_samples == score_command.score_config(args).mpc.n_samples
    status, _, err = run(capsys, "score", asset_path(WALK), "--tracking-attempts", "0")
    assert status == 2 and "MPCConfig.attempts" in err


def test_rehearse_forwards_to_the_rehearsal(capsys, tmp_path):
    with pytest.raises(SystemExit) as exc:
        cli.main(["rehearse", "--help"])
    assert exc.value.code == 0 and "--scenario" in capsys.readouterr().out
    status, out, _ = run(capsys, "rehearse", WALK, "--out", tmp_path / "r", "--no-render")
    assert status == 0 and "reaction(s) started" in out
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["reactions"] == []  # a walk holds no gesture: nothing is started
    with pytest.raises(SystemExit) as exc:  # other commands still reject unknown options
        cli.main(["info", str(asset_path(WALK)), "--bogus"])
    assert exc.value.code == 2 and "unrecognized arguments: --bogus" in capsys.readouterr().err

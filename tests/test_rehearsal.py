"""Offline rehearsal: every output written, reactions measured in simulation, agents wired."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import simenv
import simenv.models
import simenv.room.scenario
from simenv.assets import WALK, asset_path
from simenv.core.errors import SimenvError
from simenv.data.gestures import GESTURE15_JOINTS
from simenv.envs.rehearsal import rehearse
from simenv.room.session import GestureEvent, Session


@pytest.fixture(scope="module")
def short() -> simenv.Motion:
    return simenv.load(asset_path(WALK)).slice(0, 60)  # 0.5 s: the user stays away


class _Always:
    """Stub classifier: always "smell"."""

    labels = ("smell", "idle")
    joint_names = GESTURE15_JOINTS

    def classify(self, window: np.ndarray, valid: np.ndarray) -> np.ndarray:
        return np.array([0.95, 0.05])


def test_labelled_rehearsal_writes_every_output(tmp_path: Path, short):
    session = Session(short, (GestureEvent("smell", 0.2, 0.5),))
    summary = rehearse(session, tmp_path, scenario="discomfort", agent="labels",
                       width=240, height=180)
    for name in ("rehearsal.mp4", "log.jsonl", "summary.json", "report.html"):
        assert (tmp_path / name).stat().st_size > 0, name
    rows = [json.loads(line) for line in (tmp_path / "log.jsonl").read_text().splitlines()]
    assert len(rows) == round(summary["duration_s"] * 25)
    assert {"t", "gesture", "probabilities", "decision", "objects", "levels",
            "labels"} <= set(rows[0])
    (reaction,) = summary["reactions"]
    assert reaction["gesture"] == "smell" and reaction["object"] == "cigarette"
    assert reaction["success"] is True and reaction["failure"] is None
    assert reaction["t_onset"] <= reaction["t_decision"] < reaction["t_object_changed"]
    assert rows[-1]["labels"]["cigarette"] == "out"
    assert summary["decision_latency_s"]["n"] == 1
    assert summary["agent_plausibility"]["ground_penetration"]["passed"]
    assert "foot_skate" in summary["agent_plausibility"]
    # The agent's own simulated contacts: pressing the cigarette touches it (an object)
    # and the desk, within the soft-contact tolerance; no assistance force anywhere.
    physics = summary["agent_physics"]
    assert set(physics["penetration_m"]) == {"floor", "furniture", "object", "self", "user"}
    assert physics["penetration_m"]["object"]["max"] > 0.0
    for kind in ("floor", "furniture", "object"):
        assert physics["penetration_m"][kind]["steps_over_tolerance"] == 0, kind
    assert physics["assistance_max_n"] == 0.0
    assert json.loads((tmp_path / "summary.json").read_text()) == summary
    report = (tmp_path / "report.html").read_text()
    assert "cigarette" in report and "assistance force" in report
    # The video: one captioned frame per log line, played by the page from relative paths.
    video = summary["video"]
    assert video["file"] == "rehearsal.mp4" and video["frames"] == len(rows)
    assert (video["width"], video["height"]) == (240, 180)
    assert "<video" in report and "src='rehearsal.mp4'" in report
    assert str(tmp_path) not in report
    if video["codec"] != "avc1":  # browsers do not play mp4v: a VP8 copy for the page
        assert video["webm"] == "rehearsal.webm" and "src='rehearsal.webm'" in report
    frames = _frames(tmp_path / "rehearsal.mp4")
    assert len(frames) == len(rows) and frames[0].shape == (180, 240, 3)
    band = 180 - 5 * 10 - 4  # five caption lines of 10 px (the least) and the padding
    for frame in frames[::25]:
        text = frame[band:].min(axis=2) > 180  # white on the darkened band
        assert text.sum() > 50
        assert np.median(frame[band:][~text]) < np.median(frame[:band])


def _frames(path: Path) -> list[np.ndarray]:
    """The frames of a video file, BGR uint8 (H, W, 3)."""
    import cv2

    cap = cv2.VideoCapture(str(path))
    frames = []
    while (frame := cap.read()[1]) is not None:
        frames.append(frame)
    cap.release()
    return frames


def test_video_size_is_validated(tmp_path: Path, short):
    from simenv.envs.rehearsal import main

    for size, field in (({"width": 0}, "width"), ({"height": -360}, "height"),
                        ({"width": 100_000}, "width"), ({"height": 360.5}, "height"),
                        ({"width": True}, "width")):
        with pytest.raises(SimenvError, match=f"video {field}") as err:
            rehearse(short, tmp_path, **size)
        assert err.value.field == field
    with pytest.raises(SimenvError, match="video height 20000; expected a whole number"):
        main([WALK, "--out", str(tmp_path), "--width", "640", "--height", "20000"])
    assert not (tmp_path / "log.jsonl").exists()  # refused before any output


def test_camera_sees_the_user_and_the_agents_face_and_hands(short):
    """Segmentation render from the rehearsal camera: the user's head and hands and the
    seated agent's head and both hands are in view, and the eye is in front of both."""
    import mujoco

    from simenv.body.render import make_renderer
    from simenv.envs.interaction_room import InteractionRoomEnv

    env = InteractionRoomEnv(Session(short, ()), scenario="discomfort", width=160,
                             height=120)
    env.reset(seed=0)
    camera = env.camera()
    assert isinstance(camera, mujoco.MjvCamera)
    renderer = make_renderer(env.model, 160, 120)
    try:
        renderer.enable_segmentation_rendering()
        renderer.update_scene(env.data, camera=camera)
        seg = renderer.render()
        eye = np.mean([renderer.scene.camera[i].pos for i in range(2)], axis=0)
    finally:
        renderer.close()
    geoms = seg[..., 0][seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)]
    seen = {env.model.body(env.model.geom_bodyid[g]).name for g in np.unique(geoms)}
    for who in ("agent", "user"):
        assert {f"{who}/head", f"{who}/left_hand", f"{who}/right_hand"} <= seen, who
        head = env.data.body(f"{who}/head")
        forward = head.xmat.reshape(3, 3)[:2, 0]  # the body's x axis: where it faces
        assert forward @ (eye - head.xpos)[:2] > 0, who


def test_scripted_agent_decides_through_the_perception_loop(tmp_path: Path, short):
    summary = rehearse(Session(short, (GestureEvent("smell", 0.0, 0.5),)), tmp_path,
                       scenario="discomfort", agent="scripted", classifier=_Always(),
                       render=False)
    first = summary["decisions"][0]
    assert first["reaction"] == "cigarette_out" and first["t_decision"] == pytest.approx(0.96)
    assert summary["reactions"][0]["success"] is True
    assert summary["perception_compute_s"]["n"] >= 1
    assert not (tmp_path / "rehearsal.mp4").exists()
    rows = [json.loads(line) for line in (tmp_path / "log.jsonl").read_text().splitlines()]
    assert rows[24]["stage"] == "real" and rows[24]["probabilities"]["smell"] > 0.9


def test_random_agent_is_seeded_and_bad_agents_fail(tmp_path: Path, short):
    a = rehearse(short, tmp_path / "a", agent="random", render=False, seed=3)
    b = rehearse(short, tmp_path / "b", agent="random", render=False, seed=3)
    assert a["decisions"] == b["decisions"]
    with pytest.raises(SimenvError, match="unknown agent"):
        rehearse(short, tmp_path, agent="oracle")


def test_scripted_agent_without_models_or_corpus_fails_clearly(tmp_path: Path, short,
                                                                monkeypatch):
    import simenv.models

    monkeypatch.setattr(simenv.models, "available", lambda: [])
    with pytest.raises(SimenvError, match="SIMENV_SHARED_DATA"):
        rehearse(short, tmp_path, agent="scripted", render=False, data=tmp_path / "none")


@pytest.mark.skipif(not {"gesture-tcn-ensemble", "predictor-gesture-25-50"}
                    <= set(simenv.models.available()),
                    reason="shipped gesture-tcn-ensemble / predictor-gesture-25-50 absent")
def test_scripted_agent_runs_on_shipped_models_without_the_corpus(tmp_path: Path,
                                                                  monkeypatch):
    """No ../shared at all: the scripted agent perceives the bundled walk (2 s) with the
    shipped classifier and predictor, one tick a second, and names them."""
    monkeypatch.setenv("SIMENV_SHARED_DATA", str(tmp_path / "no-corpus"))
    walk = simenv.load(asset_path(WALK)).slice(0, 240)
    summary = rehearse(walk, tmp_path / "out", agent="scripted", render=False)
    assert summary["perception"]["classifier"] == "gesture-tcn-ensemble"
    assert summary["perception"]["predictor"] == "predictor-gesture-25-50"
    # the loop settings the shipped recogniser's training chose are the ones it ran with
    metadata = simenv.models.load("gesture-tcn-ensemble").metadata
    assert summary["perception"]["threshold"] == metadata["loop_threshold"]
    assert summary["perception"]["window_rule"] == metadata.get("loop_window_rule", "max")
    assert [summary["perception"]["real_frames"], *summary["perception"]["context_frames"]] \
        == list(metadata["loop_windows"])
    # 0.96 and 1.96 s; no tick on the pose held after the 2-s recording
    assert summary["perception_compute_s"]["n"] == 2
    rows = [json.loads(line) for line in (tmp_path / "out" / "log.jsonl").read_text()
            .splitlines()]
    assert rows[24]["probabilities"] is not None
    assert rows[24]["stage"] in ("real", "predicted", None)
    assert all(d["stage"] in ("real", "predicted") for d in summary["decisions"])


def test_module_command(tmp_path: Path, capsys):
    from simenv.envs.rehearsal import main

    code = main([WALK, "--out", str(tmp_path), "--scenario", "discomfort", "--gesture",
                 "smell:0.2:1.0", "--no-render"])
    assert code == 0
    out = capsys.readouterr().out
    assert "1 reaction(s) started" in out
    summary = json.loads((tmp_path / "summary.json").read_text())
    (reaction,) = summary["reactions"]
    # Measured, not assumed: here the walking user reaches the desk and shoves the agent's
    # arm while it presses, and the cigarette stays lit.
    assert reaction["success"] is False and reaction["t_object_changed"] is None
    # Why, for people, printed and in summary.json, from what the simulation measured: the
    # object short of its threshold, the hand's closest approach, the user's pushes (no
    # deeper than the agent's deepest contact with the user over the whole session).
    why = reaction["failure"]
    assert f"cigarette_out (decided at 0.20 s) failed: {why}" in out
    assert why.startswith("the cigarette stayed lit")
    assert reaction["object_level_start"] <= reaction["object_level_best"] < 0.5
    assert reaction["t_decision"] <= reaction["t_hand_closest"] <= summary["duration_s"]
    assert f"no closer than {reaction['hand_distance_min_m']:.3f} m" in why
    contact = reaction["user_contact"]
    assert reaction["t_decision"] <= contact["t_first"] <= contact["t_last"]
    assert 0 < contact["max_depth_m"] <= summary["agent_physics"]["penetration_m"]["user"]["max"]
    assert f"the user's body pushed into the agent from {contact['t_first']:.2f}" in why
    assert "why it failed" in (tmp_path / "report.html").read_text()
    with pytest.raises(SimenvError, match="LABEL:ONSET_S:END_S"):
        main([WALK, "--out", str(tmp_path), "--gesture", "smell"])


def test_real_wave_is_greeted_back(tmp_path: Path, shared_data):
    """A real MSR Action3D "high arm wave" recording as the session, labelled wave: the
    agent turns to face the user (measured within 30 deg) with its hand above its
    shoulder, seated, and the summary says when and how close it came."""
    from simenv.io import msr_action3d

    wave = msr_action3d.read(shared_data / "gestures" / "msr_action3d" /
                             "a01_s01_e01_skeleton3D.txt")
    session = Session(wave, (GestureEvent("wave", 0.0, wave.num_frames / wave.fps),))
    summary = rehearse(session, tmp_path, agent="labels", render=False)
    (reaction,) = summary["reactions"]
    assert reaction["reaction"] == "greet" and reaction["object"] is None
    assert reaction["success"] is True and reaction["facing_deg_min"] < 30.0
    assert reaction["hand_raised"] is True and reaction["failure"] is None
    assert reaction["t_decision"] < reaction["t_success"] < summary["duration_s"]
    assert reaction["t_object_changed"] is None


def test_loud_turns_the_hifi_down(tmp_path: Path, short):
    """Discomfort scenario, a labelled "loud": the agent's fingertips grasp the knob and
    turn it; the hi-fi's level in the log falls below the threshold only after the
    decision."""
    summary = rehearse(Session(short, (GestureEvent("loud", 0.2, 0.5),)), tmp_path,
                       scenario="discomfort", agent="labels", render=False)
    (reaction,) = summary["reactions"]
    assert reaction["reaction"] == "hifi_down" and reaction["grasped"] is True
    assert reaction["success"] is True
    assert reaction["t_decision"] < reaction["t_object_changed"] == reaction["t_success"]
    rows = [json.loads(line) for line in (tmp_path / "log.jsonl").read_text().splitlines()]
    quiet = [r["t"] for r in rows if r["labels"]["hifi"] == "quiet"]
    assert quiet and min(quiet) > reaction["t_decision"]
    assert rows[-1]["levels"]["hifi"] < 0.5


def test_reactions_not_started_are_not_reported(tmp_path: Path, short):
    """The hi-fi across the room (out of seated reach) and a bow answered by opening the
    door (no planner): both decisions are logged with the reason, and the summary's
    reactions list stays empty."""
    text = Path(simenv.room.scenario.load_scenario("default").source).read_text()
    far = tmp_path / "far.toml"
    far.write_text(text.replace("position = [0.75, -0.3]", "position = [-1.8, 1.6]")
                   .replace("yaw_deg = 90.0 ", "yaw_deg = -90.0 ")
                   .replace('bow = "bow_back"', 'bow = "open_door"'))
    session = Session(short, (GestureEvent("answer_phone", 0.1, 0.2),
                              GestureEvent("bow", 0.3, 0.45)))
    summary = rehearse(session, tmp_path / "out", scenario=str(far), agent="labels",
                       render=False)
    assert summary["reactions"] == []
    reasons = {d["reaction"]: d["not_started"] for d in summary["decisions"]}
    assert "out of the seated agent's" in reasons["hifi_down"]
    assert reasons["open_door"] == "not implemented"


# -- session recipes (assets/sessions) ---------------------------------------------------


def test_recipe_without_the_corpus_names_the_file_and_the_option(tmp_path: Path, capsys):
    from simenv.envs.rehearsal import main
    from simenv.room.session import session_recipes

    names = session_recipes()
    assert len(names) >= 3
    with pytest.raises(SimenvError, match="joints_s02_e01.txt.*SIMENV_SHARED_DATA"):
        Session.load("utkinect-s02-e01-wave", data=tmp_path)
    with pytest.raises(SimenvError, match="--data"):
        main(["utkinect-s02-e01-wave", "--out", str(tmp_path / "o"), "--data",
              str(tmp_path)])
    bad = tmp_path / "bad.toml"
    bad.write_text('[session]\nsource = "x.txt"\nfps = 15.0\nstart_frame = "a"\n')
    with pytest.raises(SimenvError, match="start_frame") as err:
        Session.load(bad, data=tmp_path)
    assert err.value.field == "session.start_frame"


def test_recipes_cut_labelled_waves_of_different_subjects(shared_data):
    """Every bundled recipe: a real UTKinect session's frames (compared with the reader's
    whole session), the wave where index.csv puts waveHands (to a frame), >= 1.9 s of
    unlabelled lead-in and >= 0.7 s of lead-out."""
    import csv

    from simenv.io import utkinect
    from simenv.room.session import session_recipes

    index = {(r["file"], r["class_name"].strip()): r for r in
             csv.DictReader((shared_data / "gestures" / "index.csv").open())}
    subjects = set()
    for name in session_recipes():
        session = Session.load(name, data=shared_data)
        m = session.motion
        (wave,) = session.gestures
        source = Path(m.metadata["source"])
        full = utkinect.read(source)  # with its segments, from actionLabel.txt
        i0 = int(np.argmin(np.abs(full.positions[:, 0] - m.positions[0, 0]).sum(axis=1)))
        np.testing.assert_array_equal(m.positions, full.positions[i0:i0 + m.num_frames])
        seg = next(s for s in full.metadata["segments"] if s["label"] == "waveHands")
        row = index[(f"utkinect/joints/{source.name}", "waveHands")]
        assert (seg["start_frame"], seg["end_frame"]) == (int(row["start_frame"]),
                                                          int(row["end_frame"]))
        assert wave.label == "wave"
        frame = 1.0 / m.fps + 1e-9  # the reader rounds to its frames, the recipe does not
        assert abs(wave.onset_s - (seg["start"] - i0) / m.fps) <= frame
        assert abs(wave.end_s - (seg["end"] - i0) / m.fps) <= frame
        assert wave.onset_s >= 1.9 and m.num_frames / m.fps - wave.end_s >= 0.7
        subjects.add(m.metadata["subject"])
    assert len(subjects) >= 3


@pytest.fixture(scope="module")
def recipe_rehearsals(tmp_path_factory, shared_data):
    """Every bundled recipe (UTKinect subjects 2, 4, 6, 10: test subjects of the
    classifier) rehearsed with the scripted agent on the shipped models, by name."""
    from simenv.room.session import session_recipes

    if not {"gesture-tcn-ensemble", "predictor-gesture-25-50"} <= set(
            simenv.models.available()):
        pytest.skip("shipped gesture-tcn-ensemble / predictor-gesture-25-50 absent")
    out = tmp_path_factory.mktemp("recipe")
    return {name: rehearse(name, out / name, agent="scripted", render=False,
                           data=shared_data) for name in session_recipes()}


def test_recipe_rehearsal_greets_through_the_loop(recipe_rehearsals):
    summary = recipe_rehearsals["utkinect-s02-e01-wave"]
    assert summary["gestures"][0]["label"] == "wave"
    assert summary["perception"]["classifier"] == "gesture-tcn-ensemble"
    greetings = [r for r in summary["reactions"] if r["reaction"] == "greet"]
    assert greetings and greetings[0]["success"] is True
    assert greetings[0]["facing_deg_min"] < 30.0
    assert {d["stage"] for d in summary["decisions"]} <= {"real", "predicted"}


@pytest.mark.parametrize("recipe", [
    "utkinect-s02-e01-wave", "utkinect-s04-e02-wave",
    pytest.param("utkinect-s06-e01-wave", marks=pytest.mark.xfail(
        strict=True, reason="measured with gesture-tcn-ensemble: the greeting is decided at "
        "the tick ending 1.96 s (P(wave) 0.97 on the real stage; 0.98 with the ensemble of "
        "2026-12-04), 1.0 s before the labelled onset 2.967 s (on 2026-12-04 gesture-tcn "
        "alone: the same tick, 0.94; the transformer: 7 ms before it)")),
    "utkinect-s10-e01-wave"])
def test_recipe_rehearsal_greets_after_the_labelled_onset(recipe_rehearsals, recipe,
                                                         shared_data):
    """No greeting in the unlabelled lead-in: the first greeting is decided after the
    labelled wave starts and before it ends -- to the recording's own time resolution: the
    loop's 25-fps frames are interpolated linearly from the recording's samples (UTKinect:
    15 fps), so a tick less than one sample before the labelled onset already sees the
    recording's first sample at or after it (utkinect-s02-e01-wave: the tick ending
    1.96 s, onset 1.967 s, P(wave) 0.69 on the windows' mean with gesture-tcn-ensemble of
    2026-12-05)."""
    from simenv.room.session import Session

    summary = recipe_rehearsals[recipe]
    wave = summary["gestures"][0]
    greets = [d for d in summary["decisions"] if d["reaction"] == "greet"]
    assert greets
    sample_s = 1.0 / Session.load(recipe, data=shared_data).motion.fps
    assert wave["onset_s"] - sample_s < greets[0]["t_decision"] <= wave["end_s"]

"""Shipped checkpoints (predictors and gesture classifier): loading by name, prediction
shapes, size budget, evaluation through ``simenv eval``/``simenv train``, bad input."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import torch

from simenv.cli import main as cli
from simenv.core.errors import MotionError, SimenvError
from simenv.core.motion import Motion
from simenv.data import prediction_data as pdata
from simenv.data.gestures import GESTURE_LABELS, normalise_windows, to_gesture_joints
from simenv.io import bvh
from simenv.learning import train_predictor as tp
from simenv.models import available, checkpoint_path, load

torch.set_num_threads(1)

PREDICTORS = ("predictor-10-10", "predictor-25-25", "predictor-25-50", "predictor-dctmlp-25-25",
              "predictor-dctmlp-25-50")
SHIPPED = (*PREDICTORS, "gesture-classifier")
#: Budget of every checkpoint and card of the prediction/recognition models, bytes.
BUDGET_BYTES = 20 * 1024 * 1024


def _require(name: str) -> None:
    if name not in available():
        pytest.skip(f"{name} is not shipped in assets/models")


def _walk() -> Motion:
    """The bundled real CMU walk (02_01)."""
    return bvh.read(Path(str(resources.files("simenv.assets"))) / "cmu_02_01_walk.bvh")


def _history(frames: int, n: int = 2, seed: int = 0) -> np.ndarray:
    """(n, frames, 17, 3) root-relative pred17 histories from the bundled real CMU walk,
    with small seeded noise, metres."""
    w = pdata.windows_from_motions([_walk()], frames - 1, 1, stride=50)
    rng = np.random.default_rng(seed)
    return (w.frames[:n, :frames] + rng.normal(0, 1e-3, (n, frames, 17, 3))).astype(np.float32)


def test_every_model_is_shipped_with_a_card_within_budget() -> None:
    assert set(SHIPPED) <= set(available())
    total = 0
    for name in SHIPPED:
        path = checkpoint_path(name)
        card = path.with_suffix(".md")
        assert card.is_file(), f"{name} has no model card"
        text = card.read_text()
        assert "split" in text.lower() and ("MPJPE" in text or "accuracy" in text)
        total += path.stat().st_size + card.stat().st_size
    assert total <= BUDGET_BYTES, f"shipped models take {total / 2**20:.1f} MB"


@pytest.mark.parametrize("name", PREDICTORS)
def test_shipped_predictor_predicts_the_right_shapes(name: str) -> None:
    _require(name)
    model = load(name)
    p, f = (int(x) for x in name.split("-")[-2:])
    assert (model.past_len, model.future_len, model.history_len) == (p, f, p + 1)
    assert getattr(model, "fps", 25.0) == 25.0
    history = _history(p + 1)
    out = model.predict(history)
    assert out.shape == (2, f, 17, 3) and out.dtype == np.float32 and np.isfinite(out).all()
    assert model.predict(history[0]).shape == (f, 17, 3)
    # longer histories are fine: the last 1 + P frames are used
    longer = np.concatenate([history[:, :3], history], axis=1)
    np.testing.assert_allclose(model.predict(longer), out, atol=1e-5)
    # no seam: the first predicted frame moves at most a few cm from the last observed one
    assert np.linalg.norm(out[:, 0] - history[:, -1], axis=-1).max() < 0.1
    info = model.config.info
    assert info["train_clips"] and info["test_clips"]
    assert not set(info["train_clips"]) & set(info["test_clips"])


def test_shipped_classifier_classifies_and_embeds() -> None:
    _require("gesture-classifier")
    model = load("gesture-classifier")
    assert model.config.labels == GESTURE_LABELS
    t = model.config.window
    walk = _walk().resample(model.config.fps)
    frames = to_gesture_joints(walk, model.config.extra["joint_set"])
    frames = np.concatenate([frames, frames[::-1]])  # the 2.9-s walk and back: >= 3 s
    windows = np.stack([frames[i:i + t] for i in (0, 10, 20)])  # (3, 75, J, 3) metres
    p = model.classify_world(windows)
    assert p.shape == (3, len(GESTURE_LABELS)) and np.allclose(p.sum(1), 1, atol=1e-5)
    assert model.classify_world(windows[0]).shape == (len(GESTURE_LABELS),)
    x = torch.as_tensor(normalise_windows(windows, joints=model.config.joint_names))
    assert model.features(x).shape == (3, model.config.feature_dim)


@pytest.mark.parametrize("name", PREDICTORS)
def test_shipped_predictor_rejects_bad_histories(name: str) -> None:
    _require(name)
    model = load(name)
    p = model.past_len
    with pytest.raises(MotionError, match=rf"has {p} frames; this predictor needs at least "
                                          rf"{p + 1}"):
        model.predict(_history(p))
    bad = _history(p + 1)
    bad[1, 4, 6, 0] = np.nan
    with pytest.raises(MotionError, match=r"frame 4.*non-finite value in window 1, joint 6"):
        model.predict(bad)
    with pytest.raises(MotionError, match="expects 17"):
        model.predict(_history(p + 1)[:, :, :15])


def test_shipped_classifier_rejects_bad_windows() -> None:
    _require("gesture-classifier")
    model = load("gesture-classifier")
    j = len(model.config.joint_names)
    rng = np.random.default_rng(1)
    short = rng.normal(0, 0.3, (2, 25, j, 3))
    with pytest.raises(MotionError, match=r"shape \(B, 75, .*got \(2, 25"):
        model.classify_world(short)
    nan = rng.normal(0, 0.3, (2, 75, j, 3))
    nan[1, 10, 2, 1] = np.nan
    with pytest.raises(MotionError, match="non-finite"):
        model.classify_world(nan)
    with pytest.raises(MotionError, match=rf"\(N, T, {j}, 3\)"):
        model.classify_world(rng.normal(0, 0.3, (2, 75, j + 1, 3)))


def test_unknown_model_names_list_the_shipped_ones() -> None:
    with pytest.raises(SimenvError, match="unknown model 'predictor-9-9'; available: .*"
                                          "predictor-25-25"):
        load("predictor-9-9")
    with pytest.raises(SimenvError, match="unknown model 'gesture-net'"):
        load("gesture-net")


def test_eval_predictor_json_on_given_clips(tmp_path: Path, capsys, shared_data: Path) -> None:
    _require("predictor-10-10")
    clip = shared_data / "cmu" / "bvh" / "02_01.bvh"
    status = cli.main(["eval", "predictor", "predictor-10-10", "--data", str(clip), "--json",
                       "--out", str(tmp_path)])
    assert status == 0
    got = json.loads(capsys.readouterr().out)
    assert got["fps"] == 25 and got["horizons_ms"] == [80, 160, 320, 400, 1000]
    assert got["clips"] == 1 and got["windows"] > 10
    for method in ("model", "zero_velocity", "constant_velocity"):
        row = got["mpjpe_mm"][method]
        assert len(row) == 5 and row[4] is None  # 1000 ms is beyond 10 frames
        assert all(0 < v < 1000 for v in row[:4])
    assert all(a < b for a, b in zip(got["mpjpe_mm"]["zero_velocity"][:3],
                                      got["mpjpe_mm"]["zero_velocity"][1:4], strict=True))
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    for key in ("mpjpe_mm", "rms_mpjpe_up_to_horizon_mm", "mpjs_m_s", "bone_drift_mm"):
        assert key in metrics["overall"]["model"]
    assert set(metrics["per_action"]) == {"walk"}
    rates = metrics["plausibility"]["pass_rate"]
    assert set(rates) == {"ground_truth", "model", "model_carried_amplitude", "zero_velocity",
                          "constant_velocity"}
    assert set(rates["model"]) >= {"bone_length", "foot_skate", "jitter", "velocity"}
    assert rates["ground_truth"]["bone_length"] == rates["zero_velocity"]["bone_length"] == 1.0
    assert len(metrics["recursive"]["model"]) == 30
    assert (tmp_path / "error_curve.png").stat().st_size > 1000


def test_train_predictor_errors_are_clear(tmp_path: Path, capsys) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.txt").write_text("no motion here\n")
    assert cli.main(["train", "predictor", "--data", str(empty), "--out",
                     str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "error:" in err and str(empty) in err
    assert not (tmp_path / "o" / "model.npz").exists()
    config = tmp_path / "c.toml"
    config.write_text("minutes = 0.5\ncritic_steps = 3\n")
    assert cli.main(["train", "predictor", "--config", str(config)]) == 2
    assert "unknown option(s) critic_steps" in capsys.readouterr().err


def test_config_file_sets_defaults_that_options_override(tmp_path: Path) -> None:
    toml = tmp_path / "c.toml"
    toml.write_text('minutes = 0.5\nn-critic = 1\nspeeds = [1.0]\nmirror = false\n')
    args = tp.parse_args(["--config", str(toml), "--minutes", "2"])
    assert (args.minutes, args.n_critic, args.speeds, args.mirror) == (2.0, 1, [1.0], False)
    js = tmp_path / "c.json"
    js.write_text('{"past": 10, "future": 10}')
    assert (tp.parse_args(["--config", str(js)]).past, tp.parse_args([]).past) == (10, 25)
    (tmp_path / "bad.toml").write_text("minutes = \n")
    with pytest.raises(SimenvError, match="bad.toml.*cannot read config"):
        tp.parse_args(["--config", str(tmp_path / "bad.toml")])


def test_recognition_condition_with_the_shipped_predictor(shared_data: Path) -> None:
    _require("predictor-25-50")
    from simenv.data import gestures as g
    from simenv.learning.train_classifier import extrapolate_with_predictor

    root = shared_data / "gestures"
    if not (root / "florence3d" / "skeletal_data.mat").is_file():
        pytest.skip(f"Florence 3D not found under {root}")
    clips = g.load_gesture_clips(root, datasets=["florence3d"])[:6]
    short = g.make_windows(clips, real_frames=g.SHORT_FRAMES)
    out = extrapolate_with_predictor(short, load("predictor-25-50"))
    assert out.x.shape == short.x.shape and out.valid.all() and np.isfinite(out.x).all()
    np.testing.assert_array_equal(out.x[short.valid], short.x[short.valid])
    # the continuation starts where the real second ends (no jump larger than 10 cm)
    n = short.valid.sum(1)
    seams = [np.linalg.norm(out.x[i, n[i]] - out.x[i, n[i] - 1], axis=-1).max()
             for i in range(len(n))]
    assert max(seams) < 0.1
    nine = g.make_windows(g.load_gesture_clips(root, datasets=["florence3d"],
                                               joints="gesture9")[:2],
                          real_frames=g.SHORT_FRAMES, joints=g.gesture_skeleton(
                              "gesture9").joint_names)
    with pytest.raises(MotionError, match="needs gesture15 windows"):
        extrapolate_with_predictor(nine, load("predictor-25-50"))


def test_eval_classifier_writes_every_condition(tmp_path: Path, capsys,
                                                shared_data: Path) -> None:
    _require("gesture-classifier")
    florence = shared_data / "gestures" / "florence3d"
    if not (florence / "skeletal_data.mat").is_file():
        pytest.skip(f"Florence 3D not found under {florence.parent}")
    data = tmp_path / "gestures"
    data.mkdir()
    (data / "florence3d").symlink_to(florence)
    out = tmp_path / "eval"
    assert cli.main(["eval", "classifier", "gesture-classifier", "--data", str(data), "--out",
                     str(out)]) == 0
    assert "real_3s: accuracy" in capsys.readouterr().out
    metrics = json.loads((out / "metrics.json").read_text())
    expected = {"real_3s", "real_1s", "real_1s_pred_2s_cv", "real_1s_pred_2s_zv"}
    if "predictor-25-50" in available():
        expected.add("real_1s_pred_2s_model")
        assert metrics["predictor"] == "predictor-25-50"
    assert set(metrics["test"]) == expected
    for result in metrics["test"].values():
        assert 0 <= result["accuracy"] <= 1
        assert np.sum(result["confusion"]) == result["n"] > 0
    assert (out / "confusion.png").stat().st_size > 1000


def test_train_classifier_on_a_folder_without_recordings(tmp_path: Path, capsys) -> None:
    assert cli.main(["train", "classifier", "--data", str(tmp_path), "--out",
                     str(tmp_path / "o")]) == 2
    assert "error:" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_train_predictor_writes_checkpoint_card_metrics_and_plot(tmp_path: Path, capsys,
                                                                 shared_data: Path) -> None:
    clips = [str(shared_data / "cmu" / "bvh" / f"{n}.bvh") for n in ("02_01", "49_02")]
    out = tmp_path / "run"
    assert cli.main(["train", "predictor", "--data", *clips, "--past", "10", "--future", "10",
                     "--iterations", "3", "--speeds", "1.0", "--no-mirror", "--quiet",
                     "--out", str(out)]) == 0
    assert "zero_velocity" in capsys.readouterr().out
    for name in ("model.npz", "predictor-10-10.npz", "predictor-10-10.md", "metrics.json",
                 "error_curve.png"):
        assert (out / name).is_file(), name
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["config"]["iterations"] == 3
    assert not set(metrics["config"]["train_clips"]) & set(metrics["config"]["test_clips"])
    card = (out / "predictor-10-10.md").read_text()
    assert "Goal check" in card and "Plausibility" in card
    shipped = tp.PredictiveMAWGAN.load(out / "predictor-10-10.npz")
    assert shipped.predict(_history(11)).shape == (2, 10, 17, 3)


#: Budget of the shipped two-person models (checkpoints and cards), bytes.
INTERACTION_BUDGET_BYTES = 40 * 1024 * 1024


def test_shipped_two_person_models_have_cards_within_budget() -> None:
    from simenv.models import INTERACTION_MODELS

    shipped = [n for n in INTERACTION_MODELS if n in available()]
    if not shipped:
        pytest.skip("no two-person model is shipped in assets/models")
    total = 0
    for name in shipped:
        path = checkpoint_path(name)
        card = path.with_suffix(".md")
        assert card.is_file(), f"{name} has no model card"
        assert "split" in card.read_text().lower()
        total += path.stat().st_size + card.stat().st_size
    assert total <= INTERACTION_BUDGET_BYTES, f"two-person models take {total / 2**20:.1f} MB"


@pytest.mark.parametrize("name", ["interformer", "reactive-gan", "bigraphdiff",
                                  "interaction-augment"])
def test_shipped_two_person_model_loads_by_name_and_generates(name: str,
                                                              shared_data: Path) -> None:
    from simenv.data import interaction_data as idata

    _require(name)
    model = load(name)
    assert model.name == name
    windows = idata.make_windows(idata.load_recordings(shared_data))
    test = windows.subset(idata.split_by_recording(windows).test)
    a, b = test.actor[:2], test.reactor[:2]
    if name == "bigraphdiff":
        label = model.labels[0]
        actor, reactor = model.sample([label, label], seed=0)
        assert actor.shape == reactor.shape == (2, test.window, 18, 3)
        again, _ = model.sample([label, label], seed=0)
        np.testing.assert_allclose(actor, again, atol=1e-5)
        assert np.isfinite(actor).all() and np.isfinite(reactor).all()
    elif name == "interaction-augment":
        a2, b2, scales = model.augment(a, b, seed=0)
        assert a2.shape == a.shape and b2.shape == b.shape and scales.shape[0] == 2
        assert np.isfinite(a2).all() and np.isfinite(b2).all()
    else:
        out = model.generate(a, b[:, 0])
        assert out.shape == a.shape and out.dtype == np.float32 and np.isfinite(out).all()
        # Longer than the trained window: chunked generation.
        long = np.concatenate([test.actor[0], test.actor[0][::-1]])
        assert model.generate(long, test.reactor[0, 0]).shape == long.shape

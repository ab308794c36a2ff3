"""The gesture-domain forecaster: shipped checkpoint, validation, checkpoints,
body frame, and a short training run on the real gesture corpus."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import torch

import simenv.models
from simenv.core.errors import MotionError
from simenv.data.gestures import (
    GESTURE15_JOINTS,
    GESTURE_FPS,
    gesture_skeleton,
    to_gesture_joints,
)
from simenv.io import bvh
from simenv.models.checkpoint import CheckpointError
from simenv.models.gesture_predictor import (
    GesturePredictor,
    GesturePredictorConfig,
    body_frame,
    from_body,
    mirror_world,
    observer_offset,
    to_body,
)

torch.set_num_threads(1)
NAME = "predictor-gesture-25-50"


@pytest.fixture(scope="module")
def walk15() -> np.ndarray:
    """The bundled real CMU walk 02_01 on gesture15 at 25 fps: (72, 15, 3) metres."""
    m = bvh.read(Path(str(resources.files("simenv.assets"))) / "cmu_02_01_walk.bvh")
    sub = m.with_positions(to_gesture_joints(m), skeleton=gesture_skeleton())
    return sub.resample(GESTURE_FPS).positions.astype(np.float64)


@pytest.fixture(scope="module")
def shipped() -> GesturePredictor:
    if NAME not in simenv.models.available():
        pytest.skip(f"{NAME} is not shipped in assets/models")
    return simenv.models.load(NAME)


def test_shipped_checkpoint_predicts_world_frames(shipped, walk15) -> None:
    assert isinstance(shipped, GesturePredictor)
    assert (shipped.history_len, shipped.future_len, shipped.fps) == (25, 50, 25.0)
    one = shipped.predict(walk15[:25])
    assert one.shape == (50, 15, 3) and one.dtype == np.float32
    batch = shipped.predict_batch(np.stack([walk15[:25], walk15[10:35]]))
    assert batch.shape == (2, 50, 15, 3)
    np.testing.assert_allclose(batch[0], one, atol=1e-5)
    # World frame: the forecast starts near the last observed pose (within 0.15 m per
    # joint at the first frame: a walker moves ~5 cm in 40 ms) and stays person-sized.
    assert np.linalg.norm(one[0] - walk15[24], axis=-1).max() < 0.15
    assert 1.0 < one[:, :, 2].max() < 2.2 and one[:, :, 2].min() > -0.2
    # A longer history uses its last 25 frames.
    np.testing.assert_allclose(shipped.predict(walk15[:35]), shipped.predict(walk15[10:35]),
                               atol=1e-5)


def test_shipped_checkpoint_is_small_and_has_a_card() -> None:
    path = Path(str(resources.files("simenv.assets"))) / "models" / f"{NAME}.npz"
    if not path.is_file():
        pytest.skip(f"{NAME} is not shipped")
    assert path.stat().st_size < 1024 * 1024
    text = path.with_suffix(".md").read_text()
    assert "MPJPE" in text and "split" in text.lower() and "ms per single" in text


def test_bad_histories_are_clear_errors(walk15) -> None:
    model = GesturePredictor(seed=0)
    h = walk15[:25].copy()
    h[7, 4, 1] = np.nan
    with pytest.raises(MotionError, match="non-finite") as exc:
        model.predict(h)
    assert exc.value.frame == 7
    with pytest.raises(MotionError, match="at least 25"):
        model.predict(walk15[:10])
    with pytest.raises(MotionError, match="15"):
        model.predict(np.zeros((25, 17, 3)))
    with pytest.raises(MotionError, match="shape"):
        model.predict(np.zeros((25, 45)))
    flat = walk15[:25].copy()
    flat[:, 6] = flat[:, 3]  # shoulders on top of each other: facing undefined
    with pytest.raises(MotionError, match="faces"):
        model.predict(flat)
    with pytest.raises(MotionError, match="root_mode"):
        GesturePredictor(GesturePredictorConfig(root_mode="sideways"))


def test_untrained_model_is_zero_velocity(walk15) -> None:
    """The output layer starts at zero, so the untrained forecast repeats the last pose."""
    out = GesturePredictor(seed=3).predict(walk15[:25])
    np.testing.assert_allclose(out, np.repeat(walk15[24:25], 50, axis=0), atol=1e-5)


def test_body_frame_faces_plus_x_and_round_trips(walk15) -> None:
    rng = np.random.default_rng(0)
    h = walk15[None, :25]
    origin, angle = body_frame(h)
    b = to_body(h, origin, angle)
    np.testing.assert_allclose(b[0, -1, 0], 0.0, atol=1e-9)  # last spine at the origin
    across = b[0, -1, 6] - b[0, -1, 3]  # right - left shoulder points to -Y: facing +X
    assert across[1] < 0 and abs(across[0]) < abs(across[1])
    np.testing.assert_allclose(from_body(b, origin, angle), h, atol=1e-9)
    # Rotating and moving the input rotates and moves the forecast (equivariance).
    model = GesturePredictor(seed=1)
    with torch.no_grad():
        for p in model.net.fc_out.parameters():
            p.copy_(0.01 * torch.as_tensor(rng.standard_normal(p.shape), dtype=torch.float32))
    turn, shift = 0.7, np.array([1.0, -2.0, 0.0])
    c, s = np.cos(turn), np.sin(turn)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    moved = walk15[:25] @ rot.T + shift
    np.testing.assert_allclose(model.predict(moved), model.predict(walk15[:25]) @ rot.T + shift,
                               atol=1e-4)


def test_root_modes(walk15) -> None:
    model = GesturePredictor(seed=0)
    still = model.variant(root_mode="still").predict(walk15[:25])
    np.testing.assert_allclose(still[:, 0], np.repeat(walk15[24:25, 0], 50, axis=0), atol=1e-5)
    damped = model.variant(root_mode="damped", root_tau_s=0.5).predict(walk15[:25])
    step = np.linalg.norm(np.diff(damped[:, 0, :2], axis=0), axis=-1)
    assert step[0] > 0.02 and step[-1] < 0.3 * step[0]  # walking ~1.3 m/s, then slows


def _perturb(model: GesturePredictor, seed: int = 1) -> GesturePredictor:
    """Small random weights everywhere (the output layer starts at zero: zero velocity)."""
    gen = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in model.net.parameters():
            p.add_(0.05 * torch.randn(p.shape, generator=gen))
    return model


def test_mirror_average(tmp_path, walk15) -> None:
    model = _perturb(GesturePredictor(GesturePredictorConfig(hidden=32), seed=0))
    history = walk15[:25]
    mirrored = model.variant(mirror_average=True)
    # The average of the forecast and the mirrored forecast of the mirrored history ...
    np.testing.assert_allclose(
        mirrored.predict(history),
        0.5 * (model.predict(history) + mirror_world(model.predict(mirror_world(history)))),
        atol=1e-5)
    # ... commutes with the mirror, which the network alone does not.
    np.testing.assert_allclose(mirrored.predict(mirror_world(history)),
                               mirror_world(mirrored.predict(history)), atol=1e-5)
    assert not np.allclose(model.predict(mirror_world(history)),
                           mirror_world(model.predict(history)), atol=1e-3)
    assert mirrored.net is model.net and not model.config.mirror_average
    back = GesturePredictor.load(mirrored.save(tmp_path / "m.npz"))
    assert back.config.mirror_average
    np.testing.assert_array_equal(back.predict(history), mirrored.predict(history))
    with pytest.raises(MotionError, match="root_mode"):
        model.variant(root_mode="flying")


def test_observer_offset_is_where_the_observer_stands_in_the_body_frame(walk15) -> None:
    h = walk15[None, :25]
    origin, angle = body_frame(h)
    # An observer 2 m ahead of the person (body +X) and 1 m to its left (body +Y).
    ahead = from_body(np.array([[[[2.0, 1.0, 0.5]]]]), origin, angle)[0, 0, 0]
    np.testing.assert_allclose(observer_offset(ahead[None], origin, angle),
                               [[20.0, 10.0, 1.0]], atol=1e-9)  # decimetres, known
    for unknown in (None, np.full((1, 3), np.nan)):
        np.testing.assert_array_equal(observer_offset(unknown, origin, angle), [[0, 0, 0]])


def test_observer_input(tmp_path, walk15) -> None:
    """The forecast depends on where the observer stands, turns and moves with the world,
    commutes with the mirror when averaged, and survives save/load."""
    config = GesturePredictorConfig(hidden=32, observer_input=True, mirror_average=True)
    model = _perturb(GesturePredictor(config, seed=0))
    history, near, far = walk15[:25], np.array([1.0, 0.5, 0.0]), np.array([6.0, -3.0, 0.0])
    assert not np.allclose(model.predict(history, near), model.predict(history, far),
                           atol=1e-3)
    # Unknown: None, or a non-finite row of a batch.
    both = model.predict(np.stack([history, history]), np.stack([near, np.full(3, np.nan)]))
    np.testing.assert_allclose(both[0], model.predict(history, near), atol=1e-6)
    np.testing.assert_allclose(both[1], model.predict(history), atol=1e-6)
    turn, shift = 0.7, np.array([1.0, -2.0, 0.0])
    c, s = np.cos(turn), np.sin(turn)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    np.testing.assert_allclose(model.predict(history @ rot.T + shift, near @ rot.T + shift),
                               model.predict(history, near) @ rot.T + shift, atol=1e-4)
    flip = np.array([1.0, -1.0, 1.0])
    np.testing.assert_allclose(model.predict(mirror_world(history), near * flip),
                               mirror_world(model.predict(history, near)), atol=1e-5)
    back = GesturePredictor.load(model.save(tmp_path / "m.npz"))
    assert back.config.observer_input
    np.testing.assert_array_equal(back.predict(history, near), model.predict(history, near))
    # A model without the input ignores the observer.
    plain = _perturb(GesturePredictor(GesturePredictorConfig(hidden=32), seed=0))
    np.testing.assert_array_equal(plain.predict(history, near), plain.predict(history))
    with pytest.raises(MotionError, match="observer"):
        model.predict(history, np.zeros((2, 3)))
    with pytest.raises(MotionError, match="observer"):
        model.predict(history, "left")


def test_save_load_round_trip(tmp_path, walk15) -> None:
    model = GesturePredictor(GesturePredictorConfig(hidden=32, root_mode="damped"), seed=5)
    _perturb(model)
    path = model.save(tmp_path / "m.npz", metadata={"fold": 2})
    back = GesturePredictor.load(path)
    assert back.config == model.config and back.metadata["fold"] == 2
    np.testing.assert_array_equal(back.predict(walk15[:25]), model.predict(walk15[:25]))
    with np.load(path, allow_pickle=False) as data:  # arrays only: loads without pickle
        assert "net.fc_in.weight" in data.files
    with pytest.raises(CheckpointError):
        GesturePredictor.load(tmp_path / "missing.npz")
    np.savez(tmp_path / "other.npz", format=np.array("something-else"))
    with pytest.raises(CheckpointError, match="not a"):
        GesturePredictor.load(tmp_path / "other.npz")


# -- real gesture corpus ---------------------------------------------------------------


@pytest.fixture(scope="module")
def recordings(shared_data, gesture_root):
    from simenv.learning.train_gesture_predictor import load_sequences

    return load_sequences(shared_data, cmu=False)


def test_folds_keep_held_out_subjects_out(recordings) -> None:
    from simenv.learning.train_gesture_predictor import eval_windows, split_fold

    assert {r.dataset for r in recordings} == {"msr_action3d", "utkinect"}
    assert all(len(r.positions) >= 75 for r in recordings)
    for k in range(5):
        train, test = split_fold(recordings, k)
        held = {r.subject_key for r in test}
        assert held and not held & {r.subject_key for r in train}
        assert all(int(s.rsplit("/s", 1)[1]) % 5 == (k + 1) % 5 for s in held)
        windows, names = eval_windows(test)
        assert windows.shape[1:] == (75, 15, 3) and len(names) == len(windows)


def test_training_windows_carry_their_observer(recordings, walk15) -> None:
    """Kinect windows see their sensor (the world origin, moved by the augmentation like
    the body), CMU windows no observer; the network's flag says which."""
    from simenv.learning.train_gesture_predictor import (
        Recording,
        WindowSampler,
        training_tensors,
    )

    there_and_back = np.concatenate([walk15, walk15[::-1]]).astype(np.float32)  # >= 75 frames
    cmu = Recording(there_and_back, "cmu", None, "cmu/02_01")
    sampler = WindowSampler([recordings[0], cmu], 75, cmu_fraction=0.5, seed=0)
    windows, observers = sampler.sample(64)
    is_cmu = np.isnan(observers).all(axis=1)
    assert 0 < is_cmu.sum() < 64
    np.testing.assert_array_equal(observers[~is_cmu], 0.0)
    model = GesturePredictor(GesturePredictorConfig(observer_input=True))
    *_, observer, target = training_tensors(model, windows, np.zeros(64), observers)
    np.testing.assert_array_equal(observer[:, 2].numpy(), (~is_cmu).astype(np.float32))
    # The sensor stands in front of the Kinect subjects: 1.5-4 m ahead in the body frame.
    ahead = observer[~is_cmu, 0].numpy() / 10
    assert target.shape == (64, 50, 45) and np.median(ahead) > 1.0


def test_weight_average_leaves_training_alone(recordings) -> None:
    """The moving average of the weights is what the model ends with; the steps that
    train it are the same with or without it."""
    from simenv.learning.train_gesture_predictor import TrainConfig, train

    runs = [train(recordings, TrainConfig(steps=100, batch=16, ema_fraction=f),
                  progress=False) for f in (0.0, 0.25)]
    assert runs[0][1]["loss"] == runs[1][1]["loss"]
    last, averaged = (m.net.fc_out.weight.detach().numpy() for m, _ in runs)
    assert not np.allclose(last, averaged)
    # The average lags the last weights: nearer the zero-velocity start (W_out = 0).
    assert 0 < np.abs(averaged).sum() < np.abs(last).sum()


def test_short_training_lowers_the_loss_and_evaluates(recordings, tmp_path) -> None:
    from simenv.learning.train_gesture_predictor import (
        TrainConfig,
        eval_windows,
        evaluate,
        retrieval_baselines,
        train,
        write_doc,
    )

    train_recs = [r for r in recordings if r.fold != 0]
    model, history = train(train_recs, TrainConfig(
        steps=300, batch=64, seed=0, model={"mirror_average": True, "observer_input": True}),
        progress=False)
    assert history["loss"][-1] < 0.9 * history["loss"][0]
    assert "utkinect/s01" not in history["subjects"]  # fold 0's subject stays out
    windows, names = eval_windows([r for r in recordings if r.fold == 0], stride=25)
    result = evaluate(model, windows, names, retrieval_baselines(train_recs))
    assert set(result) >= {"all", "utkinect", "msr_action3d"}
    table = result["all"]
    for method in ("model-learned", "model-damped", "model-unmirrored", "model-no-observer",
                   "zero-velocity", "constant-velocity", "nearest-neighbour",
                   "20-nearest-neighbours"):
        assert np.isfinite(table[method]["mpjpe_2s_mm"])
    assert table["zero-velocity"]["mpjs_mps"] == 0.0 and table["real_mpjs_mps"] > 0
    # The mirror average and the observer move the forecast, so the rows differ.
    for other in ("model-unmirrored", "model-no-observer"):
        assert table["model-learned"]["mpjpe_2s_mm"] != table[other]["mpjpe_2s_mm"]
    doc = tmp_path / "gesture_prediction.md"
    write_doc(doc, {"folds": {0: result}, "pooled": result, "train_cpu_s": {0: 1.0},
                    "skipped": []}, "pytest", "learned")
    text = doc.read_text()
    assert "## Mirror average (pooled)" in text and "the network alone" in text
    assert "## Where the observer is (pooled)" in text and "not told" in text
    assert "## Where the error is (pooled)" in text
    # Zero velocity keeps the spine where it was: its spine error is the spine's travel.
    spine, w = GESTURE15_JOINTS.index("spine"), windows.astype(np.float64)
    travel = 1000 * np.linalg.norm(w[:, 74, spine] - w[:, 24, spine], axis=-1).mean()
    zv = table["zero-velocity"]
    assert zv["spine_curve_mm"][49] == pytest.approx(travel, abs=0.01)
    for method in ("model-learned", "zero-velocity"):  # the pose error ignores the spine
        assert 0 < table[method]["pose_curve_mm"][49] < table[method]["curve_mm"][49] + 1e-6

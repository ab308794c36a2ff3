"""Gesture classifier: adjacency mask, masked attention, shapes, training on real
windows, checkpoints and the evaluation conditions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from simenv.core.errors import FormatError, MotionError
from simenv.data import gestures as g
from simenv.learning.train_classifier import (
    TrainConfig,
    build_model,
    class_weights,
    extrapolate,
    score,
    train_step,
    training_windows,
)
from simenv.models.gesture_classifier import (
    GestureClassifier,
    MaskedAttention,
    adjacency_mask,
    adjacency_matrices,
)

SHIPPED = Path(__file__).resolve().parent.parent / "assets" / "models" / "gesture-classifier.npz"


@pytest.fixture(scope="module")
def florence(shared_data: Path) -> list[g.GestureClip]:
    root = shared_data / "gestures"
    if not (root / "florence3d" / "skeletal_data.mat").is_file():
        pytest.skip(f"Florence 3D not found under {root}")
    return g.load_gesture_clips(root, datasets=["florence3d"])


def _small_model(seed: int = 0) -> GestureClassifier:
    config = TrainConfig(seed=seed, dim=32, heads=4, layers=1, ffn=64, feature_dim=32,
                         dropout=0.0)
    return build_model(config)


def test_adjacency_is_identity_plus_inward_plus_outward() -> None:
    # spine -> neck -> (head, left shoulder): joint 1 has children 2 and 3.
    parents = (-1, 0, 1, 1)
    eye, inward, outward = adjacency_matrices(parents)
    expected_in = np.array([[0, 1, 0, 0],
                            [0, 0, 1, 1],
                            [0, 0, 0, 0],
                            [0, 0, 0, 0]], np.float32)
    assert np.array_equal(eye, np.eye(4))
    assert np.array_equal(inward, expected_in)
    assert np.array_equal(outward, expected_in.T)
    expected_mask = np.array([[1, 1, 0, 0],
                              [1, 1, 1, 1],
                              [0, 1, 1, 0],
                              [0, 1, 0, 1]], bool)
    assert np.array_equal(adjacency_mask(parents).numpy(), expected_mask)
    # gesture15: the wrist only sees itself and its elbow.
    names = g.GESTURE15_JOINTS
    mask = adjacency_mask(g.gesture_skeleton().parents).numpy()
    rw = names.index("right_wrist")
    assert {names[j] for j in np.flatnonzero(mask[rw])} == {"right_wrist", "right_elbow"}
    assert mask.sum() == 15 + 2 * 14  # identity + two directions of the 14 bones


def test_attention_gives_masked_pairs_zero_weight() -> None:
    torch.manual_seed(0)
    att = MaskedAttention(16, 4)
    x = torch.randn(6, 15, 16)
    allowed = adjacency_mask(g.gesture_skeleton().parents)
    out, w = att(x, allowed=allowed, return_weights=True)
    assert w.shape == (6, 4, 15, 15)
    assert (w[:, :, ~allowed] == 0).all()
    assert (w[:, :, allowed] > 0).all()
    assert torch.allclose(w.sum(-1), torch.ones(6, 4, 15))
    # The fused path computes the same thing.
    assert torch.allclose(att(x, allowed=allowed), out, atol=1e-5)
    # Key masking (padded frames) in temporal attention.
    key_valid = torch.arange(15)[None].expand(6, 15) < torch.tensor([[3], [15], [7], [1],
                                                                    [9], [12]])
    out_t, w_t = att(x, key_valid=key_valid, return_weights=True)
    invalid = ~key_valid[:, None, None, :].expand_as(w_t)
    assert (w_t[invalid] == 0).all() and (w_t[~invalid] > 0).all()
    assert torch.allclose(att(x, key_valid=key_valid), out_t, atol=1e-5)


def test_forward_shapes_and_padding_carries_no_signal(florence) -> None:
    model = _small_model().eval()
    w = g.make_windows(florence[:4])
    x, valid = torch.from_numpy(w.x), torch.from_numpy(w.valid)
    logits = model(x, valid)
    assert logits.shape == (4, len(g.GESTURE_LABELS))
    assert model.features(x, valid).shape == (4, 32)
    assert model.predict_proba(w.x, w.valid).shape == (4, len(g.GESTURE_LABELS))
    # Florence clips are < 2 s: scribbling over the padded frames changes nothing.
    assert (~w.valid).any(axis=1).all()
    scribbled = x.clone()
    scribbled[~valid] = torch.randn(int((~valid).sum()), 15, 3)
    with torch.no_grad():
        assert torch.allclose(model(scribbled, valid), logits, atol=1e-5)
        assert not torch.allclose(model(scribbled), logits, atol=1e-3)
        # A window's logits do not depend on the other windows of its batch (the model
        # drops the batch's trailing padding).
        i = int(valid.sum(1).argmin())
        assert valid[i].sum() < valid.sum(1).max()
        assert torch.allclose(model(x[i:i + 1], valid[i:i + 1])[0], logits[i], atol=1e-5)
    raw, v = g.cut_window(florence[0].positions)
    assert np.allclose(model.classify_world(raw, v), model.predict_proba(w.x[:1], w.valid[:1])[0],
                       atol=1e-5)
    with pytest.raises(MotionError, match=r"shape \(B, 75, 15, 3\)"):
        model(x[:, :50])
    with pytest.raises(MotionError, match="at least one valid frame"):
        model(x, torch.zeros_like(valid))


def test_training_steps_reduce_loss_on_real_windows(florence) -> None:
    torch.set_num_threads(1)
    rng = np.random.default_rng(0)
    pick = rng.choice(len(florence), 32, replace=False)
    batch = g.make_windows([florence[i] for i in pick])
    model = _small_model(seed=1)
    weights = class_weights(batch.y, len(g.GESTURE_LABELS))
    opt = torch.optim.AdamW(model.parameters(), lr=2e-3)
    x, valid, y = (torch.from_numpy(a) for a in (batch.x, batch.valid, batch.y))

    def loss() -> float:
        with torch.no_grad():
            return torch.nn.functional.cross_entropy(model.eval()(x, valid), y).item()

    before = loss()
    for _ in range(25):
        train_step(model, opt, batch, weights, label_smoothing=0.0)
    after = loss()
    assert after < 0.7 * before


def test_checkpoint_round_trip(tmp_path: Path, florence) -> None:
    model = _small_model(seed=2).eval()
    w = g.make_windows(florence[:3])
    path = model.save(tmp_path / "gc.npz", metadata={"note": "test"})
    loaded = GestureClassifier.load(path)
    assert loaded.metadata == {"note": "test"}
    assert loaded.config == model.config
    assert np.allclose(loaded.predict_proba(w.x, w.valid), model.predict_proba(w.x, w.valid))
    (tmp_path / "junk.npz").write_bytes(b"not a checkpoint")
    with pytest.raises(FormatError, match="cannot read checkpoint"):
        GestureClassifier.load(tmp_path / "junk.npz")
    np.savez(tmp_path / "other.npz", format=np.array("other"))
    with pytest.raises(FormatError, match="not a simenv-gesture-classifier"):
        GestureClassifier.load(tmp_path / "other.npz")
    with pytest.raises(FormatError, match="not found"):
        GestureClassifier.load(tmp_path / "missing.npz")


def test_extrapolation_and_scores(florence) -> None:
    short = g.make_windows(florence[:6], real_frames=g.SHORT_FRAMES)
    cv = extrapolate(short, "cv")
    zv = extrapolate(short, "zv")
    assert cv.valid.all() and zv.valid.all()
    for i, v in enumerate(short.valid):
        n = int(v.sum())
        step = short.x[i, n - 1] - short.x[i, n - 2]
        assert np.allclose(cv.x[i, :n], short.x[i, :n])
        assert np.allclose(cv.x[i, -1], short.x[i, n - 1] + (75 - n) * step, atol=1e-4)
        assert np.allclose(zv.x[i, n:], short.x[i, n - 1])
    y_true = np.array([0, 0, 1, 2, 10])
    y_pred = np.array([0, 1, 1, 2, 0])
    s = score(y_true, y_pred, ["a", "a", "b", "b", "b"])
    assert s["accuracy"] == 0.6
    c = len(g.GESTURE_LABELS)
    assert s["confusion"][0] == [1, 1] + [0] * (c - 2) and s["confusion"][10][0] == 1
    assert s["per_dataset_accuracy"] == {"a": 0.5, "b": round(2 / 3, 4)}
    # wave (0) -> answer_phone (1) is a wrong reaction; other (10) -> wave too.
    assert s["room_reaction_accuracy"] == 0.6
    # An idle window read as idle counts in the accuracy, not in accuracy_labelled.
    idle = g.GESTURE_LABELS.index(g.IDLE_LABEL)
    s = score(np.append(y_true, idle), np.append(y_pred, idle), ["a", "a", "b", "b", "b", "b"])
    assert s["accuracy"] == round(4 / 6, 4) and s["accuracy_labelled"] == 0.6


def test_training_windows_short_held_and_full(florence) -> None:
    """The three kinds of training window: 1 s with the rest masked, 1 s with the last
    pose held as valid frames, a 3-s crop; each a contiguous stretch of its clip."""
    long_clips = [c for c in florence if c.num_frames > 30][:8]
    joints = g.GESTURE15_JOINTS
    masked = training_windows(long_clips, np.random.default_rng(0),
                              TrainConfig(short_prob=1.0, hold_prob=0.0), joints)
    assert (masked.valid.sum(1) == g.SHORT_FRAMES).all()
    held = training_windows(long_clips, np.random.default_rng(0),
                            TrainConfig(short_prob=0.0, hold_prob=1.0), joints)
    assert held.valid.all()
    assert np.allclose(held.x[:, g.SHORT_FRAMES:], held.x[:, g.SHORT_FRAMES - 1:g.SHORT_FRAMES])
    assert np.allclose(held.x[:, :g.SHORT_FRAMES], masked.x[:, :g.SHORT_FRAMES])  # same draw
    full = training_windows(long_clips, np.random.default_rng(0),
                            TrainConfig(short_prob=0.0, hold_prob=0.0), joints)
    assert (full.valid.sum(1) == [min(c.num_frames, 75) for c in long_clips]).all()
    # The 1 s is a stretch of the clip: it equals the clip's frames at some offset once
    # both are normalised the same way.
    clip = long_clips[0]
    offsets = [o for o in range(clip.num_frames - g.SHORT_FRAMES + 1) if np.allclose(
        g.normalise_windows(*g.cut_window(clip.positions, offset=o,
                                          real_frames=g.SHORT_FRAMES)), masked.x[0],
        atol=1e-5)]
    assert len(offsets) == 1


@pytest.mark.skipif(not SHIPPED.is_file(), reason="no shipped gesture classifier checkpoint")
def test_shipped_checkpoint_recognises_held_out_subjects(shared_data: Path) -> None:
    model = GestureClassifier.load(SHIPPED)
    assert model.config.labels == g.GESTURE_LABELS
    clips = g.load_gesture_clips(shared_data / "gestures", datasets=["florence3d"],
                                 joints=model.config.extra["joint_set"])
    _, test = g.split_cross_subject(clips)
    w = g.make_windows(test, joints=model.config.joint_names)
    pred = model.predict_proba(w.x, w.valid).argmax(1)
    # 9 Florence classes map to 8 labels; chance is ~1/8.
    assert (pred == w.y).mean() > 0.4

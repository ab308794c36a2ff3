"""Interaction augmentation with skeleton priors (simenv.models.interaction_augment)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from simenv.core.errors import MotionError
from simenv.data import augment_targets as at
from simenv.data import interaction_data as idata
from simenv.models import interaction_augment as ia
from simenv.models.predictor import CheckpointError

TINY = ia.InteractionAugmenterConfig(hidden=8, latent=4, prior_hidden=16, epochs=6,
                                     batch=4, lr=1e-3, scales_per_window=1,
                                     rotate_augment=False, prior_steps=200)
SHIPPED = Path(__file__).resolve().parent.parent / "assets" / "models" / \
    "interaction-augment.npz"


@pytest.fixture(scope="module")
def small(interaction_windows):
    """Twelve real windows, half of them with key-pair contacts."""
    d = at.contact_distances(interaction_windows.actor, interaction_windows.reactor)
    touch = (d < 0.15).any(axis=(1, 2))
    idx = np.concatenate([np.flatnonzero(touch)[::20][:6], np.flatnonzero(~touch)[::40][:6]])
    return interaction_windows.subset(np.sort(idx))


@pytest.fixture(scope="module")
def trained(small):
    return ia.train(small, TINY, seed=0, progress=False)


def test_normalised_adjacency_toy():
    """Two connected nodes: A + I is all ones, degrees 2, so every entry is 1/2."""
    np.testing.assert_allclose(ia.normalised_adjacency([(0, 1)], 2), np.full((2, 2), 0.5))
    adj = ia.normalised_adjacency(ia.two_person_edges(), 36)
    assert adj.shape == (36, 36) and np.allclose(adj, adj.T)
    hand, spine = idata.INTER18_JOINTS.index("right_hand"), idata.INTER18_JOINTS.index("spine")
    assert adj[hand, 18 + spine] > 0 and adj[0, 18] == 0


def test_zero_offsets_reproduce_fk_scaling(small):
    """With zero decoder offsets the assembled reactor is B with every bone scaled."""
    b = torch.as_tensor(small.reactor[:2])
    s = torch.full((2, 17), 1.2)
    scaled = (b[..., at.BONE_CHILDREN, :] - b[..., [at.PARENTS[j] for j in at.BONE_CHILDREN],
                                                :]) * s[:, None, :, None]
    out = ia.assemble(b[..., 0, :], scaled, torch.zeros(2, b.shape[1], 18, 3))
    expect = b[..., :1, :] + 1.2 * (b - b[..., :1, :])
    np.testing.assert_allclose(out.numpy(), expect.numpy(), atol=1e-5)


def test_training_lowers_loss(trained):
    model, history = trained
    assert len(history["loss"]) == TINY.epochs
    assert history["loss"][-1] < history["loss"][0]
    assert {"b_rec", "a_rec", "a_jpd", "prior_loss", "cpu_seconds"} <= set(history)
    assert history["prior_loss"][-1] < history["prior_loss"][0]


def test_augment_shapes_and_protocol(trained, small):
    model, _ = trained
    assert model.name == "interaction-augment"
    a, b = small.actor[:3], small.reactor[:3]
    na, nb, s = model.augment(a, b, seed=1)
    assert na.shape == nb.shape == a.shape and na.dtype == np.float32
    assert s.shape == (3, 17)
    assert np.isin(np.round(s, 2), at.SCALE_GRID).all()
    na1, nb1, s1 = model.augment(a[0], b[0], np.full(17, 0.8), seed=1)
    assert na1.shape == nb1.shape == a[0].shape and s1.shape == (17,)
    again = model.augment(a, b, seed=1)
    np.testing.assert_array_equal(again[1], nb)
    # any T >= 2
    assert model.augment(a[:, :7], b[:, :7], seed=0)[0].shape == (3, 7, 18, 3)


def test_augment_bad_input(trained, small):
    model, _ = trained
    a, b = small.actor[:2], small.reactor[:2]
    with pytest.raises(MotionError, match="one shape"):
        model.augment(a, b[:, :10])
    with pytest.raises(MotionError, match="actor_window"):
        model.augment(a[..., :17, :], b)
    with pytest.raises(MotionError, match="T >= 2"):
        model.augment(a[:, :1], b[:, :1])
    bad = b.copy()
    bad[0, 3, 4, 1] = np.nan
    with pytest.raises(MotionError, match="non-finite"):
        model.augment(a, bad)
    with pytest.raises(MotionError, match="scales") as err:
        model.augment(a, b, np.full(17, 1.5))
    assert err.value.field == "scales"
    with pytest.raises(MotionError, match="scales"):
        model.augment(a, b, np.ones((3, 17)))


def test_save_load_round_trip(trained, small, tmp_path):
    model, _ = trained
    path = model.save(tmp_path / "aug.npz", metadata={"note": "test"})
    back = ia.InteractionAugmenter.load(path)
    assert back.config == model.config and back.metadata["note"] == "test"
    x = model.augment(small.actor[:2], small.reactor[:2], seed=4)
    y = back.augment(small.actor[:2], small.reactor[:2], seed=4)
    for u, v in zip(x, y, strict=True):
        np.testing.assert_array_equal(u, v)
    with np.load(path) as data:
        assert "format" in data.files
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(CheckpointError):
        ia.InteractionAugmenter.load(tmp_path / "junk.npz")
    np.savez(tmp_path / "other.npz", format=np.array("something-else"))
    with pytest.raises(CheckpointError, match="not a"):
        ia.InteractionAugmenter.load(tmp_path / "other.npz")


def test_evaluate_reports_model_and_naive(trained, small):
    model, _ = trained
    targets = at.build_targets(small, 1, seed=5)
    res = ia.evaluate(model, targets)
    assert res["naive"]["B_error_mm"] == pytest.approx(0.0, abs=1e-3)  # B' is FK scaling
    assert res["naive"]["A_error_mm"] > 0 and res["model"]["B_error_mm"] > 0
    assert res["naive"]["jpd_contact_mm"] > 0


def test_generalisation_splits_no_leakage(interaction_windows):
    targets = at.build_targets(interaction_windows, 1, seed=0,
                               weights=at.AdaptWeights(iterations=2))
    splits = ia.generalisation_splits(targets, interaction_windows)
    assert set(splits) == {"random", "cross-scale", "cross-interaction", "both"}
    rec = interaction_windows.window_recording_names[targets.window]
    label = interaction_windows.window_labels[targets.window]
    dev = np.abs(targets.scales.mean(axis=1) - 1)
    for name, (tr, te) in splits.items():
        assert len(tr) and len(te) and not set(tr) & set(te)
        assert not set(rec[tr]) & set(rec[te]), name
    for name in ("cross-scale", "both"):
        tr, te = splits[name]
        assert dev[te].min() > dev[tr].max()
    for name in ("cross-interaction", "both"):
        tr, te = splits[name]
        assert not set(label[tr]) & set(label[te])
    assert set(label[splits["cross-interaction"][1]]) == {"salsa"}
    with pytest.raises(MotionError, match="held_out_label"):
        ia.generalisation_splits(targets, interaction_windows, held_out_label="wave")


@pytest.mark.skipif(not SHIPPED.is_file(), reason="interaction-augment checkpoint not shipped")
def test_shipped_checkpoint_loads_and_augments(small):
    model = ia.InteractionAugmenter.load(SHIPPED)
    na, nb, s = model.augment(small.actor[:2], small.reactor[:2], seed=0)
    assert np.isfinite(na).all() and np.isfinite(nb).all()
    assert SHIPPED.stat().st_size < 8 * 2 ** 20
    # the prior spreads over the range (the uniform grid has std 0.158) and keeps the
    # left/right symmetry of its training scales
    s = model.sample_scales(1000, seed=0)
    assert s.std(axis=0).mean() > 0.08 and s.min() >= 0.75 and s.max() <= 1.25
    left, right = at.BONE_NAMES.index("left_knee"), at.BONE_NAMES.index("right_knee")
    assert np.mean(s[:, left] == s[:, right]) > 0.8

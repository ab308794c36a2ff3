"""Training targets of interaction augmentation (simenv.data.augment_targets)."""

from __future__ import annotations

import numpy as np
import pytest

from simenv.core.errors import MotionError
from simenv.data import augment_targets as at


@pytest.fixture(scope="module")
def contact_windows(interaction_windows):
    """Eight real windows (salsa) whose key pairs come into contact."""
    d = at.contact_distances(interaction_windows.actor, interaction_windows.reactor)
    idx = np.flatnonzero((d < 0.15).any(axis=(1, 2)))
    return interaction_windows.subset(idx[:: max(1, len(idx) // 8)][:8])


def test_grid_bones_and_groups():
    assert at.SCALE_GRID == (0.75, 0.8, 0.85, 0.9, 0.95, 1.0, 1.05, 1.1, 1.15, 1.2, 1.25)
    assert at.NUM_BONES == 17
    assert len(at.SCALE_GROUPS) == 10
    for group in at.SCALE_GROUPS:
        names = {at.BONE_NAMES[k].removeprefix("left_").removeprefix("right_")
                 for k in group}
        assert len(names) == 1


def test_sample_scales_symmetric_and_free():
    rng = np.random.default_rng(0)
    s = at.sample_scales(500, rng)
    assert s.shape == (500, 17)
    assert np.isin(np.round(s, 2), at.SCALE_GRID).all()
    for group in at.SCALE_GROUPS:
        assert (s[:, list(group)] == s[:, [group[0]]]).all()
    assert set(np.round(s[:, 0], 2)) == set(at.SCALE_GRID)  # every value reachable
    free = at.sample_scales(500, rng, symmetric=False)
    left, right = at.BONE_NAMES.index("left_knee"), at.BONE_NAMES.index("right_knee")
    assert (free[:, left] != free[:, right]).any()


def test_scale_skeleton_uniform_toy_matches_similarity():
    """Uniform scale s: B' = root + s (B - root), then the lowest ankle back at its height."""
    rng = np.random.default_rng(1)
    pose = rng.normal(size=(5, 18, 3))
    pose[:, :, 2] += 1.0
    out = at.scale_skeleton(pose, np.full(17, 1.25))
    expect = pose[:, :1] + 1.25 * (pose - pose[:, :1])
    low = pose[:, at.ANKLES, 2].min(axis=1) - expect[:, at.ANKLES, 2].min(axis=1)
    expect[..., 2] += low[:, None]
    np.testing.assert_allclose(out, expect, atol=1e-5)
    np.testing.assert_allclose(at.scale_skeleton(pose, np.ones(17)), pose, atol=1e-6)


def test_scale_skeleton_real_bones_scaled_directions_kept(interaction_windows):
    b = interaction_windows.reactor[:6]
    s = at.sample_scales(6, np.random.default_rng(2))
    out = at.scale_skeleton(b, s)
    v0, v1 = at.bone_vectors(b), at.bone_vectors(out)
    len0, len1 = np.linalg.norm(v0, axis=-1), np.linalg.norm(v1, axis=-1)
    np.testing.assert_allclose(len1, len0 * s[:, None], rtol=1e-4, atol=1e-6)
    cos = (v0 * v1).sum(-1) / (len0 * len1)
    assert cos.min() > 1 - 1e-5
    np.testing.assert_allclose(out[:, :, at.ANKLES, 2].min(-1), b[:, :, at.ANKLES, 2].min(-1),
                               atol=1e-5)


def test_bad_scales_and_positions():
    pose = np.zeros((4, 18, 3))
    with pytest.raises(MotionError, match="scales") as err:
        at.scale_skeleton(pose, np.full(17, 1.3))
    assert err.value.field == "scales"
    with pytest.raises(MotionError, match="17"):
        at.scale_skeleton(pose, np.ones(16))
    with pytest.raises(MotionError, match="positions"):
        at.scale_skeleton(np.zeros((4, 17, 3)), np.ones(17))
    with pytest.raises(MotionError, match="non-finite"):
        at.scale_skeleton(np.full((4, 18, 3), np.nan), np.ones(17))


def test_adapt_without_contact_is_identity(interaction_windows):
    d = at.contact_distances(interaction_windows.actor, interaction_windows.reactor)
    free = np.flatnonzero(~(d < 0.15).any(axis=(1, 2)))[:3]
    a, b = interaction_windows.actor[free], interaction_windows.reactor[free]
    nb = at.scale_skeleton(b, np.full(17, 1.2))
    out, info = at.adapt_actor(a, b, nb)
    assert info["optimised_windows"] == 0 and info["jpd_contact_mm"] is None
    np.testing.assert_array_equal(out, a)


def test_adapt_keeps_contacts_and_bone_lengths(contact_windows):
    w = contact_windows
    s = np.full((len(w), 17), 1.25)
    nb = at.scale_skeleton(w.reactor, s)
    out, info = at.adapt_actor(w.actor, w.reactor, nb)
    assert info["optimised_windows"] == len(w)
    assert info["energy_end"] < info["energy_start"]
    # contacts kept much better than by the unchanged actor
    assert info["jpd_contact_mm"] < 0.5 * info["jpd_contact_naive_mm"]
    np.testing.assert_allclose(np.linalg.norm(at.bone_vectors(out), axis=-1),
                               np.linalg.norm(at.bone_vectors(w.actor), axis=-1), atol=1e-4)
    with pytest.raises(MotionError, match="shape"):
        at.adapt_actor(w.actor, w.reactor, nb[:, :10])


def test_build_targets(contact_windows):
    w = contact_windows.subset(np.arange(4))
    quick = at.AdaptWeights(iterations=10)
    t = at.build_targets(w, 2, seed=3, weights=quick)
    assert len(t) == 2 * len(w)
    assert t.actor_target.shape == t.reactor_target.shape == t.actor.shape
    np.testing.assert_array_equal(t.window, np.repeat(np.arange(len(w)), 2))
    assert t.contact.any() and t.info["jpd_contact_mm"] < t.info["jpd_contact_naive_mm"]
    again = at.build_targets(w, 2, seed=3, weights=quick)
    np.testing.assert_array_equal(again.actor_target, t.actor_target)
    sub = t.subset([0, 3])
    assert len(sub) == 2 and np.array_equal(sub.scales, t.scales[[0, 3]])
    with pytest.raises(MotionError, match="scales_per_window"):
        at.build_targets(w, 0)

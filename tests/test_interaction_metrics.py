"""Tests for simenv.data.interaction_metrics on toy inputs with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from simenv.core.errors import MotionError
from simenv.data import interaction_metrics as im
from simenv.data.interaction_data import INTER18_JOINTS, inter18_skeleton
from simenv.learning.interaction_features import default_feature_extractor

J = list(INTER18_JOINTS)
PARENTS = inter18_skeleton().parents


def _poses(n: int = 3, t: int = 20, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(n, t, 18, 3))


def test_afd_and_joint_error_known_offsets():
    x = _poses()
    assert im.afd(x, x) == 0.0 and im.joint_error_mm(x, x) == 0.0
    shifted = x + np.array([0.1, 0.0, 0.0])
    # every joint 0.1 m off: squared pose distance 18 * 0.01 m^2, joint error 100 mm
    assert im.afd(shifted, x) == pytest.approx(18 * 0.01)
    assert im.joint_error_mm(shifted, x) == pytest.approx(100.0)
    # one joint 0.3 m off in one frame of one window: AFD = 0.09 / (N * T)
    one = x.copy()
    one[1, 4, 7] += [0.0, 0.3, 0.0]
    assert im.afd(one, x) == pytest.approx(0.09 / 60)
    with pytest.raises(MotionError, match="same shape"):
        im.afd(x[:, :10], x)
    bad = x.copy()
    bad[0, 2, 3, 1] = np.nan
    with pytest.raises(MotionError, match="non-finite"):
        im.afd(bad, x)


def test_bone_length_error():
    x = _poses()
    ref = x[:, 0]
    rigid = x[:, :1] + np.array([1.0, -2.0, 0.5])  # translated copy of frame 0
    assert im.bone_length_error_mm(np.repeat(rigid, 5, axis=1), ref, PARENTS) == \
        pytest.approx(0.0, abs=1e-9)
    # scaled by 1.1 about the pelvis: every bone 10 % longer
    grown = ref[:, None, 0:1] + 1.1 * (ref[:, None] - ref[:, None, 0:1])
    lengths = np.linalg.norm(ref[:, [j for j, p in enumerate(PARENTS) if p >= 0]]
                             - ref[:, [p for p in PARENTS if p >= 0]], axis=-1)
    assert im.bone_length_error_mm(grown, ref, PARENTS) == \
        pytest.approx(100.0 * lengths.mean())


def _pair_scene(gap_real: float, gap_gen: float, t: int = 10
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Actor at the origin; every reactor joint at (gap, 0, 0) from the actor's joints."""
    actor = np.zeros((1, t, 18, 3))
    real = actor + [gap_real, 0.0, 0.0]
    gen = actor + [gap_gen, 0.0, 0.0]
    return actor, gen, real


def test_jpd_known_distances():
    actor, gen, real = _pair_scene(1.0, 1.2)
    out = im.jpd_mm(actor, gen, real)
    assert set(out) == {"A:right_hand-B:spine", "A:right_hand-B:right_hand",
                        "A:left_hand-B:right_hand", "mean"}
    for v in out.values():
        assert v == pytest.approx(200.0)
    assert im.jpd_mm(actor, real, real)["mean"] == 0.0
    d = im.joint_pair_distances(actor, real, [("head", "pelvis")])
    np.testing.assert_allclose(d, 1.0)
    with pytest.raises(MotionError, match="nose"):
        im.jpd_mm(actor, gen, real, pairs=[("nose", "spine")])


def test_contact_retention():
    t = 20
    actor = np.zeros((1, t, 18, 3))
    real = actor + [1.0, 0.0, 0.0]
    gen = real.copy()
    rh = J.index("right_hand")
    real[0, :10, rh] = [0.05, 0.0, 0.0]  # real right hands touch in frames 0-9
    gen[0, :5, rh] = [0.05, 0.0, 0.0]  # generated ones in frames 0-4 only
    out = im.contact_retention(actor, gen, real, pairs=[("right_hand", "right_hand"),
                                                          ("head", "head")])
    assert out["A:right_hand-B:right_hand"] == pytest.approx(0.5)
    assert out["A:head-B:head"] is None  # never in contact in the real windows
    assert out["mean"] == pytest.approx(0.5) and out["real_contact_frames"] == 10
    assert im.contact_retention(actor, real, real)["A:right_hand-B:right_hand"] == 1.0


def test_frechet_closed_forms():
    # 1-D: (mu1 - mu2)^2 + (s1 - s2)^2
    assert im.frechet_distance(np.array([1.0]), np.array([[4.0]]), np.array([-2.0]),
                               np.array([[9.0]])) == pytest.approx(9.0 + 1.0)
    # diagonal: sum over dimensions of the 1-D values
    s1, s2 = np.diag([1.0, 4.0, 0.25]), np.diag([9.0, 1.0, 0.25])
    mu1, mu2 = np.zeros(3), np.array([1.0, 0.0, 2.0])
    assert im.frechet_distance(mu1, s1, mu2, s2) == pytest.approx(5.0 + 4.0 + 1.0 + 0.0)
    # identical Gaussians -> 0, also for a singular covariance
    rank1 = np.outer([1.0, 2.0], [1.0, 2.0])
    assert im.frechet_distance(mu2[:2], rank1, mu2[:2], rank1) == pytest.approx(0.0, abs=1e-9)
    # non-commuting covariances: against the textbook formula with scipy's sqrtm
    from scipy.linalg import sqrtm

    a = np.array([[2.0, 0.5], [0.5, 1.0]])
    b = np.array([[1.0, -0.3], [-0.3, 3.0]])
    expected = np.trace(a + b - 2 * np.real(sqrtm(a @ b)))
    assert im.frechet_distance(np.zeros(2), a, np.zeros(2), b) == pytest.approx(expected)
    # from samples: a set against itself is 0; a shifted copy gives the squared shift
    f = np.random.default_rng(1).normal(size=(50, 4))
    assert im.frechet_feature_distance(f, f) == pytest.approx(0.0, abs=1e-9)
    assert im.frechet_feature_distance(f, f + [3.0, 0, 0, 4.0]) == pytest.approx(25.0)
    with pytest.raises(MotionError):
        im.frechet_distance(np.zeros(2), a, np.zeros(3), np.eye(3))


def test_diversity_and_multimodality_known_values():
    same = np.ones((10, 5))
    assert im.diversity(same) == 0.0
    # K points at mutual distance 2 sqrt(2) (scaled one-hot vectors): every distinct pair
    simplex = 2.0 * np.eye(6)
    assert im.diversity(simplex, num_pairs=500, seed=3) == pytest.approx(2 * np.sqrt(2))
    # two classes, each collapsed to one point: no variety within a class
    feats = np.concatenate([np.zeros((5, 3)), np.ones((5, 3))])
    labels = np.array([0] * 5 + [1] * 5)
    assert im.multimodality(feats, labels) == 0.0
    assert im.diversity(feats) > 0.5
    # within-class simplices of edge sqrt(2) and 3 sqrt(2) -> mean 2 sqrt(2)
    feats = np.concatenate([np.eye(4), 3 * np.eye(4)])
    labels = np.array([0] * 4 + [1] * 4)
    assert im.multimodality(feats, labels, num_pairs=50) == pytest.approx(2 * np.sqrt(2))
    # deterministic for a seed
    f = np.random.default_rng(0).normal(size=(30, 4))
    assert im.diversity(f, seed=7) == im.diversity(f, seed=7)
    with pytest.raises(MotionError, match="two samples"):
        im.multimodality(np.zeros((2, 3)), np.array([0, 1]))


def _speed_driven(profile: np.ndarray) -> np.ndarray:
    """(1, T, 18, 3) body translating along x with the given per-step speed (m/frame)."""
    x = np.concatenate([[0.0], np.cumsum(profile)])
    out = np.zeros((1, len(x), 18, 3))
    out[0, :, :, 0] = x[:, None]
    return out


def test_reaction_lag_recovers_a_known_shift():
    rng = np.random.default_rng(0)
    speeds = np.abs(rng.normal(size=60)) * 0.02
    shift = 3
    actor = _speed_driven(speeds[shift:shift + 40])
    reactor = _speed_driven(speeds[:40])  # s_B(t + 3) = s_A(t): B follows 3 frames later
    assert im.reaction_lag_s(actor, reactor, 25.0)[0] == pytest.approx(3 / 25)
    assert im.reaction_lag_s(reactor, actor, 25.0)[0] == pytest.approx(-3 / 25)
    assert im.reaction_lag_s(actor, actor, 25.0)[0] == 0.0
    frozen = np.repeat(actor[:, :1], 41, axis=1)
    assert np.isnan(im.reaction_lag_s(actor, frozen, 25.0)[0])
    np.testing.assert_allclose(im.speed_profile(actor, 25.0)[0],
                               25.0 * speeds[shift:shift + 40])


def test_pose_segment_features():
    x = _poses(n=4, t=40)
    ext = im.PoseSegmentFeatures(segments=4)
    assert isinstance(ext, im.FeatureExtractor) and "FALLBACK" in ext.name
    f = ext(x)
    assert f.shape == (4, 4 * 18 * 3)
    np.testing.assert_allclose(f[:, :54], x[:, :10].mean(axis=1).reshape(4, -1))
    assert im.pose_features(x).shape == (160, 54)


def test_classifier_features_pad_and_mask():
    import torch

    from simenv.data.gestures import GESTURE15_JOINTS, gesture_skeleton
    from simenv.models.gesture_classifier import ClassifierConfig, GestureClassifier

    torch.set_num_threads(1)
    torch.manual_seed(0)
    config = ClassifierConfig(GESTURE15_JOINTS, gesture_skeleton().parents, ("a", "b"),
                              dim=16, heads=2, layers=1, ffn=16, feature_dim=8)
    ext = im.ClassifierFeatures(GestureClassifier(config))
    x = _poses(n=3, t=40) * 0.1 + np.array([0.0, 0.0, 1.0])
    rs, ls = J.index("right_shoulder"), J.index("left_shoulder")
    x[:, :, rs] = [0.0, -0.2, 1.4]
    x[:, :, ls] = [0.0, 0.2, 1.4]
    f = ext(x)
    assert f.shape == (3, 8) and np.isfinite(f).all()
    assert "gesture-classifier" in ext.name
    np.testing.assert_allclose(ext(x), f)  # deterministic in eval mode


def test_default_extractor_labels_what_it_is():
    ext, reason = default_feature_extractor()
    if reason is None:
        assert "gesture-classifier" in ext.name
    else:
        assert "FALLBACK" in ext.name and "unavailable" in reason

"""Lie-group descriptors (simenv.learning.lie_group) on real UTKinect clips: the relative
geometry of bone pairs, its Fourier temporal pyramid, and the ridge classifier on them."""

from __future__ import annotations

import numpy as np
import pytest

from simenv.core.errors import SimenvError
from simenv.core.motion import resample_linear
from simenv.learning.covariance import CovarianceClassifier
from simenv.learning.lie_group import (
    CURVE_SAMPLES,
    FOURIER_FRACTIONS,
    bone_pairs,
    fourier_pyramid,
    lie_group_descriptors,
    relative_geometry,
    rotation_from_x,
    se3_log_translation,
)
from simenv.learning.recognition import clip_skeleton
from simenv.learning.recognition_protocols import whole_windows


@pytest.fixture(scope="module")
def utk(utkinect_clips):
    """Normalised whole UTKinect clips, their skeleton's parents, labels and subjects."""
    x, valid = whole_windows(utkinect_clips)
    labels = sorted({c.label for c in utkinect_clips})
    return (x, valid, clip_skeleton(utkinect_clips).parents,
            np.array([labels.index(c.label) for c in utkinect_clips]),
            np.array([c.subject for c in utkinect_clips]))


def _bone_directions(frames: np.ndarray, parents) -> np.ndarray:
    start, end = bone_pairs(parents)
    v = frames[:, end] - frames[:, start]
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_the_smallest_rotation_takes_x_to_each_bone(utk):
    x, valid, parents, _, _ = utk
    u = _bone_directions(x[0][valid[0]].astype(np.float64), parents).reshape(-1, 3)
    u = np.concatenate([u, [[1.0, 0, 0], [-1.0, 0, 0]]])  # the two degenerate directions
    rot, omega = rotation_from_x(u)
    np.testing.assert_allclose(rot[:, :, 0], u, atol=1e-9)
    np.testing.assert_allclose(rot @ np.swapaxes(rot, 1, 2), np.broadcast_to(np.eye(3),
                                                                           rot.shape),
                               atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-9)
    # Smallest: the angle is the one between x and u, about an axis normal to both.
    np.testing.assert_allclose(np.linalg.norm(omega, axis=1), np.arccos(np.clip(u[:, 0], -1,
                                                                                1)),
                               atol=1e-7)
    np.testing.assert_allclose(omega[:, 0], 0.0, atol=1e-12)


def test_the_log_translation_inverts_the_exponential_map(utk):
    x, valid, parents, _, _ = utk
    _, omega = rotation_from_x(_bone_directions(x[3][valid[3]].astype(np.float64), parents))
    omega = np.concatenate([omega.reshape(-1, 3), [[0.0, 0.0, 1e-7]]])  # near identity too
    rng = np.random.default_rng(0)
    d = rng.normal(size=omega.shape)
    v = se3_log_translation(omega, d)
    # exp maps (omega, v) to translation V v (module docstring): V v must give d back.
    theta = np.linalg.norm(omega, axis=1)[:, None, None]
    k = np.zeros((len(omega), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -omega[:, 2], omega[:, 1], -omega[:, 0]
    k = k - np.swapaxes(k, 1, 2)
    big = theta > 1e-4
    t = np.where(big, theta, 1.0)
    vmat = (np.eye(3) + np.where(big, (1 - np.cos(t)) / t ** 2, 0.5) * k
            + np.where(big, (t - np.sin(t)) / t ** 3, 1 / 6) * (k @ k))
    np.testing.assert_allclose(np.einsum("nij,nj->ni", vmat, v), d, atol=1e-9)


def test_relative_geometry_describes_bone_pairs_wherever_the_body_stands(utk):
    x, valid, parents, _, _ = utk
    frames = x[0][valid[0]].astype(np.float64)
    m = len(bone_pairs(parents)[0])
    f = relative_geometry(frames, parents)
    assert f.shape == (len(frames), 6 * m * (m - 1))
    np.testing.assert_allclose(relative_geometry(frames + [0.4, -1.2, 0.3], parents), f,
                               atol=1e-9)
    # The rotation of pair (0, 1) takes x to bone 1's direction in bone 0's frame.
    u = _bone_directions(frames, parents)
    rot0, _ = rotation_from_x(u[:, 0])
    in_frame0 = np.einsum("tji,tj->ti", rot0, u[:, 1])
    rot01, omega01 = rotation_from_x(in_frame0)
    np.testing.assert_allclose(f[:, :3], omega01, atol=1e-9)
    np.testing.assert_allclose(rot01[:, :, 0], in_frame0, atol=1e-9)
    # Different actions are different curves.
    assert not np.allclose(relative_geometry(x[40][valid[40]], parents)[:10], f[:10])
    bad = frames.copy()
    bad[7, 2] = np.nan
    with pytest.raises(SimenvError, match="frame 7 holds non-finite"):
        relative_geometry(bad, parents)
    with pytest.raises(SimenvError, match=r"frames must be \(T, 15, 3\)"):
        relative_geometry(frames[:, :14], parents)
    with pytest.raises(SimenvError, match="no frames"):
        relative_geometry(frames[:0], parents)
    with pytest.raises(SimenvError, match="at least 2 bones"):
        relative_geometry(frames[:, :2], parents[:2])


def test_the_pyramid_keeps_low_frequencies_whatever_the_clip_length(utk):
    x, valid, parents, _, _ = utk
    curve = relative_geometry(x[5][valid[5]], parents)
    d = fourier_pyramid(curve, 0.25)
    kept = sum(int(np.ceil(0.25 * len(s))) for level in range(3)
               for s in np.array_split(np.arange(CURVE_SAMPLES), 2 ** level))
    assert d.shape == (kept * curve.shape[1],) and (d >= 0).all()
    # The same movement recorded at twice the frame rate gives (nearly) the same pyramid.
    fine = resample_linear(curve, 2 * len(curve) - 1)
    np.testing.assert_allclose(fourier_pyramid(fine, 0.25), d, rtol=0.05, atol=0.05)
    # A still pose has only its mean (the zero frequency).
    still = fourier_pyramid(np.repeat(curve[:1], 30, axis=0), 0.25)[:16 * curve.shape[1]]
    assert np.abs(still.reshape(16, -1)[1:]).max() < 1e-9
    with pytest.raises(SimenvError, match="fraction"):
        fourier_pyramid(curve, 0.0)
    with pytest.raises(SimenvError, match="levels"):
        fourier_pyramid(curve, 0.25, levels=8)


def test_the_classifier_recognises_an_unseen_person_from_lie_group_descriptors(utk):
    x, valid, parents, y, subjects = utk
    lie = lie_group_descriptors(x, valid, parents)
    assert set(lie) == set(FOURIER_FRACTIONS)
    test, train = subjects == 10, subjects != 10
    variants = {f"lie@{f:g}": d for f, d in lie.items()}
    clf = CovarianceClassifier(10).fit({k: v[train] for k, v in variants.items()}, y[train],
                                       subjects[train])
    p = clf.predict_proba({k: v[test] for k, v in variants.items()})
    # Ten classes: chance is 0.1.
    assert (p.argmax(1) == y[test]).mean() > 0.6
    empty = valid.copy()
    empty[2] = False
    with pytest.raises(SimenvError, match="window 2 has no real frame"):
        lie_group_descriptors(x[:3], empty[:3], parents)


def test_blocks_weigh_the_same_whatever_their_size(utk):
    x, valid, parents, y, subjects = utk
    a = lie_group_descriptors(x, valid, parents, fractions=(0.125,))[0.125]
    train = subjects != 10
    fit = {"one": a[train], "one-tuple": (a[train],), "pair": (a[train], a[train]),
           "pair-wide": (a[train], np.repeat(a[train], 3, axis=1))}
    test = {"one": a[~train], "one-tuple": (a[~train],), "pair": (a[~train], a[~train]),
            "pair-wide": (a[~train], np.repeat(a[~train], 3, axis=1))}

    def proba(name: str, lam: float) -> np.ndarray:
        clf = CovarianceClassifier(10, lambdas=(lam,)).fit({name: fit[name]}, y[train],
                                                           subjects[train])
        return clf.predict_proba({name: test[name]})

    np.testing.assert_allclose(proba("one-tuple", 1e3), proba("one", 1e3), atol=1e-9)
    # A block with its columns repeated three times still weighs as much as the other:
    # the pair's Gram matrix only doubles, which a doubled regulariser absorbs.
    np.testing.assert_allclose(proba("pair-wide", 2e3), proba("pair", 1e3), atol=1e-6)
    clf = CovarianceClassifier(10).fit({"pair": fit["pair"]}, y[train], subjects[train])
    with pytest.raises(SimenvError, match="blocks of"):
        clf.predict_proba({"pair": test["pair"][0]})

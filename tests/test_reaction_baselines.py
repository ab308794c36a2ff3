"""Tests for simenv.models.reaction_baselines: one interface, known geometry, fitting,
equivariance to rigid motions about Z, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import MotionError
from simenv.data import interaction_data as idata
from simenv.models import reaction_baselines as rb

J = list(idata.INTER18_JOINTS)


def _standing(x: float = 0.0, facing_x: bool = True) -> np.ndarray:
    """(18, 3) a simple standing pose at (x, 0) facing +x (or -x)."""
    side = {"left": 1.0, "right": -1.0}
    pose = np.zeros((18, 3))
    heights = {"pelvis": 1.0, "hip": 0.95, "knee": 0.5, "ankle": 0.1, "spine": 1.2,
               "neck": 1.5, "head": 1.65, "shoulder": 1.45, "elbow": 1.15, "wrist": 0.9,
               "hand": 0.82}
    for j, name in enumerate(J):
        s, _, part = name.partition("_") if "_" in name else ("", "", name)
        pose[j, 2] = heights[part]
        if s:
            width = 0.1 if part in ("hip", "knee", "ankle") else 0.2
            pose[j, 1] = side[s] * width
    if not facing_x:
        pose[:, 1] *= -1
    pose[:, 0] += x
    return pose


def _raise_right_hand(pose: np.ndarray, forward: float) -> np.ndarray:
    out = pose.copy()
    out[J.index("right_hand")] += [forward, 0.0, 0.6]
    return out


@pytest.fixture(scope="module")
def real(shared_data: Path) -> tuple[idata.InteractionWindows, object]:
    windows = idata.make_windows(idata.load_recordings(shared_data))
    return windows, idata.split_by_recording(windows)


def test_every_baseline_shares_the_interface():
    a = np.stack([_standing(), _raise_right_hand(_standing(), 0.2)])
    b0 = _standing(1.0, facing_x=False)
    train_a, train_b = a[None], np.stack([b0, b0])[None]
    for name in rb.BASELINE_NAMES:
        gen = rb.make_baseline(name, train_a, train_b)
        assert isinstance(gen, rb.ReactionGenerator) and gen.name == name
        single = gen.generate(a, b0)
        assert single.shape == (2, 18, 3) and single.dtype == np.float32
        batch = gen.generate(np.stack([a, a]), np.stack([b0, b0]))
        assert batch.shape == (2, 2, 18, 3)
        np.testing.assert_allclose(batch[1], single, atol=1e-6)


def test_zero_velocity_holds_the_first_frame():
    b0 = _standing(1.0, facing_x=False)
    out = rb.ZeroVelocity().generate(np.repeat(_standing()[None], 5, axis=0), b0)
    np.testing.assert_array_equal(out, np.repeat(b0[None], 5, axis=0).astype(np.float32))


def test_mirror_and_copy_face_to_face():
    a = np.stack([_standing(), _raise_right_hand(_standing(), 0.3)])
    b0 = _standing(1.0, facing_x=False)  # 1 m ahead, facing the actor
    copy = rb.MirrorActor(reflect=False).generate(a, b0)
    mirror = rb.MirrorActor(reflect=True).generate(a, b0)
    # frame 0: the actor's standing pose placed at the reactor (symmetric pose: both equal b0)
    np.testing.assert_allclose(copy[0], b0, atol=1e-6)
    np.testing.assert_allclose(mirror[0], b0, atol=1e-6)
    # frame 1: the actor's right hand went 0.3 m forward (towards B) and up
    rh, lh = J.index("right_hand"), J.index("left_hand")
    np.testing.assert_allclose(copy[1, rh], b0[rh] + [-0.3, 0.0, 0.6], atol=1e-6)
    np.testing.assert_allclose(mirror[1, lh], b0[lh] + [-0.3, 0.0, 0.6], atol=1e-6)
    # mirror = reflection across the plane x = 0.5 between them
    reflected = a[1][rb.mirror_index(J)] * [-1.0, 1.0, 1.0] + [1.0, 0.0, 0.0]
    np.testing.assert_allclose(mirror[1], reflected, atol=1e-6)


def test_nearest_neighbour_returns_the_co_occurring_reactor(real):
    windows, split = real
    train = windows.subset(split.train)
    nn = rb.NearestNeighbour().fit(train.actor, train.reactor)
    assert nn.num_frames == len(train) * train.window
    out = nn.generate(train.actor[:4], train.reactor[:4, 0])
    np.testing.assert_allclose(out, train.reactor[:4], atol=1e-4)
    test = windows.subset(split.test)
    gen = nn.generate(test.actor[:3], test.reactor[:3, 0])
    assert gen.shape == test.reactor[:3].shape and np.isfinite(gen).all()
    with pytest.raises(MotionError, match="fit"):
        rb.NearestNeighbour().generate(test.actor[0], test.reactor[0, 0])


def test_baselines_are_equivariant_to_rigid_motion_about_z(real):
    windows, split = real
    train = windows.subset(split.train)
    test = windows.subset(split.test[:3])
    yaw = np.full(3, 0.7)
    origin = np.tile([2.0, -1.0, 0.0], (3, 1))
    moved_a = idata.denormalise(test.actor, origin, yaw)
    moved_b0 = idata.denormalise(test.reactor[:, :1], origin, yaw)[:, 0]
    for name in rb.BASELINE_NAMES:
        gen = rb.make_baseline(name, train.actor, train.reactor)
        here = gen.generate(test.actor, test.reactor[:, 0])
        there = gen.generate(moved_a, moved_b0)
        np.testing.assert_allclose(there, idata.denormalise(here, origin, yaw), atol=1e-4)


def test_bad_input():
    a = np.zeros((5, 18, 3))
    with pytest.raises(MotionError, match="reactor_first_frame"):
        rb.ZeroVelocity().generate(a, np.zeros((17, 3)))
    with pytest.raises(MotionError, match="actor_window"):
        rb.ZeroVelocity().generate(np.zeros((5, 17, 3)), np.zeros((17, 3)))
    bad = np.repeat(_standing()[None], 5, axis=0)
    bad[2, 3, 0] = np.inf
    with pytest.raises(MotionError, match="non-finite"):
        rb.MirrorActor().generate(bad, _standing(1.0))
    with pytest.raises(MotionError, match="unknown reaction baseline"):
        rb.make_baseline("interformer")
    with pytest.raises(MotionError, match="needs train"):
        rb.make_baseline("nearest_neighbour")

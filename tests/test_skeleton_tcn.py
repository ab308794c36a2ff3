"""SkeletonTCN: shapes, masking, calibration, checkpoints, the shipped recogniser."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

import simenv
import simenv.models
from simenv.assets import WALK, asset_path
from simenv.core.errors import MotionError
from simenv.data.gestures import GESTURE15_JOINTS, gesture_skeleton, to_gesture_joints
from simenv.models.checkpoint import CheckpointError
from simenv.models.skeleton_tcn import (
    SkeletonTCN,
    SkeletonTCNEnsemble,
    TCNConfig,
    fit_temperature,
)


@pytest.fixture(scope="module")
def walk_windows() -> np.ndarray:
    """Two normalised 3-s windows of the bundled CMU walk on gesture15 (real mocap)."""
    from simenv.data.gestures import normalise_windows

    m = simenv.load(asset_path(WALK)).resample(25.0)
    p = to_gesture_joints(m)
    return normalise_windows(np.stack([p[0:50], p[10:60]]))


def _net(seed: int = 0) -> SkeletonTCN:
    skel = gesture_skeleton("gesture15")
    torch.manual_seed(seed)
    return SkeletonTCN(TCNConfig(skel.joint_names, skel.parents, ("a", "b", "c"))).eval()


def test_padding_is_exactly_masked(walk_windows):
    """A window padded with anything after its valid frames classifies as the window cut."""
    net = _net()
    x = torch.from_numpy(walk_windows)
    short = net(x[:, :30])
    padded = x.clone()
    padded[:, 30:] = 5.0 * torch.randn_like(padded[:, 30:])
    valid = torch.zeros(x.shape[:2], dtype=torch.bool)
    valid[:, :30] = True
    torch.testing.assert_close(net(padded, valid), short, atol=1e-5, rtol=1e-5)
    # ... and the padding matters when it is declared valid.
    assert not torch.allclose(net(padded), short, atol=1e-3)


def test_any_length_and_errors(walk_windows):
    net = _net()
    for t in (1, 7, 50):
        assert net(torch.from_numpy(walk_windows[:, :t])).shape == (2, 3)
    with pytest.raises(MotionError, match="shape"):
        net(torch.zeros(2, 10, 9, 3))
    with pytest.raises(MotionError, match="valid"):
        net(torch.from_numpy(walk_windows), torch.zeros(2, 50, dtype=torch.bool))


def test_temperature_fit_recovers_a_known_scale():
    rng = np.random.default_rng(0)
    true = rng.normal(0, 1.5, (4000, 5))
    y = np.array([rng.choice(5, p=np.exp(z) / np.exp(z).sum()) for z in true])
    # logits twice as sharp as the distribution the labels came from -> tau ~= 2
    assert fit_temperature(2.0 * true, y) == pytest.approx(2.0, rel=0.1)
    with pytest.raises(ValueError):
        fit_temperature(np.zeros((3, 2)), np.zeros(2, int))


def test_temperature_scales_probabilities_not_decisions(walk_windows):
    net = _net()
    p1 = net.predict_proba(walk_windows)
    net.config.temperature = 3.0
    p3 = net.predict_proba(walk_windows)
    assert (p1.argmax(1) == p3.argmax(1)).all()
    assert p3.max() < p1.max()


def test_checkpoint_round_trip(tmp_path: Path, walk_windows):
    net = _net(1)
    net.config.temperature = 1.7
    path = net.save(tmp_path / "t.npz", metadata={"loop_threshold": 0.6})
    back = SkeletonTCN.load(path)
    np.testing.assert_allclose(back.predict_proba(walk_windows), net.predict_proba(walk_windows),
                               atol=1e-6)
    assert back.metadata["loop_threshold"] == 0.6 and back.config.temperature == 1.7
    (tmp_path / "bad.npz").write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError):
        SkeletonTCN.load(tmp_path / "bad.npz")


def _members() -> list[SkeletonTCN]:
    nets = [_net(seed) for seed in (0, 1, 2)]
    for net, tau in zip(nets, (1.0, 0.7, 1.6), strict=True):
        net.config.temperature = tau
    return nets


def _walk_batch(walk_windows: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
    """The walk windows and a third, three rows with different valid frames."""
    x = torch.from_numpy(np.concatenate([walk_windows, walk_windows[:1, ::-1].copy()]))
    valid = torch.ones(x.shape[:2], dtype=torch.bool)
    valid[1, 35:] = False
    valid[2, :8] = False
    return x, valid


def test_ensemble_runs_the_members_fused(walk_windows):
    """The fused pass (grouped convolutions, one group norm per member) gives each member's
    own logits on real walk windows, masks included, and the probabilities are
    softmax(mean_m z_m / tau_m)."""
    members = _members()
    ensemble = SkeletonTCNEnsemble(members)
    x, valid = _walk_batch(walk_windows)
    with torch.no_grad():
        own = torch.stack([m(x, valid) for m in members], dim=1)
    torch.testing.assert_close(ensemble.member_logits(x, valid), own, atol=1e-5, rtol=1e-5)
    with torch.no_grad():  # every frame valid: the unmasked path
        whole = torch.stack([m(x) for m in members], dim=1)
    torch.testing.assert_close(ensemble.member_logits(x), whole, atol=1e-5, rtol=1e-5)
    z = (own / torch.tensor([1.0, 0.7, 1.6])[None, :, None]).mean(1)
    np.testing.assert_allclose(ensemble.predict_proba(x.numpy(), valid.numpy()),
                               torch.softmax(z, -1).numpy(), atol=1e-6)
    one = SkeletonTCNEnsemble(members[:1])
    np.testing.assert_allclose(one.predict_proba(x.numpy(), valid.numpy()),
                               members[0].predict_proba(x.numpy(), valid.numpy()), atol=1e-6)


def test_ensemble_follows_its_members_weights_and_round_trips(tmp_path: Path, walk_windows):
    members = _members()
    ensemble = SkeletonTCNEnsemble(members)
    x = walk_windows
    before = ensemble.predict_proba(x)
    with torch.no_grad():
        members[1].out.weight.mul_(-1.0)
    after = ensemble.predict_proba(x)
    assert np.abs(after - before).max() > 1e-3  # the fused weights were rebuilt
    ensemble.metadata = {"loop_threshold": 0.8}
    back = SkeletonTCNEnsemble.load(ensemble.save(tmp_path / "e.npz"))
    assert back.temperatures == pytest.approx((1.0, 0.7, 1.6))
    assert back.metadata["loop_threshold"] == 0.8
    np.testing.assert_allclose(back.predict_proba(x), after, atol=1e-6)
    with pytest.raises(CheckpointError):
        SkeletonTCN.load(tmp_path / "e.npz")


def test_ensemble_refuses_members_that_differ():
    from simenv.core.errors import SimenvError
    from simenv.perception.loop import TrainedClassifier

    skel = gesture_skeleton("gesture15")
    other = SkeletonTCN(TCNConfig(skel.joint_names, skel.parents, ("a", "b", "c"), width=64))
    with pytest.raises(ValueError, match="member 1"):
        SkeletonTCNEnsemble([_net(), other])
    with pytest.raises(ValueError, match="at least one"):
        SkeletonTCNEnsemble([])
    # The loop's classifier names the problem as a simenv error.
    with pytest.raises(SimenvError, match="member 1"):
        TrainedClassifier([_net(), other])


@pytest.mark.parametrize("name", ["gesture-tcn", "gesture-tcn-ensemble"])
def test_shipped_recogniser_on_a_real_walk(name):
    """The shipped network and the room's ensemble read the bundled CMU walk (mocap they
    never trained on) as walking, with calibrated probabilities and their loop threshold
    recorded."""
    if name not in simenv.models.available():
        pytest.skip(f"shipped {name} absent")
    net = simenv.models.load(name)
    assert net.config.joint_names == GESTURE15_JOINTS
    m = simenv.load(asset_path(WALK)).resample(25.0)
    p = net.classify_world(to_gesture_joints(m)[:75])
    assert p.sum() == pytest.approx(1.0, abs=1e-5)
    assert net.config.labels[int(p.argmax())] == "walk"
    assert 0.0 < net.metadata["loop_threshold"] < 1.0 and net.config.temperature > 0

"""The recogniser's sensor-invariant input (simenv.data.sensor_invariance) on real
recordings: the same clip moved, turned, scaled or resampled gives the same input, the
trunk that an MSR Action3D Kinect puts behind the body stands upright once reconciled,
and two datasets' bodies get the same bone lengths."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from simenv.core.errors import SkeletonError
from simenv.core.motion import resample_linear
from simenv.core.skeletons import GESTURE9_JOINTS
from simenv.data.gestures import (
    GESTURE15_JOINTS,
    gesture_skeleton,
    load_labelled,
    normalise_windows,
)
from simenv.data.sensor_invariance import (
    HIP_WIDTH_RATIO,
    REFERENCE_BONES_M,
    SPINE_FRACTION,
    canonical_body,
    reconcile_joints,
    reference_bones,
)

J = list(GESTURE15_JOINTS)


def _features(positions: np.ndarray) -> np.ndarray:
    """The recogniser's input of a whole clip: normalised, then canonical."""
    return canonical_body(normalise_windows(positions), joints=GESTURE15_JOINTS)


@pytest.fixture(scope="module")
def wave(utkinect_clips):
    return next(c for c in utkinect_clips if c.label == "wave").positions


def test_same_clip_moved_turned_scaled_gives_same_input(wave):
    a = np.deg2rad(123.0)
    rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    moved = (1.3 * wave @ rot.T + np.array([2.0, -1.5, 0.4])).astype(np.float32)
    np.testing.assert_allclose(_features(moved), _features(wave), atol=1e-4)


def test_reconciling_commutes_with_resampling(wave):
    # 25 fps -> 15 fps (the rate of MSR Action3D's and UTKinect's skeleton streams): the
    # trunk joints are affine in the others but the hip width is a norm, so the two
    # orders agree to well under a millimetre, not exactly.
    n = round(len(wave) * 15 / 25)
    slow = resample_linear(wave, n)
    np.testing.assert_allclose(reconcile_joints(slow),
                               reconcile_joints(resample_linear(reconcile_joints(wave), n)),
                               atol=5e-4)


def test_trunk_joints_redefined_and_idempotent(wave):
    before = normalise_windows(wave)
    x = reconcile_joints(before)
    hip = 0.5 * (x[:, J.index("left_hip")] + x[:, J.index("right_hip")])
    top = 0.5 * (x[:, J.index("left_shoulder")] + x[:, J.index("right_shoulder")])
    shift = x[:1, J.index("left_wrist")] - before[:1, J.index("left_wrist")]
    # The hip centre stays (up to the new origin); the hips stand HIP_WIDTH_RATIO
    # shoulder widths apart.
    np.testing.assert_allclose(hip, 0.5 * (before[:, J.index("left_hip")]
                                           + before[:, J.index("right_hip")]) + shift,
                               atol=1e-5)
    np.testing.assert_allclose(
        np.linalg.norm(x[:, J.index("left_hip")] - x[:, J.index("right_hip")], axis=1),
        HIP_WIDTH_RATIO * np.linalg.norm(x[:, J.index("left_shoulder")]
                                         - x[:, J.index("right_shoulder")], axis=1), rtol=1e-4)
    np.testing.assert_allclose(x[:, J.index("neck")], top, atol=1e-6)
    np.testing.assert_allclose(x[:, J.index("spine")], hip + SPINE_FRACTION * (top - hip),
                               atol=1e-6)
    assert np.abs(x[:10, J.index("spine")].mean(axis=0)).max() < 1e-6  # new origin
    np.testing.assert_allclose(reconcile_joints(x), x, atol=1e-6)
    # Arms, head, knees and ankles are not touched: only the trunk and the origin move.
    limbs = [J.index(n) for n in J if n not in ("spine", "neck", "left_hip", "right_hip")]
    np.testing.assert_allclose((x - before)[:, limbs],
                               np.broadcast_to(shift, (len(x), len(limbs), 3)), atol=1e-5)


def test_msr_trunk_upright_once_reconciled(gesture_root):
    # MSR Action3D's Spine lies behind the body: its spine -> neck leans ~37 deg off the
    # vertical (corpus median; Kinect v1 elsewhere ~5 deg), ~18 deg once reconciled.
    clip = load_labelled([gesture_root / "msr_action3d" / "a03_s01_e01_skeleton3D.txt"])[0]
    lean = {}
    for name, x in (("raw", normalise_windows(clip.positions)),
                    ("reconciled", reconcile_joints(normalise_windows(clip.positions)))):
        up = x[:, J.index("neck")] - x[:, J.index("spine")]
        lean[name] = np.degrees(np.arccos(np.median(up[:, 2] / np.linalg.norm(up, axis=1))))
    assert lean["raw"] > 25.0
    assert lean["reconciled"] < lean["raw"] - 15.0


def test_valid_frames_set_the_origin(wave):
    x = normalise_windows(wave[:40])
    valid = np.zeros(40, bool)
    valid[5:] = True
    out = reconcile_joints(x, valid)
    assert np.abs(out[5:15, J.index("spine")].mean(axis=0)).max() < 1e-6


def test_bodies_of_two_sensors_get_the_same_bones(wave, gesture_root):
    # UTKinect (Kinect v1) and Florence 3D (OpenNI): thighs 0.50 vs 0.42 m of the
    # normalised body as recorded; directions kept, lengths the reference's.
    florence = load_labelled([gesture_root / "florence3d"])[0].positions
    parents = gesture_skeleton().parents
    for clip in (wave, florence):
        before = reconcile_joints(normalise_windows(clip))
        x = reference_bones(before)
        for j, p in enumerate(parents):
            if p < 0:
                continue
            bone, was = x[:, j] - x[:, p], before[:, j] - before[:, p]
            np.testing.assert_allclose(np.linalg.norm(bone, axis=1), REFERENCE_BONES_M[J[j]],
                                       rtol=1e-4)
            cos = (bone * was).sum(1) / np.linalg.norm(bone, axis=1) / np.linalg.norm(was, axis=1)
            assert cos.min() > 1 - 1e-5
        np.testing.assert_allclose(x[:, 0], before[:, 0])  # the root stays


def test_joint_set_without_hips_is_refused():
    with pytest.raises(SkeletonError, match="left_hip"):
        reconcile_joints(np.zeros((4, len(GESTURE9_JOINTS), 3)), joints=GESTURE9_JOINTS)
    with pytest.raises(SkeletonError, match="no reference length for pelvis"):
        reference_bones(np.zeros((4, 2, 3)), joints=("spine", "pelvis"), parents=(-1, 0))


def test_network_marked_canonical_reads_canonical_input(wave):
    """Whoever calls it (the protocols' logits_of, the room loop's predict_proba, world-frame
    classify_world, an ensemble), a network marked canonical reads canonical-body input."""
    from simenv.learning.recognition import logits_of
    from simenv.models.skeleton_tcn import (
        CANONICAL_BODY,
        SkeletonTCN,
        SkeletonTCNEnsemble,
        TCNConfig,
    )

    skel = gesture_skeleton()
    torch.manual_seed(0)
    config = TCNConfig(skel.joint_names, skel.parents, ("a", "b"), fps=25.0, width=16,
                       extra={CANONICAL_BODY: True})
    net = SkeletonTCN(config)
    x = normalise_windows(wave[:75])[None]
    valid = np.ones((1, len(x[0])), bool)
    net.eval()
    with torch.no_grad():
        direct = net(torch.from_numpy(canonical_body(x, valid)), torch.from_numpy(valid))
    np.testing.assert_allclose(logits_of(net, x, valid), direct.numpy(), atol=1e-5)
    expected = torch.softmax(direct / config.temperature, -1).numpy()
    np.testing.assert_allclose(net.predict_proba(x, valid), expected, atol=1e-5)
    np.testing.assert_allclose(net.classify_world(wave[:75]), expected[0], atol=1e-5)
    ensemble = SkeletonTCNEnsemble([net])
    np.testing.assert_allclose(ensemble.predict_proba(x, valid), expected, atol=1e-5)
    np.testing.assert_allclose(logits_of(ensemble, x, valid),
                               direct.numpy() / config.temperature, atol=1e-5)
    plain = SkeletonTCN(TCNConfig(skel.joint_names, skel.parents, ("a", "b"), fps=25.0,
                                  width=16))
    with pytest.raises(ValueError, match="different input"):
        SkeletonTCNEnsemble([net, plain])

"""Covariance descriptors and their ridge classifier (simenv.learning.covariance) on real
UTKinect clips, and the benchmark protocols running it alone and fused with a network."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import SimenvError
from simenv.learning.covariance import (
    TEMPERATURES,
    CovarianceClassifier,
    covariance_descriptor,
    descriptors,
    pyramid_windows,
)
from simenv.learning.recognition import RecognitionConfig
from simenv.learning.recognition_protocols import (
    FUSION_WEIGHTS,
    fusion_weight,
    run_benchmark,
    whole_windows,
)
from simenv.perception.train_recogniser import benchmark_table


@pytest.fixture(scope="module")
def msr_two_takes(gesture_root: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A gestures folder holding the real MSR Action3D recordings' first two takes of every
    action by every subject (e01, e02; two thirds of the clips, every class and subject) and
    the protocol's file list: the benchmark's code paths on fewer clips."""
    source = gesture_root / "msr_action3d"
    if not source.is_dir():
        pytest.skip("MSR Action3D not in the corpus")
    root = tmp_path_factory.mktemp("msr_two_takes")
    (root / "msr_action3d").mkdir()
    for path in source.iterdir():
        if not path.name.endswith("_e03_skeleton3D.txt"):
            (root / "msr_action3d" / path.name).symlink_to(path)
    return root


@pytest.fixture(scope="module")
def utk_descriptors(utkinect_clips):
    """Both descriptor variants of every UTKinect clip, with labels, subjects and frames."""
    x, valid = whole_windows(utkinect_clips)
    labels = sorted({c.label for c in utkinect_clips})
    y = np.array([labels.index(c.label) for c in utkinect_clips])
    subjects = np.array([c.subject for c in utkinect_clips])
    variants = {"joints": descriptors(x, valid, velocity=False),
                "joints+velocity": descriptors(x, valid, velocity=True)}
    return variants, y, subjects, x, valid


def test_pyramid_windows_cover_the_clip_at_each_level():
    w = pyramid_windows(100)
    assert len(w) == 1 + 3 + 7
    assert w[0] == (0, 100)
    assert w[1:4] == [(0, 50), (25, 75), (50, 100)]  # halves, overlapping by half
    assert w[-1] == (75, 100)
    assert all(b - a >= 2 for a, b in pyramid_windows(3))  # a short clip repeats frames
    with pytest.raises(SimenvError, match="at least 2 frames"):
        pyramid_windows(1)


def test_a_descriptor_is_the_covariance_of_the_joints_over_time(utk_descriptors):
    variants, _, _, x, valid = utk_descriptors
    frames = x[0][valid[0]].astype(np.float64)
    J = frames.shape[1]
    d = covariance_descriptor(frames, velocity=False)
    assert d.shape == (11 * (3 * J) * (3 * J + 1) // 2,)
    # Its first window is the whole clip: the covariance numpy computes, upper triangle.
    whole = np.cov(frames.reshape(len(frames), -1), rowvar=False)
    np.testing.assert_allclose(d[:whole.shape[0] * (whole.shape[0] + 1) // 2],
                               whole[np.triu_indices(len(whole))], rtol=1e-10)
    # A covariance forgets where the body stands, not how it moves.
    np.testing.assert_allclose(covariance_descriptor(frames + 0.7, False), d,
                               atol=1e-9)
    assert not np.allclose(covariance_descriptor(frames[::-1] * 1.5, False), d)
    assert variants["joints+velocity"].shape[1] == 11 * (6 * J) * (6 * J + 1) // 2
    bad = frames.copy()
    bad[3, 2, 1] = np.nan
    with pytest.raises(SimenvError, match="non-finite"):
        covariance_descriptor(bad)
    with pytest.raises(SimenvError, match=r"\(T, J, 3\)"):
        covariance_descriptor(frames[..., :2])


def test_the_classifier_recognises_an_unseen_person(utk_descriptors):
    variants, y, subjects, _, _ = utk_descriptors
    test, train = subjects == 10, subjects != 10
    clf = CovarianceClassifier(10).fit({k: v[train] for k, v in variants.items()}, y[train],
                                       subjects[train])
    # The choice is made on the training subjects only, and recorded.
    assert clf.variant in variants and clf.lam in clf.lambdas
    assert set(clf.selection) == set(variants)
    assert clf.selection[clf.variant][clf.lam] == max(
        acc for per in clf.selection.values() for acc in per.values())
    assert clf.temperature in TEMPERATURES
    p = clf.predict_proba({k: v[test] for k, v in variants.items()})
    assert p.shape == (int(test.sum()), 10)
    np.testing.assert_allclose(p.sum(1), 1.0, atol=1e-9)
    # Ten classes: chance is 0.1; an unseen person's actions are recognised well above it.
    assert (p.argmax(1) == y[test]).mean() > 0.6


def test_bad_input_is_named(utk_descriptors):
    variants, y, subjects, _, _ = utk_descriptors
    with pytest.raises(SimenvError, match="fit the classifier first"):
        CovarianceClassifier(10).predict_proba(variants)
    with pytest.raises(SimenvError, match="at least 2"):
        CovarianceClassifier(10).fit(variants, y, np.zeros_like(subjects))
    with pytest.raises(SimenvError, match="labels must be in"):
        CovarianceClassifier(3).fit(variants, y, subjects)
    with pytest.raises(SimenvError, match="descriptors, "):
        CovarianceClassifier(10).fit(variants, y[:-1], subjects[:-1])
    with pytest.raises(SimenvError, match="num_classes"):
        CovarianceClassifier(1)
    with pytest.raises(SimenvError, match="lambdas"):
        CovarianceClassifier(10, lambdas=(0.0,))
    clf = CovarianceClassifier(10).fit({"joints": variants["joints"]}, y, subjects)
    with pytest.raises(SimenvError, match="variant 'joints' missing"):
        clf.predict_proba({"joints+velocity": variants["joints+velocity"]})
    with pytest.raises(SimenvError, match="descriptors must be"):
        clf.predict_proba({"joints": variants["joints"][:, :10]})


def test_the_benchmark_runs_it_alone_and_fused_with_a_network(msr_two_takes: Path):
    alone = run_benchmark("msr_action3d", msr_two_takes, covariance="alone", progress=False)
    assert alone["method"] == "covariance" and alone["mirror"] == "none"
    (fold,) = alone["folds"]
    # The descriptor may be the native 20 joints or gesture15, chosen on training subjects.
    assert fold["covariance"]["variant"].split("+")[0] in ("gesture15", "native")
    assert 0.5 < alone["scores"]["accuracy"] < 1.0  # twenty classes: chance is 0.05
    # A thin network: the assertions are about the covariance side and the fusion weight's
    # choice, not the network's accuracy.
    config = RecognitionConfig(partial_prob=0.0, max_frames=75, epochs=1, width=16)
    fused = run_benchmark("msr_action3d", msr_two_takes, config, covariance="fused",
                          progress=False)
    assert fused["method"] == "network + covariance"
    assert fused["folds"][0]["covariance"] == fold["covariance"]  # the same classifier
    assert fused["scores"]["n"] == alone["scores"]["n"]
    weighted = run_benchmark("msr_action3d", msr_two_takes, config, covariance="weighted",
                             progress=False)
    assert weighted["method"] == "network + covariance, weighted"
    chosen = dict(weighted["folds"][0]["covariance"])
    # The weight is chosen on the five training subjects, each held out once: every
    # training clip classified once by models that never saw its subject.
    fusion = chosen.pop("fusion")
    assert chosen == fold["covariance"]
    assert fusion["subjects"] == 5 and fusion["weight"] in FUSION_WEIGHTS
    assert fusion["held_out_clips"] + weighted["scores"]["n"] == weighted["clips"]
    assert fusion["held_out_accuracy"][f"{fusion['weight']:g}"] == max(
        fusion["held_out_accuracy"].values())
    table = benchmark_table([alone, fused, weighted])
    assert "covariance descriptors (ridge)" in table
    assert "fused with the covariance classifier" in table
    assert f"weight from the training subjects ({fusion['weight']:g})" in table
    with_lie = run_benchmark("msr_action3d", msr_two_takes, covariance="alone",
                             lie_group=True, progress=False)
    assert with_lie["descriptors"] == ["covariance", "lie group"]
    assert alone["descriptors"] == ["covariance"]
    # The Lie-group descriptors are further candidates: the choice is made on the training
    # subjects among more variants, so it can only do as well there or better.
    chosen = with_lie["folds"][0]["covariance"]
    assert chosen["held_out_accuracy"] >= fold["covariance"]["held_out_accuracy"]
    assert "covariance and Lie-group descriptors (ridge)" in benchmark_table([with_lie])
    with pytest.raises(SimenvError, match="give a covariance mode"):
        run_benchmark("msr_action3d", msr_two_takes, lie_group=True)
    with pytest.raises(SimenvError, match="unknown covariance mode"):
        run_benchmark("msr_action3d", msr_two_takes, covariance="both")  # type: ignore[arg-type]
    with pytest.raises(SimenvError, match="runs alone"):
        run_benchmark("msr_action3d", msr_two_takes, neighbour="dtw", covariance="alone")


def test_the_fusion_weight_is_the_one_that_classifies_held_out_clips_best():
    y = np.array([0, 0, 0, 1, 1, 1])
    # The network is sure of the first three and slightly wrong on the last three; the
    # covariance model is slightly wrong on the first three and sure of the last three.
    net = np.log(np.array([[0.9, 0.1]] * 3 + [[0.6, 0.4]] * 3))
    cov = np.log(np.array([[0.45, 0.55]] * 3 + [[0.1, 0.9]] * 3))
    weight, accuracy = fusion_weight(net, cov, y)
    assert accuracy["0"] == accuracy["1"] == 0.5
    assert 0.0 < weight < 1.0 and accuracy[f"{weight:g}"] == 1.0
    assert set(accuracy) == {f"{w:g}" for w in FUSION_WEIGHTS}
    # Ties in accuracy go to the weight whose fused softmax fits the labels best.
    weight, _ = fusion_weight(net[:3], cov[:3], y[:3])
    assert weight == 0.0
    with pytest.raises(SimenvError, match="must both be"):
        fusion_weight(net, cov[:, :1], y)
    with pytest.raises(SimenvError, match="no held-out clips"):
        fusion_weight(net[:0], cov[:0], y[:0])

"""Tests for simenv.models.predictor_regression (DCT-residual MLP) on real CMU windows."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import asdict, replace

import numpy as np
import pytest
import torch

from simenv.core.errors import MotionError, SimenvError
from simenv.data import prediction_data as pdata
from simenv.data.interaction_data import DEFAULT_TEST_RECORDINGS
from simenv.io import bvh
from simenv.learning import train_predictor as tp
from simenv.models import predictor as P
from simenv.models import predictor_regression as R
from simenv.models.baselines import ZeroVelocity

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def clips(shared_data):
    return [bvh.read(shared_data / "cmu" / "bvh" / f"{n}.bvh") for n in ("02_01", "49_02")]


@pytest.fixture(scope="module")
def windows(clips):
    return pdata.windows_from_motions(clips, 10, 10, stride=4)


def test_dct_matrix_is_orthonormal_and_puts_a_constant_in_the_first_coefficient():
    for n in (1, 11, 26):
        m = R.dct_matrix(n)
        np.testing.assert_allclose(m @ m.T, np.eye(n), atol=1e-12)
        c = m @ np.full(n, 2.0)
        assert c[0] == pytest.approx(2.0 * np.sqrt(n))
        np.testing.assert_allclose(c[1:], 0.0, atol=1e-12)


def test_untrained_model_is_zero_velocity_and_heading_equivariant(windows):
    model = R.DCTRegressionPredictor(R.RegressionConfig(10, 10))
    history = windows.frames[:5, :11]
    np.testing.assert_allclose(model.predict(history), ZeroVelocity(10).predict(history),
                               atol=1e-5)
    torch.manual_seed(0)
    for p in model.net.fc_out.parameters():
        torch.nn.init.normal_(p, std=0.1)
    pred = model.predict(history)
    assert np.abs(pred - ZeroVelocity(10).predict(history)).max() > 1e-3
    turned = P.rotate_z(history.astype(np.float64), np.full(5, 0.8))
    np.testing.assert_allclose(model.predict(turned),
                               P.rotate_z(pred.astype(np.float64), np.full(5, 0.8)),
                               atol=1e-4)
    np.testing.assert_allclose(model.predict(history[0]), pred[0], atol=1e-6)


_INIT_DIGEST = """
import hashlib, sys
from simenv.models.predictor_regression import DCTRegressionPredictor, RegressionConfig
m = DCTRegressionPredictor(RegressionConfig(10, 10, blocks=2, members=2), seed=int(sys.argv[1]))
h = hashlib.md5()
for v in m.nets.state_dict().values():
    h.update(v.numpy().tobytes())
print(h.hexdigest())
"""


def _init_digest(seed: int | None) -> str:
    """Digest of a fresh 2-member model's weights built in a new Python process."""
    code = _INIT_DIGEST if seed is not None else _INIT_DIGEST.replace(
        ", seed=int(sys.argv[1])", "")
    done = subprocess.run([sys.executable, "-c", code, str(seed)], capture_output=True,
                          text=True, check=True, env=os.environ | {"OMP_NUM_THREADS": "1"})
    return done.stdout.strip()


def test_seeded_initial_weights_are_the_same_in_every_process():
    # torch seeds its global generator randomly per process: an unseeded model differs
    # from process to process, which made same-seed trainings select different iterations
    assert _init_digest(None) != _init_digest(None)
    assert _init_digest(3) == _init_digest(3)  # seeds 3 and 4 differ: the last line below
    a = R.DCTRegressionPredictor(R.RegressionConfig(10, 10, members=2), seed=3)
    b = R.DCTRegressionPredictor(R.RegressionConfig(10, 10, members=1), seed=4)
    # member i starts from seed + i whatever the ensemble size, and the global
    # generator is left as it was
    state = torch.random.get_rng_state()
    R.DCTRegressionPredictor(R.RegressionConfig(10, 10), seed=0)
    assert torch.equal(state, torch.random.get_rng_state())
    for k, v in b.net.state_dict().items():
        assert torch.equal(a.nets[1].state_dict()[k], v)
    assert not torch.equal(a.nets[0].fc_in.weight, a.nets[1].fc_in.weight)


def test_short_training_lowers_the_loss_and_keeps_the_best_validation_state(clips):
    train_w = pdata.windows_from_motions(clips[:1], 10, 10, stride=2)
    val_w = pdata.windows_from_motions(clips[1:], 10, 10, stride=4)
    model = R.DCTRegressionPredictor(R.RegressionConfig(10, 10))
    residual, last, future = R.targets(model.history_len, train_w.frames)

    def loss() -> float:
        with torch.no_grad():
            return R.regression_loss(model.forward(residual, last), future).item()

    before = loss()
    tp.train_regression(model, train_w, iterations=150, lr=1e-3, progress=False)
    assert loss() < 0.8 * before
    model = R.DCTRegressionPredictor(R.RegressionConfig(10, 10))
    log = tp.train_regression(model, train_w, iterations=150, lr=1e-3,
                              validation=val_w, validate_every=50, progress=False)
    scores = [e["val_mpjpe_mm"] for e in log if "val_mpjpe_mm" in e]
    assert len(scores) >= 3
    # the restored state is the best one seen on the validation windows
    assert tp.validation_score(model, val_w) == pytest.approx(min(scores), rel=1e-5)


def test_checkpoint_round_trip_and_errors(windows, tmp_path):
    model = R.DCTRegressionPredictor(R.RegressionConfig(10, 10, blocks=2))
    torch.manual_seed(1)
    for p in model.net.fc_out.parameters():
        torch.nn.init.normal_(p, std=0.1)
    again = R.DCTRegressionPredictor.load(model.save(tmp_path / "r.npz"))
    history = windows.frames[:3, :11]
    np.testing.assert_array_equal(again.predict(history), model.predict(history))
    gan = P.fit_geometry(windows, P.PredictorConfig(10, 10), max_iter=5)
    with pytest.raises(P.CheckpointError, match="simenv-dct-mlp-1"):
        R.DCTRegressionPredictor.load(gan.save(tmp_path / "g.npz"))
    with pytest.raises(MotionError, match="needs at least 11"):
        model.predict(windows.frames[:2, :6])
    short = pdata.PredictionWindows(windows.frames[:, :11], windows.root[:, :11],
                                    windows.clip, windows.start, windows.clip_names, 5, 5,
                                    windows.fps)
    with pytest.raises(MotionError, match="the model is 10->10"):
        tp.train_regression(model, short, iterations=1, progress=False)


def test_evaluation_of_a_regression_model_has_no_carried_amplitude(windows):
    model = R.DCTRegressionPredictor(R.RegressionConfig(10, 10))
    preds = tp.predictions(model, windows.subset(np.arange(8)))
    assert set(preds) == {"model", "zero_velocity", "constant_velocity"}
    np.testing.assert_allclose(preds["model"], preds["zero_velocity"], atol=1e-5)


def _perturbed(config: R.RegressionConfig, seed: int) -> R.DCTRegressionPredictor:
    """A model whose networks are not zero-velocity (random output layers)."""
    model = R.DCTRegressionPredictor(config)
    torch.manual_seed(seed)
    for net in model.nets:
        for p in net.fc_out.parameters():
            torch.nn.init.normal_(p, std=0.1)
    return model


def test_ensemble_is_the_mean_of_its_members_and_mirror_averaging_is_equivariant(windows):
    history = windows.frames[:6, :11]
    model = _perturbed(R.RegressionConfig(10, 10, members=3), seed=2)
    members = [model.member(i).predict(history) for i in range(3)]
    np.testing.assert_allclose(model.predict(history), np.mean(members, axis=0), atol=1e-5)
    assert np.abs(members[0] - members[1]).max() > 1e-3  # the members differ
    # member() shares the network: changing the view changes the ensemble
    with torch.no_grad():
        model.member(1).net.fc_out.bias.add_(0.5)
    assert np.abs(model.member(1).predict(history) - members[1]).max() > 1e-3
    plain = model.predict(history)
    averaged = R.DCTRegressionPredictor(replace(model.config, mirror_average=True))
    averaged.nets = model.nets
    pred = averaged.predict(history)
    np.testing.assert_allclose(pred, 0.5 * (plain + P.mirror(model.predict(P.mirror(history)))),
                               atol=1e-5)
    # the mirror of the prediction is the prediction of the mirrored history
    np.testing.assert_allclose(averaged.predict(P.mirror(history)), P.mirror(pred), atol=1e-5)
    assert np.abs(P.mirror(plain) - model.predict(P.mirror(history))).max() > 1e-3
    with pytest.raises(MotionError, match="members must be >= 1"):
        R.DCTRegressionPredictor(R.RegressionConfig(10, 10, members=0))


def test_ensemble_checkpoint_round_trip_and_single_network_files_still_load(windows, tmp_path):
    history = windows.frames[:3, :11]
    model = _perturbed(R.RegressionConfig(10, 10, blocks=2, members=2, mirror_average=True), 3)
    again = R.DCTRegressionPredictor.load(model.save(tmp_path / "e.npz"))
    assert again.config.members == 2 and again.config.mirror_average
    np.testing.assert_array_equal(again.predict(history), model.predict(history))
    # a checkpoint of the single-network format ("net.<k>" arrays, no members field)
    single = _perturbed(R.RegressionConfig(10, 10, blocks=2), 4)
    config = {k: v for k, v in asdict(single.config).items()
              if k not in ("members", "mirror_average")}
    arrays = {"format": np.array(R.CHECKPOINT_FORMAT), "config": np.array(json.dumps(config))}
    arrays |= {f"net.{k}": v.numpy() for k, v in single.net.state_dict().items()}
    np.savez(tmp_path / "old.npz", **arrays)
    old = R.DCTRegressionPredictor.load(tmp_path / "old.npz")
    assert old.config.members == 1 and not old.config.mirror_average
    np.testing.assert_array_equal(old.predict(history), single.predict(history))


def test_cross_fitted_ensemble_run_validates_each_member_on_its_own_fold(shared_data,
                                                                        tmp_path):
    files = [shared_data / "cmu" / "bvh" / f"{n}.bvh"
             for n in ("02_01", "12_01", "16_15", "49_06", "02_06")]
    args = tp.parse_args(["--model", "regression", "--past", "10", "--future", "10",
                          "--members", "2", "--cross-fit", "--iterations", "20", "--speeds", "1.0",
                          "--data", *map(str, files), "--out", str(tmp_path), "--quiet"])
    metrics = tp.run(args)
    info = metrics["config"]
    members = info["members"]
    held = [c for m in members for c in m["validation_clips"]]
    assert sorted(held) == sorted(info["train_clips"])  # every training clip once
    assert not set(info["test_clips"]) & set(held)
    assert all(m["iterations"] == 20 for m in members)
    model = R.DCTRegressionPredictor.load(tmp_path / "predictor-dctmlp-10-10.npz")
    assert model.config.members == 2 and model.config.mirror_average
    card = (tmp_path / "predictor-dctmlp-10-10.md").read_text()
    assert "cross-fitted" in card and "| 1 | " in card


def test_root_input_model_uses_the_root_velocity_in_the_heading_frame(windows, tmp_path):
    history, root = windows.frames[:4, :11], windows.root[:4, :11]
    model = _perturbed(R.RegressionConfig(10, 10, root_input=True, mirror_average=True), 5)
    torch.manual_seed(6)
    for net in model.nets:
        torch.nn.init.normal_(net.root.weight, std=0.5)
    pred = model.predict(history, root=root)
    # a translated root is the same motion; a faster root is not
    np.testing.assert_allclose(model.predict(history, root=root + np.float32([3, -2, 0])),
                               pred, atol=1e-5)
    faster = root[:, :1] + 2.0 * (root - root[:, :1])
    assert np.abs(model.predict(history, root=faster) - pred).max() > 1e-3
    # turning the whole window (body and root path) turns the prediction
    turned = P.rotate_z(history.astype(np.float64), np.full(4, 0.7))
    turned_root = P.rotate_z(root.astype(np.float64), np.full(4, 0.7))
    np.testing.assert_allclose(model.predict(turned, root=turned_root),
                               P.rotate_z(pred.astype(np.float64), np.full(4, 0.7)), atol=1e-4)
    again = R.DCTRegressionPredictor.load(model.save(tmp_path / "root.npz"))
    np.testing.assert_array_equal(again.predict(history, root=root), pred)
    with pytest.raises(MotionError, match="root trajectory") as err:
        model.predict(history)
    assert err.value.field == "root"
    with pytest.raises(MotionError, match="root must be"):
        model.predict(history, root=root[:2])


def test_root_input_training_lowers_the_loss(clips):
    train_w = pdata.windows_from_motions(clips[:1], 10, 10, stride=2)
    model = R.DCTRegressionPredictor(R.RegressionConfig(10, 10, root_input=True))
    residual, last, future = R.targets(model.history_len, train_w.frames)
    velocity = R.root_targets(model.history_len, train_w.frames, train_w.root, train_w.fps)

    def loss() -> float:
        with torch.no_grad():
            return R.regression_loss(model.forward(residual, last, velocity), future).item()

    before = loss()
    tp.train_regression(model, train_w, iterations=150, lr=1e-3, progress=False)
    assert loss() < 0.8 * before


def test_weighted_sampling_gives_the_extra_sources_their_share(shared_data, clips):
    extra, notes = tp.extra_motions(shared_data, ["nuisi"])
    names = [m.name for m in extra]
    assert len(extra) == 18 and not notes  # 9 training repetitions x 2 people
    assert not {n.rsplit("/", 1)[0] for n in names} & set(DEFAULT_TEST_RECORDINGS)
    cmu = pdata.windows_from_motions(clips[:1], 10, 10, stride=4)
    kin = pdata.windows_from_motions(extra[:2], 10, 10, stride=4)
    both = pdata.PredictionWindows(
        np.concatenate([cmu.frames, kin.frames]), np.concatenate([cmu.root, kin.root]),
        np.concatenate([cmu.clip, kin.clip + len(cmu.clip_names)]),
        np.concatenate([cmu.start, kin.start]), cmu.clip_names + kin.clip_names, 10, 10, 25.0)
    w = tp.source_weights(both, 0.25)
    extra_side = np.arange(len(both)) >= len(cmu)
    assert w[extra_side].sum() / w.sum() == pytest.approx(0.25)
    assert np.ptp(w[extra_side]) == 0 and np.ptp(w[~extra_side]) == 0
    with pytest.raises(MotionError, match="extra_share"):
        tp.source_weights(both, 1.0)
    with pytest.raises(MotionError, match="sample_weights"):
        tp.train_regression(R.DCTRegressionPredictor(R.RegressionConfig(10, 10)), both,
                            iterations=1, sample_weights=w[:3], progress=False)
    with pytest.raises(SimenvError, match="unknown extra data source"):
        tp.extra_motions(shared_data, ["florence"])


def test_run_with_extra_data_trains_on_it_but_never_validates_or_tests_on_it(shared_data,
                                                                            tmp_path):
    files = [shared_data / "cmu" / "bvh" / f"{n}.bvh" for n in ("02_01", "12_01", "49_06")]
    args = tp.parse_args(["--model", "regression", "--past", "10", "--future", "10",
                          "--members", "2", "--iterations", "20", "--speeds", "1.0",
                          "--validation", "0.3", "--extra-data", "nuisi", "--extra-share",
                          "0.4", "--data", *map(str, files), "--shared", str(shared_data),
                          "--out", str(tmp_path), "--quiet"])
    info = tp.run(args)["config"]
    assert info["extra_data"] == ["nuisi"] and info["extra_share"] == 0.4
    assert 0 < info["extra_windows"] < info["train_windows"]
    cmu = {"02_01", "12_01", "49_06"}
    assert set(info["test_clips"]) | set(info["validation_clips"]) <= cmu
    for m in info["members"]:
        assert set(m["validation_clips"]) <= cmu
    card = (tmp_path / "predictor-dctmlp-10-10.md").read_text()
    assert "extra training data" in card and "nuisi" in card


def test_horizon_weighted_loss_favours_the_late_frames():
    target = torch.zeros(2, 5, 51)
    early, late = target.clone(), target.clone()
    early[:, 0, 0] = 1.0  # the pelvis 1 dm off along x in the first frame only
    late[:, -1, 0] = 1.0  # ... in the last frame only
    w = R.horizon_weights(5, 2.0)
    np.testing.assert_allclose(w.numpy(), np.array([1, 1.5, 2, 2.5, 3]) / 2, rtol=1e-6)
    flat = [R.regression_loss(p, target).item() for p in (early, late)]
    assert flat[0] == pytest.approx(flat[1])
    assert flat[0] == pytest.approx(1 / 17 / 5 + 1 / 17 / 4)  # position + velocity term
    weighted = [R.regression_loss(p, target, 2.0).item() for p in (early, late)]
    assert weighted[0] == pytest.approx(0.5 / 17 / 5 + (1.5 / 2.25) / 17 / 4)
    assert weighted[1] == pytest.approx(1.5 / 17 / 5 + (3 / 2.25) / 17 / 4)

"""InterFormer: the attention masks and the interaction-distance term on toy inputs, the
reaction-generator protocol (any T, chunked long generation), cached (incremental)
decoding against the full re-decode, bad input, checkpoints and a short training run on
real windows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from simenv.core.errors import MotionError
from simenv.data import interaction_data as idata
from simenv.models.interformer import (
    Attention,
    DecoderCache,
    InterFormer,
    InterFormerConfig,
    _spatial,
    interaction_distance_bias,
    train,
)
from simenv.models.predictor import CheckpointError
from simenv.models.reaction_baselines import ReactionGenerator

SHIPPED = Path(__file__).resolve().parent.parent / "assets" / "models" / "interformer.npz"
#: A tiny configuration: tests train for a few CPU seconds.
TINY = InterFormerConfig(window=12, d_model=16, heads=2, encoder_layers=1,
                         decoder_layers=1, ffn=32, epochs=8, batch_size=8,
                         chunk_context=4, lr=3e-3)


@pytest.fixture(scope="module")
def recordings(shared_data: Path) -> list:
    return idata.load_recordings(shared_data)


@pytest.fixture(scope="module")
def short_windows(recordings: list) -> idata.InteractionWindows:
    """Real 12-frame windows (stride 20) of the training recordings."""
    windows = idata.make_windows(recordings, window=TINY.window, stride=20)
    return windows.subset(idata.split_by_recording(windows).train)


@pytest.fixture(scope="module")
def trained(short_windows: idata.InteractionWindows) -> tuple[InterFormer, dict]:
    rng = np.random.default_rng(0)
    return train(short_windows.subset(rng.choice(len(short_windows), 32, replace=False)),
                 TINY, seed=0, progress=False)


def _untrained(seed: int = 0) -> InterFormer:
    torch.manual_seed(seed)
    return InterFormer(TINY).eval()


# -- math on toy inputs ----------------------------------------------------------------


def test_spatial_attention_only_mixes_adjacent_joints() -> None:
    # Changing joint k's token changes exactly the outputs of the joints adjacent to k
    # (itself, its parent, its children): the adjacency mask I + A_in + A_out.
    torch.manual_seed(0)
    model = InterFormer(TINY)
    att = Attention(16, 2, 0.0)
    parents = TINY.parents
    x = torch.randn(1, 1, len(parents), 16)
    k = idata.INTER18_JOINTS.index("spine")
    y = x.clone()
    y[0, 0, k] += 1.0
    with torch.no_grad():
        change = (_spatial(att, y, y, model.adjacency_bias)
                  - _spatial(att, x, x, model.adjacency_bias)).abs().sum(-1)[0, 0]
    adjacent = {k, parents[k]} | {c for c, p in enumerate(parents) if p == k}
    assert {int(i) for i in torch.nonzero(change > 1e-6)} == adjacent
    assert {idata.INTER18_JOINTS[i] for i in adjacent} == {
        "spine", "pelvis", "neck", "left_shoulder", "right_shoulder"}


def test_interaction_distance_bias_is_scaled_softmax_of_negative_distance() -> None:
    reactor = torch.tensor([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    actor = torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, 2.0]])
    sigma = 0.5
    d = np.array([[0.0, 2.0], [1.0, np.sqrt(5.0)]])
    e = np.exp(-d / sigma)
    expected = 4 * e / e.sum()
    got = interaction_distance_bias(reactor, actor, sigma).numpy()
    np.testing.assert_allclose(got, expected, rtol=1e-5)
    assert got.mean() == pytest.approx(1.0)
    assert np.unravel_index(got.argmax(), got.shape) == (0, 0)  # the touching pair


def test_decoder_is_causal() -> None:
    model = _untrained()
    rng = np.random.default_rng(1)
    actor = torch.as_tensor(rng.normal(size=(1, 12, 18, 3)), dtype=torch.float32)
    reactor = torch.as_tensor(rng.normal(size=(1, 11, 18, 3)), dtype=torch.float32)
    later = reactor.clone()
    later[:, 6] += 0.3
    with torch.no_grad():
        a, b = model(actor, reactor), model(actor, later)
    diff = (a - b).abs().amax(dim=(0, 2, 3))
    assert torch.all(diff[:6] == 0)  # steps before the changed frame do not see it
    assert torch.all(diff[6:] > 0)


def test_mirror_is_an_involution_that_swaps_sides() -> None:
    model = _untrained()
    x = torch.randn(2, 3, 18, 3)
    np.testing.assert_allclose(model.mirror(model.mirror(x)), x)
    left, right = (idata.INTER18_JOINTS.index(n) for n in ("left_hand", "right_hand"))
    m = model.mirror(x)
    np.testing.assert_allclose(m[:, :, left], x[:, :, right] * torch.tensor([1, -1, 1]))


# -- protocol ---------------------------------------------------------------------------


def test_generate_follows_the_protocol_for_any_length(trained, recordings) -> None:
    model, _ = trained
    assert isinstance(model, ReactionGenerator) and model.name == "interformer"
    rec = next(r for r in recordings if r.num_frames >= 40)
    actor, reactor = rec.actor.positions[:40], rec.reactor.positions[:40]
    for t in (2, 5, TINY.window, 31):  # 31 > 12: three chunks
        out = model.generate(actor[:t], reactor[0])
        assert out.shape == (t, 18, 3) and out.dtype == np.float32
        assert np.isfinite(out).all()
        np.testing.assert_allclose(out[0], reactor[0], atol=1e-5)
    batch = model.generate(np.stack([actor[:20], actor[5:25]]),
                           np.stack([reactor[0], reactor[5]]))
    assert batch.shape == (2, 20, 18, 3)
    np.testing.assert_allclose(batch[1], model.generate(actor[5:25], reactor[5]), atol=1e-5)


def test_chunked_generation_keeps_the_first_chunk_and_continues(trained, recordings
                                                                ) -> None:
    model, _ = trained
    rec = next(r for r in recordings if r.num_frames >= 40)
    actor, b0 = rec.actor.positions[:40], rec.reactor.positions[0]
    long = model.generate(actor, b0)
    first = model.generate(actor[:TINY.window], b0)
    # The first chunk never sees later actor frames.
    np.testing.assert_allclose(long[:TINY.window], first, atol=1e-5)
    # Later chunks start from the last generated frames: no jump at the seams beyond the
    # largest step the model takes inside a chunk.
    step = np.linalg.norm(np.diff(long, axis=0), axis=-1).max(axis=-1)
    seam = TINY.window  # first frame generated by chunk 2
    assert step[seam - 1] <= 2 * step[:TINY.window - 1].max() + 1e-6


def test_generation_is_equivariant_to_rigid_motion_about_z(trained, short_windows) -> None:
    model, _ = trained
    a, b0 = short_windows.actor[0], short_windows.reactor[0, 0]
    theta, shift = 0.7, np.array([2.0, -1.0, 0.0])
    c, s = np.cos(theta), np.sin(theta)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    moved = model.generate(a @ rot.T + shift, b0 @ rot.T + shift)
    np.testing.assert_allclose(moved, model.generate(a, b0) @ rot.T + shift, atol=1e-4)


def test_bad_input_is_a_clear_error() -> None:
    model = _untrained()
    a = np.zeros((5, 18, 3))
    a[:, idata.INTER18_JOINTS.index("right_shoulder"), 1] = -0.2
    b0 = a[0]
    with pytest.raises(MotionError, match="actor_window") as err:
        model.generate(a[:, :17], b0)
    assert err.value.field == "actor_window"
    with pytest.raises(MotionError, match="reactor_first_frame"):
        model.generate(np.stack([a, a]), b0[None])
    with pytest.raises(MotionError, match="at least 2 frames"):
        model.generate(a[:1], b0)
    bad = a.copy()
    bad[2, 3, 0] = np.nan
    with pytest.raises(MotionError, match="non-finite"):
        model.generate(bad, b0)
    with pytest.raises(MotionError, match="chunk_context"):
        InterFormerConfig(window=10, chunk_context=10)


# -- checkpoints ------------------------------------------------------------------------


def test_save_load_round_trip_gives_identical_outputs(trained, short_windows, tmp_path
                                                      ) -> None:
    model, _ = trained
    path = model.save(tmp_path / "m.npz", {"note": "test"})
    loaded = InterFormer.load(path)
    assert loaded.config == model.config and loaded.metadata == {"note": "test"}
    a, b0 = short_windows.actor[:3], short_windows.reactor[:3, 0]
    np.testing.assert_array_equal(loaded.generate(a, b0), model.generate(a, b0))
    with np.load(path, allow_pickle=False) as data:  # arrays only
        assert str(data["format"]) == "simenv-interformer-1"


def test_bad_checkpoints_raise_checkpoint_error(trained, tmp_path) -> None:
    model, _ = trained
    with pytest.raises(CheckpointError):
        InterFormer.load(tmp_path / "missing.npz")
    np.savez(tmp_path / "foreign.npz", x=np.zeros(3))
    with pytest.raises(CheckpointError, match="not a simenv-interformer-1"):
        InterFormer.load(tmp_path / "foreign.npz")
    path = model.save(tmp_path / "m.npz")
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["weights.head.weight"] = np.zeros((2, 2), np.float32)
    np.savez(tmp_path / "wrong.npz", **arrays)
    with pytest.raises(CheckpointError, match="do not fit"):
        InterFormer.load(tmp_path / "wrong.npz")


# -- training ---------------------------------------------------------------------------


def test_short_training_on_real_windows_lowers_the_loss(trained) -> None:
    model, history = trained
    loss = history["loss"]
    assert len(loss) == TINY.epochs and len(history["mse"]) == TINY.epochs
    assert loss[-1] < 0.8 * loss[0]
    assert history["cpu_seconds"] > 0 and history["steps"] == 4 * TINY.epochs
    assert model.config.window == TINY.window and not model.training


def test_training_rejects_bad_windows(short_windows) -> None:
    two = idata.InteractionWindows(
        short_windows.actor[:2, :2], short_windows.reactor[:2, :2],
        short_windows.origin[:2], short_windows.yaw[:2], short_windows.label[:2],
        short_windows.recording[:2], short_windows.start[:2], short_windows.labels,
        short_windows.recording_names, short_windows.fps, short_windows.stride)
    with pytest.raises(MotionError, match=">= 3 frames"):
        train(two, TINY, progress=False)


@pytest.mark.skipif(not SHIPPED.is_file(), reason="shipped InterFormer not trained yet")
def test_shipped_checkpoint_loads_and_generates(recordings) -> None:
    model = InterFormer.load(SHIPPED)
    assert model.config.window == idata.WINDOW_FRAMES
    assert model.metadata["test_recordings"] == list(idata.DEFAULT_TEST_RECORDINGS)
    windows = idata.make_windows(recordings, stride=40)
    test = windows.subset(idata.split_by_recording(windows).test[:2])
    out = model.generate(test.actor, test.reactor[:, 0])
    assert out.shape == test.reactor.shape and np.isfinite(out).all()


# -- cached decoding --------------------------------------------------------------------


def _full_redecode_rollout(model: InterFormer, actor: np.ndarray, prefix: np.ndarray
                           ) -> np.ndarray:
    """Reference generation within a chunk: every new frame re-decodes the whole sequence
    so far and keeps the last row (what the cache must reproduce)."""
    a = torch.as_tensor(actor, dtype=torch.float32)
    seq = torch.as_tensor(prefix, dtype=torch.float32)
    with torch.no_grad():
        memory = model.encode(a)
        while seq.shape[1] < a.shape[1]:
            seq = torch.cat([seq, model.decode(seq, memory, a)[:, -1:]], dim=1)
    return seq[:, prefix.shape[1]:].numpy()


@pytest.fixture(scope="module")
def shipped() -> InterFormer:
    if not SHIPPED.is_file():
        pytest.skip("shipped InterFormer not trained yet")
    return InterFormer.load(SHIPPED)


def test_decode_steps_in_blocks_equal_the_full_decode(shipped, recordings) -> None:
    # Teacher-forced real frames decoded as a 10-frame prefix, then blocks of 3 and 1
    # steps: every row (features with the previous block's last frame, causal attention
    # over the cached keys) equals the one-pass decode.
    model = shipped
    rec = next(r for r in recordings if r.num_frames >= model.config.window)
    window = model.config.window
    a = torch.tensor(rec.actor.positions[None, :window], dtype=torch.float32)
    b = torch.tensor(rec.reactor.positions[None, :window - 1], dtype=torch.float32)
    cache = DecoderCache(model.config.decoder_layers, window - 1)
    with torch.no_grad():
        memory = model.encode(a)
        full = model.decode(b, memory, a)
        cuts = [0, 10, 13, 14, 17, window - 1]
        rows = [model.decode_steps(b[:, i:j], memory, a, cache)
                for i, j in zip(cuts[:-1], cuts[1:], strict=True)]
        assert cache.steps == window - 1
        np.testing.assert_allclose(torch.cat(rows, dim=1), full, atol=1e-5)
        with pytest.raises(MotionError, match="need actor frames up to 40") as err:
            model.decode_steps(b[:, -1:], memory, a, cache)
    assert err.value.field == "reactor_in"


def test_cached_generation_equals_the_full_re_decode(shipped, recordings, monkeypatch
                                                     ) -> None:
    # Two of the evaluation's 40-frame windows (one chunk from the given first frame) and
    # a 90-frame real sequence (three chunks, each continuing from 10 generated frames).
    model = shipped
    windows = idata.make_windows(recordings, stride=40)
    test = windows.subset(idata.split_by_recording(windows).test[:2])
    rec = next(r for r in recordings if r.num_frames >= 90)
    long_actor, long_b0 = rec.actor.positions[:90], rec.reactor.positions[0]
    cached = (model.generate(test.actor, test.reactor[:, 0]),
              model.generate(long_actor, long_b0))
    monkeypatch.setattr(model, "_rollout",
                        lambda actor, prefix: _full_redecode_rollout(model, actor, prefix))
    full = (model.generate(test.actor, test.reactor[:, 0]),
            model.generate(long_actor, long_b0))
    for c, f in zip(cached, full, strict=True):
        np.testing.assert_allclose(c, f, atol=1e-5)  # metres
    # The model moves the reactor: the comparison is not between two still poses.
    assert np.linalg.norm(full[1][-1] - full[1][0], axis=-1).max() > 0.05

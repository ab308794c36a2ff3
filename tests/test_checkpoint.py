"""Tests for simenv.models.checkpoint: round trip of networks, config, metadata and extra
arrays; every bad file is a CheckpointError naming it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn

from simenv.models.checkpoint import CheckpointError, read_checkpoint, save_checkpoint

torch.set_num_threads(1)


def _nets(seed: int) -> dict[str, nn.Module]:
    torch.manual_seed(seed)
    return {"a": nn.Linear(3, 2), "b": nn.Sequential(nn.Linear(2, 4), nn.Linear(4, 1))}


def test_round_trip_restores_weights_config_metadata_and_arrays(tmp_path: Path) -> None:
    nets = _nets(0)
    path = save_checkpoint(tmp_path / "sub" / "m.npz", "fmt-1", {"width": 4, "labels": ["x"]},
                           nets, metadata={"seed": np.int64(3)},
                           arrays={"mean": np.arange(3.0)})
    ck = read_checkpoint(path, "fmt-1")
    assert ck.config == {"width": 4, "labels": ["x"]} and ck.metadata == {"seed": 3.0}
    np.testing.assert_array_equal(ck.arrays["mean"], np.arange(3.0))
    fresh = _nets(1)
    ck.load_into(fresh)
    x = torch.randn(5, 3)
    with torch.no_grad():
        np.testing.assert_array_equal(fresh["a"](x).numpy(), nets["a"](x).numpy())
        np.testing.assert_array_equal(fresh["b"](nets["a"](x)).numpy(),
                                      nets["b"](nets["a"](x)).numpy())


def test_bad_files_are_named(tmp_path: Path) -> None:
    with pytest.raises(CheckpointError, match="cannot read") as err:
        read_checkpoint(tmp_path / "missing.npz", "fmt-1")
    assert "missing.npz" in str(err.value)
    (tmp_path / "text.npz").write_text("not a checkpoint")
    with pytest.raises(CheckpointError, match="cannot read"):
        read_checkpoint(tmp_path / "text.npz", "fmt-1")
    path = save_checkpoint(tmp_path / "m.npz", "fmt-1", {}, _nets(0))
    with pytest.raises(CheckpointError, match="not a fmt-2 checkpoint"):
        read_checkpoint(path, "fmt-2")
    np.savez(tmp_path / "json.npz", format=np.array("fmt-1"), config=np.array("{oops"))
    with pytest.raises(CheckpointError, match="bad config"):
        read_checkpoint(tmp_path / "json.npz", "fmt-1")
    with pytest.raises(CheckpointError, match="a weights do not fit"):
        read_checkpoint(path, "fmt-1").load_into({"a": nn.Linear(3, 7)})

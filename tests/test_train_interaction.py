"""Tests for simenv.learning.train_interaction: configuration from files, clear errors, and one
short real training run through the command that writes checkpoint, card and plot."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from simenv.cli import main as cli
from simenv.core.errors import SimenvError
from simenv.learning import train_interaction as ti
from simenv.models import INTERACTION_MODELS, interaction_model_class


@pytest.mark.parametrize("name", list(INTERACTION_MODELS))
def test_every_registered_model_has_config_train_and_checkpoints(name: str) -> None:
    cls = interaction_model_class(name)
    assert cls.name == name and callable(cls.load)
    config = ti.make_config(name)
    assert type(config).__name__ == f"{cls.__name__}Config"
    module = __import__(INTERACTION_MODELS[name][0], fromlist=["train"])
    assert callable(module.train)


def test_unknown_fields_and_models_are_named(tmp_path: Path) -> None:
    with pytest.raises(SimenvError, match="unknown InterFormerConfig field.*colour.*known"):
        ti.make_config("interformer", {"colour": 1}, source=tmp_path / "c.toml")
    with pytest.raises(SimenvError, match="unknown two-person model 'gpt'"):
        ti.make_config("gpt")
    # A value the configuration rejects is reported, not a traceback.
    with pytest.raises(SimenvError, match="heads"):
        ti.make_config("interformer", {"d_model": 30, "heads": 4})


def test_lists_from_files_become_tuple_fields(tmp_path: Path) -> None:
    path = tmp_path / "c.json"
    default = ti.make_config("interformer")
    path.write_text(json.dumps({"epochs": 2, "joint-names": list(default.joint_names)}))
    config = ti.make_config("interformer", ti.read_options(path), source=path)
    assert config.epochs == 2 and config.joint_names == default.joint_names


def test_cli_bad_config_exits_2(tmp_path: Path, capsys) -> None:
    path = tmp_path / "c.toml"
    path.write_text("wings = 2\n")
    status = cli.main(["train", "interaction", "--model", "interformer", "--config",
                       str(path), "--out", str(tmp_path / "out"), "--quiet"])
    assert status == 2
    assert "wings" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_short_real_training_run_writes_checkpoint_card_and_plot(
        tmp_path: Path, capsys, shared_data: Path) -> None:
    path = tmp_path / "tiny.toml"
    path.write_text("epochs = 2\nd_model = 16\nheads = 2\nffn = 32\nencoder_layers = 1\n"
                    "decoder_layers = 1\n")
    out = tmp_path / "run"
    status = cli.main(["train", "interaction", "--model", "interformer", "--config",
                       str(path), "--shared", str(shared_data), "--out", str(out),
                       "--quiet"])
    assert status == 0
    assert "wrote" in capsys.readouterr().out
    history = json.loads((out / "history.json").read_text())
    assert len(history["loss"]) == 2 and all(np.isfinite(history["loss"]))
    assert (out / "loss.png").stat().st_size > 1000
    card = (out / "interformer.md").read_text()
    assert "split" in card and "Held-out metrics" in card and "zero_velocity" in card
    model = interaction_model_class("interformer").load(out / "interformer.npz")
    assert model.config.d_model == 16

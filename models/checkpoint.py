"""Arrays-only ``.npz`` checkpoints of the two-person models (no pickle).

A checkpoint holds ``format`` (the model's version tag), ``config`` and ``metadata`` (JSON
strings), any extra arrays the model needs (e.g. a standardisation), and every parameter
of each named network as ``<net>.<parameter>``. :func:`save_checkpoint` writes one,
:func:`read_checkpoint` reads it back and :meth:`Checkpoint.load_into` puts the weights
into freshly built networks; every failure is a :class:`CheckpointError` naming the file.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from simenv.errors import SimenvError

#: Keys of a checkpoint that are not network parameters or extra arrays.
RESERVED = ("format", "config", "metadata")


class CheckpointError(SimenvError):
    """A checkpoint that cannot be read or does not fit its model."""


def save_checkpoint(path: str | Path, fmt: str, config: Mapping[str, Any],
                    nets: Mapping[str, nn.Module], *, metadata: Mapping[str, Any] | None = None,
                    arrays: Mapping[str, np.ndarray] | None = None) -> Path:
    """Write a checkpoint (module docstring); the parent folder is created.

    Args:
        path: ``.npz`` file. fmt: version tag. config: JSON-able configuration.
        nets: name -> network whose state dict is stored under ``<name>.``.
        metadata: JSON-able provenance (NumPy scalars become floats).
        arrays: extra arrays, stored under their own names.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    out: dict[str, np.ndarray] = {
        "format": np.array(fmt),
        "config": np.array(json.dumps(dict(config))),
        "metadata": np.array(json.dumps(dict(metadata or {}), default=float)),
        **{k: np.asarray(v) for k, v in (arrays or {}).items()},
    }
    for name, net in nets.items():
        for key, value in net.state_dict().items():
            out[f"{name}.{key}"] = value.detach().cpu().numpy()
    with path.open("wb") as fh:
        np.savez_compressed(fh, **out)
    return path


@dataclass(frozen=True)
class Checkpoint:
    """A checkpoint read by :func:`read_checkpoint`.

    Attributes:
        path: the file. config, metadata: the decoded JSON tables.
        arrays: every stored array but the reserved keys (parameters included).
    """

    path: Path
    config: dict[str, Any]
    metadata: dict[str, Any]
    arrays: dict[str, np.ndarray]

    def load_into(self, nets: Mapping[str, nn.Module]) -> None:
        """Load each network's ``<name>.`` parameters into it.

        Raises:
            CheckpointError: weights that do not fit a network.
        """
        for name, net in nets.items():
            prefix = name + "."
            state = {k[len(prefix):]: torch.as_tensor(v) for k, v in self.arrays.items()
                     if k.startswith(prefix)}
            try:
                net.load_state_dict(state)
            except RuntimeError as exc:
                raise CheckpointError(f"{name} weights do not fit the config: {exc}",
                                      source=self.path) from None


def read_checkpoint(path: str | Path, fmt: str) -> Checkpoint:
    """Read a checkpoint written by :func:`save_checkpoint` with version tag ``fmt``.

    Raises:
        CheckpointError: missing or unreadable file, another format, or a config or
            metadata entry that is not JSON.
    """
    path = Path(path)
    try:
        data = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise CheckpointError(f"cannot read checkpoint: {exc}", source=path) from None
    with data:
        if "format" not in data.files or str(data["format"]) != fmt:
            raise CheckpointError(f"not a {fmt} checkpoint", source=path)
        try:
            config = json.loads(str(data["config"]))
            metadata = json.loads(str(data["metadata"])) if "metadata" in data.files else {}
        except (KeyError, ValueError) as exc:
            raise CheckpointError(f"bad config or metadata in checkpoint: {exc}",
                                  source=path) from None
        arrays = {k: data[k] for k in data.files if k not in RESERVED}
    return Checkpoint(path, config, metadata, arrays)

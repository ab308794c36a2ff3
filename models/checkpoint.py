"""Arrays-only ``.npz`` checkpoints of every model (no pickle).

A checkpoint holds ``format`` (the model's version tag), ``config`` and ``metadata`` (JSON
strings), any extra arrays the model needs (e.g. a standardisation), and every parameter
of each named network as ``<net>.<parameter>``. :func:`save_checkpoint` writes one,
:func:`read_checkpoint` reads it back and :meth:`Checkpoint.load_into` puts the weights
into freshly built networks; every failure is a :class:`CheckpointError` naming the file.
:class:`CheckpointMixin` gives a model ``save`` and ``load`` from three hooks.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, ClassVar, Self

import numpy as np
import torch
from torch import nn

from simenv.core.errors import FormatError, SimenvError

#: Keys of a checkpoint that are not network parameters or extra arrays.
RESERVED = ("format", "config", "metadata")


class CheckpointError(FormatError):
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

    def load_into(self, nets: Mapping[str, nn.Module], optional: Sequence[str] = ()) -> None:
        """Load each network's ``<name>.`` parameters into it; a network named in
        ``optional`` keeps its initial weights when the checkpoint has none for it.

        Raises:
            CheckpointError: weights that do not fit a network.
        """
        for name, net in nets.items():
            prefix = name + "."
            state = {k[len(prefix):]: torch.as_tensor(v) for k, v in self.arrays.items()
                     if k.startswith(prefix)}
            if not state and name in optional:
                continue
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
    if not path.is_file():
        raise CheckpointError("cannot read checkpoint: file not found", source=path)
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


class CheckpointMixin:
    """``save`` / ``load`` of a model made of torch networks, as one checkpoint
    (module docstring).

    A model sets :attr:`CHECKPOINT_FORMAT`, holds ``config`` (a dataclass) and a JSON-able
    ``metadata`` dict, and implements three hooks: :meth:`checkpoint_nets` (its networks
    by name), :meth:`checkpoint_arrays` (extra arrays, default none) and
    :meth:`from_checkpoint` (the model built, untrained, from a checkpoint's config and
    arrays; by default ``cls(CONFIG(**config))``). ``load`` then puts the weights in,
    restores ``metadata`` and sets every network to eval mode.
    """

    #: Version tag written to and required from the checkpoint.
    CHECKPOINT_FORMAT: ClassVar[str]
    #: Networks a checkpoint may leave out (e.g. a GAN's critic, not needed to predict).
    OPTIONAL_NETS: ClassVar[tuple[str, ...]] = ()
    #: The config dataclass of a model built from its config alone (the default
    #: :meth:`from_checkpoint`).
    CONFIG: ClassVar[type]

    config: Any
    metadata: dict[str, Any]

    def checkpoint_nets(self) -> dict[str, nn.Module]:
        """Name -> network whose parameters the checkpoint stores under ``<name>.``."""
        raise NotImplementedError

    def checkpoint_arrays(self) -> dict[str, np.ndarray]:
        """Extra arrays the model needs besides its config and weights."""
        return {}

    @classmethod
    def from_checkpoint(cls, checkpoint: Checkpoint) -> Self:
        """The model with fresh weights, built from ``checkpoint.config`` and arrays.
        May raise KeyError, TypeError, ValueError or :class:`SimenvError` for a config
        or array that does not fit; :meth:`load` names the file. The default builds
        ``cls(CONFIG(**checkpoint.config))``."""
        return cls(cls.CONFIG(**checkpoint.config))

    def save(self, path: str | Path, metadata: Mapping[str, Any] | None = None, *,
             leave_out: Sequence[str] = ()) -> Path:
        """Write the checkpoint with ``metadata`` (default: the model's own); the
        networks named in ``leave_out`` (of :attr:`OPTIONAL_NETS`) are not stored.
        Returns the path."""
        extra = [n for n in leave_out if n not in self.OPTIONAL_NETS]
        if extra:
            raise CheckpointError(f"only optional networks {self.OPTIONAL_NETS} can be "
                                  f"left out; got {extra}", source=Path(path))
        nets = {n: net for n, net in self.checkpoint_nets().items() if n not in leave_out}
        return save_checkpoint(path, self.CHECKPOINT_FORMAT, asdict(self.config), nets,
                               metadata=self.metadata if metadata is None else metadata,
                               arrays=self.checkpoint_arrays())

    @classmethod
    def load(cls, path: str | Path) -> Self:
        """The model saved by :meth:`save`, networks in eval mode, ``metadata`` restored.

        Raises:
            CheckpointError: missing or unreadable file, another format, a config, array
                or weights that do not fit.
        """
        ck = read_checkpoint(path, cls.CHECKPOINT_FORMAT)
        try:
            model = cls.from_checkpoint(ck)
        except CheckpointError:
            raise
        except (KeyError, TypeError, ValueError, SimenvError) as exc:
            detail = exc.detail if isinstance(exc, SimenvError) else \
                f"{type(exc).__name__}: {exc}"
            raise CheckpointError(f"{cls.__name__} checkpoint does not fit: {detail}",
                                  source=ck.path) from None
        nets = model.checkpoint_nets()
        ck.load_into(nets, optional=cls.OPTIONAL_NETS)
        for net in nets.values():
            net.eval()
        model.metadata = dict(ck.metadata)
        return model

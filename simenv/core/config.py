"""Where things live, and the option files of the training and evaluation commands.

:func:`repo_root` and :func:`shared_data_root` locate the checkout and the shared corpus.

A config file is a flat table of option values, TOML (``.toml``) or JSON (``.json``),
e.g. ``minutes = 3`` or ``{"minutes": 3}``. Keys are the option names without the
leading dashes, with ``-`` or ``_`` (``n_critic`` = ``n-critic``).
"""

from __future__ import annotations

import json
import os
from dataclasses import fields
from pathlib import Path
from typing import Any, TypeVar

from simenv.core.errors import SimenvError


def repo_root() -> Path:
    """The repository checkout holding ``simenv/`` (where ``docs/`` and ``out/`` live)."""
    return Path(__file__).resolve().parents[2]


def shared_data_root(data: str | os.PathLike[str] | None = None) -> Path:
    """Root of the shared corpus: ``data``, else ``$SIMENV_SHARED_DATA``, else
    ``shared/data`` next to the repository (where ``SOURCES.md`` lives)."""
    if data is not None:
        return Path(data)
    env = os.environ.get("SIMENV_SHARED_DATA")
    return Path(env) if env else repo_root().parent / "shared" / "data"


def read_options(path: str | Path) -> dict[str, Any]:
    """The option table of a TOML or JSON config file.

    Raises:
        SimenvError: the file cannot be read or parsed, or is not a table (the message
            names the file).
    """
    path = Path(path)
    try:
        text = path.read_text()
        if path.suffix.lower() == ".json":
            raw = json.loads(text)
        else:
            import tomllib  # Python >= 3.11; use JSON on 3.10

            raw = tomllib.loads(text)
    except (OSError, ValueError, ImportError) as exc:
        raise SimenvError(f"cannot read config: {exc}", source=path) from None
    if not isinstance(raw, dict):
        raise SimenvError("a config file must hold one table of option values", source=path)
    return raw


Config = TypeVar("Config")


def dataclass_from_file(cls: type[Config], path: str | Path, **overrides: Any) -> Config:
    """An options dataclass ``cls`` from a config file (:func:`read_options`), ``overrides``
    winning over the file.

    Raises:
        SimenvError: unreadable file, or keys that are not fields of ``cls`` (the message
            names them and the known ones).
    """
    raw = read_options(path)
    known = {f.name for f in fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(raw) - known)
    if unknown:
        raise SimenvError(f"unknown option(s) {', '.join(unknown)}; known: "
                          f"{', '.join(sorted(known))}", source=path)
    return cls(**{**raw, **overrides})

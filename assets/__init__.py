"""Real motion capture bundled with simenv (package data of ``simenv.assets``).

Files are located with :mod:`importlib.resources`, so they are found the same way from a source
checkout, an editable install and a normal wheel install. Provenance and the CMU acknowledgement
are in ``README.md`` next to this file.
"""

from __future__ import annotations

import os
from importlib.resources import files
from pathlib import Path

from simenv.core.errors import SimenvError

#: A single person walking (CMU 02_01, BVH, 120 fps).
WALK = "cmu_02_01_walk.bvh"
#: Two people walking towards each other and shaking hands (CMU 18_01 + 19_01, one BVH each).
HANDSHAKE_PAIR = "cmu-18-19-walk-shake-hands"

_MOTION_SUFFIXES = (".bvh", ".asf", ".amc", ".npz", ".txt")
#: Sub-folder of trained model checkpoints (``simenv.models``), not a motion asset.
MODELS_DIR = "models"


def assets_root() -> Path:
    """Directory holding the bundled assets (inside the installed package)."""
    return Path(os.fspath(files(__name__)))


def list_assets() -> list[str]:
    """Names of the bundled motion assets: motion files and two-person folders, sorted."""
    root = assets_root()
    names = []
    for entry in root.iterdir():
        if entry.is_file() and entry.suffix.lower() in _MOTION_SUFFIXES:
            names.append(entry.name)
        elif entry.is_dir() and entry.name != MODELS_DIR and any(
                p.suffix.lower() in _MOTION_SUFFIXES for p in entry.iterdir()):
            names.append(entry.name)
    return sorted(names)


def asset_path(name: str) -> Path:
    """Absolute path of the bundled asset ``name`` (a file or a two-person folder).

    Raises:
        SimenvError: ``name`` is not a bundled asset; the message lists the available ones.
    """
    if name not in list_assets():
        raise SimenvError(
            f"no bundled asset {name!r}; available: {', '.join(list_assets())}", field="asset"
        )
    return assets_root() / name


__all__ = ["HANDSHAKE_PAIR", "WALK", "asset_path", "assets_root", "list_assets"]

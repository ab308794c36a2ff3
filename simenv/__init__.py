"""simenv: physics-backed simulation and evaluation of 3D human skeleton motion."""

from importlib import import_module

import simenv.body.gl  # noqa: F401  (sets MUJOCO_GL before anything imports mujoco)
from simenv.core.errors import SimenvError
from simenv.core.motion import Interaction, Motion
from simenv.core.skeletons import Skeleton
from simenv.io.loader import load

__all__ = ["Interaction", "Motion", "PlausibilityReport", "ScoreConfig", "SimenvError",
           "Skeleton", "load", "score"]
__version__ = "0.1.0"

#: Names imported on first use, and their modules.
_LAZY = {"score": "report", "PlausibilityReport": "report", "ScoreConfig": "metric"}


def __getattr__(name: str):
    # The scorer pulls in MuJoCo and the retargeting; import it only when used.
    if name in _LAZY:
        return getattr(import_module(f"simenv.plausibility.{_LAZY[name]}"), name)
    raise AttributeError(f"module 'simenv' has no attribute {name!r}")

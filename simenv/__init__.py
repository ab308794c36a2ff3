"""simenv: physics-backed simulation and evaluation of 3D human skeleton motion."""

import simenv._glenv  # noqa: F401  (sets MUJOCO_GL before anything imports mujoco)
from simenv.errors import SimenvError
from simenv.io.loader import load
from simenv.motion import Interaction, Motion, Skeleton
from simenv.plausibility.report import PlausibilityReport, ScoreConfig, score

__all__ = ["Interaction", "Motion", "PlausibilityReport", "ScoreConfig", "SimenvError",
           "Skeleton", "load", "score"]
__version__ = "0.1.0"

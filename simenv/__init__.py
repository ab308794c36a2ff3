"""simenv: physics-backed simulation and evaluation of 3D human skeleton motion."""

from simenv.errors import SimenvError
from simenv.motion import Interaction, Motion, Skeleton

__all__ = ["Interaction", "Motion", "SimenvError", "Skeleton"]
__version__ = "0.1.0"

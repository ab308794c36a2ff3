"""Readers and writers of motion files; :func:`simenv.io.load` detects the format."""

from simenv.io._kinematics import UNIT_SCALES
from simenv.io.loader import load

__all__ = ["UNIT_SCALES", "load"]

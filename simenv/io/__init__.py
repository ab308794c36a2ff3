"""Readers and writers of motion files; :func:`simenv.io.load` detects the format."""

from simenv.io.loader import load

__all__ = ["load"]

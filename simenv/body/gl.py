"""Choose MuJoCo's OpenGL backend before MuJoCo is imported.

MuJoCo picks its offscreen GL backend from ``MUJOCO_GL`` once, when ``mujoco`` is first imported,
and ``MUJOCO_GL=osmesa`` without libOSMesa breaks ``import mujoco`` itself. So simenv sets the
variable at package import, and only to a backend whose library is present: an explicit
``MUJOCO_GL`` always wins; with a ``DISPLAY`` MuJoCo's default (GLFW) is kept; otherwise OSMesa
(CPU) when installed, else EGL when installed, else nothing (rendering then fails with a
:class:`simenv.core.errors.SimenvError` that says what to install).
"""

from __future__ import annotations

import ctypes.util
import os
import sys

#: True when ``mujoco`` was imported before simenv could choose its backend (choice too late).
MUJOCO_IMPORTED_FIRST = "mujoco" in sys.modules


def select_gl_backend() -> str | None:
    """Set ``MUJOCO_GL`` for headless Linux if unset; returns the backend in effect (or None)."""
    if os.environ.get("MUJOCO_GL"):
        return os.environ["MUJOCO_GL"]
    if not sys.platform.startswith("linux") or os.environ.get("DISPLAY"):
        return None
    for backend, library in (("osmesa", "OSMesa"), ("egl", "EGL")):
        if ctypes.util.find_library(library):
            os.environ["MUJOCO_GL"] = backend
            return backend
    return None


select_gl_backend()

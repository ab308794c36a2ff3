"""Assertions on simenv's errors shared by the reader and physics tests."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from simenv.core.errors import FormatError, SimenvError


def names_all(error: SimenvError, path: Path, needles: tuple[str, ...]) -> SimenvError:
    """``error``'s message names ``path`` and holds every needle; returns ``error``."""
    msg = str(error)
    assert str(path) in msg
    for needle in needles:
        assert needle in msg, msg
    return error


def rejects_lines(read: Callable[[Path], Any], path: Path, lines: list[str], match: str,
                  line: int) -> SimenvError:
    """``read(path)`` of ``lines`` written to ``path`` raises a FormatError matching
    ``match`` at line ``line``; returns it."""
    path.write_text("\n".join(lines) + "\n")
    return raises_at(FormatError, match, lambda: read(path), line=line)


def raises_at(error: type[SimenvError], match: str, call: Callable[[], Any],
              **where: Any) -> SimenvError:
    """``call()`` raises ``error`` with a message matching ``match`` and the attributes
    ``where`` (e.g. ``line=7``, ``frame=17``); returns the error."""
    with pytest.raises(error, match=match) as info:
        call()
    for key, value in where.items():
        assert getattr(info.value, key) == value
    return info.value

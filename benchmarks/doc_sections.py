"""Generated sections of hand-written docs: the text between a begin and an end marker."""

from __future__ import annotations

from pathlib import Path


def replace_section(path: Path, begin: str, end: str, body: str) -> None:
    """Write ``body`` between the markers ``begin`` and ``end`` of ``path`` (both kept,
    everything outside them untouched).

    Raises:
        ValueError: ``path`` lacks one of the markers.
    """
    text = path.read_text()
    if begin not in text or end not in text:
        raise ValueError(f"{path}: markers {begin!r} / {end!r} not found")
    head, rest = text.split(begin, 1)
    _, tail = rest.split(end, 1)
    path.write_text(f"{head}{begin}\n{body}\n{end}{tail}")


def section(text: str, begin: str, end: str) -> str:
    """The text from ``begin`` through ``end`` of ``text``, markers included.

    Raises:
        ValueError: ``text`` lacks one of the markers.
    """
    return text[text.index(begin):text.index(end) + len(end)]

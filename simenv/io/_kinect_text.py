"""Numeric-table parsing shared by the Kinect-era text readers (MSR Action3D,
UTKinect, SBU, NuiSI, NTU): every bad line is reported with file and line."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from simenv.core.errors import FormatError
from simenv.io._text import parse_float_rows, read_text, split_lines


def table_lines(path: Path, sep: str | None) -> list[tuple[int, list[str]]]:
    """Non-blank lines of ``path`` as ``(1-based line number, tokens)``.

    ``sep=None`` splits on whitespace; ``","`` on commas (tokens stripped).
    Raises :class:`FormatError` for an empty file.
    """
    out: list[tuple[int, list[str]]] = []
    for i, line in enumerate(split_lines(read_text(path)), start=1):
        if not line.strip():
            continue
        tokens = line.split() if sep is None else [t.strip() for t in line.strip().split(sep)]
        out.append((i, tokens))
    if not out:
        raise FormatError("file is empty; expected skeleton data", source=path)
    return out


def check_counts(
    path: Path, rows: list[tuple[int, list[str]]], allowed: tuple[int, ...], what: str
) -> None:
    """Raise :class:`FormatError` at the first row whose value count is not in ``allowed``."""
    for n, (line, tokens) in enumerate(rows):
        if len(tokens) not in allowed:
            expected = " or ".join(str(a) for a in allowed)
            raise FormatError(
                f"expected {expected} values per line ({what}), found {len(tokens)}",
                source=path,
                line=line,
                frame=n,
            )


def to_floats(path: Path, rows: list[tuple[int, list[str]]], field_names: list[str] | None = None
              ) -> np.ndarray:
    """(N, C) float64 from equally long rows; non-numeric or non-finite values
    raise :class:`FormatError` naming line and field."""
    return parse_float_rows(
        [r[1] for r in rows], source=path, lines=[r[0] for r in rows], field_names=field_names
    )


def head_text(head: bytes) -> list[str]:
    """The complete lines of a sniffed file head (the last, possibly cut, line
    is dropped unless the head is the whole file)."""
    text = head.decode("utf-8", errors="replace").replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    if len(head) >= 4096:
        lines = lines[:-1]
    return [ln for ln in lines if ln.strip()]


def sniff_rows(path: Path, head: bytes, *, suffix: str, lines: int, sep: str | None,
               counts: tuple[int, ...],
               accept: Callable[[list[str]], bool] | None = None) -> bool:
    """True when ``path`` ends in ``suffix`` and each of the first ``lines`` complete
    lines of its ``head`` (at least one) splits (on ``sep``; None: whitespace) into a
    count in ``counts`` of numbers that ``accept`` (when given) accepts."""
    if path.suffix.lower() != suffix:
        return False
    rows = [ln.split(sep) for ln in head_text(head)[:lines]]
    return bool(rows) and all(
        len(t) in counts and all(is_number(v) for v in t) and (accept is None or accept(t))
        for t in rows)


def is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def resample_stamped(t_s: np.ndarray, pos: np.ndarray, fps: float) -> tuple[np.ndarray,
                                                                           np.ndarray]:
    """Positions sampled at time stamps, linearly interpolated onto a uniform grid.

    Args:
        t_s: (N,) increasing time stamps, seconds from the first (N >= 2).
        pos: (N, J, 3) positions at those stamps.
        fps: frames per second of the grid, which starts at 0 and ends at or before the
            last stamp.

    Returns:
        times (M,) seconds and positions (M, J, 3) on the grid.
    """
    times = np.arange(int(np.floor(t_s[-1] * fps + 1e-9)) + 1) / fps
    flat = pos.reshape(len(pos), -1)
    out = np.stack([np.interp(times, t_s, flat[:, c]) for c in range(flat.shape[1])], axis=1)
    return times, out.reshape(len(times), *pos.shape[1:])


"""Text helpers shared by the mocap readers: decoding, line splitting and
number parsing that report the file, line and field of bad input."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from simenv.core.errors import FormatError


def read_text(path: Path) -> str:
    """File contents as text. Undecodable bytes become U+FFFD so that a
    corrupt file fails later with a located :class:`FormatError` rather than
    a ``UnicodeDecodeError``."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FormatError(f"cannot read file: {exc.strerror or exc}", source=path) from None
    return data.decode("utf-8", errors="replace")


def split_lines(text: str) -> list[str]:
    """Lines of ``text`` accepting LF, CRLF and lone CR endings (line ``i`` of
    the file is element ``i - 1``)."""
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


def parse_float(token: str, *, source: Path, line: int, field: str) -> float:
    """One finite float, else :class:`FormatError` naming line and field."""
    try:
        value = float(token)
    except ValueError:
        raise FormatError(
            f"expected a number for {field}, found {token[:40]!r}", source=source, line=line
        ) from None
    if not math.isfinite(value):
        raise FormatError(
            f"expected a finite number for {field}, found {token!r}", source=source, line=line
        )
    return value


def parse_float_rows(
    rows: list[list[str]],
    *,
    source: Path,
    lines: list[int],
    field_names: list[str] | None = None,
    frame_offset: int = 0,
) -> np.ndarray:
    """Parse equally long rows of number tokens into a (N, C) float64 array.

    The common case is one vectorised conversion; only when it fails is the
    offending row located to name its line, frame and field.

    Args:
        rows: N token lists, all of length C (checked by the caller).
        lines: (N,) 1-based file line of each row.
        field_names: (C,) names used in error messages (e.g. channel names).
        frame_offset: frame index of ``rows[0]``.
    """
    n = len(rows)
    c = len(rows[0]) if rows else 0
    flat = [tok for row in rows for tok in row]
    try:
        values = np.array(flat, dtype=np.float64).reshape(n, c)
    except ValueError:
        values = None
    if values is not None and np.isfinite(values).all():
        return values
    for r, row in enumerate(rows):
        for k, tok in enumerate(row):
            try:
                ok = math.isfinite(float(tok))
            except ValueError:
                ok = False
            if not ok:
                name = field_names[k] if field_names else f"value {k + 1}"
                raise FormatError(
                    f"expected a finite number, found {tok[:40]!r}",
                    source=source,
                    line=lines[r],
                    frame=frame_offset + r,
                    field=name,
                )
    raise FormatError("could not parse numeric data", source=source)  # pragma: no cover

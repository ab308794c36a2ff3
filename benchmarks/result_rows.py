"""Incremental benchmark results: one JSON object per line, each with a ``key``, appended as it
finishes; a rerun reads what is there and skips those keys."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def read_rows(path: Path) -> dict[str, dict[str, Any]]:
    """Rows already written to the JSONL ``path``, by key (the last one of a key wins)."""
    rows: dict[str, dict[str, Any]] = {}
    if path.exists():
        for line in path.read_text().splitlines():
            if line.strip():
                row = json.loads(line)
                rows[row["key"]] = row
    return rows

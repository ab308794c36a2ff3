"""How simenv reads real motion files of each joint-naming convention, today.

For every motion file under the given paths (default: ``tests/data/conventions``, one
folder per convention; see its ``SOURCES.md``), load it with :func:`simenv.load` and print
one table row: file, joints, frames, fps, ``metadata["units"]``, how many of the 21
canonical keypoints the skeleton maps and which are missing, or the error message when
the file does not load. This is the "before" picture of automatic skeleton mapping
(issue 33): it measures, it does not judge.

Usage::

    .venv/bin/python benchmarks/convention_survey.py [PATH ...] [--markdown]
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import simenv
from simenv.core.errors import SimenvError
from simenv.core.motion import Interaction, Motion
from simenv.core.skeletons import canonical_skeleton

DEFAULT_ROOT = Path(__file__).resolve().parents[1] / "tests" / "data" / "conventions"
# Provenance notes that sit beside the data, not motion.
NOT_MOTION = {".md", ".txt", ".toml"}


@dataclass(frozen=True)
class Row:
    """One file's survey result; ``error`` is set instead of the figures when it fails."""

    file: str
    joints: int | None = None
    frames: int | None = None
    fps: float | None = None
    units: str | None = None
    mapped: int | None = None
    missing: tuple[str, ...] = ()
    error: str | None = None


def motion_files(paths: list[Path]) -> list[Path]:
    """Files under ``paths`` (recursively), sorted, without the provenance notes."""
    found: list[Path] = []
    for p in paths:
        if p.is_dir():
            found += [f for f in sorted(p.rglob("*")) if f.is_file() and f.suffix.lower()
                      not in NOT_MOTION and not f.name.startswith(".")]
        else:
            found.append(p)
    return found


def survey(path: Path, root: Path | None) -> Row:
    """Load ``path`` and describe what simenv made of it.

    ``fps`` is in frames per second; ``units`` is what the reader decided the file used.
    A list or an interaction is described by its first person.
    """
    name = str(path.relative_to(root)) if root is not None and path.is_relative_to(root) \
        else str(path)
    try:
        loaded = simenv.load(path)
    except (SimenvError, ValueError, OSError) as exc:
        # Typed reader errors are the finding; a bare ValueError/OSError is reported too.
        return Row(name, error=f"{type(exc).__name__}: {exc}")
    if isinstance(loaded, list):
        loaded = loaded[0]
    motion: Motion = loaded.actor if isinstance(loaded, Interaction) else loaded
    keys = canonical_skeleton().joint_names
    mapped = motion.skeleton.canonical
    return Row(
        name,
        joints=motion.skeleton.num_joints,
        frames=int(motion.positions.shape[0]),
        fps=float(motion.fps),
        units=str(motion.metadata.get("units")),
        mapped=len(mapped),
        missing=tuple(k for k in keys if k not in mapped),
    )


def render(rows: list[Row], markdown: bool) -> str:
    """The rows as a markdown table (``markdown``) or plain aligned text."""
    head = ["file", "joints", "frames", "fps", "units", "mapped/21", "missing or error"]
    cells = []
    for r in rows:
        if r.error is not None:
            cells.append([r.file, "-", "-", "-", "-", "-", r.error])
            continue
        missing = "none" if not r.missing else ", ".join(r.missing)
        cells.append([r.file, str(r.joints), str(r.frames), f"{r.fps:g}", str(r.units),
                      str(r.mapped), missing])
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |"
                  for row in cells]
        return "\n".join(lines)
    widths = [max(len(row[i]) for row in [head, *cells]) for i in range(len(head) - 1)]
    out = []
    for row in [head, *cells]:
        padded = [c.ljust(w) for c, w in zip(row[:-1], widths, strict=True)]
        out.append("  ".join([*padded, row[-1]]))
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("paths", nargs="*", type=Path, default=[DEFAULT_ROOT],
                    help="files or folders (default: tests/data/conventions)")
    ap.add_argument("--markdown", action="store_true", help="print a markdown table")
    args = ap.parse_args(argv)
    root = DEFAULT_ROOT if args.paths == [DEFAULT_ROOT] else None
    rows = [survey(p, root) for p in motion_files(args.paths)]
    print(render(rows, args.markdown))
    loaded = [r for r in rows if r.error is None]
    full = sum(1 for r in loaded if r.mapped == len(canonical_skeleton().joint_names))
    print(f"\n{len(rows)} files: {len(loaded)} loaded, {len(rows) - len(loaded)} failed; "
          f"{full} map all 21 canonical keypoints")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

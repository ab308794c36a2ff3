"""Calibrate the joint-level plausibility metrics on real motion capture.

Runs every metric of :data:`simenv.plausibility.KINEMATIC_METRICS` on every
real single-person CMU clip in the shared corpus (``cmu/bvh/*.bvh`` and
``cmu/asf_amc/*.amc``), prints a table (value per metric per clip, ``!``
marking a failed metric) and writes the values, verdicts, details and
violations as JSON.

Usage::

    .venv/bin/python benchmarks/calibrate_kinematic.py [--data DIR] [--out FILE.json]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from simenv.io import asf_amc, bvh
from simenv.motion import Motion
from simenv.plausibility import DEFAULT_THRESHOLDS, KINEMATIC_METRICS

REPO = Path(__file__).resolve().parent.parent
DEFAULT_DATA = Path(os.environ.get("SIMENV_SHARED_DATA", REPO.parent / "shared" / "data"))


def single_person_clips(data: Path) -> list[Path]:
    """The real single-person CMU clips of the corpus, BVH then AMC."""
    cmu = data / "cmu"
    return sorted((cmu / "bvh").glob("*.bvh")) + sorted((cmu / "asf_amc").glob("*.amc"))


def load(path: Path) -> Motion:
    return bvh.read(path) if path.suffix == ".bvh" else asf_amc.read(path)


def calibrate(paths: list[Path]) -> list[dict]:
    rows = []
    for path in paths:
        motion = load(path)
        start = time.perf_counter()
        results = {name: fn(motion, DEFAULT_THRESHOLDS) for name, fn in KINEMATIC_METRICS.items()}
        elapsed = time.perf_counter() - start
        rows.append({
            "clip": f"{path.parent.name}/{path.name}",
            "frames": motion.num_frames,
            "fps": motion.fps,
            "quirks": motion.metadata.get("quirks", []),
            "seconds": elapsed,
            "metrics": {name: r.to_dict() for name, r in results.items()},
        })
    return rows


def print_table(rows: list[dict]) -> None:
    names = list(KINEMATIC_METRICS)
    head = f"{'clip':24s} {'frames':>6s} " + " ".join(f"{n[:12]:>13s}" for n in names)
    print(head)
    print("-" * len(head))
    for row in rows:
        cells = []
        for n in names:
            m = row["metrics"][n]
            v = m["value"]
            mark = "" if m["passed"] in (True, None) else "!"
            cells.append(f"{'n/a' if v is None else f'{v:.4g}'}{mark:1s}".rjust(13))
        print(f"{row['clip']:24s} {row['frames']:6d} " + " ".join(cells))
    print("-" * len(head))
    thr = {n: rows[0]["metrics"][n]["threshold"] for n in names} if rows else {}
    units = {n: rows[0]["metrics"][n]["unit"] for n in names} if rows else {}
    print(f"{'threshold':24s} {'':6s} " + " ".join(f"{thr[n]:>13.4g}" for n in names))
    print(f"{'unit':24s} {'':6s} " + " ".join(f"{units[n][:13]:>13s}" for n in names))
    print("\ndetails:")
    for row in rows:
        parts = []
        for n in names:
            d = row["metrics"][n]["details"]
            parts.append(f"{n}: " + ", ".join(f"{k}={v:.3g}" for k, v in d.items()))
        print(f"  {row['clip']}: " + " | ".join(parts))
    print("\nviolations (first 3 per metric):")
    for row in rows:
        for n in names:
            viol = row["metrics"][n]["violations"]
            if viol:
                shown = ", ".join(
                    f"[{v['start_frame']}-{v['end_frame']}] {v['worst_value']:.3g}"
                    for v in viol[:3])
                print(f"  {row['clip']} {n}: {len(viol)} run(s): {shown}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--out", type=Path,
                        default=REPO / "benchmarks" / "calibrate_kinematic.json")
    args = parser.parse_args()
    paths = single_person_clips(args.data)
    if not paths:
        raise SystemExit(f"no CMU clips under {args.data}/cmu")
    rows = calibrate(paths)
    print_table(rows)
    frames = sum(r["frames"] for r in rows)
    seconds = sum(r["seconds"] for r in rows)
    print(f"\n{len(rows)} clips, {frames} frames, metrics in {seconds:.2f} s "
          f"({frames / seconds:,.0f} frames/s)")
    args.out.write_text(json.dumps({"thresholds": vars(DEFAULT_THRESHOLDS), "clips": rows},
                                   indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

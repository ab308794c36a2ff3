"""Calibrate the joint-level plausibility metrics on real motion capture.

Runs every metric of :data:`simenv.plausibility.KINEMATIC_METRICS` on every
real single-person CMU clip in the shared corpus (``cmu/bvh/*.bvh`` and
``cmu/asf_amc/*.amc``), prints a table (value per metric per clip, ``!``
marking a failed metric) and writes the values, verdicts, details and
violations as JSON. With ``--gestures`` it also summarises the real
single-person depth-sensor recordings (``gestures/``: MSR Action3D,
UTKinect, Florence 3D) per dataset: pass rate and value percentiles. The
defaults are calibrated on marker-based mocap; Kinect-era skeletons are
noisier and are reported, not tuned for.

Usage::

    .venv/bin/python benchmarks/calibrate_kinematic.py [--data DIR] [--out FILE.json] [--gestures]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import simenv
from simenv.core.config import shared_data_root
from simenv.core.motion import Motion
from simenv.io import asf_amc, bvh
from simenv.plausibility import DEFAULT_THRESHOLDS, KINEMATIC_METRICS

REPO = Path(__file__).resolve().parent.parent
DEFAULT_DATA = shared_data_root()


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


def gesture_clips(data: Path) -> dict[str, list[Motion]]:
    """Real single-person depth-sensor clips of ``gestures/``, per dataset."""
    root = data / "gestures"
    sources = {
        "msr_action3d": sorted((root / "msr_action3d").glob("*_skeleton3D.txt")),
        "utkinect": sorted((root / "utkinect" / "joints").glob("joints_*.txt")),
        "florence3d": [root / "florence3d" / "skeletal_data.mat"],
    }
    clips: dict[str, list[Motion]] = {}
    for dataset, paths in sources.items():
        for path in paths:
            try:
                loaded = simenv.load(path)
            except simenv.SimenvError as exc:
                print(f"  skipped {path.name}: {exc}")
                continue
            items = loaded if isinstance(loaded, list) else [loaded]
            clips.setdefault(dataset, []).extend(m for m in items if isinstance(m, Motion))
    return clips


def summarise_gestures(clips: dict[str, list[Motion]]) -> dict[str, dict]:
    """Per dataset and metric: clips, pass rate, value p50 / p95 / max."""
    summary: dict[str, dict] = {}
    names = list(KINEMATIC_METRICS)
    print(f"\n{'dataset':14s} {'clips':>5s} " + " ".join(f"{n[:12]:>22s}" for n in names))
    print(f"{'':14s} {'':5s} " + " ".join(f"{'pass% p50/max':>22s}" for _ in names))
    for dataset, motions in clips.items():
        per_metric: dict[str, dict] = {}
        for n in names:
            results = [KINEMATIC_METRICS[n](m, DEFAULT_THRESHOLDS) for m in motions]
            vals = np.array([r.value for r in results if r.available])
            passed = [r.passed for r in results if r.available]
            per_metric[n] = {
                "available": len(vals),
                "pass_rate": float(np.mean(passed)) if passed else None,
                "p50": float(np.percentile(vals, 50)) if len(vals) else None,
                "p95": float(np.percentile(vals, 95)) if len(vals) else None,
                "max": float(vals.max()) if len(vals) else None,
            }
        summary[dataset] = {"clips": len(motions), "metrics": per_metric}
        cells = []
        for n in names:
            m = per_metric[n]
            if m["pass_rate"] is None:
                cells.append("n/a".rjust(22))
            else:
                cells.append(f"{100 * m['pass_rate']:3.0f}% {m['p50']:.3g}/{m['max']:.3g}"
                             .rjust(22))
        print(f"{dataset:14s} {len(motions):5d} " + " ".join(cells))
    return summary


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
    parser.add_argument("--out", type=Path, default=REPO / "out" / "calibrate_kinematic.json")
    parser.add_argument("--gestures", action="store_true",
                        help="also summarise the depth-sensor gesture recordings")
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
    result = {"thresholds": vars(DEFAULT_THRESHOLDS), "clips": rows}
    if args.gestures:
        result["gestures"] = summarise_gestures(gesture_clips(args.data))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

"""Calibrate the body-level plausibility metrics on real motion capture.

Retargets every real single-person CMU clip of the shared corpus
(``cmu/bvh/*.bvh`` and ``cmu/asf_amc/*.amc``) onto its fitted MuJoCo humanoid
and runs every body-level metric of the scorer's registry
(:data:`simenv.plausibility.metric_registry.PERSON_REGISTRY`) on the shared
fit and poses: geom ground penetration and floating, joint limits (relaxed
refit), self-penetration, root residual (inferred: no tracking run), balance;
then PD physics tracking without and with root assistance. Also runs the
pairwise geom metrics (inter-person penetration, contact JPD) on the real
two-person pairs. Metrics are keyed by their report names.
Prints a table (``!`` marks a failed metric) and writes values, verdicts,
details and violations as JSON.

Usage::

    .venv/bin/python benchmarks/calibrate_body.py [--data DIR] [--frames N] [--out FILE.json]
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from dataclasses import asdict
from functools import partial
from pathlib import Path

import simenv
from simenv.body.retarget import RetargetResult, retarget
from simenv.core.config import shared_data_root
from simenv.core.motion import Interaction, Motion
from simenv.io import asf_amc, bvh
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS
from simenv.plausibility.metric import Needs, PairInputs, PersonInputs, ScoreConfig
from simenv.plausibility.metric_registry import PAIR_REGISTRY, PERSON_REGISTRY
from simenv.plausibility.timeline import MetricResult
from simenv.plausibility.tracking import tracking

REPO = Path(__file__).resolve().parent.parent
DEFAULT_DATA = shared_data_root()

#: The registry's body metrics, without the scorer's tracking run (the root
#: residual is then the inferred one).
BODY_ONLY = ScoreConfig(tracking=False)
#: The body metrics of one retargeted clip, in report order.
BODY_METRICS = [m for m in PERSON_REGISTRY if m.needs is Needs.BODY and m.name != "tracking"]
#: PD physics tracking, calibrated without and with the root assistance.
TRACKERS: dict[str, Callable[[RetargetResult], MetricResult]] = {
    "tracking": tracking,
    "tracking_assisted": lambda r: tracking(r, assist=True),
}
#: Table cells: (metric, detail or None for the value, header).
COLUMNS = (
    ("ground_penetration", None, "pen mm"),
    ("floating", None, "float mm"),
    ("joint_limits", None, "jlim deg"),
    ("self_penetration", None, "self mm"),
    ("root_residual", None, "root BW"),
    ("root_residual", "p95", "root p95"),
    ("balance", None, "bal mm"),
    ("tracking", "time_to_failure_s", "PD ttf s"),
    ("tracking", "mpjpe_mm", "PD mpjpe"),
    ("tracking_assisted", "mpjpe_mm", "as mpjpe"),
    ("tracking_assisted", "assist_force_mean", "as BW"),
)


def single_person_clips(data: Path) -> list[Path]:
    """The real single-person CMU clips of the corpus, BVH then AMC."""
    cmu = data / "cmu"
    return sorted((cmu / "bvh").glob("*.bvh")) + sorted((cmu / "asf_amc").glob("*.amc"))


def load(path: Path, frames: int | None) -> Motion:
    motion = bvh.read(path) if path.suffix == ".bvh" else asf_amc.read(path)
    return motion.slice(0, frames) if frames and motion.num_frames > frames else motion


def score_clip(motion: Motion) -> dict:
    t0 = time.perf_counter()
    result = retarget(motion)
    t_ret = time.perf_counter() - t0
    metrics: dict[str, dict] = {}
    seconds: dict[str, float] = {"retarget": t_ret}
    inputs = PersonInputs(motion, result, None, BODY_ONLY)
    runs: dict[str, Callable[[], MetricResult]] = {
        m.name: partial(inputs.measure, m) for m in BODY_METRICS}
    runs.update({name: partial(fn, result) for name, fn in TRACKERS.items()})
    for name, run in runs.items():
        t = time.perf_counter()
        metrics[name] = run().to_dict()
        seconds[name] = time.perf_counter() - t
    return {"frames": motion.num_frames, "fps": motion.fps,
            "mean_residual_m": result.mean_residual, "mass_kg": result.humanoid.total_mass,
            "height_m": result.humanoid.dims.height, "seconds": seconds, "metrics": metrics}


def score_pair(pair: Interaction) -> dict:
    result = retarget(pair)
    inputs = PairInputs(pair, result, None, BODY_ONLY)
    out = {m.name: inputs.measure(m).to_dict() for m in PAIR_REGISTRY if m.basis == "geoms"}
    return {"frames": int(result.qpos.shape[0]), "metrics": out}


def _cell(row: dict, metric: str, detail: str | None) -> str:
    m = row["metrics"][metric]
    v = m["value"] if detail is None else m["details"].get(detail)
    if v is None:
        return "n/a"
    mark = "!" if detail is None and m["passed"] is False else ""
    return f"{v:.3g}{mark}"


def print_table(rows: list[dict]) -> None:
    head = f"{'clip':26s} {'frames':>6s} " + " ".join(f"{h:>9s}" for *_, h in COLUMNS)
    print(head)
    print("-" * len(head))
    for row in rows:
        cells = " ".join(f"{_cell(row, m, d):>9s}" for m, d, _ in COLUMNS)
        print(f"{row['clip']:26s} {row['frames']:6d} {cells}")
    print("-" * len(head))
    if rows:
        thr = " ".join(f"{(rows[0]['metrics'][m]['threshold'] if d is None else ''):>9}"
                       for m, d, _ in COLUMNS)
        print(f"{'threshold':26s} {'':6s} {thr}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--frames", type=int, default=None,
                        help="score at most the first N frames of each clip")
    parser.add_argument("--out", type=Path, default=REPO / "out" / "calibrate_body.json")
    args = parser.parse_args()
    paths = single_person_clips(args.data)
    if not paths:
        raise SystemExit(f"no CMU clips under {args.data}/cmu")
    rows = []
    for path in paths:
        row = score_clip(load(path, args.frames))
        row["clip"] = f"{path.parent.name}/{path.name}"
        rows.append(row)
        print(f"  scored {row['clip']} ({row['frames']} frames, "
              f"{sum(row['seconds'].values()):.1f} s)", flush=True)
    print()
    print_table(rows)
    pairs = []
    for folder in sorted((args.data / "cmu" / "two_person").glob("*")):
        pair = simenv.load(folder)
        if args.frames:
            pair = Interaction(pair.actor.slice(0, min(args.frames, pair.actor.num_frames)),
                               pair.reactor.slice(0, min(args.frames, pair.reactor.num_frames)),
                               label=pair.label, name=pair.name)
        row = score_pair(pair)
        row["pair"] = folder.name
        pairs.append(row)
        m = row["metrics"]
        ip, ct = m["inter_penetration"], m["contact"]
        hands = ct["details"].get("min_mm_0", float("nan"))
        print(f"{folder.name:26s} {row['frames']:6d} inter_penetration "
              f"{ip['value']:.3g} mm{'' if ip['passed'] else '!'}  contact JPD "
              f"{ct['value']:.3g} mm  min hand-hand {hands:.0f} mm")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"thresholds": asdict(DEFAULT_BODY_THRESHOLDS),
                                    "clips": rows, "pairs": pairs}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

"""The room agent's decisions on real data, recorded to compare two versions of the code.

``record DIR`` writes what a change to the room's perception or agent must not alter:

* ``rehearse_<run>/``: scripted rehearsals (no video) of the bundled UTKinect session
  recipes, with the shipped ``gesture-tcn-ensemble`` and with the transformer
  ``gesture-classifier`` (whose forecast stage runs): ``log.jsonl`` and ``summary.json``;
* ``decisions_<classifier>.json``: :func:`simenv.perception.loop.loop_readings` of the
  labelled and idle clips of UTKinect subjects 2 and 4 and MSR Action3D subject 2, and
  :func:`~simenv.perception.loop.choose_threshold`'s :func:`~simenv.perception.loop.
  loop_decisions` on them at every grid threshold, for both classifiers;
* ``protocol.json``: :func:`simenv.perception.protocol.loop_outcomes` (5 thresholds),
  :func:`~simenv.perception.protocol.choose_threshold` and
  :func:`~simenv.perception.protocol.cross_fitted_outcomes` on the stream readings of the
  same clips (``gesture-tcn``, without and with the shipped forecaster), with and without
  the forecast stage, under both window rules.

``compare BEFORE AFTER`` prints, per output, whether it is identical: ``log.jsonl`` byte for
byte, ``summary.json`` but for its wall times (``timing_s``, the mean and max of
``perception_compute_s``), the JSON files as values; exit status 1 when any differs.

One torch thread (the networks' sums in a fixed order). Needs the shared corpus and the
shipped models. About 4 min of one core::

    .venv/bin/python benchmarks/room_agent_equivalence.py record out/agent-before
    # ... change the code ...
    .venv/bin/python benchmarks/room_agent_equivalence.py record out/agent-after
    .venv/bin/python benchmarks/room_agent_equivalence.py compare out/agent-before out/agent-after
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

import simenv.models  # noqa: E402
from simenv.core.config import shared_data_root  # noqa: E402
from simenv.data.gestures import GESTURE_LABELS, load_gesture_clips, subject_fold  # noqa: E402
from simenv.envs.rehearsal import rehearse  # noqa: E402
from simenv.perception import loop as perception_loop  # noqa: E402
from simenv.perception import protocol  # noqa: E402
from simenv.perception.train_recogniser import LOOP_WINDOWS, shipped_forecaster  # noqa: E402
from simenv.room.scenario import load_scenario  # noqa: E402

#: Rehearsals: run name -> (session recipe, classifier; None: the room's default).
REHEARSALS = {"s02": ("utkinect-s02-e01-wave", None),
              "s10": ("utkinect-s10-e01-wave", None),
              "s02_transformer": ("utkinect-s02-e01-wave", "gesture-classifier"),
              "s04_transformer": ("utkinect-s04-e02-wave", "gesture-classifier"),
              "s10_transformer": ("utkinect-s10-e01-wave", "gesture-classifier")}
#: Subjects whose clips the loop readings and the protocol are run on.
SUBJECTS = ("utkinect/s02", "utkinect/s04", "msr_action3d/s02")
#: Temperatures of the cross-fitted folds (any fixed values: the comparison is of code).
FOLD_TEMPERATURES = (1.0, 1.2, 0.9, 1.1, 1.3)


def _dump(path: Path, obj: Any) -> None:
    path.write_text(json.dumps(obj, indent=1, default=lambda o: o.tolist()
                               if isinstance(o, np.ndarray) else str(o)))


def record(out: Path, data: Path) -> None:
    """Write the outputs of the module docstring to ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    vocabulary = load_scenario("default").behaviour.vocabulary
    for run, (recipe, name) in REHEARSALS.items():
        classifier = None if name is None else perception_loop.TrainedClassifier.shipped(
            name, vocabulary)
        rehearse(recipe, out / f"rehearse_{run}", agent="scripted", classifier=classifier,
                 render=False, data=data)
        print(f"rehearsed {run}", flush=True)
    clips = [c for c in load_gesture_clips(data / "gestures",
                                           datasets=("utkinect", "msr_action3d"), idle=True)
             if c.subject_key in SUBJECTS]
    for name in ("gesture-tcn-ensemble", "gesture-classifier"):
        classifier = perception_loop.TrainedClassifier.shipped(name)
        readings, skipped = perception_loop.loop_readings(clips, classifier,
                                                          perception_loop.load_predictor())
        best, rows = perception_loop.choose_threshold(readings, classifier.labels)
        _dump(out / f"decisions_{name}.json", {
            "best": best, "rows": rows, "skipped": skipped,
            "readings": [(r.name, r.label, r.subject, r.p_real, r.p_pred) for r in readings]})
        print(f"loop decisions of {name} on {len(readings)} clips", flush=True)
    avatars, skipped = protocol.avatar_clips(clips, progress=False)
    net = simenv.models.load("gesture-tcn")
    results = {}
    for tag, forecaster in (("none", None), ("forecast", shipped_forecaster())):
        readings = protocol.stream_readings(avatars, net, forecaster, seed=3,
                                            real_windows=LOOP_WINDOWS)
        for use in (False, True):
            for rule in perception_loop.WINDOW_RULES:
                key = f"{tag}|{use}|{rule}"  # forecaster|forecast stage used|window rule
                for t in (0.3, 0.5, 0.65, 0.8, 0.9):
                    results[f"{key}|{t}"] = protocol.loop_outcomes(
                        readings, GESTURE_LABELS, t, 1.3, use_forecast=use, window_rule=rule)
                results[f"{key}|choose"] = protocol.choose_threshold(
                    readings, GESTURE_LABELS, 1.3, use_forecast=use, window_rule=rule)
                results[f"{key}|cross"] = protocol.cross_fitted_outcomes(
                    readings, subject_fold, GESTURE_LABELS, FOLD_TEMPERATURES,
                    use_forecast=use, window_rule=rule)
    _dump(out / "protocol.json", {"skipped": skipped, "results": results})
    print(f"protocol: {len(results)} results on {len(avatars)} avatar clips", flush=True)


def _without_wall_times(summary: dict[str, Any]) -> dict[str, Any]:
    summary.pop("timing_s", None)
    for key in ("mean", "max"):
        summary["perception_compute_s"].pop(key, None)
    return summary


def compare(before: Path, after: Path) -> int:
    """Print what is identical between two records; the number of outputs that differ."""
    differ = 0
    for run in sorted(before.glob("rehearse_*")):
        logs = [(d / run.name / "log.jsonl").read_bytes() for d in (before, after)]
        a, b = (_without_wall_times(json.loads((d / run.name / "summary.json").read_text()))
                for d in (before, after))
        same = logs[0] == logs[1] and a == b
        differ += not same
        decisions = [(d["reaction"], d["t_decision"], d.get("stage")) for d in a["decisions"]]
        print(f"{run.name}: log.jsonl {'identical' if logs[0] == logs[1] else 'DIFFERS'} "
              f"({logs[0].count(10)} lines), summary.json "
              f"{'identical' if a == b else 'DIFFERS'} (decisions {decisions}, "
              f"{a['perception_compute_s']['n']} ticks)")
    for path in sorted(before.glob("*.json")):
        same = json.loads(path.read_text()) == json.loads((after / path.name).read_text())
        differ += not same
        print(f"{path.name}: {'identical' if same else 'DIFFERS'}")
    print("all identical" if not differ else f"{differ} output(s) differ")
    return differ


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("record")
    p.add_argument("out", type=Path)
    p.add_argument("--data", type=Path, default=None, help="shared data folder")
    p = sub.add_parser("compare")
    p.add_argument("before", type=Path)
    p.add_argument("after", type=Path)
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.command == "record":
        record(args.out, shared_data_root(args.data))
        return 0
    return int(compare(args.before, args.after) > 0)


if __name__ == "__main__":
    raise SystemExit(main())

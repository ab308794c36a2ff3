"""Cost of one perception tick, the room's recogniser against the previous stack.

A tick of :class:`simenv.perception.loop.PerceptionLoop` on real keypoints (the bundled CMU
walk retargeted into the room, as the rehearsal gives them): the real stage alone, and the
real + forecast stage (forced by a threshold of 1.1, so both stages always run). Stacks:

* ``gesture-tcn`` + ``predictor-gesture-25-50`` (the room's now),
* ``gesture-classifier`` (transformer) + ``predictor-25-50`` (PredictiveMA-WGAN): the
  reference it replaces.

One torch thread (a 90 Hz frame is 11 ms of one core); the median over ``--ticks`` ticks
and the ratio reference / room are printed, and ``--json`` writes them.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

import simenv  # noqa: E402
import simenv.models  # noqa: E402
from simenv.assets import WALK, asset_path  # noqa: E402
from simenv.perception.loop import PerceptionLoop, TrainedClassifier, load_predictor  # noqa: E402
from simenv.room.scenario import load_scenario  # noqa: E402
from simenv.room.session import Session, user_track  # noqa: E402

STACKS = {"room": ("gesture-tcn", "predictor-gesture-25-50"),
          "reference": ("gesture-classifier", "predictor-25-50")}


def tick_ms(classifier: str, predictor: str, keypoints: np.ndarray, ticks: int
            ) -> dict[str, float]:
    """Median ms of a tick with the real stage only and with both stages."""
    behaviour = load_scenario("default").behaviour
    clf, ahead = TrainedClassifier.shipped(classifier), load_predictor(predictor)
    need = max(25, ahead.history_len)
    out = {}
    for name, threshold in (("real_stage_ms", 0.0), ("both_stages_ms", 1.1)):
        loop = PerceptionLoop(behaviour, clf, ahead, threshold=threshold, use_forecast=True)
        times = []
        for k in range(ticks):
            end = need + k % (len(keypoints) - need)
            start = time.perf_counter()
            loop.perceive(end / 25.0, keypoints[end - need:end])
            times.append(time.perf_counter() - start)
        out[name] = round(1000 * float(np.median(times[5:])), 2)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=200)
    parser.add_argument("--json", help="write the results here")
    args = parser.parse_args()
    torch.set_num_threads(1)
    kp = user_track(Session(simenv.load(asset_path(WALK)))).keypoints.astype(np.float32)
    results = {}
    for stack, (classifier, predictor) in STACKS.items():
        if not {classifier, predictor} <= set(simenv.models.available()):
            print(f"{stack}: {classifier} / {predictor} not shipped; skipped")
            continue
        results[stack] = {"classifier": classifier, "predictor": predictor,
                          **tick_ms(classifier, predictor, kp, args.ticks)}
        print(f"{stack:>9} ({classifier} + {predictor}): real stage "
              f"{results[stack]['real_stage_ms']} ms, both stages "
              f"{results[stack]['both_stages_ms']} ms a tick")
    if len(results) == 2:
        for key in ("real_stage_ms", "both_stages_ms"):
            ratio = results["reference"][key] / results["room"][key]
            results[f"ratio_{key}"] = round(ratio, 2)
            print(f"reference / room, {key}: {ratio:.2f}x")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

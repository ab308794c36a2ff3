"""Speed of the shipped prediction and recognition models on one CPU thread.

For every shipped predictor (``predictor-<P>-<F>``) and the gesture classifier: calls per
second for single samples (the room's loop: one history every second) and samples per
second in batches of 64. Inputs are real: histories from the bundled CMU walk (02_01),
gesture windows from the same clip (played forwards then backwards, for 3-s windows)
on the classifier's joints. The goal is
>= 100 single-sample predictions/s, far inside a 25 fps loop.

Usage::

    .venv/bin/python benchmarks/bench_models.py [--seconds S] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from importlib import resources
from pathlib import Path

import numpy as np
import torch

from simenv.data import prediction_data as pdata
from simenv.data.gestures import to_gesture_joints
from simenv.io import bvh
from simenv.models import INTERACTION_MODELS, available, load


def rate(fn: Callable[[], object], seconds: float) -> float:
    """Calls per CPU second of ``fn`` (after one warm-up call), over about ``seconds``."""
    fn()
    calls, start = 0, time.process_time()
    while time.process_time() - start < seconds:
        fn()
        calls += 1
    return calls / (time.process_time() - start)


def measure(seconds: float = 3.0, *, verbose: bool = False) -> dict[str, dict[str, float]]:
    """Single-sample and batched rates of every shipped model on one thread, each over
    about ``seconds`` CPU seconds; ``verbose`` prints each model's result."""
    torch.set_num_threads(1)
    walk = bvh.read(Path(str(resources.files("simenv.assets"))) / "cmu_02_01_walk.bvh")
    results: dict[str, dict[str, float]] = {}
    gesture_frames = to_gesture_joints(walk.resample(25.0), "gesture15")
    # The two-person generators (INTERACTION_MODELS) are benchmarked apart: they take other inputs.
    for name in (n for n in available() if n not in INTERACTION_MODELS):
        model = load(name)
        if name.startswith("predictor-gesture-"):
            # world-frame gesture15 histories, not the pred17 layout
            h = model.history_len
            batch = np.stack([gesture_frames[i:i + h]
                              for i in range(len(gesture_frames) - h)][:64])
            single = batch[0]
            unit = "predictions"
            one, many = (lambda m=model, x=single: m.predict(x)), \
                (lambda m=model, x=batch: m.predict_batch(x))
        elif name.startswith("predictor-"):
            w = pdata.windows_from_motions([walk], model.past_len, 1, stride=1)
            batch = w.frames[:64, : model.history_len]
            single = batch[0]
            unit = "predictions"
            one, many = (lambda m=model, x=single: m.predict(x)), \
                (lambda m=model, x=batch: m.predict(x))
        else:
            frames = to_gesture_joints(walk.resample(model.config.fps),
                                       model.config.extra.get("joint_set", "gesture15"))
            # the 2.9-s walk played forwards then backwards: long enough for 3-s windows
            frames = np.concatenate([frames, frames[::-1]])
            t = getattr(model.config, "window", 75)  # the TCN takes any length: 3 s
            batch = np.stack([frames[i:i + t] for i in range(0, len(frames) - t, 1)][:64])
            unit = "classifications"
            one, many = (lambda m=model, x=batch[0]: m.classify_world(x)), \
                (lambda m=model, x=batch: m.classify_world(x))
        results[name] = {f"single_{unit}_per_s": round(rate(one, seconds), 1),
                         f"batched_{unit}_per_s": round(len(batch) * rate(many, seconds),
                                                        1),
                         "batch": len(batch)}
        if verbose:
            print(name, results[name])
    return results


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0, help="CPU seconds per measurement")
    ap.add_argument("--json", help="also write the results to this JSON file")
    args = ap.parse_args()
    results = measure(args.seconds, verbose=True)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()

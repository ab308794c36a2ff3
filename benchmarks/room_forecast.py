"""The gesture forecaster in the room, on people it never saw: told or not told where the
recording's sensor stands.

Every UTKinect session of the shared corpus is put into the room the way a rehearsal puts
its user there (:func:`simenv.room.session.user_track`: retargeted at 25 fps onto a fitted
body, placed where the scenario puts the user, the sensor placed with it as
``UserTrack.observer``). On the avatar's canonical keypoints, every 75-frame window
(stride 5) is forecast from its first 25 frames by the fold forecaster that never saw the
session's subject (``out/gesture-predictor/fold{K}/model.npz``, ``python -m
simenv.learning.train_gesture_predictor --fold K``), run as the room runs it
(:class:`simenv.perception.loop.CanonicalPredictor`), told the placed sensor and not told;
zero velocity beside them. MPJPE over the forecaster's 15 joints, mm, pooled over windows.

Usage::

    .venv/bin/python benchmarks/room_forecast.py [--folds out/gesture-predictor] [--json F]
        [--doc docs/room.md]    # rewrites its section there
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import torch
from doc_sections import replace_section
from tqdm import tqdm

from simenv.core.config import shared_data_root
from simenv.core.skeletons import CANONICAL_KEYPOINTS
from simenv.data.gestures import GESTURE15_JOINTS, subject_fold
from simenv.data.prediction_metrics import per_frame_mpjpe_mm
from simenv.models.gesture_predictor import GesturePredictor
from simenv.perception.loop import CanonicalPredictor, forecast
from simenv.room.session import Session, user_track

HISTORY, FUTURE, STRIDE = 25, 50, 5
BEGIN = "<!-- room-forecast:begin (benchmarks/room_forecast.py) -->"
END = "<!-- room-forecast:end -->"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folds", type=Path, default=Path("out/gesture-predictor"))
    parser.add_argument("--data", type=Path, default=None, help="shared data folder")
    parser.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    parser.add_argument("--doc", type=Path, default=None,
                        help="rewrite the section between its markers in this file")
    args = parser.parse_args()
    torch.set_num_threads(1)
    sessions = sorted((shared_data_root(args.data) / "gestures" / "utkinect" / "joints")
                      .glob("joints_s*_e*.txt"))
    missing = [k for k in range(5) if not (args.folds / f"fold{k}" / "model.npz").is_file()]
    if missing:
        raise SystemExit(f"no fold forecaster {args.folds}/fold{{{','.join(map(str, missing))}}}"
                         "/model.npz: train them with `python -m "
                         "simenv.learning.train_gesture_predictor --fold K` (K = 0..4)")
    joints = [CANONICAL_KEYPOINTS.index(j) for j in GESTURE15_JOINTS]
    curves: dict[str, list[np.ndarray]] = {"told": [], "not told": [], "zero velocity": []}
    for path in tqdm(sessions, desc="sessions"):
        subject = int(path.stem.split("_")[1][1:])
        fold = subject_fold(f"utkinect/s{subject:02d}")
        model = GesturePredictor.load(args.folds / f"fold{fold}" / "model.npz")
        predictor = CanonicalPredictor(model, joints=GESTURE15_JOINTS, root_relative=False)
        track = user_track(Session.load(path))
        kp = track.keypoints.astype(np.float32)
        for s in range(0, len(kp) - HISTORY - FUTURE + 1, STRIDE):
            history, future = kp[s:s + HISTORY], kp[s + HISTORY:s + HISTORY + FUTURE][:, joints]
            for name, pred in (
                    ("told", forecast(predictor, history, track.observer)),
                    ("not told", forecast(predictor, history)),
                    ("zero velocity", np.repeat(history[-1:], FUTURE, axis=0))):
                curves[name].append(per_frame_mpjpe_mm(pred[None, :, joints].astype(np.float64),
                                                       future[None].astype(np.float64)))
    zv = np.mean(curves["zero velocity"], axis=0)
    result = {"windows": len(curves["told"]), "sessions": len(sessions)}
    lines = [f"{result['windows']} windows (75 frames, stride {STRIDE}) of the "
             f"{len(sessions)} UTKinect sessions retargeted into the room (`user_track`), "
             "each forecast by the fold model that never saw its subject, on the avatar's "
             "keypoints; MPJPE over the forecaster's 15 joints.", "",
             "| forecast | MPJPE 1 s / 2 s, mm | vs zero velocity 1 s / 2 s |", "|---|---|---|"]
    for name, c in curves.items():
        m = np.mean(c, axis=0)
        result[name] = {"mpjpe_1s_mm": float(m[HISTORY - 1]), "mpjpe_2s_mm": float(m[-1])}
        lines.append(f"| {name} | {m[HISTORY - 1]:.0f} / {m[-1]:.0f} | "
                     f"{100 * (1 - m[HISTORY - 1] / zv[HISTORY - 1]):+.1f} % / "
                     f"{100 * (1 - m[-1] / zv[-1]):+.1f} % |")
    print("\n".join(lines))
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    if args.doc:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True).stdout.strip() or "unknown"
        header = (f"Generated by `python benchmarks/room_forecast.py {' '.join(sys.argv[1:])}` "
                  f"at commit `{commit}`, {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC; "
                  "do not edit by hand.")
        replace_section(args.doc, BEGIN, END, "\n".join([header, "", *lines]))
        print(f"wrote its section of {args.doc}")


if __name__ == "__main__":
    main()

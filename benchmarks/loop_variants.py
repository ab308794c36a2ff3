"""Recogniser variants through the room's perception loop, on subjects they never saw.

The loop's protocol of :mod:`simenv.perception.train_recogniser` (step 2) for any recogniser
variant, one fold at a time so that runs resume and stay within one CPU:

``train --tag NAME [--seed S] [--set key=value ...]``: per fold k of the leave-subjects-out
split (:func:`simenv.data.gestures.split_subject_folds`), a network trained on the other folds'
clips (with the fold's forecaster ``--forecasters DIR/fold<k>/model.npz`` when given, as the
shipped protocol), saved as ``OUT/NAME_s<S>/fold<k>.npz`` with its held-out readings
``fold<k>_readings.npz``: raw logits of the fold's clips in ``real_3s`` / ``real_1s`` (for
the temperature) and the loop's stream readings of its avatar clips
(:func:`simenv.perception.protocol.stream_readings`, windows
:data:`simenv.perception.train_recogniser.LOOP_WINDOWS`, phase seed k).

``import --tag NAME --folds-dir DIR``: the same readings of existing fold checkpoints
``DIR/fold<k>.npz`` (e.g. the shipped ``out/gesture-tcn/folds``).

``score MEMBER [MEMBER ...]``: the loop of an ensemble (logits averaged over members,
``NAME_s<S>`` folders), with the protocol's cross-fitting: fold k's temperature is fitted
on the other folds' held-out ``real_3s`` + ``real_1s`` logits and its threshold chosen on
the other folds' loop readings (:func:`simenv.perception.protocol.cross_fitted_outcomes`,
last 1 / 2 / 3 s real, no forecast stage). Prints waves / other / idle greeted and the
decision time; ``--json`` appends the row to ``OUT/scores.jsonl``.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from simenv.core.config import shared_data_root  # noqa: E402
from simenv.data.gestures import (  # noqa: E402
    GESTURE_LABELS,
    SUBJECT_FOLDS,
    load_gesture_clips,
    split_subject_folds,
    subject_fold,
)
from simenv.learning.recognition import (  # noqa: E402
    RecognitionConfig,
    logits_of,
    train_recogniser,
)
from simenv.learning.recognition_protocols import condition_windows  # noqa: E402
from simenv.models.skeleton_tcn import SkeletonTCN, fit_temperature  # noqa: E402
from simenv.perception.protocol import (  # noqa: E402
    StreamReading,
    avatar_clips,
    cross_fitted_outcomes,
    stream_readings,
)
from simenv.perception.train_recogniser import LOOP_WINDOWS, fold_forecasters  # noqa: E402

#: The gesture corpus the folds are cut from.
GESTURES = shared_data_root(None) / "gestures"


def _avatars(path: Path, clips: list[Any]) -> list[Any]:
    """The loop's avatar clips (cached in ``path``; Florence has none)."""
    if path.is_file():
        av = pickle.load(path.open("rb"))
        return av[0] if isinstance(av, tuple) else av
    av, _ = avatar_clips([c for c in clips if c.dataset != "florence3d"])
    path.parent.mkdir(parents=True, exist_ok=True)
    pickle.dump(av, path.open("wb"))
    return av


def _readings(model: SkeletonTCN, test: list[Any], avatars: list[Any], k: int
              ) -> dict[str, np.ndarray]:
    """Held-out logits of fold ``k`` (module docstring) as arrays."""
    conds = condition_windows(test, None)
    held = [c for c in avatars if subject_fold(c.subject_key) == k]
    rd = stream_readings(held, model, None, seed=k, real_windows=LOOP_WINDOWS)
    return {"z3": logits_of(model, *conds["real_3s"]), "z1": logits_of(model, *conds["real_1s"]),
            "y": np.array([GESTURE_LABELS.index(c.label) for c in test]),
            "names": np.array([r.name for r in rd]),
            "meta": np.array([[r.label, r.subject, r.dataset] for r in rd]),
            "duration": np.array([r.duration_s for r in rd]),
            "ticks": np.concatenate([r.ticks_s for r in rd]),
            "logits": np.concatenate([r.logits_real for r in rd]),
            "counts": np.array([len(r.ticks_s) for r in rd])}


def _parse_sets(pairs: list[str]) -> dict[str, Any]:
    kinds = {f.name: f.type for f in fields(RecognitionConfig)}
    out: dict[str, Any] = {}
    for pair in pairs:
        key, value = pair.split("=", 1)
        if key not in kinds:
            raise SystemExit(f"unknown option {key}")
        out[key] = json.loads(value)
    return out


def cmd_train(args: argparse.Namespace) -> None:
    clips = load_gesture_clips(GESTURES, idle=True)
    avatars = _avatars(Path(args.avatars), clips)
    config = RecognitionConfig(seed=args.seed, **_parse_sets(args.set))
    forecasters = fold_forecasters(Path(args.forecasters) if args.forecasters else None,
                                   SUBJECT_FOLDS)
    folder = Path(args.out) / f"{args.tag}_s{args.seed}"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "config.json").write_text(json.dumps(config.__dict__, indent=1))
    for k, (train, test) in enumerate(split_subject_folds(clips)):
        if args.folds and k not in args.folds or (folder / f"fold{k}_readings.npz").is_file():
            continue
        forecast = forecasters[k] if forecasters else None
        model, history = train_recogniser(
            train, list(GESTURE_LABELS), lambda c: c.label,
            config if forecast is not None else replace(config, forecast_prob=0.0),
            forecast=forecast, extra={"protocol": f"fold {k}", "variant": args.tag})
        model.save(folder / f"fold{k}.npz")
        np.savez(folder / f"fold{k}_readings.npz", **_readings(model, test, avatars, k))
        print(f"fold {k}: {history['train_cpu_s']} CPU s", flush=True)


def cmd_import(args: argparse.Namespace) -> None:
    clips = load_gesture_clips(GESTURES, idle=True)
    avatars = _avatars(Path(args.avatars), clips)
    folder = Path(args.out) / f"{args.tag}_s{args.seed}"
    folder.mkdir(parents=True, exist_ok=True)
    for k, (_, test) in enumerate(split_subject_folds(clips)):
        model = SkeletonTCN.load(Path(args.folds_dir) / f"fold{k}.npz")
        np.savez(folder / f"fold{k}_readings.npz", **_readings(model, test, avatars, k))


def score(members: list[Path]) -> dict[str, Any]:
    """Cross-fitted loop outcomes of the ensemble ``members`` (module docstring)."""
    folds = [[np.load(m / f"fold{k}_readings.npz") for m in members]
             for k in range(SUBJECT_FOLDS)]
    mean = [{key: np.mean([d[key] for d in ds], axis=0) for key in ("z3", "z1", "logits")}
            for ds in folds]
    temps = []
    for k in range(SUBJECT_FOLDS):
        others = [j for j in range(SUBJECT_FOLDS) if j != k]
        z = np.concatenate([mean[j][key] for j in others for key in ("z3", "z1")])
        y = np.concatenate([folds[j][0]["y"] for j in others for _ in ("z3", "z1")])
        temps.append(fit_temperature(z, y))
    readings = []
    for k, ds in enumerate(folds):
        d = ds[0]
        bounds = np.concatenate([[0], np.cumsum(d["counts"])])
        for i, name in enumerate(d["names"]):
            label, subject, dataset = d["meta"][i]
            a, b = bounds[i], bounds[i + 1]
            readings.append(StreamReading(str(name), str(label), str(subject), str(dataset),
                                          float(d["duration"][i]), d["ticks"][a:b],
                                          mean[k]["logits"][a:b],
                                          np.full((b - a, len(GESTURE_LABELS)), np.nan)))
    out = cross_fitted_outcomes(readings, subject_fold, GESTURE_LABELS, temps,
                                use_forecast=False)
    out["temperatures"] = [round(t, 4) for t in temps]
    return out


def cmd_score(args: argparse.Namespace) -> None:
    r = score([Path(args.out) / m for m in args.members])
    greeted = "  ".join(f"{name} {k}/{n} ({k / n:.1%})" for name, (k, n) in
                        zip(("waves", "other", "idle"), (r["greet_clips"], r["other_clips"],
                                                         r["idle_clips"]), strict=True))
    d = r["decision_after_onset_s"]
    print(f"{'+'.join(args.members)}: {greeted}  decision median {d['median']} s, p90 "
          f"{d['p90']} s  thresholds {[f['threshold'] for f in r['folds']]}  temperatures "
          f"{r['temperatures']}")
    if args.json:
        with (Path(args.out) / "scores.jsonl").open("a") as fh:
            fh.write(json.dumps({"members": args.members, **r}) + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/exp14-loop")
    parser.add_argument("--avatars", default="out/exp14-loop/avatar_clips.pkl",
                        help="cache of the loop's avatar clips (made when missing)")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("train")
    p.add_argument("--tag", required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--set", nargs="*", default=[], help="RecognitionConfig key=JSON value")
    p.add_argument("--forecasters", help="folder of per-fold gesture predictors")
    p.add_argument("--folds", type=int, nargs="*")
    p = sub.add_parser("import")
    p.add_argument("--tag", required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--folds-dir", required=True)
    p = sub.add_parser("score")
    p.add_argument("members", nargs="+", help="NAME_s<S> folders under --out")
    p.add_argument("--json", action="store_true")
    args = parser.parse_args()
    {"train": cmd_train, "import": cmd_import, "score": cmd_score}[args.command](args)


if __name__ == "__main__":
    main()

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
last 1 / 2 / 3 s real, no forecast stage), the windows' probabilities combined by
``--window-rule`` (:func:`simenv.perception.loop.real_stage`: ``max``, the most confident
window, or ``mean``), each tick decided by :func:`simenv.perception.loop.decide` (the rule
the room's agent, :class:`simenv.perception.room_agent.RoomAgent`, decides by). Prints
waves / other / idle greeted and the decision time; ``--json`` appends the row to
``OUT/scores.jsonl``.

``ship MEMBER [MEMBER ...] [--name N] [--ship-dir DIR]``: the ensemble as the room ships
it: each member variant trained once more on every subject (its ``config.json``, the shipped
forecaster; ``DIR/<member>.npz``, kept across runs), the temperature fitted on all the
members' out-of-fold mean logits, the loop threshold chosen on all out-of-fold loop readings
(:func:`simenv.perception.protocol.choose_threshold`, as ``train_recogniser train`` does
for one network) under ``--window-rule``, which the checkpoint records
(``loop_window_rule``: the room's loop combines its windows so), written as ``DIR/N.npz``
(:class:`simenv.models.skeleton_tcn.SkeletonTCNEnsemble`) with its card ``DIR/N.md`` (the
unseen-subject numbers of ``score``; ``--previous CHECKPOINT``: the ensemble it replaces,
its figures beside them; whether the fold networks had per-fold forecasters, from
``NAME_s<S>/forecasters.json``, which ``train`` writes). Copy both into ``assets/models``
to ship.
"""

from __future__ import annotations

import argparse
import json
import os
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
from simenv.learning.recognition_protocols import (  # noqa: E402
    calibrated,
    classification_scores,
    condition_windows,
)
from simenv.models.skeleton_tcn import (  # noqa: E402
    CANONICAL_BODY,
    SkeletonTCN,
    SkeletonTCNEnsemble,
    fit_temperature,
)
from simenv.perception.loop import WINDOW_RULES  # noqa: E402
from simenv.perception.protocol import (  # noqa: E402
    StreamReading,
    avatar_clips,
    choose_threshold,
    cross_fitted_outcomes,
    stream_readings,
)
from simenv.perception.train_recogniser import (  # noqa: E402
    LOOP_WINDOWS,
    fold_forecasters,
    shipped_forecaster,
)

#: The gesture corpus the folds are cut from.
GESTURES = shared_data_root(None) / "gestures"


def _avatars(clips: list[Any]) -> list[Any]:
    """The loop's avatar clips (Florence has none; kept on disk by
    :func:`simenv.perception.protocol.avatar_clips`)."""
    return avatar_clips([c for c in clips if c.dataset != "florence3d"])[0]


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
    avatars = _avatars(clips)
    sets = _parse_sets(args.set) | ({"epochs": args.epochs} if args.epochs else {})
    config = RecognitionConfig(seed=args.seed, **sets)
    forecasters = fold_forecasters(Path(args.forecasters) if args.forecasters else None,
                                   SUBJECT_FOLDS)
    folder = Path(args.out) / f"{args.tag}_s{args.seed}"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "config.json").write_text(json.dumps(config.__dict__, indent=1))
    # The fold networks' forecast windows (the card says whether they had them).
    (folder / "forecasters.json").write_text(json.dumps({"forecasters": args.forecasters}))
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
    avatars = _avatars(clips)
    folder = Path(args.out) / f"{args.tag}_s{args.seed}"
    folder.mkdir(parents=True, exist_ok=True)
    for k, (_, test) in enumerate(split_subject_folds(clips)):
        model = SkeletonTCN.load(Path(args.folds_dir) / f"fold{k}.npz")
        np.savez(folder / f"fold{k}_readings.npz", **_readings(model, test, avatars, k))


def _ensemble_readings(members: list[Path]) -> tuple[list[Any], list[dict[str, np.ndarray]]]:
    """Every fold's held-out readings of the ensemble ``members``: the members' logits
    averaged (one :class:`StreamReading` per avatar clip, and per fold the arrays
    ``z3``, ``z1``, ``logits``, ``y``)."""
    folds = [[np.load(m / f"fold{k}_readings.npz") for m in members]
             for k in range(SUBJECT_FOLDS)]
    mean = [{key: np.mean([d[key] for d in ds], axis=0) for key in ("z3", "z1", "logits")}
            | {"y": ds[0]["y"]} for ds in folds]
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
    return readings, mean


def _temperature(mean: list[dict[str, np.ndarray]], folds: list[int]) -> float:
    """τ of the mean logits fitted on the ``real_3s`` + ``real_1s`` logits of ``folds``."""
    z = np.concatenate([mean[j][key] for j in folds for key in ("z3", "z1")])
    y = np.concatenate([mean[j]["y"] for j in folds for _ in ("z3", "z1")])
    return fit_temperature(z, y)


def score(members: list[Path], window_rule: str = "max") -> dict[str, Any]:
    """Cross-fitted loop outcomes of the ensemble ``members`` (module docstring)."""
    return _cross_fitted(*_ensemble_readings(members), window_rule)


def _cross_fitted(readings: list[Any], mean: list[dict[str, np.ndarray]],
                  window_rule: str) -> dict[str, Any]:
    """:func:`score` of readings already read."""
    temps = [_temperature(mean, [j for j in range(SUBJECT_FOLDS) if j != k])
             for k in range(SUBJECT_FOLDS)]
    out = cross_fitted_outcomes(readings, subject_fold, GESTURE_LABELS, temps,
                                use_forecast=False, window_rule=window_rule)
    out["temperatures"] = [round(t, 4) for t in temps]
    return out


def cmd_score(args: argparse.Namespace) -> None:
    r = score([Path(args.out) / m for m in args.members], args.window_rule)
    greeted = "  ".join(f"{name} {k}/{n} ({k / n:.1%})" for name, (k, n) in
                        zip(("waves", "other", "idle"), (r["greet_clips"], r["other_clips"],
                                                         r["idle_clips"]), strict=True))
    d = r["decision_after_onset_s"]
    print(f"{'+'.join(args.members)} ({args.window_rule}): {greeted}  decision median "
          f"{d['median']} s, p90 {d['p90']} s  thresholds "
          f"{[f['threshold'] for f in r['folds']]}  temperatures {r['temperatures']}")
    if args.json:
        with (Path(args.out) / "scores.jsonl").open("a") as fh:
            fh.write(json.dumps({"members": args.members, **r}) + "\n")


def train_members(members: list[Path], out: Path) -> list[Path]:
    """Each member variant (``NAME_s<S>`` folder: its ``config.json``) trained once more on
    every subject of the corpus with the shipped forecaster, as the shipped recogniser is
    (:func:`simenv.perception.train_recogniser.run_train`, step 3); saved as
    ``out/<NAME_s<S>>.npz`` and skipped when already there (runs resume)."""
    clips = load_gesture_clips(GESTURES, idle=True)
    forecast = shipped_forecaster()
    paths = []
    for member in members:
        path = out / f"{member.name}.npz"
        paths.append(path)
        if path.is_file():
            continue
        config = RecognitionConfig(**json.loads((member / "config.json").read_text()))
        model, history = train_recogniser(
            clips, list(GESTURE_LABELS), lambda c: c.label,
            config if forecast is not None else replace(config, forecast_prob=0.0),
            forecast=forecast, extra={"joint_set": "gesture15", "variant": member.name,
                                      "trained_on": "every subject of the corpus"})
        model.save(path)
        print(f"{member.name}: {history['train_cpu_s']} CPU s on every subject", flush=True)
    return paths


def _greeted(loop: dict[str, Any]) -> str:
    """Waves, other actions and idle clips greeted by a loop's outcomes, as text."""
    return ", ".join(f"{what} {k}/{n} ({k / n:.1%})" for what, (k, n) in
                     zip(("waves", "other actions", "idle"),
                         (loop["greet_clips"], loop["other_clips"], loop["idle_clips"]),
                         strict=True))


def _previous(metadata: dict[str, Any]) -> str:
    """The card's comparison with the ensemble this one replaces (its checkpoint's
    metadata under ``previous``), or ""."""
    old = metadata.get("previous")
    if not old:
        return ""
    acc, loop = old["protocol_accuracy"], old["unseen_subject_loop"]
    read = "canonical-body" if old["canonical_body"] else "normalised, not canonical-body,"
    return f"""
Replaces `{old['file']}` ({read} input), whose fold networks gave, on the same folds: real_3s
{acc['real_3s']['accuracy']:.3f}, real_1s {acc['real_1s']['accuracy']:.3f}; the loop
{_greeted(loop)}; decision median {loop['decision_after_onset_s']['median']} s.
"""


def ensemble_card(name: str, metadata: dict[str, Any]) -> str:
    """The shipped ensemble's model card (markdown)."""
    r, acc = metadata["unseen_subject_loop"], metadata["protocol_accuracy"]
    greeted = _greeted(r)
    d = r["decision_after_onset_s"]
    reads = ("the canonical body (`simenv.data.sensor_invariance.canonical_body`: trunk "
             "joints redefined from the shoulders and hips, every bone at a reference "
             "length), marked in the members' config so every caller feeds it so"
             if metadata["config"].get("canonical_body", False) else
             "normalised windows (`simenv.data.gestures.normalise_windows`)")
    folds_forecast = ("with \"1 s real + forecast\" windows from per-fold forecasters"
                      if metadata.get("fold_forecasters") else "without forecast windows "
                      "(no per-fold forecaster given)")
    return f"""# {name}

The room's gesture recogniser: {len(metadata['members'])} skeleton TCNs
(`simenv.models.skeleton_tcn.SkeletonTCN`, the `gesture-tcn` architecture) run as one fused
network (`SkeletonTCNEnsemble`: probabilities `softmax(mean_m z_m / τ)`), on the 15 gesture
joints at 25 fps and the room's vocabulary ({', '.join(GESTURE_LABELS)}). Members
{', '.join(metadata['members'])}: trained with loop-tick windows (`stream_prob`
{metadata['config']['stream_prob']}), seeds {metadata['seeds']}, on every subject of the
gesture corpus with "1 s real + forecast" windows from `predictor-gesture-25-50`, by
`python benchmarks/loop_variants.py ship {' '.join(metadata['members'])} --window-rule
{metadata['loop_window_rule']}`.
Input: {reads}.
Temperature {metadata['temperature']:.3f} (fitted on the members' out-of-fold mean logits);
loop threshold {metadata['loop_threshold']} (chosen on every out-of-fold loop reading: greetings
on at most 2 % of non-wave clips); real windows {metadata['loop_windows']} frames, their
probabilities combined by the `{metadata['loop_window_rule']}` rule
(`simenv.perception.loop.real_stage`), no forecast stage.

## On subjects it never saw

Leave-subjects-out, {SUBJECT_FOLDS} folds, with the fold networks of the same variants
(trained {folds_forecast}).
Accuracy on the room vocabulary: real_3s {acc['real_3s']['accuracy']:.3f} (balanced
{acc['real_3s']['balanced_accuracy']:.3f}), real_1s {acc['real_1s']['accuracy']:.3f}
(balanced {acc['real_1s']['balanced_accuracy']:.3f}).

The loop (cross-fitted temperature and threshold): {greeted}; decision after the labelled
onset median {d['median']} s, p90 {d['p90']} s; {r['decided_before_end']:.1%} of the greeted
waves decided before the wave ends.

{_previous(metadata)}
Training options: `{json.dumps(metadata['config'])}`.
"""


def cmd_ship(args: argparse.Namespace) -> None:
    """Train the members on every subject and write the shipped ensemble (main's help)."""
    members = [Path(args.out) / m for m in args.members]
    ship = Path(args.ship_dir)
    nets = [SkeletonTCN.load(p) for p in train_members(members, ship)]
    readings, mean = _ensemble_readings(members)
    temperature = _temperature(mean, list(range(SUBJECT_FOLDS)))
    threshold = choose_threshold(readings, GESTURE_LABELS, temperature, use_forecast=False,
                                 window_rule=args.window_rule)
    y = np.concatenate([m["y"] for m in mean])
    accuracy = {cond: classification_scores(y, np.concatenate(
        [m[key] for m in mean]).argmax(1), GESTURE_LABELS)
        for cond, key in (("real_3s", "z3"), ("real_1s", "z1"))}
    loop = _cross_fitted(readings, mean, args.window_rule)
    configs = [json.loads((m / "config.json").read_text()) for m in members]
    provenance = [m / "forecasters.json" for m in members]
    fold_forecasters = all(p.is_file() and json.loads(p.read_text())["forecasters"]
                           for p in provenance)
    metadata = {"loop_threshold": threshold, "loop_uses_forecast": False,
                "loop_windows": list(LOOP_WINDOWS), "loop_window_rule": args.window_rule,
                "temperature": temperature,
                "members": [m.name for m in members], "seeds": [c["seed"] for c in configs],
                "fold_forecasters": fold_forecasters,
                "config": configs[0],
                "protocol_accuracy": {c: {k: a[k] for k in ("accuracy", "balanced_accuracy")}
                                      for c, a in accuracy.items()},
                "unseen_subject_loop": {k: loop[k] for k in (
                    "greet_clips", "other_clips", "idle_clips", "decision_after_onset_s",
                    "decided_before_end")}}
    if args.previous:
        old = SkeletonTCNEnsemble.load(args.previous)
        metadata["previous"] = {
            "file": Path(args.previous).name,
            "canonical_body": bool(old.members[0].config.extra.get(CANONICAL_BODY, False)),
            **{k: old.metadata[k] for k in ("protocol_accuracy", "unseen_subject_loop")}}
    ensemble = SkeletonTCNEnsemble([calibrated(n, temperature) for n in nets])
    ensemble.save(ship / f"{args.name}.npz", metadata)
    (ship / f"{args.name}.md").write_text(ensemble_card(args.name, metadata))
    print(f"{ship / args.name}.npz: temperature {temperature:.3f}, threshold {threshold}, "
          f"unseen-subject loop waves {loop['greet_clips']}, other {loop['other_clips']}, "
          f"idle {loop['idle_clips']}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/exp14-loop")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("train")
    p.add_argument("--tag", required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--set", nargs="*", default=[], help="RecognitionConfig key=JSON value")
    p.add_argument("--forecasters", help="folder of per-fold gesture predictors")
    p.add_argument("--folds", type=int, nargs="*")
    p.add_argument("--epochs", type=int, help="training epochs of each network (a quick run: "
                   "1; default --set's, else RecognitionConfig's); config.json records them, "
                   "so ship trains its members as long")
    p = sub.add_parser("import")
    p.add_argument("--tag", required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--folds-dir", required=True)
    p = sub.add_parser("score")
    p.add_argument("members", nargs="+", help="NAME_s<S> folders under --out")
    p.add_argument("--json", action="store_true")
    p.add_argument("--window-rule", choices=WINDOW_RULES, default="max",
                   help="how a tick's real windows make the real stage (real_stage)")
    p = sub.add_parser("ship", help="train the members on every subject; write the "
                       "ensemble checkpoint (temperature and loop threshold from the "
                       "members' out-of-fold readings) and its card to --ship-dir")
    p.add_argument("members", nargs="+", help="NAME_s<S> folders under --out")
    p.add_argument("--name", default="gesture-tcn-ensemble")
    p.add_argument("--ship-dir", default="out/gesture-tcn-ensemble")
    p.add_argument("--window-rule", choices=WINDOW_RULES, default="max",
                   help="the real-window rule the threshold is chosen with and the "
                   "checkpoint records")
    p.add_argument("--previous", help="the ensemble checkpoint this one replaces: its "
                   "unseen-subject figures go into the card beside the new ones")
    args = parser.parse_args()
    if args.command in ("score", "ship"):
        missing = _missing_members(Path(args.out), args.members)
        if missing:
            parser.exit(2, f"loop_variants {args.command}: error: {missing}\n")
    {"train": cmd_train, "import": cmd_import, "score": cmd_score,
     "ship": cmd_ship}[args.command](args)


def _missing_members(out: Path, members: list[str]) -> str:
    """What the members ``score`` and ``ship`` read and ``train`` writes is missing
    (their ``config.json`` and every fold's readings), as a message naming the
    command that makes it; "" when nothing is."""
    lines = []
    for name in members:
        folder = out / name
        need = [folder / "config.json"] + [folder / f"fold{k}_readings.npz"
                                           for k in range(SUBJECT_FOLDS)]
        absent = [p for p in need if not p.is_file()]
        if absent:
            tag, _, seed = name.rpartition("_s")
            lines.append(f"member {name!r}: {len(absent)} of {len(need)} files missing "
                         f"(first {absent[0]}); make it with python benchmarks/loop_variants.py "
                         f"--out {out} train --tag {tag or name} --seed {seed or 0} "
                         "[--set KEY=VALUE ...] [--forecasters DIR]")
    return "\n".join(lines)


if __name__ == "__main__":
    main()

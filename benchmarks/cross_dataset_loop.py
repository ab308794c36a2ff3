"""The room's loop on people of a dataset it never trained on (issue 34, goal 2).

``train [--datasets D ...]``: for each left-out dataset D of the cross-dataset corpus
(:func:`simenv.learning.cross_dataset.load_corpus`: the gesture corpus and, with
``--msrc12``, MSRC-12 without person p06; with ``--kindergator``, Kinder-Gator, which
trains every network and is never left out; with ``--mhad``, Berkeley MHAD, left out in
turn as the others), one network trained on every clip of the other
datasets with the shipped ensemble members' options (``--config``, default the
``stream_s0`` options of ``benchmarks/loop_variants.py``; ``forecast_prob`` 0: no
forecaster here was trained without D), saved as ``OUT/<D>.npz`` with its readings
``OUT/<D>_readings.pkl``: the raw logits of D's clips in ``real_3s`` / ``real_1s``
(centre-cropped, as the protocol) and the loop's stream readings of D's clips as the room's
agent sees them (:func:`simenv.perception.protocol.avatar_clips`, the loop's windows
:data:`simenv.perception.train_recogniser.LOOP_WINDOWS`, no forecast stage). Florence 3D
is not left out here: its clips (at most 1.75 s) are shorter than the loop's 3-s window.

``score [--window-rule R]``: the loop's outcomes on each left-out dataset
(:func:`simenv.perception.protocol.cross_fitted_outcomes`, the room's decision rule),
cross-fitted over datasets as the leave-subjects-out protocol is over folds: D's
temperature is fitted on the other left-out datasets' ``real_3s`` + ``real_1s`` logits
(each read by the network that never saw it) and D's threshold chosen on the other
datasets' loop readings, never on D's. Prints per dataset: waves greeted, other actions
greeted, idle greeted, decision time after the clip's start (the labelled onset);
``--json`` writes ``OUT/scores.json``.

``shipped CHECKPOINT [...]``: a shipped ensemble (temperature, threshold and window rule
from its checkpoint) on the MSRC-12 clips, which no shipped recogniser trained on:
accuracy in ``real_3s`` / ``real_1s`` and the loop's greetings.

``docs [--lso-scores FILE] [--before OUT2]``: the section of docs/recognition.md between
the markers, from ``OUT/scores.json``, ``OUT/shipped.json``, a
``benchmarks/loop_variants.py`` ``scores.jsonl`` (its member sets' leave-subjects-out loop)
and, with ``--before``, another run's ``scores.json`` beside this one's (what a change of
training sources did).
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import subprocess
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from simenv.core.config import shared_data_root  # noqa: E402
from simenv.data.gestures import GESTURE_LABELS, GestureClip  # noqa: E402
from simenv.learning.cross_dataset import KINDER_GATOR, load_corpus  # noqa: E402
from simenv.learning.recognition import (  # noqa: E402
    RecognitionConfig,
    logits_of,
    train_recogniser,
)
from simenv.learning.recognition_protocols import real_windows  # noqa: E402
from simenv.models.skeleton_tcn import (  # noqa: E402
    CANONICAL_BODY,
    SkeletonTCNEnsemble,
    fit_temperature,
)
from simenv.perception.protocol import (  # noqa: E402
    avatar_clips,
    choose_threshold,
    cross_fitted_outcomes,
    loop_outcomes,
    stream_readings,
)
from simenv.perception.train_recogniser import LOOP_WINDOWS  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "recognition.md"
BEGIN = "<!-- cross-dataset-loop:begin (benchmarks/cross_dataset_loop.py) -->"
END = "<!-- cross-dataset-loop:end -->"
#: The shipped ensemble members' options (loop_variants ``--set stream_prob=0.3``).
MEMBER_OPTIONS: dict[str, Any] = {"stream_prob": 0.3}


def _corpus(args: argparse.Namespace) -> list[GestureClip]:
    """The cross-dataset corpus, cached in ``OUT/corpus.pkl`` (loading MSRC-12 is slow)."""
    cache = Path(args.out) / "corpus.pkl"
    if cache.is_file():
        return pickle.load(cache.open("rb"))
    clips = load_corpus(shared_data_root(None) / "gestures", msrc12_folder=args.msrc12,
                        kinder_gator_folder=args.kindergator, mhad_folder=args.mhad)
    cache.parent.mkdir(parents=True, exist_ok=True)
    pickle.dump(clips, cache.open("wb"))
    return clips


def _avatars(out: Path, name: str, clips: list[GestureClip]) -> list[GestureClip]:
    """The avatar clips of dataset ``name`` (cached in ``out/avatars_<name>.pkl``)."""
    cache = out / f"avatars_{name}.pkl"
    if cache.is_file():
        return pickle.load(cache.open("rb"))
    av, skipped = avatar_clips(clips, progress=False)
    pickle.dump(av, cache.open("wb"))
    print(f"{name}: {len(av)} avatar clips, {len(skipped)} skipped", flush=True)
    return av


def cmd_train(args: argparse.Namespace) -> None:
    out = Path(args.out)
    clips = _corpus(args)
    config = (RecognitionConfig.from_file(args.config) if args.config
              else RecognitionConfig(**MEMBER_OPTIONS))
    config = replace(config, forecast_prob=0.0)
    if args.epochs:
        config = replace(config, epochs=args.epochs)
    # Kinder-Gator trains only (simenv.learning.cross_dataset); Florence has no avatar.
    names = args.datasets or sorted({c.dataset for c in clips} - {"florence3d", KINDER_GATOR})
    for name in names:
        if (out / f"{name}_readings.pkl").is_file():
            continue
        test = [c for c in clips if c.dataset == name]
        avatars = _avatars(out, name, test)
        model, history = train_recogniser(
            [c for c in clips if c.dataset != name], list(GESTURE_LABELS), lambda c: c.label,
            config, progress=False, extra={"protocol": f"cross-dataset loop, {name} left out"})
        model.save(out / f"{name}.npz")
        conds = real_windows(test)
        readings = {"z3": logits_of(model, *conds["real_3s"]),
                    "z1": logits_of(model, *conds["real_1s"]),
                    "y": np.array([GESTURE_LABELS.index(c.label) for c in test]),
                    "stream": stream_readings(avatars, model, None, seed=0,
                                              real_windows=LOOP_WINDOWS),
                    "config": config.__dict__, "train_cpu_s": history["train_cpu_s"],
                    "train_datasets": sorted({c.dataset for c in clips} - {name})}
        pickle.dump(readings, (out / f"{name}_readings.pkl").open("wb"))
        print(f"{name} left out: {history['train_cpu_s']} CPU s", flush=True)


def score(out: Path, window_rule: str) -> dict[str, Any]:
    """Cross-fitted loop outcomes per left-out dataset (module docstring)."""
    names = sorted(p.name.removesuffix("_readings.pkl") for p in out.glob("*_readings.pkl"))
    if len(names) < 2:
        raise SystemExit(f"score needs the readings of at least two left-out datasets in "
                         f"{out}; found {names}")
    data = {n: pickle.load((out / f"{n}_readings.pkl").open("rb")) for n in names}
    temps = []
    for n in names:
        others = [data[m] for m in names if m != n]
        z = np.concatenate([d[key] for d in others for key in ("z3", "z1")])
        y = np.concatenate([d["y"] for d in others for _ in ("z3", "z1")])
        temps.append(fit_temperature(z, y))
    readings = [r for n in names for r in data[n]["stream"]]
    r = cross_fitted_outcomes(readings, lambda s: names.index(s.split("/")[0]),
                              GESTURE_LABELS, temps, use_forecast=False,
                              window_rule=window_rule)
    per = {}
    keys = ("threshold", "greet_clips", "other_clips", "idle_clips", "decision_after_onset_s",
            "decided_before_end")
    for k, n in enumerate(names):
        held = [x for x in readings if x.dataset == n]
        fold = next(f for f in r["folds"] if f["fold"] == k)
        row = loop_outcomes(held, GESTURE_LABELS, fold["threshold"], temps[k],
                            use_forecast=False, window_rule=window_rule)
        per[n] = {"temperature": round(temps[k], 4), "train_cpu_s": data[n]["train_cpu_s"],
                  "epochs": data[n]["config"]["epochs"],
                  "train_datasets": data[n].get("train_datasets"),
                  **{key: row[key] for key in keys}}
        # An upper bound, not a figure the room could reach: temperature and threshold
        # fitted on the left-out dataset itself.
        tau = fit_temperature(np.concatenate([data[n]["z3"], data[n]["z1"]]),
                              np.concatenate([data[n]["y"], data[n]["y"]]))
        t = choose_threshold(held, GESTURE_LABELS, tau, use_forecast=False,
                             window_rule=window_rule)
        own = loop_outcomes(held, GESTURE_LABELS, t, tau, use_forecast=False,
                            window_rule=window_rule)
        per[n]["fitted_on_itself"] = {"temperature": round(tau, 4),
                                      **{key: own[key] for key in keys}}
    return {"window_rule": window_rule, "datasets": per}


def _greeted(k: int, n: int) -> str:
    return f"{k}/{n} ({k / n:.1%})" if n else "none"


def cmd_score(args: argparse.Namespace) -> None:
    result = score(Path(args.out), args.window_rule)
    for name, d in result["datasets"].items():
        m = d["decision_after_onset_s"]
        print(f"{name} left out: waves {_greeted(*d['greet_clips'])}, other "
              f"{_greeted(*d['other_clips'])}, idle {_greeted(*d['idle_clips'])}; decision "
              f"median {m['median']} s, p90 {m['p90']} s; threshold {d['threshold']}, "
              f"temperature {d['temperature']}")
        o = d["fitted_on_itself"]
        print(f"   fitted on itself: waves {_greeted(*o['greet_clips'])}, other "
              f"{_greeted(*o['other_clips'])}, idle {_greeted(*o['idle_clips'])}; median "
              f"{o['decision_after_onset_s']['median']} s; threshold {o['threshold']}, "
              f"temperature {o['temperature']}")
    if args.json:
        (Path(args.out) / "scores.json").write_text(json.dumps(result, indent=1))


def cmd_shipped(args: argparse.Namespace) -> None:
    out = Path(args.out)
    test = [c for c in _corpus(args) if c.dataset == "msrc12"]
    avatars = _avatars(out, "msrc12", test)
    conds = real_windows(test)
    y = np.array([GESTURE_LABELS.index(c.label) for c in test])
    path = out / "shipped.json"
    rows = json.loads(path.read_text()) if path.is_file() else {}
    for checkpoint in args.checkpoints:
        net = SkeletonTCNEnsemble.load(checkpoint)
        meta = net.metadata
        acc = {cond: round(float((logits_of(net, *conds[cond]).argmax(1) == y).mean()), 4)
               for cond in ("real_3s", "real_1s")}
        # The ensemble's logits are already divided by its temperature.
        loop = loop_outcomes(stream_readings(avatars, net, None, seed=0,
                                             real_windows=meta["loop_windows"]),
                             GESTURE_LABELS, meta["loop_threshold"], 1.0, use_forecast=False,
                             window_rule=meta["loop_window_rule"])
        key = args.label or Path(checkpoint).stem
        rows[key] = {"checkpoint": str(checkpoint), "canonical_body": bool(
            net.members[0].config.extra.get(CANONICAL_BODY, False)),
            "epochs": meta["config"]["epochs"], "clips": len(test),
            "persons": len({c.subject for c in test}), **acc,
            **{k: loop[k] for k in ("threshold", "greet_clips", "other_clips")},
            # Its own leave-subjects-out figures on the room corpus (checkpoint metadata).
            "unseen_subjects": {"real_3s": meta["protocol_accuracy"]["real_3s"]["accuracy"],
                                "real_1s": meta["protocol_accuracy"]["real_1s"]["accuracy"],
                                **{k: meta["unseen_subject_loop"][k]
                                   for k in ("greet_clips", "other_clips")}}}
        print(key, rows[key], flush=True)
    path.write_text(json.dumps(rows, indent=1))


def section(out: Path, command: str, lso_scores: str | None = None,
            before: Path | None = None) -> str:
    """The generated docs section (markdown, between the markers); ``lso_scores``: a
    ``benchmarks/loop_variants.py`` ``scores.jsonl`` whose member sets are listed;
    ``before``: the output folder of another run, whose rows are listed beside these."""
    result = json.loads((out / "scores.json").read_text())
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, cwd=REPO).stdout.strip()
    stamp = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    lines = [BEGIN, "## The loop on people of a dataset it never trained on", "",
             f"Section generated by `{command}` on {stamp} "
             f"at commit `{commit}`. **Do not edit by hand**: rerun it.", "",
             "For each left-out dataset, one network trained on every clip of the other "
             "datasets (the shipped ensemble members' options, "
             f"{next(iter(result['datasets'].values()))['epochs']} epochs, no forecast "
             "windows) reads the left-out dataset's recordings as the room's agent sees "
             "them (retargeted onto the avatar, a tick every second, the last 1 / 2 / 3 s "
             f"combined by the `{result['window_rule']}` rule, no forecast stage). The "
             "temperature and the threshold of each left-out dataset are fitted on the "
             "other left-out datasets (cross-fitted over datasets, as the leave-subjects-"
             "out protocol is over folds). One network per dataset, where the room ships "
             "an ensemble of two. Florence 3D is not left out (clips of at most 1.75 s); "
             "MSRC-12 has no wave (its gestures are bow and other). Goal: >= 90 % of waves "
             "greeted, <= 3 % of other actions, decision median <= 1.5 s after onset.", "",
             *_sources(result),
             "The rows *fitted on itself* fit the temperature and choose the threshold "
             "on the left-out dataset's own readings: an upper bound no room could reach "
             "(it would need labelled recordings of the new people), not a result.", "",
             "| left out | calibration | waves greeted | other actions greeted | idle "
             "greeted | decision after onset, s (median / p90) | threshold | temperature |",
             "|---|---|---|---|---|---|---|---|"]
    for name, d in result["datasets"].items():
        for how, r in (("other datasets (the protocol)", d),
                       ("fitted on itself (upper bound)", d["fitted_on_itself"])):
            m = r["decision_after_onset_s"]
            lines.append(f"| {name} | {how} | {_greeted(*r['greet_clips'])} | "
                         f"{_greeted(*r['other_clips'])} | {_greeted(*r['idle_clips'])} | "
                         f"{m['median']} / {m['p90']} | {r['threshold']} | "
                         f"{r['temperature']} |")
    if before is not None:
        lines += _before_rows(json.loads((before / "scores.json").read_text()), result)
    shipped = out / "shipped.json"
    if shipped.is_file():
        rows = json.loads(shipped.read_text())
        first = next(iter(rows.values()))
        lines += ["", f"Ensembles of the room's recipe on MSRC-12 ({first['clips']} clips of "
                  f"{first['persons']} persons, p06 never read; none of them trained on it), "
                  "each with its own temperature, threshold and window rule, beside their "
                  "leave-subjects-out figures on the room's corpus (their checkpoints' "
                  "metadata):", "",
                  "| recogniser | canonical body | epochs | MSRC-12 real_3s / real_1s | "
                  "MSRC-12 loop: actions greeted (threshold) | unseen subjects real_3s / "
                  "real_1s | unseen subjects loop: waves / other actions greeted |",
                  "|---|---|---|---|---|---|---|"]
        for key, r in rows.items():
            u = r["unseen_subjects"]
            lines.append(f"| {key} | {'yes' if r['canonical_body'] else 'no'} | "
                         f"{r['epochs']} | {r['real_3s']:.3f} / {r['real_1s']:.3f} | "
                         f"{_greeted(*r['other_clips'])} ({r['threshold']}) | "
                         f"{u['real_3s']:.3f} / {u['real_1s']:.3f} | "
                         f"{_greeted(*u['greet_clips'])} / {_greeted(*u['other_clips'])} |")
    if lso_scores is not None:
        lines += ["", "The room's recipe shortened as here (20 epochs, no per-fold forecaster), "
                  "leave-subjects-out on the room's corpus, per member set "
                  "(`benchmarks/loop_variants.py score MEMBER [MEMBER] --window-rule mean "
                  f"--json`, "
                  f"rows of `{lso_scores}`): what the input changes at equal recipe.", "",
                  "| members | canonical body | waves greeted | other actions greeted | idle "
                  "greeted | decision after onset, s (median / p90) |", "|---|---|---|---|---|---|"]
        seen = {}
        for line in Path(lso_scores).read_text().splitlines():
            row = json.loads(line)
            seen[" + ".join(row["members"])] = row  # the last score of a member set
        for key, r in seen.items():
            config = json.loads((Path(lso_scores).parent / r["members"][0] / "config.json")
                                .read_text())
            m = r["decision_after_onset_s"]
            lines.append(f"| {key} | {'yes' if config.get('canonical_body') else 'no'} | "
                         f"{_greeted(*r['greet_clips'])} | {_greeted(*r['other_clips'])} | "
                         f"{_greeted(*r['idle_clips'])} | {m['median']} / {m['p90']} |")
    return "\n".join(lines + [END])


def _sources(result: dict[str, Any]) -> list[str]:
    """A sentence naming the training sources of the networks (when the run recorded them)."""
    sources = {name: d.get("train_datasets") for name, d in result["datasets"].items()}
    if not all(sources.values()):
        return []
    return [" ".join(f"With {name} left out the network trained on "
                     f"{' + '.join(train)}." for name, train in sources.items())
            + (" Kinder-Gator (`kindergator`: 20 people, 10 of them children, on a Kinect v1, "
               "read from a copy outside the repository, tests/data/kinder_gator/SOURCES.md) "
               "trains every network and is never left out."
               if any(KINDER_GATOR in t for t in sources.values()) else ""), ""]


def _before_rows(before: dict[str, Any], after: dict[str, Any]) -> list[str]:
    """Markdown: per left-out dataset, the protocol's loop outcomes of ``before`` -> ``after``."""
    lines = ["", "Before -> after the change of training sources (same options, seeds and "
             "left-out recordings; before, each network trained on the other datasets of the "
             "corpus only):", "",
             "| left out | calibration | waves greeted | other actions greeted | idle greeted "
             "| decision median after onset, s |", "|---|---|---|---|---|---|"]
    for name, a_row in after["datasets"].items():
        b_row = before["datasets"].get(name)
        if b_row is None:
            continue
        for how, b, a in (("other datasets (the protocol)", b_row, a_row),
                          ("fitted on itself (upper bound)", b_row["fitted_on_itself"],
                           a_row["fitted_on_itself"])):
            lines.append(
                f"| {name} | {how} | {_greeted(*b['greet_clips'])} -> "
                f"{_greeted(*a['greet_clips'])} | {_greeted(*b['other_clips'])} -> "
                f"{_greeted(*a['other_clips'])} | {_greeted(*b['idle_clips'])} -> "
                f"{_greeted(*a['idle_clips'])} | {b['decision_after_onset_s']['median']} -> "
                f"{a['decision_after_onset_s']['median']} |")
    return lines


def cmd_docs(args: argparse.Namespace) -> None:
    text = DOC.read_text()
    new = section(Path(args.out), args.command_line, args.lso_scores,
                  Path(args.before) if args.before else None)
    if BEGIN in text:
        head, rest = text.split(BEGIN, 1)
        text = head + new + rest.split(END, 1)[1]
    else:
        text = text.rstrip("\n") + "\n\n" + new + "\n"
    DOC.write_text(text)
    print(f"wrote {DOC}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/cross-dataset-loop")
    parser.add_argument("--msrc12", help="MSRC-12 folder (p06 never read)")
    parser.add_argument("--kindergator", help="Kinder-Gator folder (trains, never left out)")
    parser.add_argument("--mhad", help="Berkeley MHAD SkeletalData folder (a left-out dataset)")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("train")
    p.add_argument("--datasets", nargs="*")
    p.add_argument("--config", help="RecognitionConfig TOML/JSON (default: the members')")
    p.add_argument("--epochs", type=int)
    p = sub.add_parser("score")
    p.add_argument("--window-rule", default="mean")
    p.add_argument("--json", action="store_true")
    p = sub.add_parser("shipped")
    p.add_argument("checkpoints", nargs="+")
    p.add_argument("--label", help="row name (default: the file's stem)")
    p = sub.add_parser("docs")
    p.add_argument("--lso-scores", help="a loop_variants scores.jsonl to list (optional)")
    p.add_argument("--before", help="another run's output folder, listed beside this one")
    p.add_argument("--command-line", default="python benchmarks/cross_dataset_loop.py docs",
                   help="the commands to name in the section's header")
    args = parser.parse_args()
    {"train": cmd_train, "score": cmd_score, "shipped": cmd_shipped,
     "docs": cmd_docs}[args.command](args)


if __name__ == "__main__":
    main()

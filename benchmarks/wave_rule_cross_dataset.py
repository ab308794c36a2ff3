"""The hand-written wave rule through the room's loop, on datasets it was not tuned on.

The simplest baseline of issue 34 (:mod:`simenv.perception.wave_rule`): a wrist swinging
side to side above its shoulder, read at the loop's ticks (every second, the phases of
:func:`simenv.perception.protocol.stream_readings`) on the recordings as the room's agent
sees them (:func:`simenv.perception.protocol.avatar_clips`). Its parameters are chosen
from :data:`GRID` the way the network's thresholds are (:func:`choose_rule`): the most
waves greeted with at most :data:`simenv.perception.protocol.FALSE_GREET_TARGET` of the
other and idle clips greeted, on calibration clips only --

* **across datasets**: for each left-out dataset D (MSR Action3D, MSRC-12, UTKinect and
  Kinder-Gator; Florence 3D's clips, at most 1.75 s, are left out), chosen on every clip of
  the other datasets;
  each dataset's ticks have phase seed 0, as ``benchmarks/cross_dataset_loop.py``'s;
* **leave-subjects-out on the room's own corpus** (the shared gesture corpus's MSR
  Action3D and UTKinect clips, folds :func:`simenv.data.gestures.subject_fold`, fold k's
  ticks with phase seed k as ``benchmarks/loop_variants.py``'s): for fold k, chosen on the
  other folds.

Rows *fitted on itself* choose on the tested clips themselves: the rule family's ceiling,
not a result.

``run``: writes ``OUT/scores.json`` (per left-out dataset and per fold: the chosen rule
and the outcomes; per source class of the left-out data: clips greeted).

``fuse [--readings DIR]``: the rule fused with the networks of
``benchmarks/cross_dataset_loop.py train`` (one per left-out dataset, its stream readings
``DIR/<D>_readings.pkl`` at the same ticks; temperature fitted on the other left-out
datasets as its ``score``, windows combined by the ``mean`` rule): *and* (the rule fires
and the network's wave probability reaches a floor, :data:`WAVE_FLOORS`), *or* (the rule
fires or the network decides wave at a threshold of
:data:`simenv.perception.protocol.THRESHOLD_GRID`) and the network alone, each fusion's
rule and parameter chosen by :func:`choose_rule`'s criterion on the other datasets that
have a network; writes ``OUT/fusion.json``.

``docs``: the section of docs/recognition.md between :data:`BEGIN` and :data:`END`,
beside the network's figures (the table of the section ``cross-dataset-loop`` of the
same page, and the shipped ensemble's unseen-subject loop from its checkpoint's
metadata), with the fusion table when ``OUT/fusion.json`` exists.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import pickle
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from doc_sections import replace_section, section  # noqa: E402

from simenv.core.config import shared_data_root  # noqa: E402
from simenv.data.gestures import GESTURE_LABELS, GestureClip, subject_fold  # noqa: E402
from simenv.learning.cross_dataset import load_corpus  # noqa: E402
from simenv.models.skeleton_tcn import SkeletonTCNEnsemble, fit_temperature  # noqa: E402
from simenv.perception.loop import real_stage  # noqa: E402
from simenv.perception.protocol import (  # noqa: E402
    FALSE_GREET_TARGET,
    GREET_LABEL,
    THRESHOLD_GRID,
    avatar_clips,
)
from simenv.perception.wave_rule import WaveRule, rule_outcomes, stream_fires  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "recognition.md"
BEGIN = "<!-- wave-rule:begin (benchmarks/wave_rule_cross_dataset.py) -->"
END = "<!-- wave-rule:end -->"
NETWORK_BEGIN = "<!-- cross-dataset-loop:begin (benchmarks/cross_dataset_loop.py) -->"
NETWORK_END = "<!-- cross-dataset-loop:end -->"
ENSEMBLE = REPO / "assets" / "models" / "gesture-tcn-ensemble.npz"
#: The room's own corpus (shared gesture corpus) datasets with an avatar.
ROOM_CORPUS = ("msr_action3d", "utkinect")
#: Parameter values tried (the others at :class:`WaveRule`'s defaults: 0.4-3 Hz, 3 frames).
GRID: dict[str, tuple[float, ...]] = {
    "window_s": (1.0, 1.5, 2.0, 3.0),
    "raise_height": (-0.5, -0.25, 0.0, 0.25, 0.5),
    "swing": (0.15, 0.2, 0.3, 0.4, 0.5),
    "max_rise": (0.5, 1.0, 2.0),
    "reversals": (1, 2, 3),
}
Fires = list[tuple[np.ndarray, np.ndarray]]


def grid_rules() -> list[WaveRule]:
    """Every rule of :data:`GRID`."""
    return [WaveRule(**dict(zip(GRID, values, strict=True)))
            for values in itertools.product(*GRID.values())]


def choose_rule(rules: Sequence[WaveRule], clips: Sequence[GestureClip],
                fires: Sequence[Fires], target: float = FALSE_GREET_TARGET) -> int:
    """Index of the rule greeting the most waves of ``clips`` with a false-greeting rate
    (other + idle clips) at most ``target``; ties: the earlier median decision, then the
    earlier rule of the grid. None meeting ``target``: the lowest false-greeting rate."""
    rows = [rule_outcomes(clips, f) for f in fires]
    ok = [i for i, r in enumerate(rows) if r["false_greet_rate"] <= target]
    if not ok:
        return int(np.argmin([r["false_greet_rate"] for r in rows]))
    return max(ok, key=lambda i: (rows[i]["greeted_rate"],
                                  -(rows[i]["decision_after_onset_s"]["median"] or np.inf),
                                  -i))


def _avatars(args: argparse.Namespace) -> list[GestureClip]:
    """Every clip with an avatar, in the corpus's order (cached in ``OUT/avatars.pkl``)."""
    cache = Path(args.out) / "avatars.pkl"
    if cache.is_file():
        return pickle.load(cache.open("rb"))
    clips = load_corpus(shared_data_root(None) / "gestures", msrc12_folder=args.msrc12,
                        kinder_gator_folder=args.kindergator)
    avatars, skipped = avatar_clips([c for c in clips if c.dataset != "florence3d"],
                                    progress=False)
    print(f"{len(avatars)} avatar clips, {len(skipped)} skipped", flush=True)
    cache.parent.mkdir(parents=True, exist_ok=True)
    pickle.dump(avatars, cache.open("wb"))
    return avatars


def _by_class(clips: Sequence[GestureClip], fires: Fires) -> dict[str, list[int]]:
    """Per source class (``label: source_label``): [clips greeted, clips]."""
    out: dict[str, list[int]] = {}
    for c, (_, fired) in zip(clips, fires, strict=True):
        row = out.setdefault(f"{c.label}: {c.source_label}", [0, 0])
        row[0] += bool(fired.any())
        row[1] += 1
    return out


def _evaluate(rules: list[WaveRule], parts: dict[Any, list[GestureClip]], seeds: dict[Any, int]
              ) -> dict[str, Any]:
    """Cross-fitted over the keys of ``parts`` (datasets or folds): each part's rule
    chosen on the others, and on itself (the ceiling)."""
    t0 = time.process_time()
    fires = {k: stream_fires(clips, rules, seed=seeds[k]) for k, clips in parts.items()}
    cpu_s = time.process_time() - t0
    out: dict[str, Any] = {}
    pooled_clips, pooled_fires = [], []
    for k, clips in parts.items():
        calib = [c for j in parts if j != k for c in parts[j]]
        calib_fires = [[f for j in parts if j != k for f in fires[j][i]]
                       for i in range(len(rules))]
        chosen = choose_rule(rules, calib, calib_fires)
        own = choose_rule(rules, clips, fires[k])
        out[str(k)] = {"rule": rules[chosen].__dict__,
                       "calibration": rule_outcomes(calib, calib_fires[chosen]),
                       **rule_outcomes(clips, fires[k][chosen]),
                       "by_class": _by_class(clips, fires[k][chosen]),
                       "fitted_on_itself": {"rule": rules[own].__dict__,
                                            **rule_outcomes(clips, fires[k][own])}}
        pooled_clips += clips
        pooled_fires += fires[k][chosen]
    return {"parts": out, "pooled": rule_outcomes(pooled_clips, pooled_fires),
            "grid_cpu_s": round(cpu_s, 1)}



#: Fusions with the network (``fuse``): the network's wave probability floors under which
#: the rule's firing is ignored (``and``); the network's own thresholds (``or``).
WAVE_FLOORS: tuple[float, ...] = (0.05, 0.1, 0.2, 0.3, 0.4)
#: What ``fuse`` measures (:func:`_fusion`).
FUSIONS: tuple[str, ...] = ("network", "and", "or")


def _temperatures(data: dict[str, dict[str, Any]]) -> dict[str, float]:
    """Per left-out dataset, the temperature fitted on the other left-out datasets'
    ``real_3s`` + ``real_1s`` logits (``benchmarks/cross_dataset_loop.py score``'s)."""
    out = {}
    for n in data:
        others = [data[m] for m in data if m != n]
        out[n] = float(fit_temperature(
            np.concatenate([d[key] for d in others for key in ("z3", "z1")]),
            np.concatenate([d["y"] for d in others for _ in ("z3", "z1")])))
    return out


def _network(stream: Sequence[Any], temperature: float) -> dict[str, list[np.ndarray]]:
    """The network's per-tick wave probability (``p_wave``) and that probability where
    wave is its top class, else 0 (``p_top_wave``: it decides wave alone at a threshold
    at most this, :func:`simenv.perception.loop.decide`'s real stage), on its stream
    readings at ``temperature``, the real windows combined by the ``mean`` rule (the
    room's), no forecast stage."""
    k = GESTURE_LABELS.index(GREET_LABEL)
    out: dict[str, list[np.ndarray]] = {"p_wave": [], "p_top_wave": []}
    for r in stream:
        z = r.logits_real / temperature
        e = np.exp(z - z.max(axis=-1, keepdims=True))
        p = real_stage(e / e.sum(axis=-1, keepdims=True), "mean")
        out["p_wave"].append(p[:, k])
        out["p_top_wave"].append(np.where(p.argmax(axis=1) == k, p[:, k], 0.0))
    return out


def _flat(clips: Sequence[GestureClip], fires: Sequence[Fires], net: dict[str, Any]
          ) -> dict[str, Any]:
    """Arrays over every tick of ``clips`` (rules' firings (R, N), network (N,)) and the
    clips' first tick, group and length, for scoring thousands of fusions at once."""
    counts = np.array([len(t) for t, _ in fires[0]])
    group = np.array([0 if c.label == GREET_LABEL else 2 if c.label == "idle" else 1
                      for c in clips])
    return {"fired": np.stack([np.concatenate([f for _, f in rule]) for rule in fires]),
            "ticks": np.concatenate([t for t, _ in fires[0]]),
            "p_wave": np.concatenate(net["p_wave"]),
            "p_top_wave": np.concatenate(net["p_top_wave"]),
            "starts": np.concatenate([[0], np.cumsum(counts)[:-1]]), "group": group}


def _rates(flat: dict[str, Any], fired: np.ndarray) -> tuple[float, float, float]:
    """(waves greeted rate, false-greeting rate, median decision s) of ``fired`` (N,)."""
    greeted = np.maximum.reduceat(fired.astype(np.uint8), flat["starts"]).astype(bool)
    first = np.minimum.reduceat(np.where(fired, flat["ticks"], np.inf), flat["starts"])
    g = flat["group"]
    waves = greeted[g == 0]
    median = float(np.median(first[(g == 0) & greeted])) if waves.any() else np.inf
    return float(waves.mean()) if waves.size else 0.0, float(greeted[g > 0].mean()), median


def _choose_fusion(flat: dict[str, Any], kind: str) -> tuple[int, float]:
    """(rule index, parameter) of the ``kind`` fusion (:func:`_fusion`) that
    :func:`choose_rule`'s criterion picks on ``flat``."""
    best, key = (0, 0.0), None
    for i in range(1 if kind == "network" else len(flat["fired"])):
        for value in WAVE_FLOORS if kind == "and" else THRESHOLD_GRID:
            recall, false, median = _rates(flat, _fusion(flat, kind, i, value))
            ok = false <= FALSE_GREET_TARGET
            rank = (ok, recall if ok else -false, -median)
            if key is None or rank > key:
                best, key = (i, float(value)), rank
    return best


def cmd_fuse(args: argparse.Namespace) -> None:
    avatars = _avatars(args)
    rules = grid_rules()
    readings = Path(args.readings)
    names = sorted(p.name.removesuffix("_readings.pkl") for p in readings.glob("*_readings.pkl"))
    data = {n: pickle.load((readings / f"{n}_readings.pkl").open("rb")) for n in names}
    taus = _temperatures(data)
    parts = {n: [c for c in avatars if c.dataset == n] for n in names}
    fires = {n: stream_fires(parts[n], rules, seed=0) for n in names}
    for n in names:
        stream = data[n]["stream"]
        if [c.name for c in parts[n]] != [r.name for r in stream] or not all(
                np.allclose(t, r.ticks_s) for (t, _), r in zip(fires[n][0], stream,
                                                              strict=True)):
            raise SystemExit(f"{n}: the network's readings are not of these clips and ticks")
    result: dict[str, Any] = {"floors": list(WAVE_FLOORS), "datasets": {}}
    for n in names:
        # As cross_fitted_outcomes: the held-out dataset's temperature on every reading.
        held = _flat(parts[n], fires[n], _network(data[n]["stream"], taus[n]))
        calib_names = [m for m in names if m != n]
        calib_clips = [c for m in calib_names for c in parts[m]]
        calib_fires = [[f for m in calib_names for f in fires[m][i]]
                       for i in range(len(rules))]
        calib = _flat(calib_clips, calib_fires, _network(
            [r for m in calib_names for r in data[m]["stream"]], taus[n]))
        row: dict[str, Any] = {"temperature": round(taus[n], 4)}
        for kind in FUSIONS:
            i, value = _choose_fusion(calib, kind)
            split = np.split(_fusion(held, kind, i, value), held["starts"][1:])
            row[kind] = {"rule": rules[i].__dict__, "parameter": value,
                         **rule_outcomes(parts[n], [(t, f) for (t, _), f in
                                                    zip(fires[n][0], split, strict=True)])}
        result["datasets"][n] = row
        for kind in FUSIONS:
            d = row[kind]
            print(f"{n} left out, {kind}: waves {_greeted(*d['greet_clips'])}, other "
                  f"{_greeted(*d['other_clips'])}, idle {_greeted(*d['idle_clips'])}, median "
                  f"{d['decision_after_onset_s']['median']} s; {_rule(d['rule'])}, "
                  f"parameter {d['parameter']}", flush=True)
    path = Path(args.out) / "fusion.json"
    path.write_text(json.dumps(result, indent=1))
    print(f"wrote {path}")


def _fusion(flat: dict[str, Any], kind: str, i: int, value: float) -> np.ndarray:
    """The firing (N,) of one fusion of rule ``i`` with the network: ``and``, the rule
    fires and the network's wave probability is at least ``value``; ``or``, the rule
    fires or the network decides wave alone at threshold ``value``; ``network``, the
    network alone at threshold ``value`` (the rule ignored)."""
    if kind == "and":
        return flat["fired"][i] & (flat["p_wave"] >= value)
    network = flat["p_top_wave"] >= value
    return network if kind == "network" else flat["fired"][i] | network


def cmd_run(args: argparse.Namespace) -> None:
    avatars = _avatars(args)
    rules = grid_rules()
    names = sorted({c.dataset for c in avatars})
    cross = _evaluate(rules, {n: [c for c in avatars if c.dataset == n] for n in names},
                      dict.fromkeys(names, 0))
    room = [c for c in avatars if c.dataset in ROOM_CORPUS]
    folds = sorted({subject_fold(c.subject_key) for c in room})
    lso = _evaluate(rules, {k: [c for c in room if subject_fold(c.subject_key) == k]
                            for k in folds}, {k: k for k in folds})
    result = {"grid": {k: list(v) for k, v in GRID.items()}, "rules": len(rules),
              "false_greet_target": FALSE_GREET_TARGET, "cross_dataset": cross,
              "leave_subjects_out": lso}
    for name, d in cross["parts"].items():
        print(f"{name} left out: waves {_greeted(*d['greet_clips'])}, other "
              f"{_greeted(*d['other_clips'])}, idle {_greeted(*d['idle_clips'])}, median "
              f"{d['decision_after_onset_s']['median']} s; rule {_rule(d['rule'])}", flush=True)
    p = lso["pooled"]
    print(f"leave-subjects-out: waves {_greeted(*p['greet_clips'])}, other "
          f"{_greeted(*p['other_clips'])}, idle {_greeted(*p['idle_clips'])}, median "
          f"{p['decision_after_onset_s']['median']} s")
    path = Path(args.out) / "scores.json"
    path.write_text(json.dumps(result, indent=1))
    print(f"wrote {path}")


def _greeted(k: int, n: int) -> str:
    return f"{k}/{n} ({k / n:.1%})" if n else "none"


def _rule(r: dict[str, Any]) -> str:
    return (f"{r['window_s']:g} s, wrist >= {r['raise_height']:+g} sw, swing >= "
            f"{r['swing']:g} sw, rise <= {r['max_rise']:g} x swing, >= {r['reversals']} "
            "reversals")


def network_rows() -> dict[str, list[str]]:
    """The protocol rows of the network's cross-dataset loop table (the section
    ``cross-dataset-loop`` of docs/recognition.md): left-out dataset -> its cells
    (waves, other, idle greeted, decision median / p90)."""
    rows = {}
    for line in section(DOC.read_text(), NETWORK_BEGIN, NETWORK_END).splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) == 8 and cells[1] == "other datasets (the protocol)":
            rows[cells[0]] = cells[2:6]
    return rows


def _meets(r: dict[str, Any]) -> bool:
    """Issue 34's loop goal on outcomes ``r``: >= 90 % of waves greeted (when there are
    waves), <= 3 % of other actions, decision median <= 1.5 s after onset."""
    (a, n), (b, m) = r["greet_clips"], r["other_clips"]
    median = r["decision_after_onset_s"]["median"]
    return b <= 0.03 * m and (n == 0 or a >= 0.9 * n and median is not None
                              and median <= 1.5)


def _cells(r: dict[str, Any]) -> list[str]:
    m = r["decision_after_onset_s"]
    return [_greeted(*r["greet_clips"]), _greeted(*r["other_clips"]),
            _greeted(*r["idle_clips"]), f"{m['median']} / {m['p90']}"]


def doc_section(out: Path, command: str) -> str:
    """The generated docs section (markdown between the markers)."""
    result = json.loads((out / "scores.json").read_text())
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, cwd=REPO).stdout.strip()
    stamp = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    grid = result["grid"]
    net = network_rows()
    lines = [
        "## A hand-written wave rule through the same loop (the simplest baseline)", "",
        f"Section generated by `{command}` on {stamp} at commit `{commit}`. **Do not edit "
        "by hand**: rerun it.", "",
        "`simenv.perception.wave_rule`: at each tick of the loop (every second, the same "
        "phases and recordings as the network's rows above, retargeted onto the avatar) "
        "the rule reads the last `window_s` of the avatar's keypoints and fires when one "
        "wrist reverses its sideways motion (along the body's own shoulder axis) at least "
        "`reversals` times, each half-swing at least `swing` shoulder widths long, at "
        "0.4-3 Hz, its vertical range at most `max_rise` times its sideways travel, the "
        "wrist at least `raise_height` shoulder widths above its shoulder throughout; a "
        "clip is greeted when any tick fires. No training: its parameters are chosen from "
        f"a grid of {result['rules']} rules (window_s {grid['window_s']} s, raise_height "
        f"{grid['raise_height']}, swing {grid['swing']}, max_rise {grid['max_rise']}, "
        f"reversals {grid['reversals']}) "
        "as the network's threshold is: the most waves greeted with at most "
        f"{result['false_greet_target']:.0%} of the other and idle clips greeted, on the "
        "clips of every *other* dataset (Kinder-Gator included: the rule learns nothing "
        "from it, so it is also left out in turn). *Fitted on itself*: chosen on the "
        "tested clips, the ceiling of the rule family, not a result. Goal: >= 90 % of "
        "waves greeted, <= 3 % of other actions, decision median <= 1.5 s after onset.", "",
        "| left out | recogniser | waves greeted | other actions greeted | idle greeted | "
        "decision after onset, s (median / p90) | rule chosen |",
        "|---|---|---|---|---|---|---|"]
    for name, d in result["cross_dataset"]["parts"].items():
        own = d["fitted_on_itself"]
        lines += [f"| {name} | wave rule, chosen on the other datasets | "
                  f"{' | '.join(_cells(d))} | {_rule(d['rule'])} |",
                  f"| {name} | wave rule, fitted on itself (ceiling) | "
                  f"{' | '.join(_cells(own))} | {_rule(own['rule'])} |"]
        if name in net:
            lines.append(f"| {name} | network (section above, the protocol) | "
                         f"{' | '.join(net[name])} | |")
        else:
            lines.append(f"| {name} | network | not measured (it trains on {name}) | | | | |")
    met = [name for name, d in result["cross_dataset"]["parts"].items() if _meets(d)]
    lines += ["", "The goal is met, by the rule chosen on the other datasets, on "
              f"{', '.join(met) if met else 'no left-out dataset'}."]
    lso = result["leave_subjects_out"]
    meta = SkeletonTCNEnsemble.load(ENSEMBLE).metadata["unseen_subject_loop"]
    lines += ["", "Leave-subjects-out on the room's own corpus (the shared corpus's MSR "
              "Action3D and UTKinect clips; Florence 3D's short clips left out), 5 folds, each "
              "fold's rule chosen on the other folds:", "",
              "| recogniser | waves greeted | other actions greeted | idle greeted | "
              "decision after onset, s (median / p90) | rules chosen per fold |",
              "|---|---|---|---|---|---|",
              f"| wave rule | {' | '.join(_cells(lso['pooled']))} | "
              f"{'; '.join(_rule(d['rule']) for d in lso['parts'].values())} |",
              f"| the room's ensemble (`gesture-tcn-ensemble`, its checkpoint's metadata) | "
              f"{' | '.join(_cells(meta))} | |", "",
              f"The rule {'meets' if _meets(lso['pooled']) else 'does not meet'} the goal "
              "leave-subjects-out.", "",
              "Per source class of each left-out dataset, clips greeted by the rule chosen "
              "on the other datasets (every wave class; the other classes where it greeted "
              "any clip):", ""]
    for name, d in result["cross_dataset"]["parts"].items():
        shown = [f"{k} {g}/{n}" for k, (g, n) in d["by_class"].items()
                 if g or k.startswith("wave")]
        lines.append(f"* {name}: {', '.join(shown) or 'none greeted'}")
    if (out / "fusion.json").is_file():
        lines += _fusion_lines(json.loads((out / "fusion.json").read_text()))
    return "\n".join(lines)


def _fusion_lines(fusion: dict[str, Any]) -> list[str]:
    """Markdown: the ``fuse`` table."""
    how = {"network": "network alone", "and": "rule and network's wave probability >= floor",
           "or": "rule or network"}
    lines = ["", "Fused with the network (`fuse`): one network per left-out dataset "
             "(`benchmarks/cross_dataset_loop.py train --epochs 20`, trained on every "
             "other dataset, Kinder-Gator included, read at the same ticks), its "
             "temperature fitted on the other left-out datasets and its windows combined "
             "by the `mean` rule. Each fusion's rule and parameter (the network's wave "
             "probability floor for *and*, in "
             f"{fusion['floors']}; the network's threshold for *or* and alone) are chosen "
             "together by the same criterion on the other datasets that have a network "
             "(MSR Action3D, MSRC-12, UTKinect: each read by the network that never saw "
             "it), never on the left-out one.", "",
             "| left out | recogniser | waves greeted | other actions greeted | idle "
             "greeted | decision after onset, s (median / p90) | chosen |",
             "|---|---|---|---|---|---|---|"]
    for name, row in fusion["datasets"].items():
        for kind, label in how.items():
            r = row[kind]
            chosen = (f"threshold {r['parameter']}" if kind == "network" else
                      f"{_rule(r['rule'])}; {'floor' if kind == 'and' else 'threshold'} "
                      f"{r['parameter']}")
            lines.append(f"| {name} | {label} | {' | '.join(_cells(r))} | {chosen} |")
    return lines


def cmd_docs(args: argparse.Namespace) -> None:
    replace_section(DOC, BEGIN, END, doc_section(Path(args.out), args.command_line))
    print(f"wrote {DOC}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/wave-rule")
    parser.add_argument("--msrc12", help="MSRC-12 folder (p06 never read)")
    parser.add_argument("--kindergator", help="Kinder-Gator folder")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("run")
    p = sub.add_parser("fuse")
    p.add_argument("--readings", default="out/cross-dataset-loop-kg",
                   help="benchmarks/cross_dataset_loop.py train's output folder")
    p = sub.add_parser("docs")
    p.add_argument("--command-line", default="python benchmarks/wave_rule_cross_dataset.py "
                   "docs", help="the commands to name in the section's header")
    args = parser.parse_args()
    {"run": cmd_run, "fuse": cmd_fuse, "docs": cmd_docs}[args.command](args)


if __name__ == "__main__":
    main()

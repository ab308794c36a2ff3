"""Evaluate two-person generators on held-out real two-person windows, the papers' way
and with physics.

``python -m simenv.learning.eval_interaction [--model NAME ...] [--shared PATH] [--data PATH ...]
[--json] [--out DIR]`` (``simenv eval interaction``) writes ``DIR/interaction.md`` (the
table, generated here, never edited by hand), ``DIR/interaction.json`` and
``DIR/interaction.png``; ``DIR`` is ``out/interaction`` by default, and the repository's
``docs`` for its page. Every shipped reaction generator (InterFormer, reactive GAN) is
a row next to the baselines, in the same run; interaction generators (BiGraphDiff) get
their own table.

Protocol
--------
* **Data**: :func:`simenv.data.interaction_data.load_recordings` (CMU pairs + NuiSI
  repetitions, 25 fps, 18 keypoints), 40-frame windows every 5 frames, normalised in the
  actor's first-frame frame; train/test by recording
  (:data:`~simenv.data.interaction_data.DEFAULT_TEST_RECORDINGS`). With ``--data``, every given
  two-person file or folder is a test recording instead (``--label`` for files without a
  known label) and the shared corpus trains the nearest neighbour, less any recording
  read from the given files.
* **Generators** get the real actor window and the real reactor's first frame; every
  metric is computed on frames 1..T-1 (frame 0 is given, not generated).
* **Metrics** (:mod:`simenv.data.interaction_metrics`): AFD (m², actor frame), E_r, E_b (against
  the reactor's given first frame), JPD and keypoint contact retention over
  :data:`~simenv.data.interaction_metrics.KEY_JOINT_PAIRS`, FVD (window features of the
  reactor) and FID (single-pose features) against the real test reactions, diversity and
  multimodality of the generated reactions' features, and the reaction-lag error
  ``|lag(A, B̂) - lag(A, B)|`` (windows where both lags are defined), and recognition
  accuracy of (real actor, generated reactor) by a classifier trained on the real
  training windows (:mod:`simenv.learning.interaction_recognition`).
* **Interaction generators** sample both people for the class of every test window they
  know; FVD, FID, diversity, multimodality and E_b per person against the real windows,
  and recognition accuracy of the generated pair.
* **Physics**: :func:`simenv.score` (physics on: retargeting, body metrics, inverse
  dynamics, assisted PD tracking) of one window per test recording (the one where the
  real right hands come closest, i.e. the contact moment), placed back in the world with
  the exact inverse of the normalisation. Reported per method: the reactor's and the
  interaction's verdicts, inter-person penetration, the scorer's contact metric and
  its retention (bodies vs the keypoints they were fitted to). The real reactions are
  scored too, as the reference every method should be compared with.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from simenv.core.config import shared_data_root
from simenv.core.errors import SimenvError
from simenv.data import interaction_data as idata
from simenv.data import interaction_metrics as im
from simenv.learning.interaction_features import default_feature_extractor
from simenv.learning.interaction_recognition import InteractionRecognizer
from simenv.models import available, interaction_model_entry, interaction_model_names, load
from simenv.models.reaction_baselines import BASELINE_NAMES, make_baseline

#: Default root of the shared corpus (``SIMENV_SHARED_DATA`` overrides).
SHARED = shared_data_root()

#: Row name of the real reactions (reference) in the results.
REAL = "real"
#: Kinds of two-person models this evaluation runs (:data:`simenv.models.INTERACTION_MODELS`).
GENERATOR_KINDS = ("reaction", "interaction")

#: Headline columns of the table: (key in the results, header, format).
COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("AFD", "AFD (m²)", "{:.3f}"),
    ("E_r_mm", "E_r (mm)", "{:.0f}"),
    ("E_b_mm", "E_b (mm)", "{:.1f}"),
    ("JPD_mm", "JPD (mm)", "{:.0f}"),
    ("contact_retention", "contact ret.", "{:.2f}"),
    ("FVD", "FVD", "{:.3f}"),
    ("FID", "FID", "{:.3f}"),
    ("diversity", "diversity", "{:.3f}"),
    ("multimodality", "multimod.", "{:.3f}"),
    ("lag_error_s", "lag err (s)", "{:.3f}"),
    ("recognition_acc", "recog. acc", "{:.2f}"),
    ("recognition_reactor_acc", "recog. B only", "{:.2f}"),
)


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return None if not np.isfinite(x) else float(x)
    if isinstance(x, np.integer):
        return int(x)
    return x


def _generated(windows: idata.InteractionWindows, generator: Any) -> np.ndarray:
    """(N, T, J, 3) generated reactions of every window."""
    return np.asarray(generator.generate(windows.actor, windows.reactor[:, 0]), np.float64)


def reaction_metrics(windows: idata.InteractionWindows, generated: np.ndarray,
                     extractor: im.FeatureExtractor, seed: int = 0) -> dict[str, Any]:
    """Every non-physics metric of generated reactions vs the real ones of ``windows``.

    Args:
        windows: the held-out windows (actor frame).
        generated: (N, T, J, 3) generated reactions, same frame.
        extractor: window feature extractor of FVD, diversity and multimodality.
        seed: seed of the random pairs of diversity and multimodality.
    """
    a = windows.actor[:, 1:].astype(np.float64)
    real = windows.reactor.astype(np.float64)
    gen = np.asarray(generated, np.float64)
    jpd = im.jpd_mm(a, gen[:, 1:], real[:, 1:])
    retention = im.contact_retention(a, gen[:, 1:], real[:, 1:])
    feats_gen, feats_real = extractor(gen), extractor(real)
    lag_gen = im.reaction_lag_s(windows.actor, gen, windows.fps)
    lag_real = im.reaction_lag_s(windows.actor, real, windows.fps)
    both = ~np.isnan(lag_gen) & ~np.isnan(lag_real)
    per_label = {}
    for c, name in enumerate(windows.labels):
        sel = windows.label == c
        if sel.any():
            per_label[name] = {
                "windows": int(sel.sum()),
                "AFD": im.afd(gen[sel, 1:], real[sel, 1:]),
                "E_r_mm": im.joint_error_mm(gen[sel, 1:], real[sel, 1:]),
                "JPD_mm": im.jpd_mm(a[sel], gen[sel, 1:], real[sel, 1:])["mean"],
            }
    return {
        "AFD": im.afd(gen[:, 1:], real[:, 1:]),
        "E_r_mm": im.joint_error_mm(gen[:, 1:], real[:, 1:]),
        "E_b_mm": im.bone_length_error_mm(gen[:, 1:], real[:, 0],
                                          windows.skeleton.parents),
        "JPD_mm": jpd["mean"],
        "JPD_pairs_mm": {k: v for k, v in jpd.items() if k != "mean"},
        "contact_retention": retention["mean"],
        "contact_retention_pairs": {k: v for k, v in retention.items()
                                    if k not in ("mean", "real_contact_frames")},
        "real_contact_frames": retention["real_contact_frames"],
        "FVD": im.frechet_feature_distance(feats_gen, feats_real),
        "FID": im.frechet_feature_distance(im.pose_features(gen[:, 1:]),
                                           im.pose_features(real[:, 1:])),
        "diversity": im.diversity(feats_gen, seed=seed),
        "multimodality": im.multimodality(feats_gen, windows.label, seed=seed),
        "lag_error_s": float(np.abs(lag_gen - lag_real)[both].mean()) if both.any()
        else float("nan"),
        "lag_defined_windows": int(both.sum()),
        "mean_lag_s": float(np.nanmean(lag_gen)) if (~np.isnan(lag_gen)).any()
        else float("nan"),
        "per_label": per_label,
    }


def physics_windows(windows: idata.InteractionWindows) -> list[int]:
    """One window per recording: the one where the real right hands come closest."""
    d = im.joint_pair_distances(windows.actor, windows.reactor,
                                [("right_hand", "right_hand")])[..., 0].min(axis=1)
    out = []
    for r in np.unique(windows.recording):
        idx = np.flatnonzero(windows.recording == r)
        out.append(int(idx[np.argmin(d[idx])]))
    return out


def physics_of(windows: idata.InteractionWindows, index: Sequence[int],
               reactions: Mapping[str, np.ndarray], progress: bool = True,
               actors: Mapping[str, np.ndarray] | None = None
               ) -> dict[str, dict[str, Any]]:
    """:func:`simenv.score` (physics on) of the given windows for each method.

    Args:
        windows: the held-out windows.
        index: which windows to score.
        reactions: method name -> (N, T, J, 3) reactions of all ``windows`` (actor frame);
            :data:`REAL` for the real ones.
        actors: method name -> (N, T, J, 3) generated actors, for methods that generate
            both people (the real actor otherwise).

    Returns:
        method -> summary (``windows``, ``reactor_plausible``, ``actor_plausible``,
        ``interaction_plausible`` fractions, ``reactor_score_mean``,
        ``inter_penetration_max_mm``, ``inter_penetration_pass``, ``contact_jpd_mm``
        (scorer's body-vs-keypoint JPD, mean), ``contact_retention`` (scorer's, mean over
        pairs and windows), ``reactor_failed`` (metric -> count), ``records``).
    """
    # The scorer pulls in MuJoCo and the retargeting; only the physics pass needs it.
    from simenv.plausibility.report import score

    out: dict[str, dict[str, Any]] = {}
    jobs = [(name, n) for name in reactions for n in index]
    bar = tqdm(jobs, desc="physics", unit="window", disable=not progress)
    per: dict[str, list[dict[str, Any]]] = {name: [] for name in reactions}
    for name, n in bar:
        actor = (actors or {}).get(name)
        inter = windows.interaction(n, reactor=reactions[name][n],
                                    actor=None if actor is None else actor[n],
                                    name=f"{name}:"
                                    f"{windows.recording_names[windows.recording[n]]}")
        report = score(inter, physics=True)
        pen, con = report.interaction["inter_penetration"], report.interaction["contact"]
        retention = [v for k, v in con.details.items() if k.startswith("retention_")]
        per[name].append({
            "window": inter.name, "start_frame": int(windows.start[n]),
            "actor": report.people[0].verdict, "reactor": report.people[1].verdict,
            "interaction": report.verdict, "reactor_score": report.people[1].score,
            "reactor_failed": report.people[1].failed,
            "inter_penetration_mm": pen.value, "inter_penetration_passed": pen.passed,
            "contact_jpd_mm": con.value,
            "contact_retention": float(np.mean(retention)) if retention else None,
        })
    for name, rows in per.items():
        ok = lambda key, rows=rows: float(np.mean([r[key] == "plausible" for r in rows]))  # noqa: E731
        ret = [r["contact_retention"] for r in rows if r["contact_retention"] is not None]
        out[name] = {
            "windows": len(rows),
            "reactor_plausible": ok("reactor"), "actor_plausible": ok("actor"),
            "interaction_plausible": ok("interaction"),
            "reactor_score_mean": float(np.mean([r["reactor_score"] for r in rows])),
            "inter_penetration_max_mm": max((float(r["inter_penetration_mm"]) for r in rows
                                             if r["inter_penetration_mm"] is not None),
                                            default=None),
            "inter_penetration_pass": float(np.mean([bool(r["inter_penetration_passed"])
                                                     for r in rows])),
            "contact_jpd_mm": float(np.mean(jpd)) if (jpd := [
                r["contact_jpd_mm"] for r in rows if r["contact_jpd_mm"] is not None]) else None,
            "contact_retention": float(np.mean(ret)) if ret else None,
            "reactor_failed": dict(Counter(m for r in rows for m in r["reactor_failed"])
                                   .most_common()),
            "records": rows,
        }
    return out


def _within(path: Path, given: Path) -> bool:
    """Whether ``path`` is ``given`` or inside the folder ``given``."""
    return path == given or given in path.parents


def shipped_models() -> list[str]:
    """The shipped two-person generators that this evaluation runs by default (reaction
    and interaction kinds of :data:`simenv.models.INTERACTION_MODELS`)."""
    shipped = set(available())
    return [n for n in interaction_model_names(*GENERATOR_KINDS) if n in shipped]


def generation_metrics(windows: idata.InteractionWindows, actor: np.ndarray,
                       reactor: np.ndarray, extractor: im.FeatureExtractor,
                       recognizer: Any, seed: int = 0) -> dict[str, Any]:
    """Metrics of an interaction generator's samples (both people generated from the
    class labels of ``windows``) against the real windows: per person FVD, FID,
    diversity, multimodality and E_b (vs each real window's first-frame bones, the
    body the sample should have), and recognition accuracy of the generated pair."""
    out: dict[str, Any] = {"windows": len(windows)}
    for person, gen, real in (("actor", actor, windows.actor),
                              ("reactor", reactor, windows.reactor)):
        gen, real = np.asarray(gen, np.float64), np.asarray(real, np.float64)
        fg, fr = extractor(gen), extractor(real)
        out[person] = {
            "FVD": im.frechet_feature_distance(fg, fr),
            "FID": im.frechet_feature_distance(im.pose_features(gen),
                                               im.pose_features(real)),
            "diversity": im.diversity(fg, seed=seed),
            "multimodality": im.multimodality(fg, windows.label, seed=seed),
            "E_b_mm": im.bone_length_error_mm(gen, real[:, 0], windows.skeleton.parents),
        }
    out["recognition_acc"], out["recognition_windows"] = recognizer.accuracy(
        actor, reactor, windows.label)
    return out


def evaluate(shared: Path = SHARED, data: Sequence[str | Path] | None = None,
             label: str | None = None, physics: bool = True, seed: int = 0,
             progress: bool = True, models: Sequence[str] | None = None) -> dict[str, Any]:
    """Run the whole evaluation (module docstring) and return the JSON-ready results.

    Args:
        models: two-person generators to evaluate next to the baselines (registry names
            of :data:`simenv.models.INTERACTION_MODELS`; None: every shipped one,
            :func:`shipped_models`).
    """
    models = shipped_models() if models is None else list(models)
    kinds = {name: interaction_model_entry(name, GENERATOR_KINDS)[2] for name in models}

    t0 = time.process_time()
    train, test, test_names = _train_test(shared, data, label)
    extractor, fallback = default_feature_extractor()
    recognizer = InteractionRecognizer(extractor).fit(train.actor, train.reactor,
                                                      train.label)
    results, reactions = _reaction_results(
        train, test, [n for n in models if kinds[n] == "reaction"], extractor, recognizer,
        seed, progress)
    generation, samples = _generation_results(
        test, [n for n in models if kinds[n] == "interaction"], extractor, recognizer, seed)
    generation_real = generation_metrics(test, test.actor, test.reactor, extractor,
                                         recognizer, seed) if samples else {}
    phys = _physics(test, reactions, samples, progress) if physics else {}
    return _jsonable({
        "pairs": len(test),
        "results": results,
        "generation": generation,
        "generation_real": generation_real,
        "physics": phys,
        "feature_extractor": extractor.name,
        "feature_fallback_reason": fallback,
        "data": {
            "fps": test.fps, "window": test.window, "stride": test.stride,
            "joints": list(test.joint_names), "labels": list(test.labels),
            "train_windows": len(train), "test_windows": len(test),
            "test_recordings": test_names,
            "train_recordings": sorted(set(train.recording_names) - set(test_names)),
            "test_labels": dict(Counter(test.window_labels.tolist())),
            "train_labels": dict(Counter(train.window_labels.tolist())),
            "key_joint_pairs": [list(p) for p in im.KEY_JOINT_PAIRS],
            "closest_real_approach_m": _closest_approach(test),
        },
        "cpu_seconds": time.process_time() - t0,
    })


def _train_test(shared: Path, data: Sequence[str | Path] | None, label: str | None
                ) -> tuple[idata.InteractionWindows, idata.InteractionWindows, list[str]]:
    """(train, test windows, test recording names): the corpus split by recording, or,
    with ``data``, those files as the test set and the corpus recordings not read from
    them as the training set.

    Raises:
        SimenvError: every corpus recording is among ``data``.
    """
    recordings = idata.load_recordings(shared)
    windows = idata.make_windows(recordings)
    if not data:
        split = idata.split_by_recording(windows)
        return windows.subset(split.train), windows.subset(split.test), list(split.test_clips)
    test_recs = [idata.load_interaction(p, label=label, name=f"data/{Path(p).name}")
                 for p in data]
    test = idata.make_windows(test_recs)
    # Corpus recordings read from the given files are held out of training too.
    given = [Path(p).resolve() for p in data]
    keep = [k for k, r in enumerate(recordings)
            if not any(_within(Path(f).resolve(), g) for f in r.metadata["sources"]
                       for g in given)]
    train = windows.subset(np.isin(windows.recording, keep))
    if len(train) == 0:
        raise SimenvError("every corpus recording is among --data: nothing left to "
                          "train the nearest neighbour on")
    return train, test, list(test.recording_names)


def _closest_approach(test: idata.InteractionWindows) -> dict[str, dict[str, float]]:
    """Test recording -> ``"A:<a>-B:<b>"`` -> the closest approach of that key joint pair
    over its windows, m."""
    closest = {}
    for r, rec in enumerate(test.recording_names):
        sel = test.recording == r
        if sel.any():
            d = im.joint_pair_distances(test.actor[sel], test.reactor[sel])
            closest[rec] = {f"A:{a}-B:{b}": float(d[..., k].min())
                            for k, (a, b) in enumerate(im.KEY_JOINT_PAIRS)}
    return closest


def _reaction_results(train: idata.InteractionWindows, test: idata.InteractionWindows,
                      models: Sequence[str], extractor: im.FeatureExtractor,
                      recognizer: InteractionRecognizer, seed: int, progress: bool
                      ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """:func:`reaction_metrics` and recognition accuracies of the reaction ``models`` and
    the baselines on the test windows, then of the real reactions (row :data:`REAL`, with
    the train-vs-test FVD); returns (results, method -> (N, T, J, 3) reactions)."""
    reactor_recognizer = InteractionRecognizer(extractor, use_actor=False).fit(
        train.actor, train.reactor, train.label)
    reactions: dict[str, np.ndarray] = {REAL: test.reactor.astype(np.float64)}
    results: dict[str, Any] = {}
    generators = [(name, load(name)) for name in models]
    generators += [(name, make_baseline(name, train.actor, train.reactor))
                   for name in BASELINE_NAMES]
    for name, gen in tqdm(generators, desc="reaction generators", unit="model",
                          disable=not progress):
        reactions[name] = _generated(test, gen)
        results[name] = reaction_metrics(test, reactions[name], extractor, seed)
    # The real reactions through the same code: 0 errors by construction, and the
    # diversity, multimodality and lag every method should match.
    results[REAL] = reaction_metrics(test, reactions[REAL], extractor, seed)
    results[REAL]["FVD_train_vs_test"] = im.frechet_feature_distance(
        extractor(train.reactor), extractor(test.reactor))
    for name, r in results.items():
        r["recognition_acc"], r["recognition_windows"] = recognizer.accuracy(
            test.actor, reactions[name], test.label)
        r["recognition_reactor_acc"], _ = reactor_recognizer.accuracy(
            test.actor, reactions[name], test.label)
    return results, reactions


def _generation_results(test: idata.InteractionWindows, models: Sequence[str],
                        extractor: im.FeatureExtractor, recognizer: InteractionRecognizer,
                        seed: int) -> tuple[dict[str, Any], dict[str, tuple]]:
    """:func:`generation_metrics` of each interaction model on one sample per test window
    of a class it knows; returns (results, model -> (window indices, actor, reactor))."""
    generation, samples = {}, {}
    for name in models:
        model = load(name)
        # Samples of the classes the model knows, one per test window of those classes.
        keep = np.flatnonzero(np.isin(test.window_labels.astype(str), list(model.labels)))
        if not len(keep):
            generation[name] = {"windows": 0, "reason": "no test window of a class the "
                                f"model knows ({', '.join(model.labels)})"}
            continue
        sub = test.subset(keep)
        actor, reactor = model.sample(list(sub.window_labels.astype(str)), seed=seed)
        samples[name] = (keep, np.asarray(actor, np.float64), np.asarray(reactor, np.float64))
        generation[name] = generation_metrics(sub, actor, reactor, extractor, recognizer,
                                              seed)
    return generation, samples


def _physics(test: idata.InteractionWindows, reactions: dict[str, np.ndarray],
             samples: dict[str, tuple], progress: bool) -> dict[str, Any]:
    """:func:`physics_of` the reactions and the interaction models' samples on the
    windows of :func:`physics_windows`."""
    phys_index = physics_windows(test)
    phys = physics_of(test, phys_index, reactions, progress)
    for name, (keep, actor, reactor) in samples.items():
        # A sample of a window's class is placed where that window was in the world.
        full_a, full_b = test.actor.astype(np.float64), test.reactor.astype(np.float64)
        full_a[keep], full_b[keep] = actor, reactor
        phys |= physics_of(test, [n for n in phys_index if n in keep], {name: full_b},
                           progress, actors={name: full_a})
    return phys


def _fmt(value: Any, spec: str) -> str:
    return "n/a" if value is None else spec.format(value)


def render_markdown(res: Mapping[str, Any]) -> str:
    """docs/interaction.md from the results of :func:`evaluate` (numbers as computed)."""
    lines = [*_md_protocol(res), *_md_results(res), *_md_generation(res), *_md_physics(res),
             "", f"CPU time of the run: {res['cpu_seconds']:.0f} s.", ""]
    return "\n".join(lines)


def _md_protocol(res: Mapping[str, Any]) -> list[str]:
    """The report's title, data, protocol and metric definitions."""
    d, results = res["data"], res["results"]
    lines = [
        "# Two-person generation: evaluation",
        "",
        "Generated by `python -m simenv.learning.eval_interaction` "
        "(simenv/learning/eval_interaction.py); do not edit by hand. Raw numbers: "
        "`interaction.json`; plot: `interaction.png` (beside this page).",
        "",
        "## Data and protocol",
        "",
        f"* Real two-person recordings at {d['fps']:g} fps on {len(d['joints'])} keypoints "
        f"({', '.join(d['joints'])}); windows of {d['window']} frames every {d['stride']} "
        "frames, normalised in the actor's first-frame frame (reactive-GAN normalisation, "
        "`simenv/data/interaction_data.py`).",
        f"* Split by recording. Train ({d['train_windows']} windows): "
        f"{', '.join(d['train_recordings'])}. Test ({d['test_windows']} windows): "
        f"{', '.join(d['test_recordings'])}.",
        f"* Test windows per class: {', '.join(f'{k} {v}' for k, v in d['test_labels'].items())};"
        f" train: {', '.join(f'{k} {v}' for k, v in d['train_labels'].items())}."
        + (" Classes with no training window are unseen by every trained method "
           f"({', '.join(k for k in d['test_labels'] if k not in d['train_labels'])})."
           if any(k not in d["train_labels"] for k in d["test_labels"]) else ""),
        "* Each method gets the real actor window and the real reactor's first frame; "
        "metrics are over frames 1..T-1 (the generated ones).",
        f"* Features of FVD, diversity and multimodality: **{res['feature_extractor']}**"
        + (f" — {res['feature_fallback_reason']}." if res["feature_fallback_reason"] else "."),
        "",
        "",
        "Closest approach of the key joint pairs in the real test windows (m; contact "
        "= below 0.15 m):",
        "",
        "| test recording | " + " | ".join(
            f"A {a} - B {b}" for a, b in d["key_joint_pairs"]) + " |",
        "|---|" + "---:|" * len(d["key_joint_pairs"]),
        *[f"| {rec} | " + " | ".join(f"{v:.3f}" for v in pairs.values()) + " |"
          for rec, pairs in d["closest_real_approach_m"].items()],
        "",
        "## Metrics (papers' definitions, `simenv/data/interaction_metrics.py`)",
        "",
        "* AFD: mean over frames of the squared L2 distance of the flattened pose (m², "
        "actor frame, reactive GAN). E_r: mean joint error (mm). E_b: mean bone-length "
        "error vs the reactor's first frame (mm).",
        "* JPD: mean |d̂ - d| of the key joint-pair distances "
        f"({'; '.join(f'A {a} - B {b}' for a, b in d['key_joint_pairs'])}), mm. Contact "
        "retention: fraction of the real contact frames (pair < 0.15 m) where the generated "
        "pair is in contact too (mean over pairs that touch in the real data).",
        "* FVD: Fréchet distance of window features (generated vs real test reactions); "
        "FID: the same on single-pose features (flattened pose). Diversity / multimodality: "
        "mean feature distance of random distinct pairs (all / within a class).",
        "* Lag err: mean |lag(A, B̂) - lag(A, B)| of the speed-profile cross-correlation "
        "lag, seconds, over windows where both are defined (a frozen reactor has none).",
        "* Recog. acc: accuracy of a classifier trained on the real training windows (both "
        "people; logistic regression on the FVD features, "
        "`simenv/learning/interaction_recognition.py`) "
        "on (real actor, generated reactor) test windows of the classes it was trained on "
        f"({_fmt(results[REAL].get('recognition_windows'), '{:d}')} windows). The actor "
        "alone gives the class away when few classes are trained, so `recog. B only` is "
        "the same with a classifier of the reactor's features alone.",
        "",
    ]
    return lines


def _md_results(res: Mapping[str, Any]) -> list[str]:
    """The reaction results: the headline table and E_r per class."""
    d, results = res["data"], res["results"]
    methods = list(results)
    lines = [
        "## Results (held-out windows)",
        "",
        "| method | " + " | ".join(h for _, h, _ in COLUMNS) + " |",
        "|---|" + "---:|" * len(COLUMNS),
    ]
    for m in methods:
        r = results[m]
        lines.append(f"| {m} | " + " | ".join(_fmt(r.get(k), f) for k, _, f in COLUMNS)
                     + " |")
    real = results[REAL]
    defined = ", ".join(f"{m} {results[m]['lag_defined_windows']}" for m in methods)
    lines += [
        "",
        f"Row `{REAL}`: the real test reactions through the same code (the reference). "
        f"Lag-defined windows: {defined} of {res['pairs']}. Mean lag of the real "
        f"reactions: {real['mean_lag_s']:.3f} s. "
        f"FVD between real train and real test reactions (distribution shift between "
        f"recordings): {real['FVD_train_vs_test']:.3f}.",
        "",
        "E_r (mm) per class:",
        "",
        "| method | " + " | ".join(d["labels"]) + " |",
        "|---|" + "---:|" * len(d["labels"]),
    ]
    for m in methods[:-1] if methods[-1] == REAL else methods:
        pl = results[m]["per_label"]
        lines.append(f"| {m} | " + " | ".join(
            _fmt(pl.get(lab, {}).get("E_r_mm"), "{:.0f}") for lab in d["labels"]) + " |")
    return lines


def _md_generation(res: Mapping[str, Any]) -> list[str]:
    """The interaction generators' table (none without one)."""
    gen, gen_real = res.get("generation") or {}, res.get("generation_real") or {}
    if not gen:
        return []
    keys = (("FVD", "{:.3f}"), ("FID", "{:.3f}"), ("diversity", "{:.3f}"),
            ("multimodality", "{:.3f}"), ("E_b_mm", "{:.1f}"))
    lines = [
        "",
        "## Interaction generation (both people from the class label)",
        "",
        "One sample per test window of a class the model was trained on, against the "
        "real test windows (the `real` row: all real test windows through the same "
        "code). E_b: bone-length error against the real window's first frame. Recog. "
        "acc: the classifier above on the generated pair.",
        "",
        "| model | windows | " + " | ".join(f"{p} {k}" for p in ("actor", "reactor")
                                          for k, _ in keys) + " | recog. acc |",
        "|---|---:|" + "---:|" * (2 * len(keys) + 1),
    ]
    for m, g in [*gen.items(), *([(REAL, gen_real)] if gen_real else [])]:
        if not g.get("windows"):
            lines.append(f"| {m} | 0 | {g.get('reason', '')} |")
            continue
        lines.append(f"| {m} | {g['windows']} | " + " | ".join(
            _fmt(g[p].get(k), f) for p in ("actor", "reactor") for k, f in keys)
            + f" | {_fmt(g.get('recognition_acc'), '{:.2f}')} |")
    return lines


def _md_physics(res: Mapping[str, Any]) -> list[str]:
    """The physics table of the scored windows (none without physics)."""
    phys = res["physics"]
    if not phys:
        return []
    n = next(iter(phys.values()))["windows"]
    lines = [
        "",
        "## Physics (`simenv.score`, physics on)",
        "",
        f"{n} windows, one per test recording (the window where the real right hands "
        "come closest), placed back in the world with the inverse normalisation; the "
        "actor is the real one in every row but those of interaction generators (both "
        "people generated, for the windows of classes they know).",
        "",
        "| method | reactor plausible | interaction plausible | reactor score | "
        "inter-pen. max (mm) | inter-pen. pass | scorer contact JPD (mm) | "
        "scorer contact retention | reactor failures |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for m, p in phys.items():
        fails = ", ".join(f"{k} {v}" for k, v in p["reactor_failed"].items()) or "none"
        lines.append(
            f"| {m} | {p['reactor_plausible']:.2f} | {p['interaction_plausible']:.2f} | "
            f"{p['reactor_score_mean']:.1f} | "
            f"{_fmt(p['inter_penetration_max_mm'], '{:.0f}')} | "
            f"{p['inter_penetration_pass']:.2f} | {_fmt(p['contact_jpd_mm'], '{:.1f}')} | "
            f"{_fmt(p['contact_retention'], '{:.2f}')} | {fails} |")
    lines += [
        "",
        f"Actor (real) plausible in {phys[REAL]['actor_plausible']:.2f} of the windows. "
        "The scorer's contact metric compares the retargeted bodies with the keypoints "
        "they were fitted to (does the body keep the contacts the motion shows); "
        "contact retention against the *real* reaction is the keypoint column above.",
    ]
    return lines


def plot(res: Mapping[str, Any], path: Path) -> Path:
    """Bar charts of the headline metrics per method (and physics if present)."""
    import matplotlib  # heavy, and only the report's figure needs it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    results = res["results"]
    methods = [m for m in results if m != REAL]
    keys = [("AFD", "AFD (m²)"), ("E_r_mm", "E_r (mm)"), ("JPD_mm", "JPD (mm)"),
            ("FVD", "FVD"), ("diversity", "diversity"), ("lag_error_s", "lag error (s)")]
    phys = res.get("physics") or {}
    panels = len(keys) + (1 if phys else 0)
    fig, axes = plt.subplots(1, panels, figsize=(2.6 * panels, 3.2))
    for ax, (k, title) in zip(axes, keys, strict=False):
        vals = [results[m].get(k) for m in methods]
        ax.bar(range(len(methods)), [np.nan if v is None else v for v in vals],
               color="tab:blue")
        if k == "diversity":
            ax.axhline(results[REAL]["diversity"], color="k", ls="--", lw=1, label="real")
            ax.legend(fontsize=7)
        ax.set_title(title, fontsize=9)
        ax.set_xticks(range(len(methods)), methods, rotation=60, fontsize=7)
    if phys:
        ax = axes[-1]
        names = list(phys)
        ax.bar(range(len(names)), [phys[m]["reactor_plausible"] for m in names],
               color="tab:green")
        ax.set_ylim(0, 1)
        ax.set_title("reactor plausible (physics)", fontsize=9)
        ax.set_xticks(range(len(names)), names, rotation=60, fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv: Sequence[str] | None = None,
         parser: argparse.ArgumentParser | None = None) -> int:
    """Command line entry point (see the module docstring; options on ``parser`` when
    given, e.g. ``simenv eval interaction``)."""
    ap = parser or argparse.ArgumentParser(prog="python -m simenv.learning.eval_interaction",
                                           description=__doc__.split("\n\n")[0])
    ap.add_argument("--shared", default=str(SHARED), help="shared/data folder (training "
                    "data, and the default test split)")
    ap.add_argument("--data", nargs="*", help="two-person files/folders to evaluate on "
                    "instead of the held-out split")
    ap.add_argument("--label", help="class label of --data files that carry none")
    ap.add_argument("--model", nargs="*", metavar="NAME", help="two-person generators to "
                    "evaluate next to the baselines (default: every shipped one)")
    ap.add_argument("--no-physics", action="store_true", help="skip simenv.score")
    ap.add_argument("--seed", type=int, default=0,
                    help="seed of the generators' sampling and of the metrics' random pairs")
    ap.add_argument("--out", default="out/interaction",
                    help="folder of interaction.md/.json/.png (the repository's page: --out docs)")
    ap.add_argument("--json", action="store_true", help="print the JSON results")
    ap.add_argument("--quiet", action="store_true", help="no progress bars")
    args = ap.parse_args(argv)
    import torch  # heavy; the models loaded later import it anyway, here it gets 1 thread

    torch.set_num_threads(1)
    try:
        res = evaluate(Path(args.shared), args.data, args.label, not args.no_physics,
                       args.seed, progress=not args.quiet, models=args.model)
    except SimenvError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "interaction.json").write_text(json.dumps(res, indent=1) + "\n")
    (out / "interaction.md").write_text(render_markdown(res))
    plot(res, out / "interaction.png")
    if args.json:
        print(json.dumps({"pairs": res["pairs"], "results": res["results"],
                          "generation": res["generation"]}, indent=1))
    else:
        print(render_markdown(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

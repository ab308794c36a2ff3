"""Depth-camera profiles: calibrate each sensor family on real clips, check on sources it never saw.

A depth camera estimates every joint on its own, so its bones change length and its joints
tremble; judged by the motion-capture thresholds nearly every real Kinect clip is
implausible. This script sets, per sensor family, the thresholds of the joint-level metrics
from that family's real clips, writes them to ``assets/profiles/depth_camera.json`` (the
profiles :mod:`simenv.plausibility.profiles` applies by default to clips of that family),
and measures them on whole sources kept out of the calibration.

Families, calibration and held-out sources (whole datasets: no clip, subject or setup of a
held-out source is seen by the calibration)

    ========== ================================== =====================================
    family     calibration                        held out (the check)
    ========== ================================== =====================================
    kinect_v1  MSR Action3D (Kinect SDK, 20        Florence 3D (215 clips) and the SBU
               joints, 506 clips, subjects 1-9)   Kinect Interaction sample (OpenNI,
               + UTKinect (20 sessions)           15 joints)
    kinect_v2  NuiSI (Nuitrack, both people,      NTU RGB+D (Kinect v2, 25 joints): the
               5-s windows of the two 86-s        real files of ``tests/data/ntu``
               recordings)
    ========== ================================== =====================================

    Reserved sets are never read: UTD-MHAD (not in the corpus), MSR Action3D subject 10 (not
    in the corpus; any ``_s10_`` file would be skipped), MSRC-12 (not in the corpus).
    A second, reverse check (not shipped) calibrates ``kinect_v1`` on Florence 3D + SBU and
    judges MSR Action3D and UTKinect.

Threshold rule (:func:`fit_profile`)
    Per joint-level metric, from the calibration people's values at the default thresholds:
    ``threshold = max(default, P99)``, the 99th percentile (linear, every person one value)
    of the calibration values; written as the fields that put the metric's pass level there
    (``bone_length`` in tolerances and ``velocity`` in fractions of the limits scale their
    fields; the others take the value in their unit). ``jitter``'s value depends on
    ``normalized_jerk_max``, not on its pass level, so its percentile is set directly.
    Body-level metrics (physics on) are not measured here: the ``kinect_v1`` profile carries
    the body-level thresholds of its two calibration corpora over from
    :data:`simenv.plausibility.body_thresholds.SOURCE_BODY_THRESHOLDS` (their leave-clips-out
    calibration, the larger of the two per field); ``kinect_v2`` borrows them (no Kinect v2
    clip was scored with physics: one 5-s NuiSI window took 16 minutes).

Checks (:func:`evaluate`), physics off (the joint-level verdict)
    * real clips inside (every metric passes) with the defaults (before) and with their
      family's profile (after), per source;
    * every corruption of :data:`simenv.plausibility.corrupt.CORRUPTIONS` (seed 0) of every
      held-out person that is inside, at the registry's moderate strength and at three times
      it (capped at the generator's maximum): outside the profile, and caught by the metric
      the corruption targets;
    * CMU clips are detected as motion capture and keep the defaults.

Sensor checks (:mod:`depth_camera_sensor_checks`), measured, not shipped
    ``limb_persistence`` (joins ``bone_length``) and ``body_jump`` (joins ``velocity``), each
    limited at the P99 of the calibration people; ``limb_persistence``'s running-median
    window is the one of :data:`WINDOWS` that catches most ``bone_stretch`` copies of the
    calibration people (:func:`choose_window`). Judged once on the held-out sources they
    put more real clips outside than they caught corruptions, so the script writes their
    limits to each profile's ``provenance["sensor_measured"]``, not as checks the scorer
    runs; the tables report the held-out sources with and without them.
    :func:`filter_study` (calibration people only) measures whether a temporal denoiser
    lowers the tails the thresholds sit on.

Usage (about a minute)::

    .venv/bin/python benchmarks/depth_camera_profiles.py            # fit, write, evaluate, docs
    .venv/bin/python benchmarks/depth_camera_profiles.py --no-write # evaluate the shipped file
"""

from __future__ import annotations

import argparse
import json
import re
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
from depth_camera_sensor_checks import SENSOR_FIELDS, sensor_failures, sensor_limits, sensor_values
from doc_sections import replace_section

import simenv  # noqa: F401  (MUJOCO_GL before mujoco)
from simenv.core.config import shared_data_root
from simenv.core.errors import SimenvError
from simenv.core.motion import Interaction, Motion
from simenv.io import kinder_gator, msrc12
from simenv.io.loader import load
from simenv.learning.cross_dataset import MSRC12_RESERVED
from simenv.plausibility import kinematic_metrics
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, SOURCE_BODY_THRESHOLDS
from simenv.plausibility.corrupt import CORRUPTIONS, MIN_FRAMES, STRETCH_BONES
from simenv.plausibility.metrics.bone_length import bone_deviations, measured_bones
from simenv.plausibility.profiles import (
    PROFILE_FILE,
    Profile,
    at_profile_rate,
    detect_source,
    for_clip,
)
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds

REPO = Path(__file__).resolve().parents[1]
DATA = shared_data_root()
PROFILES = REPO / "assets" / Path(*PROFILE_FILE)
DOC = REPO / "docs" / "plausibility.md"
OUT = REPO / "out" / "depth_camera_profiles"
BEGIN, END = "<!-- depth-camera-profiles:begin -->", "<!-- depth-camera-profiles:end -->"

#: Percentile of the calibration values that sets each threshold.
PERCENTILE = 99.0
#: NuiSI's two 86-s recordings are cut into windows of this many seconds (NTU clips last 2-10 s).
WINDOW_S = 5.0
#: Running-median windows (frames) tried for the ``limb_persistence`` sensor check; the
#: calibration picks one (:func:`choose_window`).
WINDOWS = (3, 5, 7)
#: The stronger corruption level: this multiple of the registry's moderate strength.
STRONG = 3.0
#: Upper bound of each generator's strength (its own argument check).
STRENGTH_MAX = {"foot_slide": 10.0, "bone_stretch": 1.0, "sink": 100.0, "float": 100.0,
                "jitter": 10.0, "teleport": 10.0, "time_warp": 20.0}


@dataclass(frozen=True)
class Source:
    """One real corpus: its family, its role and where it is."""

    name: str
    family: str
    role: str  # "calibration" or "held_out"
    paths: tuple[Path, ...]


SOURCES: tuple[Source, ...] = (
    Source("msr_action3d", "kinect_v1", "calibration", (DATA / "gestures" / "msr_action3d",)),
    Source("utkinect", "kinect_v1", "calibration", (DATA / "gestures" / "utkinect" / "joints",)),
    Source("florence3d", "kinect_v1", "held_out",
           (DATA / "gestures" / "florence3d" / "skeletal_data.mat",)),
    Source("sbu", "kinect_v1", "held_out", (DATA / "other" / "sbu_kinect_sample",)),
    Source("nuisi", "kinect_v2", "calibration", (DATA / "other" / "nuisi",)),
    Source("ntu", "kinect_v2", "held_out", (REPO / "tests" / "data" / "ntu",)),
)
#: MSRC-12 recordings last about a minute: each gives its first and its middle 5-s window.
MSRC12_WINDOWS = 2
#: The reverse check of kinect_v1 (not shipped): calibration and held-out swapped.
REVERSE = {"calibration": ("florence3d", "sbu"), "held_out": ("msr_action3d", "utkinect")}

#: Per metric, the threshold fields its pass level scales with (several fields, or a
#: value in tolerances) or equals (one field, in the metric's unit; floating mm -> m).
FIELDS: dict[str, tuple[str, ...]] = {
    "bone_length": ("bone_length_rel_max", "bone_length_head_rel_max"),
    "foot_skate": ("skate_ratio_max",),
    "ground_penetration": ("penetration_max_mm",),
    "floating": ("float_height_m",),
    "jitter": ("high_jerk_percent_max",),
    "velocity": ("speed_limit_trunk_mps", "speed_limit_limb_mps", "speed_limit_distal_mps",
                 "teleport_distance_m", "teleport_accel_mps2"),
}
SCALED = ("bone_length", "velocity")


@dataclass
class Person:
    """One real person (or NuiSI window), its metric values and its sensor-check values
    per running-median window."""

    source: str
    label: str
    motion: Motion
    values: dict[str, float]
    sensor: dict[int, dict[str, float]]


def _files(path: Path) -> list[Path]:
    if path.is_file():
        return [path]
    return sorted(p for p in path.iterdir() if p.is_file() and not p.name.startswith(".")
                  and p.suffix.lower() in (".txt", ".skeleton", ".mat")
                  and "label" not in p.name.lower())


def source_motions(source: Source) -> Iterator[tuple[str, Motion]]:
    """(label, motion) of every person of ``source`` (NuiSI: 5-s windows; MSRC-12: the first
    and middle 5-s windows of each recording, person p06 never read; Kinder-Gator: each
    recording whole)."""
    if source.name == "msrc12":
        for f in sorted(source.paths[0].glob("*.csv")):
            person = re.search(r"_p(\d+)$", f.stem)
            if person is None or int(person.group(1)) in MSRC12_RESERVED:
                continue
            try:
                m = msrc12.read(f)
            except SimenvError:  # a recording with no tracked frame: nothing to judge
                continue
            n = int(round(WINDOW_S * m.fps))
            for s in sorted({0, max(0, (m.num_frames - n) // 2)})[:MSRC12_WINDOWS]:
                if m.num_frames - s >= MIN_FRAMES:
                    yield f"{f.name}@{s}", m.slice(s, min(m.num_frames, s + n))
        return
    if source.name == "kindergator":
        for f in sorted(source.paths[0].rglob("POSE-*.csv")):
            try:
                yield f.name, kinder_gator.read(f)
            except SimenvError:  # a recording with no tracked frame: nothing to judge
                continue
        return
    if source.name == "utkinect":
        loaded = load(source.paths[0])
        for m in loaded if isinstance(loaded, list) else [loaded]:
            yield Path(str(m.metadata["source"])).name, m
        return
    for f in _files(source.paths[0]):
        if "_s10_" in f.name:  # MSR Action3D subject 10 is reserved for evaluation
            continue
        try:
            loaded = load(f)
        except SimenvError:  # the all-zero MSR file: nothing to judge
            continue
        for k, clip in enumerate(loaded if isinstance(loaded, list) else [loaded]):
            people = clip.people if isinstance(clip, Interaction) else (clip,)
            for i, m in enumerate(people):
                label = f"{f.name}#{k}/{i}"
                if source.name != "nuisi":
                    yield label, m
                    continue
                n = int(round(WINDOW_S * m.fps))
                for s in range(0, m.num_frames - n + 1, n):
                    yield f"{label}@{s}", m.slice(s, s + n)


def values_of(results: dict[str, Any]) -> dict[str, float]:
    """Metric -> value of the available metrics of one clip."""
    return {n: float(r.value) for n, r in results.items() if r.passed is not None}


def read_people(sources: Sequence[Source] = SOURCES) -> dict[str, list[Person]]:
    """Every person of every source, with its values at the default thresholds."""
    out: dict[str, list[Person]] = {}
    for source in sources:
        people = []
        for label, m in source_motions(source):
            people.append(Person(source.name, label, m, values_of(kinematic_metrics(m)),
                                 {w: sensor_values(m, w) for w in WINDOWS}))
        out[source.name] = people
    return out


def choose_window(name: str, people: Sequence[Person], percentile: float = PERCENTILE
                  ) -> tuple[int, dict[str, Any]]:
    """The ``limb_persistence`` window of :data:`WINDOWS` whose limit (``percentile`` of the
    calibration people) catches most ``bone_stretch`` copies (seed 0, moderate and
    :data:`STRONG` x) of the calibration people themselves (no held-out clip); ties go to
    the shorter window. Returns (window, caught share per window and level)."""
    c = CORRUPTIONS["bone_stretch"]
    copies: dict[str, list[dict[int, float]]] = {"moderate": [], "strong": []}
    for p in people:
        if p.motion.num_frames < MIN_FRAMES:
            continue
        for level, k in (("moderate", 1.0), ("strong", STRONG)):
            try:
                bad = c.fn(p.motion, min(k * c.moderate, STRENGTH_MAX["bone_stretch"]), seed=0)
            except SimenvError:
                continue
            copies[level].append({w: sensor_values(bad, w)["limb_persistence"]
                                  for w in WINDOWS})
    scores: dict[str, Any] = {}
    for w in WINDOWS:
        lim = sensor_limits([p.sensor for p in people], w, percentile)["limb_persistence_max"]
        scores[str(w)] = {lv: float(np.mean([v[w] > lim for v in vals])) if vals else 0.0
                          for lv, vals in copies.items()}
    best = max(WINDOWS, key=lambda w: (sum(scores[str(w)].values()), -w))
    return best, {"family": name, "caught_in_calibration": scores}


def fit_profile(name: str, people: Sequence[Person], sources: Sequence[str],
                percentile: float = PERCENTILE) -> dict[str, Any]:
    """The family profile from the calibration people (module docstring's rule) at
    ``percentile``."""
    thresholds: dict[str, float] = {}
    levels: dict[str, dict[str, float]] = {}
    for metric, names in FIELDS.items():
        v = np.array([p.values[metric] for p in people if metric in p.values])
        v = v[np.isfinite(v)]
        if len(v) == 0:
            continue
        level = float(np.percentile(v, percentile))
        prior = 1.0 if metric in SCALED else float(getattr(DEFAULT_THRESHOLDS, names[0]))
        if metric == "floating":
            prior *= 1000.0
        levels[metric] = {"p50": float(np.percentile(v, 50)), f"p{percentile:g}": level,
                          "max": float(v.max()), "default": prior, "people": int(len(v))}
        if level <= prior:
            continue
        for f in names:
            base = float(getattr(DEFAULT_THRESHOLDS, f))
            if metric in SCALED:
                thresholds[f] = round(base * level, 4)
            elif metric == "floating":
                thresholds[f] = round(level / 1000.0, 4)
            else:
                thresholds[f] = round(level, 4)
    body: dict[str, float] = {}
    carried = [s for s in sources if s in SOURCE_BODY_THRESHOLDS]
    for f in fields(DEFAULT_BODY_THRESHOLDS):
        vals = [getattr(SOURCE_BODY_THRESHOLDS[s], f.name) for s in carried]
        default = getattr(DEFAULT_BODY_THRESHOLDS, f.name)
        if vals and max(vals) != default:
            body[f.name] = float(max(vals))
    counts: dict[str, int] = {}
    for p in people:
        counts[p.source] = counts.get(p.source, 0) + 1
    window, window_scores = choose_window(name, people, percentile)
    sensor = sensor_limits([p.sensor for p in people], window, percentile)
    return {
        "thresholds": thresholds,
        "body": body,
        "fps": float(np.median([p.motion.fps for p in people])),
        "provenance": {
            "family": name,
            "calibration_sources": {s: counts.get(s, 0) for s in sources},
            "rule": f"per joint-level metric: max(default, {percentile:g}th percentile of the "
                    "calibration people's values at the default thresholds), written as the "
                    "fields that put the metric's pass level there",
            "values": levels,
            "body_rule": ("carried over from SOURCE_BODY_THRESHOLDS of the calibration "
                          f"corpora ({', '.join(carried)}): the larger value per field"
                          if carried else "none: body-level metrics keep the defaults"),
            "sensor_rule": f"each sensor check's limit: the {percentile:g}th percentile of "
                           "the calibration people's values; limb_persistence's running-median "
                           f"window the one of {list(WINDOWS)} frames whose limit catches most "
                           "bone_stretch copies (seed 0, moderate and "
                           f"{STRONG:g}x) of the calibration people",
            "sensor_window_choice": window_scores["caught_in_calibration"],
            # Measured, not shipped: judged once on the held-out sources they cost more
            # real clips than they catch defects (docs/plausibility.md).
            "sensor_measured": sensor,
            "nuisi_window_s": WINDOW_S if "nuisi" in sources else None,
            "script": "benchmarks/depth_camera_profiles.py",
        },
    }


def _profile(name: str, raw: dict[str, Any]) -> Profile:
    """The profile of a fitted or shipped ``raw`` (its measured sensor limits stay in
    ``provenance["sensor_measured"]``)."""
    return Profile(name, dict(raw["thresholds"]), dict(raw["body"]), dict(raw["provenance"]),
                   raw.get("fps"))


def _measured(profile: Profile) -> dict[str, float]:
    """The sensor-check limits measured with ``profile`` (empty: none)."""
    return dict(profile.provenance.get("sensor_measured", {}))


def _thresholds(profile: Profile | None) -> Thresholds:
    return DEFAULT_THRESHOLDS if profile is None else replace(DEFAULT_THRESHOLDS,
                                                              **profile.thresholds)


def failed(m: Motion, profile: Profile | None, sensor: dict[str, float] | None = None
           ) -> list[str]:
    """Joint-level metrics ``m`` fails under ``profile`` (None: the mocap defaults): by
    their thresholds or by the sensor check (limits ``sensor``; None: none) that joins
    them."""
    profile = for_clip(profile, m)  # as simenv.score judges it: a rigid file's bones stay
    m = at_profile_rate(m, profile)
    out = [n for n, r in kinematic_metrics(m, _thresholds(profile)).items()
           if r.passed is False]
    return out + [n for n in sensor_failures(m, sensor) if n not in out]


def _pct(k: int, n: int) -> str:
    return f"{100 * k / n:.1f} % ({k}/{n})" if n else "-"


def judge_sources(people: dict[str, list[Person]], names: Sequence[str],
                  profile: Profile, sensor: dict[str, float] | None = None
                  ) -> dict[str, dict[str, Any]]:
    """Per source: people inside with the defaults and with ``profile`` (and the sensor
    limits ``sensor``), and the metrics that put the others outside."""
    out = {}
    for s in names:
        before = after = 0
        outside: dict[str, int] = {}
        for p in people[s]:
            before += not failed(p.motion, None)
            f = failed(p.motion, profile, sensor)
            after += not f
            for n in f:
                outside[n] = outside.get(n, 0) + 1
        out[s] = {"people": len(people[s]), "inside_default": before, "inside_profile": after,
                  "outside_by": outside}
    return out


def corruptions(people: Sequence[Person], profile: Profile,
                sensor: dict[str, float] | None = None) -> dict[str, dict[str, Any]]:
    """Per corruption and level: copies of the inside people outside the profile (and the
    sensor limits ``sensor``), and caught by the targeted metric."""
    inside = [p for p in people
              if not failed(p.motion, profile, sensor) and p.motion.num_frames >= MIN_FRAMES]
    out: dict[str, dict[str, Any]] = {}
    for name, c in CORRUPTIONS.items():
        for level, strength in (("moderate", c.moderate),
                                ("strong", min(STRONG * c.moderate, STRENGTH_MAX[name]))):
            made = outside = caught = 0
            for p in inside:
                try:
                    bad = c.fn(p.motion, strength, seed=0)
                except SimenvError:
                    continue
                made += 1
                f = failed(bad, profile, sensor)
                outside += bool(f)
                caught += any(t in f for t in c.targets)
            out[f"{name}/{level}"] = {"strength": strength, "copies": made, "outside": outside,
                                      "caught": caught, "targets": list(c.targets)}
    return out


def limb_noise(m: Motion) -> float:
    """Largest 95th-percentile relative deviation over frames of the clip's limb bones (the
    source bones ending at a canonical knee, ankle, elbow or wrist: what ``bone_stretch``
    stretches); NaN without one."""
    sk = m.skeleton
    role = {v: k for k, v in sk.canonical.items()}
    limb = [d["p95_tolerances"] * d["tolerance"]
            for (_, c), d in zip(measured_bones(sk), bone_deviations(m), strict=True)
            if d["checked"] and role.get(sk.joint_names[c]) in STRETCH_BONES]
    return max(limb) if limb else float("nan")


def goals(res: dict[str, Any]) -> list[str]:
    """The issue's goals against the held-out numbers, met or not: the profile's thresholds
    alone (before the sensor checks) and with its sensor checks."""
    lines = ["| held-out source | judged by | real clips inside (goal >= 90 %) | corruptions "
             "outside, moderate / 3x (goal >= 90 %) | caught by the targeted metric, "
             "moderate / 3x |",
             "|---|---|---|---|---|"]
    rows = [(s.name, how, part) for s in SOURCES if s.role == "held_out"
            for how, part in (("thresholds only", res["thresholds_only"]),
                              ("thresholds + sensor checks", res))]
    for name, how, part in rows:
        r = part["sources"][name]
        share = r["inside_profile"] / r["people"]
        tot = {lv: [0, 0, 0] for lv in ("moderate", "strong")}
        for key, c in part["corruptions"][name].items():
            for i, k in enumerate(("copies", "outside", "caught")):
                tot[key.split("/")[1]][i] += c[k]
        cells = []
        for i in (1, 2):
            cells.append(" / ".join(
                f"{100 * t[i] / t[0]:.1f} %{'' if t[i] / t[0] >= 0.9 else ' (not met)'}"
                if t[0] else "-" for t in tot.values()))
        lines.append(f"| {name} ({r['people']} people) | {how} | {100 * share:.1f} %"
                     f"{'' if share >= 0.9 else ' (not met)'} | {cells[0]} | {cells[1]} |")
    return lines


def held_cost(res: dict[str, Any]) -> str:
    """Held-out real clips inside by thresholds only -> with the sensor checks, and the
    metrics that put them outside, in words."""
    parts = []
    for s in SOURCES:
        if s.role != "held_out":
            continue
        a, b = res["thresholds_only"]["sources"][s.name], res["sources"][s.name]
        parts.append(f"{s.name} {_pct(a['inside_profile'], a['people'])} inside -> "
                     f"{_pct(b['inside_profile'], b['people'])}")
    return "; ".join(parts)


def cmu_profiles() -> dict[str, int]:
    """Profiles picked for the shared CMU clips (all should be ``mocap``)."""
    counts: dict[str, int] = {}
    for folder in ("cmu/bvh", "cmu/asf_amc"):
        for f in sorted((DATA / folder).iterdir()):
            if f.suffix.lower() not in (".bvh", ".amc"):
                continue
            kind = detect_source(load(f))
            counts[kind.profile] = counts.get(kind.profile, 0) + 1
    return counts


def evaluate(people: dict[str, list[Person]], profiles: dict[str, Profile],
             reverse: Profile, sources: Sequence[Source] = SOURCES) -> dict[str, Any]:
    """Every number of the report (module docstring): each profile judged with its measured
    sensor limits (``provenance["sensor_measured"]``) and, on the held-out sources, also by
    its thresholds alone (``"thresholds_only"``)."""
    out: dict[str, Any] = {"sources": {}, "corruptions": {}, "reverse": {},
                           "thresholds_only": {"sources": {}, "corruptions": {}}}
    for fam, profile in profiles.items():
        names = [s.name for s in sources if s.family == fam]
        sensor = _measured(profile)
        out["sources"].update(judge_sources(people, names, profile, sensor))
        held = [s.name for s in sources if s.family == fam and s.role == "held_out"]
        out["thresholds_only"]["sources"].update(judge_sources(people, held, profile))
        for s in held:
            out["corruptions"][s] = corruptions(people[s], profile, sensor)
            out["thresholds_only"]["corruptions"][s] = corruptions(people[s], profile)
    rev_sensor = _measured(reverse)
    out["reverse"]["sources"] = judge_sources(people, REVERSE["held_out"], reverse, rev_sensor)
    out["reverse"]["corruptions"] = {
        s: corruptions(people[s], reverse, rev_sensor) for s in REVERSE["held_out"]}
    out["cmu_profiles"] = cmu_profiles()
    out["filter_study"] = filter_study(people)
    out["families"] = {s.name: s.family for s in sources}
    out["roles"] = {s.name: s.role for s in sources}
    out["limb_noise"] = {}
    for s in sources:
        v = np.array([limb_noise(p.motion) for p in people[s.name]])
        v = v[np.isfinite(v)]
        out["limb_noise"][s.name] = {q: float(np.percentile(v, q)) for q in (10, 50, 90, 99)}
    return out


def _local_median(m: Motion, window: int) -> Motion:
    """``m`` with each joint's offset from the keypoints' centroid replaced by its running
    median over ``window`` frames (the centroid itself kept): a temporal denoiser that
    leaves whole-body moves (sink, float, slide, teleport) alone."""
    from scipy.ndimage import median_filter

    p = m.positions.astype(np.float64)
    c = p.mean(axis=1, keepdims=True)
    local = median_filter(p - c, size=(window, 1, 1), mode="nearest")
    return m.with_positions((c + local).astype(np.float32))


#: Metrics whose calibration tails :func:`filter_study` compares.
FILTERED = ("bone_length", "ground_penetration", "floating", "foot_skate")


def filter_study(people: dict[str, list[Person]]) -> dict[str, dict[str, dict[str, float]]]:
    """Calibration people only: P99 (the profile rule's level) of :data:`FILTERED` metrics
    with no denoising and after :func:`_local_median` of 3, 5 and 7 frames. The family
    thresholds sit where the P99 is, so a denoiser helps only if it lowers it."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for fam in ("kinect_v1", "kinect_v2"):
        cal = [p for s in SOURCES if s.family == fam and s.role == "calibration"
               for p in people[s.name]]
        out[fam] = {}
        for w in (1, 3, 5, 7):
            vals = [p.values if w == 1 else values_of(kinematic_metrics(_local_median(
                p.motion, w))) for p in cal]
            out[fam][str(w)] = {
                k: float(np.percentile([v[k] for v in vals if k in v], PERCENTILE))
                for k in FILTERED}
    return out


#: Percentiles compared by :func:`sweep`.
SWEEP = (90.0, 95.0, 99.0, 100.0)


def sweep(people: dict[str, list[Person]]) -> dict[str, dict[str, Any]]:
    """Per percentile of the rule: held-out people inside and their corruptions outside."""
    out: dict[str, dict[str, Any]] = {}
    for q in SWEEP:
        row: dict[str, Any] = {}
        for fam in ("kinect_v1", "kinect_v2"):
            names = [s.name for s in SOURCES if s.family == fam and s.role == "calibration"]
            prof = _profile(fam, fit_profile(fam, [p for s in names for p in people[s]],
                                             names, q))
            held = [s.name for s in SOURCES if s.family == fam and s.role == "held_out"]
            for s, r in judge_sources(people, held, prof).items():
                tot = {lv: [0, 0] for lv in ("moderate", "strong")}
                for key, c in corruptions(people[s], prof).items():
                    tot[key.split("/")[1]][0] += c["copies"]
                    tot[key.split("/")[1]][1] += c["outside"]
                row[s] = {"people": r["people"], "inside": r["inside_profile"],
                          "corruptions": tot}
        out[f"{q:g}"] = row
    return out


def _sweep_rows(res: dict[str, dict[str, Any]]) -> list[str]:
    held = [s.name for s in SOURCES if s.role == "held_out"]
    lines = ["| percentile | " + " | ".join(
        f"{s}: inside / corruptions outside (moderate, 3x)" for s in held) + " |",
        "|---|" + "---|" * len(held)]
    for q, row in res.items():
        cells = []
        for s in held:
            r = row[s]
            c = r["corruptions"]
            cells.append(f"{100 * r['inside'] / r['people']:.1f} % / "
                         + ", ".join(f"{100 * o / n:.1f} %" if n else "-"
                                     for n, o in (c["moderate"], c["strong"])))
        lines.append(f"| P{q} | " + " | ".join(cells) + " |")
    return lines


def _threshold_table(profiles: dict[str, dict[str, Any]]) -> list[str]:
    lines = ["| field | default | " + " | ".join(profiles) + " |",
             "|---|---|" + "---|" * len(profiles)]
    names = sorted({f for p in profiles.values() for f in p["thresholds"]},
                   key=[f.name for f in fields(Thresholds)].index)
    for f in names:
        lines.append(f"| `{f}` | {getattr(DEFAULT_THRESHOLDS, f):g} | " + " | ".join(
            f"{p['thresholds'][f]:g}" if f in p["thresholds"] else "default"
            for p in profiles.values()) + " |")
    for f in SENSOR_FIELDS:
        lines.append(f"| `{f}` (sensor check: measured, not shipped) | none | " + " | ".join(
            f"{p['provenance']['sensor_measured'][f]:g}"
            if f in p["provenance"].get("sensor_measured", {}) else "none"
            for p in profiles.values()) + " |")
    body = sorted({f for p in profiles.values() for f in p["body"]},
                  key=[f.name for f in fields(DEFAULT_BODY_THRESHOLDS)].index)
    for f in body:
        lines.append(f"| `{f}` (body) | {getattr(DEFAULT_BODY_THRESHOLDS, f):g} | " + " | ".join(
            f"{p['body'][f]:g}" if f in p["body"] else "default" for p in profiles.values())
            + " |")
    return lines


def _source_rows(res: dict[str, dict[str, Any]], role: dict[str, str],
                 fam: dict[str, str]) -> list[str]:
    lines = ["| source | family | role | people | inside, mocap defaults (before) | "
             "inside, family profile (after) | outside the profile by |",
             "|---|---|---|---|---|---|---|"]
    for s, r in res.items():
        by = ", ".join(f"`{k}` {v}" for k, v in sorted(r["outside_by"].items())) or "-"
        lines.append(f"| {s} | {fam[s]} | {role[s]} | {r['people']} | "
                     f"{_pct(r['inside_default'], r['people'])} | "
                     f"{_pct(r['inside_profile'], r['people'])} | {by} |")
    return lines


def _corruption_rows(res: dict[str, dict[str, Any]]) -> list[str]:
    lines = ["| source | corruption | level (strength) | copies | outside the profile | "
             "caught by its target metric |", "|---|---|---|---|---|---|"]
    for s, table in res.items():
        tot = {"moderate": [0, 0, 0], "strong": [0, 0, 0]}
        for key, r in table.items():
            name, level = key.split("/")
            lines.append(f"| {s} | {name} | {level} ({r['strength']:g}) | {r['copies']} | "
                         f"{_pct(r['outside'], r['copies'])} | {_pct(r['caught'], r['copies'])} "
                         f"(`{'`, `'.join(r['targets'])}`) |")
            for i, k in enumerate(("copies", "outside", "caught")):
                tot[level][i] += r[k]
        for level, (n, o, c) in tot.items():
            lines.append(f"| **{s}** | **all** | {level} | {n} | **{_pct(o, n)}** | "
                         f"**{_pct(c, n)}** |")
    return lines


def markdown(profiles: dict[str, dict[str, Any]], res: dict[str, Any], seconds: float) -> str:
    """The generated section of docs/plausibility.md."""
    role = {n: ("calibration" if r == "calibration" else "**held out**")
            for n, r in res["roles"].items()}
    lines = [
        f"Generated by `benchmarks/depth_camera_profiles.py` ({seconds:.0f} s; do not edit by "
        "hand). The profiles are in `assets/profiles/depth_camera.json` (installed as "
        "`simenv/assets/profiles/`), with how they were computed; `simenv.score` and "
        "`simenv score` apply them by default (`--source auto`) to clips whose skeleton is a "
        "depth camera's and record the "
        "profile in each record (`\"profile\"`).",
        "",
        f"**Rule.** Per joint-level metric, `max(default, P{PERCENTILE:g})` of the "
        "calibration people's values at the default thresholds (linear percentile, one value "
        "per person; NuiSI cut into "
        f"{WINDOW_S:g}-s windows), written as the fields that put the metric's pass level "
        "there. Body-level (physics-on) thresholds: `kinect_v1` carries those of its two "
        "calibration corpora over from `SOURCE_BODY_THRESHOLDS` (larger per field); "
        "`kinect_v2` borrows them: they are not measured on Kinect v2 clips.",
        "",
        "**Sensor checks** (`benchmarks/depth_camera_sensor_checks.py`). The thresholds "
        "sit on each family's worst real clips, so a moderate defect hides under them. Two "
        "checks measure what the sensor's noise is not, each against its family's own limit "
        f"(P{PERCENTILE:g} of the calibration people) and joined to the verdict of the metric "
        "that owns the defect: `limb_persistence` (`bone_length`): per limb bone (thigh, "
        "shin, upper arm, forearm), the 95th percentile over frames of its running-median "
        "length change divided by its own frame-to-frame length noise (RMS of the rest) "
        "plus 1 %; the window of "
        f"{', '.join(map(str, WINDOWS))} frames is the one whose limit catches most "
        "`bone_stretch` copies of the calibration people themselves. `body_jump` "
        "(`velocity`): the largest second difference of the keypoints' centroid, where "
        "joint-independent noise averages out and a whole-body jump does not. Motion "
        "capture and body models have no sensor checks. **Measured, not shipped**: scored "
        "once on the held-out sources (goals table below), the checks put real clips "
        "outside (" + held_cost(res) + ") and catch few more corruptions: the length noise "
        "of an OpenNI or a Kinect v2 skeleton is not that of the calibration sensors, so "
        "a limit in units of it does not transfer. The bundled profiles judge by their "
        "thresholds alone; each keeps its measured limits in `provenance.sensor_measured` "
        "(`simenv.score` runs no sensor check). In the tables below, \"profile\" means "
        "thresholds + sensor checks.",
        "",
        "**Held-out design.** Whole sources are kept out of each calibration: `kinect_v1` is "
        "calibrated on MSR Action3D (Kinect SDK, 20 joints, subjects 1-9) and UTKinect and "
        "judged on Florence 3D and the SBU sample (OpenNI, 15 joints); `kinect_v2` is "
        "calibrated on NuiSI (Nuitrack) and judged on NTU RGB+D (Kinect v2; the real files "
        "of `tests/data/ntu`). `kinect_v1@30` (the Kinect v1 family at the sensor's own 30 "
        "fps) is calibrated on MSRC-12 (person p06 never read) and Kinder-Gator, read from "
        "copies outside the repository, and judged on a third 30-fps source, NiTE "
        "recordings written as BVH (`benchmarks/depth_bvh_survey.py`, below). Reserved sets "
        "are never read.",
        "",
        "Thresholds of the shipped profiles:",
        "",
        *_threshold_table(profiles),
        "",
        "Calibration values (at the default thresholds) behind each joint-level threshold:",
        "",
        "| family | metric | people | p50 | p99 | max | default |",
        "|---|---|---|---|---|---|---|",
    ]
    for fam, p in profiles.items():
        for metric, v in p["provenance"]["values"].items():
            lines.append(f"| {fam} | `{metric}` | {v['people']} | {v['p50']:.3g} | "
                         f"{v[f'p{PERCENTILE:g}']:.3g} | {v['max']:.3g} | {v['default']:g} |")
    lines += ["", "Real clips inside (every joint-level metric passes; physics off), before "
              "(mocap defaults) and after (family profile). Every source gets a body with "
              "physics on (Florence 3D and SBU, which have no pelvis joint, with the pelvis at "
              "the hips' midpoint), whose metrics this table leaves out:", "",
              *_source_rows(res["sources"], role, res["families"]), "",
              "Seeded corruptions (`simenv.plausibility.corrupt`, seed 0) of the held-out "
              "people that are inside their profile, at the registry's moderate strength and "
              f"at {STRONG:g}x it (capped at the generator's maximum), judged by the profile:",
              "", *_corruption_rows(res["corruptions"]), "",
              "Reverse check (not shipped): `kinect_v1` calibrated on Florence 3D + SBU, "
              "judged on MSR Action3D and UTKinect:", "",
              *_source_rows(res["reverse"]["sources"],
                            {s: "**held out**" for s in REVERSE["held_out"]},
                            res["families"]), "",
              *_corruption_rows(res["reverse"]["corruptions"]), "",
              "Why `bone_stretch` and `sink` go unseen: the limb bones `bone_stretch` "
              "lengthens (those ending at a canonical knee, ankle, elbow or wrist) already "
              "change length this much on real clips (per clip the worst limb bone's 95th "
              "percentile over frames of `|L / median - 1|`), so a 10-30 % stretch over a "
              "quarter of the clip is within the sensor's own noise, and no single tolerance "
              "fits the Kinect SDK and OpenNI skeletons alike (Florence's limbs wander 7x more "
              "than MSR's); `sink` and `float` move the whole body against a floor that the "
              "readers estimate from the feet in the camera frame, which real clips already "
              "miss by up to half a metre (`ground_penetration` p99 above).", "",
              "| source | p10 | p50 | p90 | p99 |", "|---|---|---|---|---|",
              *[f"| {s} | " + " | ".join(f"{v[q]:.3f}" for q in (10, 50, 90, 99)) + " |"
                for s, v in res["limb_noise"].items()], "",
              "Why no temporal denoiser: the calibration people's P99 (the level each "
              "threshold takes) of the metrics a denoiser could help, with no filter (1) "
              "and after a running median of 3, 5 and 7 frames on each joint's offset from "
              "the keypoints' centroid (whole-body moves kept). The tails barely move: the "
              "noise that sets the thresholds is not frame-to-frame but held for many frames "
              "(a limb tracked wrong while occluded, a floor missed for the whole clip), so "
              "filtering cannot separate it from a defect:", "",
              "| family | window (frames) | " + " | ".join(f"`{k}` P{PERCENTILE:g}"
                                                         for k in FILTERED) + " |",
              "|---|---|" + "---|" * len(FILTERED),
              *[f"| {fam} | {w} | " + " | ".join(f"{v[k]:.3g}" for k in FILTERED) + " |"
                for fam, rows in res["filter_study"].items() for w, v in rows.items()], "",
              "Window choice of `limb_persistence` (calibration people's `bone_stretch` "
              "copies caught by the check alone, moderate / "
              f"{STRONG:g}x):", "",
              "| family | " + " | ".join(f"{w} frames" for w in WINDOWS) + " |",
              "|---|" + "---|" * len(WINDOWS),
              *[f"| {fam} | " + " | ".join(
                  " / ".join(f"{100 * x:.1f} %" for x in
                             p["provenance"]["sensor_window_choice"][str(w)].values())
                  for w in WINDOWS) + " |" for fam, p in profiles.items()], "",
              "Goals of issue 33 on the held-out sources (physics off):", "",
              *goals(res), "",
              "The percentile of the rule, measured: a lower one keeps fewer real held-out "
              "clips inside and puts more of their corruptions outside (corruptions of the "
              "clips inside at that percentile; P100: the largest calibration value). No "
              "percentile meets both goals on Florence 3D; P99 is the lowest that keeps 90 % "
              "of its real clips inside:", "", *_sweep_rows(res["sweep"]), "",
              "The reference-percentile machinery (`simenv.plausibility.reference`, `simenv "
              "score --reference`) was not used for the default: it judges only clips at the "
              "reference's frame rate (Florence 3D is 20 fps, MSR Action3D and UTKinect 15), "
              "and it scores the same metric values against the same upper tail, so it cannot "
              "see what these values do not. Each profile keeps its calibration clips' frame "
              "rate (`fps`): a depth camera's noise is per frame, so its jerk and its "
              "frame-to-frame jumps grow with the rate, and thresholds set on 15-fps clips "
              "misjudge 30-fps ones (NiTE recordings at 30 fps, below: 69 % of the development "
              "files inside `kinect_v1` at 30 fps, 99 % interpolated down to 15, where the "
              "smoothing also hid nearly every seeded jitter and teleport). So the Kinect v1 "
              "family has a second profile at the sensor's own rate, `kinect_v1@30`, and "
              "`simenv.score` judges a clip by its family's profile of the nearest rate "
              "(`profile_for(kind, fps)`; Florence 3D's 20 fps: `kinect_v1`), thinning a clip "
              "at least twice as fast to every n-th frame (`at_profile_rate`, recorded as "
              "`source_kind.judged_fps`; thinning keeps the sensor's own samples).", "",
              "CMU clips of the shared corpus (BVH and ASF/AMC) and the profile detected: " +
              ", ".join(f"`{k}` {v}" for k, v in res["cmu_profiles"].items()) +
              " (motion capture keeps the default thresholds)."]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--no-write", action="store_true",
                    help="evaluate the shipped profiles; write neither them nor the docs")
    ap.add_argument("--msrc12", type=Path, help="MSRC-12's data folder (the .csv files; "
                    "tests/data/msrc12/SOURCES.md says where): calibrates kinect_v1@30")
    ap.add_argument("--kindergator", type=Path, help="Kinder-Gator's folder (Adults/, "
                    "Children/; tests/data/kinder_gator/SOURCES.md): calibrates kinect_v1@30")
    args = ap.parse_args()
    if not args.no_write and (args.msrc12 is None or args.kindergator is None):
        ap.error("kinect_v1@30 is calibrated on MSRC-12 and Kinder-Gator: pass --msrc12 DIR "
                 "--kindergator DIR (or --no-write to judge with the shipped profiles)")
    t0 = time.time()
    # The Kinect v1 family at its sensor's 30 fps (``kinect_v1@30``), calibrated on two sources
    # the repository may not hold: MSRC-12 (person p06 never read) and Kinder-Gator (10 adults,
    # 10 children). Its held-out check is a third 30-fps source, the NiTE recordings of
    # benchmarks/depth_bvh_survey.py.
    rate_sources = tuple(Source(n, "kinect_v1@30", "calibration", (p,)) for n, p in
                         (("msrc12", args.msrc12), ("kindergator", args.kindergator))
                         if p is not None)
    sources = (*SOURCES, *rate_sources)
    people = read_people(sources)
    raw: dict[str, dict[str, Any]] = {}
    for fam in ("kinect_v1", "kinect_v2", "kinect_v1@30"):
        names = [s.name for s in sources if s.family == fam and s.role == "calibration"]
        if names:
            raw[fam] = fit_profile(fam, [p for s in names for p in people[s]], names)
    # No Kinect v2 clip was scored with physics here (about 16 min per 5-s window on the
    # shared machine): kinect_v2 borrows the Kinect v1 body-level thresholds.
    for fam, clips in (("kinect_v2", "Kinect v2 / Nuitrack"), ("kinect_v1@30", "30-fps")):
        if fam in raw:
            raw[fam]["body"] = dict(raw["kinect_v1"]["body"])
            raw[fam]["provenance"]["body_rule"] = (
                f"borrowed from kinect_v1 (not measured on {clips} clips): "
                + raw["kinect_v1"]["provenance"]["body_rule"])
    rev = fit_profile("kinect_v1", [p for s in REVERSE["calibration"] for p in people[s]],
                      REVERSE["calibration"])
    if args.no_write:
        shipped = json.loads(PROFILES.read_text())["profiles"]
        if shipped != raw:
            print("note: the shipped profiles differ from a fresh fit")
        raw = shipped
    profiles = {k: _profile(k, v) for k, v in raw.items()}
    res = evaluate(people, profiles, _profile("kinect_v1_reverse", rev), sources)
    res["sweep"] = sweep(people)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "summary.json").write_text(json.dumps(res, indent=1))
    text = markdown(raw, res, time.time() - t0)
    print(text)
    if not args.no_write:
        PROFILES.parent.mkdir(parents=True, exist_ok=True)
        PROFILES.write_text(json.dumps({
            "about": "Depth-camera sensor-family profiles of simenv.plausibility.profiles, "
                     "written by benchmarks/depth_camera_profiles.py; see docs/plausibility.md",
            "profiles": raw}, indent=1) + "\n")
        replace_section(DOC, BEGIN, END, text)


if __name__ == "__main__":
    main()

"""``foot_skate`` before and after a kernel change: real clips, seeded slides, the hop file.

Scores ``foot_skate`` (kinematic, no body fit) on every person of the shared CMU corpus
(single-person BVH and ASF/AMC, both people of the two-person trials), of the shared Kinect
sets the depth-camera profiles use (:data:`depth_camera_profiles.SOURCES`, which skips the
reserved MSR Action3D subject 10), and of the FAIR AnimatedDrawings development file
``tests/data/conventions/other/fair1_dab_zup.bvh`` (a child hopping in a dab), each at its
detected source's thresholds (:func:`simenv.plausibility.profiles.detect_source`: the mocap
defaults, or the Kinect family's ``skate_ratio_max``). Every person whose clean clip passes
``foot_skate`` is also scored after :func:`simenv.plausibility.corrupt.foot_slide` (seed 0) at
the registry's moderate strength (1 m/s) and at three times it: a failing copy is a caught
slide. So is a stance-foot slide the registry lacks (:func:`stance_slide`: only the toe of
the one planted foot drifts, while the other foot swings), the case the hop exemption must
leave counted. Every copy also lists its sliding runs however short (the metric with a
``skate_min_duration_s`` of one frame), so that a change's effect shows on the runs too short
to count, e.g. the swing's approaches to a touchdown of the CMU runs. Writes one JSON
line per person to ``--out``; ``--compare BEFORE AFTER`` prints the verdicts that moved, the
largest value change per source, the detection rates with the seeded copies' mean value
(how far above the limit the slides stay), and per source and copy the stretches of
skating removed (those lasting the minimum duration, which the value counts, apart).

Run the "before" side on a copy of the unchanged code (``git archive HEAD simenv`` into a
folder, ``PYTHONPATH=that folder``; ``SIMENV_SHARED_DATA`` then names the corpus, which the
copy cannot find beside it) and the "after" side on the changed one (about 3 min each)::

    SIMENV_SHARED_DATA=../shared/data PYTHONPATH=/tmp/before nice -n 10 \\
        .venv/bin/python benchmarks/foot_skate_hop_check.py --out out/foot_skate/before.jsonl
    nice -n 10 .venv/bin/python benchmarks/foot_skate_hop_check.py --out out/foot_skate/after.jsonl
    .venv/bin/python benchmarks/foot_skate_hop_check.py --compare out/foot_skate/before.jsonl \\
        out/foot_skate/after.jsonl
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from depth_camera_profiles import SOURCES, source_motions

import simenv  # noqa: F401  (MUJOCO_GL before mujoco)
from simenv.body.foot_contact import foot_contacts
from simenv.core.config import shared_data_root
from simenv.core.errors import SimenvError
from simenv.core.motion import Interaction, Motion
from simenv.io.loader import load
from simenv.plausibility import foot_skate
from simenv.plausibility.corrupt import CORRUPTIONS, MIN_FRAMES
from simenv.plausibility.profiles import detect_source, profile_for
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds

REPO = Path(__file__).resolve().parents[1]
#: The development file whose hops ``foot_skate`` read as sliding (docs/plausibility.md).
FAIR_DAB = REPO / "tests" / "data" / "conventions" / "other" / "fair1_dab_zup.bvh"
#: Seeded slide levels: the registry's moderate strength, and three times it (m/s).
LEVELS = {"moderate": CORRUPTIONS["foot_slide"].moderate,
          "strong": 3.0 * CORRUPTIONS["foot_slide"].moderate}


def people() -> Iterator[tuple[str, str, Motion]]:
    """(source, label, motion) of every person judged."""
    cmu = shared_data_root() / "cmu"
    paths = (sorted((cmu / "bvh").glob("*.bvh")) + sorted((cmu / "asf_amc").glob("*.amc"))
             + sorted(p for p in (cmu / "two_person").iterdir() if p.is_dir()))
    for path in paths:
        clip = load(path)
        for i, m in enumerate(clip.people if isinstance(clip, Interaction) else (clip,)):
            yield "cmu", f"{path.parent.name}/{path.name}#{i}", m
    yield "fair", FAIR_DAB.name, load(FAIR_DAB)
    for source in SOURCES:
        for label, m in source_motions(source):
            yield source.name, label, m


def stance_slide(m: Motion, speed: float) -> Motion | None:
    """Canonical copy of ``m`` whose toe drifts at ``speed`` m/s along +x through each run
    of frames its foot alone is planted (:func:`simenv.body.foot_contact.foot_contacts`),
    back in place after the run; None without two toes."""
    canon = m.to_canonical()
    feet, contacts = foot_contacts(canon)
    if feet != ["left_toe", "right_toe"]:
        return None
    pos = canon.positions.astype(np.float64)
    for f, name in enumerate(feet):
        alone = contacts[:, f] & ~contacts[:, 1 - f]
        # Frames since the run began (0 outside runs): the drift restarts with each stance.
        since = np.zeros(len(alone))
        for t in range(1, len(alone)):
            since[t] = since[t - 1] + 1 if alone[t] and alone[t - 1] else 0
        pos[:, canon.skeleton.index(name), 0] += since * speed / m.fps
    return canon.with_positions(pos.astype(np.float32))


def thresholds_of(m: Motion) -> Thresholds:
    """The thresholds of ``m``'s detected source (its profile's, or the mocap defaults)."""
    profile = profile_for(detect_source(m))
    return DEFAULT_THRESHOLDS if profile is None else replace(DEFAULT_THRESHOLDS,
                                                              **profile.thresholds)


def slide_runs(m: Motion, th: Thresholds) -> list[list[int]]:
    """[first, last] frame of each sliding run of ``m`` however short (``foot_skate`` with a
    minimum duration of one frame pair; its timeline is positive on the second frame of each
    skating pair)."""
    short = replace(th, skate_min_duration_s=1.0 / m.fps)
    tl = np.nan_to_num(foot_skate(m, short).timeline) > 0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], tl.astype(np.int8), [0]])))
    return [[int(a) - 1, int(b) - 1] for a, b in zip(edges[::2], edges[1::2], strict=True)]


def judged(m: Motion, th: Thresholds) -> dict[str, Any]:
    """``foot_skate`` value and pass of one copy, and its sliding runs (:func:`slide_runs`)."""
    r = foot_skate(m, th)
    return {"value": r.value, "passed": r.passed, "runs": slide_runs(m, th)}


def row(source: str, label: str, m: Motion) -> dict[str, Any]:
    """One person's clean value, pass and runs, and its seeded slides' ones."""
    th = thresholds_of(m)
    clean = judged(m, th)
    out: dict[str, Any] = {"source": source, "label": label, "frames": m.num_frames,
                           "fps": m.fps, "limit": th.skate_ratio_max,
                           "min_s": th.skate_min_duration_s, **clean, "seeded": {}}
    if clean["passed"] and m.num_frames >= MIN_FRAMES:
        for level, strength in LEVELS.items():
            try:
                out["seeded"][level] = judged(
                    CORRUPTIONS["foot_slide"].fn(m, strength, seed=0), th)
            except SimenvError:  # no planted foot to slide
                continue
        stance = stance_slide(m, LEVELS["moderate"])
        if stance is not None:
            out["seeded"]["stance"] = judged(stance, th)
    return out


def removed_runs(rb: dict[str, Any], ra: dict[str, Any]) -> list[list[int]]:
    """[first, last] frame of each stretch of skating frame pairs of one copy before
    (``rb``) that is no longer skating after (``ra``); [] when either side did not list
    runs. The timeline joins the feet, so a foot's run removed beside the other foot's
    kept run shows only where it stood alone."""
    def pairs(r: dict[str, Any]) -> set[int]:
        return {t for first, last in r.get("runs", []) for t in range(first, last)}
    gone = sorted(pairs(rb) - pairs(ra))
    out: list[list[int]] = []
    for t in gone:
        if out and out[-1][1] == t:
            out[-1][1] = t + 1
        else:
            out.append([t, t + 1])
    return out


def compare(before: Path, after: Path) -> None:
    """Print moved verdicts, largest value change per source and detection rates."""
    def read(p: Path) -> dict[tuple[str, str], dict[str, Any]]:
        return {(r["source"], r["label"]): r
                for r in map(json.loads, p.read_text().splitlines())}
    b, a = read(before), read(after)
    largest: dict[str, tuple[float, str]] = {}
    caught: dict[tuple[str, str], list[int]] = {}
    for key in sorted(b.keys() & a.keys()):
        rb, ra = b[key], a[key]
        if rb["passed"] != ra["passed"]:
            print(f"verdict moved: {key[0]} {key[1]} {rb['value']:.4f} -> {ra['value']:.4f} "
                  f"(limit {ra['limit']})")
        if rb["value"] is not None and ra["value"] is not None:
            d = abs(ra["value"] - rb["value"])
            if d >= largest.get(key[0], (-1.0, ""))[0]:
                largest[key[0]] = (d, key[1])
        for level in (*LEVELS, "stance"):
            sb, sa = rb["seeded"].get(level), ra["seeded"].get(level)
            if sb and sa:
                c = caught.setdefault((key[0], level), [0, 0, 0, 0.0, 0.0])
                c[0] += 1
                c[1] += sb["passed"] is False
                c[2] += sa["passed"] is False
                c[3] += sb["value"]
                c[4] += sa["value"]
    for source, (d, label) in largest.items():
        print(f"{source}: largest |change| {d:.4f} ({label})")
    print_removed(b, a)
    for (source, level), (n, cb, ca, vb, va) in sorted(caught.items()):
        print(f"{source} foot_slide {level}: caught {cb}/{n} before, {ca}/{n} after; "
              f"mean value {vb / n:.3f} -> {va / n:.3f}")


def print_removed(b: dict[tuple[str, str], dict[str, Any]],
                  a: dict[tuple[str, str], dict[str, Any]]) -> None:
    """Each removed stretch (:func:`removed_runs`) lasting the minimum duration (source,
    person, copy, frames); then per source and copy: runs before, stretches removed, those
    lasting the minimum duration, and the longest (frame pairs)."""
    tally: dict[tuple[str, str], list[int]] = {}
    for key in sorted(b.keys() & a.keys()):
        rb, ra = b[key], a[key]
        min_pairs = max(1, round(rb.get("min_s", 0.0) * rb.get("fps", 0.0)))
        copies = [("clean", rb, ra)] + [(level, rb["seeded"][level], ra["seeded"][level])
                                        for level in rb["seeded"].keys() & ra["seeded"].keys()]
        for kind, cb, ca in copies:
            gone = [last - first for first, last in removed_runs(cb, ca)]
            t = tally.setdefault((key[0], kind), [0, 0, 0, 0])
            t[0] += len(cb.get("runs", []))
            t[1] += len(gone)
            t[2] += sum(n >= min_pairs for n in gone)
            t[3] = max([t[3], *gone])
            for first, last in removed_runs(cb, ca):
                if last - first >= min_pairs:
                    print(f"run removed: {key[0]} {key[1]} {kind} frames {first}-{last}")
    for (source, kind), (n, gone, long, longest) in sorted(tally.items()):
        if n:
            print(f"{source} {kind}: {n} runs, {gone} stretches removed, {long} lasting the "
                  f"minimum duration; longest {longest} pairs")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, help="JSON-lines file to write")
    ap.add_argument("--compare", type=Path, nargs=2, metavar=("BEFORE", "AFTER"))
    args = ap.parse_args()
    if args.compare:
        compare(*args.compare)
        return
    if args.out is None:
        ap.error("--out or --compare is required")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with args.out.open("w") as fh:
        for source, label, m in people():
            fh.write(json.dumps(row(source, label, m)) + "\n")
            fh.flush()


if __name__ == "__main__":
    main()

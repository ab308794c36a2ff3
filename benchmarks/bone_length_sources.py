"""``bone_length`` on every real source: the source skeleton's bones against the
canonical keypoint pairs the metric measured before.

Reads every real clip of the shared corpus (CMU BVH, ASF/AMC and two-person
recordings; the Kinect corpora MSR Action3D, UTKinect, Florence 3D, NuiSI and
the SBU sample) and the real HumanML3D ``new_joints`` clip of the tests
(``tests/data/humanml3d``, AMASS motion on the SMPL body, read at 20 fps), and
reports per source:

* the metric's value and verdict at the default thresholds, measured on the
  source skeleton's own bones (:func:`simenv.plausibility.bone_length`) and on
  the canonical keypoint pairs (:func:`canonical_pairs`, the same formula on
  :meth:`Motion.to_canonical`'s bones: what the metric measured before), and
  which bone is worst;
* for the depth-camera corpora with a profile
  (:data:`simenv.plausibility.thresholds.SOURCE_THRESHOLDS`), the share of real
  clips within it, both ways;
* :func:`simenv.plausibility.corrupt.bone_stretch` at its moderate strength
  (10 %): every limb bone of :data:`~simenv.plausibility.corrupt.STRETCH_BONES`
  of every person of the rigid sources (seed 0), and seed 0 of every
  depth-camera person, judged at the defaults (and with the profile where
  there is one);
* the SMPL collar case: the HumanML3D clip's canonical pairs that span more
  than one SMPL bone (chest to shoulder across the collar), against those bones.

Writes the section between ``<!-- bone-length-sources:begin -->`` and
``<!-- bone-length-sources:end -->`` of ``docs/plausibility.md``. Runs in about
a minute::

    .venv/bin/python benchmarks/bone_length_sources.py
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from doc_sections import replace_section

import simenv
from simenv.core.config import shared_data_root
from simenv.core.motion import Interaction, Motion
from simenv.plausibility import bone_length
from simenv.plausibility.batch import find_targets
from simenv.plausibility.clips import norm3
from simenv.plausibility.corrupt import CORRUPTIONS, MIN_FRAMES, STRETCH_BONES, bone_stretch
from simenv.plausibility.metrics.bone_length import bone_deviations
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, SOURCE_THRESHOLDS, Thresholds

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "plausibility.md"
BEGIN, END = "<!-- bone-length-sources:begin -->", "<!-- bone-length-sources:end -->"
HUMANML3D = REPO / "tests" / "data" / "humanml3d" / "new_joints" / "012314.npy"

#: Sources in report order: folders of the shared data (or files), and whether the
#: source keeps bones rigid (motion capture, body model) or is a depth camera.
SOURCES: dict[str, tuple[tuple[str, ...], bool]] = {
    "cmu": (("cmu/bvh", "cmu/asf_amc", "cmu/two_person"), True),
    "humanml3d": ((str(HUMANML3D),), True),
    "msr_action3d": (("gestures/msr_action3d",), False),
    "utkinect": (("gestures/utkinect",), False),
    "florence3d": (("gestures/florence3d",), False),
    "nuisi": (("other/nuisi",), False),
    "sbu": (("other/sbu_kinect_sample",), False),
}


def people(data: Path) -> Iterator[tuple[str, str, Motion]]:
    """(source, label, motion) of every person of every readable real clip."""
    for source, (folders, _) in SOURCES.items():
        targets = find_targets([Path(f) if f.startswith("/") else data / f for f in folders])
        for target in targets:
            try:
                # HumanML3D keeps no frame rate: its clips are 20 fps.
                loaded = simenv.load(target, **({"fps": 20} if source == "humanml3d" else {}))
            except simenv.SimenvError:
                continue  # an all-zero MSR file, Florence's class-name file
            clips = loaded if isinstance(loaded, list) else [loaded]
            for i, clip in enumerate(clips):
                persons = clip.people if isinstance(clip, Interaction) else (clip,)
                for k, motion in enumerate(persons):
                    yield source, f"{target.name} clip {i} person {k}", motion


def canonical_pairs(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> float:
    """The bone-length formula on the canonical keypoint pairs (the metric
    before it measured source bones): 95th percentile over frames of
    ``max_b |L_b / median L_b - 1| / tol_b``, pairs shorter than
    ``bone_min_length_m`` skipped, the pair ending at ``head`` at the head
    tolerance."""
    canon = motion.to_canonical()
    names = canon.skeleton.joint_names
    pos = canon.positions.astype(np.float64)
    worst = np.zeros(canon.num_frames)
    for p, c in canon.skeleton.bones:
        length = norm3(pos[:, c] - pos[:, p])
        med = np.median(length)
        if not med >= thresholds.bone_min_length_m:
            continue
        tol = (thresholds.bone_length_head_rel_max if names[c] == "head"
               else thresholds.bone_length_rel_max)
        worst = np.maximum(worst, np.abs(length / med - 1.0) / tol)
    return float(np.percentile(worst, 95))


def worst_bone(motion: Motion) -> str:
    """Name of the source bone with the largest share of the value."""
    rows = bone_deviations(motion)
    return str(max(rows, key=lambda r: r["p95_tolerances"])["bone"]) if rows else "-"


def _pct(k: int, n: int) -> str:
    return f"{100.0 * k / n:.1f} % ({k}/{n})" if n else "-"


def _g(v: float) -> str:
    return f"{v:.3g}"


def measure(data: Path) -> dict:
    rows: dict[str, list[dict]] = {s: [] for s in SOURCES}
    stretch: dict[str, list[dict]] = {s: [] for s in SOURCES}
    for source, label, motion in people(data):
        new = bone_length(motion)
        row = {"label": label, "skeleton": motion.skeleton.name, "new": new.value,
               "checked": int(new.details.get("bones_checked", 0)),
               "old": canonical_pairs(motion), "worst": worst_bone(motion)}
        profile = SOURCE_THRESHOLDS.get(source)
        if profile is not None:
            row["new_profile"] = bone_length(motion, profile).value
            row["old_profile"] = canonical_pairs(motion, profile)
        rows[source].append(row)
        rigid = SOURCES[source][1]
        strength = CORRUPTIONS["bone_stretch"].moderate
        if motion.num_frames < MIN_FRAMES:
            continue  # too short to corrupt (a 9-frame MSR clip)
        if rigid:
            runs = [bone_stretch(motion, strength, seed=0, bone=b) for b in STRETCH_BONES]
        else:
            runs = [bone_stretch(motion, strength, seed=0)]
        for out in runs:
            # Each value with its real clip's: a copy counts only where the real clip passes.
            rec = {"new": (row["new"], bone_length(out).value),
                   "old": (row["old"], canonical_pairs(out)),
                   "bone": out.metadata["corruptions"][-1]["source_bone"]}
            if profile is not None:
                rec["new_profile"] = (row["new_profile"], bone_length(out, profile).value)
                rec["old_profile"] = (row["old_profile"], canonical_pairs(out, profile))
            stretch[source].append(rec)
    return {"rows": rows, "stretch": stretch}


def spanning_pairs() -> list[tuple[str, str, float, list[tuple[str, float]]]]:
    """The HumanML3D clip's canonical keypoint pairs that span more than one
    SMPL bone: (canonical pair, the SMPL joints it joins, its largest relative
    deviation over the clip, [(SMPL bone on the way, its largest deviation)])."""
    motion = simenv.load(HUMANML3D, fps=20)
    s = motion.skeleton
    canon = motion.to_canonical().skeleton
    pos = motion.positions.astype(np.float64)

    def largest(a: int, c: int) -> float:
        length = norm3(pos[:, c] - pos[:, a])
        return float(np.abs(length / np.median(length) - 1.0).max())

    out = []
    for a, c in canon.bones:
        top, end = (s.index(s.canonical[canon.joint_names[k]]) for k in (a, c))
        path, j = [], end
        while j not in (top, -1):
            path.append((s.parents[j], j))
            j = s.parents[j]
        if j == top and len(path) > 1:
            bones = [(f"{s.joint_names[p]}->{s.joint_names[k]}", largest(p, k))
                     for p, k in reversed(path)]
            out.append((f"{canon.joint_names[a]}->{canon.joint_names[c]}",
                        f"{s.joint_names[top]}->{s.joint_names[end]}", largest(top, end), bones))
    return out


def markdown(result: dict, spans: list[tuple[str, str, float, list[tuple[str, float]]]],
             seconds: float) -> str:
    rows, stretch = result["rows"], result["stretch"]
    lines = [
        f"Generated by `benchmarks/bone_length_sources.py` ({seconds:.0f} s; do not edit by "
        "hand). `bone_length` measures the source skeleton's own parent-child bones "
        "(`motion.skeleton.parents`, extremity fans of two or more end joints left out, bones "
        "under 1 cm skipped); \"canonical pairs\" is the same formula on the canonical keypoint "
        "pairs, what it measured before. Values in tolerances (5 %, 15 % at the head), 95th "
        "percentile over frames; a clip passes at <= 1.",
        "",
        "| source | people | skeletons | bones checked | passing, canonical pairs | passing, "
        "source bones | value p50 / max, canonical pairs | value p50 / max, source bones | "
        "worst source bone (most often) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for source, rs in rows.items():
        if not rs:
            continue
        old = np.array([r["old"] for r in rs])
        new = np.array([r["new"] for r in rs])
        checked = sorted({r["checked"] for r in rs})
        worst, n = Counter(r["worst"] for r in rs).most_common(1)[0]
        lines.append(
            f"| {source} | {len(rs)} | {', '.join(sorted({r['skeleton'] for r in rs}))} | "
            f"{checked[0]}-{checked[-1]} | {_pct(int((old <= 1).sum()), len(rs))} | "
            f"{_pct(int((new <= 1).sum()), len(rs))} | {_g(np.median(old))} / {_g(old.max())} | "
            f"{_g(np.median(new))} / {_g(new.max())} | `{worst}` ({n}) |")
    lines += ["", "Depth cameras estimate every joint on its own, so their bones are not rigid; "
              "they are judged with their sensor's profile (`SOURCE_THRESHOLDS`, fitted on the "
              "canonical pairs). Real clips within it:", "",
              "| source | canonical pairs | source bones |", "|---|---|---|"]
    for source, rs in rows.items():
        if rs and "new_profile" in rs[0]:
            old = sum(r["old_profile"] <= 1 for r in rs)
            new = sum(r["new_profile"] <= 1 for r in rs)
            lines.append(f"| {source} | {_pct(old, len(rs))} | {_pct(new, len(rs))} |")
    lines += ["", f"`bone_stretch` at {CORRUPTIONS['bone_stretch'].moderate:g} (moderate): every "
              "limb bone of every person of the rigid sources, seed 0 of every depth-camera "
              "person (clips of at least 10 frames). Caught: `bone_length` fails the copy, "
              "counted over the copies whose real clip passes with the same thresholds (a real "
              "clip that already fails shows nothing):", "",
              "| source | stretched copies | caught, canonical pairs | caught, source bones | "
              "caught with the profile, canonical pairs | caught with the profile, source "
              "bones |", "|---|---|---|---|---|---|"]
    for source, rs in stretch.items():
        if not rs:
            continue
        keys = ["old", "new"] + (["old_profile", "new_profile"] if "new_profile" in rs[0] else [])
        cells = []
        for key in keys:
            judged = [r[key] for r in rs if r[key][0] <= 1]
            cells.append(_pct(sum(v > 1 for _, v in judged), len(judged)))
        cells += ["-"] * (4 - len(cells))
        lines.append(f"| {source} | {len(rs)} | " + " | ".join(cells) + " |")
    lines += ["", "The SMPL collar case (HumanML3D `new_joints/012314.npy`, AMASS on the SMPL "
              "body): the canonical keypoint pairs that span more than one SMPL bone, and the "
              "bones on the way. The pair changes length as the joint between moves; every bone "
              "keeps its length. Largest relative deviation over the clip:", "",
              "| canonical pair | SMPL joints | largest deviation | SMPL bones on it (largest "
              "deviation) |", "|---|---|---|---|"]
    for pair, joints, dev, bones in spans:
        on = ", ".join(f"`{b}` {100.0 * d:.2g} %" for b, d in bones)
        lines.append(f"| `{pair}` | `{joints}` | {100.0 * dev:.3g} % | {on} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=shared_data_root())
    ap.add_argument("--docs", type=Path, default=DOC)
    args = ap.parse_args()
    start = time.perf_counter()
    result = measure(args.data)
    text = markdown(result, spanning_pairs(), time.perf_counter() - start)
    replace_section(args.docs, BEGIN, END, text)
    print(text)


if __name__ == "__main__":
    main()

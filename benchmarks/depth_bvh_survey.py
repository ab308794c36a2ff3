"""A depth camera's skeletons written as BVH, from a dataset no profile saw, judged by default.

Kinect-era tools export the OpenNI / NiTE skeleton tracker's output as BVH (joint names
``TORSO``, ``LEFT_HIP``, ``LEFT_FOOT`` ...; millimetres; the sensor's frame, so the floor is
about the sensor's height below the file's zero). Issue 33 asks that real depth-camera clips
of datasets the reference never saw are inside their sensor family's profile by default
(>= 90 %) and that their seeded corruptions fall outside it (>= 90 %). This survey reads the
Movement Analysis Engine's evaluation recordings (furylynx/MAE, GPL-3.0: read from the fetched
snapshot into /tmp, never copied), each file as ``simenv.load`` reads it (joint names -> the
``openni`` convention, floor from the feet, ``kinect_v1`` profile by the joint names), and
judges its joint-level metrics the way ``simenv score FILE`` does (physics off: OpenNI has
no pelvis joint, and the body fitted with the hips' midpoint as pelvis is not run here). The seeded
corruptions are those of ``benchmarks/depth_camera_profiles.py`` (every generator of the
registry at its moderate strength and 3x it, seed 0) of the clips judged inside.

Split (fixed in this file before any held-out file was read): the development set is the
two performers whose files were opened while building the reader path (``ah``, ``ba``); the
held-out set is every other performer of the folder (``ank``, ``ark``, ``bk``, ``jk``,
``sk``). Files without a performer prefix (Labanotation test sequences) are left out.

Usage::

    nice -n 10 .venv/bin/python benchmarks/depth_bvh_survey.py --role dev
    nice -n 10 .venv/bin/python benchmarks/depth_bvh_survey.py --role heldout
    .venv/bin/python benchmarks/depth_bvh_survey.py --docs-only

One JSON line per file goes to ``out/depth_bvh_survey/<role>.jsonl`` as it is judged (a
rerun skips the files there); the corruption counts to ``<role>_corruptions.json``; the
section of docs/plausibility.md between the markers is rewritten from what is there. A run
kept from before a change (``heldout_first.jsonl`` / ``heldout_first_corruptions.json``: the
held-out set as first scored) is tabulated beside the current one.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import time
from pathlib import Path
from typing import Any

from depth_camera_profiles import Person, corruptions, failed
from doc_sections import replace_section

import simenv  # noqa: F401  (MUJOCO_GL before mujoco)
from simenv.core.errors import SimenvError
from simenv.io.loader import load
from simenv.plausibility.profiles import Profile, detect_source, profile_for

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "plausibility.md"
OUT = REPO / "out" / "depth_bvh_survey"
MIRROR = Path("/work/.mirror/furylynx+MAE/repo")
#: The snapshot commit the files are read at.
COMMIT = "60ddb7fc287eeea5bffe4a0b216c09f68665cb14"
FOLDER = "evaluation/mae_evaluator/bvhs/"
#: The split, by performer (the file name's prefix).
ROLES: dict[str, tuple[str, ...]] = {"dev": ("ah", "ba"),
                                     "heldout": ("ank", "ark", "bk", "jk", "sk")}
BEGIN, END = "<!-- depth-bvh-survey:begin -->", "<!-- depth-bvh-survey:end -->"
#: Result files tabulated, in order, with their labels.
TABLES: dict[str, str] = {"dev": "development", "heldout_first": "held out, first scored",
                          "heldout": "held out, now"}


def files(role: str) -> list[str]:
    """The blobs of ``role``'s performers in the snapshot, sorted."""
    listing = subprocess.run(["git", "-C", str(MIRROR), "ls-tree", "-r", "--name-only", COMMIT,
                              FOLDER], capture_output=True, text=True, check=True).stdout
    return sorted(b for b in listing.split() if b.endswith(".bvh")
                  and Path(b).name.split("_")[0] in ROLES[role])


def materialise(blob: str, dest: Path) -> Path:
    """``blob`` of the snapshot written under ``dest`` (read, never copied to the repo)."""
    target = dest / blob
    if not target.exists():
        data = subprocess.run(["git", "-C", str(MIRROR), "show", f"{COMMIT}:{blob}"],
                              capture_output=True, check=True).stdout
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
    return target


def judge(path: Path) -> tuple[dict[str, Any], Person | None]:
    """One file's row (source kind, floor, failing joint-level metrics) and, when it loads,
    the person for the corruption count."""
    row: dict[str, Any] = {"file": path.name, "performer": path.name.split("_")[0]}
    t0 = time.process_time()
    try:
        motion = load(path)
    except SimenvError as exc:
        row.update(loaded=False, error=str(exc)[:300])
        return row, None
    kind = detect_source(motion)
    profile = profile_for(kind, motion.fps)
    fails = failed(motion, profile)
    cf = motion.metadata.get("camera_frame", {})
    row.update(loaded=True, frames=motion.num_frames, fps=motion.fps,
               convention=motion.metadata.get("joint_map", {}).get("convention"),
               source_kind=kind.record(), profile=profile.name if profile else None,
               sensor_height_m=cf.get("sensor_height_m"),
               tilt_deg=cf.get("tilt_deg"), inside=not fails, failed=fails,
               cpu_s=round(time.process_time() - t0, 2))
    return row, Person("mae", path.name, motion, {}, {})


def corruption_counts(people: list[Person]) -> dict[str, dict[str, Any]]:
    """Per corruption and level: copies of the inside people, outside their profile, caught
    by the targeted metric (:func:`depth_camera_profiles.corruptions`, each person judged by
    the profile ``simenv score`` picks for it)."""
    by_profile: dict[str, tuple[Profile, list[Person]]] = {}
    for p in people:
        profile = profile_for(detect_source(p.motion), p.motion.fps)
        by_profile.setdefault(profile.name, (profile, []))[1].append(p)
    out: dict[str, dict[str, Any]] = {}
    for profile, group in by_profile.values():
        for key, c in corruptions(group, profile).items():
            total = out.setdefault(key, {**c, "copies": 0, "outside": 0, "caught": 0})
            for field in ("copies", "outside", "caught"):
                total[field] += c[field]
    return out


def run(role: str, dest: Path) -> None:
    """Judge every file of ``role`` (skipping those already written), then its corruptions."""
    OUT.mkdir(parents=True, exist_ok=True)
    rows_path = OUT / f"{role}.jsonl"
    done = {json.loads(line)["file"] for line in rows_path.read_text().splitlines()} \
        if rows_path.exists() else set()
    inside: list[Person] = []
    blobs = files(role)
    for i, blob in enumerate(blobs):
        path = materialise(blob, dest)
        row, person = judge(path)
        if path.name not in done:
            with rows_path.open("a") as fh:
                fh.write(json.dumps(row) + "\n")
        if person is not None and row["inside"]:
            inside.append(person)
        print(f"[{i + 1}/{len(blobs)}] {path.name}: "
              f"{'inside' if row.get('inside') else row.get('failed') or row.get('error')}",
              flush=True)
    counts = corruption_counts(inside)
    (OUT / f"{role}_corruptions.json").write_text(json.dumps(counts, indent=1))


def _pct(k: int, n: int) -> str:
    return f"{100 * k / n:.1f} % ({k}/{n})" if n else "-"


def markdown() -> str:
    """The docs section from what ``out/depth_bvh_survey`` holds."""
    lines = [
        "Generated by `benchmarks/depth_bvh_survey.py` (do not edit by hand): real NiTE "
        f"recordings exported to BVH (furylynx/MAE @ `{COMMIT[:7]}`, `{FOLDER}`, GPL-3.0, read "
        "from the snapshot, not copied), each read by `simenv.load` and judged by the profile "
        "`simenv score FILE` picks, physics off (the joint-level verdict; with physics on "
        "`simenv score` also fits a body, its pelvis at the hips' midpoint, which this "
        "survey does not run). Development: performers "
        f"{', '.join(ROLES['dev'])} (opened while the reader path was built); held out: "
        f"{', '.join(ROLES['heldout'])} (split fixed before any of their files was read).", "",
        "| role | files | loaded | kinect_v1 profile by joint names | sensor height, m (median) "
        "| inside the profile | outside by |", "|---|---|---|---|---|---|---|"]
    for role, label in TABLES.items():
        path = OUT / f"{role}.jsonl"
        if not path.exists():
            continue
        rows = [json.loads(line) for line in path.read_text().splitlines()]
        ok = [r for r in rows if r["loaded"]]
        by = sum(r["source_kind"]["how"] == "joint names openni" for r in ok)
        heights = sorted(r["sensor_height_m"] for r in ok if r["sensor_height_m"] is not None)
        outside: dict[str, int] = {}
        for r in ok:
            for n in r["failed"]:
                outside[n] = outside.get(n, 0) + 1
        lines.append(
            f"| {label} | {len(rows)} | {len(ok)} | {by} | "
            f"{heights[len(heights) // 2] if heights else '-'} | "
            f"{_pct(sum(r['inside'] for r in ok), len(ok))} | "
            + (", ".join(f"`{n}` {k}" for n, k in sorted(outside.items())) or "-") + " |")
    for role, label in TABLES.items():
        path = OUT / f"{role}_corruptions.json"
        if not path.exists():
            continue
        counts = json.loads(path.read_text())
        lines += ["", f"Seeded corruptions of the clips inside their profile ({label}; seed 0):",
                  "",
                  "| corruption | level (strength) | copies | outside the profile | caught by its "
                  "target metric |", "|---|---|---|---|---|"]
        total: dict[str, list[int]] = {}
        for key, c in counts.items():
            name, level = key.split("/")
            t = total.setdefault(level, [0, 0, 0])
            t[0] += c["copies"]
            t[1] += c["outside"]
            t[2] += c["caught"]
            lines.append(f"| {name} | {level} ({c['strength']:g}) | {c['copies']} | "
                         f"{_pct(c['outside'], c['copies'])} | {_pct(c['caught'], c['copies'])} "
                         f"(`{'`, `'.join(c['targets'])}`) |")
        for level, (n, o, k) in total.items():
            lines.append(f"| **all** | {level} | {n} | **{_pct(o, n)}** | **{_pct(k, n)}** |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--role", choices=sorted(ROLES))
    ap.add_argument("--extract-to", type=Path, default=Path("/tmp/depth_bvh_survey"))
    ap.add_argument("--docs-only", action="store_true")
    args = ap.parse_args()
    if not args.docs_only:
        if args.role is None:
            ap.error("--role or --docs-only")
        run(args.role, args.extract_to)
    replace_section(DOC, BEGIN, END, markdown())


if __name__ == "__main__":
    main()

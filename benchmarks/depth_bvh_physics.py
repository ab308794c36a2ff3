"""NiTE recordings written as BVH, judged the way ``simenv score FILE`` does: physics on.

An OpenNI / NiTE skeleton has both hips and no pelvis joint; the body fit puts its pelvis at
the hips' midpoint (:func:`simenv.body.retarget.with_derived_pelvis`), so the default command
fits a body and judges the body-level metrics with the ``kinect_v1@30`` profile's body
thresholds, which were carried over from Kinect v1 clips with a real hip centre. This script
measures that verdict on development files of ``benchmarks/depth_bvh_survey.py`` (furylynx/MAE,
GPL-3.0, read from the snapshot into ``--extract-to``, never copied): each cut to its first
``--max-seconds`` and scored by :func:`simenv.score` with ``physics=True`` (default planner,
thresholds and ``source="auto"``) and, beside it, ``physics=False`` on the same cut.

Files (:data:`FILES`, fixed before any was scored): only the development performers (``ah``,
``ba``); one file per gesture folder, the first in sort order, over the 16 folders that are
not a second or third take of another folder's gesture (``testeval_dontcare2``,
``testeval_dontcare3``, ``testeval_pinch2``, ``testeval_scrollup2``, ``testeval_throw2`` left
out). The held-out performers are never read.

Usage (about 1-2 min of CPU per 4-s clip; niced, one process)::

    nice -n 10 .venv/bin/python benchmarks/depth_bvh_physics.py

    nice -n 10 .venv/bin/python benchmarks/depth_bvh_physics.py --upright \\
        ba_hammer_01.bvh ba_scroll_down_01.bvh

One JSON line per file goes to ``out/depth_bvh_physics/dev.jsonl`` as it finishes (a rerun
skips the files there): the physics-on verdict, score, failing metrics (value / threshold /
unit), every metric's details, and the physics-off verdict and failing metrics. The result
is summarised by hand in docs/plausibility.md (NiTE section, "With physics on").

``--upright NAME ...`` is the diagnosis of the tracking failures: the named files, each
pitched about its ankles so that its neck stands over them (:func:`upright`), scored the same
way (rows in ``upright.jsonl``, with the pitch).

``--heldout-levelling`` runs the same on :func:`heldout_files` (``heldout_levelling.jsonl``),
once, after the levelling code was committed.

``--levelling`` (cheap, physics off) loads every file twice, levelled with the body-axis prior
(as before issue 33's change) and as :func:`simenv.load` levels it now (the centre of mass
over the feet for a person in place), and writes per file the tilt, the neck's and the
keypoint centre of mass's forward offset from the ankles' midpoint and the physics-off
verdict of each (``levelling.jsonl``). ``--only NAME ... --rows FILE`` scores only the named
files of :data:`FILES` physics on, into ``FILE`` (e.g. ``levelled.jsonl``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
from depth_bvh_survey import FOLDER, files, materialise

import simenv  # noqa: F401  (MUJOCO_GL before mujoco)
from simenv.core.errors import SimenvError
from simenv.core.motion import Motion
from simenv.io import camera_frame
from simenv.io.loader import load

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "out" / "depth_bvh_physics"
#: The development files scored, relative to the snapshot's BVH folder; the two performers
#: alternate so that a run cut short still holds both.
FILES: tuple[str, ...] = (
    "testeval_clap/ba_clap_01.bvh",
    "cut/ah_cut_01.bvh",
    "testeval_cut/ba_cut_01.bvh",
    "dontcare/ah_dontcare_01.bvh",
    "testeval_dontcare/ba_dontcare_01.bvh",
    "indi/ah_indi_01.bvh",
    "testeval_hammer/ba_hammer_01.bvh",
    "raise/ah_raise_01.bvh",
    "testeval_pinch/ba_pinch_01.bvh",
    "sequential/ah_sequential_01.bvh",
    "testeval_rotation/ba_rotation_01.bvh",
    "wheel/ah_wheel_01.bvh",
    "testeval_scroll_up/ba_scroll_up_01.bvh",
    "testeval_scrolldown/ba_scroll_down_01.bvh",
    "testeval_throw/ba_throw_01.bvh",
    "testeval_wave/ba_wave_01.bvh",
)


#: Folders holding a second or third take of another folder's gesture (left out of the
#: held-out levelling check as they were of :data:`FILES`).
TAKES = ("testeval_dontcare2", "testeval_dontcare3", "testeval_pinch2", "testeval_pinch3",
         "testeval_scrollup2", "testeval_throw2")


def heldout_files() -> list[str]:
    """The held-out files of the levelling check, relative to the snapshot's BVH folder: per
    held-out performer (``ank``, ``ark``, ``bk``, ``jk``, ``sk``) and gesture folder (not
    :data:`TAKES`), the first file in sort order. Chosen by this rule from the file names
    only, fixed before any was read."""
    first: dict[tuple[str, str], str] = {}
    for blob in files("heldout"):
        folder, name = Path(blob).parent.name, Path(blob).name
        if folder not in TAKES:
            first.setdefault((folder, name.split("_")[0]), blob.removeprefix(FOLDER))
    return [first[k] for k in sorted(first)]


def _failing(rec: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {n: {"value": m["value"], "threshold": m["threshold"], "unit": m["unit"]}
            for n, m in rec["metrics"].items() if m["passed"] is False}


def upright(motion: Motion) -> tuple[Motion, float]:
    """``motion`` pitched about its ankles' median midpoint so that the median neck lies over
    it (a rotation about the horizontal hip axis; the lowest ankle height is kept).

    Returns:
        The pitched motion (positions (T, J, 3) metres, Z up) and the pitch, degrees
        (positive: the clip leaned back and was tipped forward).
    """
    sk, c = motion.skeleton, motion.skeleton.canonical
    pos = motion.positions.astype(np.float64)

    def joint(k: str) -> np.ndarray:
        return pos[:, sk.index(c[k])]

    ankles = [sk.index(c["left_ankle"]), sk.index(c["right_ankle"])]
    pivot = np.median(pos[:, ankles].mean(axis=1), axis=0)
    left = np.median(joint("left_hip") - joint("right_hip"), axis=0)
    left[2] = 0.0
    left /= np.linalg.norm(left)
    neck = np.median(joint("neck"), axis=0) - pivot
    # A positive rotation about the person's left axis tips the top forward.
    angle = float(np.arctan2(neck @ np.cross([0.0, 0.0, 1.0], left), neck[2]))
    k = np.array([[0.0, -left[2], left[1]], [left[2], 0.0, -left[0]],
                  [-left[1], left[0], 0.0]])
    rot = np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * k @ k
    out = (pos - pivot) @ rot.T + pivot
    out[:, :, 2] += pos[:, ankles, 2].min() - out[:, ankles, 2].min()
    pitched = Motion(out.astype(motion.positions.dtype), motion.fps, sk, motion.name,
                     dict(motion.metadata))
    return pitched, float(np.degrees(angle))


def _forward_offsets(motion: Motion) -> dict[str, float]:
    """Median forward offset, metres, of the neck and of the keypoint centre of mass
    (:func:`simenv.io.camera_frame.centre_of_mass`) from the ankles' midpoint (negative:
    behind the ankles), forward being the hip line crossed with up."""
    sk, c = motion.skeleton, motion.skeleton.canonical
    pos = motion.positions.astype(np.float64)
    ankles = pos[:, [sk.index(c["left_ankle"]), sk.index(c["right_ankle"])]].mean(axis=1)
    fwd = np.cross(pos[:, sk.index(c["left_hip"])] - pos[:, sk.index(c["right_hip"])],
                   [0.0, 0.0, 1.0])
    fwd[:, 2] = 0.0
    fwd /= np.linalg.norm(fwd, axis=1, keepdims=True)
    com = camera_frame.centre_of_mass(pos, sk)
    neck = pos[:, sk.index(c["neck"])]
    return {"neck_fwd_m": round(float(np.median(np.einsum("ij,ij->i", neck - ankles, fwd))), 4),
            "com_fwd_m": round(float(np.median(np.einsum("ij,ij->i", com - ankles, fwd))), 4)}


def levelling_row(path: Path, max_seconds: float) -> dict[str, Any]:
    """``path`` levelled the old way (body-axis prior) and the new way, physics off: tilt,
    prior used, forward offsets (:func:`_forward_offsets`), verdict and failing metrics of
    the cut to its first ``max_seconds``."""
    row: dict[str, Any] = {"file": path.name}
    saved = camera_frame.IN_PLACE_SPREAD_M
    for label in ("old", "new"):
        # Old: nobody counts as in place, so the body axis centres the prior as before.
        camera_frame.IN_PLACE_SPREAD_M = -1.0 if label == "old" else saved
        try:
            clip = load(path)
        except SimenvError as exc:
            return row | {"error": str(exc), "error_type": type(exc).__name__}
        finally:
            camera_frame.IN_PLACE_SPREAD_M = saved
        assert isinstance(clip, Motion)
        motion = clip.slice(0, min(clip.num_frames, int(round(max_seconds * clip.fps))))
        cf = clip.metadata["camera_frame"]
        off = simenv.score(motion, physics=False).to_records()[0]
        row[label] = {"tilt_deg": cf["tilt_deg"], "pitch_down_deg": cf["pitch_down_deg"],
                      "prior": cf.get("prior", "body axis"), **_forward_offsets(motion),
                      "verdict": off["verdict"], "score": off["score"],
                      "failing": _failing(off)}
    return row


def score_file(path: Path, max_seconds: float, pitch: bool = False) -> dict[str, Any]:
    """Load ``path``, cut it to its first ``max_seconds`` s and score it physics on and off.

    Returns:
        A JSON-ready row (``pitch``: the cut first made :func:`upright`, its angle in
        ``pitch_deg``): ``file``, ``frames`` and ``seconds`` scored, ``verdict``, ``score``,
        ``profile``, ``failing`` {metric: {value, threshold, unit}} and ``metrics`` (each
        metric's record, details included) with physics on, ``off_verdict`` / ``off_failing``
        with physics off, ``repairs``, ``cpu_s`` (physics on); or ``error`` (a typed
        :class:`SimenvError`).
    """
    row: dict[str, Any] = {"file": path.name}
    try:
        clip = load(path)
        if not isinstance(clip, Motion):
            raise SimenvError(f"{path}: expected one person's clip", field="people")
        motion = clip.slice(0, min(clip.num_frames, int(round(max_seconds * clip.fps))))
        if pitch:
            motion, row["pitch_deg"] = upright(motion)
        off = simenv.score(motion, physics=False).to_records()[0]
        t0 = time.process_time()
        rec = simenv.score(motion, physics=True).to_records()[0]
    except SimenvError as exc:
        return row | {"error": str(exc), "error_type": type(exc).__name__}
    return row | {
        "frames": motion.num_frames, "seconds": round(motion.duration, 2),
        "verdict": rec["verdict"], "score": rec["score"], "profile": rec.get("profile"),
        "failing": _failing(rec), "metrics": rec["metrics"], "repairs": rec.get("repairs"),
        "off_verdict": off["verdict"], "off_score": off["score"], "off_failing": _failing(off),
        "cpu_s": round(time.process_time() - t0, 1)}


def main() -> None:
    """Score every file of :data:`FILES` not yet in the results."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--max-seconds", type=float, default=4.0, help="seconds scored per file")
    ap.add_argument("--extract-to", type=Path, default=Path("/tmp/mae_bvh"),
                    help="where the snapshot's files are written (outside the repository)")
    ap.add_argument("--upright", nargs="+", metavar="NAME",
                    help="score these files of FILES pitched upright (upright.jsonl)")
    ap.add_argument("--levelling", action="store_true",
                    help="old vs new levelling, physics off, every file (levelling.jsonl)")
    ap.add_argument("--heldout-levelling", action="store_true",
                    help="--levelling on heldout_files() (heldout_levelling.jsonl); once, at "
                    "the end")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="score only these files of FILES")
    ap.add_argument("--rows", help="result file name under out/depth_bvh_physics/")
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    if args.heldout_levelling:
        args.levelling = True
    default = "upright.jsonl" if args.upright else "heldout_levelling.jsonl" \
        if args.heldout_levelling else "levelling.jsonl" if args.levelling else "dev.jsonl"
    rows_path = OUT / (args.rows or default)
    only = args.upright or args.only
    done = {json.loads(line)["file"] for line in rows_path.read_text().splitlines()} \
        if rows_path.exists() else set()
    for i, rel in enumerate(heldout_files() if args.heldout_levelling else FILES):
        if Path(rel).name in done or (only and Path(rel).name not in only):
            continue
        path = materialise(FOLDER + rel, args.extract_to)
        if args.levelling:
            row = levelling_row(path, args.max_seconds)
            with rows_path.open("a") as fh:
                fh.write(json.dumps(row, default=str) + "\n")
            if "error" in row:
                print(f"{row['file']}: {row['error_type']} {row['error'][:120]}", flush=True)
                continue
            print(f"{row['file']}: " + "; ".join(
                f"{k} tilt {row[k]['tilt_deg']:.1f} neck {row[k]['neck_fwd_m']:+.3f} com "
                f"{row[k]['com_fwd_m']:+.3f} {row[k]['verdict']} {list(row[k]['failing'])}"
                for k in ("old", "new")), flush=True)
            continue
        row = score_file(path, args.max_seconds, pitch=bool(args.upright))
        with rows_path.open("a") as fh:
            fh.write(json.dumps(row, default=str) + "\n")
        print(f"[{i + 1}/{len(FILES)}] {row['file']}: {row.get('verdict', row.get('error'))} "
              f"{ {n: f['value'] for n, f in row.get('failing', {}).items()} } "
              f"off {row.get('off_verdict')} {row.get('cpu_s')} s", flush=True)


if __name__ == "__main__":
    main()

"""Calibration of simenv.io.floor's toe-less floor rule and tilted-floor levelling (issue 33).

Both rules are checked on motion capture *with* toe keypoints, where the answer is known:

* the shared CMU corpus (``/work/shared/data/cmu``: BVH, ASF/AMC and the two-person pairs),
  whose floors are the capture volume's, level and under the soles. Per person: the tilt of
  the plane through the still toes (and through the still ankles), and whether either rule
  would move the clip; the toe-less rule runs on the clip with its toe keypoints removed,
  as read and after a HumanML3D-style "put on floor" on the ankles (the lowest ankle centre
  moved to z = 0), where it must raise the clip back by about what was taken away;
* Holden's processed Xia clips (deep-motion-editing ``style_transfer/data/xia_test``, whose
  floor is at the feet's joint centres; ``fetch`` the snapshot into /work/.mirror): the toe
  rule's raise against the toe-less rule's raise on the same clips with the toes removed.

Files are read by :func:`simenv.load` with :func:`simenv.io.floor.put_on_floor` switched off
(the file's own floor). One JSON line per person goes to ``--out``; a summary is printed::

    .venv/bin/python benchmarks/floor_rule_check.py
"""

from __future__ import annotations

import argparse
import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np

import simenv
import simenv.io.loader as loader
from simenv.body.humanoid import fit_dimensions
from simenv.core.motion import Interaction, Motion
from simenv.core.skeletons import canonical_skeleton
from simenv.io import floor

CMU = Path("/work/shared/data/cmu")
DME = Path("/work/.mirror/DeepMotionEditing+deep-motion-editing/repo")
XIA_TEST = "style_transfer/data/xia_test/"


def toeless(m: Motion) -> Motion:
    """``m``'s canonical keypoints without the toes (a rig like Aalto's), same frames."""
    c = m.to_canonical()
    keys = [k for k in c.skeleton.joint_names if not k.endswith("_toe")]
    idx = [c.skeleton.index(k) for k in keys]
    return Motion(c.positions[:, idx], c.fps, canonical_skeleton().subset(keys, name="canonical"),
                  c.name, dict(c.metadata))


def on_ankles(m: Motion) -> tuple[Motion, float]:
    """``m`` lowered so that its lowest ankle centre over the clip is at z = 0 (HumanML3D's
    put-on-floor on a rig whose lowest joints are the ankles), and the drop, metres."""
    c = m.to_canonical()
    low = float(min(c.joint(f"{s}_ankle")[:, 2].min() for s in ("left", "right")))
    return m.with_positions(m.positions - np.array([0.0, 0.0, low], np.float32)), low


def _plane(people: list[Motion]) -> dict[str, Any]:
    p = floor.floor_plane(people)
    if p is None:
        return {"tilt_deg": None}
    return {"tilt_deg": round(p.tilt_deg, 3), "residual_mm": round(1000 * p.residual_m, 2),
            "spread_m": round(p.spread_m, 2), "levelled": floor.is_tilted_floor(p)}


def person_row(m: Motion, corpus: str, file: str) -> dict[str, Any]:
    """The floor rules' numbers on one person read with the file's own floor."""
    bare = toeless(m)
    ankles = floor.planted_ankle_heights(bare)
    fit_h = floor.fit_ankle_height(bare)
    lowered, drop = on_ankles(bare)
    row: dict[str, Any] = {
        "corpus": corpus, "file": file, "person": m.name, "planted_ankles": int(ankles.size),
        "fit_ankle_mm": round(1000 * fit_h, 1),
        "body_fit_ankle_mm": round(1000 * fit_dimensions(bare).ankle_height, 1),
        "toe_raise_mm": round(1000 * floor.floor_offset([m]), 1),
        "ankle_raise_mm": round(1000 * floor.ankle_floor_offset([bare]), 1),
        "on_ankles_drop_mm": round(1000 * drop, 1),
        "on_ankles_raise_mm": round(1000 * floor.ankle_floor_offset([lowered]), 1),
        "toe_plane": _plane([m]), "ankle_plane": _plane([bare]),
    }
    if ankles.size:
        pts, side = floor.planted_contacts(bare, "ankle", floor.STILL_SPEED_MPS)
        feet = [pts[side == s, 2] for s in (0, 1)]
        feet = [f for f in feet if f.size >= floor.MIN_PLANTED] or [pts[:, 2]]
        row["lower_foot_p90_ratio"] = round(min(float(np.percentile(f, 90)) for f in feet)
                                            / fit_h, 3)
        row["ankle_median_mm"] = round(1000 * float(np.median(ankles)), 1)
    return row


def _people(loaded: Any) -> list[Motion]:
    return list(loaded.people) if isinstance(loaded, Interaction) else [loaded]


def files() -> list[tuple[str, Path]]:
    """(corpus, path) of every file checked; the Xia clips extracted from the snapshot to /tmp."""
    out = [("cmu", p) for p in sorted((CMU / "bvh").glob("*.bvh"))]
    out += [("cmu", p) for p in sorted((CMU / "asf_amc").glob("*.amc"))]
    out += [("cmu", d) for d in sorted((CMU / "two_person").iterdir()) if d.is_dir()]
    dest = Path("/tmp/floor_rule/xia")
    dest.mkdir(parents=True, exist_ok=True)
    names = subprocess.run(["git", f"--git-dir={DME}", "ls-tree", "--name-only", "HEAD",
                            XIA_TEST], check=True, capture_output=True, text=True).stdout.split()
    for blob in names:
        path = dest / Path(blob).name
        path.write_bytes(subprocess.run(["git", f"--git-dir={DME}", "show", f"HEAD:{blob}"],
                                        check=True, capture_output=True).stdout)
        out.append(("xia", path))
    return out


def _summary(rows: list[dict[str, Any]]) -> None:
    cmu = [r for r in rows if r["corpus"] == "cmu"]
    xia = [r for r in rows if r["corpus"] == "xia"]
    ratios = [r["lower_foot_p90_ratio"] for r in cmu
              if r["planted_ankles"] >= floor.MIN_PLANTED]
    print(f"CMU people: {len(cmu)}; toe rule fires on {sum(r['toe_raise_mm'] > 0 for r in cmu)}; "
          f"toe-less rule on the toe-stripped clips fires on "
          f"{sum(r['ankle_raise_mm'] > 0 for r in cmu)} "
          f"({[(r['person'], r['ankle_raise_mm']) for r in cmu if r['ankle_raise_mm'] > 0]}); "
          f"lower foot's planted-ankle p90 / fit ankle height: min {min(ratios):.3f}, "
          f"median {np.median(ratios):.3f}")
    err = [r["on_ankles_raise_mm"] - r["on_ankles_drop_mm"] for r in cmu
           if r["on_ankles_raise_mm"] > 0]
    print(f"CMU toe-stripped, floor put on the ankles: raised {len(err)} of {len(cmu)}; "
          f"raise - drop: median {np.median(err):+.1f} mm, range {min(err):+.1f} to "
          f"{max(err):+.1f} mm" if err else "CMU put on the ankles: none raised")
    diff = [r["fit_ankle_mm"] - r["body_fit_ankle_mm"] for r in rows]
    print(f"fit_ankle_height - fit_dimensions ankle height (toe-less): median "
          f"{np.median(diff):+.1f} mm, max |{max(np.abs(diff)):.1f}| mm")
    for kind in ("toe_plane", "ankle_plane"):
        t = sorted(r[kind]["tilt_deg"] for r in cmu if r[kind]["tilt_deg"] is not None)
        print(f"CMU {kind} tilt (deg, {len(t)} people with >= {floor.MIN_SPREAD_M} m spread): "
              f"{[round(x, 2) for x in t]}; levelled: "
              f"{[r['person'] for r in cmu if r[kind].get('levelled')]}")
    xr = [r["lower_foot_p90_ratio"] for r in xia]
    e = [r["ankle_raise_mm"] - r["toe_raise_mm"] for r in xia]
    pairs = [(r["person"], r["toe_raise_mm"], r["ankle_raise_mm"]) for r in xia]
    print(f"Xia ({len(xia)}): toe rule raises {sum(r['toe_raise_mm'] > 0 for r in xia)}, "
          f"toe-less rule {sum(r['ankle_raise_mm'] > 0 for r in xia)}; lower-foot p90 ratio "
          f"max {max(xr):.3f}; toe-less - toe raise: median {np.median(e):+.1f} mm, max "
          f"|{max(np.abs(e)):.1f}| mm (person, toe, toe-less mm): {pairs}")
    for kind in ("toe_plane", "ankle_plane"):
        print(f"Xia {kind}: {[(r['person'], r[kind]['tilt_deg']) for r in xia]}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("out/floor_rule/check.jsonl"))
    args = ap.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    loader.put_on_floor = lambda x: x  # the file's own floor: the rules are what is measured
    rows = []
    with args.out.open("w") as fh:
        for corpus, path in files():
            for m in _people(simenv.load(path)):
                rows.append(person_row(m, corpus, path.name))
                fh.write(json.dumps(rows[-1]) + "\n")
                fh.flush()
    _summary(rows)


if __name__ == "__main__":
    main()

"""Real clips and corrupted copies on which the joint-level metrics' results
are pinned (``tests/data/kinematic_golden.npz``).

The golden file was written by the straightforward, unoptimised metric code
(commit 701f1ef), but for ``walk_drift``'s ``foot_skate``, rewritten when the metric
stopped counting feet moving apart in a hop as sliding (commit 02a2c98: 0.792 -> 0.725,
still failing; no other case moved), and ``walk_no_toes``'s ``floating``, rewritten when a
toe-less skeleton's ankles started counting their sole height lower (120.1 mm, failing ->
0, passing: the real walk does not float; no other case moved);
``tests/test_plausibility_kinematic_golden.py`` checks that
the optimised metrics and :func:`simenv.plausibility.kinematic_metrics_batch`
still give the same values. Regenerate (only when a metric changes *on
purpose*) with::

    .venv/bin/python tests/kinematic_cases.py
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from simenv.assets import WALK, asset_path
from simenv.core.motion import Motion
from simenv.core.skeletons import Skeleton
from simenv.io import asf_amc, bvh
from simenv.plausibility import KINEMATIC_METRICS, MetricResult

GOLDEN = Path(__file__).resolve().parent / "data" / "kinematic_golden.npz"
#: AMC clips are cut to this many frames to keep the golden file small.
AMC_FRAMES = 1200


def _variants(walk: Motion) -> Iterator[tuple[str, Motion]]:
    """Seeded corruptions and edge cases of the bundled walk, so that every
    branch of every metric (violations, not-available reasons, resampling,
    the ankle fallback) is pinned, not only clean passes."""
    pos = walk.positions
    up = np.array([0.0, 0.0, 1.0], dtype=np.float32)
    yield "walk_raised_30cm", walk.with_positions(pos + 0.3 * up)
    yield "walk_lowered_5cm", walk.with_positions(pos - 0.05 * up)
    rng = np.random.default_rng(0)
    yield "walk_noise_5mm", walk.with_positions(
        pos + rng.normal(0, 0.005, pos.shape).astype(np.float32))
    tele = pos.copy()
    tele[150:153] += np.array([0.4, 0.0, 0.0], dtype=np.float32)
    yield "walk_teleport", walk.with_positions(tele)
    slide = pos.copy()
    slide[:, :, 0] += np.linspace(0, 3.0, len(pos), dtype=np.float32)[:, None]
    yield "walk_drift", walk.with_positions(slide)
    canon = walk.to_canonical()
    stretch = canon.positions.copy()
    knee, ankle = canon.skeleton.index("left_knee"), canon.skeleton.index("left_ankle")
    stretch[:, ankle:] += (np.linspace(0, 0.2, len(pos), dtype=np.float32)[:, None, None]
                           * (stretch[:, ankle:ankle + 1] - stretch[:, knee:knee + 1]))
    yield "walk_bone_stretch", canon.with_positions(stretch)
    toeless = [n for n in canon.skeleton.joint_names if not n.endswith("_toe")]
    yield "walk_no_toes", Motion(canon.positions[:, [canon.skeleton.index(n) for n in toeless]],
                                 canon.fps, canon.skeleton.subset(toeless), "no_toes")
    hover = pos.copy()
    hover[100:160] += 0.25 * up
    yield "walk_hover", walk.with_positions(hover)
    bare = Skeleton("unmapped", walk.skeleton.joint_names, walk.skeleton.parents, {})
    yield "walk_unmapped", Motion(pos, walk.fps, bare, "unmapped")
    yield "walk_30fps", walk.resample(30.0)
    yield "walk_25fps", walk.resample(25.0)
    for n in (1, 2, 3, 5, 36, 37, 40):
        yield f"walk_first_{n}", walk.slice(0, n)


def cases(shared_data: Path | None) -> Iterator[tuple[str, Motion]]:
    """(name, motion) of every pinned case; the shared-corpus clips only when
    ``shared_data`` is given."""
    walk = bvh.read(asset_path(WALK))
    yield "walk", walk
    yield from _variants(walk)
    if shared_data is None:
        return
    for path in sorted((shared_data / "cmu" / "bvh").glob("*.bvh")):
        yield f"bvh/{path.stem}", bvh.read(path)
    for path in sorted((shared_data / "cmu" / "asf_amc").glob("*.amc")):
        m = asf_amc.read(path)
        yield f"amc/{path.stem}", m.slice(0, min(AMC_FRAMES, m.num_frames))


def summary(result: MetricResult) -> dict:
    """Everything of a result but its timeline, JSON-exact (floats as repr)."""
    def num(v: float) -> float | str:
        return v if math.isfinite(v) else repr(v)
    return {"value": num(result.value), "unit": result.unit, "threshold": result.threshold,
            "passed": result.passed, "frame_threshold": result.frame_threshold,
            "timeline_unit": result.timeline_unit, "reason": result.reason,
            "details": {k: num(v) for k, v in result.details.items()},
            "violations": [[s, e, num(w)] for s, e, w in result.violations]}


def write(shared_data: Path) -> None:
    meta: dict[str, dict] = {}
    arrays: dict[str, np.ndarray] = {}
    for name, motion in cases(shared_data):
        results = {m: fn(motion) for m, fn in KINEMATIC_METRICS.items()}
        meta[name] = {m: summary(r) for m, r in results.items()}
        for m, r in results.items():
            arrays[f"{name}:{m}"] = r.timeline
    GOLDEN.parent.mkdir(exist_ok=True)
    np.savez_compressed(GOLDEN, _meta=np.array(json.dumps(meta)), **arrays)
    print(f"wrote {GOLDEN} ({len(meta)} cases)")


if __name__ == "__main__":
    from conftest import SHARED_DATA  # the script's folder is on sys.path

    write(SHARED_DATA)

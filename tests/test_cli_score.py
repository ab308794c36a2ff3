"""``simenv score``'s feedback on long work: the physics tracking shows its frames."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import simenv
from simenv.assets import WALK, asset_path
from simenv.io.npz import write_npz


def test_score_with_physics_shows_tracking_progress(tmp_path: Path) -> None:
    """A real walk's first 0.3 s scored with physics and --progress: stderr carries the
    tracking's bar (its 35 frame steps); stdout stays one JSON line."""
    clip = write_npz(simenv.load(asset_path(WALK)).slice(0, 36), tmp_path / "walk.npz")
    # The bar, not the verdict: the quick planner, one attempt.
    run = subprocess.run([sys.executable, "-m", "simenv", "score", str(clip), "--json",
                          "--progress", "--planner", "fast", "--tracking-attempts", "1"],
                         capture_output=True, text=True, timeout=None)
    assert run.returncode == 0, run.stderr
    assert len(run.stdout.strip().splitlines()) == 1
    assert re.search(r"track cmu_02_01_walk \(mpc\):.*/35 \[.*frame/s", run.stderr)


def test_score_out_says_what_it_scored_and_skipped(tmp_path: Path, capsys) -> None:
    """With --out, a run ends with one line counting the files scored, skipped (already in
    the results: a rerun resumes) and failed; with --json it goes to stderr."""
    from simenv.cli.main import main

    out = tmp_path / "new" / "results.jsonl"  # a folder that does not exist yet
    walk = str(asset_path(WALK))
    assert main(["score", walk, "--no-physics", "--out", str(out)]) == 0
    first = capsys.readouterr().out.strip().splitlines()
    assert first[-1] == f"results in {out}: 1 file(s) scored, 0 skipped (already there), 0 failed"
    assert main(["score", walk, "--no-physics", "--out", str(out), "--json"]) == 0
    rerun = capsys.readouterr()
    assert rerun.out == ""
    assert rerun.err.strip().splitlines()[-1] == (
        f"results in {out}: 0 file(s) scored, 1 skipped (already there), 0 failed")
    assert len(out.read_text().splitlines()) == 1


def test_planner_fast_searches_less_with_the_scorers_seeds_and_attempts() -> None:
    from simenv.cli.main import build_parser
    from simenv.cli.score import score_config
    from simenv.control import FAST
    from simenv.plausibility.metric import ScoreConfig

    parse = build_parser().parse_args
    assert score_config(parse(["score", "x.bvh"])) is None
    default = ScoreConfig().mpc
    fast = score_config(parse(["score", "x.bvh", "--planner", "fast"])).mpc
    assert (fast.n_samples, fast.timestep_factor, fast.antithetic) == (
        FAST.n_samples, FAST.timestep_factor, FAST.antithetic)
    assert (fast.seed, fast.attempts, fast.retry_horizon_s) == (
        default.seed, default.attempts, default.retry_horizon_s)
    assert fast.n_samples * default.timestep_factor < default.n_samples * fast.timestep_factor
    one = score_config(parse(["score", "x.bvh", "--planner", "fast", "--tracking-attempts", "1"]))
    assert one.mpc.attempts == 1 and one.mpc.n_samples == FAST.n_samples

"""The planner choices of the physics verdict (simenv.plausibility.planner)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from simenv.cli import main as cli
from simenv.control import FAST, MPCConfig
from simenv.plausibility.metric import ScoreConfig
from simenv.plausibility.planner import PLANNERS, planner_record, planning_cost, with_planner
from simenv.plausibility.report import DEFAULT_SCORE_CONFIG


def test_fast_plans_with_fast_search_and_the_configs_seeds():
    base = ScoreConfig(mpc=MPCConfig(seed=7, attempts=2, retry_horizon_s=0.5))
    assert with_planner(base, "default") is base
    fast = with_planner(base, "fast")
    assert fast.mpc == replace(FAST, seed=7, attempts=2, retry_horizon_s=0.5,
                               nthread=base.mpc.nthread)
    assert replace(fast, mpc=base.mpc) == base  # every threshold kept
    with pytest.raises(ValueError, match="default, fast"):
        with_planner(base, "slow")
    assert PLANNERS == ("default", "fast")


def test_cost_and_record_compare_with_the_scorers_planner():
    shipped = DEFAULT_SCORE_CONFIG
    fast = with_planner(shipped, "fast")
    # 128 samples x 0.45 s / 2 physics steps per planning step / 10 between replans, and
    # FAST's quarter of it (mirrored pairs of 64 samples, an 8 ms planning step).
    ratio = planning_cost(shipped.mpc) / planning_cost(fast.mpc)
    assert ratio == pytest.approx(4.0, rel=0.05)
    record = planner_record(fast)
    assert record["n_samples"] == FAST.n_samples and record["antithetic"] is True
    assert f"({ratio:.0f}x the rolled-out steps)" in record["text"]
    assert planner_record(shipped)["text"].endswith("(1x the rolled-out steps)")


def test_rehearse_takes_the_planner_only_for_a_reaction_generator(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        cli.main(["rehearse", "cmu_02_01_walk.bvh", "--agent", "labels", "--out",
                  str(tmp_path), "--planner", "fast"])
    assert exit_.value.code == 2
    assert "--planner: not used with --agent labels" in capsys.readouterr().err

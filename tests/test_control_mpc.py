"""The unassisted tracking MPC (simenv.control.mpc) on real CMU motion.

Short clips only (at most 1.5 s of the bundled walk): the long per-clip
evaluation lives in benchmarks/eval_tracking.py and docs/plausibility.md.
"""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from simenv.control import FAST, MPCConfig, TrackingMPC, TrackingReference
from simenv.control.model import root_dofs
from simenv.core.errors import PhysicsError
from simenv.plausibility.tracking import track, tracking

#: A cheaper planner than the scorer's default for the behavioural tests (the
#: scorer's default is exercised by tests/test_plausibility_report.py).
QUICK = MPCConfig(n_samples=16, timestep_factor=2, horizon_s=0.25)


@pytest.fixture(scope="module")
def walk_mpc(walk_2s_retargeted):
    return track(walk_2s_retargeted, controller="mpc", mpc=QUICK, max_seconds=1.5)


def test_mpc_keeps_the_real_walk_up_where_the_pd_servos_fall(walk_mpc,
                                                             walk_2s_retargeted) -> None:
    pd = track(walk_2s_retargeted, max_seconds=1.5)
    assert not pd.success and pd.time_to_failure_s < 1.2
    assert walk_mpc.success and walk_mpc.controller == "mpc" and not walk_mpc.assisted
    assert walk_mpc.time_to_failure_s == pytest.approx(1.5)
    assert walk_mpc.mpjpe_mm < 200.0
    assert not np.isnan(walk_mpc.body_error[:181]).any()
    # Walking costs the muscles work: positive, and per kilogram below a sprint's
    # order of magnitude (a body thrashing against itself would do far more).
    assert 1.0 < walk_mpc.work_j_per_kg < 100.0
    assert walk_mpc.work_j == pytest.approx(
        walk_mpc.work_j_per_kg * walk_2s_retargeted.humanoid.total_mass)


def test_nothing_but_the_hinge_servos_acts_on_the_body(walk_2s_retargeted) -> None:
    ref = TrackingReference.from_retarget(walk_2s_retargeted, max_seconds=0.2)
    with TrackingMPC(walk_2s_retargeted.humanoid, ref, QUICK) as mpc:
        model = mpc.model
        assert model.neq == 0 and model.nmocap == 0
        assert (model.actuator_trntype == mujoco.mjtTrn.mjTRN_JOINT).all()
        free = model.jnt_type == mujoco.mjtJoint.mjJNT_FREE
        assert not np.isin(model.actuator_trnid[:, 0], np.flatnonzero(free)).any()
        data = mujoco.MjData(model)
        mpc.reset(data)
        root = root_dofs(model)
        for s in range(ref.n_steps):
            data.ctrl[:] = mpc.control(data, s)
            mujoco.mj_step(model, data)
            assert not data.xfrc_applied.any() and not data.qfrc_applied.any()
            assert not data.qfrc_actuator[root].any()
        assert mpc.replans == ref.n_steps // QUICK.replan_steps


def test_same_seed_same_motion_whatever_the_threads(walk_2s_retargeted) -> None:
    runs = [track(walk_2s_retargeted, controller="mpc", max_seconds=0.15,
                  mpc=replace(QUICK, nthread=n, seed=seed))
            for n, seed in ((1, 0), (2, 0), (2, 1))]
    np.testing.assert_array_equal(runs[0].sim_keypoints, runs[1].sim_keypoints)
    assert not np.array_equal(runs[0].sim_keypoints[-1], runs[2].sim_keypoints[-1])


def test_a_teleported_walk_fails_at_the_jump(walk_2s_retargeted) -> None:
    q = walk_2s_retargeted.qpos.copy()
    q[60:, 0] += 2.0  # the whole reference jumps 2 m sideways at 0.5 s
    r = tracking(replace(walk_2s_retargeted, qpos=q), controller="mpc", mpc=QUICK,
                 max_seconds=0.7)
    assert r.passed is False and r.details["mpc"] == 1.0
    assert r.details["time_to_failure_s"] == pytest.approx(0.5, abs=2 / 120.0)
    assert r.details["assist_force_mean"] == 0.0 and r.details["work_j"] > 0.0


def test_a_teleport_corruption_fails_where_it_was_put(walk_2s) -> None:
    from simenv.body.retarget import retarget
    from simenv.plausibility.corrupt import teleport

    bad = teleport(walk_2s, 1.0, seed=0)  # 1-4 frames 1 m away, the seed picks where
    start, _ = bad.metadata["corruptions"][-1]["frames"][0]
    tr = track(retarget(bad), controller="mpc", mpc=QUICK)
    assert not tr.success
    assert tr.frames_tracked - 1 == pytest.approx(start, abs=1)


def test_a_floating_walk_falls(walk_2s_retargeted) -> None:
    q = walk_2s_retargeted.qpos.copy()
    q[:, 2] += 1.0  # a body 1 m in the air cannot follow a walk up there
    tr = track(replace(walk_2s_retargeted, qpos=q), controller="mpc", mpc=QUICK)
    assert not tr.success and tr.error is None and tr.time_to_failure_s < 0.6


def test_retries_rewind_to_states_the_body_reached_and_still_fail_the_impossible(
        walk_2s_retargeted) -> None:
    """A 2 m teleport at 0.5 s: each retry rewinds 0.25 s (to a checkpoint the body
    reached itself), draws new samples and fails at the jump again; the run reports its
    rewinds, its frames after the failure stay empty, and without retries the run is the
    same as before the option existed."""
    q = walk_2s_retargeted.qpos.copy()
    q[60:, 0] += 2.0
    jumped = replace(walk_2s_retargeted, qpos=q)
    once = track(jumped, controller="mpc", mpc=QUICK, max_seconds=0.7)
    again = track(jumped, controller="mpc", mpc=replace(QUICK, retries=2, rewind_s=0.25),
                  max_seconds=0.7)
    assert once.retries == 0 and again.retries == 2
    assert not again.success and again.frames_tracked == once.frames_tracked
    assert np.isnan(again.body_error[again.frames_tracked:]).all()
    # The kept trajectory is one the body performed: before the last checkpoint it is
    # the first attempt's, bit for bit; the discarded attempts cost simulator steps.
    np.testing.assert_array_equal(again.sim_keypoints[:30], once.sim_keypoints[:30])
    assert again.steps > once.steps
    r = tracking(jumped, controller="mpc", mpc=replace(QUICK, retries=1, rewind_s=0.25),
                 max_seconds=0.7)
    assert r.passed is False and r.details["retries"] == 1.0


def test_attempts_try_further_seeds_until_one_tracks(walk_2s_retargeted) -> None:
    """A run the first seed tracks is not simulated again; a 2 m teleport fails every seed
    (the further ones planning over ``retry_horizon_s``), and the run kept is the one that
    got furthest (the first of equals), the others' cost counted."""
    easy = track(walk_2s_retargeted, controller="mpc", max_seconds=0.15, mpc=QUICK)
    tried = track(walk_2s_retargeted, controller="mpc", max_seconds=0.15,
                  mpc=replace(QUICK, attempts=3))
    assert easy.success and tried.success and tried.runs == 1
    np.testing.assert_array_equal(tried.sim_keypoints, easy.sim_keypoints)
    q = walk_2s_retargeted.qpos.copy()
    q[60:, 0] += 2.0
    jumped = replace(walk_2s_retargeted, qpos=q)
    # The further attempts plan over the longer retry horizon.
    seeds = [track(jumped, controller="mpc", max_seconds=0.7, mpc=replace(QUICK, seed=s, **kw))
             for s, kw in ((0, {}), (1, {"horizon_s": QUICK.retry_horizon_s}))]
    both = track(jumped, controller="mpc", max_seconds=0.7, mpc=replace(QUICK, attempts=2))
    assert not both.success and both.runs == 2
    assert both.steps == seeds[0].steps + seeds[1].steps
    furthest = max(seeds, key=lambda r: r.frames_tracked)
    np.testing.assert_array_equal(both.sim_keypoints, furthest.sim_keypoints)
    r = tracking(jumped, controller="mpc", max_seconds=0.7, mpc=replace(QUICK, attempts=2))
    assert r.passed is False and r.details["runs"] == 2.0


def test_attempt_settings_move_the_seed_and_plan_further_ahead_after_the_first() -> None:
    cfg = MPCConfig(seed=5, horizon_s=0.45, retry_horizon_s=0.6)
    assert cfg.attempt(0) == cfg
    assert (cfg.attempt(2).seed, cfg.attempt(2).horizon_s) == (7, 0.6)
    assert replace(cfg, retry_horizon_s=None).attempt(1).horizon_s == 0.45


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"controller": "lqr"}, "controller"),
    ({"controller": "mpc", "assist": True}, "assist"),
])
def test_bad_tracking_options_raise_naming_the_field(walk_2s_retargeted, kwargs, field) -> None:
    with pytest.raises(PhysicsError) as err:
        track(walk_2s_retargeted, max_seconds=0.1, **kwargs)
    assert err.value.field == field


@pytest.mark.parametrize("field", ["horizon_s", "n_samples", "replan_steps", "nthread",
                                   "timestep_factor", "temperature", "retries", "rewind_s",
                                   "attempts", "retry_horizon_s"])
def test_bad_mpc_settings_raise_naming_the_field(field) -> None:
    with pytest.raises(PhysicsError) as err:
        MPCConfig(**{field: -1 if field in ("temperature", "retries") else 0})
    assert err.value.field == field


def test_the_planner_counts_its_rolled_out_steps(walk_2s_retargeted) -> None:
    """``rollout_steps`` is the planner's cost in simulator steps: N samples x H planning
    steps per replan, summed by the tracker over every run (zero for the PD servos)."""
    ref = TrackingReference.from_retarget(walk_2s_retargeted, max_seconds=0.1)
    with TrackingMPC(walk_2s_retargeted.humanoid, ref, QUICK) as mpc:
        data = mujoco.MjData(mpc.model)
        mpc.reset(data)
        for s in range(ref.n_steps):
            data.ctrl[:] = mpc.control(data, s)
            mujoco.mj_step(mpc.model, data)
        assert mpc.rollout_steps == mpc.replans * QUICK.n_samples * mpc.horizon > 0
        per_run = mpc.rollout_steps
    tr = track(walk_2s_retargeted, controller="mpc", mpc=replace(QUICK, attempts=2),
               max_seconds=0.1)
    assert tr.runs == 1 and tr.rollout_steps == per_run
    assert track(walk_2s_retargeted, max_seconds=0.1).rollout_steps == 0


def test_the_fast_planner_rolls_out_a_quarter_of_the_default_ones_steps(
        walk_2s_retargeted) -> None:
    """Issue 35: :data:`FAST`'s budget per simulated step against the default's (128 samples
    over 0.45 s at a 4 ms planning step), from the horizons the planners build."""
    ref = TrackingReference.from_retarget(walk_2s_retargeted, max_seconds=0.1,
                                          feedforward=False)
    budgets = []
    for cfg in (MPCConfig(), FAST):
        with TrackingMPC(walk_2s_retargeted.humanoid, ref, replace(cfg, nthread=1)) as mpc:
            budgets.append(cfg.n_samples * mpc.horizon / cfg.replan_steps)
    assert budgets[0] == pytest.approx(128 * 112 / 10)
    assert budgets[1] == pytest.approx(budgets[0] / 4, rel=0.01)
    assert FAST.antithetic and not MPCConfig().antithetic


def test_antithetic_coarse_planning_is_seeded_and_thread_independent(walk_2s_retargeted) -> None:
    """FAST's sampling (mirrored pairs) and 8 ms planning step keep the contract: the same
    seed gives the same motion on 1 or 2 rollout threads, another seed another motion."""
    cheap = replace(QUICK, antithetic=FAST.antithetic, timestep_factor=FAST.timestep_factor)
    runs = [track(walk_2s_retargeted, controller="mpc", max_seconds=0.15,
                  mpc=replace(cheap, nthread=n, seed=seed))
            for n, seed in ((1, 0), (2, 0), (1, 1))]
    np.testing.assert_array_equal(runs[0].sim_keypoints, runs[1].sim_keypoints)
    assert not np.array_equal(runs[0].sim_keypoints[-1], runs[2].sim_keypoints[-1])
    assert runs[0].success and runs[0].rollout_steps == runs[1].rollout_steps


def test_a_screened_replan_prices_its_survivors_as_a_whole_rollout_would(
        walk_2s_retargeted) -> None:
    """``screen_fraction``: every sample rolls a third of the horizon, the cheaper half the
    rest from where it stopped. The continued rollouts cost exactly what whole ones do (the
    same physics), the others never win (here the cheapest whole rollout is among the
    survivors), and the rolled-out steps drop to N H (1/3 + 2/3 / 2)."""
    ref = TrackingReference.from_retarget(walk_2s_retargeted, max_seconds=0.3)
    costs, steps = {}, {}
    for name, cfg in (("whole", QUICK), ("screened", replace(QUICK, screen_fraction=1 / 3))):
        with TrackingMPC(walk_2s_retargeted.humanoid, ref, cfg) as mpc:
            data = mujoco.MjData(mpc.model)
            mpc.reset(data)
            mpc.plan(data, 0)
            costs[name], steps[name] = mpc.last_costs.copy(), mpc.rollout_steps
    kept = np.isfinite(costs["screened"])
    assert kept.sum() == QUICK.n_samples // 2
    np.testing.assert_allclose(costs["screened"][kept], costs["whole"][kept], rtol=1e-9)
    assert kept[np.argmin(costs["whole"])]
    horizon = steps["whole"] // QUICK.n_samples
    h1 = round(horizon / 3)
    assert steps["screened"] == QUICK.n_samples * h1 + QUICK.n_samples // 2 * (horizon - h1)
    with pytest.raises(PhysicsError, match="screen_fraction"):
        MPCConfig(screen_fraction=1.0)

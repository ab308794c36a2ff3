"""The learned tracking policy (simenv.control.policy) and its tracker with the planner as
fallback (simenv.plausibility.policy_tracking), on the real CMU walk 02_01 (the bundled
clip): a policy fitted here on the planner's own actions over the walk's first 0.1 s (a
one-layer least-squares fit: the trained network of benchmarks/train_tracking_policy.py is
the same class with more layers)."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from simenv.control import FAST, TrackingReference
from simenv.control.policy import (
    ExpertRecorder,
    Observer,
    PolicyConfig,
    PolicyTracker,
    TrackingPolicy,
)
from simenv.core.errors import PhysicsError
from simenv.plausibility.policy_tracking import track_policy

PLANNER = replace(FAST, nthread=1)


@pytest.fixture(scope="module")
def recorded(walk_2s_retargeted):
    """The planner (FAST, one thread) driving and labelling the walk's first 0.1 s: the
    reference, the recorder's features (S, D) and offsets (S, A)."""
    ref = TrackingReference.from_retarget(walk_2s_retargeted, max_seconds=0.1)
    with ExpertRecorder(walk_2s_retargeted.humanoid, ref, PLANNER) as rec:
        data = mujoco.MjData(rec.model)
        rec.reset(data)
        for s in range(ref.n_steps):
            data.ctrl[:] = rec.control(data, s)
            mujoco.mj_step(rec.model, data)
        return ref, np.array(rec.features), np.array(rec.offsets), rec.actuators


@pytest.fixture(scope="module")
def policy(recorded) -> TrackingPolicy:
    """A linear-tanh policy least-squares fitted to the recorded planner offsets."""
    _, X, Y, actuators = recorded
    mean, std = X.mean(0), X.std(0) + 1e-3
    Z = np.hstack([(X - mean) / std, np.ones((len(X), 1))])
    target = np.arctanh(np.clip(Y / PLANNER.limit_rad, -0.95, 0.95))
    W = np.linalg.lstsq(Z, target, rcond=None)[0]
    return TrackingPolicy((W[:-1],), (W[-1],), mean, std, actuators, PLANNER.limit_rad)


def test_recorder_labels_each_step_with_the_planners_offsets(recorded, walk_2s_retargeted):
    ref, X, Y, actuators = recorded
    obs = Observer(walk_2s_retargeted.humanoid.model, ref, ref.ctrl,
                   walk_2s_retargeted.humanoid.site_ids)
    assert X.shape == (ref.n_steps, obs.size) and np.isfinite(X).all()
    # The planner's sampled actuators (lumbar and legs), offsets within its knot limit.
    assert Y.shape == (ref.n_steps, len(actuators)) and 0 < len(actuators) < ref.ctrl.shape[1]
    assert np.abs(Y).max() <= PLANNER.limit_rad + 1e-9 and np.abs(Y).max() > 0


def test_policy_acts_within_the_servo_ranges_and_round_trips(policy, recorded,
                                                             walk_2s_retargeted, tmp_path):
    ref, X, _, actuators = recorded
    a = policy(X)
    assert a.shape == (len(X), len(actuators)) and np.abs(a).max() <= PLANNER.limit_rad
    with PolicyTracker(walk_2s_retargeted.humanoid, ref, policy,
                       PolicyConfig(engage_m=np.inf, planner=PLANNER)) as tracker:
        data = mujoco.MjData(tracker.model)
        tracker.reset(data)
        lo, hi = tracker.model.actuator_ctrlrange.T
        limited = tracker.model.actuator_ctrllimited.astype(bool)
        for s in range(ref.n_steps):
            u = tracker.control(data, s)
            assert np.all((u[limited] >= lo[limited]) & (u[limited] <= hi[limited]))
            mujoco.mj_step(tracker.model, data)
        assert tracker.policy_steps == ref.n_steps and tracker.rollout_steps == 0
    policy.save(tmp_path / "p.npz")
    again = TrackingPolicy.load(tmp_path / "p.npz")
    np.testing.assert_allclose(again(X[:5]), a[:5], atol=1e-5)  # float32 weights


def test_fallback_engages_when_forced_and_runs_reproduce(policy, walk_2s_retargeted):
    forced = PolicyConfig(engage_m=1e-6, release_m=1e-6, planner=PLANNER)
    run = track_policy(walk_2s_retargeted, policy, forced, max_seconds=0.1)
    # The body starts on the reference (error 0); from the second step on its error exceeds
    # a micrometre and the planner drives the rest.
    assert (run.policy_steps, run.fallback_steps, run.engagements) == (1, 49, 1)
    assert run.result.rollout_steps > 0 and run.result.controller == "policy"
    alone = PolicyConfig(engage_m=np.inf, planner=PLANNER)
    a = track_policy(walk_2s_retargeted, policy, alone, max_seconds=0.1)
    b = track_policy(walk_2s_retargeted, policy, alone, max_seconds=0.1)
    assert a.fallback_steps == 0 and a.result.rollout_steps == 0
    np.testing.assert_array_equal(a.result.body_error, b.result.body_error)


def test_bad_policy_input_is_a_typed_error(policy, walk_2s_retargeted, tmp_path):
    bad = tmp_path / "not_a_policy.npz"
    np.savez(bad, mean=np.zeros(3))
    with pytest.raises(PhysicsError, match="not_a_policy"):
        TrackingPolicy.load(bad)
    short = replace(policy, weights=(policy.weights[0][:-1],), mean=policy.mean[:-1],
                    std=policy.std[:-1])
    with pytest.raises(PhysicsError, match="features"):
        track_policy(walk_2s_retargeted, short, max_seconds=0.1)
    with pytest.raises(PhysicsError, match="release_m"):
        PolicyConfig(engage_m=0.05, release_m=0.1)


def test_shipped_policy_fits_a_fitted_body(walk_2s_retargeted):
    """The trained policy (assets/models/tracking-policy.npz, its card beside it), loaded by
    name as every shipped model, reads the features of another fitted body and drives it,
    alone, through the walk's first 0.1 s."""
    import simenv.models

    if "tracking-policy" not in simenv.models.available():
        pytest.skip("assets/models/tracking-policy.npz is not shipped")
    path = simenv.models.checkpoint_path("tracking-policy")
    assert "split" in path.with_suffix(".md").read_text().lower()
    shipped = simenv.models.load("tracking-policy")
    assert isinstance(shipped, TrackingPolicy)
    run = track_policy(walk_2s_retargeted, shipped, PolicyConfig(engage_m=np.inf,
                                                                  planner=PLANNER),
                       max_seconds=0.1)
    assert run.policy_steps == 50 and run.result.success

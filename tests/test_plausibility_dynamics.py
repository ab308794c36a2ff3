"""Inverse-dynamics root residual and balance on real retargeted mocap."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from expect import raises_at

import simenv
from simenv.body.dynamics import DEFAULT_DYNAMICS, finite_differences
from simenv.body.humanoid import Humanoid
from simenv.body.retarget import retarget
from simenv.core.errors import PhysicsError
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS
from simenv.plausibility.dynamics import (
    dynamics_settings,
    root_residual,
    root_residual_wrench,
)
from simenv.plausibility.metrics.balance import balance, distance_outside
from simenv.plausibility.metrics.ground_penetration import body_penetration

UP = np.array([0.0, 0.0, 1.0], dtype=np.float32)


def test_dynamics_defaults_are_the_body_thresholds() -> None:
    assert dynamics_settings(DEFAULT_BODY_THRESHOLDS) == DEFAULT_DYNAMICS


def test_real_walk_needs_no_invisible_help(walk_2s_retargeted) -> None:
    r = root_residual(walk_2s_retargeted)
    assert r.available and r.passed, (r.value, r.details)
    assert r.value < 0.05
    # Walking needs about one body weight of ground reaction on average,
    # which the feet provide.
    assert 0.8 < r.details["required_mean"] < 1.2
    assert r.details["unsupported_fraction"] == 0.0


def test_real_walk_is_balanced(walk_2s_retargeted) -> None:
    r = balance(walk_2s_retargeted)
    assert r.available and r.passed, (r.value, r.details)


def test_walk_raised_30cm_needs_one_body_weight(walk_2s) -> None:
    high = retarget(walk_2s.with_positions(walk_2s.positions + 0.30 * UP))
    r = root_residual(high)
    assert r.passed is False
    assert r.value == pytest.approx(1.0, abs=0.1)
    assert r.details["unsupported_fraction"] == 1.0
    assert r.violations == [(0, high.num_frames - 1, pytest.approx(r.details["max"], rel=1e-6))]


def test_residual_grows_with_unsupported_time(walk_2s_retargeted) -> None:
    # Lift only the middle second: the residual is there and nowhere else.
    q = walk_2s_retargeted.qpos.copy()
    q[60:180, 2] += 0.3
    rr = root_residual_wrench(replace(walk_2s_retargeted, qpos=q))
    assert (rr.support_points[70:170] == 0).all()
    assert np.median(rr.force[70:170]) > 0.8
    assert np.median(rr.force[:50]) < 0.1


def test_measured_residual_counts_only_what_the_controller_could_not_track(
        walk_2s_retargeted) -> None:
    """With an unassisted controller's body error, frames it followed need no help
    and the rest keep the inferred residual: a walk lifted 30 cm for its middle
    second, which a body under gravity cannot follow there, still needs it."""
    q = walk_2s_retargeted.qpos.copy()
    q[60:180, 2] += 0.3
    lifted = replace(walk_2s_retargeted, qpos=q)
    inferred = root_residual(lifted)
    T = lifted.num_frames
    err = np.full(T, 0.03)
    err[60:180] = 0.25   # the simulated body dropped to the floor there
    err[-20:] = np.nan   # and stopped before the end
    measured = root_residual(lifted, tracked_error=err)
    untracked = np.zeros(T, dtype=bool)
    untracked[60:180] = untracked[-20:] = True
    np.testing.assert_allclose(measured.timeline[untracked], inferred.timeline[untracked])
    assert (measured.timeline[~untracked] == 0.0).all()
    assert measured.details["measured_fraction"] == pytest.approx((~untracked).mean())
    assert measured.details["inferred_mean"] == pytest.approx(inferred.value)
    assert inferred.details["measured_fraction"] == 0.0
    # The lift alone (120 of T frames at ~1 BW) keeps it implausible.
    assert not measured.passed and 0.8 * 120 / T < measured.value < inferred.value
    # A controller that followed every frame within the limit measured no help.
    assert root_residual(lifted, tracked_error=np.zeros(T)).value == 0.0
    with pytest.raises(PhysicsError, match="one body error per frame"):
        root_residual(lifted, tracked_error=np.zeros(T - 1))


def test_balance_flags_a_lean_past_the_feet(walk_2s_retargeted) -> None:
    # A frozen pose is quasi-static on every frame. Standing frozen in the
    # walk's first pose is balanced; the same pose tipped forward by 0.4 rad
    # about the root puts the centre of mass beyond the toes.
    still = np.repeat(walk_2s_retargeted.qpos[:1], 60, axis=0)
    lean = still.copy()
    lean[:, 3:7] = [np.cos(0.2), 0.0, np.sin(0.2), 0.0]
    ok = balance(replace(walk_2s_retargeted, qpos=still))
    bad = balance(replace(walk_2s_retargeted, qpos=lean))
    assert ok.passed and ok.details["judged_fraction"] == 1.0
    assert bad.passed is False
    assert bad.details["outside_fraction"] == 1.0 and bad.value > 50.0


def test_distance_outside_polygon() -> None:
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert distance_outside(np.array([0.5, 0.5]), square) == 0.0
    assert distance_outside(np.array([2.0, 0.5]), square) == pytest.approx(1.0)
    assert distance_outside(np.array([2.0, 2.0]), square) == pytest.approx(np.sqrt(2.0))
    # Degenerate supports: one point, a segment (collinear points).
    assert distance_outside(np.array([3.0, 4.0]), square[:1]) == pytest.approx(5.0)
    seg = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    assert distance_outside(np.array([1.0, 1.0]), seg) == pytest.approx(1.0)
    assert distance_outside(np.array([3.0, 0.0]), seg) == pytest.approx(1.0)


def test_finite_differences_of_a_constant_velocity_root(walk_2s_retargeted) -> None:
    model = walk_2s_retargeted.humanoid.model
    q = np.repeat(walk_2s_retargeted.qpos[:1], 50, axis=0)
    q[:, 0] += 1.5 * np.arange(50) / 120.0  # 1.5 m/s along x
    qvel, qacc = finite_differences(model, q, 120.0)
    assert qvel.shape == qacc.shape == (50, model.nv)
    np.testing.assert_allclose(qvel[5:-5, 0], 1.5, atol=1e-6)
    np.testing.assert_allclose(qacc[5:-5], 0.0, atol=1e-6)


def test_short_and_bad_input(walk_2s_retargeted) -> None:
    two = replace(walk_2s_retargeted, qpos=walk_2s_retargeted.qpos[:2])
    for metric in (root_residual, balance):
        r = metric(two)
        assert r.passed is None and "3 frames" in r.reason
    with pytest.raises(PhysicsError, match="at least 2 frames"):
        finite_differences(walk_2s_retargeted.humanoid.model, walk_2s_retargeted.qpos[:1], 120.0)
    q = walk_2s_retargeted.qpos.copy()
    q[33, 0] = np.inf
    raises_at(PhysicsError, "NaN/inf", lambda: root_residual(replace(walk_2s_retargeted, qpos=q)),
              frame=33)
    with pytest.raises(PhysicsError, match="shape"):
        balance(replace(walk_2s_retargeted, qpos=walk_2s_retargeted.qpos[:, :5]))


def test_clip_end_cut_mid_stride_needs_no_help_but_a_dead_stop_does(walk_2s_retargeted) -> None:
    # The finite differences are one-sided at a clip's ends: cutting the real walk
    # mid-stride must not make its last frames need help (measured: <= 0.03 body
    # weight). Holding the last pose for 6 frames, as the final frames of CMU 49_04 do,
    # stops the 1.3 m/s walker dead, which the floor's friction cannot do (0.5-0.6).
    w = walk_2s_retargeted
    for cut in (120, 160, 200):
        cut_end = root_residual_wrench(replace(w, qpos=w.qpos[:cut])).force[-8:]
        assert cut_end.max() < 0.1, (cut, cut_end)
        frozen = np.concatenate([w.qpos[:cut], np.repeat(w.qpos[cut - 1:cut], 6, axis=0)])
        assert root_residual_wrench(replace(w, qpos=frozen)).force[-12:].max() > 0.3


def test_131_04_opening_balance_hinges_on_the_fitted_sole(shared_data) -> None:
    # CMU 131_04 (docs/plausibility.md, calibration findings): this subject's ball
    # keypoints sit 3-5 cm higher over the ankles in the quiet stances than in the single
    # stances. The body fit (simenv.body.humanoid.fit_dimensions) measures the foot's drop on
    # the planted frames and places the one sole between the lowest balls and the lowest
    # ankles: the opening stance's forefeet then carry the body and nothing sinks.
    motion = simenv.load(shared_data / "cmu" / "asf_amc" / "131_04.amc")
    fitted = retarget(motion)
    b = balance(fitted)
    assert b.passed and b.details["judged_fraction"] > 0.1, (b.value, b.details)
    assert body_penetration(fitted).passed
    # The previous rule's body (sole from the lowest balls alone, drop = lowest ankle
    # minus lowest ball, from different frames) stands on its heels in frames 0-8 with
    # the forefoot corners above the 5 cm support height (measured: 105 mm outside).
    canon = motion.to_canonical()
    names = canon.skeleton.joint_names
    low = {key: float(np.percentile(canon.positions[:, [names.index(f"{s}_{key}")
                                                         for s in ("left", "right")], 2], 2))
           for key in ("toe", "ankle")}
    old = Humanoid(replace(fitted.humanoid.dims, toe_height=low["toe"],
                           ankle_height=low["ankle"]))
    timeline = balance(retarget(motion, old)).timeline
    outside = np.flatnonzero(timeline > 50.0)
    assert len(outside) and (outside < 12).all(), outside

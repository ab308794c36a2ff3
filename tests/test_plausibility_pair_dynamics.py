"""Two-person root residual: hand-contact forces between partners, on real CMU salsa."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import simenv
from simenv.assets import HANDSHAKE_PAIR, asset_path
from simenv.body.retarget import retarget
from simenv.plausibility.body_thresholds import BodyThresholds
from simenv.plausibility.dynamics import root_residual
from simenv.plausibility.metric import ScoreConfig
from simenv.plausibility.pair_dynamics import (
    hand_contacts,
    pair_root_residual,
    pair_root_residual_wrench,
)

UP = np.array([0.0, 0.0, 1.0], dtype=np.float32)


@pytest.fixture(scope="module")
def salsa(shared_data):
    """CMU salsa 60_05 (lead) + 61_05 (follower), 2 s from frame 700: the partners'
    hands touch on most of these frames (measured 0.86 of a 2 s window)."""
    clip = simenv.load(shared_data / "cmu" / "two_person" / "60_61_salsa_05")
    return clip.slice(700, 940)


@pytest.fixture(scope="module")
def salsa_fit(salsa):
    return retarget(salsa)


def test_partner_hands_explain_part_of_the_followers_residual(salsa_fit) -> None:
    pr = pair_root_residual_wrench(salsa_fit)
    touching = pr.contacts.counts > 0
    assert touching.mean() > 0.5
    follower = pr.single[1].force
    # Frames without contact keep the single-person residual exactly.
    np.testing.assert_array_equal(pr.force[1][~touching], follower[~touching])
    # With contact the follower needs clearly less help from nowhere ...
    assert pr.force[1][touching].mean() < 0.75 * follower[touching].mean()
    # ... and the force used is bounded: at most F per contact (box inscribed in the ball),
    # so their sum is at most F times the number of contacts.
    n = pr.contacts.counts[touching]
    assert (pr.contact_force[touching] <= BodyThresholds().grip_force_max_bw * n + 1e-9).all()
    assert pr.contact_force[touching].max() > 0.05


def test_a_vanishing_grip_is_the_single_person_residual(salsa_fit) -> None:
    th = replace(BodyThresholds(), grip_force_max_bw=1e-6)
    pr = pair_root_residual_wrench(salsa_fit, th)
    for i in (0, 1):
        np.testing.assert_allclose(pr.force[i], pr.single[i].force, atol=1e-4)
        single = root_residual(salsa_fit.people[i], th)
        assert float(pr.force[i].mean()) == pytest.approx(single.value, abs=1e-5)


def test_a_tighter_grip_bound_explains_less(salsa_fit) -> None:
    # The bound is a strength capacity (0.25 BW); dancers were measured exchanging 10-30 N
    # (0.05 BW of 60 kg is 30 N). A tighter bound can only leave more of the two residuals
    # unexplained: per frame, the objective both people share (squared residual wrench in
    # each one's body weights) grows as the bound shrinks, up to the floor-only value.
    contacts = hand_contacts(salsa_fit)
    levers = [p.humanoid.dims.hip_height for p in salsa_fit.people]

    def objective(force: np.ndarray, torque: np.ndarray) -> np.ndarray:
        return sum(force[i] ** 2 + (torque[i] / levers[i]) ** 2 for i in (0, 1))

    costs, follower = [], []
    for grip in (0.05, 0.25, 1.0):
        th = replace(BodyThresholds(), grip_force_max_bw=grip)
        pr = pair_root_residual_wrench(salsa_fit, th, contacts=contacts)
        costs.append(objective(pr.force, pr.torque))
        follower.append(float(pr.force[1].mean()))
    single = objective(np.stack([s.force for s in pr.single]),
                       np.stack([s.torque for s in pr.single]))
    assert (costs[0] <= single + 1e-6).all()
    assert (costs[1] <= costs[0] + 1e-6).all() and (costs[2] <= costs[1] + 1e-6).all()
    assert follower[0] > follower[1] > follower[2], follower


def test_partner_cannot_hide_a_floated_follower(salsa) -> None:
    # The follower lifted 15 cm: no floor contact, about one body weight missing on every
    # frame; the lead's hands (at most 0.25 body weight per contact) cannot carry it.
    lifted = replace(salsa, reactor=salsa.reactor.with_positions(
        salsa.reactor.positions + 0.15 * UP))
    fit = retarget(lifted)
    pair, (lead, follower) = pair_root_residual(fit)
    assert follower.passed is False and follower.value > 0.5
    assert follower.details["single_person_value"] > 0.8
    assert pair.passed is False and pair.value == pytest.approx(follower.value)
    # Where the hands still touch (measured: 13 % of the frames) each contact takes at
    # most the grip bound off the follower's residual, and the lead, who must supply
    # the reaction through the floor, needs more help than alone.
    pr = pair_root_residual_wrench(fit)
    touching = pr.contacts.counts > 0
    assert touching.mean() > 0.05
    drop = (pr.single[1].force - pr.force[1])[touching] / pr.contacts.counts[touching]
    assert drop.max() <= BodyThresholds().grip_force_max_bw + 0.02
    assert pr.force[0][touching].mean() > pr.single[0].force[touching].mean()


def test_handshake_pair_hands_stay_apart() -> None:
    # Measured: in CMU 18_01 / 19_01 the right hand boxes come no closer than 18 cm, so
    # the pair check finds no hand contact and changes nothing.
    fit = retarget(simenv.load(asset_path(HANDSHAKE_PAIR)))
    assert (hand_contacts(fit).counts == 0).all()
    pair, people = pair_root_residual(fit)
    for m in people:
        assert m.value == pytest.approx(m.details["single_person_value"])
    assert pair.passed and pair.details["contact_fraction"] == 0.0


def test_two_person_report_uses_the_partner_explained_residual(salsa, salsa_fit) -> None:
    report = simenv.score(salsa, config=ScoreConfig(tracking=False, joint_limits=False))
    recs = report.to_records()
    block = recs[0]["interaction"]["metrics"]["pair_root_residual"]
    assert block["unit"] == "body weight" and block["basis"] == "dynamics"
    assert block["threshold"] == BodyThresholds().root_force_mean_max
    for i, rec in enumerate(recs):
        rr = rec["metrics"]["root_residual"]
        single = root_residual(salsa_fit.people[i])
        assert rr["details"]["single_person_value"] == pytest.approx(single.value, rel=1e-6)
        assert rr["value"] <= single.value + 1e-9
        assert block["details"][f"mean_{i}"] == pytest.approx(rr["value"])
    assert block["value"] == pytest.approx(max(r["metrics"]["root_residual"]["value"]
                                               for r in recs))


def test_short_pair_is_not_available(salsa_fit) -> None:
    short = replace(salsa_fit, qpos=salsa_fit.qpos[:2])
    pair, people = pair_root_residual(short)
    for m in (pair, *people):
        assert m.passed is None and "3 frames" in m.reason

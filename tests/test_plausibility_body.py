"""Body-level metrics (simenv.plausibility.body) on real retargeted mocap."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from expect import raises_at

import simenv
from simenv.assets import HANDSHAKE_PAIR, asset_path
from simenv.body.geometry import body_poses, check_qpos
from simenv.body.retarget import retarget
from simenv.core.errors import MotionError, PhysicsError
from simenv.core.motion import Interaction
from simenv.plausibility.metrics.contact import contact, pair_distances
from simenv.plausibility.metrics.floating import body_floating
from simenv.plausibility.metrics.ground_penetration import body_penetration
from simenv.plausibility.metrics.inter_penetration import inter_penetration
from simenv.plausibility.metrics.joint_limits import joint_limit_excess, joint_limits
from simenv.plausibility.metrics.self_penetration import self_contact_pairs, self_penetration

UP = np.array([0.0, 0.0, 1.0], dtype=np.float32)
DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def handshake() -> Interaction:
    """The bundled real CMU pair 18_01 / 19_01, the 2 s around the handshake."""
    pair = simenv.load(asset_path(HANDSHAKE_PAIR))
    return pair.slice(40, 280)


def test_real_walk_passes_the_body_metrics(walk_2s_retargeted) -> None:
    for metric in (body_penetration, body_floating, self_penetration):
        r = metric(walk_2s_retargeted)
        assert r.available and r.passed, (r.name, r.value, r.threshold, r.violations[:3])
        assert r.timeline.shape == (walk_2s_retargeted.num_frames,)
    # The soles really touch the floor: not hovering, not sunk.
    pen = body_penetration(walk_2s_retargeted)
    assert pen.value < 20.0
    assert body_floating(walk_2s_retargeted).details["airborne_fraction"] == 0.0


def test_walk_lowered_10cm_sinks_into_the_floor(walk_2s) -> None:
    low = retarget(walk_2s.with_positions(walk_2s.positions - 0.10 * UP))
    r = body_penetration(low)
    assert r.passed is False
    assert 70.0 < r.value < 150.0  # ~10 cm minus the sole's own clearance
    assert r.details["frames_below_floor"] > 0.9
    assert r.violations and r.violations[0][0] == 0
    # Lowering alone does not make it float.
    assert body_floating(low).passed


def test_walk_raised_30cm_floats(walk_2s) -> None:
    high = retarget(walk_2s.with_positions(walk_2s.positions + 0.30 * UP))
    r = body_floating(high)
    assert r.passed is False
    assert r.details["floating_fraction"] == 1.0 and r.details["jumps"] == 0.0
    assert 250.0 < r.value < 400.0
    assert body_penetration(high).passed


def test_self_penetration_flags_an_arm_inside_the_torso(walk_2s_retargeted) -> None:
    h = walk_2s_retargeted.humanoid
    q = walk_2s_retargeted.qpos.copy()
    # Adduct the right upper arm by 1.5 rad on frames 100-139: it passes
    # through the trunk.
    q[100:140, h.hinge_qpos[list(h.joint_names).index("right_upper_arm_abd")]] = -1.5
    bad = replace(walk_2s_retargeted, qpos=q)
    r = self_penetration(bad)
    assert self_penetration(walk_2s_retargeted).passed
    assert r.passed is False and r.value > 50.0
    assert [(s, e) for s, e, _ in r.violations] == [(100, 139)]
    frame, a, b, depth = next(c for c in self_contact_pairs(bad) if c[0] == 120)
    assert "right_upper_arm" in (a, b) and depth > 50.0


def test_retargeted_motion_respects_joint_limits(walk_2s_retargeted) -> None:
    r = joint_limits(walk_2s_retargeted)
    assert r.passed and r.value <= 1.0
    h = walk_2s_retargeted.humanoid
    q = walk_2s_retargeted.qpos.copy()
    knee = list(h.joint_names).index("left_shin_flex")
    q[50:60, h.hinge_qpos[knee]] = h.joint_limits[knee, 1] + np.deg2rad(40.0)
    over = joint_limit_excess(h, q)
    assert over[55, knee] == pytest.approx(40.0, abs=1e-6)
    bad = joint_limits(replace(walk_2s_retargeted, qpos=q))
    assert bad.passed is False and bad.value == pytest.approx(40.0, abs=1e-6)
    assert bad.violations[0][:2] == (50, 59)


def test_handshake_hands_approach_on_the_bodies(handshake) -> None:
    result = retarget(handshake)
    r = contact(result)
    assert r.available and r.passed, (r.value, r.details)
    d = pair_distances(result)[:, 0]  # A right hand - B right hand
    # The people walk up to each other: the hands start far apart and are
    # closest in the middle of the window (CMU frames 100-150: the handshake).
    assert d[0] > 2 * d.min()
    closest = int(np.argmin(d)) + 40
    assert 100 <= closest <= 150
    # The bodies reproduce the recorded approach to within a few cm. Measured:
    # the recorded right-hand keypoints of this pair come no closer than
    # 29 cm (frame 123), so the 15 cm contact test does not fire here.
    assert r.details["min_mm_0"] < 350.0
    assert r.details["reference_contact_0"] == 0.0


def test_salsa_partners_hold_hands(shared_data) -> None:
    pair = simenv.load(shared_data / "cmu" / "two_person" / "60_61_salsa_05")
    result = retarget(pair.slice(0, 360))
    pairs = (("left_hand", "right_hand"),)
    r = contact(result, pairs=pairs)
    assert r.details["reference_contact_0"] > 0.2
    assert r.details["min_mm_0"] < 100.0
    # The bodies keep most of the recorded hand contact.
    assert r.details["retention_0"] > 0.6
    assert r.passed


def test_real_pair_does_not_interpenetrate(handshake) -> None:
    r = inter_penetration(retarget(handshake))
    assert r.available and r.passed, (r.value, r.violations[:3])


def test_two_people_on_top_of_each_other_interpenetrate(walk_2s) -> None:
    other = walk_2s.with_positions(walk_2s.positions + np.array([0.05, 0.0, 0.0], dtype=np.float32))
    r = inter_penetration(retarget(Interaction(walk_2s.slice(0, 60), other.slice(0, 60))))
    assert r.passed is False
    assert r.value > 100.0
    assert r.details["frames_over"] == 1.0


def test_contact_reference_of_another_length_is_an_error(handshake) -> None:
    result = retarget(handshake.slice(0, 30))
    with pytest.raises(MotionError, match="frames"):
        contact(result, reference=handshake.slice(0, 20))
    with pytest.raises(MotionError, match="not a canonical keypoint"):
        pair_distances(result, pairs=(("right_hand", "tail"),))


def test_bad_qpos_raises_physics_errors(walk_2s_retargeted) -> None:
    model = walk_2s_retargeted.humanoid.model
    q = walk_2s_retargeted.qpos.copy()
    q[17, 9] = np.nan
    raises_at(PhysicsError, "NaN", lambda: body_penetration(replace(walk_2s_retargeted, qpos=q)),
              frame=17)
    with pytest.raises(PhysicsError, match="frame 17"):
        self_penetration(replace(walk_2s_retargeted, qpos=q))
    with pytest.raises(PhysicsError, match=r"expected \(T >= 1"):
        body_poses(model, walk_2s_retargeted.qpos[:, :-1])
    with pytest.raises(PhysicsError, match="shape"):
        check_qpos(model, walk_2s_retargeted.qpos[0])
    with pytest.raises(PhysicsError, match="shape"):
        check_qpos(model, np.zeros((0, model.nq)))


def test_short_clips(walk_2s_retargeted) -> None:
    two = replace(walk_2s_retargeted, qpos=walk_2s_retargeted.qpos[:2])
    r = body_floating(two)
    assert r.passed is None and "3 frames" in r.reason
    one = replace(walk_2s_retargeted, qpos=walk_2s_retargeted.qpos[:1])
    assert body_penetration(one).timeline.shape == (1,)


def test_penetration_judges_only_the_geoms_the_source_places(walk_2s, walk_2s_retargeted
                                                            ) -> None:
    """HumanML3D's SMPL joints end at the wrists: the hands' angle is the fit's guess, so
    their geoms are not judged for penetration; a CMU skeleton's hand keypoints place them.
    The real HumanML3D clip 011673 sits low on the floor with the forearms pointing down:
    the guessed hands, not the observed body, reach below it."""
    from simenv.plausibility.metrics.ground_penetration import observed_geoms

    model = walk_2s_retargeted.humanoid.model
    body = np.flatnonzero(model.geom_bodyid > 0)
    assert np.array_equal(observed_geoms(walk_2s_retargeted, walk_2s), body)
    sitting = simenv.load(DATA / "humanml3d" / "new_joints" / "011673.npy").slice(0, 21)
    fitted = retarget(sitting)
    model = fitted.humanoid.model
    seen = observed_geoms(fitted, sitting)
    left_out = np.setdiff1d(np.flatnonzero(model.geom_bodyid > 0), seen)
    assert {model.body(int(model.geom_bodyid[g])).name for g in left_out} == {
        "left_hand", "right_hand"}
    assert body_penetration(fitted).value > body_penetration(fitted, geoms=seen).value

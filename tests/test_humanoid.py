"""Tests of simenv.body.humanoid: the MjSpec body, its dimensions, fitting, scenes."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from simenv.body.humanoid import (
    BONES,
    JOINTS,
    RANGE_SOURCES,
    ROM_REFERENCES,
    ROM_SPREAD_DEG,
    SHOD_TOE_ALLOWANCE,
    BodyDimensions,
    Humanoid,
    build_scene,
    fit_dimensions,
    fit_humanoid,
)
from simenv.core.errors import RetargetError
from simenv.core.motion import Motion
from simenv.core.skeletons import CANONICAL_KEYPOINTS, canonical_skeleton
from simenv.io import bvh


@pytest.fixture(scope="module")
def adult() -> Humanoid:
    return Humanoid()


def random_pose(h: Humanoid, rng: np.random.Generator, frames: int) -> np.ndarray:
    """(frames, nq) smooth random trajectories inside the joint limits, root 1.4 m up."""
    t = np.arange(frames)[:, None] / 120.0
    lo, hi = h.joint_limits.T
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    phase = rng.uniform(0, 2 * np.pi, len(lo))
    freq = rng.uniform(0.3, 1.5, len(lo))
    th = centre + 0.8 * half * np.sin(2 * np.pi * freq * t + phase)
    q = np.tile(h.default_qpos(), (frames, 1))
    q[:, 2] = 1.4
    yaw = 0.5 * np.sin(t[:, 0])
    q[:, 3:7] = np.stack([np.cos(yaw / 2), 0 * yaw, 0 * yaw, np.sin(yaw / 2)], axis=1)
    q[:, h.hinge_qpos] = th
    return q


def fk_motion(h: Humanoid, qpos: np.ndarray, name: str = "fk") -> Motion:
    """Canonical-keypoint Motion produced by the humanoid's own kinematics."""
    return Motion(h.keypoints(qpos).astype(np.float32), 120.0, canonical_skeleton(), name)


def test_default_adult_is_a_plausible_human(adult: Humanoid) -> None:
    assert 1.70 <= adult.dims.height <= 1.80
    assert 60.0 <= adult.total_mass <= 80.0
    kp = adult.keypoints(adult.default_qpos())
    assert kp.shape == (21, 3)
    names = [adult.model.site(int(s)).name for s in adult.site_ids]
    assert names == list(CANONICAL_KEYPOINTS)
    # The standing rest pose: head keypoint well above the pelvis, ankles near the floor.
    idx = {k: i for i, k in enumerate(CANONICAL_KEYPOINTS)}
    assert kp[idx["head"], 2] > 1.45
    assert 0.03 < kp[idx["left_ankle"], 2] < 0.12
    # MuJoCo's sites equal the dimensions' own rest keypoints (pelvis-relative).
    np.testing.assert_allclose(kp - kp[0], adult.dims.rest_keypoints(), atol=1e-9)


def test_joint_limits_and_actuators(adult: Humanoid) -> None:
    m = adult.model
    lim = dict(zip(adult.joint_names, np.degrees(adult.joint_limits), strict=True))
    for side in ("left", "right"):
        # Soucie et al. 2011 knee flexion 152.6 / hyperextension 5.4 and the elbow's
        # 149 / 2 of Macedo & Magee, each + ROM_SPREAD_DEG (RANGE_SOURCES).
        np.testing.assert_allclose(lim[f"{side}_shin_flex"], [-15, 163])
        np.testing.assert_allclose(lim[f"{side}_forearm_flex"], [-12, 159])
    central = ("lumbar", "thorax", "chest", "neck")
    expected = sum(len(v) * (1 if part in central else 2) for part, v in JOINTS.items())
    assert len(adult.joint_names) == expected == adult.nv - 6
    # One position actuator per hinge, with positive kp and kv.
    assert m.nu == len(adult.joint_names)
    for a in range(m.nu):
        assert m.actuator(a).name == adult.joint_names[a]
        kp, kv = m.actuator_gainprm[a, 0], -m.actuator_biasprm[a, 2]
        assert kp > 0 and kv > 0
        np.testing.assert_allclose(m.actuator_ctrlrange[a], adult.joint_limits[a])
    assert (m.dof_armature[6:] > 0).all() and (m.dof_damping[6:] > 0).all()


def test_range_table_is_sourced(adult: Humanoid) -> None:
    """Every hinge's two range ends name a motion and a reference; a published end
    is that value plus the population spread (rounded to the degree), and the
    rest pose (all zeros) lies inside every range."""
    hinges = {f"{part}_{js.name}": js.range_deg for part, specs in JOINTS.items()
              for js in specs}
    assert set(RANGE_SOURCES) == set(hinges)
    published = 0
    for name, (lo, hi) in hinges.items():
        assert lo < 0.0 < hi, name
        for end, value, sign in zip(RANGE_SOURCES[name], (lo, hi), (-1.0, 1.0), strict=True):
            assert end.motion and end.source.split(",")[0].split(" ")[0] in ROM_REFERENCES, end
            if end.published_deg is None:
                assert end.source == "model" or end.source in ROM_REFERENCES, (name, end)
                continue
            published += 1
            assert abs(value - sign * (end.published_deg + ROM_SPREAD_DEG)) <= 0.5, (name, end)
    # Most ends are published values; the model's own angles are the exceptions.
    assert published >= 30
    # Both sides of the built body carry the table's ranges.
    lim = dict(zip(adult.joint_names, np.degrees(adult.joint_limits), strict=True))
    for side in ("left", "right"):
        np.testing.assert_allclose(lim[f"{side}_thigh_flex"], hinges["thigh_flex"])
        np.testing.assert_allclose(lim[f"{side}_hand_dev"], hinges["hand_dev"])


def test_rest_pose_touches_only_the_floor(adult: Humanoid) -> None:
    m = adult.model
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    pairs = {(c.geom1, c.geom2) for c in d.contact[: d.ncon]}
    assert pairs, "the feet should touch the floor in the rest pose"
    assert all(floor in p for p in pairs), "no self-contact in the rest pose"


def test_standing_under_pd_control_is_stable(adult: Humanoid) -> None:
    m = adult.model
    d = mujoco.MjData(m)
    for _ in range(500):  # 1 s
        d.ctrl[:] = 0.0
        mujoco.mj_step(m, d)
    assert np.isfinite(d.qpos).all()
    assert d.qpos[2] > 0.5 * adult.dims.hip_height


def test_from_scale_scales_each_bone() -> None:
    base = BodyDimensions.default()
    d = BodyDimensions.from_scale({"left_knee": 1.2, "right_elbow": 0.8})
    assert d.left_thigh == pytest.approx(1.2 * base.left_thigh)
    assert d.right_upper_arm == pytest.approx(0.8 * base.right_upper_arm)
    assert d.right_thigh == pytest.approx(base.right_thigh)
    lengths = d.bone_lengths()
    assert lengths["left_knee"] == pytest.approx(1.2 * base.bone_lengths()["left_knee"])
    vec = np.full(len(BONES), 0.9)
    assert BodyDimensions.from_scale(vec).height == pytest.approx(0.9 * base.height, rel=0.06)


@pytest.mark.parametrize("scale", [{"left_knee": 1.3}, {"spine": 0.7}, {"head": float("nan")}])
def test_from_scale_rejects_out_of_range(scale: dict[str, float]) -> None:
    bone = next(iter(scale))
    with pytest.raises(RetargetError, match=bone):
        BodyDimensions.from_scale(scale)


def test_from_scale_rejects_bad_vectors() -> None:
    with pytest.raises(RetargetError, match="20"):
        BodyDimensions.from_scale([1.0] * 5)
    with pytest.raises(RetargetError, match="unknown bone"):
        BodyDimensions.from_scale({"tail": 1.0})


@pytest.mark.parametrize("change", [{"left_thigh": 3.0}, {"lumbar": float("nan")},
                                    {"right_forearm": 0.01}, {"left_hip_offset": (0, 5, 0)}])
def test_absurd_dimensions_are_rejected(change: dict[str, object]) -> None:
    with pytest.raises(RetargetError, match=next(iter(change))):
        BodyDimensions(**change)


def test_fit_recovers_the_bones_of_a_known_body() -> None:
    rng = np.random.default_rng(0)
    truth = BodyDimensions.from_scale(rng.uniform(0.8, 1.2, len(BONES)))
    h = Humanoid(truth)
    motion = fk_motion(h, random_pose(h, rng, 240))
    fitted = fit_dimensions(motion)
    for name in ("lumbar", "thorax", "neck", "left_thigh", "right_shin", "left_upper_arm",
                 "right_forearm", "left_hand", "right_foot", "left_clavicle"):
        assert getattr(fitted, name) == pytest.approx(getattr(truth, name), abs=1e-4), name
    # The pelvis triangle is recovered exactly (its orientation is the median
    # lumbar posture, so compare frame-invariant quantities).
    for side in ("left", "right"):
        off = f"{side}_hip_offset"
        assert np.linalg.norm(getattr(fitted, off)) == pytest.approx(
            np.linalg.norm(getattr(truth, off)), abs=1e-4)
    assert np.linalg.norm(np.subtract(fitted.left_hip_offset, fitted.right_hip_offset)) == \
        pytest.approx(np.linalg.norm(np.subtract(truth.left_hip_offset, truth.right_hip_offset)),
                      abs=1e-4)
    want = truth.bone_lengths()
    got = fitted.bone_lengths()
    for bone in BONES:
        if bone.endswith("toe"):  # the foot's pitch depends on the sole heights
            continue
        assert got[bone] == pytest.approx(want[bone], abs=1e-3), bone


def standing_motion(h: Humanoid, frames: int = 120) -> Motion:
    """The humanoid standing still in its rest pose (soles flat on z = 0), its arms
    swinging so the frames differ."""
    q = np.tile(h.default_qpos(), (frames, 1))
    names = [mujoco.mj_id2name(h.model, mujoco.mjtObj.mjOBJ_JOINT, j)
             for j in range(h.model.njnt)]
    for j, n in enumerate(names):
        if n and "upper_arm" in n:
            q[:, h.model.jnt_qposadr[j]] = 0.3 * np.sin(np.linspace(0, 2 * np.pi, frames))
    return fk_motion(h, q, "stand")


def test_fit_recovers_the_sole_of_a_flat_standing_body(adult: Humanoid) -> None:
    # Both feet flat on the floor on every frame: the planted ankle-over-toe drop and
    # both lowest-height anchors agree, so the fit returns the body's own foot heights.
    d = fit_dimensions(standing_motion(adult))
    assert d.toe_height == pytest.approx(adult.dims.toe_height, abs=1e-4)
    assert d.ankle_height == pytest.approx(adult.dims.ankle_height, abs=1e-4)


def test_fit_splits_disagreeing_foot_keypoints_by_least_squares(adult: Humanoid) -> None:
    # The ball keypoints raised by delta on 60 % of the (planted) frames, as CMU 131_04's
    # are in its quiet stances: the planted drop becomes drop - delta (the median), the
    # lowest toes still say toe_height and the lowest ankles ankle_height, so the one
    # sole offset that fits both anchors best is toe_height + delta / 2 (and the ankle
    # sits delta / 2 lower). The old rule (toe from the ball alone) kept toe_height.
    motion = standing_motion(adult, 100)
    delta = 0.02
    P = motion.positions.copy()
    for side in ("left", "right"):
        P[40:, CANONICAL_KEYPOINTS.index(f"{side}_toe"), 2] += delta
    d = fit_dimensions(Motion(P, motion.fps, motion.skeleton, "raised balls"))
    assert d.toe_height == pytest.approx(adult.dims.toe_height + delta / 2, abs=1e-4)
    assert d.ankle_height == pytest.approx(adult.dims.ankle_height - delta / 2, abs=1e-4)


def test_fit_sole_follows_the_floor_up_to_a_shod_foot(adult: Humanoid) -> None:
    # Raising every keypoint by h raises the fitted sole offset by h (the readers put
    # the floor at z = 0, so higher feet mean a thicker sole under them) up to the shod
    # allowance; beyond it the data's floor is taken to be off and the offset is capped.
    motion = standing_motion(adult)
    for lift in (0.03, 0.10):
        P = motion.positions + np.float32(lift) * np.array([0, 0, 1], dtype=np.float32)
        d = fit_dimensions(Motion(P, motion.fps, motion.skeleton, "lifted"))
        want = min(adult.dims.toe_height + lift, adult.dims.toe_height + SHOD_TOE_ALLOWANCE)
        assert d.toe_height == pytest.approx(want, abs=1e-4), lift
        assert d.ankle_height - d.toe_height == pytest.approx(
            adult.dims.ankle_height - adult.dims.toe_height, abs=1e-4), lift


def test_fit_on_real_cmu_clip(shared_data) -> None:
    motion = bvh.read(shared_data / "cmu/bvh/02_01.bvh")
    h = fit_humanoid(motion)
    canon = motion.to_canonical()
    P = canon.positions
    names = canon.skeleton.joint_names
    knee, ankle = P[:, names.index("left_knee")], P[:, names.index("left_ankle")]
    assert h.dims.left_shin == pytest.approx(np.median(np.linalg.norm(knee - ankle, axis=1)))
    assert 1.4 < h.dims.height < 2.0
    assert 40.0 < h.total_mass < 100.0
    assert "fitted" in h.dims.notes[0]


def test_fit_with_missing_keypoints_falls_back_and_says_so(shared_data) -> None:
    canon = bvh.read(shared_data / "cmu/bvh/02_01.bvh").to_canonical()
    keep = [k for k in canon.skeleton.joint_names if not k.endswith(("hand", "wrist"))]
    sub = canon.skeleton.subset(keep, name="no_hands")
    idx = [canon.skeleton.index(k) for k in sub.joint_names]
    motion = Motion(canon.positions[:, idx], canon.fps, sub, "no_hands")
    d = fit_dimensions(motion)
    assert any("left_forearm" in n and "default adult" in n for n in d.notes)
    assert 0.15 < d.left_forearm < 0.35


def test_fit_without_a_chest_keypoint_keeps_the_trunk_length(shared_data) -> None:
    from simenv.body.retarget import retarget
    from simenv.data import interaction_data as idata
    from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS
    from simenv.plausibility.metrics.joint_limits import joint_limits

    walk = idata.to_layout(bvh.read(shared_data / "cmu/bvh/02_01.bvh")).slice(0, 240)
    assert "chest" not in walk.skeleton.joint_names
    d = fit_dimensions(walk)
    assert any("no chest keypoint" in n for n in d.notes)
    canon = walk.to_canonical()
    names = canon.skeleton.joint_names
    spine_neck = np.median(np.linalg.norm(canon.positions[:, names.index("neck")]
                                          - canon.positions[:, names.index("spine")], axis=1))
    assert d.thorax + d.upper_chest == pytest.approx(spine_neck, rel=1e-6)
    # The body then reaches the keypoints with a relaxed trunk: before, thorax and upper
    # chest were scaled from other bones and the chest joints went to their limits (60
    # deg past them in the relaxed fit) with a 20 mm mean residual.
    fit = retarget(walk, fit_humanoid(walk))
    assert float(fit.residuals.mean()) < 0.003
    assert joint_limits(walk).value <= DEFAULT_BODY_THRESHOLDS.joint_limit_max_deg


def test_fit_takes_a_spine_rigid_on_the_pelvis_as_the_lumbar_joint(shared_data) -> None:
    """SMPL's spine1 is fixed in the pelvis's frame (real HumanML3D clips: it moves
    0.001 mm there) and the lumbar turns at it. Before, the body kept its lumbar
    joint at the pelvis keypoint: the rigid spine keypoint locked it, and the
    thorax took the whole bend on top of SMPL's rest kink at spine1, on its 45-deg
    bound in 124 of the 199 frames of the real walk 000612. Now the lumbar and
    thorax joints sit at spine1 and share the bend; a CMU clip, whose spine
    keypoint ends a lumbar turning at the pelvis, keeps the body it had."""
    from simenv.body.retarget import retarget
    from simenv.io.loader import load

    data = Path(__file__).parent / "data" / "humanml3d"
    walk = load(data / "new_joint_vecs" / "000612.npy")
    d = fit_dimensions(walk)
    assert d.spine_on_pelvis and d.lumbar == 0.0
    assert any("rigid on the pelvis" in n for n in d.notes)
    p, names = walk.positions.astype(np.float64), walk.skeleton.joint_names

    def dist(a: str, b: str) -> float:
        return float(np.median(np.linalg.norm(p[:, names.index(b)] - p[:, names.index(a)],
                                              axis=1)))

    assert np.linalg.norm(d.lumbar_offset) == pytest.approx(dist("pelvis", "spine1"), rel=1e-4)
    assert d.thorax == pytest.approx(dist("spine1", "spine3"), rel=1e-6)
    h = Humanoid(d)
    spine = h.site_ids[CANONICAL_KEYPOINTS.index("spine")]
    assert h.model.body(int(h.model.site_bodyid[spine])).name == "pelvis"
    rest = d.rest_keypoints()
    np.testing.assert_allclose(rest[CANONICAL_KEYPOINTS.index("chest")]
                               - rest[CANONICAL_KEYPOINTS.index("spine")], [0, 0, d.thorax])

    fit = retarget(walk, h)
    assert float(np.percentile(fit.residuals, 95)) < 0.004
    q = np.rad2deg(fit.qpos[:, h.hinge_qpos])
    for hinge in ("lumbar_flex", "thorax_flex", "thorax_lat"):
        i = h.joint_names.index(hinge)
        lo, hi = np.rad2deg(h.joint_limits[i])
        assert np.all((q[:, i] > lo + 5.0) & (q[:, i] < hi - 5.0)), hinge

    cmu = fit_dimensions(bvh.read(shared_data / "cmu/bvh/02_01.bvh"))
    assert not cmu.spine_on_pelvis and cmu.lumbar_offset == (0.0, 0.0, 0.0)


def test_fit_requires_pelvis_and_hips(shared_data) -> None:
    canon = bvh.read(shared_data / "cmu/bvh/02_01.bvh").to_canonical()
    keep = [k for k in canon.skeleton.joint_names if k != "left_hip"]
    sub = canon.skeleton.subset(keep)
    motion = Motion(canon.positions[:, [canon.skeleton.index(k) for k in keep]], 120.0, sub)
    with pytest.raises(RetargetError, match="left_hip"):
        fit_dimensions(motion)


def test_keypoints_refuse_nan(adult: Humanoid) -> None:
    q = adult.default_qpos()
    q[10] = np.nan
    with pytest.raises(RetargetError, match="NaN"):
        adult.keypoints(q)


def test_scene_holds_several_people() -> None:
    a = Humanoid()
    b = Humanoid(BodyDimensions.from_scale(np.full(len(BONES), 0.85)))
    scene = build_scene([a, b], ["p0", "p1"])
    m = scene.model
    assert m.nq == a.nq + b.nq and m.nu == a.model.nu + b.model.nu
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "p1/left_hand") >= 0
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor") >= 0
    rng = np.random.default_rng(1)
    qa, qb = random_pose(a, rng, 3), random_pose(b, rng, 3)
    qb[:, 0] += 2.0
    q = scene.combine_qpos([qa, qb])
    d = mujoco.MjData(m)
    d.qpos[:] = q[2]
    mujoco.mj_kinematics(m, d)
    np.testing.assert_allclose(d.site_xpos[scene.site_ids[0]], a.keypoints(qa[2]), atol=1e-9)
    np.testing.assert_allclose(d.site_xpos[scene.site_ids[1]], b.keypoints(qb[2]), atol=1e-9)
    assert q[:, scene.qpos_slices[1]].shape == (3, b.nq)
    with pytest.raises(RetargetError, match="unique"):
        build_scene([a, b], ["x", "x"])


HUMANML3D = Path(__file__).parent / "data" / "humanml3d"


def test_fit_reads_a_knee_off_the_straight_leg_as_the_skeleton(shared_data) -> None:
    """SMPL's knee joint centre sits beside the hip-ankle line even on a straight leg
    (real HumanML3D M010968, BMLmovi: legs straight throughout, the knee 29 mm outwards).
    The fit measures that offset from the clip and puts the knee keypoint there on the
    thigh, along the knee's hinge axis, keeping the bone lengths; a CMU skeleton, whose
    straight leg is straight, keeps a knee on the line."""
    from simenv.io.loader import load

    d = fit_dimensions(load(HUMANML3D / "new_joints" / "M010968.npy"))
    for side, sign in (("left", 1.0), ("right", -1.0)):
        a = getattr(d.rest, f"{side}_knee_lateral")
        assert 0.02 < a < 0.045, side
        rest = d.rest_keypoints()
        hip, knee, ankle = (rest[CANONICAL_KEYPOINTS.index(f"{side}_{k}")]
                            for k in ("hip", "knee", "ankle"))
        assert np.linalg.norm(knee - hip) == pytest.approx(getattr(d, f"{side}_thigh"))
        assert np.linalg.norm(ankle - knee) == pytest.approx(getattr(d, f"{side}_shin"))
        # Straight leg: the ankle under the hip, the knee out beside the line.
        np.testing.assert_allclose((ankle - hip)[:2], 0.0, atol=1e-12)
        assert (knee - hip)[1] == pytest.approx(sign * a)
    assert any("knee keypoints off" in n for n in d.notes)
    cmu = fit_dimensions(bvh.read(shared_data / "cmu/bvh/02_01.bvh"))
    assert cmu.rest.left_knee_lateral == cmu.rest.right_knee_lateral == 0.0
    assert cmu.leg_line("left") == (cmu.left_thigh, cmu.left_shin)


def test_fit_reads_the_head_direction_from_the_clip() -> None:
    """SMPL's head joint sits forward of its neck joint (real HumanML3D M010655: 50 deg
    forward of the chest -> neck line on its upright first frame). The fit takes the
    clip's median head direction as the neck's zero, so the upright frame's neck is
    near neutral instead of 50 of its 55 deg of flexion."""
    from simenv.io.loader import load

    d = fit_dimensions(load(HUMANML3D / "new_joints" / "M010655.npy"))
    tilt = np.degrees(np.arctan2(d.rest.head_direction[0], d.rest.head_direction[2]))
    assert 35.0 < tilt < 65.0
    h = Humanoid(d)
    head = h.keypoints(h.default_qpos())[CANONICAL_KEYPOINTS.index("head")]
    neck = h.keypoints(h.default_qpos())[CANONICAL_KEYPOINTS.index("neck")]
    assert np.linalg.norm(head - neck) == pytest.approx(d.neck)
    assert d.height == pytest.approx(d.hip_height + d.lumbar_offset[2] + d.lumbar + d.thorax
                                     + d.upper_chest + (head - neck)[2] + 1.75 * d.head_radius)


@pytest.mark.parametrize("change", [{"left_knee_lateral": 0.2},
                                    {"right_knee_lateral": float("nan")},
                                    {"head_direction": (0.0, 0.0, -1.0)}])
def test_absurd_rest_geometry_is_rejected(change: dict[str, object]) -> None:
    from simenv.body.humanoid import RestGeometry

    with pytest.raises(RetargetError, match=next(iter(change))):
        RestGeometry(**change)


def test_a_knee_offset_longer_than_half_the_leg_is_rejected() -> None:
    from simenv.body.humanoid import RestGeometry

    with pytest.raises(RetargetError, match="left_knee_lateral"):
        BodyDimensions(left_thigh=0.15, rest=RestGeometry(left_knee_lateral=0.09))


def test_fit_reads_a_rig_spine_hung_from_the_pelvis_joint_upright() -> None:
    """FAIR's capture rig (real BVH, tests/data/conventions/other) hangs its first spine
    joint from ``Hips`` 5.3 cm away, 34 deg off the trunk's line, with the pelvis keypoint
    on the hip line. Taken as the trunk's direction, that offset made the performer's
    upright trunk read ~28 deg of thorax flexion; as a joint rigid on the pelvis, with the
    trunk's zero from the rig's rest pose, the upright dab reads within a few degrees and
    the lumbar joint sits at the spine keypoint. A CMU rig, whose spine ends a lumbar bone,
    is not such a rig."""
    from simenv.body.humanoid import rest_trunk
    from simenv.body.retarget import retarget
    from simenv.io.loader import load

    dab = load(Path(__file__).parent / "data/conventions/other/fair1_dab_zup.bvh").slice(0, 60)
    assert rest_trunk(dab) is not None
    d = fit_dimensions(dab)
    assert d.spine_on_pelvis and d.lumbar == 0.0
    assert any("rest pose" in n for n in d.notes)
    h = Humanoid(d)
    fit = retarget(dab, h)
    assert float(np.percentile(fit.residuals, 95)) < 0.005
    q = np.rad2deg(fit.qpos[:, h.hinge_qpos])
    trunk = sum(np.median(q[:, h.joint_names.index(j)]) for j in ("lumbar_flex", "thorax_flex"))
    assert abs(trunk) < 10.0, trunk

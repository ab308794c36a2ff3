"""Named, documented, configurable thresholds of the joint-level metrics.

Every default states where it comes from: a published metric (so scores are
comparable with papers), a physical or physiological bound, or the
calibration on real CMU motion capture (``benchmarks/calibrate_kinematic.py``
runs every metric on every real single-person clip and prints the values).
Override any of them with :func:`dataclasses.replace`::

    from dataclasses import replace
    strict = replace(Thresholds(), skate_ratio_max=0.05)

Leave-clips-out check (``benchmarks/calibrate_loo.py``, ``docs/calibration.md``):
each real CMU person judged with thresholds set from the other subjects' clips
by ``max(prior, largest training value within Q3 + 3 IQR)``; for the CMU motion
capture every joint-level rule value equals the default below (no real clip
without a capture defect exceeds one), and the defaults catch 118 of the 119
corrupted copies (foot slide, bone stretch, sink, float, jitter, teleport, time
warp) of the 17 clean single-person CMU clips; the miss is the time warp of the
lambada 55_02 (a 10x segment of a slow dance peaks at 0.65 of the speed limits).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

from simenv.core.errors import SimenvError


@dataclass(frozen=True)
class PositiveThresholds:
    """Base of a set of named thresholds (:class:`Thresholds`,
    :class:`~simenv.plausibility.body_thresholds.BodyThresholds`): every field is a
    positive number (NaN refused, infinity allowed), stored as a float.

    Raises:
        SimenvError: on construction, a field that is not a positive number (``field``
            names it).
    """

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, (int, float)) or not value > 0 or value != value:
                raise SimenvError(
                    f"threshold {f.name} must be a positive number; got {value!r}",
                    field=f.name,
                )
            object.__setattr__(self, f.name, float(value))


@dataclass(frozen=True)
class Thresholds(PositiveThresholds):
    """Thresholds of the joint-level plausibility metrics (SI units).

    Bone length (on the source skeleton's own parent-child bones)
        bone_length_rel_max: 0.05. Tolerance on a source bone's relative
            deviation ``|L_b(t) / median_t L_b - 1|``; the metric fails when
            the 95th percentile over frames of the worst ``deviation /
            tolerance`` exceeds 1. Sources that keep bones rigid score below
            1e-4 tolerances on every bone (float32 rounding): CMU BVH and
            ASF/AMC, the Poser-template salsa pairs, HumanML3D / AMASS SMPL
            joints; a bone stretched by 10 % over a quarter of the clip fails
            at 2 tolerances. Depth-camera skeletons fluctuate far more (MSR
            Action3D: median 2.3 tolerances, 10 % of clips pass) and fail:
            their bones really do not keep their length (see
            :data:`SOURCE_THRESHOLDS`).
        bone_length_head_rel_max: 0.15. Tolerance of the bones at the joint
            mapped to canonical ``head``: a head-centre estimate on depth
            cameras (their profiles below keep it at 3x the limb tolerance).
            Rigid sources keep their head bone to 1e-5; the canonical
            neck-to-head pair that once needed this tolerance on motion
            capture spans CMU's upper-neck joint (02_04 nods it by 6.5 %),
            which the source-bone metric measures as two rigid bones.
        bone_min_length_m: 0.01. Bones whose median length over the clip is
            shorter than this are skipped: a converter's collapsed bones
            (CMU BVH ``Hips->LHipJoint``, the thorax and the wrist), whose
            relative deviation is meaningless.
        bone_reference_error_max_mm: 20. Limit on the mean absolute bone
            length error against a reference skeleton (E_b of the
            interaction-augmentation seed, on canonical keypoint pairs);
            2 cm is about one anthropometric standard deviation of a limb
            bone.

    Foot contact and skating
        contact_height_m: 0.05. A toe keypoint is low enough for contact when
            it is less than 5 cm above the clip's foot floor (HumanML3D /
            GMD / InterGen use 5 cm for the foot joint).
        contact_height_ankle_m: 0.05. Same test for an ankle keypoint, used
            when a side has no toe keypoint; measured from the ankles' own
            lowest level. InterGen tests ankles at 12 cm above a toe-level
            floor, which lies ~7 cm below the planted ankle centre, i.e. ~5 cm
            above it. Coarser than the toe test: with the toes removed, real
            CMU clips score 0-15 % skating (median 2 %, the dance 05_02 the
            highest), a 1 m/s drift at least 24 %.
        contact_speed_mps: 0.949. A low foot is *planted* when its 3-D speed
            is below this: InterGen's test ``|dp|^2 < 0.001 m^2`` per frame at
            30 fps, i.e. ``sqrt(0.001) * 30`` m/s, written as a speed so it
            holds at any frame rate.
        skate_speed_mps: 0.5. GMD / OmniControl foot-skating test: a low foot
            whose horizontal speed, both instantaneous and averaged over
            ``skate_window_s``, exceeds 0.5 m/s is skating.
        skate_window_s: 0.25. GMD's 5-frame average at 20 fps, as a duration
            (used for the published ratio reported in the details).
        skate_min_duration_s: 0.15. A slide counts as skating only when it
            lasts this long: on joint-centre mocap every early swing keeps the
            toe within 5 cm of the floor for 20-100 ms (CMU walks and runs:
            at most 0.15 s), whereas a sliding planted foot slides for much of
            its stance (0.3-0.6 s).
        skate_support_margin_m: 0.01. A low sliding foot is *unloaded* (a
            shuffle or a low swing, not a skate) while the other foot is
            planted (horizontal speed at most ``skate_speed_mps``) and lower
            than it by more than this at both frames: the weight is then on
            the other foot. Measured on the real clips: the CMU handshake
            pair 18_01 / 19_01, whose adjustment steps keep the toe 1-5 cm
            above the floor at 1-3 m/s, scored 47 % / 14 % skating without
            this test and 0 % with it; the salsa followers 61_05 / 61_10
            18 % / 9 % and 2.4 % / 0 %. A sliding stance foot (the lower one)
            and a whole body drifting on both feet are still skating.
        skate_stance_speed_mps: 0.1. A low sliding foot is also unloaded
            while the other foot stands still on the floor (low, horizontal
            speed below this, a fifth of ``skate_speed_mps``; the planted toe's
            median speed on the CMU corpus is 0.08 m/s), whatever their
            heights: SMPL's toe joints sit 1-3 cm apart in height when both
            are planted, so a low swing (the real HumanML3D walk 000612, toe
            1-2 cm above its stance height at 1.5-2.5 m/s) is not lower-foot
            supported. The foot_slide corruption moves every planted foot,
            so none stands still: caught on 45 / 99 seeded copies at 0.5 m/s
            and 96 / 99 at 1 m/s with and without this test; 000612 scored
            15.2 % skating without it, 0 % with it.
        skate_ratio_max: 0.08. Largest allowed fraction of frames with a
            skating foot. Calibrated: real CMU walks, runs and jumps score
            0-3.5 %, the modern-dance pirouette (05_02) 6.4 % and the
            Michael-Jackson-style clip (131_03) 5.1 %: pivots and deliberate
            slides on the ball of the foot are real sliding.
        skate_reference_fps: 20. PhysDiff's "skate" (mm per frame) is
            reported per frame of a 20 fps clip (HumanML3D's rate), i.e.
            ``speed_mps * 1000 / 20``, so it is comparable across frame rates.

    Ground penetration and floating (keypoint level)
        penetration_max_mm: 30. Largest allowed depth of the lowest keypoint
            below the floor (z = 0). Keypoints are joint centres 2-8 cm above
            the skin, so a keypoint 3 cm under the floor means the body is
            5 cm or more into it. Calibrated: real CMU clips reach at most
            ~1 cm (excluding the converter's T-pose frame).
        float_height_m: 0.10. A frame is airborne when its lowest keypoint is
            more than 10 cm above the floor. Planted CMU toe keypoints sit
            1-9 cm high depending on the subject's marker set.
        float_hand_reach_m: 0.15. Wrist and hand keypoints may be supported
            by the palm and fingers below them: their height counts this much
            lower in the airborne test (adult hand length is 17-20 cm; in the
            CMU cartwheel 49_06 the hand keypoints stay 18-21 cm above the
            floor while the hands carry the body).
        float_ankle_sole_m: 0.07. On a skeleton without toe keypoints (OpenNI /
            NiTE, H36M-style layouts) the ankles are its lowest points, and an
            ankle joint centre stands about 7 cm over the sole of a flat foot
            (lateral malleolus height, adult anthropometry; the floor estimate of
            :mod:`simenv.io.camera_frame` puts it there): their height counts
            this much lower in the airborne test, so a standing foot has the
            same 10-cm margin as a toe. Skeletons with toes are unchanged.
        ballistic_tolerance_m: 0.03. An airborne phase is a jump, not
            floating, when the centre-of-mass proxy's height is fitted by a
            free-fall parabola ``z0 + v0 t - g t^2 / 2`` with an RMS residual
            below this. Calibrated: real CMU jumps, hops, runs and leaps fit
            within 1-6 mm, the tuck jumps of 49_02 within 22 mm (the trunk
            mean is not the true centre of mass when the legs tuck). A body
            hovering for 0.3 s leaves ~3 cm, for 0.5 s ~9 cm.
        gravity_mps2: 9.81. Standard gravity.

    Jitter (smoothness)
        jerk_fps: 30. Jerk is evaluated at (at most) this rate: the clip is
            linearly resampled down first, because finite-difference jerk
            amplifies capture noise by ``fps^3`` and ProtoMotions' 6500
            threshold was set at its 30 Hz control rate.
        jerk_window_s: 0.4. ProtoMotions' normalized-jerk window.
        normalized_jerk_max: 6500. ProtoMotions' high-jerk threshold on the
            dimensionless normalized jerk ``T^5 * int |j|^2 dt / L^2`` of one
            body (keypoint) in one window.
        high_jerk_percent_max: 10. Largest allowed percentage of windows in
            which the median keypoint exceeds ``normalized_jerk_max``.
            Calibrated: real CMU clips score 0-1 %; 5 mm of added noise scores
            67-100 % on walks and dances (runs, with long paths per window,
            need ~1 cm).

    Velocity and teleports
        speed_limit_trunk_mps: 12.5. Pelvis, hips, spine, chest, neck, head,
            shoulders. Fastest measured human running speed, 12.3 m/s
            (Bolt, 2009 Berlin 100 m; Graubner & Nixdorf 2011).
        speed_limit_limb_mps: 20. Knees and elbows (about 2/3 of the
            distal limit: they sit at mid-limb).
        speed_limit_distal_mps: 30. Wrists, hands, ankles, toes. Olympic
            boxers' fists reach 9.1 +- 2.1 m/s (Walilko et al. 2005), maximal
            soccer instep kicks 18-24 m/s of foot speed (Lees & Nolan 1998).
            Elite baseball pitches leave the hand at 35-40 m/s (Fleisig et
            al. 1995): raise this limit for such material.
        teleport_distance_m: 0.15. A keypoint *teleports* in a frame when it
            leaves its constant-velocity path by more than
            ``max(teleport_distance_m, teleport_accel_mps2 / fps^2)``
            (second difference). Real CMU capture has single-frame wobbles of
            up to 9 cm at toes and knees.
        teleport_accel_mps2: 300. Acceleration a real limb can reach
            (~30 g: punches and kicks peak at a few hundred m/s^2), so that at
            low frame rates fast real motion is not taken for a teleport.
    """

    bone_length_rel_max: float = 0.05
    bone_length_head_rel_max: float = 0.15
    bone_min_length_m: float = 0.01
    bone_reference_error_max_mm: float = 20.0

    contact_height_m: float = 0.05
    contact_height_ankle_m: float = 0.05
    contact_speed_mps: float = 0.949
    skate_speed_mps: float = 0.5
    skate_window_s: float = 0.25
    skate_min_duration_s: float = 0.15
    skate_support_margin_m: float = 0.01
    skate_stance_speed_mps: float = 0.1
    skate_ratio_max: float = 0.08
    skate_reference_fps: float = 20.0

    penetration_max_mm: float = 30.0
    float_height_m: float = 0.10
    float_hand_reach_m: float = 0.15
    float_ankle_sole_m: float = 0.07
    ballistic_tolerance_m: float = 0.03
    gravity_mps2: float = 9.81

    jerk_fps: float = 30.0
    jerk_window_s: float = 0.4
    normalized_jerk_max: float = 6500.0
    high_jerk_percent_max: float = 10.0

    speed_limit_trunk_mps: float = 12.5
    speed_limit_limb_mps: float = 20.0
    speed_limit_distal_mps: float = 30.0
    teleport_distance_m: float = 0.15
    teleport_accel_mps2: float = 300.0


#: The defaults, shared by every metric when no thresholds are passed.
DEFAULT_THRESHOLDS = Thresholds()


#: Joint-level thresholds of each depth-camera corpus of the shared data, its own
#: source calibration: the leave-clips-out rule of ``benchmarks/calibrate_loo.py``
#: (``max(default, largest real value within Q3 + 3 IQR)``) on every real clip of
#: the corpus, written as the fields that put each metric's pass level there
#: (ratio metrics scale their fields). Kinect v1 skeletons (joint estimates from one
#: depth image) keep neither bone lengths, foot heights nor speeds the way marker
#: capture does; judged with the defaults 0-2 % of their real clips are plausible,
#: leave-subjects-out with their own calibration 76 % (MSR Action3D, 506 people),
#: 55 % (UTKinect, 20 sessions) and 81 % (Florence 3D, 215), see docs/calibration.md.
#: The bone tolerances were fitted when ``bone_length`` measured canonical keypoint
#: pairs; on the source bones (which differ on these skeletons only at the shoulders,
#: and for OpenNI at the hips) the share of real clips within them is unchanged:
#: 99.4 % (MSR Action3D), 100 % (UTKinect), 100 % (Florence 3D)
#: (``benchmarks/bone_length_sources.py``, docs/plausibility.md).
#: These per-corpus profiles serve the leave-clips-out calibration; by default the scorer
#: judges a depth-camera clip by its *sensor family's* profile instead
#: (:mod:`simenv.plausibility.profiles`, calibrated on whole corpora and checked on others).
#: Use with the body-level profile of the same name
#: (:data:`simenv.plausibility.body_thresholds.SOURCE_BODY_THRESHOLDS`)::
#:
#:     ScoreConfig(thresholds=SOURCE_THRESHOLDS["msr_action3d"],
#:                 body=SOURCE_BODY_THRESHOLDS["msr_action3d"])
SOURCE_THRESHOLDS: dict[str, Thresholds] = {
    "msr_action3d": replace(DEFAULT_THRESHOLDS, bone_length_rel_max=0.5191,
                            bone_length_head_rel_max=1.5574, skate_ratio_max=0.2308),
    "utkinect": replace(DEFAULT_THRESHOLDS, bone_length_rel_max=1.5062,
                        bone_length_head_rel_max=4.5186, skate_ratio_max=0.082,
                        speed_limit_trunk_mps=17.7591, speed_limit_limb_mps=28.4145,
                        speed_limit_distal_mps=42.6218, teleport_distance_m=0.2131,
                        teleport_accel_mps2=426.218),
    # No body is fitted to Florence's 15 joints: ground and floating run on keypoints.
    "florence3d": replace(DEFAULT_THRESHOLDS, bone_length_rel_max=0.9782,
                          bone_length_head_rel_max=2.9346, penetration_max_mm=69.696,
                          float_height_m=0.2709, speed_limit_trunk_mps=18.1308,
                          speed_limit_limb_mps=29.0093, speed_limit_distal_mps=43.5139,
                          teleport_distance_m=0.2176, teleport_accel_mps2=435.139),
}

"""Named, documented, configurable thresholds of the body-level metrics.

The body-level metrics (:mod:`simenv.plausibility.body`,
:mod:`simenv.plausibility.dynamics`, :mod:`simenv.plausibility.tracking`)
judge the retargeted MuJoCo humanoid rather than the keypoints. Each default
states its source: a published metric, a physical bound, or the calibration
on real CMU motion capture (``benchmarks/calibrate_body.py`` runs every
metric on every real single-person clip; its table is quoted below).
Override any of them with :func:`dataclasses.replace`::

    from dataclasses import replace
    strict = replace(BodyThresholds(), root_force_mean_max=0.05)

Every threshold below was checked leave-clips-out on the real clips of the
corpus (``benchmarks/calibrate_loo.py``, ``docs/calibration.md``): each CMU
person judged with thresholds set from the other subjects' clips, by the rule
``max(prior, largest training value within Q3 + 3 IQR)``. For the CMU
motion capture every rule value equals the default below: the 21 people
without a diagnosed capture defect are all plausible, the 6 with one (16_15,
49_02, 49_04, 49_06 and the salsa 60_10 lead and 61_10 follower, frames in
``docs/calibration.md``) are all caught.

Joint limits on the real CMU clips with the sourced ranges of
:data:`simenv.body.humanoid.JOINTS` (``benchmarks/calibrate_loo.py`` records;
degrees the motion demands beyond the range, held 25 ms / peak frame)::

    clip                      held   peak   worst hinge
    bvh/49_02                 36.3   36.8   lumbar_flex     (capture's pelvis)
    bvh/49_06 (cartwheel)     31.9   32.3   chest_flex      (collapsed thorax)
    salsa 60_10 lead          59.2   60.0   left_thigh_flex (glitch frames)
    asf_amc/135_06             6.3   12.3   right_foot_abd
    salsa 61_10 follower       5.0    5.1   right_forearm_flex
    salsa 61_05 follower       0.0   18.5   right_foot_inv  (frame 623 alone)
    the 21 others              0.0    0.0

With the former ranges (AAOS + margins) 131_01 demanded 16.6 (the left foot
turned 52-58 deg in from the bent knee's plane in a pivot, now within the
knee's passive rotation) and 103_charleston1 3.1 (elbow flexion 155).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from simenv.plausibility.thresholds import PositiveThresholds


@dataclass(frozen=True)
class BodyThresholds(PositiveThresholds):
    """Thresholds of the body-level plausibility metrics (SI units).

    Geoms against the floor (plane z = 0)
        geom_penetration_max_mm: 30. Largest allowed depth of the lowest
            point of any body geom below the floor. Soft tissue and shoe
            soles compress by 1-2 cm under body weight, and the retargeting
            lets the soles follow the data's own floor where the data sinks.
            Calibrated: real CMU clips reach 0-27 mm (the deepest are
            clips whose recorded toes dip below the floor).
        geom_float_clearance_m: 0.05. A frame is airborne when the lowest
            point of every geom is more than 5 cm above the floor. Real
            planted soles of the retargeted body sit within 0-3 cm (the sole
            height is fitted from the data's own lowest toe positions).
        ballistic_tolerance_m: 0.03. An airborne run is a jump when the
            body's true centre of mass (MuJoCo body masses) follows a
            free-fall parabola within this RMS residual (as the keypoint-
            level floating test, whose calibration this inherits).

    Joint limits
        joint_limit_probe_deg: 60. For the joint-limit metric a motion is
            retargeted once more onto a copy of the body whose hinge ranges
            are widened by this much on both sides, so the fit may leave the
            anatomical range where the motion demands it; the violation is
            measured against the anatomical range (AAOS normal ranges plus
            margins, see :mod:`simenv.body.humanoid`).
        joint_limit_cost_m: 0.01. A hinge's violation counts on a frame
            when (a) over the keypoints that hinge moves, the limited fit's
            worst residual exceeds the relaxed fit's by more than this, and
            (b) clamping that hinge alone back into its range in the relaxed
            solution (forward kinematics, no re-solve) raises their worst
            residual by more than this (1 cm: above the retargeting's
            typical residual of a few millimetres on real clips). See
            :func:`simenv.plausibility.body.joint_limit_demand`.
        joint_limit_max_deg: 10. Largest allowed excess of any hinge beyond
            its range: the joint-centre error of motion capture, which the
            range table itself leaves out (module table: 24 of 27 CMU people
            at 0-6.3 deg, three failing on frames whose data are damaged);
            a knee bent 30+ deg backwards or an elbow hyperextended 30 deg in
            a real walk scores >= 30 and >= 15, the Charleston with a knee bent
            backwards >= 20 (tests/test_plausibility_joint_limits.py).
        joint_limit_min_duration_s: 0.025. The excess the metric reports is
            the largest one held this long (3 frames at 120 fps; a single
            frame below 40 fps). Measured on real CMU clips with the sourced
            ranges: two single-frame excesses are the retargeting's basin on
            one frame, not the joint -- the salsa 61_05 follower's right foot
            on frame 623 (18.5 deg at the eversion bound -35; 0.0 at -30 and
            11.7 at -40, so not a monotone function of the range) and 135_06's
            right foot on frame 1986 (12.3 deg); both hold 0 over 3 frames.
            A corrupted pose lasts as long as the corruption (the bent knees
            and elbows of the tests: 10-50 frames).

    Self- and inter-person penetration
        self_penetration_max_mm: 100. Largest allowed penetration depth
            between two non-neighbouring geoms of one body (bodies at tree
            distance >= 3; neighbours overlap by construction). The geoms are
            capsules and boxes, fuller than skin where the body is concave:
            the pelvis capsule fills the crotch gap between the thighs, the
            thigh capsules keep their hip-end girth down to the knee, the box
            feet are wider than a shoe's waist. Real contacts therefore read
            as overlap; measured on the real single-person CMU clips (max
            depth, pair): 02_06 bend-and-scoop 89 mm (upper arm along the
            thigh), 131_01 / 131_03 74 / 72 mm (hand in front of the crotch,
            Michael-Jackson style), 49_02 64 mm (forearm on the thigh),
            103 Charleston 49 mm (feet crossing), 135_06 karate 40 mm (fist
            chambered at the chest), walks 4-10 mm. A forearm driven through
            the torso (the bundled walk with the right wrist and hand moved
            into the chest) measures 130 mm. The threshold sits between the
            two: only penetrations deeper than any real contact of the capsule
            body are flagged.
        inter_penetration_max_mm: 100. Same limit between geoms of two
            people, for the same reason: partners' real contacts overlap the
            capsule bodies (measured: CMU salsa 60/61_05 47 mm and 60/61_10
            50 mm, the lead's hand on the follower's back; NuiSI fist bumps
            39 mm), while two bodies standing in one another overlap by
            decimetres.

    Interaction contacts
        contact_distance_m: 0.15. Two keypoints (e.g. the right hands in a
            handshake) are *in contact* when their centres are closer than
            this: hand keypoints sit at the knuckles, so clasped hands keep
            them 5-12 cm apart.
        jpd_max_mm: 50. Largest allowed mean error of the key joint-pair
            distances against the reference (JPD of the interaction-
            augmentation seed; 5 cm is about a hand's thickness).

    Dynamics (inverse dynamics of the retargeted trajectory)
        filter_cutoff_hz: 6. Velocities are low-pass filtered (4th-order
            zero-phase Butterworth) before differentiation, the standard
            cutoff for marker-based gait data (Winter, *Biomechanics and
            Motor Control of Human Movement*, 4th ed., sec. 2.2.4.4).
        friction: 1.0. Coulomb friction coefficient of the feet on the floor
            (rubber soles on concrete 0.8-1.0; MuJoCo's default is 1).
        support_height_m: 0.05. A geom point lower than this above the floor
            may carry load (a contact candidate). On data whose foot keypoints
            vary between loaded frames a planted forefoot can hover near this
            height: with the sole fitted from the lowest balls alone, CMU
            131_04's opening stance failed ``balance`` on frames 0-8 with its
            forefoot corners at 5.0-5.4 cm; the fit's two-anchor sole
            (:func:`simenv.body.humanoid.fit_dimensions`) passes it, at 49.96 mm of
            the 50 mm margin (docs/plausibility.md, calibration findings).
        root_force_mean_max: 0.15. Largest allowed mean (over frames) of the
            residual root force, as a fraction of body weight m g: the
            "invisible help" the motion needs after the best feasible ground
            reaction forces. Real walking needs (near) zero; a walk lifted
            30 cm needs ~1. Calibrated on real CMU clips: single-person clips
            0.00-0.12, except 49_04 at 0.160, whose last 6 frames are frozen
            copies (the body stops dead rising at 0.9 m/s; 0.070 without
            them). In two-person files each person is judged on the residual
            left after the partner's hand forces (``pair_root_residual``):
            salsa followers 0.157 -> 0.130 and 0.167 -> 0.148 (0.164 -> 0.136
            and 0.176 -> 0.156 with the previous sole fit; the 61_10 template
            file needed 0.38 at the dancer's own size, see docs/plausibility.md).
        root_force_frame_max: 0.5. Per-frame limit (fraction of body weight)
            for the residual's violation runs (landings of real jumps peak
            briefly as the 6 Hz filter spreads the impact).
        root_residual_tracked_m: 0.1. When an unassisted controller tracked
            the motion, ``root_residual`` counts no help on the frames where
            its body error (mean keypoint distance) stayed within this: the
            simulated body did them alone. Twice the tracking goal
            (mean body-point error <= 5 cm); a body that cannot
            follow a 15 cm hover (the moderate ``float`` corruption) is
            further off than this once it drops.
        pair_contact_gap_m: 0.05. Two-person files
            (:mod:`simenv.plausibility.pair_dynamics`): a hand is in contact
            with the partner when its geom (a box from the wrist to the
            knuckles, no fingers) is within 5 cm of a partner geom -- the
            fingers reach past the box.
        grip_force_max_bw: 0.25. Largest force one hand contact may carry
            between partners, as a fraction of the lighter partner's body
            weight: a strength capacity, since plausibility asks what a body
            could do. 0.25 of a 60 kg partner's weight is 147 N, women's
            maximal standing isometric push (140 N; pull 244 N; men 251 /
            400 N; Das & Wang, Int J Occup Saf Ergon 2004, 10(1):43-58); a
            partner cannot hold the other up with one hand. Partner dancers
            exchange far less: 10-30 N in partnered stepping (Sawers et al.,
            J NeuroEng Rehabil 2017, 14:8), so the partner-explained residual
            is the most help the hands could give. Measured on the salsa
            followers 61_05 / 61_10: 0.155 / 0.171 at 0.05 (30 N for 60 kg),
            0.136 / 0.156 at 0.25, 0.125 / 0.149 at 1.0.
        balance_accel_mps2: 0.5. A frame is quasi-static when the centre of
            mass accelerates less than this (about 5 % of g) ...
        balance_speed_mps: 0.1. ... and moves horizontally slower than this.
            Static balance only binds a body at rest: a dancer turning or a
            walker starting a step moves the centre of mass past the support
            edge with little acceleration (measured on real CMU clips: the
            05_02 pirouette at 0.13 m/s, 01_01 turning between hops at
            0.07-0.11 m/s, the 49_06 cartwheel at 0.68 m/s); those frames are
            judged by the full dynamics of ``root_residual``.
        balance_support_band_m: 0.03. Geom points within this of the frame's
            lowest point also support the body (CMU 131_01's wide stance: one
            sole at 3.1 cm, the other at 5.5 cm above z = 0).
        balance_margin_mm: 50. Largest allowed distance of the centre of
            mass ground projection outside the support polygon on
            quasi-static frames (soft tissue and the shoe extend the support
            beyond the box soles by a few centimetres).

    Physics tracking
        tracking_fail_m: 0.5. PHC's failure rule (Luo et al. 2023): the
            simulation has failed once the mean distance between simulated
            and reference keypoints exceeds 0.5 m.
        tracking_max_seconds: 20. Longest stretch simulated per clip.
        tracking_segment_s: 4. A clip longer than this is judged in segments of this
            many seconds, each simulated from the captured state ``tracking_lead_s``
            before it (the first from frame 0): every stretch of the motion is asked of
            the body with a run-up of its own, so that a controller's drift over a long
            clip is not counted against the motion
            (:func:`simenv.plausibility.tracking.track`). 4 s is the stretch the
            unassisted MPC tracks 18 of 20 real CMU clips over from their first frame;
            whole, it falls in the hops of the 23 s 01_01 at 9 s (docs/plausibility.md).
            Infinity tracks every clip in one run.
        tracking_lead_s: 1. The run-up of a segment, seconds: a corruption at a
            segment's start is met by a body already moving on its own.
        assist_timeconst_s: 0.02. Time constant of the optional root
            assistance: a critically damped soft weld (MuJoCo equality
            constraint, ``solref = (0.02, 1)``) between the pelvis and a
            mocap body that follows the reference root; its constraint force
            is the measured help. 20 ms is MuJoCo's default constraint time
            constant, stable at the 2 ms timestep.
    """

    geom_penetration_max_mm: float = 30.0
    geom_float_clearance_m: float = 0.05
    ballistic_tolerance_m: float = 0.03

    joint_limit_probe_deg: float = 60.0
    joint_limit_max_deg: float = 10.0
    joint_limit_cost_m: float = 0.01
    joint_limit_min_duration_s: float = 0.025

    self_penetration_max_mm: float = 100.0
    inter_penetration_max_mm: float = 100.0

    contact_distance_m: float = 0.15
    jpd_max_mm: float = 50.0

    filter_cutoff_hz: float = 6.0
    friction: float = 1.0
    support_height_m: float = 0.05
    root_force_mean_max: float = 0.15
    root_force_frame_max: float = 0.5
    root_residual_tracked_m: float = 0.1
    pair_contact_gap_m: float = 0.05
    grip_force_max_bw: float = 0.25
    balance_accel_mps2: float = 0.5
    balance_speed_mps: float = 0.1
    balance_support_band_m: float = 0.03
    balance_margin_mm: float = 50.0

    tracking_fail_m: float = 0.5
    tracking_max_seconds: float = 20.0
    tracking_segment_s: float = 4.0
    tracking_lead_s: float = 1.0
    assist_timeconst_s: float = 0.02

    gravity_mps2: float = 9.81


#: The defaults, shared by every body-level metric when no thresholds are passed.
DEFAULT_BODY_THRESHOLDS = BodyThresholds()


#: Body-level thresholds of each depth-camera corpus, its own source calibration
#: (see :data:`simenv.plausibility.thresholds.SOURCE_THRESHOLDS`, whose joint-level
#: profiles go with these). ``joint_limit_max_deg`` = 60 = the probe's widening:
#: on these skeletons the relaxed fit leaves most ranges by the whole probe, so
#: joint limits are not judged. Florence has no body-level profile: no body is
#: fitted to its 15 joints.
SOURCE_BODY_THRESHOLDS: dict[str, BodyThresholds] = {
    "msr_action3d": replace(DEFAULT_BODY_THRESHOLDS, geom_penetration_max_mm=91.9249,
                            joint_limit_max_deg=60.0, self_penetration_max_mm=139.572,
                            root_force_mean_max=0.3515, balance_margin_mm=183.374),
    "utkinect": replace(DEFAULT_BODY_THRESHOLDS, geom_penetration_max_mm=563.294,
                        geom_float_clearance_m=0.4315, joint_limit_max_deg=60.0,
                        self_penetration_max_mm=151.532, root_force_mean_max=0.3646,
                        balance_margin_mm=511.926),
    "florence3d": DEFAULT_BODY_THRESHOLDS,
}

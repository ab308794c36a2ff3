"""A MuJoCo humanoid built to a subject's measurements with :class:`mujoco.MjSpec`.

Body tree (every body frame is aligned with the world in the rest pose: x forward,
y left, z up; the rest pose is standing with the arms hanging)::

    pelvis (free joint) -+- lumbar -- thorax -- chest -+- neck -- head
                         |                             +- {l,r}_clavicle -- upper_arm
                         |                                   -- forearm -- hand
                         +- {l,r}_thigh -- shin -- foot -- toes

Each body carries a site at its canonical keypoint (site name = keypoint name, see
:data:`simenv.core.skeletons.CANONICAL_KEYPOINTS`), so keypoints are read from
``data.site_xpos``. A keypoint is the origin of the body it starts, except the
rigid ones: the hips live on the pelvis, the neck on the chest, and the spine on
the pelvis for a source whose spine keypoint is rigid there (SMPL ``spine1``, a
rig's first spine joint hung from its pelvis joint: the lumbar then turns at it,
:attr:`BodyDimensions.lumbar_offset`), and a knee
keypoint the source puts beside its hip-ankle line (on the thigh, off the knee
hinge along its axis; :class:`RestGeometry`, with the head keypoint's direction).

Joints are hinges (triplets where the anatomy has three degrees of freedom, so
every degree of freedom gets its own box limit and its own position actuator).
Limits follow one rule: the largest value a named normative study reports for
healthy people (aged 2 and over; dancers included where a study measured them)
plus :data:`ROM_SPREAD_DEG` for the population's spread; ends no study gives
(the spine's split over three joints, the upper arm's Euler angles) are stated
assumptions. :data:`RANGE_SOURCES` gives each end's motion,
value and reference (:data:`ROM_REFERENCES`); ``docs/plausibility.md`` tabulates
them. Signs are mirrored between the sides so that a positive angle means the
same anatomical motion on the left and on the right. See :data:`JOINTS`.

Masses come from the geoms at body density (:data:`BODY_DENSITY`); the default
adult (1.75 m) weighs about 72 kg (see :attr:`Humanoid.total_mass`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from functools import cached_property
from typing import NamedTuple

import mujoco
import numpy as np

from simenv.body.foot_contact import foot_contacts
from simenv.core.errors import RetargetError
from simenv.core.motion import Motion
from simenv.core.skeletons import CANONICAL_KEYPOINTS, CANONICAL_TREE

#: Body density, kg/m^3 (lean tissue ~1060, whole body ~1010-1060).
BODY_DENSITY = 1040.0

#: Canonical bones, named after their child keypoint (order of the scale vector).
BONES: tuple[str, ...] = tuple(k for k in CANONICAL_KEYPOINTS if CANONICAL_TREE[k] is not None)

#: Allowed per-bone scale range (interaction-augmentation skeleton prior).
SCALE_RANGE = (0.75, 1.25)

#: Plausible range of each length of :class:`BodyDimensions`, metres. Outside ->
#: :class:`RetargetError` (the input is not a human, or not in metres).
LENGTH_RANGE = (0.0, 0.9)
HEIGHT_RANGE = (0.5, 2.6)

_SIDES = ("left", "right")


@dataclass(frozen=True)
class JointSpec:
    """One hinge: name suffix, axis in the (left-side) body frame, range in degrees
    (positive = the named anatomical motion), PD gains of its position actuator."""

    name: str
    axis: tuple[float, float, float]
    range_deg: tuple[float, float]
    kp: float
    mirror: bool = True


#: Population spread added to the largest published value of a motion, degrees:
#: about two standard deviations of goniometric range-of-motion measures (an
#: assumption: the tables quoted in :data:`RANGE_SOURCES` give means, not their
#: spread). Motion capture's own joint-centre error is not in the table; it is
#: the tolerance of the joint-limit metric
#: (:attr:`simenv.plausibility.body_thresholds.BodyThresholds.joint_limit_max_deg`).
ROM_SPREAD_DEG = 10.0

#: Full references of the range table (keys of :class:`RangeEnd.source`).
ROM_REFERENCES: dict[str, str] = {
    "NW-A1": "Norkin CC, White DJ. Measurement of Joint Motion: A Guide to Goniometry "
             "(F.A. Davis), Appendix A, Table A.1 'Shoulder, Elbow, Forearm, and Wrist "
             "Motion: Mean Values in Degrees': means of Boone & Azen 1979 (1-54 y, 109 M), "
             "Greene & Wolf (18-55 y, 10 M 10 F), Walker et al. (65-85 y), Macedo & Magee "
             "(18-59 y, 90 F), AAOS and AMA; universal goniometer",
    "Soucie": "Soucie JM et al. Range of motion measurements: reference values and a "
              "database for comparison studies. Haemophilia 2011;17(3):500-507 (674 "
              "healthy subjects 2-69 y, passive ROM, goniometer); reference values as "
              "published by the CDC, archive.cdc.gov/www_cdc_gov/ncbddd/jointrom",
    "Merck": "The Merck Manual (professional edition, Merck Sharp & Dohme 2010-2013), "
             "Table 'Normal Values for Range of Motion of Joints' (ranges for people of "
             "all ages)",
    "Bennell": "Bennell K et al., ballet dancers and controls, Br J Sports Med, Table 3 "
               "'Baseline and final measurements of range of motion ... mean (SD)' "
               "(bjsm.bmj.com/highwire/markup/79235)",
    "Rabin": "Rabin A, Kozol Z. J Am Podiatr Med Assoc 2012;102(5):406-411 "
             "(weight-bearing lunge test: the tibia 30-45 deg over the foot)",
    "AJSM1983": "Am J Sports Med 1983;11(3):152-156: passive knee axial rotation with the "
                "knee flexed 30-90 deg, about 25 internal and 45 external (as cited in "
                "docs/plausibility.md's calibration findings); the foot's toe-out hinge turns "
                "about the shin, so it carries the tibia's rotation when the knee is bent",
    "AAOS": "American Academy of Orthopaedic Surgeons, Joint Motion: Method of Measuring "
            "and Recording, 1965 (the figures of this table's previous version)",
    "model": "no published counterpart: a range of this model's own angle (the spine "
             "split over three joints, the upper arm's Euler angles measured from the "
             "A-pose) -- an assumption, sized on the real CMU clips",
}


class RangeEnd(NamedTuple):
    """Where one end of a hinge's range comes from.

    Attributes:
        motion: the anatomical motion at that end (e.g. ``"extension"``).
        published_deg: the largest value the cited healthy-population study
            reports for it (a group mean, or the upper end of a quoted normal
            range), degrees; None when the end is an assumption (``source``
            ``"model"``, or a figure no normative study gives).
        source: key of :data:`ROM_REFERENCES`, plus the group the value is from.
    """

    motion: str
    published_deg: float | None
    source: str


#: Joint table per body (left side; right side mirrored: x and z axis
#: components negated so positive angles keep their anatomical meaning).
#: Ranges follow one rule (:data:`RANGE_SOURCES` gives each end's motion,
#: value and source): the largest value a cited study reports for healthy
#: people aged 2 and over (children are the most mobile group of Soucie et al.;
#: infants are left out), plus :data:`ROM_SPREAD_DEG`. Ends with no such
#: value are assumptions, said so in the source. Gains (not calibrated here):
#: kp in N m/rad, kv = 0.1 * kp (N m s/rad). kp grows with the mass the
#: joint carries; 0.1 s time constant keeps PD tracking critically damped-ish.
JOINTS: dict[str, tuple[JointSpec, ...]] = {
    # Thoraco-lumbar spine split over lumbar / thorax / chest: no normative
    # study gives per-segment ranges of a keypoint spine (whose segments also
    # carry the pelvis tilt and marker errors the goniometer's single spine
    # does not); kept as sized on the CMU clips (totals flexion 145, extension
    # 90, lateral 80, rotation 95 against AAOS 80 / 25 / 35 / 45).
    "lumbar": (
        JointSpec("flex", (0, 1, 0), (-30, 60), 600),
        JointSpec("lat", (1, 0, 0), (-30, 30), 600),
        JointSpec("rot", (0, 0, 1), (-35, 35), 400),
    ),
    "thorax": (
        JointSpec("flex", (0, 1, 0), (-30, 45), 500),
        JointSpec("lat", (1, 0, 0), (-25, 25), 500),
        JointSpec("rot", (0, 0, 1), (-30, 30), 300),
    ),
    "chest": (
        JointSpec("flex", (0, 1, 0), (-30, 40), 400),
        JointSpec("lat", (1, 0, 0), (-25, 25), 400),
        JointSpec("rot", (0, 0, 1), (-30, 30), 300),
    ),
    # Cervical spine + head (AAOS: flexion 45, extension 45, lateral 45, rotation 60).
    "neck": (
        JointSpec("flex", (0, 1, 0), (-55, 55), 80),
        JointSpec("lat", (1, 0, 0), (-55, 55), 80),
        JointSpec("rot", (0, 0, 1), (-70, 70), 60),
    ),
    # Shoulder girdle (AAOS: elevation 45, depression 15, protraction and
    # retraction 30).
    "clavicle": (
        JointSpec("protract", (0, 0, -1), (-40, 40), 200),
        JointSpec("elevate", (1, 0, 0), (-25, 55), 200),
    ),
    # Glenohumeral, as Euler angles of this model (Table A.1's largest adult
    # means: flexion 188, extension 70, abduction 188, medial rotation 94,
    # lateral rotation 108, Macedo & Magee). The third angle is axial rotation
    # only near neutral elevation; with the arm raised it absorbs the Codman
    # coupling, hence its wider (model) range. Angles are measured from the
    # A-pose of :data:`ARM_TILT`: abduction -50..198 deg from the hanging arm
    # becomes -84..164; flexion in the tilted plane reaches -90 (extension with
    # the arm abducted, seen in CMU dance clips; a model range).
    "upper_arm": (
        JointSpec("flex", (0, -1, 0), (-90, 198), 200),
        JointSpec("abd", (1, 0, 0), (-84, 164), 200),
        JointSpec("rot", (0, 0, -1), (-150, 150), 100),
    ),
    # Elbow flexion / hyperextension; forearm pronation > 0, supination < 0.
    "forearm": (
        JointSpec("flex", (0, -1, 0), (-12, 159), 120),
        JointSpec("pronate", (0, 0, -1), (-106, 102), 40),
    ),
    # Wrist (palm facing the thigh at rest): extension > 0, palmar flexion < 0;
    # ulnar deviation > 0, radial < 0.
    "hand": (
        JointSpec("flex", (1, 0, 0), (-103, 96), 30),
        JointSpec("dev", (0, 1, 0), (-35, 51), 30),
    ),
    # Hip: flexion > 0; abduction > 0; internal rotation > 0.
    "thigh": (
        JointSpec("flex", (0, -1, 0), (-38, 151), 600),
        JointSpec("abd", (1, 0, 0), (-55, 55), 600),
        JointSpec("rot", (0, 0, -1), (-57, 55), 300),
    ),
    # Knee flexion > 0, hyperextension < 0.
    "shin": (JointSpec("flex", (0, 1, 0), (-15, 163), 500),),
    # Ankle + subtalar inversion / eversion + toe-out about the shin (the
    # tibia's axial rotation when the knee is bent, plus forefoot abduction).
    # flex > 0 is plantarflexion (toe down about +y;
    # 0 = shin perpendicular to the flat sole, the toe keypoint the fitted drop
    # below the ankle). Dorsiflexion is the weight-bearing range, not the
    # passive one: under body weight with the knee bent (squats, landings,
    # lunges) the tibia leans 30-45 deg over the foot (Rabin & Kozol).
    "foot": (
        JointSpec("flex", (0, 1, 0), (-55, 60), 300),
        JointSpec("inv", (1, 0, 0), (-35, 45), 150),
        JointSpec("abd", (0, 0, 1), (-55, 55), 100),
    ),
    # Metatarsophalangeal: extension > 0, flexion < 0.
    "toes": (JointSpec("ext", (0, -1, 0), (-40, 90), 40),),
}

#: Per hinge (``"<body>_<hinge>"``, keys of :data:`JOINTS`), the motion, the
#: published value and the source of its lower and upper range ends. Where
#: ``published_deg`` is given, the range end is ``published_deg +``
#: :data:`ROM_SPREAD_DEG` (signed: the lower end is its negative).
RANGE_SOURCES: dict[str, tuple[RangeEnd, RangeEnd]] = {
    "lumbar_flex": (RangeEnd("extension", None, "model"), RangeEnd("flexion", None, "model")),
    "lumbar_lat": (RangeEnd("lateral flexion, right", None, "model"),
                   RangeEnd("lateral flexion, left", None, "model")),
    "lumbar_rot": (RangeEnd("rotation, right", None, "model"),
                   RangeEnd("rotation, left", None, "model")),
    "thorax_flex": (RangeEnd("extension", None, "model"), RangeEnd("flexion", None, "model")),
    "thorax_lat": (RangeEnd("lateral flexion, right", None, "model"),
                   RangeEnd("lateral flexion, left", None, "model")),
    "thorax_rot": (RangeEnd("rotation, right", None, "model"),
                   RangeEnd("rotation, left", None, "model")),
    "chest_flex": (RangeEnd("extension", None, "model"), RangeEnd("flexion", None, "model")),
    "chest_lat": (RangeEnd("lateral flexion, right", None, "model"),
                  RangeEnd("lateral flexion, left", None, "model")),
    "chest_rot": (RangeEnd("rotation, right", None, "model"),
                  RangeEnd("rotation, left", None, "model")),
    "neck_flex": (RangeEnd("extension", 45.0, "AAOS"), RangeEnd("flexion", 45.0, "AAOS")),
    "neck_lat": (RangeEnd("lateral flexion, right", 45.0, "AAOS"),
                 RangeEnd("lateral flexion, left", 45.0, "AAOS")),
    "neck_rot": (RangeEnd("rotation, right", 60.0, "AAOS"),
                 RangeEnd("rotation, left", 60.0, "AAOS")),
    "clavicle_protract": (RangeEnd("retraction", 30.0, "AAOS"),
                          RangeEnd("protraction", 30.0, "AAOS")),
    "clavicle_elevate": (RangeEnd("depression", 15.0, "AAOS"),
                         RangeEnd("elevation", 45.0, "AAOS")),
    "upper_arm_flex": (RangeEnd("extension in the A-pose plane", None, "model"),
                       RangeEnd("flexion", 188.0, "NW-A1, Macedo & Magee (women 18-59 y)")),
    "upper_arm_abd": (RangeEnd("adduction across the body", None, "model"),
                      RangeEnd("abduction, less the A-pose tilt of 34", 154.0,
                               "NW-A1, Macedo & Magee (women 18-59 y): 188 - 34")),
    "upper_arm_rot": (RangeEnd("lateral rotation with Codman coupling", None, "model"),
                      RangeEnd("medial rotation with Codman coupling", None, "model")),
    "forearm_flex": (RangeEnd("hyperextension", 2.0, "NW-A1, Macedo & Magee (women 18-59 y)"),
                     RangeEnd("flexion", 149.0, "NW-A1, Macedo & Magee (women 18-59 y)")),
    "forearm_pronate": (RangeEnd("supination", 96.0, "NW-A1, Macedo & Magee (women 18-59 y)"),
                        RangeEnd("pronation", 92.0, "NW-A1, Macedo & Magee (women 18-59 y)")),
    "hand_flex": (RangeEnd("palmar flexion", 93.0, "NW-A1, Macedo & Magee (women 18-59 y)"),
                  RangeEnd("extension", 86.0, "NW-A1, Macedo & Magee (women 18-59 y)")),
    "hand_dev": (RangeEnd("radial deviation", 25.0, "NW-A1, Greene & Wolf (18-55 y)"),
                 RangeEnd("ulnar deviation", 41.0, "NW-A1, Macedo & Magee (women 18-59 y)")),
    "thigh_flex": (RangeEnd("extension", 28.3, "Soucie, boys 2-8 y"),
                   RangeEnd("flexion", 140.8, "Soucie, girls 2-8 y")),
    "thigh_abd": (RangeEnd("adduction", 45.0, "Merck"), RangeEnd("abduction", 45.0, "Merck")),
    "thigh_rot": (RangeEnd("external rotation", 47.2,
                           "Bennell, ballet dancers (final, supine, mean)"),
                  RangeEnd("internal rotation", 45.0, "Merck")),
    "shin_flex": (RangeEnd("hyperextension", 5.4, "Soucie, girls 2-8 y"),
                  RangeEnd("flexion", 152.6, "Soucie, girls 2-8 y")),
    "foot_flex": (RangeEnd("dorsiflexion, weight-bearing", 45.0, "Rabin (upper end)"),
                  RangeEnd("plantarflexion", 50.0, "Merck")),
    "foot_inv": (RangeEnd("eversion", 25.0, "Merck"), RangeEnd("inversion", 35.0, "Merck")),
    "foot_abd": (RangeEnd("toe-in: knee internal rotation + forefoot adduction", 45.0,
                          "AJSM1983 25 + AAOS 20"),
                 RangeEnd("toe-out: knee external rotation", 45.0, "AJSM1983")),
    "toes_ext": (RangeEnd("flexion", 30.0, "Merck"), RangeEnd("extension", 80.0, "Merck")),
}


def _v(x: Sequence[float]) -> tuple[float, float, float]:
    a = np.asarray(x, dtype=float).reshape(3)
    return (float(a[0]), float(a[1]), float(a[2]))


#: Largest sideways offset of a knee keypoint from its hip-ankle line that the fit
#: takes as the source skeleton's rest geometry (:attr:`RestGeometry.left_knee_lateral`),
#: metres: a person-sized skeleton's knee joint centre (SMPL's: 29-40 mm) sits well
#: within it; beyond it the "knee" is not a knee.
KNEE_LATERAL_MAX = 0.1


@dataclass(frozen=True)
class RestGeometry:
    """The source skeleton's constant rest geometry, which the body carries so that its
    zero pose is the source's own rest pose rather than a pose read into it.

    A skeleton's joint centres need not sit where this humanoid's straight segments put
    them: SMPL's knee joint centre lies 29-40 mm lateral of the line from hip to ankle
    even on a straight leg, and its head joint sits forward of its neck joint. Measured
    as pose, such constants read as a thigh turned ~90 deg to "bend" the hinge knee
    sideways, or a neck flexed 50 deg on an upright frame. Measured by
    :func:`fit_dimensions` from the clip's own frames; the default is this humanoid's
    straight layout (every field neutral).

    Attributes:
        left_knee_lateral, right_knee_lateral: the knee keypoint's offset from the
            hip-ankle line along the knee's hinge axis, metres, outwards positive
            (within :data:`KNEE_LATERAL_MAX`). The hinge turns about a line through
            the keypoint, so the offset is invariant under knee flexion: the thigh
            carries the keypoint off its axis and the shin's hinge sits on the line.
        head_direction: unit direction of the neck -> head keypoint in the neck body's
            frame at zero neck angles (x forward, y left, z along the chest -> neck
            line); (0, 0, 1) is straight on.
    """

    left_knee_lateral: float = 0.0
    right_knee_lateral: float = 0.0
    head_direction: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        for side in _SIDES:
            a = float(getattr(self, f"{side}_knee_lateral"))
            if not (np.isfinite(a) and abs(a) <= KNEE_LATERAL_MAX):
                raise RetargetError(
                    f"{side}_knee_lateral = {a!r} m; a knee keypoint's sideways rest offset "
                    f"must be within +-{KNEE_LATERAL_MAX} m", field=f"{side}_knee_lateral")
            object.__setattr__(self, f"{side}_knee_lateral", a)
        h = np.asarray(self.head_direction, dtype=float).reshape(-1)
        if h.shape != (3,) or not np.all(np.isfinite(h)) or h[2] <= 0.0:
            raise RetargetError(f"head_direction = {h.tolist()}; expected a finite 3-vector "
                                "pointing up the neck (positive z)", field="head_direction")
        object.__setattr__(self, "head_direction", _v(h / np.linalg.norm(h)))

    def to_dict(self) -> dict[str, object]:
        """JSON-friendly dict of the fields."""
        return {"left_knee_lateral": self.left_knee_lateral,
                "right_knee_lateral": self.right_knee_lateral,
                "head_direction": list(self.head_direction)}


@dataclass(frozen=True)
class BodyDimensions:
    """The measurements that define a body, metres (body frame: x forward, y left, z up).

    Segment lengths are distances between canonical keypoints; ``*_offset``
    fields are the rigid 3D offsets of keypoints that share a body (hips on the
    pelvis). A zero length is allowed where the source skeleton places two
    keypoints at one point (e.g. CMU BVH neck = chest, hand = wrist).

    Attributes:
        left_hip_offset, right_hip_offset: hip joint centres in the pelvis frame.
        lumbar_offset: where the lumbar joint sits in the pelvis frame. Zero (the
            default, CMU's layout): it turns at the pelvis keypoint and the spine
            keypoint ends the lumbar. Non-zero: the source's spine keypoint is
            rigid on the pelvis (SMPL ``spine1``: a joint's position is fixed in
            its parent's frame, and spine1's parent is the pelvis) and the lumbar
            turns *at* it, so the spine site sits on the pelvis there; the fit
            then gives the lumbar zero length (see :attr:`spine_on_pelvis`).
        lumbar: pelvis -> spine (lumbar joint -> thorax joint when
            :attr:`spine_on_pelvis`). thorax: spine -> chest (thorax joint ->
            chest). upper_chest: chest -> neck.
        neck: neck -> head keypoint (base of the skull).
        clavicle_pivot: height of the sterno-clavicular pivot above the chest
            keypoint, along the chest's z axis.
        {left,right}_clavicle: pivot -> shoulder. *_upper_arm: shoulder -> elbow.
        *_forearm: elbow -> wrist. *_hand: wrist -> hand keypoint.
        *_thigh: hip -> knee. *_shin: knee -> ankle. *_foot: ankle -> toe (ball).
        ankle_height, toe_height: heights of the ankle and toe keypoints above
            the sole with the foot flat. toes_length: toe keypoint -> tip.
        heel_length: heel behind the ankle. foot_width: sole width.
        girth: scale of the segment radii (1 = default adult).
        rest: the source skeleton's own rest geometry (:class:`RestGeometry`): a knee
            keypoint off the hip-ankle line, a head keypoint off the neck's axis.
        notes: how the dimensions were obtained (fallbacks are recorded here).
    """

    left_hip_offset: tuple[float, float, float] = (0.0, 0.09, -0.09)
    right_hip_offset: tuple[float, float, float] = (0.0, -0.09, -0.09)
    lumbar_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    lumbar: float = 0.12
    thorax: float = 0.12
    upper_chest: float = 0.21
    neck: float = 0.125
    clavicle_pivot: float = 0.19
    left_clavicle: float = 0.2
    right_clavicle: float = 0.2
    left_upper_arm: float = 0.30
    right_upper_arm: float = 0.30
    left_forearm: float = 0.25
    right_forearm: float = 0.25
    left_hand: float = 0.09
    right_hand: float = 0.09
    left_thigh: float = 0.43
    right_thigh: float = 0.43
    left_shin: float = 0.41
    right_shin: float = 0.41
    left_foot: float = 0.15
    right_foot: float = 0.15
    ankle_height: float = 0.07
    toe_height: float = 0.025
    toes_length: float = 0.06
    heel_length: float = 0.06
    foot_width: float = 0.09
    girth: float = 1.0
    rest: RestGeometry = field(default_factory=RestGeometry)
    notes: tuple[str, ...] = field(default=(), compare=False)

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name in ("notes", "rest"):
                continue
            v = np.asarray(getattr(self, f.name), dtype=float)
            if not np.all(np.isfinite(v)):
                raise RetargetError(f"body dimension {f.name} = {v.tolist()} is not finite",
                                    field=f.name)
            lo, hi = LENGTH_RANGE if f.name != "girth" else (0.3, 3.0)
            if f.name.endswith("_offset"):
                bad = np.abs(v).max() > hi
            else:
                bad = not lo <= float(v) <= hi
            if bad:
                raise RetargetError(
                    f"body dimension {f.name} = {np.round(v, 4).tolist()} m is outside the "
                    f"human range [{lo}, {hi}]; the input is not a human body in metres",
                    field=f.name,
                )
            if f.name.endswith("_offset"):
                object.__setattr__(self, f.name, _v(v))
        for side in _SIDES:
            for seg in ("thigh", "shin", "upper_arm", "forearm"):
                if getattr(self, f"{side}_{seg}") < 0.05:
                    raise RetargetError(
                        f"{side}_{seg} = {getattr(self, f'{side}_{seg}'):.4f} m; a limb "
                        "segment must be at least 0.05 m", field=f"{side}_{seg}")
        for side in _SIDES:
            a = abs(getattr(self.rest, f"{side}_knee_lateral"))
            if a > 0.5 * min(getattr(self, f"{side}_thigh"), getattr(self, f"{side}_shin")):
                raise RetargetError(
                    f"{side}_knee_lateral = {a:.4f} m is more than half the {side} thigh or "
                    "shin; the knee keypoint cannot sit that far off its leg's line",
                    field=f"{side}_knee_lateral")
        if not HEIGHT_RANGE[0] <= self.height <= HEIGHT_RANGE[1]:
            raise RetargetError(
                f"standing height {self.height:.3f} m is outside {HEIGHT_RANGE} m",
                field="height")

    # -- derived quantities -------------------------------------------------

    def leg_line(self, side: str) -> tuple[float, float]:
        """``(hip -> knee hinge, knee hinge -> ankle)`` along the straight leg's line,
        metres: the thigh and shin lengths less the knee keypoint's sideways rest
        offset (:attr:`RestGeometry.left_knee_lateral`; equal to them without one)."""
        a = getattr(self.rest, f"{side}_knee_lateral")
        thigh, shin = getattr(self, f"{side}_thigh"), getattr(self, f"{side}_shin")
        if a == 0.0:  # exact: no rounding through the square root
            return float(thigh), float(shin)
        return float(np.sqrt(thigh**2 - a * a)), float(np.sqrt(shin**2 - a * a))

    @property
    def hip_height(self) -> float:
        """Height of the pelvis keypoint when standing straight, metres."""
        leg = max(
            self.ankle_height + sum(self.leg_line(s)) - getattr(self, f"{s}_hip_offset")[2]
            for s in _SIDES
        )
        return float(leg)

    @property
    def spine_on_pelvis(self) -> bool:
        """Whether the spine keypoint is rigid on the pelvis at :attr:`lumbar_offset`
        (the lumbar joint) rather than the end of the lumbar."""
        return bool(np.any(np.asarray(self.lumbar_offset) != 0.0))

    @property
    def height(self) -> float:
        """Standing height (sole to top of the head), metres."""
        return float(self.hip_height + self.lumbar_offset[2] + self.lumbar + self.thorax
                     + self.upper_chest + self.neck * self.rest.head_direction[2]
                     + self.head_radius * 1.75)

    @property
    def scale(self) -> float:
        """Overall size relative to the default adult (ratio of heights)."""
        return self.height / DEFAULT_HEIGHT

    @property
    def head_radius(self) -> float:
        return 0.1 * self.girth

    def bone_lengths(self) -> dict[str, float]:
        """Rest-pose distance of every canonical bone (keyed by child keypoint), metres."""
        kp = self.rest_keypoints()
        idx = {k: i for i, k in enumerate(CANONICAL_KEYPOINTS)}
        return {b: float(np.linalg.norm(kp[idx[b]] - kp[idx[CANONICAL_TREE[b]]])) for b in BONES}

    def rest_keypoints(self) -> np.ndarray:
        """(21, 3) canonical keypoints of the rest pose, pelvis at the origin."""
        return _rest_keypoints(self)

    @classmethod
    def default(cls) -> BodyDimensions:
        """The default adult, 1.75 m (segment proportions after Winter,
        *Biomechanics and Motor Control of Human Movement*, 4th ed., fig. 4.1)."""
        return DEFAULT

    @classmethod
    def from_scale(cls, scale: Mapping[str, float] | Sequence[float] | np.ndarray,
                   base: BodyDimensions | None = None) -> BodyDimensions:
        """Scale the default adult (or ``base``) per canonical bone.

        Args:
            scale: per-bone factors in [0.75, 1.25], either a mapping from bone
                name (:data:`BONES`, named by child keypoint, e.g. ``"left_knee"``
                for the left thigh) to factor (missing bones keep 1), or a
                sequence of ``len(BONES)`` factors in :data:`BONES` order.
            base: dimensions to scale (default: the default adult).
        """
        base = base or DEFAULT
        if isinstance(scale, Mapping):
            unknown = sorted(set(scale) - set(BONES))
            if unknown:
                raise RetargetError(f"unknown bone(s) {unknown} in scale; expected names from "
                                    f"{list(BONES)}", field=unknown[0])
            vec = np.array([float(scale.get(b, 1.0)) for b in BONES])
        else:
            vec = np.asarray(scale, dtype=float).reshape(-1)
            if vec.shape != (len(BONES),):
                raise RetargetError(f"scale vector has {vec.size} entries; expected "
                                    f"{len(BONES)} (one per bone: {', '.join(BONES)})")
        for b, s in zip(BONES, vec, strict=True):
            if not (np.isfinite(s) and SCALE_RANGE[0] <= s <= SCALE_RANGE[1]):
                raise RetargetError(f"scale of bone {b!r} is {s!r}; expected a factor in "
                                    f"[{SCALE_RANGE[0]}, {SCALE_RANGE[1]}]", field=b)
        s = dict(zip(BONES, vec.tolist(), strict=True))
        ch: dict[str, object] = {}
        for side in _SIDES:
            ch[f"{side}_hip_offset"] = _v(np.asarray(getattr(base, f"{side}_hip_offset"))
                                          * s[f"{side}_hip"])
            for seg, bone in (("thigh", "knee"), ("shin", "ankle"), ("foot", "toe"),
                              ("clavicle", "shoulder"), ("upper_arm", "elbow"),
                              ("forearm", "wrist"), ("hand", "hand")):
                ch[f"{side}_{seg}"] = getattr(base, f"{side}_{seg}") * s[f"{side}_{bone}"]
        ch["lumbar_offset"] = _v(np.asarray(base.lumbar_offset) * s["spine"])
        ch["lumbar"] = base.lumbar * s["spine"]
        ch["thorax"] = base.thorax * s["chest"]
        ch["upper_chest"] = base.upper_chest * s["neck"]
        ch["clavicle_pivot"] = base.clavicle_pivot * s["neck"]
        ch["neck"] = base.neck * s["head"]
        foot = (s["left_toe"] + s["right_toe"]) / 2
        ch["toes_length"] = base.toes_length * foot
        ch["heel_length"] = base.heel_length * foot
        ch["rest"] = replace(base.rest, **{
            f"{side}_knee_lateral": getattr(base.rest, f"{side}_knee_lateral")
            * s[f"{side}_knee"] for side in _SIDES})
        ch["notes"] = (*base.notes, f"per-bone scale {np.round(vec, 3).tolist()}")
        return replace(base, **ch)

    def to_dict(self) -> dict[str, object]:
        """JSON-friendly dict of all fields plus the height."""
        out: dict[str, object] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = (list(v) if isinstance(v, tuple)
                           else v.to_dict() if isinstance(v, RestGeometry) else v)
        out["height"] = self.height
        return out


DEFAULT = BodyDimensions(notes=("default adult 1.75 m",))
DEFAULT_HEIGHT = DEFAULT.height


def _mirror(v: Sequence[float], side: str) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    return a * np.array([1.0, -1.0, 1.0]) if side == "right" else a


def _clavicle_dir(side: str) -> np.ndarray:
    return np.array([0.0, 1.0 if side == "left" else -1.0, 0.0])


def _foot_vector(d: BodyDimensions, side: str) -> np.ndarray:
    """Ankle -> toe keypoint in the foot frame (foot flat at zero angles)."""
    length = getattr(d, f"{side}_foot")
    drop = min(max(d.ankle_height - d.toe_height, 0.0), 0.9 * length)
    return np.array([np.sqrt(max(length**2 - drop**2, 0.0)), 0.0, -drop])


#: The upper arm's frame is tilted about x by this angle (abducted, an A-pose
#: at zero angles). Reason: a hinge triplet is singular when its middle angle
#: is +-90 deg, i.e. when the arm points along the first hinge axis. Untilted,
#: that is the arm held out sideways (T-pose, frequent in mocap); tilted, it is
#: the arm raised 34 deg above horizontal sideways or held down across the
#: body, the rarest arm directions in the CMU clips (0.1 % of frames within
#: 25 deg, against 1.7 % for the T-pose direction).
ARM_TILT = np.deg2rad(34.0)


def _arm_rest_dir(side: str) -> np.ndarray:
    sy = 1.0 if side == "left" else -1.0
    return np.array([0.0, sy * np.sin(ARM_TILT), -np.cos(ARM_TILT)])


def _arm_quat(side: str) -> list[float]:
    a = ARM_TILT if side == "left" else -ARM_TILT
    return [float(np.cos(a / 2)), float(np.sin(a / 2)), 0.0, 0.0]


def _knee_site(d: BodyDimensions, side: str) -> np.ndarray:
    """Knee keypoint in the thigh frame: down the leg's line to the knee hinge, then
    outwards along the hinge axis by the source's rest offset."""
    lateral = getattr(d.rest, f"{side}_knee_lateral") * (1.0 if side == "left" else -1.0)
    return np.array([0.0, lateral, -d.leg_line(side)[0]])


def _rest_keypoints(d: BodyDimensions) -> np.ndarray:
    kp: dict[str, np.ndarray] = {"pelvis": np.zeros(3)}
    pivot = np.asarray(d.lumbar_offset, dtype=float)
    kp["spine"] = pivot if d.spine_on_pelvis else pivot + [0, 0, d.lumbar]
    kp["chest"] = pivot + [0, 0, d.lumbar + d.thorax]
    kp["neck"] = kp["chest"] + [0, 0, d.upper_chest]
    kp["head"] = kp["neck"] + d.neck * np.asarray(d.rest.head_direction)
    for s in _SIDES:
        kp[f"{s}_hip"] = np.asarray(getattr(d, f"{s}_hip_offset"))
        thigh, shin = d.leg_line(s)
        kp[f"{s}_knee"] = kp[f"{s}_hip"] + _knee_site(d, s)
        kp[f"{s}_ankle"] = kp[f"{s}_hip"] - [0, 0, thigh + shin]
        kp[f"{s}_toe"] = kp[f"{s}_ankle"] + _foot_vector(d, s)
        pivot = kp["chest"] + [0, 0, d.clavicle_pivot]
        kp[f"{s}_shoulder"] = pivot + _clavicle_dir(s) * getattr(d, f"{s}_clavicle")
        arm = _arm_rest_dir(s)
        kp[f"{s}_elbow"] = kp[f"{s}_shoulder"] + arm * getattr(d, f"{s}_upper_arm")
        kp[f"{s}_wrist"] = kp[f"{s}_elbow"] + arm * getattr(d, f"{s}_forearm")
        kp[f"{s}_hand"] = kp[f"{s}_wrist"] + arm * getattr(d, f"{s}_hand")
    return np.stack([kp[k] for k in CANONICAL_KEYPOINTS])


# ---------------------------------------------------------------------------
# Model construction
# ---------------------------------------------------------------------------

#: Contact classes: every body geom collides with the floor, with other people
#: and with non-neighbouring parts of its own body (see the exclusions).
_BODY_CONTYPE = 1
_BODY_CONAFFINITY = 1
_SKIN = (0.85, 0.65, 0.5, 1.0)
_CLOTH = (0.25, 0.35, 0.6, 1.0)


def _capsule(body: mujoco.MjsBody, a: Sequence[float], b: Sequence[float], r: float,
             name: str, rgba: Sequence[float] = _CLOTH) -> None:
    a, b = np.asarray(a, float), np.asarray(b, float)
    g = body.add_geom()
    g.name = name
    if np.linalg.norm(b - a) < 1e-3:
        g.type = mujoco.mjtGeom.mjGEOM_SPHERE
        g.size = [r, 0, 0]
        g.pos = (a + b) / 2
    else:
        g.type = mujoco.mjtGeom.mjGEOM_CAPSULE
        g.fromto = [*a, *b]
        g.size = [r, 0, 0]
    g.rgba = list(rgba)
    g.density = BODY_DENSITY
    g.contype, g.conaffinity = _BODY_CONTYPE, _BODY_CONAFFINITY
    g.condim = 3


def _box(body: mujoco.MjsBody, center: Sequence[float], half: Sequence[float], name: str,
         rgba: Sequence[float] = _CLOTH) -> None:
    g = body.add_geom()
    g.name = name
    g.type = mujoco.mjtGeom.mjGEOM_BOX
    g.size = list(half)
    g.pos = list(center)
    g.rgba = list(rgba)
    g.density = BODY_DENSITY
    g.contype, g.conaffinity = _BODY_CONTYPE, _BODY_CONAFFINITY
    g.condim = 3


def _site(body: mujoco.MjsBody, name: str, pos: Sequence[float]) -> None:
    s = body.add_site()
    s.name = name
    s.pos = list(np.asarray(pos, float))
    s.size = [0.012, 0, 0]
    s.rgba = [1.0, 0.2, 0.2, 0.6]
    s.group = 4  # hidden by default in viewers; renderers may enable group 4


def _joints(body: mujoco.MjsBody, part: str, side: str | None, prefix: str,
            actuated: list[tuple[str, float]]) -> None:
    for js in JOINTS[part]:
        axis = np.asarray(js.axis, float)
        lo, hi = js.range_deg
        if side == "right" and js.mirror:
            axis = axis * np.array([-1.0, 1.0, -1.0])
        j = body.add_joint()
        j.name = f"{prefix}{(side + '_') if side else ''}{part}_{js.name}"
        j.type = mujoco.mjtJoint.mjJNT_HINGE
        j.axis = list(axis)
        j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        j.range = [np.deg2rad(lo), np.deg2rad(hi)]
        # Armature and damping scale with the joint's gain: they regularise
        # the light distal segments so the default timestep stays stable.
        j.armature = max(0.01, js.kp * 1e-4)
        j.damping = [max(0.5, js.kp * 0.01), 0.0, 0.0]
        actuated.append((j.name, js.kp))


def _child(parent: mujoco.MjsBody, name: str, at: Sequence[float]) -> mujoco.MjsBody:
    """A new body ``name`` in ``parent`` at offset ``at`` (metres, parent frame)."""
    b = parent.add_body()
    b.name = name
    b.pos = list(np.asarray(at, float))
    return b


def _add_trunk(spec: mujoco.MjSpec, d: BodyDimensions, prefix: str, pos: Sequence[float],
               actuated: list[tuple[str, float]]) -> tuple[mujoco.MjsBody, mujoco.MjsBody]:
    """Pelvis (free joint) to head; returns ``(pelvis, chest)``, where the legs
    and the clavicles attach."""
    g = d.girth
    pelvis = _child(spec.worldbody, prefix + "pelvis",
                    np.asarray(pos, float) + [0, 0, d.hip_height])
    fj = pelvis.add_freejoint()
    fj.name = prefix + "root"
    _site(pelvis, prefix + "pelvis", (0, 0, 0))
    hl, hr = np.asarray(d.left_hip_offset), np.asarray(d.right_hip_offset)
    _capsule(pelvis, hl + [0, -0.02, 0.02], hr + [0, 0.02, 0.02], 0.085 * g, prefix + "pelvis")
    for s in _SIDES:
        _site(pelvis, f"{prefix}{s}_hip", getattr(d, f"{s}_hip_offset"))

    pivot = np.asarray(d.lumbar_offset, dtype=float)
    lumbar = _child(pelvis, prefix + "lumbar", pivot)
    _joints(lumbar, "lumbar", None, prefix, actuated)
    if d.spine_on_pelvis:
        # The lower back up to the lumbar joint is part of the rigid pelvis.
        _capsule(pelvis, (0, 0, 0.03 * g), pivot, 0.09 * g, prefix + "lower_back")
        _capsule(lumbar, (0, 0, 0), (0, 0, d.lumbar), 0.09 * g, prefix + "lumbar")
        _site(pelvis, prefix + "spine", pivot)
    else:
        _capsule(lumbar, (0, 0, 0.03 * g), (0, 0, d.lumbar), 0.09 * g, prefix + "lumbar")
        _site(lumbar, prefix + "spine", (0, 0, d.lumbar))
    thorax = _child(lumbar, prefix + "thorax", (0, 0, d.lumbar))
    _joints(thorax, "thorax", None, prefix, actuated)
    _capsule(thorax, (0, 0, 0), (0, 0, d.thorax), 0.1 * g, prefix + "thorax")
    _site(thorax, prefix + "chest", (0, 0, d.thorax))
    chest = _child(thorax, prefix + "chest", (0, 0, d.thorax))
    _joints(chest, "chest", None, prefix, actuated)
    cw = 0.55 * min(d.left_clavicle, d.right_clavicle)
    cz = max(d.clavicle_pivot - 0.07 * g, 0.04 * g)
    _capsule(chest, (0, cw, cz), (0, -cw, cz), 0.11 * g, prefix + "chest")
    _site(chest, prefix + "neck", (0, 0, d.upper_chest))
    neck = _child(chest, prefix + "neck", (0, 0, d.upper_chest))
    _joints(neck, "neck", None, prefix, actuated)
    head_at = d.neck * np.asarray(d.rest.head_direction)
    _capsule(neck, (0, 0, 0), head_at, 0.045 * g, prefix + "neck", _SKIN)
    _site(neck, prefix + "head", head_at)
    head = _child(neck, prefix + "head", head_at)
    # The skull sits along the neck -> head keypoint line, wherever the source puts it.
    head.quat = _quat_between((0.0, 0.0, 1.0), d.rest.head_direction)
    _capsule(head, (0.02 * g, 0, 0.07 * g), (0.02 * g, 0, 0.07 * g), d.head_radius,
             prefix + "head", _SKIN)
    return pelvis, chest


def _quat_between(a: Sequence[float], b: Sequence[float]) -> list[float]:
    """(w, x, y, z) of the smallest rotation taking unit ``a`` onto unit ``b`` (not
    opposite); the identity, exactly, when they are equal."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    q = np.array([1.0 + a @ b, *np.cross(a, b)])
    return (q / np.linalg.norm(q)).tolist()


def _add_arm(chest: mujoco.MjsBody, d: BodyDimensions, s: str, prefix: str,
             actuated: list[tuple[str, float]]) -> None:
    """Clavicle, upper arm, forearm and hand of side ``s``."""
    g = d.girth
    p = f"{prefix}{s}_"
    sy = 1.0 if s == "left" else -1.0
    clav = _child(chest, p + "clavicle", (0, 0, d.clavicle_pivot))
    _joints(clav, "clavicle", s, prefix, actuated)
    cl = getattr(d, f"{s}_clavicle")
    _capsule(clav, (0, sy * 0.3 * cl, 0), (0, sy * 0.85 * cl, 0), 0.045 * g, p + "clavicle")
    _site(clav, p + "shoulder", _clavicle_dir(s) * cl)
    ua = _child(clav, p + "upper_arm", _clavicle_dir(s) * cl)
    ua.quat = _arm_quat(s)
    _joints(ua, "upper_arm", s, prefix, actuated)
    lu = getattr(d, f"{s}_upper_arm")
    _capsule(ua, (0, 0, -0.05 * lu), (0, 0, -lu), 0.042 * g, p + "upper_arm")
    _site(ua, p + "elbow", (0, 0, -lu))
    fa = _child(ua, p + "forearm", (0, 0, -lu))
    _joints(fa, "forearm", s, prefix, actuated)
    lf = getattr(d, f"{s}_forearm")
    _capsule(fa, (0, 0, 0), (0, 0, -lf), 0.034 * g, p + "forearm", _SKIN)
    _site(fa, p + "wrist", (0, 0, -lf))
    hand = _child(fa, p + "hand", (0, 0, -lf))
    _joints(hand, "hand", s, prefix, actuated)
    lh = getattr(d, f"{s}_hand")
    hl_geo = max(lh, 0.09 * d.scale)
    _box(hand, (0, 0, -0.55 * hl_geo), (0.045 * g, 0.017 * g, 0.55 * hl_geo), p + "hand", _SKIN)
    _site(hand, p + "hand", (0, 0, -lh))


def _add_leg(pelvis: mujoco.MjsBody, d: BodyDimensions, s: str, prefix: str,
             actuated: list[tuple[str, float]]) -> None:
    """Thigh, shin, foot and toes of side ``s``."""
    g = d.girth
    p = f"{prefix}{s}_"
    thigh = _child(pelvis, p + "thigh", np.asarray(getattr(d, f"{s}_hip_offset")))
    _joints(thigh, "thigh", s, prefix, actuated)
    # The knee hinge sits on the hip-ankle line; the keypoint may sit off it along the
    # hinge axis (the source's rest geometry), where flexion does not move it.
    lt, ls = d.leg_line(s)
    _capsule(thigh, (0, 0, -0.08 * lt), (0, 0, -lt), 0.066 * g, p + "thigh")
    _site(thigh, p + "knee", _knee_site(d, s))
    shin = _child(thigh, p + "shin", (0, 0, -lt))
    _joints(shin, "shin", s, prefix, actuated)
    _capsule(shin, (0, 0, -0.02), (0, 0, -ls + 0.04 * g), 0.045 * g, p + "shin")
    _site(shin, p + "ankle", (0, 0, -ls))
    foot = _child(shin, p + "foot", (0, 0, -ls))
    _joints(foot, "foot", s, prefix, actuated)
    toe = _foot_vector(d, s)
    sole = -d.ankle_height
    top = min(0.0, sole + 0.06 * g)
    half_w = d.foot_width / 2
    x0, x1 = -d.heel_length, toe[0]
    _box(foot, ((x0 + x1) / 2, 0, (sole + top) / 2), ((x1 - x0) / 2, half_w, (top - sole) / 2),
         p + "foot")
    _site(foot, p + "toe", toe)
    toes = _child(foot, p + "toes", toe)
    _joints(toes, "toes", s, prefix, actuated)
    tsole = -d.toe_height
    ttop = tsole + 0.025 * g
    _box(toes, (d.toes_length / 2, 0, (tsole + ttop) / 2),
         (d.toes_length / 2, half_w, (ttop - tsole) / 2), p + "toes")


def _add_actuators(spec: mujoco.MjSpec, pelvis: mujoco.MjsBody,
                   actuated: list[tuple[str, float]]) -> None:
    """One position servo per hinge of ``actuated`` (name, kp), in the compiled
    joint order (depth-first over the bodies below ``pelvis``), so that
    ctrl[i] drives the i-th hinge of the person."""
    rank: dict[str, int] = {}

    def visit(b: mujoco.MjsBody) -> None:
        rank[b.name] = len(rank)
        for c in b.bodies:
            visit(c)

    visit(pelvis)
    body_of = {j.name: j.parent.name for j in spec.joints}
    for jname, kp in sorted(actuated, key=lambda item: rank[body_of[item[0]]]):
        a = spec.add_actuator()
        a.name = jname
        a.target = jname
        a.trntype = mujoco.mjtTrn.mjTRN_JOINT
        a.set_to_position(kp=kp, kv=0.1 * kp, inheritrange=1.0)
        a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        a.forcerange = [-2.0 * kp, 2.0 * kp]


def add_person(spec: mujoco.MjSpec, d: BodyDimensions, prefix: str,
               pos: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
    """Add one humanoid (bodies, joints, sites, exclusions, actuators) to ``spec``."""
    actuated: list[tuple[str, float]] = []
    pelvis, chest = _add_trunk(spec, d, prefix, pos, actuated)
    for s in _SIDES:  # arm then leg per side: the order the bodies are added in
        _add_arm(chest, d, s, prefix, actuated)
        _add_leg(pelvis, d, s, prefix, actuated)
    _exclude_neighbours(spec, prefix)
    _add_actuators(spec, pelvis, actuated)


def _exclude_neighbours(spec: mujoco.MjSpec, prefix: str) -> None:
    """Exclude contacts between bodies at tree distance <= 2 (MuJoCo already
    filters parent-child pairs): siblings and grandparents overlap at rest."""
    bodies = [b for b in spec.bodies if b.name.startswith(prefix) and b.name != "world"]
    parent = {b.name: b.parent.name for b in bodies}
    names = list(parent)
    chain = {n: [n, parent[n], parent.get(parent[n], "")] for n in names}
    seen = set()
    for a in names:
        for b in names:
            if a >= b:
                continue
            pa, pb = chain[a], chain[b]
            close = (pa[1] == pb[1] or pa[2] == b or pb[2] == a)
            if close and (a, b) not in seen:
                seen.add((a, b))
                e = spec.add_exclude()
                e.bodyname1, e.bodyname2 = a, b


def new_spec(name: str) -> mujoco.MjSpec:
    """An empty scene named ``name``: the simulation options every body here is simulated
    with (2 ms implicit-fast steps, radians) and the floor plane."""
    spec = mujoco.MjSpec()
    spec.modelname = name
    spec.option.timestep = 0.002
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.compiler.degree = False
    wb = spec.worldbody
    floor = wb.add_geom()
    floor.name = "floor"
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.size = [0, 0, 0.05]
    floor.rgba = [0.55, 0.55, 0.5, 1]
    floor.contype, floor.conaffinity = 1, 1
    light = wb.add_light()
    light.name = "sun"
    light.pos = [0, 0, 4]
    light.dir = [0, 0.2, -1]
    light.castshadow = True
    light.diffuse = [0.7, 0.7, 0.7]
    return spec


# ---------------------------------------------------------------------------
# Humanoid and Scene
# ---------------------------------------------------------------------------


class Humanoid:
    """A compiled single-person humanoid built from :class:`BodyDimensions`.

    Attributes:
        dims: the measurements it was built from.
        spec: the :class:`mujoco.MjSpec` (floor and light included).
        model: the compiled :class:`mujoco.MjModel`.
        keypoint_names: canonical keypoint names, one site each.
        site_ids: (K,) site ids of the keypoints in ``model``.
        joint_names: hinge joint names in qpos order (after the 7 free-joint
            coordinates: position x y z, quaternion w x y z).
        joint_limits: (nhinge, 2) radians.
        hinge_qpos: (nhinge,) qpos addresses of the hinges.
        total_mass: kg.
    """

    def __init__(self, dims: BodyDimensions | None = None, name: str = "humanoid") -> None:
        self.dims = dims or DEFAULT
        self.name = name
        self.spec = new_spec(name)
        add_person(self.spec, self.dims, "")
        try:
            self.model = self.spec.compile()
        except ValueError as exc:  # MuJoCo compile errors are ValueError
            raise RetargetError(f"could not build the humanoid: {exc}") from None
        m = self.model
        self.keypoint_names: tuple[str, ...] = CANONICAL_KEYPOINTS
        self.site_ids = np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, k)
                                  for k in self.keypoint_names])
        hinges = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
        self.joint_names: tuple[str, ...] = tuple(m.joint(j).name for j in hinges)
        self.joint_limits = m.jnt_range[hinges].copy()
        self.hinge_qpos = m.jnt_qposadr[hinges].copy()
        self.total_mass = float(m.body_subtreemass[0])

    @property
    def nq(self) -> int:
        return int(self.model.nq)

    @property
    def nv(self) -> int:
        return int(self.model.nv)

    @cached_property
    def _data(self) -> mujoco.MjData:
        return mujoco.MjData(self.model)

    def default_qpos(self) -> np.ndarray:
        """(nq,) rest pose: standing on the floor, all hinges 0."""
        return self.model.qpos0.copy()

    def keypoints(self, qpos: np.ndarray) -> np.ndarray:
        """Keypoint positions for one (nq,) or many (T, nq) configurations.

        Returns:
            (K, 3) or (T, K, 3) float64 metres, in :attr:`keypoint_names` order.
        """
        q = np.asarray(qpos, dtype=float)
        single = q.ndim == 1
        q = q.reshape(-1, self.nq)
        if not np.all(np.isfinite(q)):
            raise RetargetError("qpos contains NaN/inf; refusing to pass it to MuJoCo")
        out = np.empty((len(q), len(self.site_ids), 3))
        d = self._data
        for t, qt in enumerate(q):
            d.qpos[:] = qt
            mujoco.mj_kinematics(self.model, d)
            out[t] = d.site_xpos[self.site_ids]
        return out[0] if single else out

    def __repr__(self) -> str:
        return (f"Humanoid(height={self.dims.height:.3f} m, mass={self.total_mass:.1f} kg, "
                f"nq={self.nq})")


@dataclass
class Scene:
    """Several humanoids in one MjModel, names prefixed per person (``"p0/"``...).

    Attributes:
        spec, model: the combined MjSpec and compiled model (one floor, one light).
        names: person names; ``prefixes[i] = names[i] + "/"``.
        humanoids: the single-person humanoids (their qpos layouts match the
            slices below one to one).
        qpos_slices, qvel_slices: per-person slices into the scene's qpos / qvel.
        ctrl_slices: per-person slices into ctrl (actuators, same order as
            the person's hinges).
        site_ids: (P, K) keypoint site ids per person.
    """

    spec: mujoco.MjSpec
    model: mujoco.MjModel
    names: tuple[str, ...]
    humanoids: tuple[Humanoid, ...]
    qpos_slices: tuple[slice, ...]
    qvel_slices: tuple[slice, ...]
    ctrl_slices: tuple[slice, ...]
    site_ids: np.ndarray

    @property
    def prefixes(self) -> tuple[str, ...]:
        return tuple(f"{n}/" for n in self.names)

    def combine_qpos(self, per_person: Sequence[np.ndarray]) -> np.ndarray:
        """Stack per-person (T, nq_i) trajectories into the scene's (T, nq)."""
        if len(per_person) != len(self.humanoids):
            raise RetargetError(f"{len(per_person)} trajectories for "
                                f"{len(self.humanoids)} people")
        t = per_person[0].shape[0]
        out = np.tile(self.model.qpos0, (t, 1))
        for sl, q in zip(self.qpos_slices, per_person, strict=True):
            out[:, sl] = q
        return out


def build_scene(humanoids: Sequence[Humanoid], names: Sequence[str] | None = None) -> Scene:
    """Put several humanoids into one model (shared floor and light).

    Args:
        humanoids: the people, each with its own :class:`BodyDimensions`.
        names: one unique name per person (default ``p0``, ``p1``, ...); body,
            joint, site and actuator names get the prefix ``name + "/"``.
    """
    names = tuple(names) if names is not None else tuple(f"p{i}" for i in range(len(humanoids)))
    if len(names) != len(humanoids) or len(set(names)) != len(names) or not humanoids:
        raise RetargetError(f"need one unique name per humanoid; got {list(names)} for "
                            f"{len(humanoids)} humanoid(s)")
    spec = new_spec("scene")
    for i, (h, n) in enumerate(zip(humanoids, names, strict=True)):
        add_person(spec, h.dims, f"{n}/", pos=(0.0, 1.0 * i, 0.0))
    try:
        model = spec.compile()
    except ValueError as exc:
        raise RetargetError(f"could not build the scene: {exc}") from None
    qs, vs, cs, sites = [], [], [], []
    for h, n in zip(humanoids, names, strict=True):
        root = model.joint(f"{n}/root")
        qa, va = int(root.qposadr[0]), int(root.dofadr[0])
        qs.append(slice(qa, qa + h.nq))
        vs.append(slice(va, va + h.nv))
        a0 = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{n}/{h.joint_names[0]}")
        cs.append(slice(a0, a0 + h.model.nu))
        sites.append([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{n}/{k}")
                      for k in h.keypoint_names])
    return Scene(spec, model, names, tuple(humanoids), tuple(qs), tuple(vs), tuple(cs),
                 np.array(sites))


# ---------------------------------------------------------------------------
# Fitting to a motion
# ---------------------------------------------------------------------------

#: Keypoints without which the body frame cannot be measured.
REQUIRED_FOR_FIT = ("pelvis", "left_hip", "right_hip")

#: A pelvis keypoint closer than this to the hip line (median, metres) does not
#: give the pelvis frame its z axis (:func:`pelvis_frames`).
PELVIS_OFF_HIP_LINE = 0.02

#: Most the spine keypoint may move in the pelvis frame (95th percentile of its
#: distance from its median position there, metres) for the fit to take it as
#: rigid on the pelvis (:attr:`BodyDimensions.spine_on_pelvis`). Measured: a
#: joint fixed in the pelvis's frame moves <= 0.002 mm (HumanML3D 012314 and
#: 000612: SMPL ``spine1``; the Rokoko/Mixamo, 27-joint BVH and Xsens MVN samples
#: of tests/data/conventions), the end of a lumbar that turns at the pelvis
#: keypoint >= 8.1 mm on every shared CMU clip (walks 8-13 mm, 12_01 the least)
#: and 19.5 mm on the NTU Kinect v2 clip. Half the least moving one.
RIGID_SPINE_SPREAD = 0.004

#: Skeletons whose rigid spine keypoint is taken as the lumbar joint: the body models,
#: where it was measured to help (HumanML3D 012314: limited-fit residual p95 41 -> 26 mm,
#: joint_limits 47.7 -> 8.3 deg). Not the Poser/Second-Life template, whose ``abdomen`` is
#: as rigid on ``hip``: there it raised the salsa pair's retargeting residuals from 0.2 mm
#: to 42-52 mm (mean) and the root residual from 0.08-0.19 to 0.72-1.09 body weights.
RIGID_SPINE_SKELETONS: frozenset[str] = frozenset({"smpl22", "kit21"})


def _hip_axis_and_up(pelvis: np.ndarray, lhip: np.ndarray, rhip: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(T, 3) unit right -> left hip axis and (T, 3) hip midpoint -> pelvis
    keypoint orthogonal to it (metres)."""
    y = lhip - rhip
    y = y / np.maximum(np.linalg.norm(y, axis=-1, keepdims=True), 1e-9)
    u = pelvis - (lhip + rhip) / 2
    return y, u - np.sum(u * y, axis=-1, keepdims=True) * y


def _pelvis_off_hip_line(u: np.ndarray) -> bool:
    """Whether the pelvis keypoint (``u`` of :func:`_hip_axis_and_up`) is off the
    hip line, so that it gives the pelvis frame its z axis."""
    return bool(np.median(np.linalg.norm(u, axis=-1)) >= PELVIS_OFF_HIP_LINE)


def pelvis_frames(pelvis: np.ndarray, lhip: np.ndarray, rhip: np.ndarray,
                  spine: np.ndarray | None = None) -> np.ndarray:
    """Per-frame orthonormal frame of the pelvis triangle, before the tilt fix.

    y points from the right to the left hip, z from the hip midpoint to the
    pelvis keypoint (orthogonalised), x = y x z. When the pelvis keypoint lies
    on the hip line (e.g. H36M) z comes from the spine keypoint, else world up.

    Args:
        pelvis, lhip, rhip: (T, 3). spine: optional (T, 3).
    Returns:
        (T, 3, 3) rotation matrices (columns = axes in world coordinates).
    """
    y, u = _hip_axis_and_up(pelvis, lhip, rhip)
    if not _pelvis_off_hip_line(u):
        u = (spine - pelvis) if spine is not None else np.broadcast_to([0.0, 0, 1], y.shape)
        u = u - np.sum(u * y, axis=-1, keepdims=True) * y
    z = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-9)
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=-1)


def _rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


#: Most a shod foot's toe keypoint may sit above the anthropometric (barefoot)
#: value, metres: the forefoot sole of a regular shoe (forefoot stack up to
#: ~30 mm: running shoes' heel stack 9-35 mm minus a 0-12 mm heel-toe drop,
#: RunRepeat's lab measurements) plus the offset of a keypoint solved from a
#: toe marker on the shoe's upper (~9 mm from the surface for a 14 mm sphere
#: on a ~2 mm base: an assumption, no source gives CMU's marker size). CMU
#: subjects' planted balls sit 34-46 mm above
#: the floor, a few 57-68 mm (01_01, 131_03, 55_02).
SHOD_TOE_ALLOWANCE = 0.04


def _foot_heights(motion: Motion, kp: Mapping[str, np.ndarray],
                  scale: float) -> tuple[float, float]:
    """Toe height above the sole and ankle-over-toe drop of the neutral foot, metres.

    The floor is z = 0 (readers put it there). A rigid foot standing flat has
    its ankle keypoint ``drop`` above its toe keypoint, so:

    * ``drop`` is measured within frames, as the median of ``z_ankle - z_toe``
      over the frames a foot is planted (:func:`simenv.body.foot_contact.foot_contacts`:
      low and slow): a loaded foot is flat for most of its stance, the
      assumption a gait lab's static calibration makes ("foot flat").
    * The sole offset then has two estimates, one per keypoint: the 2nd
      percentile of the toe heights ``t2`` (the ball on the floor) and that
      of the ankle heights less the drop, ``a2 - drop`` (the heel on the
      floor). For a rigid foot they agree; where the data's foot keypoints
      disagree between loaded frames (CMU 131_04: the ball 4-5 cm higher
      relative to the ankle in its quiet stances than in its single stances)
      the fit takes the least-squares value of the one offset, their mean
      ``toe_height = (t2 + a2 - drop) / 2``.

    ``toe_height`` is kept within 0.6x the scaled anthropometric value and
    that value plus :data:`SHOD_TOE_ALLOWANCE` (clips whose floor is off
    z = 0 would otherwise give absurd soles), ``drop`` within 0.3-1x the
    scaled ankle height. Without toe keypoints the anthropometric values are
    used; without a planted frame the drop is the difference of the two
    percentiles (the two estimates then agree).
    """
    toe_default = DEFAULT.toe_height * scale
    ankle_default = DEFAULT.ankle_height * scale
    low = {}
    for key in ("ankle", "toe"):
        zs = [kp[f"{s}_{key}"][:, 2] for s in _SIDES if f"{s}_{key}" in kp]
        low[key] = float(np.percentile(np.concatenate(zs), 2)) if zs else None
    if low["toe"] is None:
        return toe_default, ankle_default - toe_default
    if low["ankle"] is None:
        return float(np.clip(low["toe"], 0.6 * toe_default,
                             toe_default + SHOD_TOE_ALLOWANCE)), ankle_default - toe_default
    feet, planted = foot_contacts(motion)
    drops = [kp[f"{s}_ankle"][planted[:, feet.index(f"{s}_toe")], 2]
             - kp[f"{s}_toe"][planted[:, feet.index(f"{s}_toe")], 2]
             for s in _SIDES if f"{s}_toe" in feet and f"{s}_ankle" in kp]
    both = np.concatenate(drops) if drops else np.zeros(0)
    drop = float(np.median(both)) if both.size else low["ankle"] - low["toe"]
    drop = float(np.clip(drop, 0.3 * ankle_default, ankle_default))
    toe_h = 0.5 * (low["toe"] + low["ankle"] - drop)
    return float(np.clip(toe_h, 0.6 * toe_default, toe_default + SHOD_TOE_ALLOWANCE)), drop


#: Body dimension -> the two keypoints whose median distance measures it.
_BONE_KEYPOINTS: dict[str, tuple[str, str]] = {
    "lumbar": ("pelvis", "spine"), "thorax": ("spine", "chest"),
    "upper_chest": ("chest", "neck"), "neck": ("neck", "head"),
    **{k: v for s in _SIDES for k, v in {
        f"{s}_upper_arm": (f"{s}_shoulder", f"{s}_elbow"),
        f"{s}_forearm": (f"{s}_elbow", f"{s}_wrist"),
        f"{s}_hand": (f"{s}_wrist", f"{s}_hand"),
        f"{s}_thigh": (f"{s}_hip", f"{s}_knee"),
        f"{s}_shin": (f"{s}_knee", f"{s}_ankle"),
        f"{s}_foot": (f"{s}_ankle", f"{s}_toe")}.items()},
}


def _median_distance(kp: Mapping[str, np.ndarray], a: str, b: str) -> float | None:
    """Median over frames of the distance between keypoints ``a`` and ``b``
    (metres), None when either is missing."""
    if a in kp and b in kp:
        return float(np.median(np.linalg.norm(kp[a] - kp[b], axis=-1)))
    return None


def _rigid_spine(kp: Mapping[str, np.ndarray], s_loc: np.ndarray) -> bool:
    """Whether the spine keypoint, at ``s_loc`` (T, 3) in the pelvis frame, is
    rigid on the pelvis (:data:`RIGID_SPINE_SPREAD`). Only testable when the
    pelvis keypoint is off the hip line: on it the spine gives the frame its z
    axis, so it is still in that frame whatever the lumbar does."""
    if not _pelvis_off_hip_line(_hip_axis_and_up(kp["pelvis"], kp["left_hip"],
                                                 kp["right_hip"])[1]):
        return False
    spread = np.linalg.norm(s_loc - np.median(s_loc, axis=0), axis=-1)
    return bool(np.percentile(spread, 95) <= RIGID_SPINE_SPREAD)


def rest_trunk(motion: Motion) -> dict[str, np.ndarray] | None:
    """The rest pose's pelvis, hips, spine and trunk-top keypoints (each (1, 3), metres)
    when ``motion``'s spine keypoint is rigid on its pelvis by construction, else None.

    A source whose positions are forward kinematics of fixed offsets (BVH and ASF/AMC:
    ``metadata["offsets_m"]``) carries a joint that is the pelvis joint's own child
    along with the pelvis: its position is the pelvis's transform applied to a
    constant offset. When the canonical spine is such a child, the rest pose (every
    rotation zero: positions are the summed offsets) tells where the rig's trunk
    stands relative to that offset. The trunk top is the chest keypoint, else the neck.
    """
    sk, meta = motion.skeleton, motion.metadata
    c = sk.canonical
    top = "chest" if "chest" in c else "neck"
    if "offsets_m" not in meta or not {"pelvis", "left_hip", "right_hip", "spine", top} <= c.keys():
        return None
    if sk.parents[sk.index(c["spine"])] != sk.index(c["pelvis"]):
        return None
    offsets = np.asarray(meta["offsets_m"], dtype=np.float64)
    if offsets.shape != (len(sk.joint_names), 3):
        return None
    rest = np.zeros_like(offsets)
    for j, parent in enumerate(sk.parents):
        rest[j] = offsets[j] + (rest[parent] if parent >= 0 else 0.0)
    keys = ("pelvis", "left_hip", "right_hip", "spine")
    out = {k: rest[None, sk.index(c[k])] for k in keys}
    out["top"] = rest[None, sk.index(c[top])]
    return out


def _rest_trunk_tilt(rest: Mapping[str, np.ndarray]) -> float:
    """Angle about the hip axis (radians) from the spine keypoint's direction to the rest
    pose's pelvis -> trunk-top direction, in the pelvis frame the spine gives
    (:func:`pelvis_frames` with the pelvis keypoint on the hip line)."""
    R = pelvis_frames(rest["pelvis"], rest["left_hip"], rest["right_hip"], rest["spine"])[0]
    top = R.T @ (rest["top"][0] - rest["pelvis"][0])
    return float(np.arctan2(top[0], top[2]))


def _pelvis_offsets(kp: Mapping[str, np.ndarray], body_model: bool,
                    rest: Mapping[str, np.ndarray] | None = None
                    ) -> dict[str, tuple[float, float, float]]:
    """``left_hip_offset`` / ``right_hip_offset``: median hip positions in the
    pelvis frame (metres), and ``lumbar_offset``.

    On a body model's skeleton (``body_model``, :data:`RIGID_SPINE_SKELETONS`), a
    spine keypoint rigid on the pelvis (:func:`_rigid_spine`) is the lumbar
    joint: ``lumbar_offset`` is its median position and the frame stays the
    pelvis triangle's, so the zero of the trunk and hip angles is fixed to the
    pelvis rather than to that joint's offset (SMPL's ``spine1`` sits 17-25 deg
    behind the pelvis keypoint's line; tilted by it, SMPL's zero pose read 21
    deg of hip extension and 22 of thorax flexion; untilted, 4 and 4).

    With the pelvis keypoint on the hip line the frame's z axis comes from the
    spine keypoint, so its rigidity cannot be measured; ``rest`` (:func:`rest_trunk`)
    says it from the source's hierarchy. Such a spine is the lumbar joint too, and
    the frame is rotated about the hip axis so that the rest pose's trunk is +z: the
    offset of a rig's first spine joint is a design choice, not the trunk's line (a
    FAIR capture rig's lies 34 deg off it; taken as the trunk, a standing child read
    34 deg of thorax flexion).

    Otherwise the frame is rotated about the hip axis
    so that the median spine direction is +z, and ``lumbar_offset`` is zero."""
    R = pelvis_frames(kp["pelvis"], kp["left_hip"], kp["right_hip"], kp.get("spine"))
    out: dict[str, tuple[float, float, float]] = {}
    tilt = 0.0
    if "spine" in kp:
        s_loc = np.einsum("tji,tj->ti", R, kp["spine"] - kp["pelvis"])
        on_hip_line = not _pelvis_off_hip_line(
            _hip_axis_and_up(kp["pelvis"], kp["left_hip"], kp["right_hip"])[1])
        if body_model and _rigid_spine(kp, s_loc):
            out["lumbar_offset"] = _v(np.median(s_loc, axis=0))
        elif rest is not None and on_hip_line:
            tilt = _rest_trunk_tilt(rest)
            out["lumbar_offset"] = _v(np.median(s_loc, axis=0) @ _rot_y(tilt))
        else:
            tilt = float(np.arctan2(np.median(s_loc[:, 0]), np.median(s_loc[:, 2])))
    R = R @ _rot_y(tilt)
    for s in _SIDES:
        out[f"{s}_hip_offset"] = _v(np.median(np.einsum("tji,tj->ti", R,
                                                         kp[f"{s}_hip"] - kp["pelvis"]), axis=0))
    return out


#: The straightest frames of a leg, on which the fit reads its knees' rest offset: those
#: whose knee keypoint lies nearest the hip-ankle line, up to this percentile of the
#: clip's distances.
STRAIGHT_LEG_PERCENTILE = 10.0

#: Smallest sideways knee offset the fit tells from zero, metres (a rigid skeleton's
#: straight leg is exactly straight; its joint centres carry float noise only).
KNEE_LATERAL_RESOLUTION = 0.001


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _knee_displacement(kp: Mapping[str, np.ndarray], side: str, R: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Sideways (outwards) and forward parts of the knee keypoint's displacement from
    the hip-ankle line on the leg's straightest frames (:data:`STRAIGHT_LEG_PERCENTILE`),
    metres, along the pelvis frame ``R`` (T, 3, 3) made normal to the leg."""
    hip, knee, ankle = (kp[f"{side}_{k}"] for k in ("hip", "knee", "ankle"))
    sign = 1.0 if side == "left" else -1.0
    thigh, down = knee - hip, _unit(ankle - hip)
    off = thigh - np.sum(thigh * down, axis=-1, keepdims=True) * down
    out = R[:, :, 1] * sign
    out = _unit(out - np.sum(out * down, axis=-1, keepdims=True) * down)
    fwd = np.cross(down, out) * sign
    dist = np.linalg.norm(off, axis=-1)
    straight = dist <= np.percentile(dist, STRAIGHT_LEG_PERCENTILE)
    return np.sum(off * out, axis=-1)[straight], np.sum(off * fwd, axis=-1)[straight]


def _knee_lateral(kp: Mapping[str, np.ndarray], R: np.ndarray) -> float:
    """The knees' sideways rest offset from the hip-ankle line, metres (outwards
    positive), or 0 when the clip shows none.

    A knee bends forwards: a hinge puts the knee keypoint in front of its hip-ankle
    line, never beside it. So on each leg's straightest frames (the knee nearest the
    line, :func:`_knee_displacement`) the displacement is split along the pelvis frame
    ``R`` (T, 3, 3) into a forward part (flexion: pose) and a sideways part. When the
    sideways part's median over both legs exceeds the forward part's (by
    :data:`KNEE_LATERAL_RESOLUTION`), the legs are straighter than the sideways offset
    lets them be, and that median is the skeleton's offset (the skeleton is taken as
    symmetric: one value for both knees, read over both legs' frames). Measured: SMPL
    clips with straight legs (HumanML3D 007005, 000021, M010968) 29-40 mm sideways
    against a forward part under 35 mm; every shared CMU clip's straightest frames are
    bent forwards (the sideways part -22 to +23 mm, at most a third of the forward part)
    or exactly straight: 0."""
    lateral, forward = [], []
    for s in _SIDES:
        if all(f"{s}_{k}" in kp for k in ("hip", "knee", "ankle")):
            lat, fwd = _knee_displacement(kp, s, R)
            lateral.append(lat)
            forward.append(fwd)
    if not lateral:
        return 0.0
    lat, fwd = float(np.median(np.concatenate(lateral))), float(np.median(np.concatenate(forward)))
    if abs(lat) <= abs(fwd) + KNEE_LATERAL_RESOLUTION:
        return 0.0
    return float(np.clip(lat, -KNEE_LATERAL_MAX, KNEE_LATERAL_MAX))


#: Shortest chest -> neck and neck -> head distances (median, metres) from which the fit
#: reads the head keypoint's rest direction (:func:`_head_direction`).
HEAD_FRAME_MIN = 0.01


def _head_direction(kp: Mapping[str, np.ndarray]) -> tuple[float, float, float]:
    """The neck -> head keypoint's rest direction in the chest frame (z along chest ->
    neck, y along the shoulder line): its median over the clip.

    The head's last keypoint carries no face direction, so nothing in one frame tells a
    head keypoint the skeleton puts forward of the neck (SMPL's: 33-58 deg forward of
    the chest -> neck line, median over a clip, on upright trunks) from a head bowed.
    The clip's median head direction is taken as its neutral; the neck's hinges are
    judged from it. Straight on (0, 0, 1) without chest, neck, head and both shoulders,
    or when the chest and neck or the neck and head coincide."""
    need = ("chest", "neck", "head", "left_shoulder", "right_shoulder")
    if not all(k in kp for k in need):
        return (0.0, 0.0, 1.0)
    up, head = kp["neck"] - kp["chest"], kp["head"] - kp["neck"]
    if min(np.median(np.linalg.norm(up, axis=-1)),
           np.median(np.linalg.norm(head, axis=-1))) < HEAD_FRAME_MIN:
        return (0.0, 0.0, 1.0)
    z = _unit(up)
    y = kp["left_shoulder"] - kp["right_shoulder"]
    y = _unit(y - np.sum(y * z, axis=-1, keepdims=True) * z)
    frame = np.stack([np.cross(y, z), y, z], axis=-1)
    d = np.median(np.einsum("tji,tj->ti", frame, _unit(head)), axis=0)
    return _v(d / np.linalg.norm(d)) if d[2] > 0 else (0.0, 0.0, 1.0)


def _rest_geometry(kp: Mapping[str, np.ndarray]) -> RestGeometry:
    """The source skeleton's rest geometry measured from the clip (:class:`RestGeometry`):
    the knees' sideways offset (:func:`_knee_lateral`; from the legs with hip, knee and
    ankle) and the head's direction (:func:`_head_direction`)."""
    R = pelvis_frames(kp["pelvis"], kp["left_hip"], kp["right_hip"], kp.get("spine"))
    knee = _knee_lateral(kp, R)
    return RestGeometry(left_knee_lateral=knee, right_knee_lateral=knee,
                        head_direction=_head_direction(kp))


def _split_trunk(measured: dict[str, float]) -> None:
    """A spine rigid on the pelvis: the source bends its lumbar and lower
    thorax at that one keypoint, and nothing it measures tells how the bend
    splits between them (two joints a distance apart would have to fold to
    reach a chest at a constant distance). So the lumbar gets zero length: the
    thorax joint sits at the lumbar joint, the thorax spans the measured
    spine -> chest distance, and the bend is shared by both joints' ranges, as
    on a skeleton whose lumbar turns at the pelvis keypoint."""
    measured["lumbar"] = 0.0


def _derive_chest(kp: dict[str, np.ndarray], measured: dict[str, float]) -> bool:
    """Layouts without a chest keypoint (H36M-like, Kinect, our 18-keypoint
    two-person layout): split the measured spine->neck distance into thorax
    and upper chest in the default proportion, and add the chest keypoint
    there to ``kp``. Scaling both from other bones instead gives a trunk that
    is too long or short, and the solver then bends the chest joints to their
    limits to reach the neck and shoulders (60 deg on the CMU walk 02_01).
    Returns whether the chest was derived."""
    if "chest" in kp or not {"spine", "neck"} <= kp.keys():
        return False
    total = _median_distance(kp, "spine", "neck")
    part = DEFAULT.thorax / (DEFAULT.thorax + DEFAULT.upper_chest)
    measured["thorax"], measured["upper_chest"] = part * total, (1 - part) * total
    kp["chest"] = kp["spine"] + part * (kp["neck"] - kp["spine"])
    return True


def _clavicle_fraction(kp: Mapping[str, np.ndarray]) -> float:
    """Where on the chest->neck segment (0-1) the shoulder distances vary least."""
    seg = kp["neck"] - kp["chest"]

    def spread(a: float) -> float:
        piv = kp["chest"] + a * seg
        return float(np.std(np.linalg.norm(kp["left_shoulder"] - piv, axis=-1))
                     + np.std(np.linalg.norm(kp["right_shoulder"] - piv, axis=-1)))

    grid = np.linspace(0.0, 1.0, 21)
    a = float(grid[np.argmin([spread(g) - 1e-6 * (g > 0) for g in grid])])
    for step in (0.025, 0.00125):  # two finer passes around the best
        fine = np.clip(a + step * np.arange(-20, 21), 0.0, 1.0)
        a = float(fine[np.argmin([spread(g) for g in fine])])
    return a


def _measure_clavicles(kp: Mapping[str, np.ndarray], measured: dict[str, float],
                       derived_chest: bool) -> None:
    """``clavicle_pivot`` and the clavicle lengths into ``measured``: the pivot
    on the chest->neck segment where the shoulder distances vary least
    (:func:`_clavicle_fraction`), or at the default fraction when the chest
    keypoint was derived (nothing to search along)."""
    if not {"chest", "neck", "left_shoulder", "right_shoulder"} <= kp.keys():
        return
    if derived_chest:
        a = DEFAULT.clavicle_pivot / DEFAULT.upper_chest
    else:
        a = _clavicle_fraction(kp)
    piv = kp["chest"] + a * (kp["neck"] - kp["chest"])
    measured["clavicle_pivot"] = a * measured["upper_chest"]
    for s in _SIDES:
        measured[f"{s}_clavicle"] = float(np.median(
            np.linalg.norm(kp[f"{s}_shoulder"] - piv, axis=-1)))


def _body_scale(measured: Mapping[str, float], hips: Mapping[str, object]) -> float:
    """Median ratio of the measured bones (and hip width) to the default
    adult's, within 0.5-1.5."""
    ratios = [measured[k] / getattr(DEFAULT, k) for k in measured
              if getattr(DEFAULT, k) > 0.05 and measured[k] > 0.02]
    hip_w = np.linalg.norm(np.subtract(hips["left_hip_offset"], hips["right_hip_offset"]))
    ratios.append(hip_w / np.linalg.norm(np.subtract(DEFAULT.left_hip_offset,
                                                      DEFAULT.right_hip_offset)))
    return float(np.clip(np.median(ratios), 0.5, 1.5))


def _lengths_or_default(measured: Mapping[str, float], scale: float
                        ) -> tuple[dict[str, float], list[str]]:
    """Every length of :class:`BodyDimensions` (not the offsets, girth or foot
    heights): measured, or the default adult's times ``scale``; and the names
    of the keypoint-measured lengths that fell back."""
    out, fallback = {}, []
    for f in fields(BodyDimensions):
        if f.name in ("notes", "girth", "rest") or f.name.endswith("_offset"):
            continue
        if f.name in measured:
            out[f.name] = measured[f.name]
        elif f.name not in ("ankle_height", "toe_height"):
            out[f.name] = getattr(DEFAULT, f.name) * scale
            if (f.name in _BONE_KEYPOINTS or f.name.endswith("clavicle")
                    or f.name == "clavicle_pivot"):
                fallback.append(f.name)
    return out, fallback


def _fit_notes(motion: Motion, num_frames: int, measured: Mapping[str, float],
               fallback: Sequence[str], scale: float, derived_chest: bool,
               spine_on_pelvis: bool, rest: RestGeometry, trunk_from_rest: bool
               ) -> tuple[str, ...]:
    """The fit's provenance and every fallback, for :attr:`BodyDimensions.notes`."""
    notes = [f"fitted to {motion.name!r} ({num_frames} frames, median over frames)"]
    knees = {s: getattr(rest, f"{s}_knee_lateral") for s in _SIDES}
    if any(knees.values()):
        notes.append("knee keypoints off the straight leg's line (the skeleton's rest "
                     "geometry): " + ", ".join(f"{s} {1000 * a:+.1f} mm outwards"
                                               for s, a in knees.items()))
    tilt = np.degrees(np.arctan2(rest.head_direction[0], rest.head_direction[2]))
    if abs(tilt) >= 1.0:
        notes.append(f"head keypoint {tilt:+.0f} deg forward of the neck's axis (the clip's "
                     "median, taken as the neutral head)")
    if spine_on_pelvis:
        notes.append("spine keypoint rigid on the pelvis: the lumbar and the thorax turn at it "
                     "(zero lumbar length)" + ("; the source's spine joint is its pelvis "
                                              "joint's child, and the trunk's zero is its rest "
                                              "pose's" if trunk_from_rest else ""))
    if fallback:
        notes.append(f"missing keypoints: {', '.join(fallback)} from the default adult scaled "
                     f"by {scale:.3f} (median measured/default bone ratio)")
    for s in _SIDES:
        if measured.get(f"{s}_hand", 1.0) < 0.01:
            notes.append(f"{s}_hand coincides with {s}_wrist in the source skeleton")
    if derived_chest:
        notes.append("no chest keypoint: thorax and upper chest split from the spine->neck "
                     "distance in the default proportion, clavicles measured from the "
                     "default pivot")
    if measured.get("upper_chest", 1.0) < 0.01:
        notes.append("neck coincides with chest in the source skeleton")
    return tuple(notes)


def fit_dimensions(motion: Motion) -> BodyDimensions:
    """Measure a subject's :class:`BodyDimensions` from its canonical keypoints.

    Lengths are medians over frames of keypoint distances; the hips' 3D
    offsets are medians in the pelvis frame (pelvis-hip-hip triangle, rotated
    about the hip axis so that the median spine direction is +z), so the rigid
    pelvis fits exactly. A spine keypoint that does not move in the pelvis
    frame is rigid on it: it becomes the lumbar joint
    (:attr:`BodyDimensions.lumbar_offset`; the frame is then not rotated), with
    the thorax joint at the same point (:func:`_split_trunk`). So does a spine
    joint that a BVH or ASF/AMC rig hangs from its pelvis joint when the pelvis
    keypoint lies on the hip line (:func:`rest_trunk`); the frame is then rotated
    so that the rig's rest-pose trunk is upright. The clavicle
    pivot is the point of the chest->neck segment whose distance to the
    shoulders varies least. Without a chest keypoint, the spine->neck distance
    is split into thorax and upper chest in the default proportion. Other
    keypoints the motion lacks fall back to the default adult scaled by the
    median ratio of the measured bones to the default ones; each fallback is
    recorded in ``notes``.
    """
    canon = motion.to_canonical()
    src = motion.metadata.get("source")
    names = canon.skeleton.joint_names
    missing = [k for k in REQUIRED_FOR_FIT if k not in names]
    if missing:
        raise RetargetError(f"cannot fit a body: motion {motion.name!r} lacks keypoint(s) "
                            f"{missing}; the pelvis and both hips are required", source=src)
    P = canon.positions.astype(np.float64)
    kp = {k: P[:, i] for i, k in enumerate(names)}
    body_model = motion.skeleton.name in RIGID_SPINE_SKELETONS
    rest_pose = None if body_model else rest_trunk(motion)
    ch: dict[str, object] = dict(_pelvis_offsets(kp, body_model=body_model, rest=rest_pose))
    measured = {name: v for name, (a, b) in _BONE_KEYPOINTS.items()
                if (v := _median_distance(kp, a, b)) is not None}
    derived_chest = _derive_chest(kp, measured)
    spine_on_pelvis = "lumbar_offset" in ch
    if spine_on_pelvis:
        _split_trunk(measured)
    _measure_clavicles(kp, measured, derived_chest)
    scale = _body_scale(measured, ch)
    lengths, fallback = _lengths_or_default(measured, scale)
    ch.update(lengths)
    toe_h, drop = _foot_heights(motion, kp, scale)
    ch["toe_height"], ch["ankle_height"] = toe_h, toe_h + drop
    ch["girth"] = float(np.clip(scale, 0.6, 1.4))
    ch["rest"] = rest = _rest_geometry(kp)
    ch["notes"] = _fit_notes(motion, canon.num_frames, measured, fallback, scale, derived_chest,
                             spine_on_pelvis, rest,
                             spine_on_pelvis and rest_pose is not None)
    try:
        return replace(DEFAULT, **ch)
    except RetargetError as exc:
        raise RetargetError(f"motion {motion.name!r} gives an implausible body: {exc.detail}",
                            source=src, field=exc.field) from None


def fit_humanoid(motion: Motion) -> Humanoid:
    """Build the humanoid matching ``motion``'s subject (see :func:`fit_dimensions`)."""
    return Humanoid(fit_dimensions(motion), name=motion.name)


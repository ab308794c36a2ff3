"""Skeleton library and the canonical keypoint set.

Every skeleton maps (a subset of) its joints onto the *canonical keypoints*,
the 21 points metrics and retargeting work on. Keypoints a skeleton does not
measure are absent from its ``canonical`` map: declared missing, never guessed.

Semantics of the canonical keypoints (joint centres unless noted):

=============== ==========================================================
pelvis          root of the trunk, between the hips
left/right_hip  hip joint centres
left/right_knee knee joint centres
left/right_ankle ankle joint centres
left/right_toe  ball of the foot / toe base
spine           lower back (lumbar)
chest           upper back / thorax
neck            base of the neck
head            head (base of the skull for mocap skeletons, head centre for
                Kinect; see each skeleton's notes)
left/right_shoulder  glenohumeral joint centres
left/right_elbow     elbow joint centres
left/right_wrist     wrist joint centres
left/right_hand      end of the hand (knuckles / hand centre)
=============== ==========================================================
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache

from simenv.core.errors import SkeletonError


@dataclass(frozen=True)
class Skeleton:
    """A kinematic tree of named joints.

    Attributes:
        name: identifier of the layout, e.g. ``"cmu31"``, ``"h36m17"``.
        joint_names: (J,) unique joint names.
        parents: (J,) parent index of each joint, ``-1`` for roots. A parent
            always precedes its child (topological order).
        canonical: map from canonical keypoint name (see
            :data:`CANONICAL_KEYPOINTS`) to this skeleton's
            joint name. Keypoints the skeleton lacks are simply absent.
    """

    name: str
    joint_names: tuple[str, ...]
    parents: tuple[int, ...]
    canonical: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        object.__setattr__(self, "parents", tuple(int(p) for p in self.parents))
        object.__setattr__(self, "canonical", dict(self.canonical))
        names, parents = self.joint_names, self.parents
        if not names:
            raise SkeletonError(f"skeleton {self.name!r} has no joints")
        if len(names) != len(parents):
            raise SkeletonError(
                f"skeleton {self.name!r}: {len(names)} joint names but {len(parents)} parents"
            )
        seen: set[str] = set()
        for name in names:
            if name in seen:
                raise SkeletonError(
                    f"skeleton {self.name!r}: duplicate joint name (names must be unique)",
                    field=name,
                )
            seen.add(name)
        for j, p in enumerate(parents):
            if not -1 <= p < j:
                raise SkeletonError(
                    f"skeleton {self.name!r}: joint {j} has parent {p}; expected -1 or an "
                    f"index below {j} (parents must precede children)",
                    field=names[j],
                )
        for key, joint in self.canonical.items():
            if joint not in seen:
                raise SkeletonError(
                    f"skeleton {self.name!r}: canonical keypoint {key!r} maps to unknown "
                    f"joint {joint!r}",
                    field=key,
                )

    def __hash__(self) -> int:
        return hash((self.name, self.joint_names, self.parents))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Skeleton):
            return NotImplemented
        return (
            self.name == other.name
            and self.joint_names == other.joint_names
            and self.parents == other.parents
            and dict(self.canonical) == dict(other.canonical)
        )

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    @property
    def bones(self) -> list[tuple[int, int]]:
        """(parent, child) index pairs, one per non-root joint."""
        return [(p, j) for j, p in enumerate(self.parents) if p >= 0]

    def index(self, name: str) -> int:
        """Index of joint ``name``; raises :class:`SkeletonError` if absent."""
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise SkeletonError(
                f"skeleton {self.name!r} has no joint {name!r}; joints are "
                f"{', '.join(self.joint_names)}"
            ) from None

    def children(self, j: int) -> list[int]:
        return [c for c, p in enumerate(self.parents) if p == j]

    def subset(self, names: Sequence[str], name: str | None = None) -> Skeleton:
        """Skeleton restricted to ``names``; each joint's parent becomes its
        nearest kept ancestor. Canonical entries of dropped joints are dropped."""
        keep = [self.index(n) for n in names]
        keep_sorted = sorted(keep)
        new_index = {old: new for new, old in enumerate(keep_sorted)}
        parents = []
        for old in keep_sorted:
            p = self.parents[old]
            while p >= 0 and p not in new_index:
                p = self.parents[p]
            parents.append(new_index[p] if p >= 0 else -1)
        kept_names = [self.joint_names[i] for i in keep_sorted]
        canonical = {k: v for k, v in self.canonical.items() if v in kept_names}
        return Skeleton(name or f"{self.name}_subset", tuple(kept_names), tuple(parents), canonical)


#: Canonical keypoints with their parent keypoint (None for the root).
CANONICAL_TREE: dict[str, str | None] = {
    "pelvis": None,
    "left_hip": "pelvis",
    "left_knee": "left_hip",
    "left_ankle": "left_knee",
    "left_toe": "left_ankle",
    "right_hip": "pelvis",
    "right_knee": "right_hip",
    "right_ankle": "right_knee",
    "right_toe": "right_ankle",
    "spine": "pelvis",
    "chest": "spine",
    "neck": "chest",
    "head": "neck",
    "left_shoulder": "chest",
    "left_elbow": "left_shoulder",
    "left_wrist": "left_elbow",
    "left_hand": "left_wrist",
    "right_shoulder": "chest",
    "right_elbow": "right_shoulder",
    "right_wrist": "right_elbow",
    "right_hand": "right_wrist",
}

CANONICAL_KEYPOINTS: tuple[str, ...] = tuple(CANONICAL_TREE)


def _tree(name: str, tree: dict[str, str | None], canonical: dict[str, str]) -> Skeleton:
    names = list(tree)
    parents = [-1 if tree[n] is None else names.index(tree[n]) for n in names]
    return Skeleton(name, tuple(names), tuple(parents), canonical)


@cache
def canonical_skeleton() -> Skeleton:
    """The 21-keypoint canonical skeleton (identity canonical map)."""
    return _tree("canonical", CANONICAL_TREE, {k: k for k in CANONICAL_TREE})


#: CMU joint-name aliases -> canonical keypoint, covering the cgspeed
#: Motionbuilder-friendly (Hips, LeftUpLeg, ...), cgspeed 3dsMax-friendly
#: (LeftHip, LeftKnee, ...) and ASF/AMC (hip, lfemur, ...) namings. In all of
#: them a joint's position is the *start* of the bone of that name, so e.g.
#: ``LeftUpLeg`` (thigh bone start) is the hip joint centre and ``LeftHand``
#: (hand bone start) the wrist.
CMU_ALIASES: dict[str, tuple[str, ...]] = {
    "pelvis": ("Hips", "hip", "root"),
    "left_hip": ("LeftUpLeg", "LeftHip", "lfemur"),
    "left_knee": ("LeftLeg", "LeftKnee", "ltibia"),
    "left_ankle": ("LeftFoot", "LeftAnkle", "lfoot"),
    "left_toe": ("LeftToeBase", "LeftToe", "ltoes"),
    "right_hip": ("RightUpLeg", "RightHip", "rfemur"),
    "right_knee": ("RightLeg", "RightKnee", "rtibia"),
    "right_ankle": ("RightFoot", "RightAnkle", "rfoot"),
    "right_toe": ("RightToeBase", "RightToe", "rtoes"),
    "spine": ("Spine", "Chest", "upperback"),
    "chest": ("Spine1", "Chest2", "thorax"),
    "neck": ("lowerneck", "Neck"),
    "head": ("Head", "head"),
    "left_shoulder": ("LeftArm", "LeftShoulder@3dsmax", "lhumerus"),
    "left_elbow": ("LeftForeArm", "LeftElbow", "lradius"),
    "left_wrist": ("LeftHand", "LeftWrist", "lwrist"),
    "left_hand": ("LeftFingerBase", "lhand"),
    "right_shoulder": ("RightArm", "RightShoulder@3dsmax", "rhumerus"),
    "right_elbow": ("RightForeArm", "RightElbow", "rradius"),
    "right_wrist": ("RightHand", "RightWrist", "rwrist"),
    "right_hand": ("RightFingerBase", "rhand"),
}


def cmu_canonical_map(joint_names: Sequence[str]) -> dict[str, str]:
    """Canonical map for any CMU naming variant, detected from the names.

    The 3dsMax-friendly release reuses ``LeftShoulder`` for the upper-arm
    joint (its clavicle is ``LeftCollar``), whereas Motionbuilder uses
    ``LeftShoulder`` for the clavicle; the variant is told by the presence of
    ``LeftCollar``. Likewise the 3dsMax ``Neck`` is the upper neck (lower neck
    is ``lowerneck``).
    """
    names = set(joint_names)
    max_variant = "LeftCollar" in names
    result: dict[str, str] = {}
    for key, aliases in CMU_ALIASES.items():
        for alias in aliases:
            base, _, tag = alias.partition("@")
            if tag == "3dsmax" and not max_variant:
                continue
            if base in names:
                result[key] = base
                break
    if max_variant:
        result["left_shoulder"] = "LeftShoulder"
        result["right_shoulder"] = "RightShoulder"
    return result


#: The CMU-31 layout of the cgspeed Motionbuilder-friendly BVH release (the
#: most common CMU conversion), in file order.
CMU31_JOINTS: tuple[str, ...] = (
    "Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
    "RHipJoint", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase",
    "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head",
    "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LeftFingerBase",
    "LeftHandIndex1", "LThumb",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightFingerBase",
    "RightHandIndex1", "RThumb",
)
_CMU31_PARENTS = (-1, 0, 1, 2, 3, 4, 0, 6, 7, 8, 9, 0, 11, 12, 13, 14, 15, 13, 17, 18, 19, 20,
                  21, 20, 13, 24, 25, 26, 27, 28, 27)


@cache
def cmu31_skeleton() -> Skeleton:
    """CMU-31 (cgspeed Motionbuilder naming). The converter collapses the
    thorax and wrist bones to zero length, so canonical ``neck`` is ``Neck1``
    and ``hand`` is ``LeftHandIndex1`` (see :func:`cmu_canonical_map`'s users
    in :mod:`simenv.io.bvh`, which record the remap as a quirk)."""
    canonical = cmu_canonical_map(CMU31_JOINTS)
    canonical.update(neck="Neck1", left_hand="LeftHandIndex1", right_hand="RightHandIndex1")
    return Skeleton("cmu31", CMU31_JOINTS, _CMU31_PARENTS, canonical)


#: Canonical map of the 43-joint Poser/Second-Life template used by the
#: outworldz BVH release of CMU (e.g. the salsa pairs 60_xx/61_xx). ``lThigh``
#: is the hip joint (``lButtock`` is a short pelvis bone), ``lShldr`` the
#: shoulder, ``lHand`` the wrist, ``lMid1`` the middle-finger knuckle; the
#: toe is the foot's End Site (``lFoot_end``, kept by the BVH reader).
POSER_CANONICAL: dict[str, str] = {
    "pelvis": "hip",
    "left_hip": "lThigh",
    "left_knee": "lShin",
    "left_ankle": "lFoot",
    "left_toe": "lFoot_end",
    "right_hip": "rThigh",
    "right_knee": "rShin",
    "right_ankle": "rFoot",
    "right_toe": "rFoot_end",
    "spine": "abdomen",
    "chest": "chest",
    "neck": "neck",
    "head": "head",
    "left_shoulder": "lShldr",
    "left_elbow": "lForeArm",
    "left_wrist": "lHand",
    "left_hand": "lMid1",
    "right_shoulder": "rShldr",
    "right_elbow": "rForeArm",
    "right_wrist": "rHand",
    "right_hand": "rMid1",
}


def is_poser_template(joint_names: Sequence[str]) -> bool:
    """Whether the joint names are the Poser/Second-Life template layout."""
    return {"hip", "abdomen", "lShldr", "rShldr", "lThigh", "rThigh"} <= set(joint_names)


def poser_canonical_map(joint_names: Sequence[str]) -> dict[str, str]:
    """Canonical map for the Poser/Second-Life template: the entries of
    :data:`POSER_CANONICAL` whose joints are present."""
    names = set(joint_names)
    return {k: v for k, v in POSER_CANONICAL.items() if v in names}


# =============================================================================
# Kinect-era, array and gesture skeletons (non-CMU). Everything below this line
# is one section: Kinect v1 (20), SBU (15), Florence (OpenNI 15), Kinect v2
# (25), Nuitrack (24), H36M (17), the 9-joint gesture set and the registry.
# =============================================================================
#
# Joint *names* are the source's own (SDK enum names, dataset README names) so
# that a joint can be traced back to its documentation. Joint *order* is the
# source's file order wherever that order is topological (every parent before
# its child); Kinect v2 is the exception (its SpineShoulder, SDK index 20, is
# the parent of joints 2, 4 and 8), so its readers permute with
# :data:`KINECT_V2_SDK_ORDER`. The OpenNI-style skeletons (SBU, Florence,
# Nuitrack) list the head first, so in file order the head is the root of the
# tree; bones (undirected parent-child pairs) are what matters downstream.
#
# Canonical maps, per skeleton (keypoints not listed are absent = not measured):
#
# ============== ================ ==============================================
# skeleton       canonical        source joint (why)
# ============== ================ ==============================================
# kinect_v1_20   pelvis           HipCenter
#                spine            Spine (mid back)
#                neck             ShoulderCenter (base of neck, between shoulders)
#                head             Head (head centre)
#                *_wrist/*_hand   Wrist*/Hand* (SDK hand = hand centre)
#                *_ankle/*_toe    Ankle*/Foot* (SDK foot = forefoot point)
#                chest            absent
# kinect_v2_25   pelvis, spine    SpineBase, SpineMid
#                neck             SpineShoulder (base of neck; v2 ``Neck`` is
#                                 higher, mid-neck, and stays unmapped)
#                head             Head
#                *_hand, *_toe    Hand*, Foot*; HandTip*/Thumb* unmapped
#                chest            absent
# sbu15          head, neck       HEAD, NECK
#                spine            TORSO (torso centre)
#                *_wrist          *_HAND: OpenNI/NITE "hand" ends the forearm;
#                                 measured SBU elbow-"hand" 0.28-0.30 m, i.e.
#                                 the wrist region, so it is the wrist
#                *_ankle          *_FOOT: NITE "foot" ends the shin (SBU knee-
#                                 "foot" 0.41-0.44 m), i.e. the ankle
#                pelvis, chest,   absent (no such joints; the pelvis is NOT
#                *_hand, *_toe    synthesised from the hips)
# florence15     as sbu15         the dataset README already calls the hand and
#                                 foot joints Wrist and Ankle
# nuitrack       pelvis           JOINT_WAIST
#                spine            JOINT_TORSO
#                neck             JOINT_LEFT_COLLAR (both collars are the same
#                                 point, at the base of the neck; JOINT_NECK is
#                                 mid-neck and stays unmapped)
#                head             JOINT_HEAD
#                *_wrist/*_hand   JOINT_*_WRIST / JOINT_*_HAND
#                *_toe            JOINT_*_FOOT (never tracked in NuiSI: the
#                                 reader drops it, and with it the mapping)
#                chest            absent; fingertips unmapped
# h36m17         pelvis           Hip
#                spine            Spine (H36M Spine1, mid back)
#                neck             Thorax (H36M "Neck", base of the neck, where
#                                 the clavicles attach)
#                head             Neck/Nose (H36M "Head" joint: base of the
#                                 skull); ``Head`` is the head-top end site and
#                                 stays unmapped
#                *_ankle          RFoot/LFoot (start of the foot bone = ankle)
#                *_wrist          RWrist/LWrist; chest, toes, hands absent
# gesture9       identity         spine, neck, head, shoulders, elbows, wrists
# smpl22         pelvis, hips,    the SMPL joints of the same names
#                knees, ankles,
#                shoulders,
#                elbows, wrists,
#                neck, head
#                *_toe            left_foot/right_foot (SMPL "foot" = toe base)
#                spine            spine1 (lumbar, ~0.12 m above the pelvis)
#                chest            spine3 (upper thorax, where neck and collars
#                                 branch, as CMU ``Spine1``); spine2 and the
#                                 collars stay unmapped; *_hand absent
# ============== ================ ==============================================

#: Kinect SDK v1 ``NUI_SKELETON_POSITION_INDEX`` order (0-based), as in
#: UTKinect files and the Kinect for Windows SDK 1.x.
KINECT_V1_JOINTS: tuple[str, ...] = (
    "HipCenter", "Spine", "ShoulderCenter", "Head",
    "ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft",
    "ShoulderRight", "ElbowRight", "WristRight", "HandRight",
    "HipLeft", "KneeLeft", "AnkleLeft", "FootLeft",
    "HipRight", "KneeRight", "AnkleRight", "FootRight",
)
_KINECT_V1_PARENTS = (-1, 0, 1, 2, 2, 4, 5, 6, 2, 8, 9, 10, 0, 12, 13, 14, 0, 16, 17, 18)

#: Kinect SDK v2 ``JointType`` names in SDK index order (0-24), as in NTU
#: RGB+D ``.skeleton`` files.
KINECT_V2_SDK_JOINTS: tuple[str, ...] = (
    "SpineBase", "SpineMid", "Neck", "Head",
    "ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft",
    "ShoulderRight", "ElbowRight", "WristRight", "HandRight",
    "HipLeft", "KneeLeft", "AnkleLeft", "FootLeft",
    "HipRight", "KneeRight", "AnkleRight", "FootRight",
    "SpineShoulder", "HandTipLeft", "ThumbLeft", "HandTipRight", "ThumbRight",
)
#: SDK index of each joint of :func:`kinect_v2_skeleton` (topological order):
#: ``positions_ours = positions_sdk[:, KINECT_V2_SDK_ORDER]``.
KINECT_V2_SDK_ORDER: tuple[int, ...] = (
    0, 1, 20, 2, 3, 4, 5, 6, 7, 21, 22, 8, 9, 10, 11, 23, 24, 12, 13, 14, 15, 16, 17, 18, 19,
)
_KINECT_V2_PARENTS = (
    -1, 0, 1, 2, 3,  # SpineBase, SpineMid, SpineShoulder, Neck, Head
    2, 5, 6, 7, 8, 8,  # ShoulderLeft .. HandTipLeft, ThumbLeft
    2, 11, 12, 13, 14, 14,  # ShoulderRight .. HandTipRight, ThumbRight
    0, 17, 18, 19,  # HipLeft .. FootLeft
    0, 21, 22, 23,  # HipRight .. FootRight
)

#: SBU Kinect Interaction joint order (dataset README, 1-based 1..15).
SBU_JOINTS: tuple[str, ...] = (
    "HEAD", "NECK", "TORSO",
    "LEFT_SHOULDER", "LEFT_ELBOW", "LEFT_HAND",
    "RIGHT_SHOULDER", "RIGHT_ELBOW", "RIGHT_HAND",
    "LEFT_HIP", "LEFT_KNEE", "LEFT_FOOT",
    "RIGHT_HIP", "RIGHT_KNEE", "RIGHT_FOOT",
)
#: Florence 3D joint order (dataset README, f1-f45 in triples).
FLORENCE_JOINTS: tuple[str, ...] = (
    "Head", "Neck", "Spine",
    "LeftShoulder", "LeftElbow", "LeftWrist",
    "RightShoulder", "RightElbow", "RightWrist",
    "LeftHip", "LeftKnee", "LeftAnkle",
    "RightHip", "RightKnee", "RightAnkle",
)
# OpenNI 15-joint tree in file order, rooted at the head (see section notes).
_OPENNI15_PARENTS = (-1, 0, 1, 1, 3, 4, 1, 6, 7, 2, 9, 10, 2, 12, 13)

#: Nuitrack ``JointType`` names for ids 1..24 (id 0 is JOINT_NONE); skeleton
#: index = Nuitrack id - 1.
NUITRACK_JOINTS: tuple[str, ...] = (
    "JOINT_HEAD", "JOINT_NECK", "JOINT_TORSO", "JOINT_WAIST",
    "JOINT_LEFT_COLLAR", "JOINT_LEFT_SHOULDER", "JOINT_LEFT_ELBOW", "JOINT_LEFT_WRIST",
    "JOINT_LEFT_HAND", "JOINT_LEFT_FINGERTIP",
    "JOINT_RIGHT_COLLAR", "JOINT_RIGHT_SHOULDER", "JOINT_RIGHT_ELBOW", "JOINT_RIGHT_WRIST",
    "JOINT_RIGHT_HAND", "JOINT_RIGHT_FINGERTIP",
    "JOINT_LEFT_HIP", "JOINT_LEFT_KNEE", "JOINT_LEFT_ANKLE", "JOINT_LEFT_FOOT",
    "JOINT_RIGHT_HIP", "JOINT_RIGHT_KNEE", "JOINT_RIGHT_ANKLE", "JOINT_RIGHT_FOOT",
)
_NUITRACK_PARENTS = (
    -1, 0, 1, 2,  # head, neck, torso, waist
    2, 4, 5, 6, 7, 8,  # left collar (on the torso) .. fingertip
    2, 10, 11, 12, 13, 14,  # right collar .. fingertip
    3, 16, 17, 18,  # left hip (on the waist) .. foot
    3, 20, 21, 22,  # right hip .. foot
)

#: Human3.6M 17-joint order used by most 3D pose papers (VideoPose3D et al.).
H36M_JOINTS: tuple[str, ...] = (
    "Hip", "RHip", "RKnee", "RFoot", "LHip", "LKnee", "LFoot",
    "Spine", "Thorax", "Neck/Nose", "Head",
    "LShoulder", "LElbow", "LWrist", "RShoulder", "RElbow", "RWrist",
)
_H36M_PARENTS = (-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 8, 11, 12, 8, 14, 15)

#: The 9-joint upper-body gesture set: the upper-body keypoints every skeleton
#: of this library measures, so a gesture from any source maps onto it.
GESTURE9_JOINTS: tuple[str, ...] = (
    "spine", "neck", "head",
    "left_shoulder", "left_elbow", "left_wrist",
    "right_shoulder", "right_elbow", "right_wrist",
)
_GESTURE9_PARENTS = (-1, 0, 1, 1, 3, 4, 1, 6, 7)

#: The 22 body joints of SMPL in SMPL order, as text-to-motion models emit them
#: (HumanML3D ``new_joints``, MDM, InterGen). Parents follow HumanML3D's
#: ``t2m_kinematic_chain`` (github.com/EricGuo5513/HumanML3D src/humanml3d/skeletons.py;
#: the same in MDM's data_loaders/humanml/utils/paramUtil.py, and HumanML3D's rule
#: parent = previous joint of a chain): [0,2,5,8,11], [0,1,4,7,10], [0,3,6,9,12,15],
#: [9,14,17,19,21], [9,13,16,18,20].
SMPL22_JOINTS: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck",
    "left_collar", "right_collar", "head", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist",
)
SMPL22_PARENTS: tuple[int, ...] = (
    -1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19,
)


#: KIT-ML's 21 MMM joints, in the order of its files (root, pelvis, thorax, lower
#: neck, upper neck; left then right shoulder, elbow, wrist; left then right hip,
#: knee, ankle, mid-foot, toe).
KIT21_JOINTS: tuple[str, ...] = (
    "root", "BP", "BT", "BLN", "BUN", "LS", "LE", "LW", "RS", "RE", "RW",
    "LH", "LK", "LA", "LMrot", "LF", "RH", "RK", "RA", "RMrot", "RF",
)
#: Parents from HumanML3D's ``kit_kinematic_chain`` (parent = previous in chain):
#: [[0, 11, 12, 13, 14, 15], [0, 16, 17, 18, 19, 20], [0, 1, 2, 3, 4], [3, 5, 6, 7],
#: [3, 8, 9, 10]].
KIT21_PARENTS: tuple[int, ...] = (
    -1, 0, 1, 2, 3, 3, 5, 6, 3, 8, 9, 0, 11, 12, 13, 14, 0, 16, 17, 18, 19,
)


@cache
def kit21_skeleton() -> Skeleton:
    """KIT-ML's 21-joint MMM skeleton. Canonical map: ``BP`` (lumbar) is the
    spine, ``BT`` (thorax) the chest, ``BLN`` the neck base, ``BUN`` (upper
    neck, the skull base) the head, ``LF``/``RF`` (the foot's front joint) the
    toes; KIT has no hand ends."""
    canonical = {"pelvis": "root", "spine": "BP", "chest": "BT", "neck": "BLN", "head": "BUN"}
    for side, s in (("left", "L"), ("right", "R")):
        canonical |= {f"{side}_shoulder": f"{s}S", f"{side}_elbow": f"{s}E",
                      f"{side}_wrist": f"{s}W", f"{side}_hip": f"{s}H",
                      f"{side}_knee": f"{s}K", f"{side}_ankle": f"{s}A",
                      f"{side}_toe": f"{s}F"}
    return Skeleton("kit21", KIT21_JOINTS, KIT21_PARENTS, canonical)


def _sided(mapping: dict[str, str], left: str, right: str) -> dict[str, str]:
    """Expand ``{"shoulder": "Shoulder{s}"}``-style entries for both sides."""
    out: dict[str, str] = {}
    for key, pattern in mapping.items():
        out[f"left_{key}"] = pattern.format(s=left)
        out[f"right_{key}"] = pattern.format(s=right)
    return out


@cache
def kinect_v1_skeleton() -> Skeleton:
    """Kinect SDK v1 20-joint skeleton (UTKinect, MSR Action3D after reordering)."""
    canonical = {"pelvis": "HipCenter", "spine": "Spine", "neck": "ShoulderCenter",
                 "head": "Head"}
    canonical |= _sided({"shoulder": "Shoulder{s}", "elbow": "Elbow{s}", "wrist": "Wrist{s}",
                         "hand": "Hand{s}", "hip": "Hip{s}", "knee": "Knee{s}",
                         "ankle": "Ankle{s}", "toe": "Foot{s}"}, "Left", "Right")
    return Skeleton("kinect_v1_20", KINECT_V1_JOINTS, _KINECT_V1_PARENTS, canonical)


@cache
def kinect_v2_skeleton() -> Skeleton:
    """Kinect SDK v2 25-joint skeleton (NTU RGB+D) in topological order; see
    :data:`KINECT_V2_SDK_ORDER` for the SDK index of each joint."""
    names = tuple(KINECT_V2_SDK_JOINTS[i] for i in KINECT_V2_SDK_ORDER)
    canonical = {"pelvis": "SpineBase", "spine": "SpineMid", "neck": "SpineShoulder",
                 "head": "Head"}
    canonical |= _sided({"shoulder": "Shoulder{s}", "elbow": "Elbow{s}", "wrist": "Wrist{s}",
                         "hand": "Hand{s}", "hip": "Hip{s}", "knee": "Knee{s}",
                         "ankle": "Ankle{s}", "toe": "Foot{s}"}, "Left", "Right")
    return Skeleton("kinect_v2_25", names, _KINECT_V2_PARENTS, canonical)


@cache
def sbu_skeleton() -> Skeleton:
    """SBU Kinect Interaction 15-joint skeleton (OpenNI/NITE layout)."""
    canonical = {"head": "HEAD", "neck": "NECK", "spine": "TORSO"}
    canonical |= _sided({"shoulder": "{s}_SHOULDER", "elbow": "{s}_ELBOW", "wrist": "{s}_HAND",
                         "hip": "{s}_HIP", "knee": "{s}_KNEE", "ankle": "{s}_FOOT"},
                        "LEFT", "RIGHT")
    return Skeleton("sbu15", SBU_JOINTS, _OPENNI15_PARENTS, canonical)


@cache
def florence_skeleton() -> Skeleton:
    """Florence 3D Actions 15-joint skeleton (OpenNI/NITE layout)."""
    canonical = {"head": "Head", "neck": "Neck", "spine": "Spine"}
    canonical |= _sided({"shoulder": "{s}Shoulder", "elbow": "{s}Elbow", "wrist": "{s}Wrist",
                         "hip": "{s}Hip", "knee": "{s}Knee", "ankle": "{s}Ankle"},
                        "Left", "Right")
    return Skeleton("florence15", FLORENCE_JOINTS, _OPENNI15_PARENTS, canonical)


@cache
def nuitrack_skeleton() -> Skeleton:
    """Nuitrack 24-joint skeleton (ids 1..24, as in the NuiSI dataset)."""
    canonical = {"pelvis": "JOINT_WAIST", "spine": "JOINT_TORSO",
                 "neck": "JOINT_LEFT_COLLAR", "head": "JOINT_HEAD"}
    canonical |= _sided({"shoulder": "JOINT_{s}_SHOULDER", "elbow": "JOINT_{s}_ELBOW",
                         "wrist": "JOINT_{s}_WRIST", "hand": "JOINT_{s}_HAND",
                         "hip": "JOINT_{s}_HIP", "knee": "JOINT_{s}_KNEE",
                         "ankle": "JOINT_{s}_ANKLE", "toe": "JOINT_{s}_FOOT"},
                        "LEFT", "RIGHT")
    return Skeleton("nuitrack", NUITRACK_JOINTS, _NUITRACK_PARENTS, canonical)


@cache
def h36m_skeleton() -> Skeleton:
    """Human3.6M 17-joint skeleton."""
    canonical = {"pelvis": "Hip", "spine": "Spine", "neck": "Thorax", "head": "Neck/Nose"}
    canonical |= _sided({"hip": "{s}Hip", "knee": "{s}Knee", "ankle": "{s}Foot",
                         "shoulder": "{s}Shoulder", "elbow": "{s}Elbow", "wrist": "{s}Wrist"},
                        "L", "R")
    return Skeleton("h36m17", H36M_JOINTS, _H36M_PARENTS, canonical)


@cache
def smpl22_skeleton() -> Skeleton:
    """SMPL 22-joint body skeleton (HumanML3D / MDM / InterGen joint positions)."""
    canonical = {"pelvis": "pelvis", "spine": "spine1", "chest": "spine3", "neck": "neck",
                 "head": "head"}
    canonical |= _sided({"hip": "{s}_hip", "knee": "{s}_knee", "ankle": "{s}_ankle",
                         "toe": "{s}_foot", "shoulder": "{s}_shoulder",
                         "elbow": "{s}_elbow", "wrist": "{s}_wrist"}, "left", "right")
    return Skeleton("smpl22", SMPL22_JOINTS, SMPL22_PARENTS, canonical)


@cache
def gesture9_skeleton() -> Skeleton:
    """The 9-joint upper-body gesture skeleton (canonical names, identity map)."""
    return Skeleton("gesture9", GESTURE9_JOINTS, _GESTURE9_PARENTS,
                    {k: k for k in GESTURE9_JOINTS})


def _registry() -> dict[str, Callable[[], Skeleton]]:
    entries: dict[str, Callable[[], Skeleton]] = {
        "canonical": canonical_skeleton,
        "kinect_v1_20": kinect_v1_skeleton,
        "kinect_v2_25": kinect_v2_skeleton,
        "sbu15": sbu_skeleton,
        "florence15": florence_skeleton,
        "nuitrack": nuitrack_skeleton,
        "h36m17": h36m_skeleton,
        "gesture9": gesture9_skeleton,
        "cmu31": cmu31_skeleton,
        "smpl22": smpl22_skeleton,
        "kit21": kit21_skeleton,
    }
    return entries


#: Accepted spellings of registry names (compared after lower-casing and
#: turning ``-`` and spaces into ``_``).
SKELETON_ALIASES: dict[str, str] = {
    "kinect_v1": "kinect_v1_20", "kinect1": "kinect_v1_20", "kinect_v1_20": "kinect_v1_20",
    "kinect_v2": "kinect_v2_25", "kinect2": "kinect_v2_25", "ntu": "kinect_v2_25",
    "ntu25": "kinect_v2_25", "sbu": "sbu15", "sbu_15": "sbu15", "florence": "florence15",
    "florence_15": "florence15", "openni15": "florence15", "nuisi": "nuitrack",
    "h36m": "h36m17", "h36m_17": "h36m17", "gesture": "gesture9", "gesture_9": "gesture9",
    "cmu": "cmu31", "cmu_31": "cmu31",
    "smpl": "smpl22", "smpl_22": "smpl22", "humanml3d": "smpl22", "t2m": "smpl22",
    "kit": "kit21", "kit_ml": "kit21", "kitml": "kit21", "mmm": "kit21",
}


def skeleton_names() -> tuple[str, ...]:
    """Names :func:`get_skeleton` accepts (without aliases)."""
    return tuple(_registry())


def get_skeleton(name: str) -> Skeleton:
    """Skeleton of the library by name (case-insensitive; ``-`` or ``_``;
    aliases in :data:`SKELETON_ALIASES`). Raises :class:`SkeletonError` for an
    unknown name, listing the known ones."""
    key = str(name).strip().lower().replace("-", "_").replace(" ", "_")
    key = SKELETON_ALIASES.get(key, key)
    entries = _registry()
    if key not in entries:
        raise SkeletonError(
            f"unknown skeleton {name!r}; known skeletons: {', '.join(entries)}", field=str(name)
        )
    return entries[key]()

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

from collections.abc import Sequence
from functools import cache

from simenv.motion import Skeleton

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

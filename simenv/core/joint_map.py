"""Mapping any skeleton's joints onto the canonical keypoints.

A skeleton simenv has no reader-specific map for (a lab's BVH, a game rig, a body-model
export) is mapped in three steps, each recorded per keypoint in :class:`JointMapping.how`:

1. **Names.** Every joint name is normalised (:func:`normalise`): namespace and rig prefixes
   dropped (``mixamorig:``, ``Bip01``, ``Character1_``, an actor prefix every joint shares),
   the side read from a side token (``Left``/``L``/``_l``/``.L``, as prefix, suffix or glued
   capital as in OptiTrack's ``LThigh``), the rest lower-cased without separators, with
   leading zeros of numbers dropped (``spine_01`` -> ``spine1``). The normalised names are
   looked up in :data:`CONVENTIONS`, a declared table of the naming conventions in use; the
   convention matching most keypoints is read first, the others fill what it lacks.
   Conventions are read whole because the same word means different joints in different
   ones: ``LeftShoulder`` is the clavicle in MotionBuilder, Unity, Xsens and Rokoko rigs and
   the shoulder joint in Kinect and SMPL; ``LeftHand`` is the wrist in a rig and the hand
   centre in Kinect when a ``WristLeft`` exists. A name several joints answer means the one
   above all the others (a rig's helper named like its bone hangs below it), else nothing.
2. **Topology.** ``chest`` is where the two arm chains leave the spine (the lowest common
   ancestor of the shoulders); ``spine`` the first joint above the pelvis on the way to it;
   a ``pelvis`` no name gives is where the two named hips meet.
   Chains must run down the tree (hip above knee above ankle above toe, shoulder above elbow
   above wrist above hand); a keypoint whose joint breaks its chain is dropped, and so is a
   hand or toe farther from its wrist or ankle than the segment above is long, or within a
   tenth of that length (a stray or stub End Site: no hand is there).
3. **Rest pose** (only when names give no pelvis or no hips): the two leaf chains that end
   lowest are the legs and their common ancestor the pelvis; the branch point of the spine
   is the chest, its two mirror-image branches the arms (as many joints, bone lengths within
   15 %; else its two longest), the longest other one the neck and head (the head being the
   joint eyes or ears hang from, when the highest joint is one of such a pair).
   Along a limb the two longest straight segments are the upper and lower limb (so twist
   and roll joints inside a segment are skipped); a leg's segment twice as long as any
   other is thigh and shin of a straight knee (a T-pose, a standing clip), cut at its
   middle joint; an arm's segment over 0.56 of the arm is upper arm and forearm of a
   straight elbow (a T-pose), cut at its middle joint too (and at the shoulder when the
   clavicle lies in it), and the wrist is the first joint past the middle of the segment
   after the elbow (a straight wrist). Left and right come from side tokens when the names
   have them, otherwise from the body's own frame: up from pelvis to chest, forward from the
   direction the feet point (or the knees bend), left = up x forward.

A user map (:func:`read_joint_map`, a TOML file ``[canonical] left_hip = "UpperLeg_L"``)
replaces all of this; :func:`joint_map_template` writes such a file, pre-filled with what was
found, for a skeleton that could not be mapped.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import tomllib

from simenv.core.errors import SkeletonError
from simenv.core.motion import Motion
from simenv.core.skeletons import CANONICAL_KEYPOINTS, CANONICAL_TREE, Skeleton

#: Keypoints without which no humanoid can be fitted or retargeted.
REQUIRED_FOR_BODY: tuple[str, ...] = ("pelvis", "left_hip", "right_hip")

#: Help of every command's ``--joint-map`` option.
JOINT_MAP_HELP = (
    "a TOML file mapping the canonical keypoints to the file's joints ([canonical] "
    "left_hip = \"UpperLeg_L\", ...), instead of the automatic mapping; `simenv info FILE "
    "--write-joint-map MAP.toml` writes one to edit")

#: How a keypoint was found, as written in :attr:`JointMapping.how`.
HOW_NAME, HOW_TOPOLOGY, HOW_REST_POSE, HOW_USER = "name", "topology", "rest pose", "user map"


#: What a user may give as a joint map: a TOML file or the mapping itself.
JointMapSource = str | Path | Mapping[str, str]


@dataclass(frozen=True)
class NamingConvention:
    """One joint-naming convention: the joints it names for each canonical keypoint.

    Attributes:
        name: identifier, e.g. ``"unreal_mannequin"``.
        description: who uses it.
        keypoints: canonical keypoint -> joint names of the *left* side (the right side is the
            same names with the side token flipped) or of the centre line. Several names per
            keypoint are alternatives in order of preference. Names are compared after
            :func:`normalise`, so ``L_Hip``, ``left_hip`` and ``HipLeft`` are one name.
        prefix: a namespace the convention's files carry (informational; every namespace is
            stripped by :func:`normalise`).
        sensor: the depth-camera family whose skeleton tracker names joints this way
            (``"kinect_v1"``, ``"kinect_v2"``), None for motion capture and body models. A file
            so named holds a depth camera's estimates in that camera's frame, whatever its
            format (a NiTE recording exported to BVH): :func:`sensor_family`.
    """

    name: str
    description: str
    keypoints: Mapping[str, tuple[str, ...]]
    prefix: str = ""
    sensor: str | None = None


def _convention(name: str, description: str, prefix: str = "", sensor: str | None = None,
                **keypoints: str) -> NamingConvention:
    return NamingConvention(name, description,
                            {k: tuple(v.split("|")) for k, v in keypoints.items()}, prefix,
                            sensor)


#: The naming conventions in use, left-side names (see :class:`NamingConvention`).
#: ``chest`` is never named: it is where the arms leave the spine (step 2 of the module
#: docstring). Sources: Autodesk HumanIK / MotionBuilder character template, Mixamo rigs,
#: Unity ``HumanBodyBones``, Unreal Engine 4/5 Mannequin, SMPL joint names (AMASS, SMPL-X
#: exporters), 3ds Max Biped, Xsens MVN segment names, OptiTrack Motive baseline skeleton,
#: Rokoko Studio, Perception Neuron, Sony mocopi, Kinect SDK v1/v2 ``JointType``, OpenNI / NiTE
#: ``XN_SKEL_*`` and Azure Kinect Body Tracking ``k4abt_joint_id_t``.
CONVENTIONS: tuple[NamingConvention, ...] = (
    _convention(
        "motionbuilder", "Autodesk HumanIK / MotionBuilder (CMU cgspeed, Ubisoft LAFAN1, "
        "Perception Neuron, Truebones, DeepMotion)",
        pelvis="Hips", left_hip="LeftUpLeg", left_knee="LeftLeg", left_ankle="LeftFoot",
        left_toe="LeftToeBase|LeftToe|LeftFootToe", spine="Spine|LowerBack", neck="Neck",
        head="Head", left_shoulder="LeftArm", left_elbow="LeftForeArm", left_wrist="LeftHand",
        left_hand="LeftHandMiddle1|LeftFingerBase|LeftHandIndex1|LeftInHandMiddle|LeftHandEnd"),
    _convention(
        "mixamo", "Adobe Mixamo rigs (HumanIK names in the mixamorig namespace)", "mixamorig:",
        pelvis="Hips", left_hip="LeftUpLeg", left_knee="LeftLeg", left_ankle="LeftFoot",
        left_toe="LeftToeBase", spine="Spine", neck="Neck", head="Head", left_shoulder="LeftArm",
        left_elbow="LeftForeArm", left_wrist="LeftHand", left_hand="LeftHandMiddle1"),
    _convention(
        "unity_humanoid", "Unity Humanoid avatar (HumanBodyBones; also UpperLeg_L style)",
        pelvis="Hips", left_hip="LeftUpperLeg", left_knee="LeftLowerLeg", left_ankle="LeftFoot",
        left_toe="LeftToes|LeftToeBase", spine="Spine", neck="Neck", head="Head",
        left_shoulder="LeftUpperArm", left_elbow="LeftLowerArm", left_wrist="LeftHand",
        left_hand="LeftMiddleProximal|LeftHandMiddle1"),
    _convention(
        "unreal_mannequin", "Unreal Engine 4/5 Mannequin (UE skeleton)",
        pelvis="pelvis", left_hip="thigh_l", left_knee="calf_l", left_ankle="foot_l",
        left_toe="ball_l", spine="spine_01", neck="neck_01", head="head",
        left_shoulder="upperarm_l", left_elbow="lowerarm_l", left_wrist="hand_l",
        left_hand="middle_01_l|middle_metacarpal_l"),
    _convention(
        "smpl", "SMPL / SMPL-H / SMPL-X joints (AMASS, body-model fits, their BVH exports)",
        pelvis="Pelvis", left_hip="L_Hip", left_knee="L_Knee", left_ankle="L_Ankle",
        left_toe="L_Foot", spine="Spine1", neck="Neck", head="Head", left_shoulder="L_Shoulder",
        left_elbow="L_Elbow", left_wrist="L_Wrist", left_hand="L_Hand|L_Middle1|left_middle1"),
    _convention(
        "biped", "Autodesk 3ds Max Biped (Bip01 ...)", "Bip01 ",
        pelvis="Pelvis", left_hip="L Thigh", left_knee="L Calf", left_ankle="L Foot",
        left_toe="L Toe0", spine="Spine", neck="Neck", head="Head", left_shoulder="L UpperArm",
        left_elbow="L Forearm", left_wrist="L Hand", left_hand="L Finger2|L Finger1"),
    _convention(
        "xsens_mvn", "Xsens MVN segments",
        pelvis="Pelvis", left_hip="LeftUpperLeg", left_knee="LeftLowerLeg",
        left_ankle="LeftFoot", left_toe="LeftToe", spine="L5|L3", neck="Neck", head="Head",
        left_shoulder="LeftUpperArm", left_elbow="LeftForeArm", left_wrist="LeftHand"),
    _convention(
        "optitrack_motive", "OptiTrack Motive skeletons (often with an actor prefix)",
        pelvis="Hip|Hips", left_hip="LThigh", left_knee="LShin", left_ankle="LFoot",
        left_toe="LToe", spine="Ab", neck="Neck", head="Head", left_shoulder="LUArm",
        left_elbow="LFArm", left_wrist="LHand", left_hand="LMiddle1"),
    _convention(
        "rokoko", "Rokoko Studio (Smartsuit) and other Thigh/Shin rigs",
        pelvis="Hips", left_hip="LeftThigh", left_knee="LeftShin", left_ankle="LeftFoot",
        left_toe="LeftToe|LeftToeBase", spine="Spine|Spine1", neck="Neck", head="Head",
        left_shoulder="LeftArm", left_elbow="LeftForeArm", left_wrist="LeftHand"),
    _convention(
        "poser", "Poser / Second Life template (outworldz CMU conversion)",
        pelvis="hip", left_hip="lThigh", left_knee="lShin", left_ankle="lFoot",
        left_toe="lToe|lFoot_end", spine="abdomen", neck="neck", head="head",
        left_shoulder="lShldr", left_elbow="lForeArm", left_wrist="lHand", left_hand="lMid1"),
    _convention(  # no spine named: torso_1 sits ~5 cm above root; the topology rule picks
        "mocopi", "Sony mocopi (BVH export; root, torso_1..7, neck_1..2, l_up_leg ...)",
        pelvis="root", left_hip="l_up_leg", left_knee="l_low_leg", left_ankle="l_foot",
        left_toe="l_toes", neck="neck_1", head="head", left_shoulder="l_up_arm",
        left_elbow="l_low_arm", left_wrist="l_hand"),
    _convention(
        "kinect_v1", "Kinect SDK 1.x (NUI_SKELETON_POSITION_INDEX)", sensor="kinect_v1",
        pelvis="HipCenter", left_hip="HipLeft", left_knee="KneeLeft", left_ankle="AnkleLeft",
        left_toe="FootLeft", spine="Spine", neck="ShoulderCenter", head="Head",
        left_shoulder="ShoulderLeft", left_elbow="ElbowLeft", left_wrist="WristLeft",
        left_hand="HandLeft"),
    _convention(  # no pelvis: the torso centre is the spine, the hips hang from it
        "openni", "OpenNI / NiTE (PrimeSense, Kinect v1 era; XN_SKEL_* names, often as BVH)",
        sensor="kinect_v1", left_hip="LEFT_HIP", left_knee="LEFT_KNEE",
        left_ankle="LEFT_FOOT", spine="TORSO", neck="NECK", head="HEAD",
        left_shoulder="LEFT_SHOULDER", left_elbow="LEFT_ELBOW", left_wrist="LEFT_HAND"),
    _convention(
        "kinect_v2", "Kinect SDK 2.0 (JointType; NTU RGB+D)", sensor="kinect_v2",
        pelvis="SpineBase", left_hip="HipLeft", left_knee="KneeLeft", left_ankle="AnkleLeft",
        left_toe="FootLeft", spine="SpineMid", neck="SpineShoulder", head="Head",
        left_shoulder="ShoulderLeft", left_elbow="ElbowLeft", left_wrist="WristLeft",
        left_hand="HandLeft"),
    _convention(  # SDK 1.0 renamed SPINE_NAVAL (kept for older files) to SPINE_NAVEL
        "azure_kinect", "Azure Kinect Body Tracking (k4abt_joint_id_t)", sensor="kinect_v2",
        pelvis="PELVIS", left_hip="HIP_LEFT", left_knee="KNEE_LEFT", left_ankle="ANKLE_LEFT",
        left_toe="FOOT_LEFT", spine="SPINE_NAVEL|SPINE_NAVAL", neck="NECK", head="HEAD",
        left_shoulder="SHOULDER_LEFT", left_elbow="ELBOW_LEFT", left_wrist="WRIST_LEFT",
        left_hand="HAND_LEFT"),
    _convention(
        "generic", "descriptive names (Hip/Knee/Ankle, Shoulder/Elbow/Wrist, Femur/Tibia)",
        pelvis="Hips|Pelvis|Hip|Root|Waist|HipCenter", left_hip="Hip|UpLeg|UpperLeg|Thigh|Femur",
        left_knee="Knee|LowerLeg|Calf|Shin|Tibia|Leg", left_ankle="Ankle|Foot",
        left_toe="Toe|Toes|ToeBase|Ball|Toe0|Foot", spine="Spine|Spine1|Abdomen|Torso|LowerBack",
        neck="Neck|Neck1", head="Head", left_shoulder="UpperArm|Arm|Humerus|Shoulder",
        left_elbow="ForeArm|LowerArm|Elbow|Radius", left_wrist="Wrist|Hand",
        left_hand="Hand|HandMiddle1|Middle1|FingerBase"),
)


def sensor_family(motion: Motion) -> str | None:
    """The depth-camera family (:attr:`NamingConvention.sensor`) whose convention mapped
    ``motion``'s joints by name (``metadata["joint_map"]["convention"]``), else None."""
    record = motion.metadata.get("joint_map")
    name = record.get("convention") if isinstance(record, Mapping) else None
    return next((c.sensor for c in CONVENTIONS if c.name == name), None)


# Rig prefixes that precede a name with a separator ("Bip01 L Thigh", "Character1_Hips").
_RIG_PREFIX = re.compile(r"^(?:bip0*1|character\d*|jnt|joint|def|mch|org|b)[\s_.\-]+",
                         re.IGNORECASE)
_SEPARATORS = re.compile(r"[\s_.\-:|]+")
_WORDS = re.compile(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+|\d+")
_TIP_WORDS = ("end", "top", "nub", "tip", "site")
_LEFT, _RIGHT = frozenset({"l", "left", "lf", "lft"}), frozenset({"r", "right", "rt", "rgt"})


@dataclass(frozen=True)
class NormalisedName:
    """A joint name reduced to what identifies it: ``side`` (``"left"``, ``"right"`` or
    ``None``) and ``stem`` (lower case, no separators, numbers without leading zeros)."""

    side: str | None
    stem: str


def _strip_prefixes(name: str) -> str:
    tail = re.split(r"[:|]", name)[-1] or name
    stripped = _RIG_PREFIX.sub("", tail)
    return stripped or tail


def normalise(name: str, common_prefix: str = "") -> NormalisedName:
    """Side and stem of a joint name.

    Args:
        name: the joint name as written in the file.
        common_prefix: a prefix all joints of the file share (an actor or take name), removed
            first; see :func:`common_prefix`.
    """
    text = _strip_prefixes(name[len(common_prefix):] if name.startswith(common_prefix) else name)
    side: str | None = None
    # A side letter glued to a capitalised word: OptiTrack "LThigh", "LUArm", Poser "lShldr".
    glued = re.match(r"^([LRlr])([A-Z].*[a-z].*)$", text)
    if glued:
        side = "left" if glued.group(1).lower() == "l" else "right"
        text = glued.group(2)
    words = [w for part in _SEPARATORS.split(text) for w in _WORDS.findall(part)]
    lower = [w.lower() for w in words]
    if side is None:
        for i, w in enumerate(lower):
            rest = lower[:i] + lower[i + 1:]
            edge = i in (0, len(lower) - 1) and any(r.isalpha() for r in rest)
            if w in ("left", "right") or (edge and w in _LEFT | _RIGHT):
                side = "left" if w in _LEFT else "right"
                del lower[i]
                break
    stem = "".join(str(int(w)) if w.isdigit() else w for w in lower)
    return NormalisedName(side, stem)


def common_prefix(names: Sequence[str]) -> str:
    """The prefix every name shares up to and including a separator (``"Actor1_"``,
    ``"Skeleton:"``), or ``""``; never the whole of any name."""
    if len(names) < 2:
        return ""
    shared = names[0]
    for n in names[1:]:
        k = 0
        while k < min(len(shared), len(n)) and shared[k] == n[k]:
            k += 1
        shared = shared[:k]
    cut = max(shared.rfind(c) for c in "_: |.-")
    return shared[:cut + 1] if cut >= 0 and all(len(n) > cut + 1 for n in names) else ""


def _declared(name: str, side: str | None) -> NormalisedName:
    """A convention's (left-side) name as it reads for ``side``."""
    n = normalise(name)
    if n.side is None or side is None:
        return n
    return NormalisedName(side, n.stem)


@dataclass(frozen=True)
class JointMapping:
    """A skeleton's canonical map and how each entry was found.

    Attributes:
        canonical: canonical keypoint -> joint name.
        how: canonical keypoint -> :data:`HOW_NAME` (with the convention, e.g.
            ``"name (unreal_mannequin)"``), :data:`HOW_TOPOLOGY`, :data:`HOW_REST_POSE` or
            :data:`HOW_USER`.
        convention: the naming convention that matched most keypoints, or None.
        notes: what was dropped or decided, and why.
    """

    canonical: dict[str, str]
    how: dict[str, str] = field(default_factory=dict)
    convention: str | None = None
    notes: tuple[str, ...] = ()

    @property
    def missing(self) -> tuple[str, ...]:
        """Canonical keypoints left unmapped."""
        return tuple(k for k in CANONICAL_KEYPOINTS if k not in self.canonical)

    @property
    def maps_body(self) -> bool:
        """Whether a humanoid can be fitted (pelvis and both hips mapped)."""
        return all(k in self.canonical for k in REQUIRED_FOR_BODY)

    def as_metadata(self) -> dict[str, object]:
        """JSON-ready record for ``Motion.metadata["joint_map"]``."""
        return {"convention": self.convention, "canonical": dict(self.canonical),
                "how": dict(self.how), "missing": list(self.missing), "notes": list(self.notes)}


class _Tree:
    """Parent/child lookups of one skeleton."""

    def __init__(self, names: Sequence[str], parents: Sequence[int]) -> None:
        self.names = list(names)
        self.parents = [int(p) for p in parents]
        self.index = {n: i for i, n in enumerate(self.names)}
        self.children: list[list[int]] = [[] for _ in self.names]
        for j, p in enumerate(self.parents):
            if p >= 0:
                self.children[p].append(j)

    def ancestors(self, j: int) -> list[int]:
        """``j`` and its ancestors, ``j`` first."""
        out = [j]
        while self.parents[out[-1]] >= 0:
            out.append(self.parents[out[-1]])
        return out

    def is_ancestor(self, a: int, b: int) -> bool:
        """Whether ``a`` is a strict ancestor of ``b``."""
        return a != b and a in self.ancestors(b)

    def lca(self, a: int, b: int) -> int:
        """Lowest common ancestor (``-1`` when in different trees)."""
        up = set(self.ancestors(a))
        return next((j for j in self.ancestors(b) if j in up), -1)

    def subtree(self, j: int) -> list[int]:
        out, stack = [], [j]
        while stack:
            k = stack.pop()
            out.append(k)
            stack.extend(self.children[k])
        return out

    def path(self, top: int, bottom: int) -> list[int]:
        """Joints from ``top`` down to ``bottom`` (both included); ``top`` must be an
        ancestor of ``bottom`` or equal to it."""
        chain = self.ancestors(bottom)
        return chain[: chain.index(top) + 1][::-1]


_CHAINS: tuple[tuple[str, ...], ...] = tuple(
    (f"{s}_hip", f"{s}_knee", f"{s}_ankle", f"{s}_toe") for s in ("left", "right")
) + tuple((f"{s}_shoulder", f"{s}_elbow", f"{s}_wrist", f"{s}_hand") for s in ("left", "right"))


def _by_names(tree: _Tree, prefix: str) -> tuple[dict[str, str], dict[str, str], str | None]:
    """Keypoints named by the conventions: (canonical, how, best convention)."""
    lookup: dict[NormalisedName, list[str]] = {}
    for n in tree.names:
        lookup.setdefault(normalise(n, prefix), []).append(n)

    def find(convention: NamingConvention, key: str) -> str | None:
        side = "left" if key.startswith("left_") else "right" if key.startswith("right_") else None
        declared = convention.keypoints.get(key.replace("right_", "left_"))
        for alias in declared or ():
            hit = _one_of(tree, lookup.get(_declared(alias, side), []))
            if hit is not None:
                return hit
        return None

    scores = []
    for conv in CONVENTIONS:
        found = {k: j for k in CANONICAL_KEYPOINTS if (j := find(conv, k)) is not None}
        scores.append((len(found), conv, found))
    # On a tie the convention whose namespace the names carry wins (Mixamo's mixamorig:).
    best = max(scores, key=lambda s: (s[0], bool(s[1].prefix) and any(
        n.lower().startswith(s[1].prefix.lower().split(":")[0]) for n in tree.names)))
    if best[0] == 0:
        return {}, {}, None
    canonical: dict[str, str] = {}
    how: dict[str, str] = {}
    used: set[str] = set()
    for _, conv, found in sorted(scores, key=lambda s: -s[0]):
        for k, j in found.items():
            if k not in canonical and j not in used:
                canonical[k], how[k] = j, f"{HOW_NAME} ({conv.name})"
                used.add(j)
    _hand_and_foot_rule(canonical, how, tree)
    return canonical, how, best[1].name


def _one_of(tree: _Tree, hits: list[str]) -> str | None:
    """The joint a name means when several joints share it after normalisation: the one
    above all the others (a rig's helper or twist joint named like its bone hangs below it,
    as SNU MRL's ``Character1_Neck`` > ``Neck``, ``Character1_LeftFoot`` > ``L_Foot``);
    None when no such joint exists (the name is ambiguous)."""
    if len(hits) <= 1:
        return hits[0] if hits else None
    idx = [tree.index[h] for h in hits]
    top = [a for a in idx if all(a == b or tree.is_ancestor(a, b) for b in idx)]
    return tree.names[top[0]] if len(top) == 1 else None


def _hand_and_foot_rule(canonical: dict[str, str], how: dict[str, str], tree: _Tree) -> None:
    """``Hand`` and ``Foot`` name the wrist and the ankle in rigs, but the hand centre and the
    forefoot where a skeleton also names a wrist and an ankle (Kinect, SMPL). So a hand or toe
    that hangs directly from the elbow or knee is the wrist or ankle, and one that lies above
    the wrist or ankle trades places with it."""
    for side in ("left", "right"):
        for upper, outer, inner in (("elbow", "wrist", "hand"), ("knee", "ankle", "toe")):
            u, a, b = (canonical.get(f"{side}_{k}") for k in (upper, outer, inner))
            if a and b and tree.is_ancestor(tree.index[b], tree.index[a]):
                canonical[f"{side}_{outer}"], canonical[f"{side}_{inner}"] = b, a
            elif u and b and not a and tree.parents[tree.index[b]] == tree.index[u]:
                canonical[f"{side}_{outer}"] = canonical.pop(f"{side}_{inner}")
                how[f"{side}_{outer}"] = how.pop(f"{side}_{inner}")


def _check_chains(canonical: dict[str, str], how: dict[str, str], tree: _Tree,
                  notes: list[str]) -> None:
    """Drop keypoints whose joint does not lie below the previous keypoint of its chain."""
    for chain in _CHAINS:
        last: str | None = None
        for key in chain:
            if key not in canonical:
                continue
            if last is not None and not tree.is_ancestor(tree.index[canonical[last]],
                                                         tree.index[canonical[key]]):
                notes.append(f"{key} -> {canonical[key]} dropped: not below {last} -> "
                             f"{canonical[last]} in the hierarchy")
                del canonical[key]
                how.pop(key, None)
                continue
            last = key
    pelvis = canonical.get("pelvis")
    if pelvis is None or any(tree.is_ancestor(tree.index[j], tree.index[pelvis])
                             for j in canonical.values()):
        return  # no pelvis, or a tree not rooted at it (OpenNI skeletons hang from the head)
    for key in [k for k in canonical if k not in ("pelvis",) and not k.endswith(("_shoulder",
                "_elbow", "_wrist", "_hand"))]:
        if not tree.is_ancestor(tree.index[pelvis], tree.index[canonical[key]]):
            notes.append(f"{key} -> {canonical[key]} dropped: not below the pelvis {pelvis}")
            del canonical[key]
            how.pop(key, None)


def _pelvis_by_topology(canonical: dict[str, str], how: dict[str, str], tree: _Tree) -> None:
    """``pelvis`` where the two named hips meet (their lowest common ancestor) when no name
    gives it. OptiTrack Motive 3 names the hip bone after the skeleton asset (``763:763`` in a
    real Gaga dance export, its children ``763:Ab``, ``763:LThigh``), so no convention can; the
    rest-pose step that ran instead took a straight knee for part of the thigh. Not when that
    joint already stands for another keypoint (OpenNI's hips hang from the torso, the spine)."""
    left, right = canonical.get("left_hip"), canonical.get("right_hip")
    if "pelvis" in canonical or left is None or right is None:
        return
    hub = tree.lca(tree.index[left], tree.index[right])
    if hub >= 0 and tree.names[hub] not in canonical.values():
        canonical["pelvis"], how["pelvis"] = tree.names[hub], HOW_TOPOLOGY


def _spine_by_topology(canonical: dict[str, str], how: dict[str, str], tree: _Tree,
                       rest: np.ndarray | None) -> None:
    """``chest`` where the arms leave the spine; ``spine`` the first joint above the pelvis.

    A joint the names call the spine that is itself where the arms leave it is the chest:
    a minimal rig's only trunk joint (PyMO's demo walk: ``Hips -> Spine``, the head and
    both arms on ``Spine``) carries the shoulders, and fitted as the lumbar it bent the
    chest 40 deg to reach them. The spine is then whatever lies between it and the pelvis.
    """
    ls, rs, pelvis = (canonical.get(k) for k in ("left_shoulder", "right_shoulder", "pelvis"))
    if ls and rs and "chest" not in canonical:
        hub = tree.lca(tree.index[ls], tree.index[rs])
        neck = canonical.get("neck")
        if neck is not None and hub == tree.index[neck]:
            hub = tree.parents[hub]  # clavicles on the neck (3ds Max Biped)
        elif (hub >= 0 and canonical.get("spine") == tree.names[hub] and pelvis is not None
              and tree.is_ancestor(tree.index[pelvis], hub)):
            del canonical["spine"]
            how.pop("spine", None)
        taken = {canonical[k] for k in ("pelvis", "spine", "neck") if k in canonical}
        if (hub >= 0 and tree.names[hub] not in taken and pelvis is not None
                and tree.is_ancestor(tree.index[pelvis], hub)):
            canonical["chest"], how["chest"] = tree.names[hub], HOW_TOPOLOGY
    chest = canonical.get("chest")
    if pelvis and chest and "spine" not in canonical:
        between = tree.path(tree.index[pelvis], tree.index[chest])[1:-1]
        if rest is not None:
            size = float(np.linalg.norm(rest[tree.index[chest]] - rest[tree.index[pelvis]]))
            between = [j for j in between
                       if np.linalg.norm(rest[j] - rest[tree.index[pelvis]]) > 0.15 * size]
        if between:
            canonical["spine"], how["spine"] = tree.names[between[0]], HOW_TOPOLOGY


def _ends_by_topology(canonical: dict[str, str], how: dict[str, str], tree: _Tree,
                      rest: np.ndarray, exclude: set[str] | frozenset[str] = frozenset()
                      ) -> None:
    """A hand or toe the names did not give: the first joint at least 3 % of the body's
    height beyond the wrist or ankle, along the child that reaches furthest (the middle
    finger's knuckle, the ball of the foot); never one of ``exclude``."""
    size = float(np.ptp(rest[:, 2])) or 1.0
    for side in ("left", "right"):
        for outer, inner in (("wrist", "hand"), ("ankle", "toe")):
            base = canonical.get(f"{side}_{outer}")
            if base is None or f"{side}_{inner}" in canonical:
                continue
            j = _distal(tree, tree.index[base], rest, 0.03 * size)
            if (j is not None and tree.names[j] not in canonical.values()
                    and tree.names[j] not in exclude):
                canonical[f"{side}_{inner}"], how[f"{side}_{inner}"] = tree.names[j], HOW_TOPOLOGY


def _drop_stray_ends(canonical: dict[str, str], how: dict[str, str], tree: _Tree,
                     pos: np.ndarray, notes: list[str]) -> set[str]:
    """Drop a hand or toe that is no hand or forefoot (medians over the clip): one farther
    from the wrist or ankle than the forearm or shank is long (a rig's stray end: SNU MRL's
    MASS walk, ``Character1_RightHand_end`` 1.6 m off the wrist), or one within a tenth of
    that length of it (a stub End Site on the joint: MASS's left hands, 1 cm off; a hand
    keypoint there says nothing of where the hand is, so the hand is not judged as placed
    by the source). The topology step may then find a better one.

    Args:
        pos: (T, J, 3) positions, metres.

    Returns:
        The joints dropped.
    """
    dropped: set[str] = set()
    for side in ("left", "right"):
        for upper, outer, inner in (("elbow", "wrist", "hand"), ("knee", "ankle", "toe")):
            u, a, b = (canonical.get(f"{side}_{k}") for k in (upper, outer, inner))
            if not (u and a and b):
                continue
            iu, ia, ib = (tree.index[j] for j in (u, a, b))
            limb = float(np.median(np.linalg.norm(pos[:, ia] - pos[:, iu], axis=-1)))
            end = float(np.median(np.linalg.norm(pos[:, ib] - pos[:, ia], axis=-1)))
            if limb <= 0 or 0.1 * limb <= end <= limb:
                continue
            what = (f"longer than the {upper}-{outer} segment" if end > limb
                    else f"under a tenth of the {upper}-{outer} segment")
            notes.append(f"{side}_{inner} -> {b} dropped: {end:.3f} m from the {outer}, "
                         f"{what} ({limb:.2f} m)")
            del canonical[f"{side}_{inner}"]
            how.pop(f"{side}_{inner}", None)
            dropped.add(b)
    return dropped


def _note_crossed_arms(canonical: Mapping[str, str], tree: _Tree, pos: np.ndarray,
                       notes: list[str]) -> None:
    """Say when the shoulders face the other way from the hips on most frames: the left
    shoulder keypoint on the right of the right one, seen along the up axis (Z) across the
    hip line. No trunk twists past 90 degrees, so the file's arm chains cross over (arm
    labels swapped, or clavicle rotations flipped by the capture's solve: FAIR's
    ``5yr_old/skipping``, clavicles turned ~180 degrees, shoulder line 173 degrees from the
    hip line); the map is kept as named, the note says why the fit will twist the spine.

    Args:
        pos: (T, J, 3) positions, metres, Z up.
    """
    keys = ("left_hip", "right_hip", "left_shoulder", "right_shoulder")
    if not all(k in canonical for k in keys):
        return
    lh, rh, ls, rs = (pos[:, tree.index[canonical[k]], :2] for k in keys)
    hips, shoulders = lh - rh, ls - rs
    cross = hips[:, 0] * shoulders[:, 1] - hips[:, 1] * shoulders[:, 0]
    turn = np.degrees(np.abs(np.arctan2(cross, np.einsum("ti,ti->t", hips, shoulders))))
    crossed = float(np.mean(turn > 90.0))
    if crossed > 0.5:
        notes.append(f"the arms cross over: the shoulder line ({canonical['left_shoulder']} - "
                     f"{canonical['right_shoulder']}) faces away from the hip line on "
                     f"{100 * crossed:.0f} % of frames ({np.median(turn):.0f} deg median); no "
                     "trunk twists that far: the file's arm labels or clavicle rotations look "
                     "swapped")


def _segments(chain: list[int], pos: np.ndarray) -> list[tuple[int, int, float]]:
    """The chain cut into straight segments (start, end, length in metres): consecutive bones
    within 5 degrees of each other over the clip are one segment (twist and roll joints lie on
    the bone they split); a joint on top of its parent stands for the parent.

    Args:
        pos: (T, J, 3) positions, metres.
    """
    segs: list[list[int]] = []
    first_of: dict[int, int] = {}
    for a, b in zip(chain[:-1], chain[1:], strict=True):
        a = first_of.get(a, a)
        d = pos[:, b] - pos[:, a]
        if np.median(np.linalg.norm(d, axis=-1)) < 1e-4:
            first_of[b] = a
            continue
        if segs:
            prev = pos[:, segs[-1][1]] - pos[:, segs[-1][0]]
            cos = np.einsum("ti,ti->t", prev, d) / (
                np.linalg.norm(prev, axis=-1) * np.linalg.norm(d, axis=-1) + 1e-12)
            if np.median(cos) > np.cos(np.radians(5.0)):
                segs[-1][1] = b
                continue
        segs.append([a, b])
    return [(a, b, float(np.median(np.linalg.norm(pos[:, b] - pos[:, a], axis=-1))))
            for a, b in segs]


#: How many times longer than every other segment of a leg its longest one must be to be
#: thigh and shin in one: those two are about one length, so together twice a shin, and no
#: hip bone or foot is as long as a shin. Measured on real legs: bent ones' longest segment
#: is at most 1.35 times the next, straight ones' merged thigh and shin 4.9 times or more.
_KNEE_SPLIT = 2.0


def _split_straight_knee(tree: _Tree, segs: list[tuple[int, int, float]], pos: np.ndarray
                         ) -> list[tuple[int, int, float]]:
    """A leg's segments with a straight knee's thigh-and-shin segment cut at the knee.

    Thigh and shin are a leg's two long bones, of about one length (their ratio is near 1 in
    every body and rig), each longer than the hip bone, the foot or the toes. A straight knee
    (a T-pose, a standing clip: under the 5 degrees :func:`_segments` merges at) makes them one
    segment over twice as long as any other, and the limb's first two segments would be the
    whole leg and the foot (knee on the ankle joint, ankle on the toe). So a segment at least
    :data:`_KNEE_SPLIT` times as long as every other one of the chain is cut at the joint
    inside it nearest its middle, the knee, if one lies within its middle 40 %.

    Args:
        segs: the chain's straight segments (start, end, length in metres), :func:`_segments`.
        pos: (T, J, 3) positions, metres.
    """
    if not segs:
        return segs
    i = max(range(len(segs)), key=lambda k: segs[k][2])
    length = segs[i][2]
    if any(_KNEE_SPLIT * s[2] > length for k, s in enumerate(segs) if k != i):
        return segs
    knee = _middle_joint(_inside(tree, segs[i], pos))
    return segs if knee is None else _cut(segs, i, [knee], pos)


def _inside(tree: _Tree, seg: tuple[int, int, float], pos: np.ndarray) -> dict[int, float]:
    """The joints inside a straight segment (none on top of its parent) -> how far along it
    each lies, as a fraction of its length (medians over the clip).

    Args:
        seg: (start, end, length in metres), :func:`_segments`.
        pos: (T, J, 3) positions, metres.
    """
    a, b, length = seg
    return {j: float(np.median(np.linalg.norm(pos[:, j] - pos[:, a], axis=-1))) / length
            for j in tree.path(a, b)[1:-1]
            if np.median(np.linalg.norm(pos[:, j] - pos[:, tree.parents[j]], axis=-1)) >= 1e-4}


def _middle_joint(frac: dict[int, float]) -> int | None:
    """Of a segment's inside joints (:func:`_inside`), the one nearest its middle, if it lies
    within the segment's middle 40 % (a knee or an elbow of a straight limb); else None."""
    if not frac:
        return None
    joint = min(frac, key=lambda j: abs(frac[j] - 0.5))
    return joint if abs(frac[joint] - 0.5) <= 0.2 else None


def _cut(segs: list[tuple[int, int, float]], i: int, joints: list[int], pos: np.ndarray
         ) -> list[tuple[int, int, float]]:
    """``segs`` with segment ``i`` cut at ``joints`` (inside it, in any order)."""
    a, b, _ = segs[i]
    ends = [a, *sorted(joints, key=lambda j: float(np.median(
        np.linalg.norm(pos[:, j] - pos[:, a], axis=-1)))), b]
    parts = [(s, e, float(np.median(np.linalg.norm(pos[:, e] - pos[:, s], axis=-1))))
             for s, e in zip(ends[:-1], ends[1:], strict=True)]
    return [*segs[:i], *parts, *segs[i + 1:]]


#: Share of an arm chain's length (from the chest to its farthest leaf: clavicle, upper arm,
#: forearm, hand) above which one straight segment holds both long bones, a straight elbow.
#: Measured on 100 real arms (26 clips, 24 skeletons' zero-rotation rests): an upper arm alone
#: is at most 0.46 of its chain (CMU 05_02, a short forearm), a straight elbow's merged
#: segment at least 0.68.
_ELBOW_SPLIT = 0.56


def _split_straight_arm(tree: _Tree, segs: list[tuple[int, int, float]], pos: np.ndarray
                        ) -> list[tuple[int, int, float]]:
    """An arm's segments with a straight elbow's segment cut at the elbow (a T-pose).

    The upper arm and the forearm are an arm's two long bones; with the elbow straight
    (under the 5 degrees :func:`_segments` merges at) they are one segment, with the hand too
    when the wrist is straight, and the limb's first two segments would be the clavicle and
    the whole arm (shoulder on the clavicle, elbow on the shoulder, wrist on the fingertips).
    So a segment over :data:`_ELBOW_SPLIT` of the chain's length is cut at the joint inside
    it nearest its middle, the elbow, if one lies within its middle 40 %. When that segment
    starts the chain, the clavicle lies straight in it too (no girdle segment before it):
    it is also cut at the shoulder, the last joint before the middle of the part above the
    elbow (a clavicle is shorter than an upper arm). The wrist is found by :func:`_limb`.

    Args:
        segs: the chain's straight segments (start, end, length in metres), :func:`_segments`.
        pos: (T, J, 3) positions, metres.
    """
    if not segs:
        return segs
    i = max(range(len(segs)), key=lambda k: segs[k][2])
    if segs[i][2] < _ELBOW_SPLIT * sum(s[2] for s in segs):
        return segs
    frac = _inside(tree, segs[i], pos)
    elbow = _middle_joint(frac)
    if elbow is None:
        return segs
    cuts = [elbow]
    above = [j for j in frac if frac[j] < 0.5 * frac[elbow]]
    if i == 0 and above:
        cuts.append(max(above, key=lambda j: frac[j]))
    return _cut(segs, i, cuts, pos)


def _limb(tree: _Tree, hub: int, start: int, leaf: int, pos: np.ndarray, leg: bool = False
          ) -> tuple[int, int, int] | None:
    """(proximal joint, middle joint, distal joint) of the limb that leaves ``hub`` at
    ``start`` and ends at ``leaf``: its first two straight segments, after a girdle bone
    (clavicle, hip bone): a first segment that starts on the hub itself or is shorter than
    each of the two after it. A straight knee or elbow is found by bone lengths
    (:func:`_split_straight_knee`, :func:`_split_straight_arm`), not by its bend; an arm's
    wrist is the first joint past the middle of its second segment (a straight wrist puts
    the hand in the forearm's segment, and the hand, fingers included, is shorter than the
    forearm)."""
    segs = _segments(tree.path(start, leaf), pos)
    segs = (_split_straight_knee if leg else _split_straight_arm)(tree, segs, pos)
    if len(segs) >= 3:
        gap = float(np.median(np.linalg.norm(pos[:, segs[0][0]] - pos[:, hub], axis=-1)))
        if gap < 0.1 * segs[0][2] or segs[0][2] < min(segs[1][2], segs[2][2]):
            segs = segs[1:]
    if len(segs) < 2:
        return None
    if not leg:
        frac = _inside(tree, segs[1], pos)
        past = [j for j in frac if frac[j] > 0.5]
        if past:
            return segs[0][0], segs[0][1], min(past, key=lambda j: frac[j])
    return segs[0][0], segs[0][1], segs[1][1]


#: Bone-length difference of two chest branches (sum of the differences of their sorted bone
#: lengths over their mean total) under which they are a body's two arms. Measured on 50 real
#: skeletons: arms at most 0.055 apart (CMU solves' left and right differ by a few %) but for
#: SNU MASS's walk (0.80: a 1.6 m stray hand end on one side; reach decides there), a head
#: branch of as many joints as an arm 0.21 from it (Azure Kinect's face joints).
_ARM_PAIR = 0.15


def _arm_pair(tree: _Tree, branches: list[int], pos: np.ndarray) -> list[int] | None:
    """The chest branches that are the arms: the two alike ones (as many joints, bone lengths
    within :data:`_ARM_PAIR`), the longest such pair; None when no two are alike.

    The arms are mirror images, the head branch is not: it differs in its joints (eyes, a
    head top) and lengths. Reach from the chest alone tells them apart in a T-pose but not
    when the hands stay near the chest (a salsa couple's arms bent in hold: the head's
    eyes reach farther than a hand).

    Args:
        branches: children of the chest, in the order to prefer on a tie.
        pos: (T, J, 3) positions, metres.
    """
    def bones(c: int) -> np.ndarray:
        return np.sort([float(np.median(np.linalg.norm(pos[:, s] - pos[:, tree.parents[s]],
                                                        axis=-1))) for s in tree.subtree(c)])

    lengths = {c: bones(c) for c in branches}
    best: tuple[float, list[int]] | None = None
    for k, a in enumerate(branches):
        for b in branches[k + 1:]:
            la, lb = lengths[a], lengths[b]
            if len(la) != len(lb):
                continue
            total = 0.5 * float(la.sum() + lb.sum())
            if float(np.abs(la - lb).sum()) <= _ARM_PAIR * total and (best is None
                                                                       or total > best[0]):
                best = (total, [a, b])
    return best[1] if best else None


def _distal(tree: _Tree, j: int, rest: np.ndarray, min_len: float) -> int | None:
    """The first joint below ``j`` at least ``min_len`` from it, following the child with the
    most joints below it, then the one reaching furthest (the fingers rather than the thumb,
    the middle finger, the toes); else the last joint of that path if it is at least a fifth
    of ``min_len`` away (a short hand), else None."""
    k = j
    while tree.children[k]:
        k = max(tree.children[k], key=lambda c: (len(tree.subtree(c)), max(
            float(np.linalg.norm(rest[s] - rest[j])) for s in tree.subtree(c))))
        if np.linalg.norm(rest[k] - rest[j]) >= min_len:
            return k
    return k if k != j and np.linalg.norm(rest[k] - rest[j]) >= 0.2 * min_len else None


def _side_of(tree: _Tree, j: int, prefix: str) -> str | None:
    return normalise(tree.names[j], prefix).side


def _by_rest_pose(tree: _Tree, positions: np.ndarray, prefix: str,
                  notes: list[str]) -> tuple[dict[str, str], dict[str, str]]:
    """Keypoints from the hierarchy and the pose alone (module docstring, step 3).

    Args:
        positions: (T, J, 3) metres, Z up (or (J, 3)).
    """
    pos = positions.reshape(-1, len(tree.names), 3)
    rest = np.median(pos - pos[:, :1], axis=0)
    height = np.median(pos[..., 2], axis=0)
    leaves = [j for j in range(len(tree.names)) if not tree.children[j]]
    if len(leaves) < 5:
        return {}, {}
    feet = sorted(leaves, key=lambda j: height[j])
    a = feet[0]
    b = next((j for j in feet[1:] if tree.lca(a, j) not in (a, j)
              and tree.lca(a, j) not in tree.ancestors(a)[:2]), None)
    if b is None:
        return {}, {}
    hub = tree.lca(a, b)
    body = max(float(np.ptp(rest[:, 2])), 1e-6)
    legs = []
    for leaf in (a, b):
        first = tree.path(hub, leaf)[1]
        limb = _limb(tree, hub, first, leaf, pos, leg=True)
        if limb is None:
            return {}, {}
        toe = _distal(tree, limb[2], rest, 0.03 * body)
        legs.append((limb, toe))
    others = [c for c in tree.children[hub] if not (set(tree.subtree(c)) & {a, b})]
    if not others:
        return {}, {}
    spine_root = max(others, key=lambda c: max(height[s] for s in tree.subtree(c)))
    chest = spine_root
    while True:
        big = [c for c in tree.children[chest]
               if max(np.linalg.norm(rest[s] - rest[chest]) for s in tree.subtree(c)) > 0.08 * body]
        if len(big) >= 2 or not tree.children[chest]:
            break
        chest = big[0] if big else tree.children[chest][0]
    if len(big) < 2:
        return {}, {}

    def reach(c: int) -> float:
        return max(float(np.linalg.norm(rest[s] - rest[chest])) for s in tree.subtree(c))

    branches = sorted(big, key=reach, reverse=True)
    arm_roots = _arm_pair(tree, branches, pos) or branches[:2]
    others = [c for c in branches if c not in arm_roots]
    head_root = others[0] if others else None
    arms = []
    for root in arm_roots:
        # The arm's end is a leaf (a bent elbow, hands in front of the chest, is farther
        # from the chest than the hand) and one of the deepest: the fingers, not a helper
        # hanging from the upper arm (SNU MASS's L_Humerus, 0.5 m long, beyond a bent hand).
        leaf = max((s for s in tree.subtree(root) if not tree.children[s]),
                   key=lambda s: (len(tree.ancestors(s)),
                                  float(np.linalg.norm(rest[s] - rest[chest]))))
        limb = _limb(tree, chest, root, leaf, pos)
        if limb is None:
            return {}, {}
        hand = _distal(tree, limb[2], rest, 0.03 * body)
        arms.append((limb, hand))

    up = rest[chest] - rest[hub]
    up /= np.linalg.norm(up) + 1e-12
    sides = _sides(tree, legs, arms, pos, up, prefix, notes)
    if sides is None:
        return {}, {}
    leg_sides, arm_sides = sides
    canonical: dict[str, str] = {"pelvis": tree.names[hub], "chest": tree.names[chest]}
    for (limb, toe), side in zip(legs, leg_sides, strict=True):
        for key, j in zip(("hip", "knee", "ankle"), limb, strict=True):
            canonical[f"{side}_{key}"] = tree.names[j]
        if toe is not None:
            canonical[f"{side}_toe"] = tree.names[toe]
    for (limb, hand), side in zip(arms, arm_sides, strict=True):
        for key, j in zip(("shoulder", "elbow", "wrist"), limb, strict=True):
            canonical[f"{side}_{key}"] = tree.names[j]
        if hand is not None:
            canonical[f"{side}_hand"] = tree.names[hand]
    if head_root is not None:
        chain = tree.path(head_root, max(tree.subtree(head_root), key=lambda s: height[s]))
        tip = normalise(tree.names[chain[-1]], prefix).stem.endswith(_TIP_WORDS)
        head = len(chain) - (2 if (tip or _face_pair(tree, chain, pos)) and len(chain) >= 2
                             else 1)
        canonical["head"] = tree.names[chain[head]]
        if head > 0:
            canonical["neck"] = tree.names[chain[0]]
    return canonical, {k: HOW_REST_POSE for k in canonical}


def _face_pair(tree: _Tree, chain: list[int], pos: np.ndarray) -> bool:
    """Whether the head chain's highest joint is an eye or an ear: a leaf with a leaf beside
    it as long within 10 % (its mirror image). Eyes and ears sit above the head joint they
    hang from (a Poser rig's ``leftEye``/``rightEye``, Azure Kinect's face), a head top
    nothing mirrors (SNU MASS's head beside a 1 cm mesh helper, 9 times shorter).

    Args:
        chain: the head branch, from the chest's child down to its highest joint.
        pos: (T, J, 3) positions, metres.
    """
    top = chain[-1]
    if len(chain) < 2 or tree.children[top]:
        return False

    def bone(j: int) -> float:
        return float(np.median(np.linalg.norm(pos[:, j] - pos[:, tree.parents[j]], axis=-1)))

    return any(c != top and not tree.children[c] and abs(bone(c) - bone(top)) <= 0.1 * bone(top)
               for c in tree.children[chain[-2]])


def _sides(tree: _Tree, legs: list, arms: list, pos: np.ndarray, up: np.ndarray, prefix: str,
           notes: list[str]) -> tuple[tuple[str, str], tuple[str, str]] | None:
    """Left/right of the two legs and the two arms: from side tokens when both limbs of a
    pair carry opposite ones, else from the body frame (left = up x forward)."""
    def named(pair_first: list[int]) -> tuple[str, str] | None:
        s = [_side_of(tree, j, prefix) for j in pair_first]
        return (s[0], s[1]) if None not in s and s[0] != s[1] else None  # type: ignore[return-value]

    leg_sides = named([legs[0][0][1], legs[1][0][1]])
    arm_sides = named([arms[0][0][1], arms[1][0][1]])
    if leg_sides and arm_sides:
        return leg_sides, arm_sides
    forward = np.zeros(3)
    for (hip, knee, ankle), toe in legs:
        if toe is not None:
            forward += (pos[:, toe] - pos[:, ankle]).mean(axis=0)
        else:  # knees bend forward: knee ahead of the hip-ankle line
            mid = 0.5 * (pos[:, hip] + pos[:, ankle])
            forward += (pos[:, knee] - mid).mean(axis=0)
    forward -= (forward @ up) * up
    if np.linalg.norm(forward) < 1e-6:
        notes.append("left and right could not be told: no side in the names, no foot or "
                     "knee direction in the motion")
        return None
    left = np.cross(up, forward / np.linalg.norm(forward))
    centre = pos.mean(axis=(0, 1))

    def by_geometry(a: int, b: int) -> tuple[str, str]:
        da = float(((pos[:, a] - centre) @ left).mean())
        db = float(((pos[:, b] - centre) @ left).mean())
        return ("left", "right") if da > db else ("right", "left")

    notes.append("left/right told from the body frame (feet point forward), not from names")
    # Knees and elbows: the limbs' roots may share one point (collapsed clavicles).
    return (leg_sides or by_geometry(legs[0][0][1], legs[1][0][1]),
            arm_sides or by_geometry(arms[0][0][1], arms[1][0][1]))


def infer_joint_map(names: Sequence[str], parents: Sequence[int],
                    positions: np.ndarray | None = None) -> JointMapping:
    """The canonical map of a skeleton from its joint names, hierarchy and motion.

    Args:
        names: (J,) joint names as in the file.
        parents: (J,) parent index per joint, ``-1`` for roots; parents precede children.
        positions: (T, J, 3) or (J, 3) joint positions, metres, Z up; needed for the
            rest-pose step and for telling spine joints from the pelvis. Without it only the
            names and the hierarchy are used.

    Returns:
        The mapping, with how each keypoint was found (see the module docstring).
    """
    tree = _Tree(names, parents)
    prefix = common_prefix(list(names))
    notes: list[str] = []
    canonical, how, convention = _by_names(tree, prefix)
    _pelvis_by_topology(canonical, how, tree)
    rest = None
    if positions is not None:
        pos = np.asarray(positions, dtype=np.float64).reshape(-1, len(names), 3)
        rest = np.median(pos, axis=0)
    if not all(k in canonical for k in REQUIRED_FOR_BODY) and positions is not None:
        found, found_how = _by_rest_pose(tree, np.asarray(positions, dtype=np.float64), prefix,
                                         notes)
        if all(k in found for k in REQUIRED_FOR_BODY):
            named = {k: v for k, v in canonical.items() if v not in found.values()}
            canonical, how = dict(found), dict(found_how)
            for k, v in named.items():
                if k not in canonical:
                    canonical[k] = v
                    how[k] = f"{HOW_NAME} ({convention})"
            notes.append("names did not give the pelvis and both hips: the legs, spine, arms "
                         "and head were found from the hierarchy and the pose")
    _check_chains(canonical, how, tree, notes)
    _spine_by_topology(canonical, how, tree, rest)
    stray = (_drop_stray_ends(canonical, how, tree, pos, notes) if positions is not None
             else set())
    if positions is not None:
        _note_crossed_arms(canonical, tree, pos, notes)
    if rest is not None:
        _ends_by_topology(canonical, how, tree, rest, stray)
    ordered = {k: canonical[k] for k in CANONICAL_KEYPOINTS if k in canonical}
    return JointMapping(ordered, {k: how[k] for k in ordered}, convention, tuple(notes))


# -- user maps ----------------------------------------------------------------------------


def read_joint_map(source: JointMapSource) -> dict[str, str]:
    """A user's joint map: canonical keypoint -> joint name.

    Args:
        source: a TOML file with a ``[canonical]`` table (``left_hip = "UpperLeg_L"``; see
            :func:`joint_map_template`), or the mapping itself.

    Raises:
        SkeletonError: unreadable file, TOML syntax, no ``[canonical]`` table, an unknown
            keypoint or a value that is not a joint name (naming the file and the field).
    """
    where: str | None = None
    if isinstance(source, Mapping):
        table: object = dict(source)
    else:
        path = Path(source)
        where = str(path)
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except OSError as exc:
            raise SkeletonError(f"cannot read the joint map: {exc.strerror or exc}",
                                source=path) from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise SkeletonError(f"not a TOML joint map: {exc}", source=path) from None
        table = data.get("canonical")
        if table is None:
            raise SkeletonError("expected a [canonical] table (keypoint = \"joint name\")",
                                source=path, field="canonical")
    if not isinstance(table, dict):
        raise SkeletonError("the joint map must be a table of keypoint = \"joint name\"",
                            source=where, field="canonical")
    out: dict[str, str] = {}
    for key, joint in table.items():
        if key not in CANONICAL_TREE:
            raise SkeletonError(f"unknown canonical keypoint {key!r}; known: "
                                f"{', '.join(CANONICAL_KEYPOINTS)}", source=where, field=key)
        if not isinstance(joint, str) or not joint:
            raise SkeletonError(f"expected a joint name (a string) for {key}, got {joint!r}",
                                source=where, field=key)
        out[key] = joint
    return out


def apply_user_map(names: Sequence[str], user: Mapping[str, str],
                   source: str | None = None) -> JointMapping:
    """The user's map checked against the skeleton's joints.

    Raises:
        SkeletonError: a mapped joint is not in the skeleton (listing its joints).
    """
    known = set(names)
    for key, joint in user.items():
        if joint not in known:
            raise SkeletonError(
                f"joint map: {key} = {joint!r}, but the skeleton has no such joint; its joints "
                f"are {', '.join(names)}", source=source, field=key)
    ordered = {k: user[k] for k in CANONICAL_KEYPOINTS if k in user}
    return JointMapping(ordered, {k: HOW_USER for k in ordered}, None, ())


def user_joint_mapping(names: Sequence[str], joint_map: JointMapSource,
                       source: str | None = None) -> JointMapping:
    """The user's ``joint_map`` (:func:`read_joint_map`) checked against ``names``
    (:func:`apply_user_map`; errors name the map file, else ``source``), noting the file."""
    where = None if isinstance(joint_map, Mapping) else str(joint_map)
    mapping = apply_user_map(names, read_joint_map(joint_map), source=where or source)
    return replace(mapping, notes=(f"from {where}",)) if where else mapping


_KEYPOINT_HELP: dict[str, str] = {
    "pelvis": "root of the trunk, between the hips",
    "spine": "lower back (lumbar)", "chest": "upper back, where the arms leave the spine",
    "neck": "base of the neck", "head": "head (base of the skull)",
    "hip": "hip joint centre", "knee": "knee joint centre", "ankle": "ankle joint centre",
    "toe": "ball of the foot", "shoulder": "shoulder joint (not the clavicle)",
    "elbow": "elbow joint", "wrist": "wrist joint", "hand": "knuckles / hand centre",
}


def joint_map_template(names: Sequence[str], mapping: JointMapping | None = None,
                       source: str | None = None) -> str:
    """A ready-to-edit TOML joint map for a skeleton: every canonical keypoint, pre-filled
    where ``mapping`` has it (commented out where not), and the skeleton's joints listed.
    Pass the edited file to ``--joint-map`` or ``simenv.load(..., joint_map=FILE)``."""
    canonical = mapping.canonical if mapping else {}
    lines = ["# simenv joint map" + (f" for {source}" if source else ""),
             "# canonical keypoint = \"joint name in the file\"; comment a line out to leave",
             "# a keypoint unmapped. pelvis, left_hip and right_hip are needed for a body.",
             "# The skeleton's joints:"]
    row = "#  "
    for n in names:
        if len(row) + len(n) > 92:
            lines.append(row.rstrip(", "))
            row = "#  "
        row += f"{n}, "
    lines += [row.rstrip(", "), "", "[canonical]"]
    for key in CANONICAL_KEYPOINTS:
        what = _KEYPOINT_HELP[key.split("_", 1)[1] if "_" in key else key]
        if key in canonical:
            lines.append(f"{key} = \"{canonical[key]}\"".ljust(40) + f"# {what}")
        else:
            lines.append(f"# {key} = \"\"".ljust(40) + f"# {what}")
    return "\n".join(lines) + "\n"


def remap_motion(motion: Motion, mapping: JointMapping) -> Motion:
    """``motion`` with its skeleton's canonical map replaced by ``mapping`` (joints, positions
    and rotations unchanged), recorded in ``metadata["joint_map"]``."""
    sk = motion.skeleton
    skeleton = Skeleton(sk.name, sk.joint_names, sk.parents, mapping.canonical)
    meta = dict(motion.metadata)
    meta["joint_map"] = mapping.as_metadata()
    return replace(motion, skeleton=skeleton, metadata=meta)


def map_motion(motion: Motion, joint_map: JointMapSource | None = None) -> Motion:
    """``motion`` mapped onto the canonical keypoints: by the user's ``joint_map`` (a TOML
    file or a mapping, see :func:`read_joint_map`) when given; otherwise, when the reader
    left the pelvis or a hip unmapped, by :func:`infer_joint_map` (kept only if it maps more
    keypoints). A motion the reader mapped fully is returned as it is.

    Raises:
        SkeletonError: a bad user map (naming the file, the keypoint and the joints).
    """
    names = motion.skeleton.joint_names
    recorded = motion.metadata.get("joint_map")
    if joint_map is not None:
        if recorded and set(recorded["how"].values()) == {HOW_USER}:
            return motion  # the reader applied it (BVH: End Sites can be mapped there)
        return remap_motion(motion, user_joint_mapping(names, joint_map))
    if recorded is not None or all(k in motion.skeleton.canonical
                                   for k in REQUIRED_FOR_BODY):
        return motion
    mapping = infer_joint_map(names, motion.skeleton.parents, motion.positions)
    if len(mapping.canonical) <= len(motion.skeleton.canonical):
        return motion
    return remap_motion(motion, mapping)


__all__ = ["CONVENTIONS", "HOW_NAME", "HOW_REST_POSE", "HOW_TOPOLOGY", "HOW_USER",
           "JOINT_MAP_HELP", "REQUIRED_FOR_BODY", "JointMapSource", "JointMapping",
           "NamingConvention", "NormalisedName", "apply_user_map", "common_prefix",
           "infer_joint_map", "joint_map_template", "map_motion", "normalise", "read_joint_map",
           "remap_motion", "user_joint_mapping"]

"""Joint definitions reconciled across sensors, for the gesture recogniser's input.

The gesture joints (``gesture15``) are named alike in every dataset, but the trunk joints
are not the same points of the body. Measured on the normalised windows of the corpus
(first 60 frames of every clip, median, metres of the reference body; issue 34):

=============== ============== ================= ================= ============
dataset, sensor spine -> neck  neck above the    hip centre below  hip width
                               shoulders         the spine
=============== ============== ================= ================= ============
Florence 3D     0.197          0.00              0.194             0.189
(OpenNI-15)     (``Torso``,    (``Neck`` = mid-
                mid-trunk)     shoulders)
MSR Action3D    0.258, leaning 0.07              0.176, 0.15 m     0.33
(Kinect v1 SDK  34 deg forward                   *in front of* the
beta)           (its ``Spine``                   spine
                lies behind
                the body)
MSRC-12         0.384          0.12              0.146             0.159
(Kinect v1)
UTKinect        0.349          0.10              0.145             0.157
(Kinect v1)
=============== ============== ================= ================= ============

So a network reading ``spine`` and ``neck`` reads which sensor recorded a person -- and the
window normalisation (:func:`simenv.data.gestures.normalise_windows`) puts its origin at
``spine``, so every joint's position carries the offset; the hips are 0.44 (Kinect v1) to
0.98 (MSR) shoulder widths apart. :func:`reconcile_joints` redefines the trunk joints from
what every sensor places alike -- the shoulders, and the hip centre and hip axis (the
body's midline and its left-right direction) --, per frame:

    neck'  = (l_shoulder + r_shoulder) / 2
    spine' = h + SPINE_FRACTION (neck' - h),     h = (l_hip + r_hip) / 2
    hip'   = h ± HIP_WIDTH_RATIO |l_shoulder - r_shoulder| / 2 · (l_hip - r_hip) / |l_hip - r_hip|

and moves the window so that the mean ``spine'`` over its first
:data:`~simenv.data.gestures.NORM_FRAMES` valid frames is the origin, as the
normalisation does with ``spine``. The definitions are built from joint positions,
midpoints and a length ratio, so the result does not depend on where, how turned, or how
large the body was before (translation, rotation and uniform scale commute with them) --
applied to normalised windows it equals normalising reconciled ones -- and barely on the
frame rate (linear resampling commutes with the affine ``neck'`` and ``spine'`` exactly,
with the hips to a fraction of a millimetre).
:data:`SPINE_FRACTION` = 0.3 is where Kinect v1 puts its ``Spine`` (0.145 of
0.49 m from the hip centre to the shoulder centre), and :data:`HIP_WIDTH_RATIO` = 0.5 near
its hip width (0.44-0.45 shoulder widths), so the Kinect v1 data move least.

Bone lengths still differ by sensor and person (thigh 0.42 m of the reference body in
Florence 3D, 0.50-0.54 in the Kinect v1 sets, with the arms scaled alike).
:func:`reference_bones` keeps every bone's direction and gives it the length of
:data:`REFERENCE_BONES_M`, walking the tree from ``spine`` -- the recogniser's view of a
body retargeted onto one reference skeleton. It works on normalised windows (lengths in
metres of the reference body), so it depends on nothing the normalisation removed.
:func:`canonical_body` applies both.

Retargeting does not do this. The room reads its user off the humanoid fitted to the
recording (:func:`simenv.perception.protocol.avatar_clips`), and that body is fitted to
the sensor's own joints, so its keypoints keep the sensor's trunk: on one UTKinect wave,
one MSR Action3D wave and one MSRC-12 bow, ``spine`` at 0.39 / 0.68 / 0.36 of the way from
the hip centre to the shoulder centre and hips 0.42 / 0.78 / 0.44 shoulder widths apart on
the avatar, against 0.39 / 0.69 / 0.36 and 0.43 / 0.79 / 0.46 in the recorded joints.
Training on recorded joints and testing on the avatar's is therefore consistent within a
sensor, and equally sensor-specific; :func:`canonical_body` applies on either path.

Measured (issue 34, cross-dataset protocol, 20 epochs, each dataset left out, 3 s / 1 s
real, mean of the four): as given 0.442 / 0.385; ``neck`` and ``spine`` reconciled
0.515 / 0.392; and the hips 0.565 / 0.448; and reference bone lengths 0.596 / 0.498
(docs/recognition.md, *Across datasets*). Leave-subjects-out on the room's corpus (the
three datasets, 5 folds, 40 epochs, no forecast windows, same seeds): 3 s 0.930 -> 0.934,
1 s 0.835 -> 0.815.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from simenv.core.errors import SkeletonError
from simenv.data.gestures import GESTURE15_JOINTS, NORM_FRAMES, gesture_skeleton

#: Height of the reconciled ``spine`` on the line from the hip centre (0) to the
#: shoulder centre (1).
SPINE_FRACTION = 0.3

#: Distance between the reconciled hips, in shoulder widths.
HIP_WIDTH_RATIO = 0.5

#: Bone lengths of the reference body, child joint -> length from its parent in
#: ``gesture15``, metres of the normalised body (arm size
#: :data:`~simenv.data.gestures.REFERENCE_SIZE_M`): an adult's proportions, set once by eye
#: from the corpus's per-dataset medians before the one run that measured them, not tuned
#: (neck = shoulder centre, so neck -> shoulder is half the shoulder width). The reconciled
#: medians of the four datasets, for comparison: spine -> neck 0.23-0.30, neck -> head
#: 0.23-0.32, half shoulder width 0.15-0.18, upper arm 0.26-0.27, forearm 0.24-0.28,
#: spine -> hip 0.13-0.15, thigh 0.42-0.54, shank 0.39-0.41. Every body gets these
#: lengths, so their values do not favour a dataset.
REFERENCE_BONES_M: dict[str, float] = {
    "neck": 0.34, "head": 0.27, "left_shoulder": 0.17, "right_shoulder": 0.17,
    "left_elbow": 0.265, "right_elbow": 0.265, "left_wrist": 0.26, "right_wrist": 0.26,
    "left_hip": 0.167, "right_hip": 0.167, "left_knee": 0.45, "right_knee": 0.45,
    "left_ankle": 0.40, "right_ankle": 0.40,
}

#: Joints :func:`reconcile_joints` reads or writes.
RECONCILE_JOINTS: tuple[str, ...] = ("spine", "neck", "left_shoulder", "right_shoulder",
                                     "left_hip", "right_hip")


def reconcile_joints(windows: np.ndarray, valid: np.ndarray | None = None, *,
                     joints: Sequence[str] = GESTURE15_JOINTS) -> np.ndarray:
    """Windows with ``neck``, ``spine`` and the hips redefined from the shoulders and hips
    (module docstring), re-centred on the new ``spine``.

    Args:
        windows: (N, T, J, 3) or (T, J, 3) positions, metres, Z up (normalised windows,
            or world-frame ones: the definitions do not depend on the frame).
        valid: (N, T) or (T,) bool, True for real frames (default all real); the origin
            is the mean new ``spine`` over each window's first ``NORM_FRAMES`` valid
            frames (a window without one keeps its translation).
        joints: joint names of axis J.

    Returns:
        float32 array of the shape of ``windows``.

    Raises:
        SkeletonError: ``joints`` lacks one of :data:`RECONCILE_JOINTS`, or its length is
            not the windows' joint count.
    """
    names = list(joints)
    missing = [j for j in RECONCILE_JOINTS if j not in names]
    x = np.array(windows, dtype=np.float32)
    if missing or x.ndim not in (3, 4) or x.shape[-2:] != (len(names), 3):
        raise SkeletonError(
            f"reconcile_joints needs windows (N, T, J, 3) on joints naming "
            f"{', '.join(RECONCILE_JOINTS)}; got shape {x.shape}"
            + (f", joints lacking {', '.join(missing)}" if missing else ""), field="joints")
    single = x.ndim == 3
    if single:
        x = x[None]
    v = (np.ones(x.shape[:2], bool) if valid is None
         else np.asarray(valid, bool).reshape(x.shape[:2]))
    i = {n: names.index(n) for n in RECONCILE_JOINTS}
    lh, rh = x[:, :, i["left_hip"]], x[:, :, i["right_hip"]]
    ls, rs = x[:, :, i["left_shoulder"]], x[:, :, i["right_shoulder"]]
    hip, neck = 0.5 * (lh + rh), 0.5 * (ls + rs)
    axis = lh - rh
    # Hips on top of each other (a tracking failure) give no direction: keep them there.
    axis /= np.maximum(np.linalg.norm(axis, axis=-1, keepdims=True), 1e-6)
    half = 0.5 * HIP_WIDTH_RATIO * np.linalg.norm(ls - rs, axis=-1, keepdims=True)
    x[:, :, i["left_hip"]] = hip + half * axis
    x[:, :, i["right_hip"]] = hip - half * axis
    x[:, :, i["neck"]] = neck
    x[:, :, i["spine"]] = hip + SPINE_FRACTION * (neck - hip)
    ref = v & (np.cumsum(v, axis=1) <= NORM_FRAMES)
    cnt = ref.sum(axis=1)
    origin = (x[:, :, i["spine"]] * ref[..., None]).sum(axis=1) / np.maximum(cnt, 1)[:, None]
    x -= np.where(cnt[:, None] > 0, origin, 0.0)[:, None, None, :].astype(np.float32)
    return x[0] if single else x


def reference_bones(windows: np.ndarray, *, joints: Sequence[str] = GESTURE15_JOINTS,
                    parents: Sequence[int] | None = None) -> np.ndarray:
    """Normalised windows with every bone given its :data:`REFERENCE_BONES_M` length along
    its own direction, the root joint kept (module docstring).

    Args:
        windows: (..., J, 3) normalised positions, metres of the reference body.
        joints: joint names of axis J; ``parents``: their parent indices (-1 for the root,
            parents before children), default ``gesture15``'s.

    Returns:
        float32 array of the shape of ``windows`` (a bone of zero length keeps length 0).

    Raises:
        SkeletonError: a non-root joint without a reference length, or ``parents`` not
            matching ``joints``.
    """
    names = list(joints)
    parents = list(gesture_skeleton().parents if parents is None else parents)
    missing = ([n for n, p in zip(names, parents, strict=True)
                if p >= 0 and n not in REFERENCE_BONES_M] if len(parents) == len(names) else [])
    x = np.asarray(windows, dtype=np.float32)
    if missing or len(parents) != len(names) or x.shape[-2:] != (len(names), 3):
        raise SkeletonError(
            f"reference_bones needs windows (..., {len(names)}, 3) on a tree of the "
            f"gesture15 joints; got shape {x.shape}, {len(parents)} parents"
            + (f", no reference length for {', '.join(missing)}" if missing else ""),
            field="joints")
    out = x.copy()
    for j, p in enumerate(parents):
        if p < 0:
            continue
        bone = x[..., j, :] - x[..., p, :]
        bone /= np.maximum(np.linalg.norm(bone, axis=-1, keepdims=True), 1e-6)
        out[..., j, :] = out[..., p, :] + REFERENCE_BONES_M[names[j]] * bone
    return out


def has_canonical_joints(joints: Sequence[str]) -> bool:
    """Whether :func:`canonical_body` applies to windows on ``joints``: the joints of
    :data:`RECONCILE_JOINTS`, every other one with a reference bone length."""
    return (set(RECONCILE_JOINTS) <= set(joints)
            and all(j in REFERENCE_BONES_M or j == "spine" for j in joints))


def canonical_body(windows: np.ndarray, valid: np.ndarray | None = None, *,
                   joints: Sequence[str] = GESTURE15_JOINTS) -> np.ndarray:
    """:func:`reconcile_joints` then :func:`reference_bones` of normalised windows
    ((N, T, J, 3) or (T, J, 3), ``valid`` as for :func:`reconcile_joints`): the
    recogniser's sensor-invariant input."""
    return reference_bones(reconcile_joints(windows, valid, joints=joints), joints=joints)


__all__ = ["HIP_WIDTH_RATIO", "RECONCILE_JOINTS", "REFERENCE_BONES_M", "SPINE_FRACTION",
           "canonical_body", "has_canonical_joints", "reconcile_joints", "reference_bones"]

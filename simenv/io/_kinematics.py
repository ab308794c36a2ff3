"""Forward kinematics, unit detection and source-quirk detection shared by
the BVH and ASF/AMC readers.

Forward kinematics over a joint tree (parents precede children), for every
frame t at once::

    R_w[j] = R_w[p] @ R_l[j]                 (world rotation of joint j)
    x_w[j] = x_w[p] + R_w[p] @ (o[j] + d[j])  (world position of joint j)

with ``o[j]`` the constant offset of joint j in its parent's frame and
``d[j]`` an optional per-frame translation (T, 3). Roots use identity
for ``R_w[p]`` and zero for ``x_w[p]``. The loop runs over joints; every
step is vectorised over frames.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from simenv.core.errors import UnitsError

#: One CMU skeleton unit in metres: ASF ``:units length 0.45`` of inches.
CMU_UNIT_M = 0.0254 / 0.45

#: Length units a mocap file may use, name -> metres per file unit.
UNIT_SCALES: dict[str, float] = {
    "m": 1.0,
    "cmu": CMU_UNIT_M,
    "inch": 0.0254,
    "cm": 0.01,
    "mm": 0.001,
}

#: Range of plausible standing heights (m) used to tell the units apart. The
#: candidate ranges in file units do not overlap (CMU 17.7-39.0, inch
#: 39.4-86.6, cm 100-220, mm 1000-2200, m 1.0-2.2).
PLAUSIBLE_HEIGHT_M = (1.0, 2.2)

#: Looser range accepted with a quirk note (children, scaled templates).
TOLERATED_HEIGHT_M = (0.4, 3.0)

#: Typical adult height used to pick the closest unit outside the strict range.
TYPICAL_HEIGHT_M = 1.7

#: Axis change from a Y-up file frame to our Z-up world: (x, y, z) -> (x, -z, y).
#: A proper rotation (det = +1), so handedness is kept.
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

#: T-pose frame 0 test: mean root-relative joint jump from frame 0 to 1 must
#: exceed this (m) and be this many times the clip's median frame-to-frame
#: motion. Real 120 Hz capture moves ~0.1-1 cm per frame; the converters'
#: T-pose differs from the first real frame by decimetres.
TPOSE_MIN_JUMP_M = 0.05
TPOSE_JUMP_RATIO = 10.0
TPOSE_NEXT_RATIO = 3.0


def euler_to_matrices(angles_deg: np.ndarray, axes: str, *, intrinsic: bool = True) -> np.ndarray:
    """Rotation matrices of Euler angles.

    Args:
        angles_deg: (..., k) angles in degrees, k = len(axes).
        axes: rotation axes in listed order, e.g. ``"ZYX"``.
        intrinsic: True (BVH): ``"ZYX"`` gives ``R_Z(a0) @ R_Y(a1) @ R_X(a2)``.
            False (Acclaim ASF/AMC, extrinsic): ``"XYZ"`` gives
            ``R_Z(a2) @ R_Y(a1) @ R_X(a0)``.

    Returns:
        (..., 3, 3) rotation matrices.
    """
    shape = angles_deg.shape[:-1]
    if not axes:
        return np.broadcast_to(np.eye(3), (*shape, 3, 3)).copy()
    flat = angles_deg.reshape(-1, len(axes))
    seq = axes.upper() if intrinsic else axes.lower()
    mats = Rotation.from_euler(seq, flat, degrees=True).as_matrix()
    return mats.reshape(*shape, 3, 3)


def matrices_to_quaternions(mats: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions (w, x, y, z)
    with w >= 0."""
    shape = mats.shape[:-2]
    q = Rotation.from_matrix(mats.reshape(-1, 3, 3)).as_quat(scalar_first=True)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q.reshape(*shape, 4)


def forward_kinematics(
    parents: Sequence[int],
    offsets: np.ndarray,
    local_rotations: np.ndarray,
    translations: dict[int, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """World positions and rotations of every joint for every frame.

    Args:
        parents: (J,) parent indices, -1 for roots, parents before children.
        offsets: (J, 3) offset of each joint in its parent's frame.
        local_rotations: (T, J, 3, 3) rotation of each joint relative to its
            parent.
        translations: joint index -> (T, 3) per-frame translation added to
            that joint's offset (root position channels).

    Returns:
        positions (T, J, 3) and world rotations (T, J, 3, 3), in the units and
        frame of ``offsets``.
    """
    t, j = local_rotations.shape[:2]
    translations = translations or {}
    pos = np.zeros((t, j, 3))
    rot = np.empty((t, j, 3, 3))
    for k, p in enumerate(parents):
        local = np.broadcast_to(offsets[k], (t, 3))
        if k in translations:
            local = local + translations[k]
        if p < 0:
            rot[:, k] = local_rotations[:, k]
            pos[:, k] = local
        else:
            rot[:, k] = rot[:, p] @ local_rotations[:, k]
            pos[:, k] = pos[:, p] + np.einsum("tab,tb->ta", rot[:, p], local)
    return pos, rot


def rigid_bones(parents: Sequence[int], translations: dict[int, np.ndarray]) -> bool:
    """Whether every bone of a rotation-channel file is its fixed offset: no joint below a
    root carries a translation channel (BVH position channels, ASF ``tx``/``ty``/``tz``).
    Such a file cannot change a bone's length, whatever captured it; a file with
    translations below the root (a suit's solver, NiTE-to-BVH tools that write every
    joint's position) can."""
    return all(parents[k] < 0 for k in translations)


def to_z_up_metres(positions: np.ndarray, local_rotations: np.ndarray, offsets: np.ndarray,
                   up: str, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Forward-kinematics results in file axes and file units -> simenv's Z-up metres.

    Args:
        positions: (T, J, 3) joint positions; local_rotations: (T, J, 3, 3); offsets:
            (J, 3), in the file's axes and units.
        up: the file's up axis, ``"y"`` (mapped by :data:`Y_UP_TO_Z_UP`) or ``"z"``.
        scale: metres per file unit.

    Returns:
        positions (T, J, 3) and offsets (J, 3) in metres, and the local rotations
        ``C R C^T`` (C the axis change), so that FK with the converted offsets reproduces
        the converted positions.
    """
    conv = Y_UP_TO_Z_UP if up.lower() == "y" else np.eye(3)
    return ((positions @ conv.T) * scale, conv @ local_rotations @ conv.T,
            (offsets @ conv.T) * scale)


def units_metadata(fmt: str, stem: str, units: str, reason: str, scale: float,
                   up: str) -> dict[str, str | float]:
    """The metadata entries both mocap readers write about the file and its units:
    ``format``, ``subject`` (the file stem up to its first ``_``), ``units``,
    ``units_reason``, ``scale_m_per_unit`` and ``up_axis_in_file``."""
    return {"format": fmt, "subject": stem.split("_")[0], "units": units,
            "units_reason": reason, "scale_m_per_unit": scale, "up_axis_in_file": up.upper()}


def detect_units(
    height: float, *, source: Path, units: str | None = None, scale: float | None = None
) -> tuple[str, float, str, list[str]]:
    """Choose the length unit of a skeleton from its size.

    Args:
        height: size of the skeleton in file units (largest side of the
            rest-pose bounding box: about the standing height or arm span).
        units: explicit unit name from :data:`UNIT_SCALES` (overrides detection).
        scale: explicit metres per file unit (overrides everything).

    Returns:
        (unit name, metres per unit, human-readable reason, quirk notes).

    Raises:
        UnitsError: no unit gives a height within :data:`TOLERATED_HEIGHT_M`
            (e.g. a 180 m person), or an explicit choice is invalid.
    """
    if scale is not None:
        if not np.isfinite(scale) or scale <= 0:
            raise UnitsError(
                f"scale must be a positive number of metres per unit; got {scale!r}", source=source
            )
        return "explicit", float(scale), f"scale={scale:g} given by the caller", []
    if units is not None:
        if units not in UNIT_SCALES:
            raise UnitsError(
                f"unknown units {units!r}; expected one of {', '.join(UNIT_SCALES)}",
                source=source,
            )
        return units, UNIT_SCALES[units], f"units={units!r} given by the caller", []
    if not np.isfinite(height) or height <= 0:
        raise UnitsError(
            f"skeleton has no extent ({height!r} file units); cannot infer units", source=source
        )
    lo, hi = PLAUSIBLE_HEIGHT_M
    for name, s in UNIT_SCALES.items():
        if lo <= height * s <= hi:
            reason = (
                f"rest-pose size {height:.4g} file units = {height * s:.3f} m in {name}, "
                f"the only unit giving a height within {lo}-{hi} m"
            )
            return name, s, reason, []
    name, s = min(
        UNIT_SCALES.items(), key=lambda kv: abs(np.log(height * kv[1] / TYPICAL_HEIGHT_M))
    )
    tlo, thi = TOLERATED_HEIGHT_M
    if not tlo <= height * s <= thi:
        options = ", ".join(f"{n}: {height * v:.4g} m" for n, v in UNIT_SCALES.items())
        raise UnitsError(
            f"rest-pose size {height:.4g} file units is not a plausible person in any known "
            f"unit ({options}); expected {lo}-{hi} m. Give the unit (simenv.load(path, "
            f"units='cm'); the commands' --units cm) or metres per file unit (scale=, "
            f"--scale)",
            source=source,
        )
    reason = (
        f"rest-pose size {height:.4g} file units; {name} gives {height * s:.3f} m, "
        f"outside {lo}-{hi} m but the closest to {TYPICAL_HEIGHT_M} m"
    )
    quirk = (
        f"skeleton is {height * s:.2f} m tall in {name}: outside the plausible adult "
        f"range {lo}-{hi} m (a child, or a template/rescaled skeleton)"
    )
    return name, s, reason, [quirk]


def rest_extent(parents: Sequence[int], offsets: np.ndarray) -> float:
    """Largest side of :func:`rest_extents`, in the units of ``offsets``."""
    return float(rest_extents(parents, offsets).max())


def rest_extents(parents: Sequence[int], offsets: np.ndarray) -> np.ndarray:
    """(3,) sides of the bounding box of the rest pose (all rotations
    identity), in the units and axes of ``offsets``, over the body only: the
    joints at and below the first joint with several children (the pelvis).
    The offsets on the way down to it place the body in the room (some
    exporters write the actor's start position, metres away, into a root or
    hip OFFSET), so they say nothing of its size."""
    rest = np.zeros((1, len(parents), 3, 3))
    rest[:] = np.eye(3)
    pos, _ = forward_kinematics(parents, offsets, rest)
    return np.ptp(pos[0][body_joints(parents)], axis=0)


def posed_extents(parents: Sequence[int], positions: np.ndarray) -> np.ndarray:
    """(3,) sides of the body's bounding box in the motion (median over frames), over the
    joints of :func:`body_joints`: its size when the all-zero rest pose is no standing body
    (rigs whose joints carry their own axes write every OFFSET along the joint's X).

    Args:
        positions: (T, J, 3) joint positions, any unit and axes.
    """
    body = body_joints(parents)
    return np.median(np.ptp(positions[:, body], axis=1), axis=0)


def body_joints(parents: Sequence[int]) -> list[int]:
    """The joints at and below the first joint with several children (the pelvis), or every
    joint when the skeleton has several roots."""
    children: dict[int, list[int]] = {}
    for j, p in enumerate(parents):
        children.setdefault(int(p), []).append(j)
    roots = children.get(-1, [])
    if len(roots) != 1:
        return list(range(len(parents)))
    hub = roots[0]
    while len(children.get(hub, [])) == 1:
        hub = children[hub][0]
    body, stack = [], [hub]
    while stack:
        j = stack.pop()
        body.append(j)
        stack.extend(children.get(j, []))
    return body


def tpose_jump(positions: np.ndarray) -> tuple[float, float, float] | None:
    """Frame-0 jump statistics used to recognise a prepended T-pose.

    Args:
        positions: (T, J, 3) metres.

    Returns:
        (mean root-relative joint displacement from frame 0 to 1, the same
        from frame 1 to 2, its median over frames 1..T-1), metres, or None
        when the clip has fewer than 3 frames.
    """
    if positions.shape[0] < 3:
        return None
    rel = positions - positions[:, :1]
    step = np.linalg.norm(np.diff(rel, axis=0), axis=-1).mean(axis=1)
    return float(step[0]), float(step[1]), float(np.median(step[1:]))


def is_tpose_frame0(positions: np.ndarray) -> tuple[bool, str]:
    """Whether frame 0 is a rest/T-pose unrelated to the rest of the clip.

    Frame 0 counts as a prepended pose when its jump to frame 1 exceeds
    :data:`TPOSE_MIN_JUMP_M` and :data:`TPOSE_JUMP_RATIO` times the clip's
    median step, while the next step (frame 1 to 2) is ordinary (below
    :data:`TPOSE_NEXT_RATIO` times the median, or below the jump over
    :data:`TPOSE_JUMP_RATIO`: a clip that stands nearly still has a median step
    of a tenth of a millimetre, against which a few millimetres of ordinary
    motion look large): an isolated discontinuity, not a fast start (the salsa
    clips blend in over 4 frames, each step as large as the first).

    Returns:
        (decision, note with the measured numbers).
    """
    stats = tpose_jump(positions)
    if stats is None:
        return False, "fewer than 3 frames: T-pose test skipped"
    jump, nxt, typical = stats
    ratio = jump / max(typical, 1e-6)
    found = (
        jump > TPOSE_MIN_JUMP_M
        and ratio > TPOSE_JUMP_RATIO
        and nxt < max(TPOSE_NEXT_RATIO * max(typical, 1e-6), jump / TPOSE_JUMP_RATIO)
    )
    note = (
        f"frame 0->1 mean joint jump {jump * 100:.1f} cm, frame 1->2 {nxt * 100:.2f} cm, "
        f"median {typical * 100:.2f} cm per frame"
    )
    return found, note

"""Depth-sensor camera frame -> simenv world frame (Z up, floor at z = 0).

Kinect-era skeletons are stored in the sensor's *camera frame*: right-handed,
``x`` toward the sensor's left (a subject facing the sensor has its right side
at larger ``x``), ``y`` up along the sensor's vertical axis, ``z`` away from the
sensor along its optical axis, metres. The sensor height and tilt are unknown,
so the floor is neither at ``y = 0`` nor perpendicular to ``y``.

Conversion, in two steps (``p_world = R @ p_cam + t``):

1. **Axes.** :data:`KINECT_TO_ZUP` is the cyclic permutation
   ``(x, y, z)_cam -> (z, x, y)``: world ``X`` = optical axis (depth),
   ``Y`` = sensor's left, ``Z`` = sensor's up. It is a proper rotation
   (det +1), so handedness is kept: ``X x Y = z_c x x_c = y_c = Z``. The
   sensor sits at the origin looking along ``+X``; a subject facing it faces
   ``-X``. (The other proper choice, ``(x, -z, y)``, a +90 deg turn about
   ``x``, only differs by a yaw; we keep depth on ``+X``. Swapping two axes,
   e.g. ``(x, z, y)``, would mirror the person and is never used.)
2. **Levelling and floor.** The world up vector ``n`` (in the permuted frame)
   is estimated by a regularised, outlier-trimmed plane fit
   ``h = a X + b Y + c`` to the per-frame lowest foot point (foot joints
   lowered by their :data:`FLOOR_CLEARANCE_M` above the sole), with a Gaussian
   prior on the slopes ``(a, b)`` (sigma ``tan 2 deg``) centred on a vertical
   estimated from the body. When the feet move over the floor (walking) the
   plane dominates; when they stay put (a gesture in place: one or two 25-cm
   floor cells) the prior does. The prior's centre is

   * for a person **in place** (ankles' midpoint within
     :data:`IN_PLACE_SPREAD_M`) who stands (knees bent less than
     :data:`STANDING_KNEE_DEG`) on at least :data:`MIN_STANDING_FRACTION` of
     the frames: the **centre of mass over the feet**,
     ``up = normalise(mean_t unit(c_t - s_t))`` over standing frames, with
     ``c_t`` the keypoint centre of mass (:data:`COM_SEGMENTS`, de Leva 1996)
     and ``s_t`` the ankles' midpoint moved :data:`SUPPORT_FORWARD_M` along
     the person's forward (hip line x up, horizontal). A standing person's
     centre of mass stays over the base of support; its mean horizontal
     offset from the centre of pressure is ``h / g`` times the mean horizontal
     acceleration, nil over a clip that starts and ends at rest in place.
     :func:`standing_up`.
   * otherwise the **body axis**: the median, over frames, of the unit
     vectors ankle->knee (both shanks) and hips->neck (trunk), vertical in
     upright standing and seated poses but not with bent knees or a bent
     trunk (on CMU boxing, dancing and bending clips it is 10-25 deg off).

   With several people, the centres of the in-place ones and the body axes
   of the others are averaged; with nobody in place the prior is the body
   axis of all. The minimal rotation taking ``n`` to ``+Z`` removes the
   sensor's pitch and roll (its yaw is kept), and the floor height is the
   plane's intercept, so the floor ends at ``z = 0`` and the world origin lies
   on the floor right below the sensor.

Accuracy of the in-place vertical (``benchmarks/levelling_check.py``, true vertical
known): 51 standing 4-s windows of 9 CMU motion-capture clips as OpenNI keypoints with
2 cm of noise, in four sensor poses: tilt error median 2.1 deg, p95 7.0 (the body axis
19.5 / 27.7); UTKinect's actions other than the walk, levelled by the walk: 3.2 / 13.4
(7.1 / 15.4). The residual is where the centre of pressure sits under the feet (a dancer
on the balls of the feet: 17 cm in front of the ankles, 7 deg) and seated phases.

The estimate (tilt, pitch, roll, sensor height, fit residual) is returned as a
:class:`FloorEstimate` and recorded by the readers in
``metadata["camera_frame"]``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from simenv.core.errors import MotionError
from simenv.core.joint_map import sensor_family
from simenv.core.motion import Interaction, Motion
from simenv.core.skeletons import Skeleton
from simenv.io.floor import FILE_FLOOR_FORMATS

#: Camera (x left, y up, z forward) -> Z-up axes: ``p_zup = KINECT_TO_ZUP @ p_cam``.
KINECT_TO_ZUP = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

#: Height of a foot joint centre above the floor when the foot is flat,
#: metres, by canonical keypoint kind: the forefoot/toe point of Kinect SDK
#: skeletons sits about 3 cm up, the ankle joint centre (lateral malleolus)
#: about 7 cm (adult anthropometry).
FLOOR_CLEARANCE_M: dict[str, float] = {"toe": 0.03, "ankle": 0.07}

#: Noise of one floor-cell sample, metres (sigma of the plane fit): Kinect foot
#: joints are noisy (~2 cm) and biased by depth and occlusion, so 4 cm.
FOOT_NOISE_M = 0.04
#: Prior sigma on each floor slope (tan of the angle) around the body axis.
BODY_AXIS_PRIOR_SLOPE = float(np.tan(np.radians(2.0)))
#: Side of the square floor cells that each give one floor sample, metres.
FLOOR_CELL_M = 0.25
#: Floor points farther than this many robust sigmas from the plane are dropped.
OUTLIER_SIGMAS = 3.0
#: Largest accepted tilt estimate, degrees. Sensors are mounted within about
#: +-30 deg (Kinect v1 motor range +-27 deg), but a short clip of a bending
#: person can push an estimate to ~40 deg; data in the wrong axis convention
#: (Z-up given as camera frame) lands near 90 deg and is what this catches.
MAX_TILT_DEG = 60.0
#: Coordinates farther than this from the sensor are not a depth-sensor
#: measurement (Kinect range is ~0.5-8 m): an error, metres.
MAX_RANGE_M = 50.0

#: Keypoint body model for the centre of mass: (first keypoint, second keypoint, mass
#: fraction, centre-of-mass position as a fraction of the way from the first to the second),
#: de Leva (1996, J Biomech 29:1223, Table 4, adult males). ``hips`` is the hips' midpoint
#: (or the pelvis): the trunk runs from the neck (suprasternale) to it; the head's mass sits
#: at the head keypoint, the hand's at the wrist and the foot's at the ankle (keypoint
#: skeletons have no finger tips or heels). Segments a skeleton lacks are left out and the
#: fractions renormalised.
COM_SEGMENTS: tuple[tuple[str, str, float, float], ...] = (
    ("head", "head", 0.0694, 0.0),
    ("neck", "hips", 0.4346, 0.4486),
    *((f"{s}_{a}", f"{s}_{b}", m, c) for s in ("left", "right") for a, b, m, c in (
        ("shoulder", "elbow", 0.0271, 0.5772), ("elbow", "wrist", 0.0162, 0.4574),
        ("wrist", "wrist", 0.0061, 0.0), ("hip", "knee", 0.1416, 0.4095),
        ("knee", "ankle", 0.0433, 0.4459), ("ankle", "ankle", 0.0137, 0.0))),
)
#: Forward offset, metres, from the ankles' midpoint to the point under a standing person's
#: centre of mass (the mean centre of pressure lies in front of the ankles, mid-foot):
#: the median over 51 standing 4-s windows of 9 CMU motion-capture clips turned into
#: OpenNI-like keypoints (``benchmarks/levelling_check.py``; window sd 34 mm, clip medians
#: 53-174 mm), never measured on depth-camera clips. Toe keypoints are not used: on the same
#: windows they made the estimate worse.
SUPPORT_FORWARD_M = 0.085
#: A frame counts as standing when both knees bend less than this, degrees: motion-captured
#: standing, boxing and dancing bend them 20-60 deg (CMU, 10-90 %), sitting about 90.
STANDING_KNEE_DEG = 60.0
#: A person whose ankles' midpoint stays within this extent (5-95 %, both horizontal
#: axes), metres, is in place: their floor points give no slope and the prior centre comes
#: from the centre of mass over the feet.
IN_PLACE_SPREAD_M = 0.5
#: At least this fraction of an in-place person's frames must be standing for the centre
#: of mass to give the vertical; otherwise the body axis does.
MIN_STANDING_FRACTION = 0.25


@dataclass(frozen=True)
class FloorEstimate:
    """Rigid transform from a sensor's camera frame to the Z-up world.

    ``p_world = rotation @ p_cam + translation``.

    Attributes:
        rotation: (3, 3) proper rotation, camera -> world.
        translation: (3,) metres; ``(0, 0, sensor_height_m)``.
        up_camera: (3,) unit world-up vector in camera coordinates.
        tilt_deg: angle between the sensor's up axis and world up.
        pitch_down_deg: sensor pitch, positive when it looks down.
        roll_deg: sensor roll, positive when its left side is raised.
        sensor_height_m: height of the sensor's origin above the floor.
        floor_rms_m: RMS distance of the kept floor points to the plane.
        floor_points: number of frames whose lowest foot point was kept.
        feet_spread_m: (2,) extent (5-95 percentile) of the kept floor points
            along their two horizontal principal axes: small values mean the
            tilt came mostly from the prior.
        prior: what centred the slope prior: ``"body axis"`` or ``"centre of mass over
            feet"`` (someone stood in place, :func:`standing_up`).
    """

    rotation: np.ndarray
    translation: np.ndarray
    up_camera: np.ndarray
    tilt_deg: float
    pitch_down_deg: float
    roll_deg: float
    sensor_height_m: float
    floor_rms_m: float
    floor_points: int
    feet_spread_m: tuple[float, float]
    prior: str = "body axis"

    def apply(self, positions_cam: np.ndarray) -> np.ndarray:
        """(..., 3) camera-frame metres -> (..., 3) float32 world metres."""
        p = np.asarray(positions_cam, dtype=np.float64)
        return (p @ self.rotation.T + self.translation).astype(np.float32)

    def as_metadata(self) -> dict[str, Any]:
        """JSON-friendly summary for ``Motion.metadata["camera_frame"]``."""
        return {
            "convention": "camera x=sensor left, y=up, z=forward -> world X=forward, Y=left, "
            "Z=up; floor from feet (plane + prior: body axis, or centre of mass over the feet "
            "for a person in place), z=0 on the floor",
            "tilt_deg": round(self.tilt_deg, 3),
            "pitch_down_deg": round(self.pitch_down_deg, 3),
            "roll_deg": round(self.roll_deg, 3),
            "sensor_height_m": round(self.sensor_height_m, 4),
            "floor_rms_m": round(self.floor_rms_m, 4),
            "floor_points": self.floor_points,
            "feet_spread_m": [round(v, 3) for v in self.feet_spread_m],
            "prior": self.prior,
            "rotation": np.round(self.rotation, 6).tolist(),
        }


def keypoint_indices(skeleton: Skeleton, keys: Sequence[str]) -> list[int]:
    """Joint indices of the canonical keypoints ``keys`` that ``skeleton`` maps (the others
    are skipped)."""
    return [skeleton.index(skeleton.canonical[k]) for k in keys if k in skeleton.canonical]


def _foot_joints(skeleton: Skeleton) -> tuple[list[int], list[float]]:
    idx: list[int] = []
    clearance: list[float] = []
    for kind, c in FLOOR_CLEARANCE_M.items():
        for side in ("left", "right"):
            key = f"{side}_{kind}"
            if key in skeleton.canonical:
                idx.append(skeleton.index(skeleton.canonical[key]))
                clearance.append(c)
    return idx, clearance


def _body_axis_votes(p: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(N, 3) unit 'up' votes from shanks and trunk, in the permuted frame."""
    votes = []
    for side in ("left", "right"):
        pair = keypoint_indices(skeleton, [f"{side}_ankle", f"{side}_knee"])
        if len(pair) == 2:
            votes.append(p[:, pair[1]] - p[:, pair[0]])
    hips = keypoint_indices(skeleton, ["left_hip", "right_hip"])
    low = p[:, hips].mean(axis=1) if len(hips) == 2 else None
    if low is None and "pelvis" in skeleton.canonical:
        low = p[:, skeleton.index(skeleton.canonical["pelvis"])]
    top = keypoint_indices(skeleton, ["neck"]) or keypoint_indices(skeleton, ["head"])
    if low is not None and top:
        votes.append(p[:, top[0]] - low)
    if not votes:
        return np.zeros((0, 3))
    v = np.concatenate(votes)
    n = np.linalg.norm(v, axis=1)
    return v[n > 1e-6] / n[n > 1e-6, None]


def _rotation_to_z(n: np.ndarray) -> np.ndarray:
    """Minimal rotation taking unit vector ``n`` to +Z (Rodrigues)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(n, z)
    s, c = np.linalg.norm(axis), float(np.dot(n, z))
    if s < 1e-12:
        return np.eye(3)
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * (kx @ kx)


def _keypoint(p: np.ndarray, skeleton: Skeleton, key: str) -> np.ndarray | None:
    """(T, 3) positions of canonical ``key`` (``hips``: the hips' midpoint, else the
    pelvis), or None when the skeleton lacks it."""
    if key == "hips":
        hips = keypoint_indices(skeleton, ["left_hip", "right_hip"])
        if len(hips) == 2:
            return p[:, hips].mean(axis=1)
        key = "pelvis"
    if key not in skeleton.canonical:
        return None
    return p[:, skeleton.index(skeleton.canonical[key])]


#: Keypoints the centre of mass and the standing test cannot do without.
_STANDING_KEYS = ("neck", "hips", *(f"{s}_{k}" for s in ("left", "right")
                                    for k in ("hip", "knee", "ankle")))


def centre_of_mass(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray | None:
    """Whole-body centre of mass from keypoints (:data:`COM_SEGMENTS`, de Leva 1996).

    Args:
        positions: (T, J, 3) metres, any frame.
        skeleton: maps at least the neck, the hips and both legs (hip, knee, ankle).

    Returns:
        (T, 3) metres in the frame of ``positions``, or None when a required keypoint is
        missing.
    """
    p = np.asarray(positions, dtype=np.float64)
    if any(_keypoint(p[:1], skeleton, k) is None for k in _STANDING_KEYS):
        return None
    acc, total = np.zeros((len(p), 3)), 0.0
    for a, b, mass, along in COM_SEGMENTS:
        pa, pb = _keypoint(p, skeleton, a), _keypoint(p, skeleton, b)
        if pa is None or pb is None:
            continue  # e.g. no head keypoint: renormalise over the rest
        acc += mass * (pa + along * (pb - pa))
        total += mass
    return acc / total


def standing_up(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray | None:
    """The vertical of a person standing in place: their centre of mass is over their feet.

    A standing person's centre of mass stays over the base of support; over a clip its
    horizontal offset from the centre of pressure averages to the mean horizontal
    acceleration times its height over g, which is nil when the person starts and ends at
    rest in one place. So the mean, over standing frames (both knees bent less than
    :data:`STANDING_KNEE_DEG`), of the unit vector from the support point (the ankles'
    midpoint moved :data:`SUPPORT_FORWARD_M` forward, perpendicular to the hip line) to the
    centre of mass (:func:`centre_of_mass`) is up. (Only standing frames, not only quiet
    ones: keeping the half with the lowest centre-of-mass acceleration did not narrow the
    offset's scatter on motion capture.)

    Args:
        positions: (T, J, 3) metres, roughly Z up (within ~30 deg: the forward direction
            is taken in this frame's horizontal plane).
        skeleton: its canonical map locates neck, hips, knees and ankles.

    Returns:
        (3,) unit up vector in the frame of ``positions``, or None when the person is not
        in place (ankles' midpoint spread over more than :data:`IN_PLACE_SPREAD_M`), stands
        on fewer than :data:`MIN_STANDING_FRACTION` of the frames, or lacks a keypoint.
    """
    p = np.asarray(positions, dtype=np.float64)
    com = centre_of_mass(p, skeleton)
    if com is None:
        return None
    ankles = keypoint_indices(skeleton, ["left_ankle", "right_ankle"])
    if max(principal_spread(p[:, ankles, :2].mean(axis=1))) > IN_PLACE_SPREAD_M:
        return None
    standing = np.ones(len(p), dtype=bool)
    for side in ("left", "right"):
        hip, knee, ankle = (_keypoint(p, skeleton, f"{side}_{k}") for k in ("hip", "knee", "ankle"))
        thigh, shank = knee - hip, ankle - knee
        cos = np.einsum("ij,ij->i", thigh, shank) / np.maximum(
            np.linalg.norm(thigh, axis=1) * np.linalg.norm(shank, axis=1), 1e-9)
        standing &= np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))) < STANDING_KNEE_DEG
    if standing.mean() < MIN_STANDING_FRACTION:
        return None
    support = p[:, ankles].mean(axis=1)
    # The person's forward: their left (hip line) crossed with up, in the horizontal plane.
    left = _keypoint(p, skeleton, "left_hip") - _keypoint(p, skeleton, "right_hip")
    forward = np.cross(left, [0.0, 0.0, 1.0])
    forward[:, 2] = 0.0
    forward /= np.maximum(np.linalg.norm(forward, axis=1, keepdims=True), 1e-9)
    v = (com - support - SUPPORT_FORWARD_M * forward)[standing]
    v = (v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-9)).mean(axis=0)
    return v / np.linalg.norm(v)


def _samples(
    people: list[tuple[np.ndarray, Skeleton, list[int], np.ndarray]]
) -> tuple[np.ndarray, np.ndarray, str]:
    """Per-frame lowest floor points (N, 3), the centre of the slope prior (3,) (not
    normalised) and what gave it, in the frame the positions are given in (Z roughly up).

    A person in place (:func:`standing_up`) votes with the vertical their centre of mass
    over their feet gives; everyone else with their body axis (median of the shank and
    trunk directions). With nobody in place the prior is the body axis of all."""
    floor_pts, votes, standing = [], [], []
    for p, skeleton, feet, clearance in people:
        votes.append(_body_axis_votes(p, skeleton))
        standing.append(standing_up(p, skeleton))
        h = p[:, feet, 2] - clearance
        lowest = np.argmin(h, axis=1)
        pts = p[np.arange(len(p)), np.asarray(feet)[lowest]].copy()
        pts[:, 2] -= clearance[lowest]
        floor_pts.append(pts)
    if all(s is None for s in standing):
        return np.concatenate(floor_pts), np.median(np.concatenate(votes), axis=0), "body axis"
    centres = [s if s is not None else np.median(v, axis=0) / max(
        float(np.linalg.norm(np.median(v, axis=0))), 1e-9) for s, v in zip(standing, votes,
                                                                        strict=True)]
    return np.concatenate(floor_pts), np.mean(centres, axis=0), "centre of mass over feet"


def _fit_plane(pts: np.ndarray, axis: np.ndarray, source: str | None
               ) -> tuple[np.ndarray, np.ndarray]:
    """Regularised robust fit ``h = a X + b Y + c`` with the slope prior perpendicular to
    ``axis`` (3,); returns (coef, keep mask over ``pts``)."""
    axis = np.array(axis, dtype=np.float64)
    if np.linalg.norm(axis) < 1e-6 or axis[2] <= 0:
        raise MotionError(
            "the body axis points down or is undefined in the camera frame; expected y-up "
            "Kinect camera coordinates (x left, y up, z forward)",
            source=source,
        )
    axis /= np.linalg.norm(axis)
    prior = -axis[:2] / axis[2]  # slopes of the plane perpendicular to the body axis

    # Kinect foot noise is strongly correlated in time, so frames are not
    # independent samples of the floor: one point (the median) per occupied
    # floor cell is. A person gesturing in place gives one or two cells and
    # the prior decides; a walk gives many and the feet decide.
    cell = np.floor(pts[:, :2] / FLOOR_CELL_M).astype(np.int64)
    _, inverse = np.unique(cell, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    cells = np.array([np.median(pts[inverse == k], axis=0) for k in range(inverse.max() + 1)])

    keep = np.ones(len(cells), dtype=bool)
    reg = np.diag([1.0, 1.0, 0.0]) / BODY_AXIS_PRIOR_SLOPE**2
    coef = np.array([prior[0], prior[1], np.median(cells[:, 2])])
    for _ in range(5):
        q = cells[keep]
        a = np.column_stack([q[:, 0], q[:, 1], np.ones(len(q))]) / FOOT_NOISE_M
        b = q[:, 2] / FOOT_NOISE_M
        rhs = a.T @ b + reg @ np.array([prior[0], prior[1], 0.0])
        coef = np.linalg.solve(a.T @ a + reg + 1e-12 * np.eye(3), rhs)
        resid = cells[:, 2] - (cells[:, 0] * coef[0] + cells[:, 1] * coef[1] + coef[2])
        mad = 1.4826 * np.median(np.abs(resid[keep] - np.median(resid[keep])))
        new_keep = np.abs(resid) <= OUTLIER_SIGMAS * max(mad, FOOT_NOISE_M)
        if not new_keep.any() or np.array_equal(new_keep, keep):
            break
        keep = new_keep
    resid = pts[:, 2] - (pts[:, 0] * coef[0] + pts[:, 1] * coef[1] + coef[2])
    spread = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
    point_keep = keep[inverse] & (np.abs(resid) <= OUTLIER_SIGMAS * max(FOOT_NOISE_M, spread))
    if not point_keep.any():
        point_keep = np.ones(len(pts), dtype=bool)
    return coef, point_keep


def estimate_floor(
    people: Sequence[tuple[np.ndarray, Skeleton]], *, source: str | None = None
) -> FloorEstimate:
    """Estimate the camera -> world transform from the feet of everyone seen
    by one sensor.

    The fit is done twice: the second time in the frame levelled by the
    first, so that the result does not depend on how tilted the sensor was
    (least squares on heights and slope priors are only rotation-invariant
    near level).

    Args:
        people: one ``(positions, skeleton)`` per person, positions (T, J, 3)
            metres in the Kinect camera convention (see module docstring).
            Every skeleton must map left/right ankles or toes and at least
            one shank or the trunk.
        source: file name for error messages.

    Returns:
        The :class:`FloorEstimate`.
    """
    prepared = [_prepared(positions, skeleton, source) for positions, skeleton in people]
    if not prepared:
        raise MotionError("no person to estimate the floor from", source=source)

    level = np.eye(3)  # rotation from the permuted frame to the current frame
    for _ in range(2):
        pts, axis, prior = _samples([(p @ level.T, s, f, c) for p, s, f, c in prepared])
        coef, keep = _fit_plane(pts, axis, source)
        n_cur = np.array([-coef[0], -coef[1], 1.0])
        n_cur /= np.linalg.norm(n_cur)
        level = _rotation_to_z(n_cur) @ level
    # The last fit was in a nearly level frame; its plane passes through
    # (0, 0, c), so the floor level along n is c * n_z there.
    floor_level = float(coef[2] * n_cur[2])
    n = level.T @ np.array([0.0, 0.0, 1.0])
    tilt = float(np.degrees(np.arccos(np.clip(n[2], -1.0, 1.0))))
    if tilt > MAX_TILT_DEG:
        raise MotionError(
            f"estimated sensor tilt is {tilt:.1f} deg (> {MAX_TILT_DEG} deg); the data is "
            "probably not in y-up Kinect camera coordinates",
            source=source,
        )
    q = pts[keep] @ _rotation_to_z(n_cur).T
    spread = principal_spread(q[:, :2])
    rms = float(np.sqrt(np.mean((q[:, 2] - floor_level) ** 2)))
    return FloorEstimate(
        rotation=level @ KINECT_TO_ZUP,
        translation=np.array([0.0, 0.0, -floor_level]),
        up_camera=KINECT_TO_ZUP.T @ n,
        tilt_deg=tilt,
        pitch_down_deg=float(np.degrees(np.arcsin(np.clip(-n[0], -1, 1)))),
        roll_deg=float(np.degrees(np.arcsin(np.clip(n[1], -1, 1)))),
        sensor_height_m=-floor_level,
        floor_rms_m=rms,
        floor_points=int(keep.sum()),
        feet_spread_m=(spread[0], spread[1]),
        prior=prior,
    )


def _prepared(positions: np.ndarray, skeleton: Skeleton, source: str | None
              ) -> tuple[np.ndarray, Skeleton, list[int], np.ndarray]:
    """One person's input to the floor fit: (T, J, 3) positions permuted to Z-up (not yet
    levelled), the skeleton, its foot joints and their clearances above the floor.

    Raises:
        MotionError: a position that is not finite or out of the sensor's range, a
            skeleton without feet or without shanks or a trunk.
    """
    p = np.asarray(positions, dtype=np.float64)
    bad = np.argwhere(~(np.abs(p) <= MAX_RANGE_M))
    if bad.size:
        t, j = int(bad[0][0]), int(bad[0][1])
        raise MotionError(
            f"joint position {p[t, j].tolist()} is not finite or farther than "
            f"{MAX_RANGE_M:g} m from the sensor; expected camera-frame metres",
            source=source, frame=t, field=skeleton.joint_names[j],
        )
    p = p @ KINECT_TO_ZUP.T
    feet, clearance = _foot_joints(skeleton)
    if not feet:
        raise MotionError(
            f"skeleton {skeleton.name!r} maps no ankle or toe keypoint; the floor cannot be "
            "estimated from the feet",
            source=source,
        )
    if len(_body_axis_votes(p[:1], skeleton)) == 0:
        raise MotionError(
            f"skeleton {skeleton.name!r} has neither shanks (knee, ankle) nor a trunk "
            "(hips/pelvis to neck/head) to estimate the vertical from",
            source=source,
        )
    return p, skeleton, feet, np.asarray(clearance)


def principal_spread(xy: np.ndarray) -> tuple[float, float]:
    """5-95 % extent (m) of (N, 2) floor points along their two principal axes."""
    centred = xy - xy.mean(axis=0)
    if len(centred) < 2:
        return (0.0, 0.0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    proj = centred @ vt.T
    return (float(np.ptp(np.percentile(proj[:, 0], [5, 95]))),
            float(np.ptp(np.percentile(proj[:, 1], [5, 95]))))


def camera_to_world(
    positions: np.ndarray, skeleton: Skeleton, *, source: str | None = None
) -> tuple[np.ndarray, FloorEstimate]:
    """Convert one person's camera-frame clip to the world frame.

    Args:
        positions: (T, J, 3) metres, Kinect camera convention.
        skeleton: the clip's skeleton (its canonical map locates feet, knees,
            hips and neck).
        source: file name for error messages.

    Returns:
        ((T, J, 3) float32 world positions, the :class:`FloorEstimate`).
    """
    est = estimate_floor([(positions, skeleton)], source=source)
    return est.apply(positions), est


def world_motion(
    positions_cam: np.ndarray,
    skeleton: Skeleton,
    *,
    fps: float,
    name: str,
    metadata: dict[str, Any],
    source: str | None = None,
) -> Motion:
    """Build a world-frame :class:`Motion` from a one-person camera-frame clip
    (the common last step of the Kinect readers); the floor estimate goes to
    ``metadata["camera_frame"]``."""
    world, est = camera_to_world(positions_cam, skeleton, source=source)
    meta = dict(metadata)
    meta["camera_frame"] = est.as_metadata()
    return Motion(world, fps, skeleton, name, meta)


#: Reader output (Z up: the file's up axis became ``+Z``) -> the Kinect camera convention
#: (``x`` left, ``y`` up, ``z`` forward): ``(X, Y, Z) -> (X, Z, -Y)``, a proper rotation.
ZUP_TO_CAMERA = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])

#: A sensor-named file whose estimated floor lies within these of level and of z = 0 is
#: already in a world frame and is left as it is (the estimate's scatter on levelled real
#: Kinect clips: tilt < 3 deg, floor < 5 cm off).
WORLD_FRAME_TILT_DEG = 3.0
WORLD_FRAME_HEIGHT_M = 0.05


def level_sensor_frame(loaded: Motion | Interaction) -> Motion | Interaction:
    """A file holding a depth camera's skeleton, put in the world frame on its floor.

    A BVH, ASF/AMC or joint table whose joints a depth camera's tracker named
    (:func:`simenv.core.joint_map.sensor_family`: a NiTE recording exported to BVH, an
    OpenNI or Kinect tool's dump) holds the sensor's estimates in the sensor's frame: the
    floor is about the sensor's height below the file's zero, and tilted with it. Such a
    clip (both people of a two-person clip: one sensor) goes through
    :func:`estimate_floor` in the file's own axes, which are the camera's (the reader's
    change of a Y-up file to Z up, :data:`ZUP_TO_CAMERA`, undone; a file the reader took as
    Z up is already in them); the estimate goes to ``metadata["camera_frame"]``. Anything
    else, a clip a reader already levelled (``metadata["camera_frame"]``), or one whose feet
    already stand level on z = 0 (:data:`WORLD_FRAME_TILT_DEG`, :data:`WORLD_FRAME_HEIGHT_M`:
    Kinect data someone put in a world frame) is returned unchanged.

    Raises:
        MotionError: the feet or the body axis give no floor (see :func:`estimate_floor`).
    """
    people = list(loaded.people) if isinstance(loaded, Interaction) else [loaded]
    meta = people[0].metadata
    if (str(meta.get("format", "")).lower() not in FILE_FLOOR_FORMATS or "camera_frame" in meta
            or sensor_family(people[0]) is None):
        return loaded
    # The file's own axes are the camera's: undo the reader's axis change (none when it read
    # the file's Z as up, a sensor that stood the person along its optical axis's normal).
    turn = ZUP_TO_CAMERA if str(meta.get("up_axis_in_file", "Y")).upper() == "Y" else np.eye(3)
    cams = [(p.positions.astype(np.float64) @ turn.T, p.skeleton) for p in people]
    est = estimate_floor(cams, source=meta.get("source"))
    if est.tilt_deg <= WORLD_FRAME_TILT_DEG and abs(est.sensor_height_m) <= WORLD_FRAME_HEIGHT_M:
        return loaded  # already level on z = 0: the file is in a world frame
    levelled = [replace(p, positions=est.apply(cam).astype(np.float32),
                        metadata={**p.metadata, "camera_frame": est.as_metadata()})
                for p, (cam, _) in zip(people, cams, strict=True)]
    if isinstance(loaded, Interaction):
        return replace(loaded, actor=levelled[0], reactor=levelled[1])
    return levelled[0]

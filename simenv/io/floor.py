"""A file whose floor is at the feet's joint centres, or tilted: put it on the floor.

simenv takes a motion-capture file's own ground plane as the floor (z = 0 after reading):
a calibrated capture volume has its floor there, and the body fit
(:func:`simenv.body.humanoid.fit_dimensions`) hangs each sole below the toe (ball) keypoint
from it. Some processed data sets instead put the *lowest joint centre* at zero: Holden et
al.'s preprocessing of the data retargeted to the CMU skeleton (the Xia et al. style set of
deep-motion-editing), and HumanML3D's ``motion_representation`` ("put on floor": the
minimum joint height subtracted). On such a file the planted balls stand at or below z = 0;
a ball (metatarsophalangeal) joint centre of a loaded foot is at least about 15 mm above its
sole (0.6x the 25-mm anthropometric toe height, the lowest toe height the body fit accepts),
so the file's zero cannot be the floor the person stood on, and every ground metric would
then measure the file's convention instead of the motion.

The rule (:func:`floor_offset`): on every frame the lower toe keypoint, when it stands still
(:func:`planted_toe_heights`: the supporting ball, found without reference to any height, so
independent of where the file's zero is), gives a ball height; when even
their 90th percentile is below :data:`MIN_BALL_HEIGHT_M` -- nearly the whole stance below the
lowest possible ball -- the floor is at the joint centres, and the clip is raised so that
the planted balls' median stands at :data:`BALL_HEIGHT_M`. A floor at the joint centres
puts the planted balls about zero (measured: medians -12 to +8 mm on the Xia clips); a
median more than a ball's height (:data:`BALL_HEIGHT_M`) below it is a body sunk through
the floor (a defect the ground metrics must see, e.g. in a generated clip), not that
convention, and is not touched. One stance sinking (a capture glitch, a corrupted segment)
leaves the other stances' balls above the bound and is not touched; a clip without toe
keypoints or planted frames is not touched. The raise is noted in ``metadata["repairs"]``.

**A rig without toe keypoints** (:func:`ankle_floor_offset`; Aalto's and Adelaide's
OptiTrack Arena exports end the leg at the ankle) is judged on its still ankles instead,
against the ankle height the body fit gives such a clip (:func:`fit_ankle_height`: the
anthropometric 70 mm scaled by the subject's size; the fit hangs the sole that far below the
ankle keypoint): when on the foot whose planted ankles stand lowest their 90th percentile is
below :data:`MAX_ANKLE_RATIO` (0.8) of it, the floor is at the joint centres and the clip is
raised so that the planted ankles' median stands at that height. Calibrated with the toes
removed from motion capture whose answer is known: on the shared CMU corpus (27 people, floors
under the soles) the ratio is at least 0.87 (median 1.27: no clip raised); on Holden's Xia
clips (9, floor at the joint centres) at most 0.73 (all raised; the raise minus the toe
rule's: median +2 mm, at most 26 mm, the anthropometric height against the rig's own); the
CMU clips lowered onto their ankle centres are raised back in 23 of 27 (error median -9 mm,
-38 to +26 mm). A median more than a ball's height below zero is a sunk body, left alone.

**A tilted floor** (:func:`floor_plane`): the still contacts (toes, else ankles) are fitted by
a plane with one height per foot and a slope along each horizontal axis over which one foot's
contacts spread at least :data:`MIN_SPREAD_M` (1 m). A plane tilted more than
:data:`MIN_TILT_DEG` (2 deg) with a residual SD within :data:`MAX_PLANE_RESIDUAL_M` (8 mm) is a
capture volume calibrated off level (Aalto performer ``t``'s development clip: 2.7 deg): the
clip is rotated about the contacts' centroid to level it and moved, up or down, so that they
stand at the heights above (:func:`contact_offset`). The shared CMU floors tilt 0.01-0.97 deg
through the toes (one plane at 3.9 deg, in CMU 05_02's dance with a pirouette, has a 12-mm
residual and is not trusted) and 0.01-0.92 deg through the ankles; Xia's at most 0.4 deg. A
real slope cannot be told from a tilted floor in a file that holds no floor: a clip walking up
or down a ramp of 2-6 deg is levelled as if the floor were tilted (a ramp then reads as level
ground); a steeper ramp (over :data:`MAX_TILT_DEG`) is left as it is, and so are stairs (their
risers would leave centimetres of residual about any plane; no stairs clip was at hand to
measure).

Applied by :func:`simenv.load` to the formats in :data:`FILE_FLOOR_FORMATS` (the file's
coordinate frame is the world frame); depth-camera readers, and the joint-table reader on a
camera-frame table, estimate their floor themselves (:mod:`simenv.io.camera_frame`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from simenv.core.errors import MotionError
from simenv.core.motion import Interaction, Motion

#: Lowest height of a planted ball (toe keypoint) above the sole, metres: 0.6x the
#: anthropometric 25 mm, the bound of the body fit's toe height.
MIN_BALL_HEIGHT_M = 0.015
#: Height of a planted ball above the sole, metres (the anthropometric value the body fit
#: starts from, ``BodyDimensions.toe_height``).
BALL_HEIGHT_M = 0.025
#: Speed below which the lowest ball is taken as loaded, m/s: standing still (the
#: ``skate_stance_speed_mps`` of :class:`~simenv.plausibility.thresholds.Thresholds`). Not
#: the contact detector's 0.949 m/s: in gait that also takes the frames around heel strike,
#: where both balls are still descending above the floor and the heel carries the weight.
STILL_SPEED_MPS = 0.1
#: Fewest supporting-ball samples (frames) to judge the floor on.
MIN_PLANTED = 10
#: ``metadata["format"]`` values whose floor is the file's own ground plane.
FILE_FLOOR_FORMATS = frozenset({"bvh", "asf_amc", "joint_csv"})

#: The body fit's default adult (``simenv.body.humanoid.BodyDimensions``; io cannot import
#: body): ankle keypoint over the sole, metres, which the fit scales by the subject's size
#: when the clip has no toe keypoint ...
ANKLE_HEIGHT_M = 0.07
#: ... and the default lengths (metres) of the bones the scale is measured on here: keypoint
#: pair -> length (the fit takes the median ratio over all measured bones and the hip width).
_DEFAULT_BONES_M: dict[tuple[str, str], float] = {
    **{(f"{s}_{a}", f"{s}_{b}"): v for s in ("left", "right") for a, b, v in (
        ("hip", "knee", 0.43), ("knee", "ankle", 0.41), ("shoulder", "elbow", 0.30),
        ("elbow", "wrist", 0.25))},
    ("left_hip", "right_hip"): 0.18,
}
#: A toe-less clip whose lower foot's planted ankles have their 90th percentile below this
#: fraction of the fit's ankle height has its floor at the feet's joint centres (calibration:
#: module docstring).
MAX_ANKLE_RATIO = 0.8

#: A floor tilted less than this from the file's horizontal is left as it is, degrees.
MIN_TILT_DEG = 2.0
#: A plane tilted more than this is a real slope (a ramp), not a capture floor's error, deg.
MAX_TILT_DEG = 6.0
#: Least extent (metres) of the planted contacts along a horizontal axis to measure the
#: floor's slope along it.
MIN_SPREAD_M = 1.0
#: Largest residual SD (metres) of the planted contacts about the fitted plane to trust it.
MAX_PLANE_RESIDUAL_M = 0.008


class FloorPlane(NamedTuple):
    """The plane the still foot contacts of a clip lie on (:func:`floor_plane`).

    Attributes:
        normal: (3,) unit upward normal, file frame.
        centroid: (3,) mean contact position on the plane, metres.
        tilt_deg: angle between ``normal`` and +z, degrees.
        residual_m: SD of the contacts' heights about the plane, metres.
        spread_m: largest extent of one foot's contacts along a horizontal axis, metres.
        keypoint: ``"toe"`` or ``"ankle"``, the contacts used.
    """

    normal: np.ndarray
    centroid: np.ndarray
    tilt_deg: float
    residual_m: float
    spread_m: float
    keypoint: str


def planted_contacts(motion: Motion, key: str, speed_mps: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3), metres, and sides (N,) (0 left, 1 right) of the lower ``key``
    keypoint (``"toe"`` or ``"ankle"``) on each frame where its 3-D speed to the next frame is
    below ``speed_mps``. Empty when the skeleton maps neither or the clip has one frame."""
    empty = np.zeros((0, 3)), np.zeros(0, dtype=int)
    try:
        canon = motion.to_canonical()
    except MotionError:
        return empty
    sides = [i for i, s in enumerate(("left", "right"))
             if f"{s}_{key}" in canon.skeleton.joint_names]
    if not sides or canon.num_frames < 2:
        return empty
    names = [f"{('left', 'right')[i]}_{key}" for i in sides]
    pos = np.stack([canon.joint(n) for n in names], axis=1).astype(np.float64)  # (T, F, 3)
    speed = np.linalg.norm(np.diff(pos, axis=0), axis=-1) * canon.fps
    speed = np.concatenate([speed, speed[-1:]])
    lowest = pos[..., 2].argmin(axis=1)
    rows = np.arange(canon.num_frames)
    slow = speed[rows, lowest] < speed_mps
    return pos[rows, lowest][slow], np.asarray(sides)[lowest][slow]


def _has_toes(motion: Motion) -> bool:
    """Whether ``motion``'s skeleton maps a toe keypoint."""
    return any(f"{s}_toe" in motion.skeleton.canonical for s in ("left", "right"))


def planted_toe_heights(motion: Motion, speed_mps: float = STILL_SPEED_MPS) -> np.ndarray:
    """Heights (metres, z of the file) of the supporting ball: on each frame the lowest toe
    keypoint, where its 3-D speed to the next frame is below ``speed_mps`` (the ball stands
    still). Found without any height test, so it does not depend on the clip's lowest level,
    and one stance sunk through the floor does not hide the others. Empty when the skeleton
    maps no toe or the clip has one frame."""
    return planted_contacts(motion, "toe", speed_mps)[0][:, 2]


def planted_ankle_heights(motion: Motion, speed_mps: float = STILL_SPEED_MPS) -> np.ndarray:
    """Heights (metres, z of the file) of the lower ankle keypoint on the frames it stands
    still (as :func:`planted_toe_heights`, for a rig without toes). Empty when the skeleton
    maps no ankle or the clip has one frame."""
    return planted_contacts(motion, "ankle", speed_mps)[0][:, 2]


def fit_ankle_height(motion: Motion) -> float:
    """The ankle keypoint's height over the sole, metres, that the body fit gives a clip
    without toe keypoints: :data:`ANKLE_HEIGHT_M` times the subject's scale, the median ratio
    of the measured bones (:data:`_DEFAULT_BONES_M`, median over frames) to the default
    adult's, within 0.5-1.5 (``simenv.body.humanoid.fit_dimensions`` takes the same median
    over more bones; on the shared CMU corpus without toes the two differ by a median 0 mm,
    at most 7 mm)."""
    canon = motion.to_canonical()
    names = canon.skeleton.joint_names
    ratios = [float(np.median(np.linalg.norm(canon.joint(a) - canon.joint(b), axis=-1))) / v
              for (a, b), v in _DEFAULT_BONES_M.items() if a in names and b in names]
    scale = float(np.clip(np.median(ratios), 0.5, 1.5)) if ratios else 1.0
    return ANKLE_HEIGHT_M * scale


def floor_offset(people: list[Motion]) -> float:
    """How far (metres) to raise ``people`` (one shared floor) so that their supporting balls
    (:func:`planted_toe_heights`) stand on a floor under their soles; 0 when the file's
    floor already is (see the module docstring)."""
    toes = np.concatenate([planted_toe_heights(m) for m in people])
    if toes.size < MIN_PLANTED or np.percentile(toes, 90) >= MIN_BALL_HEIGHT_M:
        return 0.0
    if np.median(toes) < -BALL_HEIGHT_M:
        return 0.0  # sunk through the floor, not a floor at the joint centres
    return float(BALL_HEIGHT_M - np.median(toes))


def _ankle_gaps(people: list[Motion]) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Planted ankle heights (metres) of ``people`` pooled, each one's fit ankle height less
    it (metres), and per person and foot the heights as fractions of that fit height."""
    heights, gaps, feet = [], [], []
    for m in people:
        pts, side = planted_contacts(m, "ankle", STILL_SPEED_MPS)
        fit = fit_ankle_height(m) if len(pts) else 1.0
        heights.append(pts[:, 2])
        gaps.append(fit - pts[:, 2])
        feet += [pts[side == s, 2] / fit for s in (0, 1)]
    return np.concatenate(heights), np.concatenate(gaps), feet


def ankle_floor_offset(people: list[Motion]) -> float:
    """:func:`floor_offset` for a rig without toe keypoints: how far (metres) to raise
    ``people`` so that their planted ankles (:func:`planted_ankle_heights`) stand, at their
    median, the fit's ankle height (:func:`fit_ankle_height`) over the floor. 0 unless, on
    the foot whose planted ankles stand lowest (each foot with :data:`MIN_PLANTED` samples;
    all pooled when none has), their 90th percentile is below :data:`MAX_ANKLE_RATIO` of
    that height (an ankle cannot stand so low over its sole for nearly a whole stance); 0
    too when their median is below zero by more than a ball's height (a body sunk through
    the floor: a joint-centre floor puts a toe-less rig's lowest joints, the ankles, at
    zero)."""
    heights, gaps, feet = _ankle_gaps(people)
    if heights.size < MIN_PLANTED:
        return 0.0
    judged = [f for f in feet if f.size >= MIN_PLANTED]
    if not judged:  # pooled as fractions: each person's own fit height
        judged = [np.concatenate(feet)]
    if min(np.percentile(f, 90) for f in judged) >= MAX_ANKLE_RATIO:
        return 0.0
    if np.median(heights) < -BALL_HEIGHT_M:
        return 0.0  # sunk through the floor, not a floor at the joint centres
    return float(np.median(gaps))


def contact_offset(people: list[Motion]) -> float:
    """How far (metres, either sign) to move ``people`` up so that their still foot contacts
    stand at the sole heights the rules give, with no test: the planted balls' median at
    :data:`BALL_HEIGHT_M` (a rig with toes), else the planted ankles' median at the fit's
    ankle height. For a clip whose file floor is known wrong (a tilted one, levelled about
    its contacts' centroid: its height there is the tilt's accident); 0 without
    :data:`MIN_PLANTED` contacts."""
    if any(_has_toes(m) for m in people):
        toes = np.concatenate([planted_toe_heights(m) for m in people])
        return float(BALL_HEIGHT_M - np.median(toes)) if toes.size >= MIN_PLANTED else 0.0
    _, gaps, _ = _ankle_gaps(people)
    return float(np.median(gaps)) if gaps.size >= MIN_PLANTED else 0.0


def floor_plane(people: list[Motion]) -> FloorPlane | None:
    """The plane through the still foot contacts of ``people`` (toe keypoints, else ankles;
    :func:`planted_contacts`), fitted by least squares with one height per person and side (a
    left ankle may stand higher than the right) and a slope along each principal horizontal
    axis along which one foot's contacts spread at least :data:`MIN_SPREAD_M` (a slope across a
    walk's 0.2-m stride width is not measurable). None without :data:`MIN_PLANTED` contacts
    or any axis of that spread."""
    key = "toe" if any(_has_toes(m) for m in people) else "ankle"
    found = [planted_contacts(m, key, STILL_SPEED_MPS) for m in people]
    pts = np.concatenate([p for p, _ in found])
    if len(pts) < MIN_PLANTED:
        return None
    group = np.concatenate([2 * i + s for i, (_, s) in enumerate(found)])
    centre = pts.mean(axis=0)
    xy = pts[:, :2] - centre[:2]
    _, _, axes = np.linalg.svd(xy, full_matrices=False)  # rows: principal horizontal axes
    along = xy @ axes.T
    levels = np.unique(group)
    # An axis's slope is measured only where one foot's own contacts spread along it: with
    # per-foot heights, one stance per foot would leave the slope undetermined.
    extent = np.max([np.ptp(along[group == g], axis=0) for g in levels], axis=0)
    slopes = [k for k in range(2) if extent[k] >= MIN_SPREAD_M]
    if not slopes:
        return None
    design = np.concatenate([(group[:, None] == levels[None]).astype(float),
                             along[:, slopes]], axis=1)
    coef, *_ = np.linalg.lstsq(design, pts[:, 2], rcond=None)
    grad = np.zeros(2)
    for k, c in zip(slopes, coef[len(levels):], strict=True):
        grad += c * axes[k]
    normal = np.array([-grad[0], -grad[1], 1.0]) / np.hypot(np.linalg.norm(grad), 1.0)
    resid = pts[:, 2] - design @ coef
    on_plane = np.array([*centre[:2], float(np.mean(design[:, :len(levels)] @ coef[:len(levels)]))])
    return FloorPlane(normal, on_plane, float(np.degrees(np.arccos(normal[2]))),
                      float(resid.std()), float(extent.max()), key)


def is_tilted_floor(plane: FloorPlane | None) -> bool:
    """Whether ``plane`` is a capture floor tilted enough, and fitted well enough, to level."""
    return (plane is not None and MIN_TILT_DEG < plane.tilt_deg <= MAX_TILT_DEG
            and plane.residual_m <= MAX_PLANE_RESIDUAL_M)


def _levelling(plane: FloorPlane) -> np.ndarray:
    """(3, 3) rotation turning ``plane.normal`` onto +z about their common perpendicular."""
    n, z = plane.normal, np.array([0.0, 0.0, 1.0])
    axis = np.cross(n, z)
    s, c = np.linalg.norm(axis), float(n @ z)
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    k /= s
    return np.eye(3) + s * k + (1.0 - c) * k @ k


def _quat_of(rot: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion (w, x, y, z) of a (3, 3) rotation of less than 90 deg."""
    w = 0.5 * np.sqrt(max(1.0 + np.trace(rot), 0.0))
    return np.array([w, (rot[2, 1] - rot[1, 2]) / (4 * w), (rot[0, 2] - rot[2, 0]) / (4 * w),
                     (rot[1, 0] - rot[0, 1]) / (4 * w)])


def _rotated(m: Motion, rot: np.ndarray, about: np.ndarray) -> Motion:
    """``m`` turned by ``rot`` about the point ``about`` (metres); its root joints'
    rotations (relative to the world) turned with it."""
    pos = (m.positions.astype(np.float64) - about) @ rot.T + about
    rotations = m.rotations
    if rotations is not None:
        q = _quat_of(rot)
        r = rotations.astype(np.float64).copy()
        roots = [j for j, p in enumerate(m.skeleton.parents) if p < 0]
        w, v = r[:, roots, :1], r[:, roots, 1:]
        r[:, roots, :1] = q[0] * w - v @ q[1:, None]
        r[:, roots, 1:] = q[0] * v + w * q[1:] + np.cross(q[1:], v)
        rotations = r.astype(np.float32)
    return replace(m, positions=pos.astype(np.float32), rotations=rotations)


def _raised(m: Motion, dz: float, note: str) -> Motion:
    """``m`` moved up by ``dz`` metres, ``note`` added to its repairs."""
    pos = m.positions.copy()
    pos[..., 2] += dz
    meta = dict(m.metadata)
    meta["repairs"] = [*meta.get("repairs", []), note]
    return replace(m, positions=pos, metadata=meta)


def _level_note(plane: FloorPlane, dz: float) -> str:
    target = "balls' median stands at the ball height" if plane.keypoint == "toe" else (
        "ankles' median stands at the body fit's ankle height")
    return (f"floor tilted: the still {plane.keypoint} keypoints lie on a plane "
            f"{plane.tilt_deg:.1f} deg from the file's horizontal (residual SD "
            f"{1000 * plane.residual_m:.1f} mm, one foot's contacts over {plane.spread_m:.1f} "
            f"m); levelled about their centroid, then raised by {1000 * dz:+.0f} mm so the "
            f"planted {target} (simenv.io.floor)")


def _raise_note(people: list[Motion], dz: float) -> str:
    if any(_has_toes(m) for m in people):
        toes = np.concatenate([planted_toe_heights(m) for m in people])
        return (f"floor at the feet's joint centres: planted toe keypoints at a median "
                f"{1000 * np.median(toes):.0f} mm (90th percentile "
                f"{1000 * np.percentile(toes, 90):.0f} mm, below the "
                f"{1000 * MIN_BALL_HEIGHT_M:.0f} mm a ball stands over its sole); raised by "
                f"{1000 * dz:.0f} mm so they stand at {1000 * BALL_HEIGHT_M:.0f} mm "
                f"(simenv.io.floor)")
    ankles = np.concatenate([planted_ankle_heights(m) for m in people])
    fit = np.mean([fit_ankle_height(m) for m in people])
    return (f"floor at the feet's joint centres (no toe keypoints): planted ankle keypoints at "
            f"a median {1000 * np.median(ankles):.0f} mm, the lower foot's nearly all below "
            f"{MAX_ANKLE_RATIO:.1f}x the {1000 * fit:.0f} mm ankle height of the body fit; "
            f"raised by {1000 * dz:.0f} mm so their median stands at that height "
            f"(simenv.io.floor)")


def put_on_floor(loaded: Motion | Interaction) -> Motion | Interaction:
    """``loaded`` on the floor under its soles, each change noted in ``metadata["repairs"]``:

    * levelled when its still foot contacts lie on a tilted plane (:func:`floor_plane`;
      tilt between :data:`MIN_TILT_DEG` and :data:`MAX_TILT_DEG`, residual SD within
      :data:`MAX_PLANE_RESIDUAL_M`), about the contacts' centroid, then moved up or down
      by :func:`contact_offset` (the file's floor is then known wrong, so its height at the
      centroid is no evidence);
    * otherwise raised by :func:`floor_offset` (a rig with toe keypoints) or
      :func:`ankle_floor_offset` (without) when its file's floor is at the feet's joint
      centres.

    Unchanged otherwise, and for formats not in :data:`FILE_FLOOR_FORMATS` or read from a
    depth camera's frame (``metadata["camera_frame"]``: the reader put that clip on a floor
    it estimated from the feet)."""
    people = list(loaded.people) if isinstance(loaded, Interaction) else [loaded]
    meta = people[0].metadata
    if str(meta.get("format", "")).lower() not in FILE_FLOOR_FORMATS or "camera_frame" in meta:
        return loaded  # not the file's floor, or one the reader estimated from the feet
    plane = floor_plane(people)
    if plane is not None and is_tilted_floor(plane):
        rot = _levelling(plane)
        level = [_rotated(m, rot, plane.centroid) for m in people]
        dz = contact_offset(level)
        note = _level_note(plane, dz)
        people = [_raised(m, dz, note) for m in level]
    else:
        toes = any(_has_toes(m) for m in people)
        dz = floor_offset(people) if toes else ankle_floor_offset(people)
        if dz <= 0.0:
            return loaded
        note = _raise_note(people, dz)
        people = [_raised(m, dz, note) for m in people]
    if isinstance(loaded, Interaction):
        return replace(loaded, actor=people[0], reactor=people[1])
    return people[0]

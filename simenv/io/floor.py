"""A file whose floor is at the feet's joint centres, not under their soles: put it on the floor.

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

Applied by :func:`simenv.load` to the formats in :data:`FILE_FLOOR_FORMATS` (the file's
coordinate frame is the world frame); depth-camera readers, and the joint-table reader on a
camera-frame table, estimate their floor themselves (:mod:`simenv.io.camera_frame`).
"""

from __future__ import annotations

from dataclasses import replace

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


def planted_toe_heights(motion: Motion, speed_mps: float = STILL_SPEED_MPS) -> np.ndarray:
    """Heights (metres, z of the file) of the supporting ball: on each frame the lowest toe
    keypoint, where its 3-D speed to the next frame is below ``speed_mps`` (the ball stands
    still). Found without any height test, so it does not depend on the clip's lowest level,
    and one stance sunk through the floor does not hide the others. Empty when the skeleton
    maps no toe or the clip has one frame."""
    try:
        canon = motion.to_canonical()
    except MotionError:
        return np.zeros(0)
    toes = [f"{s}_toe" for s in ("left", "right") if f"{s}_toe" in canon.skeleton.joint_names]
    if not toes or canon.num_frames < 2:
        return np.zeros(0)
    pos = np.stack([canon.joint(t) for t in toes], axis=1).astype(np.float64)  # (T, F, 3)
    speed = np.linalg.norm(np.diff(pos, axis=0), axis=-1) * canon.fps
    speed = np.concatenate([speed, speed[-1:]])
    lowest = pos[..., 2].argmin(axis=1)
    rows = np.arange(canon.num_frames)
    slow = speed[rows, lowest] < speed_mps
    return pos[rows, lowest, 2][slow]


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


def _raised(m: Motion, dz: float, note: str) -> Motion:
    pos = m.positions.copy()
    pos[..., 2] += dz
    meta = dict(m.metadata)
    meta["repairs"] = [*meta.get("repairs", []), note]
    return replace(m, positions=pos, metadata=meta)


def put_on_floor(loaded: Motion | Interaction) -> Motion | Interaction:
    """``loaded`` raised by :func:`floor_offset` when its file's floor is at the feet's joint
    centres (noted in ``metadata["repairs"]``); unchanged otherwise, and for formats not in
    :data:`FILE_FLOOR_FORMATS` or read from a depth camera's frame (``metadata["camera_frame"]``:
    the reader put that clip on a floor it estimated from the feet)."""
    people = list(loaded.people) if isinstance(loaded, Interaction) else [loaded]
    meta = people[0].metadata
    if str(meta.get("format", "")).lower() not in FILE_FLOOR_FORMATS or "camera_frame" in meta:
        return loaded  # not the file's floor, or one the reader estimated from the feet
    dz = floor_offset(people)
    if dz <= 0.0:
        return loaded
    toes = np.concatenate([planted_toe_heights(m) for m in people])
    note = (f"floor at the feet's joint centres: planted toe keypoints at a median "
            f"{1000 * np.median(toes):.0f} mm (90th percentile "
            f"{1000 * np.percentile(toes, 90):.0f} mm, below the {1000 * MIN_BALL_HEIGHT_M:.0f}"
            f" mm a ball stands over its sole); raised by {1000 * dz:.0f} mm so they stand at "
            f"{1000 * BALL_HEIGHT_M:.0f} mm (simenv.io.floor)")
    if isinstance(loaded, Interaction):
        return replace(loaded, actor=_raised(loaded.actor, dz, note),
                       reactor=_raised(loaded.reactor, dz, note))
    return _raised(loaded, dz, note)

"""Joint-level ground metrics: foot contact, foot skating, ground penetration
and floating, on keypoint heights (not body geoms).

Frame: world Z-up, the floor is the plane z = 0, metres. Keypoints are joint
centres, which sit a few centimetres above the skin; thresholds account for
that (see :class:`~simenv.plausibility.thresholds.Thresholds`).

Feet: each side uses its toe keypoint; a side without a toe keypoint falls
back to its ankle, whose height is measured from the ankles' own lowest level
with the ankle height threshold. The ankle fallback is a coarser test: the
ankle rises and travels at heel strike and heel-off (see
:class:`~simenv.plausibility.thresholds.Thresholds`). Short clips and missing
keypoints give ``MetricResult.not_available`` with a reason, as in
:mod:`simenv.plausibility.kinematic`.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d

from simenv.motion import Motion
from simenv.plausibility.kinematic import canonical_or_reason, keypoint_indices
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult

#: Keypoints whose mean is the centre-of-mass proxy of the floating test.
COM_KEYPOINTS: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine", "chest", "neck",
    "left_shoulder", "right_shoulder",
)


#: Keypoints that may rest on the palm and fingers below them.
HAND_KEYPOINTS: tuple[str, ...] = ("left_wrist", "right_wrist", "left_hand", "right_hand")


def foot_keypoints(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS
                   ) -> tuple[list[str], np.ndarray]:
    """Foot keypoints of a canonical ``motion`` and their contact heights.

    Returns:
        (names, heights): per side the toe keypoint, or the ankle when the
        toe is missing; ``heights`` (F,) metres are ``contact_height_m`` for
        toes and ``contact_height_ankle_m`` for ankles.
    """
    present = set(motion.skeleton.joint_names)
    names, heights = [], []
    for side in ("left", "right"):
        if f"{side}_toe" in present:
            names.append(f"{side}_toe")
            heights.append(thresholds.contact_height_m)
        elif f"{side}_ankle" in present:
            names.append(f"{side}_ankle")
            heights.append(thresholds.contact_height_ankle_m)
    return names, np.array(heights)


def foot_floor(positions: np.ndarray) -> float:
    """Height (metres) taken as the floor for contact tests: the 1st
    percentile over frames of the lowest keypoint.

    As in HumanML3D / InterGen / GMD, contact heights are measured from the
    clip's own lowest point rather than z = 0, so a skeleton whose toe joint
    centres sit 7 cm above the sole, or a clip with a constant floor offset,
    still gets contacts (floor offsets are judged by
    :func:`ground_penetration` and :func:`floating`). The percentile ignores
    a few stray frames.
    """
    return float(np.percentile(positions[..., 2].min(axis=1), 1))


def _foot_heights(canon: Motion, feet: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(T, F, 3) foot positions and (T, F) heights above each foot's floor:
    toes from :func:`foot_floor`, ankles (toe-less sides) from the ankles'
    own lowest level."""
    pos = canon.positions.astype(np.float64)
    foot_pos = pos[:, keypoint_indices(canon, feet)]
    ankles = np.array([f.endswith("_ankle") for f in feet])
    floors = np.full(len(feet), foot_floor(pos))
    if ankles.any():
        floors[ankles] = np.percentile(foot_pos[:, ankles, 2].min(axis=1), 1)
    return foot_pos, foot_pos[..., 2] - floors


def foot_contacts(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS
                  ) -> tuple[list[str], np.ndarray]:
    """Planted-foot detection from height and speed (InterGen style).

    Foot f is in contact at frame t when its height above the clip's foot
    floor (:func:`foot_floor`; ankles: their own lowest level) is below its
    contact height (5 cm) and its 3-D speed to the next frame is below
    ``contact_speed_mps`` (InterGen's 0.001 m^2 per frame at 30 fps, as a
    speed). The last frame reuses the previous speed; a one-frame clip uses
    the height test alone.

    Returns:
        (foot keypoint names, contacts (T, F) bool); F may be 0 when the
        skeleton has neither toes nor ankles.
    """
    canon, _ = canonical_or_reason(motion)
    if canon is None:
        return [], np.zeros((motion.num_frames, 0), dtype=bool)
    feet, heights = foot_keypoints(canon, thresholds)
    if not feet:
        return feet, np.zeros((motion.num_frames, 0), dtype=bool)
    foot_pos, rel = _foot_heights(canon, feet)
    low = rel < heights
    if motion.num_frames < 2:
        return feet, low
    speed = np.linalg.norm(np.diff(foot_pos, axis=0), axis=-1) * motion.fps
    speed = np.concatenate([speed, speed[-1:]])
    return feet, low & (speed < thresholds.contact_speed_mps)


def foot_skate(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricResult:
    """Foot skating: sustained sliding of a foot at floor height.

    Let ``v_f(t)`` be the horizontal speed of foot f between frames t-1 and t.
    The foot is *low* over that pair when its height above the clip's foot
    floor (:func:`foot_floor`; ankles: their own lowest level) is below its
    contact height (5 cm) at both frames, and it *slides* when also ``v_f(t) >
    skate_speed_mps`` (0.5 m/s): the GMD / OmniControl skating test. Only
    sliding runs lasting at least ``skate_min_duration_s`` count as skating:
    on joint-centre mocap the toe keypoint stays within 5 cm of the floor for
    the first 20-100 ms of every swing while already moving fast, which the
    published test (with its 0.25 s moving average) counts as skating; a
    planted foot that really slides does so for a good part of its stance.
    A low foot sliding while the other foot is planted and lower (by more
    than ``skate_support_margin_m``) is unloaded -- the weight is on the
    other foot -- and does not count either.

    Timeline: ``max_f v_f(t)`` over skating feet (0 when none) in **mm per
    frame at 20 fps** (``speed * 1000 / skate_reference_fps``, PhysDiff's
    unit at HumanML3D's rate, so comparable across frame rates); NaN on frame
    0; frames above 25 mm/frame (0.5 m/s) are violations. Value: fraction of
    frame pairs with a skating foot; passes when at most ``skate_ratio_max``.

    Details: ``gmd_skating_ratio`` (the published GMD / OmniControl ratio: low
    feet whose instantaneous and ``skate_window_s``-averaged horizontal
    speeds both exceed 0.5 m/s, for comparison with papers),
    ``physdiff_skate_mm`` (PhysDiff "skate": over frame pairs, the mean
    horizontal displacement of the feet planted at both frames by
    :func:`foot_contacts` (height and speed), 0 when none, in mm per frame at
    20 fps), ``max_slide_mm`` and ``contact_fraction`` (frames with a planted
    foot). Needs two frames and a toe or ankle keypoint.
    """
    ref = thresholds.skate_reference_fps
    name, unit, thr = "foot_skate", "fraction", thresholds.skate_ratio_max
    kwargs = {"frame_threshold": thresholds.skate_speed_mps * 1000.0 / ref,
              "timeline_unit": f"mm/frame at {ref:g} fps"}
    canon, reason = canonical_or_reason(motion)
    if canon is None:
        return MetricResult.not_available(name, motion.num_frames, unit, thr, reason or "",
                                          **kwargs)
    feet, heights = foot_keypoints(canon, thresholds)
    if not feet:
        return MetricResult.not_available(
            name, motion.num_frames, unit, thr,
            "needs a toe or ankle keypoint (the skeleton has neither)", **kwargs,
        )
    if motion.num_frames < 2:
        return MetricResult.not_available(
            name, motion.num_frames, unit, thr,
            f"needs at least 2 frames for a speed; the motion has {motion.num_frames}", **kwargs,
        )
    fps = motion.fps
    foot_pos, rel = _foot_heights(canon, feet)
    low = rel < heights
    low_pair = low[1:] & low[:-1]  # (T-1, F)
    v_h = np.linalg.norm(np.diff(foot_pos[..., :2], axis=0), axis=-1) * fps
    raw_sliding = low_pair & (v_h > thresholds.skate_speed_mps)
    sliding = raw_sliding
    if sliding.shape[1] == 2:
        # The other foot, planted and lower, carries the weight: this one is unloaded.
        margin = thresholds.skate_support_margin_m
        other = slice(None, None, -1)
        supported = ((v_h[:, other] <= thresholds.skate_speed_mps)
                     & (rel[1:, other] + margin < rel[1:]) & (rel[:-1, other] + margin < rel[:-1]))
        sliding = raw_sliding & ~supported
    min_len = max(1, round(thresholds.skate_min_duration_s * fps))
    skating = np.zeros_like(sliding)
    for f in range(sliding.shape[1]):
        for start, stop in _runs(sliding[:, f]):
            if stop - start >= min_len:
                skating[start:stop, f] = True
    slide = np.where(skating, v_h, 0.0).max(axis=1)
    to_mm = 1000.0 / ref
    timeline = np.full(motion.num_frames, np.nan)
    timeline[1:] = slide * to_mm
    ratio = float(skating.any(axis=1).mean())

    window = max(1, round(thresholds.skate_window_s * fps))
    v_avg = uniform_filter1d(v_h, size=window, axis=0, mode="constant")
    gmd = raw_sliding & (v_avg > thresholds.skate_speed_mps)
    _, planted = foot_contacts(canon, thresholds)
    planted_pair = planted[1:] & planted[:-1]
    n_planted = planted_pair.sum(axis=1)
    disp = np.where(planted_pair, v_h, 0.0).sum(axis=1) / np.maximum(n_planted, 1)
    return MetricResult.from_timeline(
        name, timeline, ratio, unit, thr, **kwargs,
        details={
            "gmd_skating_ratio": float(gmd.any(axis=1).mean()),
            "physdiff_skate_mm": float(disp.mean() * to_mm),
            "max_slide_mm": float(slide.max() * to_mm),
            "contact_fraction": float(planted.any(axis=1).mean()),
            "ankle_fallback": float(any(f.endswith("_ankle") for f in feet)),
        },
    )


def ground_penetration(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS
                       ) -> MetricResult:
    """Depth of the lowest keypoint below the floor (PhysDiff "penetrate" at
    keypoint level).

    Timeline: ``max(0, -min_j z_j(t)) * 1000`` mm over all canonical keypoints
    (feet, but also hands or knees on the floor). Value: the maximum over
    frames; passes when at most ``penetration_max_mm``. Details:
    ``mean_mm`` (PhysDiff's per-clip mean over frames) and
    ``frames_below_floor`` (fraction). Works on a single frame.
    """
    name, unit, thr = "ground_penetration", "mm", thresholds.penetration_max_mm
    canon, reason = canonical_or_reason(motion)
    if canon is None:
        return MetricResult.not_available(name, motion.num_frames, unit, thr, reason or "")
    lowest = canon.positions[..., 2].astype(np.float64).min(axis=1)
    depth = np.maximum(-lowest, 0.0) * 1000.0
    return MetricResult.from_timeline(
        name, depth, float(depth.max()), unit, thr,
        details={"mean_mm": float(depth.mean()), "frames_below_floor": float((depth > 0).mean())},
    )


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True in a 1-D mask."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def ballistic_residual(height: np.ndarray, fps: float, gravity: float) -> float:
    """RMS residual (metres) of the best free-fall fit to a height track.

    Fits ``z(t) = z0 + v0 t - g t^2 / 2`` (only z0 and v0 free) by least
    squares to ``height`` (N,) sampled at ``fps``; a body with nothing
    supporting it follows such an arc exactly (its centre of mass does).
    Returns 0 for fewer than three samples (two parameters fit them exactly).
    """
    n = len(height)
    if n < 3:
        return 0.0
    t = np.arange(n) / fps
    target = np.asarray(height, dtype=np.float64) + 0.5 * gravity * t**2
    design = np.stack([np.ones(n), t], axis=1)
    coef, *_ = np.linalg.lstsq(design, target, rcond=None)
    return float(np.sqrt(np.mean((target - design @ coef) ** 2)))


def floating(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricResult:
    """Floating: airborne frames that are not a jump.

    A frame is airborne when its lowest keypoint is more than
    ``float_height_m`` above the floor (z = 0); wrist and hand keypoints
    count ``float_hand_reach_m`` lower (the palm and fingers can carry the
    body). Each maximal airborne run is tested for a ballistic flight: the
    centre-of-mass proxy (mean of the trunk keypoints :data:`COM_KEYPOINTS`
    present) must follow a free-fall parabola, i.e. vertical acceleration
    -g, within an RMS residual of ``ballistic_tolerance_m``
    (:func:`ballistic_residual`). Jumps pass; a body hovering, rising or
    sinking slowly without support fails.

    Timeline: height in mm of the lowest (support-adjusted) keypoint on
    frames of non-ballistic airborne runs, 0 elsewhere; value: its maximum;
    passes when no frame floats (value at most ``float_height_m`` in mm).
    Details: ``airborne_fraction``, ``floating_fraction``,
    ``worst_residual_m``, ``jumps`` (ballistic runs).

    Assumes the floor is the only support (no chairs, props or partners:
    those need the body-level metrics). Needs three frames.
    """
    name, unit, thr = "floating", "mm", thresholds.float_height_m * 1000.0
    canon, reason = canonical_or_reason(motion)
    if canon is None:
        return MetricResult.not_available(name, motion.num_frames, unit, thr, reason or "")
    com_idx = keypoint_indices(canon, COM_KEYPOINTS)
    if not com_idx:
        return MetricResult.not_available(
            name, motion.num_frames, unit, thr,
            "needs a trunk keypoint (pelvis, hips, spine, chest, neck or shoulders) for the "
            "centre-of-mass proxy",
        )
    if motion.num_frames < 3:
        return MetricResult.not_available(
            name, motion.num_frames, unit, thr,
            "needs at least 3 frames to tell a jump from floating; the motion has "
            f"{motion.num_frames}",
        )
    pos = canon.positions.astype(np.float64)
    hands = keypoint_indices(canon, HAND_KEYPOINTS)
    support = pos[..., 2].copy()
    support[:, hands] -= thresholds.float_hand_reach_m
    lowest = support.min(axis=1)
    com_z = pos[:, com_idx, 2].mean(axis=1)
    airborne = lowest > thresholds.float_height_m
    floating_mask = np.zeros(motion.num_frames, dtype=bool)
    worst, jumps = 0.0, 0
    for start, stop in _runs(airborne):
        residual = ballistic_residual(com_z[start:stop], motion.fps, thresholds.gravity_mps2)
        worst = max(worst, residual)
        if residual > thresholds.ballistic_tolerance_m:
            floating_mask[start:stop] = True
        else:
            jumps += 1
    timeline = np.where(floating_mask, lowest * 1000.0, 0.0)
    return MetricResult.from_timeline(
        name, timeline, float(timeline.max()), unit, thr,
        details={
            "airborne_fraction": float(airborne.mean()),
            "floating_fraction": float(floating_mask.mean()),
            "worst_residual_m": worst,
            "jumps": float(jumps),
        },
    )

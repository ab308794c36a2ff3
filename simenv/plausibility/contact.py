"""Joint-level ground metrics: foot skating, ground penetration and floating,
on keypoint heights (not body geoms).

Frame: world Z-up, the floor is the plane z = 0, metres. Keypoints are joint
centres, which sit a few centimetres above the skin; thresholds account for
that (see :class:`~simenv.plausibility.thresholds.Thresholds`).

Feet: each side uses its toe keypoint; a side without a toe keypoint falls
back to its ankle, whose height is measured from the ankles' own lowest level
with the ankle height threshold. The ankle fallback is a coarser test: the
ankle rises and travels at heel strike and heel-off (see
:class:`~simenv.plausibility.thresholds.Thresholds`); the planted-foot
detection is :mod:`simenv.body.foot_contact`. Short clips and missing
keypoints give ``MetricResult.not_available`` with a reason, as in
:mod:`simenv.plausibility.kinematic`.
"""

from __future__ import annotations

import numpy as np

from simenv.body.foot_contact import foot_keypoints
from simenv.core.motion import Motion
from simenv.plausibility import kernels
from simenv.plausibility.clips import ClipBatch, MetricSpec, score_clip
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds
from simenv.plausibility.timeline import MetricResult

#: Keypoints whose mean is the centre-of-mass proxy of the floating test.
COM_KEYPOINTS: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine", "chest", "neck",
    "left_shoulder", "right_shoulder",
)


#: Keypoints that may rest on the palm and fingers below them.
HAND_KEYPOINTS: tuple[str, ...] = ("left_wrist", "right_wrist", "left_hand", "right_hand")


def foot_skate(motion: Motion, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricResult:
    """Foot skating: sustained sliding of a foot at floor height.

    Let ``v_f(t)`` be the horizontal speed of foot f between frames t-1 and t.
    The foot is *low* over that pair when its height above the clip's foot
    floor (:func:`simenv.body.foot_contact.foot_floor`; ankles: their own
    lowest level) is below its contact height (5 cm) at both frames, and it
    *slides* when also ``v_f(t) > skate_speed_mps`` (0.5 m/s): the GMD /
    OmniControl skating test. Only sliding runs lasting at least
    ``skate_min_duration_s`` count as skating: on joint-centre mocap the toe
    keypoint stays within 5 cm of the floor for the first 20-100 ms of every
    swing while already moving fast, which the published test (with its
    0.25 s moving average) counts as skating; a planted foot that really
    slides does so for a good part of its stance. A low foot sliding while
    the other foot is planted and lower (by more than
    ``skate_support_margin_m``) is unloaded -- the weight is on the other
    foot -- and does not count either.

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
    :func:`simenv.body.foot_contact.foot_contacts` (height and speed), 0 when
    none, in mm per frame at 20 fps), ``max_slide_mm`` and
    ``contact_fraction`` (frames with a planted foot). Needs two frames and a
    toe or ankle keypoint.
    """
    return score_clip(motion, foot_skate_spec, thresholds)


def foot_skate_spec(batch: ClipBatch, thresholds: Thresholds = DEFAULT_THRESHOLDS
                    ) -> MetricSpec:
    """:func:`foot_skate` as :func:`~simenv.plausibility.clips.score` runs it."""
    ref = thresholds.skate_reference_fps
    frames, fps = batch.num_frames, batch.fps
    feet, heights = foot_keypoints(batch.names, thresholds.contact_height_m,
                                   thresholds.contact_height_ankle_m)
    ankles = np.array([f.endswith("_ankle") for f in feet], dtype=np.bool_)
    args, reason = None, ""
    if batch.skeleton is None:
        pass
    elif not feet:
        reason = "needs a toe or ankle keypoint (the skeleton has neither)"
    elif frames < 2:
        reason = f"needs at least 2 frames for a speed; the motion has {frames}"
    else:
        args = (np.array(batch.indices(feet), dtype=np.int64), heights.astype(np.float64),
                ankles, float(fps), float(thresholds.skate_speed_mps),
                float(thresholds.skate_support_margin_m),
                max(1, round(thresholds.skate_min_duration_s * fps)),
                max(1, round(thresholds.skate_window_s * fps)),
                float(thresholds.contact_speed_mps), 1000.0 / ref)
    return MetricSpec(
        kernels.FOOT, "foot_skate", "fraction", thresholds.skate_ratio_max, args,
        ("gmd_skating_ratio", "physdiff_skate_mm", "max_slide_mm", "contact_fraction",
         ("ankle_fallback", float(ankles.any()))),
        frame_threshold=thresholds.skate_speed_mps * 1000.0 / ref,
        timeline_unit=f"mm/frame at {ref:g} fps", reason=reason)


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
    return score_clip(motion, ground_penetration_spec, thresholds)


def ground_penetration_spec(batch: ClipBatch, thresholds: Thresholds = DEFAULT_THRESHOLDS
                            ) -> MetricSpec:
    """:func:`ground_penetration` as :func:`~simenv.plausibility.clips.score`
    runs it."""
    return MetricSpec(kernels.GROUND, "ground_penetration", "mm",
                      thresholds.penetration_max_mm,
                      None if batch.skeleton is None else (),
                      ("mean_mm", "frames_below_floor"))


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
    return score_clip(motion, floating_spec, thresholds)


def floating_spec(batch: ClipBatch, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> MetricSpec:
    """:func:`floating` as :func:`~simenv.plausibility.clips.score` runs it."""
    com_idx = batch.indices(COM_KEYPOINTS)
    frames = batch.num_frames
    args, reason = None, ""
    if batch.skeleton is None:
        pass
    elif not com_idx:
        reason = ("needs a trunk keypoint (pelvis, hips, spine, chest, neck or shoulders) for "
                  "the centre-of-mass proxy")
    elif frames < 3:
        reason = (f"needs at least 3 frames to tell a jump from floating; the motion has "
                  f"{frames}")
    else:
        args = (np.array(com_idx, dtype=np.int64),
                np.array(batch.indices(HAND_KEYPOINTS), dtype=np.int64),
                float(thresholds.float_hand_reach_m), float(thresholds.float_height_m),
                float(batch.fps), float(thresholds.gravity_mps2),
                float(thresholds.ballistic_tolerance_m))
    return MetricSpec(
        kernels.FLOAT, "floating", "mm", thresholds.float_height_m * 1000.0, args,
        ("airborne_fraction", "floating_fraction", "worst_residual_m", "jumps"),
        reason=reason)

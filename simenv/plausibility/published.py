"""The physics metrics of motion-generation papers, in their published definitions.

So a user can put our numbers beside a paper's table, these are computed
exactly as published (where the definition could be confirmed; see
``docs/published_metrics.md`` for the sources and for what could not be):

PhysDiff (Yuan et al., ICCV 2023), on a 20 fps clip, metres -> mm
    Penetrate
        ``mean_t max(0, -min_j z_j(t))``: per frame the distance between the
        ground (z = 0) and the lowest point below it, 0 when nothing is
        below; mean over frames.
    Float
        ``mean_t f(t)`` with ``f(t) = min_j z_j(t)`` when the lowest point
        is above the ground by more than ``float_tolerance_m``, else 0.
    Skate
        For each pair of adjacent frames, the foot joints in contact with the
        ground at both frames; their mean horizontal displacement
        ``||(x, y)_f(t+1) - (x, y)_f(t)||`` (0 when no foot is in contact);
        mean over frame pairs. Contact: foot height ``z_f < contact_height_m``
        (5 cm).
    Phys-Err
        ``Penetrate + Float + Skate`` (mm).

GMD (Karunratanakul et al., ICCV 2023) / OmniControl (Xie et al., ICLR 2024)
    Foot-skating ratio: a foot (SMPL joints 10/11, our ``left_toe`` /
    ``right_toe``) *skates* over the frame pair (t, t+1) when its height is
    below 5 cm at both frames and its horizontal speed ``v_f(t) = 20 *
    ||(x, y)_f(t+1) - (x, y)_f(t)||`` (m/s at 20 fps) exceeds 0.5 m/s (2.5 cm
    per frame) both at that pair and averaged over a 5-pair window
    (``scipy.ndimage.uniform_filter1d(size=5, mode="constant")``, zero
    padded); the ratio is the fraction of the ``T - 1`` pairs where either
    foot skates.

Common conventions
    * The published code measures heights from the plane y = 0 of the
      motion it is given (here z = 0: ``floor="world"``, the default). Real
      HumanML3D clips have their lowest joint moved onto that plane by
      HumanML3D's preprocessing (``floor_height = positions.min(axis=0)
      .min(axis=0)[1]``), generated clips are taken as the model wrote them.
      ``floor="lowest_joint"`` applies HumanML3D's preprocessing first: that is
      how a real mocap clip (whose joint centres stand a few centimetres
      above its z = 0 floor) compares with a paper's "Real" row.
    * A clip at another rate than 20 fps is first resampled to 20 fps
      (:meth:`~simenv.core.motion.Motion.resample`, linear), because Skate (mm
      per frame) and GMD's window (5 frames) are defined per 20 fps frame.
    * Points are the motion's canonical keypoints (joint centres), not the
      SMPL mesh vertices PhysDiff uses for Penetrate and Float: a joint
      centre sits a few centimetres above the skin, so on joints Float reads
      higher and Penetrate lower than on a mesh of the same motion.
    * Feet are the ``left_toe`` / ``right_toe`` keypoints (SMPL ``foot``
      joints 10/11, as GMD); a side without a toe uses its ankle (reported in
      :attr:`PublishedMetrics.feet`), which GMD does not define.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from scipy.ndimage import uniform_filter1d

from simenv.core.errors import MotionError, SimenvError, SkeletonError
from simenv.core.motion import Motion

#: Frame rate the published metrics are defined at (HumanML3D's rate).
PUBLISHED_FPS = 20.0
#: GMD ``thresh_height`` and our PhysDiff-Skate contact height: a foot joint
#: below this height (metres) touches the ground.
CONTACT_HEIGHT_M = 0.05
#: GMD ``thresh_vel``: 0.5 m/s, i.e. 2.5 cm per frame at 20 fps.
SKATE_SPEED_MPS = 0.5
#: GMD ``avg_window``: frames of the moving average of the foot speed.
SKATE_WINDOW_FRAMES = 5
#: PhysDiff Float: a lowest point within this height (metres) of the ground
#: is on it. PhysDiff publishes no tolerance; 0 follows its text.
FLOAT_TOLERANCE_M = 0.0

#: Floor conventions of :func:`published_metrics`.
Floor = Literal["world", "lowest_joint"]
FLOORS: tuple[str, ...] = ("world", "lowest_joint")

#: Names and units of the published metrics in the score JSON (``published``).
PUBLISHED_METRICS: dict[str, str] = {
    "physdiff_penetrate": "mm",
    "physdiff_float": "mm",
    "physdiff_skate": "mm",
    "physdiff_phys_err": "mm",
    "gmd_skating_ratio": "fraction",
}


@dataclass(frozen=True)
class PublishedMetrics:
    """The published metrics of one motion.

    Attributes:
        penetrate_mm, float_mm, skate_mm, phys_err_mm: PhysDiff's metrics
            (module docstring), millimetres (Skate: mm per 20 fps frame).
        skating_ratio: GMD / OmniControl foot-skating ratio in [0, 1].
        feet: the two foot keypoints used (toes, or ankles where a side has
            no toe).
        frames: frames evaluated (after resampling to 20 fps).
        resampled_from_fps: the motion's own rate when it was resampled,
            else None.
    """

    penetrate_mm: float
    float_mm: float
    skate_mm: float
    phys_err_mm: float
    skating_ratio: float
    feet: tuple[str, str]
    frames: int
    resampled_from_fps: float | None

    def values(self) -> dict[str, float]:
        """Name -> value, the keys of :data:`PUBLISHED_METRICS`."""
        return {"physdiff_penetrate": self.penetrate_mm, "physdiff_float": self.float_mm,
                "physdiff_skate": self.skate_mm, "physdiff_phys_err": self.phys_err_mm,
                "gmd_skating_ratio": self.skating_ratio}


def foot_keypoints(motion: Motion) -> tuple[str, str]:
    """The (left, right) foot keypoints of ``motion``'s canonical skeleton:
    each side's toe, else its ankle.

    Raises:
        SkeletonError: a side has neither toe nor ankle (names the source and
            the missing keypoint).
    """
    present = set(motion.skeleton.canonical)
    feet = []
    for side in ("left", "right"):
        for name in (f"{side}_toe", f"{side}_ankle"):
            if name in present:
                feet.append(name)
                break
        else:
            raise SkeletonError(
                f"skeleton {motion.skeleton.name!r} has no {side} foot (neither {side}_toe nor "
                f"{side}_ankle among its canonical keypoints); the published foot metrics "
                "need both feet", source=motion.metadata.get("source", motion.name),
                field=f"{side}_toe")
    return feet[0], feet[1]


def at_published_rate(motion: Motion) -> Motion:
    """``motion`` at :data:`PUBLISHED_FPS` (resampled linearly when needed).

    Raises:
        MotionError: fewer than two frames at 20 fps (no frame pair).
    """
    source = motion.metadata.get("source", motion.name)
    if motion.num_frames < 2:
        raise MotionError(f"the published metrics need at least 2 frames; motion has "
                          f"{motion.num_frames}", source=source)
    out = motion if abs(motion.fps - PUBLISHED_FPS) < 1e-6 else motion.resample(PUBLISHED_FPS)
    if out.num_frames < 2:
        raise MotionError(f"clip lasts {motion.duration:.3f} s: shorter than one frame pair at "
                          f"{PUBLISHED_FPS:g} fps", source=source)
    return out


def physdiff_ground(z_min: np.ndarray, float_tolerance_m: float = FLOAT_TOLERANCE_M
                    ) -> tuple[float, float]:
    """PhysDiff Penetrate and Float (mm) from the lowest point's height.

    Args:
        z_min: (T,) height of the lowest point of each frame, metres.
        float_tolerance_m: lowest points up to this high count as on the ground.

    Returns:
        ``(mean_t max(0, -z_min), mean_t z_min [z_min > tolerance])`` in mm.
    """
    penetrate = np.maximum(-z_min, 0.0)
    floating = np.where(z_min > float_tolerance_m, z_min, 0.0)
    return float(penetrate.mean() * 1000.0), float(floating.mean() * 1000.0)


def physdiff_skate(feet: np.ndarray, contact_height_m: float = CONTACT_HEIGHT_M) -> float:
    """PhysDiff Skate (mm per frame) of foot trajectories.

    Args:
        feet: (T, F, 3) foot positions, metres, Z up, T >= 2.
        contact_height_m: a foot touches the ground below this height.

    Returns:
        Mean over the T - 1 frame pairs of the mean horizontal displacement
        (mm) of the feet in contact at both frames (0 for a pair without one).
    """
    contact = feet[..., 2] < contact_height_m  # (T, F)
    both = contact[:-1] & contact[1:]  # (T-1, F)
    step = np.linalg.norm(np.diff(feet[..., :2], axis=0), axis=-1)  # (T-1, F) metres
    count = both.sum(axis=1)
    per_pair = np.where(count > 0, (step * both).sum(axis=1) / np.maximum(count, 1), 0.0)
    return float(per_pair.mean() * 1000.0)


def gmd_skating_ratio(feet: np.ndarray, fps: float = PUBLISHED_FPS,
                      contact_height_m: float = CONTACT_HEIGHT_M,
                      speed_mps: float = SKATE_SPEED_MPS,
                      window: int = SKATE_WINDOW_FRAMES) -> float:
    """GMD's ``calculate_skating_ratio`` of foot trajectories (module docstring).

    Args:
        feet: (T, F, 3) foot positions, metres, Z up, T >= 2.
        fps: frame rate of ``feet`` (GMD hard-codes 20).

    Returns:
        Fraction of the T - 1 frame pairs where a foot below ``contact_height_m``
        at both frames moves horizontally faster than ``speed_mps``, at that
        pair and on the ``window``-pair moving average.
    """
    speed = np.linalg.norm(np.diff(feet[..., :2], axis=0), axis=-1) * fps  # (T-1, F)
    average = uniform_filter1d(speed, size=window, axis=0, mode="constant", origin=0)
    low = feet[..., 2] < contact_height_m
    contact = low[:-1] & low[1:]
    skating = contact & (speed > speed_mps) & (average > speed_mps)
    return float(skating.any(axis=1).mean())


def published_metrics(motion: Motion, *, floor: Floor = "world",
                      float_tolerance_m: float = FLOAT_TOLERANCE_M) -> PublishedMetrics:
    """PhysDiff's Penetrate / Float / Skate / Phys-Err and GMD's foot-skating
    ratio of ``motion`` (module docstring), on its canonical keypoints at 20 fps.

    Args:
        motion: any skeleton with canonical feet (toes or ankles).
        floor: ``"world"``: heights from z = 0; ``"lowest_joint"``: from the
            clip's lowest keypoint over all frames (HumanML3D's preprocessing).
        float_tolerance_m: PhysDiff Float tolerance (none published).

    Raises:
        SkeletonError: no canonical keypoints, or a side without toe and ankle.
        MotionError: too short for one frame pair at 20 fps.
        SimenvError: unknown ``floor``.
    """
    if floor not in FLOORS:
        raise SimenvError(f"unknown floor {floor!r}; expected one of {', '.join(FLOORS)}",
                          field="floor")
    try:
        canon = motion.to_canonical()
    except MotionError as exc:
        raise SkeletonError(f"no canonical keypoints for the published metrics: {exc.detail}",
                            source=motion.metadata.get("source", motion.name)) from exc
    feet = foot_keypoints(canon)
    clip = at_published_rate(canon)
    pos = clip.positions.astype(np.float64)
    if floor == "lowest_joint":
        pos[..., 2] -= pos[..., 2].min()
    foot_pos = pos[:, [clip.skeleton.index(f) for f in feet]]
    penetrate, floating = physdiff_ground(pos[..., 2].min(axis=1), float_tolerance_m)
    skate = physdiff_skate(foot_pos)
    return PublishedMetrics(
        penetrate_mm=penetrate, float_mm=floating, skate_mm=skate,
        phys_err_mm=penetrate + floating + skate,
        skating_ratio=gmd_skating_ratio(foot_pos), feet=feet, frames=clip.num_frames,
        resampled_from_fps=None if clip is canon else motion.fps)


def published_record(motion: Motion) -> dict[str, Any]:
    """The ``published`` entry of a person's score record: name -> ``{value,
    unit}`` for :data:`PUBLISHED_METRICS`, plus ``feet``, ``fps`` (20) and
    ``floor`` ("world": heights from z = 0); or
    ``{"reason": ...}`` when the motion has no feet or is too short (the
    other metrics of the report are still computed)."""
    try:
        result = published_metrics(motion)
    except SimenvError as exc:
        return {"reason": exc.detail}
    out: dict[str, Any] = {name: {"value": round(value, 6), "unit": PUBLISHED_METRICS[name]}
                           for name, value in result.values().items()}
    out["feet"] = list(result.feet)
    out["fps"] = PUBLISHED_FPS
    out["floor"] = "world"
    return out


__all__ = [
    "CONTACT_HEIGHT_M",
    "FLOAT_TOLERANCE_M",
    "FLOORS",
    "PUBLISHED_FPS",
    "PUBLISHED_METRICS",
    "Floor",
    "SKATE_SPEED_MPS",
    "SKATE_WINDOW_FRAMES",
    "PublishedMetrics",
    "at_published_rate",
    "foot_keypoints",
    "gmd_skating_ratio",
    "physdiff_ground",
    "physdiff_skate",
    "published_metrics",
    "published_record",
]

"""Error metrics of motion prediction: MPJPE at horizons, MPJS, bone-length drift.

All functions take predicted and ground-truth future frames as (N, F, J, 3) arrays in
metres (root-relative in our pipeline, see :mod:`simenv.data.prediction_data`); frame ``k``
(0-based) of the future is ``(k + 1) / fps`` seconds after the last observed frame.

Two MPJPE forms, both in millimetres and both labelled wherever they are reported:

* **per-frame at the horizon** (the usual form in the motion-prediction literature):
  ``E(h) = mean_{n, j} ||x̂_{n,k,j} - x_{n,k,j}||`` at the single future frame
  ``k + 1 = round(h · fps / 1000)`` (80 ms at 25 fps is the 2nd future frame);
* **RMS up to the horizon** (the thesis's form): the root mean square of the joint
  errors over *all* future frames up to the horizon,
  ``sqrt(mean_{n, t <= k, j} ||x̂_{n,t,j} - x_{n,t,j}||²)``. It weighs large errors
  more and averages the earlier, easier frames in, so it is not comparable to the
  first form.

Joints: by default every joint whose error is not identically zero by construction is
counted; with root-relative data callers pass ``joints`` without the root (the pelvis
error is 0 for every method and would only dilute the mean).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from simenv.core.errors import MotionError

#: Horizons of the MA-GAN paper and the thesis, milliseconds.
HORIZONS_MS: tuple[int, ...] = (80, 160, 320, 400, 1000)


def _pair(pred: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(pred, dtype=np.float64)
    t = np.asarray(target, dtype=np.float64)
    if p.ndim != 4 or p.shape[-1] != 3:
        raise MotionError(f"pred must have shape (N, F, J, 3); got {p.shape}", field="pred")
    if p.shape != t.shape:
        raise MotionError(
            f"pred {p.shape} and target {t.shape} must have the same shape (N, F, J, 3)",
            field="target",
        )
    for name, a in (("pred", p), ("target", t)):
        bad = ~np.isfinite(a)
        if bad.any():
            n, f, j, _ = (int(i) for i in np.argwhere(bad)[0])
            raise MotionError(f"{name} has a non-finite value (window {n}, joint {j})",
                              frame=f, field=name)
    return p, t


def _select(a: np.ndarray, joints: Sequence[int] | None) -> np.ndarray:
    return a if joints is None else a[:, :, list(joints)]


def horizon_frames(horizons_ms: Sequence[float], fps: float) -> list[int]:
    """Number of future frames up to each horizon: ``round(h · fps / 1000)`` (>= 1)."""
    if not np.isfinite(fps) or fps <= 0:
        raise MotionError(f"fps must be positive; got {fps!r}", field="fps")
    frames = [round(h * fps / 1000.0) for h in horizons_ms]
    bad = [h for h, k in zip(horizons_ms, frames, strict=True) if k < 1]
    if bad:
        raise MotionError(f"horizons {bad} ms are shorter than one frame at {fps:g} fps",
                          field="horizons_ms")
    return frames


def joint_errors(pred: np.ndarray, target: np.ndarray,
                 joints: Sequence[int] | None = None) -> np.ndarray:
    """(N, F, J') Euclidean joint errors in metres."""
    p, t = _pair(pred, target)
    return np.linalg.norm(_select(p, joints) - _select(t, joints), axis=-1)


def per_frame_mpjpe_mm(pred: np.ndarray, target: np.ndarray,
                       joints: Sequence[int] | None = None) -> np.ndarray:
    """(F,) mean per-joint position error of every future frame, averaged over windows, mm.

    This is the error curve of a prediction (frame k is (k + 1) / fps after the last
    observed frame).
    """
    return 1000.0 * joint_errors(pred, target, joints).mean(axis=(0, 2))


def _at_horizons(horizons_ms: Sequence[float], fps: float, frames: int,
                 value: Callable[[int], float]) -> dict[float, float]:
    """``{horizon_ms: value(k)}`` for each horizon of k frames within the ``frames``
    predicted ones (longer horizons are left out, not extrapolated)."""
    return {h: value(k) for h, k in zip(horizons_ms, horizon_frames(horizons_ms, fps),
                                        strict=True) if k <= frames}


def mpjpe_at_horizons_mm(pred: np.ndarray, target: np.ndarray, fps: float,
                         horizons_ms: Sequence[float] = HORIZONS_MS,
                         joints: Sequence[int] | None = None) -> dict[float, float]:
    """Per-frame MPJPE at each horizon (the usual form), mm.

    Returns:
        ``{horizon_ms: error_mm}`` for the horizons that fall inside the F predicted
        frames (longer horizons are left out, not extrapolated).
    """
    curve = per_frame_mpjpe_mm(pred, target, joints)
    return _at_horizons(horizons_ms, fps, len(curve), lambda k: float(curve[k - 1]))


def rms_mpjpe_up_to_horizons_mm(pred: np.ndarray, target: np.ndarray, fps: float,
                                horizons_ms: Sequence[float] = HORIZONS_MS,
                                joints: Sequence[int] | None = None) -> dict[float, float]:
    """The thesis's form: RMS of joint errors over all future frames up to each horizon, mm.

    Returns:
        ``{horizon_ms: error_mm}`` for the horizons inside the F predicted frames.
    """
    sq = joint_errors(pred, target, joints) ** 2
    return _at_horizons(horizons_ms, fps, sq.shape[1],
                        lambda k: float(1000.0 * np.sqrt(sq[:, :k].mean())))


def mean_per_joint_speed(frames: np.ndarray, fps: float,
                         joints: Sequence[int] | None = None) -> float:
    """MPJS: mean over windows, frame steps and joints of ``||x_{t+1} - x_t|| · fps``, m/s.

    Args:
        frames: (N, T, J, 3) positions, T >= 2, metres (e.g. the last observed frame
            followed by the F future frames, so the first step is included).
    """
    f = np.asarray(frames, dtype=np.float64)
    if f.ndim != 4 or f.shape[1] < 2 or f.shape[-1] != 3:
        raise MotionError(f"frames must have shape (N, T >= 2, J, 3); got {f.shape}",
                          field="frames")
    f = _select(f, joints)
    return float(np.linalg.norm(np.diff(f, axis=1), axis=-1).mean() * fps)


def bone_lengths(frames: np.ndarray, parents: Sequence[int]) -> np.ndarray:
    """(..., B) lengths of the bones ``j -> parents[j]`` for every non-root joint, metres."""
    f = np.asarray(frames, dtype=np.float64)
    child = [j for j, p in enumerate(parents) if p >= 0]
    par = [parents[j] for j in child]
    if f.shape[-2] != len(parents):
        raise MotionError(
            f"frames have {f.shape[-2]} joints but the skeleton has {len(parents)}",
            field="frames",
        )
    return np.linalg.norm(f[..., child, :] - f[..., par, :], axis=-1)


def bone_length_drift_mm(pred: np.ndarray, reference: np.ndarray,
                         parents: Sequence[int]) -> dict[str, float]:
    """How far predicted bone lengths drift from the observed skeleton.

    Args:
        pred: (N, F, J, 3) predicted frames, metres.
        reference: (N, J, 3) a pose with the true bone lengths (e.g. the last observed
            frame of each window).
        parents: (J,) parent indices.

    Returns:
        ``{"mean": ..., "max": ...}``: mean and maximum over windows, frames and bones of
        ``|b̂ - b_ref|``, mm; and ``"final_mean"``: the mean at the last predicted frame.
    """
    p = np.asarray(pred, dtype=np.float64)
    r = np.asarray(reference, dtype=np.float64)
    if p.ndim != 4 or r.shape != (p.shape[0],) + p.shape[2:]:
        raise MotionError(
            f"pred must be (N, F, J, 3) and reference (N, J, 3); got {p.shape} and {r.shape}",
            field="reference",
        )
    drift = np.abs(bone_lengths(p, parents) - bone_lengths(r, parents)[:, None])
    return {"mean": float(1000 * drift.mean()), "max": float(1000 * drift.max()),
            "final_mean": float(1000 * drift[:, -1].mean())}

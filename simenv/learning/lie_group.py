"""Lie-group descriptors of skeleton sequences (Vemulapalli, Arrate and Chellappa 2014).

The representation behind the published figures the recognition benchmarks compare with
(89.5 % on MSR Action3D, 97.1 % on UTKinect, 90.9 % on Florence 3D): a skeleton as the
relative 3D geometry of every pair of its bones, a point of the Lie group
``SE(3) x ... x SE(3)``, and a clip as a curve in its Lie algebra. It sees how each limb
sits and turns relative to every other, wherever the body stands (not whatever its heading:
each bone's frame is fixed by the smallest rotation onto it, which depends on the bone's
direction in the world, so the benchmarks describe clips normalised to face one way); the
ridge classifier of :mod:`simenv.learning.covariance` classifies it, alone or beside the
covariance descriptors.

**Bones.** Bone ``m`` runs from a joint's parent ``a_m`` to the joint ``b_m`` (the
skeleton's tree; ``M`` bones for ``M + 1`` joints). Each frame is first rebuilt with the
clip's median bone lengths ``l_m`` (bone directions kept, root in place), so that Kinect's
frame-to-frame length jitter does not read as motion.

**Relative geometry.** Bone ``m``'s frame has its origin at ``a_m`` and its x axis along
the bone: ``R_m`` is the smallest rotation taking ``x = (1, 0, 0)`` to the bone's unit
direction ``u_m`` (axis ``x cross u_m``, angle ``atan2(|x cross u_m|, x . u_m)``; a
bone along ``-x`` turns about z). In it, bone ``n`` starts at
``d_mn = R_m^T (a_n - a_m)`` and points along ``R_m^T u_n``; the rigid motion
``P_mn = (R_mn, d_mn)`` in SE(3), ``R_mn`` the smallest rotation taking ``x`` to
``R_m^T u_n``, carries a bone of length ``l_n`` on the x axis at the origin onto bone ``n``.
Every ordered pair ``m != n`` gives one: ``M (M - 1)`` elements per frame.

**Lie algebra.** Each ``P_mn`` is mapped to its logarithm at the identity,
``log P = (omega, v)`` in se(3) = R^6: ``omega = theta k`` the rotation's axis-angle vector
and ``v = V^{-1} d`` with ``V = I + (1 - cos theta)/theta^2 [omega]x +
(theta - sin theta)/theta^3 [omega]x^2``, whose inverse is
``V^{-1} = I - [omega]x / 2 + (1 - theta sin theta / (2 (1 - cos theta))) / theta^2
[omega]x^2`` (``[omega]x^2 / 12`` as theta -> 0). A frame is the ``6 M (M - 1)``-vector of
all of them, a clip the curve ``f(t)`` of those vectors.

**Temporal modelling.** A Fourier temporal pyramid (Wang et al. 2012), as the paper uses:
the curve is resampled to :data:`CURVE_SAMPLES` frames (clips differ in length), split into
``1, 2, .., 2^(L-1)`` equal segments over ``L`` levels, and of each segment's discrete
Fourier transform per dimension the magnitudes of its lowest ``ceil(fraction n)``
frequencies are kept (``n`` the segment's samples): magnitudes ignore where in the segment
a movement happens, the low frequencies ignore Kinect's jitter. The paper keeps a quarter
of the frequencies; :data:`FOURIER_FRACTIONS` are the fractions the benchmarks' classifier
chooses from on its training subjects. The paper's per-class warping of every curve onto a
nominal one (dynamic time warping) and its linear SVM are not reproduced: the ridge
classifier takes the pyramid directly.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from simenv.core.errors import SimenvError
from simenv.core.motion import resample_linear

#: Samples each clip's curve is resampled to before the pyramid.
CURVE_SAMPLES = 64
#: Levels ``L`` of the Fourier temporal pyramid: 1 + 2 + 4 segments (the paper's).
FOURIER_LEVELS = 3
#: Fractions of each segment's lowest frequencies kept (the paper's quarter and an eighth).
FOURIER_FRACTIONS: tuple[float, ...] = (0.25, 0.125)


def _skew(w: np.ndarray) -> np.ndarray:
    """(..., 3, 3) cross-product matrices ``[w]x`` of (..., 3) vectors."""
    z = np.zeros(w.shape[:-1] + (3, 3))
    z[..., 0, 1], z[..., 0, 2] = -w[..., 2], w[..., 1]
    z[..., 1, 0], z[..., 1, 2] = w[..., 2], -w[..., 0]
    z[..., 2, 0], z[..., 2, 1] = -w[..., 1], w[..., 0]
    return z


def rotation_from_x(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The smallest rotation taking the x axis to each unit vector of ``u`` (..., 3).

    Returns:
        ``(R, omega)``: (..., 3, 3) rotation matrices and (..., 3) their axis-angle vectors
        (radians); a ``u`` along ``-x`` turns by pi about z.
    """
    axis = np.stack([np.zeros_like(u[..., 0]), -u[..., 2], u[..., 1]], -1)  # x cross u
    sin = np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = np.arctan2(sin, u[..., :1])
    unit = np.where(sin > 1e-9, axis / np.maximum(sin, 1e-12), np.array([0.0, 0.0, 1.0]))
    k = _skew(unit)
    rot = (np.eye(3) + np.sin(angle)[..., None] * k
           + (1.0 - np.cos(angle))[..., None] * (k @ k))
    return rot, unit * angle


def se3_log_translation(omega: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``v = V^{-1} d`` of the SE(3) logarithm (module docstring) of rotations ``omega``
    (..., 3) axis-angle and translations ``d`` (..., 3): (..., 3)."""
    theta = np.linalg.norm(omega, axis=-1)[..., None, None]
    k = _skew(omega)
    safe = np.maximum(theta, 1e-6)
    coef = np.where(theta > 1e-4,
                    (1.0 - safe * np.sin(safe) / (2.0 * (1.0 - np.cos(safe)))) / safe ** 2,
                    1.0 / 12.0)
    v_inv = np.eye(3) - 0.5 * k + coef * (k @ k)
    return np.einsum("...ij,...j->...i", v_inv, d)


def bone_pairs(parents: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """Bones of a tree (parent joint, joint), as two (M,) index arrays."""
    joints = [j for j, p in enumerate(parents) if p >= 0]
    return np.array([parents[j] for j in joints], int), np.array(joints, int)


def relative_geometry(frames: np.ndarray, parents: Sequence[int]) -> np.ndarray:
    """Every ordered pair of bones' relative rigid motion, in se(3) (module docstring).

    Args:
        frames: (T, J, 3) joint positions (any unit; the benchmarks pass normalised ones).
        parents: (J,) parent of each joint, -1 for the root; at least 2 bones.

    Returns:
        (T, 6 M (M - 1)) float64: per frame, for each pair ``m != n`` in row-major order,
        ``(omega_mn, v_mn)``. A bone of zero length has no direction; it is taken along x.

    Raises:
        SimenvError: frames not (T, J, 3) with J = len(parents), no frames, fewer than 2
            bones, or non-finite coordinates.
    """
    frames = np.asarray(frames, np.float64)
    if frames.ndim != 3 or frames.shape[-1] != 3 or frames.shape[1] != len(parents):
        raise SimenvError(f"frames must be (T, {len(parents)}, 3); got {frames.shape}",
                          field="frames")
    if len(frames) == 0:
        raise SimenvError("no frames to describe", field="frames")
    if not np.isfinite(frames).all():
        bad = int(np.argwhere(~np.isfinite(frames).all(axis=(1, 2)))[0, 0])
        raise SimenvError(f"frame {bad} holds non-finite coordinates", field="frames")
    start, end = bone_pairs(parents)
    if len(start) < 2:
        raise SimenvError(f"relative geometry needs at least 2 bones; got {len(start)}",
                          field="parents")
    vec = frames[:, end] - frames[:, start]
    length = np.linalg.norm(vec, axis=-1, keepdims=True)
    u = np.where(length > 1e-9, vec / np.maximum(length, 1e-12), np.array([1.0, 0.0, 0.0]))
    lengths = np.median(length[..., 0], axis=0)
    rebuilt = frames.copy()
    for m, (a, b) in enumerate(zip(start, end, strict=True)):  # parents precede children
        rebuilt[:, b] = rebuilt[:, a] + u[:, m] * lengths[m]
    origin = rebuilt[:, start]
    rot_t = np.swapaxes(rotation_from_x(u)[0], -1, -2)
    mm, nn = np.nonzero(~np.eye(len(start), dtype=bool))
    d = np.einsum("tkij,tkj->tki", rot_t[:, mm], origin[:, nn] - origin[:, mm])
    _, omega = rotation_from_x(np.einsum("tkij,tkj->tki", rot_t[:, mm], u[:, nn]))
    return np.concatenate([omega, se3_log_translation(omega, d)], -1).reshape(len(frames), -1)


def fourier_pyramids(curve: np.ndarray, fractions: Sequence[float],
                     levels: int = FOURIER_LEVELS, samples: int = CURVE_SAMPLES
                     ) -> dict[float, np.ndarray]:
    """The Fourier temporal pyramid of a (T, F) curve (module docstring) at each of
    ``fractions``, from one resampling and one transform per segment.

    Returns:
        fraction -> (F sum_segments ceil(fraction n_segment),) float64 magnitudes.

    Raises:
        SimenvError: a fraction outside (0, 1], fewer than 1 level or more segments than
            samples.
    """
    for fraction in fractions:
        if not 0.0 < fraction <= 1.0:
            raise SimenvError(f"fraction must be in (0, 1]; got {fraction}", field="fraction")
    if levels < 1 or 2 ** (levels - 1) > samples:
        raise SimenvError(f"{levels} levels do not fit {samples} samples", field="levels")
    resampled = resample_linear(np.asarray(curve, np.float64), samples)
    out: dict[float, list[np.ndarray]] = {f: [] for f in fractions}
    for level in range(levels):
        for segment in np.array_split(resampled, 2 ** level):
            magnitude = np.abs(np.fft.fft(segment, axis=0))
            for f in fractions:
                out[f].append(magnitude[:int(np.ceil(f * len(segment)))].ravel())
    return {f: np.concatenate(parts) for f, parts in out.items()}


def fourier_pyramid(curve: np.ndarray, fraction: float = 0.25, levels: int = FOURIER_LEVELS,
                    samples: int = CURVE_SAMPLES) -> np.ndarray:
    """:func:`fourier_pyramids` at one fraction."""
    return fourier_pyramids(curve, (fraction,), levels, samples)[fraction]


def lie_group_descriptors(x: np.ndarray, valid: np.ndarray, parents: Sequence[int],
                          fractions: Sequence[float] = FOURIER_FRACTIONS
                          ) -> dict[float, np.ndarray]:
    """Descriptors of normalised windows, each over its real frames.

    Args:
        x: (N, T, J, 3) windows; valid: (N, T) bool, at least one real frame each.
        parents: (J,) the skeleton's tree.
        fractions: the pyramid's kept fractions to describe with.

    Returns:
        fraction -> (N, D) :func:`fourier_pyramid` of each window's
        :func:`relative_geometry`.

    Raises:
        SimenvError: a window with no real frame (named by its index), or as the two
            functions raise.
    """
    out: dict[float, list[np.ndarray]] = {f: [] for f in fractions}
    for i, (seq, v) in enumerate(zip(x, valid, strict=True)):
        real = seq[np.asarray(v, bool)]
        if len(real) == 0:
            raise SimenvError(f"window {i} has no real frame", field="valid")
        for f, d in fourier_pyramids(relative_geometry(real, parents), fractions).items():
            out[f].append(d)
    return {f: np.stack(d) for f, d in out.items()}

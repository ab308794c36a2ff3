"""Metrics of two-person motion generation: the seed papers' error, distribution and
timing measures.

Inputs are windows of :mod:`simenv.data.interaction_data`: (N, T, J, 3) positions in metres in
the actor frame of each window (origin at the actor's pelvis on the floor at the first
frame, actor facing +x), joints :data:`~simenv.data.interaction_data.INTER18_JOINTS` unless
``joint_names`` says otherwise. A generated reaction ``x̂`` is compared with the real
reaction ``x`` of the same window; the actor ``a`` is the real one.

Error metrics
-------------
* **AFD** (average frame distance, Men et al., reactive GAN):
  ``AFD = mean_{n,t} ||x̂_{n,t} - x_{n,t}||²``, the squared L2 norm of the flattened
  ``J·3`` pose-vector difference, summed over joints and coordinates, then averaged over
  frames and windows. Normalisation: positions in metres in the actor frame above (no
  scaling, no centring on the reactor), so AFD is in m² and includes the reactor's
  placement relative to the actor.
* **E_r** (joint error, Li et al.): ``mean_{n,t,j} ||x̂_{n,t,j} - x_{n,t,j}||``, mm.
* **E_b** (bone-length error, Li et al.): ``mean_{n,t,k} |b̂_{n,t,k} - b^ref_{n,k}|``, mm,
  against a reference skeleton (here the reactor's given first frame).
* **JPD** (key joint-pair distance error, Li et al.): for pairs (A joint ``i``, B joint
  ``j``), ``d_{n,t} = ||a_{n,t,i} - x_{n,t,j}||``; ``JPD = mean_{n,t} |d̂ - d|``, mm, per pair
  and averaged over pairs (:data:`KEY_JOINT_PAIRS`).
* **Contact retention** (ours, on keypoints): per pair, the fraction of frames where the
  real pair is in contact (``d < contact_distance``) on which the generated one is too.

Distribution metrics (Chopin 2023; Guo et al. 2020, action-conditioned generation)
-----------------------------------------------------------------------------------
Features ``v = φ(window)`` come from a pluggable :class:`FeatureExtractor`:
:func:`simenv.learning.interaction_features.default_feature_extractor` gives the shipped
gesture classifier's penultimate features when that checkpoint loads, else the labelled
fallback :class:`PoseSegmentFeatures`.

* **Fréchet distance** of Gaussian fits ``N(μ_1, Σ_1)``, ``N(μ_2, Σ_2)``:
  ``||μ_1 - μ_2||² + Tr(Σ_1 + Σ_2 - 2 (Σ_1^{1/2} Σ_2 Σ_1^{1/2})^{1/2})``
  (:func:`frechet_distance`; the trace term is computed from the eigenvalues of the
  symmetric PSD matrix ``Σ_1^{1/2} Σ_2 Σ_1^{1/2}``, which is exact and stays real for the
  rank-deficient covariances of small sample sets). **FVD**: on window features;
  **FID**: on single-pose features (each frame's flattened ``J·3`` pose, actor frame).
* **Diversity**: ``mean_{s=1..S} ||v_{i_s} - v_{j_s}||`` over ``S`` random pairs of
  distinct generated samples (``i_s ≠ j_s``, seeded).
* **Multimodality**: the same within each class, ``S_c`` random pairs of distinct samples
  of class ``c``, averaged over the classes that have at least two samples.

Guo et al. draw the two index sets independently, so a pair can be a sample with itself;
we draw distinct pairs, so that a set of identical samples scores 0 and ``K`` samples at
mutual distance ``d`` score exactly ``d``.

Timing
------
**Reaction lag**: the speed profiles ``s_A(t)`` and ``s_B(t)`` (mean joint speed, m/s)
are cross-correlated; the lag is the ``k`` in ``[-K, K]`` frames maximising the Pearson
correlation of ``s_A(t)`` and ``s_B(t + k)`` over their overlap, so ``k > 0`` means B
moves ``k / fps`` seconds after A. A profile without variation (a frozen body) has no
lag (NaN).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from simenv.core.errors import MotionError
from simenv.data.gestures import normalise_windows
from simenv.data.interaction_data import INTER18_JOINTS, TARGET_FPS
from simenv.data.prediction_metrics import bone_lengths

#: Key joint pairs (actor joint, reactor joint) of JPD and contact retention: A right
#: hand - B spine (Li et al.'s example), right hand - right hand (handshake, fist bump),
#: A left hand - B right hand (the salsa hold).
KEY_JOINT_PAIRS: tuple[tuple[str, str], ...] = (
    ("right_hand", "spine"), ("right_hand", "right_hand"), ("left_hand", "right_hand"),
)

#: Two keypoints closer than this are in contact, metres (the plausibility scorer's
#: ``BodyThresholds.contact_distance_m``).
CONTACT_DISTANCE_M = 0.15

#: Default number of random pairs of diversity and of multimodality (per class), as in
#: Guo et al. (200 and 20).
DIVERSITY_PAIRS = 200
MULTIMODALITY_PAIRS = 20

#: Largest reaction lag searched, seconds.
MAX_LAG_S = 0.4


def _windows(x: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 4 or a.shape[-1] != 3:
        raise MotionError(f"{name} must have shape (N, T, J, 3); got {a.shape}", field=name)
    bad = ~np.isfinite(a)
    if bad.any():
        n, t, j, _ = (int(i) for i in np.argwhere(bad)[0])
        raise MotionError(f"{name} has a non-finite value (window {n}, joint {j})",
                          frame=t, field=name)
    return a


def _pair(pred: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    p, t = _windows(pred, "pred"), _windows(target, "target")
    if p.shape != t.shape:
        raise MotionError(f"pred {p.shape} and target {t.shape} must have the same shape",
                          field="target")
    return p, t


# -- error metrics -------------------------------------------------------------------------


def afd(pred: np.ndarray, target: np.ndarray) -> float:
    """AFD: mean over windows and frames of ``||x̂_t - x_t||²`` (flattened pose), m².

    Args:
        pred, target: (N, T, J, 3) metres, actor frame.
    """
    p, t = _pair(pred, target)
    return float(((p - t) ** 2).sum(axis=(2, 3)).mean())


def joint_error_mm(pred: np.ndarray, target: np.ndarray) -> float:
    """E_r: mean Euclidean joint error over windows, frames and joints, mm."""
    p, t = _pair(pred, target)
    return float(1000.0 * np.linalg.norm(p - t, axis=-1).mean())


def bone_length_error_mm(pred: np.ndarray, reference: np.ndarray,
                         parents: Sequence[int]) -> float:
    """E_b: mean ``|b̂ - b_ref|`` over windows, frames and bones, mm.

    Args:
        pred: (N, T, J, 3) generated positions, metres.
        reference: (N, J, 3) a pose of each window with the true bone lengths (e.g. the
            reactor's given first frame).
        parents: (J,) parent indices (-1 for the root).
    """
    p = _windows(pred, "pred")
    r = np.asarray(reference, dtype=np.float64)
    if r.shape != (p.shape[0],) + p.shape[2:]:
        raise MotionError(f"reference must have shape {(p.shape[0],) + p.shape[2:]} "
                          f"(N, J, 3); got {r.shape}", field="reference")
    ref = bone_lengths(r, parents)[:, None]
    return float(1000.0 * np.abs(bone_lengths(p, parents) - ref).mean())


def _pair_index(pairs: Sequence[tuple[str, str]], joint_names: Sequence[str]
                ) -> tuple[list[int], list[int]]:
    names = list(joint_names)
    missing = sorted({j for pair in pairs for j in pair if j not in names})
    if missing:
        raise MotionError(f"key joint(s) {', '.join(missing)} not among the joints "
                          f"({', '.join(names)})", field="pairs")
    return [names.index(a) for a, _ in pairs], [names.index(b) for _, b in pairs]


def joint_pair_distances(actor: np.ndarray, reactor: np.ndarray,
                         pairs: Sequence[tuple[str, str]] = KEY_JOINT_PAIRS,
                         joint_names: Sequence[str] = INTER18_JOINTS) -> np.ndarray:
    """(N, T, P) distances ``||a_i - b_j||`` of the key pairs (actor joint i, reactor joint
    j), metres."""
    a, b = _pair(actor, reactor)
    ia, ib = _pair_index(pairs, joint_names)
    return np.linalg.norm(a[:, :, ia] - b[:, :, ib], axis=-1)


def jpd_mm(actor: np.ndarray, pred: np.ndarray, target: np.ndarray,
           pairs: Sequence[tuple[str, str]] = KEY_JOINT_PAIRS,
           joint_names: Sequence[str] = INTER18_JOINTS) -> dict[str, float]:
    """JPD: ``mean_{n,t} |d̂ - d|`` per key pair and their mean, mm.

    Returns:
        ``{"A:<joint>-B:<joint>": mm, ..., "mean": mm}``.
    """
    d_hat = joint_pair_distances(actor, pred, pairs, joint_names)
    d = joint_pair_distances(actor, target, pairs, joint_names)
    err = 1000.0 * np.abs(d_hat - d).mean(axis=(0, 1))
    out = {f"A:{a}-B:{b}": float(e) for (a, b), e in zip(pairs, err, strict=True)}
    out["mean"] = float(err.mean())
    return out


def contact_retention(actor: np.ndarray, pred: np.ndarray, target: np.ndarray,
                      pairs: Sequence[tuple[str, str]] = KEY_JOINT_PAIRS,
                      joint_names: Sequence[str] = INTER18_JOINTS,
                      contact_distance: float = CONTACT_DISTANCE_M
                      ) -> dict[str, float | None]:
    """Per key pair, the fraction of the real contact frames (``d < contact_distance``)
    on which the generated pair is in contact too; None for a pair the real windows
    never bring into contact. ``"real_contact_frames"`` counts the real contact frames
    over all pairs, and ``"mean"`` averages the defined pairs (None if none is)."""
    d_hat = joint_pair_distances(actor, pred, pairs, joint_names)
    d = joint_pair_distances(actor, target, pairs, joint_names)
    real, gen = d < contact_distance, d_hat < contact_distance
    out: dict[str, float | None] = {}
    for k, (a, b) in enumerate(pairs):
        n = int(real[..., k].sum())
        out[f"A:{a}-B:{b}"] = float((gen[..., k] & real[..., k]).sum() / n) if n else None
    defined = [v for v in out.values() if v is not None]
    out["mean"] = float(np.mean(defined)) if defined else None
    out["real_contact_frames"] = float(real.sum())
    return out


# -- distributions -------------------------------------------------------------------------


def gaussian_fit(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean (D,) and unbiased covariance (D, D) of (N, D) features (N >= 2)."""
    f = np.asarray(features, dtype=np.float64)
    if f.ndim != 2 or f.shape[0] < 2:
        raise MotionError(f"features must have shape (N >= 2, D); got {f.shape}",
                          field="features")
    if not np.isfinite(f).all():
        raise MotionError("features have a non-finite value", field="features")
    return f.mean(axis=0), np.cov(f, rowvar=False, ddof=1).reshape(f.shape[1], f.shape[1])


def _psd_sqrt(s: np.ndarray) -> np.ndarray:
    w, v = np.linalg.eigh((s + s.T) / 2)
    return (v * np.sqrt(np.clip(w, 0.0, None))) @ v.T


def frechet_distance(mu1: np.ndarray, sigma1: np.ndarray, mu2: np.ndarray,
                     sigma2: np.ndarray) -> float:
    """Fréchet (2-Wasserstein²) distance of two Gaussians (module docstring), in squared
    feature units."""
    mu1, mu2 = np.atleast_1d(mu1).astype(np.float64), np.atleast_1d(mu2).astype(np.float64)
    s1, s2 = np.atleast_2d(sigma1).astype(np.float64), np.atleast_2d(sigma2).astype(np.float64)
    d = mu1.shape[0]
    if mu2.shape != (d,) or s1.shape != (d, d) or s2.shape != (d, d):
        raise MotionError(f"means must be (D,) and covariances (D, D) with one D; got "
                          f"{mu1.shape}, {s1.shape}, {mu2.shape}, {s2.shape}", field="sigma")
    r = _psd_sqrt(s1)
    m = r @ s2 @ r
    trace_sqrt = float(np.sqrt(np.clip(np.linalg.eigvalsh((m + m.T) / 2), 0.0, None)).sum())
    value = float(((mu1 - mu2) ** 2).sum() + np.trace(s1) + np.trace(s2) - 2 * trace_sqrt)
    return max(value, 0.0)  # rounding can leave -1e-15 for identical inputs


def frechet_feature_distance(features_a: np.ndarray, features_b: np.ndarray) -> float:
    """Fréchet distance of the Gaussian fits of two (N, D) feature sets."""
    return frechet_distance(*gaussian_fit(features_a), *gaussian_fit(features_b))


def _distinct_pairs(n: int, count: int, rng: np.random.Generator
                    ) -> tuple[np.ndarray, np.ndarray]:
    i = rng.integers(0, n, count)
    j = (i + rng.integers(1, n, count)) % n  # uniform over the other n - 1 samples
    return i, j


def diversity(features: np.ndarray, num_pairs: int = DIVERSITY_PAIRS, seed: int = 0
              ) -> float:
    """Mean feature distance of ``num_pairs`` random pairs of distinct samples.

    Args:
        features: (N >= 2, D) features of generated samples.
    """
    f = np.asarray(features, dtype=np.float64)
    if f.ndim != 2 or f.shape[0] < 2:
        raise MotionError(f"diversity needs (N >= 2, D) features; got {f.shape}",
                          field="features")
    i, j = _distinct_pairs(len(f), int(num_pairs), np.random.default_rng(seed))
    return float(np.linalg.norm(f[i] - f[j], axis=-1).mean())


def multimodality(features: np.ndarray, labels: np.ndarray,
                  num_pairs: int = MULTIMODALITY_PAIRS, seed: int = 0) -> float:
    """Mean over classes of the mean feature distance of ``num_pairs`` random pairs of
    distinct samples of that class (classes with one sample are skipped).

    Raises:
        MotionError: shapes disagree or no class has two samples.
    """
    f = np.asarray(features, dtype=np.float64)
    y = np.asarray(labels)
    if f.ndim != 2 or y.shape != (f.shape[0],):
        raise MotionError(f"features (N, D) and labels (N,) expected; got {f.shape} and "
                          f"{y.shape}", field="labels")
    rng = np.random.default_rng(seed)
    per_class = []
    for c in np.unique(y):
        idx = np.flatnonzero(y == c)
        if len(idx) < 2:
            continue
        i, j = _distinct_pairs(len(idx), int(num_pairs), rng)
        per_class.append(np.linalg.norm(f[idx[i]] - f[idx[j]], axis=-1).mean())
    if not per_class:
        raise MotionError("multimodality needs a class with at least two samples",
                          field="labels")
    return float(np.mean(per_class))


# -- feature extractors --------------------------------------------------------------------


@runtime_checkable
class FeatureExtractor(Protocol):
    """Maps windows of one person to feature vectors.

    ``__call__(windows)``: (N, T, J, 3) positions (metres, actor frame, joints
    :data:`INTER18_JOINTS`, at :data:`~simenv.data.interaction_data.TARGET_FPS`) -> (N, D).
    ``name`` says what the features are (reported next to every FVD/FID number).
    """

    name: str

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        ...


@dataclass(frozen=True)
class PoseSegmentFeatures:
    """Fallback features without a trained network: the window cut into ``segments``
    equal parts along time, each part's mean pose flattened, ``D = segments · J · 3``.

    ``φ(x) = [mean_{t ∈ S_1} x_t, ..., mean_{t ∈ S_K} x_t]`` (actor-frame metres): the
    flattened normalised poses of the brief, averaged over K segments so that D stays
    small next to the number of test windows.
    """

    segments: int = 4

    @property
    def name(self) -> str:
        return (f"pose-segments-{self.segments} (FALLBACK: mean actor-frame pose of "
                f"{self.segments} time segments, no trained classifier)")

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        x = _windows(windows, "windows")
        if x.shape[1] < self.segments:
            raise MotionError(f"windows of {x.shape[1]} frames cannot be cut into "
                              f"{self.segments} segments", field="windows")
        parts = np.array_split(x, self.segments, axis=1)
        return np.concatenate([p.mean(axis=1).reshape(len(x), -1) for p in parts], axis=1)


class ClassifierFeatures:
    """Penultimate features of a :class:`simenv.models.gesture_classifier.GestureClassifier`.

    Windows are taken onto the classifier's joints (a subset of :data:`INTER18_JOINTS`),
    normalised as the classifier was trained (:func:`simenv.data.gestures.normalise_windows`),
    and, being shorter than the classifier's window, padded at the end by holding the last
    pose with the padded frames marked invalid (the classifier masks them out of
    attention and pooling); longer windows keep their first ``config.window`` frames.
    """

    def __init__(self, model: object, joint_names: Sequence[str] = INTER18_JOINTS,
                 fps: float = TARGET_FPS) -> None:
        config = model.config  # type: ignore[attr-defined]
        missing = [j for j in config.joint_names if j not in joint_names]
        if missing:
            raise MotionError(f"the classifier needs joint(s) {', '.join(missing)} that the "
                              "windows lack", field="joint_names")
        if fps != config.fps:
            raise MotionError(f"windows at {fps:g} fps; the classifier expects "
                              f"{config.fps:g} fps (resample first)", field="fps")
        self.model = model
        self.index = [list(joint_names).index(j) for j in config.joint_names]
        self.name = (f"gesture-classifier penultimate features ({config.feature_dim}-d, "
                     f"{len(config.joint_names)} joints)")

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        import torch  # heavy, and only needed when a classifier is given

        x = _windows(windows, "windows")[:, :, self.index]
        length = self.model.config.window  # type: ignore[attr-defined]
        x = x[:, :length]
        valid = np.zeros((len(x), length), bool)
        valid[:, :x.shape[1]] = True
        if x.shape[1] < length:
            x = np.concatenate([x, np.repeat(x[:, -1:], length - x.shape[1], axis=1)], axis=1)
        norm = normalise_windows(x, valid, joints=self.model.config.joint_names)  # type: ignore[attr-defined]
        with torch.no_grad():
            self.model.eval()  # type: ignore[attr-defined]
            feats = self.model.features(torch.as_tensor(norm),  # type: ignore[attr-defined]
                                        torch.as_tensor(valid))
        return feats.numpy().astype(np.float64)


def pose_features(windows: np.ndarray) -> np.ndarray:
    """(N·T, J·3) single-pose features of FID: every frame's flattened actor-frame pose."""
    x = _windows(windows, "windows")
    return x.reshape(x.shape[0] * x.shape[1], -1)


# -- timing --------------------------------------------------------------------------------


def speed_profile(windows: np.ndarray, fps: float) -> np.ndarray:
    """(N, T - 1) mean joint speed ``mean_j ||x_{t+1,j} - x_{t,j}|| · fps``, m/s."""
    x = _windows(windows, "windows")
    if x.shape[1] < 2:
        raise MotionError("a speed profile needs at least 2 frames", field="windows")
    return np.linalg.norm(np.diff(x, axis=1), axis=-1).mean(axis=-1) * fps


def reaction_lag_s(actor: np.ndarray, reactor: np.ndarray, fps: float,
                   max_lag_s: float = MAX_LAG_S, min_overlap: int = 8) -> np.ndarray:
    """(N,) lag of the reactor behind the actor from their speed profiles, seconds.

    For every lag ``k`` in ``[-K, K]`` (``K = round(max_lag_s · fps)``, capped so that at
    least ``min_overlap`` steps overlap) the Pearson correlation of ``s_A(t)`` and
    ``s_B(t + k)`` over the overlap; the lag is the maximising ``k / fps`` (positive: the
    reactor moves later). NaN where a profile has no variation over an overlap.
    """
    sa, sb = speed_profile(actor, fps), speed_profile(reactor, fps)
    if sa.shape != sb.shape:
        raise MotionError(f"actor {sa.shape} and reactor {sb.shape} profiles differ",
                          field="reactor")
    steps = sa.shape[1]
    k_max = min(int(round(max_lag_s * fps)), steps - min_overlap)
    if k_max < 0:
        raise MotionError(f"windows of {steps + 1} frames are too short for a lag estimate "
                          f"with {min_overlap} overlapping steps", field="windows")
    lags = np.arange(-k_max, k_max + 1)
    corr = np.full((len(sa), len(lags)), np.nan)
    for c, k in enumerate(lags):
        a = sa[:, max(0, -k): steps - max(0, k)]
        b = sb[:, max(0, k): steps - max(0, -k)]
        a = a - a.mean(axis=1, keepdims=True)
        b = b - b.mean(axis=1, keepdims=True)
        den = np.sqrt((a ** 2).sum(axis=1) * (b ** 2).sum(axis=1))
        ok = den > 1e-12
        corr[ok, c] = (a * b).sum(axis=1)[ok] / den[ok]
    out = np.full(len(sa), np.nan)
    have = ~np.isnan(corr).all(axis=1)
    best = np.argmax(np.where(np.isnan(corr[have]), -np.inf, corr[have]), axis=1)
    out[have] = lags[best] / fps
    return out

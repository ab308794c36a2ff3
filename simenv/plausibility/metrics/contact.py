"""Contact: the key joint-pair distance error (JPD) of two people, and contact retention.

The pairwise metric (:class:`Contact`, :func:`contact`) compares distances
between key joints on the two retargeted bodies (:func:`pair_distances`) with
the keypoints they were fitted to or another interaction. Key pairs:
``ScoreConfig.contact_pairs``
(:data:`~simenv.plausibility.metric.DEFAULT_CONTACT_PAIRS`); thresholds:
``jpd_max_mm`` and ``contact_distance_m`` of
:class:`~simenv.plausibility.body_thresholds.BodyThresholds`. Metres in,
millimetres out.
"""

from __future__ import annotations

from collections.abc import Sequence
from operator import attrgetter

import numpy as np

from simenv.body.geometry import body_poses
from simenv.body.retarget import InteractionRetargetResult
from simenv.core.errors import MotionError
from simenv.core.motion import Interaction
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.metric import DEFAULT_CONTACT_PAIRS, PairInputs, PairMetric, fitted_pair
from simenv.plausibility.timeline import MetricResult


def _keypoint_tracks(names: Sequence[str], positions: np.ndarray,
                     wanted: Sequence[str]) -> dict[str, np.ndarray]:
    return {k: positions[:, list(names).index(k)] for k in wanted if k in names}


def pair_distances(result: InteractionRetargetResult,
                   pairs: Sequence[tuple[str, str]] = DEFAULT_CONTACT_PAIRS) -> np.ndarray:
    """Distances between key joint pairs on the retargeted bodies.

    Args:
        result: two retargeted people in one scene.
        pairs: (keypoint of person A, keypoint of person B), canonical names.

    Returns:
        (T, len(pairs)) metres, from the bodies' keypoint sites.
    """
    scene = result.scene
    poses = body_poses(scene.model, result.qpos)
    names = list(scene.humanoids[0].keypoint_names)
    for a, b in pairs:
        for k in (a, b):
            if k not in names:
                raise MotionError(f"contact pair ({a!r}, {b!r}): {k!r} is not a canonical "
                                  f"keypoint; expected one of {', '.join(names)}", field=k)
    sa = [scene.site_ids[0][names.index(a)] for a, _ in pairs]
    sb = [scene.site_ids[1][names.index(b)] for _, b in pairs]
    return np.linalg.norm(poses.site_xpos[:, sa] - poses.site_xpos[:, sb], axis=-1)


def _reference_distances(reference: Interaction | InteractionRetargetResult,
                         pairs: Sequence[tuple[str, str]], T: int) -> np.ndarray:
    """(T, P) reference pair distances in metres; NaN where a keypoint is missing."""
    if isinstance(reference, InteractionRetargetResult):
        people = [(p.keypoint_names, p.targets) for p in reference.people]
    else:
        people = []
        for m in reference.people:
            canon = m.to_canonical()
            people.append((canon.skeleton.joint_names, canon.positions))
    for _, pos in people:
        if len(pos) != T:
            raise MotionError(f"reference has {len(pos)} frames; the scored interaction has "
                              f"{T}: JPD compares frame by frame", field="reference")
    out = np.full((T, len(pairs)), np.nan)
    (na, pa), (nb, pb) = people
    ta = _keypoint_tracks(na, pa, [a for a, _ in pairs])
    tb = _keypoint_tracks(nb, pb, [b for _, b in pairs])
    for i, (a, b) in enumerate(pairs):
        if a in ta and b in tb:
            out[:, i] = np.linalg.norm(ta[a].astype(float) - tb[b].astype(float), axis=-1)
    return out


def contact(result: InteractionRetargetResult,
            reference: Interaction | InteractionRetargetResult | None = None,
            pairs: Sequence[tuple[str, str]] = DEFAULT_CONTACT_PAIRS,
            thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS) -> MetricResult:
    """Key joint-pair distance error (JPD) and contact retention.

    For each pair (A keypoint, B keypoint) -- by default A right hand - B right
    hand (handshake), A right hand - B spine (the interaction-augmentation
    seed's pair) and its mirror -- the distance ``d_p(t)`` on the retargeted
    bodies is compared with the reference distance ``r_p(t)``: the keypoints
    the bodies were fitted to (default), or another interaction of the same
    length (e.g. the ground truth of a generated one).

    Timeline: ``mean_p |d_p(t) - r_p(t)| * 1000`` mm (pairs missing in the
    reference are skipped); value: its mean over frames (JPD); passes when at
    most ``jpd_max_mm``. Details per pair ``i``: ``retention_i``, the fraction
    of reference contact frames (``r_p < contact_distance_m``) on which the
    bodies are in contact too (1 when the reference never touches),
    ``min_mm_i`` (closest approach on the bodies) and ``reference_contact_i``
    (fraction of frames in contact in the reference).
    """
    thr = thresholds.jpd_max_mm
    T = result.qpos.shape[0]
    d = pair_distances(result, pairs)
    r = _reference_distances(reference if reference is not None else result, pairs, T)
    have = ~np.isnan(r[0])
    if not have.any():
        return MetricResult.not_available(
            "contact", T, "mm", thr, "the reference has none of the key joint pairs "
            f"{list(pairs)}")
    err = np.abs(d[:, have] - r[:, have]) * 1000.0
    timeline = err.mean(axis=1)
    details: dict[str, float] = {}
    cd = thresholds.contact_distance_m
    for i in np.flatnonzero(have):
        ref_contact = r[:, i] < cd
        kept = (d[:, i] < cd) & ref_contact
        details[f"retention_{i}"] = float(kept.sum() / ref_contact.sum()) if ref_contact.any() \
            else 1.0
        details[f"min_mm_{i}"] = float(d[:, i].min() * 1000.0)
        details[f"reference_contact_{i}"] = float(ref_contact.mean())
    return MetricResult.from_timeline("contact", timeline, float(timeline.mean()), "mm", thr,
                                      details=details)


class Contact(PairMetric):
    """Key joint-pair distance error (JPD) (:func:`contact`).

    For each pair of ``ScoreConfig.contact_pairs`` the distance ``d_p(t)`` on
    the bodies against the fitted keypoints' ``r_p(t)``; per frame
    ``mean_p |d_p(t) - r_p(t)|`` in mm; value: its mean; passes at <=
    ``jpd_max_mm``.
    """

    name, limit = "contact", attrgetter("jpd_max_mm")

    def compute(self, inputs: PairInputs) -> MetricResult:
        return contact(fitted_pair(inputs), pairs=inputs.config.contact_pairs,
                       thresholds=inputs.config.body)

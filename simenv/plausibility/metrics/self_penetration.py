"""Self-penetration: overlap between non-neighbouring geoms of one retargeted body.

The metric (:class:`SelfPenetration`, :func:`self_penetration`) and the geom
pairs behind it (:func:`self_contact_pairs`). Threshold:
``self_penetration_max_mm`` of
:class:`~simenv.plausibility.body_thresholds.BodyThresholds`. Metres in,
millimetres out.
"""

from __future__ import annotations

from operator import attrgetter

import numpy as np

from simenv.body.geometry import contact_depths
from simenv.body.retarget import RetargetResult
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.metric import BodyMetric, PersonInputs, fitted_body
from simenv.plausibility.timeline import MetricResult


def penetration_result(name: str, depth: np.ndarray, pair: np.ndarray, thr: float
                       ) -> MetricResult:
    """Result ``name`` of a penetration depth per frame (``depth`` (T,) metres;
    ``pair`` (T, 2) geoms of the deepest contact, -1 when none) against
    ``thr`` mm."""
    mm = depth * 1000.0
    return MetricResult.from_timeline(
        name, mm, float(mm.max()), "mm", thr,
        details={"mean_mm": float(mm.mean()), "frames_over": float((mm > thr).mean()),
                 "frames_touching": float((pair[:, 0] >= 0).mean())},
    )


def self_penetration(result: RetargetResult,
                     thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS) -> MetricResult:
    """Penetration between non-neighbouring geoms of one retargeted body.

    Pairs of bodies at tree distance 1 (parent-child, filtered by MuJoCo) and
    2 (siblings, grandparents: excluded by :mod:`simenv.body.humanoid`) overlap at
    the joints by construction and are not counted; everything else (an arm
    in the torso, a hand in the head, thigh in thigh) is. Timeline: deepest
    penetration (mm) per frame (``mj_collision`` contact distance); value:
    its maximum; passes when at most ``self_penetration_max_mm``. Details:
    ``mean_mm``, ``frames_over`` (fraction above the threshold),
    ``frames_touching`` (any counted contact). See :func:`self_contact_pairs`
    for the geom names per frame.
    """
    model = result.humanoid.model
    body = model.geom_bodyid > 0
    depth, pair = contact_depths(model, result.qpos, body[:, None] & body[None, :])
    return penetration_result("self_penetration", depth, pair,
                               thresholds.self_penetration_max_mm)


def self_contact_pairs(result: RetargetResult) -> list[tuple[int, str, str, float]]:
    """Every frame with a self-contact: ``(frame, geom a, geom b, depth mm)``
    of its deepest pair (for reports naming the parts)."""
    model = result.humanoid.model
    body = model.geom_bodyid > 0
    depth, pair = contact_depths(model, result.qpos, body[:, None] & body[None, :])
    return [(t, model.geom(int(a)).name, model.geom(int(b)).name, float(d * 1000))
            for t, ((a, b), d) in enumerate(zip(pair, depth, strict=True)) if a >= 0]


class SelfPenetration(BodyMetric):
    """Penetration between non-neighbouring geoms of one body
    (:func:`self_penetration`).

    Per frame the deepest ``mj_collision`` penetration (mm) between geoms of
    bodies more than two joints apart; value: the maximum; passes at <=
    ``self_penetration_max_mm``.
    """

    name, limit = "self_penetration", attrgetter("self_penetration_max_mm")

    def compute(self, inputs: PersonInputs) -> MetricResult:
        return self_penetration(fitted_body(inputs), inputs.config.body)

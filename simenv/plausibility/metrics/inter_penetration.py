"""Inter-person penetration: overlap between the geoms of two people of one scene.

The pairwise metric (:class:`InterPenetration`, :func:`inter_penetration`).
Threshold: ``inter_penetration_max_mm`` of
:class:`~simenv.plausibility.body_thresholds.BodyThresholds`. Metres in,
millimetres out.
"""

from __future__ import annotations

from operator import attrgetter

import numpy as np

from simenv.body.geometry import contact_depths
from simenv.body.retarget import InteractionRetargetResult
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.metric import PairInputs, PairMetric, fitted_pair
from simenv.plausibility.metrics.self_penetration import penetration_result
from simenv.plausibility.timeline import MetricResult


def inter_penetration(result: InteractionRetargetResult,
                      thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS) -> MetricResult:
    """Penetration between the geoms of two people of one scene.

    A geom belongs to the person whose root body carries it
    (``body_rootid``). Timeline: deepest penetration (mm) between geoms of
    different people per frame; value: its maximum; passes when at most
    ``inter_penetration_max_mm``. Details as
    :func:`~simenv.plausibility.metrics.self_penetration.self_penetration`
    (``frames_touching``: the people's geoms touch).
    """
    model = result.scene.model
    root = model.body_rootid[model.geom_bodyid]
    person = np.where(model.geom_bodyid > 0, root, -1)
    keep = (person[:, None] >= 0) & (person[None, :] >= 0) & (person[:, None] != person[None, :])
    depth, pair = contact_depths(model, result.qpos, keep)
    return penetration_result("inter_penetration", depth, pair,
                               thresholds.inter_penetration_max_mm)


class InterPenetration(PairMetric):
    """Penetration between the geoms of two people
    (:func:`inter_penetration`).

    Per frame the deepest ``mj_collision`` penetration (mm) between geoms of
    different people; value: the maximum; passes at <= ``inter_penetration_max_mm``.
    """

    name, limit = "inter_penetration", attrgetter("inter_penetration_max_mm")

    def compute(self, inputs: PairInputs) -> MetricResult:
        return inter_penetration(fitted_pair(inputs), inputs.config.body)

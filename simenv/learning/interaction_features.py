"""The feature extractor of the two-person distribution metrics (FVD, diversity,
multimodality) and of the interaction recogniser: the shipped gesture classifier's
penultimate features when its checkpoint loads, else the labelled fallback.

The metrics and the extractors themselves live in :mod:`simenv.data.interaction_metrics`;
this module only chooses one, which needs the model registry.
"""

from __future__ import annotations

from simenv.core.errors import SimenvError
from simenv.data.interaction_metrics import (
    ClassifierFeatures,
    FeatureExtractor,
    PoseSegmentFeatures,
)
from simenv.models import load


def default_feature_extractor() -> tuple[FeatureExtractor, str | None]:
    """The shipped gesture classifier's features if the checkpoint loads, else
    :class:`~simenv.data.interaction_metrics.PoseSegmentFeatures`.

    Returns:
        ``(extractor, reason)``: ``reason`` is None for the classifier, or why the
        fallback is used.
    """
    try:
        return ClassifierFeatures(load("gesture-classifier")), None
    except (SimenvError, ImportError) as exc:  # ImportError: PyTorch is not installed
        return PoseSegmentFeatures(), f"gesture classifier unavailable: {exc}"


__all__ = ["default_feature_extractor"]

"""``foot_skate`` on real motion where the feet leave the floor together (hops)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simenv.core.motion import Motion
from simenv.io.loader import load
from simenv.plausibility import foot_skate
from simenv.plausibility.corrupt import foot_slide

FAIR_DAB = Path(__file__).parent / "data" / "conventions" / "other" / "fair1_dab_zup.bvh"


@pytest.fixture(scope="module")
def dab() -> Motion:
    """FAIR AnimatedDrawings ``fair1`` dab (224 frames at 30 fps): a child hopping in place,
    both toes 0.5-2.5 m/s and 1.6-3.1 cm up at once (tests/data/conventions/SOURCES.md)."""
    return load(FAIR_DAB)


def test_hops_with_both_feet_moving_apart_are_not_skating(dab) -> None:
    """The hops' feet move apart faster than a slide while both are low: neither stands on
    the floor sliding. The remaining skating runs (if any) stay under the limit."""
    r = foot_skate(dab)
    assert r.passed is True
    skating = np.nan_to_num(r.timeline) > 0
    # The previous rule counted the hops at 5.1 s and 6.6-7.3 s (docs/plausibility.md).
    assert not skating[int(6.6 * dab.fps):int(7.3 * dab.fps)].any()


def test_a_seeded_slide_of_the_hopping_clip_is_still_caught(dab) -> None:
    """The whole body drifting at the registry's moderate 1 m/s on planted frames moves both
    feet together, so the hop exemption does not hide it."""
    assert foot_skate(foot_slide(dab, 1.0, seed=0)).passed is False

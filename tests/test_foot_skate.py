"""``foot_skate`` on real motion whose low feet move without sliding under load: hops (the
feet leave the floor together) and a running foot's approach to its touchdown."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from simenv.body.foot_contact import foot_floor
from simenv.core.motion import Motion
from simenv.io.loader import load
from simenv.plausibility import foot_skate
from simenv.plausibility.corrupt import foot_slide
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS

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


@pytest.fixture(scope="module")
def run(shared_data: Path) -> Motion:
    """CMU 09_06, a run (141 frames at 120 fps; shared corpus, development data)."""
    return load(shared_data / "cmu" / "asf_amc" / "09_06.amc")


def test_a_running_foot_approaching_its_touchdown_is_not_a_slide(run) -> None:
    """The right toe comes down through the contact height at 1.9 m/s and slows into its
    touchdown (frames 27-33): low and faster than the skating speed, but decelerating
    throughout into the landing, so not a loaded foot sliding. With the minimum duration cut
    to one frame pair (the approach is shorter than 0.15 s) every other slide still shows."""
    canon = run.to_canonical()
    pos = canon.positions.astype(np.float64)
    toe = pos[:, canon.skeleton.index("right_toe")]
    height = toe[:, 2] - foot_floor(pos)
    speed = np.linalg.norm(np.diff(toe[:, :2], axis=0), axis=1) * run.fps
    approach = slice(27, 33)  # frame pairs (t, t + 1)
    assert (height[27:34] < DEFAULT_THRESHOLDS.contact_height_m).all()
    assert (speed[approach] > DEFAULT_THRESHOLDS.skate_speed_mps).all()
    assert speed[33] <= DEFAULT_THRESHOLDS.skate_speed_mps  # the touchdown
    short = replace(DEFAULT_THRESHOLDS, skate_min_duration_s=1.0 / run.fps)
    r = foot_skate(run, short)
    assert not np.nan_to_num(r.timeline)[28:34].any()
    assert np.nan_to_num(r.timeline).any()  # the clip's other short slides still count


@pytest.mark.parametrize("speed", [1.0, 3.0])
def test_a_seeded_slide_of_the_run_is_still_caught(run, speed: float) -> None:
    """Planted feet drifting at 1 and 3 m/s hold their speed through each stance, so no
    slide reads as an approach."""
    assert foot_skate(foot_slide(run, speed, seed=0)).passed is False

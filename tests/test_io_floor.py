"""simenv.io.floor: a file whose floor is at the feet's joint centres is raised onto the floor
under the soles; a calibrated floor, or one sunk stance, is left alone. Real clips only."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import simenv
from simenv.assets import WALK, asset_path
from simenv.io.floor import BALL_HEIGHT_M, MIN_BALL_HEIGHT_M, floor_offset, planted_toe_heights
from simenv.plausibility.corrupt import sink

XIA = Path(__file__).parent / "data" / "conventions" / "cmu_motionbuilder"


def _floor_notes(m: simenv.Motion) -> list[str]:
    return [r for r in m.metadata.get("repairs", []) if "simenv.io.floor" in r]


@pytest.mark.parametrize("name", ["xia_angry_13_000.bvh", "xia_depressed_18_000.bvh"])
def test_joint_centre_floor_is_raised(name: str) -> None:
    """Holden-style processed Xia clips put the lowest joint centres at zero: their planted
    balls stand below the file's floor; read, they stand at the ball height, noted."""
    m = simenv.load(XIA / name)
    toes = planted_toe_heights(m)
    assert len(_floor_notes(m)) == 1
    assert np.median(toes) == pytest.approx(BALL_HEIGHT_M, abs=1e-4)
    assert np.percentile(toes, 90) >= MIN_BALL_HEIGHT_M
    assert floor_offset([m]) == 0.0  # idempotent


def test_calibrated_floor_and_sunk_stance_untouched() -> None:
    """CMU's floor is the capture volume's: not moved; a 10-cm sink over part of the clip
    (one stance through the floor) is the motion's defect, not the file's floor."""
    walk = simenv.load(asset_path(WALK))
    assert not _floor_notes(walk)
    assert floor_offset([walk]) == 0.0
    assert floor_offset([sink(walk, 10.0, seed=0)]) == 0.0


@pytest.mark.parametrize("depth_m", [0.05, 0.2])
def test_a_whole_clip_sunk_through_the_floor_is_left_for_the_metrics(depth_m: float) -> None:
    """A joint-centre floor puts the planted balls at zero; the real Xia walk lowered so they
    stand centimetres below it is a sunk body (a generator's defect), not that convention."""
    xia = simenv.load(XIA / "xia_angry_13_000.bvh")  # raised onto the floor when read
    sunk = xia.with_positions(xia.positions - np.array([0.0, 0.0, BALL_HEIGHT_M + depth_m],
                                                       np.float32))
    assert np.median(planted_toe_heights(sunk)) == pytest.approx(-depth_m, abs=1e-4)
    assert floor_offset([sunk]) == 0.0

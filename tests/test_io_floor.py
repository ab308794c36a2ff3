"""simenv.io.floor: a file whose floor is at the feet's joint centres is raised onto the floor
under the soles (through its toes, or on a rig without toes its ankles); a calibrated floor,
or one sunk stance, is left alone; a tilted floor is levelled. Real clips only."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA

import simenv
from simenv.assets import WALK, asset_path
from simenv.body.humanoid import fit_dimensions
from simenv.core.skeletons import canonical_skeleton
from simenv.io.floor import (
    BALL_HEIGHT_M,
    MIN_BALL_HEIGHT_M,
    ankle_floor_offset,
    fit_ankle_height,
    floor_offset,
    floor_plane,
    planted_toe_heights,
    put_on_floor,
)
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


# -- a rig without toes, and a tilted floor --------------------------------------------------

CMU_BVH = SHARED_DATA / "cmu" / "bvh"


def _toeless(m: simenv.Motion) -> simenv.Motion:
    """``m``'s canonical keypoints without the toes (a rig like Aalto's OptiTrack export)."""
    c = m.to_canonical()
    keys = [k for k in c.skeleton.joint_names if not k.endswith("_toe")]
    idx = [c.skeleton.index(k) for k in keys]
    return simenv.Motion(c.positions[:, idx], c.fps,
                         canonical_skeleton().subset(keys, name="canonical"), c.name,
                         dict(c.metadata))


def _tilted(m: simenv.Motion, deg: float) -> simenv.Motion:
    """``m`` turned ``deg`` about the file's x axis (through the origin)."""
    a = np.radians(deg)
    rot = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])
    return m.with_positions((m.positions.astype(np.float64) @ rot.T).astype(np.float32))


@pytest.mark.parametrize("name", ["16_15.bvh", "49_02.bvh"])
def test_toeless_clip_on_its_ankle_centres_is_raised_back(name: str) -> None:
    """A real CMU clip without its toes, lowered so that its lowest ankle centre is at zero
    (HumanML3D's put-on-floor on a rig whose lowest joints are the ankles), is raised back
    to within 15 mm of its capture floor (on the shared corpus the error is -38 to +26 mm,
    median -9: the fit's anthropometric ankle height against the subject's own)."""
    bare = _toeless(simenv.load(CMU_BVH / name))
    drop = float(min(bare.joint(f"{s}_ankle")[:, 2].min() for s in ("left", "right")))
    lowered = bare.with_positions(bare.positions - np.array([0.0, 0.0, drop], np.float32))
    assert ankle_floor_offset([bare]) == 0.0
    raised = put_on_floor(lowered)
    assert len(_floor_notes(raised)) == 1
    back = float(np.mean(raised.positions[..., 2] - lowered.positions[..., 2]))
    assert back == pytest.approx(drop, abs=0.015)


def test_toeless_cmu_clip_is_not_raised() -> None:
    """The shared corpus's clip whose planted ankles stand lowest against the fit's ankle
    height (CMU 05_02, lower foot's 90th percentile 0.87x), read without toes, stays."""
    bare = _toeless(simenv.load(CMU_BVH / "05_02.bvh"))
    assert ankle_floor_offset([bare]) == 0.0
    assert put_on_floor(bare) is bare
    assert fit_ankle_height(bare) == pytest.approx(fit_dimensions(bare).ankle_height, abs=0.008)


@pytest.mark.parametrize("toes", [True, False])
def test_tilted_floor_is_levelled(toes: bool) -> None:
    """The real CMU walk 16_15 (3.9 m) turned by 3 deg is levelled back (its contacts' plane
    within 0.3 deg of level, the pelvis's height along the walk as captured within 2 cm: the
    capture's own contacts tilt 0.2 deg, 15 mm over the walk), through its toes or, without
    them, its ankles; as read (tilt under the 2-deg threshold) it is not touched."""
    walk = simenv.load(CMU_BVH / "16_15.bvh")
    walk = walk if toes else _toeless(walk)
    assert put_on_floor(walk) is walk
    plane = floor_plane([_tilted(walk, 3.0)])
    assert plane is not None and plane.tilt_deg == pytest.approx(3.0, abs=0.4)
    level = put_on_floor(_tilted(walk, 3.0))
    assert len(_floor_notes(level)) == 1 and "tilted" in _floor_notes(level)[0]
    after = floor_plane([level])
    assert after is not None and after.tilt_deg < 0.3
    pelvis = level.to_canonical().joint("pelvis")[:, 2] - walk.to_canonical().joint("pelvis")[:, 2]
    assert np.ptp(pelvis) < 0.02

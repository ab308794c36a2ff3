"""PhysDiff's Penetrate / Float / Skate / Phys-Err and GMD's foot-skating ratio
(simenv.plausibility.published): exact values on constructed motion, agreement
with a transcription of GMD's published code on real mocap, and typed errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import uniform_filter1d

import simenv
from simenv.core.errors import MotionError, SkeletonError
from simenv.core.motion import Motion
from simenv.core.skeletons import SMPL22_JOINTS, gesture9_skeleton, smpl22_skeleton
from simenv.io.humanml3d import Y_UP_TO_Z_UP, to_smpl22
from simenv.plausibility.corrupt import foot_slide
from simenv.plausibility.published import (
    PUBLISHED_METRICS,
    published_metrics,
    published_record,
)

LEFT_FOOT, RIGHT_FOOT = SMPL22_JOINTS.index("left_foot"), SMPL22_JOINTS.index("right_foot")


def _standing(frames: int, fps: float = 20.0) -> np.ndarray:
    """(T, 22, 3) an upright SMPL-22 stick figure, feet (toe joints) on z = 0,
    the lowest joints; other joints 5 cm to 1.6 m high."""
    rng = np.random.default_rng(0)
    pose = np.zeros((22, 3))
    pose[:, 2] = np.linspace(0.05, 1.6, 22)
    pose[:, 0] = rng.uniform(-0.2, 0.2, 22)
    pose[:, 1] = rng.uniform(-0.1, 0.1, 22)
    pose[[LEFT_FOOT, RIGHT_FOOT], 2] = 0.0
    pose[[LEFT_FOOT, RIGHT_FOOT], 0] = (-0.1, 0.1)
    return np.repeat(pose[None], frames, axis=0)


def _motion(pos: np.ndarray, fps: float = 20.0) -> Motion:
    return Motion(pos.astype(np.float32), fps, smpl22_skeleton(), name="synthetic")


def gmd_calculate_skating_ratio(motions: np.ndarray) -> np.ndarray:
    """GMD's ``calculate_skating_ratio`` (korrawe/guided-motion-diffusion,
    data_loaders/humanml/utils/metrics.py), transcribed for numpy input
    ``motions`` (bs, 22, 3, T) in HumanML3D's Y-up frame."""
    thresh_height, fps, thresh_vel, avg_window = 0.05, 20.0, 0.50, 5
    verts_feet = motions[:, [10, 11], :, :]
    verts_feet_plane_vel = np.linalg.norm(
        verts_feet[:, :, [0, 2], 1:] - verts_feet[:, :, [0, 2], :-1], axis=2) * fps
    vel_avg = uniform_filter1d(verts_feet_plane_vel, axis=-1, size=avg_window,
                               mode="constant", origin=0)
    verts_feet_height = verts_feet[:, :, 1, :]
    feet_contact = np.logical_and(verts_feet_height[:, :, :-1] < thresh_height,
                                  verts_feet_height[:, :, 1:] < thresh_height)
    skating = np.logical_and(feet_contact, verts_feet_plane_vel > thresh_vel)
    skating = np.logical_and(skating, vel_avg > thresh_vel)
    skating = np.logical_or(skating[:, 0, :], skating[:, 1, :])
    return np.sum(skating, axis=1) / skating.shape[1]


def test_still_figure_on_the_floor_scores_zero() -> None:
    m = published_metrics(_motion(_standing(40)))
    assert m.values() == {k: 0.0 for k in PUBLISHED_METRICS}
    assert m.feet == ("left_toe", "right_toe")


def test_penetrate_and_float_are_the_lowest_point_averaged_over_frames() -> None:
    pos = _standing(40)
    pos[:20, :, 2] -= 0.03  # first second 3 cm into the floor
    pos[20:, :, 2] += 0.10  # then 10 cm above it
    m = published_metrics(_motion(pos))
    assert m.penetrate_mm == pytest.approx(15.0, abs=1e-3)  # 30 mm on half the frames
    assert m.float_mm == pytest.approx(50.0, abs=1e-3)  # 100 mm on the other half
    assert m.phys_err_mm == pytest.approx(m.penetrate_mm + m.float_mm + m.skate_mm)


def test_skate_is_the_mean_horizontal_step_of_feet_in_contact() -> None:
    pos = _standing(41)
    pos[:, LEFT_FOOT, 0] += 0.01 * np.arange(41)  # left toe slides 1 cm per frame on the floor
    m = published_metrics(_motion(pos))
    # Every pair: only the left foot moves, the right is planted: mean of 10 mm and 0 mm.
    assert m.skate_mm == pytest.approx(5.0, abs=1e-3)
    pos[:, RIGHT_FOOT, 2] = 0.2  # right foot in the air: only the sliding foot is in contact
    assert published_metrics(_motion(pos)).skate_mm == pytest.approx(10.0, abs=1e-3)


def test_gmd_ratio_counts_zero_padded_moving_average() -> None:
    """0.7 m/s sliding on all 40 pairs: the 5-pair moving average with zero padding is
    0.42 m/s at the first and last pair (3 of 5 terms), below 0.5 m/s there."""
    pos = _standing(41)
    pos[:, LEFT_FOOT, 0] += 0.035 * np.arange(41)  # 3.5 cm per frame = 0.7 m/s at 20 fps
    assert published_metrics(_motion(pos)).skating_ratio == pytest.approx(38 / 40)
    pos[:, LEFT_FOOT, 2] = 0.06  # above GMD's 5 cm: not in contact, no skating
    assert published_metrics(_motion(pos)).skating_ratio == 0.0


def test_rate_is_converted_to_20_fps_before_per_frame_metrics() -> None:
    """The same physical slide (0.4 m/s) at 20 fps and at 60 fps gives 20 mm per 20 fps frame."""
    for fps in (20.0, 60.0):
        n = int(2 * fps) + 1
        pos = _standing(n)
        pos[:, LEFT_FOOT, 0] += 0.4 / fps * np.arange(n)
        pos[:, RIGHT_FOOT, 2] = 0.2
        m = published_metrics(_motion(pos, fps), floor="world")
        assert m.skate_mm == pytest.approx(20.0, rel=1e-4), fps
        assert m.frames == 41
        assert m.resampled_from_fps == (None if fps == 20.0 else fps)


def test_gmd_ratio_matches_gmds_code_on_real_walk(walk_2s: Motion) -> None:
    """On the bundled real CMU walk at 20 fps in HumanML3D's frame (Y up, lowest joint
    on the floor), with a foot slide added so that skating occurs, our ratio equals
    GMD's code on the same joints."""
    slid = foot_slide(walk_2s, 1.0, seed=3).resample(20.0)
    smpl = to_smpl22(slid)
    ours = published_metrics(smpl, floor="lowest_joint").skating_ratio
    pos = smpl.positions.astype(np.float64)
    pos[..., 2] -= pos[..., 2].min()
    y_up = pos @ Y_UP_TO_Z_UP  # inverse rotation: Z up -> HumanML3D's Y up
    theirs = gmd_calculate_skating_ratio(y_up.transpose(1, 2, 0)[None])[0]
    assert theirs > 0.05
    assert ours == pytest.approx(theirs, abs=1e-9)


def test_floor_conventions_on_real_mocap(walk_2s: Motion) -> None:
    """CMU toe joint centres stand above z = 0: HumanML3D's floor lowers Float and
    finds the contacts (and the skating) that the world floor misses."""
    world = published_metrics(walk_2s)
    hml = published_metrics(walk_2s, floor="lowest_joint")
    assert hml.penetrate_mm == 0.0
    assert hml.float_mm < world.float_mm - 5.0
    assert hml.skate_mm > world.skate_mm


def test_foot_slide_raises_skating_on_every_real_clip(shared_data: Path) -> None:
    clips = sorted((shared_data / "cmu" / "bvh").glob("*.bvh"))
    assert clips
    for path in clips:
        motion = simenv.load(path).slice(0, 600)
        clean = published_metrics(motion, floor="lowest_joint")
        slid = published_metrics(foot_slide(motion, 1.0), floor="lowest_joint")
        assert slid.skate_mm > clean.skate_mm + 5.0, path.name
        assert slid.skating_ratio > clean.skating_ratio, path.name


def test_no_feet_is_a_typed_error_naming_the_keypoint() -> None:
    arms = Motion(np.tile(np.linspace(0.5, 1.6, 27).reshape(1, 9, 3), (10, 1, 1))
                  .astype(np.float32), 20.0, gesture9_skeleton(), name="arms",
                  metadata={"source": "arms.npz"})
    with pytest.raises(SkeletonError) as err:
        published_metrics(arms)
    assert err.value.field == "left_toe" and err.value.source == "arms.npz"
    # In the score record the reason replaces the values; the other metrics still run.
    assert "left_toe" in published_record(arms)["reason"]


def test_too_short_and_unknown_floor_are_typed_errors() -> None:
    with pytest.raises(MotionError, match="at least 2 frames"):
        published_metrics(_motion(_standing(1)))
    with pytest.raises(MotionError, match="frame pair"):
        published_metrics(_motion(_standing(2), fps=120.0))  # 8 ms: no 20 fps pair
    with pytest.raises(simenv.SimenvError) as err:
        published_metrics(_motion(_standing(5)), floor="ceiling")  # type: ignore[arg-type]
    assert err.value.field == "floor"


def test_nan_positions_are_refused_before_any_metric() -> None:
    pos = _standing(5)
    pos[3, LEFT_FOOT, 1] = np.nan
    with pytest.raises(MotionError) as err:
        _motion(pos)
    assert err.value.frame == 3 and err.value.field == "left_foot"


def test_score_record_lists_published_metrics_without_changing_the_verdict(
        walk_2s: Motion) -> None:
    from simenv.plausibility.report import score

    report = score(walk_2s, physics=False)
    rec = report.to_records()[0]
    pub = rec["published"]
    assert set(PUBLISHED_METRICS) <= set(pub)
    assert pub["fps"] == 20.0 and pub["floor"] == "world"
    assert pub["physdiff_skate"]["unit"] == "mm"
    expected = published_metrics(walk_2s)
    assert pub["physdiff_float"]["value"] == pytest.approx(expected.float_mm, abs=1e-5)
    assert rec["verdict"] == report.verdict
    assert "physdiff_float" not in rec["metrics"]

"""Tests for simenv.envs.reaction_rehearsal: where the agent starts, the generated reaction
tracked and scored on simulated bodies, the command, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from simenv.cli import main as cli
from simenv.core.errors import SimenvError
from simenv.data import interaction_data as idata
from simenv.envs import reaction_rehearsal as rr
from simenv.models import available
from simenv.models.reaction_baselines import MirrorActor

J = list(idata.INTER18_JOINTS)


def _local_walk() -> np.ndarray:
    """(T, 18, 3) the bundled real walk in the actor frame of its first frame."""
    user = rr.user_motion("cmu_02_01_walk.bvh")
    origin, yaw = idata.actor_frame(user.positions[:1])
    return idata.normalise(user.positions[None], origin, yaw)[0].astype(np.float64)


def test_fallback_start_faces_the_user_from_a_metre() -> None:
    first = _local_walk()[0]
    pose, start = rr.start_pose(first, None)
    assert start["method"].startswith("mirrored")
    pelvis = pose[J.index("pelvis")]
    assert np.hypot(*pelvis[:2]) == pytest.approx(rr.FALLBACK_DISTANCE_M, abs=0.05)
    # Facing back toward the user (-x in the user's frame): heading of the start pose.
    _, yaw = idata.actor_frame(pose[None])
    assert abs(abs(float(yaw[0])) - np.pi) < np.deg2rad(20)


def test_start_is_the_nearest_real_training_pose(shared_data: Path) -> None:
    windows = idata.make_windows(idata.load_recordings(shared_data))
    train = windows.subset(idata.split_by_recording(windows).train)
    first = train.actor[7, 0].astype(np.float64)
    pose, start = rr.start_pose(first, train)
    assert start["pose_distance_m"] == pytest.approx(0.0, abs=1e-6)
    np.testing.assert_allclose(pose, train.reactor[7, 0], atol=1e-6)


@pytest.mark.usefixtures("quick_physics")  # the chain runs and writes; any verdict
def test_generated_reaction_is_tracked_and_scored(tmp_path: Path, shared_data: Path) -> None:
    s = rr.rehearse_reaction("cmu_02_01_walk.bvh", MirrorActor(), tmp_path, shared=shared_data,
                             seconds=1.2, report=False)
    assert s["model"] == "mirror" and s["frames"] == 30
    assert s["start"]["method"] == "nearest training window"
    agent = s["agent"]
    assert agent["verdict"] in ("plausible", "implausible")
    assert {"root_residual", "tracking", "foot_skate"} <= set(agent["metrics"])
    assert agent["metrics"]["root_residual"]["value"] is not None
    assert {"inter_penetration", "contact"} <= set(s["interaction"])
    saved = json.loads((tmp_path / "summary.json").read_text())
    assert saved["agent"]["score"] == pytest.approx(agent["score"])
    with np.load(tmp_path / "reaction.npz") as z:
        assert z["user"].shape == z["agent"].shape == (30, 18, 3)
        # The mirror moves: the agent is a real motion, not a frozen pose.
        assert np.ptp(z["agent"][:, J.index("right_hand")], axis=0).max() > 0.02


def test_bad_agents_and_durations_are_refused(tmp_path: Path, capsys) -> None:
    with pytest.raises(SimenvError, match="not a reaction generator"):
        rr.rehearse_reaction("cmu_02_01_walk.bvh", "bigraphdiff", tmp_path)
    with pytest.raises(SimenvError, match="seconds"):
        rr.rehearse_reaction("cmu_02_01_walk.bvh", MirrorActor(), tmp_path, seconds=0.0)
    with pytest.raises(SimenvError, match="no session file"):
        rr.rehearse_reaction(tmp_path / "missing.bvh", MirrorActor(), tmp_path)
    assert rr.main(["cmu_02_01_walk.bvh", "--agent", "interaction-augment", "--out",
                    str(tmp_path)]) == 2
    assert "not a reaction generator" in capsys.readouterr().err


@pytest.mark.usefixtures("quick_physics")  # the command runs and writes; any verdict
@pytest.mark.parametrize("name", ["interformer", "reactive-gan"])
def test_rehearse_command_dispatches_to_a_shipped_generator(
        name: str, tmp_path: Path, capsys, shared_data: Path) -> None:
    if name not in available():
        pytest.skip(f"{name} is not shipped in assets/models")
    status = cli.main(["rehearse", "cmu_02_01_walk.bvh", "--agent", name, "--out",
                       str(tmp_path), "--seconds", "0.6", "--shared", str(shared_data),
                       "--no-render"])
    assert status == 0
    assert f"{name} answering" in capsys.readouterr().out
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["model"] == name and Path(summary["report"]).is_file()
    # The verdicts' planner is recorded: here the suite's quick one, simenv score's default.
    assert summary["scoring"]["n_samples"] == 16 and summary["scoring"]["attempts"] == 1

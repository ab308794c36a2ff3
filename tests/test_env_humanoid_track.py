"""simenv/HumanoidTrack-v0: Gymnasium API conformance, reward, termination and guards."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import simenv
import simenv.envs  # noqa: F401  (registers the ids)
from simenv.assets import WALK, asset_path
from simenv.body.retarget import RetargetResult, retarget
from simenv.core.errors import SimenvError
from simenv.envs.humanoid_track import HumanoidTrackEnv


@pytest.fixture(scope="module")
def walk() -> RetargetResult:
    """The bundled walk retargeted at the default control rate (shared by the tests)."""
    return retarget(simenv.load(asset_path(WALK)).resample(1 / 0.03))


def _reference_action(env: HumanoidTrackEnv) -> np.ndarray:
    """PD targets at the next reference pose (open-loop tracking)."""
    k = min(env._frame + 1, len(env.reference.qpos) - 1)
    return env.reference.qpos[k, env._act_qpos].astype(np.float32)


def test_registered_and_passes_check_env():
    env = gym.make("simenv/HumanoidTrack-v0", render_mode="rgb_array")
    with pytest.warns(UserWarning):  # infinite observation bounds, unnormalised actions
        check_env(env.unwrapped)
    frame = env.unwrapped.render()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8 and frame.std() > 0
    env.close()


def test_reset_is_seeded(walk: RetargetResult):
    env = HumanoidTrackEnv(walk)
    starts = {env.reset(seed=s)[1]["frame"] for s in range(8)}
    assert len(starts) > 1  # reference state initialisation draws the start frame
    a, _ = env.reset(seed=3)
    b, _ = env.reset(seed=3)
    np.testing.assert_array_equal(a, b)
    assert env.observation_space.contains(a)
    obs, info = env.reset(options={"start_frame": 5})
    assert info["frame"] == 5 and info["body_error_m"] == pytest.approx(0.0, abs=1e-9)
    with pytest.raises(SimenvError, match="start_frame"):
        env.reset(options={"start_frame": 10_000})


def test_reward_terms_and_early_termination(walk: RetargetResult):
    """Open-loop PD on the reference tracks well at first (reward near 1), then the body
    falls behind until the PHC rule (mean keypoint error > 0.5 m) terminates."""
    env = HumanoidTrackEnv(walk)
    env.reset(options={"start_frame": 0})
    rewards, info, terminated, truncated = [], {}, False, False
    while not (terminated or truncated):
        _, r, terminated, truncated, info = env.step(_reference_action(env))
        rewards.append(r)
        assert all(0.0 < v <= 1.0 for v in info["reward_terms"].values())
    assert rewards[0] > 0.7
    assert 0.0 < min(rewards) and max(rewards) <= 1.0
    assert terminated and not truncated
    assert info["body_error_m"] > 0.5
    with pytest.raises(SimenvError, match="reset"):
        env.step(env.action_space.sample())


def test_end_of_reference_truncates(walk: RetargetResult):
    env = HumanoidTrackEnv(walk)
    env.reset(options={"start_frame": len(env.reference.qpos) - 2})
    _, _, terminated, truncated, info = env.step(_reference_action(env))
    assert truncated and not terminated
    assert info["truncation_reason"] == "end of the reference motion"


def test_guards(walk: RetargetResult):
    env = HumanoidTrackEnv(walk)
    with pytest.raises(SimenvError, match="before reset"):
        env.step(env.action_space.sample())
    env.reset(seed=0)
    with pytest.raises(SimenvError, match="shape"):
        env.step(np.zeros(3, dtype=np.float32))
    with pytest.raises(SimenvError, match="NaN"):
        env.step(np.full(env.action_space.shape, np.nan, dtype=np.float32))
    with pytest.raises(SimenvError, match="render_mode"):
        HumanoidTrackEnv(walk, render_mode="human")
    with pytest.raises(SimenvError, match="no motion file"):
        HumanoidTrackEnv("no_such_clip.bvh")


def test_divergence_truncates_with_reason(walk: RetargetResult):
    env = HumanoidTrackEnv(walk)
    obs0, _ = env.reset(seed=0)
    env.data.qvel[:] = 1e9  # a state no integrator survives
    obs, reward, terminated, truncated, info = env.step(_reference_action(env))
    assert truncated and not terminated and reward == 0.0
    assert info["truncation_reason"].startswith("physics:")
    assert np.isfinite(obs).all() and env.observation_space.contains(obs)
    with pytest.raises(SimenvError, match="reset"):
        env.step(env.action_space.sample())


def test_motion_inputs(walk: RetargetResult):
    """A Motion is retargeted at the control rate; a retargeted result at another rate is
    resampled to it."""
    motion = simenv.load(asset_path(WALK)).slice(0, 60)
    env = HumanoidTrackEnv(motion, frame_skip=10)
    assert env.reference.fps == pytest.approx(50.0)
    assert len(env.reference.qpos) == int(np.floor(59 / 120 * 50)) + 1
    env = HumanoidTrackEnv(walk, frame_skip=20)
    assert env.reference.fps == pytest.approx(25.0)
    q = env.reference.qpos
    assert np.allclose(np.linalg.norm(q[:, 3:7], axis=1), 1.0)
    assert len(q) == int(np.floor((len(walk.qpos) - 1) / walk.fps * 25.0)) + 1

"""PettingZoo ParallelEnv of the room: API test, replayed and policy-driven user, guards."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

import simenv
from simenv.assets import WALK, asset_path
from simenv.core.errors import SimenvError
from simenv.data.gestures import GESTURE15_JOINTS
from simenv.envs.room_parallel import AGENTS, RoomParallelEnv, parallel_env
from simenv.perception.loop import PerceptionLoop


@pytest.fixture(scope="module")
def short() -> simenv.Motion:
    return simenv.load(asset_path(WALK)).slice(0, 60)  # 0.5 s


@pytest.mark.parametrize("user", ["replay", "policy"])
def test_parallel_api(short, user: str):
    parallel_api_test(RoomParallelEnv(user=user, session=short), num_cycles=100)


def test_replayed_user_matches_the_single_agent_env(short):
    env = parallel_env(session=short)
    obs, _ = env.reset(seed=0)
    assert env.agents == list(AGENTS)
    single = env.env
    for _ in range(5):
        obs, rewards, term, trunc, _ = env.step({"user": 0, "agent": 0})
    room = single.room
    np.testing.assert_allclose(obs["user"]["self"], single.data.site_xpos[room.user_sites],
                               rtol=1e-6)
    np.testing.assert_allclose(obs["agent"]["user_history"][-1], obs["user"]["self"])
    assert rewards["user"] == rewards["agent"]
    with pytest.raises(SimenvError, match="one action"):
        env.step({"user": 1, "agent": 0})
    with pytest.raises(SimenvError, match="no action"):
        env.step({"agent": 0})


def test_policy_user_poses_the_avatar(short):
    env = RoomParallelEnv(user="policy", session=short)
    env.reset(seed=0)
    space = env.action_space("user")
    h = env.env.room.user
    angles = np.zeros(space.shape, dtype=np.float32)
    raise_arm = h.joint_names.index("right_upper_arm_flex")
    angles[raise_arm] = np.deg2rad(170.0)  # arm straight up
    obs, *_ = env.step({"user": angles, "agent": 0})
    kp = obs["user"]["self"]
    names = h.keypoint_names
    assert kp[names.index("right_hand"), 2] > kp[names.index("head"), 2]
    pelvis = kp[names.index("pelvis")]
    assert pelvis[:2] == pytest.approx(env.env.scenario.user.position, abs=1e-5)
    with pytest.raises(SimenvError, match="hinge angles"):
        env.step({"user": angles[:3], "agent": 0})


def test_guards(short):
    with pytest.raises(SimenvError, match="replay"):
        RoomParallelEnv(user="puppet", session=short)
    env = RoomParallelEnv(session=short)
    with pytest.raises(SimenvError, match="before reset"):
        env.step({"user": 0, "agent": 0})
    with pytest.raises(SimenvError, match="unknown agent"):
        env.observation_space("robot")


class _ReadsWave:
    """Stub classifier: always reads "wave" with probability 0.95."""

    labels = ("wave", "idle")
    joint_names = GESTURE15_JOINTS

    def classify(self, window: np.ndarray, valid: np.ndarray) -> np.ndarray:
        return np.array([0.95, 0.05])


@pytest.mark.parametrize("user", ["replay", "policy"])
def test_room_agent_plays_the_agent_side(short, user: str):
    """The room's agent acts for ``agent`` from its observation: at the first tick it
    greets; a replayed user's recording bounds its ticks, a policy user's does not."""
    env = RoomParallelEnv(user=user, session=short)
    agent = env.room_agent(PerceptionLoop(_ReadsWave()))
    assert agent.reactions == env.env.reactions
    assert agent.recorded_frames == (env.env.n_frames if user == "replay" else None)
    obs, _ = env.reset(seed=0)
    still = env.env.track.qpos[0][env.env.room.user.hinge_qpos]  # the first pose held
    for _ in range(25):
        action = agent.act(obs["agent"])
        obs, *_ = env.step({"agent": action,
                            "user": 0 if user == "replay" else still.astype(np.float32)})
    (entry,) = env.env.log
    assert entry["reaction"] == "greet" and entry["t_decision"] == pytest.approx(0.96)

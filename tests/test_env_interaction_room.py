"""simenv/InteractionRoom-v0: Gymnasium API conformance, vector envs, reward rules, guards."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import simenv
import simenv.envs  # noqa: F401  (registers the ids)
import simenv.models
from simenv.assets import WALK, asset_path
from simenv.core.errors import SimenvError
from simenv.data.gestures import GESTURE15_JOINTS
from simenv.envs.interaction_room import (
    FALSE_ALARM,
    GRACE_S,
    MISS,
    OBJECTS,
    SUCCESS,
    TAIL_S,
    TIMELINESS_S,
    InteractionRoomEnv,
)
from simenv.perception.loop import PerceptionLoop
from simenv.room.session import PERCEPTION_FPS, GestureEvent, Session

#: The bundled walk with a "wave" label on 0.4-1.0 s (the reward only reads labels).
WAVE = GestureEvent("wave", 0.4, 1.0)


@pytest.fixture(scope="module")
def env() -> InteractionRoomEnv:
    return InteractionRoomEnv(gestures=[WAVE])


def _run(env: InteractionRoomEnv, actions: dict[int, int]) -> list[dict]:
    """Step to the end, taking ``actions[step]`` (else no-op); returns the infos with reward."""
    env.reset(seed=0)
    out, k, truncated = [], 0, False
    while not truncated:
        _, r, terminated, truncated, info = env.step(actions.get(k, 0))
        assert not terminated
        out.append({**info, "reward": r, "qpos": env.data.qpos.copy()})
        k += 1
    return out


def test_registered_and_passes_check_env():
    env = gym.make("simenv/InteractionRoom-v0", render_mode="rgb_array")
    with pytest.warns(UserWarning):  # infinite observation bounds
        check_env(env.unwrapped)
    frame = env.unwrapped.render()
    assert frame.shape == (360, 480, 3) and frame.dtype == np.uint8
    env.close()


def test_spaces_and_observation(env: InteractionRoomEnv):
    assert env.reactions[0] is None
    assert set(env.reactions[1:]) == {"greet", "bow_back", "hifi_down"}
    obs, info = env.reset(seed=1)
    assert env.observation_space.contains(obs)
    K = len(env.room.user.keypoint_names)
    assert obs["user_history"].shape == (25, K, 3)
    assert obs["user_future"].shape == (50, K, 3)
    # Before the session starts, the history repeats frame 0; the prediction continues it.
    np.testing.assert_allclose(obs["user_history"][0], obs["user_history"][-1])
    states = env.room.object_states(env.data)
    levels = [env.room.objects[n].level(states[n]) for n in OBJECTS]
    np.testing.assert_allclose(obs["objects"], levels, atol=1e-6)
    assert info["object_labels"]["hifi"] == "loud"


def test_timely_correct_reaction_is_rewarded(env: InteractionRoomEnv):
    greet = env.reactions.index("greet")
    step = int(round(0.6 * PERCEPTION_FPS))  # 0.2 s after the onset
    infos = _run(env, {step: greet})
    expected = np.exp(-(step / PERCEPTION_FPS - WAVE.onset_s) / TIMELINESS_S)
    assert infos[step]["reward_terms"]["decision"] == pytest.approx(expected)
    assert infos[step]["reaction"] == "greet" and infos[step]["gesture"] == "wave"
    assert all(i["reward_terms"]["miss"] == 0 for i in infos)
    assert infos[-1]["truncation_reason"] == "end of the session"
    assert [(e["t_decision"], e["reaction"], e["gesture"], e["started"]) for e in env.log] == [
        (step / PERCEPTION_FPS, "greet", "wave", True)]
    assert isinstance(env.log[0]["success"], bool)  # measured when its plan ended


def test_wrong_late_and_missing_reactions_are_penalised(env: InteractionRoomEnv):
    greet, hifi = env.reactions.index("greet"), env.reactions.index("hifi_down")
    early = int(round(0.2 * PERCEPTION_FPS))  # before the onset: nothing to answer
    infos = _run(env, {early: greet, early + 15: hifi})
    assert infos[early]["reward_terms"]["decision"] == -FALSE_ALARM
    assert infos[early + 15]["reward_terms"]["decision"] == -FALSE_ALARM
    misses = [i["reward_terms"]["miss"] for i in infos]
    assert sum(misses) == -MISS
    first = next(k for k, m in enumerate(misses) if m)
    assert first / PERCEPTION_FPS > WAVE.end_s + GRACE_S - 1e-9
    # The same answer twice: the second is a false alarm.
    step = int(round(0.5 * PERCEPTION_FPS))
    infos = _run(env, {step: greet, step + 1: greet})
    assert infos[step]["reward_terms"]["decision"] > 0
    assert infos[step + 1]["reward_terms"]["decision"] == -FALSE_ALARM


def test_no_op_rehearsal_is_plausible_and_deterministic(env: InteractionRoomEnv):
    """Idle agent, replayed user (the walk's first half second, before the user reaches the
    desk and shoves the agent): no penalties, the same rollout twice."""
    clean = InteractionRoomEnv(simenv.load(asset_path(WALK)).slice(0, 60))
    a = _run(clean, {})
    b = _run(clean, {})
    assert all(i["reward"] == 0.0 for i in a)
    assert [i["object_labels"] for i in a] == [i["object_labels"] for i in b]
    np.testing.assert_array_equal([i["qpos"] for i in a], [i["qpos"] for i in b])


def test_guards(env: InteractionRoomEnv):
    fresh = InteractionRoomEnv(gestures=[WAVE])
    with pytest.raises(SimenvError, match="before reset"):
        fresh.step(0)
    fresh.reset(seed=0)
    for bad in (len(fresh.reactions), -1, np.array([0, 1]), 0.5):
        with pytest.raises(SimenvError, match="action"):
            fresh.step(bad)
    with pytest.raises(SimenvError, match="vocabulary"):
        InteractionRoomEnv(gestures=[GestureEvent("cold", 0.0, 1.0)])
    with pytest.raises(SimenvError, match="onset"):
        GestureEvent("wave", 2.0, 1.0)
    with pytest.raises(SimenvError, match="history"):
        InteractionRoomEnv(history_frames=1)


def test_discomfort_scenario_actions():
    env = InteractionRoomEnv(Session.load("cmu_02_01_walk.bvh",
                                          [GestureEvent("cold", 0.0, 1.0)]),
                             scenario="discomfort")
    assert set(env.reactions[1:]) == {"greet", "hifi_down", "close_window", "open_window",
                                      "cigarette_out", "close_curtain"}
    env.reset(seed=0)
    _, r, *_ = env.step(env.reactions.index("close_window"))
    assert r == pytest.approx(1.0)


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_vector_envs(mode: str):
    envs = gym.make_vec("simenv/InteractionRoom-v0", num_envs=2, vectorization_mode=mode)
    try:
        obs, _ = envs.reset(seed=0)
        assert obs["user_history"].shape[0] == 2
        obs, reward, terminated, truncated, _ = envs.step(np.array([0, 1]))
        assert reward.shape == (2,) and reward[0] == 0.0 and reward[1] == -FALSE_ALARM
        assert envs.single_observation_space.contains({k: v[0] for k, v in obs.items()})
    finally:
        envs.close()


def test_reaction_carried_out_in_simulation_changes_the_object():
    """Discomfort scenario, "smell": the agent's decision starts the cigarette_out plan; the
    cigarette goes out through the agent's hand, the episode runs past the recording until
    the plan ends, and the success is measured and rewarded."""
    short = simenv.load(asset_path(WALK)).slice(0, 60)  # 0.5 s, the user far from the desk
    env = InteractionRoomEnv(short, gestures=[GestureEvent("smell", 0.2, 0.5)],
                             scenario="discomfort")
    act = env.reactions.index("cigarette_out")
    decide = int(round(0.3 * PERCEPTION_FPS))
    infos = _run(env, {decide: act})
    assert infos[decide]["executing"] == "cigarette_out"
    (entry,) = env.log
    assert entry["started"] and entry["success"] is True
    assert entry["t_decision"] < entry["t_object_changed"] < infos[-1]["time_s"]
    assert sum(i["reward_terms"]["success"] for i in infos) == SUCCESS
    assert infos[-1]["time_s"] > 0.5 + TAIL_S  # kept simulating for the running reaction
    assert infos[-1]["object_labels"]["cigarette"] == "out"
    assert env._obs["objects"][OBJECTS.index("cigarette")] > 0.5
    assert all(i["reward_terms"]["plausibility"] == 0 for i in infos)


def test_greeting_carried_out_in_simulation_is_measured_and_rewarded():
    """Default scenario, "wave" on the first half second of the walk: the greet plan runs
    past the recording, the greeting is measured every step (Room.greeting) and its
    success rewarded once."""
    short = simenv.load(asset_path(WALK)).slice(0, 60)
    env = InteractionRoomEnv(short, gestures=[GestureEvent("wave", 0.2, 0.5)])
    decide = int(round(0.3 * PERCEPTION_FPS))
    infos = _run(env, {decide: env.reactions.index("greet")})
    (entry,) = env.log
    assert entry["started"] and entry["success"] is True
    assert entry["facing_deg_min"] < 30.0 and entry["t_decision"] < entry["t_success"]
    assert sum(i["reward_terms"]["success"] for i in infos) == SUCCESS
    assert infos[-1]["executing"] is None


@pytest.mark.skipif("predictor-gesture-25-50" not in simenv.models.available(),
                    reason="shipped predictor-gesture-25-50 absent")
def test_default_predictor_is_the_shipped_gesture_forecaster(env: InteractionRoomEnv):
    """The observation's future comes from the shipped gesture-domain forecaster (25-frame
    history, 2 s ahead) and, made at a perception tick, starts where the observed motion
    ends (no seam)."""
    assert env.predictor.name == "predictor-gesture-25-50"
    obs, _ = env.reset(seed=0)
    for _ in range(env.predict_every):
        obs, *_ = env.step(0)
    K = obs["user_history"].shape[1]
    assert obs["user_history"].shape == (25, K, 3) and obs["user_future"].shape == (50, K, 3)
    kept = env.user_keypoints()
    assert kept.shape == (25, K, 3)
    np.testing.assert_array_equal(kept[-25:], obs["user_history"])
    step = np.linalg.norm(np.diff(obs["user_history"], axis=0), axis=-1).mean()
    seam = np.linalg.norm(obs["user_future"][0] - obs["user_history"][-1], axis=-1).mean()
    assert np.isfinite(obs["user_future"]).all() and seam < 3 * step + 0.01
    with pytest.raises(SimenvError, match="reset"):
        InteractionRoomEnv(gestures=[WAVE], predictor="constant-velocity-50").user_keypoints()


class _Counting:
    """A predictor that counts its calls (and forwards them to a real one)."""

    def __init__(self, inner) -> None:
        self.inner, self.calls = inner, 0
        self.history_len, self.future_len = inner.history_len, inner.future_len

    def predict(self, history: np.ndarray) -> np.ndarray:
        self.calls += 1
        return self.inner.predict(history)


@pytest.mark.parametrize("every", [1, 25])
def test_forecast_is_made_every_predict_every_steps_and_held_between(every: int):
    """The forecast is refreshed at reset and every ``predict_every`` steps; between
    ticks the observation holds the latest one while the history moves on."""
    from simenv.perception.loop import load_predictor

    counting = _Counting(load_predictor("constant-velocity-50"))
    env = InteractionRoomEnv(gestures=[WAVE], predictor=counting, predict_every=every)
    first, _ = env.reset(seed=0)
    futures, histories = [first["user_future"]], [first["user_history"]]
    for _ in range(30):
        obs, *_ = env.step(0)
        futures.append(obs["user_future"])
        histories.append(obs["user_history"])
    assert counting.calls == 1 + 30 // every
    changed = [k for k in range(1, 31) if not np.array_equal(futures[k], futures[k - 1])]
    moved = [k for k in range(1, 31) if not np.array_equal(histories[k], histories[k - 1])]
    assert moved and set(changed) <= {k for k in moved if k % every == 0}
    if every > 1:
        assert changed == [k for k in (25,) if k in moved]
    with pytest.raises(SimenvError, match="predict_every"):
        InteractionRoomEnv(gestures=[WAVE], predictor=counting, predict_every=0)


def test_session_recipe_as_the_user(shared_data):
    """A bundled recipe (real UTKinect idle + wave + idle) is an env session: the wave is
    labelled from its onset in index.csv."""
    env = InteractionRoomEnv("utkinect-s02-e01-wave", predictor="constant-velocity-50",
                             data=shared_data)
    (wave,) = env.session.gestures
    env.reset(seed=0)
    seen = []
    for _ in range(int(wave.end_s * PERCEPTION_FPS) + 2):
        *_, info = env.step(0)
        seen.append(info["gesture"])
    first = seen.index("wave")
    assert abs((first + 1) / PERCEPTION_FPS - wave.onset_s) <= 1 / PERCEPTION_FPS + 1e-9
    assert seen[-1] is None
    # The recording's sensor, placed with its subject: as far from the user as in the
    # recording, in front of them (a UTKinect subject faces the sensor).
    track = env.track
    ahead = track.observer[:2] - track.qpos[0, :2]
    assert np.linalg.norm(ahead) == pytest.approx(np.linalg.norm(track.result.qpos[0, :2]))
    yaw = np.deg2rad(env.scenario.user.yaw_deg)
    assert ahead @ [np.cos(yaw), np.sin(yaw)] > 0.9 * np.linalg.norm(ahead)


@pytest.mark.skipif("predictor-gesture-25-50" not in simenv.models.available(),
                    reason="shipped gesture forecaster absent")
def test_the_forecast_is_told_where_the_recordings_sensor_stands(shared_data):
    env = InteractionRoomEnv("utkinect-s02-e01-wave", data=shared_data)
    assert env.predictor.uses_observer and env.track.observer is not None
    obs, _ = env.reset(seed=0)
    history = env.user_keypoints()
    np.testing.assert_allclose(obs["user_future"],
                               env.predictor.predict(history, env.track.observer), atol=1e-6)
    assert not np.allclose(obs["user_future"], env.predictor.predict(history), atol=1e-3)
    # A recording that is not a depth sensor's (the bundled CMU walk) has no observer.
    assert InteractionRoomEnv(gestures=[WAVE]).track.observer is None


def test_bow_back_is_scored_by_the_bow_meter():
    """A labelled bow (the user standing still, 0.5 s of the bundled walk): the agent bows
    back seated, and the environment measures it with Room.bow_meter (head dipped >= 15
    deg while facing the user, then back up), not with the greeting's raised hand."""
    short = simenv.load(asset_path(WALK)).slice(0, 60)
    env = InteractionRoomEnv(short, gestures=[GestureEvent("bow", 0.0, 0.4)],
                             predictor="constant-velocity-50")
    infos = _run(env, {2: env.reactions.index("bow_back")})
    (entry,) = env.log
    assert entry["reaction"] == "bow_back" and entry["started"] is True
    assert entry["success"] is True and entry["dip_max_deg"] >= 15.0
    assert entry["facing_deg_min"] < 30.0
    assert sum(i["reward_terms"].get("success", 0.0) for i in infos) == SUCCESS


def test_a_walking_agent_that_falls_ends_its_chain_with_the_fall_reported():
    """``cold`` in the discomfort scenario starts close_window: stand up (no help), then
    the steps on the agent's own legs. A shove on the pelvis during the walk (the test's
    own outside force) topples it: the help is measured on those steps (nothing else ever
    pushes: 0 N before), the walk stage's outcome says it fell, and the chain stops there
    with the fall named instead of walking on or acting from the floor."""
    short = simenv.load(asset_path(WALK)).slice(0, 60)
    env = InteractionRoomEnv(short, gestures=[GestureEvent("cold", 0.2, 0.5)],
                             scenario="discomfort", predictor="constant-velocity-50")
    env.reset(seed=0)
    act = env.reactions.index("close_window")
    pelvis = env.room.model.body("agent/pelvis").id
    decide, k, truncated, helps, walking = int(round(0.3 * PERCEPTION_FPS)), 0, False, [], 0
    while not truncated and not (env.log and env.log[0]["success"] is not None):
        stages = env.log[0].get("stages", []) if env.log else []
        walking += bool(stages) and stages[-1]["stage"] == "walk"
        # 1 s into the walk, a 0.5-s shove sideways
        shove = 25 <= walking < 38
        env.data.xfrc_applied[pelvis, :3] = [0.0, 500.0, 0.0] if shove else 0.0
        *_, truncated, _ = env.step(act if k == decide else 0)
        helps.append((shove, env.agent_assistance_n()))
        k += 1
    (entry,) = env.log
    names = [s["stage"] for s in entry["stages"]]
    assert names == ["stand_up", "walk"]  # stopped at the fall: no act, no return
    stand, walk = entry["stages"]
    assert "outcome" not in stand and "assistance" not in stand
    assert walk["outcome"]["fell"] and not walk["outcome"]["success"]
    assert entry["fell"] is True and entry["success"] is False
    assert entry["failed_stage"].startswith("walk: the agent fell")
    assert entry["returned"] is False
    assert walk["assistance"]["max_n"] == pytest.approx(500.0)  # the shove, measured
    assert all(h == 0.0 for shoved, h in helps if not shoved)
    assert walk["duration_s"] > walk["assistance"]["steps"] * env.model.opt.timestep


class _ReadsWave:
    """Stub classifier: always reads "wave" with probability 0.95."""

    labels = ("wave", "idle")
    joint_names = GESTURE15_JOINTS

    def classify(self, window: np.ndarray, valid: np.ndarray) -> np.ndarray:
        return np.array([0.95, 0.05])


def test_room_agent_decides_in_the_environment(env: InteractionRoomEnv):
    """The room's agent bound to the environment: its actions, the recording's length and
    sensor (none for the CMU walk); playing it, its first tick (0.96 s) starts a greeting,
    logged by the environment. A loop reading more history than observed is refused."""
    agent = env.room_agent(PerceptionLoop(_ReadsWave()))
    assert agent.reactions == env.reactions and agent.recorded_frames == env.n_frames
    assert agent.observer is None and env.room_agent(PerceptionLoop(_ReadsWave()),
                                                     replay=False).recorded_frames is None
    obs, _ = env.reset(seed=0)
    for _ in range(26):
        obs, *_ = env.step(agent.act(obs))
    (entry,) = env.log
    assert (entry["reaction"], entry["t_decision"], entry["started"]) == ("greet", 0.96, True)
    assert [t.step for t in agent.ticks] == [24]
    with pytest.raises(SimenvError, match="history_frames=75") as err:
        env.room_agent(PerceptionLoop(_ReadsWave(), context_frames=(50, 75)))
    assert err.value.field == "history_frames"

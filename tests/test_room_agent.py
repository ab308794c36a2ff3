"""The room's agent: perceive -> decide -> act, its ticks, cooldown and actions."""

from __future__ import annotations

import numpy as np
import pytest

import simenv.models
from simenv.core.errors import SimenvError
from simenv.data.gestures import GESTURE15_JOINTS
from simenv.perception.loop import PerceptionLoop, Stage
from simenv.perception.room_agent import COOLDOWN_S, RoomAgent
from simenv.room.scenario import load_scenario

DEFAULT = load_scenario("default")
#: An environment's actions: the no-op first, then reactions.
ACTIONS = (None, "greet", "close_window")


class _Reads:
    """Stub classifier: always reads ``label`` with probability 0.95."""

    joint_names = GESTURE15_JOINTS

    def __init__(self, label: str, other: str = "idle") -> None:
        self.labels = (label, other)

    def classify(self, window: np.ndarray, valid: np.ndarray) -> np.ndarray:
        return np.array([0.95, 0.05])


@pytest.fixture(scope="module")
def walk_keypoints() -> np.ndarray:
    """(T, 21, 3) the bundled real CMU walk as the room's user, 25 fps."""
    from simenv.assets import WALK, asset_path
    from simenv.io import load
    from simenv.room.session import Session, user_track

    return user_track(Session(load(asset_path(WALK)))).keypoints.astype(np.float32)


def _play(agent: RoomAgent, keypoints: np.ndarray, steps: int) -> list[int]:
    """The agent's actions over ``steps`` steps of a user replaying ``keypoints`` (holding
    the first frame before them, the last after), history as the environment observes it."""
    need = agent.history_frames
    held = np.concatenate([np.repeat(keypoints[:1], need - 1, axis=0), keypoints,
                           np.repeat(keypoints[-1:], steps, axis=0)])
    return [agent.act({"user_history": held[s:s + need]}) for s in range(steps)]


def test_agent_acts_at_its_ticks_once_per_cooldown(walk_keypoints):
    """A live agent whose loop always reads "wave": greet at the first tick (0.96 s),
    nothing within the cooldown, greet again at the first tick 3 s later (3.96 s); every
    tick is kept, the decided ones with their reaction."""
    agent = RoomAgent(PerceptionLoop(_Reads("wave")), DEFAULT.behaviour, ACTIONS)
    actions = _play(agent, walk_keypoints, 125)
    greet = ACTIONS.index("greet")
    assert [s for s, a in enumerate(actions) if a] == [24, 99]
    assert {actions[24], actions[99]} == {greet}
    assert [t.step for t in agent.ticks] == [24, 49, 74, 99, 124]
    assert [t.reaction for t in agent.ticks] == ["greet", None, None, "greet", None]
    assert all(t.perception.stage is Stage.REAL and t.perception.label == "wave"
               for t in agent.ticks)
    assert agent.ticks[3].perception.t_s == pytest.approx(3.96) and COOLDOWN_S == 3.0
    assert agent.last is agent.ticks[-1]
    agent.reset()  # a new episode: clock, cooldowns and ticks start over
    assert agent.last is None and _play(agent, walk_keypoints, 25)[24] == greet


def test_agent_decides_only_reactions_of_its_scenario(walk_keypoints):
    """"walk" keeps the agent working, a label outside the vocabulary never triggers, a
    reaction the environment lacks is the no-op."""
    loop = PerceptionLoop(_Reads("walk"))
    for label, actions in (("walk", ACTIONS), ("juggle", ACTIONS), ("wave", (None,))):
        agent = RoomAgent(PerceptionLoop(_Reads(label)), DEFAULT.behaviour, actions)
        assert _play(agent, walk_keypoints, 25) == [0] * 25
        assert agent.last.perception.label == label
    assert RoomAgent(loop, DEFAULT.behaviour, (None,)).decide(
        loop.perceive(1.0, walk_keypoints[:25])) is None


def test_replayed_recording_is_perceived_while_it_plays():
    """A 40-frame recording: ticks end at steps 24 and 49 (whose real second still holds
    recorded frames), none at 74 (the held last pose only); a live user: every second."""
    loop = PerceptionLoop(_Reads("wave"))
    replay = RoomAgent(loop, DEFAULT.behaviour, ACTIONS, recorded_frames=40)
    assert [s for s in range(100) if replay.due(s)] == [24, 49]
    live = RoomAgent(loop, DEFAULT.behaviour, ACTIONS)
    assert [s for s in range(100) if live.due(s)] == [24, 49, 74, 99]


def test_bad_agents_and_observations_fail_clearly(walk_keypoints):
    loop = PerceptionLoop(_Reads("wave"), context_frames=(50,))
    with pytest.raises(SimenvError, match="no-op action None") as err:
        RoomAgent(loop, DEFAULT.behaviour, ("greet",))
    assert err.value.field == "reactions"
    with pytest.raises(SimenvError, match="cooldown_s"):
        RoomAgent(loop, DEFAULT.behaviour, ACTIONS, cooldown_s=-1.0)
    agent = RoomAgent(loop, DEFAULT.behaviour, ACTIONS)
    short = {"user_history": walk_keypoints[:25]}  # the loop reads 50 frames
    with pytest.raises(SimenvError, match="history_frames=50"):
        for _ in range(25):
            agent.act(short)
    agent.reset()
    with pytest.raises(SimenvError, match="user_history"):
        for _ in range(25):
            agent.act({"objects": np.zeros(5, np.float32)})


@pytest.mark.skipif(not {"gesture-tcn-ensemble", "predictor-gesture-25-50"}
                    <= set(simenv.models.available()),
                    reason="shipped gesture-tcn-ensemble / predictor-gesture-25-50 absent")
def test_agent_greets_a_real_wave_in_the_room(shared_data):
    """A real UTKinect session (subject 2: idle, waveHands, idle) replayed as the room's
    user, the agent on the shipped models reading the avatar's keypoints: it greets, first
    within the labelled wave (to the recording's sample), and not twice within the
    cooldown."""
    from simenv.perception.loop import default_classifier, load_predictor
    from simenv.room.session import Session, user_track

    session = Session.load("utkinect-s02-e01-wave", data=shared_data)
    track = user_track(session, DEFAULT)
    loop = PerceptionLoop(default_classifier(DEFAULT.behaviour.vocabulary), load_predictor())
    agent = RoomAgent(loop, DEFAULT.behaviour, ACTIONS, observer=track.observer,
                      recorded_frames=len(track.keypoints))
    actions = _play(agent, track.keypoints.astype(np.float32), len(track.keypoints) + 50)
    greets = [s / 25.0 for s, a in enumerate(actions) if a == ACTIONS.index("greet")]
    (wave,) = session.gestures
    sample_s = 1.0 / session.motion.fps
    assert greets and wave.onset_s - sample_s < greets[0] <= wave.end_s
    assert np.all(np.diff(greets) >= COOLDOWN_S)
    assert {t.perception.stage for t in agent.ticks if t.reaction} == {Stage.REAL}

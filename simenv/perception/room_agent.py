"""The room's agent: perceive -> decide -> act, one object wherever the room runs.

The rehearsal (:func:`simenv.envs.rehearsal.rehearse`, ``simenv rehearse --agent scripted``),
the Gymnasium and PettingZoo environments (:meth:`simenv.envs.interaction_room.
InteractionRoomEnv.room_agent`, :meth:`simenv.envs.room_parallel.RoomParallelEnv.room_agent`)
and the benchmarks (``benchmarks/bench_perception.py``) all run the agent through this
class. Each environment step, :meth:`RoomAgent.act` is given the environment's observation
and returns the action the environment executes; at the ticks of its perception loop
(:meth:`RoomAgent.due`: one a second) it

1. **perceives** (:meth:`RoomAgent.perceive`): the
   :class:`~simenv.perception.loop.PerceptionLoop` reads the user's keypoints
   (``observation["user_history"]``, (H, 21, 3) m in the room) -- its real windows, and
   when they are not confident the real second continued by the forecaster, told where the
   observer stands --, and decides a gesture label by the room's one decision rule
   (:func:`simenv.perception.loop.decide`; the stage that decided:
   :class:`~simenv.perception.loop.Stage`);
2. **decides** (:meth:`RoomAgent.decide`) the scenario's reaction to the label
   (:meth:`simenv.room.scenario.Behaviour.reaction_for`), none for ``keep``, with a
   refractory period per label (:data:`COOLDOWN_S`) so that one gesture triggers once;
3. **acts**: the reaction's index in the environment's actions
   (:attr:`simenv.envs.interaction_room.InteractionRoomEnv.reactions`; 0, the no-op, when
   nothing is decided). The environment carries it out with the skills of
   :mod:`simenv.agents` (stand, walk, reach, ...), in simulation.

A replayed recording is perceived while its frames play: no tick whose real second lies
wholly in the pose the user holds after the recording's end (``recorded_frames``; that
still pose is not the user's motion). Every tick is kept in :attr:`RoomAgent.ticks` for
logs and summaries.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from simenv.core.errors import SimenvError
from simenv.perception.loop import Perception, PerceptionLoop
from simenv.room.scenario import Behaviour

#: A decided label does not trigger its reaction again within this time, s.
COOLDOWN_S = 3.0


@dataclass(frozen=True)
class Tick:
    """One perception tick of the agent and what it decided.

    Attributes:
        step: the environment step (0-based frame index) the tick ended.
        perception: what the loop read and decided (:class:`~simenv.perception.loop.Perception`).
        reaction: the reaction started (None: no label decided, ``keep``, or in cooldown).
    """

    step: int
    perception: Perception
    reaction: str | None


class RoomAgent:
    """The room's agent (module docstring): perceive -> decide -> act.

    Args:
        loop: the perception loop (classifier, forecaster, windows, threshold, ticks).
        behaviour: the scenario's gesture -> reaction map; labels outside its vocabulary
            never trigger.
        reactions: the environment's actions, index 0 the no-op (None), then one reaction
            name each (:attr:`simenv.envs.interaction_room.InteractionRoomEnv.reactions`).
        observer: (3,) world position of the observer the user faces, m, told to a
            forecaster that uses it (a recording's sensor; None: unknown).
        recorded_frames: frames of a replayed recording (None: a live user).
        cooldown_s: refractory period of a decided label, s.
        fps: environment steps per second (the perception rate), Hz.

    Raises:
        SimenvError: ``reactions`` without the no-op first, a cooldown or rate that is not
            positive.
    """

    def __init__(self, loop: PerceptionLoop, behaviour: Behaviour,
                 reactions: Sequence[str | None], *, observer: np.ndarray | None = None,
                 recorded_frames: int | None = None, cooldown_s: float = COOLDOWN_S,
                 fps: float = 25.0) -> None:
        reactions = tuple(reactions)
        if not reactions or reactions[0] is not None:
            raise SimenvError(f"reactions must start with the no-op action None; got "
                              f"{list(reactions)}", field="reactions")
        if not cooldown_s >= 0 or not fps > 0:
            raise SimenvError(f"cooldown_s must be >= 0 s and fps > 0 Hz; got {cooldown_s} "
                              f"and {fps}", field="cooldown_s" if not cooldown_s >= 0
                              else "fps")
        self.loop, self.behaviour, self.reactions = loop, behaviour, reactions
        self.observer = None if observer is None else np.asarray(observer, dtype=np.float64)
        self.recorded_frames = None if recorded_frames is None else int(recorded_frames)
        self.cooldown_s, self.fps = float(cooldown_s), float(fps)
        self.ticks: list[Tick] = []
        self._step = 0
        self._last: dict[str, float] = {}

    @property
    def history_frames(self) -> int:
        """Frames of user history a tick reads (:attr:`PerceptionLoop.history_frames`)."""
        return self.loop.history_frames

    @property
    def last(self) -> Tick | None:
        """The latest tick (None before the first)."""
        return self.ticks[-1] if self.ticks else None

    def reset(self) -> None:
        """A new episode: the clock back to step 0, no cooldown, no tick."""
        self._step = 0
        self._last.clear()
        self.ticks.clear()

    def due(self, step: int) -> bool:
        """Whether environment step ``step`` (0-based) is a perception tick: the loop's
        period (:meth:`PerceptionLoop.due`), while a replayed recording still fills part of
        the real second."""
        playing = (self.recorded_frames is None
                   or step - self.loop.real_frames < self.recorded_frames - 1)
        return self.loop.due(step) and playing

    def perceive(self, history: np.ndarray, t_s: float) -> Perception:
        """Step 1: the loop's tick on ``history`` ((H, 21, 3) canonical keypoints, m)
        ending at ``t_s`` (s), told :attr:`observer`."""
        return self.loop.perceive(t_s, history, self.observer)

    def decide(self, perception: Perception) -> str | None:
        """Step 2: the scenario's reaction to the decided label, or None (no label, a label
        outside the vocabulary, ``keep``, or the label's reaction within
        :attr:`cooldown_s` of its last start)."""
        label, t = perception.label, perception.t_s
        if label is None or label not in self.behaviour.vocabulary:
            return None
        reaction = self.behaviour.reaction_for(label).name
        if reaction == "keep" or t - self._last.get(label, -np.inf) < self.cooldown_s:
            return None
        self._last[label] = t
        return reaction

    def act(self, observation: Mapping[str, np.ndarray]) -> int:
        """One environment step: at a tick, perceive ``observation["user_history"]``,
        decide, and return the reaction's action index; 0 (no-op) otherwise. Called once
        per step from :meth:`reset` on: the agent counts the steps (time = step / fps).

        Raises:
            SimenvError: an observation without ``user_history``, or a history shorter than
                :attr:`history_frames` (the environment observes too little).
        """
        step = self._step
        self._step += 1
        if not self.due(step):
            return 0
        if "user_history" not in observation:
            raise SimenvError("the observation has no 'user_history' (the user's keypoints); "
                              f"got keys {sorted(observation)}", field="observation")
        history = np.asarray(observation["user_history"])
        if len(history) < self.history_frames:
            raise SimenvError(f"user_history has {len(history)} frames; the agent's "
                              f"perception reads {self.history_frames} (build the environment "
                              f"with history_frames={self.history_frames})",
                              field="user_history")
        perception = self.perceive(history, step / self.fps)
        reaction = self.decide(perception)
        self.ticks.append(Tick(step, perception, reaction))
        return self.reactions.index(reaction) if reaction in self.reactions else 0


__all__ = ["COOLDOWN_S", "RoomAgent", "Tick"]

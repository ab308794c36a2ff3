"""PettingZoo ``ParallelEnv`` of the room: agents ``user`` and ``agent``.

The ``agent`` is exactly :class:`~simenv.envs.interaction_room.InteractionRoomEnv`'s decision
maker (same observation, action and reward); :meth:`RoomParallelEnv.room_agent` gives the
room's own agent (:class:`~simenv.perception.room_agent.RoomAgent`: perceive -> decide ->
act) to play it, ``actions["agent"] = agent.act(observations["agent"])``. The ``user``
either replays the session (``user="replay"``: its action space is ``Discrete(1)``, the
only action is "go on") or is a policy (``user="policy"``: a ``Box`` of the user avatar's
hinge angles, radians within their joint ranges, applied kinematically each step with the
pelvis held where the scenario places the user).

The user observes ``self`` (K, 3), its own keypoints, ``agent`` (K, 3), the agent's
keypoints, and ``objects`` (5,), the object levels, all float32 in the room frame. Its
reward is the agent's (cooperative: the user is served when the agent reacts well). Both
agents' episodes end together; labelled gestures come from the session (a user policy
performs unlabelled motion).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from simenv.core.errors import SimenvError
from simenv.envs.interaction_room import OBJECTS, InteractionRoomEnv
from simenv.perception.loop import PerceptionLoop
from simenv.perception.room_agent import RoomAgent

AGENTS = ("user", "agent")


class RoomParallelEnv(ParallelEnv):
    """The room with two agents (see the module docstring).

    Args:
        user: ``"replay"`` or ``"policy"``.
        **kwargs: passed to :class:`~simenv.envs.interaction_room.InteractionRoomEnv`
            (``session``, ``gestures``, ``scenario``, ``render_mode``, ...).
    """

    metadata = {"name": "simenv_room_v0", "render_modes": ["rgb_array"], "render_fps": 25}

    def __init__(self, user: str = "replay", **kwargs: Any) -> None:
        if user not in ("replay", "policy"):
            raise SimenvError(f"user must be 'replay' or 'policy'; got {user!r}", field="user")
        self.user_mode = user
        self.env = InteractionRoomEnv(**kwargs)
        self.render_mode = self.env.render_mode
        self.possible_agents = list(AGENTS)
        self.agents: list[str] = []
        room = self.env.room
        K = len(room.user.keypoint_names)
        inf = np.float32(np.inf)
        self._spaces = {
            "agent": (self.env.observation_space, self.env.action_space),
            "user": (spaces.Dict({
                "self": spaces.Box(-inf, inf, (K, 3), np.float32),
                "agent": spaces.Box(-inf, inf, (K, 3), np.float32),
                "objects": spaces.Box(0.0, 1.0, (len(OBJECTS),), np.float32),
            }), spaces.Discrete(1) if user == "replay" else spaces.Box(
                room.user.joint_limits[:, 0].astype(np.float32),
                room.user.joint_limits[:, 1].astype(np.float32), dtype=np.float32)),
        }
        self._root = self.env.track.qpos[0, :7].copy()

    def observation_space(self, agent: str) -> spaces.Space:
        return self._spaces[self._check(agent)][0]

    def action_space(self, agent: str) -> spaces.Space:
        return self._spaces[self._check(agent)][1]

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self.agents = list(AGENTS)
        return {"agent": obs, "user": self._user_obs()}, {"agent": info, "user": {}}

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise SimenvError("step() called before reset() (or after the episode ended); "
                              "call reset() first")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise SimenvError(f"no action for {missing}", field="actions")
        user_qpos = None
        if self.user_mode == "policy":
            angles = np.asarray(actions["user"], dtype=np.float64)
            space = self._spaces["user"][1]
            if angles.shape != space.shape or not np.isfinite(angles).all():
                raise SimenvError(f"user action must be {space.shape} finite hinge angles; "
                                  f"got shape {angles.shape}", field="user")
            user_qpos = self.env.track.qpos[0].copy()
            user_qpos[:7] = self._root
            h = self.env.room.user
            user_qpos[h.hinge_qpos] = np.clip(angles, h.joint_limits[:, 0],
                                              h.joint_limits[:, 1])
        elif actions["user"] != 0:
            raise SimenvError(f"a replayed user has one action, 0; got {actions['user']!r}",
                              field="user")
        a = np.asarray(actions["agent"])
        if a.shape != () or a.dtype.kind not in "iu" or not self.env.action_space.contains(
                int(a)):
            raise SimenvError(f"agent action must be one integer in "
                              f"[0, {self.env.action_space.n}); got {actions['agent']!r}",
                              field="agent")
        obs, reward, terminated, truncated, info = self.env.advance(int(a), user_qpos)
        observations = {"agent": obs, "user": self._user_obs()}
        rewards = {"agent": reward, "user": reward}
        terminations = dict.fromkeys(AGENTS, terminated)
        truncations = dict.fromkeys(AGENTS, truncated)
        infos = {"agent": info, "user": {}}
        if terminated or truncated:
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def room_agent(self, loop: PerceptionLoop) -> RoomAgent:
        """The room's agent for the ``agent`` side, perceiving with ``loop``
        (:meth:`~simenv.envs.interaction_room.InteractionRoomEnv.room_agent`; a replayed
        user's recording sensor as the forecaster's observer, a policy user's unknown).
        Reset it with the environment; one ``act`` per step."""
        return self.env.room_agent(loop, replay=self.user_mode == "replay")

    def render(self) -> np.ndarray | None:
        return self.env.render()

    def close(self) -> None:
        self.env.close()

    def _check(self, agent: str) -> str:
        if agent not in AGENTS:
            raise SimenvError(f"unknown agent {agent!r}; agents are {list(AGENTS)}",
                              field="agent")
        return agent

    def _user_obs(self) -> dict[str, np.ndarray]:
        d, room = self.env.data, self.env.room
        return {"self": d.site_xpos[room.user_sites].astype(np.float32),
                "agent": d.site_xpos[room.agent_sites].astype(np.float32),
                "objects": self.env.object_levels()}


def parallel_env(**kwargs: Any) -> RoomParallelEnv:
    """PettingZoo-style constructor of :class:`RoomParallelEnv`."""
    return RoomParallelEnv(**kwargs)


__all__ = ["AGENTS", "RoomParallelEnv", "parallel_env"]

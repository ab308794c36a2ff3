"""Gymnasium environments of simenv, registered on import.

* ``simenv/HumanoidTrack-v0`` -- :class:`~simenv.envs.humanoid_track.HumanoidTrackEnv`:
  low-level control, PD targets of a subject-fitted humanoid tracking a reference motion.
* ``simenv/InteractionRoom-v0`` -- :class:`~simenv.envs.interaction_room.InteractionRoomEnv`:
  the room's agent decides its reactions to a recorded user's gestures.

PettingZoo (not registered; construct it): :class:`~simenv.envs.room_parallel.RoomParallelEnv`,
the room with agents ``user`` (replayed or a policy) and ``agent``.

Example::

    import gymnasium as gym
    import simenv.envs  # registers the ids

    env = gym.make("simenv/HumanoidTrack-v0", motion="cmu_02_01_walk.bvh")
"""

from __future__ import annotations

import gymnasium

_ENVS = {
    "simenv/HumanoidTrack-v0": "simenv.envs.humanoid_track:HumanoidTrackEnv",
    "simenv/InteractionRoom-v0": "simenv.envs.interaction_room:InteractionRoomEnv",
}

for _id, _entry in _ENVS.items():
    if _id not in gymnasium.registry:
        gymnasium.register(id=_id, entry_point=_entry)

__all__ = ["HumanoidTrackEnv", "InteractionRoomEnv", "RoomParallelEnv"]


def __getattr__(name: str) -> object:
    # Lazy: importing the package (to register) loads no model and no heavy module.
    if name == "HumanoidTrackEnv":
        from simenv.envs.humanoid_track import HumanoidTrackEnv

        return HumanoidTrackEnv
    if name == "InteractionRoomEnv":
        from simenv.envs.interaction_room import InteractionRoomEnv

        return InteractionRoomEnv
    if name == "RoomParallelEnv":
        from simenv.envs.room_parallel import RoomParallelEnv

        return RoomParallelEnv
    raise AttributeError(name)

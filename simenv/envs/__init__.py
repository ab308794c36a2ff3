"""Gymnasium environments of simenv, registered on import.

* ``simenv/HumanoidTrack-v0`` -- :class:`~simenv.envs.humanoid_track.HumanoidTrackEnv`:
  low-level control, PD targets of a subject-fitted humanoid tracking a reference motion.

Example::

    import gymnasium as gym
    import simenv.envs  # registers the ids

    env = gym.make("simenv/HumanoidTrack-v0", motion="cmu_02_01_walk.bvh")
"""

from __future__ import annotations

import gymnasium

_ENVS = {
    "simenv/HumanoidTrack-v0": "simenv.envs.humanoid_track:HumanoidTrackEnv",
}

for _id, _entry in _ENVS.items():
    if _id not in gymnasium.registry:
        gymnasium.register(id=_id, entry_point=_entry)

__all__ = ["HumanoidTrackEnv"]


def __getattr__(name: str) -> object:
    # Lazy: importing the package (to register) does not build any model.
    if name == "HumanoidTrackEnv":
        from simenv.envs.humanoid_track import HumanoidTrackEnv

        return HumanoidTrackEnv
    raise AttributeError(name)

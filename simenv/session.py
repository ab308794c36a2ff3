"""Interaction sessions: a recording of the user, optionally with labelled gesture onsets,
put into a room as the user avatar's trajectory.

A session is any loadable single-person motion (the gesture sets' 2-3 s clips included).
:func:`user_track` resamples it to the perception rate (25 fps, the thesis's), retargets it
onto a body fitted to the subject and places it where the scenario puts the user; the room
is then built with that body (:meth:`UserTrack.room`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from simenv.assets import asset_path, list_assets
from simenv.errors import SimenvError
from simenv.io.loader import load
from simenv.motion import Motion
from simenv.retarget import RetargetResult, retarget
from simenv.room import Room, place_on_floor
from simenv.scenario import Scenario, load_scenario

#: Perception rate of the room, frames/s (user history and predictions are at this rate).
PERCEPTION_FPS = 25.0


@dataclass(frozen=True)
class GestureEvent:
    """A labelled gesture of the session: ``label`` between ``onset_s`` and ``end_s``."""

    label: str
    onset_s: float
    end_s: float

    def __post_init__(self) -> None:
        if not (np.isfinite(self.onset_s) and np.isfinite(self.end_s)
                and 0.0 <= self.onset_s <= self.end_s):
            raise SimenvError(f"gesture {self.label!r}: need 0 <= onset_s <= end_s; got "
                              f"{self.onset_s}, {self.end_s}", field="gestures")


@dataclass(frozen=True)
class Session:
    """A recording of the user and its labelled gestures (possibly none)."""

    motion: Motion
    gestures: tuple[GestureEvent, ...] = ()

    @classmethod
    def load(cls, source: str | os.PathLike[str] | Motion,
             gestures: Sequence[GestureEvent] = ()) -> Session:
        """A session from a motion file, a bundled asset name or a Motion."""
        if isinstance(source, Motion):
            return cls(source, tuple(gestures))
        name = os.fspath(source)
        path = asset_path(name) if name in list_assets() else Path(name)
        if not path.exists():
            raise SimenvError(f"no session file {name!r} and no bundled asset of that name",
                              source=name)
        motion = load(path)
        if not isinstance(motion, Motion):
            raise SimenvError(f"a session is one person; {name!r} holds two", source=name)
        return cls(motion, tuple(gestures))


@dataclass(frozen=True)
class UserTrack:
    """The user's trajectory in the room at :data:`PERCEPTION_FPS`.

    Attributes:
        qpos: (T, nq_user) configurations of ``result.humanoid``, placed in the room.
        keypoints: (T, K, 3) the avatar's canonical keypoints in the room, m.
        result: the retargeting result (fitted body, residuals).
        scenario: the scenario it was placed for.
    """

    qpos: np.ndarray
    keypoints: np.ndarray
    result: RetargetResult
    scenario: Scenario

    def room(self) -> Room:
        """The scenario's room with this user's fitted body."""
        return Room(self.scenario, user=self.result.humanoid.dims)


def user_track(session: Session, scenario: Scenario | str = "default") -> UserTrack:
    """Retarget the session's motion at :data:`PERCEPTION_FPS` and place it in the room."""
    scenario = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    vocab = scenario.behaviour.vocabulary
    for g in session.gestures:
        if g.label not in vocab:
            raise SimenvError(f"gesture label {g.label!r} is not in the vocabulary of "
                              f"scenario {scenario.name!r}: {list(vocab)}", field="gestures")
    m = session.motion
    result = retarget(m.resample(PERCEPTION_FPS) if m.fps != PERCEPTION_FPS else m)
    u = scenario.user
    qpos = place_on_floor(result.qpos, u.position, np.deg2rad(u.yaw_deg))
    h = result.humanoid
    data = mujoco.MjData(h.model)
    kp = np.empty((len(qpos), len(h.site_ids), 3))
    for t, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(h.model, data)
        kp[t] = data.site_xpos[h.site_ids]
    return UserTrack(qpos, kp, result, scenario)


__all__ = ["PERCEPTION_FPS", "GestureEvent", "Session", "UserTrack", "user_track"]

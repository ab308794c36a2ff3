"""``simenv export``: a retargeted motion or a room scene as glTF/GLB for any 3D viewer.

Three things can be exported (:mod:`simenv.io.gltf` writes the file):

* a motion file or two-person folder: retargeted (:func:`simenv.body.retarget.retarget`) onto
  bodies fitted to its bone lengths; the humanoids' capsules and boxes over time, one
  animation at the clip's frame rate (both people in one scene for a pair);
* a scenario (bundled name or TOML file, user furniture meshes included): the furnished
  room, static, with the agent seated and the user standing where the scenario puts them;
* both: the room with the motion played by the user (retargeted at
  :data:`simenv.room.session.PERCEPTION_FPS` and placed as :meth:`simenv.room.room.Room.place_user`
  does).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from simenv.body.retarget import retarget
from simenv.core.errors import SimenvError
from simenv.core.joint_map import JointMapSource
from simenv.core.motion import Interaction, Motion
from simenv.io.gltf import body_poses, write_gltf
from simenv.io.loader import load_one
from simenv.room.room import Room
from simenv.room.scenario import load_scenario
from simenv.room.session import PERCEPTION_FPS


def export_result(result: Any, path: str | os.PathLike[str], *, stride: int = 1) -> Path:
    """Write a retargeting result (one person or a pair) as an animated glTF/GLB.

    Args:
        result: :class:`~simenv.body.retarget.RetargetResult` or
            :class:`~simenv.body.retarget.InteractionRetargetResult`.
        path: ``.glb`` or ``.gltf``.
        stride: keep every ``stride``-th frame (the animation keeps real time).
    """
    scene = getattr(result, "scene", None)
    model = scene.model if scene is not None else result.humanoid.model
    qpos = np.asarray(result.qpos)[::stride]
    return write_gltf(model, path, poses=body_poses(model, qpos), fps=result.fps / stride,
                      name=getattr(result, "name", None))


def export_room(scenario: Any, path: str | os.PathLike[str], motion: Motion | None = None,
                *, stride: int = 1) -> Path:
    """Write a scenario's room as glTF/GLB, with ``motion`` (one person) played by the
    user when given.

    Args:
        scenario: a :class:`~simenv.room.scenario.Scenario`, bundled name or TOML path.
        path: ``.glb`` or ``.gltf``.
        motion: the user's motion, or None for the static room in its initial state.
        stride: keep every ``stride``-th frame of the retargeted motion.
    """
    scenario = scenario if not isinstance(scenario, (str, os.PathLike)) \
        else load_scenario(scenario)
    if motion is None:
        room = Room(scenario)
        return write_gltf(room.model, path, data=room.make_data(), name=scenario.name)
    clip = motion.resample(PERCEPTION_FPS) if motion.fps != PERCEPTION_FPS else motion
    result = retarget(clip)
    room = Room(scenario, user=result.humanoid.dims)
    data = room.make_data()
    user = room.place_user(result.qpos)[::stride]
    agent = np.tile(data.qpos, (len(user), 1))
    poses = body_poses(room.model, agent, data,
                       before=lambda d, t: room.set_user_pose(d, user[t]))
    return write_gltf(room.model, path, poses=poses, fps=PERCEPTION_FPS / stride,
                      name=f"{scenario.name}: {motion.name}")


def export(paths: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str], *,
           scenario: str | os.PathLike[str] | None = None, stride: int = 1,
           joint_map: JointMapSource | None = None) -> Path:
    """The ``simenv export`` job: ``paths`` (a motion file or two-person recording, or
    a scenario TOML) and/or ``scenario`` to ``out`` (see the module docstring);
    ``joint_map`` as for :func:`simenv.io.loader.load`."""
    paths = [Path(p) for p in paths]
    if paths and paths[0].suffix.lower() == ".toml":
        if scenario is not None or len(paths) > 1:
            raise SimenvError("give one scenario, either as FILE or with --scenario",
                              source=paths[0])
        scenario, paths = paths[0], []
    if not paths:
        if scenario is None:
            raise SimenvError("nothing to export: give a motion file, a scenario TOML or "
                              "--scenario NAME")
        return export_room(scenario, out, stride=stride)
    clip = load_one(paths, **({} if joint_map is None else {"joint_map": joint_map}))
    if scenario is None:
        return export_result(retarget(clip), out, stride=stride)
    if isinstance(clip, Interaction):
        raise SimenvError("the room has one user: give a single-person motion with "
                          "--scenario", source=paths[0])
    return export_room(scenario, out, clip, stride=stride)


__all__ = ["export", "export_result", "export_room"]

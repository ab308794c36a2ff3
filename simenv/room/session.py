"""Interaction sessions: a recording of the user, optionally with labelled gesture onsets,
put into a room as the user avatar's trajectory.

A session is any loadable single-person motion (the gesture sets' 2-3 s clips included),
or a **session recipe**: a TOML file that cuts a labelled stretch out of a recording of the
shared corpus. :func:`user_track` resamples it to the perception rate (25 fps, the
thesis's), retargets it onto a body fitted to the subject and places it where the scenario
puts the user; the room is then built with that body (:meth:`UserTrack.room`).

Session recipes
---------------
The gesture recordings carry no open licence, so their frames cannot ship; the bundled
recipes (``assets/sessions/*.toml``, :func:`session_recipes`) say where to cut instead::

    [session]
    name = "utkinect-s02-e01-wave"
    source = "gestures/utkinect/joints/joints_s02_e01.txt"  # relative to the corpus root
    format = "utkinect"       # reader: "utkinect" or "auto" (simenv.io.load)
    fps = 15.0                # rate the reader puts the recording on, frames/s
    frame_clock_hz = 60.0     # units of the frame numbers below per second
    start_frame = 2550        # first and last frame number of the session (inclusive)
    end_frame = 3010

    [[gestures]]              # labelled gestures, frame numbers as in gestures/index.csv
    label = "wave"            # the room's vocabulary (simenv.data.gestures)
    source_label = "waveHands"
    start_frame = 2668
    end_frame = 2830

A frame number ``f`` is at ``t = (f - f_0) / frame_clock_hz`` s of the recording, ``f_0``
its first stored frame number (the UTKinect reader's clock, :mod:`simenv.io.utkinect`; for
a format without frame numbers ``f_0 = 0``). The session is the reader's frames
``ceil(t(start) fps) .. floor(t(end) fps)``; a gesture's ``onset_s`` / ``end_s`` are its
bounds' times from the session's first frame, clipped to the session. The corpus root is
``data``, else ``$SIMENV_SHARED_DATA``, else ``shared/data`` next to the repository
(:func:`shared_data_root`).
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from simenv.assets import asset_path, assets_root, list_assets
from simenv.body.retarget import RetargetResult, retarget
from simenv.core.config import shared_data_root
from simenv.core.errors import SimenvError
from simenv.core.joint_map import JointMapSource
from simenv.core.motion import Motion
from simenv.io import utkinect
from simenv.io.loader import load
from simenv.room.room import Room, place_on_floor, place_points
from simenv.room.scenario import Scenario, load_scenario

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

#: Perception rate of the room, frames/s (user history and predictions are at this rate).
PERCEPTION_FPS = 25.0
#: Sub-folder of the bundled assets holding the session recipes.
SESSIONS_DIR = "sessions"



def session_recipes() -> list[str]:
    """Names of the bundled session recipes (``assets/sessions/<name>.toml``), sorted."""
    folder = assets_root() / SESSIONS_DIR
    return sorted(p.stem for p in folder.glob("*.toml")) if folder.is_dir() else []


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
             gestures: Sequence[GestureEvent] = (), *,
             data: str | os.PathLike[str] | None = None,
             joint_map: JointMapSource | None = None) -> Session:
        """A session from a motion file, a bundled asset name, a session recipe (a
        ``.toml`` file or a bundled recipe name, :func:`session_recipes`; its recording is
        read from the corpus at ``data``, see :func:`shared_data_root`) or a Motion.
        ``gestures`` are added to a recipe's own; ``joint_map`` maps a motion file's joints
        (see :func:`simenv.io.loader.load`)."""
        if isinstance(source, Motion):
            return cls(source, tuple(gestures))
        name = os.fspath(source)
        if name in session_recipes():
            return cls.from_recipe(assets_root() / SESSIONS_DIR / f"{name}.toml", data,
                                   gestures)
        if name.lower().endswith(".toml"):
            return cls.from_recipe(name, data, gestures)
        path = asset_path(name) if name in list_assets() else Path(name)
        if not path.exists():
            raise SimenvError(f"no session file {name!r} and no bundled asset of that name",
                              source=name)
        motion = load(path, **({} if joint_map is None else {"joint_map": joint_map}))
        if not isinstance(motion, Motion):
            raise SimenvError(f"a session is one person; {name!r} holds two", source=name)
        return cls(motion, tuple(gestures))

    @classmethod
    def from_recipe(cls, recipe: str | os.PathLike[str],
                    data: str | os.PathLike[str] | None = None,
                    gestures: Sequence[GestureEvent] = ()) -> Session:
        """The session a recipe file describes (module docstring), read from the corpus
        at ``data`` (:func:`shared_data_root`), plus ``gestures``.

        Raises:
            SimenvError: unreadable recipe, a missing or wrong field (named), or the
                recording absent from the corpus (the message names the file and how to
                point at the corpus).
        """
        path = Path(recipe)
        if not path.is_file():
            raise SimenvError(f"no session recipe {os.fspath(recipe)!r} (bundled recipes: "
                              f"{', '.join(session_recipes()) or 'none'})", source=path)
        try:
            raw = tomllib.loads(path.read_text(encoding="utf-8"))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise SimenvError(f"session recipe is not valid TOML: {exc}", source=path) from None
        head = _table(raw, "session", path)
        src = _field(head, "session", "source", str, path)
        fmt = head.get("format", "auto")
        if fmt not in ("auto", "utkinect"):
            raise SimenvError(f"format {fmt!r}: expected 'auto' or 'utkinect'", source=path,
                              field="session.format")
        fps = _field(head, "session", "fps", float, path)
        first = _field(head, "session", "start_frame", float, path)
        last = _field(head, "session", "end_frame", float, path)
        if not (fps > 0 and last > first):
            raise SimenvError(f"need fps > 0 and end_frame > start_frame; got fps {fps}, "
                              f"frames {first}..{last}", source=path, field="session")
        root = shared_data_root(data)
        file = root / src
        if not file.is_file():
            raise SimenvError(
                f"session recipe {path.stem!r} cuts {src} out of the shared corpus (research "
                f"use only, not bundled), but {file} does not exist; set SIMENV_SHARED_DATA "
                "(or pass data= / --data) to the folder holding the corpus (its SOURCES.md)",
                source=path, field="session.source")
        if fmt == "utkinect":
            motion = utkinect.read(file, labels=False, fps=fps)
        else:
            motion = load(file)
            if not isinstance(motion, Motion):
                raise SimenvError(f"{src} holds two people; a session is one", source=path,
                                  field="session.source")
            if motion.fps != fps:
                motion = motion.resample(fps)
        clock = float(head.get("frame_clock_hz", motion.fps))
        f0 = float(motion.metadata.get("frame_numbers", [0])[0])

        def at(frame: float) -> float:  # s from the start of the recording
            return (frame - f0) / clock

        i0 = max(math.ceil(at(first) * fps - 1e-9), 0)
        i1 = min(math.floor(at(last) * fps + 1e-9) + 1, motion.num_frames)
        if i1 - i0 < 2:
            raise SimenvError(f"frames {first:g}..{last:g} hold {max(i1 - i0, 0)} frame(s) of "
                              f"{src} ({motion.num_frames} frames at {fps:g} fps)",
                              source=path, field="session.start_frame")
        cut = motion.slice(i0, i1)
        cut = cut.with_positions(cut.positions, name=str(head.get("name", path.stem)),
                                 metadata={**cut.metadata, "recipe": str(path),
                                           "source": str(file)})
        t0, duration = i0 / fps, (i1 - i0) / fps
        events = []
        for k, g in enumerate(raw.get("gestures", [])):
            where = f"gestures[{k}]"
            label = _field(g, where, "label", str, path)
            onset = at(_field(g, where, "start_frame", float, path)) - t0
            end = at(_field(g, where, "end_frame", float, path)) - t0
            if end <= 0.0 or onset >= duration:
                raise SimenvError(f"gesture {label!r} lies outside the session's frames",
                                  source=path, field=where)
            events.append(GestureEvent(label, max(onset, 0.0), min(end, duration)))
        return cls(cut, (*events, *gestures))


def _table(raw: dict, key: str, path: Path) -> dict:
    table = raw.get(key)
    if not isinstance(table, dict):
        raise SimenvError(f"session recipe needs a [{key}] table", source=path, field=key)
    return table


def _field(table: dict, where: str, key: str, kind: type, path: Path) -> object:
    """``table[key]`` as ``kind`` (a TOML integer is a float here); names the field."""
    value = table.get(key)
    ok = isinstance(value, str) if kind is str else (
        isinstance(value, (int, float)) and not isinstance(value, bool)
        and math.isfinite(value))
    if not ok:
        what = "a string" if kind is str else "a finite number"
        raise SimenvError(f"{where}.{key} must be {what}; got {value!r}", source=path,
                          field=f"{where}.{key}")
    return kind(value)


@dataclass(frozen=True)
class UserTrack:
    """The user's trajectory in the room at :data:`PERCEPTION_FPS`.

    Attributes:
        qpos: (T, nq_user) configurations of ``result.humanoid``, placed in the room.
        keypoints: (T, K, 3) the avatar's canonical keypoints in the room, m.
        result: the retargeting result (fitted body, residuals).
        scenario: the scenario it was placed for.
        observer: (3,) where the recording's depth sensor stands in the room, m (its floor
            point), for a recording in a sensor's camera frame (metadata
            ``camera_frame``, :mod:`simenv.io.camera_frame`: the sensor above the world
            origin); None for others. The user's recorded motion answers to it (they walk
            up to it and stop), so a forecaster is told it.
    """

    qpos: np.ndarray
    keypoints: np.ndarray
    result: RetargetResult
    scenario: Scenario
    observer: np.ndarray | None = None

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
    observer = (place_points(np.zeros((1, 3)), result.qpos[0], u.position,
                             np.deg2rad(u.yaw_deg))[0]
                if "camera_frame" in (m.metadata or {}) else None)
    h = result.humanoid
    data = mujoco.MjData(h.model)
    kp = np.empty((len(qpos), len(h.site_ids), 3))
    for t, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(h.model, data)
        kp[t] = data.site_xpos[h.site_ids]
    return UserTrack(qpos, kp, result, scenario, observer)


__all__ = ["PERCEPTION_FPS", "SESSIONS_DIR", "GestureEvent", "Session", "UserTrack",
           "session_recipes", "user_track"]

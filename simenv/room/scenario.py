"""Room scenarios: the editable TOML file that lays out the room and maps gestures to reactions.

A scenario file has one table per piece of furniture plus ``[agent]``, ``[user]`` and
``[behaviour]``; see ``assets/scenarios/default.toml`` for every field with its unit and
meaning. Bundled scenarios: ``default`` (reactions to the gestures of
:mod:`simenv.data.gestures`) and ``discomfort`` (the thesis's cold / hot / loud / smell / bright
reactions). :func:`load_scenario` checks the whole file before anything is built: unknown
tables or keys (typos), missing keys, wrong types, values outside their range, furniture
outside the room and overlapping wall openings are each a :class:`~simenv.core.errors.ScenarioError`
naming the file and the dotted field (``window.offset``).

Optional ``[[furniture]]`` tables add user-supplied meshes (OBJ, STL, glTF/GLB, ...) to the
room (:class:`simenv.room.furniture.FurnitureMesh`; reading, placement and collision
geometry in :mod:`simenv.room.furniture`); each file is read while the scenario loads, so a
missing or unreadable file, an empty mesh or one in the wrong units (larger than 10 m) is a
:class:`~simenv.core.errors.ScenarioError` naming ``furniture[i].mesh``.

Conventions: metres and degrees in the file (radians inside simenv). The room is centred on
the origin, x east, y north, z up, floor at z = 0. A wall-mounted object's ``offset`` is
measured from the wall's centre, positive to the right as seen from inside the room facing
that wall. ``yaw_deg`` is the direction an object's front (or a person) faces: 0 = +x.
"""

from __future__ import annotations

import difflib
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import ScenarioError
from simenv.data.gestures import VOCABULARY
from simenv.room.furniture import COLLISIONS, FurnitureMesh, read_mesh

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

#: Walls of the rectangular room.
WALLS: tuple[str, ...] = ("north", "east", "south", "west")
#: Wall thickness, m.
WALL_THICKNESS = 0.12
#: Travel of the sliding window pane as a fraction of the opening's width.
WINDOW_TRAVEL = 0.9
#: Door leaf size (width, height), m; the opening is 2 cm larger.
DOOR_SIZE = (0.9, 2.05)
#: Furniture footprints (x half-extent, y half-extent in their own frame), m, for the
#: inside-the-room check. The desk's reaches back over the agent's chair (0.9 m).
DESK_FOOTPRINT = (0.9, 0.7)
HIFI_FOOTPRINT = (0.2, 0.35)
#: The desk top's and the chair's own footprints (half-extents, m) and centres in the
#: desk's frame: the hi-fi may stand beside them, not in them.
DESK_TOP = ((0.0, 0.0), (0.35, 0.7))
CHAIR = ((-0.65, 0.0), (0.22, 0.22))
#: Clearance kept between the user's pelvis and the furniture, m (a body's half-width).
USER_CLEARANCE = 0.3
#: Clearance kept between a wall opening and a corner of the room, m.
CORNER_CLEARANCE = 0.1


@dataclass(frozen=True)
class Reaction:
    """What the agent does for a gesture, and how its success is measured.

    Attributes:
        name: reaction name used in scenario files.
        description: what the agent does.
        object: the room object it acts on (None: a social reaction, measured on the
            agent's body).
        target: the object's state label that counts as done (see
            :attr:`simenv.room.room.RoomObject.above` / ``below``), or None.
    """

    name: str
    description: str
    object: str | None = None
    target: str | None = None


#: Every reaction a scenario may name. Object reactions succeed when the object's state
#: label becomes ``target`` in simulation; ``greet`` succeeds when the agent's torso faces
#: the user within 30 degrees and a hand is above its shoulder (measured by the rehearsal).
REACTIONS: dict[str, Reaction] = {r.name: r for r in (
    Reaction("keep", "keep working at the desk (typing, glancing at the notebook)"),
    Reaction("greet", "stop idling, turn to face the user and wave back"),
    Reaction("bow_back", "nod or bow back to the user"),
    Reaction("hifi_down", "turn the hi-fi's volume knob down", "hifi", "quiet"),
    Reaction("close_window", "close the window (if open)", "window", "closed"),
    Reaction("open_window", "open the window (if closed)", "window", "open"),
    Reaction("cigarette_out", "press the cigarette out in the ashtray", "cigarette", "out"),
    Reaction("close_curtain", "draw the curtain across the window", "curtain", "closed"),
    Reaction("open_curtain", "draw the curtain aside", "curtain", "open"),
    Reaction("close_door", "close the door", "door", "closed"),
    Reaction("open_door", "open the door", "door", "open"),
)}


@dataclass(frozen=True)
class RoomLayout:
    """``[room]``: width (x) and depth (y) of the floor, wall height; metres."""

    size: tuple[float, float]
    wall_height: float


@dataclass(frozen=True)
class DeskLayout:
    """``[desk]``: floor position (x, y) of the desk's centre, m; yaw, degrees. The agent's
    chair stands on the desk's local -x side, facing +x."""

    position: tuple[float, float]
    yaw_deg: float


@dataclass(frozen=True)
class WindowLayout:
    """``[window]``: wall, offset along it, opening width / height / sill height, initial
    pane travel ``open`` (0 = closed); metres."""

    wall: str
    offset: float
    width: float
    height: float
    sill: float
    open: float


@dataclass(frozen=True)
class CurtainLayout:
    """``[curtain]``: initial fraction of the window the curtain covers, 0..1."""

    closed: float


@dataclass(frozen=True)
class HifiLayout:
    """``[hifi]``: floor position, m; yaw of its front, degrees; initial volume level 0..1."""

    position: tuple[float, float]
    yaw_deg: float
    volume: float


@dataclass(frozen=True)
class CigaretteLayout:
    """``[cigarette]``: whether it starts lit (it lies in the ashtray on the desk)."""

    lit: bool


@dataclass(frozen=True)
class DoorLayout:
    """``[door]``: wall, offset along it, m; initial opening angle, degrees."""

    wall: str
    offset: float
    angle_deg: float


@dataclass(frozen=True)
class AgentLayout:
    """``[agent]``: standing height of the agent, m (the default adult scaled uniformly)."""

    height: float


@dataclass(frozen=True)
class UserLayout:
    """``[user]``: where the user's pelvis stands (x, y), m; the direction they face,
    degrees; ``appearance``: ``"solid"`` (collides with the agent and the objects) or
    ``"ghost"`` (drawn translucent, collides with nothing)."""

    position: tuple[float, float]
    yaw_deg: float
    appearance: str


@dataclass(frozen=True)
class Behaviour:
    """``[behaviour]``: the gesture labels the scenario understands, the reaction to each
    listed label, and the reaction (``otherwise``) to every other label."""

    vocabulary: tuple[str, ...]
    reactions: Mapping[str, str]
    otherwise: str

    def reaction_for(self, label: str) -> Reaction:
        """The reaction to gesture ``label``.

        Raises:
            ScenarioError: ``label`` is not in the scenario's vocabulary.
        """
        if label not in self.vocabulary:
            raise ScenarioError(f"gesture {label!r} is not in the scenario's vocabulary "
                                f"{list(self.vocabulary)}", field="behaviour.vocabulary")
        return REACTIONS[self.reactions.get(label, self.otherwise)]


@dataclass(frozen=True)
class Scenario:
    """A validated scenario file (see the module docstring)."""

    name: str
    description: str
    source: str
    room: RoomLayout
    desk: DeskLayout
    window: WindowLayout
    curtain: CurtainLayout
    hifi: HifiLayout
    cigarette: CigaretteLayout
    door: DoorLayout
    agent: AgentLayout
    user: UserLayout
    behaviour: Behaviour
    furniture: tuple[FurnitureMesh, ...] = ()


# ---------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------


class _Table:
    """Typed access to one TOML table; every read is checked and named ``table.key``."""

    def __init__(self, raw: Any, name: str, source: str) -> None:
        self.name, self.source = name, source
        if not isinstance(raw, dict):
            self.fail(name, f"expected a table {self.where}, got {type(raw).__name__}")
        self.raw: dict[str, Any] = raw
        self.used: set[str] = set()

    def fail(self, field: str, message: str) -> None:
        raise ScenarioError(message, source=self.source, field=field)

    @property
    def where(self) -> str:
        return f"[{self.name}]" if self.name else "the scenario file"

    def _field(self, key: str) -> str:
        return f"{self.name}.{key}" if self.name else key

    def _get(self, key: str) -> Any:
        self.used.add(key)
        if key not in self.raw:
            typo = difflib.get_close_matches(key, [k for k in self.raw if k not in self.used], 1)
            hint = f" (found {typo[0]!r}: a typo?)" if typo else ""
            self.fail(self._field(key), f"missing key {key!r} in {self.where}{hint}")
        return self.raw[key]

    def number(self, key: str, lo: float | None = None, hi: float | None = None) -> float:
        v = self._get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(self._field(key), f"expected a number, got {v!r}")
        v = float(v)
        if v != v or (lo is not None and v < lo) or (hi is not None and v > hi):
            self.fail(self._field(key), f"{v} is outside [{lo}, {hi}]")
        return v

    def pair(self, key: str, lo: float | None = None) -> tuple[float, float]:
        v = self._get(key)
        ok = (isinstance(v, list) and len(v) == 2
              and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v))
        if not ok:
            self.fail(self._field(key), f"expected two numbers [x, y], got {v!r}")
        if lo is not None and min(v) < lo:
            self.fail(self._field(key), f"{v} has a value below {lo}")
        return (float(v[0]), float(v[1]))

    def string(self, key: str, choices: tuple[str, ...] | None = None) -> str:
        v = self._get(key)
        if not isinstance(v, str):
            self.fail(self._field(key), f"expected a string, got {v!r}")
        if choices is not None and v not in choices:
            self.fail(self._field(key), f"{v!r} is not one of {list(choices)}")
        return v

    def boolean(self, key: str) -> bool:
        v = self._get(key)
        if not isinstance(v, bool):
            self.fail(self._field(key), f"expected true or false, got {v!r}")
        return v

    def has(self, key: str) -> bool:
        """Whether optional ``key`` is present (then read it with a typed getter)."""
        return key in self.raw

    def table(self, key: str) -> _Table:
        return _Table(self._get(key), self._field(key), self.source)

    def done(self) -> None:
        extra = sorted(set(self.raw) - self.used)
        if extra:
            self.fail(self._field(extra[0]), f"unknown key {extra[0]!r} in {self.where}; "
                      f"expected one of {sorted(self.used)}")


def _bundled_dir() -> Path:
    return Path(os.fspath(files("simenv.assets"))) / "scenarios"


def list_scenarios() -> list[str]:
    """Names of the bundled scenarios (``default``, ``discomfort``, ...)."""
    return sorted(p.stem for p in _bundled_dir().glob("*.toml"))


def scenario_path(name_or_path: str | os.PathLike[str]) -> Path:
    """Path of a bundled scenario by name, or the given path itself when it is a file.

    Raises:
        ScenarioError: neither a file nor a bundled name (the message lists the names).
    """
    path = Path(name_or_path)
    if path.is_file():
        return path
    bundled = _bundled_dir() / f"{name_or_path}.toml"
    if bundled.is_file():
        return bundled
    raise ScenarioError(f"no scenario file {str(name_or_path)!r} and no bundled scenario of "
                        f"that name; bundled: {', '.join(list_scenarios())}",
                        source=str(name_or_path))


def load_scenario(name_or_path: str | os.PathLike[str] = "default") -> Scenario:
    """Read and validate a scenario (a bundled name or a TOML file path)."""
    path = scenario_path(name_or_path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"not a valid TOML file: {exc}", source=str(path)) from None
    return parse_scenario(raw, source=str(path))


def parse_scenario(raw: Mapping[str, Any], source: str = "<scenario>") -> Scenario:
    """Validate a decoded scenario (the dict of a TOML file); ``source`` names it in errors."""
    top = _Table(dict(raw), "", source)
    head = top.table("scenario")
    name, description = head.string("name"), head.string("description")
    head.done()

    t = top.table("room")
    room = RoomLayout(t.pair("size", lo=2.0), t.number("wall_height", 2.2, 6.0))
    t.done()
    t = top.table("desk")
    desk = DeskLayout(t.pair("position"), t.number("yaw_deg", -360, 360))
    t.done()
    t = top.table("window")
    wall, offset, width = t.string("wall", WALLS), t.number("offset"), t.number("width", 0.4, 3)
    window = WindowLayout(wall, offset, width, t.number("height", 0.4, 3.0),
                          t.number("sill", 0.3, 2.0),
                          t.number("open", 0.0, WINDOW_TRAVEL * width))
    t.done()
    t = top.table("curtain")
    curtain = CurtainLayout(t.number("closed", 0.0, 1.0))
    t.done()
    t = top.table("hifi")
    hifi = HifiLayout(t.pair("position"), t.number("yaw_deg", -360, 360),
                      t.number("volume", 0.0, 1.0))
    t.done()
    t = top.table("cigarette")
    cigarette = CigaretteLayout(t.boolean("lit"))
    t.done()
    t = top.table("door")
    door = DoorLayout(t.string("wall", WALLS), t.number("offset"),
                      t.number("angle_deg", 0.0, 100.0))
    t.done()
    t = top.table("agent")
    agent = AgentLayout(t.number("height", 1.35, 2.15))
    t.done()
    t = top.table("user")
    user = UserLayout(t.pair("position"), t.number("yaw_deg", -360, 360),
                      t.string("appearance", ("solid", "ghost")))
    t.done()
    behaviour = _behaviour(top.table("behaviour"))
    furniture = _furniture(top) if top.has("furniture") else ()
    top.done()

    scenario = Scenario(name, description, source, room, desk, window, curtain, hifi,
                        cigarette, door, agent, user, behaviour, furniture)
    _check_layout(scenario)
    return scenario


def _behaviour(t: _Table) -> Behaviour:
    vocab_raw = t._get("vocabulary")
    # "simenv.gestures" is the module's name before the package layout: older files still load.
    if vocab_raw in ("simenv.data.gestures", "simenv.gestures"):
        vocabulary = tuple(VOCABULARY)
    elif (isinstance(vocab_raw, list) and vocab_raw
          and all(isinstance(v, str) and v for v in vocab_raw)):
        vocabulary = tuple(vocab_raw)
        if len(set(vocabulary)) != len(vocabulary):
            t.fail("behaviour.vocabulary", f"duplicate labels in {vocab_raw}")
    else:
        t.fail("behaviour.vocabulary", 'expected "simenv.data.gestures" or a non-empty list of '
               f"label strings, got {vocab_raw!r}")
    otherwise = t.string("otherwise", tuple(REACTIONS))
    table = t.table("reactions")
    reactions = {}
    for label in table.raw:
        if label not in vocabulary:
            t.fail(f"behaviour.reactions.{label}", f"gesture {label!r} is not in the "
                   f"vocabulary {list(vocabulary)}")
        reactions[label] = table.string(label, tuple(REACTIONS))
    table.done()
    t.done()
    return Behaviour(vocabulary, reactions, otherwise)


#: Mesh suffixes whose files are Y-up by default (glTF's convention; most OBJ exporters).
_Y_UP_SUFFIXES = (".glb", ".gltf", ".obj")


def _furniture(top: _Table) -> tuple[FurnitureMesh, ...]:
    """The ``[[furniture]]`` array: each table's fields, its mesh read and measured."""
    items = top._get("furniture")
    if not isinstance(items, list):
        top.fail("furniture", "expected [[furniture]] tables (an array of tables), got "
                 f"{type(items).__name__}")
    base = Path(top.source).parent if Path(top.source).is_file() else Path.cwd()
    out: list[FurnitureMesh] = []
    for i, raw in enumerate(items):
        t = _Table(raw, f"furniture[{i}]", top.source)
        name = t.string("name") if t.has("name") else f"item{i}"
        if not name or any(c in name for c in "/ "):
            t.fail(f"{t.name}.name", f"{name!r}: expected a name without spaces or '/'")
        if name in [f.name for f in out]:
            t.fail(f"{t.name}.name", f"duplicate furniture name {name!r}")
        mesh = Path(t.string("mesh")).expanduser()
        mesh = mesh if mesh.is_absolute() else base / mesh
        position = t.pair("position")
        yaw = t.number("yaw_deg", -360, 360) if t.has("yaw_deg") else 0.0
        elevation = t.number("elevation", 0.0, 3.0) if t.has("elevation") else 0.0
        scale = t.number("scale", 1e-6, 1e3) if t.has("scale") else 1.0
        up = t.string("up", ("y", "z")) if t.has("up") else (
            "y" if mesh.suffix.lower() in _Y_UP_SUFFIXES else "z")
        collision = t.string("collision", COLLISIONS) if t.has("collision") else "parts"
        voxel = t.number("voxel", 0.005, 0.5) if t.has("voxel") else 0.03
        rgba = None
        if t.has("rgba"):
            v = t._get("rgba")
            if not (isinstance(v, list) and len(v) == 4 and all(
                    isinstance(x, (int, float)) and not isinstance(x, bool) and 0 <= x <= 1
                    for x in v)):
                t.fail(f"{t.name}.rgba", f"expected four numbers in [0, 1], got {v!r}")
            rgba = tuple(float(x) for x in v)
        t.done()
        whole, _, _ = read_mesh(mesh, scale=scale, up=up, field=f"{t.name}.mesh",
                                source=top.source)
        size = tuple(float(e) for e in whole.extents)
        if elevation + size[2] > 3.0:
            t.fail(f"{t.name}.elevation", f"the mesh reaches {elevation + size[2]:.2f} m "
                   "above the floor")
        out.append(FurnitureMesh(name, mesh, position, yaw, elevation, scale, up, collision,
                                 voxel, rgba, size, t.name))
    return tuple(out)


def _check_layout(s: Scenario) -> None:
    """Furniture inside the room, openings within their walls and not overlapping."""
    half = (s.room.size[0] / 2, s.room.size[1] / 2)

    def fail(field: str, message: str) -> None:
        raise ScenarioError(message, source=s.source, field=field)

    for field, (x, y), margin in (
        ("desk.position", s.desk.position, max(DESK_FOOTPRINT)),
        ("hifi.position", s.hifi.position, max(HIFI_FOOTPRINT)),
        ("user.position", s.user.position, 0.3),
    ):
        if abs(x) > half[0] - margin or abs(y) > half[1] - margin:
            fail(field, f"({x}, {y}) is not inside the room "
                 f"(|x| <= {half[0] - margin:.2f}, |y| <= {half[1] - margin:.2f} m for this "
                 "object's size)")
    for name, (cx, cy), yaw_deg, (hx, hy) in (
        ("desk", s.desk.position, s.desk.yaw_deg, DESK_FOOTPRINT),
        ("hifi", s.hifi.position, s.hifi.yaw_deg, HIFI_FOOTPRINT),
    ):
        yaw = np.deg2rad(yaw_deg)
        dx, dy = s.user.position[0] - cx, s.user.position[1] - cy
        u, v = np.cos(yaw) * dx + np.sin(yaw) * dy, -np.sin(yaw) * dx + np.cos(yaw) * dy
        if abs(u) < hx + USER_CLEARANCE and abs(v) < hy + USER_CLEARANCE:
            fail("user.position", f"{list(s.user.position)} puts the user inside the {name} "
                 f"(keep {USER_CLEARANCE} m clear of its {2 * hx:.2f} x {2 * hy:.2f} m "
                 "footprint)")
    for f in s.furniture:
        corners = _rectangle(f.position, f.yaw_deg, (0.0, 0.0), (f.size[0] / 2, f.size[1] / 2))
        if (np.abs(corners) > np.array(s.room.size) / 2).any():
            fail(f"{f.field}.position", f"{list(f.position)} (yaw {f.yaw_deg} deg) puts the "
                 f"{f.size[0]:.2f} x {f.size[1]:.2f} m mesh {f.mesh.name} through a wall")
        if _overlap(corners, _rectangle(s.user.position, 0.0, (0.0, 0.0),
                                        (USER_CLEARANCE, USER_CLEARANCE))):
            fail("user.position", f"{list(s.user.position)} puts the user inside furniture "
                 f"{f.name!r} (keep {USER_CLEARANCE} m clear of its footprint)")
    hifi = _rectangle(s.hifi.position, s.hifi.yaw_deg, (0.0, 0.0), HIFI_FOOTPRINT)
    for name, (centre, half) in (("desk", DESK_TOP), ("chair", CHAIR)):
        if _overlap(hifi, _rectangle(s.desk.position, s.desk.yaw_deg, centre, half)):
            fail("hifi.position", f"{list(s.hifi.position)} (yaw {s.hifi.yaw_deg} deg) puts "
                 f"the hi-fi's {2 * HIFI_FOOTPRINT[0]:.2f} x {2 * HIFI_FOOTPRINT[1]:.2f} m "
                 f"footprint into the {name}")
    openings: dict[str, list[tuple[float, float, str]]] = {w: [] for w in WALLS}
    for field, wall, offset, width in (
        ("window", s.window.wall, s.window.offset, s.window.width),
        ("door", s.door.wall, s.door.offset, DOOR_SIZE[0] + 0.02),
    ):
        length = wall_length(s.room, wall)
        if abs(offset) + width / 2 > length / 2 - CORNER_CLEARANCE:
            fail(f"{field}.offset", f"a {width:.2f} m opening at offset {offset} m does not "
                 f"fit the {length:.2f} m {wall} wall")
        openings[wall].append((offset - width / 2, offset + width / 2, field))
    if s.window.sill + s.window.height + 0.25 > s.room.wall_height:
        fail("window.height", f"sill {s.window.sill} + height {s.window.height} m leaves no "
             f"room for the curtain rail below the {s.room.wall_height} m ceiling")
    if DOOR_SIZE[1] + 0.1 > s.room.wall_height:
        fail("room.wall_height", f"the door ({DOOR_SIZE[1]} m) needs a wall of at least "
             f"{DOOR_SIZE[1] + 0.1} m")
    for wall, spans in openings.items():
        spans.sort()
        for (_, a1, fa), (b0, _, fb) in zip(spans, spans[1:], strict=False):
            if b0 < a1 + 0.1:
                fail(f"{fb}.offset", f"the {fb} overlaps the {fa} on the {wall} wall")


def _rectangle(origin: tuple[float, float], yaw_deg: float, centre: tuple[float, float],
               half: tuple[float, float]) -> np.ndarray:
    """(4, 2) corners on the floor of a rectangle of half-extents ``half`` centred at
    ``centre`` in the frame at ``origin`` turned by ``yaw_deg``, m."""
    yaw = np.deg2rad(yaw_deg)
    rot = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    local = np.array(centre) + np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]]) * half
    return local @ rot.T + origin


def _overlap(a: np.ndarray, b: np.ndarray, tol: float = 1e-6) -> bool:
    """Whether two convex polygons (N, 2) overlap by more than ``tol`` (separating axis
    test on their edge normals; touching edges do not overlap)."""
    for poly in (a, b):
        for i in range(len(poly)):
            edge = poly[(i + 1) % len(poly)] - poly[i]
            normal = np.array([-edge[1], edge[0]]) / np.linalg.norm(edge)
            pa, pb = a @ normal, b @ normal
            if pa.max() <= pb.min() + tol or pb.max() <= pa.min() + tol:
                return False
    return True


def wall_length(room: RoomLayout, wall: str) -> float:
    """Interior length of ``wall``, m."""
    return room.size[0] if wall in ("north", "south") else room.size[1]


__all__ = ["REACTIONS", "WALLS", "Behaviour", "Reaction", "Scenario",
           "list_scenarios", "load_scenario", "parse_scenario", "scenario_path", "wall_length"]

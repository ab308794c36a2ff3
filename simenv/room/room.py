"""The virtual room: a furnished MuJoCo scene with a user avatar and an agent humanoid.

Built in code with :class:`mujoco.MjSpec` from a :class:`~simenv.room.scenario.Scenario`:
floor, four walls (cut around the window and the door), a desk with keyboard, laptop,
notebook and an ashtray, the agent's chair, the scenario's own furniture meshes
(:func:`simenv.room.furniture.add_furniture`: static, colliding with the agent like the rest of the
furniture), and the interactive objects below. Each object
is a body on one joint; its *state* is that joint's position, so an object changes state only
when something in the simulation moves it (a hand's contact, a grasp constraint, a force):

============ ====================== ======== ================= ============================
object       joint (type)           unit     range             state labels
============ ====================== ======== ================= ============================
window       ``window/slide`` slide m        [0, 0.9 w]        ``open`` when > 0.10 m
curtain      ``curtain/slide`` slide m       [0, w]            ``closed`` when > 0.75 w
hifi         ``hifi/volume`` hinge  rad      [0, 3 pi / 2]     ``loud`` when > 3 pi / 4
cigarette    ``cigarette/press``    m        [0, 0.012]        ``out`` when > 0.006 m
             slide
door         ``door/hinge`` hinge   rad      [0, 100 deg]      ``open`` when > 15 deg
============ ====================== ======== ================= ============================

(``w`` = window width; the window pane's value is its travel from closed; the curtain's is
the width of window it covers; the hi-fi's knob angle gives the volume level
``angle / (3 pi / 2)``; the cigarette's is how far it has been pressed into the ashtray, so
it is lit until pressed; the door's is its opening angle.) Every joint has Coulomb friction
(``frictionloss``), so an object released anywhere holds its state, as a real sash, knob
detent or hinge does, plus viscous damping. MuJoCo's friction loss is a soft constraint that
lets a steady load creep, so no joint carries one at rest: the window, curtain and door move
perpendicular to gravity, and the knob and the cigarette are gravity-compensated.

Each object has a *handle* site where a hand acts on it (the knob's is near its rim, off
the hinge axis, so a held knob can be turned), and for each hand an inactive ``connect``
equality constraint between a hand site and the handle: the palm's *grip* site, or the
fingertips' *tip* site for the small knob (:data:`GRASP_SITE`). :meth:`Room.set_grasp`
activates it only when that site is within :data:`GRASP_RADIUS` of the handle (a
proximity grasp), after which the hand drags the object through the constraint force.

The agent's chair is an office chair: it rolls back from the desk on its casters (slide
``chair/roll`` along the desk's x axis, friction :data:`CHAIR_ROLL_FRICTION`) and its seat
and back swivel on the base (hinge ``chair/swivel``, friction :data:`SWIVEL_FRICTION`), so
the seated agent turns or pushes itself back with its planted feet; the chair is
furniture, not one of the objects.

People:

* the **agent** (prefix ``agent/``): a :class:`~simenv.body.humanoid.Humanoid` with its PD
  position actuators, seated on the chair facing the desk (:meth:`Room.seated_pose`);
* the **user** (prefix ``user/``): the same body tree built from the user's
  :class:`~simenv.body.humanoid.BodyDimensions`, but as *mocap* bodies: kinematic, driven
  frame by frame from a qpos of the user's own humanoid (:meth:`Room.set_user_pose`),
  infinitely strong, adding no degrees of freedom. A ``solid`` user collides with the agent
  and the objects; a ``ghost`` is translucent and collides with nothing.

Collision groups (bit = ``contype``; a geom pair collides when either one's ``contype``
meets the other's ``conaffinity``): furniture and floor only touch the agent; the agent
touches everything including itself (the humanoid's neighbour exclusions apply); the user
touches the agent and the objects; objects touch people, not their own frames (their joint
ranges stand in for the frames).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from simenv.body.humanoid import (
    BONES,
    DEFAULT,
    BodyDimensions,
    Humanoid,
    add_person,
    new_spec,
)
from simenv.core.errors import ScenarioError, SimenvError
from simenv.room.furniture import add_furniture
from simenv.room.scenario import (
    DOOR_SIZE,
    WALL_THICKNESS,
    WINDOW_TRAVEL,
    Scenario,
    load_scenario,
    wall_length,
)

# Collision bits (see the module docstring).
_STATIC, _AGENT, _USER, _OBJECT = 1, 2, 4, 8
_AFFINITY = {
    _STATIC: _AGENT,
    _AGENT: _STATIC | _AGENT | _USER | _OBJECT,
    _USER: _AGENT | _OBJECT,
    _OBJECT: _AGENT | _USER,
}

#: Distance (m) within which a hand's grasp site may grasp an object's handle.
GRASP_RADIUS = 0.06
#: Hand site each object is grasped with: the palm (``grip``) holds handles and panels,
#: the fingertips (``tip``) hold the hi-fi's small knob (a palm laid on it would press the
#: hand's box into the knob).
GRASP_SITE = {"window": "grip", "curtain": "grip", "hifi": "tip", "cigarette": "grip",
              "door": "grip"}
#: Knob travel of the hi-fi, rad (the volume level is angle / this).
KNOB_TRAVEL = 1.5 * np.pi
#: Distance of the knob's handle from its hinge axis, m.
KNOB_GRIP_RADIUS = 0.027
#: Press depth of the cigarette's slide, m.
CIGARETTE_TRAVEL = 0.012
#: Maximum door opening, rad.
DOOR_TRAVEL = np.deg2rad(100.0)
#: Desk top height, m.
DESK_HEIGHT = 0.74
#: Chair centre in the desk's frame (the agent sits on the -x side, facing +x), m.
CHAIR_OFFSET = (-0.65, 0.0)
#: The chair's swivel: range either way, rad; Coulomb friction, N m (holds the seated
#: agent's reaching reactions, gives way to its feet).
SWIVEL_RANGE = np.pi
SWIVEL_FRICTION = 4.0
#: The chair rolls back from the desk on its casters (a slide along the desk's x axis): up
#: to this far, m, against this Coulomb friction, N.
CHAIR_ROLL = 0.8
CHAIR_ROLL_FRICTION = 30.0
#: Hands of the agent (keypoint site suffixes) that can grasp.
HANDS = ("left_hand", "right_hand")
#: A greeting needs the agent's chest to face the user within this angle, degrees.
GREET_FACING_DEG = 30.0
#: A bow needs the head to pitch this far down, degrees, from where it was when the agent
#: came to face the user, and then to come back up within BOW_RETURN_DEG of it
#: (:class:`BowMeter`).
BOW_DIP_DEG = 15.0
BOW_RETURN_DEG = 5.0

_WOOD = (0.55, 0.38, 0.22, 1.0)
_WALL = (0.85, 0.84, 0.8, 1.0)
_DARK = (0.15, 0.15, 0.17, 1.0)
_METAL = (0.6, 0.6, 0.63, 1.0)
_EMBER = (1.0, 0.35, 0.05, 1.0)
_ASH = (0.45, 0.45, 0.45, 1.0)


@dataclass(frozen=True)
class RoomObject:
    """One interactive object: a body on one joint whose position is the object's state.

    Attributes:
        name: object name (``window``, ``curtain``, ``hifi``, ``cigarette``, ``door``).
        joint: joint name in the room model.
        unit: ``"m"`` (slide) or ``"rad"`` (hinge).
        lower, upper: joint range, in ``unit``.
        threshold: the state is ``above`` when the value exceeds it, else ``below``.
        below, above: state labels (e.g. ``"closed"`` / ``"open"``).
        qpos_adr, dof_adr: addresses of the joint in qpos / qvel.
        handle: name of the site where a hand acts on the object.
    """

    name: str
    joint: str
    unit: str
    lower: float
    upper: float
    threshold: float
    below: str
    above: str
    qpos_adr: int
    dof_adr: int
    handle: str

    def label(self, value: float) -> str:
        """State label of a joint value."""
        return self.above if value > self.threshold else self.below

    def level(self, value: float) -> float:
        """Joint value as a fraction of its range, 0..1 (the hi-fi's volume level)."""
        return float((value - self.lower) / (self.upper - self.lower))


# ---------------------------------------------------------------------------
# Geometry helpers
# ---------------------------------------------------------------------------


def _yaw_quat(yaw: float) -> list[float]:
    return [float(np.cos(yaw / 2)), 0.0, 0.0, float(np.sin(yaw / 2))]


def _geom(body: mujoco.MjsBody, name: str, kind: mujoco.mjtGeom, size: Sequence[float],
          pos: Sequence[float], rgba: Sequence[float], group: int,
          quat: Sequence[float] | None = None, mass: float | None = None) -> mujoco.MjsGeom:
    g = body.add_geom()
    g.name = name
    g.type = kind
    g.size = list(size) + [0.0] * (3 - len(size))
    g.pos = list(pos)
    if quat is not None:
        g.quat = list(quat)
    g.rgba = list(rgba)
    g.contype, g.conaffinity = group, _AFFINITY[group]
    if mass is not None:
        g.mass = mass
    return g


def _box(body: mujoco.MjsBody, name: str, half: Sequence[float], pos: Sequence[float],
         rgba: Sequence[float] = _WOOD, group: int = _STATIC, **kw: object) -> mujoco.MjsGeom:
    return _geom(body, name, mujoco.mjtGeom.mjGEOM_BOX, half, pos, rgba, group, **kw)


def _body(parent: mujoco.MjsBody, name: str, pos: Sequence[float],
          yaw: float = 0.0) -> mujoco.MjsBody:
    b = parent.add_body()
    b.name = name
    b.pos = [float(p) for p in pos]
    b.quat = _yaw_quat(yaw)
    return b


def _joint(body: mujoco.MjsBody, name: str, kind: mujoco.mjtJoint, axis: Sequence[float],
           rng: tuple[float, float], friction: float, damping: float,
           armature: float = 0.0) -> None:
    j = body.add_joint()
    j.name = name
    j.type = kind
    j.axis = list(axis)
    j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    j.range = list(rng)
    j.frictionloss = friction
    j.damping = [damping, 0.0, 0.0]
    j.armature = armature


def _handle(body: mujoco.MjsBody, name: str, pos: Sequence[float]) -> None:
    s = body.add_site()
    s.name = name
    s.pos = list(pos)
    s.size = [0.015, 0, 0]
    s.rgba = [0.1, 0.9, 0.3, 0.5]
    s.group = 4


def _wall_frame(scenario: Scenario, wall: str) -> tuple[np.ndarray, float]:
    """Interior face centre (x, y, 0) and yaw of ``wall``'s frame: x along the wall (to the
    right seen from inside), y outward, z up."""
    hx, hy = scenario.room.size[0] / 2, scenario.room.size[1] / 2
    normal = {"north": (0.0, 1.0), "south": (0.0, -1.0), "east": (1.0, 0.0),
              "west": (-1.0, 0.0)}[wall]
    centre = np.array([normal[0] * hx, normal[1] * hy, 0.0])
    return centre, float(np.arctan2(normal[1], normal[0]) - np.pi / 2)


# ---------------------------------------------------------------------------
# Room
# ---------------------------------------------------------------------------


class Room:
    """The room of a scenario, compiled, with its agent and user.

    Args:
        scenario: a :class:`~simenv.room.scenario.Scenario`, a bundled scenario name or a path.
        user: the user's body (e.g. :func:`simenv.body.humanoid.fit_dimensions` of the session's
            motion); default: the default adult.
        agent: the agent's body; default: the default adult scaled to
            ``scenario.agent.height``.

    Attributes:
        scenario, spec, model: the scenario, the MjSpec and the compiled model.
        objects: object name -> :class:`RoomObject`.
        agent: the agent's standalone humanoid (its qpos/ctrl layout is the room's slices).
        agent_qpos, agent_qvel, agent_ctrl: slices of the agent in the room's qpos, qvel, ctrl.
        agent_sites: (K,) room site ids of the agent's keypoints.
        user: the user's standalone humanoid (:meth:`set_user_pose` takes its qpos).
        user_sites: (K,) room site ids of the user's keypoints.
        seat_height: top of the chair's seat, m.
    """

    def __init__(self, scenario: Scenario | str = "default",
                 user: BodyDimensions | None = None,
                 agent: BodyDimensions | None = None) -> None:
        self.scenario = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
        s = self.scenario
        self.agent = Humanoid(agent or _scaled_default(s.agent.height), name="agent")
        self.user = Humanoid(user or DEFAULT, name="user")
        self.seat_height = _seat_height(self.agent.dims)
        spec = new_spec(f"room-{s.name}")
        spec.option.timestep = 0.002
        for g in spec.worldbody.geoms:  # the floor
            g.contype, g.conaffinity = _STATIC, _AFFINITY[_STATIC]
            g.size = [s.room.size[0] / 2 + 0.5, s.room.size[1] / 2 + 0.5, 0.05]
        self._build_walls(spec)
        self._build_desk(spec)
        self._build_hifi(spec)
        for item in s.furniture:
            add_furniture(spec, item, contype=_STATIC, conaffinity=_AFFINITY[_STATIC],
                          source=s.source)
        self._build_cameras(spec)
        add_person(spec, self.agent.dims, "agent/", pos=(0.0, 0.0, 0.0))
        for g in spec.geoms:
            if g.name.startswith("agent/"):
                g.contype, g.conaffinity = _AGENT, _AFFINITY[_AGENT]
        self._add_grips(spec)
        self._build_user(spec)
        self._build_grasps(spec)
        self.spec = spec
        try:
            self.model = spec.compile()
        except ValueError as exc:
            raise ScenarioError(f"could not build the room: {exc}", source=s.source) from None
        self._index()

    # -- construction ---------------------------------------------------------

    def _build_walls(self, spec: mujoco.MjSpec) -> None:
        s = self.scenario
        H, t = s.room.wall_height, WALL_THICKNESS
        w = s.window
        door_half = DOOR_SIZE[0] / 2 + 0.01
        openings = {wall: [] for wall in ("north", "east", "south", "west")}
        openings[w.wall].append((w.offset - w.width / 2, w.offset + w.width / 2, w.sill,
                                 w.sill + w.height))
        openings[s.door.wall].append((s.door.offset - door_half, s.door.offset + door_half,
                                      0.0, DOOR_SIZE[1] + 0.02))
        for wall, holes in openings.items():
            centre, yaw = _wall_frame(s, wall)
            body = _body(spec.worldbody, f"wall_{wall}", centre, yaw)
            half_len = wall_length(s.room, wall) / 2 + t  # overlap the corners
            for k, (u0, u1, z0, z1) in enumerate(_wall_slabs(holes, half_len, H)):
                _box(body, f"wall_{wall}_{k}", ((u1 - u0) / 2, t / 2, (z1 - z0) / 2),
                     ((u0 + u1) / 2, t / 2, (z0 + z1) / 2), _WALL)
            if wall == w.wall:
                self._build_window(body)
            if wall == s.door.wall:
                self._build_door(body)

    def _build_window(self, wall: mujoco.MjsBody) -> None:
        w, t = self.scenario.window, WALL_THICKNESS
        # Pane: a pocket sash sliding along the wall (+x opens) in the wall's mid-plane.
        pane = _body(wall, "window", (w.offset, t / 2, w.sill + w.height / 2))
        _joint(pane, "window/slide", mujoco.mjtJoint.mjJNT_SLIDE, (1, 0, 0),
               (0.0, WINDOW_TRAVEL * w.width), friction=5.0, damping=20.0)
        _box(pane, "window/pane", (w.width / 2, 0.01, w.height / 2), (0, 0, 0),
             (0.7, 0.85, 1.0, 0.35), _OBJECT, mass=8.0)
        grip = (-w.width / 2 + 0.08, -t / 2 - 0.03, 0.0)
        _box(pane, "window/handle", (0.015, 0.03, 0.06), grip, _METAL, _OBJECT, mass=0.2)
        _handle(pane, "window/handle", grip)
        # Curtain: a panel on a rail inside the room; at 0 it hangs left of the opening.
        rail_z = w.sill + w.height + 0.12
        rail = _geom(wall, "curtain/rail", mujoco.mjtGeom.mjGEOM_CAPSULE, (0.012,), (0, 0, 0),
                     _METAL, _STATIC)
        rail.fromto = [w.offset - 1.55 * w.width, -0.1, rail_z,
                       w.offset + w.width / 2 + 0.05, -0.1, rail_z]
        drop = w.height + 0.3
        curtain = _body(wall, "curtain", (w.offset - w.width, -0.1, rail_z - drop / 2))
        _joint(curtain, "curtain/slide", mujoco.mjtJoint.mjJNT_SLIDE, (1, 0, 0),
               (0.0, w.width), friction=1.0, damping=5.0)
        _box(curtain, "curtain/panel", (w.width / 2, 0.008, drop / 2), (0, 0, 0),
             (0.75, 0.3, 0.25, 1.0), _OBJECT, mass=1.0)
        _handle(curtain, "curtain/handle", (w.width / 2 - 0.03, -0.02, 0.0))

    def _build_door(self, wall: mujoco.MjsBody) -> None:
        d, t = self.scenario.door, WALL_THICKNESS
        width, height = DOOR_SIZE
        # Hinge on the leaf's left edge; the -z axis makes a positive angle swing into the room.
        leaf = _body(wall, "door", (d.offset - width / 2, t / 2, 0.01))
        _joint(leaf, "door/hinge", mujoco.mjtJoint.mjJNT_HINGE, (0, 0, -1), (0.0, DOOR_TRAVEL),
               friction=2.0, damping=5.0)
        _box(leaf, "door/leaf", (width / 2 - 0.01, 0.02, height / 2), (width / 2, 0, height / 2),
             (0.45, 0.3, 0.18, 1.0), _OBJECT, mass=20.0)
        grip = (width - 0.1, -0.07, 1.0)
        _box(leaf, "door/handle", (0.06, 0.012, 0.012), grip, _METAL, _OBJECT, mass=0.3)
        _handle(leaf, "door/handle", grip)

    def _build_desk(self, spec: mujoco.MjSpec) -> None:
        s = self.scenario
        yaw = np.deg2rad(s.desk.yaw_deg)
        desk = _body(spec.worldbody, "desk", (*s.desk.position, 0.0), yaw)
        top = DESK_HEIGHT
        _box(desk, "desk/top", (0.35, 0.7, 0.015), (0, 0, top - 0.015))
        for i, (x, y) in enumerate(((0.31, 0.65), (0.31, -0.65), (-0.31, 0.65), (-0.31, -0.65))):
            _box(desk, f"desk/leg{i}", (0.025, 0.025, (top - 0.03) / 2), (x, y, (top - 0.03) / 2))
        _box(desk, "desk/keyboard", (0.07, 0.22, 0.01), (-0.17, 0.0, top + 0.01), _DARK)
        _box(desk, "desk/laptop_base", (0.11, 0.16, 0.008), (0.08, 0.1, top + 0.008), _METAL)
        lean = np.deg2rad(-20.0)  # lid tilted back
        _box(desk, "desk/laptop_lid", (0.005, 0.16, 0.11),
             (0.19 + 0.11 * np.sin(-lean), 0.1, top + 0.016 + 0.11 * np.cos(lean)), _METAL,
             quat=[float(np.cos(lean / 2)), 0.0, float(np.sin(lean / 2)), 0.0])
        _box(desk, "desk/notebook", (0.1, 0.075, 0.006), (-0.12, 0.45, top + 0.006),
             (0.7, 0.15, 0.1, 1.0))
        tray = (-0.1, -0.45, top)  # within the seated agent's right-hand reach
        # A flat dish: its base collides; its rim is drawn only, so that a hand pressing
        # inside it reaches the cigarette instead of resting on the rim.
        glass = (0.3, 0.35, 0.4, 0.9)
        _geom(desk, "desk/ashtray", mujoco.mjtGeom.mjGEOM_CYLINDER, (0.06, 0.003),
              (tray[0], tray[1], top + 0.003), glass, _STATIC)
        for i in range(12):
            a = 2 * np.pi * i / 12
            rim = _box(desk, f"desk/ashtray_rim{i}", (0.004, 0.016, 0.008),
                       (tray[0] + 0.058 * np.cos(a), tray[1] + 0.058 * np.sin(a), top + 0.008),
                       glass, quat=_yaw_quat(a))
            rim.contype = rim.conaffinity = 0
        # Cigarette across the tray: slides down (into the ash) when pressed; lit until then.
        cig = _body(desk, "cigarette", (tray[0], tray[1], top + 0.024))
        cig.gravcomp = 1.0  # it rests on the tray's rim: its weight must not press it out
        _joint(cig, "cigarette/press", mujoco.mjtJoint.mjJNT_SLIDE, (0, 0, -1),
               (0.0, CIGARETTE_TRAVEL), friction=0.3, damping=1.0, armature=0.02)
        _geom(cig, "cigarette/body", mujoco.mjtGeom.mjGEOM_CAPSULE, (0.004, 0.035), (0, 0, 0),
              (0.95, 0.95, 0.9, 1.0), _OBJECT, quat=[np.sqrt(0.5), 0.0, np.sqrt(0.5), 0.0],
              mass=0.005)
        _geom(cig, "cigarette/tip", mujoco.mjtGeom.mjGEOM_SPHERE, (0.0045,), (0.037, 0, 0),
              _EMBER, _OBJECT, mass=0.001)
        _handle(cig, "cigarette/handle", (0.0, 0.0, 0.005))
        # The agent's chair: seat top at the agent's seated thigh height. An office chair:
        # seat and back swivel on the base (a hinge with friction), so the seated agent turns
        # by pushing with its feet, and the back turns with it.
        chair = _body(desk, "chair", (*CHAIR_OFFSET, 0.0))
        _joint(chair, "chair/roll", mujoco.mjtJoint.mjJNT_SLIDE, (1, 0, 0),
               (-CHAIR_ROLL, 0.02), friction=CHAIR_ROLL_FRICTION, damping=20.0)
        seat = self.seat_height
        for i, (x, y) in enumerate(((0.19, 0.19), (0.19, -0.19), (-0.19, 0.19), (-0.19, -0.19))):
            _box(chair, f"chair/leg{i}", (0.02, 0.02, (seat - 0.05) / 2),
                 (x, y, (seat - 0.05) / 2), _METAL)
        swivel = _body(chair, "chair_seat", (0.0, 0.0, 0.0))
        _joint(swivel, "chair/swivel", mujoco.mjtJoint.mjJNT_HINGE, (0, 0, 1),
               (-SWIVEL_RANGE, SWIVEL_RANGE), friction=SWIVEL_FRICTION, damping=5.0,
               armature=0.1)
        _box(swivel, "chair/seat", (0.22, 0.22, 0.025), (0, 0, seat - 0.025), _DARK, mass=4.0)
        _box(swivel, "chair/back", (0.02, 0.2, 0.25), (-0.21, 0, seat + 0.3), _DARK, mass=2.0)

    def _build_hifi(self, spec: mujoco.MjSpec) -> None:
        h = self.scenario.hifi
        hifi = _body(spec.worldbody, "hifi", (*h.position, 0.0), np.deg2rad(h.yaw_deg))
        _box(hifi, "hifi/cabinet", (0.2, 0.35, 0.3), (0, 0, 0.3))
        _box(hifi, "hifi/amplifier", (0.18, 0.25, 0.06), (0, 0, 0.66), _DARK)
        for i, y in enumerate((-0.27, 0.27)):
            _box(hifi, f"hifi/speaker{i}", (0.12, 0.07, 0.16), (0, y, 0.76), _DARK)
        # Volume knob on the front face (+x); its hinge axis points out of the face.
        knob = _body(hifi, "hifi_knob", (0.19, 0.12, 0.66))
        knob.gravcomp = 1.0  # the pointer's weight must not turn the knob
        _joint(knob, "hifi/volume", mujoco.mjtJoint.mjJNT_HINGE, (1, 0, 0), (0.0, KNOB_TRAVEL),
               friction=0.05, damping=0.02, armature=0.002)
        _geom(knob, "hifi/knob", mujoco.mjtGeom.mjGEOM_CYLINDER, (0.03, 0.012), (0.012, 0, 0),
              _METAL, _OBJECT, quat=[np.sqrt(0.5), 0.0, np.sqrt(0.5), 0.0], mass=0.05)
        _box(hifi, "hifi/scale", (0.002, 0.045, 0.002), (0.0, 0.12, 0.712), (0.9, 0.9, 0.9, 1))
        pointer = _box(knob, "hifi/pointer", (0.003, 0.003, 0.012), (0.025, 0, 0.016),
                       (1, 1, 1, 1), _OBJECT, mass=0.001)
        pointer.contype = pointer.conaffinity = 0  # a painted mark: a palm lies flat over it
        # The handle is on the knob's face near its rim, off the hinge axis, so that a hand
        # holding it there turns the knob (a grasp on the axis could transmit no torque).
        _handle(knob, "hifi/handle", (0.026, 0.0, KNOB_GRIP_RADIUS))

    def _build_cameras(self, spec: mujoco.MjSpec) -> None:
        hx, hy = self.scenario.room.size[0] / 2, self.scenario.room.size[1] / 2
        # Overview from above the south-west corner towards the room centre.
        _look_at(spec.worldbody, "room", (-hx + 0.2, -hy + 0.2, 2.9), (0.4, 0.3, 0.7))
        dx, dy = self.scenario.desk.position
        yaw = np.deg2rad(self.scenario.desk.yaw_deg)
        fwd = np.array([np.cos(yaw), np.sin(yaw)])
        # Across the desk, facing the seated agent (kept inside the walls).
        eye = np.array([dx, dy]) + 1.0 * fwd + 0.7 * np.array([-fwd[1], fwd[0]])
        eye = np.clip(eye, [-hx + 0.15, -hy + 0.15], [hx - 0.15, hy - 0.15])
        _look_at(spec.worldbody, "agent", (*eye, 1.5), (dx - 0.6 * fwd[0], dy - 0.6 * fwd[1],
                                                        0.9))
        lamp = spec.worldbody.add_light()
        lamp.name = "ceiling"
        lamp.pos = [0.0, 0.0, self.scenario.room.wall_height - 0.1]
        lamp.dir = [0.0, 0.0, -1.0]
        lamp.diffuse = [0.5, 0.5, 0.5]
        lamp.castshadow = False
        # Shadows cost ~7x the frame time of the software (OSMesa) renderer in this scene.
        for light in spec.lights:
            light.castshadow = False

    def _build_user(self, spec: mujoco.MjSpec) -> None:
        """Mocap copies of the user humanoid's bodies, geoms and keypoint sites."""
        m = self.user.model
        ghost = self.scenario.user.appearance == "ghost"
        group = _USER
        for b in range(1, m.nbody):
            body = spec.worldbody.add_body()
            body.name = f"user/{m.body(b).name}"
            body.mocap = True
            for g in range(m.body_geomadr[b], m.body_geomadr[b] + m.body_geomnum[b]):
                rgba = m.geom_rgba[g].copy()
                if ghost:
                    rgba = np.array([0.6, 0.8, 1.0, 0.3])
                geom = _geom(body, f"user/{m.geom(g).name}", mujoco.mjtGeom(m.geom_type[g]),
                             m.geom_size[g], m.geom_pos[g], rgba, group, quat=m.geom_quat[g])
                if ghost:
                    geom.contype = geom.conaffinity = 0
            for site in range(m.nsite):
                if m.site_bodyid[site] == b:
                    st = body.add_site()
                    st.name = f"user/{m.site(site).name}"
                    st.pos = list(m.site_pos[site])
                    st.size = [0.012, 0, 0]
                    st.group = 4

    def _add_grips(self, spec: mujoco.MjSpec) -> None:
        """Two grasp sites on each of the agent's hands: the *grip*, the centre of the hand
        box's medial face (the palm faces the thigh in the rest pose), and the *tip*, just
        beyond the box's fingertip end. Grasps anchor there (see :data:`GRASP_SITE`), so a
        held handle sits on the hand's surface instead of inside its collision box."""
        m = self.agent.model
        for hand in HANDS:
            g = m.geom(hand)
            medial = -1.0 if hand.startswith("left") else 1.0
            body = spec.body(f"agent/{hand}")
            _handle(body, f"agent/{hand}_grip",
                    g.pos + [0.0, medial * (g.size[1] + 0.002), 0.0])
            _handle(body, f"agent/{hand}_tip", g.pos - [0.0, 0.0, g.size[2] + 0.002])

    def _build_grasps(self, spec: mujoco.MjSpec) -> None:
        for obj in ("window", "curtain", "hifi", "cigarette", "door"):
            for hand in HANDS:
                eq = spec.add_equality()
                eq.name = f"grasp/{hand}/{obj}"
                eq.type = mujoco.mjtEq.mjEQ_CONNECT
                eq.objtype = mujoco.mjtObj.mjOBJ_SITE
                eq.name1, eq.name2 = f"agent/{hand}_{GRASP_SITE[obj]}", f"{obj}/handle"
                eq.active = False
                eq.solref = [0.02, 1.0]  # a firm hand (~1.5 cm give pulling a door at 40 N)

    def _index(self) -> None:
        m, s = self.model, self.scenario
        w = s.window.width

        def obj(name: str, joint: str, threshold: float, below: str, above: str) -> RoomObject:
            j = m.joint(joint)
            unit = "m" if j.type[0] == mujoco.mjtJoint.mjJNT_SLIDE else "rad"
            return RoomObject(name, joint, unit, float(j.range[0]), float(j.range[1]),
                              threshold, below, above, int(j.qposadr[0]), int(j.dofadr[0]),
                              f"{name}/handle")

        self.objects: dict[str, RoomObject] = {o.name: o for o in (
            obj("window", "window/slide", 0.10, "closed", "open"),
            obj("curtain", "curtain/slide", 0.75 * w, "open", "closed"),
            obj("hifi", "hifi/volume", 0.5 * KNOB_TRAVEL, "quiet", "loud"),
            obj("cigarette", "cigarette/press", 0.5 * CIGARETTE_TRAVEL, "lit", "out"),
            obj("door", "door/hinge", np.deg2rad(15.0), "closed", "open"),
        )}
        root = m.joint("agent/root")
        qa, va = int(root.qposadr[0]), int(root.dofadr[0])
        self.agent_qpos = slice(qa, qa + self.agent.nq)
        self.agent_qvel = slice(va, va + self.agent.nv)
        a0 = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR,
                               f"agent/{self.agent.joint_names[0]}")
        self.agent_ctrl = slice(a0, a0 + self.agent.model.nu)
        site = mujoco.mjtObj.mjOBJ_SITE
        self.agent_sites = np.array([mujoco.mj_name2id(m, site, f"agent/{k}")
                                     for k in self.agent.keypoint_names])
        self.user_sites = np.array([mujoco.mj_name2id(m, site, f"user/{k}")
                                    for k in self.user.keypoint_names])
        um = self.user.model
        body = mujoco.mjtObj.mjOBJ_BODY
        self._user_mocap = np.array([
            m.body_mocapid[mujoco.mj_name2id(m, body, f"user/{um.body(b).name}")]
            for b in range(1, um.nbody)])
        self._user_data = mujoco.MjData(um)
        self._cigarette_tip = m.geom("cigarette/tip").id
        self._agent_bodies = np.array([b for b in range(m.nbody)
                                       if m.body(b).name.startswith("agent/")])
        self._agent_root = int(m.jnt_dofadr[m.body("agent/pelvis").jntadr[0]])
        self._grasp_eq = {name: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_EQUALITY, name)
                          for name in (f"grasp/{h}/{o}" for h in HANDS for o in self.objects)}
        self._help_eq = self._help_equalities()

    def _help_equalities(self) -> np.ndarray:
        """(neq,) bool: the equality constraints that would be help on the agent (one end on
        its bodies, not a hand's proximity grasp), which :meth:`assist_wrench` measures."""
        m = self.model
        agent = set(self._agent_bodies.tolist())
        grasps = set(self._grasp_eq.values())
        out = np.zeros(m.neq, dtype=bool)
        for eq in range(m.neq):
            ends = {int(m.eq_obj1id[eq]), int(m.eq_obj2id[eq])}
            if m.eq_objtype[eq] == mujoco.mjtObj.mjOBJ_SITE:
                ends = {int(m.site_bodyid[i]) for i in ends}
            out[eq] = eq not in grasps and bool(ends & agent)
        return out

    # -- state ---------------------------------------------------------------

    def make_data(self) -> mujoco.MjData:
        """A new MjData in the scenario's initial state (see :meth:`reset`)."""
        data = mujoco.MjData(self.model)
        self.reset(data)
        return data

    def reset(self, data: mujoco.MjData) -> None:
        """Initial state: the agent seated with its PD targets at the seated pose, the
        objects as the scenario says, the user standing at its place in the rest pose."""
        mujoco.mj_resetData(self.model, data)
        s = self.scenario
        q = self.seated_pose()
        data.qpos[self.agent_qpos] = q
        data.ctrl[self.agent_ctrl] = q[self.agent.hinge_qpos]
        w = s.window.width
        for name, value in (("window", s.window.open), ("curtain", s.curtain.closed * w),
                            ("hifi", s.hifi.volume * KNOB_TRAVEL),
                            ("cigarette", 0.0 if s.cigarette.lit else CIGARETTE_TRAVEL),
                            ("door", np.deg2rad(s.door.angle_deg))):
            self.set_object_state(data, name, value)
        self.set_user_pose(data, self.place_user(self.user.default_qpos()[None])[0])
        mujoco.mj_forward(self.model, data)

    def object_states(self, data: mujoco.MjData) -> dict[str, float]:
        """Object name -> joint value (m or rad, see the module table)."""
        return {n: float(data.qpos[o.qpos_adr]) for n, o in self.objects.items()}

    def wall_slide_frame(self, data: mujoco.MjData, name: str
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Geometry of a slide object on a wall (the window pane, the curtain) in the state
        ``data``: its handle (3,), the slide's +axis along the wall (3,), the wall's inward
        normal (3,), all world frame, and the slide's position now, m."""
        m, o = self.model, self.objects[name]
        jnt = m.joint(o.joint).id
        wall = data.xmat[m.body_parentid[m.jnt_bodyid[jnt]]].reshape(3, 3)
        inward = -wall[:, 1]  # the wall frames' +y points out of the room
        return (data.site_xpos[m.site(o.handle).id].copy(), data.xaxis[jnt].copy(), inward,
                float(data.qpos[o.qpos_adr]))

    def object_labels(self, data: mujoco.MjData) -> dict[str, str]:
        """Object name -> state label (``open``/``closed``, ``loud``/``quiet``, ...)."""
        return {n: o.label(float(data.qpos[o.qpos_adr])) for n, o in self.objects.items()}

    def set_object_state(self, data: mujoco.MjData, name: str, value: float) -> None:
        """Put object ``name`` at joint value ``value`` at rest (qvel 0). Derived quantities
        (positions, contacts) update at the next ``mj_forward``/``mj_step``.

        Raises:
            SimenvError: unknown object, or ``value`` outside the joint's range.
        """
        if name not in self.objects:
            raise SimenvError(f"unknown room object {name!r}; objects: {list(self.objects)}",
                              field=name)
        o = self.objects[name]
        if not np.isfinite(value) or not o.lower - 1e-9 <= value <= o.upper + 1e-9:
            raise SimenvError(f"{name} state {value!r} {o.unit} is outside its range "
                              f"[{o.lower:.4g}, {o.upper:.4g}] {o.unit}", field=name)
        data.qpos[o.qpos_adr] = value
        data.qvel[o.dof_adr] = 0.0

    # -- agent ---------------------------------------------------------------

    def seated_pose(self) -> np.ndarray:
        """(nq_agent,) the agent sitting on the chair facing the desk: hips and knees at
        90 degrees, feet flat on the floor, upper arms slightly forward, elbows bent."""
        h, s = self.agent, self.scenario
        q = h.default_qpos()
        yaw = np.deg2rad(s.desk.yaw_deg)
        c, sn = np.cos(yaw), np.sin(yaw)
        cx, cy = CHAIR_OFFSET[0] + 0.03, CHAIR_OFFSET[1]
        dx, dy = s.desk.position
        q[:3] = [dx + c * cx - sn * cy, dy + sn * cx + c * cy, _seated_pelvis_height(h.dims)]
        q[3:7] = _yaw_quat(yaw)
        angles = {"thigh_flex": np.pi / 2, "shin_flex": np.pi / 2, "upper_arm_flex": 0.35,
                  "forearm_flex": 1.3}
        for i, name in enumerate(h.joint_names):
            for suffix, a in angles.items():
                if name.endswith(suffix):
                    q[h.hinge_qpos[i]] = a
        return q

    def agent_keypoints(self, data: mujoco.MjData) -> np.ndarray:
        """(K, 3) the agent's keypoints, m (after ``mj_forward``/``mj_step``)."""
        return data.site_xpos[self.agent_sites].copy()

    def set_grasp(self, data: mujoco.MjData, hand: str, name: str, on: bool) -> bool:
        """Close (``on``) or open the proximity grasp of ``hand`` on object ``name``.

        A grasp closes only when the hand's grasp site (:data:`GRASP_SITE`: palm centre or
        fingertips) is within :data:`GRASP_RADIUS` of the object's handle; returns whether
        the grasp is now closed.
        """
        key = f"grasp/{hand}/{name}"
        if key not in self._grasp_eq:
            raise SimenvError(f"no grasp {key!r}; hands {list(HANDS)}, objects "
                              f"{list(self.objects)}", field=key)
        eq = self._grasp_eq[key]
        if on:
            hand_pos = data.site_xpos[mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE,
                                                         f"agent/{hand}_{GRASP_SITE[name]}")]
            handle = data.site_xpos[mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE,
                                                      self.objects[name].handle)]
            on = float(np.linalg.norm(hand_pos - handle)) <= GRASP_RADIUS
        data.eq_active[eq] = on
        return on

    def assist_wrench(self, data: mujoco.MjData) -> tuple[float, float]:
        """External help on the agent now: the largest force (N) and torque (N m) put on
        any of its bodies from outside its own servos and contacts, ``xfrc_applied`` on
        its bodies and ``qfrc_applied`` on its free joint (translation, rotation); and the
        force (N) of any active equality constraint on it other than the hands' proximity
        grasps. The room has no assistance mechanism (walking and standing are the
        agent's own, :mod:`simenv.agents.gait`); this measures that nothing added one.
        """
        x = data.xfrc_applied[self._agent_bodies]
        root = data.qfrc_applied[self._agent_root:self._agent_root + 6]
        force = torque = 0.0
        if x.any() or root.any():  # (called every physics step: the norms only when needed)
            force = max(float(np.linalg.norm(x[:, :3], axis=1).max()),
                        float(np.linalg.norm(root[:3])))
            torque = max(float(np.linalg.norm(x[:, 3:], axis=1).max()),
                         float(np.linalg.norm(root[3:])))
        for eq in np.flatnonzero(data.eq_active & self._help_eq):
            rows = np.flatnonzero(
                (data.efc_type[:data.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
                & (data.efc_id[:data.nefc] == eq))
            force = max(force, float(np.linalg.norm(data.efc_force[rows][:3])))
        return force, torque

    def grasp_force(self, data: mujoco.MjData) -> float:
        """The largest force (N) of the hands' active proximity grasps at the last step
        (their constraint rows' ``efc_force``, translation): what a held handle pushes or
        pulls on the hand with, 0 with no grasp closed. A grasp is the hand holding an
        object, not help; it is measured so that a hand hanging on a handle shows."""
        out = 0.0
        for eq in self._grasp_eq.values():
            if not data.eq_active[eq]:
                continue
            rows = np.flatnonzero(
                (data.efc_type[:data.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
                & (data.efc_id[:data.nefc] == eq))
            out = max(out, float(np.linalg.norm(data.efc_force[rows][:3])))
        return out

    # -- user ----------------------------------------------------------------

    def place_user(self, qpos: np.ndarray) -> np.ndarray:
        """Move a user trajectory (T, nq_user) to the scenario's place: rotated about z and
        translated so that frame 0's pelvis stands at ``user.position`` (x, y; its height
        is kept) facing ``user.yaw_deg``. The motion's shape is unchanged."""
        q = np.asarray(qpos, dtype=float)
        if q.ndim != 2 or q.shape[1] != self.user.nq:
            raise SimenvError(f"user qpos must be (T, {self.user.nq}); got {q.shape}",
                              field="qpos")
        u = self.scenario.user
        return place_on_floor(q, u.position, np.deg2rad(u.yaw_deg))

    def set_user_pose(self, data: mujoco.MjData, qpos: np.ndarray) -> None:
        """Drive the user's mocap bodies to one configuration (nq_user,) of the user's
        humanoid, already placed in the room (see :meth:`place_user`)."""
        d = self._user_data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(self.user.model, d)
        data.mocap_pos[self._user_mocap] = d.xpos[1:]
        data.mocap_quat[self._user_mocap] = d.xquat[1:]

    def user_keypoints(self, data: mujoco.MjData) -> np.ndarray:
        """(K, 3) the user's keypoints, m (after ``mj_forward``/``mj_step``)."""
        return data.site_xpos[self.user_sites].copy()

    # -- measurements --------------------------------------------------------

    def facing_deg(self, data: mujoco.MjData) -> float:
        """Angle on the floor between the agent's chest forward axis and the direction from
        its chest to the user's chest, degrees (0 = facing the user)."""
        names = self.agent.keypoint_names
        agent, user = self.agent_keypoints(data), self.user_keypoints(data)
        chest = self.model.body("agent/chest").id
        forward = data.xmat[chest].reshape(3, 3)[:2, 0]
        to_user = user[names.index("chest"), :2] - agent[names.index("chest"), :2]
        cos = forward @ to_user / max(np.linalg.norm(forward) * np.linalg.norm(to_user), 1e-9)
        return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))

    def head_pitch_deg(self, data: mujoco.MjData) -> float:
        """How far the agent's head looks down, degrees: the angle of its forward (x) axis
        below the horizontal, ``asin(-x_z)`` (0 level, positive looking down)."""
        x_z = data.xmat[self.model.body("agent/head").id][6]  # row z, column x
        return float(np.degrees(np.arcsin(np.clip(-x_z, -1.0, 1.0))))

    def greeting(self, data: mujoco.MjData) -> dict[str, float | bool]:
        """Whether the agent greets the user now (the issue's success rule).

        ``facing_deg``: :meth:`facing_deg`; ``hand_above_shoulder``: a hand keypoint
        higher than the same side's shoulder; ``success``: facing within
        :data:`GREET_FACING_DEG` and a hand raised.
        """
        names = self.agent.keypoint_names
        agent = self.agent_keypoints(data)
        facing = self.facing_deg(data)
        raised = any(agent[names.index(f"{s}_hand"), 2] > agent[names.index(f"{s}_shoulder"), 2]
                     for s in ("left", "right"))
        return {"facing_deg": facing, "hand_above_shoulder": bool(raised),
                "success": bool(facing <= GREET_FACING_DEG and raised)}

    def bow_meter(self) -> BowMeter:
        """A new :class:`BowMeter` (start it with the bow, then call it every step)."""
        return BowMeter(self)

    def sync_visuals(self, data: mujoco.MjData) -> None:
        """Colour state that is not geometry: the cigarette's tip glows while it is lit.
        (Writes ``model.geom_rgba``; call before rendering.)"""
        lit = self.object_labels(data)["cigarette"] == "lit"
        self.model.geom_rgba[self._cigarette_tip] = _EMBER if lit else _ASH


class BowMeter:
    """Whether the agent has bowed (or nodded) to the user, measured step by step.

    The reference is the head pitch ``p_ref`` (:meth:`Room.head_pitch_deg`) at the first
    step the chest faces the user within :data:`GREET_FACING_DEG` (:meth:`Room.facing_deg`),
    so that the forward lean a seated turn brings (measured: ~20 deg of head pitch in a
    greeting) is not counted as a bow. With ``dip = p - p_ref``, the agent *bowed* once
    ``dip >=`` :data:`BOW_DIP_DEG` at a step where it faces the user; the bow *succeeds* at
    the first later step where the head has come back up, ``dip <=`` :data:`BOW_RETURN_DEG`.
    Calling the meter with the simulation state returns ``facing_deg``, ``dip_deg`` (None
    before the agent faced the user), ``bowed`` and ``success`` (both latched);
    ``dip_max_deg`` keeps the deepest dip.
    """

    def __init__(self, room: Room) -> None:
        self.room = room
        self.ref_pitch_deg: float | None = None
        self.bowed = self.success = False
        self.dip_max_deg = 0.0

    def __call__(self, data: mujoco.MjData) -> dict[str, float | bool | None]:
        facing = self.room.facing_deg(data)
        pitch = self.room.head_pitch_deg(data)
        facing_user = facing <= GREET_FACING_DEG
        if self.ref_pitch_deg is None and facing_user:
            self.ref_pitch_deg = pitch
        dip = None if self.ref_pitch_deg is None else pitch - self.ref_pitch_deg
        if dip is not None:
            self.dip_max_deg = max(self.dip_max_deg, dip)
            if dip >= BOW_DIP_DEG and facing_user:
                self.bowed = True
            elif self.bowed and dip <= BOW_RETURN_DEG:
                self.success = True
        return {"facing_deg": facing, "dip_deg": dip, "bowed": self.bowed,
                "success": self.success}


# ---------------------------------------------------------------------------
# Small pieces of geometry
# ---------------------------------------------------------------------------


def _wall_slabs(holes: list[tuple[float, float, float, float]], half_len: float,
                height: float) -> list[tuple[float, float, float, float]]:
    """Boxes (u0, u1, z0, z1) of a wall from -half_len to half_len along it, cut around
    non-overlapping rectangular openings (u0, u1, z0, z1): full-height slabs between the
    openings, and a slab below and above each one."""
    slabs, cursor = [], -half_len
    for u0, u1, z0, z1 in sorted(holes):
        slabs += [(cursor, u0, 0.0, height), (u0, u1, 0.0, z0), (u0, u1, z1, height)]
        cursor = u1
    slabs.append((cursor, half_len, 0.0, height))
    return [b for b in slabs if b[1] - b[0] > 1e-6 and b[3] - b[2] > 1e-6]


def place_on_floor(qpos: np.ndarray, position: Sequence[float], yaw: float) -> np.ndarray:
    """A free-root trajectory (T, nq) turned about z and shifted so that frame 0's root is
    at ``position`` (x, y, m; height kept) with heading ``yaw`` (rad); a copy."""
    q = np.array(qpos, dtype=float, copy=True)
    q[:, :3] = place_points(q[:, :3], q[0], position, yaw)
    q[:, 3:7] = _quat_mul(np.array(_yaw_quat(yaw - _heading(q[0, 3:7]))), q[:, 3:7])
    return q


def place_points(points: np.ndarray, q0: np.ndarray, position: Sequence[float], yaw: float
                 ) -> np.ndarray:
    """World points (N, 3), m, moved as :func:`place_on_floor` moves a trajectory whose
    frame 0 is ``q0`` (nq,): turned about z by ``yaw`` minus ``q0``'s heading about
    ``q0``'s root, which lands on ``position``; heights kept. E.g. where a recording's
    sensor stands once its subject is placed in the room."""
    p = np.array(points, dtype=float, copy=True)
    turn = yaw - _heading(np.asarray(q0, dtype=float)[3:7])
    c, sn = np.cos(turn), np.sin(turn)
    xy = p[:, :2] - np.asarray(q0, dtype=float)[:2]
    p[:, 0] = c * xy[:, 0] - sn * xy[:, 1] + position[0]
    p[:, 1] = sn * xy[:, 0] + c * xy[:, 1] + position[1]
    return p


def _scaled_default(height: float) -> BodyDimensions:
    factor = height / DEFAULT.height
    return BodyDimensions.from_scale(dict.fromkeys(BONES, factor))


def _seated_pelvis_height(d: BodyDimensions) -> float:
    """Pelvis height with thighs horizontal, shins vertical and soles on the floor, m."""
    hip_z = max(d.left_hip_offset[2], d.right_hip_offset[2])
    return float(-hip_z + max(d.left_shin, d.right_shin) + d.ankle_height)


def _seat_height(d: BodyDimensions) -> float:
    """Chair seat top under the seated agent: the lower of the pelvis capsule and the
    thigh capsules (radii as in :func:`simenv.body.humanoid.add_person`), m."""
    hip_z = min(d.left_hip_offset[2], d.right_hip_offset[2])
    bottom = min(hip_z + 0.02 - 0.085 * d.girth, hip_z - 0.066 * d.girth)
    return _seated_pelvis_height(d) + bottom


def _heading(quat: np.ndarray) -> float:
    """Yaw (rad) of a body's x axis projected on the floor."""
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat, dtype=float))
    return float(np.arctan2(mat[3], mat[0]))


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b for one quaternion ``a`` (4,) and many ``b`` (T, 4)."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b.T
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=-1)


def _look_at(parent: mujoco.MjsBody, name: str, eye: Sequence[float],
             target: Sequence[float]) -> None:
    """A fixed camera at ``eye`` looking at ``target`` (MuJoCo cameras look along -z,
    with y up in the image)."""
    eye_v, tgt = np.asarray(eye, float), np.asarray(target, float)
    back = eye_v - tgt
    back /= np.linalg.norm(back)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.column_stack([right, up, back]).ravel())
    cam = parent.add_camera()
    cam.name = name
    cam.pos = list(eye_v)
    cam.quat = list(quat)
    cam.fovy = 60.0


__all__ = ["BOW_DIP_DEG", "BOW_RETURN_DEG", "GRASP_RADIUS", "GRASP_SITE", "GREET_FACING_DEG",
           "HANDS", "KNOB_GRIP_RADIUS", "KNOB_TRAVEL", "BowMeter", "Room", "RoomObject",
           "place_on_floor", "place_points"]

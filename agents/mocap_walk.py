"""Walking at a person's pace by replaying real walking motion capture, tracked once
offline by the unassisted planner, with time-varying feedback.

The library (``assets/walk-primitives/mocap_walk.json``, built by
``benchmarks/build_mocap_walk.py`` from the bundled CMU 02_01 walk) holds walking
*primitives* cut from one tracking run of the sampling MPC
(:class:`simenv.control.TrackingMPC`, nothing acting on the root) on the room agent's own
body: a start from standing, straight gait cycles, a cycle bending left or right
(:data:`TURN_DEG` each), and a stop to standing; each as the planner's servo targets
``u*`` and the states ``x*`` the body went through, every :attr:`Library.stride` physics
steps, and time-varying LQR gains ``K`` (on ``mjd_transitionFD`` linearisations about
``x*``, for the legs' and the lumbar spine's servos) stored as a low-rank time basis.

At run time nothing is planned. The tracking run started from the standing body the room
gives (:func:`simenv.agents.gait.standing_agent`: the rest pose balanced 1 s), so the start
fits the room's standing agent (bringing it first onto the start's first targets with the
stepping gait's balance instead made it fall, measured). A primitive is placed on the
floor where the body is when it starts (turned about the vertical and shifted so that its
legs' and pelvis's keypoints, :data:`ANCHOR_KEYPOINTS`, lie nearest the measured ones,
:func:`fit_frame`: a flat floor's physics does not change under either), and every physics
step the servo targets are ::

    u = u*(t) - K(t) dx,   dx = (mj_differentiatePos(x*_q, x_q), x_v - x*_v)

(``x*`` interpolated between its stored steps). The feedback absorbs what differs from the
offline run: the room's model and the body's drift. It does not absorb a seam between two
states of the tracked run: pieces join only where one starts on the other's last tracked
state (:func:`seam_rms` within :data:`SEAM_TOL_RAD`, :attr:`Anchors.join`), i.e. in the
order they were tracked (``start`` -> ``half_c`` -> ``half_b`` -> ``half_a`` / ``straight``
-> ``half_d`` / ``left``, each half cycle ending at the left or the right foot's mid-swing,
:attr:`Primitive.phase_in` / :attr:`Primitive.phase_out`), and a stop after a piece whose
last state it was tracked from. Joining any two pieces at the same gait phase (one cycle's
end state is 0.12-0.2 rad rms from another cycle's start, up to 0.64 rad at a foot; a
mirrored piece's up to 1.7 rad at the neck) fell in 4 of 8 composed walks on open floor,
and blending the reference across such a seam (the offset fading over 0.3 or 0.6 s) in 6-8
of 8 (measured). Every primitive also exists mirrored left to right (:func:`mirror`), so
the right bend is the tracked left one reflected and a walk can start on either foot;
mirrored pieces join mirrored ones. :func:`compose` picks the sequence whose predicted end
(:class:`Anchors`) is nearest the goal, and at every seam :class:`MocapWalkPlan` re-picks
the rest of the walk (stop now or walk on, and how) from where the body really is.

Replayed in the room from the tracked run's own first state, the stored targets alone
reproduce the tracked run to the millimetre for 5 s (the room's agent is the same model;
measured): the feedback is for everything else.

Nothing but the agent's servos and its contacts acts on it: the plan's feedback is a
:class:`~simenv.agents.walk.GaitMeter`, which measures the external help (0 N) and the
pelvis's height every physics step.

Stops: tracked from a piece's last tracked state (:attr:`Primitive.after`), one per piece
(``stop_after_<name>``; ``half_d`` ends on ``straight``'s last state and shares its stop)
and, after the pieces ending at a right mid-swing, a shorter *halt* (``halt_after_<name>``:
the stop after a right mid-swing walks a whole cycle more, 1.5 m against 0.9 m).

Measured (``benchmarks/bench_mocap_walk.py``, 1 thread, shared machine; table in
docs/room.md): on eight open-floor goals no walk falls (4 of 8 fell when any two pieces at
the same phase could join), 0 N of help on every physics step, 0.08-0.13 CPU seconds per
simulated second; straight ahead it ends 0.12-0.28 m from the goal at 0.40-0.64 m/s net
standing to standing (the stepping gait: 0.05 m, 0.04 m/s); it walks where the body faces
(goals 1-1.5 m aside missed by 1.0-1.3 m, 0.25-0.35 m after a stepping turn on the spot).
Its shortest walk is 1.54 m; in the room the walk to the window falls. It ends in stride,
a stance the stepping gait cannot take over from (its first weight shift is out of the
legs' reach), so it is not wired into the room's reactions.

:class:`PersonWalk` puts the stepping gait around it: a turn on the spot to face the goal,
the walk only where it gains (its predicted end 0.3 m nearer the goal, passing it by at
most :data:`OVERSHOOT_M`), else the stepping gait the whole way (the walk to the window: no
fall, 0.05 m off, at 0.04 m/s). Closing stops that end with the feet close and the pelvis
upright, tracked from real motion capture of a person stopping and then onto the stepping
gait's stance (``build_mocap_walk.py --close``, :data:`CLOSE_STOP`), let the stepping gait
take over straight ahead in one library of three (4 of 5 open-floor walks 0.023-0.059 m
from the goal), never after a stepping turn (measured; docs/room.md), so they are not
bundled and the walk still ends 0.1-0.9 m off the goal.
"""

from __future__ import annotations

import base64
import json
import zlib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np

from simenv.agents.gait import quat_yaw
from simenv.agents.walk import GaitMeter, check_standing
from simenv.assets import assets_root
from simenv.body.humanoid import Humanoid
from simenv.core.errors import SimenvError
from simenv.room.room import Room

#: The library's file, in the package's assets (JSON: arrays as base64 of their zlib-packed
#: little-endian bytes; a folder holding an ``.npz`` would be listed as a motion asset).
LIBRARY = ("walk-primitives", "mocap_walk.json")
#: Heading change of one bend cycle, deg (as the library was built).
TURN_DEG = 15.0
#: Largest number of gait cycles between the start and the stop that :func:`compose`
#: considers.
MAX_CYCLES = 4
#: :func:`compose`'s price of a second of walking, in metres of distance from the goal.
SECOND_M = 0.02
#: Standing still after the stop, balanced by the stop's last feedback, s.
SETTLE_S = 0.5
#: The feedback's largest change of a servo target, rad.
FEEDBACK_CLIP_RAD = 0.3
#: Hinges (name parts) whose error the feedback ignores (besides the neck's).
UNFED = ("clavicle", "upper_arm", "forearm", "hand")
#: Body dimensions may differ from the library's by this much (m) and still replay.
DIMS_TOL_M = 1e-3
#: Largest seam (:func:`seam_rms`) a composed walk may have, rad: pieces join only where
#: the first starts on the other's last tracked state (float32 storage: 1e-7 rad).
SEAM_TOL_RAD = 1e-3
#: The name prefix of the closing stops (``close_after_<piece>``: tracked from real motion
#: capture of a person coming to rest with a short last step, then onto the stepping
#: gait's upright stance; ``benchmarks/build_mocap_walk.py --close``, not in the bundled
#: library: no walk after a stepping turn arrived with them, measured).
CLOSE_STOP = "close_after_"


def _yaw_quat(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def _rot(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


@dataclass(frozen=True)
class Primitive:
    """One walking primitive (module docstring).

    Attributes:
        name: its name in the library. qpos: (N, nq) the tracked agent's states every
            ``stride`` physics steps (the last one is where the next primitive starts),
            m / rad, in the offline run's frame; qvel: (N, nv) m/s, rad/s; ctrl: (N, nu)
            the servo targets, rad. coef: (N, r) the gains' coefficients on the library's
            basis. phase_in, phase_out: the foot at mid-swing at its start and end
            (``"left"``, ``"right"``, or ``"stand"``). advance: (3,) where its last pelvis
            pose is relative to its first, in the first's heading frame (forward m, left
            m, turn rad). mirrored: the tracked primitive reflected left to right
            (:func:`mirror`; its gains are on the library's mirrored basis). after: for a
            stop, the primitive it was tracked after (it starts on that one's last state
            and follows only a piece ending there, :attr:`Anchors.join`), else None.
    """

    name: str
    qpos: np.ndarray
    qvel: np.ndarray
    ctrl: np.ndarray
    coef: np.ndarray
    phase_in: str
    phase_out: str
    advance: np.ndarray
    mirrored: bool = False
    after: str | None = None

    @property
    def knots(self) -> int:
        """Stored steps spanned (its duration is ``knots * stride`` physics steps)."""
        return len(self.qpos) - 1


@dataclass(frozen=True)
class Library:
    """The primitives and what they share.

    Attributes:
        primitives: name -> :class:`Primitive`. basis: (r, m, 2 nv) the gains' basis
            (``K = coef @ basis``). feedback_ctrl: (m,) the actuators the gains drive (the
            legs and the lumbar spine; the others follow ``u*``). stride: physics steps
            between stored steps. dt: the physics step, s. dims: (D,) the body's
            dimensions the library was built for, m. meta: how it was built (JSON).
    """

    primitives: dict[str, Primitive]
    basis: np.ndarray
    basis_mirrored: np.ndarray
    feedback_ctrl: np.ndarray
    stride: int
    dt: float
    dims: np.ndarray
    meta: dict

    def gain(self, p: Primitive, k: int) -> np.ndarray:
        """(m, 2 nv) the feedback gain of ``p``'s stored step ``k``."""
        basis = self.basis_mirrored if p.mirrored else self.basis
        return np.tensordot(p.coef[min(k, len(p.coef) - 1)], basis, axes=1)

    def seconds(self, name: str) -> float:
        """Duration of primitive ``name``, s."""
        return self.primitives[name].knots * self.stride * self.dt


def _swap(name: str) -> str:
    return name.replace("left_", "@").replace("right_", "left_").replace("@", "right_")


#: Hinges on the body's midline whose angle changes sign in a left-right reflection (the
#: others are either sagittal or have a mirrored twin on the other side, measured on the
#: fitted humanoid: every geom lands on its twin's reflection).
_MIDLINE_ODD = ("lumbar_lat", "lumbar_rot", "thorax_lat", "thorax_rot", "chest_lat",
                "chest_rot", "neck_lat", "neck_rot")


def _reflection(names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Index and sign of each hinge's image under the left-right reflection."""
    idx = np.array([names.index(_swap(n)) for n in names])
    sign = np.array([-1.0 if n in _MIDLINE_ODD else 1.0 for n in names])
    return idx, sign


def mirror(qpos: np.ndarray, qvel: np.ndarray, ctrl: np.ndarray, hinges: list[str]
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A trajectory reflected left to right in its frame (y -> -y): the free root's
    position and orientation (quaternion (w, x, y, z) -> (w, -x, y, -z)), its velocities
    (linear in the world, angular in the pelvis's frame), every hinge's angle, velocity
    and servo target exchanged with its twin's, midline lateral bends and twists negated.
    Shapes (N, 7 + n), (N, 6 + n), (N, n) in and out (the actuators in hinge order)."""
    idx, sign = _reflection(hinges)
    q, v = qpos.copy(), qvel.copy()
    q[:, 1] *= -1
    q[:, 4] *= -1
    q[:, 6] *= -1
    q[:, 7:] = qpos[:, 7:][:, idx] * sign
    v[:, [1, 3, 5]] *= -1
    v[:, 6:] = qvel[:, 6:][:, idx] * sign
    return q, v, ctrl[:, idx] * sign


def _mirror_gains(basis: np.ndarray, fb: np.ndarray, hinges: list[str]) -> np.ndarray:
    """(r, m, 2 nv) gains ``K' = M_u K M_x^T`` of the reflected system (``M`` the signed
    permutations of :func:`mirror` on the targets ``fb`` and on the state)."""
    idx, sign = _reflection(hinges)
    n = len(hinges)
    root_sign = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0])
    half_idx = np.concatenate([np.arange(6), 6 + idx])
    half_sign = np.concatenate([root_sign, sign])
    nv = 6 + n
    x_idx = np.concatenate([half_idx, nv + half_idx])
    x_sign = np.concatenate([half_sign, half_sign])
    fb_list = list(fb)
    rows = np.array([fb_list.index(idx[a]) for a in fb])
    return basis[:, rows][:, :, x_idx] * sign[fb][None, :, None] * x_sign[None, None, :]


def body_signature(h: Humanoid) -> np.ndarray:
    """(D,) the body's dimensions (lengths and offsets, m) in a fixed order: a library
    replays on the body it was built for."""
    out: list[float] = []
    for v in h.dims.to_dict().values():
        if isinstance(v, float):
            out.append(v)
        elif isinstance(v, list) and all(isinstance(x, float) for x in v):
            out.extend(v)
    return np.array(out, float)


def pack_array(a: np.ndarray) -> dict:
    """``a`` as JSON: dtype, shape and base64 of its zlib-packed little-endian bytes."""
    a = np.ascontiguousarray(a)
    dt = a.dtype.newbyteorder("<")
    return {"dtype": dt.str, "shape": list(a.shape),
            "data": base64.b64encode(zlib.compress(a.astype(dt).tobytes(), 9)).decode()}


def unpack_array(d: dict) -> np.ndarray:
    """The array :func:`pack_array` wrote."""
    raw = zlib.decompress(base64.b64decode(d["data"]))
    return np.frombuffer(raw, dtype=np.dtype(d["dtype"])).reshape(d["shape"])


@lru_cache(maxsize=4)
def load_library(path: str | None = None) -> Library:
    """The walking primitives (module docstring) from ``path`` (default: the bundled
    :data:`LIBRARY`).

    Raises:
        SimenvError: the file is missing, not the library's JSON, or lacks an array.
    """
    file = Path(path) if path is not None else assets_root().joinpath(*LIBRARY)
    if not file.is_file():
        raise SimenvError(f"{file}: no walking primitives (build them with "
                          "benchmarks/build_mocap_walk.py)", field="library")
    try:
        doc = json.loads(file.read_text())
        meta, arrays = doc["meta"], doc["arrays"]
    except (ValueError, KeyError, TypeError) as exc:
        raise SimenvError(f"{file}: not a walking-primitive library ({exc})",
                          field="library") from None

    def get(key: str) -> np.ndarray:
        if key not in arrays:
            raise SimenvError(f"{file}: the library lacks {key!r}", field=key)
        return unpack_array(arrays[key]).astype(float)

    other = {"left": "right", "right": "left", "stand": "stand"}
    hinges = list(meta["joint_names"])
    prims = {}
    for name, info in meta["primitives"].items():
        parts = [get(f"{name}_{k}") for k in ("qpos", "qvel", "ctrl", "coef")]
        adv = np.array(info["advance"], float)
        after = info.get("after")
        prims[name] = Primitive(name, *parts, info["phase_in"], info["phase_out"], adv,
                                after=after)
        mq, mv, mu = mirror(*parts[:3], hinges)
        prims[f"{name}_mirrored"] = Primitive(
            f"{name}_mirrored", mq, mv, mu, parts[3], other[info["phase_in"]],
            other[info["phase_out"]], adv * [1.0, -1.0, -1.0], mirrored=True,
            after=None if after is None else f"{after}_mirrored")
    basis = get("gain_basis")
    fb = get("feedback_ctrl").astype(int)
    return Library(prims, basis, _mirror_gains(basis, fb, hinges), fb, int(meta["stride"]),
                   float(meta["dt"]), get("dims"), meta)


def _check_body(room: Room, lib: Library) -> None:
    dims = body_signature(room.agent)
    if dims.shape != lib.dims.shape or np.abs(dims - lib.dims).max() > DIMS_TOL_M:
        raise SimenvError("the walking primitives were built for another body (rebuild them "
                          "with benchmarks/build_mocap_walk.py for this agent)", field="agent")


#: The keypoints a primitive is placed on the body by (the legs and the pelvis: the arms
#: swing, and the pelvis alone twists up to 25 deg either way in the tracked walk).
ANCHOR_KEYPOINTS = ("pelvis", "left_hip", "right_hip", "left_knee", "right_knee",
                    "left_ankle", "right_ankle", "left_toe", "right_toe")

Frame = tuple[float, np.ndarray]
"""A placement on the floor: turn about the vertical (rad) and shift (2,) m, ``x -> R x + t``."""


def fit_frame(src: np.ndarray, dst: np.ndarray) -> Frame:
    """The placement taking the points ``src`` (K, 2) nearest ``dst`` (K, 2) (least squares,
    2D Procrustes without scaling)."""
    ps, pd = src.mean(axis=0), dst.mean(axis=0)
    h = (src - ps).T @ (dst - pd)
    psi = float(np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1]))
    return psi, pd - _rot(psi) @ ps


def _then(a: Frame, b: Frame) -> Frame:
    """``a`` after ``b``: x -> a(b(x))."""
    return a[0] + b[0], _rot(a[0]) @ b[1] + a[1]


def seam_rms(a: Primitive, b: Primitive) -> float:
    """Root mean square of the hinge angles' differences (rad) between ``a``'s last
    stored state and ``b``'s first."""
    return float(np.sqrt(np.mean((a.qpos[-1, 7:] - b.qpos[0, 7:]) ** 2)))


class Anchors:
    """Where each primitive of ``lib`` has ``h``'s :data:`ANCHOR_KEYPOINTS` on the floor at
    its first and last stored step ((K, 2), m), and the placements joining them: ``join[a,
    b]`` takes ``b``'s coordinates into ``a``'s with ``b``'s first pose on ``a``'s last,
    for the pairs that may join (``b`` starts on ``a``'s last tracked state: phases equal,
    :func:`seam_rms` within :data:`SEAM_TOL_RAD`)."""

    def __init__(self, lib: Library, h: Humanoid) -> None:
        names = list(h.keypoint_names)
        idx = [names.index(k) for k in ANCHOR_KEYPOINTS]
        self.lib = lib
        self.first = {n: h.keypoints(p.qpos[0])[idx, :2] for n, p in lib.primitives.items()}
        self.last = {n: h.keypoints(p.qpos[-1])[idx, :2] for n, p in lib.primitives.items()}
        self.end = {n: p.qpos[-1, :2].copy() for n, p in lib.primitives.items()}
        self.join: dict[tuple[str, str], Frame] = {}
        for a, pa in lib.primitives.items():
            for b, pb in lib.primitives.items():
                if pa.phase_out == pb.phase_in != "stand" and seam_rms(pa, pb) <= SEAM_TOL_RAD:
                    self.join[a, b] = fit_frame(self.first[b], self.last[a])
        self.sites = idx

    def predicted_end(self, names: list[str], frame: Frame) -> np.ndarray:
        """(2,) where the pelvis ends after the primitives ``names``, the first placed by
        ``frame``, m."""
        f = frame
        for a, b in zip(names, names[1:], strict=False):
            f = _then(f, self.join[a, b])
        return _rot(f[0]) @ self.end[names[-1]] + f[1]


def _sequences(anchors: Anchors, max_cycles: int, stop: str | None = None
               ) -> list[list[str]]:
    """Every sequence start .. stop with at most ``max_cycles`` primitives between them
    whose seams all join (:attr:`Anchors.join`: the same tracked state); with ``stop``,
    only those whose stop's name starts with it (e.g. :data:`CLOSE_STOP`)."""
    prims = anchors.lib.primitives
    nxt: dict[str, list[str]] = {}
    for a, b in anchors.join:
        nxt.setdefault(a, []).append(b)
    out: list[list[str]] = []

    def extend(seq: list[str], depth: int) -> None:
        for n in nxt.get(seq[-1], []):
            if prims[n].phase_out == "stand":
                if stop is None or n.startswith(stop):
                    out.append([*seq, n])
            elif depth < max_cycles:
                extend([*seq, n], depth + 1)

    for n, p in prims.items():
        if p.phase_in == "stand":
            extend([n], 0)
    return out


def _passes(origin: np.ndarray, goal: np.ndarray, end: np.ndarray,
            overshoot_m: float | None) -> bool:
    """Whether ``end`` (2,) lies more than ``overshoot_m`` beyond ``goal`` (2,) along the
    line from ``origin`` (2,) (never with ``overshoot_m`` None)."""
    if overshoot_m is None:
        return False
    d = goal - origin
    n = float(np.linalg.norm(d))
    return n > 0 and float((end - origin) @ d) / n > n + overshoot_m


def compose(anchors: Anchors, keypoints: np.ndarray, goal: np.ndarray,
            max_cycles: int = MAX_CYCLES, overshoot_m: float | None = None,
            stop: str | None = None) -> tuple[list[str] | None, float]:
    """The primitive sequence (start, cycles, stop) from the standing body whose
    :data:`ANCHOR_KEYPOINTS` are at ``keypoints`` (K, 2) whose predicted end
    (:meth:`Anchors.predicted_end`) is nearest ``goal`` (2,) (plus :data:`SECOND_M` per
    second of walking), and that end's distance from the goal, m. With ``overshoot_m``,
    only sequences whose predicted end is at most that far beyond the goal along the line
    from the pelvis (the goal may be in front of a wall); with ``stop``, only sequences
    ending in a stop whose name starts with it; ``(None, inf)`` when none is."""
    lib = anchors.lib
    best, cost, err = None, np.inf, np.inf
    frames = {n: fit_frame(anchors.first[n], keypoints) for n, p in lib.primitives.items()
              if p.phase_in == "stand"}
    for seq in _sequences(anchors, max_cycles, stop):
        end = anchors.predicted_end(seq, frames[seq[0]])
        if _passes(keypoints[0], goal, end, overshoot_m):
            continue
        e = float(np.linalg.norm(end - goal))
        c = e + SECOND_M * sum(lib.seconds(n) for n in seq)
        if c < cost:
            best, cost, err = seq, c, e
    return best, err


class MocapWalkPlan:
    """The primitives ``names`` played on the agent (module docstring), with the
    interface of a :class:`~simenv.agents.reach.PDPlan` (``duration``, ``grasps``,
    ``feedback``, :meth:`control`).

    At each seam the next primitive is placed where the body is (its first keypoints on
    the measured ones); when ``goal`` is given, the rest of the walk is re-chosen there
    among the joined sequences that begin with the pieces played (:func:`compose`'s, with
    at most :data:`MAX_CYCLES` pieces between start and stop) as the one whose predicted
    end is nearest the goal, so :attr:`duration` may change at a seam (read it every
    step); with ``overshoot_m``, none predicted to pass the goal by more than that (m,
    along the line from where the walk started), with ``stop``, only those ending in a
    stop whose name starts with it (:func:`compose`).
    """

    def __init__(self, room: Room, data: mujoco.MjData, names: list[str],
                 goal: np.ndarray | None = None, lib: Library | None = None,
                 overshoot_m: float | None = None, stop: str | None = None) -> None:
        self.room = room
        self.lib = lib = lib or load_library()
        _check_body(room, lib)
        self.names = list(names)
        self.goal = None if goal is None else np.asarray(goal, float)[:2]
        self._origin = data.qpos[room.agent_qpos][:2].copy()
        self._overshoot = overshoot_m
        self.grasps: tuple = ()
        st = lib.stride
        self._starts = np.concatenate([[0], np.cumsum([lib.primitives[n].knots * st
                                                       for n in self.names])])
        self.duration = float(self._starts[-1] * lib.dt) + SETTLE_S
        self._model = room.agent.model
        self._shadow = mujoco.MjData(self._model)
        self._shadow_at: tuple[str, int] = ("", -1)
        self._shadow_u = np.zeros(self._model.nu)
        self.anchors = anchors_of(lib, room.agent)
        self._options = _sequences(self.anchors, MAX_CYCLES, stop)
        self._cur = -1
        self._anchor = (0.0, np.zeros(2))
        self._dq = np.zeros(room.agent.nv)
        self._fb = np.asarray(lib.feedback_ctrl, int)
        # The arms, hands and neck follow their targets; their error is not fed back (the
        # standing arms start 0.5 rad from the start's hanging pose, and the legs' gains
        # on it twisted the body over, measured).
        h = room.agent
        free = [h.model.jnt_dofadr[h.model.joint(n).id] for n in h.joint_names
                if n.split("_")[0] == "neck" or any(k in n for k in UNFED)]
        self._mask = np.ones(2 * h.nv)
        self._mask[free] = 0.0
        self._mask[np.asarray(free) + h.nv] = 0.0
        self._gain_k = -1
        self._gain = np.zeros((len(self._fb), 2 * room.agent.nv))
        #: Measured at every seam: (time s, primitive, pelvis x, y, heading rad).
        self.seams: list[tuple[float, str, float, float, float]] = []
        self.feedback = GaitMeter(room, _Passthrough(), self.goal)  # type: ignore[arg-type]

    def _begin(self, i: int, t: float, data: mujoco.MjData) -> None:
        """Place primitive ``i`` on the measured body (re-picking its bend)."""
        anc = self.anchors
        kp = data.site_xpos[self.room.agent_sites[anc.sites], :2]
        if self.goal is not None and i > 0:
            self._repick(i, kp)
        name = self.names[i]
        self._anchor = fit_frame(anc.first[name], kp)
        self._cur = i
        self._gain_k = -1
        q = data.qpos[self.room.agent_qpos]
        self.seams.append((t, name, float(q[0]), float(q[1]), quat_yaw(q[3:7])))

    def _repick(self, i: int, kp: np.ndarray) -> None:
        """The rest of the walk from piece ``i`` on re-chosen, among the sequences that
        begin with the pieces played so far, as the one whose predicted end from the
        measured keypoints ``kp`` (K, 2) is nearest the goal."""
        played = self.names[:i]
        best, cost = self.names[i:], np.inf
        for seq in self._options:
            if seq[:i] != played or len(seq) <= i:
                continue
            end = self.anchors.predicted_end(seq[i:], fit_frame(self.anchors.first[seq[i]], kp))
            if _passes(self._origin, self.goal, end, self._overshoot):
                continue
            c = float(np.linalg.norm(end - self.goal))
            if c < cost - 1e-9:
                best, cost = seq[i:], c
        self.names[i:] = best
        st = self.lib.stride
        self._starts = np.concatenate([[0], np.cumsum([self.lib.primitives[n].knots * st
                                                       for n in self.names])])
        self.duration = float(self._starts[-1] * self.lib.dt) + SETTLE_S

    def _reference(self, p: Primitive, s: int) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                        int]:
        """The reference state (world frame) and targets at step ``s`` of ``p``, and the
        stored step whose gain applies. The state is the shadow's: the agent's own model
        put on the stored state at every stored step and stepped between them with the
        targets interpolated, so that the reference is a state the body can be in (its
        feet on the floor); straight interpolation of the stored states is not, and the
        gains' stiff directions (a foot pressed into the floor) turned its error into
        servo targets of 100+ rad, measured."""
        st = self.lib.stride
        s = min(s, p.knots * st)
        k, r = divmod(s, st)
        k1 = min(k + 1, p.knots)
        w = r / st
        u = (1 - w) * p.ctrl[k] + w * p.ctrl[k1]
        sh = self._shadow
        if r == 0 or self._shadow_at != (p.name, s - 1):
            sh.qpos[:], sh.qvel[:] = p.qpos[k], p.qvel[k]
            for j in range(r):  # steps from the stored state (when called out of order)
                sh.ctrl[:] = (1 - j / st) * p.ctrl[k] + j / st * p.ctrl[k1]
                mujoco.mj_step(self._model, sh)
        else:
            sh.ctrl[:] = self._shadow_u
            mujoco.mj_step(self._model, sh)
        self._shadow_at, self._shadow_u = (p.name, s), u
        q, v = sh.qpos.copy(), sh.qvel.copy()
        psi, off = self._anchor
        q[:2] = _rot(psi) @ q[:2] + off
        tmp = np.zeros(4)
        mujoco.mju_mulQuat(tmp, _yaw_quat(psi), q[3:7])
        q[3:7] = tmp
        v[:2] = _rot(psi) @ v[:2]
        return q, v, u, k

    def control(self, t: float, data: mujoco.MjData) -> np.ndarray:
        """(nu,) the agent's servo targets ``t`` s into the plan (module docstring)."""
        room, lib = self.room, self.lib
        q = data.qpos[room.agent_qpos]
        step = int(round(t / lib.dt))
        i = min(int(np.searchsorted(self._starts, step, side="right")) - 1, len(self.names) - 1)
        if i != self._cur:
            self._begin(i, t, data)
        p = lib.primitives[self.names[i]]
        qr, vr, u, k = self._reference(p, step - int(self._starts[i]))
        if k != self._gain_k:
            self._gain, self._gain_k = lib.gain(p, k), k
        mujoco.mj_differentiatePos(self._model, self._dq, 1.0, qr, q)
        dx = np.concatenate([self._dq, data.qvel[room.agent_qvel] - vr]) * self._mask
        u = u.copy()
        u[self._fb] -= np.clip(self._gain @ dx, -FEEDBACK_CLIP_RAD, FEEDBACK_CLIP_RAD)
        return self.feedback(t, data, u)


class _Passthrough:
    """The inner feedback of the plan's :class:`~simenv.agents.walk.GaitMeter`: the
    targets are already final."""

    def __call__(self, t: float, data: mujoco.MjData, targets: np.ndarray) -> np.ndarray:
        return targets


def plan_mocap_walk(room: Room, data: mujoco.MjData, goal: np.ndarray,
                    lib: Library | None = None, max_cycles: int = MAX_CYCLES,
                    overshoot_m: float | None = None) -> MocapWalkPlan:
    """Plan for walking the standing agent towards ``goal`` (x, y, m) with the primitives
    (module docstring): the sequence :func:`compose` picks from where the pelvis is and
    where it heads. It starts straight ahead, so face the goal first (a turn on the
    spot, :func:`simenv.agents.walk.turn_steps`); the pelvis ends where the nearest chain
    of pieces ends (``feedback.outcome``: 0.12-0.35 m off on open floor, measured), in
    stride, a stance the stepping gait cannot start from (module docstring).

    Raises:
        SimenvError: the agent is not standing, or the library was built for another
            body.
    """
    check_standing(room, data, "walk")
    lib = lib or load_library()
    _check_body(room, lib)
    anc = anchors_of(lib, room.agent)
    kp = data.site_xpos[room.agent_sites[anc.sites], :2]
    names, _ = compose(anc, kp, np.asarray(goal, float)[:2], max_cycles, overshoot_m)
    if names is None:
        raise SimenvError(f"every walk of the primitives passes the goal by more than "
                          f"{overshoot_m} m", field="goal")
    return MocapWalkPlan(room, data, names, goal, lib, overshoot_m)


#: A composed walk is played only when its predicted end is at least this much nearer the
#: goal than where the body stands, m (else the stepping gait walks the whole way).
MIN_GAIN_M = 0.3
#: How far a composed walk may be predicted to end beyond the goal (along the line from
#: where it starts), m: the goal may be in front of a wall (the walk to the window passed
#: its spot and struck the wall, measured).
OVERSHOOT_M = 0.05
#: The stepping gait corrects the walk's end when it is farther than this from the goal,
#: m, or turned more than :data:`simenv.agents.walk.ALIGN_DEG` from its heading.
ARRIVE_M = 0.05
#: While a stage of :class:`PersonWalk` is still to be planned, its duration reads this
#: much beyond the current stage's end, s.
PENDING_S = 1.0


class _StagesMeter:
    """The :class:`~simenv.agents.walk.GaitMeter` readings of a :class:`PersonWalk`'s
    stages as one (``summary``, ``outcome``, ``fallen``, ``lowest_m``, ``grasp_max_n``)."""

    def __init__(self, room: Room, goal: np.ndarray) -> None:
        self.room, self.goal = room, goal
        self.meters: list[GaitMeter] = []

    def __call__(self, t: float, data: mujoco.MjData, targets: np.ndarray) -> np.ndarray:
        return targets  # each stage's own meter has measured already

    def merged(self) -> GaitMeter:
        """One meter holding every stage's readings in order."""
        m = GaitMeter(self.room, _Passthrough(), self.goal)  # type: ignore[arg-type]
        for x in self.meters:
            m.forces_n += x.forces_n
            m.torques_nm += x.torques_nm
            m.lowest_m = min(m.lowest_m, x.lowest_m)
            m.grasp_max_n = max(m.grasp_max_n, x.grasp_max_n)
        return m

    def summary(self, steps_per_frame: int = 20) -> dict:
        """:meth:`simenv.agents.walk.GaitMeter.summary` over all stages."""
        return self.merged().summary(steps_per_frame)

    def outcome(self, data: mujoco.MjData) -> dict:
        """:meth:`simenv.agents.walk.GaitMeter.outcome` over all stages."""
        return self.merged().outcome(data)

    def fallen(self) -> bool:
        """Whether the body fell in any stage so far."""
        return self.merged().fallen()

    @property
    def lowest_m(self) -> float:
        """The lowest pelvis height over the stages so far, m."""
        return self.merged().lowest_m


class PersonWalk:
    """Walking the standing agent to ``goal`` (x, y, m) facing ``goal_yaw`` (rad) at a
    person's pace where the primitives reach, with the interface of a
    :class:`~simenv.agents.reach.PDPlan`; its stages, each planned from the state the one
    before it left:

    1. ``turn``: the stepping gait's turn on the spot to face the goal
       (:func:`simenv.agents.walk.plan_walk` onto the pelvis's own place), when the body
       faces more than :data:`simenv.agents.walk.ALIGN_DEG` away from it;
    2. ``mocap``: the primitives' walk (:class:`MocapWalkPlan`; none predicted to pass
       the goal by more than :data:`OVERSHOOT_M`), when its predicted end is at least
       :data:`MIN_GAIN_M` nearer the goal than the body is (so a goal nearer than the
       shortest walk is left to the stepping gait);
    3. ``step``: the stepping gait's walk onto the goal and turn onto ``goal_yaw``, when
       the body ends farther than :data:`ARRIVE_M` from it or turned away from its heading.

    With ``stop`` (:data:`CLOSE_STOP`), the walk ends only in those stops.
    :attr:`duration` grows as stages are planned (read it every step); :attr:`stages`
    lists the stages played ((name, start s, plan)); ``feedback`` measures the help (none)
    and the outcome over all of them.
    """

    def __init__(self, room: Room, data: mujoco.MjData, goal: np.ndarray, goal_yaw: float,
                 lib: Library | None = None, overshoot_m: float | None = OVERSHOOT_M,
                 stop: str | None = None) -> None:
        check_standing(room, data, "walk")
        self.overshoot_m, self.stop = overshoot_m, stop
        self.room, self.lib = room, lib or load_library()
        _check_body(room, self.lib)
        self.goal = np.asarray(goal, float)[:2]
        self.goal_yaw = float(goal_yaw)
        self.grasps: tuple = ()
        self.feedback = _StagesMeter(room, self.goal)
        self.stages: list[tuple[str, float, object]] = []
        #: Why the stepping gait's correction was refused (its footsteps out of the legs'
        #: reach from the stance the walk ended in), or None.
        self.refused: str | None = None
        self._todo = ["turn", "mocap", "step"]
        self._next(0.0, data)

    @property
    def duration(self) -> float:
        """Seconds planned so far (plus :data:`PENDING_S` while a stage is to be planned)."""
        cur = self.stages[-1][1] + self.stages[-1][2].duration if self.stages else 0.0
        return cur + (PENDING_S if self._todo else 0.0)

    def _plan(self, name: str, data: mujoco.MjData) -> object | None:
        from simenv.agents.walk import ALIGN_DEG, plan_walk

        q = data.qpos[self.room.agent_qpos]
        to = self.goal - q[:2]
        dist = float(np.linalg.norm(to))
        heading = float(np.arctan2(to[1], to[0]))
        off = abs(np.rad2deg(np.angle(np.exp(1j * (heading - quat_yaw(q[3:7]))))))
        if name == "turn":
            return plan_walk(self.room, data, q[:2].copy(), heading) if off > ALIGN_DEG \
                else None
        if name == "mocap":
            anc = anchors_of(self.lib, self.room.agent)
            kp = data.site_xpos[self.room.agent_sites[anc.sites], :2]
            names, err = compose(anc, kp, self.goal, MAX_CYCLES, self.overshoot_m, self.stop)
            if names is None or err > dist - MIN_GAIN_M:
                return None
            return MocapWalkPlan(self.room, data, names, self.goal, self.lib,
                                 self.overshoot_m, self.stop)
        yaw_off = abs(np.rad2deg(np.angle(np.exp(1j * (self.goal_yaw - quat_yaw(q[3:7]))))))
        if dist <= ARRIVE_M and yaw_off <= ALIGN_DEG:
            return None
        try:
            return plan_walk(self.room, data, self.goal, self.goal_yaw)
        except SimenvError as exc:  # the body stands where it ended, reported
            self.refused = str(exc)
            return None

    def _next(self, t: float, data: mujoco.MjData) -> None:
        """Plan the next stage that is needed from the state now (``t`` s into the walk)."""
        while self._todo:
            name = self._todo.pop(0)
            if self.stages and self.stages[-1][2].feedback.fallen():
                self._todo.clear()
                return
            plan = self._plan(name, data)
            if plan is not None:
                self.stages.append((name, t, plan))
                self.feedback.meters.append(plan.feedback)
                return

    def control(self, t: float, data: mujoco.MjData) -> np.ndarray:
        """(nu,) the agent's servo targets ``t`` s into the walk."""
        _, t0, plan = self.stages[-1]
        if t - t0 >= plan.duration and self._todo:
            self._next(t, data)
            _, t0, plan = self.stages[-1]
        return plan.control(t - t0, data)


def plan_person_walk(room: Room, data: mujoco.MjData, goal: np.ndarray, goal_yaw: float,
                     lib: Library | None = None, overshoot_m: float | None = OVERSHOOT_M,
                     stop: str | None = None) -> PersonWalk:
    """:class:`PersonWalk` to ``goal`` (x, y, m) facing ``goal_yaw`` (rad), its walk
    predicted to pass the goal by at most ``overshoot_m`` (None: any; on open floor the
    nearest end may lie beyond the goal: a goal 3.2 m away is then missed by 0.35 m
    instead of 0.87 m, measured), ending in a stop whose name starts with ``stop`` when
    given (:data:`CLOSE_STOP` with a library built with closing stops).

    Raises:
        SimenvError: the agent is not standing, the library was built for another body,
            or a stepping gait's footstep is out of the legs' reach.
    """
    return PersonWalk(room, data, goal, goal_yaw, lib, overshoot_m, stop)


_ANCHORS: dict[tuple[int, int], Anchors] = {}


def anchors_of(lib: Library, h: Humanoid) -> Anchors:
    """The :class:`Anchors` of ``lib`` on ``h`` (one per pair)."""
    key = (id(lib), id(h))
    if key not in _ANCHORS:
        _ANCHORS[key] = Anchors(lib, h)
    return _ANCHORS[key]


__all__ = ["ANCHOR_KEYPOINTS", "CLOSE_STOP", "LIBRARY", "Anchors", "Library",
           "MocapWalkPlan", "PersonWalk", "Primitive", "anchors_of", "body_signature",
           "compose", "fit_frame", "load_library", "mirror", "plan_mocap_walk",
           "plan_person_walk"]

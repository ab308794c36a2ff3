"""``simenv/InteractionRoom-v0``: decide the agent's reaction to the user's gestures.

The room of a scenario (:class:`simenv.room.room.Room`) with the user's avatar replaying a
session (:class:`simenv.room.session.Session`, retargeted onto a body fitted to the subject) at
the perception rate, 25 fps; one environment step is one user frame (0.04 s, 20 physics
steps of 2 ms). The agent sits at the desk, its PD servos holding the seated pose.

Observation (``Dict``, float32)
    ``user_history`` (H, K, 3): the user's last H = 25 frames (1 s) of canonical keypoints
    in the room frame, m (frames before the session start repeat its first frame);
    ``user_future`` (F, K, 3): the predictor's F frames ahead of the history as it was at
    the latest prediction (default :func:`simenv.perception.loop.load_predictor`: the shipped
    gesture-domain forecaster ``predictor-gesture-25-50``, 2 s, run on the keypoints through
    :class:`~simenv.perception.loop.CanonicalPredictor` and told where the recording's sensor
    stands, :attr:`simenv.room.session.UserTrack.observer`; the constant-velocity baseline
    ``constant-velocity-50`` when it is not shipped). It predicts at the perception loop's
    rate, every ``predict_every`` = 25 steps (1 s) and at reset, and holds the forecast in
    between: the WGAN takes ~14 ms a call on one core, more than the 25 steps' physics;
    ``predict_every=1`` forecasts at every step); ``agent``
    (nq_a - 2 + nv_a,): the agent's
    ``qpos[2:]`` and ``qvel``; ``objects`` (5,): each object's state as a fraction of its
    joint range (order :data:`OBJECTS`; see :mod:`simenv.room.room` for thresholds).

Action (``Discrete(1 + R)``)
    0 = no-op (keep doing what the agent does), ``1..R`` = the scenario's reactions other
    than ``keep``, in the order of :data:`simenv.room.scenario.REACTIONS` (:attr:`reactions`).
    The room's own agent chooses them from the observation: :meth:`InteractionRoomEnv.room_agent`
    (:class:`~simenv.perception.room_agent.RoomAgent`, ``action = agent.act(observation)``).

Reward (per step, documented constants below)
    * a decision during a labelled gesture (from its onset to :data:`GRACE_S` after its end)
      that is the scenario's reaction to it: ``+exp(-(t - onset) / TIMELINESS_S)``, once per
      gesture (earlier is better; deciding on predicted motion pays);
    * any other decision (wrong reaction, no gesture, gesture already answered):
      ``-FALSE_ALARM``;
    * a gesture whose reaction is not ``keep`` left unanswered :data:`GRACE_S` after its
      end: ``-MISS``;
    * a started reaction that succeeded in simulation by the end of its plan: its object
      reached its target state (:func:`simenv.agents.scripted.object_success`), or, for
      ``greet``, the agent faced the user within 30 degrees with a hand above its shoulder
      at some step (:meth:`simenv.room.room.Room.greeting`), for ``bow_back``, facing the user
      its head dipped and came back up (:meth:`simenv.room.room.Room.bow_meter`): ``+SUCCESS``;
    * implausible agent motion: ``-PLAUSIBILITY_WEIGHT`` per centimetre by which the agent's
      deepest contact with the floor, the furniture, the objects or itself penetrates beyond
      :data:`PENETRATION_TOLERANCE_M` (contacts with the kinematic user, who pushes with
      unbounded force, are not the agent's doing).

Episode
    Truncated :data:`TAIL_S` after the session ends (the user holding the last pose; later
    while a reaction still runs, at most :data:`MAX_TAIL_S`), or when the physics diverges,
    with ``info["truncation_reason"]``. Stepping before ``reset``, after the end, or with an
    action outside the space raises :class:`~simenv.core.errors.SimenvError`.

Execution
    A decision whose reaction has a planner in :data:`simenv.agents.scripted.PLANNERS`
    (``cigarette_out``, ``hifi_down``, ``greet``, ``bow_back`` seated; ``close_window``,
    ``close_curtain`` and ``open_window`` as chained stages: stand up, walk, act, walk back,
    sit) starts it when the agent is idle and the planner finds it feasible from the current
    state. Idle, the agent types and glances at the notebook
    (:func:`simenv.agents.idle.plan_idle`, cycle after cycle). The plan's PD targets are
    applied at every physics step until it ends, and the object changes state only if the
    agent's hand makes it so. Other decisions are logged and rewarded as decisions but not
    carried out (``started`` False, ``not_started`` says why: not implemented, busy with
    another reaction, or the planner's reason, e.g. the hi-fi out of seated reach).
    :attr:`log` lists every decision with ``t_decision``, ``reaction``, ``gesture``,
    ``started``, ``not_started``, ``t_object_changed``, ``t_success`` (when success was
    first measured) and ``success``, plus ``facing_deg_min`` for a greeting or a bow (the
    closest the chest came to facing the user), ``dip_max_deg`` for a bow (the head's
    deepest dip below its pitch on facing the user) and ``grasped`` for a reaction that
    grasps (whether the
    proximity grasp closed: the hand was at the handle). A chained reaction
    (:class:`~simenv.agents.reach.PlanChain`) plans each stage when the previous one ends,
    from the state it left, then the return stages after it; its entry lists ``stages``
    (``stage``, ``duration_s``, ``pelvis_end``; for a stage on the feet, ``assistance``: the
    external help on the agent per physics step -- applied forces and torques, equality
    constraints other than the hands' grasps, :meth:`simenv.room.room.Room.assist_wrench`; there
    is no assistance mechanism, so it measures 0 -- summarised in N and body weights with
    ``per_frame_n`` per env step, and ``outcome``: ``fell``, ``lowest_pelvis_m``,
    ``goal_error_m``, ``success``), the total ``assistance``, ``fell`` (True when a stage's
    body fell: the chain stops there) and ``failed_stage`` when a stage could not be
    planned or its body fell. A reaction that did not succeed says why in ``failure``
    (:meth:`InteractionRoomEnv._failure`): what the object reached, how close the nearer
    hand came to its handle (``hand_distance_min_m`` at ``t_hand_closest``), the facing and
    the raised hand of a greeting, the stage that failed, the user's body pushing into the
    agent (``user_contact``: ``t_first``, ``t_last``, ``max_depth_m``), or the episode
    ending while it ran; the measurements are logged whether or not it succeeded
    (``object_level_start`` / ``object_level_best``: fractions of the object's range).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from simenv.agents.idle import plan_idle
from simenv.agents.reach import PDPlan, PlanChain
from simenv.agents.scripted import PLANNERS, object_success
from simenv.assets import WALK
from simenv.body.divergence import physics_problem, warning_counts
from simenv.core.errors import SimenvError
from simenv.core.motion import Motion
from simenv.perception.loop import PerceptionLoop, forecast, load_predictor
from simenv.perception.room_agent import RoomAgent
from simenv.room.room import BOW_DIP_DEG, CHAIR_OFFSET, GREET_FACING_DEG, HANDS
from simenv.room.scenario import REACTIONS, Scenario, load_scenario
from simenv.room.session import PERCEPTION_FPS, GestureEvent, Session, user_track

#: What an agent's contact is with, in :meth:`InteractionRoomEnv.agent_penetration`.
_CONTACT_KINDS = ("floor", "furniture", "object", "self", "user")
_SELF = _CONTACT_KINDS.index("self")
#: Object order of the ``objects`` observation.
OBJECTS = ("window", "curtain", "hifi", "cigarette", "door")
#: Time constant of the timeliness reward, s.
TIMELINESS_S = 1.0
#: How long after a gesture's end a decision still answers it, s.
GRACE_S = 1.0
#: Penalty of a decision that answers no gesture.
FALSE_ALARM = 0.2
#: Penalty of a gesture left unanswered.
MISS = 0.5
#: Reward of a reaction whose object reached its target state through the agent.
SUCCESS = 0.5
#: Penalty per cm of agent penetration beyond the tolerance.
PLAUSIBILITY_WEIGHT = 0.1
#: Contact penetration (m) that soft contacts produce at rest; not penalised.
PENETRATION_TOLERANCE_M = 0.01
#: The user holds the last pose this long after the recording ends, s ...
TAIL_S = 2.0
#: ... or longer while a reaction is still running, up to this bound, s (a chained
#: reaction on the agent's own legs, such as close_window: stand up, ~120 s of stepping to
#: the window, push, then ~100 s of stepping back to the chair and sitting: ~250 s).
MAX_TAIL_S = 300.0
#: The render camera's eye: height above the floor, m (over the people's heads and the desk
#: top, so the seated agent's hands show; under the ceiling) ...
CAMERA_HEIGHT_M = 2.2
#: ... least clearance to the walls, m (a wall behind the eye would hide the room) ...
CAMERA_WALL_CLEARANCE_M = 0.3
#: ... vertical field of view, degrees (as the room's fixed cameras: wide enough for the user,
#: the agent and the desk from inside a small room) ...
CAMERA_FOVY_DEG = 60.0
#: ... least horizontal distance to the user and to the seated agent, m (so that a standing
#: body fits in the vertical field) ...
CAMERA_MIN_RANGE_M = 2.0
#: ... least angle between the directions to the user and to the agent, degrees (so that
#: neither hides the other) ...
CAMERA_MIN_SEPARATION_DEG = 20.0
#: ... and the angle kept free at the edges of the horizontal field of view, degrees in all
#: (a body's half width and a raised arm on either side, at ~3 m).
CAMERA_FOV_MARGIN_DEG = 20.0
#: Height the render camera aims at, m: between the seated agent's hands and the user's chest.
CAMERA_AIM_HEIGHT_M = 1.0


def _assistance_total(stages: list[dict[str, Any]]) -> dict[str, float]:
    """Root assistance over a chained reaction's stages: ``max_n`` (N), ``max_bw`` (body
    weights), step-weighted ``mean_n`` / ``mean_bw`` and the assisted ``steps``."""
    parts = [s["assistance"] for s in stages if "assistance" in s]
    steps = sum(p["steps"] for p in parts)
    if not steps:
        return {"max_n": 0.0, "max_bw": 0.0, "mean_n": 0.0, "mean_bw": 0.0, "steps": 0}
    return {"max_n": max(p["max_n"] for p in parts), "max_bw": max(p["max_bw"] for p in parts),
            "mean_n": sum(p["mean_n"] * p["steps"] for p in parts) / steps,
            "mean_bw": sum(p["mean_bw"] * p["steps"] for p in parts) / steps, "steps": steps}


class InteractionRoomEnv(gym.Env[dict, int]):
    """Choose the agent's reactions to a recorded user (see the module docstring).

    Args:
        session: a :class:`~simenv.room.session.Session`, a motion file, a bundled asset name,
            a session recipe (``.toml`` or a bundled recipe name) or a Motion (default: the
            bundled CMU walk, which holds no gesture).
        gestures: labelled gestures of the session when ``session`` is not a Session.
        scenario: a :class:`~simenv.room.scenario.Scenario`, a bundled name or a TOML path.
        history_frames: H, frames of user history observed.
        predictor: ``"auto"`` (the shipped ``predictor-gesture-25-50`` when present, else
            ``constant-velocity-50``), a ``simenv.models.load`` name (shipped
            ``predictor-*`` models are run on the keypoints through
            :class:`~simenv.perception.loop.CanonicalPredictor`) or an object with
            ``predict(history)`` ((H, K, 3) -> (F, K, 3)), ``history_len`` and
            ``future_len`` (:func:`simenv.perception.loop.load_predictor`).
        predict_every: steps between forecasts of ``user_future`` (25: the perception
            loop's 1 s; 1: every step).
        data: root of the shared corpus for a session recipe
            (:func:`simenv.core.config.shared_data_root`).
        render_mode: None or ``"rgb_array"`` (the room camera). width, height: pixels.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": int(PERCEPTION_FPS)}

    def __init__(self, session: Session | str | os.PathLike[str] | Motion = WALK, *,
                 gestures: Sequence[GestureEvent] = (), scenario: Scenario | str = "default",
                 history_frames: int = 25, predictor: Any = "auto", predict_every: int = 25,
                 render_mode: str | None = None, width: int = 480, height: int = 360,
                 data: str | os.PathLike[str] | None = None) -> None:
        if render_mode not in (None, "rgb_array"):
            raise SimenvError(f"render_mode {render_mode!r} is not supported; expected None "
                              "or 'rgb_array'", field="render_mode")
        self.render_mode = render_mode
        self._size = (int(width), int(height))
        self.scenario = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
        if not isinstance(session, Session):
            session = Session.load(session, gestures, data=data)
        self.session = session
        self.track = user_track(session, self.scenario)
        self.room = self.track.room()
        self.model = self.room.model
        self.data = mujoco.MjData(self.model)
        predictor = load_predictor(predictor)
        self.predictor = predictor
        self.history_frames = int(history_frames)
        if self.history_frames < 2:
            raise SimenvError(f"history_frames must be at least 2; got {history_frames}",
                              field="history_frames")
        if int(predict_every) < 1:
            raise SimenvError(f"predict_every must be at least 1 step; got {predict_every}",
                              field="predict_every")
        self.predict_every = int(predict_every)
        self._future: np.ndarray | None = None
        # The predictor may need more frames than are observed (the WGAN: 1 + 25).
        self._kept = max(self.history_frames, int(predictor.history_len))
        self.frame_skip = int(round(1.0 / PERCEPTION_FPS / self.model.opt.timestep))
        used = {self.scenario.behaviour.otherwise, *self.scenario.behaviour.reactions.values()}
        #: Reaction of each action index (index 0: no-op).
        self.reactions: tuple[str | None, ...] = (None, *(
            r for r in REACTIONS if r in used and r != "keep"))
        self.action_space = spaces.Discrete(len(self.reactions))
        K = len(self.room.user.keypoint_names)
        n_agent = self.room.agent.nq - 2 + self.room.agent.nv
        inf = np.float32(np.inf)
        self.observation_space = spaces.Dict({
            "user_history": spaces.Box(-inf, inf, (self.history_frames, K, 3), np.float32),
            "user_future": spaces.Box(-inf, inf, (int(predictor.future_len), K, 3), np.float32),
            "agent": spaces.Box(-inf, inf, (n_agent,), np.float32),
            "objects": spaces.Box(0.0, 1.0, (len(OBJECTS),), np.float32),
        })
        self.n_frames = len(self.track.qpos)
        self.max_steps = self.n_frames - 1 + int(round(TAIL_S * PERCEPTION_FPS))
        self.hard_max_steps = self.n_frames - 1 + int(round(MAX_TAIL_S * PERCEPTION_FPS))
        geom_body = self.model.geom_bodyid
        names = [self.model.body(b).name for b in range(self.model.nbody)]
        owner = [names[geom_body[g]].split("/")[0] for g in range(self.model.ngeom)]
        self._agent_geom = np.array([o == "agent" for o in owner])
        self._user_geom = np.array([o == "user" for o in owner])
        objects = {self.model.body(self.model.jnt_bodyid[self.model.joint(o.joint).id]).name
                   for o in self.room.objects.values()}
        self._agent_bodies = np.array([b for b, n in enumerate(names)
                                       if n.split("/")[0] == "agent"])
        # What each geom is, for agent_penetration: an index into _CONTACT_KINDS, with
        # the agent's own geoms at "self".
        kind = ["floor" if geom_body[g] == 0 else "self" if o == "agent" else "user"
                if o == "user" else "object" if names[geom_body[g]] in objects else "furniture"
                for g, o in enumerate(owner)]
        self._geom_kind = np.array([_CONTACT_KINDS.index(k) for k in kind])
        self._step: int | None = None
        self._obs: dict[str, np.ndarray] | None = None
        self._renderer: mujoco.Renderer | None = None
        self._camera: mujoco.MjvCamera | str = "room"
        self.model.vis.global_.fovy = CAMERA_FOVY_DEG  # the field of camera()'s free camera

    # -- Gymnasium API ----------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        super().reset(seed=seed)
        self.room.reset(self.data)
        self.room.set_user_pose(self.data, self.track.qpos[0])
        mujoco.mj_forward(self.model, self.data)
        self._step = 0
        self._answered: set[int] = set()
        self._missed: set[int] = set()
        self.log: list[dict[str, Any]] = []
        self._running: dict[str, Any] | None = None
        self._idle: tuple[PDPlan, float] | None = None
        now = self.data.site_xpos[self.room.user_sites].astype(np.float32)
        self._history = np.repeat(now[None], self._kept, axis=0)
        self._obs = self._observe()
        return self._obs, self._info(None, {})

    def step(self, action: int) -> tuple[dict[str, np.ndarray], float, bool, bool,
                                         dict[str, Any]]:
        a = np.asarray(action)
        if a.shape != () or a.dtype.kind not in "iu" or not self.action_space.contains(int(a)):
            raise SimenvError(f"action must be one integer in [0, {self.action_space.n}) "
                              f"(reactions {list(self.reactions)}); got {action!r}",
                              field="action")
        return self.advance(int(a))

    def advance(self, action: int, user_qpos: np.ndarray | None = None
                ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """:meth:`step` with a validated action index, the user's next pose optionally
        given (``user_qpos`` (nq_user,), placed in the room; default: the recording's next
        frame, holding the last one after the end). For multi-agent wrappers."""
        if self._step is None:
            raise SimenvError("step() called before reset() (or after the episode ended); "
                              "call reset() first")
        t = self._step / PERCEPTION_FPS
        reaction = self.reactions[action]
        terms = {"decision": self._decide(t, reaction), "miss": self._misses(t)}
        if reaction is not None:
            self._start(t, reaction)
        m, d = self.model, self.data
        self._step += 1
        if user_qpos is None:
            user_qpos = self.track.qpos[min(self._step, self.n_frames - 1)]
        self.room.set_user_pose(d, user_qpos)
        counts = warning_counts(d)
        self._simulate(t)
        problem = physics_problem(m, d, counts)
        if problem is not None:
            self._cut_short(f"the physics diverged at {t:.2f} s ({problem})", t)
            self._step = None
            return self._obs, 0.0, False, True, {"truncation_reason": f"physics: {problem}"}
        # What the agent sees: the user's keypoints as simulated (mocap bodies moved).
        self._history = np.concatenate(
            [self._history[1:], d.site_xpos[self.room.user_sites][None]]).astype(np.float32)
        terms["success"] = self._follow_up(self._step / PERCEPTION_FPS)
        terms["plausibility"] = -PLAUSIBILITY_WEIGHT * self._excess_penetration() / 0.01
        self._obs = self._observe()
        info = self._info(reaction, terms)
        # After the recording the user holds its last pose until running reactions finish.
        truncated = (self._step >= self.max_steps and self._running is None
                     or self._step >= self.hard_max_steps)
        if truncated:
            info["truncation_reason"] = "end of the session"
            self._cut_short(f"the episode ended {MAX_TAIL_S:.0f} s after the session with "
                            "the reaction still running", self._step / PERCEPTION_FPS)
            self._step = None
        return self._obs, float(sum(terms.values())), False, truncated, info

    def render(self) -> np.ndarray | None:
        """The room seen by :meth:`camera`: an RGB image (height, width, 3) uint8, or None
        unless ``render_mode="rgb_array"``."""
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            # The renderer's module loads OpenCV (video): only rgb_array rendering needs it.
            from simenv.body.render import make_renderer

            self._renderer = make_renderer(self.model, *self._size)
            self._camera = self.camera()
        self.room.sync_visuals(self.data)
        self._renderer.update_scene(self.data, camera=self._camera)
        return self._renderer.render()

    def camera(self) -> mujoco.MjvCamera | str:
        """A fixed viewpoint that sees the user's gestures and the agent's face and hands.

        The eye, :data:`CAMERA_HEIGHT_M` high and inside the walls, is the point of a 5-cm
        grid that sees the less frontally seen of the two people -- the agent in its chair,
        facing the desk, and the user where the scenario places the session's first frame
        (``user.position``, facing ``user.yaw_deg``) -- as frontally as possible, and both
        from the front half, at least :data:`CAMERA_MIN_RANGE_M` away and at least
        :data:`CAMERA_MIN_SEPARATION_DEG` apart; the user, the agent and the desk's centre
        fit in the horizontal field of view less :data:`CAMERA_FOV_MARGIN_DEG`. It aims at
        the middle of them, :data:`CAMERA_AIM_HEIGHT_M` high. (The room's ``room`` camera,
        in a corner behind the user, sees the user's back, who hides the agent.)

        Returns:
            a free camera, or ``"room"`` when no eye in the room meets these conditions.
        """
        width, height = self._size
        half_v = np.deg2rad(CAMERA_FOVY_DEG) / 2
        fov_h = np.degrees(2 * np.arctan(np.tan(half_v) * width / height))
        hx, hy = np.asarray(self.scenario.room.size) / 2 - CAMERA_WALL_CLEARANCE_M
        gx, gy = np.meshgrid(np.arange(-hx, hx + 1e-9, 0.05), np.arange(-hy, hy + 1e-9, 0.05))
        eyes = np.column_stack([gx.ravel(), gy.ravel()])  # (N, 2), m
        yaw = np.deg2rad(self.scenario.desk.yaw_deg)
        turn = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
        seat = np.asarray(self.scenario.desk.position) + turn @ np.asarray(CHAIR_OFFSET)
        user = np.asarray(self.scenario.user.position)
        user_yaw = np.deg2rad(self.scenario.user.yaw_deg)
        facing = np.array([[np.cos(yaw), np.sin(yaw)], [np.cos(user_yaw), np.sin(user_yaw)]])
        # Eye -> seated agent, user, desk centre (the agent's objects lie on it), (N, 3, 2).
        to = np.stack([seat, user, self.scenario.desk.position])[None] - eyes[:, None]
        dist = np.linalg.norm(to, axis=2)
        frontal = -(to[:, :2] * facing[None]).sum(axis=2) / dist[:, :2]  # cos(facing, -> eye)
        # Directions seen from the eye relative to the user's, degrees in (-180, 180].
        bearing = np.arctan2(to[..., 1], to[..., 0])
        rel = np.degrees(np.angle(np.exp(1j * (bearing - bearing[:, 1:2]))))
        fits = ((dist[:, :2].min(axis=1) >= CAMERA_MIN_RANGE_M) & (frontal.min(axis=1) > 0)
                & (np.abs(rel[:, 0]) >= CAMERA_MIN_SEPARATION_DEG)
                & (np.ptp(rel, axis=1) <= fov_h - CAMERA_FOV_MARGIN_DEG))
        if not fits.any():
            return "room"
        best = int(np.argmax(np.where(fits, frontal.min(axis=1), -np.inf)))
        eye = np.array([*eyes[best], CAMERA_HEIGHT_M])
        # Aim at the middle of the framed directions.
        mid = bearing[best, 1] + np.deg2rad(rel[best].max() + rel[best].min()) / 2
        aim = np.array([*(eyes[best] + dist[best].mean() * np.array([np.cos(mid), np.sin(mid)])),
                        CAMERA_AIM_HEIGHT_M])
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = aim
        ahead = aim - eye
        cam.distance = float(np.linalg.norm(ahead))
        cam.azimuth = float(np.degrees(np.arctan2(ahead[1], ahead[0])))
        cam.elevation = float(np.degrees(np.arctan2(ahead[2], np.linalg.norm(ahead[:2]))))
        return cam

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # -- execution -------------------------------------------------------------

    def _start(self, t: float, reaction: str) -> None:
        entry = {"t_decision": t, "reaction": reaction, "gesture": self._active(t),
                 "started": False, "t_object_changed": None, "t_success": None,
                 "success": None, "not_started": None}
        self.log.append(entry)
        if self._running is not None:
            entry["not_started"] = f"busy with {self._running['entry']['reaction']}"
            return
        if reaction not in PLANNERS:
            entry["not_started"] = "not implemented"
            return
        try:
            plan = PLANNERS[reaction](self.room, self.data)
            stages: list = []
            if isinstance(plan, PlanChain):
                stages = list(plan.stages)
                entry["stages"] = []
                plan = self._plan_stage(entry, stages)
        except SimenvError as exc:  # e.g. the object is out of the seated agent's reach
            entry["not_started"] = str(exc)
            return
        entry["started"] = True
        if REACTIONS[reaction].object is None:
            entry["facing_deg_min"] = None
        self._running = {"entry": entry, "t0": t, "t_start": t, "plan": plan,
                         "grasps": list(plan.grasps), "stages": stages,
                         "before": self.room.object_labels(self.data)}
        obj = REACTIONS[reaction].object
        if obj is not None:
            o = self.room.objects[obj]
            entry["object_level_start"] = entry["object_level_best"] = o.level(
                float(self.data.qpos[o.qpos_adr]))
            entry["hand_distance_min_m"] = entry["t_hand_closest"] = None
        else:
            entry["hand_raised"] = False
        entry["user_contact"] = None
        if reaction == "bow_back":
            self._running["bow"] = self.room.bow_meter()
            entry["dip_max_deg"] = 0.0
        self._note_grasps(entry, plan)

    def _plan_stage(self, entry: dict[str, Any], stages: list) -> PDPlan:
        """Plan the next stage of a chained reaction from the current state, logged in
        ``entry["stages"]``."""
        name, planner = stages.pop(0)
        plan = planner(self.room, self.data)
        entry["stages"].append({"stage": name, "duration_s": plan.duration})
        return plan

    @staticmethod
    def _note_grasps(entry: dict[str, Any], plan: PDPlan) -> None:
        if plan.grasps and "grasped" not in entry:
            entry["grasped"] = False

    def _end_plan(self, run: dict[str, Any]) -> None:
        """A finished plan holds nothing; its measured external help (if it measures it:
        the stages on the feet) and its measured outcome (if its feedback measures one,
        e.g. whether a walk fell, or the seated check that ends the return to the chair)
        go into the log. A stage whose body fell ends the chain, logged as failed."""
        for g in run["plan"].grasps:
            self.room.set_grasp(self.data, g.hand, g.name, False)
        if "stages" in run["entry"]:
            stage = run["entry"]["stages"][-1]
            stage["pelvis_end"] = self.data.qpos[self.room.agent_qpos][:3].tolist()
            summary = getattr(run["plan"].feedback, "summary", None)
            if summary is not None:
                stage["assistance"] = summary(self.frame_skip)
            outcome = getattr(run["plan"].feedback, "outcome", None)
            if outcome is not None:
                stage["outcome"] = outcome(self.data)
                if stage["outcome"].get("fell"):
                    run["entry"]["fell"] = True
                    run["entry"]["failed_stage"] = (
                        f"{stage['stage']}: the agent fell (pelvis down to "
                        f"{stage['outcome']['lowest_pelvis_m']:.2f} m)")
                    run["stages"] = []

    def _simulate(self, t: float) -> None:
        """One env step of physics; a running plan sets the agent's targets every substep."""
        m, d = self.model, self.data
        if self._running is None:
            self._simulate_idle(t)
            return
        self._idle = None  # after the reaction, a new idle cycle starts from where it ended
        run = self._running
        plan, t0, dt = run["plan"], run["t0"], m.opt.timestep
        for i in range(self.frame_skip):
            tau = t - t0 + i * dt
            while run["grasps"] and run["grasps"][0].t <= tau:
                g = run["grasps"].pop(0)
                closed = self.room.set_grasp(d, g.hand, g.name, g.close)
                if g.close:
                    run["entry"]["grasped"] = run["entry"]["grasped"] or closed
            d.ctrl[self.room.agent_ctrl] = plan.control(tau, d)
            mujoco.mj_step(m, d)

    def _simulate_idle(self, t: float) -> None:
        """One env step of idling: the current idle cycle's targets every substep, a new
        cycle planned from the current state when the last one ended."""
        m, d = self.model, self.data
        if self._idle is None or t - self._idle[1] >= self._idle[0].duration:
            self._idle = (plan_idle(self.room, d), t)
        plan, t0 = self._idle
        for i in range(self.frame_skip):
            d.ctrl[self.room.agent_ctrl] = plan.control(t - t0 + i * m.opt.timestep, d)
            mujoco.mj_step(m, d)

    def _follow_up(self, t: float) -> float:
        """Record when the running reaction's object changes; score it when its plan ends."""
        run = self._running
        if run is None:
            return 0.0
        entry = run["entry"]
        self._measure(entry, t)
        if REACTIONS[entry["reaction"]].object is None:
            # A greeting succeeds when, at some step, the agent faces the user and a hand is
            # raised (Room.greeting); a bow when, facing the user, the head dipped and came
            # back up (Room.bow_meter); either is over when its plan ends.
            if "bow" in run:
                g = run["bow"](self.data)
                entry["dip_max_deg"] = run["bow"].dip_max_deg
            else:
                g = self.room.greeting(self.data)
            best = entry["facing_deg_min"]
            entry["facing_deg_min"] = g["facing_deg"] if best is None else min(
                best, g["facing_deg"])
            if entry["t_success"] is None and g["success"]:
                entry["t_success"] = t
            done = entry["t_success"] is not None
        else:
            labels = self.room.object_labels(self.data)
            done = object_success(self.room, run["before"], labels, entry["reaction"])
            if entry["t_object_changed"] is None and done:
                entry["t_object_changed"] = entry["t_success"] = t
        fallen = getattr(run["plan"].feedback, "fallen", None)
        if t - run["t0"] < run["plan"].duration and not (fallen is not None and fallen()):
            return 0.0
        self._end_plan(run)
        # The chain goes on after its object succeeded: the return stages bring the agent
        # back to its chair. The reaction's success stays the object's.
        if run["stages"]:
            try:
                run["plan"] = self._plan_stage(entry, run["stages"])
            except SimenvError as exc:  # a later stage is infeasible from where this one ended
                entry["failed_stage"] = str(exc)
            else:
                run["t0"], run["grasps"] = t, list(run["plan"].grasps)
                self._note_grasps(entry, run["plan"])
                return 0.0
        self._running = None
        entry["success"] = bool(done)
        if "stages" in entry:
            entry["assistance"] = _assistance_total(entry["stages"])
            # Back on the chair: the chain ran to its seated check and it held (a walk's
            # outcome, at a chain cut short, is not a return).
            last = entry["stages"][-1].get("outcome") or {}
            entry["returned"] = bool("seat_contact" in last and last["success"])
        entry["failure"] = None if entry["success"] else self._failure(entry, run)
        return SUCCESS if entry["success"] else 0.0

    def _measure(self, entry: dict[str, Any], t: float) -> None:
        """What a failed reaction's reason needs, measured at every step it runs (``t``,
        s): its object's level closest to the target and the nearer hand's closest
        approach to the object's handle (m), or whether a hand rose above its shoulder
        (greetings), and the user's body pushing into the agent."""
        d, reaction = self.data, REACTIONS[entry["reaction"]]
        if reaction.object is not None:
            o = self.room.objects[reaction.object]
            level = o.level(float(d.qpos[o.qpos_adr]))
            best = max if reaction.target == o.above else min
            entry["object_level_best"] = best(entry["object_level_best"], level)
            handle = d.site_xpos[mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE,
                                                   o.handle)]
            names = self.room.agent.keypoint_names
            hands = d.site_xpos[[self.room.agent_sites[names.index(h)] for h in HANDS]]
            gap = float(np.linalg.norm(hands - handle, axis=1).min())
            if entry["hand_distance_min_m"] is None or gap < entry["hand_distance_min_m"]:
                entry["hand_distance_min_m"], entry["t_hand_closest"] = gap, t
        else:
            entry["hand_raised"] = entry["hand_raised"] or bool(
                self.room.greeting(d)["hand_above_shoulder"])
        depth = self.agent_penetration()["user"]
        if depth > 0.0:
            contact = entry["user_contact"] or {"t_first": t, "max_depth_m": 0.0}
            contact["t_last"] = t
            contact["max_depth_m"] = max(contact["max_depth_m"], depth)
            entry["user_contact"] = contact

    def _cut_short(self, why: str, t: float) -> None:
        """The episode ends at ``t`` (s) for ``why`` with a reaction still running: its
        ``success`` stays None (never judged) and ``failure`` says so."""
        run = self._running
        if run is not None:
            run["entry"]["failure"] = self._failure(
                run["entry"], run, f"{why}, {t - run['t_start']:.2f} s after it started")

    def _failure(self, entry: dict[str, Any], run: dict[str, Any],
                 cut: str | None = None) -> str:
        """Why the reaction of ``entry`` did not succeed, for people: ``cut`` (the episode
        ended while it ran), the stage that failed, what its object or greeting reached
        against what success needs, the hand's closest approach and the user's pushes."""
        reaction = REACTIONS[entry["reaction"]]
        parts = [cut] if cut else []
        if entry.get("failed_stage"):
            parts.append(f"stage {entry['failed_stage']}")
        for stage in entry.get("stages", []):
            out = stage.get("outcome") or {}
            if out and not out.get("success") and not out.get("fell"):
                err = out.get("goal_error_m")
                parts.append(f"stage {stage['stage']} did not succeed" + (
                    "" if err is None else f" (ended {err:.2f} m from its goal)"))
        if reaction.object is not None:
            o = self.room.objects[reaction.object]
            now = self.room.object_labels(self.data)[reaction.object]
            side = "above" if reaction.target == o.above else "below"
            parts.append(
                f"the {reaction.object} stayed {now}: from {entry['object_level_start']:.0%} "
                f"of its range it got to {entry['object_level_best']:.0%} at best "
                f"({reaction.target} needs {side} {o.level(o.threshold):.0%})")
            if entry["hand_distance_min_m"] is not None:
                parts.append(f"the nearer hand came no closer than "
                             f"{entry['hand_distance_min_m']:.3f} m to its handle (at "
                             f"{entry['t_hand_closest']:.2f} s)")
            if entry.get("grasped") is False:
                parts.append("the grasp never closed (the hand was not at the handle)")
        else:
            facing = entry.get("facing_deg_min")
            if facing is not None:
                parts.append(f"the agent's chest faced the user at best {facing:.0f} deg "
                             f"(within {GREET_FACING_DEG:.0f} needed)")
            if "bow" in run:
                parts.append(f"its head dipped {entry.get('dip_max_deg', 0.0):.0f} deg at "
                             f"most ({BOW_DIP_DEG:.0f} needed, then back up)")
            elif not entry["hand_raised"]:
                parts.append("no hand rose above its shoulder")
        contact = entry["user_contact"]
        if contact is not None:
            parts.append(f"the user's body pushed into the agent from {contact['t_first']:.2f} "
                         f"to {contact['t_last']:.2f} s (up to "
                         f"{1000 * contact['max_depth_m']:.0f} mm deep)")
        return "; ".join(parts)

    # -- reward ----------------------------------------------------------------

    def _decide(self, t: float, reaction: str | None) -> float:
        if reaction is None:
            return 0.0
        behaviour = self.scenario.behaviour
        for i, g in enumerate(self.session.gestures):
            if i in self._answered or not g.onset_s <= t <= g.end_s + GRACE_S:
                continue
            if behaviour.reaction_for(g.label).name == reaction:
                self._answered.add(i)
                return float(np.exp(-(t - g.onset_s) / TIMELINESS_S))
        return -FALSE_ALARM

    def _misses(self, t: float) -> float:
        penalty = 0.0
        for i, g in enumerate(self.session.gestures):
            late = t > g.end_s + GRACE_S
            if late and i not in self._answered and i not in self._missed:
                self._missed.add(i)
                if self.scenario.behaviour.reaction_for(g.label).name != "keep":
                    penalty -= MISS
        return penalty

    def agent_penetration(self) -> dict[str, float]:
        """Deepest penetration (m, >= 0) of the agent's contacts now, by what it touches:
        ``floor``, ``furniture``, ``object``, ``self`` (its own body) and ``user``."""
        d = self.data
        out = np.zeros(len(_CONTACT_KINDS))
        if d.ncon:
            kinds = self._geom_kind[d.contact.geom[:d.ncon]]
            mine = (kinds == _SELF).any(axis=1)
            other = np.where(kinds[:, 0] == _SELF, kinds[:, 1], kinds[:, 0])[mine]
            np.maximum.at(out, other, -d.contact.dist[:d.ncon][mine])
        return dict(zip(_CONTACT_KINDS, out.tolist(), strict=True))

    def agent_assistance_n(self) -> float:
        """Largest external force (N) acting now on the agent from outside its own servos
        and contacts (:meth:`simenv.room.room.Room.assist_wrench`: ``xfrc_applied`` on its
        bodies, ``qfrc_applied`` on its free joint, equality constraints other than the
        hands' grasps); nothing in the room applies one, so 0 unless someone adds it."""
        return self.room.assist_wrench(self.data)[0]

    def _excess_penetration(self) -> float:
        d = self.data
        if d.ncon == 0:
            return 0.0
        geoms = d.contact.geom[:d.ncon]
        # The kinematic user pushes with unbounded force: its contacts are not the agent's doing.
        mine = self._agent_geom[geoms].any(axis=1) & ~self._user_geom[geoms].any(axis=1)
        if not mine.any():
            return 0.0
        deepest = -float(d.contact.dist[:d.ncon][mine].min())
        return max(0.0, deepest - PENETRATION_TOLERANCE_M)

    # -- observation -----------------------------------------------------------

    def _observe(self) -> dict[str, np.ndarray]:
        history = self._history[-self.history_frames:].copy()
        if self._future is None or self._step % self.predict_every == 0:
            self._future = forecast(self.predictor, self._history, self.track.observer)
        d, room = self.data, self.room
        agent = np.concatenate([d.qpos[room.agent_qpos][2:], d.qvel[room.agent_qvel]])
        return {"user_history": history,
                "user_future": self._future.copy(),
                "agent": agent.astype(np.float32),
                "objects": self.object_levels()}

    def room_agent(self, loop: PerceptionLoop, *, replay: bool = True) -> RoomAgent:
        """The room's agent deciding in this environment
        (:class:`~simenv.perception.room_agent.RoomAgent`): ``loop`` perceives the user,
        the scenario's behaviour picks the reaction, and the action indexes
        :attr:`reactions`. ``replay``: the user replays the session, so the forecaster is
        told where the recording's sensor stands (:attr:`simenv.room.session.UserTrack.
        observer`) and the agent perceives while the recording plays; False (a user driven
        otherwise, e.g. a policy): observer unknown, perceiving to the end.

        Raises:
            SimenvError: the observation's history is shorter than ``loop`` reads.
        """
        if self.history_frames < loop.history_frames:
            raise SimenvError(f"the agent's perception reads {loop.history_frames} frames of "
                              f"user history; this environment observes {self.history_frames}"
                              f" (build it with history_frames={loop.history_frames})",
                              field="history_frames")
        return RoomAgent(loop, self.scenario.behaviour, self.reactions,
                         observer=self.track.observer if replay else None,
                         recorded_frames=self.n_frames if replay else None,
                         fps=PERCEPTION_FPS)

    def user_keypoints(self) -> np.ndarray:
        """(max(H, predictor history), K, 3) float32 the user's latest canonical keypoints
        in the room, m (the observed history and, before it, the frames the predictor
        also needs), for a perception loop."""
        if self._step is None and self._obs is None:
            raise SimenvError("user_keypoints() called before reset(); call reset() first")
        return self._history.copy()

    def object_levels(self) -> np.ndarray:
        """(5,) float32 each object's state as a fraction of its joint range, in
        :data:`OBJECTS` order (clipped to [0, 1]: soft joint limits overshoot slightly)."""
        states = self.room.object_states(self.data)
        levels = [self.room.objects[n].level(states[n]) for n in OBJECTS]
        return np.clip(levels, 0.0, 1.0).astype(np.float32)

    def _active(self, t: float) -> str | None:
        active = [g.label for g in self.session.gestures if g.onset_s <= t <= g.end_s]
        return active[0] if active else None

    def _info(self, reaction: str | None, terms: dict[str, float]) -> dict[str, Any]:
        t = self._step / PERCEPTION_FPS
        return {"time_s": t, "gesture": self._active(t), "reaction": reaction,
                "executing": None if self._running is None else self._running["entry"][
                    "reaction"],
                "reward_terms": terms, "object_labels": self.room.object_labels(self.data)}

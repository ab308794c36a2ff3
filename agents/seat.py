"""Back to the chair: turn on the feet, walk back to the desk, turn to face it, sit down.

The return stages (:data:`RETURN_STAGES`) follow a standing act (``close_window``,
``close_curtain``, ``open_window``) in its :class:`~simenv.agents.reach.PlanChain`, each
planned from the state the previous one left:

1. ``turn_away`` (:func:`plan_turn_away`): a stepping turn (:func:`plan_step`) from
   facing the object onto the heading that leaves towards the chair;
2. ``walk_back`` (:func:`plan_walk_back`): :func:`simenv.agents.walk.plan_walk` from there
   to :data:`ARRIVE_OFF_M` in front of the seat (wherever it rolled), arriving across the
   desk's heading from the side the agent comes from, so that the path passes between the
   chair's front and the desk instead of over the chair;
3. ``turn_to_desk`` (:func:`plan_turn_to_desk`): steps onto :func:`chair_spot`, turning
   onto the desk's heading, the seat now behind the agent;
4. ``sit_down`` (:func:`simenv.agents.stand.plan_sit_down`) and ``settle``
   (:func:`plan_settle`): crouch onto the seat, then hold the seated pose; the settle's
   plan measures the result (:func:`seated_on_chair`) when it ends.

A stepping turn by ``Theta`` is ``K = ceil(|Theta| / STEP_DEG)`` steps of ``theta = Theta /
K``; step ``k`` has four phases of :data:`TURN_PHASE_S` each, with the pelvis yaw ``psi_k =
psi_0 + k theta`` and the feet's places ``f(psi)`` those of the standing rest pose with the
pelvis at ``psi`` (leg hinges solved by damped least squares on the four feet keypoints,
:func:`~simenv.agents.reach.reach_pose`): lift the leading foot (the one on the side of
the turn) :data:`LIFT_M`; yaw the pelvis to ``psi_k`` and set that foot down at
``f(psi_k)``, the other still planted (its hip twists); lift the trailing foot; set it
down at ``f(psi_k)``. A short shift of the pelvis (up to :data:`STEP_M` a step) is
interpolated with the yaw the same way. The feet are re-placed, not dragged round on the
floor as by a blend of the pelvis's yaw. While stepping the pelvis is
:data:`TURN_CROUCH_M` lower, moves :data:`WEIGHT_SHIFT_M` over the standing foot while the
other is lifted, and the stance legs' static torques are fed forward
(:func:`stance_targets`); it is held on that reference by
:class:`~simenv.agents.walk.RootAssist` (measured, reported). :func:`plan_turn_then_walk`
puts such a turn before a walk in one plan (the walks to the window and the curtain).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from simenv.agents.reach import PDPlan, PDTrajectory, pd_targets, reach_pose, upper_body_joints
from simenv.agents.stand import FEET, plan_sit_down
from simenv.agents.walk import GRAVITY, RootAssist, plan_walk
from simenv.errors import SimenvError
from simenv.humanoid import Humanoid
from simenv.room import Room

#: Pelvis in front of the seat's centre along the desk's heading when the agent stands to
#: sit, m (measured where standing up leaves it: 0.25-0.26 m).
SEAT_STAND_OFF_M = 0.26
#: The walk back arrives this far in front of the seat's centre (between the chair's
#: front and the desk, clear of both), m; the last steps bring the pelvis to
#: :data:`SEAT_STAND_OFF_M`.
ARRIVE_OFF_M = 0.45
#: Largest yaw, deg, and largest shift of the pelvis, m, of one step (:func:`plan_step`).
STEP_DEG = 45.0
STEP_M = 0.12
#: Duration of each of the four phases of a turning step, s.
TURN_PHASE_S = 0.5
#: Swing foot's lift during a turning step, m.
LIFT_M = 0.06
#: The pelvis lowers this much while turning (knees bent: the legs reach the feet where
#: the walk left them, up to 0.15 m ahead and behind), m.
TURN_CROUCH_M = 0.04
#: While a foot is lifted the pelvis moves this far towards the standing foot, m.
WEIGHT_SHIFT_M = 0.09
#: Seated hold after sitting down, s.
SETTLE_S = 1.5


def _yaw(quat: np.ndarray) -> float:
    w, x, y, z = quat
    return float(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def _yaw_quat(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def _wrap(angle: float) -> float:
    return float((angle + np.pi) % (2 * np.pi) - np.pi)


def desk_heading(room: Room) -> float:
    """The seated agent's heading, facing the desk, rad."""
    return float(np.deg2rad(room.scenario.desk.yaw_deg))


def chair_spot(room: Room, data: mujoco.MjData, off: float = SEAT_STAND_OFF_M
               ) -> np.ndarray:
    """Where the agent stands to sit down: pelvis (x, y), m, ``off`` in front of the
    seat's centre (where the chair is now) along the desk's heading."""
    seat = data.xpos[room.model.body("chair_seat").id, :2]
    yaw = desk_heading(room)
    return seat + off * np.array([np.cos(yaw), np.sin(yaw)])


def _arrival_yaw(room: Room, data: mujoco.MjData) -> float:
    """Heading of the walk's arrival at :func:`chair_spot`: across the desk's heading,
    moving away from the side of the desk the agent is on."""
    yaw = desk_heading(room)
    rel = data.qpos[room.agent_qpos][:2] - chair_spot(room, data)
    left = float(rel @ np.array([-np.sin(yaw), np.cos(yaw)]))
    return _wrap(yaw - np.pi / 2 if left >= 0 else yaw + np.pi / 2)


def stance_targets(humanoid: Humanoid, qpos: np.ndarray, support: Sequence[str],
                   compensate: Sequence[str] = ()) -> np.ndarray:
    """(nu,) servo targets holding ``qpos`` (nq,) standing on the keypoints ``support``
    (e.g. both feet's ankle and toe), with the torque each hinge needs there fed forward:
    :func:`~simenv.agents.reach.pd_targets` (``compensate``: hinges in the air) plus,
    for every other hinge ``j``, ``tau_j / kp_j`` with the static torques of the body's
    weight carried equally by the ``n`` support points::

        tau = g(q) - sum_i J_i^T f_i,    f_i = (0, 0, M g / n)

    (``g`` the generalised gravity force, ``J_i`` the support point's position Jacobian).
    Without it the stance legs' servos sag and whatever holds the pelvis carries the
    weight (measured in a stepping turn: 0.63 -> 0.39 body weights of weld force).
    """
    m = humanoid.model
    data = mujoco.MjData(m)
    data.qpos[:] = qpos
    mujoco.mj_forward(m, data)
    tau = data.qfrc_bias.copy()
    f = np.array([0.0, 0.0, humanoid.total_mass * GRAVITY / len(support)])
    jacp = np.zeros((3, m.nv))
    for name in support:
        mujoco.mj_jacSite(m, data, jacp, None, m.site(name).id)
        tau -= jacp.T @ f
    targets = pd_targets(humanoid, qpos, compensate)
    kp = m.actuator_gainprm[:, 0]
    skip = set(compensate)
    for i, name in enumerate(humanoid.joint_names):
        if name not in skip:
            targets[i] += tau[m.joint(name).dofadr[0]] / kp[i]
    return targets


def plan_step(room: Room, data: mujoco.MjData, goal: np.ndarray, goal_yaw: float
              ) -> PDPlan:
    """Plan for stepping the standing agent to ``goal`` (x, y, m, a short way: up to
    :data:`STEP_M` a step) facing ``goal_yaw`` (rad), turning on the spot when ``goal``
    is where it stands (module docstring); the pelvis is held by a measured
    :class:`RootAssist`.

    Raises:
        SimenvError: a foot's place is out of the legs' reach (IK more than 2 cm short).

    Returns:
        the plan (``4 K`` phases of :data:`TURN_PHASE_S`, the rise to the standing rest
        pose, then 0.5 s standing).
    """
    h = room.agent
    q0 = data.qpos[room.agent_qpos].copy()
    yaw0 = _yaw(q0[3:7])
    turn = _wrap(goal_yaw - yaw0)
    shift = np.asarray(goal, float)[:2] - q0[:2]
    k_steps = max(1, int(np.ceil(abs(np.rad2deg(turn)) / STEP_DEG - 1e-9)),
                  int(np.ceil(float(np.linalg.norm(shift)) / STEP_M - 1e-9)))
    legs = tuple(n for n in h.joint_names if n.split("_")[1] in ("thigh", "shin", "foot"))
    upper = upper_body_joints(h)
    # The leading foot is on the side of the turn (or of the sideways shift): it opens.
    left = turn if abs(turn) > 1e-3 else float(shift @ [-np.sin(yaw0), np.cos(yaw0)])
    lead, trail = ("left", "right") if left >= 0 else ("right", "left")
    idx = {s: [FEET.index(f"{s}_ankle"), FEET.index(f"{s}_toe")] for s in ("left", "right")}
    kp = [h.keypoint_names.index(f) for f in FEET]

    def root(u: float, drop: float) -> np.ndarray:
        return np.array([*(q0[:2] + u * shift), q0[2] - drop])

    def pose(u: float, drop: float = TURN_CROUCH_M) -> np.ndarray:
        q = h.default_qpos()
        q[:3] = root(u, drop)
        q[3:7] = _yaw_quat(yaw0 + u * turn)
        return q

    def places(u: float) -> np.ndarray:  # the standing rest pose's feet, on the floor
        return h.keypoints(pose(u, 0.0))[kp]

    feet = h.keypoints(q0)[kp]  # planted where they are (a heel may be up) until moved
    configs: list[np.ndarray] = []
    stances: list[list[str]] = []
    q = pose(0.0)
    q[7:] = q0[7:]
    for k in range(1, k_steps + 1):
        u0, u1 = (k - 1) / k_steps, k / k_steps
        new = places(u1)
        for side, u, lift in ((lead, u0, True), (lead, u1, False), (trail, u1, True),
                              (trail, u1, False)):
            target = feet.copy()
            if lift:
                target[idx[side]] = places(0.5 * (u0 + u1))[idx[side]] + [0.0, 0.0, LIFT_M]
            else:
                target[idx[side]] = feet[idx[side]] = new[idx[side]]
            start = q.copy()
            start[:7] = pose(u)[:7]
            if lift:  # the weight over the standing foot
                other = "right" if side == "left" else "left"
                toward = feet[idx[other], :2].mean(axis=0) - start[:2]
                start[:2] += WEIGHT_SHIFT_M * toward / max(float(np.linalg.norm(toward)), 1e-6)
            q, err = reach_pose(h.model, start, FEET, target, legs, iterations=400)
            if err > 0.02:
                raise SimenvError(f"a step is out of the legs' reach ({err:.3f} m short)",
                                  field="step")
            configs.append(q.copy())
            stances.append([f for f in FEET if not (lift and f.startswith(side))])
    now = data.ctrl[room.agent_ctrl].copy()
    stand = pose(1.0, 0.0)
    # The last, standing targets carry no feed-forward: released from the weld after it,
    # the body with it fell in the sit-down that follows (measured), without it sits.
    targets = [*(stance_targets(h, c, st, upper) for c, st in zip(configs, stances,
                                                                  strict=True)),
               pd_targets(h, stand, upper)]
    segments = [PDTrajectory(a, b, TURN_PHASE_S)
                for a, b in zip([now, *targets[:-1]], targets, strict=True)]
    segments.append(PDTrajectory(targets[-1], targets[-1], 0.5))
    # The weld's reference: the pelvis of each phase's pose, then standing.
    times = TURN_PHASE_S * np.arange(len(targets) + 1)
    times = np.append(times, times[-1] + 0.5)
    refs = [q0[:7], *[c[:7] for c in configs], stand[:7], stand[:7]]
    pos = np.array([r[:3] for r in refs])
    quat = np.array([r[3:7] for r in refs])
    return PDPlan(segments, feedback=RootAssist(room, times, pos, quat))


def plan_turn_then_walk(room: Room, data: mujoco.MjData, goal: np.ndarray, goal_yaw: float,
                        start_yaw: float) -> PDPlan:
    """One plan: a stepping turn on the spot (:func:`plan_step`) onto ``start_yaw`` (rad),
    then :func:`~simenv.agents.walk.plan_walk` to ``goal`` (x, y, m) facing ``goal_yaw``,
    planned from the state the turn is planned to end in (standing rest pose, turned);
    one :class:`~simenv.agents.walk.RootAssist` over both (measured)."""
    q = data.qpos[room.agent_qpos]
    turn = plan_step(room, data, q[:2].copy(), start_yaw)
    after = mujoco.MjData(room.model)
    after.qpos[:] = data.qpos
    end = room.agent.default_qpos()
    end[:3] = q[:3]
    end[3:7] = _yaw_quat(start_yaw)
    after.qpos[room.agent_qpos] = end
    after.ctrl[:] = data.ctrl
    after.ctrl[room.agent_ctrl] = turn.segments[-1].goal
    walk = plan_walk(room, after, goal, goal_yaw, start_yaw=start_yaw)
    a, b = turn.feedback, walk.feedback
    quat = np.concatenate([a.quat[:-1], b.quat])
    for k in range(1, len(quat)):  # one hemisphere, as in plan_walk
        quat[k] *= np.sign(quat[k] @ quat[k - 1]) or 1.0
    assist = RootAssist(room, np.concatenate([a.times[:-1], b.times + turn.duration]),
                        np.concatenate([a.pos[:-1], b.pos]), quat)
    return PDPlan([*turn.segments, *walk.segments], feedback=assist)


def plan_turn_away(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for the stepping turn from facing the object onto the heading that leaves
    towards the chair: a quarter turn from the current heading, to the side of
    :func:`chair_spot`."""
    q = data.qpos[room.agent_qpos]
    yaw = _yaw(q[3:7])
    to = chair_spot(room, data) - q[:2]
    side = np.sign(np.cos(yaw) * to[1] - np.sin(yaw) * to[0]) or 1.0  # left or right of it
    return plan_step(room, data, q[:2], _wrap(yaw + side * np.pi / 2))


def plan_walk_back(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for walking from where the agent stands (leaving along its heading) to
    :func:`chair_spot`, arriving across the desk's heading (module docstring)."""
    return plan_walk(room, data, chair_spot(room, data, ARRIVE_OFF_M),
                     _arrival_yaw(room, data))


def plan_turn_to_desk(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for the steps onto :func:`chair_spot` (where the chair is now), turning onto
    the desk's heading (the seat behind)."""
    return plan_step(room, data, chair_spot(room, data), desk_heading(room))


def seated_on_chair(room: Room, data: mujoco.MjData) -> dict[str, float | bool]:
    """Whether the agent sits on the chair now, measured:

    * ``seat_contact``: the pelvis or a thigh touches the chair's seat;
    * ``pelvis_height_m`` within 5 cm of the seated pose's (``pelvis_height_error_m``);
    * ``seat_distance_m``: the pelvis within 15 cm of the seat's centre on the floor;
    * ``torso_tilt_deg``: the chest's vertical axis within 30 deg of upright;
    * ``fallen``: any agent geom but a foot or toe touching the floor;
    * ``success``: all of them.
    """
    m = room.model
    seat = m.geom("chair/seat").id
    floor = 0  # the world's first geom
    sitting = {m.geom(f"agent/{n}").id for n in ("pelvis", "left_thigh", "right_thigh")}
    feet = {m.geom(f"agent/{n}").id for n in ("left_foot", "left_toes", "right_foot",
                                              "right_toes")}
    agent = {g for g in range(m.ngeom) if m.geom(g).name.startswith("agent/")}
    contact, fallen = False, False
    for g1, g2 in data.contact.geom[:data.ncon]:
        pair = {int(g1), int(g2)}
        if seat in pair and pair & sitting:
            contact = True
        if floor in pair and pair & agent and not pair & feet:
            fallen = True
    q = data.qpos[room.agent_qpos]
    dz = float(q[2] - room.seated_pose()[2])
    centre = data.xpos[m.body("chair_seat").id, :2]
    dist = float(np.linalg.norm(q[:2] - centre))
    up = data.xmat[m.body("agent/chest").id].reshape(3, 3)[:, 2]
    tilt = float(np.rad2deg(np.arccos(np.clip(up[2], -1.0, 1.0))))
    ok = contact and abs(dz) <= 0.05 and dist <= 0.15 and tilt <= 30.0 and not fallen
    return {"seat_contact": contact, "pelvis_height_m": float(q[2]),
            "pelvis_height_error_m": dz, "seat_distance_m": dist, "torso_tilt_deg": tilt,
            "fallen": fallen, "success": bool(ok)}


@dataclass
class SeatedCheck:
    """A :data:`~simenv.agents.reach.Feedback` that passes the targets through; its
    :meth:`outcome` is :func:`seated_on_chair` in the state given (the settle's end)."""

    room: Room

    def __call__(self, t: float, data: mujoco.MjData, targets: np.ndarray) -> np.ndarray:
        return targets

    def outcome(self, data: mujoco.MjData) -> dict[str, float | bool]:
        return seated_on_chair(self.room, data)


def plan_settle(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for settling into the seated pose over :data:`SETTLE_S` (after
    :func:`~simenv.agents.stand.plan_sit_down`); its feedback (:class:`SeatedCheck`)
    measures the result at the end."""
    h = room.agent
    seated = pd_targets(h, room.seated_pose(), upper_body_joints(h))
    return PDPlan([PDTrajectory(data.ctrl[room.agent_ctrl].copy(), seated, SETTLE_S)],
                  feedback=SeatedCheck(room))


#: The return to the chair, appended to a standing act's chain.
RETURN_STAGES = (("turn_away", plan_turn_away), ("walk_back", plan_walk_back),
                 ("turn_to_desk", plan_turn_to_desk), ("sit_down", plan_sit_down),
                 ("settle", plan_settle))


__all__ = ["RETURN_STAGES", "SeatedCheck", "chair_spot", "desk_heading", "plan_settle",
           "plan_step", "plan_turn_away", "plan_turn_then_walk", "plan_turn_to_desk",
           "plan_walk_back", "seated_on_chair", "stance_targets"]

"""Scripted reactions carried out physically by the room's agent.

A reaction is planned from the current simulation state as a :class:`~simenv.agents.reach.PDPlan`
of the agent's position-servo targets: via-points of the hand solved with
:func:`~simenv.agents.reach.reach_pose`, joined by minimum-jerk segments, with the upper
body's gravity torque fed forward (:func:`~simenv.agents.reach.pd_targets`; the seated
legs rest on the chair and are not compensated). Playing the plan is the only thing the
reaction does: whether the object changes state is up to the simulated contact between the
hand and the object, and is measured, never assumed (:func:`object_success`).

Implemented, all seated (:data:`PLANNERS`):

* ``cigarette_out``: lift the hand off the desk, move above the cigarette, press it into
  the ashtray, lift, return to the seated pose;
* ``hifi_down``: when the scenario puts the hi-fi within seated reach (its knob beside
  the chair), take the knob's handle in the fingertips with a proximity grasp and turn it
  down (:func:`plan_hifi_down`); otherwise the planner refuses (out of reach);
* ``greet``: turn to the user (the chair's swivel turned by the planted feet, then the
  spine) and wave the user-side arm above the shoulder (:func:`plan_greet`);
* ``bow_back``: the same turn, then a nod (:func:`plan_bow_back`; measured by
  :class:`simenv.room.room.BowMeter`).

Standing ones (stand up, walk on the agent's own legs, act, walk back and sit down) are
chained stages, each an :class:`~simenv.agents.object_task.ObjectTask`: ``close_window``
(:mod:`simenv.agents.window`), ``open_window`` (:mod:`simenv.agents.window_open`) and
``close_curtain`` (:mod:`simenv.agents.curtain`). The door and a hi-fi across the room are
not done.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

from simenv.agents.curtain import plan_close_curtain
from simenv.agents.reach import (
    GraspEvent,
    PDPlan,
    PDTrajectory,
    PlanChain,
    arm_joints,
    hinge_adr,
    pd_targets,
    reach_pose,
    upper_body_joints,
)
from simenv.agents.window import plan_close_window
from simenv.agents.window_open import plan_open_window
from simenv.core.errors import SimenvError
from simenv.room.room import HANDS, Room
from simenv.room.scenario import REACTIONS

#: Hand clearance above the desk / the cigarette on the way, m.
LIFT_M = 0.12
APPROACH_M = 0.08
#: How far below the cigarette's top the pressing hand aims, m: the servos stop short of
#: a target they cannot reach, so aiming past the surface is what makes the hand push.
PRESS_DEPTH_M = 0.03


def plan_cigarette_out(room: Room, data: mujoco.MjData, side: str = "right") -> PDPlan:
    """Plan for pressing the cigarette out with the ``side`` hand, from the current state.

    Returns:
        the plan of the agent's targets (``data.ctrl[room.agent_ctrl]``), 3.9 s long.
    """
    h = room.agent
    q = data.qpos[room.agent_qpos].copy()
    site = f"{side}_hand"
    hand = data.site_xpos[room.agent_sites[h.keypoint_names.index(site)]].copy()
    handle = data.site_xpos[mujoco.mj_name2id(room.model, mujoco.mjtObj.mjOBJ_SITE,
                                              room.objects["cigarette"].handle)].copy()
    arm, upper = arm_joints(side), upper_body_joints(h)
    rest = pd_targets(h, room.seated_pose(), upper)
    targets, pose = [], q
    for goal in (hand + [0, 0, LIFT_M], handle + [0, 0, APPROACH_M],
                 handle - [0, 0, PRESS_DEPTH_M]):
        pose, err = reach_pose(h.model, pose, site, goal, arm)
        if err > 0.02:
            raise SimenvError(f"the cigarette is out of the agent's {side}-hand reach "
                              f"({err:.3f} m short)", field="cigarette")
        targets.append(pd_targets(h, pose, upper))
    lift, above, press = targets
    now = data.ctrl[room.agent_ctrl].copy()
    return PDPlan([PDTrajectory(now, lift, 0.6), PDTrajectory(lift, above, 0.8),
                   PDTrajectory(above, press, 0.6), PDTrajectory(press, press, 0.3),
                   PDTrajectory(press, above, 0.5), PDTrajectory(above, rest, 1.1)])


#: Knob level the hi-fi reaction aims at, as a fraction of the knob's travel (the
#: ``quiet`` threshold is 0.5), and the number of via-points on the knob's arc (0.25 s
#: each). The hand lags its targets round so small a circle, the more the faster it goes:
#: from 0.8, aiming at 0.0 stops the knob near 0.31 with 16 via-points, 0.39 with 12 and
#: 0.51 (still loud) with 8 (measured).
HIFI_QUIET_LEVEL = 0.0
KNOB_VIA = 16
#: Distance in front of the knob's face from which the hand comes in and leaves, m.
KNOB_APPROACH_M = 0.05
#: Spine hinges that lean the seated trunk sideways when the arm alone falls short.
SPINE_LEAN = ("lumbar_lat", "thorax_lat", "chest_lat")
#: How far into the knob's face the fingertips aim, m, so that they rest on the face (the
#: servos stop short of their target) with the tip site at the handle.
KNOB_PRESS_M = 0.004


def plan_hifi_down(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for turning the hi-fi's volume down, seated, from the current state.

    The nearer hand lifts off the desk, comes to a point :data:`KNOB_APPROACH_M` in front
    of the knob, puts its fingertips (the ``tip`` grasp site) on the knob's handle near the
    rim, pointing into the face with the wrist straight out along the knob's axis, and asks
    for the proximity grasp there (:class:`~simenv.agents.reach.GraspEvent`); the hand
    then moves round the handle's circle about the hinge axis, aiming at
    :data:`HIFI_QUIET_LEVEL` of the travel, in :data:`KNOB_VIA` IK via-points, lets go and
    returns to the seated pose. The IK may lean the trunk sideways (:data:`SPINE_LEAN`).
    The knob turns only if the grasp closed and the hand dragged it round; the servos lag
    on so small a circle, so the knob stops short of the aimed level (measured).

    Raises:
        SimenvError: the knob is already below the ``quiet`` threshold, or out of the
            seated agent's reach (the IK falls more than 2 cm short).

    Returns:
        the plan of the agent's targets, ``3.9 + 0.25 KNOB_VIA`` s long.
    """
    m, h, knob = room.model, room.agent, room.objects["hifi"]
    angle = float(data.qpos[knob.qpos_adr])
    if angle <= knob.threshold:
        raise SimenvError(f"the hi-fi is already quiet (level {knob.level(angle):.2f})",
                          field="hifi")
    handle = data.site_xpos[m.site(knob.handle).id].copy()
    grips = {hand: data.site_xpos[m.site(f"agent/{hand}_grip").id] for hand in HANDS}
    hand = min(grips, key=lambda k: float(np.linalg.norm(grips[k] - handle)))
    side = hand.split("_")[0]
    jnt = m.joint(knob.joint).id
    axis, anchor = data.xaxis[jnt].copy(), data.xanchor[jnt].copy()
    turn = angle - (knob.lower + HIFI_QUIET_LEVEL * (knob.upper - knob.lower))
    arc = [anchor + _rotate(handle - anchor, axis, -turn * k / KNOB_VIA)
           for k in range(1, KNOB_VIA + 1)]
    front = axis * KNOB_APPROACH_M
    # The trunk may lean sideways to extend the arm's reach (the knob is low and to the
    # side); the wrist turns the hand so that its fingertips point into the knob's face.
    joints = [f"agent/{j}" for j in (*arm_joints(side), f"{side}_hand_flex",
                                       f"{side}_hand_dev", *SPINE_LEAN)]
    # Fingertips (the hifi's grasp site) on the handle with the wrist straight out along
    # the knob's axis: the hand points into the face and the forearm stays clear of it.
    sites = [f"agent/{hand}_tip", f"agent/{side}_wrist"]
    reach = float(-room.model.site(sites[0]).pos[2])
    hand_line = np.array([[0.0, 0.0, 0.0], reach * axis])
    upper = upper_body_joints(h)
    pose = data.qpos.copy()
    targets = []
    # Out in front of the knob first: the knob sits on the amplifier's face. While it turns
    # the knob the hand moves round the handle's circle without rotating (the grasp is a
    # ball joint at the handle).
    press = -KNOB_PRESS_M * axis
    for k, goal in enumerate((grips[hand] + [0.0, 0.0, LIFT_M], handle + front,
                              handle + press, *(p + press for p in arc), arc[-1] + front)):
        if k == 0:
            pose, err = reach_pose(m, pose, f"agent/{hand}_grip", goal, joints)
        else:
            pose, err = reach_pose(m, pose, sites, goal + hand_line, joints, iterations=400)
        if err > 0.02:
            raise SimenvError(f"the hi-fi's knob is out of the seated agent's {side}-hand "
                              f"reach ({err:.3f} m short)", field="hifi")
        targets.append(pd_targets(h, pose[room.agent_qpos], upper))
    lift, before, on, *turning, after = targets
    rest = pd_targets(h, room.seated_pose(), upper)
    now = data.ctrl[room.agent_ctrl].copy()
    segments = [PDTrajectory(now, lift, 0.6), PDTrajectory(lift, before, 1.0),
                PDTrajectory(before, on, 0.5), PDTrajectory(on, on, 0.3)]
    t_close = sum(seg.duration for seg in segments)
    for a, b in zip([on, *turning], turning, strict=False):
        segments.append(PDTrajectory(a, b, 0.25))
    segments.append(PDTrajectory(turning[-1], turning[-1], 0.2))
    t_open = sum(seg.duration for seg in segments) - 0.05
    segments += [PDTrajectory(turning[-1], after, 0.4), PDTrajectory(after, rest, 0.9)]
    return PDPlan(segments, [GraspEvent(t_close, hand, "hifi", True),
                             GraspEvent(t_open, hand, "hifi", False)])


def _rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """``v`` rotated by ``angle`` (rad) about the unit ``axis`` (Rodrigues)."""
    c, s = np.cos(angle), np.sin(angle)
    return v * c + np.cross(axis, v) * s + axis * (axis @ v) * (1.0 - c)


#: Spine hinges turning the chest about the body's long axis (their ranges add up: 95 deg
#: either way), and the share of that range a greeting uses (the limits stay soft).
SPINE_ROT = ("lumbar_rot", "thorax_rot", "chest_rot")
SPINE_SHARE = 0.85
#: Largest turn of the chair the greeting asks of the feet, rad (beyond it the planted feet
#: slip on the floor instead of turning the seat, measured).
MAX_SWIVEL = np.deg2rad(40.0)
#: How far below the floor the planted feet aim, m: the knees then press them down (from
#: ~7 N resting to ~100 N a foot), so floor friction holds them while the hips turn the
#: seat; deeper (5 cm) lifts the thighs off the seat and the agent slips.
PLANT_DEPTH_M = 0.03
#: The waving arm: shoulder flexion, abduction and elbow flexion of the raised arm, rad;
#: the wave swings the abduction by +-WAVE_SWING, WAVE_CYCLES times of WAVE_PERIOD_S.
WAVE_POSE = {"upper_arm_flex": np.deg2rad(150.0), "upper_arm_abd": np.deg2rad(20.0),
             "forearm_flex": np.deg2rad(60.0)}
WAVE_SWING = np.deg2rad(15.0)
WAVE_CYCLES = 3
WAVE_PERIOD_S = 0.5
#: Feet keypoints kept planted on the floor while the seated agent turns.
FEET = ("left_ankle", "left_toe", "right_ankle", "right_toe")


def user_bearing(room: Room, data: mujoco.MjData) -> float:
    """Signed angle (rad, counter-clockwise positive) on the floor from the agent's chest
    forward axis to the direction from its chest to the user's chest."""
    names = room.agent.keypoint_names
    agent, user = room.agent_keypoints(data), room.user_keypoints(data)
    forward = data.xmat[room.model.body("agent/chest").id].reshape(3, 3)[:2, 0]
    to_user = user[room.user.keypoint_names.index("chest"), :2] - agent[names.index("chest"), :2]
    return float(np.arctan2(forward[0] * to_user[1] - forward[1] * to_user[0],
                            forward @ to_user))


def _turn_to_user(room: Room, data: mujoco.MjData, short: float | None = None
                  ) -> tuple[str, np.ndarray, np.ndarray, np.ndarray]:
    """The seated turn towards the user shared by the greeting and the bow, as agent qpos
    (nq,): the feet pressed onto the floor (``plant``), the leg hinges solved for the
    pelvis turned about the swivel axis with the feet where they are (``twisted``), then
    the spine's axial rotations added (``turned``); and the user's side (``left`` /
    ``right``). See :func:`plan_greet`.

    With ``short`` None (the greeting) the spine takes the turn first and the swivel the
    rest; with ``short`` (rad) the turn stops that much short of the user's bearing and
    the swivel takes it first, the spine the rest (the bow: a spine turned to its limit
    and held there, without the raised arm's counterweight, tipped the agent off the seat
    towards a user on its left, measured).

    Raises:
        SimenvError: the leg IK cannot keep the feet planted for the turn (1 cm).
    """
    h = room.agent
    q = data.qpos[room.agent_qpos].copy()
    phi = user_bearing(room, data)
    side = "right" if phi < 0 else "left"
    sign = np.sign(phi) or 1.0
    limits = {n: h.joint_limits[h.joint_names.index(n)] for n in SPINE_ROT}
    reach = SPINE_SHARE * sum(abs(lim[1 if sign > 0 else 0]) for lim in limits.values())
    if short is None:
        spine = min(1.0, abs(phi) / reach)
        delta = float(np.clip(phi - sign * spine * reach, -MAX_SWIVEL, MAX_SWIVEL))
    else:
        aim = max(abs(phi) - short, 0.0)
        delta = float(sign * min(aim, MAX_SWIVEL))
        spine = min(1.0, (aim - abs(delta)) / reach)
    legs = tuple(n for n in h.joint_names if n.split("_")[1] in ("thigh", "shin", "foot"))
    sites = [h.keypoint_names.index(f) for f in FEET]
    pressed = h.keypoints(q)[sites] - [0.0, 0.0, PLANT_DEPTH_M]
    plant, err0 = reach_pose(h.model, q, FEET, pressed, legs, iterations=400)
    axis = data.xpos[room.model.body("chair_seat").id][:2]
    turned, err1 = reach_pose(h.model, _swivelled(q, axis, delta), FEET, pressed, legs,
                              iterations=400)
    if max(err0, err1) > 0.01:
        raise SimenvError(f"the seated agent cannot turn {np.degrees(delta):.0f} deg with "
                          f"its feet planted ({max(err0, err1):.3f} m short)", field="greet")
    turned[:7] = q[:7]  # the legs' targets only: the root turns if the physics turns it
    # The spine turns after the seat: turning both at once, the spine's reaction torque on
    # the pelvis works against the feet and the seat turns less.
    twisted = turned.copy()
    for name in SPINE_ROT:
        turned[hinge_adr(h, name)] = spine * SPINE_SHARE * limits[name][1 if sign > 0 else 0]
    return side, plant, twisted, turned


def plan_greet(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for turning to face the user and waving, seated, from the current state.

    The chest turns by the user's bearing ``phi`` (:func:`user_bearing`): the spine's axial
    rotations take up to :data:`SPINE_SHARE` of their range and the rest, up to
    :data:`MAX_SWIVEL`, is the chair's swivel, turned by the legs: the feet are pressed
    onto the floor (:data:`PLANT_DEPTH_M`) and the leg hinges are solved (IK on the four
    feet keypoints) for the pelvis turned about the swivel axis with the feet where they
    are, so the servos twist the seat round over the planted feet. The arm on the user's
    side rises above the shoulder (:data:`WAVE_POSE`) and waves, then everything returns
    to the seated pose (the legs untwist and turn the seat back). Whether the agent
    faced the user is measured (:meth:`simenv.room.room.Room.greeting`), not assumed.

    Returns:
        the plan of the agent's targets, 7.8 s long.
    """
    h = room.agent
    side, plant, twisted, turned = _turn_to_user(room, data)
    raised = turned.copy()
    for part, angle in WAVE_POSE.items():
        raised[hinge_adr(h, f"{side}_{part}")] = angle
    upper = upper_body_joints(h)

    def targets(pose: np.ndarray) -> np.ndarray:
        return pd_targets(h, pose, upper)

    abd = hinge_adr(h, f"{side}_upper_arm_abd")
    swings = []
    for k in range(2 * WAVE_CYCLES):
        pose = raised.copy()
        pose[abd] += WAVE_SWING * (1 if k % 2 == 0 else -1)
        swings.append(targets(pose))
    now, t_plant, t_twist, t_raise = (data.ctrl[room.agent_ctrl].copy(), targets(plant),
                                      targets(twisted), targets(raised))
    rest = pd_targets(h, room.seated_pose(), upper)
    waves = [PDTrajectory(a, b, WAVE_PERIOD_S / 2)
             for a, b in zip([t_raise, *swings], [*swings, t_raise], strict=True)]
    return PDPlan([PDTrajectory(now, t_plant, 0.5), PDTrajectory(t_plant, t_twist, 1.5),
                   PDTrajectory(t_twist, t_raise, 1.0), *waves,
                   PDTrajectory(t_raise, t_twist, 1.0), PDTrajectory(t_twist, t_plant, 1.5),
                   PDTrajectory(t_plant, rest, 0.5)])


#: The seated bow, a nod: flexion of the neck, rad (added to the turned posture), reached
#: in BOW_DOWN_S, held BOW_HOLD_S, undone in BOW_UP_S. Flexing the spine too (5-10 deg a
#: segment) tipped the turned agent off the seat, measured.
BOW_POSE = {"neck_flex": np.deg2rad(30.0)}
#: Lateral lean of the lumbar spine away from the user's side during the nod, rad: the
#: turned trunk's weight sits over the seat's edge on the user's side (without it the agent
#: slid off the seat nodding to a user behind its right, measured).
BOW_COUNTER_LEAN = np.deg2rad(20.0)
#: The bow's turn stops this far short of the user's bearing, rad (within the 30 deg a
#: bow is measured at; see :func:`_turn_to_user`).
BOW_SHORT = np.deg2rad(15.0)
BOW_DOWN_S = 0.8
BOW_HOLD_S = 0.6
BOW_UP_S = 0.8


def plan_bow_back(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for bowing back to the user, seated, from the current state.

    The same turn as :func:`plan_greet` (planted feet twist the chair's swivel, then the
    spine's axial hinges turn the chest towards the user; the turn stops
    :data:`BOW_SHORT` short of the user and the swivel takes it first), then the neck
    flexes forward (:data:`BOW_POSE`) with the trunk leaning away from the user's side
    (:data:`BOW_COUNTER_LEAN`), holds, comes back up, and the agent turns back to the
    seated pose. Whether it bowed to the user is measured (:class:`simenv.room.room.BowMeter`:
    the head pitched at least 15 deg below its start while the chest faced the user within
    30 deg, then came back up), not assumed.

    Returns:
        the plan of the agent's targets, ``6 + BOW_DOWN_S + BOW_HOLD_S + BOW_UP_S`` s
        long (8.2 s).
    """
    h = room.agent
    side, plant, twisted, turned = _turn_to_user(room, data, BOW_SHORT)
    bowed = turned.copy()
    for name, angle in BOW_POSE.items():
        bowed[hinge_adr(h, name)] += angle
    # Positive lateral flexion leans to the right: lean away from the user's side.
    bowed[hinge_adr(h, "lumbar_lat")] += BOW_COUNTER_LEAN * (1.0 if side == "left" else -1.0)
    upper = upper_body_joints(h)
    now = data.ctrl[room.agent_ctrl].copy()
    t_plant, t_twist, t_turn, t_bow = (pd_targets(h, pose, upper)
                                       for pose in (plant, twisted, turned, bowed))
    rest = pd_targets(h, room.seated_pose(), upper)
    return PDPlan([PDTrajectory(now, t_plant, 0.5), PDTrajectory(t_plant, t_twist, 1.5),
                   PDTrajectory(t_twist, t_turn, 1.0), PDTrajectory(t_turn, t_bow, BOW_DOWN_S),
                   PDTrajectory(t_bow, t_bow, BOW_HOLD_S), PDTrajectory(t_bow, t_turn, BOW_UP_S),
                   PDTrajectory(t_turn, t_twist, 1.0), PDTrajectory(t_twist, t_plant, 1.5),
                   PDTrajectory(t_plant, rest, 0.5)])


def _swivelled(q: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """A copy of the agent's configuration with its root turned by ``angle`` (rad) about
    the vertical through ``axis`` (x, y, m)."""
    out = q.copy()
    c, s = np.cos(angle), np.sin(angle)
    v = q[:2] - axis
    out[:2] = axis + [c * v[0] - s * v[1], s * v[0] + c * v[1]]
    w1, z1 = np.cos(angle / 2), np.sin(angle / 2)
    w2, x2, y2, z2 = q[3:7]
    out[3:7] = [w1 * w2 - z1 * z2, w1 * x2 - z1 * y2, w1 * y2 + z1 * x2, w1 * z2 + z1 * w2]
    return out


#: Reaction name -> planner (room, data) -> PDPlan, or a PlanChain of stages planned one
#: after the other (the :class:`~simenv.agents.object_task.ObjectTask` planners
#: ``close_window`` / ``open_window`` / ``close_curtain``: stand up, walk, push / pull, walk
#: back, sit down; :mod:`simenv.agents.window`, :mod:`simenv.agents.window_open`,
#: :mod:`simenv.agents.curtain`).
PLANNERS: dict[str, Callable[[Room, mujoco.MjData], PDPlan | PlanChain]] = {
    "bow_back": plan_bow_back,
    "cigarette_out": plan_cigarette_out,
    "close_curtain": plan_close_curtain,
    "close_window": plan_close_window,
    "greet": plan_greet,
    "hifi_down": plan_hifi_down,
    "open_window": plan_open_window,
}


def object_success(room: Room, before: dict[str, str], after: dict[str, str],
                   reaction: str) -> bool:
    """Whether ``reaction``'s object went to its target label between two
    :meth:`~simenv.room.room.Room.object_labels` readings (False if it already was there)."""
    r = REACTIONS[reaction]
    if r.object is None:
        raise SimenvError(f"reaction {reaction!r} acts on no object", field="reaction")
    return before[r.object] != r.target and after[r.object] == r.target


__all__ = ["PLANNERS", "object_success", "plan_bow_back", "plan_cigarette_out",
           "plan_greet", "plan_hifi_down", "user_bearing"]

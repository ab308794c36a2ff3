"""Sit-to-stand for the seated agent: roll the chair back, draw the feet in, lean, rise,
and balance on the feet with centre-of-mass feedback; and sitting back down
(:func:`plan_sit_down`).

The phases are PD-target segments (minimum jerk, upper body gravity fed forward, as in
:mod:`simenv.agents.scripted`):

1. *roll back* (1.0 s): the feet pressed onto the floor and the leg hinges solved (IK on
   the four feet keypoints) for the pelvis :data:`ROLL_BACK_M` further back with the feet
   where they are; the knees extend and push the chair back on its casters (the room's
   ``chair/roll`` slide), clearing the knees from under the desk;
2. *feet in* (1.0 s): knees flexed to :data:`KNEE_DRAWN` and ankles dorsiflexed, the
   lightly loaded feet slide back towards the seat;
3. *lean* (1.2 s): hips flexed to :data:`HIP_LEAN` and the spine bent forward, which
   brings the centre of mass over the feet;
4. *rise* (2.0 s) and *stand* (:data:`HOLD_S`): targets to the standing rest pose.

Open-loop, the rise tips the body over the feet (measured: it ends on the desk, centre of
mass 0.43 m ahead of the feet). From the rise on, :class:`ComBalance` corrects the
targets at every physics step with the horizontal error ``e`` (m) of the centre of mass
``c`` with respect to the centre ``f`` of the four feet keypoints along the pelvis's
forward axis ``x``, and its rate ``e'`` (m/s)::

    e = (c - f) . x,    ankle flexion += K e + D e',    hip flexion -= H (K e + D e') if e < 0

(ankle strategy: plantarflexing -- ``foot_flex`` > 0 -- pushes the body back when the
centre of mass is ahead of the feet; hip strategy: while it is behind them, flexing the
hips further brings it forward). Nothing but the agent's own servos acts on it.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from functools import partial

import mujoco
import numpy as np

from simenv.agents.reach import (
    PDPlan,
    PDTrajectory,
    hinge_adr,
    pd_targets,
    reach_pose,
    upper_body_joints,
)
from simenv.body.humanoid import Humanoid
from simenv.core.errors import SimenvError
from simenv.room.room import Room

#: How far back the legs push the chair, m.
ROLL_BACK_M = 0.30
#: Knee flexion with the feet drawn in, rad (110-120 deg stand up; 130 deg measured to
#: tip the body forward onto the desk), and ankle dorsiflexion then, rad.
KNEE_DRAWN = np.deg2rad(120.0)
ANKLE_DRAWN = np.deg2rad(-25.0)
#: Hip flexion and forward bend of each of the three spine segments in the lean, rad.
HIP_LEAN = np.deg2rad(125.0)
SPINE_LEAN = np.deg2rad(15.0)
#: Durations of the phases, s.
PHASES_S = (1.0, 1.0, 1.2, 2.0)
#: Knee flexion of the standing pose the rise ends in, rad (:func:`standing_pose`).
STAND_KNEE = np.deg2rad(10.0)
#: Standing balanced after the rise, s.
HOLD_S = 3.0
#: Feet keypoints (planted; their centre is the support's).
FEET = ("left_ankle", "left_toe", "right_ankle", "right_toe")
#: How far below the floor the feet aim while they push, m (see
#: :data:`simenv.agents.scripted.PLANT_DEPTH_M`).
PLANT_DEPTH_M = 0.03


@dataclass
class ComBalance:
    """Centre-of-mass feedback on the ankles and hips (module docstring), active from
    ``t_on`` s into the plan.

    Attributes:
        room: the room (agent bodies, sites and actuators).
        t_on: start of the feedback, s into the plan.
        k: ``K``, rad of ankle flexion per m of error; d: ``D``, rad per m/s.
        hip: ``H``, hip flexion per unit of ankle correction while the centre of mass is
            behind the feet.
    """

    room: Room
    t_on: float
    k: float = 10.0
    d: float = 1.0
    hip: float = 2.0

    def __post_init__(self) -> None:
        h = self.room.agent
        self._ankles = [h.joint_names.index(f"{s}_foot_flex") for s in ("left", "right")]
        self._hips = [h.joint_names.index(f"{s}_thigh_flex") for s in ("left", "right")]
        self._feet = self.room.agent_sites[[h.keypoint_names.index(f) for f in FEET]]
        self._pelvis = self.room.model.body("agent/pelvis").id
        self._last: tuple[float, float] | None = None

    def error(self, data: mujoco.MjData) -> float:
        """``e``: centre of mass ahead of the feet's centre along the pelvis's forward axis,
        m (after ``mj_forward``/``mj_step``)."""
        forward = data.xmat[self._pelvis].reshape(3, 3)[:2, 0]
        centre = data.site_xpos[self._feet, :2].mean(axis=0)
        return float((data.subtree_com[self._pelvis, :2] - centre) @ forward)

    def __call__(self, t: float, data: mujoco.MjData, targets: np.ndarray) -> np.ndarray:
        e = self.error(data)
        last, self._last = self._last, (t, e)
        if t < self.t_on:
            return targets
        rate = 0.0 if last is None or t <= last[0] else (e - last[1]) / (t - last[0])
        u = targets.copy()
        correction = self.k * e + self.d * rate
        u[self._ankles] += correction
        if e < 0.0:
            u[self._hips] -= self.hip * correction
        return u


def standing_pose(h: Humanoid) -> np.ndarray:
    """(nq,) the standing rest pose with the knees :data:`STAND_KNEE` flexed (the hips
    and ankles half that each, the trunk upright): the knee's range reaches 15 deg of
    hyperextension, and a straight knee under the body's weight buckled back into it
    (measured: the rising body then leant onto the desk, centre of mass 0.38 m ahead of
    the feet)."""
    q = h.default_qpos()
    for side in ("left", "right"):
        for name, angle in ((f"{side}_shin_flex", STAND_KNEE),
                            (f"{side}_thigh_flex", STAND_KNEE / 2),
                            (f"{side}_foot_flex", -STAND_KNEE / 2)):
            q[h.hinge_qpos[h.joint_names.index(name)]] = angle
    return q


def plan_stand_up(room: Room, data: mujoco.MjData, balance: bool = True) -> PDPlan:
    """Plan for standing up from the chair from the current (seated) state.

    Args:
        balance: with :class:`ComBalance` from the rise on (False: open loop, which falls).

    Raises:
        SimenvError: the legs cannot push the chair back with the feet planted (IK more
            than 2 cm short).

    Returns:
        the plan of the agent's targets (``sum(PHASES_S) + HOLD_S`` = 8.2 s), with its
        feedback.
    """
    h = room.agent
    q = data.qpos[room.agent_qpos].copy()
    legs = tuple(n for n in h.joint_names if n.split("_")[1] in ("thigh", "shin", "foot"))
    feet = [h.keypoint_names.index(f) for f in FEET]
    pressed = h.keypoints(q)[feet] - [0.0, 0.0, PLANT_DEPTH_M]
    back = q.copy()
    heading = data.xmat[room.model.body("agent/pelvis").id].reshape(3, 3)[:2, 0]
    back[:2] -= ROLL_BACK_M * heading
    # The knees stop straight (the model's range reaches 15 deg of hyperextension, which
    # the IK then used: the chair rolled 0.5 m instead of 0.4 and the rise tipped onto
    # the desk, measured).
    m = copy.copy(h.model)
    for side in ("left", "right"):
        m.jnt_range[m.joint(f"{side}_shin_flex").id, 0] = 0.0
    pushed, err = reach_pose(m, back, FEET, pressed, legs, iterations=400)
    if err > 0.02:
        raise SimenvError(f"the seated agent cannot push its chair back ({err:.3f} m short)",
                          field="stand_up")
    pushed[:7] = q[:7]  # the legs' targets only: the chair rolls if the physics rolls it
    adr = partial(hinge_adr, h)
    drawn = q.copy()
    for side in ("left", "right"):
        drawn[adr(f"{side}_shin_flex")] = KNEE_DRAWN
        drawn[adr(f"{side}_foot_flex")] = ANKLE_DRAWN
    lean = drawn.copy()
    for side in ("left", "right"):
        lean[adr(f"{side}_thigh_flex")] = HIP_LEAN
    for name in ("lumbar_flex", "thorax_flex", "chest_flex"):
        lean[adr(name)] = SPINE_LEAN
    upper = upper_body_joints(h)
    poses = [pd_targets(h, p, upper) for p in (pushed, drawn, lean, standing_pose(h))]
    now = data.ctrl[room.agent_ctrl].copy()
    segments = [PDTrajectory(a, b, dt)
                for a, b, dt in zip([now, *poses[:-1]], poses, PHASES_S, strict=True)]
    segments.append(PDTrajectory(poses[-1], poses[-1], HOLD_S))
    t_rise = sum(PHASES_S[:3])
    return PDPlan(segments, feedback=ComBalance(room, t_rise) if balance else None)


#: Sitting down: the crouch (knee and hip flexion, rad) lowered to with balance, and the
#: durations of the crouch, of the move to the seated pose and of the hold, s.
KNEE_CROUCH = np.deg2rad(100.0)
HIP_CROUCH = np.deg2rad(100.0)
SIT_PHASES_S = (2.5, 1.5, 1.5)


def plan_sit_down(room: Room, data: mujoco.MjData) -> PDPlan:
    """Plan for sitting back down on the chair behind the standing agent (where standing
    up left it, or where :mod:`simenv.agents.seat`'s steps put it), from the current
    state: crouch with the spine bent forward until the seat takes the weight, move to the
    seated pose, hold. Open loop: the seat is behind
    the feet, so the crouch ends on it (measured: peak descent 0.4 m/s, centre of mass at
    most 14 cm behind the feet before the seat touches; :class:`ComBalance` during the
    crouch changed neither). The chair stays where it rolled: pulling it back to the desk
    with the feet does not work yet (measured: the pelvis slides on the seat instead).

    Returns:
        the plan (``sum(SIT_PHASES_S)`` = 5.5 s).
    """
    h = room.agent
    adr = partial(hinge_adr, h)
    crouch = h.default_qpos()
    for side in ("left", "right"):
        crouch[adr(f"{side}_shin_flex")] = KNEE_CROUCH
        crouch[adr(f"{side}_thigh_flex")] = HIP_CROUCH
        crouch[adr(f"{side}_foot_flex")] = ANKLE_DRAWN
    for name in ("lumbar_flex", "thorax_flex", "chest_flex"):
        crouch[adr(name)] = SPINE_LEAN
    upper = upper_body_joints(h)
    low, seated = (pd_targets(h, p, upper) for p in (crouch, room.seated_pose()))
    now = data.ctrl[room.agent_ctrl].copy()
    down, sit, hold = SIT_PHASES_S
    return PDPlan([PDTrajectory(now, low, down), PDTrajectory(low, seated, sit),
                   PDTrajectory(seated, seated, hold)])


def seated(room: Room, data: mujoco.MjData) -> bool:
    """Whether the chair's seat carries the agent now (touches any of its geoms)."""
    seat = room.model.geom("chair/seat").id
    geoms = data.contact.geom[:data.ncon]
    return bool(((geoms == seat).any(axis=1)).any())


def standing(room: Room, data: mujoco.MjData, tolerance_m: float = 0.05) -> dict[str, float | bool]:
    """Whether the agent stands now: ``pelvis_height`` (m) at least 90 % of its standing
    rest height, the centre of mass within ``tolerance_m`` of the feet's centre along its
    heading (``com_error_m``), and nothing but its feet on the floor or the chair
    (``other_contacts``: agent geoms touching anything but through a foot or toe).
    """
    h, m = room.agent, room.model
    pelvis = float(data.qpos[room.agent_qpos][2])
    rest = float(h.default_qpos()[2])
    e = ComBalance(room, 0.0).error(data)
    others = 0
    for k in range(data.ncon):
        g1, g2 = (m.geom(int(g)).name for g in data.contact.geom[k])
        ours = [g for g in (g1, g2) if g.startswith("agent/")]
        if len(ours) == 1 and not any(p in ours[0] for p in ("foot", "toes")):
            others += 1
    return {"pelvis_height": pelvis, "com_error_m": e, "other_contacts": others,
            "success": bool(pelvis >= 0.9 * rest and abs(e) <= tolerance_m and others == 0)}


__all__ = ["ComBalance", "plan_sit_down", "plan_stand_up", "seated", "standing"]

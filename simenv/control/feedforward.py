"""Feed-forward hinge torques from the inverse dynamics of the reference.

A servo alone, ``kp (q* - q) + kv (qd* - qd)``, only pushes once the joint
has already missed its target: a stance knee carrying the body sags by
``tau / kp`` (0.1-0.2 rad at the humanoid's gains). The torques the
reference motion needs are known up front. Per reference frame ``t``, with
``M`` the mass matrix, ``c`` the bias forces (gravity, Coriolis, passive) and
``tau_id = M(q) qdd* + c(q, qd*)`` (``mj_inverse`` without contacts), the
floor must supply the root's part of ``tau_id``: the contact forces
``lambda >= 0`` on the friction-pyramid edges of the body's points near the
floor that best reproduce the root wrench
(:func:`simenv.body.dynamics.floor_forces`, non-negative least
squares). The hinges supply the rest::

    tau_ff = tau_id,hinge - sum_p (J_p^T f_p)_hinge,   f_p = sum_d lambda_pd e_d

with ``J_p`` the translational Jacobian of the body that carries support
point ``p``. Whatever root wrench the floor cannot explain is *not*
applied anywhere -- it is the balance the planner must find with the limbs.
The torques are clipped to the actuator force limits (muscles, never the root).
"""

from __future__ import annotations

import mujoco
import numpy as np

from simenv.body.dynamics import (
    DEFAULT_DYNAMICS,
    DynamicsSettings,
    finite_differences,
    floor_forces,
    friction_pyramid,
    inverse_dynamics,
    root_wrench,
)
from simenv.body.geometry import body_geoms, geom_support_points, support_point_bodies
from simenv.body.retarget import RetargetResult


def feedforward_torques(result: RetargetResult,
                        settings: DynamicsSettings = DEFAULT_DYNAMICS) -> np.ndarray:
    """``tau_ff`` per reference frame and actuator (module docstring), (T, nu) N m,
    clipped to the actuator force ranges of ``result.humanoid.model``. ``settings``:
    the velocity filter, the floor's friction and which points may carry load."""
    model = result.humanoid.model
    q = result.qpos
    qvel, qacc = finite_differences(model, q, result.fps, settings.cutoff_hz)
    tau = inverse_dynamics(model, q, qvel, qacc)
    rw = root_wrench(result, settings)
    geoms = body_geoms(model)
    points = geom_support_points(model, rw.poses, geoms)
    bodies = support_point_bodies(model, geoms)
    edges = friction_pyramid(settings.friction)
    joints = model.actuator_trnid[:, 0]
    dofs = model.jnt_dofadr[joints]
    data = mujoco.MjData(model)
    jacp = np.empty((3, model.nv))
    out = tau[:, dofs].copy()
    for t in range(len(q)):
        near = points[t, :, 2] < settings.support_height_m
        if not near.any():
            continue
        lam = floor_forces(rw, t).reshape(-1, len(edges))
        forces = lam @ edges
        data.qpos[:] = q[t]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        contact = np.zeros(model.nv)
        for p, body, f in zip(points[t, near], bodies[near], forces, strict=True):
            if not f.any():
                continue
            mujoco.mj_jac(model, data, jacp, None, p, int(body))
            contact += jacp.T @ f
        out[t] -= contact[dofs]
    lo, hi = model.actuator_forcerange[:, 0], model.actuator_forcerange[:, 1]
    return np.clip(out, lo, hi)

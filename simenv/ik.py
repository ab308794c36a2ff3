"""Batched kinematics of a floating-base hinge tree, for whole-clip inverse kinematics.

The tree is read from a compiled :class:`mujoco.MjModel` with one free joint
(the root) and hinge joints elsewhere. A configuration of T frames is

* ``root_pos`` (T, 3) and ``root_rot`` (T, 3, 3): the root body's pose,
* ``theta`` (T, H): the hinge angles, in the model's joint order.

Forward kinematics composes, per body b with parent p,
``R_b = R_p R(q_b) H_1(theta_1) ... H_n(theta_n)`` and
``x_b = x_p + R_p pos_b``, vectorised over frames (the Python loop runs over the
~20 bodies, never over frames). Points are ``x_b + R_b s`` for body-fixed
offsets ``s`` (sites, geom corners).

Jacobians are analytic: with the tangent ``delta = (dx, dw, dtheta)`` (root
translation, root rotation as a world-frame rotation vector, hinge angles),

* d point / dx = I,
* d point / dw_i = e_i x (point - x_root),
* d point / dtheta_j = a_j x (point - c_j) when joint j is an ancestor of the
  point's body (a_j the world axis, c_j the world anchor), else 0.

This matches MuJoCo's ``mj_jac`` up to the root-rotation frame (MuJoCo uses the
body frame for the free joint's angular velocity; we use the world frame).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (w, x, y, z) -> (..., 3, 3) rotation matrices."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def mat_to_quat(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions (w, x, y, z), w >= 0."""
    m = R
    tr = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    cand = np.stack([
        np.stack([1 + tr, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0],
                  m[..., 1, 0] - m[..., 0, 1]], -1),
        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2],
                  m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),
        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0],
                  1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2], m[..., 1, 2] + m[..., 2, 1]],
                 -1),
        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0],
                  m[..., 1, 2] + m[..., 2, 1], 1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2]],
                 -1),
    ], -2)
    # Pick the numerically best of the four (largest diagonal term).
    diag = np.stack([tr, m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]], -1)
    best = np.argmax(diag, axis=-1)
    q = np.take_along_axis(cand, best[..., None, None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return q * np.where(q[..., :1] < 0, -1.0, 1.0)


def axis_angle_mat(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: (..., 3) unit axes, (...) angles -> (..., 3, 3)."""
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    x, y, z = np.moveaxis(axis, -1, 0)
    zero = np.zeros_like(x)
    K = np.stack([np.stack([zero, -z, y], -1), np.stack([z, zero, -x], -1),
                  np.stack([-y, x, zero], -1)], -2)
    eye = np.broadcast_to(np.eye(3), K.shape)
    return eye + s * K + (1 - c) * (K @ K)


def hinge_mat(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices (T, 3, 3) about one fixed unit ``axis`` (3,) by ``angle`` (T,).

    Axis-aligned hinges (the usual case) are filled in directly; other axes use
    Rodrigues' formula.
    """
    i = int(np.argmax(np.abs(axis)))
    if abs(abs(axis[i]) - 1.0) > 1e-12:
        return axis_angle_mat(np.broadcast_to(axis, (len(angle), 3)), angle)
    c, s = np.cos(angle), np.sin(angle) * np.sign(axis[i])
    j, k = (i + 1) % 3, (i + 2) % 3
    R = np.zeros((len(angle), 3, 3))
    R[:, i, i] = 1.0
    R[:, j, j] = c
    R[:, k, k] = c
    R[:, k, j] = s
    R[:, j, k] = -s
    return R


def rotvec_mat(v: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors -> (..., 3, 3)."""
    ang = np.linalg.norm(v, axis=-1)
    axis = v / np.maximum(ang, 1e-12)[..., None]
    return axis_angle_mat(axis, ang)


@dataclass
class Kinematics:
    """FK result for T frames.

    Attributes:
        body_rot: (T, B, 3, 3) world rotations. body_pos: (T, B, 3) world origins.
        axes: (T, H, 3) world hinge axes. anchors: (T, H, 3) world hinge anchors.
        points: (T, P, 3) world positions of the tree's points.
    """

    body_rot: np.ndarray
    body_pos: np.ndarray
    axes: np.ndarray
    anchors: np.ndarray
    points: np.ndarray


class HingeTree:
    """Kinematic tree of a free-floating model with hinge joints, plus body-fixed points.

    Args:
        model: compiled MjModel; body 1 must carry the only free joint, every
            other joint must be a hinge.
        point_bodies: (P,) body id of each point. point_offsets: (P, 3) offsets
            in the body frame.

    Attributes:
        H: number of hinges. nv = 6 + H tangent dimension.
        lower, upper: (H,) hinge limits (radians, -inf/inf when unlimited).
        ancestor: (H, P) bool, joint j moves point p.
        qpos_hinge: (H,) qpos addresses of the hinges.
    """

    def __init__(self, model: mujoco.MjModel, point_bodies: np.ndarray,
                 point_offsets: np.ndarray) -> None:
        free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
        if len(free) != 1 or model.jnt_bodyid[free[0]] != 1:
            raise ValueError("HingeTree needs exactly one free joint, on body 1")
        hinges = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
        if len(hinges) + 1 != model.njnt:
            raise ValueError("HingeTree supports only hinge joints below the root")
        self.model = model
        self.root_qpos = int(model.jnt_qposadr[free[0]])
        self.nb = model.nbody
        self.parent = model.body_parentid.copy()
        self.body_offset = model.body_pos.copy()
        self.body_quat_rot = quat_to_mat(model.body_quat.copy())
        self.body_has_rot = ~np.all(np.isclose(model.body_quat, [1, 0, 0, 0]), axis=1)
        self.H = len(hinges)
        self.nv = 6 + self.H
        self.hinge_body = model.jnt_bodyid[hinges].copy()
        self.hinge_axis = model.jnt_axis[hinges].copy()
        self.hinge_pos = model.jnt_pos[hinges].copy()
        self.qpos_hinge = model.jnt_qposadr[hinges].copy()
        # Axis-aligned hinges (index of the axis, its sign) take a fast path.
        idx = np.argmax(np.abs(self.hinge_axis), axis=1)
        aligned = np.isclose(np.abs(self.hinge_axis[np.arange(self.H), idx]), 1.0)
        self.hinge_index = np.where(aligned, idx, -1)
        self.hinge_sign = np.sign(self.hinge_axis[np.arange(self.H), idx])
        limited = model.jnt_limited[hinges].astype(bool)
        self.lower = np.where(limited, model.jnt_range[hinges, 0], -np.inf)
        self.upper = np.where(limited, model.jnt_range[hinges, 1], np.inf)
        self.body_hinges = [np.flatnonzero(self.hinge_body == b) for b in range(self.nb)]
        self.point_bodies = np.asarray(point_bodies, dtype=int)
        self.point_offsets = np.asarray(point_offsets, dtype=float)
        anc_body = np.zeros((self.nb, len(self.point_bodies)), dtype=bool)
        for p, b in enumerate(self.point_bodies):
            while b > 0:
                anc_body[b, p] = True
                b = self.parent[b]
        self.ancestor = anc_body[self.hinge_body]
        self.pair_hinge, self.pair_point = np.nonzero(self.ancestor)

    # -- conversions between qpos and (root_pos, root_rot, theta) ------------

    def split_qpos(self, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r = self.root_qpos
        return (qpos[:, r:r + 3].copy(), quat_to_mat(qpos[:, r + 3:r + 7]),
                qpos[:, self.qpos_hinge].copy())

    def join_qpos(self, root_pos: np.ndarray, root_rot: np.ndarray, theta: np.ndarray,
                  ) -> np.ndarray:
        T = len(theta)
        q = np.tile(self.model.qpos0, (T, 1))
        r = self.root_qpos
        q[:, r:r + 3] = root_pos
        q[:, r + 3:r + 7] = mat_to_quat(root_rot)
        q[:, self.qpos_hinge] = theta
        return q

    # -- forward kinematics and Jacobians ------------------------------------

    def forward(self, root_pos: np.ndarray, root_rot: np.ndarray, theta: np.ndarray,
                ) -> Kinematics:
        """Batched FK over T frames (see the class docstring for shapes)."""
        T = len(theta)
        Rb = np.empty((T, self.nb, 3, 3))
        xb = np.empty((T, self.nb, 3))
        axes = np.empty((T, self.H, 3))
        anchors = np.empty((T, self.H, 3))
        Rb[:, 0] = np.eye(3)
        xb[:, 0] = 0.0
        for b in range(1, self.nb):
            if b == 1:
                R, x = root_rot, root_pos
            else:
                p = self.parent[b]
                Rp = Rb[:, p]
                x = xb[:, p] + Rp @ self.body_offset[b]
                R = Rp @ self.body_quat_rot[b] if self.body_has_rot[b] else Rp
            for j in self.body_hinges[b]:
                anchors[:, j] = x + R @ self.hinge_pos[j] if self.hinge_pos[j].any() else x
                i = self.hinge_index[j]
                if i < 0:
                    axes[:, j] = R @ self.hinge_axis[j]
                    R = R @ hinge_mat(self.hinge_axis[j], theta[:, j])
                    continue
                # Axis-aligned hinge: the world axis is a column of R, and
                # R @ H(theta) only mixes the two other columns.
                sign = self.hinge_sign[j]
                axes[:, j] = sign * R[:, :, i]
                c, s = np.cos(theta[:, j])[:, None], (sign * np.sin(theta[:, j]))[:, None]
                k1, k2 = (i + 1) % 3, (i + 2) % 3
                col1, col2 = R[:, :, k1], R[:, :, k2]
                R = R.copy()
                R[:, :, k1] = c * col1 + s * col2
                R[:, :, k2] = c * col2 - s * col1
            Rb[:, b] = R
            xb[:, b] = x
        pts = xb[:, self.point_bodies] + np.einsum(
            "tpij,pj->tpi", Rb[:, self.point_bodies], self.point_offsets)
        return Kinematics(Rb, xb, axes, anchors, pts)

    def jacobian(self, kin: Kinematics, root_pos: np.ndarray) -> np.ndarray:
        """(T, P, 3, nv) Jacobian of every point w.r.t. (dx, dw, dtheta)."""
        pts = kin.points
        T, P, _ = pts.shape
        J = np.zeros((T, P, 3, self.nv))
        J[:, :, 0, 0] = J[:, :, 1, 1] = J[:, :, 2, 2] = 1.0
        r = pts - root_pos[:, None, :]
        # e_i x r: columns of the cross-product matrix -[r]x.
        J[:, :, 0, 4], J[:, :, 0, 5] = r[..., 2], -r[..., 1]
        J[:, :, 1, 3], J[:, :, 1, 5] = -r[..., 2], r[..., 0]
        J[:, :, 2, 3], J[:, :, 2, 4] = r[..., 1], -r[..., 0]
        # Only (hinge, point) pairs where the hinge moves the point.
        jj, pp = self.pair_hinge, self.pair_point
        a = kin.axes[:, jj]
        lv = pts[:, pp] - kin.anchors[:, jj]
        cols = np.stack([a[..., 1] * lv[..., 2] - a[..., 2] * lv[..., 1],
                         a[..., 2] * lv[..., 0] - a[..., 0] * lv[..., 2],
                         a[..., 0] * lv[..., 1] - a[..., 1] * lv[..., 0]], axis=0)
        J[:, pp, :, 6 + jj] = cols.transpose(2, 1, 0)
        return J

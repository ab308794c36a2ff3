"""Batched kinematics of a floating-base hinge tree, for whole-clip inverse kinematics.

The tree is read from a compiled :class:`mujoco.MjModel` with one free joint
(the root) and hinge joints elsewhere. A configuration of T frames is

* ``root_pos`` (T, 3) and ``root_rot`` (T, 3, 3): the root body's pose,
* ``theta`` (T, H): the hinge angles, in the model's joint order.

Forward kinematics composes, per body b with parent p,
``R_b = R_p R(q_b) H_1(theta_1) ... H_n(theta_n)`` and
``x_b = x_p + R_p pos_b`` (a compiled loop over frames, then bodies). Points
are ``x_b + R_b s`` for body-fixed offsets ``s`` (sites, geom corners).

Jacobians are analytic: with the tangent ``delta = (dx, dw, dtheta)`` (root
translation, root rotation as a world-frame rotation vector, hinge angles),

* d point / dx = I,
* d point / dw_i = e_i x (point - x_root),
* d point / dtheta_j = a_j x (point - c_j) when joint j is an ancestor of the
  point's body (a_j the world axis, c_j the world anchor), else 0.

This matches MuJoCo's ``mj_jac`` up to the root-rotation frame (MuJoCo uses the
body frame for the free joint's angular velocity; we use the world frame).

:meth:`HingeTree.fit_iteration` runs one projected Levenberg-Marquardt step of
a keypoint fit on many frames. FK, Jacobians and the fit are compiled per-frame
kernels (numba, cached on disk), called once per batch of frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numba
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


def half_rotation(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations -> the rotations about the same axes by half the
    angle (the quaternion halfway from the identity: ``unit(q + 1)``, w >= 0)."""
    q = mat_to_quat(R)
    q[..., 0] += 1.0
    return quat_to_mat(q)


def swing(R: np.ndarray, v0: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Smallest rotation turning ``R @ v0`` onto the direction ``u``, applied to R.

    Args:
        R: (T, 3, 3) rotations. v0: (3,) body vector. u: (T, 3) world directions.
    Returns:
        (T, 3, 3) ``exp([a]x phi) R`` with a = unit(R v0 x u) (x when parallel) and
        phi the angle between R v0 and u.
    """
    out = np.empty((len(R), 3, 3))
    _swing_batch(_f64(R), _f64(v0), _f64(u), out)
    return out


def _frame(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3, 3) orthonormal frame with columns unit(a), unit(b's part normal to a), their cross."""
    e1 = a / max(np.linalg.norm(a), 1e-12)
    e2 = b - (b @ e1) * e1
    e2 = e2 / max(np.linalg.norm(e2), 1e-12)
    return np.stack([e1, e2, np.cross(e1, e2)], axis=-1)


def two_vector(v0: np.ndarray, w0: np.ndarray, u: np.ndarray, wt: np.ndarray) -> np.ndarray:
    """World rotations taking the body vector v0 exactly onto u and w0 as close as
    possible to wt: ``F(u, wt) F(v0, w0)^T`` with F the frame of :func:`_frame`.

    Args:
        v0, w0: (3,) body vectors. u, wt: (T, 3) world vectors.
    Returns:
        (T, 3, 3) rotations.
    """
    out = np.empty((len(u), 3, 3))
    _two_vector_batch(_f64(_frame(v0, w0).T), _f64(u), _f64(wt), out)
    return out


def compose_hinges(R: np.ndarray, axes: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """``R H(a_1, angles_1) ... H(a_n, angles_n)`` per frame.

    Args:
        R: (T, 3, 3). axes: (n, 3) unit hinge axes (body frame). angles: (T, n) radians.
    Returns:
        (T, 3, 3).
    """
    out = _f64(R).copy()
    _compose_batch(out, _f64(axes), _f64(angles.reshape(len(R), -1)))
    return out


def euler_branches(R: np.ndarray, order: tuple[int, int, int], signs: np.ndarray,
                   lower: np.ndarray, upper: np.ndarray,
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Both intrinsic Tait-Bryan decompositions R = R_i(a) R_j(b) R_k(c), per frame.

    The two solutions are (a, b, c) and (a + pi, pi - b, c + pi) with
    b = asin(eps R_ik), a = atan2(-eps R_jk, R_kk), c = atan2(-eps R_ij, R_ii),
    eps = +1 for an even (i, j, k), -1 for an odd one. The first n = len(signs)
    angles are a joint's hinge angles (times the hinge axis signs), wrapped
    into the 2 pi window centred on the joint range; the others are dropped.

    Args:
        R: (T, 3, 3) local rotations. order: axis indices (i, j, k), a permutation.
        signs: (n,) +-1 sign of each hinge axis. lower, upper: (n,) limits, radians.
    Returns:
        sols (T, 2, n) wrapped hinge angles clipped to the limits; viol (T, 2) sum
        of the limit violations before clipping (radians); dropped (T, 2) sum of
        |dropped angle| (wrapped to [-pi, pi)).
    """
    T, n = len(R), len(signs)
    eps = 1.0 if tuple(order) in ((0, 1, 2), (1, 2, 0), (2, 0, 1)) else -1.0
    finite = np.isfinite(lower + upper)
    centre = np.where(finite, (lower + upper) / 2, 0.0)
    sols, viol, dropped = np.empty((T, 2, n)), np.empty((T, 2)), np.empty((T, 2))
    _euler_batch(_f64(R), np.asarray(order, dtype=np.int64), eps, _f64(signs), _f64(lower),
                 _f64(upper), _f64(centre), sols, viol, dropped)
    return sols, viol, dropped


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


@dataclass(frozen=True)
class PointFit:
    """Settings of one :meth:`HingeTree.fit_iteration` (the objective's weights).

    Attributes:
        reg: weight of |theta|^2 (per rad^2).
        smooth: weight of |theta - theta_nbr|^2 + |x_root - x_nbr|^2.
        floor_weight: weight of min(0, z - floor)^2 per floor point.
        max_step: largest |delta| over rotation and hinge coordinates (radians).
        tol: relative cost decrease below which an accepted frame is done.
        step_tol: largest |delta| below which an accepted frame is done.
    """

    reg: float
    smooth: float
    floor_weight: float
    max_step: float
    tol: float
    step_tol: float


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
        self.parent = model.body_parentid.astype(np.int64)
        self.body_offset = model.body_pos.copy()
        self.body_quat_rot = quat_to_mat(model.body_quat.copy())
        self.body_has_rot = ~np.all(np.isclose(model.body_quat, [1, 0, 0, 0]), axis=1)
        self.H = len(hinges)
        self.nv = 6 + self.H
        self.hinge_body = model.jnt_bodyid[hinges].astype(np.int64)
        self.hinge_axis = model.jnt_axis[hinges].copy()
        self.hinge_pos = model.jnt_pos[hinges].copy()
        self.qpos_hinge = model.jnt_qposadr[hinges].copy()
        limited = model.jnt_limited[hinges].astype(bool)
        self.lower = np.where(limited, model.jnt_range[hinges, 0], -np.inf)
        self.upper = np.where(limited, model.jnt_range[hinges, 1], np.inf)
        self.body_hinges = [np.flatnonzero(self.hinge_body == b) for b in range(self.nb)]
        self.point_bodies = np.asarray(point_bodies, dtype=np.int64)
        self.point_offsets = np.asarray(point_offsets, dtype=float)
        anc_body = np.zeros((self.nb, len(self.point_bodies)), dtype=bool)
        for p, b in enumerate(self.point_bodies):
            while b > 0:
                anc_body[b, p] = True
                b = self.parent[b]
        self.ancestor = anc_body[self.hinge_body]
        # MuJoCo numbers joints body by body, so body b's hinges are the
        # contiguous range hinge_start[b]:hinge_start[b + 1] (what the kernels use).
        if np.any(np.diff(self.hinge_body) < 0):
            raise ValueError("HingeTree expects the hinges ordered by body")
        hinge_start = np.searchsorted(self.hinge_body, np.arange(self.nb + 1)).astype(np.int64)
        # Each point's ancestor hinges, CSR: anc_idx[anc_ptr[p]:anc_ptr[p + 1]].
        anc_ptr = np.concatenate([[0], np.cumsum(self.ancestor.sum(axis=0))]).astype(np.int64)
        anc_idx = np.nonzero(self.ancestor.T)[1].astype(np.int64)
        # The arrays every kernel takes, in the order _unpack documents.
        self.arrays = (self.parent, np.ascontiguousarray(self.body_offset),
                       np.ascontiguousarray(self.body_quat_rot), hinge_start,
                       np.ascontiguousarray(self.hinge_axis), np.ascontiguousarray(self.hinge_pos),
                       self.point_bodies, np.ascontiguousarray(self.point_offsets), anc_ptr,
                       anc_idx, np.ascontiguousarray(self.lower),
                       np.ascontiguousarray(self.upper))

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

    # -- forward kinematics, Jacobians, point fitting ------------------------

    def forward(self, root_pos: np.ndarray, root_rot: np.ndarray, theta: np.ndarray,
                ) -> Kinematics:
        """Batched FK over T frames (see the class docstring for shapes)."""
        T, P = len(theta), len(self.point_bodies)
        kin = Kinematics(np.empty((T, self.nb, 3, 3)), np.empty((T, self.nb, 3)),
                         np.empty((T, self.H, 3)), np.empty((T, self.H, 3)),
                         np.empty((T, P, 3)))
        _forward_batch(_f64(root_pos), _f64(root_rot), _f64(theta), self.arrays,
                       kin.body_rot, kin.body_pos, kin.axes, kin.anchors, kin.points)
        return kin

    def points(self, root_pos: np.ndarray, root_rot: np.ndarray, theta: np.ndarray,
               ) -> np.ndarray:
        """(T, P, 3) world positions of the points only (FK without keeping the bodies)."""
        pts = np.empty((len(theta), len(self.point_bodies), 3))
        _points_batch(_f64(root_pos), _f64(root_rot), _f64(theta), self.arrays, pts)
        return pts

    def jacobian(self, kin: Kinematics, root_pos: np.ndarray) -> np.ndarray:
        """(T, P, 3, nv) Jacobian of every point w.r.t. (dx, dw, dtheta)."""
        T, P, _ = kin.points.shape
        J = np.zeros((T, P, 3, self.nv))
        _jacobian_batch(_f64(root_pos), kin.axes, kin.anchors, kin.points, self.arrays, J)
        return J

    def fit_iteration(self, frames: np.ndarray, state: tuple[np.ndarray, np.ndarray, np.ndarray],
                      nbr_pos: np.ndarray, nbr_theta: np.ndarray, mu: np.ndarray,
                      active: np.ndarray, targets: np.ndarray, weights: np.ndarray,
                      floor: np.ndarray | None, dofs: np.ndarray, fit: PointFit) -> None:
        """One projected Levenberg-Marquardt iteration on each frame of ``frames``.

        Per frame t, with the first K points as keypoints and the rest as floor
        points, it decreases

            E(q) = sum_k w_k |p_k(q) - x_tk|^2 + floor_weight sum_c min(0, z_c(q) - f_t)^2
                 + reg |theta|^2 + smooth (|theta - theta_nbr|^2 + |x_root - x_nbr|^2)

        by the Gauss-Newton step over the tangent coordinates ``dofs``,
        ``(H + mu diag(H) + 1e-6 mu) delta = -g``, with H = J^T W J + the
        regularisers (J sparse: a point moves only with its ancestor hinges,
        so the normal matrix is accumulated point by point over those columns
        only). Hinges at a bound whose gradient pushes outwards are frozen
        (active set), the step is scaled to ``max_step`` and projected onto
        the limits. The step is kept if E decreases (then mu *= 0.3, else
        mu *= 8, mu in [1e-7, 1e6]); a frame leaves ``active`` when an accepted
        step decreased E by less than ``tol`` E + 1e-10 or moved less than
        ``step_tol``, or when mu reaches 1e6.

        Args:
            frames: (n,) int frame indices to iterate on.
            state: (root_pos (T, 3), root_rot (T, 3, 3), theta (T, H)), updated in place.
            nbr_pos, nbr_theta: (n, 3), (n, H) the smoothness targets of ``frames``.
            mu: (T,) damping, updated in place. active: (T,) bool, updated in place.
            targets: (T, K, 3) keypoint targets (m). weights: (K,) keypoint weights.
            floor: (T,) lowest allowed height of the floor points (m), or None
                (no floor term).
            dofs: tangent coordinates that move (indices into the nv of (dx, dw, dtheta)).
            fit: the objective's weights and the stopping rules.
        """
        root_pos, root_rot, theta = state
        K = targets.shape[1]
        col_map = np.full(self.nv, -1, dtype=np.int64)
        col_map[dofs] = np.arange(len(dofs))
        use_floor = floor is not None
        fl = _f64(floor) if use_floor else np.zeros(len(theta))
        _fit_iteration(frames.astype(np.int64), root_pos, root_rot, theta, _f64(nbr_pos),
                       _f64(nbr_theta), mu, active, _f64(targets), _f64(weights), K, fl,
                       use_floor, col_map, self.arrays, fit.reg, fit.smooth, fit.floor_weight,
                       fit.max_step, fit.tol, fit.step_tol)


def _f64(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


# ---------------------------------------------------------------------------
# Compiled kernels (numba). The solver's work is many tiny per-frame problems
# (a 20-body chain, a 52x52 normal system) on data-dependent subsets of
# frames: as vectorised numpy each step costs a few hundred array operations
# whose per-call overhead dwarfs the arithmetic, so the kernels loop over
# frames in compiled code instead. cache=True keeps the machine code on disk
# (compiled once per installation, for any clip length).
# ---------------------------------------------------------------------------

_jit = numba.njit(cache=True, nogil=True)


@_jit
def _rodrigues(ax, ay, az, angle, out):
    """out (3, 3) = rotation about the unit axis (ax, ay, az) by ``angle``:
    c I + s [a]x + (1 - c) a a^T."""
    c, s = np.cos(angle), np.sin(angle)
    v = 1.0 - c
    out[0, 0], out[0, 1], out[0, 2] = c + v * ax * ax, v * ax * ay - s * az, v * ax * az + s * ay
    out[1, 0], out[1, 1], out[1, 2] = v * ay * ax + s * az, c + v * ay * ay, v * ay * az - s * ax
    out[2, 0], out[2, 1], out[2, 2] = v * az * ax - s * ay, v * az * ay + s * ax, c + v * az * az


@_jit
def _forward_frame(rp, rr, th, arrays, Rb, xb, axes, anchors, pts):
    """FK of one frame into Rb (B, 3, 3), xb (B, 3), axes/anchors (H, 3), pts (P, 3).

    ``arrays`` = (parent, body_offset, body_rot, hinge_start, hinge_axis,
    hinge_pos, point_body, point_offset, anc_ptr, anc_idx, lower, upper).
    """
    parent, body_offset, body_rot, hinge_start, hinge_axis, hinge_pos = arrays[:6]
    point_body, point_offset = arrays[6], arrays[7]
    nbody = parent.shape[0]
    Hm = np.empty((3, 3))
    tmp = np.empty((3, 3))
    for i in range(3):
        xb[0, i] = 0.0
        for k in range(3):
            Rb[0, i, k] = 1.0 if i == k else 0.0
    for b in range(1, nbody):
        if b == 1:
            for i in range(3):
                xb[1, i] = rp[i]
                for k in range(3):
                    Rb[1, i, k] = rr[i, k]
        else:
            p = parent[b]
            for i in range(3):
                xb[b, i] = xb[p, i] + (Rb[p, i, 0] * body_offset[b, 0]
                                       + Rb[p, i, 1] * body_offset[b, 1]
                                       + Rb[p, i, 2] * body_offset[b, 2])
                for k in range(3):
                    Rb[b, i, k] = (Rb[p, i, 0] * body_rot[b, 0, k] + Rb[p, i, 1] * body_rot[b, 1, k]
                                   + Rb[p, i, 2] * body_rot[b, 2, k])
        for j in range(hinge_start[b], hinge_start[b + 1]):
            ax, ay, az = hinge_axis[j, 0], hinge_axis[j, 1], hinge_axis[j, 2]
            for i in range(3):
                anchors[j, i] = xb[b, i] + (Rb[b, i, 0] * hinge_pos[j, 0]
                                            + Rb[b, i, 1] * hinge_pos[j, 1]
                                            + Rb[b, i, 2] * hinge_pos[j, 2])
                axes[j, i] = Rb[b, i, 0] * ax + Rb[b, i, 1] * ay + Rb[b, i, 2] * az
            # R <- R H(a, theta).
            _rodrigues(ax, ay, az, th[j], Hm)
            for i in range(3):
                for k in range(3):
                    tmp[i, k] = (Rb[b, i, 0] * Hm[0, k] + Rb[b, i, 1] * Hm[1, k]
                                 + Rb[b, i, 2] * Hm[2, k])
            for i in range(3):
                for k in range(3):
                    Rb[b, i, k] = tmp[i, k]
    for q in range(point_body.shape[0]):
        b = point_body[q]
        for i in range(3):
            pts[q, i] = xb[b, i] + (Rb[b, i, 0] * point_offset[q, 0]
                                    + Rb[b, i, 1] * point_offset[q, 1]
                                    + Rb[b, i, 2] * point_offset[q, 2])


@_jit
def _forward_batch(root_pos, root_rot, theta, arrays, Rb, xb, axes, anchors, pts):
    for t in range(theta.shape[0]):
        _forward_frame(root_pos[t], root_rot[t], theta[t], arrays, Rb[t], xb[t], axes[t],
                       anchors[t], pts[t])


@_jit
def _points_batch(root_pos, root_rot, theta, arrays, pts):
    nbody, H = arrays[0].shape[0], arrays[4].shape[0]
    Rb, xb = np.empty((nbody, 3, 3)), np.empty((nbody, 3))
    axes, anchors = np.empty((H, 3)), np.empty((H, 3))
    for t in range(theta.shape[0]):
        _forward_frame(root_pos[t], root_rot[t], theta[t], arrays, Rb, xb, axes, anchors, pts[t])


@_jit
def _point_columns(q, rp, axes, anchors, pts, arrays, Jl):
    """Nonzero Jacobian columns of point q into Jl (3, 6 + its ancestor hinges):
    d/dx = I, d/dw_i = e_i x (p - x_root), d/dtheta_j = a_j x (p - c_j)."""
    anc_ptr, anc_idx = arrays[8], arrays[9]
    rx, ry, rz = pts[q, 0] - rp[0], pts[q, 1] - rp[1], pts[q, 2] - rp[2]
    for i in range(3):
        for k in range(6):
            Jl[i, k] = 0.0
        Jl[i, i] = 1.0
    Jl[1, 3], Jl[2, 3] = -rz, ry
    Jl[0, 4], Jl[2, 4] = rz, -rx
    Jl[0, 5], Jl[1, 5] = -ry, rx
    n = 6
    for m in range(anc_ptr[q], anc_ptr[q + 1]):
        j = anc_idx[m]
        lx, ly, lz = pts[q, 0] - anchors[j, 0], pts[q, 1] - anchors[j, 1], pts[q, 2] - anchors[j, 2]
        a0, a1, a2 = axes[j, 0], axes[j, 1], axes[j, 2]
        Jl[0, n] = a1 * lz - a2 * ly
        Jl[1, n] = a2 * lx - a0 * lz
        Jl[2, n] = a0 * ly - a1 * lx
        n += 1
    return n


@_jit
def _jacobian_batch(root_pos, axes, anchors, pts, arrays, J):
    anc_ptr, anc_idx = arrays[8], arrays[9]
    Jl = np.empty((3, J.shape[3]))
    for t in range(pts.shape[0]):
        for q in range(pts.shape[1]):
            n = _point_columns(q, root_pos[t], axes[t], anchors[t], pts[t], arrays, Jl)
            for c in range(n):
                col = c if c < 6 else 6 + anc_idx[anc_ptr[q] + c - 6]
                for i in range(3):
                    J[t, q, i, col] = Jl[i, c]


@_jit
def _frame_cost(pts, rp, th, x, w, K, use_floor, f, nbr_pos, nbr_th, reg, smooth, fw):
    c = 0.0
    for k in range(K):
        if w[k] != 0.0:
            c += w[k] * ((pts[k, 0] - x[k, 0]) ** 2 + (pts[k, 1] - x[k, 1]) ** 2
                         + (pts[k, 2] - x[k, 2]) ** 2)
    if use_floor:
        for q in range(K, pts.shape[0]):
            z = pts[q, 2] - f
            if z < 0.0:
                c += fw * z * z
    for j in range(th.shape[0]):
        c += reg * th[j] * th[j] + smooth * (th[j] - nbr_th[j]) ** 2
    for i in range(3):
        c += smooth * (rp[i] - nbr_pos[i]) ** 2
    return c


@_jit
def _moving_points(col_map, anc_ptr, anc_idx, P):
    """(P,) bool: the points some moving coordinate (``col_map >= 0``) moves;
    the others add nothing to the step."""
    moves = np.zeros(P, dtype=np.bool_)
    for q in range(P):
        for d in range(6):
            moves[q] = moves[q] or col_map[d] >= 0
        for m in range(anc_ptr[q], anc_ptr[q + 1]):
            moves[q] = moves[q] or col_map[6 + anc_idx[m]] >= 0
    return moves


@_jit
def _normal_equations(rp, x, f, pts, axes, anchors, arrays, moves, weights, K, use_floor, fw,
                      col_map, Jl, cols, A, g):
    """``A = J^T W J`` and ``g = J^T W r`` of one frame's keypoint and floor
    residuals over the reduced coordinates, into A (nd, nd) and g (nd,)
    (upper triangle accumulated, then mirrored)."""
    anc_ptr, anc_idx = arrays[8], arrays[9]
    nd = g.shape[0]
    A[:, :] = 0.0
    g[:] = 0.0
    for q in range(pts.shape[0]):
        if not moves[q]:
            continue
        floor_row = q >= K
        if floor_row:  # floor points: only the height row, only below the floor
            if not use_floor:
                break
            r2 = pts[q, 2] - f
            if r2 >= 0.0:
                continue
            wq, r0, r1 = fw, 0.0, 0.0
        else:
            wq = weights[q]
            if wq == 0.0:
                continue
            r0, r1, r2 = pts[q, 0] - x[q, 0], pts[q, 1] - x[q, 1], pts[q, 2] - x[q, 2]
        m = _point_columns(q, rp, axes, anchors, pts, arrays, Jl)
        for c in range(m):
            cols[c] = col_map[c] if c < 6 else col_map[6 + anc_idx[anc_ptr[q] + c - 6]]
        for a in range(m):
            ia = cols[a]
            if ia < 0:
                continue
            j0, j1, j2 = Jl[0, a], Jl[1, a], Jl[2, a]
            if floor_row:
                j0, j1 = 0.0, 0.0
            g[ia] += wq * (j0 * r0 + j1 * r1 + j2 * r2)
            for b in range(m):
                ib = cols[b]
                if ib >= ia:
                    A[ia, ib] += wq * (j0 * Jl[0, b] + j1 * Jl[1, b] + j2 * Jl[2, b])
    for a in range(nd):
        for b in range(a):
            A[a, b] = A[b, a]


@_jit
def _regularise(A, g, rp, th, nbr_pos, nbr_theta, mu, lower, upper, col_map, reg, smooth):
    """Add the smoothness and hinge regularisers and the Levenberg-Marquardt
    damping ``mu`` to A, g; then freeze (identity row, zero gradient) the
    hinges at a bound whose gradient pushes outwards (active set)."""
    nv, nd = col_map.shape[0], g.shape[0]
    for d in range(nv):
        i = col_map[d]
        if i < 0:
            continue
        if d < 3:
            A[i, i] += smooth
            g[i] += smooth * (rp[d] - nbr_pos[d])
        elif d >= 6:
            j = d - 6
            A[i, i] += reg + smooth
            g[i] += reg * th[j] + smooth * (th[j] - nbr_theta[j])
    for i in range(nd):
        A[i, i] += mu * (A[i, i] + 1e-6)
    for d in range(6, nv):
        i = col_map[d]
        if i < 0:
            continue
        j = d - 6
        if (th[j] <= lower[j] + 1e-9 and g[i] > 0) or (th[j] >= upper[j] - 1e-9 and g[i] < 0):
            for k in range(nd):
                A[i, k] = 0.0
                A[k, i] = 0.0
            A[i, i] = 1.0
            g[i] = 0.0


@_jit
def _cholesky_step(A, g):
    """In place: Cholesky ``A = L L^T`` (lower triangle of A), then g <- -A^-1 g.
    A matrix that is not positive definite gives NaN (the step is rejected)."""
    nd = g.shape[0]
    for j in range(nd):
        s = A[j, j]
        for k in range(j):
            s -= A[j, k] * A[j, k]
        if not s > 0.0:
            s = np.nan
        A[j, j] = np.sqrt(s)
        for i in range(j + 1, nd):
            s2 = A[i, j]
            for k in range(j):
                s2 -= A[i, k] * A[j, k]
            A[i, j] = s2 / A[j, j]
    for i in range(nd):
        s = -g[i]
        for k in range(i):
            s -= A[i, k] * g[k]
        g[i] = s / A[i, i]
    for i in range(nd - 1, -1, -1):
        s = g[i]
        for k in range(i + 1, nd):
            s -= A[k, i] * g[k]
        g[i] = s / A[i, i]


@_jit
def _limited_step(g, col_map, max_step, delta):
    """delta (nv,) <- the reduced step g on the full coordinates (0 where not
    moving), scaled so no rotation or hinge moves more than ``max_step``
    radians. Returns (all finite, largest entry after scaling)."""
    nv = col_map.shape[0]
    big = 0.0
    finite = True
    for d in range(nv):
        delta[d] = g[col_map[d]] if col_map[d] >= 0 else 0.0
        finite = finite and np.isfinite(delta[d])
        if d >= 3 and abs(delta[d]) > big:
            big = abs(delta[d])
    scale = min(1.0, max_step / max(big, 1e-12))
    largest = 0.0
    for d in range(nv):
        delta[d] *= scale
        largest = max(largest, abs(delta[d]))
    return finite, largest


@_jit
def _trial_pose(rp, rr, th, delta, lower, upper, rp2, rr2, th2, Rw):
    """Trial point rp2, rr2, th2 = x + dx, exp([dw]x) R, clip(theta + dtheta)."""
    for i in range(3):
        rp2[i] = rp[i] + delta[i]
    wx, wy, wz = delta[3], delta[4], delta[5]
    ang = np.sqrt(wx * wx + wy * wy + wz * wz)
    inv = 1.0 / max(ang, 1e-12)
    _rodrigues(wx * inv, wy * inv, wz * inv, ang, Rw)
    for i in range(3):
        for k in range(3):
            rr2[i, k] = Rw[i, 0] * rr[0, k] + Rw[i, 1] * rr[1, k] + Rw[i, 2] * rr[2, k]
    for j in range(th.shape[0]):
        th2[j] = min(max(th[j] + delta[6 + j], lower[j]), upper[j])


@_jit
def _fit_iteration(frames, root_pos, root_rot, theta, nbr_pos, nbr_theta, mu, active, targets,
                   weights, K, floor, use_floor, col_map, arrays, reg, smooth, fw, max_step,
                   tol, step_tol):
    """See :meth:`HingeTree.fit_iteration`."""
    parent, hinge_axis, point_body = arrays[0], arrays[4], arrays[6]
    lower, upper = arrays[10], arrays[11]
    nbody, H, P = parent.shape[0], hinge_axis.shape[0], point_body.shape[0]
    nv = 6 + H
    nd = 0
    for d in range(nv):
        if col_map[d] >= 0:
            nd += 1
    Rb, xb = np.empty((nbody, 3, 3)), np.empty((nbody, 3))
    axes, anchors, pts = np.empty((H, 3)), np.empty((H, 3)), np.empty((P, 3))
    pts2 = np.empty((P, 3))
    Jl = np.empty((3, nv))
    cols = np.empty(nv, dtype=np.int64)
    A = np.empty((nd, nd))
    g = np.empty(nd)
    delta = np.empty(nv)
    rp2, rr2, th2 = np.empty(3), np.empty((3, 3)), np.empty(H)
    Rw = np.empty((3, 3))
    moves = _moving_points(col_map, arrays[8], arrays[9], P)
    for n in range(frames.shape[0]):
        t = frames[n]
        rp, rr, th = root_pos[t], root_rot[t], theta[t]
        x, f = targets[t], floor[t]
        _forward_frame(rp, rr, th, arrays, Rb, xb, axes, anchors, pts)
        c0 = _frame_cost(pts, rp, th, x, weights, K, use_floor, f, nbr_pos[n], nbr_theta[n],
                         reg, smooth, fw)
        _normal_equations(rp, x, f, pts, axes, anchors, arrays, moves, weights, K, use_floor,
                          fw, col_map, Jl, cols, A, g)
        _regularise(A, g, rp, th, nbr_pos[n], nbr_theta[n], mu[t], lower, upper, col_map,
                    reg, smooth)
        _cholesky_step(A, g)
        finite, largest = _limited_step(g, col_map, max_step, delta)
        _trial_pose(rp, rr, th, delta, lower, upper, rp2, rr2, th2, Rw)
        _forward_frame(rp2, rr2, th2, arrays, Rb, xb, axes, anchors, pts2)
        c1 = _frame_cost(pts2, rp2, th2, x, weights, K, use_floor, f, nbr_pos[n], nbr_theta[n],
                         reg, smooth, fw)
        ok = finite and c1 < c0
        if ok:
            rp[:] = rp2
            rr[:, :] = rr2
            th[:] = th2
        mu[t] = min(max(mu[t] * (0.3 if ok else 8.0), 1e-7), 1e6)
        if (ok and (c0 - c1 < tol * c0 + 1e-10 or largest < step_tol)) or mu[t] >= 1e6:
            active[t] = False


@_jit
def _swing_batch(R, v0, u, out):
    """See :func:`swing`."""
    M = np.empty((3, 3))
    c = np.empty(3)
    for t in range(R.shape[0]):
        for i in range(3):
            c[i] = R[t, i, 0] * v0[0] + R[t, i, 1] * v0[1] + R[t, i, 2] * v0[2]
        nc = max(np.sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]), 1e-12)
        nu = max(np.sqrt(u[t, 0] * u[t, 0] + u[t, 1] * u[t, 1] + u[t, 2] * u[t, 2]), 1e-12)
        c0, c1, c2 = c[0] / nc, c[1] / nc, c[2] / nc
        u0, u1, u2 = u[t, 0] / nu, u[t, 1] / nu, u[t, 2] / nu
        a0, a1, a2 = c1 * u2 - c2 * u1, c2 * u0 - c0 * u2, c0 * u1 - c1 * u0
        s = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        ang = np.arctan2(s, c0 * u0 + c1 * u1 + c2 * u2)
        if s > 1e-9:
            _rodrigues(a0 / s, a1 / s, a2 / s, ang, M)
        else:  # parallel (no turn) or antiparallel (half turn about x)
            _rodrigues(1.0, 0.0, 0.0, ang, M)
        for i in range(3):
            for k in range(3):
                out[t, i, k] = M[i, 0] * R[t, 0, k] + M[i, 1] * R[t, 1, k] + M[i, 2] * R[t, 2, k]


@_jit
def _two_vector_batch(F0T, u, wt, out):
    """See :func:`two_vector`; F0T = F(v0, w0)^T."""
    F = np.empty((3, 3))
    for t in range(u.shape[0]):
        n1 = max(np.sqrt(u[t, 0] ** 2 + u[t, 1] ** 2 + u[t, 2] ** 2), 1e-12)
        e0, e1, e2 = u[t, 0] / n1, u[t, 1] / n1, u[t, 2] / n1
        d = wt[t, 0] * e0 + wt[t, 1] * e1 + wt[t, 2] * e2
        f0, f1, f2 = wt[t, 0] - d * e0, wt[t, 1] - d * e1, wt[t, 2] - d * e2
        n2 = max(np.sqrt(f0 * f0 + f1 * f1 + f2 * f2), 1e-12)
        f0, f1, f2 = f0 / n2, f1 / n2, f2 / n2
        F[0, 0], F[1, 0], F[2, 0] = e0, e1, e2
        F[0, 1], F[1, 1], F[2, 1] = f0, f1, f2
        F[0, 2], F[1, 2], F[2, 2] = e1 * f2 - e2 * f1, e2 * f0 - e0 * f2, e0 * f1 - e1 * f0
        for i in range(3):
            for k in range(3):
                out[t, i, k] = F[i, 0] * F0T[0, k] + F[i, 1] * F0T[1, k] + F[i, 2] * F0T[2, k]


@_jit
def _compose_batch(R, axes, angles):
    """See :func:`compose_hinges` (R updated in place)."""
    M = np.empty((3, 3))
    tmp = np.empty((3, 3))
    for t in range(R.shape[0]):
        for j in range(axes.shape[0]):
            _rodrigues(axes[j, 0], axes[j, 1], axes[j, 2], angles[t, j], M)
            for i in range(3):
                for k in range(3):
                    tmp[i, k] = R[t, i, 0] * M[0, k] + R[t, i, 1] * M[1, k] + R[t, i, 2] * M[2, k]
            R[t] = tmp


@_jit
def _euler_batch(R, order, eps, signs, lower, upper, centre, sols, viol, dropped):
    """See :func:`euler_branches`."""
    i, j, k = order[0], order[1], order[2]
    n = signs.shape[0]
    ang = np.empty(3)
    for t in range(R.shape[0]):
        mid = np.arcsin(min(max(eps * R[t, i, k], -1.0), 1.0))
        first = np.arctan2(-eps * R[t, j, k], R[t, k, k])
        last = np.arctan2(-eps * R[t, i, j], R[t, i, i])
        for br in range(2):
            if br == 0:
                ang[0], ang[1], ang[2] = first, mid, last
            else:
                ang[0], ang[1], ang[2] = first + np.pi, np.pi - mid, last + np.pi
            v = 0.0
            for m in range(n):
                x = ang[m] * signs[m]
                x = centre[m] + (x - centre[m] + np.pi) % (2 * np.pi) - np.pi
                v += max(lower[m] - x, 0.0) + max(x - upper[m], 0.0)
                sols[t, br, m] = min(max(x, lower[m]), upper[m])
            d = 0.0
            for m in range(n, 3):
                d += abs((ang[m] + np.pi) % (2 * np.pi) - np.pi)
            viol[t, br] = v
            dropped[t, br] = d


@_jit
def viterbi2(unary, trans):
    """Cheapest path through two states per frame.

    Args:
        unary: (T, 2) cost of each state. trans: (T - 1, 2, 2) cost of moving
            from state ``prev`` at t to state ``cur`` at t + 1, as [t, cur, prev].
    Returns:
        (T,) int64 states minimising sum unary + sum trans (ties: the lower state).
    """
    T = unary.shape[0]
    back = np.zeros((T, 2), dtype=np.int64)
    acc0, acc1 = unary[0, 0], unary[0, 1]
    for t in range(1, T):
        a0, a1 = acc0 + trans[t - 1, 0, 0], acc1 + trans[t - 1, 0, 1]
        b0, b1 = acc0 + trans[t - 1, 1, 0], acc1 + trans[t - 1, 1, 1]
        back[t, 0] = 0 if a0 <= a1 else 1
        back[t, 1] = 0 if b0 <= b1 else 1
        acc0, acc1 = min(a0, a1) + unary[t, 0], min(b0, b1) + unary[t, 1]
    pick = np.empty(T, dtype=np.int64)
    pick[T - 1] = 0 if acc0 <= acc1 else 1
    for t in range(T - 1, 0, -1):
        pick[t - 1] = back[t, pick[t]]
    return pick

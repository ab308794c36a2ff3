"""Tests of simenv.body.ik's compiled kinematics on a humanoid, against MuJoCo."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from simenv.body.humanoid import Humanoid
from simenv.body.ik import (
    HingeTree,
    compose_hinges,
    euler_branches,
    quat_to_mat,
    swing,
    two_vector,
    viterbi2,
)


@pytest.fixture(scope="module")
def body() -> tuple[Humanoid, HingeTree, np.ndarray]:
    h = Humanoid()
    m = h.model
    tree = HingeTree(m, m.site_bodyid[h.site_ids], m.site_pos[h.site_ids])
    rng = np.random.default_rng(0)
    q = np.tile(h.default_qpos(), (5, 1))
    q[:, :3] = rng.normal(0, 0.5, (5, 3))
    quat = rng.normal(size=(5, 4))
    q[:, 3:7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    lo, hi = h.joint_limits.T
    q[:, h.hinge_qpos] = rng.uniform(lo, hi, (5, len(lo)))
    return h, tree, q


def test_points_match_mujoco_sites(body) -> None:
    h, tree, q = body
    pts = tree.points(*tree.split_qpos(q))
    np.testing.assert_allclose(pts, h.keypoints(q), atol=1e-12)
    np.testing.assert_allclose(tree.forward(*tree.split_qpos(q)).points, pts, atol=0)


def test_jacobian_matches_mujoco(body) -> None:
    h, tree, q = body
    m, d = h.model, mujoco.MjData(h.model)
    state = tree.split_qpos(q)
    J = tree.jacobian(tree.forward(*state), state[0])
    jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    dof_hinge = m.jnt_dofadr[[m.joint(n).id for n in h.joint_names]]
    for t in range(len(q)):
        d.qpos[:] = q[t]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        for p, s in enumerate(h.site_ids):
            mujoco.mj_jacSite(m, d, jp, jr, s)
            np.testing.assert_allclose(J[t, p][:, 6:], jp[:, dof_hinge], atol=1e-10)
            np.testing.assert_allclose(J[t, p][:, :3], jp[:, :3], atol=1e-10)
            # MuJoCo's free-joint angular velocity is in the body frame, ours in the world.
            R = d.xmat[1].reshape(3, 3)
            np.testing.assert_allclose(J[t, p][:, 3:6] @ R, jp[:, 3:6], atol=1e-10)


def test_rotation_kernels() -> None:
    rng = np.random.default_rng(1)
    q = rng.normal(size=(50, 4))
    R = quat_to_mat(q)
    v0, u = np.array([0.0, 0.0, -1.0]), rng.normal(size=(50, 3))
    S = swing(R, v0, u)
    np.testing.assert_allclose(S @ v0, u / np.linalg.norm(u, axis=1, keepdims=True), atol=1e-12)
    w0, wt = np.array([1.0, 0.0, 0.0]), rng.normal(size=(50, 3))
    V = two_vector(v0, w0, u, wt)
    np.testing.assert_allclose(V @ v0, u / np.linalg.norm(u, axis=1, keepdims=True), atol=1e-12)
    np.testing.assert_allclose(V @ np.swapaxes(V, 1, 2), np.broadcast_to(np.eye(3), V.shape),
                               atol=1e-12)
    # Euler round trip: compose R_z(a) R_x(b) R_y(c) and decompose it.
    axes = np.eye(3)[[2, 0, 1]]
    ang = rng.uniform(-1.2, 1.2, (50, 3))
    C = compose_hinges(np.broadcast_to(np.eye(3), (50, 3, 3)), axes, ang)
    big = np.full(3, 10.0)
    sols, viol, dropped = euler_branches(C, (2, 0, 1), np.ones(3), -big, big)
    again = compose_hinges(np.broadcast_to(np.eye(3), (50, 3, 3)), axes, sols[:, 0])
    np.testing.assert_allclose(again, C, atol=1e-12)
    assert (viol == 0).all() and (dropped == 0).all()


def test_viterbi_prefers_the_cheap_path() -> None:
    unary = np.array([[0.0, 1.0], [5.0, 0.0], [0.0, 1.0]])
    stay = np.array([[0.0, 3.0], [3.0, 0.0]])  # [cur, prev]: switching costs 3
    np.testing.assert_array_equal(viterbi2(unary, np.stack([stay, stay])), [1, 1, 1])
    np.testing.assert_array_equal(viterbi2(unary, np.stack([stay, stay]) * 0), [0, 1, 0])

"""Where the body's collision geoms are over a qpos trajectory.

The geoms (capsules and boxes that stand for the skin) of a MuJoCo model
posed frame by frame (:func:`body_poses`: ``mj_kinematics`` per frame, then
every geometric quantity vectorised over frames): their lowest points, the
points that can touch the floor, and the deepest geom-geom penetration.
World Z-up, floor = plane z = 0, metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from simenv.core.errors import PhysicsError

_SPHERE, _CAPSULE = int(mujoco.mjtGeom.mjGEOM_SPHERE), int(mujoco.mjtGeom.mjGEOM_CAPSULE)
_ELLIPSOID, _CYLINDER = int(mujoco.mjtGeom.mjGEOM_ELLIPSOID), int(mujoco.mjtGeom.mjGEOM_CYLINDER)
_BOX = int(mujoco.mjtGeom.mjGEOM_BOX)

#: (8, 3) signs of a box's corners in its local frame: corner ``i`` of a box
#: of half-sizes ``s`` is at ``BOX_CORNERS[i] * s``.
BOX_CORNERS: np.ndarray = np.array(
    [[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
BOX_CORNERS.flags.writeable = False


@dataclass(frozen=True)
class BodyPoses:
    """World poses of every geom, body and site over a qpos trajectory.

    Attributes:
        geom_xpos: (T, G, 3) geom centres, metres.
        geom_xmat: (T, G, 3, 3) geom orientations (columns = local axes).
        site_xpos: (T, S, 3) site positions, metres.
        xipos: (T, B, 3) body centres of mass, metres.
        com: (T, 3) whole-model centre of mass, metres.
    """

    geom_xpos: np.ndarray
    geom_xmat: np.ndarray
    site_xpos: np.ndarray
    xipos: np.ndarray
    com: np.ndarray


def check_qpos(model: mujoco.MjModel, qpos: np.ndarray, what: str = "qpos") -> np.ndarray:
    """``qpos`` as a (T, nq) float64 array, or :class:`PhysicsError` naming the
    first bad frame (NaN/inf) or the expected shape."""
    q = np.asarray(qpos, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != model.nq or q.shape[0] == 0:
        raise PhysicsError(f"{what} has shape {q.shape}; expected (T >= 1, {model.nq})",
                           field=what)
    bad = ~np.isfinite(q).all(axis=1)
    if bad.any():
        raise PhysicsError(f"{what} contains NaN/inf; refusing to pass it to MuJoCo",
                           frame=int(np.flatnonzero(bad)[0]), field=what)
    return q


def body_poses(model: mujoco.MjModel, qpos: np.ndarray) -> BodyPoses:
    """Forward kinematics (``mj_kinematics``) of every frame of ``qpos`` (T, nq)."""
    q = check_qpos(model, qpos)
    data = mujoco.MjData(model)
    T = len(q)
    gx = np.empty((T, model.ngeom, 3))
    gm = np.empty((T, model.ngeom, 9))
    sx = np.empty((T, model.nsite, 3))
    xi = np.empty((T, model.nbody, 3))
    for t in range(T):
        data.qpos[:] = q[t]
        mujoco.mj_kinematics(model, data)
        gx[t], gm[t], sx[t], xi[t] = data.geom_xpos, data.geom_xmat, data.site_xpos, data.xipos
    mass = model.body_mass
    com = (xi * mass[None, :, None]).sum(axis=1) / mass.sum()
    return BodyPoses(gx, gm.reshape(T, model.ngeom, 3, 3), sx, xi, com)


def body_geoms(model: mujoco.MjModel) -> np.ndarray:
    """Ids of the geoms attached to a moving body (not the world: floor, props)."""
    return np.flatnonzero(model.geom_bodyid > 0)


def body_boxes(model: mujoco.MjModel) -> np.ndarray:
    """Ids of the box geoms attached to a moving body (the soles, toes and hands)."""
    return np.flatnonzero((model.geom_type == _BOX) & (model.geom_bodyid > 0))


def geom_lowest_z(model: mujoco.MjModel, poses: BodyPoses, geoms: np.ndarray) -> np.ndarray:
    """Exact height of the lowest point of each geom, (T, len(geoms)) metres.

    With ``R`` the geom's orientation, ``u_i = R[2, i]`` the vertical component
    of its local axis i and ``s`` its MuJoCo size: sphere ``z - s0``; capsule
    ``z - |u_2| s1 - s0``; cylinder ``z - |u_2| s1 - s0 sqrt(1 - u_2^2)``; box
    ``z - sum_i |u_i| s_i``; ellipsoid ``z - sqrt(sum_i (u_i s_i)^2)``; other
    types (meshes) ``z - rbound`` (bounding sphere, conservative).
    """
    z = poses.geom_xpos[:, geoms, 2]
    u = poses.geom_xmat[:, geoms, 2, :]  # (T, G, 3): z components of the local axes
    size = model.geom_size[geoms]
    kind = model.geom_type[geoms]
    drop = np.broadcast_to(model.geom_rbound[geoms], z.shape).copy()
    a2 = np.abs(u[..., 2])
    drop[:, kind == _SPHERE] = size[kind == _SPHERE, 0]
    for k, expr in (
        (_CAPSULE, lambda s: a2 * s[:, 1] + s[:, 0]),
        (_CYLINDER, lambda s: a2 * s[:, 1] + s[:, 0] * np.sqrt(np.maximum(1 - a2**2, 0))),
        (_BOX, lambda s: (np.abs(u) * s[None]).sum(axis=-1)),
        (_ELLIPSOID, lambda s: np.sqrt(((u * s[None]) ** 2).sum(axis=-1))),
    ):
        sel = kind == k
        if sel.any():
            drop[:, sel] = expr(size)[:, sel]
    return z - drop


def lowest_box_z(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Height of the lowest point of the body's box geoms (:func:`body_boxes`)
    on each frame of ``qpos`` (T, nq): (T,) metres."""
    return geom_lowest_z(model, body_poses(model, qpos), body_boxes(model)).min(axis=1)


def geom_support_points(model: mujoco.MjModel, poses: BodyPoses,
                        geoms: np.ndarray) -> np.ndarray:
    """Points of the geoms that can touch the floor, (T, P, 3) metres.

    Boxes (the feet) give their 8 corners (:data:`BOX_CORNERS` order), so a
    flat sole yields a support polygon; every other geom gives its lowest
    point (a capsule's lowest end-cap point, a sphere's bottom).
    """
    T = poses.geom_xpos.shape[0]
    pts = []
    low = geom_lowest_z(model, poses, geoms)
    for i, g in enumerate(geoms):
        c, R, s = poses.geom_xpos[:, g], poses.geom_xmat[:, g], model.geom_size[g]
        if model.geom_type[g] == _BOX:
            pts.append(c[:, None] + np.einsum("tij,pj->tpi", R, BOX_CORNERS * s))
        elif model.geom_type[g] == _CAPSULE:
            axis = R[:, :, 2]
            end = c - np.sign(axis[:, 2:3]) * axis * s[1]
            pts.append(np.concatenate([end[:, :2], low[:, i:i + 1]], axis=1)[:, None])
        else:
            pts.append(np.concatenate([c[:, :2], low[:, i:i + 1]], axis=1)[:, None])
    return np.concatenate(pts, axis=1) if pts else np.zeros((T, 0, 3))


def support_point_bodies(model: mujoco.MjModel, geoms: np.ndarray) -> np.ndarray:
    """Body id of every point :func:`geom_support_points` returns for ``geoms``,
    in its order (boxes give 8 corners, other geoms one point), (P,) int."""
    out = []
    for g in geoms:
        n = len(BOX_CORNERS) if model.geom_type[g] == _BOX else 1
        out.extend([int(model.geom_bodyid[g])] * n)
    return np.array(out, dtype=int)


def contact_depths(model: mujoco.MjModel, qpos: np.ndarray,
                   keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Deepest geom-geom penetration per frame among the selected geom pairs.

    Runs ``mj_kinematics`` and ``mj_collision`` on every frame; MuJoCo's own
    filters apply (contype/conaffinity, parent-child pairs, the model's
    ``<exclude>`` pairs).

    Args:
        model: the model.
        qpos: (T, nq).
        keep: (ngeom, ngeom) bool, which geom pairs count.

    Returns:
        depth (T,) metres (0 without contact) and pair (T, 2) int geom ids of
        the deepest counted contact (-1 without contact).
    """
    q = check_qpos(model, qpos)
    data = mujoco.MjData(model)
    depth = np.zeros(len(q))
    pair = np.full((len(q), 2), -1)
    for t in range(len(q)):
        data.qpos[:] = q[t]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        n = data.ncon
        if n == 0:
            continue
        g = data.contact.geom[:n]
        ok = keep[g[:, 0], g[:, 1]]
        if not ok.any():
            continue
        d = -data.contact.dist[:n]
        d[~ok] = -np.inf
        i = int(np.argmax(d))
        if d[i] > 0:
            depth[t], pair[t] = d[i], g[i]
    return depth, pair

"""glTF 2.0 / GLB export of MuJoCo scenes and their motion, for any 3D viewer.

Geometry comes from the model's geoms (spheres, capsules, cylinders, ellipsoids, boxes,
meshes; a plane becomes a thin square slab): one glTF node per MuJoCo body, one child node
per visible geom (geom groups 0-2, alpha > 0, so hidden collision hulls and sites are left
out) carrying its shape as a triangle mesh in the body's frame with the geom's colour as a
PBR material. :mod:`trimesh` builds and writes the static scene; the motion is then added to
its glTF JSON and binary buffer here, since trimesh writes no animation: one shared time
accessor (seconds, ``min``/``max`` as the spec requires) and per moving body a
``translation`` (VEC3) and a ``rotation`` (VEC4, x y z w) channel, linear interpolation.

Frames: MuJoCo is Z-up, glTF Y-up. Every body node hangs under one root node ``world``
whose rotation (-90 degrees about x) turns Z-up into Y-up, so body translations and
rotations are written in MuJoCo's world frame (metres) unchanged. Body nodes are flat
children of ``world`` (their world poses, not MuJoCo's parent-relative ones), which is what
:func:`body_poses` measures.

API
    ``body_poses(model, qpos, data=None, before=None) -> (xpos, xquat)``
        (T, nbody, 3) positions, m, and (T, nbody, 4) quaternions (w x y z) of every body
        for a qpos trajectory (T, nq).
    ``write_gltf(model, path, *, data=None, poses=None, fps=None, name=None) -> Path``
        Writes ``.glb`` (binary) or ``.gltf`` (JSON with the buffer embedded).
    ``check_gltf(path) -> dict``
        Re-reads a written file: structure checks (accessor counts, bounds, time order,
        unit quaternions, node transforms of animated nodes) and a re-load with trimesh.
"""

from __future__ import annotations

import base64
import json
import os
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import trimesh
from trimesh.creation import box, capsule, cylinder, icosphere

from simenv.core.errors import SimenvError

#: Geom groups exported (MuJoCo's renderer shows 0-2 by default; 3+ hold hidden collision
#: geometry such as the convex parts of a furniture mesh).
VISIBLE_GROUPS = (0, 1, 2)
#: Half-size (m) of the slab standing in for an infinite plane (MuJoCo size 0), at least;
#: it grows to cover the bodies' floor extent plus this margin.
PLANE_HALF = 3.0
#: Thickness (m) of a plane's slab (its top face is the plane).
PLANE_THICKNESS = 0.01
#: A body is animated when its position moves more than this (m) or its rotation more than
#: this (quaternion component) over the frames; others get one fixed transform.
STATIC_TOL = 1e-6
#: Node rotation (x y z w) turning MuJoCo's Z-up world into glTF's Y-up: -90 deg about x.
Z_UP_TO_Y_UP = (-np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5))
#: Sphere tessellation (icosphere subdivisions) and round-shape sections.
_SUBDIVISIONS = 2
_SECTIONS = 24

_GLB_MAGIC, _JSON_CHUNK, _BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942
_FLOAT, _VEC = 5126, {1: "SCALAR", 3: "VEC3", 4: "VEC4"}


def body_poses(model: mujoco.MjModel, qpos: np.ndarray, data: mujoco.MjData | None = None,
               before: Callable[[mujoco.MjData, int], None] | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """World poses of every body along a qpos trajectory (forward kinematics only).

    Args:
        model: the model.
        qpos: (T, nq) configurations.
        data: state to start from (mocap bodies, other joints); default ``MjData(model)``
            (copied, not changed).
        before: called as ``before(data, t)`` after frame ``t``'s qpos is set and before
            the kinematics, e.g. to move mocap bodies.

    Returns:
        ``xpos`` (T, nbody, 3), m, and ``xquat`` (T, nbody, 4), w x y z.
    """
    q = np.asarray(qpos, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != model.nq or len(q) == 0:
        raise SimenvError(f"qpos must be (T >= 1, {model.nq}); got {q.shape}", field="qpos")
    d = mujoco.MjData(model)
    if data is not None:
        d.qpos[:], d.mocap_pos[:], d.mocap_quat[:] = data.qpos, data.mocap_pos, data.mocap_quat
    xpos = np.empty((len(q), model.nbody, 3))
    xquat = np.empty((len(q), model.nbody, 4))
    for t, row in enumerate(q):
        d.qpos[:] = row
        if before is not None:
            before(d, t)
        mujoco.mj_kinematics(model, d)
        xpos[t], xquat[t] = d.xpos, d.xquat
    return xpos, xquat


def write_gltf(model: mujoco.MjModel, path: str | os.PathLike[str], *,
               data: mujoco.MjData | None = None,
               poses: tuple[np.ndarray, np.ndarray] | None = None,
               fps: float | None = None, name: str | None = None) -> Path:
    """Write the model's visible geometry, and its motion when given, as glTF.

    Args:
        model: the MuJoCo model.
        path: output file, ``.glb`` or ``.gltf`` (folder created).
        data: the static state to draw when ``poses`` is None (default: ``qpos0``); its
            kinematics are computed here.
        poses: ``(xpos (T, nbody, 3), xquat (T, nbody, 4))`` from :func:`body_poses`;
            frame 0 is also the nodes' rest transform. T > 1 adds an animation.
        fps: frame rate of ``poses``, frames per second (needed when T > 1).
        name: the animation's name (default: the file's stem).

    Returns:
        The path written.

    Raises:
        SimenvError: bad suffix, shapes or fps, or a model with no visible geometry.
    """
    path = Path(path)
    if path.suffix.lower() not in (".glb", ".gltf"):
        raise SimenvError(f"glTF output must end with .glb or .gltf; got {path.name!r}",
                          field="path")
    if poses is None:
        d = mujoco.MjData(model) if data is None else data
        mujoco.mj_kinematics(model, d)
        poses = (d.xpos[None].copy(), d.xquat[None].copy())
    xpos, xquat = (np.asarray(p, dtype=np.float64) for p in poses)
    if xpos.shape[1:] != (model.nbody, 3) or xquat.shape != (*xpos.shape[:2], 4):
        raise SimenvError(f"poses must be (T, {model.nbody}, 3) and (T, {model.nbody}, 4); "
                          f"got {xpos.shape} and {xquat.shape}", field="poses")
    frames = len(xpos)
    if frames > 1 and not (fps is not None and np.isfinite(fps) and fps > 0):
        raise SimenvError(f"an animation needs fps > 0; got {fps!r}", field="fps")
    xquat = _continuous(xquat / np.linalg.norm(xquat, axis=-1, keepdims=True))
    scene, body_nodes = _scene(model, xpos, xquat)
    glb = scene.export(file_type="glb", include_normals=True)
    doc, blob = _split_glb(glb)
    moving = [b for b in body_nodes if frames > 1 and (
        np.ptp(xpos[:, b], axis=0).max() > STATIC_TOL
        or np.ptp(xquat[:, b], axis=0).max() > STATIC_TOL)]
    _use_trs(doc, body_nodes, xpos[0], xquat[0])
    _set_targets(doc)
    if moving:
        blob = _add_animation(doc, blob, {body_nodes[b]: (xpos[:, b], xquat[:, b])
                                          for b in moving},
                              np.arange(frames) / float(fps), name or path.stem)
    doc.setdefault("asset", {})["generator"] = "simenv (trimesh + animation)"
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".glb":
        path.write_bytes(_join_glb(doc, blob))
    else:
        doc["buffers"] = [{"byteLength": len(blob), "uri": "data:application/octet-stream;"
                           "base64," + base64.b64encode(blob).decode()}]
        path.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return path


def _scene(model: mujoco.MjModel, xpos: np.ndarray, xquat: np.ndarray
           ) -> tuple[Any, dict[int, str]]:
    """The trimesh scene of the model's visible geoms (a Y-up root over the Z-up world, one
    node per body with visible geoms at its frame-0 pose, one child node per geom) and body
    index -> node name.

    Raises:
        SimenvError: no visible geometry.
    """
    scene = trimesh.Scene(base_frame="scene")
    scene.graph.update(frame_from="scene", frame_to="world",
                       matrix=trimesh.transformations.quaternion_matrix(
                           _wxyz(np.array(Z_UP_TO_Y_UP))))
    plane_half = max(PLANE_HALF, float(np.abs(xpos[..., :2]).max()) + 1.0)
    body_nodes: dict[int, str] = {}
    for b in range(model.nbody):
        geoms = [g for g in range(model.body_geomadr[b],
                                  model.body_geomadr[b] + model.body_geomnum[b])
                 if _visible(model, g)]
        if not geoms:
            continue
        node = _unique(f"body:{model.body(b).name or b}", body_nodes.values())
        body_nodes[b] = node
        scene.graph.update(frame_from="world", frame_to=node,
                           matrix=_matrix(xpos[0, b], xquat[0, b]))
        for g in geoms:
            mesh = _geom_mesh(model, g, plane_half)
            if mesh is None:
                continue
            gname = _unique(f"geom:{model.geom(g).name or g}", scene.graph.nodes)
            scene.add_geometry(mesh, node_name=gname, geom_name=gname, parent_node_name=node,
                               transform=_matrix(model.geom_pos[g], model.geom_quat[g]))
    if not scene.geometry:
        raise SimenvError("the model has no visible geometry to export", field="model")
    return scene, body_nodes


def check_gltf(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Re-read a glTF/GLB written by :func:`write_gltf` and check it.

    Checks: every accessor's count and type fit its buffer view and the buffer; every
    accessor has ``min``/``max`` equal to its data's; animation times strictly increase;
    sampler input and output counts match; rotations are unit quaternions; animated nodes
    have no ``matrix``; the file re-loads with :func:`trimesh.load` with every mesh.

    Returns:
        ``{"nodes", "meshes", "animations", "channels", "frames", "duration_s",
        "vertices"}`` (counts; ``frames``/``duration_s`` of the first animation, 0 without).

    Raises:
        SimenvError: naming the first check that fails.
    """
    path = Path(path)
    raw = path.read_bytes()
    if path.suffix.lower() == ".glb":
        doc, blob = _split_glb(raw)
    else:
        doc = json.loads(raw)
        uri = doc["buffers"][0]["uri"]
        blob = base64.b64decode(uri.split(",", 1)[1])

    def fail(message: str) -> None:
        raise SimenvError(message, source=path)

    if len(blob) < doc["buffers"][0]["byteLength"]:
        fail(f"buffer holds {len(blob)} bytes, declares {doc['buffers'][0]['byteLength']}")
    arrays = []
    for i, acc in enumerate(doc["accessors"]):
        view = doc["bufferViews"][acc["bufferView"]]
        width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc["type"]]
        dtype = {5126: np.float32, 5125: np.uint32, 5123: np.uint16, 5121: np.uint8}[
            acc["componentType"]]
        start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        size = acc["count"] * width * np.dtype(dtype).itemsize
        if start + size > view.get("byteOffset", 0) + view["byteLength"] or \
                start + size > len(blob):
            fail(f"accessor {i}: {acc['count']} x {acc['type']} overruns its buffer view")
        values = np.frombuffer(blob, dtype, acc["count"] * width, start).reshape(-1, width)
        if "min" in acc and (not np.allclose(values.min(0), acc["min"], atol=1e-6)
                             or not np.allclose(values.max(0), acc["max"], atol=1e-6)):
            fail(f"accessor {i}: min/max {acc['min']}/{acc['max']} differ from its data")
        arrays.append(values)
    channels = frames = 0
    duration = 0.0
    for a, anim in enumerate(doc.get("animations", [])):
        for s, sampler in enumerate(anim["samplers"]):
            t, out = arrays[sampler["input"]][:, 0], arrays[sampler["output"]]
            if "min" not in doc["accessors"][sampler["input"]]:
                fail(f"animation {a} sampler {s}: its time accessor has no min/max")
            if len(t) != len(out) or np.any(np.diff(t) <= 0):
                fail(f"animation {a} sampler {s}: {len(t)} times (increasing?) for "
                     f"{len(out)} values")
            if out.shape[1] == 4 and not np.allclose(np.linalg.norm(out, axis=1), 1, atol=1e-4):
                fail(f"animation {a} sampler {s}: rotations are not unit quaternions")
        for ch in anim["channels"]:
            if "matrix" in doc["nodes"][ch["target"]["node"]]:
                fail(f"animation {a}: animated node {ch['target']['node']} has a matrix")
        channels += len(anim["channels"])
        if a == 0:
            t = arrays[anim["samplers"][0]["input"]][:, 0]
            frames, duration = len(t), float(t[-1] - t[0])
    loaded = trimesh.load(path, force="scene")
    if len(loaded.geometry) != len(doc["meshes"]):
        fail(f"trimesh re-loads {len(loaded.geometry)} meshes of {len(doc['meshes'])}")
    return {"nodes": len(doc["nodes"]), "meshes": len(doc["meshes"]),
            "animations": len(doc.get("animations", [])), "channels": channels,
            "frames": frames, "duration_s": duration,
            "vertices": int(sum(len(g.vertices) for g in loaded.geometry.values()))}


# -- geometry ---------------------------------------------------------------------------


def _visible(model: mujoco.MjModel, g: int) -> bool:
    return int(model.geom_group[g]) in VISIBLE_GROUPS and _rgba(model, g)[3] > 0


def _rgba(model: mujoco.MjModel, g: int) -> np.ndarray:
    mat = int(model.geom_matid[g])
    return np.asarray(model.mat_rgba[mat] if mat >= 0 else model.geom_rgba[g], dtype=float)


def _geom_mesh(model: mujoco.MjModel, g: int, plane_half: float) -> Any:
    """The geom's surface as a trimesh in the geom's own frame, coloured; None for types
    without a surface (height fields, SDFs are not exported)."""
    kind, size = int(model.geom_type[g]), model.geom_size[g]
    G = mujoco.mjtGeom
    if kind == G.mjGEOM_SPHERE:
        mesh = icosphere(subdivisions=_SUBDIVISIONS, radius=size[0])
    elif kind == G.mjGEOM_ELLIPSOID:
        mesh = icosphere(subdivisions=_SUBDIVISIONS)
        mesh.apply_scale(size[:3])
    elif kind == G.mjGEOM_CAPSULE:
        mesh = capsule(height=2 * size[1], radius=size[0], count=[_SECTIONS, _SECTIONS // 2])
    elif kind == G.mjGEOM_CYLINDER:
        mesh = cylinder(radius=size[0], height=2 * size[1], sections=_SECTIONS)
    elif kind == G.mjGEOM_BOX:
        mesh = box(extents=2 * size[:3])
    elif kind == G.mjGEOM_PLANE:
        hx, hy = (s if s > 0 else plane_half for s in size[:2])
        mesh = box(extents=(2 * hx, 2 * hy, PLANE_THICKNESS))
        mesh.apply_translation((0.0, 0.0, -PLANE_THICKNESS / 2))
    elif kind == G.mjGEOM_MESH:
        m = int(model.geom_dataid[g])
        v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
        f0, nf = model.mesh_faceadr[m], model.mesh_facenum[m]
        mesh = trimesh.Trimesh(model.mesh_vert[v0:v0 + nv].copy(),
                               model.mesh_face[f0:f0 + nf].copy(), process=False)
    else:
        return None
    rgba = _rgba(model, g)
    mesh.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
        baseColorFactor=[float(c) for c in rgba], metallicFactor=0.0, roughnessFactor=0.8,
        alphaMode="BLEND" if rgba[3] < 1 else None))
    return mesh


def _unique(name: str, taken: Any) -> str:
    taken = set(taken)
    out, k = name, 1
    while out in taken:
        out, k = f"{name}#{k}", k + 1
    return out


def _wxyz(xyzw: np.ndarray) -> np.ndarray:
    return np.asarray(xyzw)[..., [3, 0, 1, 2]]


def _xyzw(wxyz: np.ndarray) -> np.ndarray:
    return np.asarray(wxyz)[..., [1, 2, 3, 0]]


def _matrix(pos: np.ndarray, quat_wxyz: np.ndarray) -> np.ndarray:
    m = trimesh.transformations.quaternion_matrix(np.asarray(quat_wxyz, dtype=float))
    m[:3, 3] = pos
    return m


def _continuous(quat: np.ndarray) -> np.ndarray:
    """(T, B, 4) quaternions with signs flipped so that consecutive frames lie in the same
    hemisphere: linear interpolation between q and -q (the same rotation) would swing the
    long way round."""
    q = quat.copy()
    for t in range(1, len(q)):
        flip = np.sum(q[t] * q[t - 1], axis=-1) < 0
        q[t, flip] *= -1
    return q


# -- GLB container and the animation ----------------------------------------------------


def _split_glb(glb: bytes) -> tuple[dict[str, Any], bytearray]:
    magic, version, total = struct.unpack_from("<III", glb, 0)
    if magic != _GLB_MAGIC or version != 2 or total != len(glb):
        raise SimenvError(f"not a glTF 2 binary file (magic {magic:#x}, version {version}, "
                          f"length {total} of {len(glb)} bytes)")
    jlen, jtype = struct.unpack_from("<II", glb, 12)
    doc = json.loads(glb[20:20 + jlen])
    blob = bytearray()
    if 20 + jlen < total:
        blen, btype = struct.unpack_from("<II", glb, 20 + jlen)
        if jtype != _JSON_CHUNK or btype != _BIN_CHUNK:
            raise SimenvError("GLB chunks are not JSON then BIN")
        blob = bytearray(glb[28 + jlen:28 + jlen + blen])
    return doc, blob


def _join_glb(doc: dict[str, Any], blob: bytearray) -> bytes:
    doc["buffers"] = [{"byteLength": len(blob)}]
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)  # chunks are 4-byte aligned: JSON pads with spaces
    data = bytes(blob) + b"\0" * (-len(blob) % 4)
    total = 12 + 8 + len(text) + 8 + len(data)
    return (struct.pack("<III", _GLB_MAGIC, 2, total) + struct.pack("<II", len(text), _JSON_CHUNK)
            + text + struct.pack("<II", len(data), _BIN_CHUNK) + data)


def _append(doc: dict[str, Any], blob: bytearray, values: np.ndarray) -> int:
    """Append float32 ``values`` (N, width) to the buffer as a new buffer view and
    accessor (with min/max); returns the accessor's index."""
    values = np.ascontiguousarray(values, dtype=np.float32).reshape(len(values), -1)
    blob.extend(b"\0" * (-len(blob) % 4))
    doc.setdefault("bufferViews", []).append(
        {"buffer": 0, "byteOffset": len(blob), "byteLength": values.nbytes})
    blob.extend(values.tobytes())
    doc.setdefault("accessors", []).append({
        "bufferView": len(doc["bufferViews"]) - 1, "componentType": _FLOAT,
        "count": len(values), "type": _VEC[values.shape[1]],
        "min": values.min(0).tolist(), "max": values.max(0).tolist()})
    return len(doc["accessors"]) - 1


def _node_index(doc: dict[str, Any], name: str) -> int:
    for i, node in enumerate(doc["nodes"]):
        if node.get("name") == name:
            return i
    raise SimenvError(f"trimesh wrote no node {name!r}")  # a bug, not a user error


def _use_trs(doc: dict[str, Any], body_nodes: dict[int, str], xpos: np.ndarray,
             xquat: np.ndarray) -> None:
    """Body nodes get translation + rotation instead of trimesh's matrix (the spec forbids
    a matrix on animated nodes), exactly frame 0's pose; the root gets the Z-up turn."""
    root = doc["nodes"][_node_index(doc, "world")]
    root.pop("matrix", None)
    root["rotation"] = list(Z_UP_TO_Y_UP)
    for b, name in body_nodes.items():
        node = doc["nodes"][_node_index(doc, name)]
        node.pop("matrix", None)
        node["translation"] = xpos[b].tolist()
        node["rotation"] = _xyzw(xquat[b]).tolist()


def _set_targets(doc: dict[str, Any]) -> None:
    """Mark the buffer views of vertex attributes and indices as such (trimesh leaves the
    hint out; viewers may upload the views to the GPU directly with it)."""
    views = doc.get("bufferViews", [])
    for mesh in doc.get("meshes", []):
        for prim in mesh["primitives"]:
            for acc in prim["attributes"].values():
                views[doc["accessors"][acc]["bufferView"]]["target"] = 34962  # ARRAY_BUFFER
            if "indices" in prim:
                views[doc["accessors"][prim["indices"]]["bufferView"]]["target"] = 34963


def _add_animation(doc: dict[str, Any], blob: bytearray,
                   tracks: dict[str, tuple[np.ndarray, np.ndarray]], times: np.ndarray,
                   name: str) -> bytearray:
    """One animation: per node in ``tracks`` (name -> (T, 3) positions, (T, 4) w x y z
    quaternions) a translation and a rotation channel over ``times`` (T,), s."""
    t_acc = _append(doc, blob, times[:, None])
    samplers, channels = [], []
    for node_name, (pos, quat) in tracks.items():
        node = _node_index(doc, node_name)
        for target, values in (("translation", pos), ("rotation", _xyzw(quat))):
            samplers.append({"input": t_acc, "output": _append(doc, blob, values),
                             "interpolation": "LINEAR"})
            channels.append({"sampler": len(samplers) - 1,
                             "target": {"node": node, "path": target}})
    doc.setdefault("animations", []).append(
        {"name": name, "samplers": samplers, "channels": channels})
    return blob


__all__ = ["body_poses", "check_gltf", "write_gltf"]

"""glTF/GLB export (simenv.io.gltf, simenv.room.export, ``simenv export``): files re-read and
checked (accessor counts, min/max, time order, unit quaternions, trimesh re-load), and the
animation's node poses reproduce MuJoCo's geom positions frame by frame."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

from simenv.assets import WALK, asset_path
from simenv.body.humanoid import Humanoid
from simenv.cli.main import main
from simenv.core.errors import SimenvError
from simenv.io.gltf import Z_UP_TO_Y_UP, _split_glb, body_poses, check_gltf, write_gltf


def _wave(h: Humanoid, frames: int = 40) -> np.ndarray:
    """(frames, nq): the rest pose walking 1 m along x while every hinge swings."""
    q = np.tile(h.default_qpos(), (frames, 1))
    q[:, 0] += np.linspace(0.0, 1.0, frames)
    phase = np.linspace(0.0, np.pi, frames)[:, None]
    lo, hi = h.joint_limits.T
    q[:, h.hinge_qpos] = (lo + hi) / 2 + (hi - lo) / 4 * np.sin(phase + np.arange(len(lo)))
    return q


def _quat_apply(q_xyzw: np.ndarray, v: np.ndarray) -> np.ndarray:
    w, xyz = q_xyzw[3], q_xyzw[:3]
    return v + 2 * np.cross(xyz, np.cross(xyz, v) + w * v)


def _animated_pose(doc: dict, blob: bytes, node: int, frame: int) -> tuple[np.ndarray, ...]:
    """(translation, rotation x y z w) of ``node`` at ``frame`` from the GLB's animation."""
    out = {}
    (anim,) = doc["animations"]
    for ch in anim["channels"]:
        if ch["target"]["node"] != node:
            continue
        acc = doc["accessors"][anim["samplers"][ch["sampler"]]["output"]]
        view = doc["bufferViews"][acc["bufferView"]]
        width = 3 if acc["type"] == "VEC3" else 4
        values = np.frombuffer(blob, np.float32, acc["count"] * width,
                               view["byteOffset"]).reshape(-1, width)
        out[ch["target"]["path"]] = values[frame].astype(float)
    return out["translation"], out["rotation"]


def test_humanoid_motion_round_trip_matches_mujoco(tmp_path: Path):
    h = Humanoid()
    q = _wave(h)
    path = write_gltf(h.model, tmp_path / "wave.glb", poses=body_poses(h.model, q), fps=20.0)
    info = check_gltf(path)
    visible = sum(1 for g in range(h.model.ngeom) if h.model.geom_group[g] <= 2
                  and h.model.geom_rgba[g, 3] > 0)
    moving = h.model.nbody - 1  # every body but the world moves; the floor does not
    assert info["meshes"] == visible and info["animations"] == 1
    assert info["channels"] == 2 * moving and info["frames"] == len(q)
    assert info["duration_s"] == pytest.approx((len(q) - 1) / 20.0, abs=1e-6)

    doc, blob = _split_glb(path.read_bytes())
    nodes = {n.get("name"): i for i, n in enumerate(doc["nodes"])}
    assert doc["nodes"][nodes["world"]]["rotation"] == pytest.approx(list(Z_UP_TO_Y_UP))
    # glTF is Y-up: MuJoCo's (x, y, z) is shown at (x, z, -y).
    to_y_up = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
    d = mujoco.MjData(h.model)
    for frame in (0, 17, len(q) - 1):
        d.qpos[:] = q[frame]
        mujoco.mj_kinematics(h.model, d)
        for g in range(h.model.ngeom):
            b = h.model.geom_bodyid[g]
            if b == 0:
                continue
            t, r = _animated_pose(doc, blob, nodes[f"body:{h.model.body(b).name}"], frame)
            centre = t + _quat_apply(r, h.model.geom_pos[g])
            assert to_y_up @ centre == pytest.approx(to_y_up @ d.geom_xpos[g], abs=1e-5)
    # Node rest transforms are frame 0 and TRS (the spec forbids a matrix on animated nodes).
    assert not any("matrix" in doc["nodes"][nodes[f"body:{h.model.body(b).name}"]]
                   for b in range(1, h.model.nbody))
    scene = trimesh.load(path, force="scene")
    assert len(scene.geometry) == visible


def test_gltf_json_variant_and_static_scene(tmp_path: Path):
    h = Humanoid()
    path = write_gltf(h.model, tmp_path / "rest.gltf")
    info = check_gltf(path)
    assert info["animations"] == 0 and info["meshes"] > 10
    doc = json.loads(path.read_text())
    assert doc["buffers"][0]["uri"].startswith("data:application/octet-stream;base64,")


def test_export_errors(tmp_path: Path):
    h = Humanoid()
    with pytest.raises(SimenvError, match=r"\.glb or \.gltf"):
        write_gltf(h.model, tmp_path / "x.obj")
    with pytest.raises(SimenvError, match="fps"):
        write_gltf(h.model, tmp_path / "x.glb", poses=body_poses(h.model, _wave(h, 3)))
    with pytest.raises(SimenvError, match="qpos"):
        body_poses(h.model, np.zeros((3, 5)))


def test_cli_exports_motion_room_and_user_in_room(tmp_path: Path, capsys):
    walk = asset_path(WALK)
    assert main(["export", str(walk), "--to", str(tmp_path / "walk.glb"), "--stride", "4"]) == 0
    out = capsys.readouterr().out
    assert "animation of 86 frames" in out  # 343 frames at 120 fps, every 4th
    assert check_gltf(tmp_path / "walk.glb")["duration_s"] == pytest.approx(85 * 4 / 120, 1e-5)

    assert main(["export", "--scenario", "discomfort", "--to", str(tmp_path / "room.glb")]) == 0
    room = check_gltf(tmp_path / "room.glb")
    assert room["animations"] == 0 and room["meshes"] > 50

    assert main(["export", str(walk), "--scenario", "default", "--to",
                 str(tmp_path / "user.glb")]) == 0
    user = check_gltf(tmp_path / "user.glb")
    # Only the user's bodies move: the seated agent and the furniture stand still.
    assert user["animations"] == 1 and user["frames"] == 72  # 2.85 s at 25 fps
    doc, _ = _split_glb((tmp_path / "user.glb").read_bytes())
    moving = {doc["nodes"][c["target"]["node"]]["name"]
              for c in doc["animations"][0]["channels"]}
    assert moving and all(n.startswith("body:user/") for n in moving)

    assert main(["export", "--to", str(tmp_path / "none.glb")]) == 2
    assert "nothing to export" in capsys.readouterr().err

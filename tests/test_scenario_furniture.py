"""User furniture meshes in scenario TOML files (simenv.room.scenario ``[[furniture]]``,
simenv.room.furniture): real mesh files made with trimesh primitives (OBJ, STL, GLB), the
collision geometry measured by dropping a box on a chair, and clear errors for missing,
unreadable, empty and millimetre files."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from trimesh.creation import box

from simenv.core.errors import ScenarioError
from simenv.io.gltf import check_gltf, write_gltf
from simenv.room.furniture import COLLISION_GROUP, add_furniture, prepare
from simenv.room.room import Room
from simenv.room.scenario import load_scenario, scenario_path

#: Seat top and back of the test chairs (m): seat 45 x 45 cm, back 4 cm thick at -x.
SEAT_TOP, BACK_FRONT, BACK_TOP = 0.47, -0.185, 0.97


def _chair() -> trimesh.Trimesh:
    """A chair of six boxes (seat, four legs, back) in one mesh, Z-up, metres."""
    parts = [box([0.45, 0.45, 0.05]).apply_translation([0, 0, SEAT_TOP - 0.025])]
    for x in (-0.2, 0.2):
        for y in (-0.2, 0.2):
            parts.append(box([0.04, 0.04, 0.42]).apply_translation([x, y, 0.21]))
    parts.append(box([0.04, 0.45, 0.5]).apply_translation([-0.205, 0, 0.72]))
    return trimesh.util.concatenate(parts)


def _block_chair() -> trimesh.Trimesh:
    """A one-piece, non-convex chair: the L-shaped side profile (seat block and back)
    extruded 45 cm along y; one closed surface."""
    profile = [(-0.225, 0.0), (0.225, 0.0), (0.225, SEAT_TOP), (BACK_FRONT, SEAT_TOP),
               (BACK_FRONT, BACK_TOP), (-0.225, BACK_TOP)]
    n = len(profile)
    verts = [(x, y, z) for y in (-0.225, 0.225) for x, z in profile]
    # The profile is star-shaped from its reflex corner (index 3): a fan from it covers it.
    caps = [(3, (3 + k) % n, (4 + k) % n) for k in range(1, n - 1)]
    faces = caps + [(a + n, c + n, b + n) for a, b, c in caps]
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j, j + n), (i, j + n, i + n)]
    mesh = trimesh.Trimesh(verts, faces)
    mesh.fix_normals()
    assert mesh.is_watertight and mesh.volume > 0
    return mesh


def _scenario(tmp_path: Path, furniture: str, name: str = "with_furniture.toml") -> Path:
    text = scenario_path("default").read_text() + "\n" + furniture
    path = tmp_path / name
    path.write_text(text)
    return path


def _table(mesh: str, **fields: object) -> str:
    lines = ["[[furniture]]", f'mesh = "{mesh}"', "position = [-1.5, 1.2]"]
    lines += [f"{k} = {v!r}".replace("'", '"') for k, v in fields.items()]
    return "\n".join(lines) + "\n"


def _drop(tmp_path: Path, mesh: trimesh.Trimesh, collision: str,
          x: float = -0.1) -> dict[str, float]:
    """Drop a 1 kg, 10 x 10 x 5 cm box from 1.2 m onto the mesh (placed at the origin)
    with its centre at ``x``; returns the height of the first contact with the mesh and
    the box's bottom height after 1.5 s."""
    mesh.export(tmp_path / "drop.stl")
    scenario = load_scenario(_scenario(tmp_path, _table(
        str(tmp_path / "drop.stl"), name="chair", collision=collision), "drop.toml"))
    item = scenario.furniture[0]
    spec = mujoco.MjSpec()
    spec.option.timestep = 0.002
    floor = spec.worldbody.add_geom()
    floor.type, floor.size = mujoco.mjtGeom.mjGEOM_PLANE, [2, 2, 0.1]
    add_furniture(spec, item, contype=1, conaffinity=1)
    body = spec.worldbody.add_body()
    body.name = "box"
    body.pos = [item.position[0] + x, item.position[1], 1.2]
    body.add_freejoint()
    g = body.add_geom()
    g.type, g.size, g.mass = mujoco.mjtGeom.mjGEOM_BOX, [0.05, 0.05, 0.025], 1.0
    model = spec.compile()
    data = mujoco.MjData(model)
    furniture = {i for i in range(model.ngeom) if model.geom(i).name.startswith("furniture/")}
    first = None
    for _ in range(int(1.5 / model.opt.timestep)):
        mujoco.mj_step(model, data)
        if first is None:
            z = [c.pos[2] for c in data.contact[:data.ncon]
                 if furniture & {c.geom1, c.geom2}]
            first = min(z) if z else None
    return {"first_contact_z": first, "rest_bottom_z": float(data.qpos[2] - 0.025)}


def test_parts_collide_like_the_chair_and_hull_fills_it(tmp_path: Path):
    parts = _drop(tmp_path, _chair(), "parts")
    hull = _drop(tmp_path, _chair(), "hull")
    # parts: the seat itself; hull: the face sloping from the seat's front edge to the back's
    # top, 0.47 + (0.225 - x) / 0.41 * 0.5 at the box's rear edge x = -0.15: 0.93 m.
    assert parts["first_contact_z"] == pytest.approx(SEAT_TOP, abs=0.005)
    assert parts["rest_bottom_z"] == pytest.approx(SEAT_TOP, abs=0.005)
    assert hull["first_contact_z"] == pytest.approx(0.927, abs=0.02)


def test_voxels_follow_a_one_piece_non_convex_chair(tmp_path: Path, caplog):
    one_piece = _drop(tmp_path, _block_chair(), "parts")  # one piece: its hull
    assert one_piece["first_contact_z"] > SEAT_TOP + 0.3
    assert "fills only" in caplog.text  # the stated approximation is logged
    voxels = _drop(tmp_path, _block_chair(), "voxels")
    assert voxels["first_contact_z"] == pytest.approx(SEAT_TOP, abs=0.016)
    assert voxels["rest_bottom_z"] == pytest.approx(SEAT_TOP, abs=0.016)


@pytest.mark.parametrize("suffix", [".obj", ".stl", ".glb"])
def test_mesh_files_load_z_up_placed_and_coloured(tmp_path: Path, suffix: str):
    chair = _chair()
    chair.visual.face_colors = [200, 40, 40, 255]
    if suffix != ".stl":  # OBJ and glTF files are Y-up: write the chair as they would be
        chair.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    chair.export(tmp_path / f"chair{suffix}")
    path = _scenario(tmp_path, _table(f"chair{suffix}", name="armchair", yaw_deg=90.0))
    scenario = load_scenario(path)  # the mesh path is relative to the TOML's folder
    (item,) = scenario.furniture
    assert item.size == pytest.approx((0.45, 0.45, BACK_TOP), abs=1e-4)
    prepared = prepare(item)
    assert len(prepared.parts) == 6 and prepared.convexity == pytest.approx([1.0] * 6)
    if suffix != ".stl":  # STL has no colour
        assert prepared.rgba[:3] == pytest.approx((200 / 255, 40 / 255, 40 / 255), abs=0.01)
    room = Room(scenario)
    m = room.model
    body = m.body("furniture/armchair")
    assert body.pos == pytest.approx([-1.5, 1.2, 0.0])
    visual, hulls = m.geom("furniture/armchair/mesh"), [
        g for g in range(m.ngeom) if m.geom(g).name.startswith("furniture/armchair/part")]
    assert visual.contype == visual.conaffinity == 0 and len(hulls) == 6
    assert all(m.geom_group[g] == COLLISION_GROUP and m.geom_contype[g] == 1 for g in hulls)
    data = room.make_data()
    # Turned 90 degrees: the back (at -x in the file) is now on the -y side.
    back = max(hulls, key=lambda g: data.geom_xpos[g, 2])
    assert data.geom_xpos[back, :2] == pytest.approx([-1.5, 1.2 - 0.205], abs=1e-3)
    # The room's glTF shows the chair (its drawn mesh, not the hidden hulls).
    out = write_gltf(m, tmp_path / "room.glb", data=data)
    names = [n.get("name") for n in __import__("json").loads(
        out.read_bytes()[20:20 + int.from_bytes(out.read_bytes()[12:16], "little")])["nodes"]]
    assert "geom:furniture/armchair/mesh" in names
    assert not any(str(n).startswith("geom:furniture/armchair/part") for n in names)
    assert check_gltf(out)["meshes"] > 50


def test_furniture_errors_name_the_file_and_field(tmp_path: Path):
    def error(table: str) -> str:
        with pytest.raises(ScenarioError) as exc:
            load_scenario(_scenario(tmp_path, table))
        return str(exc.value)

    msg = error(_table("missing.obj"))
    assert "furniture[0].mesh" in msg and "no such mesh file" in msg
    (tmp_path / "broken.glb").write_bytes(b"glTF not really a binary glTF file")
    assert "could not read it as a mesh" in error(_table("broken.glb"))
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    assert "no triangles" in error(_table("points.obj"))
    (tmp_path / "chair.txt").write_text("")
    assert "unknown mesh type" in error(_table("chair.txt"))
    mm = _chair().apply_scale(1000.0)  # the same chair modelled in millimetres
    mm.export(tmp_path / "chair_mm.stl")
    msg = error(_table("chair_mm.stl"))
    assert "millimetres (scale = 0.001)" in msg and "450 x 450 x 970 m" in msg
    fixed = load_scenario(_scenario(tmp_path, _table("chair_mm.stl", scale=0.001)))
    assert fixed.furniture[0].size == pytest.approx((0.45, 0.45, BACK_TOP), abs=1e-4)
    _chair().export(tmp_path / "chair.stl")
    assert "through a wall" in error(_table("chair.stl").replace("[-1.5, 1.2]", "[2.4, 0]"))
    assert "inside furniture" in error(_table("chair.stl").replace("[-1.5, 1.2]",
                                                                  "[-0.8, -0.6]"))
    assert "furniture[0].collision" in error(_table("chair.stl", collision="convex"))
    assert "furniture[0].colour" in error(_table("chair.stl", colour=[1, 0, 0, 1]))
    two = _table("chair.stl", name="a") + _table("chair.stl", name="a")
    assert "duplicate furniture name" in error(two)

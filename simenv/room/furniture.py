"""User-supplied furniture meshes (OBJ, STL, glTF/GLB, PLY, OFF) in the room.

A scenario lists them as ``[[furniture]]`` tables (:class:`FurnitureMesh`, read by
:func:`simenv.room.scenario.load_scenario`; fields documented in
``assets/scenarios/default.toml``). Each file is read with :mod:`trimesh`, turned Z-up
(``up = "y"``: glTF's convention and that of most OBJ exports), scaled to metres
(``scale``), and placed by the centre of its footprint at ``position`` with its lowest
point at ``elevation`` (m), turned by ``yaw_deg``.

Collision. MuJoCo collides a mesh geom as its convex hull, so a chair given as one mesh
would collide as a solid block filling the space between its seat and its back. The
``collision`` field chooses the geometry instead (:data:`COLLISIONS`):

* ``parts`` (default): one convex hull per connected piece of the mesh (a file's separate
  objects, a chair's legs, seat and back). Exact for furniture assembled from convex
  pieces; a non-convex single piece still collides as its hull, and its convexity
  (volume / hull volume) is reported in :attr:`PreparedFurniture.convexity` and logged
  when below :data:`CONVEXITY_WARN`.
* ``voxels``: the filled volume at ``voxel`` resolution (m), merged into boxes. Any shape,
  approximated within about half a voxel (the boxes cover every voxel the surface
  touches).
* ``hull``: one convex hull of the whole mesh (the stated approximation: concavities are
  filled).
* ``none``: drawn only.

The drawn geometry is always the mesh itself (a mesh geom that collides with nothing); the
collision geoms sit in geom group :data:`COLLISION_GROUP`, hidden by default in MuJoCo's
renderer and left out of glTF exports.

Measured (``tests/test_scenario_furniture.py``): a 1 kg, 10 x 10 x 5 cm box dropped from
1.2 m onto a chair's seat (top 0.47 m), its rear edge 3.5 cm in front of the chair's back.
A chair of six boxes in one mesh, ``parts``: first contact 0.4665 m (MuJoCo's soft contact
lets it sink 3.5 mm), at rest on the seat at 0.470 m. The same chair, ``hull``: first
contact 0.927 m, on the hull's face sloping from the seat's front edge to the back's top,
down which the box then slides to the floor. A one-piece chair (its L-shaped side profile
extruded): ``parts`` is its hull (the same 0.927 m; the piece fills 69 % of its hull, which
is logged); ``voxels`` (3 cm): 0.4665 m and at rest at 0.470 m, like the six-box chair.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from simenv.core.errors import ScenarioError

if TYPE_CHECKING:
    import mujoco

log = logging.getLogger(__name__)

#: File types read (by suffix).
MESH_SUFFIXES = (".obj", ".stl", ".glb", ".gltf", ".ply", ".off")
#: Collision geometry choices (see the module docstring).
COLLISIONS = ("parts", "voxels", "hull", "none")
#: A mesh larger than this (m) along any axis after ``scale`` is taken for a unit mistake
#: (a chair modelled in millimetres reads as 800 m tall).
MAX_SIZE_M = 10.0
#: ``parts`` collision: at most this many convex pieces per mesh (use ``voxels`` or
#: ``hull`` beyond).
MAX_PARTS = 64
#: ``voxels`` collision: at most this many boxes per mesh (raise ``voxel`` beyond).
MAX_BOXES = 400
#: ``parts`` logs a warning for a piece whose volume is below this fraction of its hull's.
CONVEXITY_WARN = 0.7
#: Geom group of the collision geometry (MuJoCo's renderer shows groups 0-2).
COLLISION_GROUP = 3
#: Colour when neither the scenario nor the file gives one (RGBA 0-1).
DEFAULT_RGBA = (0.6, 0.5, 0.4, 1.0)
#: Pieces smaller than this (m^3 hull volume, or fewer than 4 vertices) are not given a
#: collision hull: MuJoCo cannot build one for a flat or degenerate piece.
MIN_PART_VOLUME = 1e-9


@dataclass(frozen=True)
class FurnitureMesh:
    """``[[furniture]]``: a user-supplied mesh placed in the room.

    Attributes:
        name: unique name; the MuJoCo body is ``furniture/<name>``.
        mesh: the mesh file (a path in the TOML is relative to the TOML's folder).
        position: floor position (x, y) of the centre of its footprint, m.
        yaw_deg: turn about the vertical from the file's orientation, degrees.
        elevation: height of its lowest point above the floor, m.
        scale: file units -> metres (0.001 for a file in millimetres).
        up: the file's up axis, ``"y"`` (default for glTF/GLB and OBJ) or ``"z"`` (STL).
        collision: ``parts`` / ``voxels`` / ``hull`` / ``none`` (:data:`COLLISIONS`).
        voxel: voxel size for ``collision = "voxels"``, m.
        rgba: colour (0-1), or None for the file's own (else a wood brown).
        size: measured bounding box (x, y, z) in the room, m, before ``yaw_deg``.
        field: the table's name in errors (``furniture[0]``).
    """

    name: str
    mesh: Path
    position: tuple[float, float]
    yaw_deg: float
    elevation: float
    scale: float
    up: str
    collision: str
    voxel: float
    rgba: tuple[float, float, float, float] | None
    size: tuple[float, float, float]
    field: str


@dataclass(frozen=True)
class PreparedFurniture:
    """A furniture mesh ready for MuJoCo, in its body's frame (origin: the footprint's
    centre on the floor below it; z up; metres).

    Attributes:
        visual: the mesh drawn (trimesh).
        parts: convex pieces collided with (trimesh; boxes for ``voxels``).
        rgba: colour (4,), 0-1.
        convexity: per ``parts`` piece, volume / hull volume (1 = convex; NaN when the
            piece is not closed); empty for the other modes.
    """

    visual: Any
    parts: tuple[Any, ...]
    rgba: tuple[float, float, float, float]
    convexity: tuple[float, ...]

    @property
    def size(self) -> tuple[float, float, float]:
        """Bounding box extents (x, y, z), m."""
        return tuple(float(e) for e in self.visual.extents)


def read_mesh(path: Path, *, scale: float, up: str, field: str,
              source: str | None = None) -> tuple[Any, list[Any], tuple[float, ...] | None]:
    """Read a mesh file, Z-up and in metres, its footprint centred on the origin and its
    lowest point at z = 0.

    Args:
        path: the file.
        scale: file units -> metres.
        up: the file's up axis, ``"y"`` or ``"z"``.
        field, source: name the scenario field and file in errors.

    Returns:
        The whole mesh, its pieces (one per object of the file), and the file's colour
        (RGBA 0-1) or None.

    Raises:
        ScenarioError: missing or unreadable file, unknown type, no triangles, non-finite
            vertices, or a size beyond :data:`MAX_SIZE_M` (units).
    """
    mesh, pieces, rgba = _read_cached(str(path), path.stat().st_mtime_ns if path.is_file()
                                      else 0, float(scale), up, field, source)
    return mesh.copy(), [p.copy() for p in pieces], rgba


@lru_cache(maxsize=16)
def _read_cached(path_text: str, _mtime: int, scale: float, up: str, field: str,
                 source: str | None) -> tuple[Any, list[Any], tuple[float, ...] | None]:
    import trimesh  # only for a scenario with mesh furniture (reading a scenario stays light)

    path = Path(path_text)

    def fail(message: str) -> None:
        raise ScenarioError(f"{path}: {message}", source=source, field=field)

    if not path.is_file():
        fail("no such mesh file")
    if path.suffix.lower() not in MESH_SUFFIXES:
        fail(f"unknown mesh type {path.suffix!r}; expected one of {list(MESH_SUFFIXES)}")
    try:
        loaded = trimesh.load(path, force=None)
    except Exception as exc:  # trimesh raises many types for bad files: all are the user's
        fail(f"could not read it as a mesh ({type(exc).__name__}: {exc})")
    if isinstance(loaded, trimesh.Scene):
        pieces = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)]
    elif isinstance(loaded, trimesh.Trimesh):
        pieces = [loaded]
    else:
        pieces = []
    pieces = [p for p in pieces if len(p.faces) > 0]
    if not pieces:
        fail("holds no triangles (an empty mesh, or only points or lines)")
    rgba = _file_colour(pieces[0])
    mesh = trimesh.util.concatenate(pieces) if len(pieces) > 1 else pieces[0].copy()
    if not np.isfinite(mesh.vertices).all():
        fail("has non-finite vertex coordinates")
    to_z_up = np.eye(4)
    if up == "y":  # +y of the file becomes +z: +90 degrees about x
        to_z_up[1:3, 1:3] = [[0.0, -1.0], [1.0, 0.0]]
    to_z_up[:3, :3] *= scale
    lo, hi = (mesh.bounds @ to_z_up[:3, :3].T)[[0, 1]]
    lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    size = hi - lo
    if size.max() > MAX_SIZE_M:
        fail(f"is {size[0]:.3g} x {size[1]:.3g} x {size[2]:.3g} m after scale = {scale:g}, "
             f"larger than {MAX_SIZE_M:g} m: is the file in millimetres (scale = 0.001) or "
             "centimetres (scale = 0.01)?")
    if size.max() <= 0:
        fail("has no extent (all vertices at one point)")
    to_z_up[:3, 3] = -np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    for m in (mesh, *pieces):
        m.apply_transform(to_z_up)
    return mesh, pieces, rgba


def _file_colour(mesh: Any) -> tuple[float, ...] | None:
    """The file's colour of a piece (material base colour or the main vertex/face colour),
    RGBA 0-1, or None when the file has none."""
    visual = mesh.visual
    material = getattr(visual, "material", None)
    colour = getattr(material, "baseColorFactor", None) if material is not None else None
    if colour is None and material is not None:
        colour = getattr(material, "diffuse", None)
    if colour is None and getattr(visual, "kind", None) in ("vertex", "face"):
        colour = visual.main_color
    if colour is None:
        return None
    c = np.asarray(colour, dtype=float).ravel()[:4]
    c = c / 255.0 if c.max() > 1.0 else c
    return tuple(float(x) for x in np.append(c, 1.0)[:4])


def prepare(item: FurnitureMesh, source: str | None = None) -> PreparedFurniture:
    """Read ``item``'s mesh and build its collision pieces (module docstring). Cached
    until the file changes: a room rebuilt for every episode reads and decomposes each
    mesh once (the result is shared, not to be modified)."""
    mtime = item.mesh.stat().st_mtime_ns if item.mesh.is_file() else 0
    return _prepare(item, source, mtime)


@lru_cache(maxsize=32)
def _prepare(item: FurnitureMesh, source: str | None, _mtime: int) -> PreparedFurniture:
    field = f"{item.field}.mesh"
    mesh, pieces, file_rgba = read_mesh(item.mesh, scale=item.scale, up=item.up, field=field,
                                        source=source)
    rgba = item.rgba or file_rgba or DEFAULT_RGBA
    convexity: tuple[float, ...] = ()
    if item.collision == "none":
        parts: list[Any] = []
    elif item.collision == "hull":
        parts = [mesh.convex_hull]
    elif item.collision == "voxels":
        parts = _voxel_boxes(mesh, item.voxel, field, source)
    else:
        components = [c for p in pieces for c in p.split(only_watertight=False)]
        if len(components) > MAX_PARTS:
            raise ScenarioError(f"{item.mesh}: {len(components)} separate pieces, more than "
                                f"{MAX_PARTS} convex hulls; use collision = \"voxels\" or "
                                "\"hull\"", source=source, field=f"{item.field}.collision")
        parts, ratios = [], []
        for c in components:
            if len(c.vertices) < 4:
                continue
            hull = c.convex_hull
            if hull.volume < MIN_PART_VOLUME:
                continue
            parts.append(hull)
            ratios.append(c.volume / hull.volume if c.is_watertight else float("nan"))
        convexity = tuple(float(r) for r in ratios)
        worst = min((r for r in convexity if np.isfinite(r)), default=1.0)
        if worst < CONVEXITY_WARN:
            log.warning("%s: a piece fills only %.0f %% of its convex hull, which it collides "
                        "as; collision = \"voxels\" follows its shape", item.mesh, 100 * worst)
    return PreparedFurniture(mesh, tuple(parts), tuple(float(c) for c in rgba), convexity)


def _voxel_boxes(mesh: Any, pitch: float, field: str, source: str | None) -> list[Any]:
    """The mesh's volume as voxels of ``pitch`` (m) merged greedily into boxes (trimesh).

    A voxel is solid when its centre is inside the mesh: the winding number along a
    vertical ray (faces crossed below the centre, +1 facing down, -1 facing up), which
    holds for closed pieces that touch or overlap, so the boxes follow the surface within
    half a voxel. A mesh without consistent winding falls back to trimesh's voxels touching
    the surface, filled, which overshoot the surface by up to one voxel.
    """
    import trimesh  # as in _read_cached

    if mesh.is_winding_consistent and mesh.volume != 0:
        filled, corner = _inside_voxels(mesh, pitch, outward=mesh.volume > 0)
    else:
        grid = mesh.voxelized(pitch).fill()
        filled = grid.matrix.copy()
        corner = grid.transform[:3, 3] - pitch / 2
    boxes = []
    for i, j, k in np.argwhere(filled):
        if not filled[i, j, k]:
            continue  # taken by an earlier box
        i1 = i + 1
        while i1 < filled.shape[0] and filled[i1, j, k]:
            i1 += 1
        j1 = j + 1
        while j1 < filled.shape[1] and filled[i:i1, j1, k].all():
            j1 += 1
        k1 = k + 1
        while k1 < filled.shape[2] and filled[i:i1, j:j1, k1].all():
            k1 += 1
        filled[i:i1, j:j1, k:k1] = False
        boxes.append(trimesh.creation.box(bounds=[corner + pitch * np.array([i, j, k]),
                                                  corner + pitch * np.array([i1, j1, k1])]))
        if len(boxes) > MAX_BOXES:
            raise ScenarioError(f"more than {MAX_BOXES} boxes at voxel = {pitch:g} m; use a "
                                "larger voxel", source=source,
                                field=field.replace(".mesh", ".voxel"))
    return boxes


def _inside_voxels(mesh: Any, pitch: float, outward: bool = True
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Voxels of a consistently wound mesh whose centres it winds around (``outward``:
    its faces' normals point out): (nx, ny, nz) bool, and the lower corner (3,) of voxel
    (0, 0, 0), m. The lattice is centred on the bounding box."""
    lo, hi = mesh.bounds
    n = np.maximum(np.ceil((hi - lo) / pitch - 1e-9).astype(int), 1)
    corner = (lo + hi) / 2 - n * pitch / 2
    centres = [corner[a] + pitch * (np.arange(n[a]) + 0.5) for a in range(3)]
    # Rays a hair off the lattice so that none runs exactly along a triangle's edge.
    gx, gy = np.meshgrid(centres[0] + 1.3e-4 * pitch, centres[1] + 0.7e-4 * pitch,
                         indexing="ij")
    points = np.stack([gx.ravel(), gy.ravel()], axis=1)  # (N, 2)
    tri = np.asarray(mesh.triangles)  # (F, 3, 3)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    keep = np.abs(area) > 1e-15  # triangles seen edge-on from above hold no crossing
    a, b, c, area = a[keep], b[keep], c[keep], area[keep]
    # A face seen counter-clockwise from above faces up: crossing it downwards leaves the
    # volume (-1) when normals point out.
    facing = -np.sign(area) * (1.0 if outward else -1.0)
    filled = np.zeros(n, dtype=bool)
    chunk = max(1, 2_000_000 // max(len(a), 1))  # (chunk, F) arrays of ~16 MB
    for start in range(0, len(points), chunk):
        p = points[start:start + chunk, None, :]
        w_a = ((b[:, 0] - p[..., 0]) * (c[:, 1] - p[..., 1])
               - (b[:, 1] - p[..., 1]) * (c[:, 0] - p[..., 0])) / area
        w_b = ((c[:, 0] - p[..., 0]) * (a[:, 1] - p[..., 1])
               - (c[:, 1] - p[..., 1]) * (a[:, 0] - p[..., 0])) / area
        w_c = 1.0 - w_a - w_b
        col, face = np.nonzero((w_a >= 0) & (w_b >= 0) & (w_c >= 0))
        z = (w_a[col, face] * a[face, 2] + w_b[col, face] * b[face, 2]
             + w_c[col, face] * c[face, 2])
        # Each crossing counts for every voxel centre above it: add it at the first such
        # centre, then sum up the column.
        steps = np.zeros((len(p), n[2] + 1))
        np.add.at(steps, (col, np.searchsorted(centres[2], z, side="right")), facing[face])
        winding = np.cumsum(steps, axis=1)[:, :n[2]]
        filled.reshape(-1, n[2])[start:start + chunk] = winding > 0.5
    return filled, corner


def add_furniture(spec: mujoco.MjSpec, item: FurnitureMesh, *, contype: int,
                  conaffinity: int, source: str | None = None) -> PreparedFurniture:
    """Add one furniture mesh to ``spec``: a static body ``furniture/<name>`` at its place,
    the drawn mesh (no collision) and its collision pieces (geom group
    :data:`COLLISION_GROUP`, the given collision bits, mesh geoms MuJoCo collides as the
    pieces' own convex hulls)."""
    # mujoco here only: reading a scenario (which reads its meshes) stays light.
    import mujoco

    prepared = prepare(item, source)
    yaw = np.deg2rad(item.yaw_deg)
    body = spec.worldbody.add_body()
    body.name = f"furniture/{item.name}"
    body.pos = [item.position[0], item.position[1], item.elevation]
    body.quat = [float(np.cos(yaw / 2)), 0.0, 0.0, float(np.sin(yaw / 2))]
    for k, (mesh, visual) in enumerate([(prepared.visual, True)]
                                       + [(p, False) for p in prepared.parts]):
        name = f"furniture/{item.name}/" + ("mesh" if visual else f"part{k - 1}")
        asset = spec.add_mesh()
        asset.name = name
        asset.uservert = np.asarray(mesh.vertices, dtype=np.float64).ravel().tolist()
        asset.userface = np.asarray(mesh.faces, dtype=np.int32).ravel().tolist()
        # Static geometry: mass and inertia are never used, and a thin or open shell has
        # no volume to compute them from.
        asset.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
        geom = body.add_geom()
        geom.name = name
        geom.type = mujoco.mjtGeom.mjGEOM_MESH
        geom.meshname = name
        if visual:
            geom.rgba = list(prepared.rgba)
            geom.contype = geom.conaffinity = 0
        else:
            geom.rgba = [0.2, 0.8, 0.3, 0.4]
            geom.group = COLLISION_GROUP
            geom.contype, geom.conaffinity = contype, conaffinity
    return prepared


__all__ = ["COLLISIONS", "MAX_SIZE_M", "MESH_SUFFIXES", "FurnitureMesh", "PreparedFurniture",
           "add_furniture", "prepare", "read_mesh"]

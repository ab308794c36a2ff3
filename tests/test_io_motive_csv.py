"""OptiTrack Motive CSV exports (simenv/io/motive_csv.py), on real motion.

No Motive export with a licence allowing redistribution was found (the real one read during
development, a Gaga dance, has none: tests/data/conventions/SOURCES.md), so each test writes a
real CMU walk (shared corpus 02_01) in Motive's layout, modelled on that file: the take row,
a blank row, Type / Name / ID / Parent rows, the property and axis rows, then one row per frame
with each bone's global Rotation (X, Y, Z, W) and Position (X, Y, Z), Y up, and unlabelled
markers (CMU's thumbs) after the bones. Motive's bones take the positions of the CMU joints at
the same place in the body (:data:`MOTIVE_FROM_CMU`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import simenv
from simenv.core.errors import FormatError, MotionError, SkeletonError, UnitsError
from simenv.core.motion import Interaction, Motion
from simenv.io import bvh, loader, motive_csv
from simenv.io.joint_csv import UP_TO_Z_UP

#: Motive bone -> the CMU BVH joint at its place (CMU's Neck sits on Spine1: Neck1 is the neck).
MOTIVE_FROM_CMU: dict[str, str] = {
    "Hip": "Hips", "Ab": "Spine", "Chest": "Spine1", "Neck": "Neck1", "Head": "Head",
    **{f"{s}{m}": f"{side}{c}" for s, side in (("L", "Left"), ("R", "Right")) for m, c in (
        ("Shoulder", "Shoulder"), ("UArm", "Arm"), ("FArm", "ForeArm"), ("Hand", "Hand"),
        ("Middle1", "HandIndex1"), ("Thigh", "UpLeg"), ("Shin", "Leg"), ("Foot", "Foot"),
        ("Toe", "ToeBase"))},
}
#: File order of the bones, as Motive 3 writes them (hip, spine, left arm, right arm, legs).
BONES: tuple[str, ...] = (
    "Hip", "Ab", "Chest", "Neck", "Head", "LShoulder", "LUArm", "LFArm", "LHand", "LMiddle1",
    "RShoulder", "RUArm", "RFArm", "RHand", "RMiddle1", "LThigh", "LShin", "LFoot", "LToe",
    "RThigh", "RShin", "RFoot", "RToe")
MARKERS = ("LThumb", "RThumb")
SCALE = {"Millimeters": 1e-3, "Centimeters": 1e-2, "Meters": 1.0}
FRAMES = 180


@pytest.fixture(scope="module")
def walk(shared_data: Path) -> Motion:
    """A real CMU walk (02_01, 120 fps), its first FRAMES frames, as read from the BVH."""
    return bvh.read(shared_data / "cmu/bvh/02_01.bvh").slice(0, FRAMES)


def _global_quats(m: Motion, up: str) -> np.ndarray:
    """(T, J, 4) x, y, z, w global rotations of ``m``'s joints in file axes with ``up`` up."""
    assert m.rotations is not None
    local = Rotation.from_quat(m.rotations.reshape(-1, 4), scalar_first=True).as_matrix()
    local = local.reshape(*m.rotations.shape[:2], 3, 3)
    world = np.empty_like(local)
    for j, p in enumerate(m.skeleton.parents):
        world[:, j] = local[:, j] if p < 0 else world[:, p] @ local[:, j]
    c = UP_TO_Z_UP[up]
    y_up = c.T @ world @ c
    return Rotation.from_matrix(y_up.reshape(-1, 3, 3)).as_quat().reshape(*local.shape[:2], 4)


def write_take(path: Path, people: list[tuple[str, Motion]], *, units: str = "Millimeters",
               parent_row: bool = True, hip_after_asset: bool = True,
               take_row: dict[str, str] | None = None, up: str = "y") -> Path:
    """Write ``people`` (asset name, CMU motion) as a Motive CSV export (module docstring):
    Motive 3 by default; ``parent_row=False`` writes Motive 2's header (no Parent row);
    ``hip_after_asset`` names the hip bone after the asset as Motive 3 does (else ``Hip``);
    ``up`` is the export's up axis (Motive's default Y)."""
    fps = people[0][1].fps
    frames = min(m.num_frames for _, m in people)
    info = {"Format Version": "1.25" if parent_row else "1.23", "Take Name": path.stem,
            "Take Notes": "", "Capture Frame Rate": f"{fps:g}", "Export Frame Rate": f"{fps:g}",
            "Capture Start Frame": "0", "Total Frames in Take": str(frames),
            "Total Exported Frames": str(frames), "Rotation Type": "Quaternion",
            "Length Units": units, "Coordinate Space": "Global", **(take_row or {})}
    c, s = UP_TO_Z_UP[up], SCALE.get(units, 1e-3)
    head = {"Type": ["", "Type"], "Name": ["", "Name"], "ID": ["", "ID"],
            "Parent": ["", "Parent"], "prop": ["", ""], "axis": ["Frame", "Time (Seconds)"]}
    blocks = []  # (T, k) values per column block
    for a, (asset, m) in enumerate(people):
        idx = {n: i for i, n in enumerate(m.skeleton.joint_names)}
        pos = (m.positions[:frames].astype(np.float64) @ c) / s  # Z up m -> Y up file units
        quat = _global_quats(m, up)[:frames]
        full = {b: f"{asset}:{asset if b == 'Hip' and hip_after_asset else b}" for b in BONES}
        parents = {b: ("Root" if b == "Hip" else full[motive_csv.MOTIVE_PARENTS[b]])
                   for b in BONES}
        for k, b in enumerate(BONES):
            j = idx[MOTIVE_FROM_CMU[b]]
            for prop, axes, values in (("Rotation", "XYZW", quat[:, j]),
                                       ("Position", "XYZ", pos[:, j])):
                head["Type"] += ["Bone"] * len(axes)
                head["Name"] += [full[b]] * len(axes)
                head["ID"] += [f"{a + 1}{k:03d}"] * len(axes)
                head["Parent"] += [parents[b]] * len(axes)
                head["prop"] += [prop] * len(axes)
                head["axis"] += list(axes)
                blocks.append(values)
    for k, mk in enumerate(MARKERS):
        head["Type"] += ["Marker"] * 3
        head["Name"] += [f"Unlabeled {1000 + k}"] * 3
        head["ID"] += [f"M{k}"] * 3
        head["Parent"] += [""] * 3
        head["prop"] += ["Position"] * 3
        head["axis"] += list("XYZ")
        m = people[0][1]
        blocks.append((m.positions[:frames, m.skeleton.joint_names.index(mk)] @ c) / s)
    data = np.concatenate(blocks, axis=1)
    width = len(head["axis"])
    first = [x for kv in info.items() for x in kv]
    rows = [first + [""] * (width - len(first)), [""] * width]
    rows += [head[k] for k in ("Type", "Name", "ID", *(("Parent",) if parent_row else ()),
                               "prop", "axis")]
    rows += [[str(t), f"{t / fps:.6f}", *(f"{v:.6f}" for v in row)] for t, row in enumerate(data)]
    path.write_text("\ufeff" + "\n".join(",".join(r) for r in rows) + "\n")
    return path


def _expected(m: Motion, frames: int = FRAMES) -> np.ndarray:
    """(T, 23, 3) metres, Z up: the CMU positions each Motive bone took, in BONES order."""
    idx = [m.skeleton.joint_names.index(MOTIVE_FROM_CMU[b]) for b in BONES]
    return m.positions[:frames, idx]


def _edit(path: Path, line: int, edit) -> Path:
    """``path`` with its 1-based ``line`` replaced by ``edit(cells)`` (a list of cells)."""
    lines = path.read_text().split("\n")
    lines[line - 1] = ",".join(edit(lines[line - 1].split(",")))
    path.write_text("\n".join(lines))
    return path


def _blank(path: Path, asset: str, frames: range) -> Path:
    """Empty every bone cell of ``asset`` in ``frames``, as Motive writes a lost skeleton."""
    lines = path.read_text().split("\n")
    names = lines[3].split(",")
    cols = [k for k, n in enumerate(names) if n.startswith(f"{asset}:")]
    first = next(i for i, ln in enumerate(lines) if ln.startswith("Frame,")) + 1
    for t in frames:
        cells = lines[first + t].split(",")
        for k in cols:
            cells[k] = ""
        lines[first + t] = ",".join(cells)
    path.write_text("\n".join(lines))
    return path


# -- round trip -------------------------------------------------------------------------------


@pytest.mark.parametrize("units", ["Millimeters", "Centimeters", "Meters"])
def test_round_trip_positions_fps_units(tmp_path: Path, walk: Motion, units: str) -> None:
    m = motive_csv.read(write_take(tmp_path / "walk.csv", [("Actor1", walk)], units=units))
    assert isinstance(m, Motion)
    assert m.fps == walk.fps == 120.0
    assert m.num_frames == FRAMES
    assert m.skeleton.joint_names == tuple(f"Actor1:{'Actor1' if b == 'Hip' else b}"
                                           for b in BONES)
    np.testing.assert_allclose(m.positions, _expected(walk), atol=2e-6)
    assert m.metadata["units"] == units and m.metadata["scale_m_per_unit"] == SCALE[units]
    assert m.metadata["up_axis_in_file"] == "y"
    assert m.metadata["parents_from"] == "the file's Parent row"
    assert m.metadata["repairs"] == [] and m.metadata["quirks"] == []
    # Rotations (23 bones x 4) and the two markers are counted, not read.
    assert m.metadata["ignored_columns"]["Bone Rotation"] == 4 * len(BONES)
    assert m.metadata["ignored_columns"]["Marker Position"] == 3 * len(MARKERS)


def test_maps_21_keypoints_with_motive_names(tmp_path: Path, walk: Motion) -> None:
    m = motive_csv.read(write_take(tmp_path / "walk.csv", [("Actor1", walk)]))
    jm = m.metadata["joint_map"]
    assert jm["convention"] == "optitrack_motive"
    canon = m.skeleton.canonical
    assert len(canon) == 21
    assert canon["pelvis"] == "Actor1:Actor1"  # the hip bone, named after the asset
    assert (canon["left_hip"], canon["left_knee"], canon["left_ankle"], canon["left_toe"]) == (
        "Actor1:LThigh", "Actor1:LShin", "Actor1:LFoot", "Actor1:LToe")
    assert (canon["right_shoulder"], canon["right_elbow"], canon["right_wrist"]) == (
        "Actor1:RUArm", "Actor1:RFArm", "Actor1:RHand")
    # Through the loader: detected by content, still 21 keypoints, on its floor.
    loaded = simenv.load(tmp_path / "walk.csv")
    assert loaded.metadata["format"] == "motive_csv"
    assert len(loaded.skeleton.canonical) == 21


def test_motive2_layout_uses_motive_hierarchy(tmp_path: Path, walk: Motion) -> None:
    with_row = motive_csv.read(write_take(tmp_path / "a.csv", [("Skel", walk)],
                                          hip_after_asset=False))
    without = motive_csv.read(write_take(tmp_path / "b.csv", [("Skel", walk)],
                                         parent_row=False, hip_after_asset=False))
    assert without.metadata["parents_from"].startswith("Motive's skeleton hierarchy")
    assert without.skeleton.joint_names == with_row.skeleton.joint_names
    assert without.skeleton.parents == with_row.skeleton.parents
    np.testing.assert_array_equal(without.positions, with_row.positions)
    assert len(without.skeleton.canonical) == 21


def test_loader_arbitrates_csv_readers(tmp_path: Path, walk: Motion) -> None:
    take = write_take(tmp_path / "walk.csv", [("Actor1", walk)])
    assert loader.detect(take)[0] == "motive_csv"
    mvn = Path(__file__).parent / "data/conventions/xsens_mvn/emokine_mvn_segment_positions.csv"
    assert loader.detect(mvn)[0] == "joint_csv"
    assert not motive_csv.sniff(mvn, mvn.read_bytes()[:4096])


def test_other_axis_convention_detected_or_given(tmp_path: Path, walk: Motion) -> None:
    path = write_take(tmp_path / "walk.csv", [("Actor1", walk)], up="z")  # Visual3D's preset
    m = motive_csv.read(path)
    assert m.metadata["up_axis_in_file"] == "z"
    assert any("not Motive's default Y up" in q for q in m.metadata["quirks"])
    np.testing.assert_allclose(m.positions, _expected(walk), atol=2e-6)
    given = motive_csv.read(path, up="z")
    assert given.metadata["quirks"] == []
    np.testing.assert_array_equal(given.positions, m.positions)
    with pytest.raises(FormatError, match="up must be"):
        motive_csv.read(path, up="w")


# -- several skeletons ------------------------------------------------------------------------


def test_two_skeletons_are_an_interaction(tmp_path: Path, walk: Motion, shared_data: Path
                                          ) -> None:
    other = bvh.read(shared_data / "cmu/bvh/16_15.bvh").slice(0, FRAMES)
    path = write_take(tmp_path / "pair.csv", [("A", walk), ("B", other)])
    pair = motive_csv.read(path)
    assert isinstance(pair, Interaction) and not pair.roles_known
    np.testing.assert_allclose(pair.actor.positions, _expected(walk), atol=2e-6)
    np.testing.assert_allclose(pair.reactor.positions, _expected(other), atol=2e-6)
    assert pair.actor.metadata["skeleton"] == "A" and pair.reactor.metadata["skeleton"] == "B"
    loaded = simenv.load(path)
    assert isinstance(loaded, Interaction)
    assert len(loaded.actor.skeleton.canonical) == len(loaded.reactor.skeleton.canonical) == 21
    one = motive_csv.read(path, skeleton="B")
    assert isinstance(one, Motion)
    np.testing.assert_array_equal(one.positions, pair.reactor.positions)
    with pytest.raises(SkeletonError, match="no skeleton 'C'"):
        motive_csv.read(path, skeleton="C")


# -- lost frames ------------------------------------------------------------------------------


def test_lost_frames_trimmed_and_interpolated_with_notes(tmp_path: Path, walk: Motion) -> None:
    path = _blank(_blank(write_take(tmp_path / "walk.csv", [("Actor1", walk)]), "Actor1",
                         range(0, 5)), "Actor1", range(60, 72))
    m = motive_csv.read(path)
    assert m.num_frames == FRAMES - 5
    repairs = m.metadata["repairs"]
    assert any(r.startswith("trimmed 5 leading and 0 trailing") for r in repairs)
    assert any("frames 55-66" in r and "lines 69-80" in r for r in repairs)  # header: 8 lines
    exp = _expected(walk)[5:]
    kept = np.r_[0:55, 67:len(exp)]
    np.testing.assert_allclose(m.positions[kept], exp[kept], atol=2e-6)
    # The gap is a straight line between its tracked neighbours (54 and 67).
    w = (np.arange(55, 67) - 54) / 13.0
    line = exp[54] + w[:, None, None] * (exp[67] - exp[54])
    np.testing.assert_allclose(m.positions[55:67], line, atol=1e-5)
    # The filled frames are not the walk's own (the gap changed them: a repair, not a no-op).
    assert np.abs(m.positions[55:67] - exp[55:67]).max() > 1e-3


def test_long_loss_is_an_error_unless_allowed(tmp_path: Path, walk: Motion) -> None:
    path = _blank(write_take(tmp_path / "walk.csv", [("Actor1", walk)]), "Actor1",
                  range(40, 112))  # 72 frames: 0.6 s at 120 fps
    with pytest.raises(MotionError, match="72 frames") as err:
        motive_csv.read(path)
    assert err.value.line == 49 and err.value.frame == 40
    m = motive_csv.read(path, max_gap_s=None)
    assert m.num_frames == FRAMES and any("frames 40-111" in r for r in m.metadata["repairs"])


def test_skeleton_never_tracked(tmp_path: Path, walk: Motion) -> None:
    path = _blank(write_take(tmp_path / "walk.csv", [("Actor1", walk)]), "Actor1",
                  range(FRAMES))
    with pytest.raises(MotionError, match="lost the skeleton throughout"):
        motive_csv.read(path)


def test_dropped_rows_noted_from_the_time_column(tmp_path: Path, walk: Motion) -> None:
    path = write_take(tmp_path / "walk.csv", [("Actor1", walk)])
    lines = path.read_text().split("\n")
    path.write_text("\n".join(lines[:100] + lines[130:]))  # 30 frame rows cut out
    m = motive_csv.read(path)
    assert m.num_frames == FRAMES - 30 and m.fps == 120.0
    assert any("rows missing" in q for q in m.metadata["quirks"])


# -- malformed input --------------------------------------------------------------------------


def _take_row_without(path: Path, key: str) -> Path:
    def drop(cells: list[str]) -> list[str]:
        k = cells.index(key)
        return cells[:k] + cells[k + 2:] + ["", ""]
    return _edit(path, 1, drop)


@pytest.mark.parametrize("missing", ["Length Units", "Frame Rate"])
def test_missing_take_fields(tmp_path: Path, walk: Motion, missing: str) -> None:
    path = write_take(tmp_path / "walk.csv", [("Actor1", walk)])
    for key in ([missing] if missing == "Length Units"
                else ["Export Frame Rate", "Capture Frame Rate"]):
        path = _take_row_without(path, key)
    with pytest.raises(FormatError) as err:
        motive_csv.read(path)
    assert err.value.line == 1
    assert err.value.field == ("Length Units" if missing == "Length Units"
                               else "Export Frame Rate")


def test_capture_rate_when_no_export_rate(tmp_path: Path, walk: Motion) -> None:
    path = _take_row_without(write_take(tmp_path / "walk.csv", [("Actor1", walk)]),
                             "Export Frame Rate")
    m = motive_csv.read(path)
    assert m.fps == 120.0 and "Capture Frame Rate" in m.metadata["fps_reason"]


def test_unknown_units_and_local_space(tmp_path: Path, walk: Motion) -> None:
    path = write_take(tmp_path / "a.csv", [("Actor1", walk)], take_row={"Length Units": "Feet"})
    with pytest.raises(UnitsError, match="'Feet'") as err:
        motive_csv.read(path)
    assert (err.value.line, err.value.field) == (1, "Length Units")
    path = write_take(tmp_path / "b.csv", [("Actor1", walk)],
                      take_row={"Coordinate Space": "Local"})
    with pytest.raises(FormatError, match="Global") as err:
        motive_csv.read(path)
    assert err.value.field == "Coordinate Space"


def test_ragged_and_non_numeric_rows(tmp_path: Path, walk: Motion) -> None:
    path = _edit(write_take(tmp_path / "a.csv", [("Actor1", walk)]), 20, lambda c: c[:-4])
    with pytest.raises(FormatError, match="cells") as err:
        motive_csv.read(path)
    assert err.value.line == 20

    path = write_take(tmp_path / "b.csv", [("Actor1", walk)])
    names = path.read_text().split("\n")[3].split(",")
    col = names.index("Actor1:LShin") + 4  # after its four rotation columns: Position X

    def garble(cells: list[str]) -> list[str]:
        cells[col] = "12.5mm"
        return cells
    with pytest.raises(FormatError, match="'12.5mm'") as err:
        motive_csv.read(_edit(path, 30, garble))
    assert (err.value.line, err.value.frame, err.value.field) == (
        30, 21, "Actor1:LShin Position X")


def test_no_skeleton_and_missing_header_rows(tmp_path: Path, walk: Motion) -> None:
    path = write_take(tmp_path / "a.csv", [("Actor1", walk)])
    with pytest.raises(SkeletonError, match="no skeleton .*Marker Position: 6") as err:
        motive_csv.read(_edit(path, 3, lambda c: [x.replace("Bone", "Rigid Body")
                                                  for x in c]))
    assert err.value.line == 3
    path = write_take(tmp_path / "b.csv", [("Actor1", walk)])
    with pytest.raises(FormatError, match="'Type'"):
        motive_csv.read(_edit(path, 3, lambda c: ["", "Kind", *c[2:]]))
    path = write_take(tmp_path / "c.csv", [("Actor1", walk)])
    with pytest.raises(FormatError, match="Format Version") as err:
        motive_csv.read(_edit(path, 1, lambda c: ["Version", *c[1:]]))
    assert err.value.line == 1

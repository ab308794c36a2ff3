"""BVH reader on the real CMU BVH files (and rewritten variants of them)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA
from expect import names_all
from scipy.spatial.transform import Rotation

from simenv.core.errors import FormatError, SimenvError, UnitsError
from simenv.io import bvh
from simenv.io._kinematics import CMU_UNIT_M, forward_kinematics, is_tpose_frame0

BVH_FILES = sorted(str(p.relative_to(SHARED_DATA)) for p in SHARED_DATA.glob("cmu/**/*.bvh"))


def sources_table(root: Path) -> dict[str, list[str]]:
    """File table rows of SOURCES.md: relative path -> cells."""
    rows = {}
    for line in (root / "SOURCES.md").read_text().splitlines():
        m = re.match(r"\|\s*`(cmu/[^`]+)`\s*\|(.*)", line)
        if m:
            rows[m.group(1)] = [c.strip() for c in m.group(2).split("|")]
    return rows


@pytest.mark.parametrize("rel", BVH_FILES)
def test_every_cmu_bvh_loads(shared_data: Path, rel: str) -> None:
    row = sources_table(shared_data)[rel]
    frames_doc, fps_doc, layout = int(row[3]), float(row[4]), row[2]
    m = bvh.read(shared_data / rel)
    meta = m.metadata
    # Frame bookkeeping: SOURCES frame count, minus the converter T-pose when dropped.
    assert meta["frames_in_file"] == frames_doc
    assert meta["tpose_frame0"] == ("cgspeed Motionbuilder" in layout)
    assert m.num_frames == frames_doc - int(meta["tpose_frame0"])
    assert meta["header_fps"] == pytest.approx(fps_doc)
    assert any("dropped T-pose frame 0" in q for q in meta["quirks"]) == meta["tpose_frame0"]
    # Units and size.
    template = row[5].startswith("43 joints")
    assert meta["units"] == ("m" if template else "cmu")
    lo, hi = (1.0, 1.4) if template else (1.2, 1.9)
    assert lo < m.height() < hi
    assert any("template skeleton" in q for q in meta["quirks"]) == template
    # Z-up: head above pelvis, feet on a floor at z ~ 0.
    c = m.skeleton.canonical
    head_up = m.joint(c["head"])[:, 2] - m.joint(c["pelvis"])[:, 2]
    assert np.median(head_up) > 0.2
    lowest = m.positions[..., 2].min(axis=1)
    assert -0.05 < np.percentile(lowest, 5) < 0.1
    ankles = np.minimum(m.joint(c["left_ankle"])[:, 2], m.joint(c["right_ankle"])[:, 2])
    assert np.median(ankles) < 0.2
    # All canonical keypoints are present and distinct from their parents.
    assert len(c) == 21
    # Rotations are unit quaternions that reproduce the positions by FK.
    q = m.rotations
    assert q.shape == (m.num_frames, m.num_joints, 4)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-5)
    mats = Rotation.from_quat(q.reshape(-1, 4), scalar_first=True).as_matrix()
    mats = mats.reshape(m.num_frames, m.num_joints, 3, 3)
    offsets = np.array(meta["offsets_m"])
    root = {0: m.positions[:, 0].astype(np.float64) - offsets[0]}
    pos, _ = forward_kinematics(m.skeleton.parents, offsets, mats, root)
    np.testing.assert_allclose(pos, m.positions, atol=2e-4)


def _cmu_text(shared_data: Path, frames: int | None = None) -> str:
    text = (shared_data / "cmu/bvh/02_01.bvh").read_text()
    if frames is None:
        return text
    head, data = text.split("Frame Time:")
    data_lines = data.splitlines()
    body = data_lines[1 : 1 + frames]
    head = re.sub(r"Frames:\s*\d+", f"Frames: {frames}", head)
    return head + "Frame Time:" + data_lines[0] + "\n" + "\n".join(body) + "\n"


def _write(tmp_path: Path, text: str, name: str = "clip.bvh", newline: str = "\n") -> Path:
    p = tmp_path / name
    p.write_bytes(text.replace("\r\n", "\n").replace("\n", newline).encode())
    return p


def _reorder_channels(text: str, order: str, root_pos_last: bool) -> str:
    """Rewrite a ZYX BVH with rotation channels in ``order`` (e.g. ``"XZY"``)
    and recompute every angle, optionally moving the root position channels
    after the rotations."""
    parsed_head, _, rest = text.partition("MOTION")
    lines = rest.strip().splitlines()
    data = np.array([ln.split() for ln in lines[2:]], dtype=np.float64)
    out = data.copy()
    n_joints = (data.shape[1] - 3) // 3
    for k in range(n_joints):
        cols = slice(3 + 3 * k, 6 + 3 * k)
        r = Rotation.from_euler("ZYX", data[:, cols], degrees=True)
        out[:, cols] = r.as_euler(order, degrees=True)
    names = " ".join(f"{a}rotation" for a in order)
    head = re.sub(r"Zrotation Yrotation Xrotation", names, parsed_head)
    if root_pos_last:
        head = head.replace(
            f"Xposition Yposition Zposition {names}", f"{names} Xposition Yposition Zposition", 1
        )
        out = np.concatenate([out[:, 3:6], out[:, :3], out[:, 6:]], axis=1)
    body = "\n".join(" ".join(f"{v:.9f}" for v in row) for row in out)
    return head + "MOTION\n" + lines[0] + "\n" + lines[1] + "\n" + body + "\n"


@pytest.mark.parametrize(
    ("order", "root_pos_last", "newline"),
    [("XZY", False, "\r\n"), ("YXZ", True, "\n"), ("ZXY", True, "\r")],
)
def test_any_rotation_order_and_line_ending(
    shared_data: Path, tmp_path: Path, order: str, root_pos_last: bool, newline: str
) -> None:
    text = _cmu_text(shared_data, 40)
    ref = bvh.read(_write(tmp_path, text, "ref.bvh"))
    other = bvh.read(
        _write(tmp_path, _reorder_channels(text, order, root_pos_last), newline=newline)
    )
    np.testing.assert_allclose(other.positions, ref.positions, atol=1e-4)
    dots = np.abs(np.sum(other.rotations * ref.rotations, axis=-1))
    np.testing.assert_allclose(dots, 1.0, atol=1e-4)


@pytest.mark.parametrize(
    ("unit", "factor"),
    [
        ("m", CMU_UNIT_M),
        ("cm", CMU_UNIT_M * 100),
        ("mm", CMU_UNIT_M * 1000),
        ("inch", CMU_UNIT_M / 0.0254),
    ],
)
def test_units_detected_from_size(
    shared_data: Path, tmp_path: Path, unit: str, factor: float
) -> None:
    text = _cmu_text(shared_data, 30)
    ref = bvh.read(_write(tmp_path, text, "ref.bvh"))

    def scale_offset(m: re.Match[str]) -> str:
        return "OFFSET " + " ".join(f"{float(v) * factor:.8f}" for v in m.group(1).split())

    head, _, motion = text.partition("MOTION")
    head = re.sub(r"OFFSET\s+([-\d.e\s]+?)(?=\s*\n)", scale_offset, head)
    lines = motion.strip().splitlines()
    rows = [ln.split() for ln in lines[2:]]
    for row in rows:
        row[:3] = [f"{float(v) * factor:.8f}" for v in row[:3]]
    body = "\n".join(" ".join(r) for r in rows)
    scaled = _write(tmp_path, head + "MOTION\n" + "\n".join(lines[:2]) + "\n" + body + "\n")
    m = bvh.read(scaled)
    assert m.metadata["units"] == unit
    assert unit in m.metadata["units_reason"]
    np.testing.assert_allclose(m.positions, ref.positions, atol=1e-4)
    forced = bvh.read(scaled, units=unit)
    assert "given by the caller" in forced.metadata["units_reason"]
    np.testing.assert_allclose(forced.positions, m.positions)
    if unit == "mm":
        with pytest.raises(UnitsError, match="median person extent"):
            bvh.read(scaled, units="m")


def test_explicit_scale_and_fps_override_are_noted(shared_data: Path) -> None:
    path = shared_data / "cmu/bvh/35_17.bvh"
    m = bvh.read(path, scale=CMU_UNIT_M, fps=60)
    assert m.metadata["units"] == "explicit"
    assert m.fps == 60
    assert any("set to 60 fps" in q for q in m.metadata["quirks"])
    kept = bvh.read(path, drop_tpose=False)
    assert kept.num_frames == m.num_frames + 1
    assert any("kept because drop_tpose=False" in q for q in kept.metadata["quirks"])


def test_end_sites_become_joints_when_asked(shared_data: Path) -> None:
    path = shared_data / "cmu/bvh/02_01.bvh"
    plain = bvh.read(path)
    full = bvh.read(path, end_sites=True)
    assert plain.num_joints == 31
    ends = [n for n in full.skeleton.joint_names if n.endswith("_end")]
    assert "Head_end" in ends and full.num_joints == 31 + len(ends)
    head_top = full.joint("Head_end")[:, 2]
    assert (head_top > full.joint("Head")[:, 2]).mean() > 0.95
    np.testing.assert_allclose(full.joint("LeftFoot"), plain.joint("LeftFoot"))


def test_template_keeps_foot_end_sites_for_toes(shared_data: Path) -> None:
    m = bvh.read(shared_data / "cmu/two_person/60_61_salsa_10/60_10_scaled.bvh")
    assert m.skeleton.canonical["left_toe"] == "lFoot_end"
    assert m.num_joints == 43 + 2
    toe_ahead = np.linalg.norm(m.joint("lFoot_end") - m.joint("lFoot"), axis=-1)
    np.testing.assert_allclose(toe_ahead, toe_ahead[0], atol=1e-5)
    assert 0.05 < toe_ahead[0] < 0.15


# -- bad input ---------------------------------------------------------------


def _expect(tmp_path: Path, text: str, err: type[SimenvError], *needles: str) -> SimenvError:
    path = _write(tmp_path, text)
    with pytest.raises(err) as info:
        bvh.read(path)
    return names_all(info.value, path, needles)


def test_truncated_file(shared_data: Path, tmp_path: Path) -> None:
    text = _cmu_text(shared_data, 20)
    _expect(tmp_path, text[: len(text) - 300], FormatError, "line", "truncated")
    _expect(tmp_path, text[: text.index("MOTION") - 200], FormatError, "MOTION")
    cut = text[: text.index("MOTION")] + "MOTION\nFrames: 20\n"
    _expect(tmp_path, cut, FormatError, "Frame Time")


def test_wrong_channel_count_and_values(shared_data: Path, tmp_path: Path) -> None:
    text = _cmu_text(shared_data, 20)
    lines = text.splitlines()
    n = lines.index("MOTION") + 4
    short = lines.copy()
    short[n] = " ".join(short[n].split()[:-1])
    err = _expect(tmp_path, "\n".join(short), FormatError, "expected 96", "found 95")
    assert err.line == n + 1 and err.frame == 1
    garbage = lines.copy()
    vals = garbage[n].split()
    vals[10] = "1.2.3"
    garbage[n] = " ".join(vals)
    err = _expect(tmp_path, "\n".join(garbage), FormatError, "'1.2.3'", "LeftUpLeg.Yrotation")
    assert err.line == n + 1
    vals[10] = "nan"
    garbage[n] = " ".join(vals)
    _expect(tmp_path, "\n".join(garbage), FormatError, "finite")
    bad_decl = text.replace(
        "CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 4 Zrotation Yrotation Xrotation", 1
    )
    _expect(tmp_path, bad_decl, FormatError, "channel")


def test_structure_errors(shared_data: Path, tmp_path: Path) -> None:
    text = _cmu_text(shared_data, 20)
    _expect(tmp_path, text.replace("HIERARCHY", "", 1), FormatError, "HIERARCHY")
    _expect(tmp_path, text.replace("Frames: 20", "Frames: 25"), FormatError, "Frames: 25", "20")
    _expect(tmp_path, text.replace("Frames: 20", "Frames: 0"), FormatError, "0 frames")
    dup = text.replace("JOINT RHipJoint", "JOINT LHipJoint", 1)
    _expect(tmp_path, dup, FormatError, "duplicate joint name 'LHipJoint'")
    unclosed = text.replace("}\nMOTION", "MOTION").replace("}\r\nMOTION", "MOTION")
    _expect(tmp_path, unclosed, FormatError, "not closed")


def test_absurd_scale(shared_data: Path, tmp_path: Path) -> None:
    text = _cmu_text(shared_data, 20)
    huge = re.sub(r"OFFSET (\S+)", lambda m: f"OFFSET {float(m.group(1)) * 1e5}", text)
    huge = re.sub(
        r"OFFSET (\S+) (\S+)", lambda m: f"OFFSET {m.group(1)} {float(m.group(2)) * 1e5}", huge
    )
    _expect(tmp_path, huge, UnitsError, "not a plausible person")
    with pytest.raises(UnitsError):
        bvh.read(_write(tmp_path, text), units="parsec")


# --- restore_collapsed_bones: the CMU converters' zero thorax and wrist offsets ---

ARM_JOINTS = (
    "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LeftFingerBase", "LThumb",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightFingerBase", "RThumb",
)  # fmt: skip
LEG_JOINTS = (
    "Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
    "RHipJoint", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase", "LowerBack",
    "Spine", "Spine1",
)  # fmt: skip


def _amc_error(motion, amc) -> dict[str, float]:
    """Max over frames of the distance to the AMC joint of the same index (m)."""
    d = np.linalg.norm(motion.positions - amc.positions, axis=-1).max(axis=0)
    return dict(zip(motion.skeleton.joint_names, d.tolist(), strict=True))


def test_restored_bones_match_the_asf_amc(shared_data: Path) -> None:
    import simenv

    amc = simenv.load(shared_data / "cmu/asf_amc/02_01.amc")
    raw = bvh.read(shared_data / "cmu/bvh/02_01.bvh")
    fixed = bvh.read(shared_data / "cmu/bvh/02_01.bvh", restore_collapsed_bones=True)
    # The BVH's T-pose frame 0 is dropped: frame k of both is AMC frame k.
    assert raw.metadata["frames_in_file"] == amc.num_frames + 1
    assert raw.num_frames == fixed.num_frames == amc.num_frames
    assert amc.num_joints == fixed.num_joints == 31
    err_raw, err = _amc_error(raw, amc), _amc_error(fixed, amc)
    for j in LEG_JOINTS:
        assert err[j] < 1e-3 and err_raw[j] < 1e-3, j
    for j in ARM_JOINTS:
        assert err_raw[j] > 0.10, j  # as written: the missing thorax (and wrist)
        assert err[j] < 0.02, j  # the thorax is approximated by the upper back
    np.testing.assert_array_equal(raw.positions[:, :14], fixed.positions[:, :14])
    repairs = fixed.metadata["repairs"]
    assert len(repairs) == 3
    assert "thorax" in repairs[0] and "Neck, LeftShoulder, RightShoulder" in repairs[0]
    assert re.search(r"set from 0 to 1[12]\.\d cm from Spine1", repairs[0])
    assert "lwrist" in repairs[1] and "LeftFingerBase" in repairs[1]
    assert "half the forearm" in repairs[1] and "rwrist" in repairs[2]
    # The restored skeleton no longer has coincident canonical keypoints.
    assert not any("coincides" in q for q in fixed.metadata["quirks"])
    assert fixed.skeleton.canonical["neck"] == "Neck"
    assert fixed.metadata["scale_m_per_unit"] == raw.metadata["scale_m_per_unit"]


def test_default_read_is_unchanged(shared_data: Path) -> None:
    for rel in ("cmu/bvh/02_01.bvh", "cmu/bvh/131_01.bvh"):
        raw = bvh.read(shared_data / rel)
        off = bvh.read(shared_data / rel, restore_collapsed_bones=False)
        np.testing.assert_array_equal(raw.positions, off.positions)
        assert "repairs" not in raw.metadata and "repairs" not in off.metadata
        assert raw.metadata == off.metadata
        assert any("a bone the converter collapsed" in q for q in raw.metadata["quirks"])


@pytest.mark.parametrize(
    "rel, thorax_parent, wrist",
    [
        ("cmu/bvh/131_01.bvh", "Chest2", "lhand"),
        ("cmu/two_person/18_19_walk_shake_hands/18_01.bvh", "thorax", "lhand"),
    ],
)
def test_restore_other_cmu_namings(
    shared_data: Path, rel: str, thorax_parent: str, wrist: str
) -> None:
    m = bvh.read(shared_data / rel, restore_collapsed_bones=True)
    names = m.skeleton.joint_names
    off = np.array(m.metadata["offsets_m"])
    parent = m.skeleton.parents[names.index(wrist)]
    np.testing.assert_allclose(off[names.index(wrist)], off[parent] / 2, atol=1e-6)
    repairs = m.metadata["repairs"]
    assert len(repairs) == 3 and f"from {thorax_parent}," in repairs[0]
    # The neck/clavicles sit a thorax (~12 cm, the upper back's length) above its parent.
    assert 0.09 < np.linalg.norm(off[names.index("lowerneck")]) < 0.15


def test_restore_does_nothing_on_other_skeletons(shared_data: Path) -> None:
    rel = "cmu/two_person/60_61_salsa_05/60_05_scaled.bvh"
    raw = bvh.read(shared_data / rel)
    m = bvh.read(shared_data / rel, restore_collapsed_bones=True)
    assert m.metadata["repairs"] == []
    assert any("nothing restored" in q and "poser" in q for q in m.metadata["quirks"])
    np.testing.assert_array_equal(raw.positions, m.positions)


def test_restore_skips_a_bone_that_is_not_collapsed(shared_data: Path, tmp_path: Path) -> None:
    lines = _cmu_text(shared_data, frames=5).splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.strip() == "JOINT LeftFingerBase")
    lines[k + 2] = lines[k + 2].replace("OFFSET 0 0 0", "OFFSET 1 0 0")
    m = bvh.read(_write(tmp_path, "\n".join(lines) + "\n"), restore_collapsed_bones=True)
    assert len(m.metadata["repairs"]) == 2
    assert any(
        "lwrist not restored" in q and "LeftFingerBase already has a non-zero offset" in q
        for q in m.metadata["quirks"]
    )


def test_restored_handshake_hands_meet() -> None:
    import simenv
    from simenv.assets import HANDSHAKE_PAIR, asset_path

    folder = asset_path(HANDSHAKE_PAIR)
    if not folder.is_dir():
        pytest.skip(f"bundled handshake pair not found at {folder}")

    def closest(**kw) -> float:
        pair = simenv.load(folder, **kw)
        a, b = pair.people
        # The hand bone's end (the knuckles) of 18_01 (ASF names) and 19_01 (cgspeed).
        return float(
            np.linalg.norm(a.joint("rfingers") - b.joint("RightHandIndex1"), axis=-1).min()
        )

    assert closest() > 0.25
    assert closest(restore_collapsed_bones=True) < 0.12
    pair = simenv.load(folder, restore_collapsed_bones=True)
    for person in pair.people:
        assert len(person.metadata["repairs"]) == 3
    assert len(pair.metadata["repairs"]) == 6
    assert "repairs" not in simenv.load(folder).metadata


def test_z_up_file_detected_from_its_rest_pose() -> None:
    """A real Z-up BVH (tests/data/conventions/other, see its SOURCES.md) stands upright
    without up='z': the head above the ankles in every frame, the detection noted; forcing
    up='y' lays the same person down."""
    path = Path(__file__).parent / "data" / "conventions" / "other" / "fair1_dab_zup.bvh"
    if not path.exists():
        pytest.skip(f"{path} absent")
    motion = bvh.read(path)
    assert any(q.startswith("up axis Z") for q in motion.metadata["quirks"])
    head = motion.joint(motion.skeleton.canonical["head"])[:, 2]
    ankles = np.maximum(motion.joint(motion.skeleton.canonical["left_ankle"])[:, 2],
                        motion.joint(motion.skeleton.canonical["right_ankle"])[:, 2])
    assert (head - ankles > 0.5 * motion.height()).all()
    lying = bvh.read(path, up="y")
    assert lying.height() < 0.6 * motion.height()


def _own_axes(src: Path, dst: Path, axis: tuple[float, float, float] | None = (1.0, 0.0, 0.0),
              scale: float = 1.0, turn_all: np.ndarray | None = None) -> Path:
    """``src`` rewritten on a rig whose joints carry their own axes, as the SNU Motion
    Database's exporter writes (``axis`` X) and Berkeley MHAD's (``axis`` Y): each joint's
    frame turned so its first child's OFFSET lies along ``axis``, every rotation channel
    changed to match, so the motion is the same and only the all-zero rest pose is no
    standing body. ``turn_all`` instead turns every joint's frame by one rotation (the rest
    pose turned as a whole, the root's rotation turning every frame back). ``scale``
    multiplies every length (OFFSETs, position channels)."""
    f = bvh.parse(src)
    n = len(f.joints)
    kids = [[k for k in range(n) if f.parents[k] == j] for j in range(n)]
    turn = [np.eye(3) for _ in range(n)]
    for j in range(n):
        d = next((f.offsets[k] for k in kids[j] if np.linalg.norm(f.offsets[k]) > 1e-6), None)
        if turn_all is not None:
            turn[j] = turn_all
        elif d is not None and any(c.lower().endswith("rotation") for c in f.channels[j]):
            turn[j] = Rotation.align_vectors([d], [axis])[0].as_matrix()
    data, col = f.data.copy(), 0
    for j, chans in enumerate(f.channels):
        above = turn[f.parents[j]] if f.parents[j] >= 0 else np.eye(3)
        rot = [col + i for i, c in enumerate(chans) if c.lower().endswith("rotation")]
        order = "".join(c[0].upper() for c in chans if c.lower().endswith("rotation"))
        pos = [col + i for i, c in enumerate(chans) if c.lower().endswith("position")]
        data[:, pos] *= scale
        if rot:
            local = Rotation.from_euler(order, data[:, rot], degrees=True).as_matrix()
            data[:, rot] = Rotation.from_matrix(above.T @ local @ turn[j]).as_euler(
                order, degrees=True)
        col += len(chans)
    offsets = [scale * (f.offsets[j] @ turn[f.parents[j]] if f.parents[j] >= 0 else f.offsets[j])
               for j in range(n)]
    lines = ["HIERARCHY"]

    def emit(j: int, pad: str) -> None:
        off = f"{pad}  OFFSET {' '.join(f'{v:.6f}' for v in offsets[j])}"
        if f.end_site[j]:
            lines.extend([f"{pad}End Site", f"{pad}{{", off, f"{pad}}}"])
            return
        lines.extend([f"{pad}{'ROOT' if f.parents[j] < 0 else 'JOINT'} {f.joints[j]}",
                      f"{pad}{{", off, f"{pad}  CHANNELS {len(f.channels[j])} "
                      f"{' '.join(f.channels[j])}"])
        for k in kids[j]:
            emit(k, pad + "  ")
        lines.append(f"{pad}}}")

    emit(0, "")
    lines += ["MOTION", f"Frames: {len(data)}", f"Frame Time: {f.frame_time:.8f}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in data]
    dst.write_text("\n".join(lines) + "\n")
    return dst


def test_rig_with_its_own_axes_reads_as_the_same_motion(tmp_path: Path) -> None:
    """A real clip (SNU MRL's MASS kick, tests/data/conventions/snu_mass) rewritten on a rig
    whose joints carry their own axes: its all-zero rest pose lies sideways (it read as Z up
    and laid the actor down), so the up axis and the units come from the motion, which
    reads as the original to float precision."""
    src = Path(__file__).parent / "data" / "conventions" / "snu_mass" / "mass_kick.bvh"
    if not src.exists():
        pytest.skip(f"{src} absent")
    original, rigged = bvh.read(src), bvh.read(_own_axes(src, tmp_path / "own_axes.bvh"))
    assert np.abs(rigged.positions - original.positions).max() < 1e-5
    assert rigged.metadata["units"] == original.metadata["units"] == "cm"
    assert any(q.startswith("rest pose is no standing body") for q in rigged.metadata["quirks"])
    assert not any(q.startswith("rest pose is no standing") or q.startswith("up axis")
                   for q in original.metadata["quirks"])


def test_rig_folded_along_y_reads_in_its_own_unit(shared_data: Path, tmp_path: Path) -> None:
    """A real CMU walk written in centimetres on a rig whose every first-child OFFSET lies
    along +Y (Berkeley MHAD's skeletons: arms and legs point up beside the head in the
    all-zero rest, about 1 m tall for a 1.7-m person): its head stands a little over its feet
    there, so the rest once passed for a standing body and the unit guess read the folded
    size. The unit now comes from the motion: centimetres, and the original's motion."""
    src = shared_data / "cmu/bvh/02_01.bvh"
    original = bvh.read(src)
    folded = bvh.read(_own_axes(src, tmp_path / "folded.bvh", axis=(0.0, 1.0, 0.0),
                                scale=CMU_UNIT_M / 0.01))
    assert folded.metadata["units"] == "cm"
    assert any(q.startswith("rest pose is no standing body") for q in folded.metadata["quirks"])
    assert np.abs(folded.positions - original.positions).max() < 1e-4


def test_rest_along_z_stood_up_along_y_by_the_root_reads_y_up(shared_data: Path,
                                                                tmp_path: Path) -> None:
    """A real CMU walk whose rest pose is turned to stand along Z while the root's rotation
    stands every frame back up along Y (a Shadow-suit export's layout): the rest pose says Z,
    the motion Y, and the motion wins, noted; the original motion to float precision. A Z-up
    file whose motion stands along Z (test_z_up_file_detected_from_its_rest_pose) keeps Z."""
    src = shared_data / "cmu/bvh/02_01.bvh"
    original = bvh.read(src)
    y_to_z = Rotation.from_euler("x", 90.0, degrees=True).as_matrix()  # +Y -> +Z
    turned = bvh.read(_own_axes(src, tmp_path / "turned.bvh", axis=None, turn_all=y_to_z.T))
    assert turned.metadata["up_axis_in_file"] == "Y"
    assert any(q.startswith("up axis Y from the motion") for q in turned.metadata["quirks"])
    assert not any(q.startswith("up axis Z: the rest") for q in turned.metadata["quirks"])
    assert np.abs(turned.positions - original.positions).max() < 1e-4
    assert bvh.read(tmp_path / "turned.bvh", up="z").metadata["up_axis_in_file"] == "Z"


def test_tpose_before_a_nearly_still_clip(shared_data: Path) -> None:
    """A T-pose frame before a person standing nearly still (a real CMU walk's first steps
    slowed 50 times after its first real step: a median step of a fraction of a millimetre,
    the first real step many times that) is found; a fast start whose next step is as large
    as its first is not."""
    walk = bvh.read(shared_data / "cmu/bvh/02_01.bvh")
    p = walk.positions.astype(np.float64)
    f = bvh.parse(shared_data / "cmu/bvh/02_01.bvh")
    rest_pos, _ = forward_kinematics(f.parents, f.offsets,
                                     np.broadcast_to(np.eye(3), (1, len(f.joints), 3, 3)))
    keep = [f.joints.index(n) for n in walk.skeleton.joint_names]
    rest = CMU_UNIT_M * rest_pos[:, keep][..., [0, 2, 1]] * [1.0, -1.0, 1.0]  # Y up -> Z up
    rest += p[:1, :1] - rest[:, :1]  # the T-pose where the walk starts
    t = np.linspace(1.0, 12.0, 551)
    slow = np.stack([np.interp(t, np.arange(len(p)), p[:, j, k])
                     for j in range(p.shape[1]) for k in range(3)], axis=-1)
    slow = slow.reshape(len(t), p.shape[1], 3)
    clip = np.concatenate([rest, p[:1], slow])
    found, note = is_tpose_frame0(clip)
    assert found, note
    fast = np.concatenate([rest, 0.5 * (rest + p[:1]), p[:1], slow])
    assert not is_tpose_frame0(fast)[0]

"""ASF/AMC reader on the real CMU Acclaim files, and the BVH cross-format check."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA
from expect import names_all
from scipy.spatial.transform import Rotation

from simenv.core.errors import FormatError
from simenv.io import asf_amc, bvh
from simenv.io._kinematics import CMU_UNIT_M, forward_kinematics

AMC_FILES = sorted(p.name for p in SHARED_DATA.glob("cmu/asf_amc/*.amc"))
ASF_FILES = sorted(p.name for p in SHARED_DATA.glob("cmu/asf_amc/*.asf"))


def _documented_frames(root: Path, name: str) -> int:
    for line in (root / "SOURCES.md").read_text().splitlines():
        if line.startswith(f"| `cmu/asf_amc/{name}`"):
            return int(line.split("|")[5])
    raise AssertionError(f"{name} not in SOURCES.md")


@pytest.mark.parametrize("name", AMC_FILES)
def test_every_cmu_amc_loads(shared_data: Path, name: str) -> None:
    m = asf_amc.read(shared_data / "cmu/asf_amc" / name)
    assert m.num_frames == _documented_frames(shared_data, name)
    assert m.fps == 120.0
    assert m.num_joints == 31 and m.skeleton.joint_names[0] == "root"
    assert m.metadata["units"] == "cmu"
    assert m.metadata["scale_m_per_unit"] == pytest.approx(CMU_UNIT_M)
    assert Path(m.metadata["asf"]).stem == name.split("_")[0] or name.startswith("103_")
    assert 1.3 < m.height() < 1.9
    c = m.skeleton.canonical
    assert len(c) == 21
    assert np.median(m.joint(c["head"])[:, 2] - m.joint(c["pelvis"])[:, 2]) > 0.3
    assert -0.05 < np.percentile(m.positions[..., 2].min(axis=1), 5) < 0.1
    # Rotations reproduce the positions through the offsets.
    mats = Rotation.from_quat(m.rotations.reshape(-1, 4), scalar_first=True).as_matrix()
    mats = mats.reshape(m.num_frames, m.num_joints, 3, 3)
    offsets = np.array(m.metadata["offsets_m"])
    pos, _ = forward_kinematics(
        m.skeleton.parents, offsets, mats, {0: m.positions[:, 0].astype(np.float64)}
    )
    np.testing.assert_allclose(pos, m.positions, atol=2e-4)


@pytest.mark.parametrize("name", ASF_FILES)
def test_asf_alone_is_a_rest_pose(shared_data: Path, name: str) -> None:
    m = asf_amc.read(shared_data / "cmu/asf_amc" / name)
    assert m.num_frames == 1
    assert any("rest pose" in q for q in m.metadata["quirks"])
    np.testing.assert_allclose(m.rotations[..., 0], 1.0, atol=1e-6)
    assert 1.3 < m.height() < 2.0


def test_bvh_and_amc_of_trial_02_01_agree(shared_data: Path) -> None:
    """cgspeed BVH 02_01 (T-pose dropped) vs the original AMC 02_01.

    The converter keeps every ASF bone except ``thorax`` and ``lwrist``,
    which it collapses to zero length. So the legs, pelvis and spine must
    coincide exactly, and everything above the thorax is displaced by
    exactly the thorax bone (same length every frame)."""
    amc = asf_amc.read(shared_data / "cmu/asf_amc/02_01.amc")
    b = bvh.read(shared_data / "cmu/bvh/02_01.bvh")
    assert amc.num_frames == b.num_frames == 343
    pairs = {
        "root": "Hips",
        "lfemur": "LeftUpLeg",
        "ltibia": "LeftLeg",
        "lfoot": "LeftFoot",
        "ltoes": "LeftToeBase",
        "rfemur": "RightUpLeg",
        "rtibia": "RightLeg",
        "rfoot": "RightFoot",
        "rtoes": "RightToeBase",
        "upperback": "Spine",
        "thorax": "Spine1",
    }
    lower = np.stack([amc.joint(a) - b.joint(v) for a, v in pairs.items()], axis=1)
    assert np.abs(lower).max() < 2e-4
    asf = asf_amc.parse_asf(shared_data / "cmu/asf_amc/02.asf")
    thorax = asf.bones["thorax"].length * CMU_UNIT_M
    for a, v in {
        "upperneck": "Neck1",
        "head": "Head",
        "lhumerus": "LeftArm",
        "rradius": "RightForeArm",
    }.items():
        gap = np.linalg.norm(amc.joint(a) - b.joint(v), axis=-1)
        np.testing.assert_allclose(gap, thorax, atol=5e-4)


def test_find_asf_rules(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / "cmu/asf_amc"
    assert asf_amc.find_asf(src / "02_01.amc").name == "02.asf"
    assert asf_amc.find_asf(src / "103_charleston1.amc").name == "103_charleston.asf"
    # The only ASF in the folder is used whatever its name.
    shutil.copy(src / "09_06.amc", tmp_path / "09_06.amc")
    shutil.copy(src / "09.asf", tmp_path / "rory.asf")
    assert asf_amc.read(tmp_path / "09_06.amc").metadata["asf"].endswith("rory.asf")
    # Two candidates and none matching: a clear error listing what was looked for.
    shutil.copy(src / "02.asf", tmp_path / "other.asf")
    with pytest.raises(FormatError, match=r"'09\.asf' or '09_\*\.asf'.*other\.asf, rory\.asf"):
        asf_amc.read(tmp_path / "09_06.amc")
    m = asf_amc.read(tmp_path / "09_06.amc", asf=tmp_path / "rory.asf")
    assert m.num_frames == 141


def _amc_lines(shared_data: Path, frames: int) -> list[str]:
    lines = (shared_data / "cmu/asf_amc/02_01.amc").read_text().splitlines()
    end = lines.index(str(frames + 1))
    return lines[:end]


def _expect(shared_data: Path, tmp_path: Path, lines: list[str], *needles: str) -> FormatError:
    path = tmp_path / "02_01.amc"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(FormatError) as info:
        asf_amc.read(path, asf=shared_data / "cmu/asf_amc/02.asf")
    return names_all(info.value, path, needles)


def test_amc_errors(shared_data: Path, tmp_path: Path) -> None:
    lines = _amc_lines(shared_data, 5)
    start = lines.index("2")
    gap = lines.copy()
    gap[start] = "3"
    err = _expect(shared_data, tmp_path, gap, "frame number 3 follows 1")
    assert err.line == start + 1
    missing = [ln for i, ln in enumerate(lines) if not (i > start and ln.startswith("lfemur"))]
    _expect(shared_data, tmp_path, missing, "lacks bone(s) lfemur", "frame 1")
    few = [re.sub(r"^(rtibia) .*", r"\1 1 2", ln) for ln in lines]
    _expect(shared_data, tmp_path, few, "expected 1 values for rtibia", "found 2")
    unknown = [ln.replace("ltoes", "ltoez") for ln in lines]
    _expect(shared_data, tmp_path, unknown, "'ltoez' is not in the ASF")
    bad = [ln.replace("lowerback 7.86573", "lowerback seven") for ln in lines]
    err = _expect(shared_data, tmp_path, bad, "'seven'", "lowerback.rx")
    assert err.frame == 0
    header = [ln for ln in lines if not ln.strip().isdigit() and ln.startswith((":", "#"))]
    _expect(shared_data, tmp_path, header, "no frames")


def test_amc_radians_equal_degrees(shared_data: Path, tmp_path: Path) -> None:
    asf = shared_data / "cmu/asf_amc/02.asf"
    lines = _amc_lines(shared_data, 10)
    deg_path = tmp_path / "deg.amc"
    deg_path.write_text("\n".join(lines) + "\n")
    rad = []
    for ln in lines:
        toks = ln.split()
        if ln == ":DEGREES":
            rad.append(":RADIANS")
        elif len(toks) > 1 and not ln.startswith("#"):
            vals = [float(t) for t in toks[1:]]
            conv = (
                vals[:3] + [np.radians(v) for v in vals[3:]]
                if toks[0] == "root"
                else [np.radians(v) for v in vals]
            )
            rad.append(toks[0] + " " + " ".join(str(float(v)) for v in conv))
        else:
            rad.append(ln)
    rad_path = tmp_path / "rad.amc"
    rad_path.write_text("\n".join(rad) + "\n")
    a = asf_amc.read(deg_path, asf=asf)
    b = asf_amc.read(rad_path, asf=asf)
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-5)


def test_asf_errors(shared_data: Path, tmp_path: Path) -> None:
    text = (shared_data / "cmu/asf_amc/02.asf").read_text()
    cases = {
        "dup": (text.replace("name rfemur", "name lfemur"), "duplicate bone name 'lfemur'"),
        "cut": (text[: text.index(":hierarchy") - 40], "not closed by 'end'"),
        "nohier": (text[: text.index(":hierarchy")], "no :hierarchy"),
        "badnum": (text.replace("length 7.59371", "length 7.5x"), "'7.5x'"),
        "unknown": (text.replace("lhumerus lradius", "lhumerus lradiuz"), "unknown bone"),
        "dof": (text.replace("dof rx ry rz", "dof rx ry l", 1), "unsupported DOF 'l'"),
    }
    for key, (bad, needle) in cases.items():
        path = tmp_path / f"{key}.asf"
        path.write_text(bad)
        with pytest.raises(FormatError, match=re.escape(needle)) as info:
            asf_amc.parse_asf(path)
        assert str(path) in str(info.value)

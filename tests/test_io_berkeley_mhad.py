"""Berkeley MHAD skeletons (``SkeletalData/skl_s<SS>_a<AA>_r<RR>.bvh``). The release's terms of
redistribution were not found (tests/data/berkeley_mhad/SOURCES.md), so the tests write a real
CMU motion-capture BVH of the shared corpus in the release's unit (centimetres) under an MHAD
file name. Released files are checked when ``SIMENV_BERKELEY_MHAD`` names a folder of them."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest
from expect import raises_at

import simenv
from simenv.core.errors import FormatError
from simenv.io import UNIT_SCALES, berkeley_mhad, bvh
from simenv.io.loader import detect

CMU_WALK = "cmu/bvh/02_01.bvh"
_NUMBER = re.compile(r"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?|-?\.\d+")


def _in_cm(src: Path, dst: Path) -> Path:
    """``src`` (CMU units) rewritten in centimetres: every OFFSET and the root's three
    position channels (the first three values of each motion line) scaled."""
    k = UNIT_SCALES["cmu"] / UNIT_SCALES["cm"]
    out, motion = [], False
    for line in src.read_text().splitlines():
        s = line.strip()
        if s.upper().startswith("OFFSET"):
            line = "OFFSET " + " ".join(f"{float(v) * k:.6f}" for v in s.split()[1:])
        elif motion and s and s[0] in "-.0123456789":
            v = s.split()
            line = " ".join([f"{float(x) * k:.6f}" for x in v[:3]] + v[3:])
        motion = motion or s.upper().startswith("FRAME TIME")
        out.append(line)
    dst.write_text("\n".join(out) + "\n")
    return dst


def test_names_labels_and_the_release_unit(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / CMU_WALK
    path = _in_cm(src, tmp_path / "skl_s03_a06_r02.bvh")
    assert detect(path)[0] == "berkeley_mhad"
    m = berkeley_mhad.read(path)
    ref = bvh.read(src)  # the CMU file in its own unit: the same motion in metres
    np.testing.assert_allclose(m.positions, ref.positions, atol=2e-4)
    assert m.metadata["units"] == "cm" and "Berkeley MHAD" in m.metadata["units_reason"]
    assert (m.metadata["subject"], m.metadata["action_id"], m.metadata["label"],
            m.metadata["repetition"], m.metadata["format"]) == (
        3, 6, "waving (one hand, right)", 2, "bvh")
    assert any("480 fps" in q for q in m.metadata["quirks"])  # a 120 fps header is noted
    loaded = simenv.load(path)
    assert loaded.metadata["dataset"] == "Berkeley MHAD"
    scaled = berkeley_mhad.read(path, scale=0.011)  # BVH options pass through
    assert scaled.metadata["units"] == "explicit"
    np.testing.assert_allclose(np.ptp(scaled.positions[0], axis=0),
                               1.1 * np.ptp(m.positions[0], axis=0), rtol=1e-3)
    tpose = berkeley_mhad.read(_in_cm(src, tmp_path / "skl_s11_t-pose.bvh"))
    assert tpose.metadata["tpose"] and "label" not in tpose.metadata
    other = _in_cm(src, tmp_path / "skl_s03_a12_r01.bvh")  # no action 12: a plain BVH
    assert detect(other)[0] == "bvh" and "dataset" not in simenv.load(other).metadata


def test_bad_files_are_located(shared_data: Path, tmp_path: Path) -> None:
    path = _in_cm(shared_data / CMU_WALK, tmp_path / "skl_s01_a01_r01.bvh")
    lines = path.read_text().splitlines()
    cut = lines.index("MOTION") + 5
    path.write_text("\n".join(lines[:cut] + [lines[cut].rsplit(" ", 3)[0]] + lines[cut + 1:]))
    e = raises_at(FormatError, "expected 96 channel values", lambda: simenv.load(path),
                  line=cut + 1, frame=2)
    assert Path(str(e.source)).name == path.name
    path.write_text("\n")  # no HIERARCHY: the MHAD reader claims .bvh and hands it on
    raises_at(FormatError, "HIERARCHY", lambda: simenv.load(path))


def _released() -> list[Path]:
    """The first released file of each person in ``SIMENV_BERKELEY_MHAD``."""
    folder = Path(os.environ.get("SIMENV_BERKELEY_MHAD", "/nonexistent"))
    first: dict[str, Path] = {}
    for path in sorted(folder.glob("skl_s*_a*_r*.bvh")):
        first.setdefault(path.name[:7], path)
    return list(first.values())


@pytest.mark.skipif(not _released(),
                    reason="set SIMENV_BERKELEY_MHAD to a folder of released skl_*.bvh files")
def test_released_files() -> None:
    for path in _released():
        m = simenv.load(path)
        assert m.fps == berkeley_mhad.MHAD_FPS and m.skeleton.num_joints == 30
        assert m.metadata["units"] == "cm" and m.metadata["label"]
        canon = m.to_canonical()
        pelvis = float(np.median(canon.joint("pelvis")[:, 2]))
        head = float(np.median(canon.joint("head")[:, 2]))
        assert 0.4 < pelvis < 1.2 and 1.0 < head < 2.0, path.name

"""SBU Kinect Interaction reader: README denormalisation, two people, clips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import FormatError
from simenv.core.motion import Interaction
from simenv.io import sbu

SBU = "other/sbu_kinect_sample"


def test_readme_formula() -> None:
    # README: X = 1280 - x*2560, Y = 960 - y*1920, Z = z*10000/7.8125 (mm).
    np.testing.assert_allclose(sbu.denormalise(np.array([0.5, 0.5, 7.8125])), [0, 0, 10.0])
    np.testing.assert_allclose(sbu.denormalise(np.array([0.0, 1.0, 1.5625])),
                               [1.28, -0.96, 2.0])


def _check_people(inter: Interaction) -> None:
    for m in inter.people:
        sk = m.skeleton
        assert (m.joint("HEAD")[:, 2] > m.joint("TORSO")[:, 2]).all()
        feet = m.positions[:, [sk.index("LEFT_FOOT"), sk.index("RIGHT_FOOT")], 2].min(1)
        assert abs(np.median(feet) - 0.07) < 0.08  # "foot" = ankle, 7 cm clearance
        assert 1.3 < np.median(m.joint("HEAD")[:, 2] - feet) < 1.8
        width = np.linalg.norm(m.joint("LEFT_SHOULDER") - m.joint("RIGHT_SHOULDER"), axis=1)
        assert 0.25 < np.median(width) < 0.40
    gap = np.linalg.norm(inter.actor.joint("TORSO") - inter.reactor.joint("TORSO"), axis=1)
    assert 0.4 < np.median(gap) < 2.5
    # A (left of the image) is at larger Y (the sensor's left) than B.
    assert np.median(inter.actor.joint("TORSO")[:, 1] - inter.reactor.joint("TORSO")[:, 1]) > 0


def test_sample_files(shared_data: Path) -> None:
    one = sbu.read(shared_data / SBU / "skeleton_pos.txt")
    assert isinstance(one, Interaction)
    assert one.num_frames == 21 and one.fps == 15.0
    assert one.metadata["frame_numbers"] == [278, 298]
    assert one.actor.skeleton.name == "sbu15"
    _check_people(one)
    two = sbu.read(shared_data / SBU / "skeleton_pos_2.txt")
    assert isinstance(two, list) and [c.num_frames for c in two] == [29, 17]
    assert [c.metadata["frame_numbers"] for c in two] == [[566, 594], [350, 366]]
    for clip in two:
        _check_people(clip)
        assert clip.metadata["quirks"]
    cf = one.metadata["camera_frame"]
    assert 0.5 < cf["sensor_height_m"] < 2.0 and cf["tilt_deg"] < 20


def test_label_from_dataset_layout(shared_data: Path, tmp_path: Path) -> None:
    folder = tmp_path / "s01s02" / "07" / "001"
    folder.mkdir(parents=True)
    (folder / "skeleton_pos.txt").write_bytes((shared_data / SBU / "skeleton_pos.txt").read_bytes())
    assert sbu.read(folder / "skeleton_pos.txt").label == "shaking hands"


def test_sniff(shared_data: Path) -> None:
    f = shared_data / SBU / "skeleton_pos.txt"
    assert sbu.sniff(f, f.read_bytes()[:4096])
    g = shared_data / "other/nuisi/Rocket_p1.txt"
    assert not sbu.sniff(g, g.read_bytes()[:4096])


@pytest.mark.parametrize("edit, message, line", [
    (lambda ls: ls[:3] + [ls[3].rsplit(",", 1)[0]] + ls[4:], "expected 91 values", 4),
    (lambda ls: ls[:2] + [ls[2].replace(",", ",abc,", 1).replace(",", "", 1)] + ls[3:],
     "expected a finite number", 3),
    (lambda ls: ["", "  "], "empty", None),
])
def test_bad_input(shared_data: Path, tmp_path: Path, edit, message: str, line) -> None:
    lines = (shared_data / SBU / "skeleton_pos.txt").read_text().splitlines()
    bad = tmp_path / "skeleton_pos.txt"
    bad.write_text("\n".join(edit(lines)) + "\n")
    with pytest.raises(FormatError, match=message) as err:
        sbu.read(bad)
    assert err.value.line == line

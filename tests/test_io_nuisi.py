"""NuiSI reader: one file per person, Nuitrack's left-handed frame, dropouts,
and the contact-based placement of the pair."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from expect import rejects_lines

from simenv.core.errors import MotionError
from simenv.core.motion import Interaction, Motion
from simenv.io import nuisi

NUISI = "other/nuisi"


def test_one_person(shared_data: Path) -> None:
    m = nuisi.read(shared_data / NUISI / "Rocket_p1.txt")
    assert isinstance(m, Motion) and m.fps == 30.0
    # 2552 lines, 9 leading dropouts, ~29.4 Hz -> ~86 s at 30 fps.
    assert m.duration == pytest.approx(86.3 - 1.5, abs=1.0)
    assert "JOINT_LEFT_FOOT" not in m.skeleton.joint_names  # never tracked -> dropped
    assert "left_toe" not in m.skeleton.canonical
    assert m.skeleton.num_joints == 20
    assert any("trimmed 9 leading" in r for r in m.metadata["repairs"])
    # Right-handed after negating Nuitrack's x: the person faces the sensor
    # (-X), i.e. left x right shoulder points toward the sensor.
    left, right = m.joint("JOINT_LEFT_SHOULDER"), m.joint("JOINT_RIGHT_SHOULDER")
    facing = np.median(np.cross(left - right, [0, 0, 1]), axis=0)
    assert facing[0] < -0.1
    # ... and the hands reach toward the sensor during the fist bumps.
    assert np.percentile(m.joint("JOINT_RIGHT_HAND")[:, 0] - m.joint("JOINT_TORSO")[:, 0], 5) < -0.2
    ankles = m.positions[:, [m.skeleton.index("JOINT_LEFT_ANKLE"),
                             m.skeleton.index("JOINT_RIGHT_ANKLE")], 2].min(1)
    assert abs(np.median(ankles) - 0.07) < 0.05
    assert 1.4 < m.height() < 1.9
    rows = nuisi.read(shared_data / NUISI / "Rocket_p1.txt", timing="rows")
    assert rows.num_frames == 2543 and rows.fps == pytest.approx(1000 / 34, rel=0.01)


def test_pair(shared_data: Path) -> None:
    inter = nuisi.read_pair(shared_data / NUISI / "Rocket_p1.txt",
                            shared_data / NUISI / "Rocket_p2.txt")
    assert isinstance(inter, Interaction) and inter.label == "Rocket"
    place = inter.metadata["placement"]
    assert 0.5 < place["separation_m"] < 1.5
    assert abs(place["contact_height_mismatch_m"]) < 0.2
    a, b = inter.actor, inter.reactor
    hands = np.linalg.norm(a.joint("JOINT_RIGHT_HAND") - b.joint("JOINT_RIGHT_HAND"), axis=1)
    assert np.percentile(hands, 2) < 0.15  # the fists meet
    # Face to face: A faces +X, B faces -X.
    for m, sign in ((a, 1), (b, -1)):
        f = np.median(np.cross(m.joint("JOINT_LEFT_SHOULDER") - m.joint("JOINT_RIGHT_SHOULDER"),
                               [0, 0, 1]), axis=0)
        assert sign * f[0] > 0.1
    fixed = nuisi.read_pair(shared_data / NUISI / "Rocket_p1.txt",
                            shared_data / NUISI / "Rocket_p2.txt", separation=1.2)
    waist_a, waist_b = fixed.actor.joint("JOINT_WAIST"), fixed.reactor.joint("JOINT_WAIST")
    gap = np.median(waist_b[:, 0] - waist_a[:, 0])
    assert gap == pytest.approx(1.2, abs=0.05)
    assert nuisi.partner_path(shared_data / NUISI / "Rocket_p2.txt").name == "Rocket_p1.txt"


def test_sniff(shared_data: Path) -> None:
    f = shared_data / NUISI / "Rocket_p2.txt"
    assert nuisi.sniff(f, f.read_bytes()[:4096])


def _lines(shared_data: Path) -> list[str]:
    return (shared_data / NUISI / "Rocket_p1.txt").read_text().splitlines()[:40]


@pytest.mark.parametrize("edit, message, line", [
    (lambda ls: ls[:12] + [ls[12].rsplit(",", 8)[0]] + ls[13:], "expected 3 or 203", 13),
    (lambda ls: ls[:12] + ["12,1693077908999,25"] + ls[13:], "n_joints is 25 with 3 values", 13),
    (lambda ls: ls[:15] + [ls[15].replace(",25,0,", ",25,3,", 1)] + ls[16:], "joint id 3", 16),
    (lambda ls: ls[:20] + [ls[20].replace(",", ",x", 5).replace(",x", ",", 4)] + ls[21:],
     "expected a finite number", 21),
])
def test_bad_input(shared_data: Path, tmp_path: Path, edit, message: str, line: int) -> None:
    rejects_lines(nuisi.read, tmp_path / "Bad_p1.txt", edit(_lines(shared_data)), message, line)


def test_no_skeleton_at_all(tmp_path: Path) -> None:
    bad = tmp_path / "Empty_p1.txt"
    bad.write_text("0,1693077907064,0\n1,1693077908292,0\n")
    with pytest.raises(MotionError, match="no line holds a skeleton"):
        nuisi.read(bad)

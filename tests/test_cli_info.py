"""``simenv info``'s text: quirks that repeat one explanation per joint are printed once, and
a pair's repairs once, on the bundled real CMU handshake pair (18_01 + 19_01)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from simenv.assets import HANDSHAKE_PAIR, asset_path
from simenv.cli import main as cli
from simenv.cli.info import MIN_SHARED_QUIRK


def test_info_prints_each_quirk_once(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["info", str(asset_path(HANDSHAKE_PAIR)), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert cli.main(["info", str(asset_path(HANDSHAKE_PAIR))]) == 0
    text = capsys.readouterr().out
    notes = info["quirks"] + [q for p in info["persons"] for q in p["quirks"]]
    # Every quirk the JSON lists appears in the text, whole or split in a group's lines
    # (the ", " it is split at left out).
    words = {w.rstrip(",") for w in text.split()}
    for note in notes:
        assert {w.rstrip(",") for w in note.split()} <= words, note
    for person in info["persons"]:
        # The collapsed-bone quirks (one per joint, one explanation): the explanation once,
        # each joint's own part on its own line.
        collapsed = [q for q in person["quirks"] if "a bone the converter collapsed" in q]
        assert len(collapsed) == 3
        shared = collapsed[0][collapsed[0].index("a bone the converter collapsed"):]
        assert len(shared) >= MIN_SHARED_QUIRK
        assert f"quirk, 3 alike: {shared}\n" in text
        for note in collapsed:
            assert f"\n      {note[:-len(shared) - 2]}\n" in text
    # The explanation: once per person, not once per joint.
    assert text.count("a bone the converter collapsed") == len(info["persons"])
    # A pair-level repair (18_01 re-timed, 19_01's T-pose dropped) is printed once.
    for note in info["quirks"]:
        assert text.count(note.split(": ", 1)[1]) == 1, note


FAIR_DAB = Path(__file__).parent / "data" / "conventions" / "other" / "fair1_dab_zup.bvh"


def _person(capsys: pytest.CaptureFixture[str], *options: str) -> dict:
    assert cli.main(["info", str(FAIR_DAB), "--json", *options]) == 0
    (person,) = json.loads(capsys.readouterr().out)["persons"]
    return person


def test_units_and_scale_options_override_the_detected_unit(
        capsys: pytest.CaptureFixture[str]) -> None:
    """The real FAIR capture reads as inches; --units / --scale say what the file holds
    instead (a rig in no known unit loads with --scale)."""
    auto = _person(capsys)
    assert auto["units_in_file"] == "inch"
    cm = _person(capsys, "--units", "cm")
    assert cm["units_in_file"] == "cm"
    # height_m is rounded to the millimetre
    assert cm["height_m"] == pytest.approx(auto["height_m"] * 0.01 / 0.0254, abs=1e-3)
    assert _person(capsys, "--scale", "0.0254")["height_m"] == pytest.approx(auto["height_m"])


def test_units_for_a_reader_without_them_is_a_clear_error(
        capsys: pytest.CaptureFixture[str], shared_data: Path) -> None:
    kinect = shared_data / "gestures" / "utkinect" / "joints" / "joints_s01_e01.txt"
    assert cli.main(["info", str(kinect), "--units", "cm"]) == 2
    err = capsys.readouterr().err
    assert "field 'units': the utkinect reader does not take units" in err

"""``simenv info``'s text: quirks that repeat one explanation per joint are printed once, and
a pair's repairs once, on the bundled real CMU handshake pair (18_01 + 19_01)."""

from __future__ import annotations

import json

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

"""simenv NPZ: exact round trips of real motions and pairs, and bad archives."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import simenv
from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Interaction, Motion
from simenv.io import asf_amc, bvh
from simenv.io.npz import VERSION, read, write_npz


def _same_motion(a: Motion, b: Motion) -> None:
    assert a.positions.dtype == b.positions.dtype == np.float32
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.fps == b.fps and a.name == b.name
    assert a.skeleton == b.skeleton
    assert json.loads(json.dumps(a.metadata)) == b.metadata
    if a.rotations is None:
        assert b.rotations is None
    else:
        np.testing.assert_array_equal(a.rotations, b.rotations)


def test_motion_round_trip_is_exact(shared_data: Path, tmp_path: Path) -> None:
    for m in (
        bvh.read(shared_data / "cmu/bvh/12_01.bvh"),
        asf_amc.read(shared_data / "cmu/asf_amc/09_06.amc"),
    ):
        out = write_npz(m, tmp_path / f"{m.name}.npz")
        back = read(out)
        _same_motion(m, back)
        _same_motion(m, simenv.load(out))
    no_rot = bvh.read(shared_data / "cmu/bvh/35_17.bvh").with_positions(
        bvh.read(shared_data / "cmu/bvh/35_17.bvh").positions
    )
    _same_motion(no_rot, read(write_npz(no_rot, tmp_path / "plain.data")))


def test_interaction_round_trip_is_exact(shared_data: Path, tmp_path: Path) -> None:
    pair = simenv.load(shared_data / "cmu/two_person/18_19_walk_shake_hands")
    assert isinstance(pair, Interaction)
    back = read(write_npz(pair, tmp_path / "pair.npz"))
    assert isinstance(back, Interaction)
    _same_motion(pair.actor, back.actor)
    _same_motion(pair.reactor, back.reactor)
    assert (back.label, back.roles_known, back.name) == (pair.label, pair.roles_known, pair.name)
    assert back.metadata == json.loads(json.dumps(pair.metadata))
    assert any("re-timed to 120 fps" in q for q in back.actor.metadata["quirks"])


def _rewrite(src: Path, dst: Path, **changes: object) -> Path:
    with np.load(src) as data:
        arrays = {k: data[k] for k in data.files}
    for k, v in changes.items():
        if v is None:
            arrays.pop(k)
        else:
            arrays[k] = np.asarray(v)
    with dst.open("wb") as fh:
        np.savez(fh, **arrays)
    return dst


def test_bad_archives(shared_data: Path, tmp_path: Path) -> None:
    m = bvh.read(shared_data / "cmu/bvh/35_17.bvh")
    good = write_npz(m, tmp_path / "good.npz")
    cases = {
        "noversion": ({"simenv_npz_version": None}, FormatError, "no 'simenv_npz_version'"),
        "version": ({"simenv_npz_version": VERSION + 1}, FormatError, "unsupported"),
        "nokey": ({"parents": None}, FormatError, "lacks key 'parents'"),
        "json": ({"metadata": "{not json"}, FormatError, "invalid JSON"),
        "kind": ({"kind": "dance"}, FormatError, "unknown kind"),
        "nan": ({"positions": np.full_like(m.positions, np.nan)}, MotionError, "non-finite"),
        "shape": ({"positions": m.positions[:, :5]}, MotionError, "joints"),
    }
    for key, (changes, err, needle) in cases.items():
        path = _rewrite(good, tmp_path / f"{key}.npz", **changes)
        with pytest.raises(err, match=needle) as info:
            read(path)
        assert str(path) in str(info.value)
    junk = tmp_path / "junk.npz"
    junk.write_bytes(good.read_bytes()[:500])
    with pytest.raises(FormatError, match="junk.npz"):
        simenv.load(junk)
    single = tmp_path / "single.npy"
    np.save(single, m.positions)
    with pytest.raises(FormatError, match="single array"):
        read(single)

"""Property-based fuzzing of the BVH, ASF/AMC and NPZ readers with mutated
real files: each either returns a valid Motion or raises a SimenvError."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from simenv.core.errors import SimenvError
from simenv.core.motion import Interaction, Motion
from simenv.io import asf_amc, bvh, npz
from simenv.io.loader import load

GARBAGE = [
    "nan",
    "inf",
    "-inf",
    "1e999",
    "abc",
    "-",
    ".",
    "1.2.3",
    "0x1F",
    "",
    "१२",
    "²",
    "{",
    "}",
    "JOINT",
    "End",
    "1e-320",
    "-0",
    "99999999999",
    "ROOT",
    ":DEGREES",
    "\x00",
]
SETTINGS = settings(
    max_examples=50,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


def _bvh_head(rel: str, frames: int = 40) -> str:
    text = (SHARED_DATA / rel).read_text()
    head, _, data = text.partition("Frame Time:")
    lines = data.splitlines()
    head = re.sub(r"Frames:\s*\d+", f"Frames: {frames}", head)
    return head + "Frame Time:" + "\n".join(lines[: frames + 1]) + "\n"


def _amc_head(frames: int = 40) -> str:
    lines = (SHARED_DATA / "cmu/asf_amc/02_01.amc").read_text().splitlines()
    return "\n".join(lines[: lines.index(str(frames + 1))]) + "\n"


@st.composite
def mutated(draw: st.DrawFn, text: str) -> bytes:
    """A real file with 1-4 random mutations: truncation, deleted, repeated or
    swapped lines, tokens replaced by garbage, duplicated names, raw bytes."""
    lines = text.splitlines()
    for _ in range(draw(st.integers(1, 4))):
        op = draw(
            st.sampled_from(
                ["truncate", "delete", "repeat", "swap", "token", "name", "bytes", "frames"]
            )
        )
        n = len(lines)
        i = draw(st.integers(0, max(n - 1, 0)))
        if op == "truncate":
            joined = "\n".join(lines)
            lines = joined[: draw(st.integers(0, len(joined)))].split("\n")
        elif op == "delete" and n:
            del lines[i : i + draw(st.integers(1, 5))]
        elif op == "repeat" and n:
            lines.insert(i, lines[i])
        elif op == "swap" and n:
            j = draw(st.integers(0, n - 1))
            lines[i], lines[j] = lines[j], lines[i]
        elif op == "token" and n:
            toks = lines[i].split()
            if toks:
                k = draw(st.integers(0, len(toks) - 1))
                toks[k] = draw(st.sampled_from(GARBAGE))
                lines[i] = " ".join(toks)
        elif op == "name":
            names = re.findall(r"(?:JOINT|name)\s+(\S+)", text)
            if len(names) > 1:
                a, b = draw(st.sampled_from(names)), draw(st.sampled_from(names))
                lines = "\n".join(lines).replace(f" {a}\n", f" {b}\n", 1).split("\n")
        elif op == "bytes" and n:
            junk = draw(st.binary(min_size=1, max_size=8)).decode("latin-1")
            pos = draw(st.integers(0, len(lines[i])))
            lines[i] = lines[i][:pos] + junk + lines[i][pos:]
        elif op == "frames":
            lines = [
                re.sub(r"Frames:\s*\d+", f"Frames: {draw(st.integers(0, 60))}", ln) for ln in lines
            ]
    newline = draw(st.sampled_from(["\n", "\r\n"]))
    return newline.join(lines).encode("utf-8", errors="replace")


def _check(result: object) -> None:
    assert isinstance(result, (Motion, Interaction))
    people = result.people if isinstance(result, Interaction) else (result,)
    for m in people:
        assert np.isfinite(m.positions).all() and m.num_frames >= 1


BVH_SOURCES = [
    "cmu/bvh/02_01.bvh",
    "cmu/bvh/131_01.bvh",
    "cmu/two_person/60_61_salsa_10/60_10_scaled.bvh",
]


def _survives_mutations(base: str, path: Path, read: Callable[[], object],
                        named: tuple[Path, ...] = ()) -> None:
    """``read()`` of ``path`` written with mutations of ``base`` returns a valid motion
    or raises a SimenvError naming ``path`` (or one of ``named``)."""

    @SETTINGS
    @given(data=mutated(base))
    def run(data: bytes) -> None:
        path.write_bytes(data)
        try:
            _check(read())
        except SimenvError as exc:
            assert any(str(p) in str(exc) for p in (path, *named))

    run()


@pytest.mark.parametrize("rel", BVH_SOURCES)
def test_bvh_reader_survives_mutations(shared_data: Path, tmp_path: Path, rel: str) -> None:
    path = tmp_path / "fuzz.bvh"
    _survives_mutations(_bvh_head(rel), path, lambda: bvh.read(path))


def test_amc_reader_survives_mutations(shared_data: Path, tmp_path: Path) -> None:
    asf = shared_data / "cmu/asf_amc/02.asf"
    path = tmp_path / "02_01.amc"
    _survives_mutations(_amc_head(), path, lambda: asf_amc.read(path, asf=asf))


def test_asf_parser_survives_mutations(shared_data: Path, tmp_path: Path) -> None:
    amc = tmp_path / "02_01.amc"
    amc.write_text(_amc_head(5))
    path = tmp_path / "02.asf"
    _survives_mutations((shared_data / "cmu/asf_amc/02.asf").read_text(), path,
                        lambda: asf_amc.read(amc, asf=path), named=(amc,))


def test_npz_reader_survives_byte_damage(shared_data: Path, tmp_path: Path) -> None:
    m = bvh.read(shared_data / "cmu/bvh/35_17.bvh").slice(0, 20)
    good = npz.write_npz(m, tmp_path / "good.npz").read_bytes()

    @SETTINGS
    @given(
        cut=st.integers(0, len(good)),
        flips=st.lists(st.tuples(st.integers(0, len(good) - 1), st.integers(1, 255)), max_size=6),
    )
    def run(cut: int, flips: list[tuple[int, int]]) -> None:
        data = bytearray(good)
        for pos, x in flips:
            data[pos] ^= x
        path = tmp_path / "fuzz.npz"
        path.write_bytes(bytes(data[: max(cut, 1)] if flips == [] else data))
        try:
            _check(load(path))
        except SimenvError as exc:
            assert str(path) in str(exc)

    run()

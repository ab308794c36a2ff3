"""Property-based fuzzing of the Kinect-era and array readers: mutated real
files either load or raise a simenv error, never anything else."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from simenv.core.errors import SimenvError
from simenv.io import florence3d, h36m, msr_action3d, ntu, nuisi, sbu, utkinect

FUZZ = settings(max_examples=int(os.environ.get("SIMENV_FUZZ_EXAMPLES", "60")), deadline=None,
                            suppress_health_check=[HealthCheck.function_scoped_fixture])


@st.composite
def text_mutation(draw: st.DrawFn, text: str) -> str:
    lines = text.splitlines()
    kind = draw(st.sampled_from(["drop", "dup", "token", "truncate", "bytes", "blank"]))
    i = draw(st.integers(0, max(len(lines) - 1, 0)))
    if kind == "drop" and lines:
        del lines[i]
    elif kind == "dup" and lines:
        lines.insert(i, lines[i])
    elif kind == "token" and lines:
        sep = "," if "," in lines[i] else " "
        toks = lines[i].split(sep)
        k = draw(st.integers(0, len(toks) - 1))
        toks[k] = draw(st.sampled_from(["", "nan", "inf", "-", "1e999", "0x1F", "é", "12 34",
                                        "-0", "1,2", "999999999999", "abc"]))
        lines[i] = sep.join(toks)
    elif kind == "truncate":
        return text[: draw(st.integers(0, len(text)))]
    elif kind == "bytes":
        chars = list(text)
        for _ in range(draw(st.integers(1, 8))):
            j = draw(st.integers(0, max(len(chars) - 1, 0)))
            if chars:
                chars[j] = draw(st.sampled_from(list("0123456789.,- \n\tx\x00")))
        return "".join(chars)
    elif kind == "blank":
        lines.insert(i, "")
    return "\n".join(lines) + "\n"


def _check(read: Callable[[Path], object], path: Path) -> None:
    try:
        read(path)
    except SimenvError:
        pass


def _seed_text(shared_data: Path, rel: str, n_lines: int) -> str:
    return "\n".join((shared_data / rel).read_text().splitlines()[:n_lines]) + "\n"


CASES = {
    "msr": ("gestures/msr_action3d/a01_s01_e02_skeleton3D.txt", 200, "a01_s01_e02.txt",
            msr_action3d.read),
    "utk": ("gestures/utkinect/joints/joints_s01_e01.txt", 40, "joints_s01_e01.txt",
            lambda p: utkinect.read(p, labels=False)),
    "sbu": ("other/sbu_kinect_sample/skeleton_pos.txt", 21, "skeleton_pos.txt", sbu.read),
    "nuisi": ("other/nuisi/Rocket_p1.txt", 40, "Rocket_p1.txt", nuisi.read),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_mutated_text_files(shared_data: Path, tmp_path: Path, case: str) -> None:
    rel, n, name, read = CASES[case]
    seed = _seed_text(shared_data, rel, n)
    read_ok = read  # the unmutated seed must load

    path = tmp_path / name
    path.write_text(seed)
    read_ok(path)

    @FUZZ
    @given(text=text_mutation(seed))
    def run(text: str) -> None:
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        _check(read, path)

    run()


def test_mutated_ntu(shared_data: Path, tmp_path: Path) -> None:
    raw = np.loadtxt(shared_data / "gestures/msr_action3d/a05_s03_e01_skeleton3D.txt")
    cam = raw.reshape(-1, 20, 4)[:4, msr_action3d.MSR_TO_SDK, :3]
    # Pad to 25 joints with measured joints (hands for tips/thumbs, head for neck).
    v2 = np.concatenate([cam, cam[:, [7, 11, 7, 11, 3]]], axis=1)
    seed_path = tmp_path / "seed.skeleton"
    ntu.write(seed_path, [v2])
    seed = seed_path.read_text()
    path = tmp_path / "fuzz.skeleton"

    @FUZZ
    @given(text=text_mutation(seed))
    def run(text: str) -> None:
        path.write_text(text)
        _check(ntu.read, path)

    run()


MAT_FUZZ = settings(FUZZ, max_examples=max(1, FUZZ.max_examples // 4))


def test_mutated_binary_files(shared_data: Path, tmp_path: Path) -> None:
    """Includes corruptions that segfault scipy's MAT parser (isolated in a
    child process by the reader); fewer examples as each spawns a process."""
    videos = scipy.io.loadmat(shared_data / "gestures/florence3d/skeletal_data.mat")
    small = tmp_path / "small.mat"
    scipy.io.savemat(small, {"skeletal_data": videos["skeletal_data"][:3]})
    mat_seed = small.read_bytes()
    npy = tmp_path / "seed.npy"
    np.save(npy, np.random.default_rng(0).normal(size=(5, 17, 3)).astype(np.float32))
    npy_seed = npy.read_bytes()
    target_mat, target_npy = tmp_path / "fuzz.mat", tmp_path / "fuzz.npy"

    @MAT_FUZZ
    @given(data=st.data())
    def run(data: st.DataObject) -> None:
        for seed, target, read in ((mat_seed, target_mat, florence3d.read),
                                   (npy_seed, target_npy, h36m.read)):
            buf = bytearray(seed)
            if data.draw(st.booleans()):
                buf = buf[: data.draw(st.integers(0, len(buf)))]
            for _ in range(data.draw(st.integers(0, 6))):
                if buf:
                    buf[data.draw(st.integers(0, len(buf) - 1))] = data.draw(st.integers(0, 255))
            target.write_bytes(bytes(buf))
            _check(read, target)

    run()

"""simenv.load: format detection, folders, two-person CMU pairs and their quirks."""

from __future__ import annotations

import importlib
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA

import simenv
from simenv.core.errors import FormatError, MotionError, UnknownFormatError
from simenv.core.motion import Interaction, Motion
from simenv.io import loader

DOCS = {".md", ".tsv", ".csv", ".md5"}
#: Companion files of the gesture sets (class names, label lists), not motion.
AUX = {
    "README.txt",
    "action_names.mat",
    "files_used_in_cvpr12_paper.txt",
    "actionLabel.txt",
    "actionLabel_modified.txt",
}
CMU_FILES = sorted(
    str(p.relative_to(SHARED_DATA))
    for p in SHARED_DATA.glob("cmu/**/*")
    if p.is_file() and p.suffix.lower() not in DOCS
)
OTHER_FILES = sorted(
    str(p.relative_to(SHARED_DATA))
    for folder in ("gestures", "other")
    for p in SHARED_DATA.glob(f"{folder}/**/*")
    if p.is_file() and p.suffix.lower() not in DOCS and p.name not in AUX
)
HANDSHAKE = "cmu/two_person/18_19_walk_shake_hands"


@pytest.mark.parametrize("rel", CMU_FILES)
def test_every_cmu_file_loads(shared_data: Path, rel: str) -> None:
    loaded = simenv.load(shared_data / rel)
    assert isinstance(loaded, Motion)
    assert loaded.metadata["source"] == str(shared_data / rel)
    assert loaded.fps == pytest.approx(120.0 if "18_01" not in rel else 30.0)


@pytest.mark.parametrize("rel", OTHER_FILES)
def test_other_real_files_are_detected(shared_data: Path, rel: str) -> None:
    try:
        name, _ = loader.detect(shared_data / rel)
    except UnknownFormatError as exc:
        missing = sorted(set(loader.READERS) - set(loader.available_readers()))
        if missing:
            pytest.skip(f"reader module(s) {', '.join(missing)} not present yet: {exc}")
        raise
    assert name in loader.available_readers()


def _check_handshake(pair: Interaction) -> None:
    assert pair.label == "shake_hands" and pair.roles_known
    assert (pair.actor.name, pair.reactor.name) == ("18_01", "19_01")
    assert pair.fps == 120.0 and pair.num_frames == 303
    assert pair.actor.num_frames == pair.reactor.num_frames
    fix = [q for q in pair.metadata["quirks"] if "re-timed to 120 fps" in q]
    assert len(fix) == 1 and "header says 30 fps" in fix[0] and "T-pose" in fix[0]
    assert fix[0] in pair.actor.metadata["quirks"]
    assert any(q.startswith("19_01: dropped T-pose") for q in pair.metadata["quirks"])
    # SOURCES.md: the pelvises come within ~0.75 m around frames 100-150 (the handshake).
    gap = np.linalg.norm(pair.actor.joint("hip")[:, :2] - pair.reactor.joint("Hips")[:, :2], axis=1)
    assert 90 <= int(gap.argmin()) <= 160 and 0.6 < gap.min() < 0.9


def test_handshake_pair_from_folder_and_from_paths(shared_data: Path) -> None:
    folder = shared_data / HANDSHAKE
    _check_handshake(simenv.load(folder))
    b, a = sorted(folder.glob("*.bvh"), reverse=True)
    _check_handshake(simenv.load([b, a]))
    _check_handshake(simenv.io.load([str(a), str(b)]))


@pytest.mark.parametrize("take", ["05", "10"])
def test_salsa_pairs(shared_data: Path, take: str) -> None:
    pair = simenv.load(shared_data / f"cmu/two_person/60_61_salsa_{take}")
    assert isinstance(pair, Interaction)
    assert pair.label == "salsa" and pair.roles_known
    assert pair.actor.name.startswith("60_") and pair.reactor.name.startswith("61_")
    assert pair.actor.num_frames == pair.reactor.num_frames == {"05": 1678, "10": 1197}[take]
    assert pair.metadata["quirks"] == []
    pelvis = np.linalg.norm(pair.actor.joint("hip") - pair.reactor.joint("hip"), axis=1)
    assert 0.3 < np.median(pelvis) < 1.5


def test_pair_without_evidence_is_refused(shared_data: Path, tmp_path: Path) -> None:
    folder = shared_data / HANDSHAKE
    with pytest.raises(MotionError, match="nothing shows which is right"):
        simenv.load([folder / "18_01.bvh", folder / "19_01.bvh"], drop_tpose=False)
    # Same files under non-CMU names: no capture-rate knowledge, no repair.
    shutil.copy(folder / "18_01.bvh", tmp_path / "alice.bvh")
    shutil.copy(folder / "19_01.bvh", tmp_path / "bob.bvh")
    with pytest.raises(MotionError, match="30 fps.*120 fps"):
        simenv.load([tmp_path / "alice.bvh", tmp_path / "bob.bvh"])
    with pytest.raises(MotionError, match="two people"):
        simenv.load([folder / "18_01.bvh"])


def test_folders_with_many_clips_give_lists(shared_data: Path, tmp_path: Path) -> None:
    # Same take number but not a CMU pair (subjects 02 and 12): two separate clips.
    for name in ("02_01.bvh", "12_01.bvh"):
        shutil.copy(shared_data / "cmu/bvh" / name, tmp_path / name)
    two = simenv.load(tmp_path)
    assert isinstance(two, list) and [m.name for m in two] == ["02_01", "12_01"]
    clips = simenv.load(shared_data / "cmu/asf_amc")
    assert isinstance(clips, list)
    assert sorted(m.name for m in clips) == sorted(
        p.stem for p in (shared_data / "cmu/asf_amc").glob("*.amc")
    )


def test_detection_by_content_and_kwargs(shared_data: Path, tmp_path: Path) -> None:
    renamed = tmp_path / "clip.txt"
    shutil.copy(shared_data / "cmu/bvh/35_17.bvh", renamed)
    assert loader.detect(renamed)[0] == "bvh"
    m = simenv.load(renamed, drop_tpose=False, units="cmu")
    assert m.num_frames == 168 and m.metadata["units_reason"].startswith("units='cmu'")
    with pytest.raises(TypeError, match="does not take colour.*drop_tpose"):
        simenv.load(renamed, colour="red")


def test_unknown_and_broken_files(shared_data: Path, tmp_path: Path) -> None:
    notes = tmp_path / "notes.xyz"
    notes.write_text("just some words\nnothing to see\n")
    with pytest.raises(UnknownFormatError, match=r"notes\.xyz.*tried bvh, asf_amc, npz"):
        simenv.load(notes)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(UnknownFormatError, match="no file any reader recognises"):
        simenv.load(empty)
    # A damaged .bvh is read by the BVH reader (claimed by extension) for a located error.
    broken = tmp_path / "broken.bvh"
    broken.write_text("HIERARCH\nROOT Hips\n")
    with pytest.raises(FormatError, match="line 1.*HIERARCHY"):
        simenv.load(broken)


def test_registry_skips_absent_modules_only(
    monkeypatch: pytest.MonkeyPatch, shared_data: Path
) -> None:
    monkeypatch.setattr(loader, "READERS", ("not_written_yet", *loader.READERS))
    assert "not_written_yet" not in loader.available_readers()
    assert loader.detect(shared_data / "cmu/bvh/35_17.bvh")[0] == "bvh"
    real_import = importlib.import_module

    def broken_import(name: str, *args: object) -> object:
        if name == "simenv.io.not_written_yet":
            raise ModuleNotFoundError("No module named 'lib_it_needs'", name="lib_it_needs")
        return real_import(name, *args)

    monkeypatch.setattr(importlib, "import_module", broken_import)
    with pytest.raises(ModuleNotFoundError, match="lib_it_needs"):
        loader.available_readers()


def test_nuisi_pair_uses_its_format_pairing(shared_data: Path, tmp_path: Path) -> None:
    folder = shared_data / "other" / "nuisi"
    from_folder = simenv.load(folder)
    from_paths = simenv.load([folder / "Rocket_p1.txt", folder / "Rocket_p2.txt"])
    for inter in (from_folder, from_paths):
        assert isinstance(inter, Interaction)
        assert inter.actor.num_frames == inter.reactor.num_frames > 2000
        # The two sensors share no world frame: the pairing places the people apart.
        a, b = inter.actor.positions, inter.reactor.positions
        gap = np.linalg.norm(a[:, 0, :2] - b[:, 0, :2], axis=1)
        assert 0.3 < float(np.median(gap)) < 2.5
    (tmp_path / "Rocket_p1.txt").write_bytes((folder / "Rocket_p1.txt").read_bytes())
    (tmp_path / "Other_p2.txt").write_bytes((folder / "Rocket_p2.txt").read_bytes())
    with pytest.raises(MotionError, match="not the partner"):
        simenv.load([tmp_path / "Rocket_p1.txt", tmp_path / "Other_p2.txt"])

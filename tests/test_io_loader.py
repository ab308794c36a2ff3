"""simenv.load: format detection, folders, two-person CMU pairs and their quirks."""

from __future__ import annotations

import importlib
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA

import simenv
from simenv.assets import HANDSHAKE_PAIR, WALK, asset_path
from simenv.core.errors import FormatError, MotionError, UnknownFormatError
from simenv.core.motion import Interaction, Motion
from simenv.io import loader
from simenv.io.humanml3d import to_smpl22, write_humanml3d, write_mdm_results
from simenv.io.intergen import write_intergen
from simenv.io.npz import write_npz

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


# -- round trips: what simenv writes, simenv reads back, from the file and from its folder ----

Clip = Motion | Interaction


@pytest.fixture(scope="module")
def walk() -> Motion:
    """The bundled real CMU 02_01 walk, as read (120 fps, CMU skeleton)."""
    return simenv.load(asset_path(WALK))


@pytest.fixture(scope="module")
def handshake() -> Interaction:
    """The bundled real CMU 18_01 + 19_01 handshake pair, as read (120 fps)."""
    return simenv.load(asset_path(HANDSHAKE_PAIR))


def _smpl(motion: Motion, fps: float) -> Motion:
    """What the SMPL-22 writers store: the motion on SMPL-22 at their frame rate."""
    return to_smpl22(motion.resample(fps))


def _pair(pair: Interaction, fps: float) -> Interaction:
    return Interaction(*(_smpl(m, fps) for m in pair.people), name=pair.name)


#: What a writer wrote into a folder: each file with the clips it holds, and the clips of
#: the folder in the order simenv.load gives them (file names, sorted).
Written = tuple[dict[Path, list[Clip]], list[Clip]]


def _write_npz(folder: Path, walk: Motion, handshake: Interaction) -> Written:
    files = {write_npz(walk, folder / "walk.npz"): [walk],
             write_npz(handshake, folder / "pair.npz"): [handshake]}
    return files, [handshake, walk]


def _write_humanml3d(folder: Path, walk: Motion, handshake: Interaction) -> Written:
    clip = _smpl(walk, 20.0)
    return {write_humanml3d(walk, folder / "walk.npy", resample=True): [clip]}, [clip]


def _write_mdm(folder: Path, walk: Motion, handshake: Interaction) -> Written:
    clips = [_smpl(walk, 20.0), _smpl(walk, 20.0).slice(10, 40)]
    return {write_mdm_results(clips, folder / "results.npy"): clips}, clips


def _write_intergen(folder: Path, walk: Motion, handshake: Interaction) -> Written:
    pair = _pair(handshake, 30.0)
    # Each person's file reads with its partner, as the pair.
    return dict.fromkeys(write_intergen(handshake, folder, resample=True), [pair]), [pair]


def _write_intergen_two(folder: Path, walk: Motion, handshake: Interaction) -> Written:
    first, second = handshake.slice(0, 120), handshake.slice(120, 303)
    pairs = [_pair(first, 30.0), _pair(second, 30.0)]
    files = {**dict.fromkeys(write_intergen(first, folder, "a", resample=True), pairs[:1]),
             **dict.fromkeys(write_intergen(second, folder, "b", resample=True), pairs[1:])}
    return files, pairs


WRITERS: dict[str, Callable[[Path, Motion, Interaction], Written]] = {
    "npz": _write_npz,
    "humanml3d": _write_humanml3d,
    "mdm_results": _write_mdm,
    "intergen": _write_intergen,
    "intergen_two_clips": _write_intergen_two,
}


def _clips(loaded: object) -> list[Clip]:
    return list(loaded) if isinstance(loaded, list) else [loaded]  # type: ignore[list-item]


def _same(got: list[Clip], ref: list[Clip]) -> None:
    """Same clips: kinds, people, frame rates, joints and positions (float32: 1e-5 m)."""
    assert [type(c) for c in got] == [type(c) for c in ref]
    for g_clip, r_clip in zip(got, ref, strict=True):
        g_people = g_clip.people if isinstance(g_clip, Interaction) else (g_clip,)
        r_people = r_clip.people if isinstance(r_clip, Interaction) else (r_clip,)
        for g, r in zip(g_people, r_people, strict=True):
            assert g.fps == r.fps and g.skeleton.joint_names == r.skeleton.joint_names
            np.testing.assert_allclose(g.positions, r.positions, atol=1e-5)


@pytest.mark.parametrize("writer", sorted(WRITERS))
def test_what_simenv_writes_loads_back(writer: str, walk: Motion, handshake: Interaction,
                                       tmp_path: Path) -> None:
    folder = tmp_path / "written" / writer  # nested and absent: every writer creates it
    files, clips = WRITERS[writer](folder, walk, handshake)
    for path, held in files.items():
        _same(_clips(simenv.load(path)), held)
    # The folder: one recording loads as that clip (the InterGen pair as its Interaction,
    # as a CMU pair folder does), anything else as the list of its clips.
    loaded = simenv.load(folder)
    assert isinstance(loaded, Interaction) if writer == "intergen" else isinstance(loaded, list)
    _same(_clips(loaded), clips)


def test_intergen_folder_with_loose_files_and_a_lone_person(handshake: Interaction, walk: Motion,
                                                            tmp_path: Path) -> None:
    pair = _pair(handshake, 30.0)
    p1, p2 = write_intergen(pair, tmp_path / "ig", "0")
    # Options reach the folder's reader; ones it does not take are named.
    assert simenv.load(tmp_path / "ig", fps=60.0).fps == 60.0
    with pytest.raises(TypeError, match="does not take drop_tpose"):
        simenv.load(tmp_path / "ig", drop_tpose=False)
    # InterGen subfolders and a loose file: every clip, in a list.
    write_npz(walk, tmp_path / "ig" / "walk.npz")
    _same(simenv.load(tmp_path / "ig"), [pair, walk])
    # A clip written for one person only reads as that person, with a note.
    shutil.copy(p2, p2.with_name("1.npy"))
    lone = [c for c in simenv.load(tmp_path / "ig") if c.name == "1_person2"]
    assert len(lone) == 1 and "not found" in lone[0].metadata["quirks"][-1]
    _same(lone, [pair.reactor])

"""Batch scoring (simenv.plausibility.batch): walking folders, incremental JSONL, workers, Ray."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from simenv.assets import HANDSHAKE_PAIR, WALK, asset_path
from simenv.core.errors import SimenvError
from simenv.io.loader import load
from simenv.io.npz import write_npz
from simenv.plausibility.batch import (
    ScoreJob,
    done_files,
    find_targets,
    index_entries,
    score_batch,
    score_target,
)

FAST = ScoreJob(physics=False)


@pytest.fixture()
def corpus(tmp_path: Path) -> Path:
    """A folder tree of real clips: one walk, one two-person pair folder, one broken file."""
    root = tmp_path / "clips"
    (root / "nested").mkdir(parents=True)
    shutil.copy(asset_path(WALK), root / "walk.bvh")
    shutil.copytree(asset_path(HANDSHAKE_PAIR), root / "nested" / "pair")
    text = Path(asset_path(WALK)).read_text().splitlines()
    (root / "nested" / "broken.bvh").write_text("\n".join(text[:-5] + ["1.0 2.0 oops"]))
    return root


def test_find_targets_walks_folders_and_keeps_pairs_whole(corpus):
    targets = find_targets([corpus])
    names = [t.name for t in targets]
    assert names == ["walk.bvh", "broken.bvh", "pair"]
    assert find_targets([corpus / "walk.bvh", corpus]) == targets  # no duplicates
    with pytest.raises(SimenvError, match="no such file"):
        find_targets([corpus / "absent"])


def test_intergen_folder_is_one_target_scored_once(tmp_path):
    """A folder laid out as InterGen's person1/ + person2/ (the real handshake pair written by
    write_intergen) is one target: the pair, not each person's file (each of which would load
    its partner again)."""
    from simenv.io.intergen import write_intergen

    folder = tmp_path / "clips" / "intergen"
    write_intergen(load(asset_path(HANDSHAKE_PAIR)), folder, resample=True)
    assert find_targets([tmp_path / "clips"]) == [folder]
    records = score_target(folder, FAST)
    assert sorted(r["person"] for r in records) == [0, 1]


def test_bad_file_becomes_an_error_record(corpus):
    (rec,) = score_target(corpus / "nested" / "broken.bvh", FAST)
    assert rec["file"].endswith("broken.bvh")
    assert "line" in rec["error"] and rec["error_type"] == "FormatError"


def test_out_file_is_appended_as_files_finish_and_reruns_skip_them(corpus, tmp_path):
    out = tmp_path / "results.jsonl"
    targets = find_targets([corpus])
    seen = []
    first = score_batch(targets[:2], FAST, out=out, progress=False,
                        on_result=lambda t, recs: seen.append((t, len(out.read_text()
                                                                      .splitlines()))))
    # Each file's lines are on disk by the time the next one starts.
    assert [n for _, n in seen] == [1, 2]
    assert len(first) == 2
    # A killed run leaves a torn last line: it is ignored and that file is scored again.
    with out.open("a") as fh:
        fh.write('{"file": "' + str(targets[2]))
    assert done_files(out) == {str(targets[0]), str(targets[1])}
    second = score_batch(targets, FAST, out=out, progress=False)
    assert {r["file"] for r in second} == {str(targets[2])}
    assert [r["person"] for r in second] == [0, 1]
    assert score_batch(targets, FAST, out=out, progress=False) == []


def test_parallel_workers_give_the_same_records(corpus):
    targets = find_targets([corpus])
    serial = score_batch(targets, FAST, jobs=1, progress=False)
    parallel = score_batch(targets, FAST, jobs=2, progress=False)

    def key(recs):
        return sorted((r["file"], r.get("person", -1), r.get("verdict"), r.get("score"))
                      for r in recs)
    assert key(serial) == key(parallel)


def test_bad_options_are_clear_errors(corpus):
    with pytest.raises(SimenvError, match="unknown backend"):
        score_batch([corpus / "walk.bvh"], FAST, backend="slurm")
    with pytest.raises(SimenvError, match="jobs must be at least 1"):
        score_batch([corpus / "walk.bvh"], FAST, jobs=0)


def test_ray_backend_on_a_local_instance(corpus):
    pytest.importorskip("ray", reason="Ray is not installed (pip install 'simenv[ray]')")
    targets = find_targets([corpus])
    local = score_batch(targets, FAST, progress=False)
    remote = score_batch(targets, FAST, backend="ray", jobs=2, progress=False)
    assert sorted(json.dumps(r, sort_keys=True) for r in local if "error" in r) == \
        sorted(json.dumps(r, sort_keys=True) for r in remote if "error" in r)
    assert sorted((r["file"], r.get("person"), r.get("score")) for r in local) == \
        sorted((r["file"], r.get("person"), r.get("score")) for r in remote)


def test_index_entries_one_row_per_file(corpus):
    records = score_batch(find_targets([corpus]), FAST, progress=False)
    rows = {Path(f).name: (page, s, status) for f, page, s, status in index_entries(records)}
    assert set(rows) == {"walk.bvh", "broken.bvh", "pair"}
    assert rows["broken.bvh"][0] is None and "line" in rows["broken.bvh"][2]
    assert rows["walk.bvh"][2] in ("plausible", "implausible")
    pair_scores = [r["score"] for r in records if Path(r["file"]).name == "pair"]
    assert rows["pair"][1] == min(pair_scores)


def test_file_with_several_clips_scores_each(shared_data):
    # The SBU sample file holds two recording segments, each a two-person clip.
    records = score_target(shared_data / "other/sbu_kinect_sample/skeleton_pos_2.txt", FAST)
    assert [(r["clip"], r["person"]) for r in records] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert records[0]["frames"] != records[2]["frames"]


def test_records_list_the_retargetings_repairs(shared_data):
    """A real SBU pair (OpenNI: both hips, no pelvis joint) gets a body per person, fitted
    with the hips' midpoint as the pelvis; each person's record lists that repair."""
    from simenv.plausibility.metric import ScoreConfig

    job = ScoreJob(config=ScoreConfig(tracking=False))  # the bodies, not the simulation
    records = score_target(shared_data / "other/sbu_kinect_sample/skeleton_pos.txt", job)
    assert [r["person"] for r in records] == [0, 1]
    for rec in records:
        (note,) = rec["repairs"]
        assert "midpoint of LEFT_HIP and RIGHT_HIP" in note
        assert rec["metrics"]["joint_limits"]["passed"] is not None
        assert rec["metrics"]["self_penetration"]["passed"] is not None
    assert "repairs" not in score_target(shared_data / "other/sbu_kinect_sample/"
                                         "skeleton_pos.txt", FAST)[0]


def test_restore_collapsed_bones_repairs_bvh_targets_only(corpus, tmp_path):
    """The option reaches the BVH reader for files and BVH pair folders, lists the
    repairs in the records and moves the upper body; a non-BVH file is read as written."""
    job = ScoreJob(physics=False, restore_collapsed_bones=True)
    walk = corpus / "walk.bvh"
    plain, repaired = score_target(walk, FAST), score_target(walk, job)
    assert "repairs" not in plain[0]
    assert any("thorax" in r for r in repaired[0]["repairs"])
    assert repaired[0]["metrics"] != plain[0]["metrics"]
    pair = score_target(corpus / "nested" / "pair", job)
    assert len(pair) == 2 and all(r["repairs"] for r in pair)
    npz = write_npz(load(walk), tmp_path / "walk.npz")
    assert "error" not in score_target(npz, job)[0]

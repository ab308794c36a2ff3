"""The avatar keypoints cache of :func:`simenv.perception.protocol.avatar_clips`, on real
UTKinect and Florence 3D clips: what it keeps, what makes a new entry, damaged entries and two
writers at once."""

from __future__ import annotations

import threading
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from simenv.perception import protocol


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty cache folder for this test (``SIMENV_CACHE``)."""
    monkeypatch.setenv(protocol.CACHE_ENV, str(tmp_path))
    return tmp_path / "avatar_clips"


@pytest.fixture(scope="module")
def two_clips(utkinect_clips):
    """The two shortest real UTKinect clips."""
    return sorted(utkinect_clips, key=lambda c: c.num_frames)[:2]


def _entries(cache: Path) -> list[Path]:
    return sorted(cache.glob("*.npz"))


def _same(a, b) -> bool:
    return all(x.name == y.name and x.label == y.label and x.positions.dtype == y.positions.dtype
               and np.array_equal(x.positions, y.positions) for x, y in zip(a, b, strict=True))


def test_cache_keeps_what_retargeting_gives(cache, two_clips, monkeypatch):
    """One file per clip; a second call reads them (no retargeting) and returns what the
    uncached call computes."""
    first, skipped = protocol.avatar_clips(two_clips, progress=False)
    assert not skipped and len(_entries(cache)) == 2
    monkeypatch.setenv(protocol.CACHE_ENV, "off")
    uncached, _ = protocol.avatar_clips(two_clips, progress=False)
    assert _same(first, uncached)
    monkeypatch.setenv(protocol.CACHE_ENV, str(cache.parent))

    def refuse(*_args, **_kwargs):
        raise AssertionError("retargeted although cached")

    monkeypatch.setattr("simenv.room.session.user_track", refuse)
    again, _ = protocol.avatar_clips(two_clips, progress=False)
    assert _same(again, first)


def test_cache_key_follows_content_and_code(cache, two_clips, monkeypatch):
    """A clip moved by 1 cm, another scenario file or other code is a new entry; the file
    path the reader recorded is not part of the key."""
    clip = two_clips[0]
    protocol.avatar_clips([clip], progress=False)
    moved = replace(clip, source=replace(clip.source, positions=clip.source.positions + 0.01))
    renamed = replace(clip, source=replace(clip.source, metadata={
        **clip.source.metadata, "source": "/elsewhere/same_bytes.txt"}))
    protocol.avatar_clips([moved, renamed], progress=False)
    assert len(_entries(cache)) == 2
    protocol.avatar_clips([clip], "discomfort", progress=False)
    assert len(_entries(cache)) == 3
    monkeypatch.setattr(protocol, "_code_key", lambda: "other code")
    protocol.avatar_clips([clip], progress=False)
    assert len(_entries(cache)) == 4


def test_cache_remakes_damaged_entries_and_keeps_skips(cache, two_clips, gesture_root):
    """A truncated entry is made again. A real Florence 3D clip (no pelvis joint: the hips'
    midpoint is its pelvis) is kept as keypoints; the same clip with its right hip unmapped
    cannot be retargeted and is kept as its reason."""
    from simenv.core.skeletons import Skeleton
    from simenv.data.gestures import load_gesture_clips

    first, _ = protocol.avatar_clips(two_clips[:1], progress=False)
    (entry,) = _entries(cache)
    entry.write_bytes(entry.read_bytes()[:100])
    again, _ = protocol.avatar_clips(two_clips[:1], progress=False)
    assert _same(again, first) and len(_entries(cache)) == 1
    florence = load_gesture_clips(gesture_root, datasets=("florence3d",))[0]
    sk = florence.source.skeleton
    one_hip = Skeleton(sk.name, sk.joint_names, sk.parents,
                       {k: j for k, j in sk.canonical.items() if k != "right_hip"})
    clips = [florence, replace(florence, source=replace(florence.source, skeleton=one_hip))]
    kept, skipped = protocol.avatar_clips(clips, progress=False)
    assert [c.name for c in kept] == [florence.name]
    assert kept[0].positions.shape[1:] == (15, 3) and np.isfinite(kept[0].positions).all()
    assert len(skipped) == 1 and skipped[0].startswith(florence.name)
    assert "['pelvis', 'right_hip']" in skipped[0]
    cached, cached_skips = protocol.avatar_clips(clips, progress=False)
    assert _same(cached, kept) and cached_skips == skipped and len(_entries(cache)) == 3


def test_two_writers_at_once(cache, two_clips):
    """Two callers filling the same entries at the same time both get the keypoints and
    leave complete files only (no temporary files)."""
    results: list = [None, None]

    def run(i: int) -> None:
        results[i] = protocol.avatar_clips(two_clips, progress=False)[0]

    threads = [threading.Thread(target=run, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert _same(results[0], results[1])
    assert sorted(p.name for p in cache.iterdir()) == [p.name for p in _entries(cache)]
    assert len(_entries(cache)) == 2

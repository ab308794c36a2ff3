"""Every Kinect-era data file of the corpus is recognised by exactly one of
the Kinect/array sniffers and loads (or, for the one all-dropout MSR file,
fails with a clear MotionError)."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import SHARED_DATA

from simenv.core.errors import MotionError
from simenv.core.motion import Interaction, Motion
from simenv.io import florence3d, h36m, msr_action3d, ntu, nuisi, sbu, utkinect

READERS = (msr_action3d, utkinect, florence3d, sbu, nuisi, ntu, h36m)
NOT_DATA = {"SOURCES.md", "MANIFEST.md5", "index.csv", "README.txt", "action_names.mat",
            "actionLabel.txt", "actionLabel_modified.txt", "files_used_in_cvpr12_paper.txt"}


def _files() -> list[str]:
    out = []
    for sub in ("gestures", "other"):
        for p in sorted((SHARED_DATA / sub).rglob("*")):
            if p.is_file() and p.name not in NOT_DATA:
                out.append(str(p.relative_to(SHARED_DATA)))
    msr = [f for f in out if "msr_action3d" in f]
    # Every MSR file is read in test_io_msr_action3d; here one in 20 plus the
    # all-zero one exercise the sniffers.
    keep = set(msr[::20]) | {f for f in msr if "a13_s09_e02" in f}
    return [f for f in out if "msr_action3d" not in f or f in keep]


@pytest.mark.parametrize("rel", _files())
def test_corpus_file_sniffed_and_loaded(shared_data: Path, rel: str) -> None:
    path = shared_data / rel
    head = path.read_bytes()[:4096]
    owners = [r for r in READERS if r.sniff(path, head)]
    assert len(owners) == 1, (rel, [r.__name__ for r in owners])
    if "a13_s09_e02" in rel:
        with pytest.raises(MotionError, match="all 38 frames are zero"):
            owners[0].read(path)
        return
    result = owners[0].read(path)
    items = result if isinstance(result, list) else [result]
    assert items
    for item in items:
        assert isinstance(item, Motion | Interaction)
        for m in item.people if isinstance(item, Interaction) else (item,):
            assert m.num_frames >= 1 and 1.0 < m.height() < 2.2
            assert "camera_frame" in m.metadata

"""Shared fixtures: the real motion-capture corpus in ../shared/data."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

import simenv  # (imported first: chooses MUJOCO_GL before any test module imports mujoco)
from simenv.core.config import shared_data_root

REPO = Path(__file__).resolve().parent.parent
SHARED_DATA = shared_data_root()

# Property tests draw the same examples on every run, so CI cannot fail on a draw nobody saw
# locally; `SIMENV_HYPOTHESIS=explore make test` searches fresh examples.
settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("SIMENV_HYPOTHESIS", "ci"))


#: The suite's longest files, longest first (CPU of a fresh-clone run: the README's commands
#: and recipes take 3-6 min each, the others 1-2 min). They go to the workers first, so that
#: no long file starts near the end and runs alone while the other workers idle
#: (longest-processing-time-first; `make test` keeps this order with --no-loadscope-reorder,
#: where xdist would otherwise hand out the files with the most tests first).
LONGEST_FILES = (
    "test_readme_recipes.py", "test_readme.py", "test_rehearsal.py",
    "test_eval_interaction.py", "test_agents_seat.py", "test_agents_window_open.py",
    "test_plausibility_html_report.py", "test_plausibility_report.py",
    "test_recognition_protocols.py", "test_covariance.py", "test_cli.py", "test_models.py",
)


#: Test files that share a costly session fixture (named here), scheduled as one unit so that
#: one worker builds it once: with ``--dist loadfile`` each file is a unit and two files on two
#: workers would build it twice (the shipped planner's run of the walk: 28 s of CPU each).
SHARED_FIXTURE_FILES = {
    "test_plausibility_html_report.py": "walk_1s_report",
    "test_plausibility_report.py": "walk_1s_report",
}


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """``--dist loadfile``, with the files of :data:`SHARED_FIXTURE_FILES` grouped by the
    fixture they share (xdist's own ``loadgroup`` does not group under pytest 9.2:
    pytest-dev/pytest-xdist#1386); any other mode is xdist's."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class SharedFixtureScheduling(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = super()._split_scope(nodeid)
            return SHARED_FIXTURE_FILES.get(Path(path).name, path)

    return SharedFixtureScheduling(config, log)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The longest files first (:data:`LONGEST_FILES`); every file's tests stay together and
    in their order, the other files in collection order."""
    rank = {name: i for i, name in enumerate(LONGEST_FILES)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


@pytest.fixture(scope="session", autouse=True)
def avatar_cache(tmp_path_factory: pytest.TempPathFactory):
    """The session's own cache of avatar keypoints (``SIMENV_CACHE``, read by
    :func:`simenv.perception.protocol.avatar_clips` and the README commands the suite runs):
    the suite starts empty, as on a fresh clone, and leaves the user's cache alone."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("SIMENV_CACHE", str(tmp_path_factory.mktemp("cache")))
        yield


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Root of the real mocap corpus; skips the test when it is absent."""
    if not (SHARED_DATA / "SOURCES.md").is_file():
        pytest.skip(
            f"real mocap corpus not found at {SHARED_DATA} "
            "(set SIMENV_SHARED_DATA to the shared/data folder)"
        )
    return SHARED_DATA


@pytest.fixture(scope="session")
def gesture_root(shared_data: Path) -> Path:
    """Root of the gesture corpus (``<shared>/gestures``: index.csv and the per-dataset
    folders); skips the test when it is absent."""
    root = shared_data / "gestures"
    if not ((root / "index.csv").is_file() and (root / "utkinect").is_dir()):
        pytest.skip(f"gesture corpus not found at {root}")
    return root


@pytest.fixture(scope="module")
def utkinect_clips(gesture_root: Path):
    """The labelled UTKinect gesture clips of the corpus, one list per test module."""
    from simenv.data.gestures import load_gesture_clips

    return load_gesture_clips(gesture_root, datasets=("utkinect",))


@pytest.fixture(scope="module")
def room():
    """The default room, one per test module (a module's tests may change its state)."""
    from simenv.room.room import Room

    return Room("default")


@pytest.fixture(scope="session")
def interaction_windows(shared_data: Path):
    """Every window of the real two-person recordings of the shared corpus
    (:func:`simenv.data.interaction_data.make_windows`, default layout), read once."""
    from simenv.data import interaction_data as idata

    return idata.make_windows(idata.load_recordings(shared_data))


@pytest.fixture
def quick_physics(monkeypatch: pytest.MonkeyPatch) -> None:
    """:func:`simenv.score` without a config tracks with a cheap planner for this test: 16
    samples over 0.25 s, one seed (the shipped one: 128 samples over 0.45 s, up to 3 seeds).
    For tests of what a command or pipeline runs and writes, not of its verdicts: tracking
    still runs and every metric is reported. The shipped planner's verdicts are tested in
    tests/test_plausibility_report.py, tests/test_plausibility_html_report.py and the
    tracking tests."""
    from simenv.control import MPCConfig
    from simenv.plausibility import report
    from simenv.plausibility.metric import ScoreConfig

    monkeypatch.setattr(report, "DEFAULT_SCORE_CONFIG",
                        ScoreConfig(mpc=MPCConfig(n_samples=16, horizon_s=0.25)))


@pytest.fixture(scope="session")
def walk_2s():
    """The bundled real CMU walk 02_01, first 2 s (240 frames at 120 fps)."""
    from simenv.assets import WALK, asset_path
    from simenv.io import bvh

    return bvh.read(asset_path(WALK)).slice(0, 240)


@pytest.fixture(scope="session")
def walk_2s_retargeted(walk_2s):
    """:func:`walk_2s` retargeted onto its fitted humanoid, once per test session (the
    body, dynamics and tracking tests share it; none of them modifies it)."""
    from simenv.body.retarget import retarget

    return retarget(walk_2s)


@pytest.fixture(scope="session")
def walk_1s_report():
    """:func:`simenv.score` of the bundled real CMU walk 02_01, first 1 s (120 frames at
    120 fps), with the shipped planner, once per test session: the report and HTML-page tests
    judge the same run (one worker runs both files: :data:`SHARED_FIXTURE_FILES`); none of
    them modifies it."""
    from simenv.assets import WALK, asset_path

    return simenv.score(simenv.load(asset_path(WALK)).slice(0, 120))

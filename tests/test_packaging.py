"""What a user gets from a normal (non-editable) install of the wheel.

The wheel is built from a copy of the working tree without build isolation (no network), then
installed with ``--no-deps`` into a fresh venv; that venv reaches the already installed
dependencies through a ``.pth`` line pointing at this interpreter's site-packages (a path in a
``.pth`` file is added to ``sys.path`` but *its* ``.pth`` files, such as the editable-install
hook of the development venv, are not run). Everything is then checked from a directory outside
the repository.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SOURCES = ("pyproject.toml", "README.md", "simenv", "models", "agents", "assets")

PROBE = """
import importlib.util, json, sys
import simenv, simenv.agents, simenv.models
from simenv.assets import HANDSHAKE_PAIR, WALK, asset_path, list_assets
walk = asset_path(WALK)
pair = asset_path(HANDSHAKE_PAIR)
print(json.dumps({
    "simenv": simenv.__file__,
    "models": simenv.models.__file__,
    "agents": simenv.agents.__file__,
    "top_level_models": importlib.util.find_spec("models") is not None,
    "top_level_agents": importlib.util.find_spec("agents") is not None,
    "assets": list_assets(),
    "walk": str(walk),
    "walk_head": walk.read_text().split()[0],
    "pair_files": sorted(p.name for p in pair.iterdir()),
    "readme": (walk.parent / "README.md").is_file(),
}))
"""


def _md5(path: Path) -> str:
    return hashlib.md5(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Build the wheel, install it into a fresh venv; returns paths for the tests."""
    root = tmp_path_factory.mktemp("packaging")
    src = root / "src"
    src.mkdir()
    for name in SOURCES:
        item = REPO / name
        if item.is_dir():
            shutil.copytree(item, src / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(item, src / name)
    dist = root / "dist"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
         "--quiet", "-w", str(dist), str(src)],
        check=True, cwd=root, capture_output=True,
    )
    (wheel,) = dist.glob("simenv-*.whl")
    venv = root / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps",
         "--no-index", "--quiet", str(wheel)],
        check=True, capture_output=True,
    )
    venv_site = Path(
        subprocess.run(
            [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            check=True, capture_output=True, text=True,
        ).stdout.strip()
    )
    (venv_site / "_simenv_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    work = root / "elsewhere"
    work.mkdir()
    return {"wheel": wheel, "venv": venv, "python": python, "site": venv_site, "cwd": work}


def test_wheel_holds_one_namespace_and_the_assets(installed: dict):
    names = zipfile.ZipFile(installed["wheel"]).namelist()
    top = {n.split("/", 1)[0] for n in names}
    assert top == {"simenv", "simenv-0.1.0.dist-info"}  # no bare models/, agents/, assets/
    for required in (
        "simenv/__main__.py",
        "simenv/models/__init__.py",
        "simenv/agents/__init__.py",
        "simenv/assets/__init__.py",
        "simenv/assets/README.md",
        "simenv/assets/cmu_02_01_walk.bvh",
        "simenv/assets/cmu-18-19-walk-shake-hands/18_01.bvh",
        "simenv/assets/cmu-18-19-walk-shake-hands/19_01.bvh",
        "simenv/assets/scenarios/default.toml",
        "simenv/assets/sessions/utkinect-s02-e01-wave.toml",
        "simenv/assets/models/predictor-25-50.npz",
    ):
        assert required in names


def test_every_asset_file_is_in_the_wheel(installed: dict):
    """Whatever assets/ holds (clips, checkpoints, scenarios, profiles) ships: a file type
    missing from pyproject.toml's package-data would work in the checkout and fail installed."""
    names = set(zipfile.ZipFile(installed["wheel"]).namelist())
    tracked = subprocess.run(["git", "ls-files", "assets"], cwd=REPO, capture_output=True,
                             text=True)
    files = ([REPO / f for f in tracked.stdout.split()] if tracked.returncode == 0
             else [p for p in (REPO / "assets").rglob("*") if p.is_file()])
    missing = [f.relative_to(REPO).as_posix() for f in files
               if "__pycache__" not in f.parts
               and f"simenv/{f.relative_to(REPO).as_posix()}" not in names]
    assert not missing, f"not in the wheel (add to [tool.setuptools.package-data]): {missing}"


def test_every_subpackage_is_in_the_wheel(installed: dict):
    """pyproject.toml lists packages explicitly (for the models/agents/assets mapping)."""
    names = set(zipfile.ZipFile(installed["wheel"]).namelist())
    for top, installed_as in (("simenv", "simenv"), ("models", "simenv/models"),
                              ("agents", "simenv/agents"), ("assets", "simenv/assets")):
        for init in (REPO / top).rglob("__init__.py"):
            if "__pycache__" in init.parts:
                continue
            inside = init.relative_to(REPO / top).as_posix()
            assert f"{installed_as}/{inside}" in names, (
                f"{top}/{inside} is not in the wheel: add its package to "
                "[tool.setuptools] packages in pyproject.toml"
            )


def test_installed_package_is_importable_outside_the_repo(installed: dict):
    run = subprocess.run(
        [str(installed["python"]), "-c", PROBE],
        cwd=installed["cwd"], capture_output=True, text=True,
    )
    assert run.returncode == 0, run.stderr
    probe = json.loads(run.stdout)
    site = str(installed["site"])
    for module in ("simenv", "models", "agents"):
        assert probe[module].startswith(site), (module, probe[module])  # not the working tree
    assert probe["models"].endswith("simenv/models/__init__.py")
    assert not probe["top_level_models"] and not probe["top_level_agents"]
    assert probe["assets"] == ["cmu-18-19-walk-shake-hands", "cmu_02_01_walk.bvh"]
    assert probe["walk_head"] == "HIERARCHY" and probe["readme"]
    assert probe["pair_files"] == ["18_01.bvh", "19_01.bvh"]
    walk = Path(probe["walk"])
    assert walk.is_relative_to(site)
    assert _md5(walk) == _md5(REPO / "assets" / "cmu_02_01_walk.bvh")


def test_installed_command_runs_on_a_bundled_asset(installed: dict):
    simenv = installed["venv"] / "bin" / "simenv"
    assert simenv.is_file()
    run = subprocess.run(
        [str(simenv), "--help"], cwd=installed["cwd"], capture_output=True, text=True
    )
    assert run.returncode == 0 and "retarget" in run.stdout
    run = subprocess.run(
        [str(installed["python"]), "-m", "simenv", "demo", "--help"],
        cwd=installed["cwd"], capture_output=True, text=True,
    )
    assert run.returncode == 0 and "--out" in run.stdout
    walk = installed["site"] / "simenv" / "assets" / "cmu_02_01_walk.bvh"
    run = subprocess.run(
        [str(simenv), "info", str(walk), "--json"],
        cwd=installed["cwd"], capture_output=True, text=True,
    )
    assert run.returncode == 0, run.stderr
    info = json.loads(run.stdout)
    assert info["people"] == 1 and info["fps"] == 120
    assert 1.4 < info["persons"][0]["stature_m"] < 2.1

"""The import rules of docs/architecture.md, checked.

* The import-linter contracts of pyproject.toml (``[tool.importlinter]``): packages import down
  the layers only, package code never imports the ``simenv`` facade, no import cycles, private
  modules stay inside their package.
* An AST scan (independent of import-linter) for cycles between simenv's packages and for
  private names (``_name``) used across modules, in simenv/, models/, agents/, assets/ and
  benchmarks/.

``models/``, ``agents/`` and ``assets/`` become ``simenv.models``, ``simenv.agents`` and
``simenv.assets`` only when installed (``[tool.setuptools.package-dir]``), while import-linter
reads the folders of the package that Python finds. The contracts are therefore checked on a copy
of the installed layout (the ``.py`` files only) in a temporary folder, made from the same
package-dir table, so the check works the same on a fresh clone and needs no install step.

``make lint`` runs this file.
"""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import pytest

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the tomli backport (a dependency there)
    import tomli as tomllib

REPO = Path(__file__).resolve().parent.parent
PYPROJECT = REPO / "pyproject.toml"
ROOT = "simenv"
#: Scanned for private names too, though outside the layers (scripts, not an installed package).
BENCHMARKS = "benchmarks"


def package_dirs() -> dict[str, Path]:
    """Installed package name -> its source folder in the checkout, for ``simenv`` and every
    folder that ``[tool.setuptools.package-dir]`` maps into it (e.g. ``simenv.models`` ->
    ``models/``)."""
    table = tomllib.loads(PYPROJECT.read_text())["tool"]["setuptools"]["package-dir"]
    return {name: REPO / folder for name, folder in table.items()
            if name == ROOT or name.startswith(ROOT + ".")}


def source_files() -> Iterator[tuple[str, Path]]:
    """``(module name, file)`` of every Python file of the installed ``simenv`` namespace and of
    benchmarks/; a package's ``__init__.py`` is named after the package."""
    roots = {**package_dirs(), BENCHMARKS: REPO / BENCHMARKS}
    for package, folder in sorted(roots.items()):
        for path in sorted(folder.rglob("*.py")):
            parts = path.relative_to(folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            yield ".".join((package, *parts)), path


@cache
def parsed_sources() -> tuple[tuple[str, Path, ast.Module], ...]:
    """``(module name, file, syntax tree)`` of :func:`source_files`, parsed once."""
    return tuple((name, path, ast.parse(path.read_text(), str(path)))
                 for name, path in source_files())


def installed_layout(dest: Path) -> Path:
    """Copy the ``.py`` files of the installed ``simenv`` layout under ``dest`` (``dest/simenv``,
    with ``dest/simenv/models`` from ``models/`` and so on) and return ``dest``."""
    for name, path in source_files():
        if name.split(".")[0] != ROOT:
            continue
        rel = Path(*name.split("."))
        target = dest / (rel / "__init__.py" if path.name == "__init__.py" else
                         rel.with_suffix(".py"))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, target)
    return dest


def test_import_contracts_are_kept(tmp_path: Path) -> None:
    """lint-imports on the installed layout keeps every contract of pyproject.toml (a layer
    that is not found, e.g. ``models`` on a wrong layout, breaks the layers contract)."""
    view = installed_layout(tmp_path / "layout")
    # The copy comes first on the path, so import-linter finds it rather than the editable
    # install (whose finder is consulted after the path).
    env = {**os.environ, "PYTHONPATH": str(view)}
    lint = Path(sys.executable).with_name("lint-imports")
    run = subprocess.run([str(lint), "--no-cache", "--no-logo", str(PYPROJECT)], cwd=view,
                         env=env, capture_output=True, text=True, timeout=300)
    report = run.stdout + run.stderr
    if run.returncode != 0 or "0 broken" not in report:
        pytest.fail(f"import contracts broken (pyproject.toml [tool.importlinter]):\n{report}",
                    pytrace=False)


@dataclass(frozen=True)
class Import:
    """One import statement's target, as found by the AST scan."""

    importer: str  # module holding the statement
    imported: str  # module imported (for `from m import f`: m, or m.f when f is a module)
    names: tuple[str, ...]  # names taken from `imported` (empty for `import m`)
    where: str  # "path:line"


def _resolve(importer: str, is_package: bool, level: int, module: str | None) -> str:
    # Absolute name of a (possibly relative) import target.
    if level == 0:
        return module or ""
    base = importer.split(".")
    base = base[:len(base) - level + (1 if is_package else 0)]
    return ".".join(base + ([module] if module else []))


def _script_sibling(importer: str, module: str, modules: set[str]) -> str:
    # A benchmark script imports its sibling scripts by their bare name (`import doc_sections`).
    sibling = f"{BENCHMARKS}.{module}"
    return sibling if importer.startswith(BENCHMARKS + ".") and sibling in modules else module


@cache
def scan_imports() -> tuple[Import, ...]:
    """Every import statement (module level or inside functions) of the scanned files."""
    modules = {name for name, _, _ in parsed_sources()}
    found = []
    for name, path, tree in parsed_sources():
        is_package = path.name == "__init__.py"
        rel = path.relative_to(REPO)
        for node in ast.walk(tree):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            where = f"{rel}:{node.lineno}"
            if isinstance(node, ast.Import):
                found += [Import(name, _script_sibling(name, a.name, modules), (), where)
                          for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                target = _script_sibling(
                    name, _resolve(name, is_package, node.level, node.module), modules)
                plain = [a.name for a in node.names if f"{target}.{a.name}" not in modules]
                found += [Import(name, f"{target}.{a.name}", (), where) for a in node.names
                          if f"{target}.{a.name}" in modules]
                if plain:
                    found.append(Import(name, target, tuple(plain), where))
    return tuple(found)


def _package(module: str) -> str | None:
    # The simenv package a module belongs to (`simenv` for the facade), None outside simenv.
    parts = module.split(".")
    if parts[0] != ROOT:
        return None
    return ".".join(parts[:2])


def _reachable(graph: dict[str, set[str]], start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        for nxt in graph.get(todo.pop(), ()):
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return seen


def test_no_import_cycles_between_packages() -> None:
    """No two packages of simenv import each other, directly or through others."""
    edges: dict[tuple[str, str], list[str]] = {}
    for imp in scan_imports():
        a, b = _package(imp.importer), _package(imp.imported)
        if a and b and a != b:
            edges.setdefault((a, b), []).append(imp.where)
    graph: dict[str, set[str]] = {}
    for a, b in edges:
        graph.setdefault(a, set()).add(b)
    reach = {node: _reachable(graph, node) for node in graph}
    cyclic = sorted((a, b) for a, b in edges if a in reach.get(b, ()))
    if cyclic:
        pytest.fail("imports between packages that import each other (directly or through "
                    "others):\n" + "\n".join(f"  {a} -> {b}: {', '.join(edges[a, b])}"
                                             for a, b in cyclic), pytrace=False)


def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _own(module: str) -> bool:
    # Whether a module is the project's (other libraries' private names are their business).
    return module.split(".")[0] in (ROOT, BENCHMARKS)


def _module_aliases(imports: list[Import], modules: set[str]) -> set[str]:
    # Local names bound to one of the project's modules by the statements of one file:
    # `import simenv.x` (binds `simenv`), `import simenv.x as m`, `from simenv import x`.
    aliases = set()
    for node in imports:
        if isinstance(node, ast.Import):
            aliases |= {a.asname or a.name.split(".")[0] for a in node.names
                        if _own(a.name) or f"{BENCHMARKS}.{a.name}" in modules}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            aliases |= {a.asname or a.name for a in node.names
                        if f"{node.module}.{a.name}" in modules}
    return aliases


def _private_use(imp: Import) -> list[str]:
    # The private parts of one import of the project's modules: a private name taken from
    # the module, or a private module imported from outside the package that holds it.
    if not _own(imp.imported):
        return []
    parts = imp.imported.split(".")
    for i, part in enumerate(parts):
        if _is_private(part):
            owner = ".".join(parts[:i])
            if not (imp.importer == owner or imp.importer.startswith(owner + ".")):
                return [f"  {imp.where}: private module {imp.imported} from outside {owner}"]
            break
    return [f"  {imp.where}: from {imp.imported} import {n}" for n in imp.names if _is_private(n)]


def test_no_private_names_across_modules() -> None:
    """No module takes a private name (``_name``) from another module: neither by
    ``from m import _name`` nor by ``m._name`` on an imported module. A private module
    (``_text.py``) may be imported only from inside its own package."""
    modules = {name for name, _, _ in parsed_sources()}
    bad = [line for imp in scan_imports() for line in _private_use(imp)]
    for _, path, tree in parsed_sources():
        aliases = _module_aliases([n for n in ast.walk(tree)
                                   if isinstance(n, (ast.Import, ast.ImportFrom))], modules)
        bad += [f"  {path.relative_to(REPO)}:{node.lineno}: {node.value.id}.{node.attr}"
                for node in ast.walk(tree)
                if isinstance(node, ast.Attribute) and _is_private(node.attr)
                and isinstance(node.value, ast.Name) and node.value.id in aliases]
    if bad:
        pytest.fail("private names used across modules:\n" + "\n".join(sorted(bad)),
                    pytrace=False)

"""README.md is a contract: every command and Python snippet in it runs as written.

The fenced ``bash`` and ``python`` blocks are read from the README and run in README order, as a
new user would after set-up: in a fresh copy of the repository's tracked files (a temporary
folder, with ``../shared/data`` next to it: the README's commands read ``assets/``,
``tests/data/`` and ``../shared/data`` from the repository root), with ``.venv/bin`` first on
the ``PATH``. Each command must exit with status 0; where the README shows its output (a JSON
object in the comment lines under it, ``...`` standing for any value), the output has those
keys and values, and where a comment under it says it prints `` `TEXT` ``, it prints TEXT. A
``bash`` command whose comment says ``not run by tests/test_readme.py:`` gives its reason
there, visibly, and is skipped; so is a command with such a comment line under it, and every
command of a block that opens with one; what it names must still exist (its input files,
scripts, modules and ``simenv`` command) and, where the parser that runs it can be built
without running it, its options parse. The ``text`` block of the command line's
synopsis is checked against each command's ``--help``: every option it names exists.

A long command (a shipped model's recipe) runs with its *quick options*: a comment of the
command (on its line or under it) saying ``quick: `OPTIONS` `` documents its smallest setting
(one epoch, a few steps, a short clip) and the test runs the command as written with OPTIONS
added at its end (comments removed), so every option of the full command is still parsed and
run, and the steps and outputs are the same, in seconds instead of hours; the test's output
says which quick options it added.

Commands that need earlier outputs find them because the README shows those steps first in
the same block: running one command alone runs the earlier commands of its block first.
"""

from __future__ import annotations

import importlib.util
import json
import os
import re
import resource
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
#: The bin folder of the environment set-up made (``make`` creates ``.venv``).
VENV_BIN = Path(sys.executable).parent
#: What a command's comment says when the README does not let the test run it.
NOT_RUN = "not run by tests/test_readme.py:"
#: Commands that take more than a few seconds of CPU even in their README form (pytest marker
#: ``readme_long``; they run in CI, ``-m "not readme_long"`` leaves them out locally): these,
#: and ``simenv score`` with physics on.
LONG = ("simenv train ", "simenv eval ", "simenv rehearse ", "simenv render ",
        "python benchmarks/", "python -m simenv.learning")
#: Seconds a README command may take before it counts as hung.
TIMEOUT_S = 600
#: How a README comment gives a command's quick options (module docstring).
QUICK = re.compile(r"quick: `([^`]+)`")


@dataclass(frozen=True)
class Snippet:
    """One runnable unit of the README: a bash command or a whole Python block."""

    language: str            # "bash" or "python"
    code: str                # the command (continuation lines joined) or the block's source
    line: int                # README line where it starts (1-based)
    block: int               # index of its fenced block in the README
    section: str             # the heading it is under
    expected: str | None = None  # README-shown output (JSON with ... for any value)
    not_run: str | None = None   # the README's reason for not running it
    prints: tuple[str, ...] = ()  # text the README says it prints
    quick: str | None = None      # the README's quick options of a long command

    @property
    def command(self) -> str:
        """What the test runs: the code, or with quick options the command's words (comments
        and line continuations removed) and the quick options after them."""
        if self.quick is None:
            return self.code
        return shlex.join(shlex.split(self.code.replace("\\\n", " "), comments=True)
                          + shlex.split(self.quick))

    @property
    def id(self) -> str:
        """A short test id: README line and the command's start."""
        head = self.code.strip().splitlines()[0] if self.code.strip() else ""
        return f"L{self.line}:{head[:60]}"


def _blocks(text: str) -> list[tuple[str, int, str, list[str]]]:
    """The README's fenced blocks: (language, first code line, section heading, lines)."""
    blocks, section, fence = [], "", None
    for number, line in enumerate(text.splitlines(), start=1):
        if fence is None:
            if line.startswith("#"):
                section = line.lstrip("#").strip()
            elif line.startswith("```"):
                fence = (line[3:].strip().split(" ")[0], number + 1, section, [])
        elif line.startswith("```"):
            blocks.append(fence)
            fence = None
        else:
            fence[3].append(line)
    return blocks


def _bash_commands(lines: list[str], first: int
                   ) -> list[tuple[str, int, str | None, str | None, tuple[str, ...],
                                   str | None]]:
    """(command, line, shown output, reason not run, printed texts, quick options) of a bash
    block: a line ending in ``\\`` continues on the next; comment lines under a command that
    hold a JSON object are its shown output, ``prints `TEXT` `` in them a text it prints; a
    comment saying :data:`NOT_RUN` gives the reason for its command, on a line of its own
    for the command above it, or, opening the block, for every command of the block; its
    quick options (:data:`QUICK`) are in its own comment or the comment lines under it."""
    commands: list[tuple[str, int, str | None]] = []
    block_reason, reasons, prints, quick = None, {}, {}, {}
    i = 0
    while i < len(lines):
        line, start = lines[i], first + i
        if not line.strip():
            i += 1
            continue
        if line.lstrip().startswith("#"):
            body = line.lstrip()[1:].strip()
            if commands:
                prints.setdefault(commands[-1][1], []).extend(
                    re.findall(r"prints `([^`]+)`", body))
                quick[commands[-1][1]] = quick.get(commands[-1][1]) or _quick(line)
            if NOT_RUN in body:
                reason = _reason(_comment(lines, i))
                if commands:
                    reasons[commands[-1][1]] = reason
                else:
                    block_reason = reason
            if body.startswith("{") and commands:
                shown = [body]
                while shown[-1].count("}") < 1 and i + 1 < len(lines):
                    i += 1
                    shown.append(lines[i].lstrip()[1:].strip())
                code, at, _ = commands[-1]
                commands[-1] = (code, at, " ".join(shown))
            i += 1
            continue
        parts = [line]
        while parts[-1].rstrip().endswith("\\") and i + 1 < len(lines):
            i += 1
            parts.append(lines[i])
        commands.append(("\n".join(parts), start, None))
        quick[start] = _quick("\n".join(parts))
        i += 1
    return [(code, at, shown, block_reason or reasons.get(at)
             or (_reason(code) if NOT_RUN in code else None), tuple(prints.get(at, ())),
             quick.get(at)) for code, at, shown in commands]


def _quick(text: str) -> str | None:
    """The quick options a README comment in ``text`` gives, or None."""
    found = QUICK.search(text.split("#", 1)[1]) if "#" in text else None
    return found.group(1) if found else None


def _comment(lines: list[str], i: int) -> str:
    """The comment starting at ``lines[i]`` and the comment lines right after it."""
    end = i + 1
    while end < len(lines) and lines[end].lstrip().startswith("#"):
        end += 1
    return " ".join(lines[i:end])


def _reason(text: str) -> str:
    """The reason after :data:`NOT_RUN` in a README comment, comment marks removed."""
    after = re.sub(r"\s*#\s*", " ", text.split(NOT_RUN, 1)[1]).strip()
    if after.endswith(")") and after.count(")") > after.count("("):
        after = after[:-1]  # the bracket that opened before the marker
    return after


def readme_snippets(text: str | None = None) -> list[Snippet]:
    """Every bash command and Python block of the README, in README order."""
    text = README.read_text() if text is None else text
    snippets = []
    for index, (language, first, section, lines) in enumerate(_blocks(text)):
        if language == "bash":
            snippets += [Snippet("bash", code, line, index, section, *rest)
                         for code, line, *rest in _bash_commands(lines, first)]
        elif language == "python":
            snippets.append(Snippet("python", "\n".join(lines), first, index, section))
    return snippets


def synopsis_lines(text: str | None = None) -> list[tuple[int, str]]:
    """(README line, line) of the command line's synopsis (the ``text`` blocks naming
    ``simenv`` commands)."""
    text = README.read_text() if text is None else text
    return [(first + k, line) for language, first, _, lines in _blocks(text)
            if language == "text" for k, line in enumerate(lines)
            if line.startswith("simenv ")]


SNIPPETS = readme_snippets()


def _expected(shown: str) -> dict:
    """The README's shown JSON, ``...`` (any value) as None."""
    return json.loads(re.sub(r":\s*\.\.\.", ": null", shown))


@pytest.fixture(scope="module")
def clone(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> Path:
    """A fresh copy of the repository as a clone has it: its tracked files (as in the working
    tree), ``../shared/data`` beside it; what the commands write stays out of the repo."""
    root = tmp_path_factory.mktemp("readme")
    (root / "shared").mkdir()
    (root / "shared" / "data").symlink_to(shared_data)
    clone = root / "simenv"
    clone.mkdir()
    tracked = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True,
                             text=True, check=True).stdout.split("\0")
    for name in tracked:
        if (REPO / name).is_file():  # not a tracked file deleted in the working tree
            (clone / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(REPO / name, clone / name)
    return clone


@pytest.fixture(scope="module")
def ran() -> dict[int, bool]:
    """README lines of the snippets already run in this module's clone: whether each
    exited with 0."""
    return {}


def _environment(cwd: Path) -> dict[str, str]:
    """The user's shell after set-up in the clone ``cwd``: ``.venv/bin`` first on the PATH,
    the corpus where the README says (``../shared/data``), no settings of the test run."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST")}
    env["PATH"] = f"{VENV_BIN}{os.pathsep}{env.get('PATH', '')}"
    # A clone's simenv finds the corpus next to its own root by default; the simenv these
    # commands import is the installed one, so the copy's ../shared/data is named.
    env["SIMENV_SHARED_DATA"] = str(cwd.parent / "shared" / "data")
    # In a clone, `python` run from its root imports the simenv that set-up installed there;
    # in this copy, the installed one (the working tree) too, not the copy's files.
    env["PYTHONSAFEPATH"] = "1"
    return env


def _run(snippet: Snippet, cwd: Path) -> subprocess.CompletedProcess:
    """Run one snippet as written in ``cwd``; fails the test on a non-zero exit."""
    if snippet.language == "python":
        argv = [str(VENV_BIN / "python"), "-c", snippet.code]
    else:
        argv = [shutil.which("bash") or "/bin/bash", "-c", snippet.command]
    done = subprocess.run(argv, cwd=cwd, env=_environment(cwd), capture_output=True, text=True,
                          timeout=TIMEOUT_S)
    assert done.returncode == 0, (
        f"README line {snippet.line} exited with {done.returncode}:\n{snippet.command}\n"
        f"--- stdout\n{done.stdout[-3000:]}\n--- stderr\n{done.stderr[-3000:]}")
    return done


#: README blocks holding a recipe with quick options (:data:`QUICK`): their commands run in
#: tests/test_readme_recipes.py, a module of its own, so that the suite's workers (``--dist
#: loadfile``: a module runs on one worker) run them beside this module's commands.
RECIPE_BLOCKS = frozenset(s.block for s in SNIPPETS if s.quick)


def snippet_params(recipes: bool) -> list:
    """The snippets of the recipe blocks (``recipes``) or of the other blocks, as pytest
    parameters (the long ones marked ``readme_long``)."""
    marks = []
    for s in SNIPPETS:
        if (s.block in RECIPE_BLOCKS) != recipes:
            continue
        long = s.language == "bash" and (s.code.startswith(LONG) or (
            s.code.startswith("simenv score ") and "--no-physics" not in s.code))
        marks.append(pytest.param(s, id=s.id,
                                  marks=[pytest.mark.readme_long] if long else []))
    return marks


@pytest.mark.parametrize("snippet", snippet_params(recipes=False))
def test_readme_snippet(snippet: Snippet, clone: Path, ran: dict[int, bool]) -> None:
    """The snippet exits with 0 (after the earlier commands of its block) and prints what the
    README shows of its output."""
    run_snippet(snippet, clone, ran)


def run_snippet(snippet: Snippet, clone: Path, ran: dict[int, bool]) -> None:
    """Run ``snippet`` in ``clone`` after the earlier commands of its block not yet ``ran``
    (skipped when the README says it is not run; failed when one of those failed, which
    is not run again), print its CPU time and check what the README shows of its output."""
    if snippet.not_run:
        pytest.skip(f"README: {snippet.not_run}")
    for earlier in SNIPPETS:
        if earlier.block == snippet.block and earlier.line < snippet.line \
                and not earlier.not_run:
            if earlier.line not in ran:
                ran[earlier.line] = False
                _run(earlier, clone)
                ran[earlier.line] = True
            if not ran[earlier.line]:
                pytest.fail(f"README line {earlier.line}, before this command in its block, "
                            "failed")
    ran[snippet.line] = False
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = _run(snippet, clone)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    ran[snippet.line] = True
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    quick = f" (with the README's quick options {snippet.quick})" if snippet.quick else ""
    print(f"README line {snippet.line}{quick}: {cpu:.1f} s of CPU")
    for text in snippet.prints:
        assert text in done.stdout, (
            f"README line {snippet.line} says it prints {text!r}; it printed:\n{done.stdout}")
    if snippet.expected is not None:
        shown = _expected(snippet.expected)
        printed = [json.loads(line) for line in done.stdout.splitlines()
                   if line.startswith("{")]
        assert printed, f"README line {snippet.line} shows a JSON object; none printed"
        for key, value in shown.items():
            assert key in printed[-1], f"README line {snippet.line}: no {key!r} printed"
            if value is not None:
                assert printed[-1][key] == value, (
                    f"README line {snippet.line}: {key} {printed[-1][key]!r}, README "
                    f"shows {value!r}")


def test_readme_extraction() -> None:
    """Continuation lines, shown output, the three places of a not-run reason and the two of
    quick options."""
    text = "\n".join([
        "# Title", "```bash", "# (not run by tests/test_readme.py: root needed)", "make a",
        "```", "## Use", "```bash", "cmd --x \\", "    --y   # note", '# {"k": 1, "v": ...}',
        "cmd two  # not run by tests/test_readme.py: a browser", "cmd three",
        "# prints `3 done` (and more)",
        "# not run by tests/test_readme.py: a", "# cluster", "cmd four", "cmd five \\",
        "    --long  # the full run; quick: `--epochs 1`", "cmd six  # slow",
        "   # quick: `--steps 5 --x 'a b'`", "```",
        "```python", "import simenv", "```", "```text", "simenv info FILE", "```"])
    snippets = readme_snippets(text)
    assert [(s.language, s.line, s.section, s.not_run) for s in snippets] == [
        ("bash", 4, "Title", "root needed"), ("bash", 8, "Use", None),
        ("bash", 11, "Use", "a browser"), ("bash", 12, "Use", "a cluster"),
        ("bash", 16, "Use", None), ("bash", 17, "Use", None), ("bash", 19, "Use", None),
        ("python", 23, "Use", None)]
    assert snippets[3].prints == ("3 done",)
    assert [s.quick for s in snippets[4:7]] == [None, "--epochs 1", "--steps 5 --x 'a b'"]
    assert snippets[4].command == snippets[4].code
    assert snippets[5].command == "cmd five --long --epochs 1"
    assert snippets[6].command == "cmd six --steps 5 --x 'a b'"
    assert snippets[1].code == "cmd --x \\\n    --y   # note"
    assert _expected(snippets[1].expected) == {"k": 1, "v": None}
    assert synopsis_lines(text) == [(26, "simenv info FILE")]


def _parser_of(words: list[str]):
    """The parser that ``simenv WORDS...`` runs with, and the options it parses, when it can be
    built without running the command (None for the training and evaluation scripts that
    build theirs when they run)."""
    from simenv.cli.common import command_parser
    from simenv.cli.evaluate import classifier_parser
    from simenv.cli.main import build_parser
    from simenv.cli.rehearse import rehearsal_parser

    command, kind = words[1], words[2] if len(words) > 2 else None
    if command == "rehearse":
        return rehearsal_parser()[0], words[2:]
    if command == "eval" and kind in ("classifier", "recogniser"):
        return classifier_parser(f"simenv eval {kind}"), words[3:]
    if command == "train" and kind in ("classifier", "recogniser"):
        from simenv.learning import train_classifier
        from simenv.perception import train_recogniser

        parser = command_parser(f"simenv train {kind}", None)
        (train_classifier if kind == "classifier" else train_recogniser).add_train_arguments(
            parser)
        return parser, words[3:]
    if command in ("train", "eval"):
        return None, []
    return build_parser(), words[1:]


@pytest.mark.parametrize("snippet", [s for s in SNIPPETS if s.not_run], ids=lambda s: s.id)
def test_readme_not_run_commands_name_real_things(snippet: Snippet, shared_data: Path) -> None:
    """A command the test does not run still names what exists: its input files (under
    ``assets/``, ``tests/``, ``benchmarks/``, ``../shared/data``), the script or module it runs,
    and for ``simenv`` the command and KIND; its options parse where the parser that runs it
    can be built without running it."""
    from simenv.cli.main import build_parser

    words = shlex.split(snippet.code.replace("\\\n", " "), comments=True)
    while words and re.fullmatch(r"[A-Z_]+=\S*", words[0]):
        words = words[1:]  # VAR=value prefixes
    for word in words:
        if word.startswith("../shared/data/"):
            path = shared_data / word.removeprefix("../shared/data/")
        elif word.split("/")[0] in ("assets", "tests", "benchmarks"):
            path = REPO / word
        else:
            continue
        assert list(path.parent.glob(path.name)), f"README line {snippet.line}: no {word}"
    if words[:2] == ["python", "-m"]:
        assert importlib.util.find_spec(words[2]), f"README line {snippet.line}: no {words[2]}"
    elif words[0] == "simenv":
        known, _ = build_parser().parse_known_args(words[1:3])
        assert known.command == words[1]
        parser, options = _parser_of(words)
        if parser is not None:
            try:
                parser.parse_args(options)
            except SystemExit:
                pytest.fail(f"README line {snippet.line}: {parser.prog} rejects {options}")


def test_readme_has_snippets() -> None:
    """The extraction finds the README's commands (a changed fence would hide them)."""
    assert sum(s.language == "bash" for s in SNIPPETS) >= 20
    assert sum(s.language == "python" for s in SNIPPETS) >= 3
    assert synopsis_lines()


@pytest.mark.parametrize("number,line", synopsis_lines(), ids=lambda v: str(v)[:40])
def test_readme_synopsis_options(number: int, line: str) -> None:
    """Every option the synopsis shows for a command is in that command's ``--help``."""
    from simenv.cli.main import build_parser

    words = line.split("#")[0].split()
    command = words[1]
    commands = build_parser()._subparsers._group_actions[0].choices  # noqa: SLF001
    if command == "COMMAND":
        return
    assert command in commands, f"README line {number}: no command simenv {command}"
    sub = commands[command]
    known = {o for action in sub._actions for o in action.option_strings}  # noqa: SLF001
    shown = {w.strip("[]|") for w in words[2:]} | {
        part for w in words[2:] for part in re.findall(r"--[a-z-]+", w)}
    missing = sorted(o for o in shown if o.startswith("--") and o not in known)
    assert not missing, f"README line {number}: simenv {command} has no {missing}"

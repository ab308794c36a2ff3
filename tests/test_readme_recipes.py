"""The README's recipes of the shipped models, run as tests/test_readme.py runs every README
command: each block's commands in order in a fresh copy of the repository, each long one with
the quick options its README comment gives (its smallest setting: one epoch, a few steps, a
short clip). A module of their own so that the suite's workers run them beside
tests/test_readme.py (``--dist loadfile``)."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_readme import Snippet, clone, ran, run_snippet, snippet_params  # noqa: F401


@pytest.mark.parametrize("snippet", snippet_params(recipes=True))
def test_readme_recipe(snippet: Snippet, clone: Path, ran: dict[int, bool]  # noqa: F811
                       ) -> None:
    """The recipe's command exits with 0 (after the earlier commands of its block), run with
    its quick options."""
    run_snippet(snippet, clone, ran)

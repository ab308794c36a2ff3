"""MATLAB 5 MAT-files, parsed safely: scipy's MAT reader can crash the interpreter
(a segmentation fault, found by fuzzing) on corrupt files, so every file is first
parsed in a child process (cached per file state); the readers turn a failure there
into a :class:`~simenv.core.errors.FormatError`."""

from __future__ import annotations

import subprocess
import sys
from functools import lru_cache
from pathlib import Path

#: First bytes of a MATLAB 5 MAT-file.
MAT_MAGIC = b"MATLAB 5.0 MAT-file"
#: Upper bound for the crash-isolation pre-check of a MAT file, seconds.
MAT_CHECK_TIMEOUT_S = 120.0
_MAT_CHECK = (
    "import sys, scipy.io\n"
    "scipy.io.whosmat(sys.argv[1])\n"
    "scipy.io.loadmat(sys.argv[1], squeeze_me=True, struct_as_record=False)\n"
)


def mat_parse_error(path: Path) -> str | None:
    """None when a child process parsed the MAT-file ``path``, else why it could not.

    Raises:
        OSError: ``path`` cannot be stat'ed.
    """
    st = path.stat()
    return _parse_in_child(str(path.resolve()), st.st_mtime_ns, st.st_size)


@lru_cache(maxsize=32)
def _parse_in_child(path: str, mtime_ns: int, size: int) -> str | None:
    del mtime_ns, size  # cache key only
    try:
        run = subprocess.run([sys.executable, "-c", _MAT_CHECK, path], capture_output=True,
                             timeout=MAT_CHECK_TIMEOUT_S, check=False)
    except subprocess.TimeoutExpired:
        return f"parsing took longer than {MAT_CHECK_TIMEOUT_S:g} s"
    if run.returncode == 0:
        return None
    if run.returncode < 0:
        return f"the MAT parser crashed (signal {-run.returncode})"
    lines = run.stderr.decode(errors="replace").strip().splitlines()
    return lines[-1] if lines else f"exit status {run.returncode}"

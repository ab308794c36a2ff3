"""simenv's own NPZ format for :class:`Motion` and :class:`Interaction`.

A compressed NumPy archive without pickles. Keys (version 1):

=========================  ===============================================
``simenv_npz_version``     int, :data:`VERSION`
``kind``                   ``"motion"`` or ``"interaction"``
``<p>positions``           (T, J, 3) float32 metres, Z-up
``<p>fps``                 float64
``<p>joint_names``         (J,) str
``<p>parents``             (J,) int64
``<p>skeleton_name``       str
``<p>canonical``           JSON object, canonical keypoint -> joint name
``<p>name``                str
``<p>metadata``            JSON object
``<p>rotations``           optional (T, J, 4) float32 quaternions (w, x, y, z)
``label``, ``roles_known``, ``name``, ``metadata``   interaction fields
=========================  ===============================================

``<p>`` is empty for a motion and ``actor/`` or ``reactor/`` for an
interaction. Arrays round-trip bit-exactly; metadata round-trips through
JSON (tuples come back as lists; NumPy scalars/arrays and paths are stored
as numbers, lists and strings).
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import FormatError, SimenvError
from simenv.core.motion import Interaction, Motion
from simenv.core.skeletons import Skeleton

FORMAT = "npz"
EXTENSIONS = (".npz",)

#: Format version written by :func:`write_npz` and accepted by :func:`read`.
VERSION = 1

_VERSION_KEY = "simenv_npz_version"


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, (set, frozenset)):
        return sorted(obj)
    raise TypeError(f"metadata value of type {type(obj).__name__} is not JSON-serialisable")


def _dumps(obj: Any, what: str) -> np.ndarray:
    try:
        return np.array(json.dumps(obj, default=_json_default))
    except (TypeError, ValueError) as exc:
        raise FormatError(f"cannot store {what} as JSON: {exc}", field=what) from None


def _motion_arrays(m: Motion, prefix: str) -> dict[str, np.ndarray]:
    out = {
        f"{prefix}positions": np.asarray(m.positions, dtype=np.float32),
        f"{prefix}fps": np.array(m.fps, dtype=np.float64),
        f"{prefix}joint_names": np.array(m.skeleton.joint_names, dtype=str),
        f"{prefix}parents": np.array(m.skeleton.parents, dtype=np.int64),
        f"{prefix}skeleton_name": np.array(m.skeleton.name),
        f"{prefix}canonical": _dumps(dict(m.skeleton.canonical), "canonical"),
        f"{prefix}name": np.array(m.name),
        f"{prefix}metadata": _dumps(m.metadata, f"{prefix}metadata"),
    }
    if m.rotations is not None:
        out[f"{prefix}rotations"] = np.asarray(m.rotations, dtype=np.float32)
    return out


def write_npz(obj: Motion | Interaction, path: str | Path) -> Path:
    """Write a Motion or Interaction to ``path`` (written as given, no
    suffix added). Returns the path."""
    path = Path(path)
    arrays: dict[str, np.ndarray] = {_VERSION_KEY: np.array(VERSION, dtype=np.int64)}
    if isinstance(obj, Motion):
        arrays["kind"] = np.array("motion")
        arrays.update(_motion_arrays(obj, ""))
    elif isinstance(obj, Interaction):
        arrays["kind"] = np.array("interaction")
        arrays.update(_motion_arrays(obj.actor, "actor/"))
        arrays.update(_motion_arrays(obj.reactor, "reactor/"))
        arrays["label"] = _dumps(obj.label, "label")
        arrays["roles_known"] = np.array(bool(obj.roles_known))
        arrays["name"] = np.array(obj.name)
        arrays["metadata"] = _dumps(obj.metadata, "metadata")
    else:
        raise TypeError(f"write_npz takes a Motion or an Interaction, not {type(obj).__name__}")
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as fh:
        np.savez_compressed(fh, **arrays)  # type: ignore[arg-type]
    return path


def sniff(path: Path, head: bytes) -> bool:
    """A zip archive holding the ``simenv_npz_version`` array."""
    if not head.startswith(b"PK\x03\x04"):
        return False
    try:
        with zipfile.ZipFile(path) as zf:
            return f"{_VERSION_KEY}.npy" in zf.namelist()
    except (zipfile.BadZipFile, OSError):
        return False


class _Archive:
    def __init__(self, data: Any, path: Path) -> None:
        self.data, self.path = data, path

    def get(self, key: str, *, optional: bool = False) -> np.ndarray | None:
        if key not in self.data.files:
            if optional:
                return None
            raise FormatError(
                f"simenv NPZ lacks key {key!r}; expected a file written by write_npz",
                source=self.path,
                field=key,
            )
        try:
            return self.data[key]
        # A damaged archive can fail in zipfile, zlib or numpy's header parser with many
        # exception types; all mean the same to the user.
        except Exception as exc:
            raise FormatError(f"cannot read array: {exc}", source=self.path, field=key) from None

    def text(self, key: str) -> str:
        arr = self.get(key)
        if arr.dtype.kind != "U" or arr.ndim != 0:
            raise FormatError(
                f"expected a string, found {arr.dtype} {arr.shape}", source=self.path, field=key
            )
        return str(arr)

    def json(self, key: str) -> Any:
        try:
            return json.loads(self.text(key))
        except json.JSONDecodeError as exc:
            raise FormatError(f"invalid JSON: {exc}", source=self.path, field=key) from None


def _motion(a: _Archive, prefix: str) -> Motion:
    skeleton = Skeleton(
        a.text(f"{prefix}skeleton_name"),
        tuple(str(n) for n in a.get(f"{prefix}joint_names")),
        tuple(int(p) for p in a.get(f"{prefix}parents")),
        a.json(f"{prefix}canonical"),
    )
    meta = a.json(f"{prefix}metadata")
    if not isinstance(meta, dict):
        raise FormatError("metadata must be a JSON object", source=a.path, field="metadata")
    return Motion(
        positions=a.get(f"{prefix}positions"),
        fps=float(a.get(f"{prefix}fps")),
        skeleton=skeleton,
        name=a.text(f"{prefix}name"),
        metadata=meta,
        rotations=a.get(f"{prefix}rotations", optional=True),
    )


def read(path: Path) -> Motion | Interaction:
    """Read a file written by :func:`write_npz`.

    Raises:
        FormatError: not a zip/NPZ, missing or unsupported
            ``simenv_npz_version``, missing keys, bad JSON.
        MotionError, SkeletonError: stored arrays that do not form a valid
            Motion (wrong shapes, NaN, bad parents).
    """
    path = Path(path)
    try:
        data = np.load(path, allow_pickle=False)
    except Exception as exc:  # damaged archive: see _Archive.get
        raise FormatError(f"not a readable NPZ archive ({exc})", source=path) from None
    if not hasattr(data, "files"):
        raise FormatError("holds a single array, not a simenv NPZ archive", source=path)
    with data:
        try:
            return _read_archive(_Archive(data, path))
        except SimenvError as exc:
            if exc.source == str(path):
                raise
            # Motion validation names the clip's original source; name the archive too.
            detail = exc.detail + (f" (clip recorded from {exc.source})" if exc.source else "")
            raise type(exc)(
                detail, source=path, line=exc.line, frame=exc.frame, field=exc.field
            ) from None


def _read_archive(a: _Archive) -> Motion | Interaction:
    path, data = a.path, a.data
    if _VERSION_KEY not in data.files:
        raise FormatError(
            f"no {_VERSION_KEY!r} key: not a simenv motion NPZ (write one with write_npz)",
            source=path,
            field=_VERSION_KEY,
        )
    version = a.get(_VERSION_KEY)
    if version.shape != () or version.dtype.kind not in "iu" or int(version) != VERSION:
        raise FormatError(
            f"unsupported simenv NPZ version {version!r}; this simenv reads version {VERSION}",
            source=path,
            field=_VERSION_KEY,
        )
    kind = a.text("kind")
    if kind == "motion":
        return _motion(a, "")
    if kind == "interaction":
        meta = a.json("metadata")
        return Interaction(
            _motion(a, "actor/"),
            _motion(a, "reactor/"),
            label=a.json("label"),
            roles_known=bool(a.get("roles_known")),
            name=a.text("name"),
            metadata=meta if isinstance(meta, dict) else {},
        )
    raise FormatError(
        f"unknown kind {kind!r}; expected 'motion' or 'interaction'", source=path, field="kind"
    )

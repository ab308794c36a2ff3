"""Human3.6M 17-joint position arrays: a (T, 17, 3) array (or (T, 51)) in
memory, ``.npy``, or ``.npz`` holding one such array.

Joint order: :data:`simenv.core.skeletons.H36M_JOINTS` (the 17-joint subset used by
VideoPose3D and most 3D-pose papers). Two coordinate frames are accepted:

* ``frame="world"`` (default): H36M's world frame, **Z up**, floor at z ~ 0
  (both the raw ``D3_Positions`` and VideoPose3D's ``positions``): used as is.
* ``frame="camera"``: an H36M camera frame (OpenCV convention: x right,
  y **down**, z forward). It is turned into the Kinect convention by a
  180 deg rotation about the optical axis (``x, y -> -x, -y``, a proper
  rotation) and levelled from the feet like every sensor-frame source
  (:mod:`simenv.io.camera_frame`).

Units: H36M ships millimetres, most derived arrays metres. ``units="auto"``
takes millimetres when the median per-frame extent exceeds
:data:`MM_EXTENT_THRESHOLD` (a person is < 3.5 m tall; 10 "metres" is
certainly mm), else metres; ``"mm"``/``"m"`` force it. H36M is 50 fps;
the papers' 25 fps variants (every 2nd frame) need ``fps=25``.

``.npz`` files are read without pickle (object arrays, e.g. VideoPose3D's
nested dict archives, are refused with a clear error); with several arrays,
``key=`` picks one.
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Literal

import numpy as np

from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Motion
from simenv.core.skeletons import h36m_skeleton
from simenv.io.camera_frame import world_motion

#: Extensions this reader claims when no sniffer accepts a file (so a broken
#: ``.npy`` gets this reader's precise error). ``.npz`` is shared with
#: simenv's own format and is not claimed.
EXTENSIONS = (".npy",)
H36M_FPS = 50.0
N_JOINTS = 17
#: Median per-frame extent above which ``units="auto"`` means millimetres.
MM_EXTENT_THRESHOLD = 10.0
_NPY_MAGIC = b"\x93NUMPY"


def _shape_ok(shape: tuple[int, ...]) -> bool:
    return (len(shape) == 3 and shape[1:] == (N_JOINTS, 3)) or (
        len(shape) == 2 and shape[1] == N_JOINTS * 3)


def sniff(path: Path, head: bytes) -> bool:
    """A ``.npy`` holding a (T, 17, 3) or (T, 51) array, or an ``.npz`` with
    exactly one such array and no ``joint_names`` entry (that is simenv's
    own NPZ format)."""
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy" and head.startswith(_NPY_MAGIC):
            arr = np.load(path, mmap_mode="r", allow_pickle=False)
            return _shape_ok(arr.shape)
        if suffix == ".npz" and zipfile.is_zipfile(path):
            with np.load(path, allow_pickle=False) as z:
                if "joint_names" in z.files or "simenv_npz_version" in z.files:
                    return False
                return sum(_shape_ok(z[k].shape) for k in z.files) == 1
    except Exception:  # any unreadable file is simply not ours
        return False
    return False


def from_array(
    array: np.ndarray,
    *,
    fps: float = H36M_FPS,
    frame: Literal["world", "camera"] = "world",
    units: Literal["auto", "m", "mm"] = "auto",
    name: str = "h36m",
    source: str | None = None,
) -> Motion:
    """H36M-17 :class:`Motion` from a (T, 17, 3) or (T, 51) array (see module
    docstring for ``frame`` and ``units``)."""
    arr = np.asarray(array)
    if not np.issubdtype(arr.dtype, np.number):
        raise MotionError(f"expected a numeric array, got dtype {arr.dtype}", source=source)
    if arr.ndim == 2 and arr.shape[1] == N_JOINTS * 3:
        arr = arr.reshape(len(arr), N_JOINTS, 3)
    if not _shape_ok(arr.shape) or arr.shape[0] == 0:
        raise MotionError(
            f"array has shape {arr.shape}; expected (T, {N_JOINTS}, 3) or (T, {N_JOINTS * 3}) "
            f"H36M-17 joint positions with T >= 1",
            source=source,
        )
    arr = arr.astype(np.float64)
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        raise MotionError("non-finite joint position", source=source, frame=int(bad[0, 0]),
                          field=h36m_skeleton().joint_names[bad[0, 1]])
    extent = float(np.median(np.ptp(arr, axis=1).max(axis=1)))
    if units == "auto":
        units = "mm" if extent > MM_EXTENT_THRESHOLD else "m"
    if units not in ("m", "mm"):
        raise ValueError(f"units must be 'auto', 'm' or 'mm', got {units!r}")
    if units == "mm":
        arr = arr / 1000.0
    meta: dict[str, object] = {"source": source, "format": "h36m", "units": units,
                               "frame": frame, "repairs": []}
    skeleton = h36m_skeleton()
    if frame == "world":
        return Motion(arr, fps, skeleton, name, meta)
    if frame == "camera":
        kinect = arr * np.array([-1.0, -1.0, 1.0])
        return world_motion(kinect, skeleton, fps=fps, name=name, metadata=meta, source=source)
    raise ValueError(f"frame must be 'world' or 'camera', got {frame!r}")


def read(
    path: Path,
    *,
    key: str | None = None,
    fps: float = H36M_FPS,
    frame: Literal["world", "camera"] = "world",
    units: Literal["auto", "m", "mm"] = "auto",
) -> Motion:
    """Read a ``.npy``/``.npz`` H36M-17 array file (see :func:`from_array`)."""
    path = Path(path)
    try:
        loaded = np.load(path, allow_pickle=False)
    except ValueError as exc:
        raise FormatError(f"cannot load without pickle ({exc}); expected a plain numeric array",
                          source=path) from None
    except Exception as exc:  # numpy raises many types for corrupt headers
        raise FormatError(f"not a readable .npy/.npz file ({type(exc).__name__}: {exc})",
                          source=path) from None
    if isinstance(loaded, np.lib.npyio.NpzFile):
        with loaded as z:
            try:
                shapes = {k: z[k].shape for k in z.files}
            except ValueError as exc:  # object arrays need pickle: refused
                raise FormatError(f"cannot load without pickle ({exc}); expected plain "
                                  "numeric arrays", source=path) from None
            except Exception as exc:  # corrupt member (zlib, truncated zip, header)
                raise FormatError(f"corrupt .npz member ({type(exc).__name__}: {exc})",
                                  source=path) from None
            if key is None:
                keys = [k for k, shape in shapes.items() if _shape_ok(shape)]
                if len(keys) != 1:
                    raise FormatError(
                        f"expected exactly one (T, 17, 3) array, found {len(keys)} among "
                        f"{', '.join(z.files) or 'no arrays'}; pass key=",
                        source=path,
                    )
                key = keys[0]
            if key not in z.files:
                raise FormatError(f"no array {key!r}; arrays: {', '.join(z.files)}",
                                  source=path, field=key)
            try:
                array = z[key]
            except Exception as exc:
                raise FormatError(f"corrupt .npz member ({type(exc).__name__}: {exc})",
                                  source=path, field=key) from None
    else:
        array = loaded
    return from_array(array, fps=fps, frame=frame, units=units, name=path.stem,
                      source=str(path))

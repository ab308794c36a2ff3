"""HumanML3D ``new_joint_vecs`` (T, 263) and KIT-ML (T, 251) feature vectors:
joint positions recovered from the root velocity and the rotation-invariant
coordinates (RIC), the representation text-to-motion models (MDM, T2M-GPT,
MoMask, ...) emit before converting to joints.

Layout of one row, for a skeleton of J joints (github.com/EricGuo5513/HumanML3D,
``motion_representation.ipynb`` ``process_file``; MDM
``data_loaders/humanml/scripts/motion_process.py``), width 4 + 9 (J-1) + 3 J + 4:

=========================  ==========  ============================================
columns                    width       meaning
=========================  ==========  ============================================
``root_angular_velocity``  1           yaw change from this frame to the next,
                                       stored as a *half* angle (rad; the y part
                                       ``arcsin(q_y)`` of the yaw quaternion)
``root_linear_velocity``   2           root (x, z) step to the next frame, in the
                                       next frame's facing frame
``root_height``            1           root y above the floor
``ric``                    3 (J-1)     joints 1..J-1 in the root's facing frame:
                                       x, z relative to the root, y absolute
``rot6d``                  6 (J-1)     joint rotations (continuous 6D)
``local_velocity``         3 J         joint velocities in the facing frame
``foot_contact``           4           left then right foot contact flags
=========================  ==========  ============================================

HumanML3D (22 SMPL joints) is 263 wide, KIT-ML (21 MMM joints) 251. Facing frame:
Y up, the body facing +Z. The file's floor is its lowest joint over the clip.

Recovery (:func:`recover_positions`, the math of HumanML3D's ``recover_from_ric``):
the yaw half-angle ``a_t`` is the cumulative sum of column 0 over the frames
before t (``a_0 = 0``), and a facing-frame vector v is turned into the world by
the rotation of ``-2 a_t`` about +Y. The root's (x, z) is the cumulative sum of
the turned steps (step t uses frame t-1's velocity and frame t's yaw), its y is
``root_height``; every other joint is the root's (x, z) plus its turned RIC.
Only the root columns and ``ric`` are used (as ``recover_from_ric`` does);
rotations, velocities and contacts are ignored. On HumanML3D's sample clip
012314 the recovered joints match its ``new_joints`` file to 2e-4 mm (float32).

Datasets (:data:`HUMANML3D`, :data:`KITML`):

* **HumanML3D**: metres, 20 fps, the ``smpl22`` skeleton; the Y-up frame is
  right-handed (see :mod:`simenv.io.humanml3d`).
* **KIT-ML**: 12.5 fps (100 Hz capture, every 8th frame kept), the 21-joint MMM
  skeleton of :func:`kit21_skeleton`. *Units*: KIT-ML joints are not the
  actor's millimetres: every clip is retargeted onto one height-normalised MMM
  body (``uniform_skeleton`` to clip 03950), whose mean root height in KIT-ML's
  mean feature row (as MDM ships it) is 559.6 units. simenv reads 1 unit as 0.75/480 m
  (:data:`KIT_METRES_PER_UNIT`, 1.5625 mm: the MMM-to-SMPL-H factor defined by
  TEMOS and reused by MLD and MotionGPT), a 0.87 m mean root height; read as
  millimetres the body would be a 1 m child. Limb lengths of the mean pose
  suggest 1.5-1.8 mm per unit, so the size is uncertain by about 10 %;
  ``units=`` overrides it. *Handedness*: the stored KIT-ML bodies are mirrored.
  MMM names joints 5-7 and 11-15 ``LS LE LW`` and ``LH LK LA LMrot LF`` (the
  source files' order, as the MDM and TEMOS maintainers list it), and
  HumanML3D's own ``kit_raw_offsets`` put them along +X with the toes along +Z
  (a right-handed body), yet in the stored features those joints lie at -X
  while the toes point +Z; MLD's renderer negates an axis of MMM joints to
  "make left/right correct". simenv negates x on reading (noted in
  ``metadata["quirks"]``) so MMM's left joints are on the body's left.

Reading into simenv: positions in metres, mirrored back for KIT-ML, then Y up
turned Z up by :data:`simenv.io.humanml3d.Y_UP_TO_Z_UP` (a proper rotation).

Normalised arrays: models work on features z-scored with the dataset's
``Mean.npy`` / ``Std.npy``; ``new_joint_vecs`` files are raw. Pass ``mean=``
and ``std=`` (arrays or ``.npy`` paths) to read a normalised array
(``features * std + mean``). A raw array is checked for two things no raw file
can hold (:func:`normalised_evidence`): a ``root_angular_velocity`` beyond
pi/2 (it is an arcsin), or a ``root_height`` below the floor in most frames
(the floor is the clip's lowest joint). Either one is reported as a
normalised array (a :class:`FormatError`), never repaired by guessing
statistics. On HumanML3D's sample clips 012314 and 000612 normalised with the
dataset's statistics, every window of 10, 20 or 40 frames shows at least one of
the two, the raw clips neither. An array that shows neither is read as raw;
when it is not a body, the person-size check fails with a :class:`UnitsError`
that names normalisation (read as raw, the two normalised clips span 3.8 and
4.1 m, beyond the 3.5 m limit), though a normalised clip could also pass it.
``check_raw=False`` skips the check for a raw array it misjudges.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import FormatError, MotionError, UnitsError
from simenv.core.motion import MAX_PERSON_EXTENT_M, MIN_PERSON_EXTENT_M, Motion
from simenv.core.skeletons import Skeleton, kit21_skeleton, smpl22_skeleton
from simenv.io.humanml3d import (
    UNIT_SCALE,
    Y_UP_TO_Z_UP,
    Units,
    load_plain_npy,
    npy_header,
)

FORMAT = "humanml3d_features"
EXTENSIONS = (".npy",)

#: KIT-ML length unit in metres (TEMOS's ``mmm_to_smplh_scaling_factor``, also in MLD and
#: MotionGPT).
KIT_METRES_PER_UNIT = 0.75 / 480

def feature_width(n_joints: int) -> int:
    """Row width of the representation for ``n_joints`` joints."""
    return 4 + 9 * (n_joints - 1) + 3 * n_joints + 4


def feature_columns(n_joints: int) -> tuple[tuple[str, slice], ...]:
    """(name, column slice) of each feature group, in row order."""
    widths = (("root_angular_velocity", 1), ("root_linear_velocity", 2), ("root_height", 1),
              ("ric", 3 * (n_joints - 1)), ("rot6d", 6 * (n_joints - 1)),
              ("local_velocity", 3 * n_joints), ("foot_contact", 4))
    out, start = [], 0
    for name, width in widths:
        out.append((name, slice(start, start + width)))
        start += width
    return tuple(out)


@dataclass(frozen=True)
class FeatureSet:
    """One dataset's variant of the representation.

    Attributes:
        name: dataset name used in messages.
        n_joints: J.
        fps: frames per second of its files.
        metres_per_unit: length of one file unit in metres.
        mirrored: the stored bodies are mirrored (x is negated on reading).
        skeleton: the joint layout.
        fmt: ``metadata["format"]`` of clips read from it.
    """

    name: str
    n_joints: int
    fps: float
    metres_per_unit: float
    mirrored: bool
    skeleton: Callable[[], Skeleton]
    fmt: str

    @property
    def width(self) -> int:
        return feature_width(self.n_joints)


HUMANML3D = FeatureSet("HumanML3D", 22, 20.0, 1.0, False, smpl22_skeleton, "humanml3d_vecs")
KITML = FeatureSet("KIT-ML", 21, 12.5, KIT_METRES_PER_UNIT, True, kit21_skeleton, "kitml_vecs")
#: Feature sets by row width (263 and 251).
BY_WIDTH: dict[int, FeatureSet] = {fs.width: fs for fs in (HUMANML3D, KITML)}

#: InterGen's per-person representation, one column short of HumanML3D's.
_INTERGEN_WIDTH = 262
_NPY_MAGIC = b"\x93NUMPY"


# -- recovery --------------------------------------------------------------------


def _yaw_matrices(half_angles: np.ndarray) -> np.ndarray:
    """(T, 3, 3) rotations by ``-2 a`` about +Y: facing frame -> world."""
    theta = -2.0 * half_angles
    c, s = np.cos(theta), np.sin(theta)
    rot = np.zeros((len(theta), 3, 3))
    rot[:, 0, 0], rot[:, 0, 2], rot[:, 1, 1], rot[:, 2, 0], rot[:, 2, 2] = c, s, 1.0, -s, c
    return rot


def recover_positions(features: np.ndarray, n_joints: int) -> np.ndarray:
    """Joint positions from raw (not normalised) feature rows.

    Args:
        features: (T, D) raw features, D >= 4 + 3 (J-1) (only the root columns
            and ``ric`` are read), lengths in the file's unit.
        n_joints: J.

    Returns:
        (T, J, 3) float64 positions in the file's frame (Y up) and unit.
    """
    f = np.asarray(features, dtype=np.float64)
    t = len(f)
    half = np.concatenate([[0.0], np.cumsum(f[:-1, 0])])
    rot = _yaw_matrices(half)
    step = np.zeros((t, 3))
    step[1:, [0, 2]] = f[:-1, 1:3]  # frame t-1's velocity, turned by frame t's yaw
    root = np.cumsum(np.einsum("tij,tj->ti", rot, step), axis=0)
    root[:, 1] = f[:, 3]
    ric = f[:, 4: 4 + 3 * (n_joints - 1)].reshape(t, n_joints - 1, 3)
    joints = np.einsum("tij,tkj->tki", rot, ric)
    joints[..., 0] += root[:, None, 0]
    joints[..., 2] += root[:, None, 2]
    return np.concatenate([root[:, None], joints], axis=1)


# -- checks ------------------------------------------------------------------------


def normalised_evidence(features: np.ndarray) -> str | None:
    """Why a (T, D) array cannot be raw features, or None if nothing shows it.

    Raw rows hold ``arcsin`` values in column 0 (within +-pi/2) and the root's
    height above the clip's lowest joint in column 3 (positive); z-scored rows
    break one or the other.
    """
    f = np.asarray(features, dtype=np.float64)
    ang = np.abs(f[:, 0])
    if ang.max() > np.pi / 2:
        t = int(ang.argmax())
        return (f"root_angular_velocity reaches {f[t, 0]:.3g} at frame {t}; a raw value is an "
                "arcsin, within +-pi/2")
    height = float(np.median(f[:, 3]))
    if height < 0:
        below = int((f[:, 3] < 0).sum())
        return (f"root_height is below the floor in {below} of {len(f)} frames (median "
                f"{height:.3g}); raw files put the floor at the clip's lowest joint")
    return None


def _statistic(value: np.ndarray | str | Path, name: str, width: int) -> np.ndarray:
    """A (width,) mean or std given as an array or a ``.npy`` path."""
    if isinstance(value, (str, Path)):
        arr = load_plain_npy(Path(value))
        source: str | None = str(value)
    else:
        arr, source = np.asarray(value), None
    if not np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.complexfloating):
        raise FormatError(f"{name} has dtype {arr.dtype}; expected real numbers", source=source,
                          field=name)
    if arr.shape != (width,):
        raise FormatError(f"{name} has shape {arr.shape}; expected ({width},), one value per "
                          "feature column (the dataset's Mean.npy / Std.npy)", source=source,
                          field=name)
    arr = arr.astype(np.float64)
    ok = np.isfinite(arr) & ((arr > 0) if name == "std" else True)
    if not ok.all():
        bad = int(np.flatnonzero(~ok)[0])
        want = "finite positive values" if name == "std" else "finite values"
        raise FormatError(f"{name}[{bad}] = {float(arr[bad])!r}; expected {want}", source=source,
                          field=name)
    return arr


def _metres_per_unit(units: Units | float | None, fs: FeatureSet) -> float:
    if units is None:
        return fs.metres_per_unit
    if isinstance(units, str):
        if units not in UNIT_SCALE:
            raise ValueError(f"units must be one of {', '.join(UNIT_SCALE)}, a number of "
                             f"metres per file unit, or None; got {units!r}")
        return UNIT_SCALE[units]
    scale = float(units)
    if not np.isfinite(scale) or scale <= 0:
        raise ValueError(f"units as a number is metres per file unit (> 0); got {units!r}")
    return scale


# -- reading -----------------------------------------------------------------------


def from_features(
    features: np.ndarray,
    *,
    mean: np.ndarray | str | Path | None = None,
    std: np.ndarray | str | Path | None = None,
    fps: float | None = None,
    units: Units | float | None = None,
    check_raw: bool = True,
    name: str = "features",
    source: str | None = None,
) -> Motion:
    """A :class:`Motion` (Z up, metres) from HumanML3D (T, 263) or KIT-ML (T, 251)
    feature rows.

    Args:
        features: (T, 263) or (T, 251) real numbers, raw unless ``mean``/``std``.
        mean, std: the dataset's (D,) feature statistics (arrays or ``.npy``
            paths), both or neither; given, rows are de-normalised as
            ``features * std + mean`` first.
        fps: overrides the dataset's rate (20 HumanML3D, 12.5 KIT-ML).
        units: the file's length unit: None for the dataset's own (metres;
            KIT-ML's :data:`KIT_METRES_PER_UNIT`), "m", "cm", "mm", or metres
            per unit as a number.
        check_raw: refuse arrays that look normalised (see
            :func:`normalised_evidence`).
        name, source: clip name and file for metadata and errors.

    Raises:
        FormatError: not a real numeric (T, 263) / (T, 251) array; mean/std
            malformed or only one given; a normalised array read as raw.
        MotionError: fewer than 2 frames; a non-finite value (naming the first
            such frame and its feature group).
        UnitsError: the recovered body is not a person-sized body in metres.
    """
    arr = np.asarray(features)
    if not np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.complexfloating):
        raise FormatError(f"expected real numeric features, got dtype {arr.dtype}",
                          source=source, field="features")
    if arr.ndim != 2 or arr.shape[1] not in BY_WIDTH:
        hint = (" ((T, 262) is InterGen's per-person representation: keep it in person1/ and "
                "person2/ folders)" if arr.ndim == 2 and arr.shape[1] == _INTERGEN_WIDTH else "")
        raise FormatError(
            f"features have shape {arr.shape}; expected (T, 263) HumanML3D or (T, 251) KIT-ML "
            f"new_joint_vecs rows{hint}", source=source, field="features")
    fs = BY_WIDTH[arr.shape[1]]
    if len(arr) < 2:
        raise MotionError(f"clip has {len(arr)} frame(s); expected at least 2 (a motion, not a "
                          "pose)", source=source, field="features")
    arr = arr.astype(np.float64)
    bad_rows = ~np.isfinite(arr).all(axis=1)
    if bad_rows.any():
        t = int(np.flatnonzero(bad_rows)[0])
        col = int(np.flatnonzero(~np.isfinite(arr[t]))[0])
        group = next(g for g, cols in feature_columns(fs.n_joints) if cols.start <= col < cols.stop)
        raise MotionError(
            f"non-finite value (NaN/inf) in column {col} ({group}) and in "
            f"{int(bad_rows.sum())} of {len(arr)} rows; expected finite {fs.name} features",
            source=source, frame=t, field=group)
    if (mean is None) != (std is None):
        raise FormatError("pass both mean= and std= (the dataset's Mean.npy and Std.npy) to "
                          "de-normalise, or neither for raw features", source=source,
                          field="mean" if mean is None else "std")
    normalised = mean is not None
    if normalised:
        arr = arr * _statistic(std, "std", fs.width) + _statistic(mean, "mean", fs.width)
    why = normalised_evidence(arr) if check_raw else None
    if why is not None and normalised:
        raise FormatError(
            f"de-normalised with the given mean and std, these {fs.name} features are still not "
            f"raw: {why}. Are mean and std this dataset's Mean.npy and Std.npy?",
            source=source, field="features")
    if why is not None:
        raise FormatError(
            f"these {fs.name} features look normalised (z-scored), not raw: {why}. Pass the "
            "dataset's statistics (mean='Mean.npy', std='Std.npy') to de-normalise them, "
            "or check_raw=False if they really are raw", source=source, field="features")
    scale = _metres_per_unit(units, fs)
    pos = recover_positions(arr, fs.n_joints) * scale
    if fs.mirrored:
        pos[..., 0] = -pos[..., 0]
    extent = float(np.median(np.ptp(pos, axis=1).max(axis=1)))
    if not MIN_PERSON_EXTENT_M <= extent <= MAX_PERSON_EXTENT_M:
        raise UnitsError(
            f"the recovered body spans {extent:.4g} m (median over frames) at {scale:g} m per "
            f"file unit; expected {MIN_PERSON_EXTENT_M}-{MAX_PERSON_EXTENT_M} m. Are the "
            "features normalised (pass mean= and std=), or in other units (pass units=)?",
            source=source, field="ric")
    quirks = []
    if fs.mirrored:
        quirks.append(f"{fs.name} bodies are stored mirrored: x negated so that MMM's left "
                      "joints (LS, LH, ...) are on the body's left")
    meta: dict[str, Any] = {
        "source": source, "format": fs.fmt, "dataset": fs.name, "up_axis": "y",
        "units": units if isinstance(units, str) else "m" if scale == 1.0 else f"{scale:g} m",
        "denormalised": normalised, "quirks": quirks,
        "unused_features": ["rot6d", "local_velocity", "foot_contact"],
    }
    return Motion((pos @ Y_UP_TO_Z_UP.T).astype(np.float32),
                  fs.fps if fps is None else float(fps), fs.skeleton(), name, meta)


def sniff(path: Path, head: bytes) -> bool:
    """A plain ``.npy`` of (T, 263) or (T, 251) numbers outside InterGen's
    ``person1``/``person2`` folders."""
    path = Path(path)
    if path.suffix.lower() != ".npy" or not head.startswith(_NPY_MAGIC):
        return False
    if path.parent.name.lower() in ("person1", "person2"):
        return False
    header = npy_header(path)
    if header is None:
        return False
    shape, dtype = header
    return not dtype.hasobject and len(shape) == 2 and shape[1] in BY_WIDTH


def read(
    path: Path,
    *,
    mean: np.ndarray | str | Path | None = None,
    std: np.ndarray | str | Path | None = None,
    fps: float | None = None,
    units: Units | float | None = None,
    check_raw: bool = True,
) -> Motion:
    """Read a HumanML3D ``new_joint_vecs`` (T, 263) or KIT-ML (T, 251) ``.npy``
    (no pickle). Options and errors: see :func:`from_features`."""
    path = Path(path)
    return from_features(load_plain_npy(path), mean=mean, std=std, fps=fps, units=units,
                         check_raw=check_raw, name=path.stem, source=str(path))

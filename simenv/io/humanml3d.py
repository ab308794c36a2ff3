"""HumanML3D ``new_joints`` and MDM ``results.npy``: the 22-joint SMPL body that
text-to-motion models emit as joint positions (no SMPL body model needed).

Layouts, as verified against their sources:

* **HumanML3D** ``new_joints/<id>.npy`` (github.com/EricGuo5513/HumanML3D,
  sample ``HumanML3D/new_joints/012314.npy``: float32 (170, 22, 3)): one clip
  per file, a plain (T, 22, 3) array of joint positions in **metres**,
  **Y up** (floor at y = 0), 20 fps (README: "Motions are downsampled into
  20 fps"; ``raw_pose_processing.ipynb``: ``ex_fps = 20``). Joints in SMPL order
  (:data:`simenv.core.skeletons.SMPL22_JOINTS`), parents from
  ``t2m_kinematic_chain`` (``src/humanml3d/skeletons.py``). The frame is
  right-handed: HumanML3D maps AMASS's Z-up world by swapping y and z *and*
  negating x (``raw_pose_processing.ipynb``: ``trans_matrix`` then
  ``data[..., 0] *= -1``: a proper rotation), and the sample clip's bodies are
  not mirrored (the toes point along up x (right hip - left hip), as in a
  right-handed frame).
  ``new_joint_vecs`` (T, 263) are features, not positions: read by
  :mod:`simenv.io.humanml3d_features`, which recovers the positions.
* **MDM** ``results.npy`` (github.com/GuyTevet/motion-diffusion-model,
  ``sample/generate.py``): ``np.save`` of a dict, so a pickled 0-d object
  array, with ``motion`` (N, 22, 3, T) float32 positions in the HumanML3D
  frame (``recover_from_ric`` then ``permute(0, 2, 3, 1)``), ``text`` (N
  prompts), ``lengths`` (N,) valid frames per sample, ``num_samples`` and
  ``num_repetitions``; entry ``rep * num_samples + sample`` is repetition
  ``rep`` of prompt ``sample``; 20 fps for HumanML3D models.

Reading into simenv (:class:`Motion`, (T, 22, 3) float32 metres, **Z up**):
Y-up positions are turned by :data:`Y_UP_TO_Z_UP`, the +90 deg rotation
about x ``(x, y, z) -> (x, -z, y)``; it is proper (det +1), so handedness and
left/right are kept, and the writers apply its inverse. ``fps=`` overrides
the format's rate; ``units=`` ("m", "cm", "mm") declares files that are not
in metres (anything else outside 0.1-3.5 m per person is an error).

Pickles: HumanML3D arrays are loaded with ``allow_pickle=False``. An MDM
results file *is* a pickle; simenv unpickles only files named ``results*.npy``
and then only NumPy arrays, strings and numbers (a restricted unpickler; any
other object in the pickle is refused), never arbitrary classes.

Writers (:func:`write_humanml3d`, :func:`write_mdm_results`) take a Motion on
any skeleton that maps onto SMPL-22 (:func:`to_smpl22`) at the format's frame
rate (or ``resample=True``).
"""

from __future__ import annotations

import pickle
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np

from simenv.core.errors import FormatError, MotionError, SimenvError, SkeletonError, UnitsError
from simenv.core.motion import MAX_PERSON_EXTENT_M, MIN_PERSON_EXTENT_M, Motion
from simenv.core.skeletons import SMPL22_JOINTS, smpl22_skeleton

FORMAT = "humanml3d"
#: Claimed so that a ``.npy`` no sniffer accepts gets this reader's located error
#: (which also names the other ``.npy`` layouts simenv reads).
EXTENSIONS = (".npy",)

HUMANML3D_FPS = 20.0
MDM_FPS = 20.0
N_JOINTS = 22
#: Widths of HumanML3D's and KIT-ML's ``new_joint_vecs`` feature rows (not positions).
HML_VEC_DIM = 263
KIT_VEC_DIM = 251

#: simenv (Z up) = Y_UP_TO_Z_UP @ source (Y up): ``(x, y, z) -> (x, -z, y)``.
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

UNIT_SCALE: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001}

Up = Literal["y", "z"]
Units = Literal["m", "cm", "mm"]

#: File names whose pickled dict simenv unpickles (MDM writes ``results.npy``).
MDM_NAME = re.compile(r"^results.*\.npy$", re.IGNORECASE)

#: Rules for the SMPL joints no canonical keypoint measures, used by
#: :func:`to_smpl22` (fitted on HumanML3D sample 012314, median error ~2 cm):
#: spine2 lies 0.72 of the way from spine1 to spine3; a collar lies 0.36 of the
#: way from a pivot (0.54 of the way from spine3 to the neck) to its shoulder.
SPINE2_FRACTION = 0.72
COLLAR_PIVOT_FRACTION = 0.54
COLLAR_FRACTION = 0.36

_NPY_MAGIC = b"\x93NUMPY"
_OTHER_NPY = "(T, 17, 3) or (T, 51) Human3.6M-17"


# -- array layer ---------------------------------------------------------------


def npy_header(path: Path) -> tuple[tuple[int, ...], np.dtype] | None:
    """(shape, dtype) of a ``.npy`` file from its header, without reading the
    data (nothing is unpickled); None when it is not a readable ``.npy``."""
    fmt = np.lib.format
    try:
        with Path(path).open("rb") as fh:
            version = fmt.read_magic(fh)
            if version == (1, 0):
                shape, _, dtype = fmt.read_array_header_1_0(fh)
            elif version == (2, 0):
                shape, _, dtype = fmt.read_array_header_2_0(fh)
            else:
                return None
    except (OSError, ValueError, SyntaxError):
        return None
    return tuple(int(n) for n in shape), dtype


def _layout_error(shape: tuple[int, ...], source: str | None, what: str) -> SimenvError:
    """The clearest error for an array that is not (T, 22, 3) positions."""
    where = f"{what} " if what else ""
    if len(shape) == 2 and shape[1] in (HML_VEC_DIM, KIT_VEC_DIM):
        return FormatError(
            f"{where}has shape {shape}: HumanML3D / KIT-ML new_joint_vecs features (root "
            "velocity, local joint data, foot contacts), not joint positions; simenv.load reads "
            "such a file, or simenv.io.humanml3d_features.from_features such an array",
            source=source, field="positions")
    if len(shape) == 3:
        t, a, b = shape
        if (a, b) == (3, N_JOINTS):
            return FormatError(
                f"{where}has shape {shape}, i.e. (T, 3, 22): coordinates before joints; "
                "expected (T, 22, 3) (transpose with array.transpose(0, 2, 1))",
                source=source, field="positions")
        if (t, a) == (N_JOINTS, 3):
            return FormatError(
                f"{where}has shape {shape}, i.e. MDM's per-sample (22, 3, T) axes; a "
                "HumanML3D clip is (T, 22, 3) (transpose with array.transpose(2, 0, 1))",
                source=source, field="positions")
        if b == 3:
            hint = {21: " (21 joints is the KIT-ML skeleton, not supported)",
                    24: " (24 is the full SMPL skeleton: keep joints [:, :22])",
                    52: " (52 is SMPL-H: keep joints [:, :22])",
                    55: " (55 is SMPL-X: keep joints [:, :22])"}.get(a, "")
            return MotionError(
                f"{where}has {a} joints per frame (shape {shape}); expected the 22 SMPL body "
                f"joints of HumanML3D/MDM/InterGen, shape (T, 22, 3){hint}",
                source=source, field="positions")
    if len(shape) == 4:
        return FormatError(
            f"{where}is a 4-D array {shape}: a batch? A HumanML3D file holds one clip "
            "(T, 22, 3); MDM batches are results.npy dicts with motion (N, 22, 3, T)",
            source=source, field="positions")
    return FormatError(
        f"{where}has shape {shape}; expected (T, 22, 3) SMPL-22 joint positions (HumanML3D "
        f"new_joints). Other .npy layouts simenv reads: {_OTHER_NPY}; InterGen per-person "
        "files in person1/ and person2/ folders", source=source, field="positions")


def _units_error(extent: float, units: str, fmt: str, source: str | None) -> UnitsError:
    if units == "m" and 100 <= extent <= 250:
        guess = f" It looks like centimetres (a {extent / 100:.2f} m person): pass units='cm'."
    elif units == "m" and 1000 <= extent <= 2500:
        guess = f" It looks like millimetres (a {extent / 1000:.2f} m person): pass units='mm'."
    else:
        guess = ""
    return UnitsError(
        f"median person extent is {extent:.4g} m with units={units!r}; expected "
        f"{MIN_PERSON_EXTENT_M}-{MAX_PERSON_EXTENT_M} m ({fmt} stores metres).{guess}",
        source=source, field="positions")


def from_array(
    array: np.ndarray,
    *,
    fps: float = HUMANML3D_FPS,
    up: Up = "y",
    units: Units = "m",
    name: str = "humanml3d",
    source: str | None = None,
    fmt: str = FORMAT,
    what: str = "",
    metadata: dict[str, Any] | None = None,
) -> Motion:
    """SMPL-22 :class:`Motion` (Z up, metres) from joint positions.

    Args:
        array: (T, 22, 3) or (T, 66) positions, ``up`` axis up, in ``units``.
        fps: frames per second. up: "y" (HumanML3D, MDM, InterGen output) or
            "z" (already Z up, e.g. raw InterHuman). units: "m", "cm", "mm".
        name, source, fmt: clip name, file, format name for metadata/errors.
        what: names the array inside the file in errors (e.g. "sample 3").
        metadata: extra metadata entries.

    Raises:
        FormatError: non-numeric array or wrong axis layout.
        MotionError: wrong joint count, fewer than 2 frames, NaN/inf (naming
            the first bad frame and joint).
        UnitsError: positions not plausible metres after ``units``.
    """
    arr = np.asarray(array)
    where = f"{what}: " if what else ""
    if not np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.complexfloating):
        raise FormatError(f"{where}expected a real numeric array, got dtype {arr.dtype}",
                          source=source, field="positions")
    if arr.ndim == 2 and arr.shape[1] == N_JOINTS * 3:
        arr = arr.reshape(len(arr), N_JOINTS, 3)
    if arr.ndim != 3 or arr.shape[1:] != (N_JOINTS, 3):
        raise _layout_error(arr.shape, source, what)
    if arr.shape[0] < 2:
        raise MotionError(
            f"{where}clip has {arr.shape[0]} frame(s); expected at least 2 (a motion, "
            "not a pose)", source=source, field="positions")
    arr = arr.astype(np.float64)
    bad = ~np.isfinite(arr).all(axis=2)
    if bad.any():
        t, j = np.argwhere(bad)[0]
        raise MotionError(
            f"{where}non-finite position (NaN/inf) in {int(bad.any(axis=1).sum())} of "
            f"{len(arr)} frames; expected finite metres", source=source, frame=int(t),
            field=SMPL22_JOINTS[j])
    if units not in UNIT_SCALE:
        raise ValueError(f"units must be one of {', '.join(UNIT_SCALE)}; got {units!r}")
    arr = arr * UNIT_SCALE[units]
    extent = float(np.median(np.ptp(arr, axis=1).max(axis=1)))
    if not MIN_PERSON_EXTENT_M <= extent <= MAX_PERSON_EXTENT_M:
        raise _units_error(extent, units, fmt, source)
    if up == "y":
        arr = arr @ Y_UP_TO_Z_UP.T
    elif up != "z":
        raise ValueError(f"up must be 'y' or 'z'; got {up!r}")
    meta: dict[str, Any] = {"source": source, "format": fmt, "units": units, "up_axis": up,
                            "quirks": [], **(metadata or {})}
    # A mis-declared up axis leaves the head beside or below the pelvis; say so (a
    # handstand clip can do that too, so it is a note, not an error).
    head_up = arr[:, SMPL22_JOINTS.index("head"), 2] - arr[:, 0, 2]
    if np.median(head_up) < 0.1:
        meta["quirks"].append(
            f"the head is not above the pelvis in most frames (median {np.median(head_up):.2f} "
            f"m along up): is the file really {up.upper()}-up? (pass up='y' or up='z')")
    return Motion(arr.astype(np.float32), float(fps), smpl22_skeleton(), name, meta)


# -- HumanML3D files ------------------------------------------------------------


def _is_pickle_header(header: tuple[tuple[int, ...], np.dtype] | None) -> bool:
    return header is not None and header[1].hasobject and header[0] == ()


def sniff(path: Path, head: bytes) -> bool:
    """A ``.npy`` holding (T, 22, 3) numbers, or an MDM pickled dict named
    ``results*.npy``. Files in ``person1``/``person2`` folders are left to
    :mod:`simenv.io.intergen`, feature rows to :mod:`simenv.io.humanml3d_features`."""
    path = Path(path)
    if path.suffix.lower() != ".npy" or not head.startswith(_NPY_MAGIC):
        return False
    header = npy_header(path)
    if header is None:
        return False
    if _is_pickle_header(header):
        return bool(MDM_NAME.match(path.name))
    shape, dtype = header
    if dtype.hasobject or path.parent.name.lower() in ("person1", "person2"):
        return False
    return len(shape) == 3 and shape[1:] == (N_JOINTS, 3)


def load_plain_npy(path: Path) -> np.ndarray:
    """A ``.npy`` array loaded without pickle, errors as :class:`FormatError`."""
    try:
        return np.load(path, allow_pickle=False)
    except ValueError as exc:
        if "pickle" in str(exc).lower():
            raise FormatError(
                "holds pickled Python objects, which simenv does not unpickle here (a pickle "
                "can run code); expected a plain numeric array. MDM result dicts are read "
                "only from files named results*.npy", source=path) from None
        raise FormatError(f"not a readable .npy file ({exc})", source=path) from None
    except Exception as exc:  # numpy raises many types for corrupt headers/truncation
        raise FormatError(f"not a readable .npy file ({type(exc).__name__}: {exc})",
                          source=path) from None


def read(
    path: Path,
    *,
    fps: float | None = None,
    units: Units = "m",
    up: Up = "y",
) -> Motion | list[Motion]:
    """Read a HumanML3D ``new_joints`` ``.npy`` (one Motion) or an MDM
    ``results*.npy`` (one Motion per sample, see :func:`read_mdm_results`).

    Args:
        fps: overrides the format's 20 fps. units: see :func:`from_array`.
        up: the file's up axis (both formats are Y up).

    Raises:
        FormatError, MotionError, UnitsError: see :func:`from_array`; a
            pickled file not named ``results*.npy`` is refused.
    """
    path = Path(path)
    header = npy_header(path)
    if _is_pickle_header(header) and MDM_NAME.match(path.name):
        return read_mdm_results(path, fps=fps, units=units, up=up)
    arr = load_plain_npy(path)
    return from_array(arr, fps=HUMANML3D_FPS if fps is None else fps, up=up, units=units,
                      name=path.stem, source=str(path), fmt=FORMAT)


# -- MDM results.npy ------------------------------------------------------------


def _numpy_globals() -> dict[tuple[str, str], Any]:
    # The exact objects np.save's pickles reference (NumPy 1 and 2 module paths).
    reconstruct = np.zeros(1).__reduce__()[0]
    scalar = np.int64(0).__reduce__()[0]
    allowed: dict[tuple[str, str], Any] = {("numpy", "ndarray"): np.ndarray,
                                           ("numpy", "dtype"): np.dtype}
    for mod in ("numpy.core.multiarray", "numpy._core.multiarray"):
        allowed[(mod, "_reconstruct")] = reconstruct
        allowed[(mod, "scalar")] = scalar
    return allowed


class _NumpyOnlyUnpickler(pickle.Unpickler):
    """Unpickles NumPy arrays, dicts, lists, strings and numbers only."""

    _allowed = _numpy_globals()

    def find_class(self, module: str, name: str) -> Any:
        try:
            return self._allowed[(module, name)]
        except KeyError:
            raise pickle.UnpicklingError(
                f"refusing to unpickle {module}.{name}: an MDM results file holds only NumPy "
                "arrays, lists, strings and numbers") from None


def _load_mdm_dict(path: Path) -> dict[str, Any]:
    try:
        with path.open("rb") as fh:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                np.lib.format.read_array_header_1_0(fh)
            elif version == (2, 0):
                np.lib.format.read_array_header_2_0(fh)
            else:
                raise ValueError(f"unsupported .npy version {version}")
            obj = _NumpyOnlyUnpickler(fh, encoding="latin1").load()
    except (pickle.UnpicklingError, ValueError, EOFError, OSError, AttributeError,
            TypeError, IndexError) as exc:
        raise FormatError(f"not a readable MDM results file ({exc})", source=path) from None
    if isinstance(obj, np.ndarray) and obj.dtype.hasobject and obj.shape == ():
        obj = obj.item()
    if not isinstance(obj, dict):
        raise FormatError(
            f"holds a pickled {type(obj).__name__}; expected MDM's dict with 'motion', "
            "'text', 'lengths', 'num_samples', 'num_repetitions'", source=path)
    return obj


def read_mdm_results(
    path: Path,
    *,
    fps: float | None = None,
    units: Units = "m",
    up: Up = "y",
) -> list[Motion]:
    """Read MDM's ``results.npy``: one Motion per generated sample.

    Each sample ``i`` is ``motion[i].transpose(2, 0, 1)[:lengths[i]]``; it is
    named ``<stem>_sampleSS_repRR`` (SS = prompt index ``i % num_samples``,
    RR = repetition ``i // num_samples``, as MDM names its videos) and its
    metadata holds ``text``, ``sample``, ``repetition`` and ``index``.

    Security: the file is a pickle. It is read only when named
    ``results*.npy``, through an unpickler that admits NumPy arrays, lists,
    strings and numbers and refuses every other class.

    Raises:
        FormatError: not a dict, no ``motion``, wrong axis layout (e.g.
            (N, T, 22, 3)), ``lengths``/``text`` inconsistent with N and T.
        MotionError, UnitsError: a sample's positions (see :func:`from_array`),
            naming the sample.
    """
    path = Path(path)
    if not MDM_NAME.match(path.name):
        raise FormatError(
            "simenv unpickles MDM results only from files named results*.npy (a pickle can "
            "run code); rename the file if you trust it", source=path)
    data = _load_mdm_dict(path)
    motion = _mdm_motion(data, path)
    n, t_max = motion.shape[0], motion.shape[3]
    if n == 0:
        raise MotionError("motion holds no samples (N = 0)", source=path, field="motion")
    lengths = np.asarray(data.get("lengths", np.full(n, t_max)))
    if lengths.shape != (n,) or not np.issubdtype(lengths.dtype, np.integer):
        raise FormatError(f"lengths has shape {lengths.shape} and dtype {lengths.dtype}; "
                          f"expected ({n},) integers, one per sample", source=path,
                          field="lengths")
    bad = np.flatnonzero((lengths < 0) | (lengths > t_max))
    if bad.size:
        raise FormatError(f"lengths[{bad[0]}] = {lengths[bad[0]]}; expected 0..{t_max} "
                          "(the frames of motion)", source=path, field="lengths")
    texts = data.get("text")
    if texts is not None:
        texts = [str(s) for s in texts]
        if len(texts) != n:
            raise FormatError(f"{len(texts)} texts for {n} samples", source=path, field="text")
    num_samples = int(data.get("num_samples", n))
    num_reps = int(data.get("num_repetitions", 1))
    if num_samples < 1 or num_samples * num_reps != n:
        # generate.py truncates to num_samples * num_repetitions, so they must agree.
        raise FormatError(f"num_samples {num_samples} x num_repetitions {num_reps} != {n} "
                          "samples in motion", source=path, field="num_samples")
    out = []
    for i in range(n):
        sample, rep = i % num_samples, i // num_samples
        text = texts[i] if texts is not None else None
        label = f"sample {i} (prompt {sample}, repetition {rep}" + (
            f", {text!r})" if text is not None else ")")
        out.append(from_array(
            motion[i].transpose(2, 0, 1)[: int(lengths[i])],
            fps=MDM_FPS if fps is None else fps, up=up, units=units,
            name=f"{path.stem}_sample{sample:02d}_rep{rep:02d}", source=str(path), fmt="mdm",
            what=label,
            metadata={"text": text, "sample": sample, "repetition": rep, "index": i},
        ))
    return out


def _mdm_motion(data: dict[str, Any], path: Path) -> np.ndarray:
    """The (N, 22, 3, T) ``motion`` entry of MDM results.

    Raises:
        FormatError: no ``motion``, not numbers, or another layout (the message names the
            layout it looks like: (N, T, 22, 3), KIT-ML's 21 joints, HumanML3D vectors).
    """
    if "motion" not in data:
        raise FormatError(f"no 'motion' entry; keys are {', '.join(map(str, data))}",
                          source=path, field="motion")
    motion = np.asarray(data["motion"])
    if not np.issubdtype(motion.dtype, np.number):
        raise FormatError(f"motion has dtype {motion.dtype}; expected numbers",
                          source=path, field="motion")
    if motion.ndim == 4 and motion.shape[1:3] == (N_JOINTS, 3):
        return motion
    shape = motion.shape
    if motion.ndim == 4 and shape[2:] == (N_JOINTS, 3):
        hint = ("this is (N, T, 22, 3); MDM stores (N, 22, 3, T) (convert with "
                "motion.transpose(0, 2, 3, 1))")
    elif motion.ndim == 4 and shape[1] == 21:
        hint = "21 joints is a KIT-ML model's output, not supported"
    elif motion.ndim == 4 and shape[1] == HML_VEC_DIM:
        hint = ("these are HumanML3D 263-feature vectors; MDM recovers positions with "
                "recover_from_ric before saving")
    else:
        hint = "expected (N, 22, 3, T) joint positions"
    raise FormatError(f"motion has shape {shape}: {hint}", source=path, field="motion")


# -- writing ------------------------------------------------------------------------


def to_smpl22(motion: Motion, *, derive_missing: bool = True) -> Motion:
    """The motion on the SMPL-22 skeleton (same frames, fps, Z up, metres).

    SMPL joints with a canonical keypoint (19 of 22) are copied from the
    source joint of that keypoint. spine2 and the two collars, which no
    canonical keypoint measures, are placed by :data:`SPINE2_FRACTION`,
    :data:`COLLAR_PIVOT_FRACTION` and :data:`COLLAR_FRACTION` and listed in
    ``metadata["derived_joints"]`` (``derive_missing=False`` refuses them).

    Raises:
        SkeletonError: the source skeleton lacks canonical keypoints SMPL-22
            needs (all named, with the SMPL joints they feed).
    """
    target = smpl22_skeleton()
    if motion.skeleton == target:
        return motion
    canon = motion.skeleton.canonical
    missing = [(k, j) for k, j in target.canonical.items() if k not in canon]
    derived = [j for j in SMPL22_JOINTS if j not in target.canonical.values()]
    if missing or not derive_missing:
        parts = []
        if missing:
            parts.append("canonical keypoint(s) " + ", ".join(f"{k} (SMPL {j})"
                                                               for k, j in missing))
        if not derive_missing:
            parts.append(f"SMPL joints {', '.join(derived)} (derive_missing=False)")
        raise SkeletonError(
            f"motion {motion.name!r} on skeleton {motion.skeleton.name!r} cannot be mapped "
            f"onto SMPL-22: it lacks {'; '.join(parts)}",
            source=motion.metadata.get("source"), field=missing[0][0] if missing else None)
    pos = motion.positions.astype(np.float64)
    out = np.zeros((motion.num_frames, N_JOINTS, 3))
    for key, joint in target.canonical.items():
        out[:, target.index(joint)] = pos[:, motion.skeleton.index(canon[key])]
    s1, s3, neck = (out[:, target.index(j)] for j in ("spine1", "spine3", "neck"))
    out[:, target.index("spine2")] = s1 + SPINE2_FRACTION * (s3 - s1)
    pivot = s3 + COLLAR_PIVOT_FRACTION * (neck - s3)
    for side in ("left", "right"):
        shoulder = out[:, target.index(f"{side}_shoulder")]
        out[:, target.index(f"{side}_collar")] = pivot + COLLAR_FRACTION * (shoulder - pivot)
    meta = dict(motion.metadata)
    meta["derived_joints"] = derived
    meta["converted_from_skeleton"] = motion.skeleton.name
    return Motion(out.astype(np.float32), motion.fps, target, motion.name, meta)


def export_positions(motion: Motion, fps: float, fmt: str, *, resample: bool = False
                     ) -> np.ndarray:
    """(T, 22, 3) float32 Y-up metres of ``motion`` for a ``fmt`` file at ``fps``.

    Raises:
        MotionError: the motion is at another rate and ``resample`` is False,
            or has fewer than 2 frames.
        SkeletonError: see :func:`to_smpl22`.
    """
    if motion.fps != fps:
        if not resample:
            raise MotionError(
                f"{fmt} files are {fps:g} fps and carry no rate of their own; motion "
                f"{motion.name!r} is at {motion.fps:g} fps (pass resample=True, or "
                f"motion.resample({fps:g}))", source=motion.metadata.get("source"))
        motion = motion.resample(fps)
    motion.require_frames(2, f"a {fmt} clip")
    smpl = to_smpl22(motion)
    # Inverse of the reader's rotation: p_y = R^T p_z, i.e. rows p_z @ R.
    return (smpl.positions.astype(np.float64) @ Y_UP_TO_Z_UP).astype(np.float32)


def _save_npy(path: Path, obj: Any, *, allow_pickle: bool) -> Path:
    # Through a handle: np.save(path) would append ".npy" to other suffixes.
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as fh:
        np.save(fh, obj, allow_pickle=allow_pickle)
    return path


def write_humanml3d(motion: Motion, path: str | Path, *, resample: bool = False) -> Path:
    """Write a HumanML3D ``new_joints`` file: (T, 22, 3) float32, metres, Y up,
    20 fps, no pickle. The motion must be at 20 fps unless ``resample``.
    Returns the path (written as given)."""
    arr = export_positions(motion, HUMANML3D_FPS, "HumanML3D", resample=resample)
    return _save_npy(Path(path), arr, allow_pickle=False)


def write_mdm_results(
    motions: Sequence[Motion],
    path: str | Path,
    *,
    texts: Sequence[str] | None = None,
    resample: bool = False,
) -> Path:
    """Write an MDM-style ``results.npy``: ``motion`` (N, 22, 3, T_max)
    float32 Y-up metres (each sample padded after its length by repeating its
    last frame), ``text`` (default: the motion names), ``lengths`` (N,)
    int64, ``num_samples`` N and ``num_repetitions`` 1. 20 fps.

    Raises:
        ValueError: the file name is not ``results*.npy`` (the reader would
            refuse to unpickle it), no motions, or texts of the wrong length.
    """
    path = Path(path)
    if not MDM_NAME.match(path.name):
        raise ValueError(f"{path}: name an MDM results file results*.npy (simenv unpickles "
                         "only those)")
    if not motions:
        raise ValueError("write_mdm_results needs at least one motion")
    texts = [m.name for m in motions] if texts is None else [str(s) for s in texts]
    if len(texts) != len(motions):
        raise ValueError(f"{len(texts)} texts for {len(motions)} motions")
    arrays = [export_positions(m, MDM_FPS, "MDM", resample=resample) for m in motions]
    t_max = max(len(a) for a in arrays)
    batch = np.stack([np.concatenate([a, np.repeat(a[-1:], t_max - len(a), axis=0)])
                      for a in arrays]).transpose(0, 2, 3, 1)
    data = {"motion": np.ascontiguousarray(batch, dtype=np.float32), "text": texts,
            "lengths": np.array([len(a) for a in arrays], dtype=np.int64),
            "num_samples": len(arrays), "num_repetitions": 1}
    return _save_npy(path, data, allow_pickle=True)

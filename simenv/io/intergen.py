"""InterHuman / InterGen two-person joint positions: one ``.npy`` per person in
``person1/`` and ``person2/`` folders, read as one :class:`Interaction`.

Layouts, as verified in github.com/tr3e/InterGen:

* InterHuman ``motions_processed/person{1,2}/<id>.npy`` (``utils/preprocess.py``
  ``load_motion``): (T, D) float rows whose first 22*3 values are the SMPL-22
  joint positions (then 62 joint positions in all, then 6D rotations at
  column 62*3, so D >= 312), **Z up**, metres, 30 fps (``FPS = 30``). The
  files themselves are Z up: ``utils/utils.py`` ``process_motion_np`` turns
  them Y up with ``trans_matrix`` ``(x, y, z) -> (x, z, -y)``.
* InterGen's motion representation (``process_motion_np`` output, and what
  the model generates, denormalised, per person in ``tools/infer.py``):
  (T, 262) = 22*3 positions (**Y up**) + 22*3 velocities + 21*6 rotations
  + 4 foot contacts.
* Plain (T, 22, 3) (or (T, 66)) joint positions, **Y up**: ``infer.py``'s
  ``joints3d = motion_output[:, :22*3].reshape(-1, 22, 3)``; this is what
  :func:`write_intergen` writes.

Only the positions are read (no SMPL body model). Y-up data are turned Z up
by :data:`simenv.io.humanml3d.Y_UP_TO_Z_UP` ``(x, y, z) -> (x, -z, y)``, the
exact inverse of InterGen's ``trans_matrix``, so raw InterHuman files and the
262-wide representation land in the same frame. ``up=`` overrides the axis,
``fps=`` the 30 fps, ``units=`` the metres. Arrays are loaded without pickle.

A folder holding ``person1/`` and ``person2/`` (what :func:`write_intergen` writes,
InterHuman's ``motions_processed/``) loads as its clips: :func:`read_folder`.

Persons: person1 is the Interaction's actor, person2 the reactor;
``roles_known`` is False (InterHuman annotates no roles). When an
InterHuman ``annots/<id>.txt`` sits beside ``motions_processed``, its
descriptions are kept in ``metadata["texts"]``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Interaction, Motion
from simenv.io.humanml3d import (
    N_JOINTS,
    Units,
    Up,
    export_positions,
    from_array,
    load_plain_npy,
    npy_header,
)

FORMAT = "intergen"
EXTENSIONS = (".npy",)
INTERGEN_FPS = 30.0
#: Width of InterGen's per-person motion representation.
REPR_DIM = 262
#: Narrowest raw InterHuman row: 62 joint positions, then 21 6D rotations.
RAW_MIN_DIM = 62 * 3 + 21 * 6
PERSON_DIRS = ("person1", "person2")


def _kind(shape: tuple[int, ...]) -> tuple[str, Up] | None:
    """(layout name, default up axis) of a per-person array shape."""
    if len(shape) == 3 and shape[1:] == (N_JOINTS, 3):
        return "joints", "y"
    if len(shape) == 2 and shape[1] == N_JOINTS * 3:
        return "joints", "y"
    if len(shape) == 2 and shape[1] == REPR_DIM:
        return "intergen262", "y"
    if len(shape) == 2 and shape[1] >= RAW_MIN_DIM:
        return "interhuman", "z"
    return None


def partner_path(path: Path) -> Path:
    """The other person's file: ``.../person1/x.npy`` <-> ``.../person2/x.npy``."""
    path = Path(path)
    folder = path.parent.name
    if folder.lower() not in PERSON_DIRS:
        return path
    other = ("2" if folder[-1] == "1" else "1")
    return path.parent.parent / (folder[:-1] + other) / path.name


def sniff(path: Path, head: bytes) -> bool:
    """A numeric ``.npy`` in a ``person1``/``person2`` folder with one of the
    per-person layouts of the module docstring."""
    path = Path(path)
    if path.suffix.lower() != ".npy" or path.parent.name.lower() not in PERSON_DIRS:
        return False
    header = npy_header(path)
    return header is not None and not header[1].hasobject and _kind(header[0]) is not None


def read_person(
    path: Path,
    *,
    fps: float | None = None,
    units: Units = "m",
    up: Up | None = None,
) -> Motion:
    """One person's file as an SMPL-22 :class:`Motion` (Z up, metres).

    Raises:
        FormatError: unreadable or a layout other than those documented.
        MotionError, UnitsError: see :func:`simenv.io.humanml3d.from_array`.
    """
    path = Path(path)
    arr = load_plain_npy(path)
    kind = _kind(arr.shape)
    if kind is None:
        raise FormatError(
            f"has shape {arr.shape}; expected one person's InterGen/InterHuman motion: "
            f"(T, 22, 3) or (T, 66) joint positions (Y up), (T, {REPR_DIM}) InterGen "
            f"representation (Y up), or (T, >= {RAW_MIN_DIM}) raw InterHuman rows (Z up), "
            "with the 22 joint positions first", source=path, field="positions")
    layout, default_up = kind
    positions = arr if layout == "joints" else arr[:, : N_JOINTS * 3]
    person = path.parent.name.lower()
    return from_array(
        positions, fps=INTERGEN_FPS if fps is None else fps, up=default_up if up is None else up,
        units=units, name=f"{path.stem}_{person}", source=str(path), fmt=FORMAT,
        metadata={"layout": layout, "person": person})


def _texts(path: Path) -> list[str] | None:
    # InterGen's dataset: annots/<id>.txt next to motions_processed/person1/<id>.npy.
    if path.parent.parent.name != "motions_processed":
        return None
    annot = path.parent.parent.parent / "annots" / f"{path.stem}.txt"
    if not annot.is_file():
        return None
    lines = annot.read_text(encoding="utf-8", errors="replace").splitlines()
    return [s.strip() for s in lines if s.strip()]


def read_pair(
    a: Path,
    b: Path,
    *,
    fps: float | None = None,
    units: Units = "m",
    up: Up | None = None,
) -> Interaction:
    """Both people of one InterHuman/InterGen clip (person1 first, whatever
    the argument order).

    Raises:
        MotionError: the two files have different frame counts.
        FormatError, UnitsError: see :func:`read_person`.
    """
    a, b = sorted((Path(a), Path(b)), key=lambda p: p.parent.name.lower())
    people = [read_person(p, fps=fps, units=units, up=up) for p in (a, b)]
    if people[0].num_frames != people[1].num_frames:
        raise MotionError(
            f"{a.parent.name} has {people[0].num_frames} frames and {b.parent.name} "
            f"{people[1].num_frames} ({b}); the two people of a clip share one clock",
            source=a)
    meta: dict[str, Any] = {"sources": [str(a), str(b)], "source": str(a), "format": FORMAT,
                            "quirks": []}
    texts = _texts(a)
    if texts is not None:
        meta["texts"] = texts
    return Interaction(people[0], people[1], label=None, roles_known=False, name=a.stem,
                       metadata=meta)


def read(
    path: Path,
    *,
    fps: float | None = None,
    units: Units = "m",
    up: Up | None = None,
) -> Interaction | Motion:
    """Read a person's file with its partner as an :class:`Interaction`; a
    file whose partner is absent reads as one :class:`Motion` (with a quirk
    noting the missing partner). Options as in :func:`read_person`."""
    path = Path(path)
    partner = partner_path(path)
    if partner != path and partner.is_file():
        return read_pair(path, partner, fps=fps, units=units, up=up)
    m = read_person(path, fps=fps, units=units, up=up)
    m.metadata["quirks"].append(f"partner file {partner} not found: read one person")
    return m


def _person_dirs(folder: Path) -> list[Path]:
    """``folder``'s ``person1`` and ``person2`` subfolders (any case), in that order."""
    found = {d.name.lower(): d for d in folder.iterdir() if d.is_dir()}
    return [found[name] for name in PERSON_DIRS if name in found]


def _person_files(folder: Path) -> dict[str, Path]:
    """Clip id -> one person's file (person1's when both have it) of an InterGen folder."""
    clips: dict[str, Path] = {}
    for person in reversed(_person_dirs(folder)):  # person1 last: its file wins
        for path in sorted(person.glob("*.npy")):
            if sniff(path, b""):
                clips[path.stem] = path
    return dict(sorted(clips.items()))


def sniff_folder(folder: Path) -> bool:
    """A folder laid out as :func:`write_intergen` writes it and as InterHuman's
    ``motions_processed/`` is: ``person1/`` and ``person2/`` subfolders holding
    per-person ``.npy`` files."""
    folder = Path(folder)
    return len(_person_dirs(folder)) == 2 and bool(_person_files(folder))


def read_folder(
    folder: Path,
    *,
    fps: float | None = None,
    units: Units = "m",
    up: Up | None = None,
) -> Interaction | Motion | list[Interaction | Motion]:
    """Every clip of an InterGen folder (:func:`sniff_folder`), by file name: each file of
    ``person1/`` with its namesake in ``person2/`` as an :class:`Interaction` (a file
    without its partner as one :class:`Motion`, noted, as :func:`read` does).

    Returns:
        The one clip of a folder that holds one (what :func:`write_intergen` writes), else
        the list of clips in file-name order. Options as in :func:`read_person`.

    Raises:
        FormatError: the folder holds no per-person file. Other errors as :func:`read`.
    """
    folder = Path(folder)
    if not (folder.is_dir() and sniff_folder(folder)):
        raise FormatError("holds no person1/ and person2/ folders of InterGen .npy files",
                          source=folder)
    clips = [read(path, fps=fps, units=units, up=up) for path in _person_files(folder).values()]
    return clips[0] if len(clips) == 1 else clips


def write_intergen(
    interaction: Interaction,
    folder: str | Path,
    name: str = "0",
    *,
    resample: bool = False,
) -> tuple[Path, Path]:
    """Write both people as InterGen joint positions: ``folder/person1/<name>.npy``
    (actor) and ``folder/person2/<name>.npy`` (reactor), each (T, 22, 3)
    float32, metres, Y up, 30 fps (``resample=True`` converts other rates).
    People on other skeletons are mapped by
    :func:`simenv.io.humanml3d.to_smpl22`. Returns the two paths; ``simenv.load(folder)``
    reads the pair back (with any other clips written there)."""
    folder = Path(folder)
    paths = []
    for person, m in zip(PERSON_DIRS, interaction.people, strict=True):
        arr = export_positions(m, INTERGEN_FPS, "InterGen", resample=resample)
        out = folder / person / f"{name}.npy"
        out.parent.mkdir(parents=True, exist_ok=True)
        with out.open("wb") as fh:  # a handle: np.save(path) appends .npy to other names
            np.save(fh, arr, allow_pickle=False)
        paths.append(out)
    return paths[0], paths[1]

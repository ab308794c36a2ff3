"""Format detection and loading: :func:`load` for files, folders and pairs.

Readers live in :mod:`simenv.io` modules listed in :data:`READERS`. Each
exposes ``sniff(path, head) -> bool`` (``head`` = the first
:data:`HEAD_BYTES` bytes) and ``read(path, **kwargs)`` returning a
:class:`Motion`, an :class:`Interaction` or a list of them; it may declare
``EXTENSIONS`` (and ``REFINES``, the name of a reader whose files it reads with more
knowledge of one dataset: it is asked before that reader), and, for a format that lays a
recording out in subfolders (InterGen's ``person1/`` + ``person2/``),
``sniff_folder(folder) -> bool`` and
``read_folder(folder, **kwargs)``, which read a folder they accept. Modules are
imported lazily; one that does not exist (yet) is skipped.

Detection order for a file: readers claiming the file's extension first,
then the others; the first whose ``sniff`` accepts the head reads it. When
no sniff accepts but a reader claims the extension, that reader reads it
(so a damaged ``.bvh`` fails with its own located :class:`FormatError`).

Two-person CMU recordings stored one file per person load as one
:class:`Interaction` from their folder or from both paths. Known pair
quirks are repaired *with a note*, never silently: a partner whose header
frame rate contradicts the other file is re-timed only when the evidence
says both are on one clock (see :func:`pair`).
"""

from __future__ import annotations

import csv
import importlib
import inspect
import re
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from simenv.core.errors import MotionError, ReaderOptionError, SimenvError, UnknownFormatError
from simenv.core.joint_map import JointMapSource, map_motion
from simenv.core.motion import Interaction, Motion
from simenv.io.camera_frame import level_sensor_frame
from simenv.io.floor import put_on_floor

#: Reader modules of :mod:`simenv.io`, in detection priority order.
READERS: tuple[str, ...] = (
    "bvh",
    "asf_amc",
    "npz",
    # Refines bvh (REFINES): a BVH named like a Berkeley MHAD skeleton, with its labels.
    "berkeley_mhad",
    "sbu",
    "msr_action3d",
    "utkinect",
    "florence3d",
    "utd_mhad",
    "nuisi",
    "ntu",
    "pku_mmd",
    # Before h36m: all four claim .npy, and an unrecognised .npy gets humanml3d's
    # error, which names every .npy layout simenv reads (the sniffs of humanml3d
    # and humanml3d_features leave person1/ and person2/ files to intergen).
    "humanml3d",
    "humanml3d_features",
    "intergen",
    "h36m",
    # Before joint_csv, which claims .csv: an MSRC-12 recording has no header row.
    "msrc12",
    # Claims .json; an Azure Kinect SDK .csv ("x y z" per cell) is the one joint_csv refuses.
    "azure_kinect",
    "joint_csv",
    # After joint_csv (both claim .csv; the first claimer explains an unrecognised one): takes
    # an OptiTrack Motive export by its "Format Version" take row.
    "motive_csv",
)

#: Bytes of a file handed to each reader's ``sniff``.
HEAD_BYTES = 4096

#: CMU captured everything at this rate (Hz).
CMU_CAPTURE_FPS = 120.0

#: Two files are on one clock when their median per-frame root displacement
#: agrees within this factor (a 30-vs-120 fps header mix-up is a factor 4).
SAME_CLOCK_STEP_RATIO = 2.0

Loaded = Motion | Interaction | list[Motion | Interaction]

_PAIR_LABELS: tuple[tuple[str, str], ...] = (
    (r"shake hands", "shake_hands"),
    (r"high-five", "high_five"),
    (r"low-five", "low_five"),
    (r"salsa", "salsa"),
    (r"chicken dance", "chicken_dance"),
    (r"pulls? up", "pull_up"),
    (r"pulls?", "pull"),
    (r"comforts?", "comfort"),
    (r"catches", "throw_catch"),
    (r"throw, catch", "throw_catch"),
    (r"arm wrestle", "arm_wrestle"),
    (r"jumping jacks", "jumping_jacks"),
    (r"squats", "squats"),
    (r"march", "march"),
    (r"conversation", "conversation"),
    (r"quarrel", "quarrel"),
)


def _module(name: str) -> ModuleType | None:
    try:
        return importlib.import_module(f"simenv.io.{name}")
    except ModuleNotFoundError as exc:
        if exc.name == f"simenv.io.{name}":
            return None
        raise


def available_readers() -> list[str]:
    """Names of the reader modules present in this installation."""
    return [n for n in READERS if _module(n) is not None]


def _head(path: Path) -> bytes:
    try:
        with path.open("rb") as fh:
            return fh.read(HEAD_BYTES)
    except OSError as exc:
        raise SimenvError(f"cannot read file: {exc.strerror or exc}", source=path) from None


def detect(path: Path) -> tuple[str, ModuleType]:
    """The reader for a file: (module name, module).

    Raises:
        UnknownFormatError: naming the file and the formats tried.
    """
    path = Path(path)
    head = _head(path)
    suffix = path.suffix.lower()
    mods = [(n, m) for n in READERS if (m := _module(n)) is not None]
    claims = [(n, m) for n, m in mods if suffix in getattr(m, "EXTENSIONS", ())]
    claims.sort(key=lambda nm: not getattr(nm[1], "REFINES", None))  # refiners first
    ordered = claims + [(n, m) for n, m in mods if (n, m) not in claims]
    for name, mod in ordered:
        try:
            if mod.sniff(path, head):
                return name, mod
        except (ValueError, UnicodeError, OSError, SimenvError):
            continue
    if claims:
        return claims[0]
    raise UnknownFormatError(
        f"no reader recognises this file (extension {suffix or 'none'!r}); tried "
        f"{', '.join(n for n, _ in ordered)}",
        source=path,
    )


def _read(path: Path, name: str, mod: ModuleType, kwargs: dict[str, Any], *,
          folder: bool = False) -> Loaded:
    """``mod.read(path, **kwargs)`` (``mod.read_folder`` with ``folder``), naming the
    options the reader does not take."""
    read = mod.read_folder if folder else mod.read
    params = inspect.signature(read).parameters
    if "joint_map" not in params:  # applied by load() to what the reader returns
        kwargs = {k: v for k, v in kwargs.items() if k != "joint_map"}
    takes_any = any(p.kind is p.VAR_KEYWORD for p in params.values())
    unknown = [k for k in kwargs if k not in params and not takes_any]
    if unknown:
        accepted = [k for k, p in params.items() if p.kind is p.KEYWORD_ONLY]
        raise ReaderOptionError(
            f"the {name} reader does not take {', '.join(unknown)}; it accepts "
            f"{', '.join(accepted) or 'no options'}",
            source=path, field=unknown[0],
        )
    return read(path, **kwargs)


def load(path: str | Path | Sequence[str | Path], **kwargs: Any) -> Loaded:
    """Load motion capture from a file, a folder, or a pair of files.

    Args:
        path: a motion file (format detected by extension and content); a
            folder (two files of one CMU two-person trial, or an InterGen
            folder of one clip -> Interaction, otherwise every motion file in it
            -> list); or a sequence of two
            files, one per person -> Interaction.
        **kwargs: passed to the reader (e.g. ``units=``, ``fps=``,
            ``drop_tpose=`` for BVH, ``asf=`` for AMC); ``joint_map=`` (a TOML
            file or a mapping, see :func:`simenv.core.joint_map.read_joint_map`)
            maps every person's joints onto the canonical keypoints instead of
            the reader's map. Without it, a skeleton the reader does not know
            is mapped by :func:`simenv.core.joint_map.map_motion` (names,
            hierarchy, pose), recorded in ``metadata["joint_map"]``. A
            motion-capture file whose floor is at the feet's joint centres is
            then raised onto a floor under the soles
            (:func:`simenv.io.floor.put_on_floor`, noted in ``metadata["repairs"]``).

    Returns:
        Motion, Interaction, or a list of them (files/folders with many
        clips).

    Raises:
        UnknownFormatError: no reader recognises the file or folder content.
        SimenvError: any reader error, naming file, line and field.
    """
    return _mapped(_load(path, kwargs), kwargs.get("joint_map"))


def _mapped(loaded: Loaded, joint_map: JointMapSource | None) -> Loaded:
    """Every person of ``loaded`` through :func:`map_motion`, then each clip on its floor: a
    depth camera's skeleton in a file format levelled onto the floor its feet give
    (:func:`~simenv.io.camera_frame.level_sensor_frame`), any other file's floor checked
    (:func:`~simenv.io.floor.put_on_floor`); both need the mapped keypoints."""
    if isinstance(loaded, list):
        return [_mapped(x, joint_map) for x in loaded]  # type: ignore[misc]
    if isinstance(loaded, Interaction):
        mapped: Motion | Interaction = replace(loaded, actor=map_motion(loaded.actor, joint_map),
                                               reactor=map_motion(loaded.reactor, joint_map))
    else:
        mapped = map_motion(loaded, joint_map)
    return put_on_floor(level_sensor_frame(mapped))


def _load(path: str | Path | Sequence[str | Path], kwargs: dict[str, Any]) -> Loaded:
    if isinstance(path, (list, tuple)):
        if len(path) != 2:
            raise MotionError(
                f"a list of paths must hold the two people of one recording; got {len(path)}"
            )
        pa, pb = (Path(p) for p in path)
        paired = _format_pair(pa, pb, kwargs)
        if paired is not None:
            return paired
        a, b = (_load_single_person(p, kwargs) for p in (pa, pb))
        return pair(a, b)
    path = Path(path)
    if path.is_dir():
        return _load_folder(path, kwargs)
    if not path.exists():
        raise SimenvError("no such file or folder", source=path)
    name, mod = detect(path)
    return _read(path, name, mod, kwargs)


def _format_pair(a: Path, b: Path, kwargs: dict[str, Any]) -> Interaction | None:
    """Both people through their format's own ``read_pair`` when the format
    records one file per person with its own pairing rules (e.g. NuiSI, whose
    two sensors share no world frame); None when the format has none."""
    if not (a.is_file() and b.is_file()):
        return None
    name_a, mod = detect(a)
    name_b, _ = detect(b)
    if name_a != name_b or not hasattr(mod, "read_pair"):
        return None
    partner = getattr(mod, "partner_path", None)
    if partner is not None and partner(a) != b:
        raise MotionError(
            f"{b.name} is not the partner recording of {a.name} for the {name_a} format",
            source=a,
        )
    return mod.read_pair(a, b, **kwargs)


def _load_single_person(path: Path, kwargs: dict[str, Any]) -> Motion:
    loaded = load(path, **kwargs)
    if not isinstance(loaded, Motion):
        raise MotionError(f"expected one person's motion, got {type(loaded).__name__}", source=path)
    return loaded


def motion_files(folder: Path) -> list[tuple[Path, str]]:
    """Files in ``folder`` (not recursive) that a reader recognises, with the
    reader name. ASF skeletons are left out when AMC motions are present
    (they are read through the AMCs); files of a reader that sets
    ``FOLDER_NEEDS_SNIFF`` count only when its ``sniff`` accepts them."""
    found = []
    for p in sorted(folder.iterdir()):
        if not p.is_file() or p.name.startswith("."):
            continue
        try:
            name, mod = detect(p)
        except UnknownFormatError:
            continue
        # A generic extension (.csv) is claimed for its error messages, not for folder walks:
        # a folder's index or label table is not a motion its reader failed to recognise.
        if getattr(mod, "FOLDER_NEEDS_SNIFF", False) and not mod.sniff(p, _head(p)):
            continue
        found.append((p, name))
    if any(p.suffix.lower() == ".amc" for p, _ in found):
        found = [(p, n) for p, n in found if p.suffix.lower() != ".asf"]
    return found


_TRIAL = re.compile(r"^(\d+)_(\d+)")


def _trial(path: Path) -> tuple[str, str] | None:
    """(subject, take) of a CMU-style file name such as ``60_10_scaled.bvh``."""
    m = _TRIAL.match(path.stem)
    return (m.group(1), m.group(2)) if m else None


def _folder_readers(folder: Path) -> list[tuple[str, ModuleType]]:
    """Readers whose format lays a recording out as a folder (``sniff_folder`` and
    ``read_folder``, e.g. InterGen's ``person1/`` + ``person2/``) and accept ``folder``."""
    return [(n, m) for n in READERS if (m := _module(n)) is not None
            and hasattr(m, "sniff_folder") and m.sniff_folder(folder)]


def is_laid_out_recording(folder: Path) -> bool:
    """Whether a reader reads ``folder`` as recordings laid out in subfolders (InterGen's
    ``person1/`` + ``person2/``): it is then one target, not its files one by one."""
    return bool(_folder_readers(Path(folder)))


def _load_folder(folder: Path, kwargs: dict[str, Any]) -> Loaded:
    files = motion_files(folder)
    # Clips of formats laid out in subfolders; with loose files too, every clip in a list.
    laid_out = [_read(folder, n, m, kwargs, folder=True) for n, m in _folder_readers(folder)]
    if not files and len(laid_out) == 1:
        return laid_out[0]
    if not files and not laid_out:
        tried = ", ".join(available_readers())
        raise UnknownFormatError(
            f"folder holds no file any reader recognises (tried {tried})", source=folder
        )
    trials = [_trial(p) for p, _ in files]
    is_pair = (
        len(files) == 2
        and all(t is not None for t in trials)
        and trials[0][1] == trials[1][1]  # type: ignore[index]
        # CMU two-person trials pair consecutive subject numbers (18/19, 60/61, ...).
        and abs(int(trials[0][0]) - int(trials[1][0])) == 1  # type: ignore[index]
    )
    if len(files) == 2 and not laid_out:
        paired = _format_pair(files[0][0], files[1][0], kwargs)
        if paired is not None:
            return paired
    if is_pair and not laid_out:
        a, b = (_load_single_person(p, kwargs) for p, _ in files)
        return pair(a, b, folder=folder)
    loaded = laid_out + [_read(p, name, _module(name), kwargs)  # type: ignore[arg-type]
                         for p, name in files]
    out: list[Motion | Interaction] = []
    for clips in loaded:
        out.extend(clips if isinstance(clips, list) else [clips])
    return out


def _descriptions(start: Path) -> dict[str, str]:
    """CMU trial descriptions (``cmu_trial_descriptions.tsv``) found in the
    folder or up to three levels above it; empty when absent."""
    for folder in [start, *list(start.parents)[:3]]:
        tsv = folder / "cmu_trial_descriptions.tsv"
        if tsv.is_file():
            with tsv.open(newline="") as fh:
                rows = list(csv.reader(fh, delimiter="\t"))
            return {r[0]: r[1] for r in rows[1:] if len(r) >= 2}
    return {}


def _label(descriptions: list[str], folder: Path | None) -> str | None:
    text = " ".join(descriptions) or (folder.name.replace("_", " ") if folder else "")
    for pattern, label in _PAIR_LABELS:
        if re.search(pattern, text, re.IGNORECASE):
            return label
    core = re.sub(r"\(.*?\)", "", descriptions[0]).strip() if descriptions else ""
    slug = re.sub(r"[^a-z0-9]+", "_", core.lower()).strip("_")
    return slug or None


def _role(description: str) -> int | None:
    """0 for the acting person (subject A / lead), 1 for B / follow."""
    d = description.lower()
    if "subject a" in d or re.search(r"\blead\b", d):
        return 0
    if "subject b" in d or re.search(r"\bfollow\b", d):
        return 1
    return None


def _median_root_step(m: Motion) -> float:
    return float(np.median(np.linalg.norm(np.diff(m.positions[:, 0], axis=0), axis=-1)))


def _with_quirk(m: Motion, note: str, **changes: Any) -> Motion:
    meta = dict(m.metadata)
    meta["quirks"] = [*meta.get("quirks", []), note]
    return replace(m, metadata=meta, **changes)


def _reconcile_fps(a: Motion, b: Motion, notes: list[str]) -> tuple[Motion, Motion]:
    """Resolve a header frame-rate contradiction between two partners.

    Evidence that both files are on one clock: equal frame counts (after any
    dropped T-pose) and per-frame root displacements within
    :data:`SAME_CLOCK_STEP_RATIO`. Then the rate that equals the CMU capture
    rate wins (both files must be CMU trials). Without such evidence the
    pair is refused.
    """
    step_a, step_b = _median_root_step(a), _median_root_step(b)
    ratio = max(step_a, step_b) / max(min(step_a, step_b), 1e-9)
    same_clock = a.num_frames == b.num_frames and ratio <= SAME_CLOCK_STEP_RATIO
    cmu = _trial(Path(a.metadata.get("source", ""))) and _trial(Path(b.metadata.get("source", "")))
    rates = {a.fps, b.fps}
    if not (same_clock and cmu and CMU_CAPTURE_FPS in rates):
        raise MotionError(
            f"{a.name} is at {a.fps:g} fps and {b.name} at {b.fps:g} fps, and nothing shows "
            f"which is right (frames {a.num_frames} vs {b.num_frames}; median root step "
            f"{step_a * 100:.2f} vs {step_b * 100:.2f} cm/frame). Pass fps= explicitly or "
            "resample one"
        )
    wrong, right = (a, b) if b.fps == CMU_CAPTURE_FPS else (b, a)
    dropped = [q for q in right.metadata.get("quirks", []) if q.startswith("dropped T-pose")]
    note = (
        f"{wrong.name}: header says {wrong.fps:g} fps but the file is on the clock of "
        f"{right.name} ({right.fps:g} fps, the CMU capture rate): both have "
        f"{wrong.num_frames} frames"
        + (f" once {right.name}'s T-pose frame 0 is dropped" if dropped else "")
        + f", and their median root steps agree ({step_a * 100:.2f} vs "
        f"{step_b * 100:.2f} cm/frame); {wrong.name} re-timed to {right.fps:g} fps"
    )
    notes.append(note)
    fixed = _with_quirk(wrong, note, fps=right.fps)
    return (fixed, b) if wrong is a else (a, fixed)


def pair(a: Motion, b: Motion, *, folder: Path | None = None) -> Interaction:
    """Make an :class:`Interaction` from two people's motions of one trial.

    Roles and label come from the CMU trial descriptions when available
    (``subject A``/``lead`` acts); otherwise the order is by file name and
    ``roles_known`` is False. A frame-rate contradiction is repaired only with
    evidence (see :func:`_reconcile_fps`) and noted in the quirks of the
    Interaction and of the re-timed Motion. Reader repairs of either person
    (e.g. BVH ``restore_collapsed_bones=True``) are listed, prefixed by the
    person's name, in the Interaction's ``metadata["repairs"]``.

    Raises:
        MotionError: different frame rates without evidence, or different
            lengths.
    """
    notes: list[str] = []
    if a.fps != b.fps:
        a, b = _reconcile_fps(a, b, notes)
    if a.num_frames != b.num_frames:
        raise MotionError(
            f"{a.name} has {a.num_frames} frames and {b.name} {b.num_frames}; a two-person "
            "recording needs one frame per person per time step (align them explicitly with "
            ".slice, or check drop_tpose)"
        )
    for m in (a, b):
        for q in m.metadata.get("quirks", []):
            if q.startswith(("dropped T-pose", "frame 0 is a T-pose")):
                notes.append(f"{m.name}: {q}")
    start = folder or Path(a.metadata.get("source", ".")).parent
    table = _descriptions(start)
    desc = []
    for m in (a, b):
        t = _trial(Path(m.metadata.get("source", m.name)))
        d = table.get(f"{t[0]}_{t[1]}") if t else None
        desc.append(d)
    roles = [_role(d) if d else None for d in desc]
    roles_known = sorted(r for r in roles if r is not None) == [0, 1]
    if roles_known and roles[0] == 1:
        a, b = b, a
        desc.reverse()
    label = _label([d for d in desc if d], folder)
    names = sorted([a.name, b.name])
    meta: dict[str, Any] = {
        "sources": [a.metadata.get("source"), b.metadata.get("source")],
        "quirks": notes,
    }
    person_repairs = [f"{m.name}: {r}" for m in (a, b) for r in m.metadata.get("repairs", [])]
    if person_repairs:
        meta["repairs"] = person_repairs
    if any(desc):
        meta["descriptions"] = desc
        meta["label_source"] = "CMU trial descriptions"
    if roles_known:
        meta["roles_source"] = "CMU trial descriptions (subject A / lead acts)"
    name = folder.name if folder else f"{names[0]}+{names[1]}"
    return Interaction(a, b, label=label, roles_known=roles_known, name=name, metadata=meta)


def load_any(paths: Sequence[str | Path], **kwargs: Any) -> list[Motion | Interaction]:
    """Load one motion file or folder, or the two files of one two-person recording
    (``kwargs`` as for :func:`load`, e.g. ``joint_map=``).

    Returns:
        The clips found (usually one; a folder of unrelated files gives several).
    """
    paths = [Path(p) for p in paths]
    for path in paths:
        if not path.exists():
            raise SimenvError("no such file or folder", source=path)
    if len(paths) > 2:
        raise SimenvError(
            f"got {len(paths)} paths; expected one file or folder, or the two files of one "
            "two-person recording"
        )
    loaded = load(paths[0], **kwargs) if len(paths) == 1 else load(paths, **kwargs)
    return list(loaded) if isinstance(loaded, list) else [loaded]


def load_one(paths: Sequence[str | Path], **kwargs: Any) -> Motion | Interaction:
    """The one clip of :func:`load_any`'s ``paths``.

    Raises:
        SimenvError: the paths hold several clips.
    """
    clips = load_any(paths, **kwargs)
    if len(clips) != 1:
        raise SimenvError(
            f"holds {len(clips)} clips; this command needs one (use `simenv info` to list them)",
            source=paths[0],
        )
    return clips[0]

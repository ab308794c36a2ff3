"""Two-person interaction datasets from real recordings: recordings, windows, splits and
the reactive-GAN normalisation.

Pipeline
--------
1. **Recordings.** Each real two-person recording becomes one
:class:`~simenv.core.motion.Interaction`
   on the common 18-keypoint layout :data:`INTER18_JOINTS`, resampled explicitly to
   :data:`TARGET_FPS`, with a class label from :data:`INTERACTION_LABELS` and actor/reactor
   roles. A *recording* is the unit of every split (:func:`split_by_recording`); no recording
   ever has windows on both sides.
2. **Windows** of :data:`WINDOW_FRAMES` frames every :data:`WINDOW_STRIDE` frames
   (:func:`make_windows`), both people cut on the same frames.
3. **Normalisation** of each window in the actor's frame (:func:`actor_frame`,
   :func:`normalise`, :func:`denormalise`).

Frame rate: 25 fps
------------------
25 fps is the rate of the rest of simenv's learning stack (MA-GAN prediction windows,
the gesture classifier whose features serve FID/FVD), so generated windows feed those
models without another resampling. CMU is captured at 120 Hz (linear resampling,
:meth:`Motion.resample`); NuiSI is read directly onto a uniform 25 fps grid of its
unix-ms timestamps (:func:`simenv.io.nuisi.read_pair` with ``fps=25``), so its irregular
~29.4 Hz lines are interpolated once, not twice.

The 18-keypoint layout
----------------------
The canonical keypoints (:mod:`simenv.core.skeletons`) that *every* recording provides for both
people: CMU skeletons have all 21, NuiSI (Nuitrack) lacks ``chest`` and the toes (never
tracked). Parents are the nearest kept canonical ancestor
(:meth:`Skeleton.subset`): the shoulders and the neck hang from ``spine``. SBU lacks the
pelvis, so the SBU sample cannot be put on this layout (nor normalised, which needs it);
it is also too short for one window (17-29 frames at 15 fps = 1.1-1.9 s) and unlabelled,
so it is not part of :func:`load_recordings`.

Roles and labels (how assigned)
-------------------------------
===================================  ==================  ==================================
recording (split unit)               label               actor (person A)
===================================  ==================  ==================================
``cmu/18_19_walk_shake_hands``       ``shake_hands``     18_01, "subject A" in the CMU
                                                         trial description
``cmu/60_61_salsa_05``, ``_10``      ``salsa``           60_xx, "lead" in the description
``nuisi/Rocket/rep01`` .. ``rep12``  ``rocket_fist_bump``  p1 by convention: NuiSI does not
                                                         say who initiates
===================================  ==================  ==================================

CMU labels and roles come from ``cmu/cmu_trial_descriptions.tsv`` through
:func:`simenv.io.loader.pair`; source labels are mapped onto the vocabulary by
:data:`SOURCE_LABELS` (an unknown label is an error, never a new class made up on the
fly). NuiSI repetitions are the 12 intervals annotated by the dataset's authors
(:data:`NUISI_ROCKET_REPETITIONS`, line indices of the files, converted to frames of the
25 fps grid through the files' timestamps): a repetition is one recording unit.

Held-out split
--------------
:data:`DEFAULT_TEST_RECORDINGS`: the handshake (the only handshake recording: it is
therefore an *unseen class* for anything trained on the train side, which the evaluation
states), salsa 60/61_10 (salsa 05 trains) and NuiSI repetitions 3, 7 and 11 (spread over
the session; the other 9 train).

Normalisation (reactive GAN, Men et al.)
----------------------------------------
Per window, from the actor's **first frame**: the origin ``o = (p_x, p_y, 0)`` is the
actor's pelvis projected onto the floor (z = 0 is the floor in simenv's world frame), and
the heading ``θ`` is the actor's facing direction, ``forward = ẑ × across`` with
``across = (r_shoulder - l_shoulder) + (r_hip - l_hip)``, ``θ = atan2(forward_y,
forward_x)``. Both people are mapped with the same rigid transform

    x_norm = R_z(-θ) (x_world - o),          x_world = R_z(θ) x_norm + o,

so the actor starts at the origin facing +x (its left along +y), the reactor keeps its
placement relative to the actor, and Z (height above the floor) is unchanged. The second
formula is the exact inverse (:func:`denormalise`), used to place generated reactions
back in the world (e.g. to score their physics).
"""

from __future__ import annotations

import csv
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import MotionError, SimenvError, SkeletonError
from simenv.core.motion import Interaction, Motion
from simenv.core.skeletons import Skeleton, canonical_skeleton
from simenv.data.prediction_data import ClipSplit, split_by_clip
from simenv.io.loader import load
from simenv.io.nuisi import read_pair

#: Frame rate of interaction windows, Hz (see the module docstring for why 25).
TARGET_FPS = 25.0
#: Frames per window (1.6 s at 25 fps) and frames between consecutive window starts.
WINDOW_FRAMES = 40
WINDOW_STRIDE = 5

#: The canonical keypoints common to every two-person recording (canonical order).
INTER18_JOINTS: tuple[str, ...] = (
    "pelvis", "left_hip", "left_knee", "left_ankle", "right_hip", "right_knee",
    "right_ankle", "spine", "neck", "head", "left_shoulder", "left_elbow", "left_wrist",
    "left_hand", "right_shoulder", "right_elbow", "right_wrist", "right_hand",
)

#: Interaction class -> what it is. Class ids are indices into the *present* labels of a
#: dataset (:attr:`InteractionWindows.labels`), in this order.
INTERACTION_LABELS: dict[str, str] = {
    "shake_hands": "walk towards each other and shake (right) hands",
    "salsa": "salsa dance, lead and follow in hand contact",
    "rocket_fist_bump": "bump fists at waist level, move them up together keeping contact",
    "high_five": "high-five",
    "low_five": "low-five",
    "pull_up": "one person pulls the other up from sitting",
    "pull": "one person pulls the other",
    "comfort": "one person comforts the other",
    "throw_catch": "throw and catch",
    "arm_wrestle": "arm wrestling",
    "chicken_dance": "chicken dance together",
    "conversation": "conversation with hand gestures",
    "quarrel": "quarrel with angry hand gestures",
    "wave": "wave at each other",
    "parachute": "NuiSI 'parachute' (hands joined, moved down together)",
}

#: Label as a source spells it -> vocabulary label (identity for the vocabulary itself).
#: CMU labels come from :func:`simenv.io.loader.pair`; NuiSI labels are file stems.
SOURCE_LABELS: dict[str, str] = {
    **{k: k for k in INTERACTION_LABELS},
    "Rocket": "rocket_fist_bump",
    "Handshake": "shake_hands",
    "Waving": "wave",
    "Parachute": "parachute",
}

#: NuiSI "Rocket" repetitions annotated by the dataset's authors: [start, end] line
#: indices of ``Rocket_p1.txt`` / ``Rocket_p2.txt`` (``shared/data/SOURCES.md``).
NUISI_ROCKET_REPETITIONS: tuple[tuple[int, int], ...] = (
    (110, 310), (340, 550), (570, 750), (770, 920), (940, 1120), (1140, 1300),
    (1310, 1470), (1500, 1640), (1680, 1815), (1840, 2000), (2030, 2240), (2290, 2500),
)

#: The CMU two-person trials of the corpus (folders under ``cmu/two_person``).
CMU_PAIRS: tuple[str, ...] = ("18_19_walk_shake_hands", "60_61_salsa_05", "60_61_salsa_10")

#: Recordings held out for evaluation (see the module docstring).
DEFAULT_TEST_RECORDINGS: tuple[str, ...] = (
    "cmu/18_19_walk_shake_hands", "cmu/60_61_salsa_10",
    "nuisi/Rocket/rep03", "nuisi/Rocket/rep07", "nuisi/Rocket/rep11",
)


@cache
def inter18_skeleton() -> Skeleton:
    """The 18-keypoint interaction layout (canonical names, identity canonical map)."""
    return canonical_skeleton().subset(INTER18_JOINTS, name="inter18")


def to_layout(motion: Motion) -> Motion:
    """``motion`` on the 18-keypoint layout (same frames, fps and metadata).

    Raises:
        SkeletonError: the skeleton lacks one of the 18 canonical keypoints.
    """
    return motion.on_layout(inter18_skeleton(), "the two-person layout")


def interaction_label(label: str | None, *, source: str | None = None) -> str:
    """The vocabulary label of a source label (see :data:`SOURCE_LABELS`).

    Raises:
        SimenvError: no label, or a label outside the vocabulary (the message lists it).
    """
    if label is None:
        raise SimenvError(
            "interaction has no class label; pass label= (one of "
            f"{', '.join(INTERACTION_LABELS)})", source=source, field="label")
    if label not in SOURCE_LABELS:
        raise SimenvError(
            f"unknown interaction label {label!r}; known labels: "
            f"{', '.join(INTERACTION_LABELS)} (source spellings: "
            f"{', '.join(k for k in SOURCE_LABELS if k not in INTERACTION_LABELS)})",
            source=source, field="label")
    return SOURCE_LABELS[label]


def make_interaction(
    actor: Motion | None,
    reactor: Motion | None,
    *,
    label: str | None,
    name: str,
    roles_source: str,
    fps: float = TARGET_FPS,
    metadata: Mapping[str, Any] | None = None,
) -> Interaction:
    """A validated recording on the 18-keypoint layout at ``fps``.

    The two people must already be synchronised: same frame rate and same frame count
    (nothing is trimmed or re-timed here, see DESIGN's conventions). Both are then mapped
    to :data:`INTER18_JOINTS` and resampled to ``fps`` if they are not at it.

    Args:
        actor: person A (acts). reactor: person B (reacts).
        label: class label, a vocabulary or source spelling (:data:`SOURCE_LABELS`).
        name: recording name (the unit of splits), e.g. ``"cmu/60_61_salsa_05"``.
        roles_source: how the actor was chosen (kept in ``metadata["roles_source"]``).
        fps: output frame rate, Hz.
        metadata: extra provenance.

    Raises:
        MotionError: a person is missing, or the two differ in fps or frame count.
        SkeletonError: a person lacks a keypoint of the layout.
        SimenvError: unknown or missing label.
    """
    missing = [role for role, m in (("actor", actor), ("reactor", reactor)) if m is None]
    if missing:
        raise MotionError(
            f"recording {name!r}: the {' and the '.join(missing)} is missing; a two-person "
            "recording needs both people", field=missing[0])
    if actor.fps != reactor.fps:
        raise MotionError(
            f"recording {name!r}: actor {actor.name!r} is at {actor.fps:g} fps and reactor "
            f"{reactor.name!r} at {reactor.fps:g} fps; both people must be on one clock "
            "(resample one explicitly)", source=actor.metadata.get("source"), field="fps")
    if actor.num_frames != reactor.num_frames:
        raise MotionError(
            f"recording {name!r}: actor {actor.name!r} has {actor.num_frames} frames and "
            f"reactor {reactor.name!r} {reactor.num_frames}; both people need one frame per "
            "time step (align them explicitly with .slice)",
            source=actor.metadata.get("source"), field="frames")
    vocab = interaction_label(label, source=name)
    people = []
    for m in (actor, reactor):
        m = to_layout(m)
        if m.fps != fps:
            m.require_frames(2, f"resampling {name!r} to {fps:g} fps")
            m = m.resample(fps)
        people.append(m)
    meta = {**(metadata or {}), "roles_source": roles_source, "source_label": label}
    return Interaction(people[0], people[1], label=vocab, roles_known=True, name=name,
                       metadata=meta)


def from_interaction(interaction: Interaction, *, name: str | None = None,
                     label: str | None = None, roles_source: str | None = None,
                     fps: float = TARGET_FPS) -> Interaction:
    """:func:`make_interaction` of a loaded :class:`Interaction` (e.g. ``simenv.load``).

    Its own label and roles are used unless ``label`` / ``roles_source`` are given; with
    unknown roles (``roles_known`` False) the first person acts and ``roles_source`` says
    so.
    """
    if roles_source is None:
        roles_source = interaction.metadata.get("roles_source") or (
            "roles from the source" if interaction.roles_known
            else "unknown in the source: the first person is taken as the actor")
    return make_interaction(
        interaction.actor, interaction.reactor, label=label or interaction.label,
        name=name or interaction.name, roles_source=roles_source, fps=fps,
        metadata={"sources": interaction.metadata.get("sources")
                  or interaction.metadata.get("source")})


def load_interaction(path: str | Path | Sequence[str | Path], *, label: str | None = None,
                     name: str | None = None, fps: float = TARGET_FPS) -> Interaction:
    """Read any two-person file, folder or pair of files as a recording (see
    :func:`from_interaction`).

    Raises:
        MotionError: the path holds one person only, or several clips.
    """
    loaded = load(path)
    where = str(path if isinstance(path, (str, Path)) else path[0])
    if isinstance(loaded, list):
        inter = [x for x in loaded if isinstance(x, Interaction)]
        if len(loaded) == 1 and inter:
            loaded = inter[0]
        elif not inter:
            raise MotionError(f"holds {len(loaded)} single-person motion(s) and no "
                              "two-person recording; the other person is missing",
                              source=where)
        else:
            raise MotionError(f"holds {len(loaded)} clips; load them one by one",
                              source=where)
    if isinstance(loaded, Motion):
        raise MotionError(
            f"holds one person only ({loaded.name!r}); a two-person recording needs the "
            "partner too (pass both files, or the trial's folder)", source=where)
    return from_interaction(loaded, name=name, label=label, fps=fps)


def _nuisi_line_times(path: Path) -> np.ndarray:
    """(lines,) seconds of each line of a NuiSI file, from its ``unix_ms`` column."""
    with path.open(newline="") as fh:
        return np.array([float(row[1]) / 1000.0 for row in csv.reader(fh) if row])


def nuisi_repetitions(
    p1: Path, p2: Path, repetitions: Sequence[tuple[int, int]] = NUISI_ROCKET_REPETITIONS,
    *, fps: float = TARGET_FPS, label: str = "Rocket",
) -> list[Interaction]:
    """The annotated repetitions of a NuiSI session, one recording each (p1 acts).

    Line indices are mapped to frames of the uniform grid that
    :func:`simenv.io.nuisi.read_pair` builds (frame ``k`` is at ``t0 + k / fps``, ``t0``
    the first time both people are tracked): ``frame = round((t_line - t0) · fps)``.

    Raises:
        MotionError: a repetition outside the tracked span of both people.
    """
    whole = read_pair(Path(p1), Path(p2), fps=fps)
    times = _nuisi_line_times(Path(p1))
    t0 = times[0] + whole.actor.metadata["time_span_s"][0]
    out = []
    for k, (a, b) in enumerate(repetitions, start=1):
        if not (0 <= a < b < len(times)):
            raise MotionError(f"repetition {k} lines [{a}, {b}] outside the file's "
                              f"{len(times)} lines", source=p1)
        start, stop = (int(round((times[i] - t0) * fps)) for i in (a, b))
        if start < 0 or stop >= whole.num_frames:
            raise MotionError(
                f"repetition {k} (lines {a}-{b}) falls outside the span tracked for both "
                f"people (frames 0-{whole.num_frames - 1} at {fps:g} fps)", source=p1)
        rep = whole.slice(start, stop + 1)
        out.append(make_interaction(
            rep.actor, rep.reactor, label=label, name=f"nuisi/{label}/rep{k:02d}",
            roles_source="NuiSI convention: p1 is the actor (the dataset does not say who "
                         "initiates)", fps=fps,
            metadata={"sources": [str(p1), str(p2)], "lines": [a, b],
                      "frames_in_session": [start, stop]}))
    return out


def load_recordings(root: str | Path, *, fps: float = TARGET_FPS) -> list[Interaction]:
    """Every real two-person recording of the shared corpus, on the layout at ``fps``:
    the three CMU pairs and the 12 NuiSI Rocket repetitions (see the module docstring).

    Args:
        root: the ``shared/data`` folder (with ``cmu/two_person`` and ``other/nuisi``).
    """
    root = Path(root)
    out = []
    for folder in CMU_PAIRS:
        inter = load(root / "cmu" / "two_person" / folder)
        out.append(from_interaction(inter, name=f"cmu/{folder}", fps=fps))
    nuisi = root / "other" / "nuisi"
    out += nuisi_repetitions(nuisi / "Rocket_p1.txt", nuisi / "Rocket_p2.txt", fps=fps)
    return out


# -- normalisation -------------------------------------------------------------------------


def _rot_z(yaw: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices about +Z by ``yaw`` (rad)."""
    c, s = np.cos(yaw), np.sin(yaw)
    z, o = np.zeros_like(yaw), np.ones_like(yaw)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1),
                     np.stack([z, z, o], -1)], -2)


def actor_frame(first_frame: np.ndarray, joint_names: Sequence[str] = INTER18_JOINTS
                ) -> tuple[np.ndarray, np.ndarray]:
    """Origin and heading of the reactive-GAN normalisation from the actor's first frame.

    Args:
        first_frame: (N, J, 3) or (J, 3) actor poses, metres, world frame Z-up.
        joint_names: names of the J joints (must include the pelvis, shoulders and hips).

    Returns:
        ``(origin, yaw)``: (N, 3) / (3,) pelvis on the floor ``(p_x, p_y, 0)`` and (N,) / ()
        facing angle about +Z, rad (0 = facing +x), float64.

    Raises:
        MotionError: the shoulders and hips give no horizontal direction (a person lying
            with the body axis vertical... or a degenerate pose).
    """
    p = np.asarray(first_frame, dtype=np.float64)
    single = p.ndim == 2
    p = p[None] if single else p
    idx = {n: list(joint_names).index(n) for n in
           ("pelvis", "left_shoulder", "right_shoulder", "left_hip", "right_hip")}
    across = (p[:, idx["right_shoulder"]] - p[:, idx["left_shoulder"]]
              + p[:, idx["right_hip"]] - p[:, idx["left_hip"]])
    forward = np.stack([-across[:, 1], across[:, 0]], axis=-1)  # ẑ × across, horizontal
    norm = np.linalg.norm(forward, axis=-1)
    if (norm < 1e-3).any():
        n = int(np.argmin(norm))
        raise MotionError(f"pose {n}: shoulders and hips give no horizontal facing "
                          "direction; cannot normalise", frame=n)
    yaw = np.arctan2(forward[:, 1], forward[:, 0])
    origin = p[:, idx["pelvis"]] * np.array([1.0, 1.0, 0.0])
    return (origin[0], yaw[0]) if single else (origin, yaw)


def normalise(positions: np.ndarray, origin: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """World -> actor frame: ``R_z(-θ) (x - o)``.

    Args:
        positions: (N, ..., 3) world positions, metres (e.g. (N, T, J, 3)).
        origin: (N, 3); yaw: (N,) rad (from :func:`actor_frame`).

    Returns:
        float32 array of the shape of ``positions``.
    """
    x = np.asarray(positions, dtype=np.float64)
    o = np.asarray(origin, dtype=np.float64)
    rot = _rot_z(-np.asarray(yaw, dtype=np.float64))  # (N, 3, 3)
    shape = (x.shape[0],) + (1,) * (x.ndim - 2)
    rel = x - o.reshape(shape + (3,))
    return np.einsum("n...j,nij->n...i", rel, rot).astype(np.float32)


def denormalise(positions: np.ndarray, origin: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Actor frame -> world, the exact inverse of :func:`normalise`: ``R_z(θ) x + o``.

    Args and returns as :func:`normalise`.
    """
    x = np.asarray(positions, dtype=np.float64)
    o = np.asarray(origin, dtype=np.float64)
    rot = _rot_z(np.asarray(yaw, dtype=np.float64))
    shape = (x.shape[0],) + (1,) * (x.ndim - 2)
    out = np.einsum("n...j,nij->n...i", x, rot) + o.reshape(shape + (3,))
    return out.astype(np.float32)


# -- windows -------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class InteractionWindows:
    """Fixed-length two-person windows, normalised in the actor's first-frame frame.

    Attributes:
        actor: (N, T, J, 3) float32 actor positions, metres, actor frame (module docstring).
        reactor: (N, T, J, 3) float32 reactor positions, same frame.
        origin: (N, 3) float64 world origin of each window's frame (actor pelvis on the
            floor at the window's first frame); yaw: (N,) float64 its heading, rad.
        label: (N,) int64 index into ``labels``.
        recording: (N,) int64 index into ``recording_names``.
        start: (N,) int64 first frame of the window in its recording (at ``fps``).
        labels: class names present, in :data:`INTERACTION_LABELS` order.
        recording_names: names of the recordings (split units).
        fps: frame rate, Hz. stride: frames between window starts.
        skipped: recordings too short for one window.
        joint_names: the J joints (:data:`INTER18_JOINTS`).
    """

    actor: np.ndarray
    reactor: np.ndarray
    origin: np.ndarray
    yaw: np.ndarray
    label: np.ndarray
    recording: np.ndarray
    start: np.ndarray
    labels: tuple[str, ...]
    recording_names: tuple[str, ...]
    fps: float
    stride: int
    skipped: tuple[str, ...] = ()
    joint_names: tuple[str, ...] = field(default=INTER18_JOINTS)

    def __len__(self) -> int:
        return int(self.actor.shape[0])

    @property
    def window(self) -> int:
        """Frames per window (T)."""
        return int(self.actor.shape[1])

    @property
    def skeleton(self) -> Skeleton:
        return inter18_skeleton()

    @property
    def window_recording_names(self) -> np.ndarray:
        """(N,) recording name of each window."""
        return np.asarray(self.recording_names, dtype=object)[self.recording]

    @property
    def window_labels(self) -> np.ndarray:
        """(N,) class name of each window."""
        return np.asarray(self.labels, dtype=object)[self.label]

    def subset(self, index: np.ndarray | Sequence[int]) -> InteractionWindows:
        """Windows selected by an integer or boolean index (names and labels kept)."""
        i = np.asarray(index)
        return InteractionWindows(
            self.actor[i], self.reactor[i], self.origin[i], self.yaw[i], self.label[i],
            self.recording[i], self.start[i], self.labels, self.recording_names, self.fps,
            self.stride, self.skipped, self.joint_names)

    def to_world(self, positions: np.ndarray) -> np.ndarray:
        """(N, T', J, 3) positions in these windows' frames -> world, metres
        (:func:`denormalise` with each window's origin and yaw)."""
        p = np.asarray(positions)
        if p.shape[0] != len(self):
            raise MotionError(f"positions hold {p.shape[0]} windows; these windows are "
                              f"{len(self)}", field="positions")
        return denormalise(p, self.origin, self.yaw)

    def interaction(self, n: int, reactor: np.ndarray | None = None,
                    name: str | None = None, actor: np.ndarray | None = None
                    ) -> Interaction:
        """Window ``n`` back in the world as an :class:`Interaction` (layout skeleton, at
        ``fps``), with ``reactor`` (and ``actor``), (T, J, 3) in the actor frame, in place
        of the real ones if given, e.g. to score a generated reaction's physics."""
        people = []
        for key, given, real in (("actor", actor, self.actor[n]),
                                 ("reactor", reactor, self.reactor[n])):
            x = real if given is None else np.asarray(given, dtype=np.float32)
            if x.shape != real.shape:
                raise MotionError(f"{key} must have shape {real.shape}; got {x.shape}",
                                  field=key)
            people.append(x)
        world = denormalise(np.stack(people)[:, None], self.origin[[n, n]],
                            self.yaw[[n, n]])[:, 0]
        rec = str(self.recording_names[self.recording[n]])
        name = name or f"{rec}@{int(self.start[n])}"
        skel = self.skeleton
        a = Motion(world[0], self.fps, skel, f"{name}/actor", {"source": rec})
        r = Motion(world[1], self.fps, skel, f"{name}/reactor", {"source": rec})
        return Interaction(a, r, label=self.labels[self.label[n]], roles_known=True,
                           name=name, metadata={"recording": rec,
                                                "start_frame": int(self.start[n])})


def make_windows(recordings: Iterable[Interaction], *, window: int = WINDOW_FRAMES,
                 stride: int = WINDOW_STRIDE) -> InteractionWindows:
    """Sliding windows over recordings made by :func:`make_interaction` (or
    :func:`load_recordings`), each normalised in its actor's first-frame frame.

    Args:
        recordings: recordings on the 18-keypoint layout, all at one fps, with
            vocabulary labels and unique names.
        window: frames per window (T >= 2). stride: frames between window starts.

    Raises:
        MotionError: bad configuration, mixed frame rates, duplicate recording names, or
            no recording long enough for one window.
        SkeletonError: a recording not on the layout.
    """
    for key, value in (("window", window), ("stride", stride)):
        if int(value) != value or value < (2 if key == "window" else 1):
            raise MotionError(f"{key} must be an integer >= {2 if key == 'window' else 1}; "
                              f"got {value!r}", field=key)
    recs = list(recordings)
    if not recs:
        raise MotionError("no recordings to cut into windows")
    fps = recs[0].fps
    names = [r.name for r in recs]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise MotionError(f"recording names must be unique (they are the split units); "
                          f"repeated: {', '.join(dup)}")
    for r in recs:
        if r.fps != fps:
            raise MotionError(f"recording {r.name!r} is at {r.fps:g} fps, {recs[0].name!r} "
                              f"at {fps:g}; build every recording at one fps", field="fps")
        for m in r.people:
            if m.skeleton.joint_names != INTER18_JOINTS:
                raise SkeletonError(f"recording {r.name!r}: {m.name!r} is not on the "
                                    "18-keypoint layout (use make_interaction)")
        interaction_label(r.label, source=r.name)
    labels = tuple(k for k in INTERACTION_LABELS if k in {r.label for r in recs})
    parts: dict[str, list[np.ndarray]] = {k: [] for k in
                                          ("a", "b", "o", "y", "l", "r", "s")}
    skipped = []
    for k, r in enumerate(recs):
        starts = np.arange(0, r.num_frames - window + 1, stride, dtype=np.int64)
        if len(starts) == 0:
            skipped.append(r.name)
            continue
        idx = starts[:, None] + np.arange(window)
        a, b = r.actor.positions[idx], r.reactor.positions[idx]
        origin, yaw = actor_frame(a[:, 0])
        parts["a"].append(normalise(a, origin, yaw))
        parts["b"].append(normalise(b, origin, yaw))
        parts["o"].append(origin)
        parts["y"].append(yaw)
        parts["l"].append(np.full(len(starts), labels.index(r.label), dtype=np.int64))
        parts["r"].append(np.full(len(starts), k, dtype=np.int64))
        parts["s"].append(starts)
    if not parts["a"]:
        seen = ", ".join(f"{r.name} ({r.num_frames} frames)" for r in recs)
        raise MotionError(f"no recording gives a single {window}-frame window at {fps:g} "
                          f"fps; recordings: {seen}")
    cat = {k: np.concatenate(v) for k, v in parts.items()}
    return InteractionWindows(cat["a"], cat["b"], cat["o"], cat["y"], cat["l"], cat["r"],
                              cat["s"], labels, tuple(names), float(fps), int(stride),
                              tuple(skipped))


def split_by_recording(
    windows: InteractionWindows,
    test_recordings: Sequence[str] | None = DEFAULT_TEST_RECORDINGS,
    *,
    test_fraction: float = 0.25,
    seed: int = 0,
) -> ClipSplit:
    """Train/test windows with no recording on both sides.

    Args:
        windows: the windows to split.
        test_recordings: recordings on the test side (default
            :data:`DEFAULT_TEST_RECORDINGS`); None: a seeded split by recording targeting
            ``test_fraction`` of the windows (:func:`simenv.data.prediction_data.split_by_clip`).
        test_fraction, seed: used only when ``test_recordings`` is None.

    Raises:
        MotionError: a named test recording is not in the windows, or one side is empty.
    """
    names = windows.window_recording_names
    if test_recordings is None:
        return split_by_clip(names, test_fraction, seed)
    present = set(windows.recording_names) - set(windows.skipped)
    unknown = [n for n in test_recordings if n not in present]
    if unknown:
        raise MotionError(f"test recording(s) {', '.join(unknown)} not among the windows' "
                          f"recordings ({', '.join(sorted(present))})",
                          field="test_recordings")
    is_test = np.isin(names.astype(str), list(test_recordings))
    if is_test.all() or not is_test.any():
        raise MotionError("the split leaves one side empty; name some but not all "
                          "recordings", field="test_recordings")
    train_names = sorted(present - set(test_recordings))
    return ClipSplit(train=np.flatnonzero(~is_test), test=np.flatnonzero(is_test),
                     train_clips=tuple(train_names), test_clips=tuple(test_recordings))

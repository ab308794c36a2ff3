"""Which kind of source a motion comes from, and the sensor-family profile that judges it.

The default thresholds (:mod:`simenv.plausibility.thresholds`,
:mod:`simenv.plausibility.body_thresholds`) are calibrated on marker-based motion capture,
whose bones are rigid and whose joint centres barely tremble. A depth camera estimates every
joint on its own in every frame: its bones change length by tens of percent and its joints
jump, so judged by the mocap thresholds nearly every real depth-camera clip is "implausible"
(``bone_length`` at 2-30 tolerances, docs/plausibility.md). Those clips are judged instead by
their *sensor family's profile*: thresholds set from real clips of that family, bundled in
``assets/profiles/depth_camera.json`` (installed as ``simenv/assets/profiles/``; written,
with how it was computed, by ``benchmarks/depth_camera_profiles.py``).

Source kinds (:data:`SOURCE_KINDS`)
    ``mocap`` (BVH, ASF/AMC), ``body_model`` (joints of a fitted body model: SMPL-22 of
    HumanML3D / AMASS, KIT-21), ``kinect_v1`` (Kinect v1 and its OpenNI 15-joint
    skeletons: MSR Action3D, UTKinect, Florence 3D, SBU), ``kinect_v2`` (Kinect v2 / Azure
    Kinect and skeleton-SDK depth cameras: NTU RGB+D, Nuitrack), ``generated`` (declared
    only: a model's output), ``unknown``.

Detection (:func:`detect_source`)
    From the reader's skeleton name (:data:`SKELETON_KINDS`), else the joint names when a
    depth camera's tracker uses them (OpenNI / NiTE, Kinect, Azure Kinect names in a BVH or a
    joint table: :attr:`~simenv.core.joint_map.NamingConvention.sensor`), else its ``format``
    metadata (:data:`FORMAT_KINDS`), else ``unknown``. A declared kind (``source=``, ``simenv score
    --source``) wins; ``generated`` is judged by the profile of the family its skeleton comes
    from (a model trained on NTU RGB+D is asked to move like NTU's real clips), the mocap
    thresholds otherwise.

Profiles (:func:`profile_for`, :func:`apply_profile`)
    ``mocap`` for ``mocap``, ``body_model``, ``unknown`` and generated motion of those: the
    defaults, unchanged. ``kinect_v1`` and ``kinect_v2``: the bundled family profile, a set of
    threshold fields calibrated at one frame rate (:attr:`Profile.fps`); a family may hold one
    per rate (``kinect_v1`` at 15 fps, ``kinect_v1@30`` at 30), and a clip is judged by the
    one of its nearest rate (:func:`profile_for`, :func:`at_profile_rate`).
    :func:`apply_profile` sets a profile field only where the given configuration still
    holds that field's default, so thresholds a user set explicitly stay theirs.

Rigid files (:func:`for_clip`)
    A depth camera's bone-length noise is in its joint positions; a file that stores
    rotations on fixed bones (a NiTE recording exported as rotation-channel BVH, a model's
    BVH output) cannot carry it: every bone is its OFFSET (the reader's
    ``metadata["rigid_bones"]``). Such a clip keeps the motion-capture bone tolerances
    (:data:`BONE_FIELDS`) under its family's profile, so a stretched bone is still caught;
    the rest of the profile (speeds, jerk, floor) judges it as the sensor's.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

from simenv.core.errors import SimenvError
from simenv.core.joint_map import sensor_family
from simenv.core.motion import Interaction, Motion
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.thresholds import DEFAULT_THRESHOLDS, Thresholds

if TYPE_CHECKING:  # the scorer's settings import the body (MuJoCo)
    from simenv.plausibility.metric import ScoreConfig

#: Every source kind a report can name.
SOURCE_KINDS: tuple[str, ...] = ("mocap", "body_model", "kinect_v1", "kinect_v2", "generated",
                                 "unknown")
#: What ``source=`` / ``--source`` accepts: ``auto`` detects.
DECLARABLE_SOURCES: tuple[str, ...] = ("auto", "mocap", "body_model", "kinect_v1", "kinect_v2",
                                       "generated")
#: The depth-camera families with a bundled profile.
DEPTH_FAMILIES: tuple[str, ...] = ("kinect_v1", "kinect_v2")
#: Name of the profile that keeps the default (motion-capture) thresholds.
MOCAP_PROFILE = "mocap"

#: Reader skeleton name -> source kind.
SKELETON_KINDS: dict[str, str] = {
    "kinect_v1_20": "kinect_v1",
    "sbu15": "kinect_v1",
    "florence15": "kinect_v1",
    "kinect_v2_25": "kinect_v2",
    "azure_kinect32": "kinect_v2",
    "nuitrack": "kinect_v2",
    "xsens_mvn23": "mocap",  # an inertial suit's segments: rigid bones, as optical mocap
    "smpl22": "body_model",
    "kit21": "body_model",
}
#: Reader ``format`` metadata -> source kind, when the skeleton name says nothing.
FORMAT_KINDS: dict[str, str] = {
    "bvh": "mocap",
    "asf_amc": "mocap",
    "msr_action3d": "kinect_v1",
    "utkinect": "kinect_v1",
    "florence3d": "kinect_v1",
    "sbu": "kinect_v1",
    "ntu": "kinect_v2",
    "nuisi": "kinect_v2",
    "humanml3d": "body_model",
    "humanml3d_features": "body_model",
}

#: Profile fields that allow a depth camera's bone-length noise; a clip whose file keeps its
#: bones rigid is judged without them (:func:`for_clip`).
BONE_FIELDS: tuple[str, ...] = ("bone_length_rel_max", "bone_length_head_rel_max")

#: The bundled profiles, relative to the assets folder.
PROFILE_FILE = ("profiles", "depth_camera.json")


@dataclass(frozen=True)
class SourceKind:
    """What a motion is, and how that was decided.

    Attributes:
        kind: one of :data:`SOURCE_KINDS`.
        profile: the profile that judges it (:data:`MOCAP_PROFILE`, a family of
            :data:`DEPTH_FAMILIES`, or that family's profile for the clip's rate, e.g.
            ``kinect_v1@30``).
        how: ``"declared"``, ``"skeleton <name>"``, ``"joint names <convention>"``,
            ``"format <name>"`` or ``"nothing matched"``.
        judged_fps: the frame rate the clip was judged at when it was thinned towards its
            profile's (:func:`at_profile_rate`), else None.
        rigid_bones: True when a family profile judges a file whose bones are rigid, so the
            motion-capture bone tolerances stayed (:func:`for_clip`).
    """

    kind: str
    profile: str
    how: str
    judged_fps: float | None = None
    rigid_bones: bool = False

    def record(self) -> dict[str, str | float | bool]:
        """JSON-ready ``{kind, profile, how}`` (and ``judged_fps``, ``rigid_bones`` when
        set)."""
        out: dict[str, str | float | bool] = {"kind": self.kind, "profile": self.profile,
                                              "how": self.how}
        if self.judged_fps is not None:
            out["judged_fps"] = self.judged_fps
        if self.rigid_bones:
            out["rigid_bones"] = True
        return out


@dataclass(frozen=True)
class Profile:
    """A sensor family's thresholds.

    Attributes:
        name: the family (``kinect_v1``, ``kinect_v2``).
        thresholds: :class:`Thresholds` field -> value (only the fields it changes).
        body: :class:`BodyThresholds` field -> value (only the fields it changes).
        provenance: how the values were computed (calibration sources, percentile, clips).
        fps: the calibration clips' frame rate (their median). A depth camera's noise is per
            frame, so the jerk and the frame-to-frame jumps of its clips grow with the rate:
            the thresholds hold at this rate, a clip is judged by its family's profile of the
            nearest rate (:func:`profile_for`) and one several times faster is thinned to it
            (:func:`at_profile_rate`). None: judged at any rate.
    """

    name: str
    thresholds: dict[str, float]
    body: dict[str, float]
    provenance: dict[str, Any]
    fps: float | None = None


def _people(clip: Motion | Interaction) -> tuple[Motion, ...]:
    return clip.people if isinstance(clip, Interaction) else (clip,)


def _first(clip: Motion | Interaction) -> Motion:
    return clip.people[0] if isinstance(clip, Interaction) else clip


def _measured_kind(motion: Motion) -> tuple[str, str]:
    """(kind, how) from the skeleton name, else the naming convention a depth camera's tracker
    uses (:func:`~simenv.core.joint_map.sensor_family`: a NiTE recording written as BVH is a
    depth camera's clip, not motion capture), else the reader's format."""
    name = motion.skeleton.name
    if name in SKELETON_KINDS:
        return SKELETON_KINDS[name], f"skeleton {name}"
    family = sensor_family(motion)
    if family is not None:
        return family, f"joint names {motion.metadata['joint_map']['convention']}"
    fmt = motion.metadata.get("format")
    if isinstance(fmt, str) and fmt in FORMAT_KINDS:
        return FORMAT_KINDS[fmt], f"format {fmt}"
    return "unknown", "nothing matched"


def detect_source(clip: Motion | Interaction, declared: str = "auto") -> SourceKind:
    """The source kind of ``clip`` and the profile that judges it (module docstring).

    Args:
        clip: a motion or a two-person interaction (one sensor: judged by its first person).
        declared: one of :data:`DECLARABLE_SOURCES`; ``"auto"`` detects.

    Raises:
        SimenvError: ``declared`` is not one of :data:`DECLARABLE_SOURCES` (``field``
            ``source``).
    """
    if declared not in DECLARABLE_SOURCES:
        raise SimenvError(f"unknown source kind {declared!r}; expected one of "
                          f"{', '.join(DECLARABLE_SOURCES)}", field="source")
    measured, how = _measured_kind(_first(clip))
    if declared == "auto":
        kind = measured
    else:
        kind, how = declared, "declared"
    family = measured if kind == "generated" else kind
    return SourceKind(kind, family if family in DEPTH_FAMILIES else MOCAP_PROFILE, how)


def profile_path() -> Path:
    """Path of the bundled profiles file (inside the installed package)."""
    from simenv.assets import assets_root  # assets sit below plausibility

    return assets_root().joinpath(*PROFILE_FILE)


def _check_fields(name: str, section: str, values: Mapping[str, Any], cls: type,
                  path: Path) -> dict[str, float]:
    known = {f.name for f in fields(cls)}
    out = {}
    for key, value in values.items():
        if key not in known or not isinstance(value, (int, float)) or not value > 0:
            raise SimenvError(f"profile {name!r} {section} field {key!r} = {value!r}: expected a "
                              f"positive number for one of {cls.__name__}'s fields",
                              source=path, field=f"{name}.{section}.{key}")
        out[key] = float(value)
    return out


@lru_cache(maxsize=4)
def _load(path: Path) -> dict[str, Profile]:
    if not path.is_file():
        raise SimenvError("the bundled depth-camera profiles are missing (regenerate them with "
                          "benchmarks/depth_camera_profiles.py)", source=path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        raw = data["profiles"]
    except (json.JSONDecodeError, KeyError, TypeError) as exc:
        raise SimenvError(f"not a profiles file (expected JSON with 'profiles'): {exc}",
                          source=path) from exc
    out = {}
    for name, p in raw.items():
        fps = p.get("fps")
        if fps is not None and not (isinstance(fps, (int, float)) and fps > 0):
            raise SimenvError(f"profile {name!r} fps = {fps!r}: expected a positive frame rate "
                              "or none", source=path, field=f"{name}.fps")
        out[name] = Profile(
            name=name,
            thresholds=_check_fields(name, "thresholds", p.get("thresholds", {}), Thresholds, path),
            body=_check_fields(name, "body", p.get("body", {}), BodyThresholds, path),
            provenance=dict(p.get("provenance", {})),
            fps=None if fps is None else float(fps))
    return out


def load_profiles(path: str | Path | None = None) -> dict[str, Profile]:
    """The sensor-family profiles, by family name (the bundled file by default).

    Raises:
        SimenvError: the file is missing, is not a profiles file, or a field is not a
            positive number of :class:`Thresholds` / :class:`BodyThresholds`.
    """
    return _load(Path(path) if path is not None else profile_path())


def profile_for(kind: SourceKind, fps: float | None = None) -> Profile | None:
    """The family profile judging ``kind``, or None for the mocap defaults.

    A family may hold one profile per calibration rate: ``<family>`` and
    ``<family>@<fps>`` (:attr:`Profile.fps`). For a clip at ``fps`` the one whose rate is
    nearest (by ratio; a tie goes to the slower) judges; see :func:`at_profile_rate` for a
    clip several times faster than it. Without ``fps``, the family's own ``<family>``
    profile.

    Raises:
        SimenvError: the bundled file lacks the family (names the file).
    """
    if kind.profile == MOCAP_PROFILE:
        return None
    profiles = load_profiles()
    if kind.profile not in profiles:
        raise SimenvError(f"no profile {kind.profile!r} in the bundled profiles (has "
                          f"{', '.join(profiles)})", source=profile_path(), field="profile")
    rated = [(p.fps, p) for n, p in profiles.items()
             if (n == kind.profile or n.startswith(f"{kind.profile}@")) and p.fps is not None]
    if fps is None or fps <= 0 or not rated:
        return profiles[kind.profile]
    return min(rated, key=lambda r: (abs(math.log(fps / r[0])), r[0]))[1]


def has_rigid_bones(clip: Motion | Interaction) -> bool:
    """Whether every person's file keeps its bones rigid (the reader's
    ``metadata["rigid_bones"]``: BVH / ASF with no translation channel below a root)."""
    return all(m.metadata.get("rigid_bones") is True for m in _people(clip))


def for_clip(profile: Profile | None, clip: Motion | Interaction) -> Profile | None:
    """``profile`` without its :data:`BONE_FIELDS` when ``clip``'s file keeps its bones rigid
    (:func:`has_rigid_bones`): the sensor's bone-length noise cannot be in such a file, so
    only a defect (a stretched bone, a generator's drifting limb) changes a bone there. None
    and every other clip: ``profile`` unchanged."""
    if profile is None or not has_rigid_bones(clip):
        return profile
    return replace(profile, thresholds={k: v for k, v in profile.thresholds.items()
                                        if k not in BONE_FIELDS})


def at_profile_rate(clip: Motion | Interaction, profile: Profile | None
                    ) -> Motion | Interaction:
    """``clip`` thinned to ``profile``'s rate when it is at least twice as fast: every
    ``n``-th frame, ``n = floor(clip fps / profile fps)`` (a 60-fps clip judged by a 30-fps
    profile reads frames 0, 2, 4, ...). Thinning keeps the sensor's own samples, so its noise
    is the noise the profile was calibrated on; interpolating would smooth it (and a seeded
    jitter with it). Unchanged otherwise, and for None or a rate-free profile."""
    if profile is None or profile.fps is None:
        return clip
    step = math.floor(clip.fps / profile.fps + 1e-6)
    if step < 2:
        return clip
    people = [replace(m, positions=m.positions[::step], fps=m.fps / step,
                      rotations=None if m.rotations is None else m.rotations[::step])
              for m in _people(clip)]
    if isinstance(clip, Interaction):
        return replace(clip, actor=people[0], reactor=people[1])
    return people[0]


def _merged(current: Any, default: Any, values: Mapping[str, float]) -> Any:
    """``current`` with each of ``values`` set where ``current`` still holds ``default``'s."""
    changes = {k: v for k, v in values.items() if getattr(current, k) == getattr(default, k)}
    return replace(current, **changes) if changes else current


def apply_profile(config: ScoreConfig, profile: Profile | None) -> ScoreConfig:
    """``config`` judged by ``profile``: each profile field replaces the configuration's
    value where that is still the default (a user's explicit threshold stays); None
    returns ``config`` unchanged."""
    if profile is None:
        return config
    return replace(config,
                   thresholds=_merged(config.thresholds, DEFAULT_THRESHOLDS, profile.thresholds),
                   body=_merged(config.body, DEFAULT_BODY_THRESHOLDS, profile.body))


__all__ = [
    "BONE_FIELDS",
    "DECLARABLE_SOURCES",
    "DEPTH_FAMILIES",
    "FORMAT_KINDS",
    "MOCAP_PROFILE",
    "PROFILE_FILE",
    "SKELETON_KINDS",
    "SOURCE_KINDS",
    "Profile",
    "SourceKind",
    "apply_profile",
    "at_profile_rate",
    "detect_source",
    "for_clip",
    "has_rigid_bones",
    "load_profiles",
    "profile_for",
    "profile_path",
]

"""What the ``simenv`` commands share: the exit status of a user error, argument types and
help, the ``train``/``eval`` parser shape, and the clip summary, retargeting and NPZ writing
of ``info``, ``retarget``, ``render`` and ``demo``.

The body modules (MuJoCo) are imported where a clip is measured or retargeted, so that
building the command line stays fast.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import SimenvError
from simenv.core.joint_map import JOINT_MAP_HELP
from simenv.core.motion import Interaction, Motion
from simenv.core.skeletons import CANONICAL_KEYPOINTS

#: Exit status of a user error (:class:`~simenv.core.errors.SimenvError`), as argparse's.
EXIT_USER_ERROR = 2

#: Help of the positional motion argument of the commands that read motion.
PATH_HELP = (
    "a motion file (BVH, ASF/AMC, Kinect text, NPZ), a folder with a two-person recording, "
    "or the two files of one"
)

def add_joint_map_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--joint-map FILE.toml`` (see :data:`JOINT_MAP_HELP`)."""
    parser.add_argument("--joint-map", metavar="FILE.toml", help=JOINT_MAP_HELP)


def add_units_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--units UNIT`` and ``--scale M``: the file's length unit when the reader cannot
    tell it from the skeleton's size (BVH, ASF/AMC and joint tables detect it)."""
    from simenv.io import UNIT_SCALES

    parser.add_argument("--units", choices=tuple(UNIT_SCALES), help=(
        "the file's length unit, instead of the one detected from the skeleton's size "
        "(BVH, ASF/AMC, joint tables)"))
    parser.add_argument("--scale", type=float, metavar="M", help=(
        "metres per file unit, for a skeleton in no known unit (e.g. a character rig "
        "twice human size: 0.005 for centimetres)"))


def read_options(args: argparse.Namespace) -> dict[str, Any]:
    """Reader options of a command's arguments: ``joint_map=``, ``units=`` and ``scale=``
    where given."""
    return {name: value for name in ("joint_map", "units", "scale")
            if (value := getattr(args, name, None)) is not None}


#: The model kinds of ``train`` and ``eval``.
MODEL_KINDS = ("predictor", "classifier", "recogniser", "interaction")


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def check_suffix(path: str, suffix: str, option: str) -> Path:
    """``path`` as a Path; a :class:`SimenvError` naming ``option`` unless it ends with
    ``suffix`` (lower case, e.g. ``".npz"``)."""
    out = Path(path)
    if out.suffix.lower() != suffix:
        raise SimenvError(f"{option} must end with {suffix}; got {out.name!r}", field=option)
    return out


class HelpFormatter(argparse.HelpFormatter):
    """argparse help that states each option's default, ``(default: X)``, unless its help
    already names one or there is nothing to state (a flag that is off, an option unset)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if (default is None or default is False or default is argparse.SUPPRESS
                or default == [] or "default" in text
                or (not action.option_strings and action.nargs not in ("?", "*"))):
            return text
        return f"{text} (default: %(default)s)".lstrip()


def command_parser(prog: str, description: str | None) -> argparse.ArgumentParser:
    """An empty parser of a second-level command (``simenv train predictor``, ``simenv
    rehearse``) whose options the script that runs it adds: help and usage errors name
    ``prog`` and every option's default (:class:`HelpFormatter`)."""
    return argparse.ArgumentParser(prog=prog, description=description,
                                   formatter_class=HelpFormatter)


def add_model_command(subparsers: argparse._SubParsersAction, verb: str, text: str,
                      run: Callable[[argparse.Namespace], int]) -> None:
    """Add ``simenv VERB KIND ...`` (``train``, ``eval``): the options after KIND go to the
    parser of that kind (``args.kind``, ``args.options``), which ``run`` builds (importing
    the kind's script, PyTorch included, only then) with :func:`command_parser`, so that
    ``simenv VERB KIND --help`` and its usage errors come from the parser that runs it."""
    cmd = subparsers.add_parser(verb, help=text.split(" (")[0].split(":")[0], description=text)
    cmd.add_argument("kind", choices=MODEL_KINDS, metavar="KIND", help=" or ".join(MODEL_KINDS))
    cmd.add_argument("options", nargs=argparse.REMAINDER, metavar="...",
                     help=f"options of that kind (simenv {verb} KIND --help)")
    cmd.set_defaults(func=run)


# -- clips ----------------------------------------------------------------------------------


def _stature(motion: Motion) -> float | None:
    """Standing height (m, sole to top of head) of the body fitted to the bone lengths (a
    skeleton without a pelvis joint: the body retargeting fits, pelvis at the hips' midpoint)."""
    from simenv.body.humanoid import fit_dimensions  # MuJoCo: only when a clip is described
    from simenv.body.retarget import with_derived_pelvis

    try:
        return round(fit_dimensions(with_derived_pelvis(motion)).height, 3)
    except SimenvError:  # e.g. no pelvis/hips to measure a body from
        return None


def joint_map_record(motion: Motion) -> dict[str, Any]:
    """How the motion's joints map onto the canonical keypoints: ``canonical`` (keypoint ->
    joint), ``how`` (keypoint -> how it was found), ``convention``, ``missing``, ``notes``.
    A skeleton whose reader knows it (CMU, Kinect, SMPL, ...) reads ``how`` = ``reader``."""
    recorded = motion.metadata.get("joint_map")
    if recorded is not None:
        return dict(recorded)
    canonical = dict(motion.skeleton.canonical)
    return {"convention": motion.skeleton.name, "canonical": canonical,
            "how": {k: "reader" for k in canonical},
            "missing": [k for k in CANONICAL_KEYPOINTS if k not in canonical], "notes": []}


def _person_info(motion: Motion) -> dict[str, Any]:
    """``height_m`` is the joint span (highest minus lowest joint, 95th percentile over
    frames); ``stature_m`` the standing height of the fitted body, when one can be fitted."""
    meta = motion.metadata
    return {
        "name": motion.name,
        "joints": motion.num_joints,
        "frames": motion.num_frames,
        "fps": motion.fps,
        "duration_s": round(motion.duration, 4),
        "height_m": round(motion.height(), 3),
        "stature_m": _stature(motion),
        "units_in_file": meta.get("units"),
        "joint_map": joint_map_record(motion),
        "quirks": list(meta.get("quirks", [])),
        "repairs": list(meta.get("repairs", [])),
    }


def describe(clip: Motion | Interaction) -> dict[str, Any]:
    """JSON-ready summary of a clip: format, people, joints, frames, fps, duration, heights."""
    people = clip.people if isinstance(clip, Interaction) else (clip,)
    first = people[0]
    info: dict[str, Any] = {
        "name": clip.name,
        "source": str(clip.metadata.get("source", first.metadata.get("source", ""))),
        "format": clip.metadata.get("format", first.metadata.get("format")),
        "people": len(people),
        "frames": first.num_frames,
        "fps": first.fps,
        "duration_s": round(first.duration, 4),
        "persons": [_person_info(m) for m in people],
    }
    if isinstance(clip, Interaction):
        info["label"] = clip.label
        info["quirks"] = list(clip.metadata.get("quirks", []))
    return info


def retarget_clip(clip: Motion | Interaction) -> Any:
    """Retarget one clip (each person on their own fitted humanoid); see
    :mod:`simenv.body.retarget`."""
    from simenv.body.retarget import retarget  # MuJoCo: only when a clip is retargeted

    return retarget(clip)


def summary(result: Any) -> dict[str, Any]:
    """The one-object JSON summary of a retargeting result (residuals in metres)."""
    qpos = np.asarray(result.qpos)
    return {
        "frames": int(qpos.shape[0]),
        "fps": float(result.fps),
        "people": len(_people_results(result)),
        "mean_residual_m": float(result.mean_residual),
        "p95_residual_m": float(result.p95_residual),
        "max_residual_m": float(result.max_residual),
        "seconds": float(result.seconds),
    }


def _people_results(result: Any) -> list[Any]:
    for attr in ("people", "results", "persons"):
        people = getattr(result, attr, None)
        if people is not None:
            return list(people)
    return [result]


def _humanoid_arrays(humanoid: Any, suffix: str) -> dict[str, np.ndarray]:
    """The humanoid's dimensions as NPZ arrays: ``dim_names``/``dim_values`` (metres; 3-vector
    offsets split into ``_x``/``_y``/``_z``), ``height`` (m) and ``mass`` (kg)."""
    names: list[str] = []
    values: list[float] = []
    dims = getattr(humanoid, "dims", None)
    if dims is not None and dataclasses.is_dataclass(dims):
        for f in dataclasses.fields(dims):
            value = getattr(dims, f.name)
            if isinstance(value, (int, float)):
                names.append(f.name)
                values.append(float(value))
            elif isinstance(value, tuple) and len(value) == 3 and all(
                isinstance(v, (int, float)) for v in value
            ):
                names += [f"{f.name}_{axis}" for axis in "xyz"]
                values += [float(v) for v in value]
    arrays = {
        f"dim_names{suffix}": np.array(names, dtype=str),
        f"dim_values{suffix}": np.array(values, dtype=np.float64),
    }
    height = getattr(dims, "height", None)
    if isinstance(height, (int, float)):
        arrays[f"height{suffix}"] = np.float64(height)
    mass = getattr(humanoid, "total_mass", None)
    if isinstance(mass, (int, float)):
        arrays[f"mass{suffix}"] = np.float64(mass)
    return arrays


def save_npz(result: Any, path: str | Path) -> Path:
    """Write ``qpos`` (T, nq), ``fps``, per-person ``qpos_i`` and humanoid dimensions to NPZ."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, np.ndarray] = {
        "qpos": np.asarray(result.qpos, dtype=np.float64),
        "fps": np.float64(result.fps),
        "residuals": np.asarray(_residuals(result), dtype=np.float32),
    }
    people = _people_results(result)
    if len(people) == 1:
        arrays.update(_humanoid_arrays(people[0].humanoid, ""))
    else:
        for i, person in enumerate(people):
            arrays[f"qpos_{i}"] = np.asarray(person.qpos, dtype=np.float64)
            arrays.update(_humanoid_arrays(person.humanoid, f"_{i}"))
    np.savez(path, **arrays)
    return path


def _residuals(result: Any) -> np.ndarray:
    people = _people_results(result)
    if len(people) == 1:
        return np.asarray(people[0].residuals)
    return np.concatenate([np.asarray(p.residuals) for p in people], axis=1)


__all__ = ["EXIT_USER_ERROR", "JOINT_MAP_HELP", "MODEL_KINDS", "PATH_HELP", "HelpFormatter",
           "add_joint_map_option", "add_model_command", "add_units_options", "check_suffix",
           "command_parser",
           "describe",
           "joint_map_record",
           "positive_int", "read_options", "retarget_clip", "save_npz", "summary"]

"""Berkeley MHAD skeletons (``SkeletalData/skl_s<SS>_a<AA>_r<RR>.bvh``).

The Berkeley Multimodal Human Action Database (Ofli et al., WACV 2013): 12 people
(``s01``-``s12``), 11 actions (``a01``-``a11``, :data:`MHAD_ACTIONS`), 5 repetitions
(``r01``-``r05``), and one T-pose per person (``skl_s<SS>_t-pose.bvh``). Its skeletons
were fitted to the optical motion capture and released as BVH: 30 joints (``Hips``,
``spine``-``spine2``, ``Neck``, ``Head``, arms with ``*ArmRoll`` / ``*ForeArmRoll`` twist
joints, legs with ``*UpLegRoll`` / ``*LegRoll``; the rest pose points every bone along
its parent's +Y), centimetres, Y up, ``Frame Time:
0.00208333`` (480 Hz, the motion capture rate). Checked on the released files of
person 12 (see ``docs/recognition.md``).

This reader reads the file with :func:`simenv.io.bvh.read` (every BVH option applies;
``metadata["format"]`` stays ``"bvh"``: the floor is the file's own, checked as for any
motion capture) and adds what the dataset's packaging says: ``dataset``, ``subject``,
``action_id``, ``label`` (:data:`MHAD_ACTIONS`), ``repetition``, or ``tpose`` for a
T-pose file. Only file names of the release's form with an action in 1-11 are taken
(:func:`sniff`); any other BVH goes to the BVH reader unchanged.

Not read here: the raw optical data (``Mocap/OpticalData/moc_s<SS>_a<AA>_r<RR>.txt``:
43 unlabelled-in-file markers x, y, z in mm, then a frame index and a Unix time stamp,
480 Hz; markers are not a skeleton) and the Kinect recordings (depth and colour images,
no skeleton stream).
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

from simenv.core.joint_map import JointMapSource
from simenv.core.motion import Motion
from simenv.io import bvh

#: Extensions this reader claims; with :data:`REFINES` it is asked before the BVH reader. A
#: ``.bvh`` no sniffer accepts reaches :func:`simenv.io.bvh.read` and its located error.
EXTENSIONS = (".bvh",)
#: The reader whose files this one reads with the dataset's knowledge added
#: (:func:`simenv.io.loader.detect` asks this one first).
REFINES = "bvh"
#: The 11 actions, id 1..11 in order (the dataset's description).
MHAD_ACTIONS: tuple[str, ...] = (
    "jumping in place", "jumping jacks", "bending (hands up all the way down)",
    "punching (boxing)", "waving (two hands)", "waving (one hand, right)",
    "clapping hands", "throwing a ball", "sit down then stand up", "sit down", "stand up",
)
#: Frame rate of the released skeletons and of the optical capture, frames/s.
MHAD_FPS = 480.0
#: Length unit of the released skeletons (default of :func:`read`).
MHAD_UNITS = "cm"

_NAME = re.compile(r"^skl_s(\d+)_(?:a(\d+)_r(\d+)|(t-pose))$", re.IGNORECASE)


def labels_from_name(path: Path) -> dict[str, object]:
    """``subject``, ``action_id``, ``label`` and ``repetition`` (or ``tpose``: True)
    parsed from a Berkeley MHAD skeleton file name; empty when the name is not of the form
    ``skl_s<SS>_a<AA>_r<RR>`` / ``skl_s<SS>_t-pose`` or the action is not 1-11."""
    m = _NAME.match(Path(path).stem)
    if not m:
        return {}
    subject, action, rep, tpose = m.groups()
    if tpose:
        return {"subject": int(subject), "tpose": True}
    if not 1 <= int(action) <= len(MHAD_ACTIONS):
        return {}
    return {"subject": int(subject), "action_id": int(action),
            "label": MHAD_ACTIONS[int(action) - 1], "repetition": int(rep)}


def sniff(path: Path, head: bytes) -> bool:
    """A BVH file (``HIERARCHY`` first) named like a Berkeley MHAD skeleton."""
    return (path.suffix.lower() == ".bvh" and bool(labels_from_name(path))
            and bvh.sniff(path, head))


def read(
    path: Path,
    *,
    units: str | None = None,
    scale: float | None = None,
    up: str | None = None,
    drop_tpose: bool = True,
    fps: float | None = None,
    end_sites: bool | None = None,
    name: str | None = None,
    restore_collapsed_bones: bool = False,
    joint_map: JointMapSource | None = None,
) -> Motion:
    """Read one Berkeley MHAD skeleton file.

    Args:
        path: a ``skl_s<SS>_a<AA>_r<RR>.bvh`` or ``skl_s<SS>_t-pose.bvh`` file.
        units: the file's length unit; default :data:`MHAD_UNITS` unless ``scale`` is
            given (the release's declared unit).
        scale, up, drop_tpose, fps, end_sites, name, restore_collapsed_bones, joint_map:
            as for :func:`simenv.io.bvh.read`.

    Returns:
        The BVH reader's :class:`Motion` (metres, Z up, 480 fps for the released files)
        with ``metadata`` ``dataset`` ("Berkeley MHAD"), ``reader`` ("berkeley_mhad") and
        the labels of :func:`labels_from_name`; a header rate other than
        :data:`MHAD_FPS` is noted in ``quirks``.

    Raises:
        FormatError: whatever the BVH reader raises for a malformed file (naming line
            and field).
    """
    path = Path(path)
    # Only a file named like the release's (a damaged .bvh reaches this reader too).
    release_units = units is None and scale is None and bool(labels_from_name(path))
    if release_units:
        # The release is in centimetres: said, not guessed. (Its rest pose folds every limb
        # up along +Y; the BVH reader measures such a file's unit on the motion, which gives
        # centimetres too.)
        units = MHAD_UNITS
    motion = bvh.read(path, units=units, scale=scale, up=up, drop_tpose=drop_tpose, fps=fps,
                      end_sites=end_sites, name=name,
                      restore_collapsed_bones=restore_collapsed_bones, joint_map=joint_map)
    meta = dict(motion.metadata)
    meta |= {"dataset": "Berkeley MHAD", "reader": "berkeley_mhad"} | labels_from_name(path)
    if release_units:
        meta["units_reason"] = f"{MHAD_UNITS}: the Berkeley MHAD release's unit"
    header_fps = meta.get("header_fps")
    if header_fps is not None and abs(float(header_fps) - MHAD_FPS) > 0.5:
        # The release writes every skeleton at the capture rate; another rate was edited.
        meta["quirks"] = [*meta.get("quirks", []),
                          f"header frame rate {float(header_fps):g} fps; the Berkeley MHAD "
                          f"release writes {MHAD_FPS:g} fps"]
    return replace(motion, metadata=meta)

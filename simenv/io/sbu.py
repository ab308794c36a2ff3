"""SBU Kinect Interaction skeletons (``skeleton_pos.txt``: two people per file).

Format (dataset README, v2.0): one row per frame,
``frame#, PA(1..15), PB(1..15)`` with ``P(i) = x, y, z`` — 91 comma-separated
values; person A is the one on the left of the image, B on the right. Joint
order: :data:`simenv.core.skeletons.SBU_JOINTS`. Coordinates are *normalised*:
x, y in [0, 1] and z in [0, 7.8125]. The README gives the inverse:

    original_X = 1280 - (normalized_X .* 2560);
    original_Y = 960 - (normalized_Y .* 1920);
    original_Z = normalized_Z .* 10000 ./ 7.8125;

which yields Kinect skeleton-space millimetres (x toward the sensor's left,
y up, z depth). We apply it exactly and divide by 1000. (Several public
loaders copy this formula with ``normalized_Y`` in the Z line by mistake; we
use Z.) Checks on the sample: median head-to-foot 1.46-1.56 m, shoulder width
0.30-0.32 m, thigh 0.39-0.46 m, depth ~2 m: plausible adults, so the formula's
units are right. Both people share one sensor, so one floor estimate from
both people's feet levels them together
(:func:`simenv.io.camera_frame.estimate_floor`).

Frame rate 15 fps (SBU capture rate). Frame numbers must increase by one; a
file whose numbering restarts or jumps (the sample ``skeleton_pos_2.txt``
holds two clips, 566-594 then 350-366) is split into contiguous clips and
``read`` returns a list of :class:`Interaction` (one per clip) in file order.
The interaction class is taken from the dataset's folder layout
(``sXXsYY/<class 01-08>/<seq>/skeleton_pos.txt``) when present.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from simenv.core.errors import FormatError
from simenv.core.motion import Interaction, Motion
from simenv.core.skeletons import sbu_skeleton
from simenv.io._kinect_text import check_counts, sniff_rows, table_lines, to_floats
from simenv.io.camera_frame import estimate_floor

SBU_FPS = 15.0
VALUES_PER_ROW = 1 + 2 * 15 * 3
#: Interaction classes by folder number 01..08 (dataset README / paper).
SBU_CLASSES: tuple[str, ...] = (
    "approaching", "departing", "kicking", "punching", "pushing", "hugging",
    "shaking hands", "exchanging",
)


def sniff(path: Path, head: bytes) -> bool:
    """A ``.txt`` of comma-separated rows of 91 numbers (frame + 2 x 15 x 3)."""
    return sniff_rows(path, head, suffix=".txt", lines=3, sep=",", counts=(VALUES_PER_ROW,))


def denormalise(norm: np.ndarray) -> np.ndarray:
    """(..., 3) SBU normalised coordinates -> Kinect camera-frame metres
    (README formula, millimetres / 1000)."""
    norm = np.asarray(norm, dtype=np.float64)
    out = np.empty_like(norm)
    out[..., 0] = 1280.0 - norm[..., 0] * 2560.0
    out[..., 1] = 960.0 - norm[..., 1] * 1920.0
    out[..., 2] = norm[..., 2] * 10000.0 / 7.8125
    return out / 1000.0


def _label(path: Path) -> str | None:
    folder = path.parent.parent.name if path.parent.parent != path.parent else ""
    if folder.isdigit() and 1 <= int(folder) <= len(SBU_CLASSES):
        return SBU_CLASSES[int(folder) - 1]
    return None


def read(path: Path, *, fps: float = SBU_FPS) -> Interaction | list[Interaction]:
    """Read an SBU ``skeleton_pos.txt``.

    Returns:
        An :class:`Interaction` (actor = person A, on the left; roles not
        known), or a list of them when the frame numbering is not contiguous.
    """
    path = Path(path)
    rows = table_lines(path, ",")
    check_counts(path, rows, (VALUES_PER_ROW,), "frame number + 2 people x 15 joints x 3")
    data = to_floats(path, rows)
    frames = data[:, 0]
    bad = np.flatnonzero(frames != np.round(frames))
    if bad.size:
        raise FormatError(f"frame number must be an integer, found {frames[bad[0]]!r}",
                          source=path, line=rows[bad[0]][0], field="frame#")
    cam = denormalise(data[:, 1:].reshape(-1, 2, 15, 3))
    skeleton = sbu_skeleton()
    est = estimate_floor([(cam[:, 0], skeleton), (cam[:, 1], skeleton)], source=str(path))
    world = est.apply(cam)
    breaks = np.flatnonzero(np.diff(frames) != 1) + 1
    label = _label(path)
    out: list[Interaction] = []
    for k, (a, b) in enumerate(zip(np.r_[0, breaks], np.r_[breaks, len(frames)], strict=True)):
        name = path.stem if not breaks.size else f"{path.stem}_clip{k + 1}"
        meta = {
            "source": str(path),
            "format": "sbu",
            "units": "normalised (README formula -> m, camera frame)",
            "dataset": "SBU Kinect Interaction",
            "frame_numbers": [int(frames[a]), int(frames[b - 1])],
            "file_lines": [rows[a][0], rows[b - 1][0]],
            "camera_frame": est.as_metadata(),
            "repairs": [],
            "quirks": ([f"frame numbering not contiguous: split into {len(breaks) + 1} clips"]
                       if breaks.size else []),
        }
        people = [
            Motion(world[a:b, p], fps, skeleton, f"{name}_{who}", dict(meta, person=who))
            for p, who in enumerate(("A_left", "B_right"))
        ]
        out.append(Interaction(people[0], people[1], label=label, roles_known=False,
                               name=name, metadata=meta))
    return out[0] if len(out) == 1 else out

"""NuiSI (Nuitrack Skeleton Interaction) recordings: one CSV file per person
(``Rocket_p1.txt`` / ``Rocket_p2.txt``), synchronised line by line.

Format (``other/SOURCES.md``; the dataset's ``read_nuisi.py``): per line
``index, unix_ms, n_joints`` then, when ``n_joints == 25``, 25 groups of
``joint_id, confidence, proj_x, proj_y, proj_z, x, y, z`` (203 values); lines
with ``n_joints == 0`` (3 values) are tracking dropouts. Joint ids are
Nuitrack's (0 = none, 1 head ... 24 right foot;
:func:`simenv.core.skeletons.nuitrack_skeleton`); ``x, y, z`` are real-world
millimetres in Nuitrack's sensor frame, which is **left-handed** (x to the
sensor's right, y up, z away): a subject facing the sensor has its left
shoulder at larger x, and the dataset's own preprocessing maps
``(x, y, z) -> (z, -x, y)``. We negate x (-> the right-handed Kinect
convention of :mod:`simenv.io.camera_frame`) and divide by 1000.

Quirks handled:

* **Dropouts** (``n_joints = 0``): leading and trailing ones are trimmed (the
  clip spans the first to the last tracked line); inner ones are filled by
  linear interpolation in time, listed in ``metadata["repairs"]``.
* **Never-tracked joints.** Fingertips (10, 16) and feet (20, 24) report
  confidence 0 and all-zero coordinates on every line; a joint that is zero
  on every tracked line carries no data, so it is dropped from the skeleton
  (``Skeleton.subset``; the canonical toes go with it) and noted in
  ``quirks``. Joints with confidence 0 but real coordinates (e.g. an ankle
  Nuitrack could not see) are kept as reported; their confidence-0 fraction
  is in ``metadata["zero_confidence_fraction"]``.
* **Timing.** Lines are ~29.4 Hz on average (median 34 ms) but unevenly
  spaced (16 ms to >1 s). ``timing="resample"`` (default) interpolates onto a
  uniform ``fps`` = 30 grid over the unix-ms timestamps; ``"rows"`` keeps one
  frame per tracked line at 1000 / median interval fps.

**Two people.** Each person was recorded in the frame of the sensor facing
them (both stand ~1.1 m from "their" sensor), so the two files do *not* share
a world frame. :func:`read_pair` levels each person on their own floor, turns
person 1 to face +X at the origin and person 2 to face -X, and places
person 2 from the interaction's physical contact: with ``contact=(joint_a,
joint_b)`` (default both right hands, the fist bump of "Rocket"), the
separation along X is the value at which those two joints touch at their
closest approach (98th percentile of the X gap, so hands never pass through
each other) and the lateral offset is their median Y difference over those
contact frames. The residual height mismatch at contact is reported in
``metadata["placement"]`` as a check. ``separation=`` places them at a given
pelvis distance instead.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Literal

import numpy as np

from simenv.core.errors import FormatError, MotionError
from simenv.core.motion import Interaction, Motion
from simenv.core.skeletons import Skeleton, nuitrack_skeleton
from simenv.io._kinect_text import check_counts, sniff_rows, table_lines, to_floats
from simenv.io.camera_frame import estimate_floor

NUISI_FPS = 30.0
N_JOINTS = 25
#: Contact points are taken where the gap is within this of its closest value, metres.
CONTACT_TOLERANCE_M = 0.03

_PAIR = re.compile(r"^(?P<stem>.*)_p(?P<who>[12])$", re.IGNORECASE)


def sniff(path: Path, head: bytes) -> bool:
    """A ``.txt`` of comma-separated lines with 3 or 203 numbers and a third
    value (joint count) of 0 or 25."""
    return sniff_rows(path, head, suffix=".txt", lines=20, sep=",",
                      counts=(3, 3 + 8 * N_JOINTS),
                      accept=lambda t: t[2].strip() in ("0", str(N_JOINTS)))


def _parse(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(times_s (N,), xyz_cam (N, 24, 3) metres right-handed, conf (N, 24),
    tracked (N,) bool) for every line."""
    rows = table_lines(path, ",")
    check_counts(path, rows, (3, 3 + 8 * N_JOINTS), "index, unix_ms, n_joints [, 25 x 8]")
    head = to_floats(path, [(ln, t[:3]) for ln, t in rows], ["index", "unix_ms", "n_joints"])
    for r, (ln, tokens) in enumerate(rows):
        expected = 3 if head[r, 2] == 0 else 3 + 8 * N_JOINTS if head[r, 2] == N_JOINTS else None
        if expected is None or len(tokens) != expected:
            raise FormatError(
                f"n_joints is {head[r, 2]:g} with {len(tokens)} values; expected 0 with 3 values "
                f"or {N_JOINTS} with {3 + 8 * N_JOINTS}",
                source=path, line=ln, frame=r, field="n_joints",
            )
    times = head[:, 1] / 1000.0
    dt = np.diff(times)
    if (dt < 0).any():
        k = int(np.flatnonzero(dt < 0)[0]) + 1
        raise FormatError("timestamp decreases; expected non-decreasing unix_ms",
                          source=path, line=rows[k][0], frame=k, field="unix_ms")
    tracked = head[:, 2] == N_JOINTS
    xyz = np.zeros((len(rows), N_JOINTS - 1, 3))
    conf = np.zeros((len(rows), N_JOINTS - 1))
    full = [r for r, ok in zip(rows, tracked, strict=True) if ok]
    if full:
        body = to_floats(path, [(ln, t[3:]) for ln, t in full]).reshape(-1, N_JOINTS, 8)
        ids = body[:, :, 0]
        bad = np.argwhere(ids != np.arange(N_JOINTS))
        if bad.size:
            r, j = bad[0]
            raise FormatError(
                f"joint id {ids[r, j]:g} in slot {j}; expected ids 0..24 in order",
                source=path, line=full[r][0], field=f"joint {j}",
            )
        xyz[tracked] = body[:, 1:, 5:8] * np.array([-0.001, 0.001, 0.001])
        conf[tracked] = body[:, 1:, 1]
    return times, xyz, conf, tracked


def _grid(times: np.ndarray, xyz: np.ndarray, valid: np.ndarray, t0: float, t1: float,
          fps: float) -> tuple[np.ndarray, list[str]]:
    """Linear interpolation of valid samples onto ``t0 + k / fps`` up to ``t1``."""
    n = int(np.floor((t1 - t0) * fps + 1e-9)) + 1
    t_new = t0 + np.arange(n) / fps
    tv = times[valid]
    flat = xyz[valid].reshape(len(tv), -1)
    out = np.stack([np.interp(t_new, tv, flat[:, c]) for c in range(flat.shape[1])], axis=1)
    notes = []
    gaps = np.flatnonzero(np.diff(tv) > 2.5 / fps)
    for k in gaps:
        notes.append(f"interpolated {tv[k + 1] - tv[k]:.3f} s without a tracked skeleton "
                     f"(t = {tv[k] - t0:.3f}-{tv[k + 1] - t0:.3f} s)")
    return out.reshape(n, *xyz.shape[1:]), notes


class _Person:
    """One parsed NuiSI file."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.times, self.xyz, self.conf, self.tracked = _parse(self.path)
        if not self.tracked.any():
            raise MotionError("no line holds a skeleton (all n_joints = 0)", source=self.path)
        full = nuitrack_skeleton()
        zero = (self.xyz[self.tracked] == 0).all(axis=(0, 2))
        keep = [n for n, z in zip(full.joint_names, zero, strict=True) if not z]
        self.dropped = [n for n, z in zip(full.joint_names, zero, strict=True) if z]
        self.skeleton: Skeleton = full.subset(keep, name="nuitrack") if self.dropped else full
        idx = [full.index(n) for n in self.skeleton.joint_names]
        self.xyz, self.conf = self.xyz[:, idx], self.conf[:, idx]
        span = np.flatnonzero(self.tracked)
        self.first, self.last = int(span[0]), int(span[-1])

    def motion(self, t0: float, t1: float, fps: float, timing: str) -> Motion:
        repairs: list[str] = []
        lead, trail = self.first, len(self.tracked) - 1 - self.last
        if lead or trail:
            repairs.append(f"trimmed {lead} leading and {trail} trailing dropout lines")
        valid = self.tracked
        if timing == "resample":
            xyz, notes = _grid(self.times, self.xyz, valid, t0, t1, fps)
            repairs += notes
            out_fps = fps
        elif timing == "rows":
            sel = valid & (self.times >= t0) & (self.times <= t1)
            xyz = self.xyz[sel]
            out_fps = 1.0 / float(np.median(np.diff(self.times[valid])))
        else:
            raise ValueError(f"timing must be 'resample' or 'rows', got {timing!r}")
        inner = int((~valid[self.first:self.last + 1]).sum())
        if inner:
            repairs.append(f"{inner} inner dropout lines (n_joints = 0) bridged by interpolation")
        quirks = []
        if self.dropped:
            quirks.append("dropped never-tracked joints (zero on every line): "
                          + ", ".join(self.dropped))
        m = _PAIR.match(self.path.stem)
        meta = {
            "source": str(self.path),
            "format": "nuisi",
            "units": "mm (Nuitrack left-handed sensor frame) -> m",
            "dataset": "NuiSI",
            "label": (m.group("stem") if m else self.path.stem),
            "repairs": repairs,
            "quirks": quirks,
            "zero_confidence_fraction": dict(zip(
                self.skeleton.joint_names,
                np.round((self.conf[valid] == 0).mean(axis=0), 3).tolist(), strict=True)),
            "time_span_s": [round(t0 - self.times[0], 3), round(t1 - self.times[0], 3)],
        }
        return Motion(xyz, out_fps, self.skeleton, self.path.stem, meta)


def _level(motion: Motion, source: str) -> Motion:
    est = estimate_floor([(motion.positions, motion.skeleton)], source=source)
    meta = dict(motion.metadata, camera_frame=est.as_metadata())
    return motion.with_positions(est.apply(motion.positions), metadata=meta)


def read(
    path: Path, *, fps: float = NUISI_FPS, timing: Literal["resample", "rows"] = "resample"
) -> Motion:
    """Read one person's NuiSI file as a world-frame :class:`Motion` in the
    frame of that person's sensor (floor at z = 0)."""
    p = _Person(Path(path))
    m = p.motion(p.times[p.first], p.times[p.last], fps, timing)
    return _level(m, str(path))


def _yaw(m: Motion) -> float:
    """Median facing direction (yaw, rad) from shoulders x up."""
    sk = m.skeleton
    left = m.positions[:, sk.index(sk.canonical["left_shoulder"])]
    right = m.positions[:, sk.index(sk.canonical["right_shoulder"])]
    fwd = np.cross(left - right, [0.0, 0.0, 1.0])
    f = np.median(fwd, axis=0)
    return float(np.arctan2(f[1], f[0]))


def _turn(p: np.ndarray, yaw: float, pivot: np.ndarray) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return (p - pivot) @ rot.T


def read_pair(
    path_a: Path,
    path_b: Path,
    *,
    contact: tuple[str, str] | None = ("JOINT_RIGHT_HAND", "JOINT_RIGHT_HAND"),
    separation: float | None = None,
    fps: float = NUISI_FPS,
) -> Interaction:
    """Both people of a NuiSI recording as one :class:`Interaction` on a
    common uniform time grid (the overlap of both tracked spans).

    Args:
        path_a, path_b: the ``_p1`` and ``_p2`` files.
        contact: joint of person A and of person B that touch during the
            interaction, used to place B (see module docstring).
        separation: if given (metres, pelvis to pelvis along X), place B there
            instead of using ``contact``.
        fps: output frame rate.
    """
    a, b = _Person(Path(path_a)), _Person(Path(path_b))
    t0 = max(a.times[a.first], b.times[b.first])
    t1 = min(a.times[a.last], b.times[b.last])
    if t1 <= t0:
        raise MotionError(f"{path_a} and {path_b} have no tracked time span in common",
                          source=path_b)
    ma = _level(a.motion(t0, t1, fps, "resample"), str(path_a))
    mb = _level(b.motion(t0, t1, fps, "resample"), str(path_b))
    pelvis_a = np.median(ma.joint(ma.skeleton.canonical["pelvis"]), axis=0) * [1, 1, 0]
    pelvis_b = np.median(mb.joint(mb.skeleton.canonical["pelvis"]), axis=0) * [1, 1, 0]
    pa = _turn(ma.positions, -_yaw(ma), pelvis_a)  # A at the origin facing +X
    pb = _turn(mb.positions, np.pi - _yaw(mb), pelvis_b)  # B facing -X
    placement: dict[str, object]
    if separation is not None:
        shift = np.array([float(separation), 0.0, 0.0])
        placement = {"method": "given separation", "separation_m": float(separation)}
    elif contact is not None:
        ja, jb = (ma.skeleton.index(contact[0]), mb.skeleton.index(contact[1]))
        gap_x = pa[:, ja, 0] - pb[:, jb, 0]
        sx = float(np.percentile(gap_x, 98))
        touching = gap_x >= sx - CONTACT_TOLERANCE_M
        sy = float(np.median(pa[touching, ja, 1] - pb[touching, jb, 1]))
        dz = float(np.median(pa[touching, ja, 2] - pb[touching, jb, 2]))
        shift = np.array([sx, sy, 0.0])
        placement = {
            "method": f"contact {contact[0]} (A) = {contact[1]} (B) at closest approach",
            "separation_m": round(float(np.hypot(sx, sy)), 4),
            "offset_xy_m": [round(sx, 4), round(sy, 4)],
            "contact_frames": int(touching.sum()),
            "contact_height_mismatch_m": round(dz, 4),
        }
    else:
        raise ValueError("give contact= joints or separation=")
    pb = pb + shift
    meta_a = dict(ma.metadata, placement=placement)
    meta_b = dict(mb.metadata, placement=placement)
    m = _PAIR.match(Path(path_a).stem)
    label = m.group("stem") if m else None
    return Interaction(
        ma.with_positions(pa, metadata=meta_a), mb.with_positions(pb, metadata=meta_b),
        label=label, roles_known=False, name=label or Path(path_a).stem,
        metadata={"source": [str(path_a), str(path_b)], "format": "nuisi",
                  "placement": placement,
                  "quirks": ["the two people were recorded by separate sensors; the common "
                             "frame is reconstructed from their contact (see placement)"]},
    )


def partner_path(path: Path) -> Path | None:
    """The other person's file (``_p1`` <-> ``_p2``) if it exists."""
    m = _PAIR.match(Path(path).stem)
    if not m:
        return None
    other = "2" if m.group("who") == "1" else "1"
    cand = Path(path).with_name(f"{m.group('stem')}_p{other}{Path(path).suffix}")
    return cand if cand.is_file() else None

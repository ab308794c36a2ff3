"""How well a depth camera's levelling finds the vertical of a person gesturing in place.

:func:`simenv.io.camera_frame.estimate_floor` fits the floor to the feet with a prior on its
slope. A person who stays in place gives the fit one or two floor cells, so the prior's
centre is the answer: the *body axis* (median shank and trunk direction) before, the
*centre of mass over the feet* (:func:`simenv.io.camera_frame.standing_up`) now. This script
measures both where the true vertical is known, never on depth-camera evaluation data:

* **CMU optical motion capture** (``/work/shared/data/cmu``, Z up; the salsa pairs left out:
  a template skeleton at 0.7x real size): every 4-s window (stride 2 s, at 30 fps) in which
  the ankles' midpoint stays within :data:`~simenv.io.camera_frame.IN_PLACE_SPREAD_M`,
  turned into an OpenNI / NiTE-like 15-joint skeleton (no toes; each joint at its canonical
  keypoint), with or without 2 cm of per-joint, per-frame Gaussian noise, and seen by
  sensors with known pose (:data:`POSES`).
* **UTKinect-Action3D** (real Kinect v1): sessions whose walk gives a good plane fit
  (:data:`GOOD_RMS_M`, feet spread over > 1 m) are the truth as the reader levelled them; each
  labelled action but the walk is cut out and put back in the same sensor poses.

``calibrate`` first: on the level CMU windows, the forward offset of the centre of mass from
the ankles' midpoint (with all standing frames and with only the quiet half, low
centre-of-mass acceleration); the constant
:data:`~simenv.io.camera_frame.SUPPORT_FORWARD_M` is the median over windows, and the
tilt errors reported for CMU use, for each clip, the median over the *other* clips
(leave one clip out).

Usage::

    nice -n 10 .venv/bin/python benchmarks/levelling_check.py

Rows go to ``out/levelling_check/{calibration,tilt}.jsonl``; a summary (median and 95th
percentile tilt error, old prior vs new) is printed.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

import simenv  # noqa: F401  (MUJOCO_GL before mujoco)
from simenv.core.motion import Motion
from simenv.core.skeletons import Skeleton, florence_skeleton, kinect_v1_skeleton
from simenv.io import camera_frame as cf
from simenv.io import utkinect
from simenv.io.loader import load

REPO = Path(__file__).resolve().parents[1]
DATA = Path("/work/shared/data")
OUT = REPO / "out" / "levelling_check"
FPS = 30.0
WINDOW_S, STRIDE_S = 4.0, 1.0
NOISE_M = 0.02
#: Sensor poses (pitch down, roll, height): degrees, degrees, metres.
POSES: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 1.0), (12.0, 3.0, 1.1),
                                                 (25.0, -5.0, 0.9), (18.0, 5.0, 1.4))
#: UTKinect sessions whose plane fit is this good (RMS, metres) are the truth.
GOOD_RMS_M = 0.05
OPENNI = florence_skeleton()


def cmu_clips() -> Iterator[tuple[str, Motion]]:
    """Every single-person CMU clip of the shared corpus at 30 fps (canonical keypoints,
    Z up, metres; the cgspeed T-pose frame dropped); salsa templates left out."""
    paths = sorted((DATA / "cmu" / "bvh").glob("*.bvh")) + sorted(
        (DATA / "cmu" / "asf_amc").glob("*.amc")) + sorted(
        (DATA / "cmu" / "two_person" / "18_19_walk_shake_hands").glob("*.bvh"))
    for path in paths:
        m = load(path)
        c = m.to_canonical()
        step = max(1, int(round(m.fps / FPS)))
        yield path.stem, Motion(c.positions[1::step], m.fps / step, c.skeleton, path.stem, {})


def as_openni(m: Motion) -> np.ndarray:
    """(T, 15, 3) positions of the OpenNI-like skeleton :data:`OPENNI`, each joint at its
    canonical keypoint of ``m``."""
    inverse = {v: k for k, v in OPENNI.canonical.items()}
    return np.stack([m.joint(inverse[n]) for n in OPENNI.joint_names], axis=1).astype(
        np.float64)


def in_place_windows(p: np.ndarray, fps: float) -> Iterator[tuple[int, np.ndarray]]:
    """(start frame, window) of ``p`` (T, J, 3) whose ankles' midpoint stays in place."""
    n, s = int(WINDOW_S * fps), int(STRIDE_S * fps)
    ankles = cf.keypoint_indices(OPENNI, ["left_ankle", "right_ankle"])
    for start in range(0, len(p) - n + 1, s):
        w = p[start:start + n]
        if max(cf.principal_spread(w[:, ankles, :2].mean(axis=1))) <= cf.IN_PLACE_SPREAD_M:
            yield start, w


def forward_offsets(w: np.ndarray, sk: Skeleton, fps: float) -> dict[str, float] | None:
    """Mean forward offset (m) of the centre of mass from the foot keypoints' midpoint over
    standing frames, all and the quiet half; None when the window is not standing."""
    com = cf.centre_of_mass(w, sk)
    if com is None or cf.standing_up(w, sk) is None:
        return None
    feet = cf.keypoint_indices(sk, ["left_ankle", "right_ankle"])
    support = w[:, feet].mean(axis=1)
    left = w[:, sk.index(sk.canonical["left_hip"])] - w[:, sk.index(sk.canonical["right_hip"])]
    fwd = np.cross(left, [0.0, 0.0, 1.0])
    fwd[:, 2] = 0
    fwd /= np.linalg.norm(fwd, axis=1, keepdims=True)
    off = np.einsum("ij,ij->i", com - support, fwd)
    k = max(1, int(round(0.1 * fps)))  # 0.2-s moving average before differencing
    smooth = np.array([com[max(0, i - k):i + k + 1].mean(axis=0) for i in range(len(com))])
    acc = np.linalg.norm(np.gradient(np.gradient(smooth[:, :2], axis=0), axis=0), axis=1) * fps**2
    quiet = acc <= np.median(acc)
    return {"all": float(off.mean()), "quiet": float(off[quiet].mean()),
            "height_m": float(np.mean(com[:, 2] - support[:, 2]))}


def to_camera(world: np.ndarray, pitch: float, roll: float, height: float
              ) -> tuple[np.ndarray, np.ndarray]:
    """World (Z up) -> a sensor's camera frame with that pose; returns (positions, true up
    in camera coordinates)."""
    tilt = Rotation.from_euler("xz", [-pitch, roll], degrees=True).as_matrix()
    cam = ((world - [0, 0, height]) @ cf.KINECT_TO_ZUP) @ tilt.T
    return cam, tilt @ np.array([0.0, 1.0, 0.0])


def tilt_errors(cam: np.ndarray, sk: Skeleton, up: np.ndarray) -> dict[str, Any]:
    """Angle (deg) between the true up and the estimated one, old prior vs new."""
    out: dict[str, Any] = {}
    saved = cf.IN_PLACE_SPREAD_M
    for label in ("old", "new"):
        cf.IN_PLACE_SPREAD_M = -1.0 if label == "old" else saved  # old: nobody is in place
        try:
            est = cf.estimate_floor([(cam, sk)])
        finally:
            cf.IN_PLACE_SPREAD_M = saved
        out[label] = float(np.degrees(np.arccos(np.clip(est.up_camera @ up, -1, 1))))
        out[f"{label}_prior"] = est.prior
    return out


def utk_segments() -> Iterator[tuple[str, str, np.ndarray, float]]:
    """(session, label, world positions of the segment, fps) of the well-levelled UTKinect
    sessions, every action but the walk."""
    for path in sorted((DATA / "gestures" / "utkinect" / "joints").glob("joints_*.txt")):
        m = utkinect.read(path)
        meta = m.metadata["camera_frame"]
        if meta["floor_rms_m"] > GOOD_RMS_M or min(meta["feet_spread_m"]) < 0.5 or max(
                meta["feet_spread_m"]) < 1.0:
            continue
        for seg in m.metadata["segments"]:
            if seg["label"] != "walk" and seg["end"] - seg["start"] >= 10:
                yield path.stem, seg["label"], m.positions[seg["start"]:seg["end"] + 1].astype(
                    np.float64), m.fps


def summary(errors: list[float]) -> str:
    """'median / p95 (n)' of degrees."""
    if not errors:
        return "-"
    return f"{np.median(errors):.2f} / {np.percentile(errors, 95):.2f} deg (n={len(errors)})"


def main() -> None:
    """Calibrate the forward offset on CMU, then measure the tilt errors, old vs new."""
    OUT.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    windows: list[dict[str, Any]] = []
    for clip, m in cmu_clips():
        for start, w in in_place_windows(as_openni(m), m.fps):
            windows.append({"clip": clip, "start": start, "w": w,
                            "offset": forward_offsets(w, OPENNI, m.fps)})
    with (OUT / "calibration.jsonl").open("w") as fh:
        for r in windows:
            fh.write(json.dumps({k: v for k, v in r.items() if k != "w"}) + "\n")
    rows = [r for r in windows if r["offset"]]
    for sel in ("all", "quiet"):
        v = np.array([r["offset"][sel] for r in rows])
        print(f"CMU: {len(rows)} standing windows of {len({r['clip'] for r in rows})} clips "
              f"({len(windows)} in place); forward offset ({sel} standing frames) median "
              f"{np.median(v) * 1000:.0f} mm, sd {v.std() * 1000:.0f} mm")
    for clip in sorted({r["clip"] for r in rows}):
        v = [r["offset"]["all"] for r in rows if r["clip"] == clip]
        print(f"  {clip}: {len(v)} windows, median {np.median(v) * 1000:.0f} mm")
    constant = float(np.median([r["offset"]["all"] for r in rows]))
    print(f"SUPPORT_FORWARD_M measured: {constant:.4f} m (in the code: {cf.SUPPORT_FORWARD_M})")

    tilt_rows: list[dict[str, Any]] = []
    saved = cf.SUPPORT_FORWARD_M
    try:
        for r in windows:
            if not r["offset"]:
                continue
            # Leave one clip out: the offset from the other clips' windows.
            cf.SUPPORT_FORWARD_M = float(np.median(
                [o["offset"]["all"] for o in rows if o["clip"] != r["clip"]]))
            for noisy in (False, True):
                w = r["w"] + (rng.normal(0, NOISE_M, r["w"].shape) if noisy else 0.0)
                for pitch, roll, height in POSES:
                    cam, up = to_camera(w, pitch, roll, height)
                    tilt_rows.append({"set": "cmu", "clip": r["clip"], "start": r["start"],
                                      "noise": noisy, "pose": [pitch, roll],
                                      **tilt_errors(cam, OPENNI, up)})
    finally:
        cf.SUPPORT_FORWARD_M = saved
    for session, label, w, _fps in utk_segments():
        for pitch, roll, height in POSES:
            cam, up = to_camera(w, pitch, roll, height)
            tilt_rows.append({"set": "utkinect", "clip": session, "label": label,
                              "noise": "real", "pose": [pitch, roll],
                              **tilt_errors(cam, kinect_v1_skeleton(), up)})
    with (OUT / "tilt.jsonl").open("w") as fh:
        for t in tilt_rows:
            fh.write(json.dumps(t) + "\n")
    for key in sorted({(t["set"], str(t["noise"])) for t in tilt_rows}):
        sel = [t for t in tilt_rows if (t["set"], str(t["noise"])) == key]
        moved = [t for t in sel if t["new_prior"] != "body axis"]
        print(f"{key[0]:9s} noise={key[1]:5s}: old {summary([t['old'] for t in sel])} | new "
              f"{summary([t['new'] for t in sel])} | centre of mass used on {len(moved)}; "
              f"on those old {summary([t['old'] for t in moved])}, new "
              f"{summary([t['new'] for t in moved])}")


if __name__ == "__main__":
    main()

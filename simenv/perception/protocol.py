"""The room's perception loop measured on people it never saw, as the room runs it.

What the loop sees (:func:`avatar_clips`): each recording is retargeted onto the user's
fitted body and placed in the room (:func:`simenv.room.session.user_track`, the
rehearsal's path), and the avatar's keypoints are read on the gesture joints -- not the
raw Kinect joints, which the agent never sees. Florence 3D has no pelvis joint: the hips'
midpoint is its pelvis (:func:`simenv.body.retarget.with_derived_pelvis`). A clip that cannot
be retargeted is left out and listed with the reason. Retargeting the corpus's 877 MSR
Action3D and UTKinect clips takes about 22 s of CPU, Florence 3D's 215 about 3.5 s, so each
clip's avatar keypoints are kept on disk (:func:`avatar_cache_dir`:
``$SIMENV_CACHE/avatar_clips``, default ``~/.cache/simenv/avatar_clips``; ``SIMENV_CACHE=off``
keeps nothing), one file per clip named by a hash of everything that makes them: the clip's
source motion (positions, frame rate, skeleton and metadata other than its file path, as the
reader made them from the file's bytes), the scenario file's bytes and the code
(:data:`AVATAR_CODE`'s Python sources, the MuJoCo and NumPy versions), so a change to any of
them is a new file. Files are written under a temporary name and renamed into place, so two
processes filling the cache at once never read a partial file.

Streaming (:func:`stream_readings`): a clip plays from its first frame (before it, the
person holds the first pose); the loop ticks every :data:`TICK_FRAMES` frames with a
seeded random phase relative to the gesture's onset (a real user does not start in step
with the loop). At each tick it computes both of its stages
(:class:`simenv.perception.loop.PerceptionLoop`): the classifier on the last seconds of real
motion -- the thesis's 1 s, and optionally longer windows ending at the tick
(``real_windows``) --, and on the last second continued by the forecaster's 2 s. Ticks
continue until the tick whose second holds the clip's last frame.

Decisions (:func:`loop_outcomes`), the loop's rule (:func:`simenv.perception.loop.decide`,
the one the room's agent decides by): a tick decides when the top class of the real stage
reaches the threshold, else when that of the real + predicted stage does; the real stage's
probabilities are its windows' combined by the window rule
(:func:`simenv.perception.loop.real_stage`: the most confident window, ``max``, or the
windows' mean, ``mean``);
a clip is *greeted* when any of its ticks decides ``wave``. Reported: waves greeted,
other labelled clips greeted, idle clips greeted, the decision's time after the gesture's
onset (median, p90) and the share of greeted waves decided before the gesture ended.

The threshold (:func:`choose_threshold`) is the lowest grid value whose greetings on
non-wave clips stay at or below :data:`FALSE_GREET_TARGET` on *calibration* readings: for
a held-out fold, the readings of the other folds (cross-fitting), never its own.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import tempfile
import zipfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from simenv.core.errors import SimenvError
from simenv.core.skeletons import CANONICAL_KEYPOINTS
from simenv.data.gestures import GESTURE15_JOINTS, GestureClip, normalise_windows
from simenv.learning.recognition import SHORT_FRAMES, Forecaster, logits_of
from simenv.perception.loop import Stage, decide, real_stage

#: Frames between perception ticks (1 s at 25 fps, the thesis's rate).
TICK_FRAMES = 25
#: Largest share of non-wave clips a chosen threshold may greet on calibration readings.
FALSE_GREET_TARGET = 0.02
#: Thresholds tried by :func:`choose_threshold`.
THRESHOLD_GRID: tuple[float, ...] = tuple(np.round(np.arange(0.30, 0.96, 0.025), 3))
GREET_LABEL = "wave"


#: Environment variable naming the cache's root folder (``off``: no cache).
CACHE_ENV = "SIMENV_CACHE"
#: The simenv sources that turn a source motion into avatar keypoints (package folders and
#: modules, relative to the ``simenv`` package): their bytes are part of each cache key.
AVATAR_CODE: tuple[str, ...] = ("core", "body", "room", "data/gestures.py",
                                "perception/protocol.py")


def avatar_cache_dir() -> Path | None:
    """Folder of the avatar keypoints cache (module docstring), None when ``SIMENV_CACHE``
    is ``off``."""
    root = os.environ.get(CACHE_ENV)
    if root == "off":
        return None
    if not root:
        root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "simenv"
    return Path(root) / "avatar_clips"


@functools.lru_cache(maxsize=1)
def _code_key() -> str:
    """Hash of :data:`AVATAR_CODE`'s Python files and the MuJoCo and NumPy versions."""
    import mujoco

    package = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256(f"mujoco {mujoco.__version__} numpy {np.__version__}".encode())
    for entry in AVATAR_CODE:
        path = package / entry
        for file in sorted(path.rglob("*.py")) if path.is_dir() else [path]:
            digest.update(str(file.relative_to(package)).encode())
            digest.update(file.read_bytes())
    return digest.hexdigest()


def _json_default(value: Any) -> Any:
    """Arrays and other values of a motion's metadata as JSON."""
    return value.tolist() if isinstance(value, np.ndarray) else str(value)


def _avatar_key(clip: GestureClip, scenario_bytes: bytes) -> str:
    """The cache key of ``clip``'s avatar keypoints (module docstring)."""
    m = clip.source
    digest = hashlib.sha256(_code_key().encode())
    digest.update(scenario_bytes)
    for array in (m.positions, m.rotations):
        if array is not None:
            digest.update(f"{array.dtype} {array.shape}".encode())
            digest.update(np.ascontiguousarray(array).tobytes())
    s = m.skeleton
    digest.update(json.dumps(
        [m.fps, s.name, s.joint_names, s.parents, sorted(s.canonical.items()),
         {k: v for k, v in m.metadata.items() if k != "source"}],
        sort_keys=True, default=_json_default).encode())
    return digest.hexdigest()


def _read_entry(path: Path) -> np.ndarray | str | None:
    """A cached clip: its keypoints (T, 15, 3), the reason it was skipped, or None when
    there is no readable entry (a damaged one is made again)."""
    try:
        with np.load(path) as entry:
            return str(entry["skipped"]) if "skipped" in entry else entry["keypoints"]
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None


def _write_entry(path: Path, **arrays: Any) -> None:
    """Write an entry under a temporary name in its folder, then rename it into place
    (atomic: a reader sees the whole file or none)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=".npz")
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, **arrays)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def avatar_clips(clips: Sequence[GestureClip], scenario: str = "default", *,
                 progress: bool = True) -> tuple[list[GestureClip], list[str]]:
    """The clips as the room's agent sees them (module docstring): the same labels and
    names, positions (T, 15, 3) of the avatar's keypoints on ``gesture15``, metres, Z up,
    25 fps; read from the cache when it holds them (:func:`avatar_cache_dir`). Returns
    (clips, skipped clips with the reason)."""
    # The session retargets onto the room's user: MuJoCo and the solver, needed here only.
    from simenv.room.scenario import scenario_path
    from simenv.room.session import Session, user_track

    cols = [CANONICAL_KEYPOINTS.index(j) for j in GESTURE15_JOINTS]
    cache = avatar_cache_dir()
    scenario_bytes = scenario_path(scenario).read_bytes()
    out, skipped = [], []
    for clip in tqdm(clips, desc="retarget onto the avatar", disable=not progress):
        if clip.source is None:
            skipped.append(f"{clip.name}: no source motion")
            continue
        path = cache / f"{_avatar_key(clip, scenario_bytes)}.npz" if cache else None
        kp = _read_entry(path) if path else None
        if kp is None:
            try:
                kp = user_track(Session(clip.source), scenario).keypoints[:, cols].astype(
                    np.float32)
            except SimenvError as exc:
                kp = f"{clip.name}: {exc.detail}"
            if path:
                _write_entry(path, **({"skipped": kp} if isinstance(kp, str)
                                      else {"keypoints": kp}))
        if isinstance(kp, str):
            skipped.append(kp)
            continue
        out.append(GestureClip(kp, clip.label, clip.source_label, clip.dataset,
                               clip.subject, clip.name, clip.source))
    return out, skipped


@dataclass(frozen=True)
class StreamReading:
    """Both stages of every tick of one clip, before any threshold.

    Attributes:
        name, label, subject, dataset: the clip's.
        duration_s: the clip's length, s.
        ticks_s: (K,) time of each tick after the clip's first frame, s.
        logits_real: (K, W, C) classifier logits on the last ``real_windows[w]`` frames of
            real motion (W = 1: the thesis's 1 s).
        logits_pred: (K, C) on 1 s real + forecast (NaN without a forecaster).
    """

    name: str
    label: str
    subject: str
    dataset: str
    duration_s: float
    ticks_s: np.ndarray
    logits_real: np.ndarray
    logits_pred: np.ndarray


def tick_frames(length: int, phase: int) -> np.ndarray:
    """End frames (exclusive) of the ticks on a clip of ``length`` frames whose loop
    phase is ``phase`` in [0, TICK_FRAMES): ``phase + 1 + k TICK_FRAMES``, k = 0, 1, ...
    up to the first tick at or after the clip's last frame."""
    return np.arange(phase + 1, length + TICK_FRAMES, TICK_FRAMES)


def stream_readings(clips: Sequence[GestureClip], model: Any,
                    forecast: Forecaster | None = None, *, seed: int = 0,
                    real_windows: Sequence[int] = (SHORT_FRAMES,)) -> list[StreamReading]:
    """The loop's two stages at every tick of every clip (module docstring).

    Args:
        clips: gesture15 clips (e.g. :func:`avatar_clips`), 25 fps.
        model: a :class:`~simenv.models.skeleton_tcn.SkeletonTCN`.
        forecast: world-frame forecaster (N, 25, 15, 3) -> (N, F, 15, 3), or None.
        seed: seed of the ticks' phases.
        real_windows: lengths (frames) of the real windows classified at each tick.
    """
    longest = max(max(real_windows), SHORT_FRAMES)
    rng = np.random.default_rng(seed)
    histories, owner, ends = [], [], []
    for i, clip in enumerate(clips):
        p = clip.positions
        lead = np.concatenate([np.repeat(p[:1], longest, axis=0), p])
        for end in tick_frames(len(p), int(rng.integers(0, TICK_FRAMES))):
            # A tick after the clip's end sees its last second (what follows a gesture
            # is not in the recording); its time stays the tick's own.
            stop = min(int(end), len(p)) + longest
            histories.append(lead[stop - longest:stop])
            owner.append(i)
            ends.append(int(end))
    full = np.stack(histories).astype(np.float32)
    z_real = np.stack([logits_of(model, normalise_windows(full[:, -w:], ones), ones)
                       for w in real_windows
                       for ones in [np.ones((len(full), w), bool)]], axis=1)
    h = full[:, -SHORT_FRAMES:]
    if forecast is not None:
        both = np.concatenate([h, np.asarray(forecast(h), np.float32)], axis=1)
        v = np.ones(both.shape[:2], bool)
        # Normalised from the real second's first frames, as a window of the loop is.
        z_pred = logits_of(model, normalise_windows(both, v), v)
    else:
        z_pred = np.full_like(z_real[:, 0], np.nan)
    owner_arr, ends_arr = np.array(owner), np.array(ends)
    out = []
    for i, clip in enumerate(clips):
        rows = np.flatnonzero(owner_arr == i)
        out.append(StreamReading(clip.name, clip.label, clip.subject_key, clip.dataset,
                                 clip.num_frames / 25.0, ends_arr[rows] / 25.0,
                                 z_real[rows], z_pred[rows]))
    return out


def _softmax(z: np.ndarray, temperature: float) -> np.ndarray:
    e = np.exp((z - z.max(axis=-1, keepdims=True)) / temperature)
    return e / e.sum(axis=-1, keepdims=True)


_GROUPS = ("greet_clips", "other_clips", "idle_clips")


@dataclass(frozen=True)
class _Outcome:
    """What the loop did on one reading: its group, its first greeting (time, stage) and
    whether its first decision named its own label (None: nothing decided)."""

    group: str
    greet: tuple[float, str] | None
    first_right: bool | None
    duration_s: float


def _probabilities(readings: Sequence[StreamReading], temperature: float,
                   use_forecast: bool, window_rule: str
                   ) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """Each reading's (real stage (K, C), its windows combined by ``window_rule``; real +
    forecast (K, C) or None) probabilities."""
    out = []
    for r in readings:
        p_pred = _softmax(r.logits_pred, temperature) if use_forecast and \
            np.isfinite(r.logits_pred).all() else None
        out.append((real_stage(_softmax(r.logits_real, temperature), window_rule), p_pred))
    return out


def _outcomes(readings: Sequence[StreamReading],
              probabilities: Sequence[tuple[np.ndarray, np.ndarray | None]],
              labels: Sequence[str], threshold: float, greet: str) -> list[_Outcome]:
    """The loop's rule (module docstring) on each reading at ``threshold``."""
    k = labels.index(greet)
    out = []
    for r, (p_real, p_pred) in zip(readings, probabilities, strict=True):
        decided = []
        for t in range(len(r.ticks_s)):
            d = decide(p_real[t], None if p_pred is None else p_pred[t], threshold)
            if d.stage is not Stage.NONE:
                decided.append((d.index, d.stage.value, r.ticks_s[t]))
        greets = [(float(t), stage) for c, stage, t in decided if c == k]
        out.append(_Outcome(outcome_group(r.label, greet), greets[0] if greets else None,
                            labels[decided[0][0]] == r.label if decided else None,
                            r.duration_s))
    return out


def outcome_group(label: str, greet: str = GREET_LABEL) -> str:
    """The group a clip of ``label`` counts in: ``greet_clips``, ``idle_clips`` or
    ``other_clips``."""
    return "greet_clips" if label == greet else "idle_clips" if label == "idle" \
        else "other_clips"


def greeting_rates(counts: Mapping[str, Sequence[int]], delays: Sequence[float],
                   before_end: int) -> dict[str, Any]:
    """The loop's counts with their rates and timing.

    Args:
        counts: per group of :func:`outcome_group`, [greeted, clips].
        delays: per greeted wave, its decision time, s after the clip's start.
        before_end: how many of those were decided before their clip ended.

    Returns:
        ``counts`` and ``greeted_rate``, ``other_greet_rate``, ``idle_greet_rate``,
        ``false_greet_rate`` (other + idle), ``decision_after_onset_s`` (median, p90),
        ``decided_before_end`` (share of the greeted waves).
    """
    (a, n), (b, m), (c, q) = (counts[g] for g in _GROUPS)
    return {**counts,
            "greeted_rate": round(a / max(n, 1), 4),
            "other_greet_rate": round(b / max(m, 1), 4),
            "idle_greet_rate": round(c / max(q, 1), 4),
            "false_greet_rate": round((b + c) / max(m + q, 1), 4),
            "decision_after_onset_s": {
                "median": round(float(np.median(delays)), 3) if delays else None,
                "p90": round(float(np.percentile(delays, 90)), 3) if delays else None},
            "decided_before_end": round(before_end / max(len(delays), 1), 4)}


def _summary(outcomes: Sequence[_Outcome]) -> dict[str, Any]:
    """Counts, rates and timing of :func:`loop_outcomes` from per-reading outcomes."""
    counts = {g: [sum(o.group == g and o.greet is not None for o in outcomes),
                  sum(o.group == g for o in outcomes)] for g in _GROUPS}
    waves = [o for o in outcomes if o.group == "greet_clips" and o.greet is not None]
    delays = [o.greet[0] for o in waves]
    stages = {Stage.REAL.value: 0, Stage.FORECAST.value: 0}
    for o in waves:
        stages[o.greet[1]] += 1
    decided = [o.first_right for o in outcomes if o.first_right is not None]
    return {**greeting_rates(counts, delays, sum(o.greet[0] < o.duration_s for o in waves)),
            "stages": stages,
            "decided_right": round(sum(decided) / max(len(decided), 1), 4)}


def loop_outcomes(readings: Sequence[StreamReading], labels: Sequence[str], threshold: float,
                  temperature: float = 1.0, *, use_forecast: bool = True,
                  greet: str = GREET_LABEL, window_rule: str = "max") -> dict[str, Any]:
    """What the loop decides on ``readings`` at ``threshold`` (module docstring), its real
    windows combined by ``window_rule``.

    Returns:
        ``greet_clips`` / ``other_clips`` / ``idle_clips``: [greeted, clips];
        ``greeted_rate``, ``false_greet_rate`` (other + idle), ``decision_after_onset_s``
        (median, p90 over greeted waves), ``decided_before_end`` (share of greeted waves),
        ``stages`` (which stage took the greetings of waves), ``decided_right`` (share of
        clips whose first decision is their own label).
    """
    probabilities = _probabilities(readings, temperature, use_forecast, window_rule)
    return {"threshold": float(threshold), "temperature": float(temperature),
            "use_forecast": use_forecast, "window_rule": window_rule,
            **_summary(_outcomes(readings, probabilities, labels, threshold, greet))}


def choose_threshold(readings: Sequence[StreamReading], labels: Sequence[str],
                     temperature: float = 1.0, *, use_forecast: bool = True,
                     grid: Sequence[float] = THRESHOLD_GRID,
                     target: float = FALSE_GREET_TARGET, window_rule: str = "max") -> float:
    """The lowest grid threshold whose false-greeting rate on ``readings`` (real windows
    combined by ``window_rule``) is at most ``target`` (the highest grid value when none
    is)."""
    probabilities = _probabilities(readings, temperature, use_forecast, window_rule)
    for t in sorted(grid):
        outcomes = _outcomes(readings, probabilities, labels, t, GREET_LABEL)
        if _summary(outcomes)["false_greet_rate"] <= target:
            return float(t)
    return float(max(grid))


def cross_fitted_outcomes(readings: Sequence[StreamReading], fold_of: Callable[[str], int],
                          labels: Sequence[str], temperatures: Sequence[float], *,
                          use_forecast: bool = True, window_rule: str = "max"
                          ) -> dict[str, Any]:
    """Loop outcomes on every held-out fold, each with the threshold chosen on the other
    folds' readings (``fold_of(subject_key)``) and its own cross-fitted temperature;
    pooled over folds, with each fold's threshold; real windows combined by
    ``window_rule``."""
    pooled: list[_Outcome] = []
    per_fold = []
    for k in sorted({fold_of(r.subject) for r in readings}):
        held = [r for r in readings if fold_of(r.subject) == k]
        calib = [r for r in readings if fold_of(r.subject) != k]
        t = choose_threshold(calib, labels, temperatures[k], use_forecast=use_forecast,
                             window_rule=window_rule)
        outcomes = _outcomes(held, _probabilities(held, temperatures[k], use_forecast,
                                                  window_rule), labels, t, GREET_LABEL)
        pooled += outcomes
        row = _summary(outcomes)
        per_fold.append({"fold": k, "threshold": t, **{g: row[g] for g in _GROUPS}})
    summary = _summary(pooled)
    return {"use_forecast": use_forecast, "window_rule": window_rule, "folds": per_fold,
            **{key: summary[key] for key in (*_GROUPS, "greeted_rate", "other_greet_rate",
                                             "idle_greet_rate", "decision_after_onset_s",
                                             "decided_before_end", "stages")}}


__all__ = ["AVATAR_CODE", "CACHE_ENV", "FALSE_GREET_TARGET", "GREET_LABEL", "THRESHOLD_GRID",
           "TICK_FRAMES", "StreamReading", "avatar_cache_dir", "avatar_clips",
           "choose_threshold", "cross_fitted_outcomes", "greeting_rates", "loop_outcomes",
           "outcome_group", "stream_readings", "tick_frames"]

"""The room's perception loop: predict ahead, classify real + predicted motion, decide.

Every :attr:`PerceptionLoop.period` frames (25 = 1 s at 25 fps, the thesis's rate) the loop
takes the user's last frames of canonical keypoints and

1. **classifies the real frames alone** -- the last second, and the longer windows of real
   motion ending now when the classifier was trained to read them (``context_frames``),
   their probabilities combined by the ``window_rule`` (:func:`real_stage`: the most
   confident window, or the windows' mean);
2. **predicts ahead** (:attr:`predictor`, e.g. the constant-velocity baseline or the
   PredictiveMA-WGAN) and classifies real + predicted frames -- only when the real stage
   is not confident, as step 3 needs it;
3. **decides** by :func:`decide`, the room's one decision rule: the real stage's top label
   when its probability reaches ``threshold`` (:attr:`Stage.REAL`), else the real +
   predicted stage's when it does (a decision anticipated from prediction,
   :attr:`Stage.FORECAST`), else nothing (:attr:`Stage.NONE`). The same function decides
   on recorded readings (:func:`loop_decisions`, :mod:`simenv.perception.protocol`).

What the room does with the decided label -- the scenario's reaction, a refractory period
per label, the action the environment executes -- is the agent's
(:class:`simenv.perception.room_agent.RoomAgent`: perceive -> decide -> act).

Each stage is an interface: any object with ``predict(history) -> future``, ``history_len``
and ``future_len`` on the 21 canonical keypoints predicts (the baselines of
:mod:`simenv.models.baselines` directly; the PredictiveMA-WGAN and the DCT-MLP, which work
on the root-relative pred17 layout, through :class:`CanonicalPredictor`); any
:class:`GestureModel` classifies. A predictor whose ``uses_observer`` is true is also told
where the observer the user faces stands, ``predict(history, observer)``, when the tick is
given it: a recording's sensor (:attr:`simenv.room.session.UserTrack.observer`), the agent
for a live user (the gesture forecaster: people walk up to what they face and stop short).

Defaults (:func:`load_predictor`, :func:`default_classifier`): the shipped models when they
are present -- the gesture-domain forecaster ``predictor-gesture-25-50``
(:data:`DEFAULT_PREDICTOR`; any other shipped ``predictor-*`` can be named, e.g. the
thesis's PredictiveMA-WGAN ``predictor-25-50``) and the two skeleton TCNs of
``gesture-tcn-ensemble`` (:data:`DEFAULT_CLASSIFIER`; the single TCN ``gesture-tcn`` and the
thesis's transformer ``gesture-classifier`` by name)
through :class:`TrainedClassifier` (one network, or an ensemble of several), with the
threshold, real windows and use of the forecast stage its training chose on held-out
subjects -- and otherwise the constant-velocity baseline and the nearest-neighbour
:class:`TemplateClassifier` built from the labelled real clips of the gesture corpus.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np
from tqdm import tqdm

import simenv.models
from simenv.core.config import shared_data_root
from simenv.core.errors import SimenvError
from simenv.core.motion import resample_linear
from simenv.core.skeletons import CANONICAL_KEYPOINTS, CANONICAL_TREE
from simenv.data.gestures import (
    GESTURE15_JOINTS,
    GESTURE_LABELS,
    WINDOW_FRAMES,
    GestureClip,
    cut_window,
    load_gesture_clips,
    normalise_windows,
    split_cross_subject,
)
from simenv.data.prediction_data import PRED17_JOINTS


@runtime_checkable
class GestureModel(Protocol):
    """A gesture classifier on world-frame windows (metres, Z up, 25 fps)."""

    labels: tuple[str, ...]
    joint_names: tuple[str, ...]

    def classify(self, window: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """(T, J, 3) window on :attr:`joint_names`, (T,) valid mask -> (C,) probabilities."""
        ...


def _one_torch_thread() -> None:
    """In a process forked after torch ran multi-threaded (gymnasium's AsyncVectorEnv
    forks its workers), the inherited OpenMP pool deadlocks the first parallel operation
    (measured: a matmul hangs in the child); one intra-op thread there avoids it."""
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)


os.register_at_fork(after_in_child=_one_torch_thread)


class TemplateClassifier:
    """Nearest-neighbour gesture classifier over labelled template windows.

    A window and every template are normalised (:func:`simenv.data.gestures.normalise_windows`:
    root at the origin, facing +x, reference size) and their valid frames resampled to
    ``length`` frames of normalised time (a gesture performed faster or slower still
    matches). The distance is the mean per-frame, per-joint Euclidean distance (m of the
    reference body); a class's distance is that of its nearest template, and the
    probabilities are ``softmax(-d_c / temperature)``.

    Args:
        templates: (N, T, J, 3) world-frame windows, m. valid: (N, T) masks.
        labels: (N,) label of each template.
        joint_names: the J joints.
        length: frames of normalised time compared.
        temperature: softmax temperature, m.
    """

    def __init__(self, templates: np.ndarray, valid: np.ndarray, labels: Sequence[str],
                 joint_names: Sequence[str] = GESTURE15_JOINTS, length: int = 25,
                 temperature: float = 0.03) -> None:
        if len(templates) == 0 or len(templates) != len(labels):
            raise SimenvError(f"need one label per template; got {len(templates)} templates "
                              f"and {len(labels)} labels", field="templates")
        self.joint_names = tuple(joint_names)
        self.labels = tuple(sorted(set(labels), key=lambda x: (
            GESTURE_LABELS.index(x) if x in GESTURE_LABELS else len(GESTURE_LABELS), x)))
        self.length, self.temperature = int(length), float(temperature)
        valid = np.asarray(valid, dtype=bool)
        normed = normalise_windows(np.asarray(templates, np.float32), valid,
                                   joints=self.joint_names)
        self._templates = np.stack([resample_linear(t[v], self.length)
                                    for t, v in zip(normed, valid, strict=True)])
        self._class = np.array([self.labels.index(label) for label in labels])

    #: What the rehearsal summary calls it.
    name = "templates"

    @classmethod
    def from_clips(cls, clips: Sequence[GestureClip], label_map: dict[str, str] | None = None,
                   **kwargs: Any) -> TemplateClassifier:
        """Templates from the centre 3 s of each labelled clip (at most; shorter clips
        whole), on the gesture joint set; ``label_map`` renames the clips' labels (e.g.
        :func:`vocabulary_map` onto a scenario's vocabulary)."""
        if not clips:
            raise SimenvError("no clips to build templates from", field="clips")
        label_map = label_map or {}
        cuts = [cut_window(c.positions, offset=max(c.num_frames - WINDOW_FRAMES, 0) // 2)
                for c in clips]
        return cls(np.stack([w for w, _ in cuts]), np.stack([v for _, v in cuts]),
                   [label_map.get(c.label, c.label) for c in clips], GESTURE15_JOINTS,
                   **kwargs)

    def classify(self, window: np.ndarray, valid: np.ndarray) -> np.ndarray:
        valid = np.asarray(valid, dtype=bool)
        if not valid.any():
            raise SimenvError("window has no valid frame", field="valid")
        x = normalise_windows(np.asarray(window, np.float32)[None], valid[None],
                              joints=self.joint_names)[0]
        q = resample_linear(x[valid], self.length)
        d = np.linalg.norm(self._templates - q[None], axis=-1).mean(axis=(1, 2))
        best = np.full(len(self.labels), np.inf)
        np.minimum.at(best, self._class, d)
        z = -(best - best.min()) / self.temperature
        p = np.exp(z)
        return p / p.sum()


def vocabulary_map(labels: Sequence[str], vocabulary: Sequence[str]) -> dict[str, str]:
    """How a classifier's labels read in a scenario's vocabulary.

    A label of the vocabulary keeps its name; ``wave`` becomes ``hello`` when the
    vocabulary has ``hello`` but no ``wave`` (the discomfort scenario: waving hello); any
    other label becomes ``idle`` when the vocabulary has it (nothing to react to), and is
    kept otherwise (a label outside the vocabulary never triggers).
    """
    vocab = set(vocabulary)
    out = {}
    for label in labels:
        if label in vocab:
            out[label] = label
        elif label == "wave" and "hello" in vocab:
            out[label] = "hello"
        else:
            out[label] = "idle" if "idle" in vocab else label
    return out


class TrainedClassifier:
    """Trained gesture network(s) (:class:`~simenv.models.skeleton_tcn.SkeletonTCN`,
    :class:`~simenv.models.gesture_classifier.GestureClassifier`) as a :class:`GestureModel`:
    one network, or an ensemble of member networks.

    A network with a fixed window of ``W`` frames (the transformer: 75 = 3 s at 25 fps) is
    given a shorter window (the loop's 1 s of real motion, or 1 s real + F predicted
    frames) padded to ``W`` by holding its last frame, the padded frames marked invalid
    (the network masks them out of attention and pooling: the thesis's "1 s real"
    condition), and a longer one's last ``W`` frames; the TCN classifies the frames it is
    given. The window is normalised once (:func:`simenv.data.gestures.normalise_windows`,
    the normalisation every member's ``classify_world`` applies).

    Ensemble math: member m (m = 1..M) gives logits ``z_m`` and its calibrated
    probabilities ``p_m = softmax(z_m / τ_m)`` (``τ_m`` its checkpoint's temperature; 1
    for the transformer). The members' temperature-scaled logits are averaged,

        p = softmax( (1/M) Σ_m z_m / τ_m ) = softmax( (1/M) Σ_m log p_m ),

    the second form because ``log p_m`` differs from ``z_m / τ_m`` by a constant per member
    that the softmax drops. TCN members run as one fused network
    (:class:`~simenv.models.skeleton_tcn.SkeletonTCNEnsemble`: the first form, at about
    the cost of one member); other members are run one by one (the second form, from
    each member's probabilities). One member gives its own ``p_1``; M copies of a network
    give its ``p`` again; members sharing one temperature τ give
    ``softmax(mean_m z_m / τ)``, the ensemble that ``benchmarks/loop_variants.py`` scores
    and ships (τ fitted on the members' mean logits). The
    class probabilities ``p_c`` are then summed onto the room's labels through
    ``label_map`` (``P_l = sum_{c -> l} p_c``).

    Args:
        model: the trained classifier (e.g. ``simenv.models.load("gesture-tcn")``), a
            shipped :class:`~simenv.models.skeleton_tcn.SkeletonTCNEnsemble` (its
            checkpoint records the loop settings: threshold, forecast stage, real
            windows), or a sequence of member networks with the same labels, joints and
            window (the first member's checkpoint records the loop settings).
        label_map: network label -> room label (default: identity). Unmapped labels keep
            their name.
        name: what the rehearsal summary calls it.

    Raises:
        SimenvError: no member, members that differ in labels, joints or window, or a
            ``label_map`` naming labels the networks lack.
    """

    #: Decision threshold suggested to :class:`PerceptionLoop` for the shipped network:
    #: its probabilities are flat (12 classes, label smoothing; median top 0.25-0.29 at a
    #: wave's tick), so 0.6 is rarely reached. Chosen on the classifier's *training*
    #: subjects only (488 MSR and UTKinect clips, 97 of them idle, retargeted into the
    #: room, through the loop: ``python -m simenv.perception.loop --subjects train``) by
    #: :func:`choose_threshold` on the grid 0.10, 0.15, ..., 0.60: Youden's J of greeting
    #: 10/55 - 20/433 = 0.136 at 0.10 and 0.15 (0.134 at 0.20, 0.113 at 0.25, 0.018 at
    #: 0.30, 0 from 0.35; with the predictor-25-50 of 2026-12-02); the tie goes to the
    #: higher. Test-subject numbers in docs/room.md.
    threshold = 0.15

    def __init__(self, model: Any | Sequence[Any], label_map: dict[str, str] | None = None,
                 name: str = "gesture-classifier") -> None:
        # torch comes with the networks: imported only once a network is given.
        from simenv.models.skeleton_tcn import SkeletonTCN, SkeletonTCNEnsemble

        members = tuple(model) if isinstance(model, (list, tuple)) else (model,)
        if not members:
            raise SimenvError("an ensemble needs at least one member network", field="model")
        record = members[0]
        if isinstance(record, SkeletonTCNEnsemble):
            members = tuple(record.members)
        config = members[0].config
        source = tuple(config.labels)
        # A network with a fixed window (the transformer) is padded to it; one that takes
        # any length (the TCN) classifies the frames it is given.
        window = int(config.window) if hasattr(config, "window") else None
        for k, m in enumerate(members[1:], start=1):
            other = int(m.config.window) if hasattr(m.config, "window") else None
            if (tuple(m.config.labels), tuple(m.config.joint_names), other) != (
                    source, tuple(config.joint_names), window):
                raise SimenvError(f"ensemble member {k} differs from member 0 in its labels, "
                                  "joints or window; members must classify alike",
                                  field="model")
        label_map = dict(label_map or {})
        unknown = sorted(set(label_map) - set(source))
        if unknown:
            raise SimenvError(f"label_map names labels {unknown} that the classifier does "
                              f"not have; its labels: {list(source)}", field="label_map")
        mapped = [label_map.get(label, label) for label in source]
        #: The member networks; :attr:`model` is the one whose record the loop follows
        #: (a shipped ensemble's own, else the first member's).
        self.members, self.model, self.name = members, record, name
        # One network (a shipped ensemble is one) classifies alone; TCN members run as one
        # fused network (same probabilities, one pass of overhead); others one by one.
        self._net = None
        if len(members) == 1 or isinstance(record, SkeletonTCNEnsemble):
            self._net = record
        elif all(isinstance(m, SkeletonTCN) for m in members):
            try:
                self._net = SkeletonTCNEnsemble(members)
            except ValueError as exc:
                raise SimenvError(str(exc), field="model") from None
        self.joint_names = tuple(config.joint_names)
        self.window = window
        # A checkpoint that records its loop threshold (chosen on held-out subjects by
        # its training) overrides the class default.
        metadata = getattr(self.model, "metadata", {})
        self.threshold = float(metadata.get("loop_threshold", type(self).threshold))
        self.uses_forecast = bool(metadata.get("loop_uses_forecast", True))
        #: Real windows (frames) its loop threshold was chosen with, and how they were
        #: combined (:func:`real_stage`; a checkpoint that does not say: ``max``).
        self.loop_windows = tuple(int(w) for w in metadata.get("loop_windows", (25,)))
        self.loop_window_rule = str(metadata.get("loop_window_rule", "max"))
        self.labels: tuple[str, ...] = tuple(dict.fromkeys(mapped))
        self._to = np.array([self.labels.index(m) for m in mapped])

    @classmethod
    def shipped(cls, name: str | Sequence[str] | None = None,
                vocabulary: Sequence[str] | None = None) -> TrainedClassifier:
        """The shipped checkpoint ``name`` (None: :data:`DEFAULT_CLASSIFIER`; several
        names: an ensemble of them, the first recording the loop settings), its labels
        mapped onto ``vocabulary`` (:func:`vocabulary_map`; None: the network's own)."""
        names = [name or DEFAULT_CLASSIFIER] if name is None or isinstance(name, str) \
            else list(name)
        models = [simenv.models.load(n) for n in names]
        mapping = None if vocabulary is None else vocabulary_map(models[0].config.labels,
                                                                 vocabulary)
        return cls(models, mapping, "+".join(names))

    def classify(self, window: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """(T, J, 3) world-frame window on :attr:`joint_names` (m, Z up, 25 fps), (T,)
        valid mask -> (len(labels),) probabilities (the ensemble's, class docstring)."""
        x = np.asarray(window, dtype=np.float32)
        v = np.asarray(valid, dtype=bool)
        if x.ndim != 3 or x.shape[1:] != (len(self.joint_names), 3) or v.shape != x.shape[:1]:
            raise SimenvError(f"window must be (T, {len(self.joint_names)}, 3) with a (T,) "
                              f"valid mask; got {x.shape} and {v.shape}", field="window")
        if not v.any():
            raise SimenvError("window has no valid frame", field="valid")
        if self.window is not None:
            x, v = x[-self.window:], v[-self.window:]
            pad = self.window - len(x)
            if pad:
                x = np.concatenate([x, np.repeat(x[-1:], pad, axis=0)])
                v = np.concatenate([v, np.zeros(pad, bool)])
        normed = normalise_windows(x[None], v[None], joints=self.joint_names)
        if self._net is not None:
            p = self._net.predict_proba(normed, v[None])[0]
        else:
            # Mean of the members' log-probabilities = mean temperature-scaled logits
            # up to a constant; the floor keeps a probability that underflowed finite.
            probs = [m.predict_proba(normed, v[None])[0] for m in self.members]
            logp = np.log(np.maximum(probs, 1e-30)).mean(axis=0)
            p = np.exp(logp - logp.max())
            p = p / p.sum()
        return np.bincount(self._to, weights=p, minlength=len(self.labels))


class CanonicalPredictor:
    """A predictor of a canonical-keypoint subset, run on all 21 canonical keypoints.

    The history is cut to the predictor's joints (made root-relative -- minus each frame's
    pelvis -- when the predictor works that way, as the PredictiveMA-WGAN's pred17 layout
    does); the forecast is put back at the last observed pelvis (the predictor forecasts
    the body's shape, not its root), and each keypoint the predictor lacks (toes, hands)
    keeps its last offset from its canonical parent.

    Args:
        predictor: ``predict(history (H, J, 3)) -> (F, J, 3)``, ``history_len``,
            ``future_len``.
        joints: the predictor's J joints, canonical keypoint names.
        root_relative: whether the predictor takes pelvis-relative positions.
        name: what the rehearsal summary calls it (default: the predictor's class).

    Attributes:
        uses_observer: the predictor takes ``predict(history, observer)`` (its own
            ``uses_observer``, on world positions: never root-relative); :meth:`predict`
            passes the observer on to it.
    """

    def __init__(self, predictor: Any, joints: Sequence[str] = PRED17_JOINTS,
                 root_relative: bool = True, name: str | None = None) -> None:
        missing = [j for j in joints if j not in CANONICAL_KEYPOINTS]
        if missing:
            raise SimenvError(f"predictor joints {missing} are not canonical keypoints",
                              field="joints")
        self.predictor, self.root_relative = predictor, bool(root_relative)
        self.name = name or type(predictor).__name__
        self.history_len = int(predictor.history_len)
        self.future_len = int(predictor.future_len)
        self.uses_observer = bool(getattr(predictor, "uses_observer", False)
                                  and not self.root_relative)
        self._idx = [CANONICAL_KEYPOINTS.index(j) for j in joints]
        self._pelvis = CANONICAL_KEYPOINTS.index("pelvis")
        # Keypoints the predictor lacks, parents first (CANONICAL_KEYPOINTS is tree-ordered).
        self._carried = [(k, CANONICAL_KEYPOINTS.index(CANONICAL_TREE[name]))
                         for k, name in enumerate(CANONICAL_KEYPOINTS)
                         if k not in self._idx and CANONICAL_TREE[name] is not None]

    def predict(self, history: np.ndarray, observer: np.ndarray | None = None) -> np.ndarray:
        """(H, 21, 3) canonical keypoints, m -> (F, 21, 3) float32. ``observer``: (3,)
        world position of the observer the user faces, m (None: unknown), for a predictor
        that ``uses_observer`` (ignored otherwise)."""
        h = np.asarray(history, dtype=np.float32)
        sub = h[:, self._idx]
        root = h[-1, self._pelvis]
        if self.root_relative:
            sub = sub - h[:, self._pelvis][:, None]
        if self.uses_observer and observer is not None:
            future = np.asarray(self.predictor.predict(sub, observer), dtype=np.float32)
        else:
            future = np.asarray(self.predictor.predict(sub), dtype=np.float32)
        if self.root_relative:
            future = future + root
        out = np.repeat(h[-1:], len(future), axis=0)
        out[:, self._idx] = future
        for k, parent in self._carried:
            out[:, k] = out[:, parent] + (h[-1, k] - h[-1, parent])
        return out


def forecast(predictor: Any, history: np.ndarray, observer: np.ndarray | None = None
             ) -> np.ndarray:
    """``predictor``'s (F, K, 3) float32 forecast after its last ``history_len`` frames of
    ``history`` (H, K, 3), m; told ``observer`` ((3,) world position, m) when it
    ``uses_observer`` and one is given."""
    recent = history[-int(predictor.history_len):]
    if observer is not None and getattr(predictor, "uses_observer", False):
        return np.asarray(predictor.predict(recent, observer), dtype=np.float32)
    return np.asarray(predictor.predict(recent), dtype=np.float32)


#: The shipped predictor the room uses by default (1 s observed -> 2 s ahead): the
#: gesture-domain forecaster, trained on Kinect recordings of people gesturing.
DEFAULT_PREDICTOR = "predictor-gesture-25-50"
#: The fallback when no learned predictor is shipped: the 2-s constant-velocity baseline.
FALLBACK_PREDICTOR = "constant-velocity-50"
#: How the real stage combines the probabilities of a tick's real windows
#: (:func:`real_stage`).
WINDOW_RULES = ("max", "mean")
#: The shipped classifier the room uses by default: two skeleton TCNs run as one, measured
#: on subjects they never saw (docs/recognition.md); ``gesture-tcn`` is one TCN alone,
#: ``gesture-classifier`` the thesis's transformer.
DEFAULT_CLASSIFIER = "gesture-tcn-ensemble"


def check_window_rule(rule: str) -> str:
    """``rule`` if it is one of :data:`WINDOW_RULES`.

    Raises:
        SimenvError: naming the unknown rule and the known ones.
    """
    if rule not in WINDOW_RULES:
        raise SimenvError(f"unknown window rule {rule!r}; expected one of "
                          f"{', '.join(WINDOW_RULES)}", field="window_rule")
    return rule


def real_stage(p: np.ndarray, rule: str = "max") -> np.ndarray:
    """The real stage's probabilities from those of a tick's real windows.

    ``max``: the window whose top label is the most probable speaks, its probabilities
    as they are (ties: the first, the shortest window). ``mean``: the windows'
    probabilities averaged, ``P = (1 / W) sum_w p_w``: one motion read at W time scales,
    so that one window's overconfident read does not decide alone (the maximum of W
    reads is biased high, and its threshold must be raised to keep false greetings
    down).

    Args:
        p: (..., W, C) probabilities of the W windows (any leading axes).
        rule: one of :data:`WINDOW_RULES`.

    Returns:
        (..., C) probabilities.

    Raises:
        SimenvError: an unknown rule or no window.
    """
    p = np.asarray(p)
    check_window_rule(rule)
    if p.ndim < 2 or p.shape[-2] == 0:
        raise SimenvError(f"window probabilities must be (..., W >= 1, C); got {p.shape}",
                          field="p")
    if rule == "mean":
        return p.mean(axis=-2)
    best = p.max(axis=-1).argmax(axis=-1)[..., None, None]
    return np.take_along_axis(p, best, axis=-2)[..., 0, :]


class Stage(Enum):
    """Which stage of a perception tick took its decision; the value is how logs, summaries
    and tables name it (``None``: no decision)."""

    REAL = "real"
    FORECAST = "predicted"
    NONE = None


@dataclass(frozen=True, slots=True)
class Decision:
    """What :func:`decide` concluded on one tick.

    Attributes:
        stage: the stage that decided (:attr:`Stage.NONE`: no label was confident).
        index: the decided class, an index into the classifier's labels (None: no decision).
        probabilities: (C,) the deciding stage's probabilities; undecided, the real +
            predicted stage's when it was read, else the real stage's.
    """

    stage: Stage
    index: int | None
    probabilities: np.ndarray


def decide(p_real: np.ndarray,
           p_forecast: np.ndarray | Callable[[], np.ndarray] | None,
           threshold: float) -> Decision:
    """The room's decision rule on one tick: the real stage first, then the forecast.

    The top class of the real stage decides when its probability reaches ``threshold``;
    otherwise the top class of the real + predicted stage does when its probability
    reaches it; otherwise nothing is decided.

    Args:
        p_real: (C,) probabilities of the real stage (its windows combined,
            :func:`real_stage`).
        p_forecast: (C,) probabilities of the real + predicted stage; a function returning
            them, called only when the real stage is not confident (a live tick forecasts
            only then); or None (no forecast stage).
        threshold: probability at which a class is decided.
    """
    p_real = np.asarray(p_real)
    if p_real.max() >= threshold:
        return Decision(Stage.REAL, int(p_real.argmax()), p_real)
    if callable(p_forecast):
        p_forecast = p_forecast()
    if p_forecast is None:
        return Decision(Stage.NONE, None, p_real)
    p = np.asarray(p_forecast)
    if p.max() >= threshold:
        return Decision(Stage.FORECAST, int(p.argmax()), p)
    return Decision(Stage.NONE, None, p)


def tick_due(frame: int, first: int = 25, period: int = 25) -> bool:
    """Whether frame index ``frame`` (0-based) ends a perception period: every ``period``
    frames once ``first`` frames have been seen (25 and 25: a tick a second at 25 fps,
    the first when the first second is complete)."""
    return frame + 1 >= first and (frame + 1) % period == 0


def load_predictor(spec: Any = None) -> Any:
    """A predictor on the 21 canonical keypoints.

    Args:
        spec: None or ``"auto"`` (:data:`DEFAULT_PREDICTOR` when shipped, otherwise
            :data:`FALLBACK_PREDICTOR`); a ``simenv.models.load`` name -- a shipped
            ``predictor-*`` (PredictiveMA-WGAN, ``predictor-dctmlp-*``: run through
            :class:`CanonicalPredictor`) or a baseline ``zero-velocity-<F>`` /
            ``constant-velocity-<F>`` (directly); or a predictor object (returned as is).

    Returns:
        an object with ``predict``, ``history_len`` and ``future_len`` (and ``name``
        when built from a name).
    """
    if spec is None or spec == "auto":
        spec = (DEFAULT_PREDICTOR if DEFAULT_PREDICTOR in simenv.models.available()
                else FALLBACK_PREDICTOR)
    if not isinstance(spec, str):
        return spec
    model = simenv.models.load(spec)
    if spec.startswith("predictor-gesture-"):
        # World-frame gesture15 forecaster: its own root motion, no pred17 layout.
        return CanonicalPredictor(model, joints=GESTURE15_JOINTS, root_relative=False,
                                  name=spec)
    if spec.startswith("predictor-"):
        return CanonicalPredictor(model, name=spec)
    model.name = spec  # a baseline: on any joints, the canonical keypoints included
    return model


def default_classifier(vocabulary: Sequence[str], data: str | os.PathLike[str] | None = None
                       ) -> GestureModel:
    """The room's classifier for a scenario's ``vocabulary``: the shipped
    :data:`DEFAULT_CLASSIFIER` (:class:`TrainedClassifier`) when present, otherwise a
    :class:`TemplateClassifier` from every labelled clip of the gesture corpus
    (``data``/gestures; ``data`` default :func:`simenv.core.config.shared_data_root`), labels
    mapped by :func:`vocabulary_map`.

    Raises:
        SimenvError: no shipped classifier and no gesture corpus.
    """
    if DEFAULT_CLASSIFIER in simenv.models.available():
        return TrainedClassifier.shipped(DEFAULT_CLASSIFIER, vocabulary)
    root = shared_data_root(data) / "gestures"
    if not root.is_dir():
        raise SimenvError(f"no shipped {DEFAULT_CLASSIFIER!r} checkpoint and no gesture "
                          f"corpus at {root} for the template classifier (set "
                          "SIMENV_SHARED_DATA or pass --data)", field="classifier")
    clips = load_gesture_clips(root)
    return TemplateClassifier.from_clips(clips, vocabulary_map(GESTURE_LABELS, vocabulary))


@dataclass(frozen=True)
class Perception:
    """One perception tick.

    Attributes:
        t_s: time of the last observed frame, s.
        probabilities: label -> probability of the stage that decided (or of the
            real + predicted stage when nothing was decided and it was read).
        stage: the stage that decided (:func:`decide`).
        label: the decided gesture (None: no decision).
        predicted_motion_m: mean displacement of the predicted frames' joints from the last
            observed pose, m (a summary of the prediction; 0 when none was made).
        compute_s: wall time of the tick, s.
    """

    t_s: float
    probabilities: dict[str, float]
    stage: Stage
    label: str | None
    predicted_motion_m: float
    compute_s: float = field(compare=False)


class PerceptionLoop:
    """Classify real motion, predict, classify real + predicted motion, and decide, every
    ``period`` frames (see the module docstring).

    Args:
        classifier: a :class:`GestureModel`.
        predictor: forecaster on canonical-keypoint windows (None: real frames only).
        real_frames: frames of real motion classified (25 = 1 s).
        context_frames: longer windows of real motion also classified at each tick, frames
            (None: the classifier's ``loop_windows`` beyond ``real_frames`` if it has
            them, else none). A history shorter than a window gives it what there is.
        window_rule: how the real windows' probabilities make the real stage's, one of
            :data:`WINDOW_RULES` (:func:`real_stage`; None: the classifier's
            ``loop_window_rule`` attribute if it has one -- the rule its threshold was
            chosen with --, else ``max``).
        period: frames between ticks.
        threshold: probability at which a label is decided (None: the classifier's
            ``threshold`` attribute if it has one, else 0.6).
        use_forecast: run the real + predicted stage (None: the classifier's
            ``uses_forecast`` attribute if it has one -- a trained recogniser records
            whether its loop greeted better with it on held-out subjects --, else True).
    """

    def __init__(self, classifier: GestureModel, predictor: Any = None, *,
                 real_frames: int = 25, period: int = 25, threshold: float | None = None,
                 use_forecast: bool | None = None,
                 context_frames: Sequence[int] | None = None,
                 window_rule: str | None = None) -> None:
        missing = [j for j in classifier.joint_names if j not in CANONICAL_KEYPOINTS]
        if missing:
            raise SimenvError(f"classifier joints {missing} are not canonical keypoints",
                              field="classifier")
        self.classifier, self.predictor = classifier, predictor
        self.real_frames, self.period = int(real_frames), int(period)
        if threshold is None:
            threshold = getattr(classifier, "threshold", 0.6)
        self.threshold = float(threshold)
        if use_forecast is None:
            use_forecast = bool(getattr(classifier, "uses_forecast", True))
        self.use_forecast = use_forecast
        if context_frames is None:
            context_frames = [w for w in getattr(classifier, "loop_windows", ())
                              if w > self.real_frames]
        self.context_frames = tuple(sorted(int(w) for w in context_frames))
        if window_rule is None:
            window_rule = str(getattr(classifier, "loop_window_rule", "max"))
        self.window_rule = check_window_rule(window_rule)
        self._joints = [CANONICAL_KEYPOINTS.index(j) for j in classifier.joint_names]

    @property
    def forecasts(self) -> bool:
        """Whether a tick may run the real + predicted stage (a predictor, and its use)."""
        return self.predictor is not None and self.use_forecast

    @property
    def history_frames(self) -> int:
        """Frames of history a tick reads: its longest real window, and the predictor's
        history when it forecasts."""
        need = max((self.real_frames, *self.context_frames))
        return max(need, int(self.predictor.history_len)) if self.forecasts else need

    def due(self, frame: int) -> bool:
        """Whether frame index ``frame`` (0-based) ends a perception period
        (:func:`tick_due` with :attr:`real_frames` and :attr:`period`)."""
        return tick_due(frame, self.real_frames, self.period)

    def perceive(self, t_s: float, history: np.ndarray,
                 observer: np.ndarray | None = None) -> Perception:
        """Run one tick on ``history`` (H >= real_frames, K = 21 canonical keypoints, 3)
        ending at time ``t_s``; ``observer``: (3,) world position of the observer the user
        faces, m (module docstring), for a predictor that ``uses_observer`` (None:
        unknown)."""
        start = time.perf_counter()
        h = np.asarray(history, dtype=np.float32)
        if h.ndim != 3 or h.shape[1:] != (len(CANONICAL_KEYPOINTS), 3) or len(h) < self.real_frames:
            raise SimenvError(f"history must be (H >= {self.real_frames}, "
                              f"{len(CANONICAL_KEYPOINTS)}, 3) canonical keypoints; got "
                              f"{h.shape}", field="history")
        real = h[-self.real_frames:][:, self._joints]
        windows = [real] + [h[-w:][:, self._joints] for w in self.context_frames]
        p_real = real_stage(np.stack([self.classifier.classify(x, np.ones(len(x), bool))
                                      for x in windows]), self.window_rule)
        motion = 0.0  # the forecast's displacement, set if decide() asks for the stage

        def real_and_predicted() -> np.ndarray:
            nonlocal motion
            future = forecast(self.predictor, h, observer)
            motion = float(np.linalg.norm(future - h[-1][None], axis=-1).mean())
            both = np.concatenate([real, future[:, self._joints]])
            return self.classifier.classify(both, np.ones(len(both), bool))

        d = decide(p_real, real_and_predicted if self.forecasts else None, self.threshold)
        label = None if d.index is None else self.classifier.labels[d.index]
        return Perception(t_s, dict(zip(self.classifier.labels, map(float, d.probabilities),
                                        strict=True)), d.stage, label, motion,
                          time.perf_counter() - start)


# -- the loop measured on labelled clips --------------------------------------------------


@dataclass(frozen=True)
class LoopReading:
    """Both stages of one perception tick on one clip, before any threshold.

    Attributes:
        name, label, subject: the clip's name, true label and subject key.
        p_real: (C,) probabilities on the 1 s of real motion.
        p_pred: (C,) probabilities on the 1 s real + the predicted frames.
    """

    name: str
    label: str
    subject: str
    p_real: np.ndarray
    p_pred: np.ndarray


def loop_readings(clips: Sequence[GestureClip], classifier: GestureModel, predictor: Any,
                  *, scenario: str = "default", real_frames: int = 25,
                  progress: bool = False) -> tuple[list[LoopReading], list[str]]:
    """The loop's stages on each clip, the room's way.

    Each clip's recording (``clip.source``) is retargeted onto the user in ``scenario``
    (:func:`simenv.room.session.user_track`) and the avatar's canonical keypoints are read at
    the tick ending ``real_frames`` into the clip's centre 3-s window (the frames a short
    clip lacks before it repeat its first, as when a session starts).

    Returns:
        (one reading per clip that could be retargeted, the skipped clips with the
        reason: no source motion, or the retargeting's error, e.g. a skeleton without the
        hips).
    """
    # The session retargets onto the room's user: MuJoCo and the solver, needed here only.
    from simenv.room.session import Session, user_track

    need = max(real_frames, int(getattr(predictor, "history_len", real_frames)))
    readings, skipped = [], []
    joints = [CANONICAL_KEYPOINTS.index(j) for j in classifier.joint_names]
    for clip in tqdm(clips, desc="loop readings", disable=not progress):
        if clip.source is None:
            skipped.append(f"{clip.name}: no source motion")
            continue
        try:
            track = user_track(Session(clip.source), scenario)
        except SimenvError as exc:
            skipped.append(f"{clip.name}: {exc.detail}")
            continue
        kp = track.keypoints.astype(np.float32)
        end = min(max(len(kp) - WINDOW_FRAMES, 0) // 2 + real_frames, len(kp))
        h = kp[max(end - need, 0):end]
        h = np.concatenate([np.repeat(h[:1], need - len(h), axis=0), h])
        real = h[-real_frames:][:, joints]
        p_real = classifier.classify(real, np.ones(len(real), bool))
        future = forecast(predictor, h, track.observer)
        both = np.concatenate([real, future[:, joints]])
        p_pred = classifier.classify(both, np.ones(len(both), bool))
        readings.append(LoopReading(clip.name, clip.label, clip.subject_key,
                                    np.asarray(p_real), np.asarray(p_pred)))
    return readings, skipped


def loop_decisions(readings: Sequence[LoopReading], labels: Sequence[str], threshold: float,
                   greet: str = "wave") -> dict[str, Any]:
    """What :class:`PerceptionLoop` decides on each reading at ``threshold`` (:func:`decide`:
    real stage first, then real + predicted), summed up: clips decided, decided label right, greet
    (label ``greet`` decided) on ``greet`` clips / on the others / on ``idle`` clips, as
    ``[k, n]``, and decisions per stage."""
    decided = right = 0
    greets = {"greet_clips": [0, 0], "other_clips": [0, 0], "idle_clips": [0, 0]}
    stages = {Stage.REAL.value: 0, Stage.FORECAST.value: 0}
    for r in readings:
        d = decide(r.p_real, r.p_pred, threshold)
        label = None if d.index is None else labels[d.index]
        groups = ["greet_clips" if r.label == greet else "other_clips"]
        if r.label == "idle":
            groups.append("idle_clips")
        for g in groups:
            greets[g][1] += 1
            greets[g][0] += int(label == greet)
        if d.stage is not Stage.NONE:
            decided += 1
            right += int(label == r.label)
            stages[d.stage.value] += 1
    n = max(len(readings), 1)
    return {"threshold": threshold, "clips": len(readings), "decided": round(decided / n, 4),
            "decided_right": round(right / max(decided, 1), 4), **greets, "stages": stages}


def choose_threshold(readings: Sequence[LoopReading], labels: Sequence[str],
                     grid: Sequence[float] = (0.10, 0.15, 0.20, 0.25, 0.30, 0.35, 0.40,
                                              0.45, 0.50, 0.55, 0.60),
                     greet: str = "wave") -> tuple[float, list[dict[str, Any]]]:
    """The grid value maximising Youden's J of greeting, ``greets on greet clips / their
    number - greets on the others / their number`` (ties: the highest threshold, the one
    deciding least); returns (threshold, :func:`loop_decisions` at every grid value)."""
    rows = [loop_decisions(readings, labels, t, greet) for t in grid]

    def j(row: dict[str, Any]) -> float:
        (a, n), (b, m) = row["greet_clips"], row["other_clips"]
        return a / max(n, 1) - b / max(m, 1)

    best = max(range(len(rows)), key=lambda k: (round(j(rows[k]), 9), grid[k]))
    for row in rows:
        row["youden_j"] = round(j(row), 4)
    return float(grid[best]), rows


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m simenv.perception.loop --subjects train|test``: the loop's decisions on the
    MSR Action3D and UTKinect clips (labelled and ``idle``) of the classifier's training
    or test subjects at every threshold of the grid, and the threshold
    :func:`choose_threshold` picks, as JSON (``--out``) and a table."""
    parser = argparse.ArgumentParser(prog="python -m simenv.perception.loop",
                                     description=main.__doc__.splitlines()[0])
    parser.add_argument("--subjects", choices=("train", "test"), required=True)
    parser.add_argument("--classifier", default=DEFAULT_CLASSIFIER)
    parser.add_argument("--predictor", default="auto")
    parser.add_argument("--data", help="corpus root (default: SIMENV_SHARED_DATA or "
                        "../shared/data)")
    parser.add_argument("--out", help="JSON file for the readings' decisions")
    args = parser.parse_args(argv)
    try:
        clips = load_gesture_clips(shared_data_root(args.data) / "gestures",
                                   datasets=("msr_action3d", "utkinect"), idle=True)
        train, test = split_cross_subject(clips)
        classifier = TrainedClassifier.shipped(args.classifier)
        predictor = load_predictor(args.predictor)
        readings, skipped = loop_readings(train if args.subjects == "train" else test,
                                          classifier, predictor, progress=True)
    except SimenvError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    best, rows = choose_threshold(readings, classifier.labels)
    print("| threshold | decided | decided right | greet on wave | greet on others | "
          "greet on idle | real / predicted | J |")
    for r in rows:
        (a, n), (b, m), (c, k) = r["greet_clips"], r["other_clips"], r["idle_clips"]
        print(f"| {r['threshold']:.2f} | {r['decided']:.3f} | {r['decided_right']:.3f} | "
              f"{a}/{n} | {b}/{m} | {c}/{k} | {r['stages']['real']} / "
              f"{r['stages']['predicted']} | {r['youden_j']:.3f} |")
    print(f"chosen threshold (max J): {best:.2f}; skipped {len(skipped)} clips")
    if args.out:
        Path(args.out).write_text(json.dumps({
            "subjects": args.subjects, "classifier": args.classifier,
            "predictor": getattr(predictor, "name", str(args.predictor)),
            "chosen_threshold": best, "rows": rows, "skipped": skipped,
            "readings": [{"name": r.name, "label": r.label, "subject": r.subject,
                          "p_real": r.p_real.round(4).tolist(),
                          "p_pred": r.p_pred.round(4).tolist()} for r in readings],
            "labels": list(classifier.labels)}, indent=1))
    return 0


__all__ = ["DEFAULT_CLASSIFIER", "DEFAULT_PREDICTOR", "FALLBACK_PREDICTOR", "WINDOW_RULES",
           "CanonicalPredictor", "Decision", "GestureModel", "LoopReading", "Perception",
           "PerceptionLoop", "Stage", "TemplateClassifier", "TrainedClassifier",
           "check_window_rule", "choose_threshold", "decide", "default_classifier", "forecast",
           "loop_decisions", "load_predictor", "loop_readings", "real_stage", "tick_due",
           "vocabulary_map"]


if __name__ == "__main__":
    raise SystemExit(main())

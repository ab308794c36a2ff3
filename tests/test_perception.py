"""Perception loop: template classifier, real / predicted stages, the decision rule."""

from __future__ import annotations

import numpy as np
import pytest

import simenv.models
from simenv.core.errors import SimenvError
from simenv.core.skeletons import CANONICAL_KEYPOINTS
from simenv.data.gestures import GESTURE15_JOINTS, load_gesture_clips, split_cross_subject
from simenv.models.baselines import ConstantVelocity, ZeroVelocity
from simenv.perception.loop import (
    CanonicalPredictor,
    GestureModel,
    PerceptionLoop,
    Stage,
    TemplateClassifier,
    decide,
    tick_due,
)
from simenv.room.scenario import load_scenario

K = len(CANONICAL_KEYPOINTS)


def _standing(T: int) -> np.ndarray:
    """(T, 21, 3) a still person: canonical keypoints of a simple standing layout."""
    base = {"pelvis": (0, 0, 1.0), "spine": (0, 0, 1.12), "chest": (0, 0, 1.3),
            "neck": (0, 0, 1.5), "head": (0, 0, 1.62)}
    for side, y in (("left", 0.18), ("right", -0.18)):
        base |= {f"{side}_shoulder": (0, y, 1.45), f"{side}_elbow": (0, y, 1.17),
                 f"{side}_wrist": (0, y, 0.92), f"{side}_hand": (0, y, 0.84),
                 f"{side}_hip": (0, y / 2, 0.92), f"{side}_knee": (0, y / 2, 0.5),
                 f"{side}_ankle": (0, y / 2, 0.08), f"{side}_toe": (0.12, y / 2, 0.02)}
    pose = np.array([base[k] for k in CANONICAL_KEYPOINTS], dtype=np.float32)
    return np.repeat(pose[None], T, axis=0)


def _waving(T: int) -> np.ndarray:
    """The still person waving the right forearm side to side above the shoulder."""
    x = _standing(T)
    i_e, i_w = CANONICAL_KEYPOINTS.index("right_elbow"), CANONICAL_KEYPOINTS.index("right_wrist")
    swing = 0.15 * np.sin(np.linspace(0, 4 * np.pi, T))
    x[:, i_e] = [0.0, -0.35, 1.5]
    x[:, i_w, 0], x[:, i_w, 1], x[:, i_w, 2] = 0.0, -0.35 + swing, 1.75
    return x


@pytest.fixture(scope="module")
def classifier() -> TemplateClassifier:
    joints = [CANONICAL_KEYPOINTS.index(j) for j in GESTURE15_JOINTS]
    templates = np.stack([_standing(75)[:, joints], _waving(75)[:, joints]])
    return TemplateClassifier(templates, np.ones((2, 75), bool), ["walk", "wave"],
                              length=25, temperature=0.01)


def test_template_classifier_on_synthetic_motion(classifier: TemplateClassifier):
    assert isinstance(classifier, GestureModel)
    joints = [CANONICAL_KEYPOINTS.index(j) for j in GESTURE15_JOINTS]
    wave = _waving(50)[:, joints] + [2.0, 1.0, 0.0]  # elsewhere in the room, slower
    p = classifier.classify(wave, np.ones(50, bool))
    assert p.sum() == pytest.approx(1.0) and classifier.labels[int(np.argmax(p))] == "wave"
    p = classifier.classify(_standing(30)[:, joints], np.ones(30, bool))
    assert classifier.labels[int(np.argmax(p))] == "walk"
    with pytest.raises(SimenvError, match="valid"):
        classifier.classify(wave, np.zeros(50, bool))
    with pytest.raises(SimenvError, match="label"):
        TemplateClassifier(np.zeros((2, 5, 15, 3)), np.ones((2, 5), bool), ["wave"])


def test_decide_takes_the_real_stage_first_then_the_forecast():
    """The room's one decision rule on probabilities whose outcome is known by hand; the
    forecast stage is computed only when the real one is not confident."""
    calls = []

    def forecast_stage() -> np.ndarray:
        calls.append(1)
        return np.array([0.1, 0.7, 0.2])

    real = decide(np.array([0.2, 0.1, 0.7]), forecast_stage, 0.6)
    assert (real.stage, real.index) == (Stage.REAL, 2) and not calls
    ahead = decide(np.array([0.5, 0.3, 0.2]), forecast_stage, 0.6)
    assert (ahead.stage, ahead.index) == (Stage.FORECAST, 1) and len(calls) == 1
    np.testing.assert_array_equal(ahead.probabilities, [0.1, 0.7, 0.2])
    unsure = decide(np.array([0.5, 0.3, 0.2]), np.array([0.4, 0.4, 0.2]), 0.6)
    assert (unsure.stage, unsure.index) == (Stage.NONE, None)
    np.testing.assert_array_equal(unsure.probabilities, [0.4, 0.4, 0.2])  # the forecast's
    blind = decide(np.array([0.5, 0.3, 0.2]), None, 0.6)
    assert blind.stage is Stage.NONE and blind.probabilities.tolist() == [0.5, 0.3, 0.2]
    assert decide(np.array([0.6, 0.4]), None, 0.6).stage is Stage.REAL  # reaching it decides
    assert [s.value for s in Stage] == ["real", "predicted", None]  # as logs name them


def test_ticks_fall_once_a_second_after_the_first():
    assert [f for f in range(80) if tick_due(f)] == [24, 49, 74]
    assert [f for f in range(80) if tick_due(f, first=50)] == [49, 74]


def test_loop_decides_on_real_motion(classifier: TemplateClassifier):
    loop = PerceptionLoop(classifier)
    assert not loop.due(0) and loop.due(24) and not loop.due(25) and loop.due(49)
    assert loop.history_frames == 25
    first = loop.perceive(1.0, _waving(25))
    assert (first.stage, first.label) == (Stage.REAL, "wave")
    assert first.probabilities["wave"] > 0.9 and first.predicted_motion_m == 0.0
    idle = loop.perceive(9.0, _standing(25))
    assert (idle.stage, idle.label) == (Stage.REAL, "walk")
    with pytest.raises(SimenvError, match="history"):
        loop.perceive(0.0, _standing(10))


class _LengthClassifier:
    """Stub: confident about "wave" only when shown more than 25 frames."""

    labels = ("wave", "other")
    joint_names = GESTURE15_JOINTS

    def classify(self, window: np.ndarray, valid: np.ndarray) -> np.ndarray:
        return np.array([0.9, 0.1]) if len(window) > 25 else np.array([0.5, 0.5])


def test_loop_anticipates_with_the_prediction():
    loop = PerceptionLoop(_LengthClassifier(), ConstantVelocity(50))
    out = loop.perceive(1.0, _waving(25))
    assert (out.stage, out.label) == (Stage.FORECAST, "wave")
    assert out.predicted_motion_m > 0.0
    blind = PerceptionLoop(_LengthClassifier()).perceive(1.0, _waving(25))
    assert blind.stage is Stage.NONE and blind.label is None
    # A tick reads its longest window, and the predictor's history when it forecasts.
    assert loop.history_frames == 25 and PerceptionLoop(
        _LengthClassifier(), ConstantVelocity(50), context_frames=(50, 75)).history_frames == 75
    assert PerceptionLoop(_LengthClassifier(), ConstantVelocity(50),
                          real_frames=1).history_frames == ConstantVelocity(50).history_len == 2
    assert PerceptionLoop(_LengthClassifier(), ConstantVelocity(50), real_frames=1,
                          use_forecast=False).history_frames == 1


def test_the_loop_tells_an_observer_aware_predictor_where_the_agent_stands():
    import torch

    from simenv.models.gesture_predictor import GesturePredictor, GesturePredictorConfig

    model = GesturePredictor(GesturePredictorConfig(hidden=16, observer_input=True), seed=0)
    gen = torch.Generator().manual_seed(1)
    with torch.no_grad():  # small random weights: an untrained model is zero velocity
        for p in model.net.parameters():
            p.add_(0.05 * torch.randn(p.shape, generator=gen))
    predictor = CanonicalPredictor(model, joints=GESTURE15_JOINTS, root_relative=False)
    assert predictor.uses_observer and not CanonicalPredictor(ZeroVelocity(3)).uses_observer
    loop = PerceptionLoop(_LengthClassifier(), predictor)
    h = _waving(30)
    near, far, unknown = (loop.perceive(1.2, h, observer=o).predicted_motion_m
                          for o in (np.array([1.0, 0.0, 0.0]), np.array([5.0, 3.0, 0.0]), None))
    assert len({near, far, unknown}) == 3
    # A predictor that does not use an observer is called as before.
    blind = PerceptionLoop(_LengthClassifier(), ConstantVelocity(50))
    assert blind.perceive(1.0, h, observer=np.zeros(3)).stage is Stage.FORECAST


def test_templates_from_real_clips_cross_subject(shared_data):
    """Florence 3D, odd subjects as templates, even subjects classified (3 s windows)."""
    clips = load_gesture_clips(shared_data / "gestures", datasets=("florence3d",))
    train, test = split_cross_subject(clips)
    tc = TemplateClassifier.from_clips(train)
    hits = []
    for c in test:
        spare = max(c.num_frames - 75, 0) // 2
        window = c.positions[spare:spare + 75]
        p = tc.classify(window, np.ones(len(window), bool))
        hits.append(tc.labels[int(np.argmax(p))] == c.label)
    chance = 1.0 / len(tc.labels)
    assert np.mean(hits) > max(0.6, 4 * chance)


def test_canonical_predictor_adapts_a_joint_subset():
    still = CanonicalPredictor(ZeroVelocity(10))
    h = _waving(30)
    out = still.predict(h)
    assert out.shape == (10, K, 3)
    np.testing.assert_allclose(out, np.repeat(h[-1:], 10, axis=0), atol=1e-6)
    # A body gliding +x at 1 cm/frame, forecast in world coordinates on pred17: the hands
    # and toes the predictor lacks ride along with their wrists and ankles.
    glide = _standing(5) + np.arange(5)[:, None, None] * np.array([0.01, 0.0, 0.0])
    moving = CanonicalPredictor(ConstantVelocity(3), root_relative=False).predict(glide)
    hand, wrist = CANONICAL_KEYPOINTS.index("right_hand"), CANONICAL_KEYPOINTS.index(
        "right_wrist")
    np.testing.assert_allclose(moving[:, wrist, 0], glide[-1, wrist, 0] + [0.01, 0.02, 0.03],
                               atol=1e-6)
    np.testing.assert_allclose(moving[:, hand] - moving[:, wrist],
                               np.repeat((glide[-1, hand] - glide[-1, wrist])[None], 3, 0),
                               atol=1e-6)
    with pytest.raises(SimenvError, match="canonical"):
        CanonicalPredictor(ZeroVelocity(3), joints=("pelvis", "tail"))


@pytest.mark.skipif("predictor-25-25" not in simenv.models.available(),
                    reason="shipped predictor checkpoint absent")
def test_loop_with_the_shipped_predictor():
    predictor = CanonicalPredictor(simenv.models.load("predictor-25-25"))
    loop = PerceptionLoop(_LengthClassifier(), predictor)
    out = loop.perceive(1.2, _waving(30))
    assert (out.stage, out.label) == (Stage.FORECAST, "wave")
    assert np.isfinite(out.predicted_motion_m)


# -- the shipped models as the loop's stages --------------------------------------------

shipped = pytest.mark.skipif(
    not {"gesture-classifier", "predictor-25-50", "gesture-tcn", "predictor-gesture-25-50"}
    <= set(simenv.models.available()),
    reason="shipped gesture-classifier / predictor-25-50 / gesture-tcn / "
           "predictor-gesture-25-50 absent")


def test_vocabulary_map_reads_labels_in_a_scenario():
    from simenv.data.gestures import GESTURE_LABELS
    from simenv.perception.loop import vocabulary_map

    default = vocabulary_map(GESTURE_LABELS, load_scenario("default").behaviour.vocabulary)
    assert all(k == v for k, v in default.items())
    discomfort = vocabulary_map(GESTURE_LABELS, load_scenario("discomfort").behaviour.vocabulary)
    assert discomfort["wave"] == "hello"
    assert {v for k, v in discomfort.items() if k != "wave"} == {"idle"}


@shipped
def test_trained_classifier_adapter_pads_truncates_and_maps(shared_data):
    """On a real MSR Action3D wave: the adapter's probabilities are the network's on the
    window padded to 75 frames (padding invalid), or on the last 75 frames of a longer
    one; mapped onto the discomfort vocabulary they sum onto hello / idle."""
    from simenv.data.gestures import load_gesture_clips
    from simenv.perception.loop import TrainedClassifier

    clips = load_gesture_clips(shared_data / "gestures", datasets=("msr_action3d",))
    wave = next(c for c in clips if c.label == "wave" and c.num_frames >= 40)
    adapter = TrainedClassifier.shipped("gesture-classifier")
    assert isinstance(adapter, GestureModel) and adapter.joint_names == GESTURE15_JOINTS
    assert adapter.labels == adapter.model.config.labels
    short = wave.positions[:25]
    padded = np.concatenate([short, np.repeat(short[-1:], 50, axis=0)])
    valid = np.arange(75) < 25
    p = adapter.classify(short, np.ones(25, bool))
    np.testing.assert_allclose(p, adapter.model.classify_world(padded, valid), atol=1e-6)
    assert p.sum() == pytest.approx(1.0, abs=1e-5)
    long = np.concatenate([np.repeat(wave.positions[:1], 40, axis=0), padded])
    long_valid = np.concatenate([np.ones(40, bool), valid])
    np.testing.assert_allclose(adapter.classify(long, long_valid), p, atol=1e-6)
    mapped = TrainedClassifier.shipped("gesture-classifier",
                                       vocabulary=load_scenario("discomfort").behaviour.vocabulary)
    assert set(mapped.labels) == {"hello", "idle"}
    q = dict(zip(mapped.labels, mapped.classify(short, np.ones(25, bool)), strict=True))
    assert q["hello"] == pytest.approx(p[adapter.labels.index("wave")], abs=1e-6)
    assert q["idle"] == pytest.approx(1.0 - q["hello"], abs=1e-5)
    with pytest.raises(SimenvError, match="label_map"):
        TrainedClassifier(adapter.model, {"cold": "hello"})
    with pytest.raises(SimenvError, match="window"):
        adapter.classify(short[:, :9], np.ones(25, bool))


@shipped
def test_ensemble_averages_the_members_temperature_scaled_logits(shared_data):
    """On a real UTKinect wave: the shipped TCN twice gives its probabilities once; with a
    second member of other output biases and twice the temperature, the ensemble is
    softmax of the mean of z_m / tau_m (the class docstring's math), also mapped onto a
    scenario's vocabulary; members that classify differently are refused."""
    import copy
    import dataclasses

    import torch

    from simenv.data.gestures import normalise_windows
    from simenv.perception.loop import TrainedClassifier

    clips = load_gesture_clips(shared_data / "gestures", datasets=("utkinect",))
    wave = next(c for c in clips if c.label == "wave" and c.num_frames >= 50)
    x, v = wave.positions[:50].astype(np.float32), np.ones(50, bool)
    one = TrainedClassifier.shipped("gesture-tcn")
    twice = TrainedClassifier.shipped(["gesture-tcn", "gesture-tcn"])
    assert len(twice.members) == 2 and twice.name == "gesture-tcn+gesture-tcn"
    assert (twice.threshold, twice.loop_windows) == (one.threshold, one.loop_windows)
    p = one.classify(x, v)
    np.testing.assert_allclose(p, one.model.classify_world(x, v), atol=1e-6)
    np.testing.assert_allclose(twice.classify(x, v), p, atol=1e-6)
    other = copy.deepcopy(one.model)
    other.config = dataclasses.replace(other.config, temperature=2 * one.model.config.temperature)
    with torch.no_grad():
        other.out.bias += torch.linspace(-1.0, 1.0, len(other.config.labels))
    ensemble = TrainedClassifier([one.model, other])
    w = torch.as_tensor(normalise_windows(x[None], v[None], joints=GESTURE15_JOINTS))
    with torch.no_grad():
        z = np.mean([m(w, torch.as_tensor(v[None]))[0].numpy() / m.config.temperature
                     for m in (one.model, other)], axis=0)
    expected = np.exp(z - z.max()) / np.exp(z - z.max()).sum()
    q = ensemble.classify(x, v)
    np.testing.assert_allclose(q, expected, atol=1e-6)
    assert np.abs(q - p).max() > 1e-3  # a different member changes the answer
    vocab = load_scenario("discomfort").behaviour.vocabulary
    mapped = TrainedClassifier.shipped(["gesture-tcn", "gesture-tcn"], vocab)
    hello = dict(zip(mapped.labels, mapped.classify(x, v), strict=True))["hello"]
    assert hello == pytest.approx(p[one.labels.index("wave")], abs=1e-6)
    with pytest.raises(SimenvError, match="member 1"):
        TrainedClassifier([one.model, simenv.models.load("gesture-classifier")])
    with pytest.raises(SimenvError, match="at least one member"):
        TrainedClassifier([])


@shipped
def test_shipped_models_are_the_defaults(monkeypatch, tmp_path):
    from simenv.perception.loop import (
        TrainedClassifier,
        default_classifier,
        load_predictor,
    )

    predictor = load_predictor()
    assert isinstance(predictor, CanonicalPredictor)
    assert predictor.name == "predictor-gesture-25-50"
    assert (predictor.history_len, predictor.future_len) == (25, 50)
    future = predictor.predict(_waving(25))
    assert future.shape == (50, K, 3) and np.isfinite(future).all()
    assert isinstance(load_predictor("constant-velocity-50"), ConstantVelocity)
    assert load_predictor("predictor-25-25").future_len == 25
    vocab = load_scenario("default").behaviour.vocabulary
    classifier = default_classifier(vocab, data=tmp_path)  # no corpus needed
    assert isinstance(classifier, TrainedClassifier)
    assert classifier.name == "gesture-tcn-ensemble"
    loop = PerceptionLoop(classifier, predictor)
    # the threshold, windows and forecast use its training chose on held-out subjects
    assert loop.threshold == classifier.model.metadata["loop_threshold"]
    assert loop.use_forecast == classifier.model.metadata["loop_uses_forecast"]
    assert (loop.real_frames, *loop.context_frames) == tuple(
        classifier.model.metadata.get("loop_windows", (25,)))
    assert loop.window_rule == classifier.model.metadata.get("loop_window_rule", "max")
    # A window rule the classifier was not measured with can be asked for; a made-up one not.
    other = "max" if loop.window_rule == "mean" else "mean"
    assert PerceptionLoop(classifier, window_rule=other).window_rule == other
    with pytest.raises(SimenvError, match="window rule 'median'"):
        PerceptionLoop(classifier, window_rule="median")
    # Nothing shipped and no corpus: a clear error naming where to point.
    monkeypatch.setattr(simenv.models, "available", lambda: [])
    assert isinstance(load_predictor(), ConstantVelocity)
    with pytest.raises(SimenvError, match="SIMENV_SHARED_DATA"):
        default_classifier(vocab, data=tmp_path)


def test_template_fallback_without_shipped_classifier(monkeypatch, shared_data):
    from simenv.perception.loop import default_classifier

    monkeypatch.setattr(simenv.models, "available", lambda: [])
    vocab = load_scenario("discomfort").behaviour.vocabulary
    classifier = default_classifier(vocab, data=shared_data)
    assert isinstance(classifier, TemplateClassifier)
    assert set(classifier.labels) == {"hello", "idle"}


@shipped
def test_loop_on_a_real_wave_with_the_shipped_models(shared_data):
    """Test subject 2 of UTKinect retargeted into the room, through the loop with the
    shipped classifier, predictor and threshold: the 1 s of real motion of its waveHands
    segment reads wave and the loop greets on the real stage; its idle stretches (near
    still, unlabelled) read idle on both stages, and nothing is greeted."""
    from simenv.data.gestures import load_gesture_clips
    from simenv.perception.loop import TrainedClassifier, load_predictor, loop_readings

    clips = load_gesture_clips(shared_data / "gestures", datasets=("utkinect",), idle=True)
    s02 = [c for c in clips if c.name.startswith("joints_s02_e01")
           and c.label in ("wave", "idle")]
    assert {c.label for c in s02} == {"wave", "idle"}
    classifier = TrainedClassifier.shipped()
    readings, _ = loop_readings(s02, classifier, load_predictor())
    loop = PerceptionLoop(classifier, load_predictor())
    for r in readings:
        top_real = classifier.labels[int(np.argmax(r.p_real))]
        top_pred = classifier.labels[int(np.argmax(r.p_pred))]
        assert top_real == top_pred == r.label
        assert r.p_real.max() >= loop.threshold  # decided on real motion
    wave = next(c for c in s02 if c.label == "wave")
    from simenv.room.session import Session, user_track

    kp = user_track(Session(wave.source)).keypoints.astype(np.float32)
    tick = loop.perceive(1.04, kp[:26])
    assert (tick.stage, tick.label) == (Stage.REAL, "wave")


# -- the loop measured on clips ------------------------------------------------------------


def _reading(label: str, p_real, p_pred):
    from simenv.perception.loop import LoopReading

    return LoopReading(f"clip-{label}", label, "x/s01", np.array(p_real), np.array(p_pred))


def test_loop_decisions_and_threshold_choice_on_known_readings():
    """Three readings whose decisions at each threshold are known by hand: the real stage
    wins when confident, else the predicted stage, else nothing."""
    from simenv.perception.loop import choose_threshold, loop_decisions

    labels = ("wave", "other", "idle")
    readings = [_reading("wave", [0.2, 0.5, 0.3], [0.6, 0.2, 0.2]),
                _reading("idle", [0.1, 0.2, 0.7], [0.5, 0.1, 0.4]),
                _reading("other", [0.3, 0.4, 0.3], [0.45, 0.45, 0.1])]
    low = loop_decisions(readings, labels, 0.45)
    # wave: real stage reads other; idle: real reads idle; other: predicted reads wave.
    assert low["greet_clips"] == [0, 1] and low["other_clips"] == [1, 2]
    assert low["idle_clips"] == [0, 1]
    assert low["stages"] == {"real": 2, "predicted": 1}
    assert low["decided_right"] == round(1 / 3, 4)  # only idle is right
    high = loop_decisions(readings, labels, 0.55)
    # wave: predicted 0.6 -> greet; idle: real 0.7 -> idle; other: nothing reaches 0.55.
    assert high["greet_clips"] == [1, 1] and high["other_clips"] == [0, 2]
    assert high["decided"] == round(2 / 3, 4) and high["decided_right"] == 1.0
    best, rows = choose_threshold(readings, labels, grid=(0.45, 0.55, 0.65))
    assert best == 0.55 and [r["youden_j"] for r in rows] == [-0.5, 1.0, 0.0]
    # A tie goes to the higher threshold (fewer decisions).
    tie, _ = choose_threshold(readings[1:], labels, grid=(0.65, 0.75))
    assert tie == 0.75


@shipped
def test_loop_readings_on_real_clips(shared_data):
    """Real MSR clips of a training subject (a wave and an idle lead-in) and a Florence clip
    (no pelvis joint: retargeted with the hips' midpoint as its pelvis, noted in the
    retargeting's repairs) retargeted into the room: each gives both stages'
    probabilities; the Florence clip with its left hip unmapped is skipped with the
    reason."""
    from dataclasses import replace

    from simenv.core.skeletons import Skeleton
    from simenv.data.gestures import load_gesture_clips
    from simenv.perception.loop import TrainedClassifier, load_predictor, loop_readings
    from simenv.room.session import Session, user_track

    root = shared_data / "gestures"
    msr = load_gesture_clips(root, datasets=("msr_action3d",), idle=True)
    wave = next(c for c in msr if c.label == "wave" and c.subject == 1)
    idle = next(c for c in msr if c.label == "idle" and c.subject == 1)
    florence = load_gesture_clips(root, datasets=("florence3d",))[0]
    sk = florence.source.skeleton
    one_hip = replace(florence, name="one hip", source=replace(florence.source, skeleton=Skeleton(
        sk.name, sk.joint_names, sk.parents,
        {k: j for k, j in sk.canonical.items() if k != "left_hip"})))
    classifier = TrainedClassifier.shipped()
    readings, skipped = loop_readings([wave, idle, florence, one_hip], classifier,
                                      load_predictor())
    assert [r.name for r in readings] == [wave.name, idle.name, florence.name]
    assert len(skipped) == 1 and skipped[0].startswith("one hip: ")
    assert "['pelvis', 'left_hip']" in skipped[0]
    (note,) = user_track(Session(florence.source)).result.repairs
    assert "midpoint of LeftHip and RightHip" in note
    for r in readings:
        assert r.p_real.shape == r.p_pred.shape == (len(classifier.labels),)
        assert r.p_real.sum() == pytest.approx(1.0, abs=1e-5)
        assert r.p_pred.sum() == pytest.approx(1.0, abs=1e-5)
        assert not np.allclose(r.p_real, r.p_pred)  # the forecast changes the reading

"""The perception loop streamed on clips: ticks, decisions, thresholds, folds."""

from __future__ import annotations

import numpy as np
import pytest

from simenv.data.gestures import GESTURE15_JOINTS, GESTURE_LABELS, subject_fold
from simenv.perception.protocol import (
    TICK_FRAMES,
    StreamReading,
    choose_threshold,
    cross_fitted_outcomes,
    loop_outcomes,
    tick_frames,
)

WAVE, IDLE, OTHER = (GESTURE_LABELS.index(k) for k in ("wave", "idle", "other"))


def _reading(label: str, subject: str, wave_logit: float, duration: float = 2.0,
             ticks: int = 2, pred_logit: float | None = None) -> StreamReading:
    z = np.zeros((ticks, len(GESTURE_LABELS)))
    z[:, WAVE] = wave_logit
    zp = np.zeros_like(z)
    zp[:, WAVE] = wave_logit if pred_logit is None else pred_logit
    return StreamReading(f"{label}-{subject}", label, subject, "msr_action3d", duration,
                         (np.arange(ticks) + 1.0) * 1.0, z[:, None], zp)


def test_tick_frames_cover_the_clip_once_past_its_end():
    assert tick_frames(60, 0).tolist() == [1, 26, 51, 76]
    assert tick_frames(10, 24).tolist() == [25]
    assert all(np.diff(tick_frames(200, 7)) == TICK_FRAMES)


def test_outcomes_count_greetings_per_group():
    readings = [_reading("wave", "msr/s01", 5.0), _reading("wave", "msr/s02", 0.0),
                _reading("other", "msr/s01", 5.0), _reading("idle", "msr/s03", 0.0)]
    row = loop_outcomes(readings, GESTURE_LABELS, 0.5, use_forecast=False)
    assert row["greet_clips"] == [1, 2] and row["other_clips"] == [1, 1]
    assert row["idle_clips"] == [0, 1]
    assert row["decision_after_onset_s"]["median"] == 1.0 and row["decided_before_end"] == 1.0
    # a strong forecast stage greets the wave the real stage missed
    readings[1] = _reading("wave", "msr/s02", 0.0, pred_logit=6.0)
    row = loop_outcomes(readings, GESTURE_LABELS, 0.5, use_forecast=True)
    assert row["greet_clips"] == [2, 2] and row["stages"] == {"real": 1, "predicted": 1}


def test_the_most_confident_real_window_decides():
    r = _reading("wave", "msr/s01", 0.0)
    z = np.repeat(r.logits_real, 2, axis=1)
    z[:, 1, WAVE] = 6.0  # the longer window sees the wave
    two = StreamReading(r.name, r.label, r.subject, r.dataset, r.duration_s, r.ticks_s, z,
                        r.logits_pred)
    assert loop_outcomes([r], GESTURE_LABELS, 0.5, use_forecast=False)["greet_clips"] == [0, 1]
    assert loop_outcomes([two], GESTURE_LABELS, 0.5, use_forecast=False)["greet_clips"] == [1, 1]


def test_the_mean_rule_averages_the_real_windows():
    """Two windows, one sure of a wave (logit 6), one not (logit 0): the max rule greets at
    0.8, the mean rule reads their average wave probability and does not."""
    r = _reading("wave", "msr/s01", 0.0)
    z = np.repeat(r.logits_real, 2, axis=1)
    z[:, 1, WAVE] = 6.0
    two = StreamReading(r.name, r.label, r.subject, r.dataset, r.duration_s, r.ticks_s, z,
                        r.logits_pred)
    e = np.exp(z[0])
    mean_wave = float((e[:, WAVE] / e.sum(axis=1)).mean())
    assert 0.5 < mean_wave < 0.8
    for rule, greeted in (("max", 1), ("mean", 0)):
        row = loop_outcomes([two], GESTURE_LABELS, 0.8, use_forecast=False, window_rule=rule)
        assert row["greet_clips"] == [greeted, 1] and row["window_rule"] == rule
    row = loop_outcomes([two], GESTURE_LABELS, mean_wave - 1e-6, use_forecast=False,
                        window_rule="mean")
    assert row["greet_clips"] == [1, 1]


def test_real_stage_rules():
    from simenv.core.errors import SimenvError
    from simenv.perception.loop import real_stage

    p = np.array([[[0.5, 0.3, 0.2], [0.1, 0.8, 0.1], [0.2, 0.2, 0.6]],
                  [[0.9, 0.05, 0.05], [0.9, 0.05, 0.05], [0.4, 0.4, 0.2]]])  # (2, 3 windows, 3)
    np.testing.assert_allclose(real_stage(p, "max"), [p[0, 1], p[1, 0]])  # ties: the first
    np.testing.assert_allclose(real_stage(p, "mean"), p.mean(axis=1))
    np.testing.assert_allclose(real_stage(p[0], "max"), p[0, 1])  # one tick, no leading axis
    with pytest.raises(SimenvError, match="window rule"):
        real_stage(p, "median")
    with pytest.raises(SimenvError, match="W >= 1"):
        real_stage(np.zeros((2, 0, 3)), "mean")


def test_threshold_keeps_false_greetings_under_target():
    readings = [_reading("wave", f"utkinect/s0{i}", 3.0 + i) for i in range(1, 6)]
    readings += [_reading("other", f"utkinect/s0{i}", 2.0 + 0.3 * i) for i in range(1, 6)]
    t = choose_threshold(readings, GESTURE_LABELS, use_forecast=False, target=0.0)
    row = loop_outcomes(readings, GESTURE_LABELS, t, use_forecast=False)
    assert row["other_clips"][0] == 0 and row["greet_clips"][0] >= 3


def test_cross_fitting_never_uses_the_held_out_fold():
    """Fold 0's threshold is chosen on folds 1-4 only: making fold 0's own non-waves look
    like waves must not move it."""
    base = [_reading(lab, f"utkinect/s{s:02d}", w)
            for s in range(1, 11) for lab, w in (("wave", 4.0), ("other", 1.0))]
    a = cross_fitted_outcomes(base, subject_fold, GESTURE_LABELS, [1.0] * 5, use_forecast=False)
    moved = [_reading(r.label, r.subject, 4.0) if subject_fold(r.subject) == 0 else r
             for r in base]
    b = cross_fitted_outcomes(moved, subject_fold, GESTURE_LABELS, [1.0] * 5,
                              use_forecast=False)
    assert a["folds"][0]["threshold"] == b["folds"][0]["threshold"]
    assert b["folds"][0]["other_clips"][0] > a["folds"][0]["other_clips"][0]
    assert a["window_rule"] == "max"
    assert cross_fitted_outcomes(base, subject_fold, GESTURE_LABELS, [1.0] * 5,
                                 use_forecast=False, window_rule="mean")["window_rule"] == "mean"


def test_avatar_clips_and_stream_readings_on_real_sessions(utkinect_clips):
    """Two real UTKinect segments retargeted into the room: gesture15 keypoints of the
    avatar, then one reading per clip with a tick per second past its end."""
    import torch

    from simenv.data.gestures import gesture_skeleton
    from simenv.models.skeleton_tcn import SkeletonTCN, TCNConfig
    from simenv.perception.protocol import avatar_clips, stream_readings

    wave = next(c for c in utkinect_clips if c.label == "wave")
    walk = next(c for c in utkinect_clips if c.label == "walk")
    avatars, skipped = avatar_clips([wave, walk], progress=False)
    assert not skipped and [a.label for a in avatars] == ["wave", "walk"]
    assert avatars[0].positions.shape == (wave.num_frames, 15, 3)
    # the avatar's hands follow the recording's: wrist paths correlate
    hand = GESTURE15_JOINTS.index("right_wrist")
    r = np.corrcoef(np.linalg.norm(np.diff(avatars[0].positions[:, hand], axis=0), axis=1),
                    np.linalg.norm(np.diff(wave.positions[:, hand], axis=0), axis=1))[0, 1]
    assert r > 0.5
    skel = gesture_skeleton("gesture15")
    torch.manual_seed(0)
    net = SkeletonTCN(TCNConfig(skel.joint_names, skel.parents, GESTURE_LABELS)).eval()
    readings = stream_readings(avatars, net, lambda h: np.repeat(h[:, -1:], 50, axis=1),
                               real_windows=(25, 50))
    for reading, clip in zip(readings, avatars, strict=True):
        duration = clip.num_frames / 25.0
        assert reading.ticks_s[-1] >= duration
        assert len(reading.ticks_s) == 1 or reading.ticks_s[-2] < duration
        assert reading.logits_real.shape == (len(reading.ticks_s), 2, len(GESTURE_LABELS))
        assert reading.logits_pred.shape == (len(reading.ticks_s), len(GESTURE_LABELS))
        assert np.isfinite(reading.logits_pred).all()

"""The hand-written wave rule on real recordings of the shared corpus, as the avatar reads
them (simenv.perception.wave_rule)."""

from __future__ import annotations

import numpy as np
import pytest

from simenv.core.errors import SimenvError
from simenv.perception.protocol import TICK_FRAMES, tick_frames
from simenv.perception.wave_rule import (
    WaveRule,
    half_swings,
    read_window,
    rule_outcomes,
    stream_fires,
)


@pytest.fixture(scope="module")
def session(utkinect_clips):
    """Every action of UTKinect person s01's first session, retargeted onto the avatar."""
    from simenv.perception.protocol import avatar_clips

    clips = [c for c in utkinect_clips if c.subject == 1 and "_e01_" in c.name]
    avatars, skipped = avatar_clips(clips, progress=False)
    assert not skipped
    return avatars


def _fires(clip) -> bool:
    """Whether the default rule fires on any window of ``clip`` (one ending at every frame,
    the first pose held before the clip, as the loop reads it)."""
    rule = WaveRule()
    w = rule.window_frames
    p = np.concatenate([np.repeat(clip.positions[:1], w, axis=0), clip.positions])
    return any(read_window(p[e:e + w], rule).fired for e in range(1, clip.num_frames + 1))


def test_a_real_wave_fires_and_the_same_persons_other_actions_do_not(session):
    wave = [c for c in session if c.label == "wave"]
    others = [c for c in session if c.label != "wave"]
    assert len(wave) == 1 and len(others) >= 8
    assert _fires(wave[0])
    assert [c.source_label for c in others if _fires(c)] == []


def test_the_waving_hand_swings_above_its_shoulder(session):
    """On the wave's most active window, the kept half-swings are raised and sideways;
    asking for more reversals than the window holds silences the rule."""
    wave = next(c for c in session if c.label == "wave")
    rule = WaveRule()
    w = rule.window_frames
    windows = [wave.positions[e - w:e] for e in range(w, wave.num_frames + 1, 5)]
    best = max(windows, key=lambda x: max(read_window(x, rule).reversals.values()))
    reading = read_window(best, rule)
    assert reading.fired and max(reading.reversals.values()) >= rule.reversals
    assert 0.2 < reading.body_size_m < 0.6  # a shoulder width, m
    legs = half_swings(best, rule.swing, rule.smooth_frames)
    assert (legs.sideways >= rule.swing).all()
    assert (legs.low >= rule.raise_height).sum() >= rule.reversals
    strict = WaveRule(reversals=max(reading.reversals.values()) + 1)
    assert not read_window(best, strict).fired


def test_reading_is_invariant_to_body_size_and_heading(session):
    """Scaled about the floor (a child) and turned about the vertical, the same motion
    gives the same half-swings: the rule works in the body's own frame and size."""
    wave = next(c for c in session if c.label == "wave")
    w = WaveRule().window_frames
    window = wave.positions[-w:].astype(np.float64)
    a = half_swings(window, 0.3)
    c, s = np.cos(2.0), np.sin(2.0)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    b = half_swings(0.6 * window @ turn.T + np.array([1.0, -2.0, 0.0]), 0.3)
    assert len(a.hand) == len(b.hand) > 0
    np.testing.assert_allclose(b.sideways, a.sideways, rtol=1e-6)
    np.testing.assert_allclose(b.low, a.low, atol=1e-9)
    assert b.body_size_m == pytest.approx(0.6 * a.body_size_m)


def test_stream_ticks_are_the_loops(session):
    """The rule is read at the loop's ticks (protocol.tick_frames, seeded phases), and the
    outcome counts follow from the ticks that fired."""
    rules = [WaveRule(), WaveRule(reversals=1, swing=0.15, raise_height=-0.5, max_rise=2.0)]
    fires = stream_fires(session, rules, seed=3)
    rng = np.random.default_rng(3)
    for clip, (ticks_s, fired) in zip(session, fires[0], strict=True):
        ends = tick_frames(clip.num_frames, int(rng.integers(0, TICK_FRAMES)))
        np.testing.assert_allclose(ticks_s, ends / TICK_FRAMES)
        assert fired.shape == ticks_s.shape
    strict, lax = (rule_outcomes(session, f) for f in fires)
    for row, f in ((strict, fires[0]), (lax, fires[1])):
        greeted = [bool(fired.any()) for _, fired in f]
        assert row["greet_clips"] == [sum(g for g, c in zip(greeted, session, strict=True)
                                          if c.label == "wave"), 1]
        assert row["other_clips"][0] + row["greet_clips"][0] + row["idle_clips"][0] \
            == sum(greeted)
    # A laxer rule greets at least every clip the strict one greets.
    for g in ("greet_clips", "other_clips", "idle_clips"):
        assert lax[g][0] >= strict[g][0] and lax[g][1] == strict[g][1]
    wave = next(i for i, c in enumerate(session) if c.label == "wave")
    ticks_s, fired = fires[1][wave]
    assert fired.any()
    assert lax["decision_after_onset_s"]["median"] == pytest.approx(ticks_s[fired][0])


def test_bad_input_gets_a_clear_error(session):
    window = session[0].positions[:50].astype(np.float64)
    bad = window.copy()
    bad[7, 5, 2] = np.nan
    with pytest.raises(SimenvError, match="NaN") as err:
        read_window(bad)
    assert err.value.frame == 7
    with pytest.raises(SimenvError, match="at least 5 frames"):
        read_window(window[:4])
    with pytest.raises(SimenvError, match=r"\(T, 15, 3\)"):
        read_window(np.zeros((50, 21, 3)))
    with pytest.raises(SimenvError, match="no body frame"):
        read_window(np.zeros((50, 15, 3)))
    with pytest.raises(SimenvError, match="min_hz"):
        WaveRule(min_hz=3.0, max_hz=0.4)
    with pytest.raises(SimenvError, match="fps"):
        stream_fires(session[:1], [WaveRule(fps=30.0)])

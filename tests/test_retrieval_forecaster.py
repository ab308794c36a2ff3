"""The nearest-neighbour forecaster on real Kinect recordings: retrieval, frames, errors."""

from __future__ import annotations

import numpy as np
import pytest

from simenv.core.errors import MotionError
from simenv.data.prediction_metrics import per_frame_mpjpe_mm
from simenv.models.retrieval_forecaster import NearestNeighbourForecaster


@pytest.fixture(scope="module")
def windows(shared_data, gesture_root):
    """(bank, held-out) 75-frame windows: Kinect subjects of folds 1-4, and of fold 0."""
    from simenv.learning.train_gesture_predictor import eval_windows, load_sequences

    recordings = load_sequences(shared_data, cmu=False)
    bank, _ = eval_windows([r for r in recordings if r.fold != 0])
    held, _ = eval_windows([r for r in recordings if r.fold == 0], stride=25)
    return bank.astype(np.float64), held.astype(np.float64)


def _yaw(x: np.ndarray, angle: float, shift: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return x @ rot.T + shift


def test_a_recorded_history_retrieves_its_own_future(windows) -> None:
    bank, _ = windows
    f = NearestNeighbourForecaster(bank, 25)
    assert f.bank_size == len(bank) and f.future_len == 50
    picks = [0, len(bank) // 2, len(bank) - 1]
    index, dist = f.neighbours(bank[picks, :25])
    np.testing.assert_array_equal(index[:, 0], picks)
    np.testing.assert_allclose(dist[:, 0], 0.0, atol=1e-3)
    np.testing.assert_allclose(f.predict(bank[picks, :25]), bank[picks, 25:], atol=1e-4)


def test_forecasts_turn_and_move_with_the_person(windows) -> None:
    bank, held = windows
    f = NearestNeighbourForecaster(bank, 25, k=5)
    history = held[:8, :25]
    shift = np.array([1.5, -0.7, 0.0])
    turned = f.predict(_yaw(history, 1.2, shift))
    np.testing.assert_allclose(turned, _yaw(f.predict(history), 1.2, shift), atol=1e-4)
    single = f.predict(history[0])  # one (H, J, 3) history: one (F, J, 3) forecast
    np.testing.assert_allclose(single, f.predict(history)[0], atol=1e-6)


def test_averaged_neighbours_beat_zero_velocity_on_unseen_subjects(windows) -> None:
    bank, held = windows
    future = held[:, 25:]
    still = np.repeat(held[:, 24:25], 50, axis=1)
    zero = per_frame_mpjpe_mm(still, future)[24]
    mean20 = per_frame_mpjpe_mm(NearestNeighbourForecaster(bank, 25, k=20)
                                .predict(held[:, :25]).astype(np.float64), future)[24]
    nearest = per_frame_mpjpe_mm(NearestNeighbourForecaster(bank, 25)
                                 .predict(held[:, :25]).astype(np.float64), future)[24]
    assert mean20 < zero  # at 1 s, on subjects outside the bank
    assert mean20 < nearest  # one neighbour's future is as often another person's habit


def test_bad_input_is_named(windows) -> None:
    bank, held = windows
    with pytest.raises(MotionError, match="bank windows"):
        NearestNeighbourForecaster(bank[:0], 25)
    with pytest.raises(MotionError, match="history_len"):
        NearestNeighbourForecaster(bank[:5], 75)
    with pytest.raises(MotionError, match="k must be"):
        NearestNeighbourForecaster(bank[:5], 25, k=6)
    broken = bank[:5].copy()
    broken[3, 10, 2, 1] = np.nan
    with pytest.raises(MotionError, match="bank window 3") as err:
        NearestNeighbourForecaster(broken, 25)
    assert err.value.frame == 10
    f = NearestNeighbourForecaster(bank[:50], 25)
    with pytest.raises(MotionError, match="needs at least 25"):
        f.predict(held[:2, :10])
    with pytest.raises(MotionError, match="gesture15"):
        f.predict(np.zeros((2, 25, 17, 3)))
    nan = held[:2, :25].copy()
    nan[1, 4, 0, 0] = np.inf
    with pytest.raises(MotionError, match="window 1"):
        f.predict(nan)

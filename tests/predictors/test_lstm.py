"""TF+LSTM internals: features, sequence windows, progress, constructor checks."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from fricbench.predictors.features import feature_names, reference_features
from fricbench.predictors.lstm import TFLSTMPredictor, _window_starts
from fricbench.trajectories import make_trajectory


def test_window_starts_tile_the_scored_part_once() -> None:
    for n, window, burn in [(1000, 300, 100), (300, 300, 100), (1234, 200, 0), (999, 250, 249)]:
        covered = np.zeros(n, dtype=int)
        for s in _window_starts(n, window, burn):
            assert 0 <= s and s + window <= n
            covered[s + burn:s + window] += 1
        covered[:burn] += 1  # the first window's warm-up is the padded rest
        assert covered.min() >= 1


def test_physical_features() -> None:
    ref = make_trajectory("m_serial")
    f = reference_features(ref.x, ref.ts, "physical", 2e-3)
    names = feature_names("physical")
    assert f.shape == (ref.n_samples, len(names))
    col = {n: f[:, i] for i, n in enumerate(names)}
    assert set(np.unique(col["direction"])) <= {-1.0, 0.0, 1.0}
    assert np.all(col["time_since_turn"] >= 0) and np.all(col["time_since_turn"] <= 0.3)
    assert np.all(col["disp_since_turn"] >= 0) and np.all(col["disp_since_turn"] <= 1e-3)
    # during a dwell the direction of the last motion is remembered
    v = np.gradient(ref.x, ref.ts)
    rest = np.flatnonzero(np.abs(v) < 1e-9)
    rest = rest[rest > 100]
    assert np.all(col["direction"][rest] != 0.0)
    assert reference_features(ref.x, ref.ts, "va", 2e-3).shape == (ref.n_samples, 3)
    with pytest.raises(ValueError, match="features"):
        feature_names("jerk")


def test_training_prints_progress_and_restores_torch_settings(small_runs, capsys) -> None:
    threads = torch.get_num_threads()
    pred = TFLSTMPredictor(max_epochs=3, hidden_size=4, window=300, burn_in=100, verbose=1,
                           n_threads=1).fit(small_runs)
    out = capsys.readouterr().out
    assert "v_break" in out and "epoch    1" in out and "done" in out
    assert torch.get_num_threads() == threads
    assert len(pred.history_) == pred.n_epochs_ <= 3
    assert pred.train_seconds_ > 0
    assert 0.5e-3 < pred.v_break_ < 5e-3


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"features": "jerk"}, "features"),
        ({"target": "all"}, "target"),
        ({"cell": "rnn"}, "cell"),
        ({"hidden_size": 0}, "hidden_size"),
        ({"window": 100, "burn_in": 100}, "burn_in"),
        ({"validation_fraction": 0.9}, "validation_fraction"),
        ({"n_poles": 2, "n_zeros": 2}, "n_zeros"),
        ({"learning_rate": -1.0}, "learning_rate"),
    ],
)
def test_constructor_rejects_bad_arguments(kwargs: dict, match: str) -> None:
    with pytest.raises((ValueError, TypeError), match=match):
        TFLSTMPredictor(**kwargs)
    with pytest.raises(TypeError):
        TFLSTMPredictor(hiden_size=8)  # type: ignore[call-arg]  # typos are not swallowed

"""TF+LSTM internals: features, sequence windows, progress, constructor checks."""

from __future__ import annotations

import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import torch

from fricbench.predictors.features import feature_names, reference_features
from fricbench.predictors.lstm import TFLSTMPredictor, _windows
from fricbench.trajectories import make_trajectory


@pytest.mark.parametrize(("n", "window", "burn", "lead"),
                         [(1000, 300, 100, 10), (300, 300, 100, 10), (1234, 200, 0, 0),
                          (999, 250, 249, 5), (1300, 300, 100, 100), (120, 300, 100, 10),
                          (1100, 300, 100, 0)])
def test_windows_tile_the_record_exactly_once(n: int, window: int, burn: int,
                                              lead: int) -> None:
    cuts = _windows(n, window, burn, lead)
    assert cuts[0] == (0, lead)  # the record's start is the first window's start
    covered = np.zeros(n, dtype=int)
    for s, first in cuts:
        length = min(n, window)
        assert 0 <= s and s + length <= n
        assert first >= (lead if s == 0 else burn)  # later windows warm up first
        covered[s + first:s + length] += 1
    assert np.all(covered[lead:] == 1) and np.all(covered[:lead] == 0)


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
        ({"lead": 300, "window": 300, "burn_in": 100}, "lead"),
        ({"n_init": 0}, "n_init"),
        ({"screen_epochs": 0}, "screen_epochs"),
        ({"n_jobs": 0}, "n_jobs"),
    ],
)
def test_constructor_rejects_bad_arguments(kwargs: dict, match: str) -> None:
    with pytest.raises((ValueError, TypeError), match=match):
        TFLSTMPredictor(**kwargs)
    with pytest.raises(TypeError):
        TFLSTMPredictor(hiden_size=8)  # type: ignore[call-arg]  # typos are not swallowed


def test_candidates_are_screened_and_threads_do_not_change_the_result(small_runs,
                                                                       capsys) -> None:
    kw = {"max_epochs": 4, "hidden_size": 4, "window": 300, "burn_in": 100, "verbose": 1,
          "n_init": 3, "screen_epochs": 2}
    one = TFLSTMPredictor(n_jobs=1, **kw).fit(small_runs)
    out = capsys.readouterr().out
    assert "candidate 3/3" in out and "screening (2 epochs)" in out
    assert len(one.candidate_val_losses_) == 3
    # the winner (smallest screening loss) carried on from where it stopped
    assert 2 <= one.n_epochs_ <= 4
    assert min(h[2] for h in one.history_[:2]) == pytest.approx(min(one.candidate_val_losses_))
    two = TFLSTMPredictor(n_jobs=2, **kw).fit(small_runs)
    assert two.candidate_val_losses_ == one.candidate_val_losses_
    ref = make_trajectory("reversal_sine", cycles=1)
    np.testing.assert_array_equal(one.predict(ref), two.predict(ref))


def test_first_window_starts_at_the_record_start(small_runs) -> None:
    # lead=0: the network's state is fresh exactly at the record's first sample, so a
    # prediction of a reference does not depend on rest samples a caller might put in front
    # of the record, only on the record itself
    pred = TFLSTMPredictor(max_epochs=1, hidden_size=4, window=300, burn_in=100, lead=0,
                           n_init=1, verbose=0).fit(small_runs)
    ref = make_trajectory("reversal_sine", cycles=1)
    y = pred.predict_friction_error(np.asarray(ref.x, dtype=float))
    assert y.shape == (ref.n_samples,) and np.all(np.isfinite(y))
    # the first window's output equals a network run on the first window alone
    feats = pred._inputs(np.asarray(ref.x, dtype=float), ref.ts)
    with torch.no_grad():
        first = pred.net_(torch.from_numpy(feats[None, :300])).double().numpy()[0]
    np.testing.assert_allclose(y[:300], first * pred.target_scale_, rtol=1e-6, atol=1e-12)


def test_same_seed_same_numbers_under_concurrent_load(small_runs) -> None:
    # the second fit runs while a busy-loop process loads the cores and a third fit trains in
    # another thread of this process (its candidates in threads too): weights and
    # predictions must match the fit made alone, bit for bit
    kw = {"max_epochs": 3, "hidden_size": 4, "window": 300, "burn_in": 100, "batch_size": 8,
          "verbose": 0, "n_init": 2, "screen_epochs": 1, "n_jobs": 2}
    ref = make_trajectory("reversal_sine", cycles=1)
    alone = TFLSTMPredictor(**kw).fit(small_runs)
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        with ThreadPoolExecutor(max_workers=1) as pool:
            other = pool.submit(lambda: TFLSTMPredictor(**kw).fit(small_runs))
            loaded = TFLSTMPredictor(**kw).fit(small_runs)
            beside = other.result()
    finally:
        busy.kill()
        busy.wait()
    expected = alone.net_.state_dict()
    for fit in (loaded, beside):
        state = fit.net_.state_dict()
        assert state.keys() == expected.keys()
        for k, v in expected.items():
            assert torch.equal(state[k], v), k
        assert fit.candidate_val_losses_ == alone.candidate_val_losses_
        np.testing.assert_array_equal(fit.predict(ref), alone.predict(ref))

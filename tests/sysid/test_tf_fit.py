"""Transfer-function identification: the paper's eq. 22 comes back from noisy, quantised data."""

from __future__ import annotations

import control
import numpy as np
import pytest
from scipy import signal

from fricbench.sysid.tf_fit import (
    TFFitError,
    fit_tf,
    fit_tf_multi,
    simulate_tf,
    tf_error_response,
)

TS = 1e-3
# the paper's eq. (22)
NUM = np.array([1351.0, 4.952e5])
DEN = np.array([1.0, 1109.0, 4.952e5])
G22 = control.tf(NUM.tolist(), DEN.tolist())


def _excitation(seed: int, k: int = 20000, offset: float = 0.05) -> np.ndarray:
    """Random feeds held 0.2 s, smoothed at 30 Hz: accelerations up to a few m/s^2."""
    rng = np.random.default_rng(seed)
    steps = np.repeat(rng.uniform(-0.05, 0.05, k // 200 + 1), 200)[:k]
    b, a = signal.butter(2, 30, fs=1.0 / TS)
    return offset + np.cumsum(signal.lfilter(b, a, steps)) * TS


def _measure(x_ref: np.ndarray, seed: int, q: float = 0.25e-6,
             noise: float = 0.3e-6) -> np.ndarray:
    """Eq. 22 on the sampled reference (python-control, at rest at x_ref[0]), quantised, noisy."""
    t = np.arange(x_ref.shape[0]) * TS
    y = control.forced_response(G22, t, x_ref - x_ref[0]).outputs + x_ref[0]
    rng = np.random.default_rng(seed + 1000)
    return q * np.round(y / q) + noise * rng.standard_normal(y.shape)


def _coeffs(g: control.TransferFunction) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(g.num[0][0], dtype=float), np.asarray(g.den[0][0], dtype=float)


@pytest.mark.parametrize("dc_gain", [None, 1.0])
def test_eq22_every_coefficient_within_one_percent(dc_gain: float | None) -> None:
    x_ref = _excitation(0)
    x = _measure(x_ref, 0, q=1e-6, noise=0.5e-6)  # 1 um encoder and 0.5 um noise
    num, den = _coeffs(fit_tf(x_ref, x, TS, dc_gain=dc_gain))
    assert num.shape == (2,) and den.shape == (3,)
    np.testing.assert_allclose(num, NUM, rtol=0.01)
    np.testing.assert_allclose(den, DEN, rtol=0.01)
    if dc_gain is not None:
        assert num[-1] == pytest.approx(den[-1], rel=1e-12)


def test_output_error_beats_equation_error_bias() -> None:
    """With heavy noise the simulation-error fit still lands within a few percent."""
    x_ref = _excitation(1)
    x = _measure(x_ref, 1, q=1e-6, noise=2e-6)
    num, den = _coeffs(fit_tf(x_ref, x, TS))
    np.testing.assert_allclose(den, DEN, rtol=0.03)
    np.testing.assert_allclose(num, NUM, rtol=0.03)


def test_multi_run_fit_matches_and_weights_are_respected() -> None:
    refs = [_excitation(2, 8000), _excitation(3, 8000, offset=-0.02)]
    xs = [_measure(r, i) for i, r in enumerate(refs)]
    xs_bad = [x.copy() for x in xs]
    xs_bad[1][3000:3500] += 50e-6  # a disturbance the weights will hide
    w = [np.ones_like(refs[0]), np.ones_like(refs[1])]
    w[1][2990:3800] = 0.0
    num, den = _coeffs(fit_tf_multi(refs, xs_bad, TS, weights=w))
    np.testing.assert_allclose(den, DEN, rtol=0.01)
    np.testing.assert_allclose(num, NUM, rtol=0.01)


def test_simulate_tf_is_pythoncontrol_forced_response_from_rest() -> None:
    x_ref = _excitation(4, 5000)
    t = np.arange(x_ref.shape[0]) * TS
    expected = control.forced_response(G22, t, x_ref - x_ref[0]).outputs + x_ref[0]
    np.testing.assert_allclose(simulate_tf(G22, x_ref, TS), expected, atol=1e-15)
    np.testing.assert_allclose(tf_error_response(G22, x_ref, TS), x_ref - expected, atol=1e-15)


def test_third_order_fit() -> None:
    g3 = control.tf([450.0, 1.035e5, 4.05e6], [1.0, 450.5, 1.035e5, 4.05e6])
    x_ref = _excitation(5, 10000)
    t = np.arange(x_ref.shape[0]) * TS
    x = control.forced_response(g3, t, x_ref - x_ref[0]).outputs + x_ref[0]
    num, den = _coeffs(fit_tf(x_ref, x, TS, 3, 2))
    np.testing.assert_allclose(den, g3.den[0][0], rtol=1e-4)
    np.testing.assert_allclose(num, g3.num[0][0], rtol=1e-4)


@pytest.mark.parametrize(
    ("x_ref", "x", "match"),
    [
        (np.linspace(0, 1e-2, 500), np.linspace(0, 1e-2, 499), "same length"),
        (np.r_[np.linspace(0, 1e-2, 499), np.nan], np.linspace(0, 1e-2, 500), "NaN"),
        (np.linspace(0, 1e-2, 500), np.r_[np.linspace(0, 1e-2, 499), np.inf], "NaN or inf"),
        (np.zeros(500), np.zeros(500), "without motion"),
        (np.zeros((2, 500)), np.zeros((2, 500)), "1-D"),
        (np.linspace(0, 1e-2, 10), np.linspace(0, 1e-2, 10), "at least 50"),
    ],
)
def test_bad_input_is_named(x_ref: np.ndarray, x: np.ndarray, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        fit_tf(x_ref, x, TS)


def test_bad_orders_and_sample_time() -> None:
    x = _excitation(6, 1000)
    with pytest.raises(ValueError, match="n_zeros"):
        fit_tf(x, x, TS, n_poles=2, n_zeros=2)
    with pytest.raises(ValueError, match="ts"):
        fit_tf(x, x, -1.0)
    with pytest.raises(ValueError, match="dc_gain"):
        fit_tf(x, x, TS, dc_gain=0.0)
    with pytest.raises(TypeError, match="sequences"):
        fit_tf_multi(x, x, TS)  # type: ignore[arg-type]
    assert issubclass(TFFitError, ValueError)

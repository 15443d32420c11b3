"""Stable non-causal inversion shared by ILC and model-inverse pre-compensation."""

from __future__ import annotations

import control
import numpy as np
import pytest

from fricbench.sysid.inverse import pulse_response, stable_inverse, zero_phase_lowpass

TS = 1e-3
G = control.tf([450.0, 1.035e5, 4.05e6], [1.0, 450.5, 1.035e5, 4.05e6])


def test_pulse_response_sums_to_the_dc_gain() -> None:
    h = pulse_response(G, TS)
    assert h.sum() == pytest.approx(1.0, abs=1e-9)
    assert h[0] == 0.0  # zero-order hold: no direct feedthrough


def test_inverse_input_reproduces_a_band_limited_target() -> None:
    h = pulse_response(G, TS)
    t = np.arange(4000) * TS
    # a smooth 5 um bump well inside the loop bandwidth
    e = 5e-6 * np.exp(-(((t - 2.0) / 0.02) ** 2))
    u = stable_inverse(h, e, TS, beta=1e-4, cutoff=150.0)
    y = np.convolve(u, h)[: t.size]
    assert np.max(np.abs(y - e)) < 0.05 * np.max(np.abs(e))
    # the inverse leads: the input peaks before the wanted output
    assert np.argmax(u) < np.argmax(e)


def test_bad_inputs_are_named() -> None:
    with pytest.raises(ValueError, match="decayed"):
        pulse_response(control.tf([1.0], [1.0, -1.0]), TS)
    with pytest.raises(ValueError, match="cutoff"):
        zero_phase_lowpass(np.zeros(100), 500.0, TS)
    with pytest.raises(ValueError, match="beta"):
        stable_inverse(pulse_response(G, TS), np.zeros(100), TS, beta=-1.0)

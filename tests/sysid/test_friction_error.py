"""Events, break velocity, pre-sliding windows and the friction error on simulated runs."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from fricbench.axis import Axis, simulate
from fricbench.sysid.friction_error import (
    NoReversalError,
    extract_friction_error,
    find_events,
    identify_v_break,
    identify_v_break_multi,
    presliding_mask,
    reference_velocity,
    tf_residual,
)
from fricbench.sysid.tf_fit import fit_tf
from fricbench.trajectories import make_trajectory

TS = 1e-3


@pytest.fixture(scope="module")
def m_serial():
    return make_trajectory("m_serial")


@pytest.fixture(scope="module")
def curve():
    return make_trajectory("curve")


def test_events_of_the_standard_trajectories(m_serial, curve) -> None:
    # m_serial docstring: 9 reversals (6 direct, 3 after a dwell) and 9 dwells at rest
    kinds = Counter(e.kind for e in find_events(m_serial.x, TS))
    assert kinds == {"start": 9, "stop": 9, "reversal": 6}
    kinds = Counter(e.kind for e in find_events(curve.x, TS))
    assert kinds["reversal"] == 23
    for e in find_events(m_serial.x, TS):
        assert e.direction in (-1, 1)
        if e.kind == "reversal":
            assert e.accel > 0.1  # direct reversals of M-serial happen at 0.25..0.5 m/s^2


def _true_break_speeds(res, ts: float) -> list[float]:
    """Reference speed at each exact breakaway, read from the noise-free true position."""
    v, _ = reference_velocity(res.x_ref, ts)
    speeds = []
    for ev in find_events(res.x_ref, ts):
        if ev.kind == "stop":
            continue
        k0 = ev.index
        d = ev.direction * (res.x_true[k0:k0 + 500] - res.x_true[k0])
        gone = np.flatnonzero(d > 10e-6)
        if gone.size == 0:
            continue
        seg = res.x_true[k0:k0 + gone[0] + 1]
        stuck = np.flatnonzero(np.diff(seg) == 0.0)  # the static law holds the axis exactly
        if stuck.size == 0:
            continue
        # the break happens during the sample after the last stuck pair
        speeds.append(float(abs(np.interp(k0 + stuck[-1] + 1.5, np.arange(v.shape[0]), v))))
    return speeds


@pytest.mark.parametrize("fs", [500.0, 650.0])
def test_v_break_matches_the_known_friction(m_serial, curve, fs: float) -> None:
    """Identified from noisy, quantised measurements vs read from the true stick-slip."""
    axis = Axis().with_friction("stribeck", fc=350.0, fs=fs, vs=2e-3).with_effects(
        noise_std=0.1e-6, quantization=0.25e-6)
    runs = [simulate(axis, r, seed=3 + i) for i, r in enumerate((m_serial, curve))]
    bv = identify_v_break_multi([r.x_ref for r in runs], [r.x for r in runs], TS)
    truth = float(np.median(sum((_true_break_speeds(r, TS) for r in runs), [])))
    assert bv.v_break == pytest.approx(truth, rel=0.15)
    assert bv.a0 == pytest.approx(bv.v_break**2 / (2 * bv.x_break))
    assert len(bv.breakaways) >= 25


def test_v_break_grows_with_static_friction(curve) -> None:
    out = []
    for fs in (450.0, 700.0):
        axis = Axis().with_friction("stribeck", fc=350.0, fs=fs, vs=2e-3).with_effects(
            quantization=0.25e-6)
        res = simulate(axis, curve)
        out.append(identify_v_break(res.x_ref, res.x, TS).v_break)
    assert out[1] > 1.2 * out[0]


def test_presliding_windows_and_friction_error(m_serial) -> None:
    axis = Axis().with_effects(noise_std=0.1e-6, quantization=0.25e-6)
    res = simulate(axis, m_serial, seed=1)
    g = fit_tf(res.x_ref, res.x, TS, 3, 2)
    mask = presliding_mask(res.x_ref, TS, 2e-3, pre=0.02, post=0.1)
    for ev in find_events(res.x_ref, TS):
        assert mask[ev.index]
    assert 0.1 < mask.mean() < 0.5
    v, _ = reference_velocity(res.x_ref, TS)
    assert np.all(mask[np.abs(v) < 1e-9])  # every dwell at rest is inside a window
    fe = extract_friction_error(g, res.x_ref, res.x, TS, 2e-3)
    np.testing.assert_array_equal(fe.mask, mask)
    np.testing.assert_allclose(fe.residual, tf_residual(g, res.x_ref, res.x, TS))
    assert np.all(fe.friction_error[~mask] == 0.0)
    np.testing.assert_array_equal(fe.friction_error[mask], fe.residual[mask])
    # the friction spikes live inside the windows
    assert np.max(np.abs(fe.residual[~mask])) < 0.5 * np.max(np.abs(fe.residual[mask]))


def test_bad_runs_raise_clear_errors() -> None:
    t = np.arange(2000) * TS
    with pytest.raises(NoReversalError, match="without motion"):
        identify_v_break(np.zeros_like(t), np.zeros_like(t), TS)
    ramp = 0.01 * t + 0.001  # one start, and an "axis" that never sticks
    with pytest.raises(NoReversalError, match="shows a breakaway"):
        identify_v_break(ramp, ramp, TS)
    with pytest.raises(ValueError, match="NaN"):
        identify_v_break(np.r_[ramp[:-1], np.nan], ramp, TS)
    with pytest.raises(ValueError, match="samples"):
        identify_v_break(ramp, ramp[:-1], TS)
    with pytest.raises(ValueError, match="v_break"):
        presliding_mask(ramp, TS, 0.0)

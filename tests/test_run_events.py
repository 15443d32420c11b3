"""The one event finder on known signals: a sine, a trapezoid with a dwell, noise about zero."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.run_events import (
    hysteresis_sign,
    motion_events,
    motion_sign,
    sign_reversals,
)

TS = 1e-3


def _kinds(events) -> list[tuple[str, int, int, int]]:
    return [(e.kind, e.index, e.onset, e.direction) for e in events]


def test_sine_reverses_at_its_zero_crossings() -> None:
    k = np.arange(2000)
    v = np.sin(2 * np.pi * k * TS)  # m/s, two periods
    events = motion_events(v, TS, rest_speed=1e-9)
    assert _kinds(events) == [("start", 0, 1, 1), ("reversal", 500, 501, -1),
                              ("reversal", 1000, 1001, 1), ("reversal", 1500, 1501, -1)]
    # a reversal of a sine happens at full acceleration: |a| = 2 pi m/s^2
    assert events[1].accel == pytest.approx(2 * np.pi, rel=1e-4)
    assert list(sign_reversals(motion_sign(v, 1e-9))) == [501, 1001, 1501]


def _trapezoid() -> np.ndarray:
    up = np.concatenate([np.zeros(100), np.linspace(0, 0.1, 100), np.full(200, 0.1),
                         np.linspace(0.1, 0, 100)[:-1]])
    return np.concatenate([up, np.zeros(150), -up, np.zeros(50)])


def test_trapezoid_with_dwell_is_a_stop_and_a_start_or_one_reversal() -> None:
    v = _trapezoid()
    # first moving samples: 101 (+) and 101 + 498 + 1 + 150 = 750 (-)
    events = motion_events(v, TS)
    assert _kinds(events) == [("start", 100, 101, 1), ("stop", 499, 499, 1),
                              ("start", 749, 750, -1), ("stop", 1148, 1148, -1)]
    # the rest is 251 samples (499..749): a reversal only when such a rest still counts as one
    assert _kinds(motion_events(v, TS, max_gap=250))[1][0] == "stop"
    events = motion_events(v, TS, max_gap=251)
    assert _kinds(events) == [("start", 100, 101, 1), ("reversal", 499, 750, -1),
                              ("stop", 1148, 1148, -1)]
    assert _kinds(motion_events(v, TS, max_gap=None)) == _kinds(events)
    assert list(sign_reversals(motion_sign(v))) == [750]


def test_noise_about_zero_is_rest_below_the_threshold() -> None:
    rng = np.random.default_rng(0)
    v = rng.normal(0.0, 1e-3, 10_000)
    assert motion_events(v, TS, rest_speed=6e-3) == []
    assert len(sign_reversals(motion_sign(v, 0.0))) > 1000  # without a threshold: chatter
    v[4000:5000] += 0.05
    assert _kinds(motion_events(v, TS, rest_speed=6e-3)) == [("start", 3999, 4000, 1),
                                                             ("stop", 5000, 5000, 1)]
    # position noise below the hysteresis width never turns it; a triangle turns 3 times
    x = np.cumsum(rng.normal(0.0, 1e-3, 10_000)) * TS
    tri = 0.01 * np.abs(((np.arange(10_000) / 2500) % 2) - 1)
    assert sign_reversals(hysteresis_sign(1e-7 * np.sin(np.arange(10_000)), 1e-6)).size == 0
    assert sign_reversals(hysteresis_sign(tri + x * 1e-3, 1e-4)).size == 3


def test_one_finder_two_views() -> None:
    """The reversals of ``sign_reversals`` are those of ``motion_events`` with any rest."""
    rng = np.random.default_rng(1)
    v = np.repeat(rng.normal(size=400), 5) * (rng.random(2000) < 0.7)
    onsets = [e.onset for e in motion_events(v, TS, rest_speed=0.2, max_gap=None)
              if e.kind == "reversal"]
    assert list(sign_reversals(motion_sign(v, 0.2))) == onsets and onsets


@pytest.mark.parametrize(("call", "error", "match"), [
    (lambda: motion_sign(np.zeros((2, 3))), ValueError, r"v has shape \(2, 3\)"),
    (lambda: motion_sign(np.array([0.0, np.nan])), ValueError, "v contains NaN.*sample 1"),
    (lambda: motion_sign(np.zeros(3), -1.0), ValueError, "rest_speed=-1.0: expected >= 0"),
    (lambda: motion_events(np.zeros(3), 0.0), ValueError, "ts=0.0: expected > 0 s"),
    (lambda: motion_events(np.zeros(3), TS, max_gap=-1), ValueError, "max_gap=-1"),
    (lambda: motion_events(np.zeros(3), TS, max_gap=1.5), TypeError, "max_gap=1.5"),
    (lambda: hysteresis_sign(np.zeros(3), 0.0), ValueError, "tol=0.0: expected > 0"),
    (lambda: sign_reversals(np.array([0.0, 2.0])), ValueError, "other than -1, 0 and"),
])
def test_bad_arguments(call, error, match) -> None:
    with pytest.raises(error, match=match):
        call()


def test_short_signals() -> None:
    assert motion_events(np.zeros(0), TS) == []
    assert _kinds(motion_events(np.ones(1), TS)) == [("start", 0, 0, 1)]
    assert sign_reversals(np.zeros(0)).size == 0

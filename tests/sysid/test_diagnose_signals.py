"""Sensor disturbances of the measurement (``diagnose.signals``: :func:`sensor_lines`,
:func:`rest_segments`, :class:`NoiseFloor` with lines)."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS
from fricbench.sysid.diagnose.signals import (
    NoiseFloor,
    mains_visible,
    noise_floor,
    rest_segments,
    sensor_lines,
)

TS = 1e-3
N = 20_000
T = np.arange(N) * TS


def _reference() -> np.ndarray:
    """Moves of 1 s (a smooth 10 mm stroke, back and forth) and rests of 1 s."""
    ref = np.zeros(N)
    s = np.linspace(0.0, 1.0, 1000)
    shape = 0.01 * (10 * s**3 - 15 * s**4 + 6 * s**5)
    for k in range(N // 2000):
        a = 2000 * k
        start = ref[a - 1] if a else 0.0
        ref[a:a + 1000] = start + (shape if k % 2 == 0 else -shape)
        ref[a + 1000:a + 2000] = ref[a + 999]
    return ref


REF = _reference()
HUM = 3e-6 * np.sin(2 * np.pi * 50.07 * T + 1.0) + 1e-6 * np.sin(2 * np.pi * 150.2 * T + 2.0)


def test_rests_are_where_the_reference_holds_after_its_transient() -> None:
    segs = rest_segments(REF, TS)
    assert len(segs) == N // 2000
    for a, b in segs:
        assert np.ptp(REF[a - 1:b]) == 0.0
        # the first quarter of each rest of about 1000 samples is the axis settling
        assert 745 <= b - a <= 755


@pytest.mark.parametrize("where", ["rests", "residual"])
def test_mains_lines_are_found_with_their_amplitude(where: str) -> None:
    rng = np.random.default_rng(0)
    x = REF + HUM + 1e-6 * rng.standard_normal(N)
    segs = rest_segments(REF, TS) if where == "rests" else [(0, N)]
    lines = sensor_lines(x - REF, TS, segs, where)
    assert [ln.harmonic for ln in lines] == [1, 3]
    assert all(ln.mains_hz == 50.0 and ln.where == where for ln in lines)
    assert lines[0].frequency_hz == pytest.approx(50.07, abs=0.01)
    assert lines[1].frequency_hz == pytest.approx(150.2, abs=0.02)
    assert lines[0].amplitude == pytest.approx(3e-6, rel=0.03)
    assert lines[1].amplitude == pytest.approx(1e-6, rel=0.05)
    assert min(ln.ratio for ln in lines) >= DEFAULT_SETTINGS.sensor_line_ratio
    # their power joins the floor: variance added to the sensor's own
    floor = NoiseFloor(1e-6, 0.0).with_lines(lines)
    assert floor.sensor_rms == 1e-6
    assert floor.rms == pytest.approx(np.sqrt(1e-12 + 0.5 * (9e-12 + 1e-12)), rel=0.05)
    assert floor.to_dict()["sensor_disturbance_rms_m"] == floor.disturbance_rms


def test_a_60_hz_grid_is_told_from_a_50_hz_one() -> None:
    rng = np.random.default_rng(1)
    hum = 2e-6 * np.sin(2 * np.pi * 59.95 * T) + 0.5e-6 * np.sin(2 * np.pi * 179.85 * T)
    lines = sensor_lines(hum + 1e-6 * rng.standard_normal(N), TS, [(0, N)], "residual")
    assert [(ln.mains_hz, ln.harmonic) for ln in lines] == [(60.0, 1), (60.0, 3)]


@pytest.mark.parametrize("seed", range(4))
def test_nothing_is_found_in_noise_and_motion(seed: int) -> None:
    rng = np.random.default_rng(10 + seed)
    # white noise, a slow random wander and an encoder's quantisation on a smooth motion
    x = REF + 1e-6 * rng.standard_normal(N) + 2e-7 * np.cumsum(rng.standard_normal(N)) / 30
    x = 5e-7 * np.round(x / 5e-7)
    assert sensor_lines(x - REF, TS, rest_segments(REF, TS), "rests") == []
    assert sensor_lines(x - REF, TS, [(0, N)], "residual") == []
    assert sensor_lines(x, TS, [(0, N)], "residual") == []
    # and the floor of such a run has no lines
    assert noise_floor(x, REF).lines == ()


def test_a_still_sensor_and_a_short_log_give_no_line() -> None:
    assert sensor_lines(np.zeros(N), TS, [(0, N)], "residual") == []
    rng = np.random.default_rng(2)
    for trial in range(50):
        short = rng.standard_normal(300)
        assert sensor_lines(short, TS, [(60, 290)], "rests") == [], trial


def test_a_log_too_slow_for_the_mains_says_so_and_finds_nothing() -> None:
    # 100 Hz: the Nyquist frequency is the mains' own (what aliases there is not told apart)
    ts = 0.01
    t = np.arange(3000) * ts
    hum = 3e-6 * np.sin(2 * np.pi * 50.07 * t + 1.0)
    assert not mains_visible(ts)
    assert sensor_lines(hum, ts, [(0, t.size)], "residual") == []
    assert mains_visible(1e-3) and mains_visible(1 / 250)


def test_a_line_below_the_sensors_own_floor_is_left_out() -> None:
    rng = np.random.default_rng(5)
    x = HUM + 1e-6 * rng.standard_normal(N)
    # the 150 Hz line (1 um) stands out of the spectrum but not above a 1.5 um sensor floor
    lines = sensor_lines(x, TS, [(0, N)], "residual", floor=1.5e-6)
    assert [ln.harmonic for ln in lines] == [1]

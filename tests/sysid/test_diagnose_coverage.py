"""Where a validation run leaves the range of the training run (``diagnose.coverage``)."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.sysid.diagnose.coverage import coverage
from fricbench.sysid.diagnose.prepared import prepare
from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS
from fricbench.sysid.io import RunData, validate_arrays


def _sine_run(amplitude: float, freq: float, unit: str = "m", seed: int = 0) -> RunData:
    rng = np.random.default_rng(seed)
    t = np.arange(8_000) * 1e-3
    x_ref = amplitude * np.sin(2 * np.pi * freq * t)
    x = x_ref + 1e-4 * amplitude * rng.standard_normal(t.shape[0])
    return validate_arrays(t, x_ref, x, position_unit=unit)


def test_a_validation_run_inside_the_training_runs_range_gets_no_warning() -> None:
    train = prepare(_sine_run(0.05, 0.5))
    other = prepare(_sine_run(0.05, 0.5, seed=1), cutoff_hz=train.cutoff_hz, decim=train.decim)
    cov = coverage(train, other)
    beyond = DEFAULT_SETTINGS.beyond_share
    assert cov.share_faster < beyond and cov.share_outside < beyond
    assert cov.warnings(train) == []


def test_a_faster_and_longer_validation_run_is_named_an_extrapolation() -> None:
    train = prepare(_sine_run(0.05, 0.5))
    # twice the stroke at the same frequency: twice the speed, half the time outside
    other = prepare(_sine_run(0.10, 0.5, seed=1), cutoff_hz=train.cutoff_hz,
                    decim=train.decim)
    cov = coverage(train, other)
    assert cov.speed_reach == pytest.approx(2 * np.pi * 0.5 * 0.05, rel=0.02)
    assert cov.speed_max_validation == pytest.approx(2 * np.pi * 0.5 * 0.10, rel=0.02)
    # faster than 1.1 reach: |cos| > 0.55, on 1 - 2 asin(0.55) / pi = 63 % of a period;
    # outside the stroke widened by a tenth of it on each side: |sin| > 0.6, on 59 %
    assert cov.share_faster == pytest.approx(1 - 2 * np.arcsin(0.55) / np.pi, abs=0.02)
    assert cov.share_outside == pytest.approx(1 - 2 * np.arcsin(0.6) / np.pi, abs=0.02)
    faster, outside = cov.warnings(train)
    assert "moves faster" in faster and "mm/s" in faster
    assert "leaves the stroke" in outside and "mm" in outside
    d = cov.to_dict()
    assert d["share_faster_pct"] == pytest.approx(100 * cov.share_faster)
    assert all(np.isfinite(v) for v in d.values())


def test_the_warnings_speak_the_logs_unit() -> None:
    train = prepare(_sine_run(np.pi / 4, 0.5, unit="deg"))
    other = prepare(_sine_run(np.pi / 2, 0.5, unit="deg", seed=1), cutoff_hz=train.cutoff_hz,
                    decim=train.decim)
    faster, outside = coverage(train, other).warnings(train)
    assert "deg/s" in faster and "deg" in outside

"""The diagnosis's verdict (``diagnose.verdict``)."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS
from fricbench.sysid.diagnose.verdict import describe, judge

TS = 1e-3
T = np.arange(4_000) * TS
X = 0.1 * np.sin(2 * np.pi * 0.5 * T)
V_REF = np.gradient(X, TS)


def _judge(effects: list[str], rms_after: float, heldout: tuple[float, float] | None,
           residual: np.ndarray | None = None) -> tuple[str, str]:
    r = 1e-6 * np.random.default_rng(0).standard_normal(T.shape[0]) if residual is None \
        else residual
    v = judge(effects, rms_after, 1e-6, r, X, V_REF, TS, heldout=heldout,
              heldout_name="validation")
    return v.verdict, v.reason


def test_the_margin_is_the_searchs_tolerance() -> None:
    assert DEFAULT_SETTINGS.heldout_gain == DEFAULT_SETTINGS.tolerance


@pytest.mark.parametrize(("after", "verdict"), [(0.5, "explained"), (0.97, "explained"),
                                                 (0.99, "not_explained"),
                                                 (1.0, "not_explained"),
                                                 (1.3, "not_explained")])
def test_effects_explain_only_a_held_out_error_that_fell_by_more_than_the_margin(
        after: float, verdict: str) -> None:
    got, reason = _judge(["coulomb_friction"], 1e-6, (1.0, after))
    assert got == verdict
    if verdict == "not_explained":
        assert "did not fall by more than 2 %" in reason and f"{after:.4g} m)" in reason


def test_no_effect_at_the_floor_is_nothing_to_explain_and_above_it_not_explained() -> None:
    assert _judge([], 1.2e-6, None)[0] == "nothing_to_explain"
    drift = 1e-4 * (T / T[-1]) ** 2
    got, _ = _judge([], 1e-4, None, residual=drift)
    assert got == "not_explained"


def test_the_residual_is_described_by_its_dominant_structure() -> None:
    drift = 1e-5 * (T / T[-1]) ** 3
    assert describe(drift, X, V_REF, TS).startswith("a drift in time")
    ring = 1e-6 * np.sin(2 * np.pi * 37.0 * T)
    assert "oscillation near 37" in describe(ring, X, V_REF, TS)
    lag = -2e-3 * V_REF
    assert describe(lag, X, V_REF, TS).startswith("a lag behind the motion")


def test_a_line_of_the_sensor_is_never_called_a_resonance() -> None:
    # mains hum left in the residual: an oscillation near 50 Hz without the line given ...
    rng = np.random.default_rng(3)
    hum = 4e-6 * np.sin(2 * np.pi * 50.07 * T + 1.0) + 1e-6 * np.sin(2 * np.pi * 150.2 * T)
    r = hum + 0.5e-6 * rng.standard_normal(T.size)
    assert "resonance" in describe(r, X, V_REF, TS)
    # ... and no resonance once it is known to be the sensor's: its sinusoids are removed and
    # no peak near them is named
    said = describe(r, X, V_REF, TS, lines=[50.07, 150.2])
    assert "resonance" not in said and "50" not in said
    # a resonance elsewhere is still one
    ring = r + 3e-6 * np.sin(2 * np.pi * 37.0 * T)
    assert "oscillation near 37" in describe(ring, X, V_REF, TS, lines=[50.07, 150.2])
    v = judge([], 5e-6, 1e-6, r, X, V_REF, TS, lines=[50.07, 150.2])
    assert "resonance" not in v.residual

"""The one run type: its validator and its events."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.run import Run, validate_run_arrays

TS = 1e-3


def _arrays(k: int = 400) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(k) * TS
    xr = 0.01 * np.sin(2 * np.pi * t)
    return t, xr, xr - 1e-6


def test_valid_arrays_come_back_as_floats_with_the_median_step() -> None:
    t, xr, x = _arrays()
    arrs, ts = validate_run_arrays(list(t), xr, x, np.ones(400, dtype=int))
    assert set(arrs) == {"t", "x_ref", "x", "u"} and arrs["u"].dtype == float
    assert ts == pytest.approx(TS)


class _Custom(ValueError):
    pass


@pytest.mark.parametrize(("change", "match"), [
    (lambda a: (a[0], a[1][None, :], a[2]), r"x_ref has shape \(1, 400\): expected a 1-D"),
    (lambda a: (a[0], a[1], a[2][:-5]), "x has 395 samples but t has 400: .*same length"),
    (lambda a: (a[0], a[1], np.where(np.arange(400) == 7, np.inf, a[2])),
     r"sample 7, x contains NaN or inf: value inf is not finite \(1 such samples\)"),
    (lambda a: (a[0][:2], a[1][:2], a[2][:2]), "t has 2 samples: too short, need at least 3"),
    (lambda a: (a[0][::-1], a[1], a[2]), r"t does not increase at sample 1"),
    (lambda a: (a[0] ** 1.01, a[1], a[2]), "irregular sampling: the step to sample"),
])
def test_bad_arrays(change, match) -> None:
    t, xr, x = change(_arrays())
    with pytest.raises(ValueError, match=match):
        validate_run_arrays(t, xr, x, min_samples=3)


def test_messages_name_the_source_the_columns_and_the_lines() -> None:
    t, xr, x = _arrays()
    x = x.copy()
    x[5] = np.nan
    with pytest.raises(_Custom, match=r"^f\.csv: line 7, column 'q' contains NaN"):
        validate_run_arrays(t, xr, x, source="f.csv", labels={"x": "column 'q'"},
                            where=lambda i: f"line {i + 2}", error=_Custom)
    with pytest.raises(ValueError, match=r"units\['position'\]='mm': expected 'm' or 'rad'"):
        validate_run_arrays(*_arrays(), units={"time": "s", "position": "mm"})
    with pytest.raises(ValueError, match="too short, need at least 500 .because."):
        validate_run_arrays(*_arrays(), min_samples=500, too_short_why=" (because)")


def test_run_events_are_those_of_its_reference() -> None:
    t = np.arange(2000) * TS
    run = Run(t, 0.01 * np.sin(2 * np.pi * t), 0.01 * np.sin(2 * np.pi * t))
    kinds = [(e.kind, e.direction) for e in run.events()]
    assert kinds == [("start", 1), ("reversal", -1), ("reversal", 1), ("reversal", -1),
                     ("reversal", 1)]
    assert [e.index for e in run.events()] == [0, 250, 750, 1250, 1750]


def test_figures_are_shown_in_the_unit_the_log_was_in() -> None:
    from fricbench.sysid.io import validate_arrays

    t = np.arange(200) * 1e-3
    x = 0.1 * np.sin(t)
    y = x + 1e-4 * np.cos(7 * t)
    assert validate_arrays(t, x, y, position_unit="deg").logged_unit.display == "deg"
    assert validate_arrays(t, x, y, position_unit="rad").logged_unit.display == "mrad"
    assert validate_arrays(t, x, y, position_unit="mm").logged_unit.display == "um"
    # a run built without the loader's record of its unit: the SI unit's family
    assert Run(t, x, x).logged_unit.display == "um"
    assert Run(t, x, x, units={"position": "rad"}).logged_unit.display == "mrad"

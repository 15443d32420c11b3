"""The friction profile along the stroke: a level of any shape, linear between knots."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.axis import Axis
from fricbench.axis import plant as PL
from fricbench.axis.simulate import simulate
from fricbench.trajectories import make_trajectory


def _row(knots: list[float], start: float, span: float) -> np.ndarray:
    p = PL.default_row(2.0)
    p[PL.FC] = 10.0
    p[PL.PD_NKNOTS] = len(knots)
    p[PL.PD_START] = start
    p[PL.PD_SPAN] = span
    p[PL.PD_KNOT0:PL.PD_KNOT0 + len(knots)] = knots
    return p


@pytest.mark.parametrize("knots", [[0.3], [0.0, 0.5], [0.0, 0.5, -0.2, 0.1, 0.0],
                                   list(np.linspace(-0.5, 1.5, PL.PD_MAX_KNOTS))])
def test_the_level_is_linear_between_knots_and_held_beyond(knots: list[float]) -> None:
    """The sliding friction at each position is ``fc (1 + l(x))``, ``l`` numpy's linear
    interpolation of the knots (held at the end values outside the span)."""
    start, span = -0.05, 0.2
    x = np.linspace(-0.2, 0.3, 501)
    v = np.full_like(x, 0.01)
    got = PL.sliding_force(_row(knots, start, span), x, v)
    grid = start + span * np.linspace(0.0, 1.0, len(knots)) if len(knots) > 1 else [start]
    want = 10.0 * (1.0 + np.interp(x, grid, knots))
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_a_level_below_zero_stops_at_no_friction() -> None:
    got = PL.sliding_force(_row([-2.0, -2.0], 0.0, 1.0), np.array([0.5]), np.array([0.01]))
    assert got[0] == 0.0


def test_no_knots_is_the_axis_without_a_profile_bit_for_bit() -> None:
    """Knot values and a span without a knot count change nothing: the 40-entry row's axis."""
    axis = Axis().with_effects(noise_std=1e-8)
    ref = make_trajectory("m_serial")
    row = axis.pack()[:PL.N_PLANT]
    assert np.array_equal(PL.pad_row(row[:PL.N_PLANT_UNPROFILED]), row)
    a = simulate(axis, ref, seed=3)
    b = simulate(axis.with_effects(friction_profile=(), friction_profile_span=0.1), ref, seed=3)
    for name in ("x", "x_true", "u", "friction"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_a_worn_stretch_raises_the_friction_there_alone() -> None:
    """A stretch of 40 % more friction over a fifth of the travel: the friction force the
    loop meets is 40 % higher inside it and unchanged outside the knots around it."""
    ref = make_trajectory("m_serial")
    lo, hi = float(np.min(ref.x)), float(np.max(ref.x))
    axis = Axis()
    worn = axis.with_effects(friction_profile=(0.0, 0.0, 0.4, 0.0, 0.0),
                             friction_profile_start=lo, friction_profile_span=hi - lo)
    a, b = simulate(axis, ref), simulate(worn, ref)
    centre = np.abs(b.x_true - 0.5 * (lo + hi)) < 0.02 * (hi - lo)
    outside = np.abs(b.x_true - 0.5 * (lo + hi)) > 0.3 * (hi - lo)
    moving = np.abs(np.gradient(b.x_true)) > 0.0
    ratio = np.abs(b.friction) / np.maximum(np.abs(a.friction), 1e-12)
    sliding = moving & (np.abs(a.friction) > 0.5 * np.max(np.abs(a.friction)))
    assert np.any(centre & sliding) and np.any(outside & sliding)
    assert np.median(ratio[centre & sliding]) == pytest.approx(1.4, rel=0.05)
    assert np.median(ratio[outside & sliding]) == pytest.approx(1.0, rel=0.02)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"friction_profile": tuple(0.1 for _ in range(PL.PD_MAX_KNOTS + 1))},
     f"friction_profile: 13 entries, expected at most {PL.PD_MAX_KNOTS}"),
    ({"friction_profile": (0.0, 0.2)}, r"friction_profile_span=0(\.0)?: expected > 0 m"),
    ({"friction_profile": (0.0, 3.0), "friction_profile_span": 0.1},
     r"friction_profile\[1\]=3"),
    ({"friction_profile": "0.1, 0.2"}, "expected a sequence of numbers"),
    ({"friction_profile_start": float("nan")}, "friction_profile_start=nan"),
])
def test_a_bad_profile_names_the_parameter(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Axis().with_effects(**kwargs)


def test_a_toml_list_becomes_a_tuple() -> None:
    axis = Axis().with_effects(friction_profile=[0.0, 0.3], friction_profile_span=0.1)
    assert axis.effects.friction_profile == (0.0, 0.3)
    assert axis.pack()[PL.PD_NKNOTS] == 2 and axis.pack()[PL.PD_KNOT0 + 1] == 0.3

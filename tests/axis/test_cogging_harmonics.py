"""The cogging ripple's second and third harmonics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fricbench.axis import Axis
from fricbench.axis import plant as PL
from fricbench.axis.simulate import simulate
from fricbench.trajectories import make_trajectory


def test_the_ripple_is_the_sum_of_its_harmonics() -> None:
    """At rest (no friction force), the plant's force is the offset plus the ripple
    ``sum_h A_h sin(2 pi h x / period + phase_h)`` with h = 1, 2, 3."""
    axis = Axis().with_effects(cogging_amplitude=3.0, cogging_period=4e-3, cogging_phase=0.4,
                               cogging_harmonics=(1.5, 0.5),
                               cogging_harmonic_phases=(-1.0, 2.0))
    p = axis.pack()[:PL.N_PLANT]
    x = np.linspace(-0.01, 0.01, 401)
    got = PL.sliding_force(p, x, np.zeros_like(x)) - p[PL.OFFSET]
    k = 2.0 * math.pi / 4e-3
    want = (3.0 * np.sin(k * x + 0.4) + 1.5 * np.sin(2 * k * x - 1.0)
            + 0.5 * np.sin(3 * k * x + 2.0))
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)


def test_harmonics_alone_need_no_fundamental() -> None:
    axis = Axis().with_effects(cogging_period=4e-3, cogging_harmonics=(0.0, 2.0))
    p = axis.pack()[:PL.N_PLANT]
    x = np.array([1e-3 / 3.0])
    got = PL.sliding_force(p, x, np.zeros(1)) - p[PL.OFFSET]
    assert got[0] == pytest.approx(2.0 * math.sin(3 * 2 * math.pi * x[0] / 4e-3))


def test_no_harmonics_is_the_axis_without_them_bit_for_bit() -> None:
    axis = Axis().with_effects(cogging_amplitude=2.0, noise_std=1e-8)
    ref = make_trajectory("reversal_sine")
    row = axis.pack()[:PL.N_PLANT]
    assert np.array_equal(PL.pad_row(row[:PL.N_PLANT_FUNDAMENTAL]), row)
    a = simulate(axis, ref, seed=4)
    b = simulate(axis.with_effects(cogging_harmonics=(0.0, 0.0)), ref, seed=4)
    for name in ("x", "x_true", "u", "friction"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"cogging_harmonics": (1.0, 1.0, 1.0)}, "cogging_harmonics: 3 entries, expected at most 2"),
    ({"cogging_harmonics": (-1.0,)}, r"cogging_harmonics\[0\]=-1"),
    ({"cogging_harmonics": (1.0, 2.0), "cogging_harmonic_phases": (0.1,)},
     "1 phases for 2 harmonics"),
    ({"cogging_harmonics": "1.0"}, "expected a sequence of numbers"),
    ({"cogging_harmonic_phases": (float("nan"),), "cogging_harmonics": (1.0,)},
     r"cogging_harmonic_phases\[0\]=nan"),
])
def test_bad_harmonics_name_the_parameter(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Axis().with_effects(**kwargs)

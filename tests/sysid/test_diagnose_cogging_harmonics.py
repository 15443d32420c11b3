"""The cogging's harmonics as candidates of the search (issue 46, item 2).

A ripple that is not a pure sinusoid (a linear motor's magnets) leaves its harmonics in the
residual of a fundamental; each order is a candidate of its own, taken where the criterion
takes it, and a report naming it names the cogging.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from fricbench.axis import Axis, simulate
from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.diagnosis import diagnose
from fricbench.sysid.diagnose.effects import effect_names, get_effect, named_as
from fricbench.sysid.diagnose.settings import defaults
from fricbench.sysid.io import validate_arrays
from fricbench.trajectories.base import Reference

FUNDAMENTAL, SECOND, PERIOD = 120.0, 75.0, 4e-3  # N, N, m


def _run(second: float, seed: int = 0):
    """A 12 s run of fricbench's axis (its Stribeck friction, a cogging ripple with a second
    harmonic of ``second`` N, 0.1 um noise) on a sine sweep of reversals: the effort logged."""
    ts = 1e-3
    t = np.arange(12_000) * ts
    x = 0.01 * np.sin(2 * np.pi * 0.3 * t) + 0.003 * np.sin(2 * np.pi * 1.3 * t + 0.4)
    s = np.clip((t - 0.2) / 0.5, 0.0, 1.0)
    x *= s**3 * (10.0 - 15.0 * s + 6.0 * s**2)
    axis = Axis().with_effects(cogging_amplitude=FUNDAMENTAL, cogging_period=PERIOD,
                               cogging_phase=0.4, cogging_harmonics=(second,) if second else (),
                               cogging_harmonic_phases=(1.1,) if second else (),
                               noise_std=1e-7, quantization=2e-8)
    res = simulate(axis, Reference.from_positions(t, x), seed=seed)
    return validate_arrays(res.t, res.x_ref, res.x, res.u)


def test_a_harmonic_names_the_cogging() -> None:
    assert named_as("cogging_harmonic_2") == "cogging"
    assert named_as("cogging_harmonic_3") == "cogging"
    assert named_as("cogging") == "cogging"
    assert named_as("not_an_effect") == "not_an_effect"
    for order in (2, 3):
        e = get_effect(f"cogging_harmonic_{order}")
        assert e.refines == "cogging" and "cogging" in e.requires


def test_the_harmonics_columns_are_the_force_law() -> None:
    """The inverse-dynamics regressors of each order reproduce the plant's force law."""
    p = CL.default_plant()
    p[CL.I_COGP] = PERIOD
    x = np.linspace(-0.02, 0.02, 501)
    v = np.full_like(x, 0.05)
    base = CL.sliding_force(p, x, v)
    for order, (a, c) in ((2, (CL.I_COGH2A, CL.I_COGH2B)), (3, (CL.I_COGH3A, CL.I_COGH3B))):
        q = p.copy()
        q[a], q[c] = 7.0, -3.0
        cols, targets, scale = get_effect(f"cogging_harmonic_{order}").idim_columns(
            q, ("cogging", f"cogging_harmonic_{order}"), x, v)
        assert targets == (a, c)
        np.testing.assert_allclose(CL.sliding_force(q, x, v) - base,
                                   cols @ (np.array([7.0, -3.0]) / scale), atol=1e-9)


@pytest.fixture(scope="module")
def with_harmonic():  # type: ignore[no-untyped-def]
    return diagnose(_run(SECOND))


def test_a_second_harmonic_is_found_and_sized(with_harmonic) -> None:  # type: ignore[no-untyped-def]
    """The ripple's second harmonic (62 % of the fundamental) is named beside the cogging, its
    amplitude within 25 % of the truth."""
    res = with_harmonic
    assert "cogging" in res.effects and "cogging_harmonic_2" in res.effects, res.effects
    p = res.final.plant
    amp = math.hypot(p[CL.I_COGH2A], p[CL.I_COGH2B])
    assert amp == pytest.approx(SECOND, rel=0.25)
    assert p[CL.I_COGP] == pytest.approx(PERIOD, rel=0.01)


def test_the_harmonic_cuts_the_free_run_error(with_harmonic) -> None:  # type: ignore[no-untyped-def]
    """The same run diagnosed without the harmonics among the candidates ends with a larger
    free-run position error: what the harmonic was taken for."""
    res = with_harmonic
    names = tuple(n for n in effect_names() if not n.startswith("cogging_harmonic"))
    without = diagnose(res.run, settings=dataclasses.replace(defaults(), candidates=names))
    assert not any(e.startswith("cogging_harmonic") for e in without.effects)
    rms = res.to_dict()["position"]["rms_after"]  # type: ignore[index]
    rms_without = without.to_dict()["position"]["rms_after"]  # type: ignore[index]
    assert rms < rms_without / 1.5, (rms, rms_without)


def test_a_pure_sinusoid_names_no_harmonic() -> None:
    """The same axis with a sinusoidal cogging: the fundamental, and no harmonic."""
    res = diagnose(_run(0.0))
    assert "cogging" in res.effects, res.effects
    assert not any(e.startswith("cogging_harmonic") for e in res.effects), res.effects

"""The friction profile along the stroke as a candidate of the search (issue 46, item 1).

A friction level of any shape along the travelled range (linear between 3, 5 or 9 knots, the
count chosen by the criterion); one profile in a model, beside the gradient and sinusoid of
``position_dependent_friction``, which a report naming a profile names.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fricbench.axis import Axis, simulate
from fricbench.axis import plant as PL
from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.diagnosis import diagnose
from fricbench.sysid.diagnose.effects import (
    default_candidates,
    effect_names,
    excluded,
    get_effect,
    named_as,
)
from fricbench.sysid.diagnose.effects.friction_profile import PROFILE_KNOTS, profile_name
from fricbench.sysid.diagnose.settings import defaults
from fricbench.sysid.io import validate_arrays
from fricbench.trajectories.base import Reference


def test_one_profile_in_a_model_beside_the_gradient_and_sinusoid() -> None:
    for n in PROFILE_KNOTS:
        name = profile_name(n)
        assert named_as(name) == "position_dependent_friction"
        others = [profile_name(k) for k in PROFILE_KNOTS if k != n]
        assert all(excluded(name, ("coulomb_friction", o)) for o in others)
        assert all(excluded(o, ("coulomb_friction", name)) for o in others)
        assert not excluded(name, ("coulomb_friction", "position_dependent_friction"))
        assert not excluded("position_dependent_friction", ("coulomb_friction", name))


@pytest.mark.parametrize("n", PROFILE_KNOTS)
def test_the_profiles_columns_are_the_force_law(n: int) -> None:
    """``fc`` times the inverse-dynamics regressors, weighted by the knots, is the change of
    the plant's sliding force the profile makes (inside the range and held beyond it)."""
    rng = np.random.default_rng(n)
    eff = get_effect(profile_name(n))
    p = CL.default_plant(2.0, 0.0)
    p[CL.I_FC] = 10.0
    p = eff.placed(p, -0.03, 0.12)
    x = np.linspace(-0.08, 0.14, 701)
    v = np.where(np.arange(x.size) % 2 == 0, 0.02, -0.02)
    base = CL.sliding_force(p, x, v)
    q = p.copy()
    knots = rng.uniform(-0.5, 1.0, n - 1)
    q[list(eff.parameters)] = knots
    cols, targets, scale = eff.idim_columns(q, ("coulomb_friction", eff.name), x, v)
    assert targets == eff.parameters and np.all(scale == 0.0)
    np.testing.assert_allclose(CL.sliding_force(q, x, v) - base, 10.0 * cols @ knots,
                               atol=1e-9)


def _run(seed: int = 0):
    """A 16 s run of fricbench's axis on a sweep of reversals over 40 mm, its friction 80 %
    higher over a stretch of about a sixth of it (a dirty spot), the effort logged."""
    ts = 1e-3
    t = np.arange(16_000) * ts
    x = 0.02 * np.sin(2 * np.pi * 0.15 * t) + 0.002 * np.sin(2 * np.pi * 1.1 * t + 0.4)
    s = np.clip((t - 0.2) / 0.5, 0.0, 1.0)
    x *= s**3 * (10.0 - 15.0 * s + 6.0 * s**2)
    lo, hi = float(np.min(x)), float(np.max(x))
    axis = Axis().with_effects(friction_profile=(0.0, 0.0, 0.0, 0.8, 0.0, 0.0, 0.0),
                               friction_profile_start=lo, friction_profile_span=hi - lo,
                               noise_std=1e-7, quantization=2e-8)
    res = simulate(axis, Reference.from_positions(t, x), seed=seed)
    return validate_arrays(res.t, res.x_ref, res.x, res.u)


def test_the_profiles_are_tried_when_asked_for() -> None:
    profiles = {profile_name(n) for n in PROFILE_KNOTS}
    assert profiles <= set(effect_names())
    assert not profiles & set(default_candidates())
    assert all(get_effect(p).tried_by_default is False for p in profiles)


def test_a_dirty_stretch_is_found_and_cuts_the_error() -> None:
    """A friction level raised over a stretch of the stroke (neither a gradient nor a
    sinusoid) is named a position-dependent friction by a profile when the profiles are
    tried, and the free-run error ends below that of the same run diagnosed on the default
    candidates (which leave them out)."""
    run = _run()
    asked = default_candidates() + tuple(profile_name(n) for n in PROFILE_KNOTS)
    res = diagnose(run, settings=dataclasses.replace(defaults(), candidates=asked))
    named = {named_as(e) for e in res.effects}
    assert "position_dependent_friction" in named, res.effects
    assert any(e.startswith("friction_profile_") for e in res.effects), res.effects
    without = diagnose(run)
    assert not any(e.startswith("friction_profile_") for e in without.effects)
    rms = res.to_dict()["position"]["rms_after"]  # type: ignore[index]
    rms_without = without.to_dict()["position"]["rms_after"]  # type: ignore[index]
    assert rms < rms_without / 1.5, (rms, rms_without, res.effects, without.effects)
    p = res.final.plant
    assert int(p[PL.PD_NKNOTS]) in PROFILE_KNOTS

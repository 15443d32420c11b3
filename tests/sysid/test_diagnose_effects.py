"""The effect registry of the diagnosis, swept: every effect is a complete, consistent class."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from fricbench.axis import Axis, simulate
from fricbench.axis.plant import N_PLANT
from fricbench.registry import DuplicateIdError, UnknownIdError
from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.effects import (
    EFFECT_NAMES,
    Effect,
    effect_names,
    effect_registry,
    get_effect,
)
from fricbench.sysid.diagnose.parameters import Bounds
from fricbench.sysid.diagnose.prepared import prepare
from fricbench.sysid.io import validate_arrays
from fricbench.trajectories import make_trajectory

BOUNDS = Bounds(force=2.0, stroke=0.05, v_max=0.05, duration=8.0, ts=1e-3, noise=2e-7)


@pytest.fixture(scope="module")
def prep():  # type: ignore[no-untyped-def]
    res = simulate(Axis(), make_trajectory("reversal_sine"), seed=0)
    return prepare(validate_arrays(res.t, res.x_ref, res.x, res.u))


def test_builtin_effects_in_search_order() -> None:
    assert EFFECT_NAMES == ("coulomb_friction", "stribeck_friction", "asymmetric_friction",
                            "force_offset", "backlash", "cogging", "cogging_harmonic_2",
                            "cogging_harmonic_3", "position_dependent_friction",
                            "friction_profile_3", "friction_profile_5", "friction_profile_9",
                            "thermal_drift", "thermal_strain", "compliance")
    assert effect_names()[: len(EFFECT_NAMES)] == EFFECT_NAMES


@pytest.mark.parametrize("name", effect_names())
def test_effect_is_consistent(name: str, prep) -> None:  # type: ignore[no-untyped-def]
    e = get_effect(name)
    assert isinstance(e, Effect) and e.name == name
    assert e.kind in ("force", "output")
    assert all(r in effect_names() for r in e.requires)
    assert e.parameters and all(0 <= i < N_PLANT for i in e.parameters)
    assert set(e.shape_parameters) <= set(e.parameters)
    assert set(e.force_parameters) <= set(e.parameters)
    assert e.summary
    p = get_effect(name).switched_on(CL.default_plant(), prep)
    for changes, fixed in e.probes(p, (name,), prep, BOUNDS, prep.x):
        assert set(changes) <= set(e.parameters)
        for i, v in {**changes, **fixed}.items():
            assert math.isfinite(v), (i, v)
            p[i] = v
    for i in e.free((name,)):
        prm = e.bounds(i, float(p[i]) or 1.0, BOUNDS)
        assert prm.target == i and prm.lo < prm.hi and prm.scale > 0
        lo, hi = prm.bounds()
        assert math.isfinite(lo) and math.isfinite(hi) and lo < hi
        assert math.isfinite(e.clip(i, 1e9, BOUNDS)) and math.isfinite(e.clip(i, -1e9, BOUNDS))
    described = e.describe(p, "N")
    assert described and all(math.isfinite(v) for v in described.values())
    # switched off: its sizes are zero, its shape is kept
    q = e.zeroed(p, (name,))
    for i in e.free((name,)):
        assert q[i] == (p[i] if i in e.shape_parameters else 0.0)
    if e.kind == "force":
        cols, targets, scale = e.idim_columns(p, (name,), prep.xf, prep.vf)
        assert cols.shape == (prep.n, len(targets)) == (prep.n, scale.shape[0])
        assert np.all(np.isfinite(cols))
    else:
        with pytest.raises(ValueError, match="not a force effect"):
            e.idim_columns(p, (name,), prep.xf, prep.vf)


def test_zeroed_plant_simulates_as_without_effect(prep) -> None:  # type: ignore[no-untyped-def]
    """Switching an effect off through its class leaves the plant of the model without it."""
    from fricbench.sysid.diagnose.controllers import CascadeController
    from fricbench.sysid.diagnose.models import GreyBox, simulate_models

    ctrl = CascadeController(wv=300.0, kp=100.0, ki=20.0, kvff=1.0)
    base = GreyBox(ctrl, CL.default_plant(), ())
    p = base.plant.copy()
    p[CL.I_COGA], p[CL.I_COGP] = 0.5, 0.004
    with_cog = GreyBox(ctrl, p, ("cogging",))
    ys = simulate_models([base, with_cog, with_cog.without("cogging")], prep)[0]
    assert not np.array_equal(ys[0], ys[1])
    assert np.array_equal(ys[0], ys[2])


def test_registry_errors() -> None:
    with pytest.raises(UnknownIdError, match="did you mean 'cogging'"):
        get_effect("coging")
    with pytest.raises(DuplicateIdError):
        effect_registry.register("cogging", "fricbench.sysid.diagnose.effects.cogging:Cogging")


def test_plugin_effect_joins_the_search_order() -> None:
    """A third-party effect registers by id and is tried after the built-in ones."""
    from fricbench.sysid.diagnose.effects.offset import ForceOffset

    class Gravity(ForceOffset):
        name = "gravity_test"
        summary = "a test plug-in"

    effect_registry.register("gravity_test", Gravity)
    try:
        assert effect_names()[-1] == "gravity_test"
        assert get_effect("gravity_test").name == "gravity_test"
    finally:
        effect_registry.unregister("gravity_test")
        get_effect.cache_clear()
    assert "gravity_test" not in effect_names()


def test_a_failed_screen_sends_a_friction_level_effect_to_a_real_fit() -> None:
    """The position search fits an effect whose linearised screen failed (its held-out ratio
    above 1: no cut at all) for real when the effect says its screen cannot be
    trusted; the others keep their rank; the always-fitted ones are fitted whatever the screen."""
    from fricbench.sysid.diagnose.search import _fitted_anyway

    posdep = "position_dependent_friction"
    assert get_effect(posdep).fitted_when_screen_fails
    assert _fitted_anyway(posdep, 1.01)
    assert not _fitted_anyway(posdep, 0.99)
    assert not _fitted_anyway("force_offset", 100.0)
    for name in effect_names():
        if get_effect(name).always_fitted:
            assert _fitted_anyway(name, 0.5) and _fitted_anyway(name, 100.0)


@pytest.mark.parametrize(("duration", "floor"), [(8.0, 0.5), (600.0, 6.0)])
def test_a_thermal_time_constant_is_never_below_half_a_second(duration: float,
                                                             floor: float) -> None:
    b = replace(BOUNDS, duration=duration)
    par = get_effect("thermal_drift").bounds(CL.I_THT, duration / 10.0, b)
    # half a second on a short run; a hundredth of the run on a long one
    assert par.lo == pytest.approx(floor)
    assert par.hi == pytest.approx(20.0 * duration)


@pytest.mark.parametrize("name", ["coulomb_friction", "stribeck_friction", "force_offset",
                                  "asymmetric_friction", "cogging"])
def test_raised_friction_bounds_widen_the_level_and_keep_the_starts(name: str, prep) -> None:  # type: ignore[no-untyped-def]
    """``Bounds.friction_raise`` widens the bound and the clip of a force level (a friction
    level, a detent force) by that factor; its probes (fractions of the force scale) do not
    move."""
    effect = get_effect(name)
    raised = replace(BOUNDS, friction_raise=10.0)
    assert raised.friction == pytest.approx(10.0 * BOUNDS.force)
    p = effect.switched_on(CL.default_plant(1.0, 0.0), prep)
    p[CL.I_FC] = 0.5 * BOUNDS.force
    levels = [i for i in effect.parameters if i not in effect.shape_parameters
              and i != CL.I_DB]
    assert levels
    for i in levels:
        assert effect.bounds(i, 0.0, raised).hi == pytest.approx(
            10.0 * effect.bounds(i, 0.0, BOUNDS).hi)
        big = 100.0 * BOUNDS.force
        assert effect.clip(i, big, raised) == pytest.approx(10.0 * effect.clip(i, big, BOUNDS))
    effects = ("coulomb_friction",) if name == "coulomb_friction" else ("coulomb_friction", name)
    assert (effect.probes(p, effects, prep, BOUNDS, prep.x)
            == effect.probes(p, effects, prep, raised, prep.x))


def test_a_stribeck_start_may_sit_well_below_the_coulomb_level() -> None:
    """The clip of a Stribeck start keeps it visible (above zero) but not above the friction a
    servo axis has: where the force scale (the largest command) is 50 times the Coulomb level
    (a stiff loop on a light axis, stribeck/28 of the second simulator: Coulomb friction at
    1.8 % of it, the stiction's excess at 0.9 %), a floor at 2 % of the force scale put every
    start above the whole friction, and no fit of a few iterations came back from there."""
    effect = get_effect("stribeck_friction")
    for share in (0.005, 0.009, 0.05):
        assert effect.clip(CL.I_FS, share * BOUNDS.force, BOUNDS) == pytest.approx(
            share * BOUNDS.force)
    assert effect.clip(CL.I_FS, 0.0, BOUNDS) > 0.0
    assert effect.clip(CL.I_FS, -1.0, BOUNDS) > 0.0


@pytest.mark.parametrize("name", [n for n in effect_names() if get_effect(n).kind == "force"
                                  and n != "coulomb_friction"])
def test_the_screens_inverse_dynamics_start_holds_on_a_run_without_a_drive_limit(
        name: str, prep) -> None:  # type: ignore[no-untyped-def]
    """A model without a drive limit holds an infinite one in its plant row (``I_IMAX``): the
    start the screen takes from the inverse dynamics of an effort must not be set aside for it
    (it was, on every such run, from the one-plant redesign on). Its fitted entries are
    finite; the limit stays infinite."""
    from fricbench.sysid.diagnose.controllers import CascadeController
    from fricbench.sysid.diagnose.models import GreyBox, InverseDynamics
    from fricbench.sysid.diagnose.search import _idim_probe

    p = CL.default_plant(1.0, 0.0)
    p[CL.I_FC] = 0.1 * BOUNDS.force
    assert math.isinf(p[CL.I_IMAX])
    model = GreyBox(CascadeController(wv=300.0, kp=100.0, ki=20.0, kvff=1.0), p,
                    ("coulomb_friction",))
    probe = _idim_probe(model, name, prep, BOUNDS, InverseDynamics(prep, prep.u))
    assert probe is not None and probe.ref is not None
    assert probe.ref.effects == ("coulomb_friction", name)
    ref = probe.ref.plant
    assert all(math.isfinite(ref[i]) for i in get_effect(name).free(probe.ref.effects))
    assert math.isinf(ref[CL.I_IMAX])

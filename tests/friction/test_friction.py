"""Friction models: every registered law, validation, true stiction and passivity."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.axis import Axis, simulate
from fricbench.friction import FrictionModel, friction_registry, make_friction
from fricbench.trajectories import Reference

ALL = friction_registry.ids()
STATIC = [i for i in ALL if not make_friction(i).is_dynamic]


def _open_loop_axis(model: FrictionModel) -> Axis:
    """Controller off: the motor force is exactly the compensation input."""
    return Axis(friction=model).with_controller(kp=0.0, kvff=0.0, kv=0.0, ti=0.0)


def _still(seconds: float) -> Reference:
    t = np.arange(0.0, seconds, 1e-3)
    z = np.zeros_like(t)
    return Reference(t, z, z, z, "still")


@pytest.mark.parametrize("fid", ALL)
def test_force_law_is_odd_vectorised_and_finite(fid: str) -> None:
    model = make_friction(fid)
    v = np.linspace(-0.1, 0.1, 201)
    f = model.force(v)
    assert f.shape == v.shape and np.all(np.isfinite(f))
    np.testing.assert_allclose(f, -model.force(-v), atol=1e-12)
    assert np.all(f[v > 0] >= 0.0)
    assert model.force(0.01).shape == ()


@pytest.mark.parametrize("fid", ALL)
def test_round_trip_dict(fid: str) -> None:
    model = make_friction(fid)
    d = model.to_dict()
    assert make_friction(d.pop("id"), **d) == model


@pytest.mark.parametrize("fid,param", [("stribeck", "vs"), ("stribeck", "fc"),
                                       ("lugre", "sigma0"), ("coulomb", "fc"),
                                       ("viscous", "fv"), ("dahl", "sigma0")])
def test_invalid_parameter_named(fid: str, param: str) -> None:
    with pytest.raises(ValueError, match=param):
        make_friction(fid, **{param: -1.0})


def test_static_below_coulomb_rejected() -> None:
    with pytest.raises(ValueError, match="fs"):
        make_friction("stribeck", fc=300.0, fs=200.0)


def test_stribeck_matches_paper_equation() -> None:
    m = make_friction("stribeck", fc=300.0, fs=450.0, vs=2e-3)
    v = np.array([1e-3, 2e-3, 1e-2])
    expected = 300.0 + 150.0 * np.exp(-((v / 2e-3) ** 2))
    np.testing.assert_allclose(m.force(v), expected, rtol=1e-12)


@pytest.mark.parametrize("fid", [i for i in STATIC if i != "viscous"])
def test_true_stiction_holds_below_breakaway(fid: str) -> None:
    model = make_friction(fid)
    ref = _still(1.0)
    push = 0.95 * model.breakaway_force * np.ones(ref.n_samples)
    res = simulate(_open_loop_axis(model), ref, u_force=push)
    assert np.max(np.abs(res.x_true)) < 1e-9  # drift < 1 nm over 1 s


@pytest.mark.parametrize("fid", [i for i in STATIC if i != "viscous"])
def test_breaks_away_above_static_level(fid: str) -> None:
    model = make_friction(fid)
    ref = _still(0.2)
    push = 1.05 * model.breakaway_force * np.ones(ref.n_samples)
    res = simulate(_open_loop_axis(model), ref, u_force=push)
    assert res.x_true[-1] > 1e-6


@pytest.mark.parametrize("fid", ALL)
def test_friction_never_adds_energy(fid: str) -> None:
    """Coasting from 20 mm/s with the motor off: kinetic plus bristle energy never grows."""
    from fricbench.axis import AxisBatch
    from fricbench.axis.kernel import S_Z

    model = make_friction(fid)
    axis = _open_loop_axis(model).with_mechanics(damping=0.0)
    sigma0 = model.kernel_params()["sigma0"]
    batch = AxisBatch(axis)
    batch.reset(0.0, 0.02)
    energy = []
    for _ in range(500):
        one = np.zeros((1, 1))
        batch.run(one, one, one)
        # E = M v^2 / 2 + sigma0 z^2 / 2
        energy.append(0.5 * axis.mechanics.mass * batch.velocity[0] ** 2
                      + 0.5 * sigma0 * batch.S[0, S_Z] ** 2)
    e = np.asarray(energy)
    assert np.all(np.isfinite(e))
    # static laws: exactly dissipative; bristle models exchange energy with the mass through a
    # semi-implicit substep, which leaves a discretisation ripple of order h (< 1e-5 of E)
    tol = 1e-12 if sigma0 == 0.0 else 1e-5
    assert np.all(np.diff(e) <= tol * e[0])
    assert e[-1] < 0.5 * e[0]


@pytest.mark.parametrize("fid", STATIC)
def test_friction_dissipates_under_random_forcing(fid: str) -> None:
    model = make_friction(fid)
    ref = _still(2.0)
    rng = np.random.default_rng(3)
    force = np.repeat(rng.uniform(-1.5, 1.5, ref.n_samples // 50), 50) * max(
        model.breakaway_force, 100.0)
    res = simulate(_open_loop_axis(model), ref, u_force=force)
    work = res.friction[:-1] * np.diff(res.x_true)
    # friction work is dissipated; a sample whose velocity changes sign inside it can show a
    # tiny negative mean-force x displacement product, never a net gain
    assert work.sum() > 0.0
    assert -work[work < 0].sum() <= 1e-3 * work[work > 0].sum()


@pytest.mark.parametrize("delta", [2.0, 1.0, 0.6])
def test_stribeck_taylor_matches_level_and_its_derivatives(delta: float) -> None:
    from fricbench.friction.laws import stribeck_level, stribeck_level_taylor

    fc, fs, vs = 300.0, 480.0, 0.003
    for speed in (1e-4, 0.001, 0.003, 0.008):
        g, dg, d2g = stribeck_level_taylor(speed, fc, fs, 1.0 / vs, delta)
        assert g == pytest.approx(stribeck_level(speed, fc, fs, vs, delta), rel=1e-12)
        h = 1e-7
        up = stribeck_level(speed + h, fc, fs, vs, delta)
        dn = stribeck_level(speed - h, fc, fs, vs, delta)
        assert dg == pytest.approx((up - dn) / (2 * h), rel=1e-5)
        assert d2g == pytest.approx((up - 2 * g + dn) / h**2, rel=1e-3, abs=1e-3 * abs(dg) / vs)
    # far above vs the law is plain Coulomb, with no slope
    assert stribeck_level_taylor(50.0, fc, fs, 1.0 / vs, delta) == (fc, 0.0, 0.0)
    assert stribeck_level_taylor(0.001, fc, fs, 0.0, delta) == (fc, 0.0, 0.0)

"""Building blocks of the diagnosis: the grey-box simulator against the axis kernel (oracle),
the controller and inverse-dynamics fits, period search, noise floor, least squares."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import optimize

from fricbench.axis import Axis, simulate
from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.controllers import CascadeController, LoopInputs, fit_arx_controller
from fricbench.sysid.diagnose.effects import EFFECT_NAMES, describe_parameters
from fricbench.sysid.diagnose.leastsq import bounded_least_squares, solve_ls
from fricbench.sysid.diagnose.models import (
    Bounds,
    GreyBox,
    InverseDynamics,
    JointPositionFit,
    PositionFit,
    position_params,
    race_fits,
    simulate_inputs,
    simulate_models,
    simulate_position,
)
from fricbench.sysid.diagnose.prepared import prepare
from fricbench.sysid.diagnose.signals import block_folds, noise_floor, period_candidates
from fricbench.sysid.io import validate_arrays
from fricbench.trajectories.base import Reference


def _reference(duration: float = 6.0, ts: float = 1e-3) -> Reference:
    t = np.arange(int(duration / ts)) * ts
    # two sines and a slow sweep: reversals at many positions and speeds
    x = 0.008 * np.sin(2 * np.pi * 0.4 * t) + 0.002 * np.sin(2 * np.pi * 1.7 * t + 0.3)
    # start at rest: 0.2 s still, then a smooth (C2) 0.5 s fade-in
    s = np.clip((t - 0.2) / 0.5, 0.0, 1.0)
    x *= s**3 * (10.0 - 15.0 * s + 6.0 * s**2)
    return Reference.from_positions(t, x)


def _grey_box_of(axis: Axis) -> GreyBox:
    """The exact grey-box counterpart of a fricbench axis (mass normalised to 1)."""
    c, m, e, f = axis.controller, axis.mechanics, axis.effects, axis.friction
    ctrl = CascadeController(wv=c.kv * c.kt / m.mass, kp=c.kp, ki=1.0 / c.ti, kvff=c.kvff,
                             kaff=c.kaff)
    p = CL.default_plant(1.0, m.damping / m.mass)
    p[CL.I_FC] = f.fc / m.mass
    p[CL.I_FS] = (f.fs - f.fc) / m.mass
    p[CL.I_VS] = f.vs
    p[CL.I_COGA] = e.cogging_amplitude * math.cos(e.cogging_phase) / m.mass
    p[CL.I_COGB] = e.cogging_amplitude * math.sin(e.cogging_phase) / m.mass
    p[CL.I_COGP] = e.cogging_period
    p[CL.I_PDG] = e.friction_gradient
    p[CL.I_PDA] = e.friction_variation * math.cos(e.friction_variation_phase)
    p[CL.I_PDB] = e.friction_variation * math.sin(e.friction_variation_phase)
    p[CL.I_PDP] = e.friction_variation_period
    p[CL.I_BL] = e.backlash
    p[CL.I_THA] = e.thermal_drift
    p[CL.I_THT] = e.thermal_time_constant
    return GreyBox(ctrl, p, EFFECT_NAMES)


def test_simulator_matches_the_axis_kernel_with_every_effect():
    """Oracle: with the axis's own parameters the grey box reproduces the project kernel."""
    ref = _reference()
    axis = Axis().with_effects(cogging_amplitude=80.0, cogging_period=4e-3, cogging_phase=0.7,
                               friction_variation=0.3, friction_variation_period=0.02,
                               friction_variation_phase=1.1, friction_gradient=0.5,
                               backlash=4e-6, thermal_drift=5e-6, thermal_time_constant=3.0)
    res = simulate(axis, ref)
    run = validate_arrays(res.t, res.x_ref, res.x)
    prep = prepare(run, n_sub=axis.controller.n_substeps)
    prep.inputs = LoopInputs(prep.inputs.t, prep.inputs.ts, ref.x, ref.v, ref.a,
                             float(ref.x[0]), float(ref.v[0]), 0.0)
    y, _ = simulate_position(_grey_box_of(axis), prep)
    # equal up to the rounding of a stick/slip decision now and then (a few nm)
    assert np.max(np.abs(y - res.x)) < 2e-8
    # and the effects matter: without them the prediction is far off
    y0, _ = simulate_position(_grey_box_of(axis.with_effects(
        cogging_amplitude=0.0, backlash=0.0, thermal_drift=0.0, friction_variation=0.0)), prep)
    assert np.max(np.abs(y0 - res.x)) > 1e-6


def test_arx_controller_recovers_the_cascade_law():
    ref = _reference()
    res = simulate(Axis(), ref)
    folds = block_folds(ref.n_samples)
    ctrl = fit_arx_controller(ref.x, ref.v, res.x, res.u, 1e-3, folds)
    assert ctrl.a.shape == (1,) and ctrl.a[0] == pytest.approx(1.0, abs=1e-6)  # integral
    u_hat = ctrl.predict(ref.x, ref.v, res.x, res.u, 1e-3)
    # the ends differ: one-sided reference differences there
    err = (u_hat - res.u)[5:-5]
    assert np.sqrt(np.mean(err**2)) < 1e-5 * np.sqrt(np.mean(res.u**2))


def test_inverse_dynamics_recovers_mass_damping_and_coulomb():
    ref = _reference(duration=10.0)
    axis = Axis().with_friction("coulomb", fc=250.0).with_mechanics(mass=300.0, damping=150.0)
    res = simulate(axis, ref)
    prep = prepare(validate_arrays(res.t, res.x_ref, res.x, res.u))
    idim = InverseDynamics(prep, res.u)
    p = idim.fit(("coulomb_friction",), CL.default_plant(1.0, 0.0))
    assert p[CL.I_M] == pytest.approx(300.0, rel=0.05)
    assert p[CL.I_FC] == pytest.approx(250.0, rel=0.03)
    assert 75.0 < p[CL.I_B] < 300.0  # weakly excited by this reference


def test_inverse_dynamics_held_out_error_per_block_adds_up():
    """``cv_blocks`` splits ``cv_sse`` into the held-out blocks (fold 0's first), with the same
    total and fold fits."""
    ref = _reference(duration=6.0)
    axis = Axis().with_friction("coulomb", fc=250.0).with_mechanics(mass=300.0, damping=150.0)
    res = simulate(axis, ref)
    prep = prepare(validate_arrays(res.t, res.x_ref, res.x, res.u))
    idim = InverseDynamics(prep, res.u)
    effects = ("coulomb_friction",)
    total, fits = idim.cv_sse(effects, CL.default_plant(1.0, 0.0))
    total_b, blocks, fits_b = idim.cv_blocks(effects, CL.default_plant(1.0, 0.0))
    assert total_b == total
    n_blocks = 1 + int(np.count_nonzero(np.diff(prep.folds_dec)))
    assert blocks.shape == (n_blocks,) and np.all(blocks >= 0.0)
    assert float(np.sum(blocks)) == pytest.approx(total, rel=1e-12)
    for a, b in zip(fits, fits_b, strict=True):
        np.testing.assert_array_equal(a, b)


def _cogging_fit(period: float) -> tuple[InverseDynamics, np.ndarray, np.ndarray]:
    """A 10 s run of fricbench's axis with a 150 N cogging of ``period`` (m): its inverse
    dynamics, the Coulomb-only fit and the fit with the cogging found."""
    ref = _reference(duration=10.0)
    axis = Axis().with_effects(cogging_amplitude=150.0, cogging_period=period,
                               cogging_phase=0.4)
    res = simulate(axis, ref)
    prep = prepare(validate_arrays(res.t, res.x_ref, res.x, res.u))
    idim = InverseDynamics(prep, res.u)
    base = idim.fit(("coulomb_friction",), CL.default_plant(1.0, 0.0))
    return idim, base, idim.fit(("coulomb_friction", "cogging"), base, new="cogging")


def test_inverse_dynamics_finds_a_cogging_period_continuously():
    _, _, p = _cogging_fit(3.37e-3)
    par = describe_parameters("cogging", p, "N")
    # not a grid value: the period is refined continuously
    assert par["period_m"] == pytest.approx(3.37e-3, rel=2e-3)
    assert par["amplitude_N"] == pytest.approx(150.0, rel=0.15)


def test_inverse_dynamics_finds_a_cogging_period_longer_than_half_the_stroke():
    """A ripple whose period is 0.7 of the stroke (1.4 periods over it): the period is searched
    up to the stroke (a periodic force's constraint), found within 2 %, and the
    direction-independent ripple explains the held-out effort better than a friction level
    varying along the stroke with the same period (which changes sign with the motion). With
    periods searched only up to half the stroke, the second simulator's cogging/12 (0.70 of its
    stroke) was named a position-dependent friction."""
    stroke = float(np.ptp(_reference(duration=10.0).x))
    period = 0.7 * stroke
    idim, base, p = _cogging_fit(period)
    assert describe_parameters("cogging", p, "N")["period_m"] == pytest.approx(period, rel=0.02)
    sse_base, _ = idim.cv_sse(("coulomb_friction",), base)
    sse_cog, _ = idim.cv_sse(("coulomb_friction", "cogging"), base, new="cogging")
    sse_pd, _ = idim.cv_sse(("coulomb_friction", "position_dependent_friction"), base,
                            new="position_dependent_friction")
    assert sse_cog < 0.5 * sse_base
    assert sse_cog < sse_pd


def test_inverse_dynamics_levels_under_a_held_variation_along_the_stroke():
    """``fit_levels`` solves the mass, damping and force levels with the relative variation of
    the friction level held: from a plant row per unit mass holding the axis's true variation it
    recovers the mass and Coulomb level in newtons, and the true variation explains the
    effort far better than none or the opposite variation (what the position mode's effort
    check judges a variation the position found with)."""
    ref = _reference(duration=10.0)
    stroke = float(np.ptp(ref.x))
    axis = (Axis().with_mechanics(mass=300.0, damping=150.0)
            .with_effects(friction_gradient=1.0, friction_variation=0.25,
                          friction_variation_period=0.8 * stroke,
                          friction_variation_phase=0.7))
    res = simulate(axis, ref)
    prep = prepare(validate_arrays(res.t, res.x_ref, res.x, res.u))
    idim = InverseDynamics(prep, res.u)
    true = _grey_box_of(axis).plant  # per unit mass
    effects = ("coulomb_friction", "stribeck_friction", "position_dependent_friction")
    p = idim.fit_levels(effects, true)
    assert p[CL.I_M] == pytest.approx(300.0, rel=0.05)
    assert p[CL.I_FC] == pytest.approx(axis.friction.fc, rel=0.03)
    for i in (CL.I_PDG, CL.I_PDA, CL.I_PDB, CL.I_PDP, CL.I_VS):
        assert p[i] == true[i]  # held
    rows = prep.sliding_dec

    def sse(q: np.ndarray) -> float:
        return float(np.sum((idim.u_dec - idim.predict(q))[rows] ** 2))

    flat = true.copy()
    flat[[CL.I_PDG, CL.I_PDA, CL.I_PDB]] = 0.0
    wrong = true.copy()
    wrong[[CL.I_PDG, CL.I_PDA, CL.I_PDB]] *= -1.0
    assert sse(p) < 0.25 * sse(idim.fit_levels(effects, flat))
    assert sse(p) < 0.25 * sse(idim.fit_levels(effects, wrong))
    # in the model's own unit it is the least-squares solution of those columns: the Coulomb-only
    # row (no variation) gives what fit() gives for Coulomb friction alone
    alone = idim.fit_levels(("coulomb_friction",), CL.default_plant(1.0, 0.0))
    np.testing.assert_allclose(alone[[CL.I_M, CL.I_B, CL.I_FC]],
                               idim.fit(("coulomb_friction",), CL.default_plant(1.0, 0.0))[
                                   [CL.I_M, CL.I_B, CL.I_FC]], rtol=1e-6)


def test_period_candidates_on_a_synthetic_residual():
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.uniform(-1e-5, 1e-5, 20000)) + np.linspace(0, 0.05, 20000)
    r = np.sin(2 * np.pi * x / 2.5e-3) + 0.5 * rng.standard_normal(x.size)
    periods = period_candidates(x, r, np.ones(x.size, dtype=bool), 1e-3, 0.01)
    assert periods and periods[0] == pytest.approx(2.5e-3, rel=0.02)


@pytest.mark.parametrize("seed", range(1, 11))
def test_period_candidates_when_the_stroke_holds_few_periods(seed: int) -> None:
    """3 to 4 periods over the stroke beside a slope up to 5 times the ripple's amplitude over
    the stroke (a friction changing along it) and noise: the periodogram's peak alone was off
    by up to 10 % on these (and by 11 % on a 100 Hz log of the second simulator's cogging/10,
    out of a fit's reach); the least-squares sinusoid with a line is within 0.2 %."""
    rng = np.random.default_rng(seed)
    stroke = 0.04
    period = stroke / rng.uniform(3.0, 4.0)
    x = np.concatenate([np.linspace(0.0, stroke, 900), np.linspace(stroke, 0.0, 900)])
    x = x + rng.normal(0.0, 1e-5, x.size)
    r = (np.sin(2 * np.pi * x / period + rng.uniform(0, 2 * np.pi))
         + rng.uniform(-5.0, 5.0) * (x - stroke / 2) / stroke
         + 0.3 * rng.standard_normal(x.size))
    periods = period_candidates(x, r, np.ones(x.size, dtype=bool), 1e-3, stroke / 2)
    assert periods and periods[0] == pytest.approx(period, rel=0.01)


def test_noise_floor_detects_noise_and_encoder_step():
    rng = np.random.default_rng(1)
    t = np.arange(20000) * 1e-3
    x_ref = 0.01 * np.sin(2 * np.pi * 0.3 * t)
    noisy = noise_floor(x_ref + 2e-7 * rng.standard_normal(t.size), x_ref)
    assert noisy.sigma == pytest.approx(2e-7, rel=0.1) and noisy.quantum == 0.0
    q = 5e-8
    stepped = noise_floor(q * np.round(x_ref / q), x_ref)
    assert stepped.quantum == pytest.approx(q, rel=1e-6)
    assert q / math.sqrt(12.0) <= stepped.rms < 2 * q / math.sqrt(12.0)


def test_solve_ls_with_sign_constraints():
    rng = np.random.default_rng(2)
    X = rng.standard_normal((500, 3))
    y = X @ np.array([1.0, -0.5, 2.0])
    assert solve_ls(X, y) == pytest.approx([1.0, -0.5, 2.0])
    c = solve_ls(X, y, nonneg=np.array([False, True, False]))
    assert c[1] == 0.0


def test_solve_ls_is_the_constrained_optimum():
    """Two anti-correlated columns both come out negative unconstrained; clamping one makes
    the other positive: the solution is the constrained optimum (clamping both at once, as an
    active set that never frees a coefficient does, is not)."""
    rng = np.random.default_rng(3)
    X = rng.standard_normal((400, 3))
    X[:, 2] = -X[:, 1] + 0.3 * rng.standard_normal(400)
    y = X @ np.array([1.0, -1.0, -0.1]) + 0.01 * rng.standard_normal(400)
    nonneg = np.array([False, True, True])
    c = solve_ls(X, y, nonneg)
    ref = optimize.lsq_linear(X, y, bounds=([-np.inf, 0.0, 0.0], np.inf)).x
    assert c[1] == 0.0 and c[2] > 0.5
    assert c == pytest.approx(ref, abs=1e-6)


def test_bounded_least_squares_respects_bounds():
    target = np.array([0.3, -2.0])

    def residuals(thetas: np.ndarray) -> np.ndarray:
        return np.array([np.r_[th - target, 0.1 * th[0] * th[1]] for th in thetas])

    sol = bounded_least_squares(residuals, np.array([1.0, 1.0]), np.array([0.0, -1.0]),
                                np.array([2.0, 2.0]), np.array([1e-6, 1e-6]), max_iter=50)
    assert sol.x[1] == pytest.approx(-1.0)  # held at the bound
    assert 0.0 <= sol.x[0] <= 2.0
    assert sol.jac.shape == (3, 2)


@pytest.mark.parametrize("max_iter", [0, 1, 3, 50])
def test_a_fit_without_its_last_jacobian_ends_on_the_same_numbers(max_iter: int) -> None:
    """Without the Jacobian at the end point, a fit that ends on max_iter simulates one batch
    fewer and returns the same point, cost and residual, bit for bit; one that stops before
    (max_iter 50: the cost stops falling) or never steps (max_iter 0) keeps its Jacobian."""
    target = np.array([0.3, -2.0, 0.7])

    def counted(rows: list[int]):
        def residuals(thetas: np.ndarray) -> np.ndarray:
            rows.append(thetas.shape[0])
            return np.array([np.r_[th - target, np.sin(th[0] * th[1]), th[2] ** 3]
                             for th in thetas])
        return residuals

    args = (np.array([1.0, 1.0, 1.0]), np.array([0.0, -3.0, -1.0]), np.array([2.0, 2.0, 2.0]),
            np.array([1e-6, 1e-6, 1e-6]))
    with_rows: list[int] = []
    without_rows: list[int] = []
    a = bounded_least_squares(counted(with_rows), *args, max_iter=max_iter)
    b = bounded_least_squares(counted(without_rows), *args, max_iter=max_iter,
                              final_jacobian=False)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.fun, b.fun)
    assert a.cost == b.cost
    if max_iter in (1, 3):
        assert a.nfev == max_iter + 1  # it ended on max_iter
        assert b.jac is None and sum(without_rows) == sum(with_rows) - 3
    else:
        assert b.jac.shape == (5, 3) and without_rows == with_rows


def test_joint_position_fit_of_one_run_is_the_position_fit():
    """The joint fit stacks runs; with one run it is the single-run output-error fit."""
    ref = _reference(duration=4.0)
    axis = Axis().with_effects(noise_std=0.1e-6)
    res = simulate(axis, ref, seed=1)
    prep = prepare(validate_arrays(res.t, res.x_ref, res.x))
    start = _grey_box_of(Axis()).copy(effects=("coulomb_friction", "stribeck_friction"))
    start.plant[CL.I_FC] *= 1.3
    b = Bounds(force=5.0, stroke=prep.stroke, v_max=prep.v_max, duration=prep.duration,
               ts=prep.ts, noise=prep.noise.rms)
    params = position_params(start, b, controller=False)
    single = PositionFit(prep, params).run(start, max_iter=6)
    joint, cost = JointPositionFit([prep], params).run(start, max_iter=6)
    np.testing.assert_allclose(joint.plant, single.model.plant, rtol=1e-12)
    assert cost == pytest.approx(single.cost, rel=1e-12)
    # the fit moved the Coulomb level back towards the truth (0.875 m/s^2)
    assert abs(joint.plant[CL.I_FC] - 0.875) < 0.3 * abs(start.plant[CL.I_FC] - 0.875)
    # simulate_inputs is simulate_models without a measured run
    y1 = simulate_inputs([joint], prep.inputs, prep.n_sub)[0]
    np.testing.assert_array_equal(y1, simulate_models([joint], prep)[0])
    with pytest.raises(ValueError, match="preps is empty"):
        JointPositionFit([], params)



def test_starts_that_race_spend_the_budget_on_the_best_heats(monkeypatch) -> None:
    """Three starts of a friction fit race (``race_share`` a third): each runs a third of the
    budget, only the best heat (a third of three) runs the rest, from where it ended (the
    same numbers as going on by hand), and ends as low as the best of the three whole fits;
    of six starts the two best heats go on; one finalist per family; a single start, or a
    race share of 1 (the default), is the whole fit, bit for bit; a share the caller passes
    races whatever the setting."""
    from dataclasses import replace

    from fricbench.sysid.diagnose import settings as S

    assert S.DEFAULT_SETTINGS.race_share == 1.0
    default = S.DEFAULT_SETTINGS
    monkeypatch.setattr(S, "DEFAULT_SETTINGS", replace(default, race_share=1.0 / 3.0))

    ref = _reference(duration=2.0)
    axis = Axis().with_effects(noise_std=0.1e-6)
    res = simulate(axis, ref, seed=3)
    prep = prepare(validate_arrays(res.t, res.x_ref, res.x))
    truth = _grey_box_of(Axis()).copy(effects=("coulomb_friction", "stribeck_friction"))
    b = Bounds(force=5.0, stroke=prep.stroke, v_max=prep.v_max, duration=prep.duration,
               ts=prep.ts, noise=prep.noise.rms)
    params = position_params(truth, b, controller=False)
    starts = []
    for factor in (3.0, 1.2, 0.3):
        st = truth.copy()
        st.plant[CL.I_FC] *= factor
        starts.append(st)
    fit = PositionFit(prep, params)
    raced = race_fits([(fit, st) for st in starts], 6)
    heats = [fit.run(st, max_iter=2) for st in starts]
    winner = int(np.argmin([h.cost for h in heats]))
    assert [r is None for r in raced] == [i != winner for i in range(3)]
    by_hand = fit.run(heats[winner].model, max_iter=4)
    np.testing.assert_array_equal(raced[winner].model.plant, by_hand.model.plant)
    assert raced[winner].cost == by_hand.cost <= heats[winner].cost
    whole = [fit.run(st, max_iter=6) for st in starts]
    assert raced[winner].cost <= 1.05 * min(w.cost for w in whole)
    # a family per start: every start is its family's best heat and finishes
    assert all(r is not None for r in race_fits([(fit, st) for st in starts], 6,
                                                family=lambda m: m.plant[CL.I_FC]))
    # an eligibility test keeps a heat out of the final
    shut = race_fits([(fit, st) for st in starts], 6, eligible=lambda i, h: i != winner)
    assert shut[winner] is None and sum(r is not None for r in shut) == 1
    alone = race_fits([(fit, starts[1])], 6)[0]
    np.testing.assert_array_equal(alone.model.plant, whole[1].model.plant)
    # six starts: a third of them, the two best heats, go on (successive halving, eta = 3)
    six = starts + [st.copy() for st in starts]
    for st, factor in zip(six[3:], (2.0, 0.8, 0.5), strict=True):
        st.plant[CL.I_FC] = truth.plant[CL.I_FC] * factor
    raced6 = race_fits([(fit, st) for st in six], 6)
    heats6 = [fit.run(st, max_iter=2).cost for st in six]
    assert ([i for i, r in enumerate(raced6) if r is not None]
            == sorted(int(i) for i in np.argsort(heats6, kind="stable")[:2]))
    monkeypatch.setattr(S, "DEFAULT_SETTINGS", default)
    every = race_fits([(fit, st) for st in starts], 6)
    for r, w in zip(every, whole, strict=True):
        assert r is not None and r.cost == w.cost
    # a share passed by the caller (the drive limit's, settings.limit_race_share) races
    # whatever settings.race_share says
    passed = race_fits([(fit, st) for st in starts], 6, share=1.0 / 3.0)
    assert [r is None for r in passed] == [r is None for r in raced]
    assert passed[winner].cost == raced[winner].cost

def test_a_period_off_by_more_than_its_trust_region_walks_to_the_truth():
    """A cogging period started 6 % long: the fit's period moves 2 % at a time (a trust
    region, not a physical range) and ends at the truth; with a fixed region it stays on the
    region's edge, 4 % long."""
    from dataclasses import replace

    ref = _reference(duration=4.0)
    axis = Axis().with_effects(noise_std=0.1e-6, cogging_amplitude=1.5, cogging_period=2e-3,
                               cogging_phase=0.5)
    res = simulate(axis, ref, seed=2)
    prep = prepare(validate_arrays(res.t, res.x_ref, res.x))
    truth = _grey_box_of(axis).copy(effects=("coulomb_friction", "stribeck_friction",
                                             "cogging"))
    start = truth.copy()
    start.plant[CL.I_COGP] *= 1.06
    b = Bounds(force=5.0, stroke=prep.stroke, v_max=prep.v_max, duration=prep.duration,
               ts=prep.ts, noise=prep.noise.rms)
    params = position_params(start, b, controller=False, effects=["cogging"], damping=False)
    period = [p for p in params if p.target == CL.I_COGP]
    assert len(period) == 1 and period[0].trust
    walked = PositionFit(prep, params).run(start, max_iter=10)
    assert walked.model.plant[CL.I_COGP] == pytest.approx(2e-3, rel=5e-3)
    fixed = [replace(p, trust=False) for p in params]
    stuck = PositionFit(prep, fixed).run(start, max_iter=10)
    assert stuck.model.plant[CL.I_COGP] == pytest.approx(2e-3 * 1.06 * 0.98, rel=2e-3)
    assert walked.cost < stuck.cost


# -- the noise floor: rounded exports, a stated quantum, never zero ---------------------------
def test_quantum_of_a_rounded_export_and_a_floor_never_zero():
    from fricbench.sysid.diagnose.signals import noise_floor

    q = 450.0 / 128.0  # deg: one count of a 10-bit potentiometer, exported to 0.01 deg
    k = np.arange(4000)
    counts = np.round(25.0 * np.sin(2 * np.pi * k / 1000.0) + 3.0 * np.sin(k / 37.0))
    x = np.round(counts * q, 2)
    assert set(np.round(np.abs(np.diff(x)), 2)) >= {3.51, 3.52}
    nf = noise_floor(x, np.round(25.0 * q * np.sin(2 * np.pi * k / 1000.0), 2))
    assert nf.quantum == pytest.approx(q, rel=1e-3) and nf.source == "quantum"
    assert nf.rms == pytest.approx(q / np.sqrt(12.0), rel=1e-3)
    stated = noise_floor(x, x + 1.0, quantum=2.0)
    assert stated.quantum == 2.0 and stated.source == "stated quantum"
    # a step run: at rest most of the time, the reference met exactly: MAD and quantum 0
    xr = np.where((k // 1000) % 2 == 1, 1.0, 0.0)
    xs = xr.copy()
    xs[1000:1003] = [0.3, 0.7, 0.9]
    floor = noise_floor(xs, xr)
    assert floor.rms > 0.0 and np.isfinite(floor.rms)
    with pytest.raises(ValueError, match="quantum"):
        noise_floor(x, x, quantum=0.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_quantum_of_a_rounded_export_over_thousands_of_steps(seed: int) -> None:
    """A rounded export whose values span thousands of sensor steps (a 3.6 um encoder over
    40 mm, exported in mm to 0.1 um, so that one step reads 3.5, 3.6 or 3.7 um): the step is
    found to 0.1 % (a step known to a few per cent from single steps used to number the far
    levels wrong, and no grid was found)."""
    from fricbench.sysid.diagnose.signals import noise_floor

    rng = np.random.default_rng(seed)
    q = rng.uniform(2.0e-6, 5.0e-6)
    t = np.arange(4000) * 1e-2
    xr = 0.02 * np.sin(0.3 * t + rng.uniform(0.0, 6.0)) + rng.uniform(-0.03, 0.03)
    x = np.round((xr + rng.normal(0.0, 0.3 * q, t.size)) / q) * q
    x = np.round(x * 1e3, 4) / 1e3  # mm, 4 decimals
    assert np.ptp(x) / q > 5000
    nf = noise_floor(x, xr)
    assert nf.quantum == pytest.approx(q, rel=1e-3)


def test_backward_elimination_drops_an_effect_the_others_made_unnecessary():
    """Forward selection may keep an effect that a later one made redundant: with the true
    Stribeck friction in the model, a position-dependent friction level adds nothing on
    held-out data and is named redundant; Stribeck friction itself is not."""
    from fricbench.sysid.diagnose.models import Bounds
    from fricbench.sysid.diagnose.search import SearchSettings, _redundant_effect

    ref = _reference(duration=8.0)
    axis = Axis().with_effects(noise_std=5e-8)
    res = simulate(axis, ref, seed=3)
    prep = prepare(validate_arrays(res.t, res.x_ref, res.x), n_sub=axis.controller.n_substeps)
    true = _grey_box_of(axis)
    true = true.copy(effects=("coulomb_friction", "stribeck_friction"))
    b = Bounds(force=5.0 * float(true.plant[CL.I_FC]) + 10.0, stroke=prep.stroke,
               v_max=prep.v_max, duration=prep.duration, ts=1e-3, noise=prep.noise.rms)
    settings = SearchSettings()
    assert _redundant_effect(true, prep, b, settings, lambda _s: None) is None
    spurious = true.copy(effects=true.effects + ("position_dependent_friction",))
    spurious.plant[CL.I_PDG] = 0.5
    found = _redundant_effect(spurious, prep, b, settings, lambda _s: None)
    assert found is not None and found[0] == "position_dependent_friction"


def _cascade_positional_reference(ctrl: CascadeController, inp: LoopInputs, y: np.ndarray,
                                  limit: float) -> np.ndarray:
    """The cascade law in its textbook positional form, sample by sample, with a clamping
    anti-windup, on a given fed-back position: an oracle written apart from
    :meth:`CascadeController.positional` and the simulator's recursion."""
    ts, p = inp.ts, ctrl.vel_pole
    xr = np.concatenate([inp.xr[0] - inp.vr[0] * ts * np.array([2.0, 1.0]), inp.xr])
    vr = np.diff(xr) / ts  # backward differences, vr[k] at sample k - 1
    ar = np.diff(vr) / ts
    y_prev = inp.x0 - inp.v0 * ts
    y_prev2 = y_prev - inp.v0 * ts
    d_f = ctrl.kvff * vr[0] - (y_prev - y_prev2) / ts  # the filter settled before the run
    q0 = ctrl.wv * (ctrl.kp * (inp.xr[0] - inp.x0) + ctrl.kvff * inp.vr[0]
                    - (inp.x0 - y_prev) / ts)
    integ = inp.u0 - q0  # in the effort's unit: wv times the cascade's integral
    out = np.empty(y.shape[0])
    for k in range(y.shape[0]):
        e = inp.xr[k] - y[k]
        d = ctrl.kvff * vr[k + 1] - (y[k] - y_prev) / ts
        d_f = p * d_f + (1.0 - p) * d
        e_v = ctrl.kp * e + d_f
        u = ctrl.wv * e_v + integ + ctrl.kaff * ar[k]
        step = ctrl.wv * ts * (ctrl.ki * e_v + ctrl.kpi * e)
        if not ((u > limit and step > 0.0) or (u < -limit and step < 0.0)):
            integ += step
        out[k] = min(max(u, -limit), limit)
        y_prev = y[k]
    return out


@pytest.mark.parametrize("ctrl", [
    CascadeController(wv=300.0, kp=40.0, ki=20.0, kvff=0.9, kaff=0.5, vel_pole=0.3),
    CascadeController(wv=200.0, kp=50.0, kvff=1.0, kpi=3000.0, vel_pole=0.6, kaff=0.2),
    CascadeController(wv=250.0, kp=30.0, ki=15.0, kvff=1.0),
], ids=["cascade-filtered", "pid", "cascade"])
def test_a_clipping_parametric_loop_holds_its_integral(ctrl: CascadeController) -> None:
    """A parametric loop whose drive clips runs in positional form with clamping anti-windup
    (as drives and LinuxCNC's pid do): its command is the oracle's on the same fed-back
    position, to rounding; unclipped, the loop is the velocity-form law's."""
    ref = _reference(3.0)
    vr = np.gradient(ref.x, ref.ts)
    inp = LoopInputs(t=ref.t, ts=ref.ts, xr=ref.x, vr=vr, ar=np.gradient(vr, ref.ts),
                     x0=0.0, v0=0.0, u0=0.0)
    p = CL.default_plant(1.0, 0.5)
    p[CL.I_FC] = 0.3
    free, _, _ = simulate_inputs([GreyBox(ctrl, p, ("coulomb_friction",))], inp)
    big = p.copy()
    big[CL.I_IMAX] = 1e9  # positional form, never clipped
    y_pos, u_pos, _ = simulate_inputs([GreyBox(ctrl, big, ("coulomb_friction",))], inp)
    assert np.max(np.abs(y_pos[0] - free[0])) < 1e-3 * np.max(np.abs(ref.x))
    np.testing.assert_allclose(u_pos[0], _cascade_positional_reference(ctrl, inp, y_pos[0], 1e9),
                               rtol=1e-9, atol=1e-9)
    clip = p.copy()
    clip[CL.I_IMAX] = 0.5 * float(np.max(np.abs(u_pos[0])))
    y, u, status = simulate_inputs([GreyBox(ctrl, clip, ("coulomb_friction",))], inp)
    assert status[0] == 0
    assert np.mean(np.abs(u[0]) >= clip[CL.I_IMAX] * (1 - 1e-12)) > 0.01  # it did clip
    np.testing.assert_allclose(u[0], _cascade_positional_reference(ctrl, inp, y[0],
                                                                   clip[CL.I_IMAX]),
                               rtol=1e-9, atol=1e-9)


def test_a_loop_faster_than_the_log_is_its_fine_run_at_the_logged_samples() -> None:
    """``n_loop``: the loop runs on the reference interpolated between the logged samples and
    the outputs are its values at those samples; a bad ``n_loop`` is refused by name."""
    ref = _reference(2.0, ts=1e-2)
    vr = np.gradient(ref.x, ref.ts)
    inp = LoopInputs(t=ref.t, ts=ref.ts, xr=ref.x, vr=vr, ar=np.gradient(vr, ref.ts),
                     x0=0.0, v0=0.0, u0=0.0, n_loop=10)
    fine = inp.fine
    assert fine.ts == pytest.approx(1e-3) and fine.n_loop == 1
    np.testing.assert_allclose(fine.xr[::10], ref.x, atol=1e-15)
    # between the samples the monotone interpolant stays within its neighbours
    lo = np.minimum(ref.x[:-1], ref.x[1:]).repeat(10)
    hi = np.maximum(ref.x[:-1], ref.x[1:]).repeat(10)
    assert np.all((fine.xr[:-1] >= lo - 1e-15) & (fine.xr[:-1] <= hi + 1e-15))
    m = GreyBox(CascadeController(wv=200.0, kp=40.0, ki=10.0, kvff=1.0),
                CL.default_plant(1.0, 0.2))
    y, u, _ = simulate_inputs([m], inp)
    y_f, u_f, _ = simulate_inputs([m], fine)
    assert y.shape == (1, ref.x.shape[0])
    np.testing.assert_array_equal(y[0], y_f[0, ::10])
    np.testing.assert_array_equal(u[0], u_f[0, ::10])
    for bad in (0, 2.5, True):
        with pytest.raises(ValueError, match="n_loop"):
            LoopInputs(t=ref.t, ts=ref.ts, xr=ref.x, vr=vr, ar=vr, x0=0.0, v0=0.0,
                       n_loop=bad)  # type: ignore[arg-type]


def _two_loops(duration: float) -> tuple:
    """``(prep, base, other)``: the default axis's run of ``duration`` s prepared, its grey
    box, and the same with a 10 % higher position gain."""
    axis = Axis()
    res = simulate(axis, _reference(duration))
    prep = prepare(validate_arrays(res.t, res.x_ref, res.x))
    base = _grey_box_of(axis)
    faster = base.controller.with_values(kp=base.controller.kp * 1.1)
    return prep, base, base.copy(controller=faster)


def test_a_run_simulated_again_is_the_run_simulated_first():
    """The free runs kept (:class:`models._FreeRunCache`) come back bit for bit: a model
    simulated again, alone, twice in one batch, beside other rows or without its effort."""
    from fricbench.sysid.diagnose import models as M

    prep, base, other = _two_loops(2.0)
    pid = base.copy(controller=base.controller.with_values(kpi=50.0, vel_pole=0.3))
    clipped = base.copy()
    clipped.plant[CL.I_IMAX] = 0.5  # a positional law (the drive clips)
    models = [base, other, pid, clipped]
    fresh = []
    for m in models:
        parts, laws, na, nc, pads = _law_of(m, prep)
        fresh.append(M._simulate_rows([m], parts, laws, prep.inputs, prep.n_sub, na, nc, pads,
                                      None, None, 0.0, None))
    y, u, status = simulate_models(models, prep)
    # the rows of a batch are padded to its widest law: kept apart by their widths
    y2, u2, _ = simulate_models([pid, base, base, clipped], prep, effort=False)
    y3, u3, _ = simulate_models([base], prep)
    assert np.array_equal(y2[1], y2[2]) and np.array_equal(y3[0], y2[1])
    assert np.array_equal(u3[0], u[0]) and np.array_equal(y2[0], y[2])
    for k, m in enumerate(models):
        y1, u1, s1, _ = fresh[k]
        alone, u_alone, _ = simulate_models([m], prep)
        assert np.array_equal(alone[0], y1[0], equal_nan=True)
        assert np.array_equal(u_alone[0], u1[0], equal_nan=True)
    assert np.array_equal(y[0], y3[0]) and status.tolist() == [0, 0, 0, 0]


def _law_of(m: GreyBox, prep) -> tuple:
    """``(parts, laws, na, nc, pads)`` of one model alone, computed afresh."""
    pos = bool(np.isfinite(m.plant[CL.I_IMAX]))
    if pos:
        law = m.controller.positional(prep.inputs)
        part = (law.a, law.c, law.r, law.q_init, law.y_init)
        pads = (law.a2.shape[0], law.c2.shape[0])
    else:
        law, part, pads = None, m.controller.arx(prep.inputs), None
    return [part], [law], part[0].shape[0], part[1].shape[0], pads


def test_a_batch_is_the_same_numbers_on_either_driver_and_with_shared_laws():
    """A batch's rows come out bit for bit the same on numba's threads or on the calling
    thread (``parallel=False``, the drivers of run_concurrently's tasks), and with the rows
    of one law sharing its reference arrays (``law_index``)."""
    from fricbench.sysid.diagnose import models as M

    prep, base, other = _two_loops(1.0)
    rows = [base, other, base.copy(), other.copy()]
    for m in rows[2:]:
        m.plant[CL.I_B] *= 1.5
    inp = prep.inputs
    arrays = [m.controller.arx(inp) for m in rows]
    a = np.stack([x[0] for x in arrays])
    c = np.stack([x[1] for x in arrays])
    u0 = np.stack([x[3] for x in arrays])
    P = np.stack([m.plant for m in rows])
    kw = dict(n_sub=prep.n_sub, x0=inp.x0, v0=inp.v0, u_init=u0, y_init=arrays[0][4])
    y, u, _ = CL.simulate_batch(P, a, c, np.stack([x[2] for x in arrays]), inp.t, inp.ts, **kw)
    shared = np.stack([arrays[0][2], arrays[1][2]])
    for parallel in (True, False):
        y2, u2, _ = CL.simulate_batch(P, a, c, shared, inp.t, inp.ts, parallel=parallel,
                                      law_index=np.array([0, 1, 0, 1]), **kw)
        assert y2.tobytes() == y.tobytes() and u2.tobytes() == u.tobytes()
    assert M.simulate_models(rows, prep)[0].tobytes() == y.tobytes()


def test_run_concurrently_is_the_tasks_in_turn():
    """Results in the tasks' order, the first error in that order raised once all ended, a
    nested call run in turn, BLAS on one thread inside and its limit lifted after."""
    from functools import partial

    from threadpoolctl import threadpool_info

    from fricbench.sysid.diagnose.models import run_concurrently

    def blas_threads() -> set[int]:
        return {d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"}

    before = blas_threads()
    done: list[int] = []

    def task(i: int) -> tuple[int, set[int]]:
        done.append(i)
        return i * i, blas_threads()

    out = run_concurrently([partial(task, i) for i in range(5)])
    assert [r for r, _ in out] == [0, 1, 4, 9, 16] and all(t == {1} for _, t in out)
    assert sorted(done) == list(range(5)) and blas_threads() == before
    nested = run_concurrently([lambda: run_concurrently([lambda: 1, lambda: 2]), lambda: 3])
    assert nested == [[1, 2], 3]

    def bad(msg: str) -> int:
        raise ValueError(msg)

    done.clear()
    with pytest.raises(ValueError, match="first"):
        run_concurrently([partial(bad, "first"), partial(task, 7), partial(bad, "second")])
    assert done == [7] and blas_threads() == before

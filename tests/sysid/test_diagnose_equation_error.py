"""The loop and its friction by equation error (fricbench.sysid.diagnose.equation_error)."""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import second_sim as S  # noqa: E402
import second_sim_check as C  # noqa: E402

from fricbench.sysid.diagnose import closed_loop as CL  # noqa: E402
from fricbench.sysid.diagnose.baselines import (  # noqa: E402
    fit_linear_cascade,
    friction_aware_fit,
)
from fricbench.sysid.diagnose.equation_error import loop_by_equation_error  # noqa: E402
from fricbench.sysid.diagnose.models import PositionFit, position_params  # noqa: E402

_STRIBECK = ("coulomb_friction", "stribeck_friction")


@pytest.fixture(scope="module")
def stribeck_10(tmp_path_factory: pytest.TempPathFactory) -> tuple[S.Case, object, object]:
    """The sweep's stribeck/10: a 1 kHz PID with a filtered derivative and a one-sample
    delay, breakaway 1.8 times the Coulomb level, no effort logged."""
    case = S.draw_case("stribeck", 10)
    assert case.ctrl.law == "pid" and case.variant.log_every == 1
    prep = C.position_only(case, tmp_path_factory.mktemp("st10"))
    _, _, bounds, _ = fit_linear_cascade(prep)
    return case, prep, bounds


def test_the_loop_gains_come_within_a_fifth_of_the_true_ones(stribeck_10: tuple) -> None:
    """Per unit mass, the PID's derivative gain ``D kt / M`` (less the damping it is
    collinear with), ``P / D``, ``I / D`` and the acceleration feedforward are found within
    20 % of the second simulator's, the Coulomb level within 30 % and the Stribeck excess and
    velocity within a half (0.55 for 0.83 m/s^2: a start, refined by output error), from the
    position alone."""
    case, prep, bounds = stribeck_10
    fits = loop_by_equation_error(prep, bounds, _STRIBECK, n_best=1)
    assert len(fits) == 1
    c, pl = case.ctrl, case.plant
    got = fits[0].model.controller
    assert got.wv == pytest.approx(c.kt * c.d / pl.mass, rel=0.2)
    assert got.kp == pytest.approx(c.p / c.d, rel=0.2)
    assert got.kpi == pytest.approx(c.i / c.d, rel=0.2)
    assert got.kaff == pytest.approx(c.kt * c.ff2 / pl.mass, rel=0.2)
    row = fits[0].model.plant
    assert row[CL.I_FC] == pytest.approx(pl.coulomb / pl.mass, rel=0.3)
    assert row[CL.I_FS] == pytest.approx((pl.breakaway - pl.coulomb) / pl.mass, rel=0.5)
    assert row[CL.I_VS] == pytest.approx(pl.stribeck_velocity, rel=0.5)
    assert fits[0].model.effects == _STRIBECK


def test_its_start_reaches_what_the_grid_of_loops_does_not(stribeck_10: tuple) -> None:
    """Refined by output error, the equation error's loop with Coulomb and Stribeck friction
    leaves a small fraction of the error of the loop fitted with Coulomb friction from the
    grid of standard loops (84 um there; 0.85 um here, the true loop's own error 0.77 um)."""
    _, prep, bounds = stribeck_10
    linear, _, _, _ = fit_linear_cascade(prep)
    grid = friction_aware_fit(linear, prep, bounds)
    assert grid is not None
    start = loop_by_equation_error(prep, bounds, _STRIBECK, n_best=1)[0].model
    res = PositionFit(prep, position_params(start, bounds, controller=True)).run(start)

    def rms(y: np.ndarray) -> float:
        return float(np.sqrt(np.mean((prep.x - y) ** 2)))

    assert rms(res.y) < 0.05 * rms(grid.y), (rms(res.y), rms(grid.y))


def test_a_mask_keeps_the_fit_on_its_samples(stribeck_10: tuple) -> None:
    """A training fold's fit differs from the whole run's; a mask with too few samples
    gives no fit rather than a guess; a mask of the wrong shape is refused by name."""
    _, prep, bounds = stribeck_10
    whole = loop_by_equation_error(prep, bounds, n_best=1)[0]
    fold = loop_by_equation_error(prep, bounds, n_best=1, mask=prep.folds != 0)[0]
    assert fold.model.controller != whole.model.controller
    assert loop_by_equation_error(prep, bounds, mask=np.zeros(prep.n, dtype=bool)) == []
    with pytest.raises(ValueError, match="mask: shape"):
        loop_by_equation_error(prep, bounds, mask=np.ones(3, dtype=bool))


@pytest.mark.parametrize(("kwargs", "match"), [
    (dict(effects=("backlash",)), "effects="),
    (dict(n_best=0), "n_best=0"),
    (dict(n_best=True), "n_best=True"),
    (dict(delays=()), "delays=()"),
    (dict(delays=(-1,)), "delays="),
])
def test_bad_arguments_are_named(stribeck_10: tuple, kwargs: dict, match: str) -> None:
    _, prep, bounds = stribeck_10
    with pytest.raises(ValueError, match=match):
        loop_by_equation_error(prep, bounds, **kwargs)


def test_the_same_run_gives_the_same_numbers(stribeck_10: tuple) -> None:
    _, prep, bounds = stribeck_10
    a = loop_by_equation_error(prep, bounds, _STRIBECK)
    b = loop_by_equation_error(prep, bounds, _STRIBECK)
    assert [f.model.controller for f in a] == [f.model.controller for f in b]
    assert all(np.array_equal(f.model.plant, g.model.plant) for f, g in zip(a, b, strict=True))


def test_a_pid_with_a_delay_is_fitted_with_its_delay(tmp_path: object) -> None:
    """control/10 of the sweep: a PID with a filtered derivative and a 3-sample command delay,
    no effort. The equation error's starts, one per delay, give the friction-aware fit the
    delay, and it comes within 1.5 times the true loop's error (10.3 times from the standard
    loops without a delay); the diagnosis's loops carry it and the position error falls to the
    noise floor (48.1 urad before, 4.46 urad floor)."""
    from fricbench.sysid.diagnose import diagnosis as D

    case = S.draw_case("control", 10)
    assert case.ctrl.law == "pid" and case.ctrl.delay == 3 and case.variant.effort is None
    prep, fit, truth, fitted = C.friction_fit_against_truth(case, str(tmp_path))
    assert fit.model.plant[CL.I_DELAY] == 3
    assert fitted <= 1.5 * truth, (fitted, truth)
    base = D._loop_base(prep, 10)
    assert base.linear.plant[CL.I_DELAY] == 3
    outcome = C.diagnose_case(case, str(tmp_path))
    assert outcome.ok, C.format_row(outcome)
    report = outcome.report
    assert report is not None
    assert report["position"]["rms_after"] <= 1.25 * case.floor
    assert "delayed by 3 loop periods (3 ms)" in report["controller_laws"]["train"]
    assert report["linear_model"]["model"]["plant"]["command_delay_loop_periods"] == 3


def test_a_loop_gain_pushed_to_its_bound_is_named(stribeck_10: tuple) -> None:
    """The check that refuses an equation error's loop refined onto a bound: a feedforward at
    its largest or a position integral at its least is named; no feedforward and no derivative
    filter (lower bounds of 0) are values a loop has, not bounds."""
    from dataclasses import replace

    from fricbench.sysid.diagnose.baselines import _gain_on_bound

    _, prep, bounds = stribeck_10
    model = loop_by_equation_error(prep, bounds, n_best=1)[0].model
    assert _gain_on_bound(model, bounds) is None
    c = model.controller
    assert _gain_on_bound(model.copy(controller=replace(c, kaff=1.5)), bounds) == "kaff"
    low = replace(c, kpi=1e-3 * c.wv**2)
    assert _gain_on_bound(model.copy(controller=low), bounds) == "kpi_per_wv2"
    free = replace(c, kvff=0.0, kaff=0.0, vel_pole=0.0)
    assert _gain_on_bound(model.copy(controller=free), bounds) is None


def test_a_cascade_keeps_its_velocity_integral() -> None:
    """A P-PI cascade whose velocity feedforward is not 1 is no PID: its velocity integral
    also integrates ``(kvff - 1) v_r``. The law is read back from the regression's
    coefficients exactly (random gains); with ``kvff = 1`` it is the PID it then is
    (``kp' = kp + ki``, ``kpi = ki kp``)."""
    from fricbench.sysid.diagnose.equation_error import _law

    rng = np.random.default_rng(12)
    for _ in range(20):
        wv, kp, ki = rng.uniform(20, 400), rng.uniform(5, 80), rng.uniform(1, 60)
        kaff, pole = rng.uniform(0, 1.2), rng.uniform(0, 0.9)
        kvff = 1.0 + rng.choice([-1, 1]) * rng.uniform(0.04, 0.5)
        coef = np.array([wv * (kp + ki), wv * kvff, wv, wv * ki * kp, kaff, 0.3,
                         wv * ki * (kvff - 1.0)])
        got = _law(coef, pole, True)
        for name, want in (("wv", wv), ("kp", kp), ("ki", ki), ("kvff", kvff),
                           ("kaff", kaff), ("vel_pole", pole)):
            assert getattr(got, name) == pytest.approx(want, rel=1e-9), name
        assert got.kpi == pytest.approx(0.0, abs=1e-9 * wv)
        pid = _law(np.array([wv * (kp + ki), wv, wv, wv * ki * kp, kaff, 0.3, 0.0]), pole,
                   True)
        assert pid.ki == 0.0 and pid.is_pid
        assert pid.kp == pytest.approx(kp + ki) and pid.kpi == pytest.approx(ki * kp)



def test_a_feedforward_is_told_from_1_by_its_standard_deviation() -> None:
    """The velocity integral's rate is read from the regression only when ``wv (kvff - 1)``
    lies beyond ``settings.detection_sd`` standard deviations of zero: a law whose two
    velocity columns carry the same coefficient is a PID however the noise moves them, one
    whose feedforward differs by 10 % is not; white or correlated noise alike (the deviation
    is inflated by the residual's correlation)."""
    from fricbench.sysid.diagnose.equation_error import _feedforward_detected
    from fricbench.sysid.diagnose.leastsq import solve_ls

    rng = np.random.default_rng(3)
    n = 4000
    false_calls = 0
    for trial in range(40):
        X = rng.normal(size=(n, 7))
        X[:, 2] = -(X[:, 1] + 0.3 * rng.normal(size=n))  # the velocity follows its reference
        noise = rng.normal(size=n)
        if trial % 2:
            noise = np.convolve(noise, np.ones(20) / 20, mode="same")  # correlated
        for kvff, want in ((1.0, False), (1.1, True)):
            wv = 50.0
            true = np.array([30.0, wv * kvff, wv, 4.0, 0.5, 0.1, 2.0])
            y = X @ true + 0.5 * noise
            coef = solve_ls(X, y)
            got = _feedforward_detected(X, y, coef)
            if want:
                assert got, (trial, kvff)
            else:
                false_calls += got
    # two standard deviations: about 5 % of the runs with kvff = 1 cross it by chance
    assert false_calls <= 6

"""The control law identified from a logged effort closes the loop the drive closed.

A semi-closed loop logs a position that is not the one the drive read (the table's scale, with
its own noise, against the motor encoder): a least-squares law then predicts the next effort
well and the loop badly (its derivative taps are biased by the log's noise). These tests run
the second simulator (``second_sim``, independent of fricbench) with its parameters drawn per
seed, identify the law the way ``diagnose`` does (:func:`fit_law`), close it around the
simulator's *true* plant, and compare the free run with the logged position.
"""

from __future__ import annotations

import math
import os
import sys

import numpy as np
import pytest

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.baselines import fit_law
from fricbench.sysid.diagnose.controllers import fit_arx_controller
from fricbench.sysid.diagnose.models import GreyBox, simulate_position
from fricbench.sysid.diagnose.prepared import prepare
from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS
from fricbench.sysid.io import load_run

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import second_sim as S  # noqa: E402

# a plain layout (metres, a 1 kHz log with a time column, the effort in A): what is tested is
# the law, not the reading of odd files (the sweep covers those)
PLAIN = dict(effort="A", saturate=False, delay=0, log_every=1, unit="m", rounded=False,
             time_column=True, sep=",", header="names")


def _case(law: str, seed: int, tmp_path) -> tuple[S.Case, object]:
    case = S.draw_case("control", seed, law=law, vel_filter=(law == "cascade"), **PLAIN)
    path = os.path.join(tmp_path, f"{law}-{seed}.csv")
    S.write_csv(case, path)
    args = S.cli_args(case, path)
    opts = dict(zip(args[1::2], args[2::2], strict=False))
    run = load_run(path, time=opts["--time"], reference=opts["--reference"],
                   position=opts["--position"], effort=opts["--effort"], position_unit="m",
                   effort_required=True)
    return case, prepare(run)


def _true_plant(case: S.Case) -> np.ndarray:
    """The simulator's plant in the diagnosis's units (forces in the effort's unit, A)."""
    kt, pl = case.ctrl.kt, case.plant
    p = CL.default_plant(pl.mass / kt, pl.damping / kt)
    p[CL.I_FC] = pl.coulomb / kt
    return p


@pytest.mark.parametrize("law,seed", [("pid", 101), ("pid", 102), ("cascade", 103),
                                      ("cascade", 104)])
def test_the_identified_law_closes_the_drives_loop(law: str, seed: int, tmp_path) -> None:
    case, prep = _case(law, seed, tmp_path)
    model = GreyBox(fit_law(prep), _true_plant(case), effects=("coulomb_friction",))
    y, _ = simulate_position(model, prep)
    err = float(np.sqrt(np.mean((prep.x - y) ** 2)))
    assert np.all(np.isfinite(y))
    # the simulator's own noise-free twin differs from the log by case.floor; a law that is
    # the drive's leaves little more
    assert err < 5.0 * case.floor, (err, case.floor)


def test_the_law_is_chosen_among_prefilters_and_reports_its_own_error(tmp_path) -> None:
    _, prep = _case("pid", 105, tmp_path)
    law = fit_law(prep)
    assert law.prefilter_hz is None or any(
        f is not None and law.prefilter_hz == pytest.approx(f * 0.5 / prep.ts)
        for f in DEFAULT_SETTINGS.law_prefilters)
    # the error reported is the law's next-effort error on the logged signals, unfiltered
    inp = prep.inputs
    e = prep.u - law.predict(inp.xr, inp.vr, prep.x, prep.u, prep.ts)
    rel = 100 * np.sqrt(np.mean(e[10:-10] ** 2) / np.mean(prep.u[10:-10] ** 2))
    assert law.relerr_pct == pytest.approx(rel, rel=0.05)
    assert "prefilter_hz" in law.to_dict() or law.prefilter_hz is None


def test_a_prefilter_out_of_range_is_refused() -> None:
    x = np.linspace(0.0, 1.0, 200)
    with pytest.raises(ValueError, match="prefilter_hz=600"):
        fit_arx_controller(x, np.ones(200), x, x, 1e-3, np.arange(200) % 2, prefilter_hz=600.0)


@pytest.mark.parametrize("seed", [111, 112])
def test_a_law_with_an_exact_integrator_is_the_same_law_in_positional_form(seed: int,
                                                                            tmp_path) -> None:
    """A law fitted with an exact integrator (its recursion summing to 1) and run in
    positional form (a clamped integral) is the velocity form's law as long as nothing
    clips: the two free runs agree to a small share of the noise floor."""
    from dataclasses import replace

    from fricbench.sysid.diagnose.controllers import ArxController

    case, prep = _case("pid", seed, tmp_path)
    inp = prep.inputs
    law = fit_arx_controller(inp.xr, inp.vr, prep.x, prep.u, prep.ts, prep.folds,
                             integrator=True)
    assert law.has_integrator and float(np.sum(law.a)) == pytest.approx(1.0, abs=1e-12)
    p = _true_plant(case)
    # a limit never reached: the positional form runs, the clamp never acts
    p[CL.I_IMAX] = 1e6 * float(np.max(np.abs(prep.u)))
    ys = [simulate_position(GreyBox(lw, p, effects=("coulomb_friction",)), prep)[0]
          for lw in (law, replace(law, clamped=True))]
    assert np.all(np.isfinite(ys[1]))
    # (floating-point order differs: a stop of the stick-slip motion may move by a sample)
    assert float(np.sqrt(np.mean((ys[0] - ys[1]) ** 2))) < 0.05 * case.floor
    with pytest.raises(ValueError, match="exact integrator"):
        ArxController(a=np.array([0.9]), b=law.b, c=law.c, lead=law.lead, clamped=True)
    with pytest.raises(ValueError, match="integrator=True"):
        fit_arx_controller(inp.xr, inp.vr, prep.x, prep.u, prep.ts, prep.folds, max_na=0,
                           integrator=True)


def _effort_case(seed: int, delay: int, tmp_path) -> tuple[S.Case, object]:
    import argparse

    from fricbench.sysid.diagnose.command import _configure  # the command line's own reading

    case = S.draw_case("control", seed, delay=delay, effort="N", log_every=1, rounded=False,
                       unit="m", time_column=True, sep=",", header="names")
    path = os.path.join(tmp_path, f"delay-{seed}-{delay}.csv")
    S.write_csv(case, path)
    ns = _configure(argparse.ArgumentParser()).parse_args(S.cli_args(case, path))
    run = load_run(path, time=ns.time, reference=ns.reference, position=ns.position,
                   effort=ns.effort, position_unit="m", effort_required=True)
    return case, prepare(run)


@pytest.mark.parametrize("seed", [300, 301, 302, 303])
def test_no_command_delay_is_given_to_a_drive_without_one(seed: int, tmp_path) -> None:
    """The effort's loop gets a command delay only when its free run clearly needs one: drives
    without a delay (PID and cascade, drawn) keep none."""
    from fricbench.sysid.diagnose.baselines import fit_linear_with_effort

    _, prep = _effort_case(seed, 0, tmp_path)
    model, idim, _, _ = fit_linear_with_effort(prep)
    assert int(model.plant[CL.I_DELAY]) == 0 and idim.delay == 0


def test_a_drives_command_delay_is_found_from_the_motion(tmp_path) -> None:
    """A clipping PID whose power stage applies the logged command 3 samples later (seed
    302): the effort's regression and loop take the delay, and the loop with friction leaves
    less than 0.8 times the squared position error of the same law without it."""
    from fricbench.sysid.diagnose.baselines import fit_linear_with_effort
    from fricbench.sysid.diagnose.models import InverseDynamics

    _, prep = _effort_case(302, 3, tmp_path)
    model, idim, _, _ = fit_linear_with_effort(prep)
    assert int(model.plant[CL.I_DELAY]) == 3 and idim.delay == 3
    sse = []
    for reg in (idim, InverseDynamics(prep, prep.u)):
        p = reg.fit(("coulomb_friction",), CL.default_plant(1.0, 0.0))
        p[CL.I_DELAY] = reg.delay
        p[CL.I_IMAX] = model.plant[CL.I_IMAX]
        y, _ = simulate_position(GreyBox(model.controller, p, effects=("coulomb_friction",)),
                                 prep)
        sse.append(float(np.sum((prep.x - y) ** 2)))
    assert sse[0] < 0.8 * sse[1], sse
    with pytest.raises(ValueError, match="delay=-1"):
        InverseDynamics(prep, prep.u, delay=-1)


@pytest.mark.parametrize("seed", [113, 114])
def test_a_cascade_law_yields_its_gains_and_is_the_same_law_clamped(seed: int,
                                                                      tmp_path) -> None:
    """A cascade's law fitted with an exact integrator is, while nothing clips, the PID
    ``P = D (k_p + k_i)``, ``I = D k_p k_i`` with velocity feedforward: :meth:`pid_terms`
    gives the drive's gains back, :meth:`cascade_integral_rates` its position gain and
    integral rate as the roots they are (sum ``P / D``, product ``I / D``), and the law run
    clamped as either cascade is the velocity form's law until the drive clips."""
    from dataclasses import replace

    from fricbench.sysid.diagnose.controllers import ArxController

    case, prep = _case("cascade", seed, tmp_path)
    c = case.ctrl
    assert np.isfinite(c.ti)
    inp = prep.inputs
    # through the narrowest prefilter: the log's own noise biases the unfiltered law's
    # derivative taps (see fit_law)
    law = fit_arx_controller(inp.xr, inp.vr, prep.x, prep.u, prep.ts, prep.folds,
                             integrator=True,
                             prefilter_hz=DEFAULT_SETTINGS.law_prefilters[-1] * 0.5 / prep.ts)
    i_gain, p_gain, d_gain, kvff = law.pid_terms(prep.ts)
    # the effort is the current command (A): D = k_v, P = k_v (k_p + k_i), I = k_v k_p k_i
    assert d_gain == pytest.approx(c.kv, rel=0.1)
    assert p_gain == pytest.approx(c.kv * (c.kp + 1.0 / c.ti), rel=0.1)
    assert i_gain == pytest.approx(c.kv * c.kp / c.ti, rel=0.1)
    assert kvff == pytest.approx(c.kvff, abs=0.05)
    rates = law.cascade_integral_rates(prep.ts)
    assert len(rates) == 2 and 0.0 < rates[0] <= rates[1]
    assert sum(rates) == pytest.approx(p_gain / d_gain, rel=1e-9)
    assert rates[0] * rates[1] == pytest.approx(i_gain / d_gain, rel=1e-9)
    p = _true_plant(case)
    p[CL.I_IMAX] = 1e6 * float(np.max(np.abs(prep.u)))  # never reached
    laws = [law] + [replace(law, clamped=True, velocity_ki=ki) for ki in rates]
    ys = [simulate_position(GreyBox(lw, p, effects=("coulomb_friction",)), prep)[0]
          for lw in laws]
    for y in ys[1:]:
        assert np.all(np.isfinite(y))
        assert float(np.sqrt(np.mean((ys[0] - y) ** 2))) < 0.05 * case.floor
    with pytest.raises(ValueError, match="velocity_ki=1.0 with clamped=False"):
        ArxController(a=law.a, b=law.b, c=law.c, lead=law.lead, velocity_ki=1.0)
    with pytest.raises(ValueError, match="velocity_ki=-1.0"):
        ArxController(a=law.a, b=law.b, c=law.c, lead=law.lead, clamped=True,
                      velocity_ki=-1.0)


def _free_run_error(law: object, plant: np.ndarray, prep: object) -> float:
    """Rms free-run position error of ``law`` closed around ``plant`` with Coulomb friction."""
    y, _ = simulate_position(GreyBox(law, plant, effects=("coulomb_friction",)), prep)
    assert np.all(np.isfinite(y))
    return float(np.sqrt(np.mean((prep.x - y) ** 2)))


def test_a_clipping_cascade_is_run_with_its_velocity_integral_held(tmp_path) -> None:
    """A cascade whose current command clips integrates its velocity error and holds that
    integral while clipped (conditional integration). Over the second simulator's cascades
    with a filtered velocity and a clipping drive (seeds 116-134; draws whose clipping is too
    rare to be detected are skipped), closed around the true plant:

    * the law run clamped as that cascade (the integral rate nearest the drive's) leaves the
      least free-run error of the three forms (within 10 %) on at least two thirds of them,
      against the same law clamped as a PID (the integral of the position error) and the
      velocity form (a law recursing on its clipped command); it misses where the two
      rates are poorly identified or every form is at the noise floor;
    * :func:`fit_law`, which chooses among all of them by the motion on a plant fitted to the
      effort, keeps a law within 1.5 times the best form's error on two thirds of them.
    """
    from dataclasses import replace

    cascade_best = chosen_close = n = 0
    for seed in range(116, 135):
        case = S.draw_case("control", seed, law="cascade", vel_filter=True,
                           **{**PLAIN, "saturate": True})
        path = os.path.join(tmp_path, f"clip-{seed}.csv")
        S.write_csv(case, path)
        args = S.cli_args(case, path)
        opts = dict(zip(args[1::2], args[2::2], strict=False))
        run = load_run(path, time=opts["--time"], reference=opts["--reference"],
                       position=opts["--position"], effort=opts["--effort"],
                       position_unit="m", effort_required=True)
        prep = prepare(run)
        if prep.saturation is None:
            continue
        n += 1
        inp = prep.inputs
        law = fit_arx_controller(inp.xr, inp.vr, prep.x, prep.u, prep.ts, prep.folds,
                                 exclude=prep.saturation.mask, integrator=True,
                                 prefilter_hz=DEFAULT_SETTINGS.law_prefilters[-1] * 0.5 / prep.ts)
        p = _true_plant(case)
        p[CL.I_IMAX] = prep.saturation.level

        others = [_free_run_error(replace(law, clamped=True), p, prep),
                  _free_run_error(law, p, prep)]
        rates = law.cascade_integral_rates(prep.ts)
        e_cascade = math.inf
        if rates:
            ki = min(rates, key=lambda r: abs(math.log(r * case.ctrl.ti)))
            e_cascade = _free_run_error(replace(law, clamped=True, velocity_ki=ki), p, prep)
        cascade_best += e_cascade <= 1.1 * min(others)
        chosen_close += _free_run_error(fit_law(prep), p, prep) <= 1.5 * min(e_cascade,
                                                                              *others)
    assert n >= 10
    assert cascade_best >= 2 * n / 3, (cascade_best, n)
    assert chosen_close >= 2 * n / 3, (chosen_close, n)


def test_an_effort_the_law_leaves_is_injected_only_where_it_drives_the_axis(tmp_path) -> None:
    """What the identified law leaves of the logged effort is fed to the free runs when it
    brings them closer to the measured position (test pulses the drive added), not because it
    is large: noise on the effort's log alone (the current sensor's) leaves a tenth of the
    effort unexplained, moves no axis, and is not injected."""
    import dataclasses

    from fricbench.sysid.diagnose.diagnosis import _injected

    case, prep = _case("pid", 106, tmp_path)
    model = GreyBox(fit_law(prep), _true_plant(case), effects=("coulomb_friction",))
    assert prep.u is not None
    rng = np.random.default_rng(0)
    noisy = dataclasses.replace(
        prep, u=prep.u + 0.15 * float(np.std(prep.u)) * rng.standard_normal(prep.u.shape))
    w, share, used = _injected(model, noisy)
    assert share is not None and share > 0.05  # a share-of-the-effort rule injected it
    assert not used and w is None
    # pulses that act on the axis: the model's own run with them is the measured one
    pulses = np.zeros_like(prep.u)
    for k in range(prep.u.shape[0] // 10, prep.u.shape[0], prep.u.shape[0] // 5):
        pulses[k:k + 50] = 0.5 * float(np.max(np.abs(prep.u)))
    y, u = simulate_position(model, prep, pulses)
    assert np.all(np.isfinite(y))
    driven = dataclasses.replace(prep, x=y, u=u)
    w, share, used = _injected(model, driven)
    assert used and w is not None

"""The loop models of a run without an effort: the P-PI cascade, the PID position loop, and
the drive's limit.

The PID form of :class:`CascadeController` (a position-error integral ``kpi`` and a filter on
the velocity error) is checked against a textbook PID written here sample by sample, and on
runs of the second simulator (``second_sim``, independent of fricbench) whose drive is a PID
position loop that the P-PI cascade cannot represent.
"""

from __future__ import annotations

import dataclasses
import os
import sys

import numpy as np
import pytest

from fricbench.sysid.diagnose import baselines as BL
from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.controllers import CascadeController, LoopInputs
from fricbench.sysid.diagnose.models import Bounds, GreyBox, cascade_effort, position_params
from fricbench.sysid.diagnose.prepared import prepare
from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS
from fricbench.sysid.io import validate_arrays

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import second_sim as S  # noqa: E402
import second_sim_check as C  # noqa: E402

TS = 1e-3


def _inputs(rng: np.random.Generator, n: int = 3000) -> tuple[LoopInputs, np.ndarray]:
    """A smooth random reference and a measured position that lags it with noise."""
    t = np.arange(n) * TS
    xr = sum(rng.uniform(1e-3, 5e-3) * np.sin(2 * np.pi * rng.uniform(0.2, 3.0) * t
                                              + rng.uniform(0, 6.3)) for _ in range(3))
    vr = np.gradient(xr, TS)
    ar = np.gradient(vr, TS)
    x = np.roll(xr, 7) + 1e-6 * rng.standard_normal(n)
    x[:7] = xr[0]
    v0 = 0.0
    return LoopInputs(t, TS, xr, vr, ar, float(x[0]), v0, rng.uniform(-1.0, 1.0)), x


def _textbook_pid(inp: LoopInputs, x: np.ndarray, p_gain: float, i_gain: float, d_gain: float,
                  tf: float, kaff: float) -> np.ndarray:
    """``u = P e + I int(e) + D de_f/dt + kaff a_r``, the derivative through a first-order
    filter by backward Euler, the integral updated after the output, the reference's
    acceleration by backward differences (as drives compute them); before the run the
    reference and the axis move at constant speed, and the integral holds ``u0``."""
    d_a = tf / (tf + TS)
    d_b = d_gain / (tf + TS)
    integ = inp.u0
    xr_prev = [inp.xr[0] - inp.vr[0] * TS, inp.xr[0] - 2 * inp.vr[0] * TS]
    e_prev = xr_prev[0] - (inp.x0 - inp.v0 * TS)
    dterm = d_gain * (inp.vr[0] - inp.v0)  # the derivative settled before the run
    out = np.empty(x.shape[0])
    for k in range(x.shape[0]):
        e = inp.xr[k] - x[k]
        dterm = d_a * dterm + d_b * (e - e_prev)
        acc = (inp.xr[k] - 2 * xr_prev[0] + xr_prev[1]) / TS**2
        out[k] = p_gain * e + integ + dterm + kaff * acc
        integ += i_gain * TS * e
        e_prev = e
        xr_prev = [inp.xr[k], xr_prev[0]]
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_pid_form_is_the_textbook_pid(seed: int) -> None:
    rng = np.random.default_rng(seed)
    inp, x = _inputs(rng)
    d_gain = rng.uniform(50.0, 300.0)
    p_gain = d_gain * rng.uniform(10.0, 60.0)
    i_gain = d_gain * rng.uniform(100.0, 900.0)
    tf = rng.uniform(1.0, 6.0) * TS
    kaff = rng.uniform(0.0, 1.0)
    ctrl = CascadeController(wv=d_gain, kp=p_gain / d_gain, kvff=1.0, kaff=kaff,
                             kpi=i_gain / d_gain, vel_pole=tf / (tf + TS))
    assert ctrl.is_pid
    gains = ctrl.pid_gains(TS)
    assert gains["p_1_s2"] == pytest.approx(p_gain) and gains["i_1_s3"] == pytest.approx(i_gain)
    assert gains["d_1_s"] == pytest.approx(d_gain) and gains["tf_s"] == pytest.approx(tf)
    run = validate_arrays(inp.t, inp.xr, x)
    prep = prepare(run)
    prep.inputs = inp
    u_model = cascade_effort(ctrl, prep, x)
    u_book = _textbook_pid(inp, x, p_gain, i_gain, d_gain, tf, kaff)
    scale = float(np.max(np.abs(u_book)))
    assert np.max(np.abs(u_model - u_book)) < 1e-9 * scale


def _textbook_law(inp: LoopInputs, x: np.ndarray, c: CascadeController) -> np.ndarray:
    """The class's definition, sample by sample: ``d = (kvff dx_r - dx) / ts`` (backward
    differences), ``d_f = p d_f + (1 - p) d``, ``e_v = kp e + d_f``,
    ``u = wv (e_v + I) + kaff a_r``, ``I += ts (ki e_v + kpi e)`` after the output."""
    p = c.vel_pole
    integ = inp.u0 / c.wv
    x_prev = inp.x0 - inp.v0 * TS
    xr_prev = [inp.xr[0] - inp.vr[0] * TS, inp.xr[0] - 2 * inp.vr[0] * TS]
    d_f = c.kvff * inp.vr[0] - inp.v0
    out = np.empty(x.shape[0])
    for k in range(x.shape[0]):
        e = inp.xr[k] - x[k]
        d = (c.kvff * (inp.xr[k] - xr_prev[0]) - (x[k] - x_prev)) / TS
        d_f = p * d_f + (1.0 - p) * d
        e_v = c.kp * e + d_f
        acc = (inp.xr[k] - 2 * xr_prev[0] + xr_prev[1]) / TS**2
        out[k] = c.wv * (e_v + integ) + c.kaff * acc
        integ += TS * (c.ki * e_v + c.kpi * e)
        x_prev = x[k]
        xr_prev = [inp.xr[k], xr_prev[0]]
    return out


@pytest.mark.parametrize("seed", [3, 4])
def test_the_general_form_is_its_definition(seed: int) -> None:
    """Every term at once (a velocity integral beside the position one, the filter, both
    feedforwards) against the class's definition written sample by sample."""
    rng = np.random.default_rng(seed)
    inp, x = _inputs(rng)
    ctrl = CascadeController(wv=rng.uniform(50, 500), kp=rng.uniform(5, 80),
                             ki=rng.uniform(1, 50), kvff=rng.uniform(0, 1.2),
                             kaff=rng.uniform(0, 1.2), kpi=rng.uniform(10, 900),
                             vel_pole=rng.uniform(0.0, 0.9))
    run = validate_arrays(inp.t, inp.xr, x)
    prep = prepare(run)
    prep.inputs = inp
    u_model = cascade_effort(ctrl, prep, x)
    u_book = _textbook_law(inp, x, ctrl)
    assert np.max(np.abs(u_model - u_book)) < 1e-9 * np.max(np.abs(u_book))


def test_pid_parameters_keep_the_family() -> None:
    """A PID model frees its position integral and filter (never the velocity integral); a
    cascade its velocity integral (never a position integral)."""
    b = Bounds(force=1.0, stroke=0.01, v_max=0.01, duration=5.0, ts=TS, noise=1e-7)
    p = np.zeros(40)
    pid = GreyBox(CascadeController(wv=100.0, kp=30.0, kvff=1.0, kpi=500.0, vel_pole=0.5), p)
    cas = GreyBox(CascadeController(wv=100.0, kp=30.0, ki=10.0, kvff=1.0), p)
    names_pid = {q.target for q in position_params(pid, b, controller=True, effects=())}
    names_cas = {q.target for q in position_params(cas, b, controller=True, effects=())}
    assert {"kpi_per_wv2", "vel_pole"} <= names_pid and "ki_per_wv" not in names_pid
    assert "ki_per_wv" in names_cas and not {"kpi_per_wv2", "vel_pole"} & names_cas
    boxed = {q.target: q for q in position_params(pid, b, controller=True, effects=(),
                                                  controller_box=1.5)}
    assert boxed["kpi_per_wv2"].lo > 0.0  # the family is kept inside a box
    assert boxed["kpi_per_wv2"].lo <= 0.05 <= boxed["kpi_per_wv2"].hi


def test_the_coulomb_starts_come_from_the_limit_grid_below_the_level_bound(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The friction-aware fit starts from the drive limit's grid below the Coulomb level's
    bound; a grid with no entry there is refused with the field's name, not the argument's."""
    from fricbench.sysid.diagnose import settings as settings_module

    b = Bounds(force=1.0, stroke=0.01, v_max=0.01, duration=5.0, ts=TS, noise=1e-7)
    grid = DEFAULT_SETTINGS.limit_friction_grid
    starts = BL.coulomb_starts(b)
    assert starts and set(starts) < set(grid) and max(starts) < min(set(grid) - set(starts))
    monkeypatch.setattr(settings_module, "DEFAULT_SETTINGS",
                        dataclasses.replace(DEFAULT_SETTINGS, limit_friction_grid=(4.0, 8.0)))
    with pytest.raises(ValueError, match=r"^limit_friction_grid=\(4\.0, 8\.0\): expected at "
                                         r"least one entry below 2,"):
        BL.coulomb_starts(b)


def test_a_pid_drive_is_modelled_as_a_pid_loop() -> None:
    """A PID position loop (complex P-PI roots, a filtered derivative) logged without effort:
    the loop identified with friction is of the PID family and the diagnosis brings the error
    near the floor, where the cascade model stayed at several times it."""
    case = S.draw_case("control", 8, law="pid", saturate=False, log_every=1, effort=None)
    c = case.ctrl
    assert c.p**2 < 4 * c.d * c.i  # no real P-PI cascade is this PID
    idx = case.index
    run = validate_arrays(case.trace.t[idx], case.trace.x_ref[idx], case.trace.y_log[idx])
    prep = prepare(run)
    linear, _, bounds, _ = BL.fit_linear_cascade(prep)
    loop = BL.friction_aware_loop(linear, prep, bounds).controller
    assert isinstance(loop, CascadeController) and loop.is_pid
    from fricbench.sysid.diagnose.diagnosis import diagnose

    res = diagnose(run)
    err = prep.x - res.train.y_after
    rms = float(np.sqrt(np.mean(err**2)))
    assert np.all(np.isfinite(err))
    assert rms < 2.0 * case.floor, (rms, case.floor)
    assert "coulomb_friction" in res.effects
    # the report says which loop was used
    assert res.to_dict()["controller_laws"]["train"].startswith("a PID position loop")


def test_a_clipping_drive_is_found_from_the_position() -> None:
    """A drive that clips its current, logged without an effort: the loop with a drive limit
    fits far better, the limit is reported as a warning and every model clips there; a drive
    that never clips gets no limit."""
    from fricbench.sysid.diagnose.diagnosis import diagnose

    case = S.draw_case("control", 12, law="cascade", saturate=True, log_every=1, effort=None)
    assert np.mean(case.trace.clipped) > 0.01  # the drive did clip
    truth = case.ctrl.limit * case.ctrl.kt / case.plant.mass
    idx = case.index
    run = validate_arrays(case.trace.t[idx], case.trace.x_ref[idx], case.trace.y_log[idx])
    prep = prepare(run)
    linear, _, bounds, _ = BL.fit_linear_cascade(prep)
    # the fit the diagnosis starts from: at the better of the two force scales
    fit, bounds = BL.friction_aware_fit_scaled(linear, prep, bounds)
    assert fit is not None
    limit = BL.drive_limits(fit, prep, bounds)[0]  # the diagnosis's call, its defaults
    assert limit is not None
    assert 0.5 * truth < limit.level < 2.0 * truth, (limit, truth)
    assert limit.sse_ratio < DEFAULT_SETTINGS.limit_margin
    assert limit.clipped_share * prep.n >= DEFAULT_SETTINGS.rows_per_parameter
    res = diagnose(run)
    assert any("the drive clips" in w for w in res.warnings)
    assert res.final.plant[CL.I_IMAX] == pytest.approx(limit.level)
    before = float(np.sqrt(np.mean((prep.x - res.train.y_before) ** 2)))
    after = float(np.sqrt(np.mean((prep.x - res.train.y_after) ** 2)))
    assert after < 0.5 * before

    calm = S.draw_case("control", 8, law="pid", saturate=False, log_every=1, effort=None)
    idx = calm.index
    prep = prepare(validate_arrays(calm.trace.t[idx], calm.trace.x_ref[idx],
                                   calm.trace.y_log[idx]))
    linear, _, bounds, _ = BL.fit_linear_cascade(prep)
    fit, bounds = BL.friction_aware_fit_scaled(linear, prep, bounds)  # the diagnosis's call
    assert fit is not None and BL.fit_drive_limit(fit, prep, bounds) is None


@pytest.mark.parametrize("seed", [4, 5, 7])
def test_a_drive_sized_for_its_friction_is_found_from_the_position(seed: int) -> None:
    """A drive whose limit is set by its friction (the second simulator's rule: at least 1.3
    times the static force) rather than by the motion, logged without an effort: a Coulomb
    friction of 0.15..0.3 times the reference's largest acceleration (drawn), so the limit lies
    below half of it, under the range a drive sized for the motion has. The limit is found,
    with the headroom it leaves over the friction (what the clipped moves show) within 25 %.
    With starts sized for the motion only, seed 4 got no limit, nor did the second simulator's
    thermal/17 (82 um left, 80 times its floor); with the two grids of tuned starts that stood
    before the headroom's, seed 7 kept a limit 3.7 times the truth with a friction 4.3 times
    it, its headroom 1.7 times the truth."""
    rng = np.random.default_rng(seed)
    case = S.draw_case("control", seed, law="cascade", saturate=False, log_every=1,
                       effort=None)
    a_ref = float(np.max(np.abs(np.diff(case.trace.x_ref, 2)))) / S.LOOP_TS**2
    fc = rng.uniform(0.15, 0.3) * a_ref * case.plant.mass
    plant = dataclasses.replace(case.plant, coulomb=fc, breakaway=fc)
    free = S.simulate(plant, case.ctrl, case.sensor, case.trace.x_ref, x0=case.origin,
                      clean=True)
    ctrl = dataclasses.replace(case.ctrl, limit=S._clip_level(rng, plant, free.command,
                                                               case.ctrl.kt))
    truth = ctrl.limit * ctrl.kt / plant.mass
    assert truth < 0.5 * a_ref  # a drive sized for its friction, not for the motion
    tr = S.simulate(plant, ctrl, case.sensor, case.trace.x_ref, x0=case.origin, seed=seed)
    assert np.mean(tr.clipped) > 0.01  # the drive did clip
    idx = case.index
    prep = prepare(validate_arrays(tr.t[idx], tr.x_ref[idx], tr.y_log[idx]))
    linear, _, bounds, _ = BL.fit_linear_cascade(prep)
    fit, bounds = BL.friction_aware_fit_scaled(linear, prep, bounds)  # the diagnosis's call
    assert fit is not None
    found = BL.fit_drive_limit(fit, prep, bounds)
    assert found is not None
    headroom = found.level - found.model.plant[CL.I_FC]
    true_headroom = truth - fc / plant.mass
    assert 0.75 * true_headroom < headroom < 1.25 * true_headroom, (headroom, true_headroom)
    assert found.sse_ratio < DEFAULT_SETTINGS.limit_margin
    assert found.clipped_share * prep.n >= DEFAULT_SETTINGS.rows_per_parameter


@pytest.mark.xfail(strict=True, reason=(
    "with the diagnosis's own search (two standard loops per start, drive_limits' default "
    "since the limit's Coulomb starts span its split) the limit ends at 0.63 against a true "
    "1.24, leaving 27 % of the squared error without a limit; with three loops per start "
    "(fit_drive_limit's default until it was aligned with the diagnosis's) 1.35 and 2.7 %"))
def test_a_drive_clipping_against_a_friction_many_times_the_motion_is_found(
        tmp_path: object) -> None:
    """The second simulator's control/28: a PID with a 3-sample delay, no effort logged, whose
    limit is 1.3 times a Coulomb friction of 2.9 times the reference's largest acceleration,
    beyond the friction's grid of starts in units of that acceleration. The fit without a limit
    finds the friction level (within 25 %) and leaves 450 noise floors. From that fitted
    friction with the limit the run's headroom above it (the clipped moves' acceleration), the
    limit is found within 15 % and the squared error falls more than tenfold (x0.051; the two
    grids of tuned starts that stood before found x0.023 from the second one)."""
    case = S.draw_case("control", 28)
    assert case.variant.law == "pid" and case.ctrl.delay == 3
    truth = case.ctrl.limit * case.ctrl.kt / case.plant.mass
    fc = case.plant.coulomb / case.plant.mass
    prep = C.position_only(case, str(tmp_path))  # the CSV as the command reads it
    a_ref = float(np.max(np.abs(prep.inputs.ar)))
    assert fc > 2.0 * a_ref and truth > 3.0 * a_ref
    linear, _, bounds, _ = BL.fit_linear_cascade(prep)
    fit, bounds = BL.friction_aware_fit_scaled(linear, prep, bounds)  # the diagnosis's call
    assert fit is not None
    assert fit.model.plant[CL.I_FC] == pytest.approx(fc, rel=0.25)
    found = BL.fit_drive_limit(fit, prep, bounds)
    assert found is not None
    assert found.level == pytest.approx(truth, rel=0.15)
    assert found.sse_ratio < 0.1
    assert found.clipped_share * prep.n >= DEFAULT_SETTINGS.rows_per_parameter


def test_a_fast_loop_clipping_against_large_friction_is_found_from_a_slow_log() -> None:
    """A PID loop at 1 kHz, logged at 100 Hz, whose drive clips against a Coulomb friction
    as large as the motion's own acceleration (no effort logged). A loop fitted without a
    limit finds no friction at all there, and a loop at the log's rate cannot reproduce the
    drive: the limit's grid of starts and the loop at ``settings.loop_ts`` find the limit and
    the friction within 25 % (the second simulator's truth; 19 and 22 % high since the grid
    of Coulomb starts in units of the headroom, 2 % before from two starts in units of the
    reference's acceleration: the limit and the friction trade along a valley, the loop with
    them leaving 0.05 % of the squared error without a limit), the diagnosis says at which
    rate its loop runs and cuts the position error far below the linear model's."""
    from fricbench.sysid.diagnose import diagnosis as D

    case = S.draw_case("control", 5)
    var = case.variant
    assert (var.law, var.saturate, var.log_every, var.effort) == ("pid", True, 10, None)
    assert np.mean(case.trace.clipped) > 0.001  # the drive did clip
    cols = case.logged()
    k = S.UNIT_PER_SI[var.unit]
    run = validate_arrays(cols["t"], cols["ref"] / k, cols["pos"] / k)  # as exported
    prep = prepare(run)
    mass, kt = case.plant.mass, case.ctrl.kt
    slow = D._loop_base(prep, run.n_reversals)
    fast = D._loop_base(prep.with_loop(10), run.n_reversals)
    assert fast.cost < slow.cost, (fast.cost, slow.cost)
    assert fast.limit is not None and fast.limit.model is not None
    truth = case.ctrl.limit * kt / mass
    assert fast.limit.level == pytest.approx(truth, rel=0.25)
    assert fast.limit.model.plant[CL.I_FC] == pytest.approx(case.plant.coulomb / mass, rel=0.25)
    res = D.diagnose(run)
    assert res.prep.inputs.n_loop == 10
    assert any("periods per logged sample" in n for n in res.notes)
    assert any("the drive clips" in w for w in res.warnings)
    assert "coulomb_friction" in res.effects
    before = float(np.sqrt(np.mean((prep.x - res.train.y_before) ** 2)))
    after = float(np.sqrt(np.mean((prep.x - res.train.y_after) ** 2)))
    assert np.isfinite(after) and after < 0.1 * before, (before, after)

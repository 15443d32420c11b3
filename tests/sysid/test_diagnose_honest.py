"""Issue 12: honest reports on runs no one here wrote.

The verdict and warnings keys, no non-finite or null number anywhere in a report, the clip
level of a saturating effort, the derivative filter chosen from a coarse sensor, sensor and fit
artefacts rejected, a control law that cannot be reproduced, and the description of an
unexplained residual. Runs are drawn at random from seeds, with their own small loop written
here (not fricbench's kernel) where the plant does not matter.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose import diagnose
from fricbench.sysid.diagnose.command import _non_finite
from fricbench.sysid.diagnose.controllers import ArxController
from fricbench.sysid.diagnose.effects import get_effect
from fricbench.sysid.diagnose.models import GreyBox
from fricbench.sysid.diagnose.parameters import Bounds
from fricbench.sysid.diagnose.prepared import prepare
from fricbench.sysid.diagnose.search import artefact
from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS
from fricbench.sysid.diagnose.signals import (
    NoiseFloor,
    choose_filter,
    detect_saturation,
)
from fricbench.sysid.diagnose.verdict import describe
from fricbench.sysid.io import validate_arrays

VERDICTS = {"explained", "nothing_to_explain", "not_explained"}


def _pd_loop(rng: np.random.Generator, n: int = 6000, ts: float = 1e-3, *, coulomb: float = 0.0,
             clip: float = np.inf, quantum: float = 0.0, noise: float = 0.0
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A PD position loop on a mass with damping and Coulomb friction (semi-implicit Euler,
    10 substeps, a stick band): t, reference, logged position, logged (clipped) force."""
    m = rng.uniform(0.5, 2.0)
    b = rng.uniform(1.0, 5.0)
    wn = rng.uniform(30.0, 60.0)
    kp, kd = m * wn**2, 2 * 0.7 * m * wn - b
    t = np.arange(n) * ts
    f = rng.uniform(0.2, 0.6)
    xr = 0.05 * np.sin(2 * np.pi * f * t) + 0.02 * np.sin(2 * np.pi * 2.3 * f * t)
    x = v = 0.0
    xs, us = np.empty(n), np.empty(n)
    h = ts / 10
    y_prev = 0.0
    for k in range(n):
        y = x + noise * rng.standard_normal()
        if quantum > 0:
            y = quantum * np.round(y / quantum)
        xs[k] = y
        # the controller sees only the measured position: a backward-difference derivative
        vr = 0.0 if k == 0 else (xr[k] - xr[k - 1]) / ts
        u = float(np.clip(kp * (xr[k] - y) + kd * (vr - (y - y_prev) / ts), -clip, clip))
        y_prev = y
        us[k] = u
        for _ in range(10):
            fv = u - b * v
            # stick: the friction holds the mass while the force is below the level
            if abs(v) < 1e-9 and abs(fv) <= coulomb:
                v = 0.0
                continue
            v_new = v + h * (fv - coulomb * np.sign(v if abs(v) > 1e-9 else fv)) / m
            # with friction, a velocity that would change sign stops (and may stick)
            v = 0.0 if coulomb > 0 and v != 0.0 and np.sign(v_new) != np.sign(v) else v_new
            x += h * v
    return t, xr, xs, us


# -- signals --------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_clipped_effort_gives_its_level(seed: int) -> None:
    rng = np.random.default_rng(seed)
    level = rng.uniform(1.0, 50.0)
    u = 1.6 * level * np.sin(np.linspace(0, 20, 5000)) + 0.05 * level * rng.standard_normal(5000)
    sat = detect_saturation(np.clip(u, -level, level))
    assert sat is not None and sat.level == pytest.approx(level)
    assert sat.mask.sum() > 100


@pytest.mark.parametrize("step", [0.0, 0.01, 1.0])
def test_an_unclipped_effort_has_no_saturation(step: float) -> None:
    """Even coarsely quantised, the peak of a smooth effort is not a clip level."""
    u = 37.0 * np.sin(np.linspace(0, 20, 5000)) + 3.0
    if step:
        u = step * np.round(u / step)
    assert detect_saturation(u) is None


def test_repeated_equal_peaks_of_a_rounded_log_are_not_a_clip() -> None:
    """Equal peaks, each touched once (a repeated move's crest written with few digits), pile
    samples onto one level as a clip does, but a clip holds its level: a plateau."""
    rng = np.random.default_rng(4)
    u = np.round(rng.uniform(-9.0, 9.0, 4000), 1)  # a log with one decimal: levels repeat
    u[::50] = 10.0  # 80 equal crests, never two in a row
    assert detect_saturation(u) is None
    # held at that level for a few samples at each of a few crests: a clip
    for start in (500, 1500, 2500, 3500):
        u[start:start + 6] = 10.0
    sat = detect_saturation(u)
    assert sat is not None and sat.high == pytest.approx(10.0)


def test_the_filter_follows_a_coarse_sensor_and_keeps_the_recipe_on_a_fine_one() -> None:
    ts = 2e-3
    t = np.arange(10000) * ts
    x = 1.5 * np.sin(2 * np.pi * 0.1 * t)
    q = 0.0614  # a 10-bit potentiometer, rad
    coarse = q * np.round(x / q)
    fc, decim, source = choose_filter(coarse, ts, NoiseFloor(0.0, q, "quantum"))
    assert source == "sensor resolution"
    assert 0.5 < fc < 5.0 and decim > 10
    fc, decim, source = choose_filter(x, ts, NoiseFloor(1e-7, 0.0))
    assert (fc, decim, source) == (pytest.approx(50.0), 10, "default")


# -- artefacts ------------------------------------------------------------------------------------
def _cogging_model(period: float) -> GreyBox:
    p = CL.default_plant(1.0, 1.0)
    p[CL.I_COGA], p[CL.I_COGB], p[CL.I_COGP] = 0.3, 0.1, period
    ctrl = ArxController(a=np.zeros(0), b=np.zeros(6), c=np.zeros(4), lead=2)
    return GreyBox(ctrl, p, ("cogging",))


@pytest.mark.parametrize("multiple", [1, 2, 3])
def test_a_period_at_a_multiple_of_the_quantum_is_the_sensor(multiple: int) -> None:
    rng = np.random.default_rng(multiple)
    q = 3.5 * np.pi / 180
    t = np.arange(4000) * 2e-3
    x = q * np.round(1.2 * np.sin(t) / q)
    run = validate_arrays(t, 1.2 * np.sin(t), x)
    prep = prepare(run)
    assert prep.noise.quantum == pytest.approx(q, rel=1e-3)
    b = Bounds(force=1.0, stroke=prep.stroke, v_max=1.2, duration=8.0, ts=2e-3, noise=q / 3.5)
    # a period the stroke cannot tell from the quantum's multiple: within one cycle over it
    resolution = multiple * q / prep.stroke
    off = rng.uniform(-0.9, 0.9) * resolution
    why = artefact(_cogging_model(multiple * q * (1.0 + off)), "cogging", prep, b)
    assert why is not None and "quantum" in why
    # one told apart from it: a cycle and a half more or less over the stroke
    assert artefact(_cogging_model(multiple * q * (1.0 + 1.5 * resolution)), "cogging", prep,
                    b) is None
    assert artefact(_cogging_model(prep.stroke / 3.3), "cogging", prep, b) is None
    assert "stroke" in str(artefact(_cogging_model(1.5 * prep.stroke), "cogging", prep, b))


@pytest.mark.parametrize("ratio", [0.96, 1.0, 1.04])
def test_a_second_periodic_term_at_the_period_of_the_first_is_the_same_term(ratio: float
                                                                           ) -> None:
    t = np.arange(4000) * 1e-3
    run = validate_arrays(t, 0.05 * np.sin(t), 0.05 * np.sin(t - 0.01))
    prep = prepare(run)
    b = Bounds(force=1.0, stroke=prep.stroke, v_max=0.05, duration=4.0, ts=1e-3, noise=1e-7)
    cog = 0.2 * prep.stroke
    m = _cogging_model(cog)
    p = m.plant.copy()
    p[CL.I_PDG], p[CL.I_PDA], p[CL.I_PDP], p[CL.I_XC] = 1.0, 0.2, ratio * cog, prep.center
    m = m.copy(plant=p, effects=("coulomb_friction", "cogging", "position_dependent_friction"))
    why = artefact(m, "position_dependent_friction", prep, b)
    assert why is not None and "that of cogging" in why
    # a friction varying at another period is a second effect
    p[CL.I_PDP] = 1.5 * cog
    assert artefact(m.copy(plant=p), "position_dependent_friction", prep, b) is None


@pytest.mark.parametrize(("inside", "on_bound"), [(1.5e-4, True), (5e-4, True), (1e-2, False)])
def test_a_shape_parameter_pressed_against_its_bound_is_on_it(inside: float,
                                                               on_bound: bool) -> None:
    # the trust-region solver stops a little inside a bound it presses against (posdep/28 of
    # the second simulator: a damping ratio 1.5e-4 inside its bound, named at 1e-4)
    t = np.arange(4000) * 1e-3
    prep = prepare(validate_arrays(t, 0.05 * np.sin(t), 0.05 * np.sin(t - 0.01)))
    b = Bounds(force=1.0, stroke=prep.stroke, v_max=0.05, duration=4.0, ts=1e-3, noise=1e-7)
    m = _cogging_model(0.2 * prep.stroke)
    p = m.plant.copy()
    hi = get_effect("compliance").bounds(CL.I_CZ, 0.05, b).hi
    p[CL.I_CR], p[CL.I_CF], p[CL.I_CZ] = 0.5, 20.0, hi * (1.0 - inside)
    why = artefact(m.copy(plant=p, effects=("compliance",)), "compliance", prep, b)
    assert (why is not None and "upper bound" in why) == on_bound


# -- residual description -------------------------------------------------------------------------
def test_describe_names_the_structure_of_a_residual() -> None:
    rng = np.random.default_rng(4)
    ts, n = 1e-3, 8000
    t = np.arange(n) * ts
    x = 0.02 * np.sin(2 * np.pi * 0.5 * t)
    v = np.gradient(x, ts)
    noise = 1e-7 * rng.standard_normal(n)
    assert "drift" in describe(2e-6 * (1 - np.exp(-t / 3)) + noise, x, v, ts)
    assert "lag" in describe(-2e-3 * v + noise, x, v, ts)
    assert "position" in describe(1e-6 * np.sin(2 * np.pi * x / 3e-3) + noise, x, v, ts)
    assert "resonance" in describe(1e-6 * np.sin(2 * np.pi * 37.0 * t) + noise, x, v, ts)
    assert "no dominant" in describe(noise, x, v, ts)


# -- whole diagnoses ------------------------------------------------------------------------------
def _check_report(out: dict) -> None:
    assert out["verdict"] in VERDICTS
    assert isinstance(out["warnings"], list) and all(isinstance(w, str) for w in out["warnings"])
    assert _non_finite(out) == []


@pytest.mark.parametrize("seed", [5, 6])
def test_a_saturating_loop_is_simulated_with_its_clip(seed: int) -> None:
    rng = np.random.default_rng(seed)
    t, xr, x, u = _pd_loop(rng, coulomb=0.0)
    clip = 0.6 * float(np.max(np.abs(u)))
    t, xr, x, u = _pd_loop(np.random.default_rng(seed), clip=clip)
    res = diagnose(validate_arrays(t, xr, x, u))
    out = res.to_dict()
    _check_report(out)
    assert out["data"]["effort_saturation"]["level"] == pytest.approx(clip)
    assert any("saturates" in w for w in out["warnings"])
    # the clipped law drives the free run: the linear model follows the data closely
    assert out["position"]["rms_before"] < 0.05 * float(np.std(x))


def test_an_effort_the_law_cannot_reproduce_falls_back_to_the_position() -> None:
    rng = np.random.default_rng(7)
    t, xr, x, u = _pd_loop(rng, coulomb=0.0, noise=1e-7)
    garbled = u + 2.0 * float(np.std(u)) * rng.standard_normal(u.shape[0])
    res = diagnose(validate_arrays(t, xr, x, garbled))
    out = res.to_dict()
    _check_report(out)
    # the law (93 % of the effort unexplained) still closes a loop that can be simulated, so
    # the effort's diagnosis runs and the criterion chooses the position's over it
    assert res.mode == "position"
    assert out["mode_comparison"]["chosen"] == "position"
    assert out["mode_comparison"]["effort"]["law_relerr_pct"] > 50.0
    assert out["mode_comparison"]["criterion"]["criterion_change"] < 0.0
    assert any("the law does not reproduce the drive's loop" in w for w in out["warnings"])


def test_a_linear_pd_loop_gets_no_effect_and_every_number_is_finite() -> None:
    rng = np.random.default_rng(8)
    t, xr, x, u = _pd_loop(rng, noise=2e-7)
    out = diagnose(validate_arrays(t, xr, x, u)).to_dict()
    _check_report(out)
    assert out["effects"] == []
    # the law is exact (the controller read the logged position at the loop's rate): the
    # effort is kept, without a comparison with a loop fitted to the position (whose free run
    # trades the noise the controller fed back for lower gains and a false force offset)
    assert out["data"]["mode"] == "effort" and "mode_comparison" not in out
    assert out["verdict"] in {"nothing_to_explain", "not_explained"}
    assert out["verdict"] != "not_explained" or out["verdict_detail"]["residual"]


@pytest.mark.xfail(strict=True, reason="position only, a PD law without integral action is "
                   "not in the model class (a cascade's integral rate is at least 2 % of its "
                   "velocity gain, a PID's position integral at least 0.1 % of wv^2: without "
                   "it friction imitates backlash), and a force offset stands in (3.92 -> "
                   "2.08 um, prediction floor 0.62 um)")
def test_a_linear_pd_loop_gets_no_effect_from_the_position_alone() -> None:
    rng = np.random.default_rng(8)
    t, xr, x, _ = _pd_loop(rng, noise=2e-7)
    out = diagnose(validate_arrays(t, xr, x)).to_dict()
    _check_report(out)
    assert out["effects"] == []


def test_the_step_run_of_the_dc_motor_is_diagnosed_honestly() -> None:
    """The shared DC-motor step log, read as logged: no error, no cogging, per-run laws."""
    import os

    from fricbench.sysid.io import load_run

    root = os.path.join(os.environ["FRICBENCH_SHARED"], "data", "keiel_dcmotor")
    if not os.path.isdir(root):
        pytest.fail(f"{root} is missing: the DC-motor logs are part of the shared data set")
    kw = dict(time=None, reference=0, position=1, effort=3, sample_time=0.002,
              position_unit="deg", effort_required=True)
    sine = load_run(os.path.join(root, "dc_motor_position_control_pid.csv"), **kw)
    step = load_run(os.path.join(root, "dc_motor_position_control_pid_step.csv"), **kw)
    for train, other in ((step, sine), (sine, step)):
        res = diagnose(train, validate=other)
        out = res.to_dict()
        _check_report(out)
        assert "cogging" not in out["effects"]
        assert out["data"]["filter_chosen_by"] == "sensor resolution"
        assert "validation run" in out["controller_laws"]["validation"]
        val = out["validation"]["position"]
        assert val["rms_after"] <= 1.02 * val["rms_before"]
        assert math.isfinite(val["rms_after"])
        # the step run moves faster than the sine run ever did after its start-up (9 % of
        # its samples), and the sine run's stroke is inside the step run's overshoots
        faster = [w for w in out["warnings"] if "moves faster" in w]
        assert bool(faster) == (train is sine)
        if faster:
            assert out["validation"]["coverage"]["share_faster_pct"] > 5.0


def test_the_effort_error_while_sliding_leaves_out_the_rests() -> None:
    """Beside the effort error over every sample, the report gives it over the samples where
    the axis slides (speed above ``settings.rest_speed_share`` of its largest, the share below
    which the inverse dynamics leaves a sample out as at rest), computed on exactly those
    rows."""
    from fricbench.sysid.diagnose.models import InverseDynamics

    rng = np.random.default_rng(4)
    t, xr, x, u = _pd_loop(rng, coulomb=0.3, noise=2e-7)
    res = diagnose(validate_arrays(t, xr, x, u))
    effort = res.train.effort()
    assert effort is not None
    idim = InverseDynamics(res.prep, res.prep.u, delay=int(res.linear.plant[CL.I_DELAY]))
    speed = np.abs(idim.v_dec)
    rows = np.flatnonzero(speed > DEFAULT_SETTINGS.rest_speed_share * speed.max())
    assert 20 <= rows.size < speed.size
    final = res.search.final.model
    assert effort["relerr_sliding_before_pct"] == idim.relerr(res.linear.plant, rows)
    assert effort["relerr_sliding_after_pct"] == idim.relerr(final.plant, rows)
    assert effort["relerr_after_pct"] == idim.relerr(final.plant)
    assert effort["relerr_sliding_after_pct"] != effort["relerr_after_pct"]
    assert "relerr_sliding_after_pct" in res.to_dict()["effort"]


@pytest.mark.parametrize("seed", [2, 4])
def test_a_loop_that_starts_moving_gets_no_command_delay(seed: int) -> None:
    """A PD loop (no delay in it) whose reference starts at speed: the free run's start-up
    transient, from a state estimated at the record's edge, is no evidence of a delay."""
    from fricbench.sysid.diagnose.baselines import fit_linear_with_effort

    t, xr, x, u = _pd_loop(np.random.default_rng(seed), coulomb=0.3, noise=2e-7)
    model, idim, _, _ = fit_linear_with_effort(prepare(validate_arrays(t, xr, x, u)))
    assert int(model.plant[CL.I_DELAY]) == 0 and idim.delay == 0


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_the_inverse_dynamics_aligns_the_effort_for_a_zero_order_hold(seed: int) -> None:
    """A frictionless PD loop whose force is held over each sample: the effort regressed on
    the zero-phase acceleration half a sample late gives the damping within 0.5 % (regressed
    on the same sample, 0.7-1.4 % low on these seeds) and the mass within 2.5 %."""
    from fricbench.sysid.diagnose.models import InverseDynamics

    rng = np.random.default_rng(seed)
    m, b = rng.uniform(0.5, 2.0), rng.uniform(1.0, 5.0)  # the first draws of _pd_loop
    t, xr, x, u = _pd_loop(np.random.default_rng(seed))
    prep = prepare(validate_arrays(t, xr, x, u))
    idim = InverseDynamics(prep, prep.u)
    p = idim.fit((), CL.default_plant(1.0, 0.0))
    assert p[CL.I_B] == pytest.approx(b, rel=5e-3)
    assert p[CL.I_M] == pytest.approx(m, rel=2.5e-2)


@pytest.mark.parametrize("rotary", [False, True])
def test_a_backlash_on_its_largest_gap_stands_in_for_something_else(rotary: bool) -> None:
    """A gap's range is physical (a few mrad of a gear train, a mm of a screw, a fifth of the
    stroke), not a multiple of the force scale: a fit that ends there is rejected as a shape
    parameter on its bound is (the second simulator's thermal/24, without backlash, took a
    50 mrad gap as its first step); a gap inside the range is not."""
    t = np.arange(4000) * 1e-3
    amp = 1.0 if rotary else 0.05
    run = validate_arrays(t, amp * np.sin(t), amp * np.sin(t - 0.01))
    prep = prepare(run)
    b = Bounds(force=1.0, stroke=prep.stroke, v_max=amp, duration=4.0, ts=1e-3, noise=1e-7,
               rotary=rotary)
    largest = get_effect("backlash").bounds(CL.I_BL, 0.0, b).hi
    assert largest == pytest.approx(0.05 if rotary else 1e-3)
    p = CL.default_plant(1.0, 1.0)
    ctrl = ArxController(a=np.zeros(0), b=np.zeros(6), c=np.zeros(4), lead=2)
    for gap, rejected in ((largest, True), (0.9999999 * largest, True), (0.3 * largest, False)):
        p[CL.I_BL] = gap
        why = artefact(GreyBox(ctrl, p.copy(), ("coulomb_friction", "backlash")), "backlash",
                       prep, b)
        assert (why is not None and "upper bound" in why) == rejected, (gap, why)

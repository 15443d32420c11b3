"""Thermal drift driven by motion in the one plant (a heating state, ``thermal_heating_speed``)."""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest

from fricbench.axis import Axis, linear_law, simulate
from fricbench.axis import plant as PL
from fricbench.trajectories import make_trajectory
from fricbench.trajectories.base import Reference

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from plant_runs import open_loop  # noqa: E402

TS = 1.0e-3


def _free_run(row: np.ndarray, force: np.ndarray, v0: float, n_sub: int
              ) -> tuple[np.ndarray, np.ndarray]:
    """Logged (table) and motor positions of a plant row driven open loop by ``force``."""
    return open_loop(row, force, TS, n_sub, v0)


KP, KV = 160.0, 240.0
C = [-KV * KP - KV / (2 * TS), 0.0, KV / (2 * TS)]


def _heated_row(amp: float, tau: float, v_heat: float) -> np.ndarray:
    p = PL.default_row(2.0, 0.0, TS, 4)
    p[PL.TH_AMP], p[PL.TH_TAU], p[PL.TH_VHEAT] = amp, tau, v_heat
    return p


def test_constant_speed_heats_as_the_analytic_first_order_law() -> None:
    """No friction, no force: the axis coasts at v0, so theta = (v0 / v_heat)(1 - e^(-t/tau))."""
    amp, tau, v_heat, v0 = 3e-6, 0.4, 0.02, 0.05
    n = 2000
    y, x_motor = _free_run(_heated_row(amp, tau, v_heat), np.zeros(n), v0, n_sub=4)
    t = np.arange(n) * TS
    drift = y - x_motor
    want = amp * (v0 / v_heat) * -np.expm1(-t / tau)
    # to rounding: of the drift itself and of the positions (0.1 m) it is read off
    np.testing.assert_allclose(drift, want, rtol=1e-12, atol=4 * np.finfo(float).eps
                               * np.max(np.abs(x_motor)))
    # and not the time law's d_inf (1 - e^(-t/tau)): the speed ratio 2.5 scales it
    assert drift[-1] > 2.0 * amp


def test_heat_relaxes_at_rest() -> None:
    """Stopped after 0.5 s, theta decays as e^(-t/tau) and the motor stays put."""
    amp, tau, v_heat, v0, mass = 5e-6, 0.3, 0.01, 0.01, 2.0
    n, k_stop = 1500, 500
    force = np.zeros(n)
    # a force held over one sample that takes the free mass from v0 to rest exactly
    force[k_stop] = -mass * v0 / TS
    y, x_motor = _free_run(_heated_row(amp, tau, v_heat), force, v0, n_sub=5)
    drift = y - x_motor
    rest = slice(k_stop + 1, n)
    assert np.ptp(x_motor[rest]) == 0.0
    t = np.arange(n) * TS
    heated = amp * -np.expm1(-t[k_stop] / tau)
    assert drift[k_stop] == pytest.approx(heated, rel=1e-12)
    # to rounding of the positions (5 mm) the drift is read off
    want = drift[k_stop + 1] * np.exp(-(t[rest] - t[k_stop + 1]) / tau)
    np.testing.assert_allclose(drift[rest], want, rtol=1e-12,
                               atol=4 * np.finfo(float).eps * np.max(np.abs(x_motor)))
    assert drift[-1] < 0.05 * heated


def _law_axis(**effects: float | str) -> Axis:
    return Axis.from_dict({
        "controller": {"ts": TS, "n_substeps": 2, "kt": 35.0, "i_max": 10.0, "law": "linear",
                       "law_reference": [KV * KP, 0.0, 0.0], "law_position": C},
        "mechanics": {"mass": 95.0, "damping": 200.0},
        "friction": {"id": "coulomb", "fc": 20.0},
        "effects": dict(effects)})


def test_kernel_and_linear_law_drivers_agree_bit_for_bit_with_heating() -> None:
    """The env's kernel and the diagnosis's driver carry the heating state the same way."""
    axis = _law_axis(thermal_drift=8e-6, thermal_time_constant=0.7,
                     thermal_heating_speed=0.02)
    ref = make_trajectory("m_serial", ts=TS)
    res = simulate(axis, ref)
    y, u = linear_law.simulate_one(
        axis.pack()[:PL.N_PLANT], np.zeros(0), np.array(C), KV * KP * ref.x, ref.t, TS,
        n_sub=2, x0=ref.x[0], v0=ref.v[0], u_init=np.zeros(0),
        y_init=ref.x[0] - ref.v[0] * TS * np.arange(1, 4))
    np.testing.assert_array_equal(res.x, y)
    np.testing.assert_array_equal(res.u, 35.0 * u)
    # the drift is on, seen by the logged (table) position only, and grows with the motion
    drift = res.x - res.x_true
    assert np.max(np.abs(drift)) > 1e-6


def test_motion_drift_follows_motion_not_time() -> None:
    """At rest the motion law leaves the axis cold; the time law grows regardless."""
    t = np.arange(3000) * TS
    still = Reference(t=t, x=np.full_like(t, 0.01), v=np.zeros_like(t), a=np.zeros_like(t),
                      name="still")
    timed = _law_axis(thermal_drift=8e-6, thermal_time_constant=0.7)
    heated = _law_axis(thermal_drift=8e-6, thermal_time_constant=0.7,
                       thermal_heating_speed=0.02)
    a, b = simulate(timed, still), simulate(heated, still)
    assert np.max(np.abs(a.x - a.x_true)) > 5e-6
    assert np.max(np.abs(b.x - b.x_true)) == 0.0


def test_heating_speed_zero_is_the_time_law_bit_for_bit() -> None:
    """A zero heating speed ignores the heating state: the 36-entry row's axis exactly."""
    axis = Axis().with_effects(thermal_drift=5e-6, thermal_time_constant=0.5,
                               noise_std=1e-8, measurement="table")
    ref = make_trajectory("s_curve")
    a = simulate(axis, ref, seed=2)
    assert axis.pack()[PL.TH_VHEAT] == 0.0
    row36 = axis.pack()[:PL.N_PLANT_COMPLIANT]
    assert np.array_equal(PL.pad_row(row36), axis.pack()[:PL.N_PLANT])
    b = simulate(axis.with_effects(thermal_heating_speed=0.0), ref, seed=2)
    for name in ("x", "x_true", "u", "friction"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_heating_speed_is_validated() -> None:
    with pytest.raises(ValueError, match=r"thermal_heating_speed=-0\.1: expected >= 0 m/s"):
        Axis().with_effects(thermal_heating_speed=-0.1)
    with pytest.raises(ValueError, match="thermal_heating_speed=nan"):
        Axis().with_effects(thermal_heating_speed=float("nan"))


def test_rows_of_earlier_layouts_are_padded_with_the_time_law() -> None:
    for n in (PL.N_PLANT_RIGID, PL.N_PLANT_COMPLIANT):
        row = PL.pad_row(PL.default_row(3.0)[:n])
        assert row.shape == (PL.N_PLANT,) and row[PL.TH_VHEAT] == 0.0
    assert PL.PLANT_NAMES[PL.TH_VHEAT] == "thermal_heating_speed"
    assert len(PL.PLANT_NAMES) == PL.N_PLANT


def test_a_strained_growth_is_proportional_to_the_distance_from_its_origin() -> None:
    """A screw grows from its bearing: ``d = (d_inf + e (x - x0)) (1 - e^(-t/tau))``; with the
    strain at 0 the 59-entry row's axis exactly."""
    amp, strain, x0, tau, v0 = 2e-6, 3e-4, 0.04, 0.5, 0.05
    n = 2000
    row = _heated_row(amp, tau, 0.0)
    row[PL.TH_STRAIN], row[PL.TH_X0] = strain, x0
    y, x_motor = _free_run(row, np.zeros(n), v0, n_sub=4)
    t = np.arange(n) * TS
    want = (amp + strain * (x_motor - x0)) * -np.expm1(-t / tau)
    np.testing.assert_allclose(y - x_motor, want, rtol=1e-12,
                               atol=4 * np.finfo(float).eps * np.max(np.abs(x_motor)))
    # the coasting table passes the origin: the growth changes sign with the distance
    assert np.ptp(np.sign(x_motor - x0)) == 2.0
    unstrained = _heated_row(amp, tau, 0.0)
    assert np.array_equal(PL.pad_row(unstrained[:PL.N_PLANT_UNSTRAINED]), unstrained)
    y0, _ = _free_run(unstrained, np.zeros(n), v0, n_sub=4)
    np.testing.assert_allclose(y0 - x_motor, amp * -np.expm1(-t / tau), rtol=1e-12,
                               atol=4 * np.finfo(float).eps * np.max(np.abs(x_motor)))


def test_thermal_strain_is_validated() -> None:
    with pytest.raises(ValueError, match=r"thermal_strain=0\.01: expected"):
        Axis().with_effects(thermal_strain=0.01)
    axis = Axis().with_effects(thermal_drift=5e-6, thermal_strain=2e-4,
                               thermal_strain_origin=0.1)
    assert axis.pack()[PL.TH_STRAIN] == 2e-4 and axis.pack()[PL.TH_X0] == 0.1

"""Open-loop diagnosis (issue 13, items 1 and 2): simulated effort-driven runs and EMPS.

The simulated runs come from an integrator written here (implicit Coulomb step, substeps),
independent of :mod:`fricbench.axis.plant`; parameters are drawn with a seed.
"""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest

from fricbench.axis import plant as PL
from fricbench.axis.open_loop import initial_state, simulate_open_loop
from fricbench.sysid.diagnose.command import main as diagnose_main
from fricbench.sysid.diagnose.open_loop import (
    BASE_EFFECTS,
    OpenLoopModel,
    fit_open_loop,
    periodic_statistics,
)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from rigid_axis import TS  # noqa: E402
from rigid_axis import multisine as _multisine  # noqa: E402
from rigid_axis import simulate_axis as _simulate_stribeck_axis  # noqa: E402

EMPS = os.path.join(os.environ["FRICBENCH_SHARED"], "data", "emps")


def _simulate_axis(u: np.ndarray, m: float, b: float, fc: float, f0: float,
                   n_sub: int = 10) -> np.ndarray:
    """M dv/dt = u - B v - fc sgn(v) - f0, implicit in the friction (sticks exactly): the
    Stribeck axis without its hump (fs = fc), the same numbers."""
    return _simulate_stribeck_axis(u, m, b, fc, fc, 1.0, f0, n_sub)


def _draw(seed: int) -> tuple[dict[str, float], np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    par = {"m": float(rng.uniform(2.0, 8.0)), "b": float(rng.uniform(20.0, 80.0)),
           "fc": float(rng.uniform(3.0, 10.0)), "f0": float(rng.uniform(-2.0, 2.0))}
    u = _multisine(6000, rng, amp=6.0 * par["fc"], period_s=2.0)
    y = _simulate_axis(u, par["m"], par["b"], par["fc"], par["f0"])
    y = y + 1e-7 * rng.standard_normal(y.size)
    return par, u, y


@pytest.mark.parametrize("seed", [0, 1])
def test_fit_recovers_rigid_axis(seed: int) -> None:
    par, u, y = _draw(seed)
    start = PL.default_row(0.7 * par["m"], 0.7 * par["b"], TS)
    start[PL.FC] = 0.5 * par["fc"]
    model, rms = fit_open_loop(OpenLoopModel(start, BASE_EFFECTS), u, y, TS,
                               segments=[(0, y.size)], n_init=20)
    p = model.plant
    assert rms < 1e-3 * np.ptp(y)
    assert p[PL.M] == pytest.approx(par["m"], rel=0.05)
    assert p[PL.B] == pytest.approx(par["b"], rel=0.05)
    assert p[PL.FC] == pytest.approx(par["fc"], rel=0.05)
    assert p[PL.OFFSET] == pytest.approx(par["f0"], abs=0.05 * par["fc"])


def test_driver_matches_own_integrator() -> None:
    par, u, y = _draw(3)
    p = PL.default_row(par["m"], par["b"], TS)
    p[PL.FC], p[PL.OFFSET] = par["fc"], par["f0"]
    ys, status = simulate_open_loop(p, u, TS, x0=0.0, v0=0.0, n_sub=10)
    assert status[0] == 0
    assert np.max(np.abs(ys[0] - y)) < 1e-3 * np.ptp(y)
    x0, v0 = initial_state(y, TS, 20)
    assert abs(x0) < 1e-3 * np.ptp(y)


def test_periodic_statistics_on_periodic_run() -> None:
    par, u, y = _draw(4)
    per = periodic_statistics(y, y, u, TS, 20)
    assert per is not None
    assert per["period_s"] == pytest.approx(2.0, rel=0.01)
    assert per["periods"] == 3


def test_cli_open_loop_without_reference(tmp_path: pytest.TempPathFactory) -> None:
    par, u, y = _draw(5)
    csv = os.path.join(str(tmp_path), "run.csv")
    np.savetxt(csv, np.column_stack([np.arange(y.size) * TS, y, u]), delimiter=",",
               header="t,x,u", comments="", fmt="%.12g")
    out = os.path.join(str(tmp_path), "report.json")
    # without --open-loop the missing reference is refused with a pointer to --open-loop
    assert diagnose_main([csv, "--quiet"]) == 2
    assert diagnose_main([csv, "--open-loop", "--max-effects", "1", "--json", out,
                          "--quiet"]) == 0
    with open(out) as fh:
        report = json.load(fh)
    for key in ("verdict", "warnings", "position", "effort", "effects", "parameter_sd",
                "not_detected"):
        assert key in report
    # the open loop reports its noise floor as the closed loop does: the sensor's noise (here
    # 1e-7 m white) and the floor of a held-out free run, at or above it (the initial state
    # taken from noisy samples drifts the simulated mass: a few times the noise)
    nf = report["noise_floor"]
    assert nf["sigma_m"] == pytest.approx(1e-7, rel=0.3)
    assert nf["rms_m"] <= nf["prediction_floor_m"] < 1e-3 * np.ptp(y)
    assert report["position"]["rms_after"] < 0.02 * np.ptp(y)
    assert "coulomb_friction" in report["effects"]
    assert report["parameters"]["coulomb_friction"]["fc_N"] == pytest.approx(par["fc"], rel=0.1)


def test_open_loop_hum_is_a_sensor_disturbance(tmp_path: pytest.TempPathFactory) -> None:
    # the same run with mains hum on the position sensor (no reference: no rests, the lines
    # are found in the free run's residual)
    par, u, y = _draw(5)
    t = np.arange(y.size) * TS
    hum = 2e-6 * np.sin(2 * np.pi * 50.03 * t + 0.4) + 0.6e-6 * np.sin(2 * np.pi * 150.09 * t)
    csv = os.path.join(str(tmp_path), "run.csv")
    np.savetxt(csv, np.column_stack([t, 1e3 * (y + hum), u]), delimiter=",",
               header="t,x,u", comments="", fmt="%.12g")
    out = os.path.join(str(tmp_path), "report.json")
    assert diagnose_main([csv, "--open-loop", "--position-unit", "mm", "--max-effects", "1",
                          "--json", out, "--quiet"]) == 0
    with open(out) as fh:
        report = json.load(fh)
    lines = report["sensor_disturbance"]
    assert [(ln["mains_hz"], ln["harmonic"], ln["where"]) for ln in lines] == [
        (50.0, 1, "residual"), (50.0, 3, "residual")]
    assert lines[0]["frequency_hz"] == pytest.approx(50.03, abs=0.01)
    assert lines[0]["amplitude_m"] == pytest.approx(2e-6, rel=0.05)
    assert lines[0]["unit"] == "mm" and lines[0]["amplitude"] == pytest.approx(2e-3, rel=0.05)
    nf = report["noise_floor"]
    assert nf["sensor_disturbance_rms_m"] == pytest.approx(np.sqrt(2e-12 + 0.18e-12), rel=0.1)
    assert nf["prediction_floor_m"] >= nf["sensor_disturbance_rms_m"]
    assert any(w.startswith("sensor disturbance") for w in report["warnings"])


MEASURED_TEST_MM = 6.84


@pytest.mark.xfail(strict=True, reason=(
    "issue 13 target <= 3.0 mm not reached: the held-out search keeps coulomb+offset and the "
    f"test run gives {MEASURED_TEST_MM} mm (R^2 0.993); the pulse run needs 0.4-1.6 N more "
    "friction at the plateaus than the training run, which a train-only rigid model cannot see"))
def test_emps_protocol_target() -> None:
    res = _protocol()
    assert 1e3 * res.test["rms"] <= 3.0


_CACHE: dict[str, object] = {}


def _protocol():  # type: ignore[no-untyped-def]
    if not os.path.isdir(EMPS):
        pytest.fail(f"{EMPS} is missing: the EMPS data are part of the shared data set")
    if "res" not in _CACHE:
        from fricbench.bench.emps_protocol import run_protocol

        _CACHE["res"] = run_protocol(EMPS)
    return _CACHE["res"]


def test_emps_protocol_measured() -> None:
    res = _protocol()
    # what the protocol reaches (measured): beats the published IDIM-LS simulated the same way
    assert 1e3 * res.test["rms"] == pytest.approx(MEASURED_TEST_MM, abs=0.3)
    assert res.test["r2"] > 0.99
    assert 1e3 * res.idim_test["rms"] == pytest.approx(8.41, abs=0.05)
    assert res.test["rms"] < res.idim_test["rms"]


def test_emps_protocol_plot_and_json(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from fricbench.bench.emps_protocol import plot_test_run

    res = _protocol()
    tr = res.traces
    assert tr["q_test"].shape == tr["y_test"].shape == tr["t"].shape
    # the traces are the figures' own: the test RMSE recomputed from them
    e = (tr["q_test"] - tr["y_test"])[20:]
    assert float(np.sqrt(np.mean(e**2))) == pytest.approx(res.test["rms"], rel=1e-9)
    out = tmp_path / "test.png"
    plot_test_run(res, out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("effect", ["stribeck_friction", "position_dependent_friction"])
def test_an_absent_effect_fitted_anyway_is_not_detected(effect: str) -> None:
    # a rigid axis with Coulomb friction only: a Stribeck excess or a friction varying along
    # the stroke, fitted in, lies within two standard deviations of zero
    from fricbench.sysid.diagnose import open_loop as O
    from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS

    par, u, y = _draw(0)
    fit = O._fit_multistart((*BASE_EFFECTS, effect), u, y, TS, [(0, y.size)], 20)
    sd, n_eff = O._uncertainty(fit, DEFAULT_SETTINGS)
    assert 1.0 <= n_eff <= y.size
    weak = O._least_detected(fit, n_eff, DEFAULT_SETTINGS)
    assert weak is not None and weak[0] == effect
    # the friction that is there is detected, its standard deviation a small share of it
    i = fit.idx.index(PL.FC)
    assert fit.model.plant[PL.FC] > 10 * sd[i]
    assert fit.model.plant[PL.FC] == pytest.approx(par["fc"], abs=10 * sd[i] + 0.01 * par["fc"])


def test_a_friction_the_linearised_sd_holds_within_is_kept_by_its_profile(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # the Jacobian's test made to call the Coulomb friction within its sd (as it can where
    # the free run is far from linear in the level): the fit without it leaves many times
    # the squared error, so the profile form detects it and it stays, with its statistic
    from fricbench.sysid.diagnose import open_loop as O

    size_over_sd = O._size_over_sd
    monkeypatch.setattr(O, "_size_over_sd", lambda fit, n_eff: {
        **size_over_sd(fit, n_eff), "coulomb_friction": 0.5})
    par, u, y = _draw(1)
    fit = O.search_open_loop(u, y, TS, candidates=())
    assert "coulomb_friction" in fit.model.effects
    assert fit.not_detected == []
    item = fit.profile_detected["coulomb_friction"]
    assert item["size_over_sd"] == 0.5 and item["profile_statistic"] > 4.0


def test_search_reports_the_parameters_standard_deviations() -> None:
    from fricbench.sysid.diagnose.open_loop import search_open_loop

    par, u, y = _draw(1)
    fit = search_open_loop(u, y, TS, candidates=())
    sd = fit.uncertainty("N")
    assert set(sd) == set(fit.model.describe("N"))
    for key, value in fit.model.describe("N").items():
        spread = sd[key]
        if isinstance(value, dict):
            assert isinstance(spread, dict) and set(spread) == set(value)
            assert all(np.isfinite(v) and v > 0.0 for v in spread.values())
        else:
            assert isinstance(spread, float) and 0.0 < spread < 0.05 * abs(value)
    assert fit.not_detected == []


def test_stribeck_friction_found_open_loop() -> None:
    # an effort-driven axis with Stribeck friction (parameters drawn here): the one search
    # adds it first (its velocity fitted from starts at shares of the top speed), the held-out
    # error falls many times, and its sizes come back
    from fricbench.sysid.diagnose.open_loop import search_open_loop

    rng = np.random.default_rng(0)
    m, b = float(rng.uniform(2.0, 8.0)), float(rng.uniform(20.0, 80.0))
    fc, f0 = float(rng.uniform(3.0, 10.0)), float(rng.uniform(-1.0, 1.0))
    fs = fc * float(rng.uniform(1.5, 2.5))
    u = _multisine(10000, rng, amp=4.0 * fc, period_s=2.0)
    v_max = float(np.max(np.abs(np.gradient(_simulate_axis(u, m, b, fc, f0), TS))))
    vs = float(rng.uniform(0.05, 0.15)) * v_max
    y = _simulate_stribeck_axis(u, m, b, fc, fs, vs, f0)
    y = y + 1e-7 * rng.standard_normal(y.size)
    fit = search_open_loop(u, y, TS, max_effects=1)
    assert fit.model.effects == (*BASE_EFFECTS, "stribeck_friction")
    base = fit.heldout["+".join(BASE_EFFECTS)]
    with_it = fit.heldout["+".join(fit.model.effects)]
    print(f"held-out {1e3 * base:.4g} -> {1e3 * with_it:.4g} mm; true fc {fc:.4g}, fs-fc "
          f"{fs - fc:.4g}, vs {vs:.4g}; fitted {fit.model.describe('N')}")
    assert with_it < 0.3 * base
    assert fit.not_detected == []
    got = fit.model.describe("N")
    assert got["coulomb_friction"]["fc_N"] == pytest.approx(fc, rel=0.05)
    assert got["stribeck_friction"]["fs_minus_fc_N"] == pytest.approx(fs - fc, rel=0.1)
    assert got["stribeck_friction"]["vs_m_s"] == pytest.approx(vs, rel=0.1)
    assert fit.train_rms < 1e-3 * np.ptp(y)

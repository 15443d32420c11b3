"""The plant substeps the diagnosis integrates with (:mod:`fricbench.sysid.diagnose.prepared`)."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.sysid.diagnose.prepared import MAX_STEP, N_SUB_MIN, prepare, substeps
from fricbench.sysid.io import RunData, validate_arrays


@pytest.mark.parametrize("ts", [1e-4, 5e-4, 1e-3, 2e-3, 4e-3, 0.01, 0.0125, 0.05])
@pytest.mark.parametrize("n_loop", [1, 2, 10])
def test_the_step_is_at_most_max_step_and_no_finer_than_it_needs(ts: float, n_loop: int
                                                                  ) -> None:
    k = substeps(ts, n_loop)
    assert k >= N_SUB_MIN
    h = ts / n_loop / k
    assert h <= MAX_STEP * (1 + 1e-9)
    # one substep fewer would break the step, unless the floor of N_SUB_MIN set it
    assert k == N_SUB_MIN or ts / n_loop / (k - 1) > MAX_STEP


def test_a_1_khz_log_keeps_two_substeps_and_a_100_hz_log_gets_ten() -> None:
    assert substeps(1e-3) == 2  # the timing benchmark's and EMPS's logs: as before
    assert substeps(2e-3) == 2
    assert substeps(0.01) == 10
    # a sample time read from a rounded time column
    assert substeps(0.01 * (1 + 1e-9)) == 10
    assert substeps(0.01, 10) == N_SUB_MIN


def _run(ts: float, n: int = 1_000) -> RunData:
    t = np.arange(n) * ts
    x_ref = 0.01 * np.sin(2 * np.pi * 0.5 * t)
    return validate_arrays(t, x_ref, x_ref + 1e-6 * np.cos(7 * t))


def test_prepare_chooses_the_substeps_from_the_sample_time_unless_told() -> None:
    assert prepare(_run(0.01)).n_sub == 10
    assert prepare(_run(1e-3)).n_sub == 2
    assert prepare(_run(0.01), n_sub=3).n_sub == 3


def test_with_loop_keeps_the_substeps_per_logged_sample() -> None:
    prep = prepare(_run(0.01))
    fast = prep.with_loop(5)
    assert fast.inputs.n_loop == 5
    assert fast.n_sub * 5 == prep.n_sub
    assert fast.with_loop(1).n_sub == prep.n_sub  # and back: the same step again
    # each loop period keeps N_SUB_MIN, the step only gets finer
    assert prep.with_loop(10).n_sub == N_SUB_MIN



def _coarse_sensor_run(rng: np.random.Generator) -> tuple[RunData, float]:
    """A slow sine tracked with a fast ripple of about a quantum (a loop hunting on a coarse
    sensor), the effort its exact rigid-body force, the position read through a 10-bit
    potentiometer's step (0.0614 rad)."""
    ts, n = 2e-3, 10_000
    t = np.arange(n) * ts
    mass, damping, coulomb = rng.uniform(1.0, 4.0), rng.uniform(10.0, 40.0), rng.uniform(3.0, 12.0)
    ripple = rng.uniform(0.015, 0.02) * np.sin(2 * np.pi * rng.uniform(2.3, 3.0) * t
                                               + rng.uniform(0.0, 2 * np.pi))
    x_ref = 1.5 * np.sin(2 * np.pi * 0.1 * t)
    x = x_ref + ripple
    v = np.gradient(x, ts)
    u = mass * np.gradient(v, ts) + damping * v + coulomb * np.sign(v)
    q = 0.0614
    return validate_arrays(t, x_ref, q * np.round(x / q), u, position_unit="rad"), mass


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_the_effort_passes_the_derivative_filter_when_that_is_the_narrower(seed: int) -> None:
    # a filter chosen from a coarse sensor (about 2 Hz) is far narrower than the decimation's
    # low-pass (10 Hz here): an effort that kept the ripple's band, which the acceleration
    # had lost, gave a mass 2.5 to 3.7 times too large; filtered alike it is within a third
    # (the ripple reverses the velocity near the sine's turns, where no filtered velocity sees
    # it: the damping and Coulomb level take that, with or without the filter, and are not
    # checked)
    from fricbench.sysid.diagnose import closed_loop as CL
    from fricbench.sysid.diagnose.models import InverseDynamics

    run, mass = _coarse_sensor_run(np.random.default_rng(seed))
    prep = prepare(run)
    assert run.u is not None
    assert prep.filter_source == "sensor resolution"
    assert prep.filters_effort
    p = InverseDynamics(prep, run.u).fit(("coulomb_friction",), CL.default_plant(1.0, 0.0))
    assert p[CL.I_M] == pytest.approx(mass, rel=0.35)


def test_the_recipes_filter_leaves_the_effort_as_it_is() -> None:
    run, _ = _coarse_sensor_run(np.random.default_rng(0))
    assert run.u is not None
    wide = prepare(run, cutoff_hz=50.0, decim=10)
    assert not wide.filters_effort
    assert wide.effort_filtered(run.u) is run.u

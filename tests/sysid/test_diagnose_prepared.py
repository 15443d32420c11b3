"""The plant substeps the diagnosis integrates with (:mod:`fricbench.sysid.diagnose.prepared`)."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.sysid.diagnose.prepared import prepare, substeps
from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS
from fricbench.sysid.io import RunData, validate_arrays


@pytest.mark.parametrize("ts", [1e-4, 5e-4, 1e-3, 2e-3, 4e-3, 0.01, 0.0125, 0.05])
@pytest.mark.parametrize("n_loop", [1, 2, 10])
def test_the_step_is_at_most_the_drives_loop_period_and_no_finer_than_it_needs(
        ts: float, n_loop: int) -> None:
    k = substeps(ts, n_loop)
    assert k >= DEFAULT_SETTINGS.n_sub_min
    h = ts / n_loop / k
    assert h <= DEFAULT_SETTINGS.loop_ts * (1 + 1e-9)
    # one substep fewer would break the step, unless the floor of settings.n_sub_min set it
    assert k == DEFAULT_SETTINGS.n_sub_min or ts / n_loop / (k - 1) > DEFAULT_SETTINGS.loop_ts


def test_a_1_khz_log_keeps_two_substeps_and_a_100_hz_log_gets_ten() -> None:
    assert substeps(1e-3) == 2  # the timing benchmark's and EMPS's logs: as before
    assert substeps(2e-3) == 2
    assert substeps(0.01) == 10
    # a sample time read from a rounded time column
    assert substeps(0.01 * (1 + 1e-9)) == 10
    assert substeps(0.01, 10) == DEFAULT_SETTINGS.n_sub_min


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
    # each loop period keeps settings.n_sub_min, the step only gets finer
    assert prep.with_loop(10).n_sub == DEFAULT_SETTINGS.n_sub_min

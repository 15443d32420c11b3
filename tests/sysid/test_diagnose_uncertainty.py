"""The closed-loop model's parameter uncertainty (:mod:`fricbench.sysid.diagnose.uncertainty`)."""

from __future__ import annotations

import math
import os
import sys

import numpy as np
import pytest

from fricbench.axis import Axis, simulate
from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.models import Bounds
from fricbench.sysid.diagnose.prepared import prepare
from fricbench.sysid.diagnose.uncertainty import model_uncertainty
from fricbench.sysid.io import validate_arrays
from fricbench.trajectories.base import Reference

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from test_diagnose_models import _grey_box_of  # noqa: E402


def _run(noise: float, seed: int = 0):
    """A 6 s run of fricbench's axis (Coulomb friction and a cogging ripple) and the exact
    grey box of it (mass normalised to 1)."""
    ts = 1e-3
    t = np.arange(6000) * ts
    x = 0.008 * np.sin(2 * np.pi * 0.4 * t) + 0.002 * np.sin(2 * np.pi * 1.7 * t + 0.3)
    s = np.clip((t - 0.2) / 0.5, 0.0, 1.0)
    x *= s**3 * (10.0 - 15.0 * s + 6.0 * s**2)
    axis = Axis().with_effects(cogging_amplitude=80.0, cogging_period=4e-3, noise_std=noise)
    res = simulate(axis, Reference.from_positions(t, x), seed=seed)
    prep = prepare(validate_arrays(res.t, res.x_ref, res.x), n_sub=axis.controller.n_substeps)
    model = _grey_box_of(axis)
    model = model.copy(effects=("coulomb_friction", "stribeck_friction", "cogging"))
    p = model.plant
    b = Bounds(force=5.0 * float(p[CL.I_FC]) + 10.0, stroke=prep.stroke, v_max=prep.v_max,
               duration=prep.duration, ts=ts, noise=prep.noise.rms)
    return prep, model, b


def test_a_present_effect_is_many_sd_from_zero_and_an_absent_one_is_not():
    """At the true model the cogging and the friction levels stand many standard deviations
    from zero; a backlash of 1 nm added beside them (1/50 of the noise) lies within 2 sd of
    zero. Every figure is finite."""
    prep, model, b = _run(5e-8)
    unc = model_uncertainty(model, prep, b, force_unit="m_s2")
    assert unc.size_over_sd["cogging"] > 10.0
    assert unc.size_over_sd["coulomb_friction"] > 10.0
    assert unc.within(2.0) == []
    assert 1.0 <= unc.n_eff <= prep.n
    for values in unc.sd.values():
        assert all(math.isfinite(v) and v >= 0.0 for v in values.values())
    spurious = model.copy(effects=model.effects + ("backlash",))
    spurious.plant[CL.I_BL] = 1e-9
    unc2 = model_uncertainty(spurious, prep, b, force_unit="m_s2")
    assert unc2.size_over_sd["backlash"] < 2.0
    assert "backlash" in unc2.within(2.0)
    assert unc2.size_over_sd["cogging"] > 10.0


def test_standard_deviations_grow_with_the_noise():
    """Four times the sensor noise (same seed): the cogging amplitude's standard deviation
    grows by about four (between 2 and 8: the residual's correlation changes a little)."""
    prep1, model, b1 = _run(5e-8)
    prep4, _, b4 = _run(2e-7)
    sd1 = model_uncertainty(model, prep1, b1, force_unit="m_s2").sd["cogging"]
    sd4 = model_uncertainty(model, prep4, b4, force_unit="m_s2").sd["cogging"]
    key = next(k for k in sd1 if k.startswith("amplitude"))
    assert 2.0 < sd4[key] / sd1[key] < 8.0


def test_a_model_without_effects_has_no_uncertainty_to_report():
    prep, model, b = _run(5e-8)
    unc = model_uncertainty(model.copy(effects=()), prep, b)
    assert unc.sd == {} and unc.to_dict()["size_over_sd"] == {}


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_model_whose_free_run_diverges_reports_nothing(bad: float):
    prep, model, b = _run(5e-8)
    broken = model.copy()
    broken.plant[CL.I_M] = bad
    assert model_uncertainty(broken, prep, b).sd == {}


def _jacobian(rng: np.random.Generator, n: int = 400, p: int = 4) -> tuple[np.ndarray, np.ndarray]:
    return rng.standard_normal((n, p)) * np.array([1.0, 30.0, 0.2, 5.0])[:p], \
        rng.standard_normal(n)


def test_the_conditional_sd_is_the_covariance_diagonal_when_every_column_counts():
    """With independent columns the projection's sd is ``sqrt`` of the output-error
    covariance's diagonal (same ``tau s^2``, same degrees of freedom)."""
    from fricbench.sysid.diagnose.criterion import conditional_sd as _conditional_sd
    from fricbench.sysid.diagnose.criterion import parameter_covariance

    jac, r = _jacobian(np.random.default_rng(3))
    keep = np.ones(jac.shape[1], dtype=bool)
    cov = parameter_covariance(jac, r, 100.0)
    for j in range(jac.shape[1]):
        assert _conditional_sd(jac, r, 100.0, j, keep) == pytest.approx(
            math.sqrt(cov[j, j]), rel=1e-9)


def test_collinear_other_columns_leak_nothing_into_a_size_and_a_column_in_their_span_is_unseen():
    """Two loop gains the run cannot tell apart (equal columns) leave a third parameter's sd
    what it is with one of them alone; a column that the others span has an infinite sd
    (its size is not seen at all)."""
    from fricbench.sysid.diagnose.criterion import conditional_sd as _conditional_sd

    jac, r = _jacobian(np.random.default_rng(4), p=3)
    twin = np.column_stack([jac, 2.0 * jac[:, 1]])
    keep3 = np.ones(3, dtype=bool)
    keep4 = np.ones(4, dtype=bool)
    alone = _conditional_sd(jac, r, 50.0, 0, keep3)
    # one parameter more in the count of degrees of freedom: (n - 3) / (n - 4)
    n = jac.shape[0]
    assert _conditional_sd(twin, r, 50.0, 0, keep4) == pytest.approx(
        alone * math.sqrt((n - 3) / (n - 4)), rel=1e-9)
    assert _conditional_sd(twin, r, 50.0, 3, keep4) == math.inf
    # held out of ``keep``, the twin no longer takes the column's place
    keep4[1] = False
    assert math.isfinite(_conditional_sd(twin, r, 50.0, 3, keep4))


def test_kept_columns_hold_a_bound_and_an_unmoved_column():
    from fricbench.sysid.diagnose.criterion import kept_columns

    jac, _ = _jacobian(np.random.default_rng(5))
    jac[:, 2] = 0.0
    keep = kept_columns(jac, np.array([False, True, False, False]))
    assert keep.tolist() == [True, False, False, True]


def test_the_size_test_holds_the_shape_and_reads_the_bounds():
    """The size is tested with its shape held: where the shape's column nearly repeats the
    size's, the marginal sd is many times the test's; a size on its upper bound is detected,
    one held out (a lower bound, moving nothing) is not; the least significant within the
    threshold is the one named."""
    from fricbench.sysid.diagnose.criterion import (
        conditional_sd,
        held_covariance,
        least_detected,
        size_over_sd,
    )

    rng = np.random.default_rng(6)
    jac, r = _jacobian(rng, p=3)
    jac[:, 2] = jac[:, 1] + 1e-3 * rng.standard_normal(jac.shape[0])  # 2: the size's shape
    keep = np.ones(3, dtype=bool)
    values, slope = np.array([0.0, 1.0, 1.0]), np.array([1.0, 2.0, 1.0])
    none = np.zeros(3, dtype=bool)
    z = size_over_sd(jac, r, 80.0, keep, [1], [2], values=values, slope=slope, upper=none)
    held = keep.copy()
    held[2] = False
    assert z == pytest.approx(1.0 / (2.0 * conditional_sd(jac, r, 80.0, 1, held)), rel=1e-12)
    marginal = 2.0 * math.sqrt(held_covariance(jac, r, 80.0, keep)[1, 1])
    assert 1.0 / marginal < z / 10.0
    assert size_over_sd(jac, r, 80.0, keep, [1], [2], values=values, slope=slope,
                        upper=np.array([False, True, False])) == math.inf
    assert size_over_sd(jac, r, 80.0, np.array([True, False, True]), [1], [2], values=values,
                        slope=slope, upper=none) == 0.0
    assert least_detected({"a": 3.0, "b": 1.5, "c": 0.5, "d": 0.5}, 2.0) == ("c", 0.5)
    assert least_detected({"a": 3.0}, 2.0) is None

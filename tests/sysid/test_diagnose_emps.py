"""The EMPS targets of issue 5 on the measured data of ``$FRICBENCH_SHARED/data/emps``.

Published (Janot, Gautier & Brunot 2019): Coulomb + viscous + offset 4.08 % on the training run
and 5.98 % cross-tested on the pulse run; asymmetric friction 3.11 % on the training run.
"""

from __future__ import annotations

import os

import pytest

from fricbench.sysid.diagnose import diagnose
from fricbench.sysid.io import load_run

ROOT = os.path.join(os.environ["FRICBENCH_SHARED"], "data", "emps")
COLUMNS = dict(time="t_s", reference="q_ref_m", position="q_m", effort="force_N",
               effort_required=True)


@pytest.fixture(scope="module")
def emps_report() -> dict:
    if not os.path.isdir(ROOT):
        pytest.fail(f"{ROOT} is missing: the EMPS data are part of the shared data set")
    train = load_run(os.path.join(ROOT, "emps_train.csv"), **COLUMNS)
    pulses = load_run(os.path.join(ROOT, "emps_test_pulses.csv"), **COLUMNS)
    return diagnose(train, validate=pulses).to_dict()


def test_emps_finds_coulomb_friction_and_the_offset(emps_report):
    effects = emps_report["effects"]
    assert effects[:2] == ["coulomb_friction", "force_offset"]
    # the published IDIM-LS levels: Fc = 20.39 N, offset = -3.16 N (before the asymmetry)
    fc = emps_report["steps"][0]["parameters"]["fc_N"]
    f0 = emps_report["steps"][1]["parameters"]["f0_N"]
    assert 19.0 < fc < 22.0 and -3.5 < f0 < -2.8


def test_emps_effort_error_beats_the_published_models(emps_report):
    effort = emps_report["effort"]
    assert effort["relerr_before_pct"] > 15.0  # the linear model: about 18 %
    assert effort["relerr_after_pct"] <= 4.08
    assert effort["relerr_after_pct"] < 3.11  # goal: the published asymmetric model
    cross = emps_report["validation"]["effort"]
    assert cross["relerr_after_pct"] <= 5.98


def test_emps_position_prediction_improves(emps_report):
    # (about 0.15 x on both runs; a law chosen through the wrong prefilter left 0.5 x on the
    # pulse run, 150.5 -> 74.75 um, which the former bound of 0.5 x let through)
    pos = emps_report["position"]
    assert pos["rms_after"] < 0.25 * pos["rms_before"]
    val = emps_report["validation"]["position"]
    assert val["rms_after"] < 0.25 * val["rms_before"]
    # the pulses are in the effort of the test run, not produced by the controller law
    assert emps_report["validation"]["injected_effort_used"] is True


def test_emps_says_why_the_training_runs_remainder_is_left_out(emps_report):
    # the training run's law leaves a fraction of a percent of the effort: not fed to
    # the free runs, and the report says so beside its share
    share = emps_report["data"]["injected_effort_share_pct"]
    assert 0.0 < share < 1.0
    assert any(f"{share:.1f} % (rms) of the effort is not explained" in n
               and "not fed to the simulations" in n for n in emps_report["notes"]), \
        emps_report["notes"]


def test_emps_steps_report_si_parameters_and_errors(emps_report):
    for step in emps_report["steps"]:
        assert set(step) >= {"effect", "parameters", "metrics"}
        assert {"position_rms_m", "effort_relerr_pct", "heldout_error_ratio"} <= set(
            step["metrics"])
        assert all(isinstance(v, float) for v in step["parameters"].values())

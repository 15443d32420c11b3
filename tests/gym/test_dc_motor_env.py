"""``fricbench/DCMotor-v0``: the twin of the shared hobby DC gear motor (a coarse sensor).

The spec (``envs/dc_motor.toml``) was written by ``fricbench diagnose --env-out`` from the PID
sine log of ``keiel_dcmotor`` (its head names the command), the potentiometer's step added.
Replayed on the log's reference: 0.0334 rad rms against the logged angle (0.0267 rad without
the sensor step; the diagnosis's free run 0.0264 rad, its linear model's 0.0266 rad).
"""

from __future__ import annotations

import os
from dataclasses import replace

import numpy as np
import pytest

from fricbench.axis import Axis, simulate
from fricbench.gym import env_ids, get_spec
from fricbench.trajectories import Reference

ENV_ID = "fricbench/DCMotor-v0"
LOG = os.path.join(os.environ["FRICBENCH_SHARED"], "data", "keiel_dcmotor",
                   "dc_motor_position_control_pid.csv")
DIAGNOSIS_RMS_RAD = 0.0264  # fricbench diagnose's free run on the log (the spec's head)
STEP_RAD = np.deg2rad(450.0 / 128.0)  # one count of the 10-bit ADC (the sketches)


def test_dc_motor_is_registered_benchmarked_and_says_where_it_came_from() -> None:
    assert ENV_ID in env_ids(benchmark_only=True)
    spec = get_spec(ENV_ID)
    assert spec.axis.controller.law == "linear" and spec.axis.controller.ts == 0.002
    assert spec.axis.controller.i_max == 100.0  # the clip seen in the log
    assert spec.axis.effects.quantization == pytest.approx(STEP_RAD)
    assert "dc_motor_position_control_pid.csv" in spec.description
    assert "fricbench diagnose" in spec.description and "Not modelled" in spec.description


def _replay(axis: Axis) -> float:
    if not os.path.isfile(LOG):
        pytest.fail(f"{LOG} is missing: the DC-motor logs are part of the shared data set")
    data = np.loadtxt(LOG, delimiter=",", skiprows=1)
    ts = axis.controller.ts
    x_ref, x = np.deg2rad(data[:, 0]), np.deg2rad(data[:, 1])
    v = np.gradient(x_ref, ts)
    ref = Reference(t=np.arange(x.size) * ts, x=x_ref, v=v, a=np.gradient(v, ts), name="log")
    res = simulate(axis, ref, seed=0, x0=float(x[0]), v0=0.0)
    return float(np.sqrt(np.mean((res.x - x) ** 2)))


def test_replay_of_the_log_with_and_without_the_coarse_sensor() -> None:
    axis = get_spec(ENV_ID).axis
    ideal = _replay(replace(axis, effects=replace(axis.effects, quantization=0.0)))
    assert ideal <= 1.05 * DIAGNOSIS_RMS_RAD, ideal  # measured 0.0267 rad
    coarse = _replay(axis)
    # measured 0.0334 rad: the sensor step in the loop, which the diagnosis left out of its fit
    assert ideal < coarse <= 1.3 * DIAGNOSIS_RMS_RAD, coarse

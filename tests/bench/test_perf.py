"""``fricbench perf``'s report: the vector env's row gives its ratio to simulate; every
target says met or missed."""

from __future__ import annotations

from fricbench.bench.perf import PERF_KEYS, format_report


def test_vector_env_row_reports_its_ratio_to_simulate() -> None:
    r = dict.fromkeys(PERF_KEYS, 1.0e6)
    r["vector_env_steps_per_s"], r["simulate_samples_per_s"] = 3.0e6, 4.0e6
    r["vector_env_to_simulate"] = 0.75
    row = next(line for line in format_report(r).splitlines()
               if line.startswith("vector_env_steps_per_s "))
    assert "3,000,000" in row and "0.75 x simulate (target >= 0.8: missed)" in row


def test_every_target_says_met_or_missed() -> None:
    r = dict.fromkeys(PERF_KEYS, 1.0e6)
    r["pendulum_steps_per_s"], r["python_control_samples_per_s"] = 4.0e6, 500.0
    r["simulate_samples_per_s"], r["vector_env_to_simulate"] = 0.9e6, 0.8
    rows = {line.split()[0]: line for line in format_report(r).splitlines()}
    assert rows["env_steps_per_s"].endswith("0.25 x Pendulum (target >= 0.5: missed)")
    assert rows["vector_env_steps_per_s"].endswith("0.80 x simulate (target >= 0.8: met)")
    assert rows["simulate_samples_per_s"].endswith("target >= 1,000,000: missed")
    assert rows["python_control_samples_per_s"].endswith(
        "simulate is 1800 x this (target >= 1000 x: met)")

"""``fricbench perf``'s report: the vector env's row gives its ratio to simulate."""

from __future__ import annotations

from fricbench.bench.perf import PERF_KEYS, format_report


def test_vector_env_row_reports_its_ratio_to_simulate() -> None:
    r = dict.fromkeys(PERF_KEYS, 1.0e6)
    r["vector_env_steps_per_s"], r["simulate_samples_per_s"] = 3.0e6, 4.0e6
    r["vector_env_to_simulate"] = 0.75
    row = next(line for line in format_report(r).splitlines()
               if line.startswith("vector_env_steps_per_s "))
    assert "3,000,000" in row and "0.75 x simulate (target >= 0.8)" in row

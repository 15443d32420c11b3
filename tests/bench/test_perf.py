"""``fricbench perf``'s report: the vector env's row gives its ratio to the kernel on the same
samples (judged) and to simulate; every target says met or missed. The measurement itself: the
kernel it times runs the vector env's own samples."""

from __future__ import annotations

from fricbench.bench.perf import PERF_KEYS, _vector_rate, format_report


def test_vector_env_row_reports_its_ratio_to_the_kernel_and_to_simulate() -> None:
    r = dict.fromkeys(PERF_KEYS, 1.0e6)
    r["vector_env_steps_per_s"], r["simulate_samples_per_s"] = 3.0e6, 4.0e6
    r["kernel_samples_per_s"], r["vector_env_to_kernel"] = 5.0e6, 0.6
    r["vector_env_to_simulate"] = 0.75
    rows = {line.split()[0]: line for line in format_report(r).splitlines()}
    row = rows["vector_env_steps_per_s"]
    assert "3,000,000" in row
    assert "0.60 x the kernel on the same samples (target >= 0.8: missed); 0.75 x simulate" \
        in row
    assert "5,000,000" in rows["kernel_samples_per_s"]


def test_every_target_says_met_or_missed() -> None:
    r = dict.fromkeys(PERF_KEYS, 1.0e6)
    r["pendulum_steps_per_s"], r["python_control_samples_per_s"] = 4.0e6, 500.0
    r["simulate_samples_per_s"], r["vector_env_to_kernel"] = 0.9e6, 0.8
    rows = {line.split()[0]: line for line in format_report(r).splitlines()}
    assert rows["env_steps_per_s"].endswith("0.25 x Pendulum (target >= 0.5: missed)")
    assert "0.80 x the kernel on the same samples (target >= 0.8: met)" \
        in rows["vector_env_steps_per_s"]
    assert rows["simulate_samples_per_s"].endswith("target >= 1,000,000: missed")
    assert rows["python_control_samples_per_s"].endswith(
        "simulate is 1800 x this (target >= 1000 x: met)")


def test_the_kernel_is_timed_on_the_vector_envs_own_samples() -> None:
    """The kernel's rate comes from the same states and samples as the env's (the measurement
    checks the final states agree, else raises), at a small size."""
    vec, kernel, peak_mb = _vector_rate(16, warmup=30, steps=20, repeats=1)
    assert vec > 0.0 and kernel > 0.0 and peak_mb > 0.0

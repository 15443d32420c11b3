"""``fricbench perf``'s report: the vector env's row gives its ratio to the kernel on the same
samples (judged) and to simulate; every target says met or missed. The measurement itself: the
kernel it times runs the vector env's own samples."""

from __future__ import annotations

import pytest

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
    vec, kernel, peak_mb = _vector_rate(16, warmup=30, steps=20, repeats=2)
    assert vec > 0.0 and kernel > 0.0 and peak_mb > 0.0


def test_a_window_past_the_shortest_episode_is_refused() -> None:
    # PaperAxis-v0's shortest reference, s_curve, has 2541 samples: 2540 steps, the last
    # truncating; a window of 2540 steps is measured, one of 2541 refused
    with pytest.raises(ValueError, match=r"warmup \+ repeats \* steps = 2541 steps: expected "
                                         r"at most 2540"):
        _vector_rate(2, warmup=41, steps=500, repeats=5)
    vec, kernel, _ = _vector_rate(2, warmup=40, steps=500, repeats=5)
    assert vec > 0.0 and kernel > 0.0


def test_a_refused_measurement_exits_1_with_the_reason(monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """A kernel run that does not reproduce the env's (e.g. a stale numba disk cache) is a
    clear error naming the remedy, exit 1, no traceback, no JSON written."""
    import fricbench.bench.perf as perf
    from fricbench.cli import main

    def refused(quick: bool = False) -> dict[str, float]:
        raise RuntimeError("the kernel's run did not reproduce the vector env's steps; "
                           "make clean-cache")

    monkeypatch.setattr(perf, "measure_performance", refused)
    assert main(["perf", "--quick"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("fricbench perf: error: the kernel's run did not reproduce")
    assert "Traceback" not in err

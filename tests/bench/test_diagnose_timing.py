"""The diagnosis benchmark runs and prints its figures (no time limit is tested here)."""

from __future__ import annotations

import pytest

from fricbench.bench.diagnose_timing import benchmark_run, main


def test_benchmark_run_has_the_requested_length() -> None:
    run = benchmark_run(3000, effort=True)
    assert run.n_samples == 3000
    assert run.u is not None
    assert benchmark_run(3000).u is None


def test_benchmark_prints_samples_seconds_and_throughput(capsys: pytest.CaptureFixture) -> None:
    assert main(["--samples", "2000", "--effort", "--no-warm-up"]) == 0
    out = capsys.readouterr().out
    for key in ("samples: 2000", "seconds:", "samples/s:", "load average:", "reference:",
                "ratio: diagnose / reference = ", "target: ratio <= 4733",
                "plant steps simulated", "free runs of the reference (counted, not timed"):
        assert key in out
    # the wall-time target is stated for the 40,000 samples only
    assert "15 s for 40000 samples" not in out


def test_benchmark_rejects_a_short_run() -> None:
    with pytest.raises(ValueError, match="samples"):
        benchmark_run(10)
    assert main(["--samples", "10"]) == 2

"""The command line: list, simulate (CSV + plot), perf keys, bench files, clear errors."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from fricbench.cli import main


def test_list(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for word in ("stribeck", "m_serial", "fricbench/PaperAxis-v0", "kalman"):
        assert word in out


def test_simulate_writes_csv_and_plot(tmp_path: Path) -> None:
    csv_path, png = tmp_path / "run.csv", tmp_path / "run.png"
    assert main(["simulate", "--env", "fricbench/PaperAxis-v0", "--trajectory", "s_curve",
                 "--csv", str(csv_path), "--plot", str(png)]) == 0
    with csv_path.open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["t", "x_ref", "x", "u"]
    assert len(rows) > 2000
    assert png.stat().st_size > 10_000


def test_unknown_env_is_a_clear_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--env", "fricbench/PaperAxs-v0"]) != 0
    assert "did you mean" in capsys.readouterr().err


def test_bench_unknown_compensator(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "--compensators", "kalmn"]) != 0
    assert "did you mean 'kalman'" in capsys.readouterr().err


def test_bench_writes_leaderboard(tmp_path: Path) -> None:
    assert main(["bench", "--envs", "fricbench/PaperAxis-v0", "--compensators", "none",
                 "--trajectories", "s_curve", "--seeds", "0", "--jobs", "1",
                 "--out", str(tmp_path)]) == 0
    assert (tmp_path / "PaperAxis-v0.csv").exists()
    assert (tmp_path / "PaperAxis-v0.md").exists()
    assert (tmp_path / "plots" / "PaperAxis-v0_s_curve.png").exists()


@pytest.mark.slow
def test_perf_writes_exactly_the_keys(tmp_path: Path) -> None:
    out = tmp_path / "perf.json"
    assert main(["perf", "--quick", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert set(data) == {"env_steps_per_s", "pendulum_steps_per_s", "vector_env_steps_per_s",
                         "simulate_samples_per_s", "python_control_samples_per_s"}
    assert all(v > 0 for v in data.values())

"""Benchmark runner, metrics and leaderboard files."""

from __future__ import annotations

import csv
from typing import ClassVar

import numpy as np
import pytest

from fricbench.bench.leaderboard import write_leaderboards
from fricbench.bench.metrics import reversal_indices, score_run
from fricbench.bench.runner import BenchTask, EpisodeRecord, run_benchmark, run_episode
from fricbench.compensators import Compensator, compensator_registry, make_compensator


class _Exploding(Compensator):
    id: ClassVar[str] = "test-exploding"

    def _act(self, observation: np.ndarray) -> np.ndarray:
        if observation[1] > 0.05:  # x_ref beyond 5 mm: mid-episode
            raise RuntimeError("boom")
        return np.zeros(1)


class _NaN(Compensator):
    id: ClassVar[str] = "test-nan"

    def _act(self, observation: np.ndarray) -> np.ndarray:
        return np.array([np.nan])


def test_reversal_indices_direct_and_after_dwell() -> None:
    v = np.array([0, 1, 2, 1, -1, -2, 0, 0, 0, 3, 0], dtype=float)
    assert list(reversal_indices(v, 1e-3)) == [4, 9]


def test_score_run_single_axis() -> None:
    t = np.arange(0, 1, 1e-3)
    x_ref = np.sin(2 * np.pi * t)
    x = x_ref - 1e-6 * np.sin(2 * np.pi * t)  # error peaks where the reference reverses
    m = score_run(t, x_ref, x, np.gradient(x_ref, t), np.zeros_like(t))
    assert m.max_error == pytest.approx(1e-6, rel=1e-3)
    assert m.rms_error == pytest.approx(1e-6 / np.sqrt(2), rel=1e-2)
    assert m.reversal_peak == pytest.approx(1e-6, rel=0.05)


def test_score_run_circle_deviation() -> None:
    t = np.arange(0, 2, 1e-3)
    th = np.pi * t
    r = 0.01
    x_ref = np.vstack([r * np.cos(th), r * np.sin(th)])
    x = np.vstack([(r + 2e-6) * np.cos(th), (r + 2e-6) * np.sin(th)])
    v = np.gradient(x_ref, t, axis=1)
    m = score_run(t, x_ref, x, v, np.zeros_like(x))
    assert m.max_error == pytest.approx(2e-6, rel=0.05)
    assert m.circular_deviation < 1e-7


def test_failing_and_nan_compensators_become_failed_rows() -> None:
    task = BenchTask("fricbench/PaperAxis-v0", "x", "s_curve", 0)
    rec = run_episode(_Exploding(), task)
    assert rec.status == "failed" and "boom" in rec.reason
    rec = run_episode(_NaN(), task)
    assert rec.status == "failed" and "non-finite" in rec.reason


def test_unknown_compensator_suggests() -> None:
    with pytest.raises(KeyError, match="did you mean 'kalman'"):
        make_compensator("kalmann")


def _rec(comp: str, seed: int, max_um: float) -> EpisodeRecord:
    return EpisodeRecord("fricbench/PaperAxis-v0", comp, "m_serial", seed, max_error=max_um * 1e-6,
                         rms_error=1e-6, reversal_peak=1e-6, effort_rms=1.0, effort_unit="N",
                         step_time=1e-5)


def test_leaderboard_rerun_replaces_own_rows_keeps_others(tmp_path) -> None:
    desc = {"fricbench/PaperAxis-v0": ("d", "fricbench/PaperAxis-v0")}
    write_leaderboards([_rec("none", 0, 20.0), _rec("kalman", 0, 8.0)], tmp_path, "cmd", "abc",
                       desc)
    write_leaderboards([_rec("kalman", 0, 5.0), _rec("kalman", 1, 6.0)], tmp_path, "cmd2",
                       "def", desc)
    with (tmp_path / "PaperAxis-v0.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    keyed = {(r["compensator"], r["seed"]): r for r in rows}
    assert set(keyed) == {("none", "0"), ("kalman", "0"), ("kalman", "1")}
    assert float(keyed[("kalman", "0")]["max_um"]) == pytest.approx(5.0)
    assert float(keyed[("kalman", "0")]["improvement_max_pct"]) == pytest.approx(75.0)
    for col in ("env", "compensator", "trajectory", "seed", "max_um", "rms_um",
                "reversal_peak_um", "improvement_max_pct"):
        assert col in rows[0]
    md = (tmp_path / "PaperAxis-v0.md").read_text()
    assert "cmd2" in md and "def" in md and "Seeds" in md
    assert not list(tmp_path.glob(".*"))  # no temp files left behind


def test_run_benchmark_small_joblib() -> None:
    recs = list(run_benchmark(["fricbench/PaperAxis-v0"], ["none"], [0, 1], ["s_curve"],
                              n_jobs=2, progress=False))
    assert len(recs) == 2 and all(r.status == "ok" for r in recs)
    assert recs[0].max_error > 5e-6


@pytest.mark.slow
def test_run_benchmark_on_local_ray() -> None:
    ray = pytest.importorskip("ray")
    try:
        ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
        recs = list(run_benchmark(["fricbench/PaperAxis-v0"], ["none"], [0], ["s_curve"],
                                  backend="ray", progress=False))
        ref = list(run_benchmark(["fricbench/PaperAxis-v0"], ["none"], [0], ["s_curve"],
                                 n_jobs=1, progress=False))
    finally:
        ray.shutdown()
    assert recs[0].status == "ok"
    assert recs[0].max_error == pytest.approx(ref[0].max_error, rel=1e-12)


def test_every_registered_compensator_id_is_listed() -> None:
    for cid in ("none", "tf-precomp", "tf-lstm-precomp", "greybox-precomp", "friction-ff",
                "kalman", "ilc", "rl-sac", "rl-ppo"):
        assert cid in compensator_registry.ids()

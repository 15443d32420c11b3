"""run_cell: the seeds of a cell stepped together give each seed's run_episode record."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from fricbench.bench.runner import BenchTask, EpisodeRecord, run_cell, run_episode
from fricbench.compensators import Compensator, compensator_registry, make_compensator

PAPER = "fricbench/PaperAxis-v0"
CIRCLE = "fricbench/CircleContouring-v0"
# the paper's LSTM trains for minutes by default: a short training is the same code path
SETTINGS = {"tf-lstm-precomp": {"predictor_kwargs": {"max_epochs": 2, "n_init": 1}}}
FIELDS = ("status", "reason", "max_error", "rms_error", "reversal_peak", "circular_deviation",
          "reversal_spike", "effort_rms", "effort_unit", "n_steps")


def _same(a: EpisodeRecord, b: EpisodeRecord) -> None:
    for f in FIELDS:
        x, y = getattr(a, f), getattr(b, f)
        assert x == y or (isinstance(x, float) and math.isnan(x) and math.isnan(y)), \
            (a.compensator, a.seed, f, x, y)
    for f in ("trace_t", "trace_error"):
        x, y = getattr(a, f), getattr(b, f)
        assert (x is None and y is None) or np.array_equal(x, y), (a.compensator, f)


def _fitted(comp_id: str, env_id: str) -> Compensator:
    return make_compensator(comp_id, **SETTINGS.get(comp_id, {})).fit(env_id, seed=1000)


@pytest.mark.parametrize("comp_id", compensator_registry.ids())
def test_every_compensator_gives_each_seed_its_own_record(comp_id: str) -> None:
    comp = _fitted(comp_id, PAPER)
    seeds = [0, 1, 4]
    tasks = [BenchTask(PAPER, comp_id, "s_curve", s) for s in seeds]
    keep = [True, False, False]
    together = run_cell([comp] * len(seeds), tasks, keep)
    for task, k, rec in zip(tasks, keep, together, strict=True):
        alone = run_episode(copy.deepcopy(comp), task, keep_trace=k)
        assert rec.status == "ok", rec.reason
        _same(rec, alone)


@pytest.mark.parametrize("comp_id", ["kalman", "rl-sac", "ekf"])
def test_two_axis_cells_in_lockstep(comp_id: str) -> None:
    comp = _fitted(comp_id, CIRCLE)
    tasks = [BenchTask(CIRCLE, comp_id, "circle", s) for s in (2, 7)]
    for task, rec in zip(tasks, run_cell([comp, comp], tasks), strict=True):
        _same(rec, run_episode(copy.deepcopy(comp), task))


class _Unstable(Compensator):
    """Pushes ever harder on seed 1's episode only: that seed's plant fails, not the others."""

    id = "unstable"
    category = "online"

    def _reset(self, context, seed):  # type: ignore[no-untyped-def]
        self._boom = seed == 1 + 7919

    def _act(self, observation: np.ndarray) -> np.ndarray:
        return np.array([np.inf if self._boom and observation[0] != 0.0 else 0.0])


def test_a_failing_seed_fails_alone() -> None:
    tasks = [BenchTask(PAPER, "unstable", "s_curve", s) for s in (0, 1, 2)]
    recs = run_cell([_Unstable(), _Unstable(), _Unstable()], tasks)
    assert [r.status for r in recs] == ["ok", "failed", "ok"]
    assert "non-finite action" in recs[1].reason
    ok = run_episode(_Unstable(), tasks[0])
    _same(recs[0], ok)

"""The Ray backend loses no finished run when a worker dies in the middle of a bench."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from fricbench.bench import runner
from fricbench.bench.runner import run_benchmark
from fricbench.compensators import Compensator, EpisodeContext, compensator_registry

ray = pytest.importorskip("ray")

ENV = "fricbench/PaperAxis-v0"


class _KillsItsWorker(Compensator):
    """Acts as ``none``, but its first ``kills`` episodes (counted in the file ``marker``,
    across processes) end their worker process, as a crash or the OOM killer would."""

    id: ClassVar[str] = "test-kills-once"
    category: ClassVar[str] = "online"
    kills: ClassVar[int] = 1

    def __init__(self, *, marker: str = "") -> None:
        super().__init__()
        self.marker = marker

    def _reset(self, context: EpisodeContext, seed: int | None) -> None:
        path = Path(self.marker)
        n = int(path.read_text()) if path.exists() else 0
        if n < self.kills:
            path.write_text(str(n + 1))
            os._exit(1)  # no cleanup, no exception: the worker is gone

    def _act(self, observation: np.ndarray) -> np.ndarray:
        return np.zeros(1)


class _KillsAlways(_KillsItsWorker):
    id: ClassVar[str] = "test-kills-always"
    kills: ClassVar[int] = 100


def _register() -> None:
    """Register the test compensators (in the driver, and in each Ray worker as it starts)."""
    # imported here: this function reaches the workers by value, the registry must be theirs
    from fricbench.compensators import compensator_registry as registry

    for cls in (_KillsItsWorker, _KillsAlways):
        if cls.id not in registry.ids():
            registry.register(cls.id, cls)


@pytest.fixture
def local_ray() -> Iterator[None]:
    # the workers get this module by value (it is not importable there)
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    _register()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             runtime_env={"worker_process_setup_hook": _register})
    try:
        yield
    finally:
        ray.shutdown()
        for cls in (_KillsItsWorker, _KillsAlways):
            compensator_registry.unregister(cls.id)
        ray.cloudpickle.unregister_pickle_by_value(sys.modules[__name__])


@pytest.mark.slow
def test_a_killed_worker_loses_no_finished_run(local_ray: None, tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(runner, "RAY_MAX_RETRIES", 1)  # one worker start fewer than the default
    once, always = tmp_path / "once", tmp_path / "always"
    records = list(run_benchmark(
        [ENV], ["none", _KillsItsWorker.id, _KillsAlways.id], [0, 1], ["s_curve"],
        backend="ray", progress=False,
        comp_kwargs={_KillsItsWorker.id: {"marker": str(once)},
                     _KillsAlways.id: {"marker": str(always)}}))
    by = {(r.compensator, r.seed): r for r in records}
    assert len(records) == 6 and len(by) == 6
    # the cell killed once was rerun: the same numbers as `none`, whose rows were kept
    assert once.read_text() == "1"
    for seed in (0, 1):
        none, rerun = by[("none", seed)], by[(_KillsItsWorker.id, seed)]
        assert none.status == rerun.status == "ok", (none.reason, rerun.reason)
        assert rerun.max_error == none.max_error and rerun.rms_error == none.rms_error
    # the cell killed on every try: given up after its retries, each seed a failed record
    assert always.read_text() == "2"  # the first try and its one retry
    for seed in (0, 1):
        lost = by[(_KillsAlways.id, seed)]
        assert lost.status == "failed"
        assert lost.reason.startswith("cell lost: WorkerCrashedError after 1 retries"), \
            lost.reason

"""TaskConfig: the action range an offset compensator gets on an env."""

from __future__ import annotations

from dataclasses import replace

import pytest

from fricbench.bench.runner import bench_env
from fricbench.compensators import make_compensator
from fricbench.gym import get_spec
from fricbench.gym.task import OFFSET_RANGE, ObservationConfig, TaskConfig


def test_offset_scale_is_sized_from_the_env_error_scale() -> None:
    task = TaskConfig(observation=ObservationConfig(error_scale=2e-4))
    assert task.offset_scale == pytest.approx(OFFSET_RANGE * 2e-4)
    # an env that acts by offset keeps its own range
    assert replace(task, action="offset", action_scale=3e-5).offset_scale == 3e-5


@pytest.mark.parametrize("env_id,scale", [("fricbench/PaperAxis-v0", 1e-4),
                                          ("fricbench/EMPS-v0", 5.78e-3)])
def test_the_bench_gives_offset_compensators_the_env_range(env_id: str, scale: float) -> None:
    """The paper axis keeps exactly its 0.1 mm; the EMPS twin, whose error is 0.58 mm of lag,
    gets 5.78 mm; a force compensator keeps the env's force range."""
    spec = get_spec(env_id)
    for cid in ("ilc", "greybox-precomp"):
        task = bench_env(env_id, make_compensator(cid)).task
        assert task.action == "offset" and task.action_scale == pytest.approx(scale, rel=1e-12)
    assert bench_env(env_id, make_compensator("kalman")).task == spec.task

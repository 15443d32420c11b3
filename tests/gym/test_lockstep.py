"""LockstepEnvs: every row gets exactly the numbers its env's own step gives."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.bench.runner import plant_axes
from fricbench.gym import ServoAxisEnv, get_spec
from fricbench.gym.lockstep import LockstepEnvs


def _envs(env_id: str, seeds: list[int], trajectory: str) -> list[ServoAxisEnv]:
    spec = get_spec(env_id)
    envs = []
    for s in seeds:
        told, plant = plant_axes(env_id, s)
        env = ServoAxisEnv(axis=told, task=spec.task, plant=plant)
        env.reset(seed=s, options={"trajectory": trajectory})
        envs.append(env)
    return envs


@pytest.mark.parametrize("env_id, trajectory", [
    ("fricbench/PaperAxis-v0", "s_curve"),         # encoder and current noise per seed
    ("fricbench/CircleContouring-v0", "circle"),   # two axes: the contour error column
    ("fricbench/EMPS-v0", "s_curve"),              # cogging, offset, position-dependent friction
])
def test_lockstep_rows_equal_their_own_envs_bit_for_bit(env_id: str, trajectory: str) -> None:
    seeds = [0, 3, 5]
    alone, together = _envs(env_id, seeds, trajectory), _envs(env_id, seeds, trajectory)
    lock = LockstepEnvs(together)
    d = lock.n_axes
    rng = np.random.default_rng(1)
    steps = min(lock.n_samples - 1, 1500)
    for _ in range(steps):
        # actions beyond [-1, 1] too: both clip
        actions = rng.uniform(-1.2, 1.2, (len(seeds), d)).astype(np.float32)
        obs, err = lock.step(actions)
        for i, env in enumerate(alone):
            o, _, _, _, info = env.step(actions[i])
            assert np.array_equal(obs[i], o)
            assert np.array_equal(err[i], info["error_m"])
    lock.close()
    for a, b in zip(alone, together, strict=True):
        assert np.array_equal(a.true_position, b.true_position)
        # the generators advanced alike: the next draws agree
        assert a.np_random.standard_normal() == b.np_random.standard_normal()


def test_lockstep_refuses_mixed_or_stepped_envs() -> None:
    envs = _envs("fricbench/PaperAxis-v0", [0, 1], "s_curve")
    other = _envs("fricbench/PaperAxis-v0", [2], "curve")
    with pytest.raises(ValueError, match="samples"):
        LockstepEnvs([envs[0], other[0]])
    with pytest.raises(ValueError, match="at least one"):
        LockstepEnvs([])
    envs[1].step(np.zeros(1, dtype=np.float32))
    with pytest.raises(ValueError, match=r"envs\[1\]: expected an env just reset"):
        LockstepEnvs(envs)
    lock = LockstepEnvs(_envs("fricbench/PaperAxis-v0", [0, 1], "s_curve"))
    with pytest.raises(ValueError, match=r"shape \(2, 1\)"):
        lock.step(np.zeros((3, 1)))
    with pytest.raises(ValueError, match=r"actions\[1\]"):
        lock.step(np.array([[0.0], [np.nan]]))

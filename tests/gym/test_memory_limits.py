"""Sizes refused up front with the memory they need (issue 14 item 15): ``num_envs``,
``reference_pool`` and a reset trajectory's ``duration``, instead of a ``MemoryError`` after a
minute of work."""

from __future__ import annotations

import time

import gymnasium as gym
import pytest

import fricbench  # noqa: F401  (registers the envs)
from fricbench import _memory
from fricbench.gym.vector import ServoAxisVectorEnv, bytes_per_env


@pytest.fixture
def two_gb(monkeypatch: pytest.MonkeyPatch) -> None:
    """A machine with 2 GB left (the figure the checks compare against)."""
    monkeypatch.setattr(_memory, "available_memory", lambda: (2_000_000_000, "test limit"))


def test_num_envs_beyond_memory_is_refused_before_allocating(two_gb: None) -> None:
    t0 = time.perf_counter()
    # the figures follow the kernel's rows (a sub-env holds its plant, controller and state rows)
    message = (r"^num_envs=10000000: needs about \d\d(\.\d)? GB of memory "
               r"\(about \d\.\d+ kB per sub-env\) but 2 GB is available "
               r"\(test limit\); expected num_envs <= \d+ here")
    with pytest.raises(ValueError, match=message):
        gym.make_vec("fricbench/RandomFriction-v0", num_envs=10**7,
                     vectorization_mode="vector_entry_point")
    assert time.perf_counter() - t0 < 5.0


def test_num_envs_no_machine_holds_is_refused() -> None:
    with pytest.raises(ValueError, match=r"^num_envs=1000000000: needs about \d\.\d+ TB"):
        gym.make_vec("fricbench/PaperAxis-v0", num_envs=10**9,
                     vectorization_mode="vector_entry_point")


def test_reference_pool_beyond_memory_is_refused(two_gb: None) -> None:
    # 10 s references: 10001 samples, about 0.96 MB each
    with pytest.raises(ValueError, match=r"^reference_pool=3000: needs about 2\.\d+ GB .*3000 "
                                         r"references of 10001 samples.*reference_pool <= 20\d\d"):
        gym.make_vec("fricbench/RandomFriction-v0", num_envs=2, reference_pool=3000,
                     vectorization_mode="vector_entry_point")


def test_reset_with_a_trajectory_beyond_memory_is_refused(two_gb: None) -> None:
    env = gym.make("fricbench/RandomFriction-v0")
    env.reset(seed=0)
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"^trajectory 'random' duration=100000\.0 s: needs "
                                         r"about 9\.6 GB of memory \(100000001 samples at "
                                         r"ts=0\.001 s, 96 B each\) but 2 GB is available"
                                         r".*expected duration <= 2\.08e\+04 s here"):
        env.reset(seed=0, options={"trajectory": {"id": "random", "duration": 1e5}})
    assert time.perf_counter() - t0 < 5.0
    # the env still works, with the spec's own trajectories
    env.reset(seed=0)
    env.step(env.action_space.sample())


def test_estimate_covers_the_arrays_of_a_small_vector_env() -> None:
    """The per-sub-env estimate is not below what the env's arrays hold."""
    venv = ServoAxisVectorEnv(num_envs=8)
    venv.reset(seed=0)
    held = sum(a.nbytes for a in (venv._batch.P, venv._batch.S, venv._batch.status,
                                  venv._ref_id, venv._k, venv._prev_action, venv._obs,
                                  venv._autoreset, venv._work, venv._no_noise))
    assert held / 8 <= bytes_per_env(venv._nf, randomized=False)


def test_reset_refuses_an_episode_longer_than_the_cap() -> None:
    """A reference over the cap is refused at once, even where it fits in memory (the generators
    slow down far more than linearly: a 1e5 s one would take hours)."""
    env = gym.make("fricbench/PaperAxis-v0")
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match="duration=2000.0 s.*MAX_EPISODE_SAMPLES"):
        env.reset(seed=0, options={"trajectory": {"id": "random", "duration": 2000.0}})
    assert time.perf_counter() - t0 < 5.0


def test_num_envs_beyond_the_cap_is_refused_at_once() -> None:
    from fricbench.gym.vector import MAX_NUM_ENVS

    t0 = time.perf_counter()
    # refused by the cap, or first by the memory check on a smaller machine
    with pytest.raises(ValueError, match=r"num_envs=10000000: (expected at most "
                                         r"1048576 \(MAX_NUM_ENVS\)|needs about)"):
        gym.make_vec("fricbench/PaperAxis-v0", num_envs=10**7,
                     vectorization_mode="vector_entry_point")
    assert time.perf_counter() - t0 < 5.0 and MAX_NUM_ENVS >= 4096

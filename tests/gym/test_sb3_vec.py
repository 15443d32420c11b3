"""The stable-baselines3 VecEnv adapter over the native vector env: the contract of SB3's
``DummyVecEnv`` (its env_checker does not check VecEnvs), seeding, and training on it."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3 import PPO, SAC
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

from fricbench.gym import ServoAxisEnv, ServoAxisVectorEnv, get_spec, make_vector_env
from fricbench.gym.sb3 import SB3VecEnv, make_sb3_vec_env
from fricbench.gym.task import TaskConfig, TrajectoryChoice

TRAIN = "fricbench/RandomFriction-v0"


def _short(spec_id: str, **params: Any) -> TaskConfig:
    """The spec's task on one short ``random`` reference (0.05 s: 51 samples, 50 steps)."""
    return replace(get_spec(spec_id).task,
                   trajectories=(TrajectoryChoice("random", {"duration": 0.05, **params}),))


def _short_keywords(**params: Any) -> list[dict[str, Any]]:
    """:func:`_short`'s trajectories as a gym.make keyword (merged onto the spec)."""
    return [{"id": "random", "duration": 0.05, **params}]


def _adapter(n: int = 3, seed: int = 0, spec_id: str = TRAIN, **params: Any) -> SB3VecEnv:
    return make_sb3_vec_env(spec_id, n, seed=seed, trajectories=_short_keywords(**params))


def _rollout(vec: Any, actions: np.ndarray) -> tuple[list[Any], ...]:
    obs = [vec.reset()]
    rewards, dones, infos = [], [], []
    for a in actions:
        o, r, d, i = vec.step(a)
        obs.append(o)
        rewards.append(r)
        dones.append(d)
        infos.append(i)
    return obs, rewards, dones, infos


def _actions(n_steps: int, n_envs: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, (n_steps, n_envs, 1)).astype(np.float32)


def test_spaces_shapes_and_dtypes() -> None:
    vec = _adapter(3)
    nf = vec.venv.single_observation_space.shape[0]
    assert vec.num_envs == 3
    assert vec.observation_space == gym.spaces.Box(-np.inf, np.inf, (nf,), np.float32)
    assert vec.action_space == gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    obs = vec.reset()
    assert obs.shape == (3, nf) and obs.dtype == np.float32
    assert vec.reset_infos == [{}, {}, {}]
    obs, rewards, dones, infos = vec.step(np.zeros((3, 1), dtype=np.float32))
    assert obs.shape == (3, nf) and obs.dtype == np.float32
    assert rewards.shape == (3,) and rewards.dtype == np.float32
    assert dones.shape == (3,) and dones.dtype == bool and not dones.any()
    assert infos == [{"TimeLimit.truncated": False}] * 3
    assert infos[0] is not infos[1]
    vec.close()


def test_autoreset_returns_reset_obs_and_terminal_observation() -> None:
    # ground truth: the NEXT_STEP vector env, same seed and actions, whose held step after an
    # episode's end shows the reset observation
    vec = _adapter(3, seed=4)
    spec = get_spec(TRAIN)
    truth = ServoAxisVectorEnv(num_envs=3, axis=spec.axis, task=_short(TRAIN), seed=4)
    obs = vec.reset()
    t_obs, _ = truth.reset()
    np.testing.assert_array_equal(obs, t_obs)
    episodes = 0
    for a in _actions(160, 3):
        obs, rewards, dones, infos = vec.step(a)
        t_obs, t_rew, _, t_trunc, _ = truth.step(a)
        np.testing.assert_array_equal(dones, t_trunc)
        np.testing.assert_array_equal(rewards, t_rew.astype(np.float32))
        if dones.any():
            episodes += 1
            assert dones.all()  # equal lengths: every sub-env ends together
            for i in range(3):
                assert infos[i]["TimeLimit.truncated"] is True
                terminal = infos[i]["terminal_observation"]
                assert terminal.shape == obs[i].shape and terminal.dtype == np.float32
                np.testing.assert_array_equal(terminal, t_obs[i])
            t_obs, t_rew, _, _, _ = truth.step(a)  # NEXT_STEP: the reset observation
            assert (t_rew == 0.0).all()
            assert not np.array_equal(obs, infos[0]["terminal_observation"])
            assert (obs[:, 5] == 0.0).all()  # the previous action of a fresh episode
            assert vec.reset_infos == [{}, {}, {}]
        else:
            assert all("terminal_observation" not in i for i in infos)
        np.testing.assert_array_equal(obs, t_obs)
    assert episodes == 3  # 50 steps an episode


def test_terminal_observation_when_sub_envs_end_apart() -> None:
    # reset one sub-env mid-episode by hand: the sub-envs then end on different steps
    vec = _adapter(2, seed=1)
    vec.reset()
    actions = _actions(90, 2)  # the axes move under random forces (the reference may rest)
    for a in actions[:10]:
        vec.step(a)
    vec.venv._reset_rows(np.array([True, False]))
    ended: dict[int, int] = {}
    last = None
    for step, a in enumerate(actions[10:]):
        obs, _, dones, infos = vec.step(a)
        for i in np.flatnonzero(dones):
            ended.setdefault(int(i), step)
            terminal = infos[i]["terminal_observation"]
            assert "terminal_observation" not in infos[1 - i]
            assert vec.venv._k[i] == 0 and vec.venv._k[1 - i] > 0
            assert obs[i, 5] == 0.0  # a fresh episode's previous action
            assert last is not None
            assert not np.array_equal(terminal, obs[i])
            assert not np.array_equal(terminal, last[i])
        last = obs
    assert ended == {1: 39, 0: 49}


def test_same_seed_same_rollouts_bit_for_bit() -> None:
    actions = _actions(120, 3)
    runs = []
    for seed in (7, 7, 8):
        vec = _adapter(3, seed=0)
        vec.seed(seed)
        runs.append(_rollout(vec, actions))
    for a, b in zip(runs[0][:3], runs[1][:3]):
        np.testing.assert_array_equal(np.array(a), np.array(b))
    terminal = [[i["terminal_observation"] for step in run[3] for i in step
                 if "terminal_observation" in i] for run in runs]
    np.testing.assert_array_equal(np.array(terminal[0]), np.array(terminal[1]))
    # another seed draws other friction and references
    assert not np.array_equal(np.array(runs[0][0]), np.array(runs[2][0]))
    # the seed is used once: a second reset goes on with the generator
    vec = _adapter(3, seed=0)
    vec.seed(7)
    first = _rollout(vec, actions[:20])[0]
    again = _rollout(vec, actions[:20])[0]
    assert not np.array_equal(np.array(first), np.array(again))


def test_first_episodes_match_a_dummy_vec_env_of_scalar_envs() -> None:
    # nominal axis and fixed references: the scalar and the native env agree bit for bit, also
    # over the autoreset (friction redrawn per episode would use the generators differently)
    spec = get_spec("fricbench/PaperAxis-v0")
    task = _short("fricbench/PaperAxis-v0", seed=3)
    vec = make_sb3_vec_env("fricbench/PaperAxis-v0", 2, seed=5,
                           trajectories=_short_keywords(seed=3))
    dummy = DummyVecEnv([lambda: ServoAxisEnv(axis=spec.axis, task=task) for _ in range(2)])
    vec.seed(5)
    dummy.seed(5)
    actions = _actions(120, 2)
    native, scalar = _rollout(vec, actions), _rollout(dummy, actions)
    np.testing.assert_array_equal(np.array(native[0]), np.array(scalar[0]))
    np.testing.assert_array_equal(np.array(native[1]), np.array(scalar[1]))
    np.testing.assert_array_equal(np.array(native[2]), np.array(scalar[2]))
    assert np.array(native[2]).sum() == 4  # two episodes of 50 steps in each sub-env
    for n_info, s_info in zip(native[3], scalar[3]):
        for n_i, s_i in zip(n_info, s_info):
            assert n_i["TimeLimit.truncated"] == s_i["TimeLimit.truncated"]
            assert ("terminal_observation" in n_i) == ("terminal_observation" in s_i)
            if "terminal_observation" in n_i:
                np.testing.assert_array_equal(n_i["terminal_observation"],
                                              s_i["terminal_observation"])


def _tiny_ppo(seed: int) -> PPO:
    # the adapter's own seed differs from the model's: the model's seed must rule
    vec = VecMonitor(_adapter(2, seed=3))
    model = PPO("MlpPolicy", vec, n_steps=64, batch_size=64, n_epochs=1, seed=seed,
                device="cpu", policy_kwargs={"net_arch": [16]})
    return model.learn(256)


def test_tiny_ppo_and_sac_learn_on_the_adapter() -> None:
    model = _tiny_ppo(seed=0)
    assert model.num_timesteps == 256
    assert len(model.ep_info_buffer) == 4  # VecMonitor saw 2 x 128 steps of 50-step episodes
    vec = model.get_env()
    assert vec is not None
    action, _ = model.predict(vec.reset(), deterministic=True)
    assert action.shape == (2, 1)
    # same seed, same training bit for bit
    again = _tiny_ppo(seed=0)
    for (name, p), q in zip(model.policy.state_dict().items(),
                            again.policy.state_dict().values()):
        assert torch.equal(p, q), name
    assert [e["r"] for e in model.ep_info_buffer] == [e["r"] for e in again.ep_info_buffer]
    sac = SAC("MlpPolicy", _adapter(2, seed=0), learning_starts=64, batch_size=32,
              train_freq=1, gradient_steps=1, buffer_size=1000, seed=0, device="cpu",
              policy_kwargs={"net_arch": [16]})
    sac.learn(128)
    assert sac.num_timesteps == 128 and sac.replay_buffer.size() == 64


def test_attributes_are_the_shared_vector_env_s() -> None:
    vec = _adapter(3)
    assert vec.get_attr("num_envs") == [3, 3, 3]
    assert vec.get_attr("num_envs", indices=[np.int64(1)]) == [3]
    assert vec.get_attr("render_mode") == [None] * 3
    with pytest.raises(AttributeError):
        vec.get_attr("no_such_attribute")
    with pytest.raises(ValueError, match=r"indices=3: expected an integer in \[0, 2\]"):
        vec.get_attr("num_envs", indices=3)
    vec.set_attr("note", "x")
    assert vec.venv.note == "x"  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match=r"indices=\[0\]: set_attr acts on the one vector env"):
        vec.set_attr("note", "y", indices=[0])
    with pytest.raises(ValueError, match="env_method acts on the one vector env"):
        vec.env_method("reset", indices=1)
    obs = vec.env_method("reset", seed=1)
    assert len(obs) == 3 and obs[0] is obs[2]
    assert vec.env_is_wrapped(gym.Wrapper) == [False] * 3
    assert vec.env_is_wrapped(gym.Wrapper, indices=0) == [False]


def test_bad_vector_envs_and_options_are_refused() -> None:
    with pytest.raises(ValueError, match="autoreset_mode=<AutoresetMode.NEXT_STEP.*SAME_STEP"):
        SB3VecEnv(make_vector_env("fricbench/PaperAxis-v0", 2))
    with pytest.raises(TypeError, match="expected a gymnasium.vector.VectorEnv"):
        SB3VecEnv(gym.make("fricbench/PaperAxis-v0"))  # type: ignore[arg-type]
    vec = _adapter(2)
    with pytest.raises(RuntimeError, match="step_async"):
        vec.step_wait()
    vec.set_options({"trajectory": "curve"})
    with pytest.raises(ValueError, match="reset options.*takes none"):
        vec.reset()


def _readme_example() -> str:
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    section = readme.split("## Training SB3 on the native vector env", 1)[1]
    match = re.search(r"```python\n(.*?)```", section, re.S)
    assert match is not None
    return match.group(1)


def test_readme_example_runs() -> None:
    code = _readme_example()
    # the same code with few steps
    for old, new in (("total_timesteps=100_000", "total_timesteps=256"),
                     ("n_steps=1024", "n_steps=32")):
        assert old in code
        code = code.replace(old, new)
    scope: dict[str, Any] = {}
    exec(compile(code, "README.md", "exec"), scope)
    assert scope["model"].num_timesteps == 256
    assert scope["action"].shape == (8, 1)

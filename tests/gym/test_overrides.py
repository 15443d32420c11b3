"""Keywords of ``gym.make`` / ``make_env`` / ``make_vector_env`` merged onto an env's spec."""

from __future__ import annotations

import pickle
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from fricbench.axis import Axis
from fricbench.friction import LuGre, Stribeck
from fricbench.gym import (
    EnvKeywordError,
    env_ids,
    get_spec,
    make_env,
    make_vector_env,
    resolve_overrides,
)
from fricbench.gym.task import Randomization, TrajectoryChoice

PAPER = "fricbench/PaperAxis-v0"
SHIFTED = "fricbench/PaperAxisShifted-v0"  # friction +30 %, vs = 3 mm/s
RANDOM = "fricbench/RandomFriction-v0"
SHIFTED_FRICTION = Stribeck(fc=455.0, fs=650.0, vs=3.0e-3)


def _made(env_id: str, **kwargs: Any) -> tuple[Axis, Any]:
    env = gym.make(env_id, **kwargs)
    axis, task = env.unwrapped.axis, env.unwrapped.task
    env.close()
    return axis, task


def test_the_shifted_spec_is_what_these_tests_assume() -> None:
    spec = get_spec(SHIFTED)
    assert spec.axis.friction == SHIFTED_FRICTION
    assert spec.axis.effects.quantization == 2.5e-7


@pytest.mark.parametrize("kwargs", [{"fc": 400.0}, {"friction": {"fc": 400.0}},
                                    {"fc": np.float64(400.0)}], ids=["flat", "dict", "numpy"])
def test_a_friction_level_keeps_the_rest_of_the_spec(kwargs: dict[str, Any]) -> None:
    spec = get_spec(SHIFTED)
    axis, task = _made(SHIFTED, **kwargs)
    assert axis.friction == replace(SHIFTED_FRICTION, fc=400.0)  # fs, vs: still the spec's
    assert axis.effects == spec.axis.effects and axis.controller == spec.axis.controller
    assert task == spec.task


def test_a_friction_id_switches_the_model_and_keeps_the_shared_levels() -> None:
    spec = get_spec(SHIFTED)
    axis, task = _made(SHIFTED, friction="lugre")
    assert axis.friction == LuGre(fc=455.0, fs=650.0, vs=3.0e-3)  # sigma0, sigma1: defaults
    assert axis.effects == spec.axis.effects and task == spec.task
    axis, _ = _made(SHIFTED, friction={"id": "lugre", "sigma0": 1.0e8, "fc": 400.0})
    assert axis.friction == LuGre(fc=400.0, fs=650.0, vs=3.0e-3, sigma0=1.0e8)
    axis, _ = _made(SHIFTED, friction="coulomb")
    assert axis.friction.to_dict() == {"id": "coulomb", "fc": 455.0}


def test_axis_tables_merge_key_by_key() -> None:
    spec = get_spec(SHIFTED)
    axis, task = _made(SHIFTED, effects={"noise_std": 1e-7}, controller={"kp": 150.0},
                       mechanics={"mass": 450.0})
    assert axis.friction == SHIFTED_FRICTION
    assert axis.effects == replace(spec.axis.effects, noise_std=1e-7)  # quantization kept
    assert axis.controller == replace(spec.axis.controller, kp=150.0)
    assert axis.mechanics == replace(spec.axis.mechanics, mass=450.0)
    assert task == spec.task
    axis, _ = _made(SHIFTED, kp=150.0, noise_std=1e-7)  # the same, each key on its own
    assert axis.controller.kp == 150.0 and axis.effects.noise_std == 1e-7
    assert axis.friction == SHIFTED_FRICTION


def test_task_keywords() -> None:
    spec = get_spec(SHIFTED)
    axis, task = _made(SHIFTED, trajectories=["s_curve", {"id": "curve", "duration": 5.0}],
                       reward={"action_weight": 0.1}, observation={"preview": 2},
                       action_scale=500.0)
    assert task.trajectories == (TrajectoryChoice("s_curve"),
                                 TrajectoryChoice("curve", {"duration": 5.0}))
    assert task.reward == replace(spec.task.reward, action_weight=0.1)
    assert task.observation == replace(spec.task.observation, preview=2)
    assert task.action_scale == 500.0 and axis == spec.axis
    env = gym.make(SHIFTED, observation={"preview": 2})
    assert env.observation_space.shape == (7 + 2 * 2,)
    env.close()
    _, task = _made(SHIFTED, action="offset", action_scale=1e-4)
    assert (task.action, task.action_scale) == ("offset", 1e-4)


def test_none_restores_a_default_and_stops_a_draw() -> None:
    axis, _ = _made(SHIFTED, friction={"fs": None})
    assert axis.friction == replace(SHIFTED_FRICTION, fs=Stribeck().fs)
    axis, _ = _made("fricbench/LuGreAxis-v0", friction={"id": None}, fc=400.0)
    assert axis.friction == Stribeck(fc=400.0)  # the default model; LuGre's fs, vs kept
    spec = get_spec(RANDOM)
    _, task = _made(RANDOM, randomize={"fc": None, "vs": [1e-3, 2e-3]})
    assert dict(task.randomize.ranges) == {"fs_ratio": spec.task.randomize.ranges["fs_ratio"],
                                           "vs": (1e-3, 2e-3)}
    _, task = _made(RANDOM, randomize=dict.fromkeys(spec.task.randomize.ranges))
    assert task.randomize == Randomization()


def test_vector_env_takes_the_same_keywords() -> None:
    venv = gym.make_vec(SHIFTED, num_envs=2, vectorization_mode="vector_entry_point",
                        friction="lugre", effects={"noise_std": 1e-7}, reference_pool=1)
    assert venv.unwrapped.axis.friction == LuGre(fc=455.0, fs=650.0, vs=3.0e-3)
    assert venv.unwrapped.axis.effects.quantization == 2.5e-7
    venv.close()
    venv = make_vector_env(SHIFTED, num_envs=2, fc=400.0, seed=3)
    assert venv.axis.friction == replace(SHIFTED_FRICTION, fc=400.0)
    with pytest.raises(EnvKeywordError, match="did you mean 'fc'"):
        make_vector_env(SHIFTED, num_envs=2, fcc=400.0)


def test_an_axis_that_agrees_with_the_spec_is_used_and_merged_onto() -> None:
    spec = get_spec(SHIFTED)
    mine = spec.axis.with_effects(noise_std=1e-7)
    axis, _ = _made(SHIFTED, axis=mine)
    assert axis == mine
    axis, _ = _made(SHIFTED, axis=mine, fc=400.0)
    assert axis == replace(mine, friction=replace(SHIFTED_FRICTION, fc=400.0))


def test_an_axis_or_task_that_contradicts_the_spec_is_refused() -> None:
    """``axis=Axis()`` used to replace the spec's axis whole: the +30 % friction was lost."""
    with pytest.raises(EnvKeywordError) as info:
        gym.make(SHIFTED, axis=Axis())
    msg = str(info.value)
    assert msg.startswith(f"{SHIFTED} keywords: axis=Axis(...) contradicts what {SHIFTED} sets")
    assert "friction.fc=350.0 (the spec: 455.0)" in msg and "friction.vs=0.002" in msg
    assert "effects.quantization=0.0 (the spec: 2.5e-07)" in msg
    assert "friction={'fc': 400.0}" in msg  # the way to say it
    with pytest.raises(EnvKeywordError, match=r"friction\.id='lugre' \(the spec: 'stribeck'\)"):
        gym.make(PAPER, axis=get_spec(PAPER).axis.with_friction("lugre"))
    spec = get_spec(PAPER)
    with pytest.raises(EnvKeywordError, match=r"task=TaskConfig\(\.\.\.\) contradicts .*"
                                              r"trajectories=\['s_curve'\]"):
        gym.make(PAPER, task=replace(spec.task, trajectories=(TrajectoryChoice("s_curve"),)))


@pytest.mark.parametrize(("kwargs", "expected"), [
    ({"fcc": 400.0}, "fcc: unknown keyword; did you mean 'fc'?"),
    ({"controler": {"kp": 200.0}}, "controler: unknown keyword; did you mean 'controller'"),
    ({"friction": {"fcc": 400.0}}, "friction.fcc: unknown key; did you mean 'fc'?; expected "
                                   "one of fc, fs, vs, delta, fv"),
    ({"friction": "stribek"}, "friction.id='stribek': unknown friction model; did you mean "
                              "'stribeck'?"),
    ({"friction": "stribek", "fc": 400.0}, "friction.id='stribek': unknown friction model; did "
                                           "you mean 'stribeck'?"),
    ({"effects": {"quantisation": 1e-6}}, "effects.quantisation: unknown key; did you mean "
                                          "'quantization'?"),
    ({"trajectories": ["m_serail"]}, "trajectories[0]: unknown trajectory id 'm_serail'; did "
                                     "you mean 'm_serial'?"),
    ({"trajectories": [{"id": "curve", "duraton": 3.0}]},
     "trajectories[0].duraton: unknown parameter of trajectory 'curve'; did you mean "
     "'duration'?"),
])
def test_typos_name_the_key_with_a_suggestion(kwargs: dict[str, Any], expected: str) -> None:
    with pytest.raises(EnvKeywordError) as info:
        gym.make(SHIFTED, **kwargs)
    assert str(info.value).startswith(f"{SHIFTED} keywords: ")
    assert expected in str(info.value)


@pytest.mark.parametrize(("kwargs", "expected"), [
    ({"fc": "fast"}, "friction.fc='fast': expected a number"),
    ({"fc": True}, "friction.fc=True: expected a number"),
    ({"fc": -1.0}, "friction.fc=-1.0: expected >= 0 N"),
    ({"friction": {"fs": 100.0}}, "friction.fs=100.0: expected >= fc=455.0"),
    ({"friction": 5}, "friction=5 (int): expected a friction model id or a dict"),
    ({"controller": 3}, "controller=3 (int): expected a dict of ControllerParams fields"),
    ({"randomize": [1, 2]}, "randomize=[1, 2] (list): expected a dict of [low, high] ranges"),
    ({"effects": {"measurement": "laser"}}, "effects.measurement='laser'"),
    ({"trajectories": "s_curve"}, "trajectories='s_curve': expected an array"),
    ({"action": "torque"}, "action='torque'"),
    ({"kp": 1e6}, "controller.kp=1e+06 1/s"),
    ({"error_scale": 1e-6}, "error_scale: a key of observation and reward; give it in one of "
                            "them"),
    ({"fc": 400.0, "friction": {"fc": 300.0}}, "both set friction.fc; give it once"),
    ({"friction": "coulomb", "fs": 500.0}, "fs: unknown keyword"),
])
def test_wrong_types_and_values_are_precise(kwargs: dict[str, Any], expected: str) -> None:
    with pytest.raises(EnvKeywordError) as info:
        gym.make(SHIFTED, **kwargs)
    assert expected in str(info.value), str(info.value)
    assert isinstance(info.value, ValueError)


def test_a_new_friction_model_and_the_spec_randomisation() -> None:
    with pytest.raises(EnvKeywordError, match=r"randomize\.vs: unknown key.*"
                                              r"randomize=\{'vs': None\} stops drawing it"):
        gym.make(RANDOM, friction="coulomb")
    _, task = _made(RANDOM, friction="coulomb", randomize={"vs": None, "fs_ratio": None})
    assert set(task.randomize.ranges) == {"fc"}


def test_every_problem_is_listed_and_the_error_pickles() -> None:
    with pytest.raises(EnvKeywordError) as info:
        make_env(SHIFTED, fcc=1.0, controler={})
    assert len(info.value.problems) == 2 and info.value.env_id == SHIFTED
    again = pickle.loads(pickle.dumps(info.value))
    assert str(again) == str(info.value) and type(again) is EnvKeywordError


@pytest.mark.parametrize("env_id", env_ids())
def test_an_empty_override_is_the_registered_env(env_id: str) -> None:
    spec = get_spec(env_id)
    empty = {k: {} for k in ("controller", "mechanics", "friction", "effects", "observation",
                             "reward", "randomize")}
    axis, task = resolve_overrides(env_id, **empty)
    assert axis == spec.axis and task == spec.task
    axis, task = _made(env_id, friction={})
    assert axis == spec.axis and task == spec.task
    axis, task = _made(env_id)
    assert axis == spec.axis and task == spec.task

"""Gymnasium environments of the servo feed axis, registered from the TOML specs in ``envs/``.

Importing :mod:`fricbench` registers every spec under the ``fricbench/`` namespace::

    import gymnasium as gym
    import fricbench  # noqa: F401
    env = gym.make("fricbench/PaperAxis-v0")
    env = gym.make("fricbench/PaperAxisShifted-v0", friction="lugre", effects={"noise_std": 1e-7})

Keywords of ``gym.make`` are merged onto the env's spec and checked as spec files are
(:func:`make_env` lists them; :class:`EnvKeywordError` names each problem). A malformed spec
on ``FRICBENCH_ENV_PATH`` is skipped with an :class:`EnvSpecWarning`; :func:`check_specs`
(``fricbench list --check``) reports every problem. The ids and their parsed specs are on
:data:`env_registry`, the project's shared :class:`~fricbench.registry.Registry`: a
third-party package adds env specs through the entry-point group ``fricbench.envs``
(:class:`EnvRegistry`). stable-baselines3 trains on the native
vector env through :mod:`fricbench.gym.sb3` (not imported here: it imports stable-baselines3
and torch).
"""

from fricbench.gym.env import ServoAxisEnv
from fricbench.gym.specs import (
    EnvKeywordError,
    EnvRegistry,
    EnvSpecError,
    EnvSpecFile,
    EnvSpecWarning,
    check_specs,
    env_ids,
    env_registry,
    get_spec,
    make_env,
    make_vector_env,
    register_envs,
    resolve_overrides,
    spec_files,
)
from fricbench.gym.task import ObservationConfig, Randomization, RewardConfig, TaskConfig
from fricbench.gym.vector import ServoAxisVectorEnv

__all__ = [
           "EnvKeywordError",
           "EnvRegistry",
           "EnvSpecError",
           "EnvSpecFile",
           "EnvSpecWarning",
           "ObservationConfig",
           "Randomization",
           "RewardConfig",
           "ServoAxisEnv",
           "ServoAxisVectorEnv",
           "TaskConfig",
           "check_specs",
           "env_ids",
           "env_registry",
           "get_spec",
           "make_env",
           "make_vector_env",
           "register_envs",
           "resolve_overrides",
           "spec_files",
]

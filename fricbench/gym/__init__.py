"""Gymnasium environments of the servo feed axis, registered from the TOML specs in ``envs/``.

Importing :mod:`fricbench` registers every spec under the ``fricbench/`` namespace::

    import gymnasium as gym
    import fricbench  # noqa: F401
    env = gym.make("fricbench/PaperAxis-v0")

A malformed spec on ``FRICBENCH_ENV_PATH`` is skipped with an :class:`EnvSpecWarning`;
:func:`check_specs` (``fricbench list --check``) reports every problem.
"""

from fricbench.gym.env import ServoAxisEnv
from fricbench.gym.specs import (
    EnvSpecError,
    EnvSpecWarning,
    check_specs,
    env_ids,
    get_spec,
    make_env,
    make_vector_env,
    register_envs,
    spec_files,
)
from fricbench.gym.task import ObservationConfig, Randomization, RewardConfig, TaskConfig
from fricbench.gym.vector import ServoAxisVectorEnv

__all__ = [
           "EnvSpecError",
           "EnvSpecWarning",
           "ObservationConfig",
           "Randomization",
           "RewardConfig",
           "ServoAxisEnv",
           "ServoAxisVectorEnv",
           "TaskConfig",
           "check_specs",
           "env_ids",
           "get_spec",
           "make_env",
           "make_vector_env",
           "register_envs",
           "spec_files",
]

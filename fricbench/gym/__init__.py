"""Gymnasium environments of the servo feed axis, registered from the TOML specs in ``envs/``.

Importing :mod:`fricbench` registers every spec under the ``fricbench/`` namespace::

    import gymnasium as gym
    import fricbench  # noqa: F401
    env = gym.make("fricbench/PaperAxis-v0")
"""

from fricbench.gym.env import ServoAxisEnv
from fricbench.gym.specs import env_ids, get_spec, make_env, make_vector_env, register_envs
from fricbench.gym.task import ObservationConfig, Randomization, RewardConfig, TaskConfig
from fricbench.gym.vector import ServoAxisVectorEnv

__all__ = [
           "ObservationConfig",
           "Randomization",
           "RewardConfig",
           "ServoAxisEnv",
           "ServoAxisVectorEnv",
           "TaskConfig",
           "env_ids",
           "get_spec",
           "make_env",
           "make_vector_env",
           "register_envs",
]

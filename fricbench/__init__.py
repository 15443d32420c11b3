"""fricbench: simulate, learn, measure and compare servo-friction compensation.

Importing the package registers the Gymnasium environments of ``envs/*.toml`` under the
``fricbench/`` namespace.
"""

from fricbench.gym.specs import register_envs as _register_envs

__version__ = "0.1.0"

_register_envs()

"""fricbench: simulate, learn, measure and compare servo-friction compensation.

Importing the package registers the Gymnasium environments of ``envs/*.toml`` under the
``fricbench/`` namespace. Imported before numpy, it first pins numpy's, OpenBLAS's and torch's
CPU dispatch, so that a run gives the same numbers on an AVX-512 machine as on an AVX2 one (see
:mod:`fricbench.reproducible`).
"""

from fricbench.reproducible import pin_cpu_dispatch as _pin_cpu_dispatch

_pin_cpu_dispatch()

from fricbench._compile_notice import announce_compiles as _announce_compiles  # noqa: E402
from fricbench.gym.specs import register_envs as _register_envs  # noqa: E402 (after the pin)

__version__ = "0.1.0"

_announce_compiles()  # one line on stderr when numba compiles the kernel (a cold cache)
_register_envs()

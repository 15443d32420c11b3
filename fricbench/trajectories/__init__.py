"""Standard reference trajectories, registered by id.

``make_trajectory("m_serial")`` returns a :class:`Reference`; third parties add generators through
the entry-point group ``fricbench.trajectories``.
"""

from __future__ import annotations

from typing import Any

from fricbench.registry import Registry
from fricbench.trajectories.base import Reference

__all__ = [
    "EVALUATION_SET",
    "TRAINING_SET",
    "Reference",
    "make_trajectory",
    "trajectory_registry",
]

trajectory_registry: Registry[Reference] = Registry("trajectory", "fricbench.trajectories")

_BUILTIN = {
    "m_serial": "fricbench.trajectories.m_serial:m_serial",
    "curve": "fricbench.trajectories.curve:curve",
    "circle": "fricbench.trajectories.circle:circle",
    "reversal_sine": "fricbench.trajectories.reversal_sine:reversal_sine",
    "s_curve": "fricbench.trajectories.s_curve:s_curve",
    "random": "fricbench.trajectories.random_mix:random_mixture",
}
for _id, _ep in _BUILTIN.items():
    trajectory_registry.register(_id, _ep)

# single-axis evaluation references used by the benchmark; ``random`` is for training only
EVALUATION_SET = ("m_serial", "curve", "reversal_sine", "s_curve")
TRAINING_SET = ("random",)


def make_trajectory(id: str, **params: Any) -> Reference:
    """Generate the trajectory registered as ``id`` with validated ``params``."""
    return trajectory_registry.make(id, **params)

"""Compensation strategies, registered by id.

``make_compensator("kalman")`` builds one; ``compensator_registry.ids()`` lists them; third
parties add theirs through the entry-point group ``fricbench.compensators``.
"""

from __future__ import annotations

from typing import Any

from fricbench.compensators.base import (
    Compensator,
    CompensatorError,
    EpisodeContext,
    NotFittedError,
    feature_index,
)
from fricbench.registry import Registry

__all__ = [
    "Compensator",
    "CompensatorError",
    "EpisodeContext",
    "NotFittedError",
    "compensator_registry",
    "feature_index",
    "make_compensator",
]

compensator_registry: Registry[Compensator] = Registry("compensator", "fricbench.compensators")

_BUILTIN = {
    "none": "fricbench.compensators.none:NoCompensation",
    "tf-precomp": "fricbench.compensators.precomp:TFPrecompensation",
    "tf-lstm-precomp": "fricbench.compensators.precomp:TFLSTMPrecompensation",
    "greybox-precomp": "fricbench.compensators.precomp:GreyBoxPrecompensation",
    "friction-ff": "fricbench.compensators.friction_ff:FrictionFeedforward",
    "kalman": "fricbench.compensators.kalman:KalmanDisturbanceObserver",
    "ilc": "fricbench.compensators.ilc:IterativeLearningControl",
    "rl-sac": "fricbench.compensators.rl:SACCompensator",
    "rl-ppo": "fricbench.compensators.rl:PPOCompensator",
}
for _id, _ep in _BUILTIN.items():
    compensator_registry.register(_id, _ep)


def make_compensator(id: str, **kwargs: Any) -> Compensator:
    """Build the compensator registered as ``id``."""
    return compensator_registry.make(id, **kwargs)

"""Compensation strategies, registered by id.

``make_compensator("kalman")`` builds one; ``compensator_registry.ids()`` lists them; third
parties add theirs through the entry-point group ``fricbench.compensators``.
"""

from __future__ import annotations

import inspect
from typing import Any

from fricbench.compensators.base import (
    CATEGORIES,
    Compensator,
    CompensatorBatch,
    CompensatorError,
    EpisodeContext,
    NotFittedError,
    feature_index,
)
from fricbench.registry import Registry

__all__ = [
    "CATEGORIES",
    "Compensator",
    "CompensatorBatch",
    "CompensatorError",
    "EpisodeContext",
    "NotFittedError",
    "compensator_id_kwargs",
    "compensator_parameters",
    "compensator_registry",
    "feature_index",
    "make_compensator",
]

compensator_registry: Registry[Compensator] = Registry("compensator", "fricbench.compensators")

_BUILTIN: dict[str, tuple[str, dict[str, Any], str]] = {
    "none": ("fricbench.compensators.none:NoCompensation", {}, "no compensation (the reference)"),
    "tf-precomp": ("fricbench.compensators.precomp:Precompensation", {"predictor": "tf"},
                   "pre-compensation by the TF predictor's predicted error"),
    "tf-lstm-precomp": ("fricbench.compensators.precomp:Precompensation",
                        {"predictor": "tf+lstm"},
                        "the paper: reference shifted by the TF+LSTM predicted error"),
    "greybox-precomp": ("fricbench.compensators.precomp:Precompensation",
                        {"predictor": "greybox", "iterations": 10, "gain": 0.5, "advance": 3},
                        "pre-compensation refined on the identified closed loop"),
    "friction-ff": ("fricbench.compensators.friction_ff:FrictionFeedforward", {},
                    "model-based friction feedforward (Stribeck fit)"),
    "kalman": ("fricbench.compensators.kalman:KalmanDisturbanceObserver", {},
               "Kalman disturbance observer, estimate fed back as force"),
    "ekf": ("fricbench.compensators.ekf:ExtendedFrictionObserver", {},
            "extended Kalman filter with an online Stribeck friction level, fed back as force"),
    "ilc": ("fricbench.compensators.ilc:IterativeLearningControl", {},
            "iterative learning control (rehearses the scored reference)"),
    "rl-sac": ("fricbench.compensators.rl:RLCompensator", {"algo": "sac"},
               "SAC policy (stable-baselines3) acting as a force"),
    "rl-ppo": ("fricbench.compensators.rl:RLCompensator", {"algo": "ppo"},
               "PPO policy (stable-baselines3) acting as a force"),
    "rl-residual": ("fricbench.compensators.rl_residual:ResidualRLCompensator", {},
                    "policy (stable-baselines3) adding a residual force to the kalman observer"),
}
for _id, (_ep, _kw, _desc) in _BUILTIN.items():
    compensator_registry.register(_id, _ep, kwargs=_kw, description=_desc)

PRECOMP_PREFIX = "precomp:"
"""``make_compensator("precomp:<predictor id>")`` pre-compensates with any registered predictor."""


def make_compensator(id: str, **kwargs: Any) -> Compensator:
    """Build the compensator registered as ``id``, or ``precomp:<predictor id>``.

    ``kwargs`` override the registered defaults. The instance's ``id`` is the id it was made
    by.
    """
    if isinstance(id, str) and id.startswith(PRECOMP_PREFIX):
        from fricbench.compensators.precomp import Precompensation

        comp: Compensator = Precompensation(predictor=id[len(PRECOMP_PREFIX):], **kwargs)
    else:
        comp = compensator_registry.make(id, **kwargs)
    comp.id = id
    return comp


def compensator_id_kwargs(id: str) -> dict[str, Any]:
    """The keywords that ``id`` itself names and that cannot change under it.

    The registered defaults given as a name (``algo="sac"`` of ``rl-sac``, ``predictor="tf"``
    of ``tf-precomp``; ``predictor`` of ``precomp:<predictor id>``): a leaderboard row of
    ``rl-sac`` must not come from a PPO policy. Numbers (gains, iterations) stay settable.

    Raises
    ------
    UnknownIdError
        If ``id`` is not registered (with near matches).
    """
    if isinstance(id, str) and id.startswith(PRECOMP_PREFIX):
        return {"predictor": id[len(PRECOMP_PREFIX):]}
    return {k: v for k, v in compensator_registry.spec(id).kwargs.items() if isinstance(v, str)}


def compensator_parameters(id: str) -> list[str] | None:
    """The keyword arguments a compensator's settings may give for ``id``.

    Read from the constructor's signature, without those the id names
    (:func:`compensator_id_kwargs`).

    Returns
    -------
    list of str or None
        The names in the constructor's order; ``None`` when it takes ``**kwargs`` (any name).

    Raises
    ------
    UnknownIdError
        If ``id`` is not registered (with near matches).
    """
    fixed = compensator_id_kwargs(id)
    if isinstance(id, str) and id.startswith(PRECOMP_PREFIX):
        from fricbench.compensators.precomp import Precompensation

        factory: Any = Precompensation
    else:
        factory = compensator_registry.spec(id).load()
    try:
        params = inspect.signature(factory).parameters.values()
    except (TypeError, ValueError):  # a builtin without a signature: nothing to check against
        return None
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return None
    return [p.name for p in params
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and p.name not in fixed]

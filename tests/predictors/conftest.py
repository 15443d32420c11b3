"""Small simulated runs and fast predictor settings shared by the predictor tests."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

import pytest

from fricbench.axis import Axis, simulate
from fricbench.predictors import Predictor, make_predictor, predictor_registry
from fricbench.trajectories import make_trajectory

#: Shrinks the neural predictors so that the whole registry trains in seconds.
FAST = {"max_epochs": 2, "hidden_size": 8, "window": 300, "burn_in": 100, "verbose": 0,
        "batch_size": 8}


def _make_fast(pid: str, **extra: Any) -> Predictor:
    accepted = set(inspect.signature(predictor_registry.spec(pid).load()).parameters)
    kwargs = {k: v for k, v in FAST.items() if k in accepted}
    kwargs.update(extra)
    return make_predictor(pid, **kwargs)


@pytest.fixture(scope="session")
def make_fast() -> Callable[..., Predictor]:
    """``make_fast(pid, **extra)``: ``make_predictor`` with every :data:`FAST` setting the
    constructor accepts (third-party predictors get only what they understand)."""
    return _make_fast


@pytest.fixture(scope="session")
def small_reference():
    """A 6 s curve: eight reversals, a start and a stop."""
    return make_trajectory("curve", duration=6.0, ramp=1.0)


@pytest.fixture(scope="session")
def small_runs(small_reference):
    """Two noisy runs of the default axis on the small curve."""
    axis = Axis().with_effects(noise_std=0.1e-6, quantization=0.25e-6)
    return [simulate(axis, small_reference, seed=s) for s in (1, 2)]

"""Tracking-error predictors, registered by id.

``make_predictor("tf+lstm").fit(runs)`` builds and trains one; ``predictor_registry.ids()``
lists them; third parties add predictors through the entry-point group
``fricbench.predictors`` (each entry point names a callable taking the registry, or an object
with ``register(registry)``).

Registered ids:

================  =====================================================================
``tf``            transfer function only (paper, Sec. 3.1)
``tf+lstm``       the paper's TF + LSTM on reference velocity and acceleration
``tf+stribeck``   physics baseline: fitted Stribeck friction through the known loop's
                  disturbance path (uses the true loop)
``tf+lstm-phys``  TF + LSTM with physical stick-slip features (direction, time and
                  displacement since the turning point, ``a0``, time to the next one)
``greybox``       the servo loop itself: cascade controller, unit mass and Stribeck
                  friction with stiction, all identified from the runs and run free
``greybox+lstm``  ``greybox`` plus an LSTM on physical features trained on its whole
                  residual (what the loop's structure lacks: pre-sliding, play, ripple)
================  =====================================================================
"""

from __future__ import annotations

from typing import Any

from fricbench.predictors.base import (
    NotFittedError,
    Predictor,
    PredictorFileError,
    Run,
)
from fricbench.predictors.registered import predictor_registry

__all__ = ["Predictor", "Run", "NotFittedError", "PredictorFileError", "predictor_registry",
           "make_predictor"]


def make_predictor(id: str, **params: Any) -> Predictor:
    """Build the (unfitted) predictor registered as ``id``; ``params`` override its defaults."""
    return predictor_registry.make(id, **params)

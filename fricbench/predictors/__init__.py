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
from fricbench.registry import Registry

__all__ = ["Predictor", "Run", "NotFittedError", "PredictorFileError", "predictor_registry",
           "make_predictor"]

predictor_registry: Registry[Predictor] = Registry("predictor", "fricbench.predictors")

_LSTM = "fricbench.predictors.lstm:TFLSTMPredictor"
predictor_registry.register("tf", "fricbench.predictors.tf:TFPredictor",
                            description="transfer function only")
predictor_registry.register("tf+lstm", _LSTM,
                            description="the paper: TF + LSTM on reference velocity and "
                                        "acceleration")
predictor_registry.register("tf+stribeck", "fricbench.predictors.stribeck:TFStribeckPredictor",
                            description="TF + fitted Stribeck friction through the known "
                                        "loop's disturbance path")
predictor_registry.register("tf+lstm-phys", _LSTM, kwargs={"features": "physical"},
                            description="TF + LSTM on physical stick-slip features")
predictor_registry.register("greybox", "fricbench.predictors.greybox:GreyBoxPredictor",
                            description="identified closed loop (cascade, mass, Stribeck "
                                        "friction with stiction), run free on the reference")
predictor_registry.register("greybox+lstm", _LSTM,
                            kwargs={"base": "greybox", "features": "physical",
                                    "target": "residual"},
                            description="greybox plus an LSTM on physical features trained on "
                                        "its residual")


def make_predictor(id: str, **params: Any) -> Predictor:
    """Build the (unfitted) predictor registered as ``id``; ``params`` override its defaults."""
    return predictor_registry.make(id, **params)

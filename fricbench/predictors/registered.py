"""The predictors' registry: the shipped ids and their entry points (re-exported by
:mod:`fricbench.predictors`).

Kept apart from the package's ``__init__`` so that :mod:`fricbench.predictors.base` (saving and
loading a predictor by its id) reads it without importing the package that imports it.
Entry points are strings: registering imports no predictor.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from fricbench.registry import Registry

if TYPE_CHECKING:
    from fricbench.predictors.base import Predictor

__all__ = ["predictor_registry"]

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

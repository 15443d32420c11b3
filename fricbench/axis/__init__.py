"""The servo feed axis: parameters, the batched kernel, simulation and the linear model."""

from fricbench.axis.batch import AxisBatch, SimulationDivergedError
from fricbench.axis.linear import closed_loop, closed_loop_tf_continuous
from fricbench.axis.params import Axis, ControllerParams, Effects, MechanicsParams
from fricbench.axis.simulate import SimulationResult, simulate, simulate_many

__all__ = [
           "Axis",
           "AxisBatch",
           "ControllerParams",
           "Effects",
           "MechanicsParams",
           "SimulationDivergedError",
           "SimulationResult",
           "closed_loop",
           "closed_loop_tf_continuous",
           "simulate",
           "simulate_many",
]

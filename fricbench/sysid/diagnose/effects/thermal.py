"""Thermal drift: a slow growth of the measured position with time (thermal expansion)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.effects.base import Effect, Probe, SimulateFn
from fricbench.sysid.diagnose.leastsq import sumsq
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared

if TYPE_CHECKING:
    from fricbench.sysid.diagnose.models import GreyBox

MIN_DURATION_S = 2.0
"""Shortest run on which a drift can be told from a slow loop, s."""


class ThermalDrift(Effect):
    """``y = x + d_inf (1 - exp(-t / tau))``."""

    name = "thermal_drift"
    kind = "output"
    summary = "a slow growth of the measured position with time (thermal expansion)"
    parameters = (CL.I_THA, CL.I_THT)
    shape_parameters = (CL.I_THT,)

    def available(self, prep: Prepared) -> bool:
        return prep.duration >= MIN_DURATION_S

    @staticmethod
    def _largest(b: Bounds) -> float:
        return max(1e-3, 0.1 * b.stroke)

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        if i == CL.I_THT:
            return Param(i, True, b.duration / 100.0, 20.0 * b.duration, 1.0)
        d = self._largest(b)
        return Param(i, False, -d, d, max(b.noise, 1e-7))

    def clip(self, i: int, value: float, b: Bounds) -> float:
        if i == CL.I_THA:
            d = self._largest(b)
            return float(np.clip(value, -0.9 * d, 0.9 * d))
        return value

    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        return [({CL.I_THA: max(b.noise, 1e-7)}, {CL.I_THT: tau})
                for tau in prep.duration * np.array([0.05, 0.2, 1.0, 5.0])]

    def output_start(self, model: GreyBox, prep: Prepared, b: Bounds, w: np.ndarray | None,
                     y: np.ndarray, mask: np.ndarray, simulate: SimulateFn) -> GreyBox:
        """Best time constant on a grid, amplitude by least squares on ``mask``."""
        r = prep.x - y
        t = prep.inputs.t
        best = (math.inf, 0.0, prep.duration)
        for tau in prep.duration * np.array([0.03, 0.1, 0.3, 1.0, 3.0]):
            col = 1.0 - np.exp(-t / tau)
            den = sumsq(col[mask])
            if den <= 0:
                continue
            amp = float(np.einsum("i,i->", col[mask], r[mask])) / den
            sse = float(np.sum((r[mask] - amp * col[mask]) ** 2))
            if sse < best[0]:
                best = (sse, amp, tau)
        q = model.plant.copy()
        q[CL.I_THA] = best[1]
        q[CL.I_THT] = best[2]
        return model.copy(plant=q)

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        return {"d_inf_m": float(p[CL.I_THA]), "tau_s": float(p[CL.I_THT])}

"""The thermal growth's strain: a screw grows from its fixed bearing.

A ball screw warmed by its nut and bearings lengthens from the end its axial bearing holds:
the table's error is the screw's strain times the distance from that bearing, not one offset
for the whole stroke (Bryan 1990; ISO 230-3's thermal drift tests measure it at several
positions for that reason). With the thermal drift's law ``s(t)`` (of time, or of heating by
motion, :mod:`~fricbench.sysid.diagnose.effects.thermal`) the growth at the table position
``x`` is ``s(t) (d_inf + e (x - x0))``: ``e`` the strain at the drift's asymptote, ``x0`` a
fixed origin (the middle of the logged stroke, so that ``d_inf`` stays the growth there). A
further term of the thermal drift, on its time law: the search adds it only where the held-out
error, penalised per parameter, takes it, as every other effect.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.effects.base import Effect, Probe, SimulateFn
from fricbench.sysid.diagnose.effects.thermal import drift_law
from fricbench.sysid.diagnose.leastsq import sumsq
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared

if TYPE_CHECKING:
    from fricbench.sysid.diagnose.models import GreyBox


def _origin(prep: Prepared) -> float:
    """The strain's origin: the middle of the logged stroke."""
    return 0.5 * (float(np.min(prep.x)) + float(np.max(prep.x)))


def _half_stroke(prep: Prepared, b: Bounds) -> float:
    return max(0.5 * (float(np.max(prep.x)) - float(np.min(prep.x))), 0.5 * b.stroke, 1e-9)


class ThermalStrain(Effect):
    """``y = x + s(t) (d_inf + e (x - x0))``: the thermal drift's part proportional to the
    table position."""

    name = "thermal_strain"
    kind = "output"
    requires = ("thermal_drift",)
    refines = "thermal_drift"
    summary = ("the thermal growth's part proportional to the position (a screw growing from "
               "its fixed bearing)")
    parameters = (CL.I_THS,)
    physical_sizes = (CL.I_THS,)
    #: largest strain of a structure warming up: steel (11.5e-6 / K) warmed by 20 K strains
    #: 2.3e-4; beyond 1e-3 (87 K of steel) it is no thermal growth. Physics, not tuned
    LARGEST = 1.0e-3

    def switched_on(self, p: np.ndarray, prep: Prepared) -> np.ndarray:
        q = p.copy()
        q[CL.I_THX0] = _origin(prep)
        return q

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        # scaled by the strain that moves the stroke's ends by one sensor noise
        return Param(i, False, -self.LARGEST, self.LARGEST,
                     max(b.noise, 1e-9) / max(b.stroke, 1e-6))

    def clip(self, i: int, value: float, b: Bounds) -> float:
        return float(np.clip(value, -0.9 * self.LARGEST, 0.9 * self.LARGEST))

    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        # the drift's law is the shape: one probe, the strain moving the stroke's ends by a
        # few sensor noises
        return [({CL.I_THS: 3.0 * max(b.noise, 1e-9) / _half_stroke(prep, b)},
                 {CL.I_THX0: _origin(prep)})]

    def output_start(self, model: GreyBox, prep: Prepared, b: Bounds, w: np.ndarray | None,
                     y: np.ndarray, mask: np.ndarray, simulate: SimulateFn) -> GreyBox:
        """The strain by least squares on ``mask``: the residual against the drift's law
        times the distance from the origin (the law's temperature from the reference speed,
        as the thermal drift's own start takes it)."""
        p = model.plant
        x0 = _origin(prep)
        col = drift_law(prep, float(p[CL.I_THT]), float(p[CL.I_THV])) * (y - x0)
        r = prep.x - y
        den = sumsq(col[mask])
        strain = float(np.einsum("i,i->", col[mask], r[mask])) / den if den > 0.0 else 0.0
        q = p.copy()
        q[CL.I_THX0] = x0
        q[CL.I_THS] = self.clip(CL.I_THS, strain, b)
        return model.copy(plant=q)

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        return {"strain": float(p[CL.I_THS]), "origin_m": float(p[CL.I_THX0])}

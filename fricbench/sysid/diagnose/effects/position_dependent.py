"""Position-dependent friction: friction levels that change along the stroke."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.effects.base import Effect, Probe
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared


class PositionDependentFriction(Effect):
    """Friction levels scaled by ``s(x) = 1 + g (x - x_c) + a sin(2 pi x / P) + b cos(...)``.

    ``x_c`` is the centre of the run's stroke (not fitted); the gradient and the variation are
    fractions of the friction level.
    """

    name = "position_dependent_friction"
    kind = "force"
    requires = ("coulomb_friction",)
    needs_reversals = True
    summary = "friction levels that change along the stroke"
    parameters = (CL.I_PDG, CL.I_PDA, CL.I_PDB, CL.I_PDP)
    shape_parameters = (CL.I_PDP,)
    relative_parameters = (CL.I_PDG, CL.I_PDA, CL.I_PDB)
    # a gradient plus one slow sinusoid: friction varying along the stroke, whose period may
    # well exceed the stroke
    periodic = False
    idim_nonlinear = CL.I_PDP
    period_parameter = CL.I_PDP
    # its screen is a friction level changed along a stick-slip motion: fitted for real when
    # the linear step leaves its range (posdep/2 of the second simulator: screen x10.5, fit
    # x0.25 of the error); not at every step, which costs 4.5 s on the 40k-sample benchmark
    fitted_when_screen_fails = True

    def switched_on(self, p: np.ndarray, prep: Prepared) -> np.ndarray:
        q = p.copy()
        q[CL.I_XC] = prep.center
        return q

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        stroke = max(b.stroke, 1e-9)
        if i == CL.I_PDP:
            return Param(i, True, value * 0.8, value * 1.25, 1.0)
        if i == CL.I_PDG:
            return Param(i, False, -1.8 / stroke, 1.8 / stroke, 1.0 / stroke)
        return Param(i, False, -0.9, 0.9, 0.3)

    def clip(self, i: int, value: float, b: Bounds) -> float:
        if i == CL.I_PDG:
            return float(np.clip(value, -1.2 / b.stroke, 1.2 / b.stroke))
        if i in (CL.I_PDA, CL.I_PDB):
            return float(np.clip(value, -0.6, 0.6))
        return value

    def probe_step(self, i: int, value: float, b: Bounds) -> float:
        if i == CL.I_PDG:
            return 0.2 * abs(value) + 0.05 / b.stroke
        return super().probe_step(i, value, b)

    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        return [({CL.I_PDG: 0.3 / b.stroke, CL.I_PDA: 0.3, CL.I_PDB: 0.3},
                 {CL.I_PDP: per, CL.I_XC: prep.center})
                for per in (b.stroke / 3.0, b.stroke / 1.5, 1.5 * b.stroke)]

    def idim_columns(self, p: np.ndarray, effects: Sequence[str], x: np.ndarray,
                     v: np.ndarray) -> tuple[np.ndarray, tuple[int, ...], np.ndarray]:
        # s(x) fc sgn(v) ~ fc sgn(v) + (fc g)(x - xc) sgn(v) + (fc a) sin sgn(v) + (fc b) cos sgn(v)
        sgn = np.sign(v)
        ph = 2.0 * np.pi * x / p[CL.I_PDP]
        cols = np.column_stack([sgn * (x - p[CL.I_XC]), sgn * np.sin(ph), sgn * np.cos(ph)])
        # factor 0: the entries are the coefficients divided by the Coulomb level
        return cols, (CL.I_PDG, CL.I_PDA, CL.I_PDB), np.zeros(3)

    def idim_key(self, p: np.ndarray, effects: Sequence[str]) -> tuple[object, ...]:
        return (float(p[CL.I_PDP]), float(p[CL.I_XC]))

    def idim_grid(self, idim: Any, effects: tuple[str, ...], p: np.ndarray, rows: np.ndarray,
                  start: bool) -> np.ndarray:
        if not start:
            return np.array([p[CL.I_PDP]])
        stroke = idim.prep.stroke
        return np.geomspace(stroke / 8.0, 2.0 * stroke, 10)

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        amp = math.hypot(p[CL.I_PDA], p[CL.I_PDB])
        return {"gradient_1_m": float(p[CL.I_PDG]), "variation": amp,
                "variation_period_m": float(p[CL.I_PDP]),
                "variation_phase_rad": math.atan2(p[CL.I_PDB], p[CL.I_PDA]),
                "x_center_m": float(p[CL.I_XC])}

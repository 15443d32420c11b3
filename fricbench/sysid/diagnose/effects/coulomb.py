"""Coulomb friction: a force of constant level opposing the motion."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.effects.base import Effect, Probe
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared
from fricbench.sysid.diagnose.settings import defaults


class CoulombFriction(Effect):
    """``F = s(x) sgn(v) fc``; at rest up to the static level holds the axis (stiction)."""

    name = "coulomb_friction"
    kind = "force"
    friction = True
    # the first suspect of any servo axis, and its linearised screen is the least reliable
    # (stiction is far from linear): fitted for real at every step while it is missing
    always_fitted = True
    needs_reversals = True
    shown_at_rests = True
    summary = "a friction force of constant level opposing the motion"
    parameters = (CL.I_FC,)
    force_parameters = (CL.I_FC,)
    nonnegative = (CL.I_FC,)

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        return Param(i, False, 0.0, 2.0 * b.friction, b.force)

    def clip(self, i: int, value: float, b: Bounds) -> float:
        return min(max(value, 0.02 * b.force), 1.5 * b.friction)

    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        return [({CL.I_FC: min(defaults().limit_friction_grid) * b.force}, {})]

    def idim_columns(self, p: np.ndarray, effects: Sequence[str], x: np.ndarray,
                     v: np.ndarray) -> tuple[np.ndarray, tuple[int, ...], np.ndarray]:
        # F = fc sgn(v)
        return np.sign(v)[:, None], (CL.I_FC,), np.ones(1)

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        return {f"fc_{force_unit}": float(p[CL.I_FC])}

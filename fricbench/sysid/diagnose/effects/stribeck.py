"""Stribeck friction: extra friction at low speed that decays with a Stribeck velocity."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.effects.base import Effect, Probe
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared


def _vs_range(v_max: float) -> tuple[float, float]:
    # Stribeck velocities from 0.1 % to half of the top speed
    return max(1e-3 * v_max, 1e-7), max(0.5 * v_max, 2e-7)


class StribeckFriction(Effect):
    """``F = s(x) sgn(v) (fs - fc) exp(-(v / vs)^2)`` on top of the Coulomb level."""

    name = "stribeck_friction"
    kind = "force"
    friction = True
    requires = ("coulomb_friction",)
    needs_reversals = True
    shown_at_rests = True
    summary = "extra friction at low speed that decays with a Stribeck velocity"
    parameters = (CL.I_FS, CL.I_VS)
    shape_parameters = (CL.I_VS,)
    force_parameters = (CL.I_FS,)
    # like Coulomb friction, stiction is far from linear: its linearised screen under-rates
    # it (x0.999 on runs where the real fit cuts the held-out error 6x), so it is fitted
    always_fitted = True
    nonnegative = (CL.I_FS,)
    idim_nonlinear = CL.I_VS
    # every Stribeck velocity the screen tries is a start: its linearised ranking of them is
    # no better than its rating of the effect (stribeck/28 of the second simulator: the two
    # best-ranked were 8 and 40 times too slow, and the stiction was missed)
    n_starts = 3

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        if i == CL.I_VS:
            return Param(i, True, *_vs_range(b.v_max), 1.0)
        return Param(i, False, 0.0, 2.0 * b.friction, b.force)

    def clip(self, i: int, value: float, b: Bounds) -> float:
        if i == CL.I_FS:
            # visible, yet below the friction of an axis whose largest command is far above
            # it: a floor at 2 % of the force scale sat above the whole friction of a stiff
            # loop on a light axis (Coulomb friction at 1.8 % of that scale), and the fits of a
            # few iterations stayed there
            return min(max(value, 0.002 * b.force), 1.5 * b.friction)
        return value

    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        fc = max(p[CL.I_FC], 0.1 * b.force)
        return [({CL.I_FS: 0.3 * fc}, {CL.I_VS: max(frac * b.v_max, 1e-6)})
                for frac in (0.01, 0.05, 0.25)]

    def idim_columns(self, p: np.ndarray, effects: Sequence[str], x: np.ndarray,
                     v: np.ndarray) -> tuple[np.ndarray, tuple[int, ...], np.ndarray]:
        # F = (fs - fc) sgn(v) exp(-(v / vs)^2)
        return (np.sign(v) * np.exp(-(v / p[CL.I_VS]) ** 2))[:, None], (CL.I_FS,), np.ones(1)

    def idim_grid(self, idim: Any, effects: tuple[str, ...], p: np.ndarray, rows: np.ndarray,
                  start: bool) -> np.ndarray:
        if not start:
            return np.array([p[CL.I_VS]])
        return np.geomspace(*_vs_range(idim.prep.v_max), 14)

    def open_loop_starts(self, effort: np.ndarray, y: np.ndarray, ts: float
                         ) -> list[dict[int, float]]:
        """Stribeck velocities at the closed loop's probe shares of the run's top speed, with
        an excess of a tenth of the effort's rms (the fit sizes it): the error surface is
        multimodal in the velocity, so each is a start."""
        v_max = float(np.max(np.abs(np.gradient(y, ts)))) if y.size > 1 else 0.0
        fs = 0.1 * float(np.sqrt(np.mean(np.square(effort)))) if effort.size else 0.0
        if not (v_max > 0.0 and fs > 0.0):
            return []
        lo, hi = _vs_range(v_max)
        return [{CL.I_FS: fs, CL.I_VS: float(np.clip(frac * v_max, lo, hi))}
                for frac in (0.01, 0.05, 0.25)]

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        return {f"fs_minus_fc_{force_unit}": float(p[CL.I_FS]), "vs_m_s": float(p[CL.I_VS])}

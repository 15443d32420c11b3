"""Thermal drift: a slow growth of the measured position, with time or with heating by motion.

Two laws of the one plant (:mod:`fricbench.axis.plant`), chosen from the data by the fit's start:

* of time, ``d(t) = d_inf (1 - exp(-t / tau))`` (a machine warming up whatever it does);
* of motion, ``tau dtheta/dt = |v_M| / v_heat - theta``, ``d = d_inf theta`` (a ball screw
  heated by turning: it grows while the axis moves and relaxes at rest). ``v_heat`` is the
  run's mean reference speed, a fixed normaliser, so ``d_inf`` is the growth in sustained
  motion at that speed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from scipy import signal

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.effects.base import Effect, Probe, SimulateFn
from fricbench.sysid.diagnose.leastsq import sumsq
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared
from fricbench.sysid.diagnose.settings import defaults

if TYPE_CHECKING:
    from fricbench.sysid.diagnose.models import GreyBox


def tau_floor(duration: float) -> float:
    """Lower bound of the time constant on a run of ``duration`` s."""
    return max(duration / 100.0, defaults().thermal_min_tau_s)


def heating_speed(prep: Prepared) -> float:
    """The motion law's normaliser ``v_heat``: the run's mean reference speed (0 at rest)."""
    speed = float(np.mean(np.abs(prep.inputs.vr)))
    return speed if math.isfinite(speed) and speed > 0.0 else 0.0


def heating_from_reference(prep: Prepared, tau: float, v_heat: float) -> np.ndarray:
    """``theta`` at each sample, heated by the reference speed (the motor's, once it tracks).

    ``theta[k+1] = theta[k] + (|v_r[k]| / v_heat - theta[k]) (1 - exp(-ts / tau))``, from
    ``theta[0] = 0``: the plant's law for a speed held over each sample.
    """
    g = -math.expm1(-prep.ts / tau)
    s = np.abs(prep.inputs.vr) / v_heat
    # lfilter gives theta[k+1] = g s[k] + (1 - g) theta[k]; shift by one sample
    after = signal.lfilter([g], [1.0, g - 1.0], s)
    return np.concatenate(([0.0], after[:-1]))


def drift_law(prep: Prepared, tau: float, v_heat: float) -> np.ndarray:
    """The drift's shape at each sample, its size 1: heated by the reference speed
    (:func:`heating_from_reference`) when ``v_heat > 0``, else ``1 - exp(-t / tau)``."""
    if v_heat > 0.0:
        return heating_from_reference(prep, tau, v_heat)
    return 1.0 - np.exp(-prep.inputs.t / tau)


class ThermalDrift(Effect):
    """``y = x + d_inf (1 - exp(-t / tau))``, or ``y = x + d_inf theta`` heated by motion."""

    name = "thermal_drift"
    kind = "output"
    summary = ("a slow growth of the measured position (thermal expansion), with time or with "
               "heating by motion")
    # the heating speed (time law: 0) is a fixed normaliser set by the start, never fitted
    parameters = (CL.I_THA, CL.I_THT)
    shape_parameters = (CL.I_THT,)

    @staticmethod
    def _largest(b: Bounds) -> float:
        return max(1e-3, 0.1 * b.stroke)

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        if i == CL.I_THT:
            return Param(i, True, tau_floor(b.duration), 20.0 * b.duration, 1.0)
        d = self._largest(b)
        return Param(i, False, -d, d, max(b.noise, 1e-7))

    def clip(self, i: int, value: float, b: Bounds) -> float:
        if i == CL.I_THA:
            d = self._largest(b)
            return float(np.clip(value, -0.9 * d, 0.9 * d))
        return value

    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        v_heat = heating_speed(prep)
        laws = (0.0, v_heat) if v_heat > 0.0 else (0.0,)
        return [({CL.I_THA: max(b.noise, 1e-7)}, {CL.I_THT: tau, CL.I_THV: v})
                for v in laws
                for tau in np.maximum(prep.duration * np.array([0.05, 0.2, 1.0, 5.0]),
                                      tau_floor(prep.duration))]

    def output_start(self, model: GreyBox, prep: Prepared, b: Bounds, w: np.ndarray | None,
                     y: np.ndarray, mask: np.ndarray, simulate: SimulateFn) -> GreyBox:
        """Best law and time constant on a grid, amplitude by least squares on ``mask``.

        The motion law's temperature comes from the reference speed here (no simulation);
        the fit then refines amplitude and time constant with the plant's own temperature,
        heated by the simulated motor.
        """
        r = prep.x - y
        v_heat = heating_speed(prep)
        best = (math.inf, 0.0, prep.duration, 0.0)
        for tau in np.maximum(prep.duration * np.array(defaults().thermal_tau_grid),
                              tau_floor(prep.duration)):
            for law in ((0.0, v_heat) if v_heat > 0.0 else (0.0,)):
                col = drift_law(prep, tau, law)
                den = sumsq(col[mask])
                if den <= 0:
                    continue
                amp = float(np.einsum("i,i->", col[mask], r[mask])) / den
                sse = float(np.sum((r[mask] - amp * col[mask]) ** 2))
                if sse < best[0]:
                    best = (sse, amp, tau, law)
        q = model.plant.copy()
        q[CL.I_THA] = best[1]
        q[CL.I_THT] = best[2]
        q[CL.I_THV] = best[3]
        return model.copy(plant=q)

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        return {"d_inf_m": float(p[CL.I_THA]), "tau_s": float(p[CL.I_THT]),
                "heating_speed_m_s": float(p[CL.I_THV])}

"""A harmonic of the cogging: the 2nd or 3rd order of a force periodic in position.

A linear motor's magnets, a screw's ball circuits or a stepper's detents do not pull with a
pure sinusoid: the ripple carries harmonics of its period. Each order is a candidate of its
own, on top of the fundamental (:mod:`~fricbench.sysid.diagnose.effects.cogging`), whose
period it shares: the search adds it only where the criterion takes it, so the number of
orders is chosen by the same held-out error, penalised per parameter, as every other effect.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.effects.base import Effect, Probe
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared


class _CoggingHarmonic(Effect):
    """``F = A_s sin(n 2 pi x / lambda) + A_c cos(n 2 pi x / lambda)``, ``lambda`` the
    fundamental's period (:attr:`order` ``n``)."""

    order: int
    kind = "force"
    requires = ("cogging",)
    refines = "cogging"

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        # a force level like the fundamental's (Bounds.friction): a harmonic of a detent
        # force is not larger than the friction the fundamental is bounded by
        return Param(i, False, -2.0 * b.friction, 2.0 * b.friction, b.force)

    def clip(self, i: int, value: float, b: Bounds) -> float:
        return float(np.clip(value, -1.5 * b.friction, 1.5 * b.friction))

    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        # the fundamental's period is the shape: nothing to search, one probe of each phase
        a, c = self.parameters
        return [({a: 0.2 * b.force, c: 0.2 * b.force}, {})]

    def idim_columns(self, p: np.ndarray, effects: Sequence[str], x: np.ndarray,
                     v: np.ndarray) -> tuple[np.ndarray, tuple[int, ...], np.ndarray]:
        ph = 2.0 * np.pi * self.order * x / p[CL.I_COGP]
        return np.column_stack([np.sin(ph), np.cos(ph)]), self.parameters, np.ones(2)

    def idim_key(self, p: np.ndarray, effects: Sequence[str]) -> tuple[Any, ...]:
        # the columns follow the fundamental's period, which its own search moves
        return (float(p[CL.I_COGP]),)

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        a, c = (float(p[i]) for i in self.parameters)
        return {f"amplitude_{force_unit}": float(np.hypot(a, c)),
                "period_m": float(p[CL.I_COGP]) / self.order,
                "phase_rad": float(np.arctan2(c, a))}


class CoggingHarmonic2(_CoggingHarmonic):
    """The cogging's second harmonic (half its period)."""

    name = "cogging_harmonic_2"
    order = 2
    summary = "the cogging's 2nd harmonic (a ripple that is not a pure sinusoid)"
    parameters = (CL.I_COGH2A, CL.I_COGH2B)
    force_parameters = (CL.I_COGH2A, CL.I_COGH2B)


class CoggingHarmonic3(_CoggingHarmonic):
    """The cogging's third harmonic (a third of its period)."""

    name = "cogging_harmonic_3"
    order = 3
    summary = "the cogging's 3rd harmonic (a ripple that is not a pure sinusoid)"
    parameters = (CL.I_COGH3A, CL.I_COGH3B)
    force_parameters = (CL.I_COGH3A, CL.I_COGH3B)

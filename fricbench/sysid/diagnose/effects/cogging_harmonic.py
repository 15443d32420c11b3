"""A harmonic of the cogging: the 2nd or 3rd order of a force periodic in position.

A linear motor's magnets, a screw's ball circuits or a stepper's detents do not pull with a
pure sinusoid: the ripple carries harmonics of its period. Each order is a candidate of its
own, on top of the fundamental (:mod:`~fricbench.sysid.diagnose.effects.cogging`), whose
period it shares: the search adds it only where the criterion takes it, so the number of
orders is chosen by the same held-out error, penalised per parameter, as every other effect.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.effects.base import Effect, Probe, signed_level, signed_level_clip
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared

_ENTRIES = {2: (CL.I_COGH2A, CL.I_COGH2B), 3: (CL.I_COGH3A, CL.I_COGH3B)}
"""The plant entries of each order's sine and cosine amplitudes."""


class _CoggingHarmonic(Effect):
    """``F = A_s sin(n 2 pi x / lambda) + A_c cos(n 2 pi x / lambda)``, ``lambda`` the
    fundamental's period (:attr:`order` ``n``)."""

    order: ClassVar[int]
    kind = "force"
    requires = ("cogging",)
    refines = "cogging"

    def __init_subclass__(cls, order: int = 0, **kwargs: Any) -> None:
        # each order is a registered class of its own: its id and its two plant entries
        super().__init_subclass__(**kwargs)
        if order:
            cls.order = order
            cls.name = f"cogging_harmonic_{order}"
            cls.summary = (f"the cogging's harmonic of order {order} (a ripple that is not a "
                           "pure sinusoid)")
            cls.parameters = _ENTRIES[order]
            cls.force_parameters = _ENTRIES[order]

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        # a force level like the fundamental's (Bounds.friction): a harmonic of a detent
        # force is not larger than the friction the fundamental is bounded by
        return signed_level(i, b)

    def clip(self, i: int, value: float, b: Bounds) -> float:
        return signed_level_clip(value, b)

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


class CoggingHarmonic2(_CoggingHarmonic, order=2):
    """The cogging's second harmonic (half its period)."""


class CoggingHarmonic3(_CoggingHarmonic, order=3):
    """The cogging's third harmonic (a third of its period)."""

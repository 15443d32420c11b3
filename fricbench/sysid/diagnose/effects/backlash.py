"""Backlash: lost motion between the motor and the measured position (a play operator)."""

from __future__ import annotations

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


class Backlash(Effect):
    """``y = play_beta(x)``: the table follows the motor once the lost motion is taken up."""

    name = "backlash"
    kind = "output"
    needs_reversals = True
    summary = "lost motion between the motor and the measured position (play operator)"
    parameters = (CL.I_BL,)

    #: largest gap: 1 mm on a linear axis, 50 mrad (about 3 deg) on a rotary one (a gear train)
    LARGEST = 1e-3
    LARGEST_ROTARY = 0.05

    @classmethod
    def _largest(cls, b: Bounds) -> float:
        # and at most a fifth of the stroke
        return min(cls.LARGEST_ROTARY if b.rotary else cls.LARGEST, 0.2 * b.stroke)

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        return Param(i, False, 0.0, self._largest(b), max(b.noise, 1e-7))

    def clip(self, i: int, value: float, b: Bounds) -> float:
        return min(max(value, b.noise), 0.15 * b.stroke)

    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        return [({CL.I_BL: min(max(s, 1e-8), 0.2 * b.stroke)}, {})
                for s in (3.0 * b.noise, 30.0 * b.noise)]

    def output_start(self, model: GreyBox, prep: Prepared, b: Bounds, w: np.ndarray | None,
                     y: np.ndarray, mask: np.ndarray, simulate: SimulateFn) -> GreyBox:
        """The best of a few sizes on ``mask`` (the play is not smooth at zero)."""
        sizes = list(np.geomspace(max(b.noise, 1e-8), self._largest(b), 8))
        models = []
        for s in sizes:
            q = model.plant.copy()
            q[CL.I_BL] = s
            models.append(model.copy(plant=q))
        ys, _, _ = simulate(models, prep, w)
        sse = []
        for yy in ys:
            r = (prep.x - yy)[mask]
            sse.append(sumsq(r) if np.all(np.isfinite(r))
                       else float("inf"))
        return models[int(np.argmin(sse))]

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        return {"backlash_m": float(p[CL.I_BL])}

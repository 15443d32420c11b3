"""Backlash: lost motion between the motor and the measured position.

Two models of the gap: a play operator on the output (the table stops the instant the motor
leaves it), or two bodies (``Effects.backlash_load_fraction``, the load's share of the mass
and damping, with the friction): the load coasts until its friction stops it while the motor
crosses the gap alone, so the loop meets a lighter, frictionless axis at each reversal. The
load share is not a free parameter (the fit is not smooth in it, and it does not tend to the
play operator as it vanishes): the start is the best of the play operator and a few shares.
"""

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
    """``y = play_beta(x)``: the table follows the motor once the lost motion is taken up; or
    two bodies across the gap (a load share of the mass held from the start)."""

    name = "backlash"
    # fitted as an output effect (judged on the free-run position from a grid of starts) in
    # both forms, though two bodies also change the loop's mechanics
    kind = "output"
    needs_reversals = True
    summary = ("lost motion between the motor and the measured position (play operator, or "
               "two bodies across the gap)")
    parameters = (CL.I_BL,)
    # a gap on its largest value (a few mrad of a gear train, a mm of a screw, a fifth of the
    # stroke) stands in for another mismatch: on the second simulator's thermal/24 (no
    # backlash; a loop at 1 ms logged at 100 Hz) a gap of 50 mrad was the first step
    physical_sizes = (CL.I_BL,)

    #: largest gap: 1 mm on a linear axis, 50 mrad (about 3 deg) on a rotary one (a gear train)
    LARGEST = 1e-3
    LARGEST_ROTARY = 0.05
    #: the load's shares of the mass tried beside the play operator (0): a table lighter than
    #: the motor and screw, about as heavy, and heavier
    LOAD_SHARES = (0.0, 0.25, 0.5, 0.75)

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
        """The best of a few sizes and load shares on ``mask`` (the play is not smooth at
        zero, and the share is held where it starts)."""
        sizes = list(np.geomspace(max(b.noise, 1e-8), self._largest(b), 8))
        models = []
        for share in self.LOAD_SHARES:
            for s in sizes:
                q = model.plant.copy()
                q[CL.I_BL] = s
                q[CL.I_BL_LOAD] = share
                models.append(model.copy(plant=q))
        ys, _, _ = simulate(models, prep, w)
        sse = []
        for yy in ys:
            r = (prep.x - yy)[mask]
            sse.append(sumsq(r) if np.all(np.isfinite(r))
                       else float("inf"))
        return models[int(np.argmin(sse))]

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        out = {"backlash_m": float(p[CL.I_BL])}
        if p[CL.I_BL_LOAD] > 0.0:
            # two bodies across the gap: the load's share of the mass (and of the damping)
            out["load_fraction"] = float(p[CL.I_BL_LOAD])
        return out

"""A constant force: gravity on an inclined axis, cable drag, a drive or sensor offset."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.effects.base import Effect, Probe, signed_level, signed_level_clip
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared


class ForceOffset(Effect):
    """``F = f0``, whatever the motion."""

    name = "force_offset"
    kind = "force"
    friction = True
    summary = "a constant force (gravity, cable drag, a drive or sensor offset)"
    parameters = (CL.I_OFF,)
    force_parameters = (CL.I_OFF,)

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        return signed_level(i, b)

    def clip(self, i: int, value: float, b: Bounds) -> float:
        return signed_level_clip(value, b)

    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        return [({CL.I_OFF: 0.1 * b.force}, {})]

    def idim_columns(self, p: np.ndarray, effects: Sequence[str], x: np.ndarray,
                     v: np.ndarray) -> tuple[np.ndarray, tuple[int, ...], np.ndarray]:
        return np.ones((v.shape[0], 1)), (CL.I_OFF,), np.ones(1)

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        return {f"f0_{force_unit}": float(p[CL.I_OFF])}

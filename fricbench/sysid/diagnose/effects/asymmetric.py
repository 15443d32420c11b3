"""Asymmetric friction: Coulomb and viscous levels that depend on the direction of motion."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.effects.base import Effect, Probe, signed_level, signed_level_clip
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared


class AsymmetricFriction(Effect):
    """``F = s(x) sgn(v) (fc + sgn(v) dfc / 2) + (B + sgn(v) dB / 2) v``.

    The direction-dependent Coulomb level ``dfc`` and a constant force are the same force
    while the axis moves (they differ only at rest), so with ``force_offset`` in the model
    the effect carries ``dB`` only.
    """

    name = "asymmetric_friction"
    kind = "force"
    friction = True
    requires = ("coulomb_friction",)
    needs_reversals = True
    summary = "friction levels (Coulomb and viscous) that depend on the direction"
    parameters = (CL.I_DFC, CL.I_DB)
    force_parameters = (CL.I_DFC, CL.I_DB)

    def free(self, effects: Sequence[str]) -> tuple[int, ...]:
        if "force_offset" in effects:
            # dfc and a constant force are the same force while moving: keep f0 only
            return (CL.I_DB,)
        return self.parameters

    def zeroed(self, p: np.ndarray, effects: Sequence[str]) -> np.ndarray:
        q = super().zeroed(p, effects)
        q[CL.I_DFC] = 0.0
        return q

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        if i == CL.I_DB:
            return Param(i, False, -b.damping_max, b.damping_max, b.damping_scale)
        return signed_level(i, b)

    def clip(self, i: int, value: float, b: Bounds) -> float:
        if i == CL.I_DB:
            return float(np.clip(value, -0.9 * b.damping_max, 0.9 * b.damping_max))
        return signed_level_clip(value, b)

    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        fc = max(p[CL.I_FC], 0.1 * b.force)
        changes = {CL.I_DB: 0.3 * (p[CL.I_B] + b.force / b.v_max)}
        if CL.I_DFC in self.free(effects):
            changes[CL.I_DFC] = 0.2 * fc
        return [(changes, {})]

    def idim_columns(self, p: np.ndarray, effects: Sequence[str], x: np.ndarray,
                     v: np.ndarray) -> tuple[np.ndarray, tuple[int, ...], np.ndarray]:
        idx = self.free(effects)
        cols = []
        if CL.I_DFC in idx:
            # sgn(v) * sgn(v) dfc / 2 = dfc / 2 while moving
            cols.append(0.5 * (np.sign(v) != 0).astype(float))
        # sgn(v) dB / 2 * v = dB |v| / 2
        cols.append(0.5 * np.abs(v))
        return np.column_stack(cols), idx, np.ones(len(idx))

    def idim_key(self, p: np.ndarray, effects: Sequence[str]) -> tuple[object, ...]:
        return ("force_offset" in effects,)

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        fu = force_unit
        return {f"fc_pos_{fu}": float(p[CL.I_FC] + 0.5 * p[CL.I_DFC]),
                f"fc_neg_{fu}": float(p[CL.I_FC] - 0.5 * p[CL.I_DFC]),
                f"fv_pos_{fu}_s_m": float(p[CL.I_B] + 0.5 * p[CL.I_DB]),
                f"fv_neg_{fu}_s_m": float(p[CL.I_B] - 0.5 * p[CL.I_DB])}

"""Base class of friction models: validated SI parameters, vectorised force law, packing."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any, ClassVar

import numpy as np

from fricbench.friction.laws import KIND_STATIC, steady_force

__all__ = ["FrictionModel"]


@dataclass(frozen=True)
class FrictionModel:
    """A friction force law ``F(v)`` (N) of the sliding velocity ``v`` (m/s).

    Subclasses are frozen dataclasses whose fields are the model parameters in SI units; they
    validate them in ``__post_init__`` and map them onto the kernel's friction columns in
    :meth:`kernel_params`. Every model is a superset-free special case of one kernel law:
    ``F = sgn(v) [fc + (fs - fc) exp(-(|v|/vs)^delta)] + fv v`` (static laws), optionally with a
    bristle state (LuGre, Dahl).
    """

    id: ClassVar[str] = ""

    def kernel_params(self) -> dict[str, float]:
        """Kernel columns: kind, fc, fs, vs, delta, fv, sigma0, sigma1 (SI units)."""
        raise NotImplementedError

    def force(self, v: np.ndarray | float) -> np.ndarray:
        """Steady-state sliding friction force (N) at velocity ``v`` (m/s), vectorised.

        At ``v = 0`` the force is set-valued (static friction holds anything up to the breakaway
        level); this returns 0 there.
        """
        k = self.kernel_params()
        return steady_force(v, k["fc"], k["fs"], k["vs"], k["delta"], k["fv"])

    @property
    def breakaway_force(self) -> float:
        """Largest force the friction holds at rest (N)."""
        k = self.kernel_params()
        return max(k["fs"], k["fc"])

    @property
    def is_dynamic(self) -> bool:
        """True for models with an internal pre-sliding state."""
        return self.kernel_params()["kind"] != KIND_STATIC

    def scaled(self, factor: float) -> FrictionModel:
        """The same model with every force level multiplied by ``factor`` (velocities kept)."""
        changes: dict[str, Any] = {}
        for f in fields(self):
            if f.name in ("fc", "fs", "fv"):
                changes[f.name] = getattr(self, f.name) * factor
        return type(self)(**{**asdict(self), **changes})

    def to_dict(self) -> dict[str, Any]:
        """``{"id": ..., **parameters}``: JSON-ready, accepted by :func:`make_friction`."""
        return {"id": self.id, **asdict(self)}

"""The reference trajectory returned by every generator."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Reference"]


@dataclass(frozen=True)
class Reference:
    """A sampled reference: time, position, velocity and acceleration in SI units.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Sample times, s, uniformly spaced by ``ts`` starting at 0.
    x, v, a : ndarray, shape (K,) or (D, K)
        Position (m), velocity (m/s), acceleration (m/s^2); 2-D for ``D`` coordinated axes
        (``circle``: D = 2, rows X and Y).
    name : str
        Registered id of the generator.
    params : dict
        The keyword arguments that made it (JSON-ready), for reports and reproducibility.
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    name: str = ""
    params: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        k = self.t.shape[0]
        for nm in ("x", "v", "a"):
            arr = getattr(self, nm)
            if arr.shape[-1] != k or arr.ndim not in (1, 2):
                raise ValueError(f"{nm} has shape {arr.shape}: expected ({k},) or (D, {k})")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{nm} contains NaN or inf")

    @property
    def ts(self) -> float:
        """Sample time, s."""
        return float(self.t[1] - self.t[0]) if self.t.shape[0] > 1 else 0.0

    @property
    def n_samples(self) -> int:
        """Number of samples K."""
        return int(self.t.shape[0])

    @property
    def n_axes(self) -> int:
        """Number of coordinated axes D (1 for a single-axis reference)."""
        return 1 if self.x.ndim == 1 else int(self.x.shape[0])

    @property
    def duration(self) -> float:
        """Length in s."""
        return float(self.t[-1] - self.t[0])

    def axis(self, i: int) -> Reference:
        """The single-axis reference of coordinate ``i`` of a multi-axis reference."""
        if self.x.ndim == 1:
            if i != 0:
                raise IndexError(f"axis index {i}: this reference has one axis")
            return self
        return Reference(self.t, self.x[i], self.v[i], self.a[i], f"{self.name}[{i}]",
                         self.params)

    @classmethod
    def from_positions(cls, t: np.ndarray, x: np.ndarray, name: str = "custom",
                       params: dict[str, Any] | None = None) -> Reference:
        """Build from sampled positions; velocity and acceleration by central differences."""
        t = np.asarray(t, dtype=float)
        x = np.asarray(x, dtype=float)
        ts = float(t[1] - t[0])
        v = np.gradient(x, ts, axis=-1)
        a = np.gradient(v, ts, axis=-1)
        return cls(t, x, v, a, name, dict(params or {}))

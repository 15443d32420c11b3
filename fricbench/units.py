"""Position units of a run: conversion to SI and the units figures are shown in.

A log may give positions in m, mm, um (a linear axis) or rad, deg (a rotary axis). The loader
converts them to SI (m or rad) once; every computation works in SI. Printed figures and plots
use a unit of the same family as the log: um for a linear axis (as always), mrad for a rotary
axis logged in rad, deg for one logged in deg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["POSITION_UNITS", "PositionUnit", "position_unit"]


@dataclass(frozen=True)
class PositionUnit:
    """A position unit of a log.

    Attributes
    ----------
    name : str
        As given (``"m"``, ``"mm"``, ``"um"``, ``"rad"``, ``"deg"``).
    to_si : float
        Factor from this unit to SI: ``x_si = to_si * x``.
    si : str
        The SI unit of the family, ``"m"`` or ``"rad"``.
    display : str
        Unit of printed positions and errors (``"um"``, ``"mrad"`` or ``"deg"``).
    per_si : float
        Factor from SI to ``display``.
    """

    name: str
    to_si: float
    si: str
    display: str
    per_si: float

    @property
    def rotary(self) -> bool:
        """Whether the axis is rotary (positions in rad)."""
        return self.si == "rad"

    @property
    def velocity_display(self) -> str:
        """Unit of printed velocities: mm/s, mrad/s or deg/s."""
        return {"um": "mm/s", "mrad": "mrad/s", "deg": "deg/s"}[self.display]

    @property
    def velocity_per_si(self) -> float:
        """Factor from SI velocity to :attr:`velocity_display`."""
        return 1e3 if self.display == "um" else self.per_si

    @property
    def coarse_display(self) -> str:
        """Unit of printed positions along the stroke: mm, rad or deg."""
        return {"um": "mm", "mrad": "rad", "deg": "deg"}[self.display]

    @property
    def coarse_per_si(self) -> float:
        """Factor from SI to :attr:`coarse_display`."""
        return 1e3 if self.display == "um" else (1.0 if self.display == "mrad" else self.per_si)


_DEG = math.pi / 180.0
POSITION_UNITS: dict[str, PositionUnit] = {
    "m": PositionUnit("m", 1.0, "m", "um", 1e6),
    "mm": PositionUnit("mm", 1e-3, "m", "um", 1e6),
    "um": PositionUnit("um", 1e-6, "m", "um", 1e6),
    "rad": PositionUnit("rad", 1.0, "rad", "mrad", 1e3),
    "deg": PositionUnit("deg", _DEG, "rad", "deg", 1.0 / _DEG),
}
"""The position units a log may use, by name."""


def position_unit(name: str) -> PositionUnit:
    """The :class:`PositionUnit` called ``name``.

    Raises
    ------
    ValueError
        ``name`` is not one of :data:`POSITION_UNITS`.
    """
    try:
        return POSITION_UNITS[name]
    except (KeyError, TypeError):
        raise ValueError(f"position unit {name!r}: expected one of "
                         f"{', '.join(POSITION_UNITS)}") from None

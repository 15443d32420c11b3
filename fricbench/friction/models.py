"""The registered friction models. Parameters in SI units: forces in N, velocities in m/s."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from fricbench._validation import check_nonneg, check_positive, check_range
from fricbench.friction.base import FrictionModel
from fricbench.friction.laws import KIND_DAHL, KIND_LUGRE, KIND_STATIC

__all__ = ["Coulomb", "Dahl", "LuGre", "Stribeck", "Viscous"]


def _static(fc: float, fs: float, vs: float, delta: float, fv: float) -> dict[str, float]:
    return {"kind": KIND_STATIC, "fc": fc, "fs": fs, "vs": vs, "delta": delta, "fv": fv,
            "sigma0": 0.0, "sigma1": 0.0}


@dataclass(frozen=True)
class Coulomb(FrictionModel):
    """Coulomb friction with true stiction: ``F = fc sgn(v)``; at rest ``|F| <= fc``.

    Parameters
    ----------
    fc : float
        Coulomb (and breakaway) level, N, ``>= 0``.
    """

    fc: float = 350.0
    id: ClassVar[str] = "coulomb"

    def __post_init__(self) -> None:
        check_nonneg("fc", self.fc, "N")

    def kernel_params(self) -> dict[str, float]:
        return _static(self.fc, self.fc, 0.0, 2.0, 0.0)


@dataclass(frozen=True)
class Viscous(FrictionModel):
    """Viscous friction ``F = fv v``.

    Parameters
    ----------
    fv : float
        Viscous coefficient, N s/m, ``>= 0``.
    """

    fv: float = 500.0
    id: ClassVar[str] = "viscous"

    def __post_init__(self) -> None:
        check_nonneg("fv", self.fv, "N s/m")

    def kernel_params(self) -> dict[str, float]:
        return _static(0.0, 0.0, 0.0, 2.0, self.fv)


@dataclass(frozen=True)
class Stribeck(FrictionModel):
    """Stribeck friction (the paper's eq. 8) with an optional viscous term.

    ``F(v) = [fc + (fs - fc) exp(-(|v|/vs)^delta)] sgn(v) + fv v``; at rest ``|F| <= fs``
    (true stiction through the implicit update of the axis kernel).

    Parameters
    ----------
    fc : float
        Coulomb level, N, ``>= 0``.
    fs : float
        Static (breakaway) level, N, ``>= fc``.
    vs : float
        Stribeck velocity, m/s, ``> 0``.
    delta : float
        Stribeck exponent (2: Gaussian, the paper's form), in ``[0.5, 4]``.
    fv : float
        Viscous coefficient, N s/m, ``>= 0`` (0 in the paper, whose linear model holds ``B``).
    """

    fc: float = 350.0
    fs: float = 500.0
    vs: float = 2.0e-3
    delta: float = 2.0
    fv: float = 0.0
    id: ClassVar[str] = "stribeck"

    def __post_init__(self) -> None:
        check_nonneg("fc", self.fc, "N")
        check_nonneg("fs", self.fs, "N")
        if self.fs < self.fc:
            raise ValueError(f"fs={self.fs!r}: expected >= fc={self.fc!r} (static >= Coulomb)")
        check_positive("vs", self.vs, "m/s")
        check_range("delta", self.delta, 0.5, 4.0)
        check_nonneg("fv", self.fv, "N s/m")

    def kernel_params(self) -> dict[str, float]:
        return _static(self.fc, self.fs, self.vs, self.delta, self.fv)


@dataclass(frozen=True)
class LuGre(FrictionModel):
    """LuGre dynamic friction (Canudas de Wit et al. 1995): bristles give pre-sliding.

    ``dz/dt = v - sigma0 |v| z / g(v)``, ``g(v) = fc + (fs - fc) exp(-(|v|/vs)^delta)``,
    ``F = sigma0 z + sigma1 dz/dt + fv v``. The bristle update is exact for a velocity frozen
    over a substep, so it is stable for any substep; the ``sigma1`` damping is implicit.

    Parameters
    ----------
    fc, fs : float
        Coulomb and static levels, N, ``0 <= fc <= fs``.
    vs : float
        Stribeck velocity, m/s, ``> 0``.
    sigma0 : float
        Bristle stiffness, N/m, ``> 0`` (pre-sliding distance about ``fc / sigma0``).
    sigma1 : float
        Bristle damping, N s/m, ``>= 0``.
    fv : float
        Viscous coefficient, N s/m, ``>= 0``.
    delta : float
        Stribeck exponent, in ``[0.5, 4]``.
    """

    fc: float = 350.0
    fs: float = 500.0
    vs: float = 2.0e-3
    sigma0: float = 1.75e8
    sigma1: float = 3.0e4
    fv: float = 0.0
    delta: float = 2.0
    id: ClassVar[str] = "lugre"

    def __post_init__(self) -> None:
        check_nonneg("fc", self.fc, "N")
        check_nonneg("fs", self.fs, "N")
        if self.fs < self.fc:
            raise ValueError(f"fs={self.fs!r}: expected >= fc={self.fc!r} (static >= Coulomb)")
        check_positive("vs", self.vs, "m/s")
        check_positive("sigma0", self.sigma0, "N/m")
        check_nonneg("sigma1", self.sigma1, "N s/m")
        check_nonneg("fv", self.fv, "N s/m")
        check_range("delta", self.delta, 0.5, 4.0)

    def kernel_params(self) -> dict[str, float]:
        return {"kind": KIND_LUGRE, "fc": self.fc, "fs": self.fs, "vs": self.vs,
                "delta": self.delta, "fv": self.fv, "sigma0": self.sigma0,
                "sigma1": self.sigma1}


@dataclass(frozen=True)
class Dahl(FrictionModel):
    """Dahl pre-sliding friction (exponent 1): a rate-independent hysteresis at reversals.

    ``dF/dx = sigma0 (1 - F sgn(v) / fc)``, i.e. ``F = sigma0 z`` with
    ``dz/dt = v - sigma0 |v| z / fc``; after a reversal the force swings from ``+fc`` to ``-fc``
    over a travel of a few ``fc / sigma0``. No Stribeck peak, no stiction beyond the bristles.

    Parameters
    ----------
    fc : float
        Coulomb level, N, ``>= 0``.
    sigma0 : float
        Rest stiffness, N/m, ``> 0``.
    fv : float
        Viscous coefficient, N s/m, ``>= 0``.
    """

    fc: float = 350.0
    sigma0: float = 1.75e8
    fv: float = 0.0
    id: ClassVar[str] = "dahl"

    def __post_init__(self) -> None:
        check_nonneg("fc", self.fc, "N")
        check_positive("sigma0", self.sigma0, "N/m")
        check_nonneg("fv", self.fv, "N s/m")

    def kernel_params(self) -> dict[str, float]:
        return {"kind": KIND_DAHL, "fc": self.fc, "fs": self.fc, "vs": 0.0, "delta": 2.0,
                "fv": self.fv, "sigma0": self.sigma0, "sigma1": 0.0}

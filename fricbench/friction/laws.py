"""Pure friction force laws, compiled with numba.

These scalar functions are the single source of the friction equations: the batched axis kernel
(:mod:`fricbench.axis.kernel`) calls them inside its loop, and the friction model classes call them
through :func:`steady_force` to evaluate curves for plots and fitting. SI units: velocity in m/s,
force in N.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = [
    "KIND_DAHL",
    "KIND_LUGRE",
    "KIND_STATIC",
    "steady_force",
    "stribeck_level",
    "stribeck_level_taylor",
]

# Kernel codes of the friction dynamics. Static laws use the stick-slip-correct implicit update
# (Kikuuwe et al. 2005); dynamic laws carry a bristle/pre-sliding state z (m).
KIND_STATIC = 0
KIND_LUGRE = 1
KIND_DAHL = 2


@numba.njit(cache=True, inline="always")
def stribeck_level(speed: float, fc: float, fs: float, vs: float, delta: float) -> float:
    """Sliding friction magnitude at ``speed >= 0`` (N), without the viscous part.

    ``g(v) = fc + (fs - fc) * exp(-(|v|/vs)**delta)``; with ``vs <= 0`` the law is plain Coulomb
    ``fc`` while sliding (``fs`` still holds at rest).
    """
    if vs <= 0.0:
        return fc
    r = speed / vs
    # pow() is the slowest call in the kernel's inner loop; delta = 2 (the paper's) is common
    e = r * r if delta == 2.0 else r**delta
    if e > 40.0:
        # exp(-40) < 5e-18: the Stribeck term is below float resolution of fc (cruising speed)
        return fc
    # g(v) = fc + (fs - fc) exp(-(v/vs)^delta)
    return fc + (fs - fc) * math.exp(-e)


@numba.njit(cache=True, inline="always")
def stribeck_level_taylor(speed: float, fc: float, fs: float, inv_vs: float,
                          delta: float) -> tuple[float, float, float]:
    """:func:`stribeck_level` at ``speed > 0`` with its first and second derivatives in
    ``|v|`` (N s/m, N s^2/m^2), from one ``exp``; ``inv_vs = 1 / vs`` (0: plain Coulomb)."""
    if inv_vs <= 0.0:
        return fc, 0.0, 0.0
    r = speed * inv_vs
    if delta == 2.0:
        e = r * r
        de = 2.0 * r * inv_vs
        d2e = 2.0 * inv_vs * inv_vs
    else:
        e = r**delta
        de = delta * e / speed
        d2e = (delta - 1.0) * de / speed
    if e > 40.0:
        return fc, 0.0, 0.0
    # g = fc + (fs - fc) exp(-e):  g' = -(g - fc) e',  g'' = (g - fc) (e'^2 - e'')
    stribeck = (fs - fc) * math.exp(-e)
    return fc + stribeck, -stribeck * de, stribeck * (de * de - d2e)


@numba.njit(cache=True)
def _steady_force(v: np.ndarray, fc: float, fs: float, vs: float, delta: float, fv: float,
                  out: np.ndarray) -> None:
    for i in range(v.shape[0]):
        vi = v[i]
        if vi > 0.0:
            out[i] = stribeck_level(vi, fc, fs, vs, delta) + fv * vi
        elif vi < 0.0:
            out[i] = -stribeck_level(-vi, fc, fs, vs, delta) + fv * vi
        else:
            out[i] = 0.0


def steady_force(v: np.ndarray | float, fc: float, fs: float, vs: float, delta: float,
                 fv: float) -> np.ndarray:
    """Steady-state sliding friction ``F(v) = sgn(v) g(|v|) + fv v`` (N), vectorised over ``v``.

    At ``v == 0`` the friction force is set-valued (anything in ``[-fs, fs]``); this returns 0.
    """
    arr = np.atleast_1d(np.asarray(v, dtype=np.float64)).ravel()
    out = np.empty_like(arr)
    _steady_force(arr, float(fc), float(fs), float(vs), float(delta), float(fv), out)
    return out.reshape(np.shape(v))

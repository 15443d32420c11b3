"""The free parameters of a grey-box fit and the physical ranges of one run.

:class:`Param` maps one controller gain or plant entry to the optimiser's coordinate (a
logarithm for positive parameters spanning decades, a scaled value otherwise) within physical
bounds; :class:`Bounds` holds the scales of a run (force, stroke, speed, duration, noise) that
every effect's bounds, starts and probes are expressed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from fricbench.sysid.diagnose.settings import defaults

if TYPE_CHECKING:
    from fricbench.sysid.diagnose.models import GreyBox

__all__ = ["Param", "Bounds"]


@dataclass(frozen=True)
class Param:
    """One free parameter of an output-error fit.

    Attributes
    ----------
    target : str or int
        Controller attribute (``"wv"``, ``"kp"``, ...) or plant index (``closed_loop.I_*``).
    log : bool
        Optimised as a logarithm (positive parameters spanning decades).
    lo, hi : float
        Physical bounds.
    scale : float
        Typical magnitude (optimiser scaling and finite-difference step).
    trust : bool
        ``lo`` and ``hi`` are a trust region around the start, not a physical range (a
        period found by a spectrum, refined by the fit): a fit that ends on one of them moves
        the region to its end point and goes on (:meth:`~.models.PositionFit.run`).
    """

    target: str | int
    log: bool
    lo: float
    hi: float
    scale: float
    trust: bool = False

    def recentred(self, value: float) -> Param:
        """The same region moved so that its centre (geometric for a logarithmic parameter,
        arithmetic otherwise) is ``value``."""
        if self.log:
            r = value / math.sqrt(self.lo * self.hi)
            return replace(self, lo=self.lo * r, hi=self.hi * r)
        d = value - 0.5 * (self.lo + self.hi)
        return replace(self, lo=self.lo + d, hi=self.hi + d)

    def on_bound(self, value: float, tol: float | None = None) -> bool:
        """Whether ``value`` ended within ``tol`` of the optimiser's range from a bound (the
        test of a trust region's edge, in the optimiser's coordinate; default
        ``settings.bound_tolerance``)."""
        if tol is None:
            tol = defaults().bound_tolerance
        lo, hi = self.bounds()
        t = self.to_theta(value)
        return t <= lo + tol * (hi - lo) or t >= hi - tol * (hi - lo)

    def bound_hit(self, value: float, tol: float | None = None) -> str | None:
        """``"upper"`` or ``"lower"`` when ``value`` ended on that physical bound (within
        ``tol``; default ``settings.bound_tolerance``), else None. A lower bound of 0 is a value
        a parameter has (no friction, no feedforward), not a bound it was pushed to."""
        if tol is None:
            tol = defaults().bound_tolerance
        span = self.hi - self.lo
        if not (math.isfinite(span) and span > 0.0):
            return None
        upper = tol * abs(self.hi) if self.log else tol * span
        if value >= self.hi - upper:
            return "upper"
        lower = tol * abs(self.lo) if self.log else tol * span
        if self.lo != 0.0 and value <= self.lo + lower:
            return "lower"
        return None

    def get(self, model: GreyBox) -> float:
        """Physical value in ``model``."""
        if isinstance(self.target, str):
            ctrl = model.controller
            if self.target.endswith("_per_wv2"):
                wv = float(ctrl.wv)  # type: ignore[union-attr]
                return float(getattr(ctrl, self.target[:-8])) / (wv * wv)
            if self.target.endswith("_per_wv"):
                return float(getattr(ctrl, self.target[:-7])) / float(ctrl.wv)  # type: ignore
            return float(getattr(ctrl, self.target))
        return float(model.plant[self.target])

    def to_theta(self, value: float) -> float:
        """Optimiser coordinate of a physical value."""
        v = min(max(value, self.lo), self.hi)
        return math.log(v) if self.log else v / self.scale

    def from_theta(self, theta: float) -> float:
        """Physical value of an optimiser coordinate."""
        return math.exp(theta) if self.log else theta * self.scale

    def bounds(self) -> tuple[float, float]:
        """Optimiser bounds."""
        if self.log:
            return math.log(self.lo), math.log(self.hi)
        return self.lo / self.scale, self.hi / self.scale


@dataclass(frozen=True)
class Bounds:
    """Physical ranges of the parameters of one run.

    Attributes
    ----------
    force : float
        Force scale: largest effort magnitude (effort unit, or m/s^2 without effort).
    stroke : float
        Range of motion, m.
    v_max : float
        Largest reference speed, m/s.
    duration : float
        Length of the run, s.
    ts : float
        Sample time, s.
    noise : float
        Noise floor of the position, m.
    loop_ts : float, optional
        The model loop's period, s, when it runs faster than the log (see
        :attr:`fricbench.sysid.diagnose.controllers.LoopInputs.n_loop`); default ``ts``.
    rotary : bool
        Positions are angles (rad): the limits stated as lengths (a backlash of at most
        1 mm) are stated as angles instead.
    friction_raise : float
        Factor the force levels' bounds (Coulomb, Stribeck, a constant force, a direction's
        difference, a detent force) are raised by beyond their multiples of ``force``
        (:attr:`friction`): 1, or more once a fit pressed a friction level against its bound
        (a slow axis held by a friction many times the inertial force that sets ``force``).
        Starts stay multiples of ``force``.
    """

    force: float
    stroke: float
    v_max: float
    duration: float
    ts: float
    noise: float
    loop_ts: float | None = None
    rotary: bool = False
    friction_raise: float = 1.0

    @property
    def friction(self) -> float:
        """The scale of the friction levels' bounds: ``force`` times ``friction_raise``."""
        return self.force * self.friction_raise

    @property
    def controller_ts(self) -> float:
        """The period the controller gains are bounded with, s."""
        return self.ts if self.loop_ts is None else self.loop_ts

    @property
    def damping_max(self) -> float:
        """Largest viscous coefficient: the whole force at a tenth of the top speed."""
        return 10.0 * self.force / max(self.v_max, 1e-9)

    @property
    def damping_scale(self) -> float:
        """Typical viscous coefficient: the force scale at the top speed."""
        return max(self.force / max(self.v_max, 1e-9), 1e-12)

"""A friction profile: friction levels of any shape along the travelled range.

The plant's profile ``l(x)`` (:func:`fricbench.axis.plant.profile_level`): relative changes of
the friction levels at ``n`` equally spaced knots over the run's travelled range, linear
between knots, held beyond them. The first knot is held at 0, so the Coulomb level is the
level at the start of the range and the profile the change from there: a gradient is a
profile of two knots, a worn or dirty stretch a bump of a few. The number of knots is the
candidate's: the library registers 3, 5 and 9 (a bump at the middle, a stretch of a quarter
of the range, one of an eighth: halvings of the spacing). One profile may be in a model
(:attr:`Effect.excludes`), and the one criterion chooses among them as among any candidates
(fewer knots, fewer parameters). A profile adds to the gradient and sinusoid of
``position_dependent_friction`` (the plant sums them): a level varying once per turn and a
tight spot are both in a worm-driven table, and the criterion takes each where the run shows
it. A report naming a profile names a position-dependent friction (:attr:`Effect.refines`).

The search tries them when asked (``fricbench diagnose --try friction_profile_5``, or
``DiagnoseSettings.candidates``): on the held-out sets they found a local change of the
friction the gradient and sinusoid missed, and once named a position-dependent friction in a
friction-only run, which keeps them out of the default library until that is understood.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from fricbench.axis import plant as PL
from fricbench.sysid.diagnose.effects.base import Effect, Probe
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared

__all__ = ["FrictionProfile", "PROFILE_KNOTS", "profile_name"]

PROFILE_KNOTS = (3, 5, 9)
"""Knot counts of the registered profiles (spacings halved from one to the next): the
candidate library's make-up, as the registered effects are, not a setting."""


def profile_name(n_knots: int) -> str:
    """Registry id of the profile with ``n_knots`` knots."""
    return f"friction_profile_{n_knots}"


class FrictionProfile(Effect):
    """``s(x) = 1 + l(x)``, ``l`` linear between :attr:`n_knots` knots over the travelled range.

    Subclasses fix :attr:`n_knots`; the knots' values after the first are the parameters.
    """

    n_knots: ClassVar[int]
    kind = "force"
    requires = ("coulomb_friction",)
    refines = "position_dependent_friction"
    needs_reversals = True
    periodic = False
    # asked for, not tried by default: with the profiles tried, the second simulator's held-out
    # set named a position-dependent friction in one friction-only run of 17 (none without
    # them; docs/diagnosis_method.md has the figures)
    tried_by_default = False
    # as the gradient and sinusoid: a friction level changed along a stick-slip motion,
    # as far from linear as stiction, so fitted for real when its linearised screen fails
    fitted_when_screen_fails = True

    def __init_subclass__(cls, n_knots: int = 0, **kwargs: Any) -> None:
        # each knot count is a registered class of its own: its id, its parameters (the knots
        # after the first, held at 0) and the other counts it excludes follow from the count
        super().__init_subclass__(**kwargs)
        if n_knots:
            cls.n_knots = n_knots
            cls.name = profile_name(n_knots)
            cls.summary = f"friction levels along the stroke, linear between {n_knots} knots"
            cls.parameters = tuple(PL.PD_KNOT0 + j for j in range(1, n_knots))
            cls.relative_parameters = cls.parameters
            cls.excludes = tuple(profile_name(k) for k in PROFILE_KNOTS if k != n_knots)

    def switched_on(self, p: np.ndarray, prep: Prepared) -> np.ndarray:
        lo, hi = float(np.min(prep.x)), float(np.max(prep.x))
        return self.placed(p, lo, hi - lo)

    def placed(self, p: np.ndarray, start: float, span: float) -> np.ndarray:
        """Row ``p`` with the profile's knots spread over ``[start, start + span]``."""
        q = p.copy()
        q[PL.PD_START] = start
        q[PL.PD_SPAN] = max(span, 1e-12)
        q[PL.PD_NKNOTS] = self.n_knots
        return q

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        return Param(i, False, PL.PD_LEVEL_RANGE[0], PL.PD_LEVEL_RANGE[1], 0.3)

    def clip(self, i: int, value: float, b: Bounds) -> float:
        return float(np.clip(value, 0.5 * PL.PD_LEVEL_RANGE[0], 0.5 * PL.PD_LEVEL_RANGE[1]))

    def probe_step(self, i: int, value: float, b: Bounds) -> float:
        return 0.2 * abs(value) + 0.05

    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        q = self.switched_on(p, prep)
        fixed = {i: float(q[i]) for i in (PL.PD_START, PL.PD_SPAN, PL.PD_NKNOTS)}
        return [({i: 0.3 for i in self.parameters}, fixed)]

    def idim_columns(self, p: np.ndarray, effects: Sequence[str], x: np.ndarray,
                     v: np.ndarray) -> tuple[np.ndarray, tuple[int, ...], np.ndarray]:
        # fc s(x) sgn(v) ~ fc sgn(v) + sum_j (fc l_j) hat_j(x) sgn(v): the hat functions of
        # the knots after the first (held at 0), the last one held beyond the range
        n = self.n_knots
        u = (x - p[PL.PD_START]) * (n - 1) / max(float(p[PL.PD_SPAN]), 1e-12)
        u = np.clip(u, 0.0, n - 1)
        j = np.arange(1, n)
        hats = np.clip(1.0 - np.abs(u[:, None] - j[None, :]), 0.0, 1.0)
        cols = np.sign(v)[:, None] * hats
        # factor 0: the entries are the coefficients divided by the Coulomb level
        return cols, self.parameters, np.zeros(n - 1)

    def idim_key(self, p: np.ndarray, effects: Sequence[str]) -> tuple[Any, ...]:
        return (float(p[PL.PD_START]), float(p[PL.PD_SPAN]))

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        out = {"start_m": float(p[PL.PD_START]), "span_m": float(p[PL.PD_SPAN])}
        for j in range(self.n_knots):
            out[f"level_change_{j}"] = float(p[PL.PD_KNOT0 + j])
        return out


class FrictionProfile3(FrictionProfile, n_knots=3):
    """A friction profile of 3 knots (2 parameters)."""


class FrictionProfile5(FrictionProfile, n_knots=5):
    """A friction profile of 5 knots (4 parameters)."""


class FrictionProfile9(FrictionProfile, n_knots=9):
    """A friction profile of 9 knots (8 parameters)."""

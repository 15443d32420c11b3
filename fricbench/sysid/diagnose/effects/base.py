"""What a candidate effect of the diagnosis is: its plant entries and how to fit them.

An :class:`Effect` is a physically parameterised term of the grey-box plant
(:mod:`fricbench.axis.plant`). *Force* effects act on the mass, inside the loop
(``M dv/dt = u - B v - F_eff``); *output* effects act between the motor and the logged
position, outside the loop. Each effect says, in one place:

* which plant entries are its free parameters (:attr:`Effect.parameters`), which of them only
  shape it (a period, a time constant, a Stribeck velocity: kept when the effect is switched
  off, never probed) and which are forces (rescaled when a start comes from an effort of
  another mass);
* their bounds in the units of a run (:meth:`Effect.bounds`) and the narrower range a
  linearised start is clipped to (:meth:`Effect.clip`);
* how to switch it on and off (:meth:`Effect.switched_on`, :meth:`Effect.zeroed`);
* the probes of the position screen (:meth:`Effect.probes`);
* force effects: the inverse-dynamics regressors (:meth:`Effect.idim_columns`) and, for a
  nonlinear entry, its search grid (:meth:`Effect.idim_grid`);
* output effects: a start for their fit (:meth:`Effect.output_start`);
* how to report it (:meth:`Effect.describe`).

The search (:mod:`fricbench.sysid.diagnose.search`) and the fits
(:mod:`fricbench.sysid.diagnose.models`) only call these methods.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from fricbench.sysid.diagnose.parameters import Bounds, Param

if TYPE_CHECKING:
    from fricbench.sysid.diagnose.models import GreyBox
    from fricbench.sysid.diagnose.prepared import Prepared

__all__ = ["Effect", "Probe"]

def signed_level(i: int, b: Bounds) -> Param:
    """Bounds of a signed force level of either sign (a constant force, a ripple's amplitude,
    a direction's share of the friction): within twice the run's friction level, on the force
    scale (a level like the friction's, not a multiple of the motion's inertial force)."""
    return Param(i, False, -2.0 * b.friction, 2.0 * b.friction, b.force)


def signed_level_clip(value: float, b: Bounds) -> float:
    """A linearised start of a :func:`signed_level` clipped within 1.5 friction levels."""
    return float(np.clip(value, -1.5 * b.friction, 1.5 * b.friction))


Probe = tuple[dict[int, float], dict[int, float]]
"""One probe of the position screen: ``(changes, fixed)``. Each changed entry gives a
finite-difference column (the entry set to the value, the rest as in the model with the fixed
entries set)."""

SimulateFn = Callable[[Sequence[Any], Any, Any], tuple[np.ndarray, np.ndarray, np.ndarray]]


class Effect(ABC):
    """Base class of the candidate effects (one small subclass per file).

    Class attributes
    ----------------
    name : str
        Registry id, used in reports.
    kind : {"force", "output"}
        Where the effect acts: on the mass inside the loop, or on the logged position.
    requires : tuple of str
        Effects that must already be in the model (a change of a friction level needs a
        friction level).
    excludes : tuple of str
        Effects that may not be in a model with it: the same term in another shape (a
        friction profile of another number of knots). Either side listing the other is
        enough.
    tried_by_default : bool
        Among the candidates the closed-loop search tries when the user names none
        (``settings.candidates`` None); False: tried only when asked for (``--try NAME``), a
        candidate whose held-out record does not yet earn it a place by default.
    refines : str or None
        The effect this one is a further term of (a harmonic of the cogging): it is found only
        with it, and a run that names it names that effect (what a judge of the diagnosis
        counts).
    needs_reversals : bool
        Only identifiable when the motion reverses.
    shown_at_rests : bool
        Also identifiable, without reversals, from starts from rest
        (:data:`fricbench.sysid.io.MIN_STARTS`): a friction level, which holds the axis at rest
        where a constant force would push it.
    summary : str
        One line for reports.
    parameters : tuple of int
        Plant entries that are its free parameters, in fit order.
    shape_parameters : tuple of int
        Entries that only shape the effect (kept when it is switched off, never probed).
    force_parameters : tuple of int
        Entries that are forces (divided by the mass of an inverse-dynamics start).
    nonnegative : tuple of int
        Entries the inverse-dynamics least squares keeps non-negative (friction levels).
    relative_parameters : tuple of int
        Entries that are fractions of the friction level, not forces (a level's variation
        along the stroke): the position mode's effort check holds them with the shape
        (:meth:`~fricbench.sysid.diagnose.models.InverseDynamics.fit_levels`).
    physical_sizes : tuple of int
        Sizes whose range is a physical limit of the axis, not a multiple of the run's force
        scale (the largest backlash of a drive train): one that ends on its bound is an
        artefact, as a shape parameter there is (:func:`~fricbench.sysid.diagnose.search.
        artefact`).
    idim_nonlinear : int or None
        The entry its inverse-dynamics regressors are nonlinear in (searched, not solved).
    period_parameter : int or None
        The entry that is a spatial period, m (starts within 2 % of each other are one start).
    friction : bool
        A friction term (Coulomb, Stribeck, an offset, asymmetric levels): the first suspect of
        any servo axis. Other effects are claims that need stronger evidence when judged on the
        position (``settings.min_gain_position_other``).
    periodic : bool
        The effect is a periodic term, so a period longer than the stroke is an artefact (a
        level change); False for a smooth variation along the stroke described by a period.
    n_starts : int
        Starts of its real position fits (more where the error surface is multimodal).
    always_fitted : bool
        Fitted for real at every step of the position search, whatever its linearised screen.
    fitted_when_screen_fails : bool
        Fitted for real when its linearised screen fails (a held-out error ratio above
        the natural bound 1: no cut at all): a friction level that changes
        is as far from linear as stiction, and a screen that far off says nothing of it.
    refits_mass : bool
        An output effect that changes the dynamics between force and motion (a compliant
        coupling): where the loop is the law identified from the effort, the mass and damping
        of the rigid inverse dynamics (biased by it) are fitted on the position with it.
    """

    name: ClassVar[str]
    kind: ClassVar[str]
    requires: ClassVar[tuple[str, ...]] = ()
    excludes: ClassVar[tuple[str, ...]] = ()
    refines: ClassVar[str | None] = None
    tried_by_default: ClassVar[bool] = True
    needs_reversals: ClassVar[bool] = False
    shown_at_rests: ClassVar[bool] = False
    summary: ClassVar[str]
    parameters: ClassVar[tuple[int, ...]]
    shape_parameters: ClassVar[tuple[int, ...]] = ()
    force_parameters: ClassVar[tuple[int, ...]] = ()
    nonnegative: ClassVar[tuple[int, ...]] = ()
    relative_parameters: ClassVar[tuple[int, ...]] = ()
    physical_sizes: ClassVar[tuple[int, ...]] = ()
    idim_nonlinear: ClassVar[int | None] = None
    period_parameter: ClassVar[int | None] = None
    periodic: ClassVar[bool] = True
    friction: ClassVar[bool] = False
    n_starts: ClassVar[int] = 1
    always_fitted: ClassVar[bool] = False
    fitted_when_screen_fails: ClassVar[bool] = False
    refits_mass: ClassVar[bool] = False

    # -- parameters ----------------------------------------------------------------------------
    def free(self, effects: Sequence[str]) -> tuple[int, ...]:
        """Plant entries that are free parameters given the model's ``effects``."""
        return self.parameters

    def conditional(self, p: np.ndarray) -> tuple[int, ...]:
        """Plant entries fitted besides :meth:`free` where the row ``p`` gives them a meaning
        (a compliant axis's share of the damping on the motor, with the friction on the load);
        neither sizes nor shapes, never probed."""
        return ()

    def held(self, p: np.ndarray) -> tuple[int, ...]:
        """Entries of :meth:`free` the position fits hold at their start where the row ``p``
        leaves them unidentified (a compliant axis's damping ratio beside the load's own
        damping)."""
        return ()

    def available(self, prep: Prepared) -> bool:
        """Whether the run can show the effect at all (beyond ``needs_reversals``)."""
        return True

    def switched_on(self, p: np.ndarray, prep: Prepared) -> np.ndarray:
        """Plant row with the effect switched on at neutral values (a fit's start)."""
        return p.copy()

    def zeroed(self, p: np.ndarray, effects: Sequence[str]) -> np.ndarray:
        """Plant row with the effect switched off (its sizes zeroed, its shape kept)."""
        q = p.copy()
        for i in self.free(effects):
            if i not in self.shape_parameters:
                q[i] = 0.0
        return q

    @abstractmethod
    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        """Bounds and scaling of entry ``i`` (current value ``value``) on a run."""

    @abstractmethod
    def clip(self, i: int, value: float, b: Bounds) -> float:
        """A linearised start of entry ``i`` clipped into its plausible range."""

    def probe_step(self, i: int, value: float, b: Bounds) -> float:
        """Finite-difference step of entry ``i`` around a start."""
        if i in self.force_parameters:
            return 0.2 * abs(value) + 0.02 * b.force
        return 0.2 * abs(value) + 0.05

    # -- the position screen -------------------------------------------------------------------
    @abstractmethod
    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        """Probes of the linearised position screen around plant row ``p`` (effect on).

        ``y`` is the current model's free-run position (its residual locates periods).
        """

    # -- force effects: inverse dynamics -------------------------------------------------------
    def idim_columns(self, p: np.ndarray, effects: Sequence[str], x: np.ndarray,
                     v: np.ndarray) -> tuple[np.ndarray, tuple[int, ...], np.ndarray]:
        """Regressors in the inverse dynamics ``u = M a + B v + F_eff``.

        The force is linear in the returned coefficients once :attr:`idim_nonlinear` is fixed
        at ``p``. Returns the columns (K, q), the plant entries the coefficients map to, and
        the factor from coefficient to entry (0: the coefficient divided by the Coulomb level).
        """
        raise ValueError(f"effect={self.name!r} is not a force effect with inverse-dynamics "
                         "regressors")

    def idim_key(self, p: np.ndarray, effects: Sequence[str]) -> tuple[Any, ...]:
        """What the regressors depend on besides the motion (their cache key)."""
        nl = self.idim_nonlinear
        return (float(p[nl]) if nl is not None else None,)

    def idim_grid(self, idim: Any, effects: tuple[str, ...], p: np.ndarray, rows: np.ndarray,
                  start: bool) -> np.ndarray:
        """Values of :attr:`idim_nonlinear` to try (all of them to find it, ``start=True``)."""
        raise ValueError(f"effect={self.name!r} has no nonlinear parameter")

    def idim_bracket(self, best: float, grid: np.ndarray, start: bool) -> tuple[float, float]:
        """Log-coordinate bracket of the continuous refinement around the best grid value."""
        if start and grid.size > 1:
            ratio = float(grid[1] / grid[0])
            return float(np.log(best / ratio)), float(np.log(best * ratio))
        return float(np.log(best)) - 0.2, float(np.log(best)) + 0.2

    # -- output effects ------------------------------------------------------------------------
    def output_start(self, model: GreyBox, prep: Prepared, b: Bounds, w: np.ndarray | None,
                     y: np.ndarray, mask: np.ndarray, simulate: SimulateFn) -> GreyBox:
        """Start of an output effect's fit on the samples ``mask`` (``model`` has it on).

        ``simulate(models, prep, w)`` runs models free (for starts found by simulation).
        """
        raise ValueError(f"effect={self.name!r} is not an output effect")

    def evidence(self, model: GreyBox, prep: Prepared, w: np.ndarray | None,
                 simulate: SimulateFn) -> str | None:
        """Why the run does not show the fitted effect where it should, or None.

        A check beyond the held-out error for an effect that could stand in for a mismatch of
        the model elsewhere: ``model`` has it on; ``simulate(models, prep, w)`` runs models
        free. Most effects have no such check.
        """
        return None

    # -- open loop -----------------------------------------------------------------------------
    def open_loop_starts(self, effort: np.ndarray, y: np.ndarray, ts: float
                         ) -> list[dict[int, float]]:
        """Starts of its entries from an open-loop run (effort in, position out), or none.

        The open-loop fit (:mod:`fricbench.sysid.diagnose.open_loop`) fits only sizes from
        shapes fixed by the run's scales, unless an effect finds its shape in the data here
        (a resonance in the frequency response): then those entries are fitted too.
        """
        return []

    # -- reports -------------------------------------------------------------------------------
    @abstractmethod
    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        """Fitted parameters in SI units, keyed ``symbol_unit`` (forces in ``force_unit``)."""

"""The library of candidate effects of the diagnosis, registered by id.

One small class per effect, one file each (see :class:`~.base.Effect` for what a class
says). With ``sigma = sgn(v)`` and the friction scale
``s(x) = 1 + g (x - x_c) + a sin(2 pi x / P) + b cos(2 pi x / P)``::

    F_eff = s(x) sigma [fc + sigma dfc/2 + fs exp(-(v/vs)^2)]      Coulomb, asymmetric, Stribeck
            + sigma (dB/2) v                                       asymmetric viscous
            + f0                                                   constant force
            + A_s sin(2 pi x / lambda) + A_c cos(2 pi x / lambda)  cogging
            + sum_n A_sn sin(2 pi n x / lambda) + A_cn cos(...)    its harmonics (n = 2, 3)
    y     = play_beta(x) + d_inf (1 - exp(-t / tau))               backlash, thermal drift
            (or + d_inf theta, tau theta' = |v| / v_heat - theta)   (of time, or of motion)
            d_inf + e (x - x0) in place of d_inf                    its strain (a screw)
    m_M a_M = ... + k d + c d' ,  m_L a_L = -k d - c d'             compliance (d = x_L - x_M)

Third parties add effects through the entry-point group ``fricbench.effects`` (a callable
taking the registry); an effect's parameters must be entries of the plant row
(:mod:`fricbench.axis.plant`). ``docs/diagnosis_effects.md`` adds one, end to end.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache

import numpy as np

from fricbench.registry import Registry
from fricbench.sysid.diagnose.effects.base import Effect, Probe

__all__ = ["Effect", "Probe", "effect_registry", "get_effect", "effect_names", "EFFECT_NAMES",
           "named_as", "excluded", "default_candidates", "free_indices", "size_entries",
           "describe_parameters"]

effect_registry: Registry[Effect] = Registry("effect", "fricbench.effects")

_PKG = "fricbench.sysid.diagnose.effects"
effect_registry.register("coulomb_friction", f"{_PKG}.coulomb:CoulombFriction",
                         description="a friction force of constant level opposing the motion")
effect_registry.register("stribeck_friction", f"{_PKG}.stribeck:StribeckFriction",
                         description="extra friction at low speed, decaying with a Stribeck "
                                     "velocity")
effect_registry.register("asymmetric_friction", f"{_PKG}.asymmetric:AsymmetricFriction",
                         description="Coulomb and viscous levels that depend on the direction")
effect_registry.register("force_offset", f"{_PKG}.offset:ForceOffset",
                         description="a constant force (gravity, cable drag, an offset)")
effect_registry.register("backlash", f"{_PKG}.backlash:Backlash",
                         description="lost motion between motor and measured position")
effect_registry.register("cogging", f"{_PKG}.cogging:Cogging",
                         description="a force periodic in position (cogging, ripple)")
effect_registry.register("cogging_harmonic_2", f"{_PKG}.cogging_harmonic:CoggingHarmonic2",
                         description="the cogging's 2nd harmonic, at half its period")
effect_registry.register("cogging_harmonic_3", f"{_PKG}.cogging_harmonic:CoggingHarmonic3",
                         description="the cogging's 3rd harmonic, at a third of its period")
effect_registry.register("position_dependent_friction",
                         f"{_PKG}.position_dependent:PositionDependentFriction",
                         description="friction levels that change along the stroke")
for _knots in (3, 5, 9):
    effect_registry.register(f"friction_profile_{_knots}",
                             f"{_PKG}.friction_profile:FrictionProfile{_knots}",
                             description="friction levels of any shape along the stroke, "
                                         f"linear between {_knots} knots")
effect_registry.register("thermal_drift", f"{_PKG}.thermal:ThermalDrift",
                         description="a slow growth of the measured position with time")
effect_registry.register("thermal_strain", f"{_PKG}.thermal_strain:ThermalStrain",
                         description="the thermal growth's part proportional to the position "
                                     "(a screw growing from its fixed bearing)")
effect_registry.register("compliance", f"{_PKG}.compliance:Compliance",
                         description="motor and load masses on a spring and a damper (a "
                                     "resonance)")


@cache
def get_effect(name: str) -> Effect:
    """The (stateless) effect registered as ``name``; unknown names raise with near matches."""
    effect = effect_registry.make(name)
    if not isinstance(effect, Effect) or effect.name != name:
        raise TypeError(f"effect {name!r}: the registry entry must build an Effect named "
                        f"{name!r}, got {effect!r}")
    return effect


def effect_names() -> tuple[str, ...]:
    """Registered effects, built-in ones first in the order the search tries them."""
    return tuple(effect_registry.ids(sort=False))


EFFECT_NAMES = effect_names()
"""The built-in effects (plug-ins registered later are in :func:`effect_names`)."""


def default_candidates() -> tuple[str, ...]:
    """The effects the closed-loop search tries when the user names none: the library as
    registered now, but for those tried only when asked for (:attr:`Effect.tried_by_default`)."""
    return tuple(n for n in effect_names() if get_effect(n).tried_by_default)


def named_as(name: str) -> str:
    """The effect a report naming ``name`` names: the effect it is a further term of
    (:attr:`Effect.refines`: a harmonic of the cogging names the cogging), else itself (a name
    the registry does not know is returned as it is)."""
    if name not in effect_registry:
        return name
    return get_effect(name).refines or name


def excluded(name: str, effects: Sequence[str]) -> bool:
    """Whether effect ``name`` may not join a model with ``effects`` (the same term in another
    shape: :attr:`Effect.excludes`, on either side)."""
    mine = set(get_effect(name).excludes)
    return any(e in mine or name in get_effect(e).excludes for e in effects)


def free_indices(name: str, effects: Sequence[str]) -> tuple[int, ...]:
    """Plant entries that are free parameters of effect ``name`` given the model's effects."""
    return get_effect(name).free(effects)


def size_entries(name: str, idx: Sequence[int]) -> list[int]:
    """Entries of ``idx`` that are sizes of effect ``name`` (a gap, a level, an amplitude),
    not its shape (a period, a time constant): what "not detected" is judged on."""
    eff = get_effect(name)
    return [i for i in eff.parameters if i not in eff.shape_parameters and i in idx]


def describe_parameters(name: str, p: np.ndarray, force_unit: str) -> dict[str, float]:
    """The fitted parameters of effect ``name`` in SI units, keyed ``symbol_unit``.

    Parameters
    ----------
    name : str
        Effect name.
    p : ndarray, shape (N_PLANT,)
        Plant row.
    force_unit : str
        Unit of forces: the effort's unit (e.g. ``"N"``) or ``"m_s2"`` for forces per unit
        mass when the run has no effort.
    """
    return get_effect(name).describe(p, force_unit)

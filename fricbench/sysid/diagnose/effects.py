"""The library of candidate effects: what each one is, its parameters and their units.

Every effect is a physically parameterised term of the grey-box model of
:mod:`fricbench.sysid.diagnose.closed_loop`. *Force* effects act on the mass, inside the loop
(``M dv/dt = u - B v - F_eff``); *output* effects act between the motor and the logged
position, outside the loop. With ``sigma = sgn(v)`` and the friction scale
``s(x) = 1 + g (x - x_c) + a sin(2 pi x / P) + b cos(2 pi x / P)``::

    F_eff = s(x) sigma [fc + sigma dfc/2 + fs exp(-(v/vs)^2)]      Coulomb, asymmetric, Stribeck
            + sigma (dB/2) v                                       asymmetric viscous
            + f0                                                   constant force
            + A_s sin(2 pi x / lambda) + A_c cos(2 pi x / lambda)  cogging
    y     = play_beta(x) + d_inf (1 - exp(-t / tau))               backlash, thermal drift

The direction-dependent Coulomb level ``dfc`` and a constant force ``f0`` are the same force
while the axis moves (they differ only at rest), so ``asymmetric_friction`` carries ``dfc`` only
while ``force_offset`` is not in the model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL

__all__ = ["EffectSpec", "EFFECTS", "EFFECT_NAMES", "free_indices", "describe_parameters",
           "idim_columns", "IDIM_NONLINEAR"]


@dataclass(frozen=True)
class EffectSpec:
    """One candidate effect.

    Attributes
    ----------
    name : str
        Identifier used in reports.
    kind : {"force", "output"}
        Where the effect acts: on the mass inside the loop, or on the logged position.
    requires : tuple of str
        Effects that must already be in the model (a change of a friction level needs a
        friction level).
    needs_reversals : bool
        Only identifiable when the motion reverses.
    summary : str
        One line for reports.
    """

    name: str
    kind: str
    requires: tuple[str, ...]
    needs_reversals: bool
    summary: str


EFFECTS: dict[str, EffectSpec] = {
    e.name: e for e in (
        EffectSpec("coulomb_friction", "force", (), True,
                   "a friction force of constant level opposing the motion"),
        EffectSpec("stribeck_friction", "force", ("coulomb_friction",), True,
                   "extra friction at low speed that decays with a Stribeck velocity"),
        EffectSpec("asymmetric_friction", "force", ("coulomb_friction",), True,
                   "friction levels (Coulomb and viscous) that depend on the direction"),
        EffectSpec("force_offset", "force", (), False,
                   "a constant force (gravity, cable drag, a drive or sensor offset)"),
        EffectSpec("backlash", "output", (), True,
                   "lost motion between the motor and the measured position (play operator)"),
        EffectSpec("cogging", "force", (), False,
                   "a force periodic in position (cogging, screw or motor ripple)"),
        EffectSpec("position_dependent_friction", "force", ("coulomb_friction",), True,
                   "friction levels that change along the stroke"),
        EffectSpec("thermal_drift", "output", (), False,
                   "a slow growth of the measured position with time (thermal expansion)"),
    )
}
EFFECT_NAMES = tuple(EFFECTS)

# plant entries that are free parameters of each effect (fit order)
_FREE: dict[str, tuple[int, ...]] = {
    "coulomb_friction": (CL.I_FC,),
    "stribeck_friction": (CL.I_FS, CL.I_VS),
    "asymmetric_friction": (CL.I_DFC, CL.I_DB),
    "force_offset": (CL.I_OFF,),
    "backlash": (CL.I_BL,),
    "cogging": (CL.I_COGA, CL.I_COGB, CL.I_COGP),
    "position_dependent_friction": (CL.I_PDG, CL.I_PDA, CL.I_PDB, CL.I_PDP),
    "thermal_drift": (CL.I_THA, CL.I_THT),
}

# nonlinear parameter of the IDIM regressors of an effect (searched, not solved)
IDIM_NONLINEAR: dict[str, int] = {
    "stribeck_friction": CL.I_VS,
    "cogging": CL.I_COGP,
    "position_dependent_friction": CL.I_PDP,
}


def free_indices(name: str, effects: tuple[str, ...] | list[str]) -> tuple[int, ...]:
    """Plant entries that are free parameters of effect ``name`` given the model's effects."""
    if name not in _FREE:
        raise ValueError(f"effect={name!r}: expected one of {', '.join(EFFECT_NAMES)}")
    idx = _FREE[name]
    if name == "asymmetric_friction" and "force_offset" in effects:
        # dfc and a constant force are the same force while moving: keep f0 only
        idx = (CL.I_DB,)
    return idx


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
    fu = force_unit
    if name == "coulomb_friction":
        return {f"fc_{fu}": float(p[CL.I_FC])}
    if name == "stribeck_friction":
        return {f"fs_minus_fc_{fu}": float(p[CL.I_FS]), "vs_m_s": float(p[CL.I_VS])}
    if name == "asymmetric_friction":
        out = {f"fc_pos_{fu}": float(p[CL.I_FC] + 0.5 * p[CL.I_DFC]),
               f"fc_neg_{fu}": float(p[CL.I_FC] - 0.5 * p[CL.I_DFC]),
               f"fv_pos_{fu}_s_m": float(p[CL.I_B] + 0.5 * p[CL.I_DB]),
               f"fv_neg_{fu}_s_m": float(p[CL.I_B] - 0.5 * p[CL.I_DB])}
        return out
    if name == "force_offset":
        return {f"f0_{fu}": float(p[CL.I_OFF])}
    if name == "backlash":
        return {"backlash_m": float(p[CL.I_BL])}
    if name == "cogging":
        amp = math.hypot(p[CL.I_COGA], p[CL.I_COGB])
        # A_s sin(th) + A_c cos(th) = A sin(th + phi)
        return {f"amplitude_{fu}": amp, "period_m": float(p[CL.I_COGP]),
                "phase_rad": math.atan2(p[CL.I_COGB], p[CL.I_COGA])}
    if name == "position_dependent_friction":
        amp = math.hypot(p[CL.I_PDA], p[CL.I_PDB])
        return {"gradient_1_m": float(p[CL.I_PDG]), "variation": amp,
                "variation_period_m": float(p[CL.I_PDP]),
                "variation_phase_rad": math.atan2(p[CL.I_PDB], p[CL.I_PDA]),
                "x_center_m": float(p[CL.I_XC])}
    if name == "thermal_drift":
        return {"d_inf_m": float(p[CL.I_THA]), "tau_s": float(p[CL.I_THT])}
    raise ValueError(f"effect={name!r}: expected one of {', '.join(EFFECT_NAMES)}")


def idim_columns(name: str, p: np.ndarray, effects: tuple[str, ...] | list[str],
                 x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, tuple[int, ...], np.ndarray]:
    """Regressors of a force effect in the inverse dynamics ``u = M a + B v + F_eff``.

    The effect's force is linear in the returned coefficients once its nonlinear parameter
    (``IDIM_NONLINEAR``: Stribeck velocity, cogging or variation period) is fixed at ``p``.

    Parameters
    ----------
    name : str
        A force effect.
    p : ndarray, shape (N_PLANT,)
        Current plant row (nonlinear parameters, Coulomb level for the position dependence).
    effects : sequence of str
        Effects of the model the columns are for.
    x, v : ndarray, shape (K,)
        Filtered position (m) and velocity (m/s).

    Returns
    -------
    cols : ndarray, shape (K, q)
        Regressors at the full rate.
    targets : tuple of int
        Plant entries the coefficients map to (see ``coef_scale``).
    coef_scale : ndarray, shape (q,)
        Multiply a coefficient by this to get the plant entry; 0 means the entry is the
        coefficient divided by the Coulomb level (position-dependent friction).
    """
    sgn = np.sign(v)
    moving = (sgn != 0).astype(float)
    if name == "coulomb_friction":
        return sgn[:, None], (CL.I_FC,), np.ones(1)
    if name == "stribeck_friction":
        return (sgn * np.exp(-(v / p[CL.I_VS]) ** 2))[:, None], (CL.I_FS,), np.ones(1)
    if name == "asymmetric_friction":
        idx = free_indices(name, effects)
        cols = []
        if CL.I_DFC in idx:
            # sigma * sigma dfc / 2 = dfc / 2 while moving
            cols.append(0.5 * moving)
        cols.append(0.5 * np.abs(v))
        return np.column_stack(cols), idx, np.ones(len(idx))
    if name == "force_offset":
        return np.ones((v.shape[0], 1)), (CL.I_OFF,), np.ones(1)
    if name == "cogging":
        ph = 2.0 * np.pi * x / p[CL.I_COGP]
        return np.column_stack([np.sin(ph), np.cos(ph)]), (CL.I_COGA, CL.I_COGB), np.ones(2)
    if name == "position_dependent_friction":
        # s(x) fc sigma ~ fc sigma + (fc g)(x - xc) sigma + (fc a) sin sigma + (fc b) cos sigma
        ph = 2.0 * np.pi * x / p[CL.I_PDP]
        pd_cols = np.column_stack([sgn * (x - p[CL.I_XC]), sgn * np.sin(ph), sgn * np.cos(ph)])
        return pd_cols, (CL.I_PDG, CL.I_PDA, CL.I_PDB), np.zeros(3)
    raise ValueError(f"effect={name!r} is not a force effect with inverse-dynamics regressors")

"""The servo feed axis's plant: actuator, mechanics, effects and sensor, without a controller.

This is the one copy of the axis physics. Two controller drivers call it, as python-control's
``nlsys`` separates a system's update function from the law that closes the loop:

* the position/velocity cascade of :mod:`fricbench.axis.kernel` (the environments, the native
  vector env, ``simulate``, the benchmark);
* any identified linear discrete law, :mod:`fricbench.axis.linear_law` (the diagnosis, the
  ``greybox`` predictor and ``greybox-precomp``).

One sample of period ``Ts`` (zero-order hold on the actuator command)::

    i_app  = sat_imax(i_cmd[k - d])                                   delay d, saturation
    M dv/dt = Kt i_app - (B + fv_dir) v - F_f(x, v) - f0 - F_cog(x)    n_sub substeps
    y_fb   = Q(x or x_table) + n ,  y = Q(x_table or x) + n            sensor
    x_table = play_beta(x) + delta + d_th                              backlash, compliance,
                                                                       thermal drift

with the friction level in the direction ``sigma = sgn(v)``, scaled along the stroke::

    s(x)     = max(1 + g (x - x_c) + a sin(2 pi x / P) + b cos(2 pi x / P) + l(x), 0)
    fc_dir   = max(fc + sigma dfc / 2, 0) ,  fs_dir = fc_dir + fs_excess
    F_f      = s(x) sigma [fc_dir + (fs_dir - fc_dir) exp(-(|v|/vs)^delta)]   static laws
    F_cog    = sum_h [A_s,h sin(2 pi h x / lambda) + A_c,h cos(2 pi h x / lambda)],  h = 1, 2, 3
    fv_dir   = fv + sigma dB / 2

``l(x)`` is a friction profile along the stroke (off while its knot count is 0): the relative
level changes ``l_0 .. l_{n-1}`` at ``n`` equally spaced knots from ``x_0`` over a span ``L``
(``x_i = x_0 + i L / (n - 1)``), linear between knots and held at the end knots' values beyond
them. A worn or dirty stretch of the guides, a gradient and a bump are all of that form; up
to :data:`PD_MAX_KNOTS` knots.

Static laws use the implicit update of Kikuuwe et al. (2005), so that stiction holds exactly;
LuGre and Dahl integrate their bristle state exactly for a velocity frozen over a substep.

Thermal drift ``d_th`` (off while ``d_inf`` is 0) follows one of two laws. With the heating
speed ``v_heat`` at 0 it is a function of time, ``d_th = d_inf (1 - exp(-t / tau))``. With
``v_heat > 0`` it is driven by motion (a ball screw heated by turning): a normalised temperature
``theta`` (state ``S_HEAT``, 0 at the start of a run) follows::

    tau dtheta/dt = |v_M| / v_heat - theta ,   d_th = d_inf theta

integrated exactly for the motor speed frozen over each substep (the mean of its ends), so
``d_inf`` is the growth in sustained motion at ``v_heat`` and the drift relaxes at rest. A
screw grows from its fixed bearing: its growth at the table is a strain times that distance,
so the size ``d_inf`` may carry a part proportional to the table position, ``d_inf + strain
(x - x0)`` (off while ``strain`` is 0; ``x0`` a fixed origin, e.g. the middle of the stroke).

Compliance (off while the load fraction ``r`` is 0): the mass ``M`` splits into a motor side
``m_M = (1 - r) M`` (rotor, screw; the actuator force, the friction, the damping ``B``, the
offset and the cogging act on it) and a load ``m_L = r M`` (the table) coupled to it by a spring
``k`` and a damper ``c``. With the deflection ``delta = x_L - x_M``::

    m_M dv/dt = (the rigid right-hand side above) + k delta + c ddelta/dt
    m_L dv_L/dt = -k delta - c ddelta/dt
    k = mu w_r^2 ,  c = 2 zeta mu w_r ,  mu = m_M m_L / M ,  w_r = 2 pi f_r

``f_r`` is the resonance of the free axis (motor force in, nothing held), ``zeta`` its damping
ratio; the anti-resonance of the motor side is ``f_a = f_r sqrt(1 - r)``. Friction acting on
the motor side is the usual reduction of a ball-screw axis (screw bearings, nut, motor) and
keeps a zero load fraction identical to the rigid axis. Per substep, the two-mass system
(with ``B``) under the motor force ``g`` held (actuator, friction, cogging: all but the spring
and ``B``) is integrated exactly (a matrix exponential, once per row); ``g`` itself comes from
the implicit update above with the mass a held force accelerates over the substep
(``m_eff = h / Gamma_v``: the motor side's for a soft spring, ``M`` for a stiff one), stiction
and all. So the linear two-mass axis is exact for a force held over each substep (a zero-order
hold, as the rigid axis is; scipy's ZOH discretisation to 1e-9 in the tests), for any stiffness
(a spring of 100 kHz gives the rigid axis to 1e-10 of the stroke), without numerical damping;
friction is implicit as on the rigid axis.

With ``compliance_friction_load`` set (1), the friction (every law above, at the load's
position ``x_M + delta``) and the viscous damping ``B`` (the friction's viscous part) act on
the load instead: a belt's or a long screw's carriage on its guides, the motor side nearly
free. The two-mass system with ``B`` on the load is integrated exactly for two forces held
over the substep, the motor's (actuator, offset, cogging) and the load's friction, which comes
from the same implicit update applied to the load's velocity with the mass a force held on the
load accelerates over the substep (:func:`compliance_load_constants`). The friction held over
a substep stops the load at the substep's ends, so a resonance needs substeps well below its
period (first order in the substep where the motor side's is exact: the tests'
stick-slip runs converge to the rigid axis as the coupling stiffens and the substep shrinks).
A zero load fraction ignores it (the rigid axis). The share ``compliance_b_motor_share`` of
``B`` acts on the motor instead (0, the default: all on the load): a real drive's viscous
losses are in both bodies' bearings (the carriage's guides, the pulleys' and the motor's), and
a model with all of them on one body makes up for the rest with the coupling's damping
``zeta``. Ignored with the friction on the motor.

Backlash between two bodies (off while the load fraction ``r_b`` is 0, the play operator
above): the motor ``m_M = (1 - r_b) M`` takes the actuator force, the offset and the cogging; the
load ``m_L = r_b M`` (the table) carries the friction (at its own position); the damping ``B``
is split as the mass is. With the deflection ``delta = x_L - x_M`` within ``[-b/2, b/2]``: in
contact the two move as one body (the rigid update above with the whole mass) while the contact
force pushes; apart, the motor moves alone (exactly, ``B`` implicit) and the load coasts
against its friction (the implicit update with its own mass); a gap that closes within a
substep is an inelastic impact, the substep then taken together from its start with the
velocity of the momentum. The state reuses the deflection entries (``S_DEF``, ``S_DEFV``). A
vanishing gap gives the rigid axis; a vanishing load share the play operator with the motor
frictionless while it crosses the gap. Drive trains with lost motion behave this way: the table
coasts until its friction stops it, and the loop meets the motor's inertia alone at every
reversal.

The plant row (columns below) is the union of what the environments and the diagnosis need.
Everything is in one consistent set of units: SI for the environments; the diagnosis may use
an effort unit for forces (``Kt = 1``) or a unit mass (forces become accelerations). A second
(compliant) mass adds its columns (``compliance_*``, ``log_motor``) and state entries
(``S_DEF``, ``S_DEFV``) here, and a second branch in :func:`advance`; the drivers only carry the
state along. The motion-driven thermal drift does the same with one column
(``thermal_heating_speed``) and one state entry (``S_HEAT``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from fricbench.friction.laws import (
    KIND_DAHL,
    KIND_LUGRE,
    KIND_STATIC,
    stribeck_level,
    stribeck_level_taylor,
)

# Fast-math without the no-NaN/no-inf assumptions, so that the divergence checks stay valid:
# reciprocals, fused multiply-add and reassociation change results by rounding only.
FASTMATH = {"arcp", "contract", "reassoc", "nsz", "afn"}

# -- plant row layout ---------------------------------------------------------------------------
(TS, NSUB, M, B, KT, IMAX, DELAY, FKIND, FC, DFC, FS_EXCESS, VS, DELTA, FV, DB, SIGMA0, SIGMA1,
 OFFSET, COG_SIN, COG_COS, COG_PERIOD, PD_GRAD, PD_SIN, PD_COS, PD_PERIOD, PD_CENTER,
 BACKLASH, TH_AMP, TH_TAU, QUANT, NOISE, MEAS_TABLE, COMP_RATIO, COMP_FREQ, COMP_ZETA,
 LOG_MOTOR, TH_VHEAT, BL_LOAD, COMP_LOAD, COMP_B_MOTOR, PD_START, PD_SPAN, PD_NKNOTS,
 PD_KNOT0) = range(44)
PD_MAX_KNOTS = 12
"""Most knots of the friction profile ``l(x)`` (columns ``pd_profile_0`` ..)."""
PD_LEVEL_RANGE = (-0.9, 2.0)
"""Relative level changes a knot of the friction profile may take: a level at least a tenth of
the reference level, at most three times it (env specs are checked against it, the diagnosis
fits within it)."""
COG_H2_SIN, COG_H2_COS, COG_H3_SIN, COG_H3_COS = range(PD_KNOT0 + PD_MAX_KNOTS,
                                                      PD_KNOT0 + PD_MAX_KNOTS + 4)
"""The cogging's second and third harmonics (a linear motor's magnets, a motor's slots and
poles): sine and cosine coefficients on the cogging period."""
TH_STRAIN, TH_X0 = COG_H3_COS + 1, COG_H3_COS + 2
"""The thermal growth's strain (a screw's growth proportional to the distance from its fixed
bearing) and the position it is measured from: ``d_th = s (d_inf + strain (x - x0))``."""
N_PLANT = TH_X0 + 1
PLANT_NAMES = (
    "ts", "n_substeps", "mass", "damping", "kt", "i_max", "delay_samples", "friction_kind",
    "fc", "dfc", "fs_excess", "vs", "delta", "fv", "dB", "sigma0", "sigma1", "offset",
    "cog_sin", "cog_cos", "cog_period", "pd_gradient", "pd_sin", "pd_cos", "pd_period",
    "pd_center", "backlash", "thermal_amplitude", "thermal_tau", "quantization", "noise_std",
    "measure_table", "compliance_load_fraction", "compliance_frequency", "compliance_damping",
    "log_motor", "thermal_heating_speed", "backlash_load_fraction",
    "compliance_friction_load", "compliance_b_motor_share", "pd_profile_start",
    "pd_profile_span", "pd_profile_knots", *(f"pd_profile_{i}" for i in range(PD_MAX_KNOTS)),
    "cog_h2_sin", "cog_h2_cos", "cog_h3_sin", "cog_h3_cos", "thermal_strain",
    "thermal_strain_origin",
)
N_PLANT_RIGID = 32
"""Length of the plant row before compliance (rows of that length are padded by
:func:`pad_row`)."""
N_PLANT_COMPLIANT = 36
"""Length of the plant row before the motion-driven thermal drift (padded by
:func:`pad_row`)."""
N_PLANT_HEATED = 37
"""Length of the plant row before the two-body backlash (padded by :func:`pad_row`)."""
N_PLANT_TWO_BODY = 38
"""Length of the plant row before the compliant axis's friction on the load (padded by
:func:`pad_row`)."""
N_PLANT_LOAD_FRICTION = 39
"""Length of the plant row before the motor's share of the damping of a compliant axis with
the friction on the load (padded by :func:`pad_row`)."""
N_PLANT_UNPROFILED = 40
"""Length of the plant row before the friction profile along the stroke (padded by
:func:`pad_row`)."""
N_PLANT_FUNDAMENTAL = PD_KNOT0 + PD_MAX_KNOTS
"""Length of the plant row before the cogging's harmonics (padded by :func:`pad_row`)."""
N_PLANT_UNSTRAINED = COG_H3_COS + 1
"""Length of the plant row before the thermal growth's strain (padded by :func:`pad_row`)."""
OLDER_PLANT_LENGTHS = (N_PLANT_RIGID, N_PLANT_COMPLIANT, N_PLANT_HEATED, N_PLANT_TWO_BODY,
                       N_PLANT_LOAD_FRICTION, N_PLANT_UNPROFILED, N_PLANT_FUNDAMENTAL,
                       N_PLANT_UNSTRAINED)
"""Lengths of the earlier plant layouts :func:`pad_row` accepts (and stored rows may have)."""

# -- plant state layout (the first entries of a driver's state row) -----------------------------
S_X, S_V, S_XPLAY, S_Z, S_DEF, S_DEFV, S_HEAT = 0, 1, 2, 3, 4, 5, 6
N_PLANT_STATE = 7
DELAY_MAX = 16


def default_row(mass: float = 1.0, damping: float = 0.0, ts: float = 1.0e-3,
                n_sub: int = 1) -> np.ndarray:
    """A plant row with every effect off: no friction, no actuator limits, an ideal sensor.

    Parameters
    ----------
    mass : float
        Moving mass (kg, or 1 for a unit mass).
    damping : float
        Viscous damping ``B`` (force per m/s).
    ts : float
        Sample time, s.
    n_sub : int
        Mechanics substeps per sample.

    Returns
    -------
    ndarray, shape (N_PLANT,)
    """
    p = np.zeros(N_PLANT)
    p[TS] = ts
    p[NSUB] = n_sub
    p[M] = mass
    p[B] = damping
    p[KT] = 1.0
    p[IMAX] = np.inf
    p[FKIND] = KIND_STATIC
    p[VS] = 1.0e-3
    p[DELTA] = 2.0
    p[COG_PERIOD] = 1.0
    p[PD_PERIOD] = 1.0
    p[TH_TAU] = 1.0
    p[COMP_FREQ] = 50.0
    p[COMP_ZETA] = 0.05
    return p


def pad_row(row: np.ndarray) -> np.ndarray:
    """A plant row of the current layout from one of an earlier layout.

    Rows of the rigid layout (32 entries), the compliant one (36), the one with the heating
    speed (37), the one with the two-body backlash (38), the one with the compliant axis's
    friction on the load (39), the one before the friction profile (40), the one before the
    cogging's harmonics (55) and the one before the thermal strain (59) are accepted: the
    entries added since (compliance, the logged side, the thermal heating speed, the
    backlash's load fraction, the compliant axis's friction on the load, the motor's share of
    its damping, the friction profile, the cogging's harmonics, the thermal strain) are
    appended off, so an older row keeps its meaning; a row of the
    current length is returned as a copy.
    """
    r = np.asarray(row, dtype=float)
    if r.shape == (N_PLANT,):
        return r.copy()
    if r.ndim != 1 or r.shape[0] not in OLDER_PLANT_LENGTHS:
        older = ", ".join(str(n) for n in sorted(OLDER_PLANT_LENGTHS, reverse=True))
        raise ValueError(f"row: expected a plant row of {N_PLANT} (or {older}) entries, got "
                         f"shape {r.shape}")
    out = default_row()
    out[:r.shape[0]] = r
    return out


def _coupling(m_total: float, ratio: float, f_r: float,
              zeta: float) -> tuple[float, float, float, float]:
    """The two masses, the spring ``k = mu w_r^2`` and the damper ``c = 2 zeta mu w_r`` of a
    compliant axis (``mu = m_M m_L / M``)."""
    m_load = ratio * m_total
    m_motor = m_total - m_load
    w_r = 2.0 * math.pi * f_r
    mu = m_motor * m_load / m_total
    return m_motor, m_load, mu * w_r * w_r, 2.0 * zeta * mu * w_r


def _expm(F: np.ndarray) -> np.ndarray:
    """``expm(F)`` by scaling and squaring with a Taylor series (1e-16 accurate once scaled):
    the compliant substep's exact map, once per plant row (scipy's expm is not callable from
    compiled code)."""
    n_dim = F.shape[0]
    norm = 0.0
    for i in range(n_dim):
        row = 0.0
        for j in range(n_dim):
            row += abs(F[i, j])
        norm = max(norm, row)
    n_sq = 0
    while norm > 0.25:
        norm *= 0.5
        n_sq += 1
    Fs = F * (0.5 ** n_sq)
    E = np.eye(n_dim)
    term = np.eye(n_dim)
    for n in range(1, 18):
        term = term @ Fs / n
        E = E + term
    for _ in range(n_sq):
        E = E @ E
    return E


def compliance_constants(m_total: float, ratio: float, f_r: float, zeta: float,
                         h: float, damping: float = 0.0) -> tuple[float, ...]:
    """Substep constants of the compliant coupling (see the module docstring).

    The two-mass system (with the motor side's viscous ``damping`` B) with the motor's force
    ``g`` (everything but the spring and B: the actuator, friction, cogging) held over a
    substep ``h`` is integrated exactly: with
    ``s = (v_M, d, d')``, ``s+ = Phi s + Gamma g`` and ``x_M+ = x_M + Psi s + Lambda g``.

    Returns ``(Phi (row-major, 9), Gamma (3), Psi (3), Lambda)``, 16 numbers.
    """
    m_motor, m_load, k, c = _coupling(m_total, ratio, f_r, zeta)
    # w = [v, d, d', int v, g]:  m_M v' = g - B v + k d + c d' ;  d'' = -(k d + c d') / m_L - v'
    F = np.zeros((5, 5))
    F[0, 0] = -damping / m_motor
    F[2, 0] = damping / m_motor
    F[0, 1] = k / m_motor
    F[0, 2] = c / m_motor
    F[0, 4] = 1.0 / m_motor
    F[1, 2] = 1.0
    F[2, 1] = -k / m_load - k / m_motor
    F[2, 2] = -c / m_load - c / m_motor
    F[2, 4] = -1.0 / m_motor
    F[3, 0] = 1.0
    E = _expm(F * h)
    return (E[0, 0], E[0, 1], E[0, 2], E[1, 0], E[1, 1], E[1, 2], E[2, 0], E[2, 1], E[2, 2],
            E[0, 4], E[1, 4], E[2, 4], E[3, 0], E[3, 1], E[3, 2], E[3, 4])



def compliance_load_constants(m_total: float, ratio: float, f_r: float, zeta: float,
                              h: float, damping: float = 0.0,
                              motor_share: float = 0.0) -> tuple[float, ...]:
    """Substep constants of the compliant coupling with the friction and the damping on the load.

    The two-mass system with the viscous ``damping`` B on the load (a belt's carriage on its
    guides: the friction's viscous part), but for the share ``motor_share`` of it on the
    motor (its bearings, the pulleys), is integrated exactly for two forces held over a
    substep ``h``: ``g_M`` on the motor (the actuator, the offset, cogging) and ``g_L`` on the
    load (its friction): with
    ``s = (v_M, d, d')``, ``s+ = Phi s + Gamma_M g_M + Gamma_L g_L`` and
    ``x_M+ = x_M + Psi s + Lambda_M g_M + Lambda_L g_L``.

    Returns ``(Phi (row-major, 9), Gamma_M (3), Psi (3), Lambda_M, Gamma_L (3), Lambda_L)``,
    20 numbers: the first 16 in the order of :func:`compliance_constants`.
    """
    m_motor, m_load, k, c = _coupling(m_total, ratio, f_r, zeta)
    # w = [v, d, d', int v, g_M, g_L]:  m_M v' = g_M - B_M v + k d + c d' ;
    # m_L (v + d')' = g_L - B_L (v + d') - k d - c d'   (B_M = motor_share B, B_L = B - B_M)
    b_motor = motor_share * damping
    b_load = damping - b_motor
    F = np.zeros((6, 6))
    F[0, 1] = k / m_motor
    F[0, 2] = c / m_motor
    F[0, 4] = 1.0 / m_motor
    F[1, 2] = 1.0
    F[2, 0] = -b_load / m_load
    F[2, 1] = -k / m_load - k / m_motor
    F[2, 2] = -(c + b_load) / m_load - c / m_motor
    if b_motor != 0.0:
        # only then: all of B on the load stays the same numbers bit for bit
        F[0, 0] = -b_motor / m_motor
        F[2, 0] += b_motor / m_motor
    F[2, 4] = -1.0 / m_motor
    F[2, 5] = 1.0 / m_load
    F[3, 0] = 1.0
    E = _expm(F * h)
    return (E[0, 0], E[0, 1], E[0, 2], E[1, 0], E[1, 1], E[1, 2], E[2, 0], E[2, 1], E[2, 2],
            E[0, 4], E[1, 4], E[2, 4], E[3, 0], E[3, 1], E[3, 2], E[3, 4],
            E[0, 5], E[1, 5], E[2, 5], E[3, 5])


class Plant(NamedTuple):
    """Per-axis constants of a plant row, unpacked once per run (registers, not array loads)."""

    h: float
    n_sub: int
    m: float
    b: float  # the damping of the implicit update (0 on a compliant axis: in its exact map)
    kt: float
    i_max: float
    delay: int
    kind: int
    fc: float
    dfc: float
    fs_excess: float
    vs: float
    inv_vs: float
    delta: float
    fv: float
    db: float
    inv_pos: float
    inv_neg: float
    sigma0: float
    sigma1: float
    offset: float
    cog_a: float
    cog_b: float
    cog_k: float
    pd_g: float
    pd_a: float
    pd_b: float
    pd_k: float
    pd_xc: float
    backlash: float
    th_amp: float
    th_tau: float
    quant: float
    noise: float
    meas_table: bool
    m_eff: float
    comp: bool
    p_vv: float
    p_vd: float
    p_vdv: float
    p_dv: float
    p_dd: float
    p_ddv: float
    p_rv: float
    p_rd: float
    p_rdv: float
    g_v: float
    g_d: float
    g_r: float
    x_v: float
    x_d: float
    x_dv: float
    x_g: float
    log_motor: bool
    heat: bool  # motion-driven thermal drift (v_heat > 0)
    inv_vheat: float
    th_gain: float  # 1 - exp(-h / tau): theta's exact step towards |v| / v_heat
    two_body: bool  # backlash between two bodies (load fraction > 0), not a play operator
    m_motor: float
    b_motor: float
    m_load: float
    inv_pos_load: float  # 1 / M_eff of the load alone in each direction (its own B and fv)
    inv_neg_load: float
    b_load: float
    load_fric: bool  # compliant axis: the friction and the damping B on the load
    gl_v: float  # Gamma_L and Lambda_L of compliance_load_constants
    gl_d: float
    gl_r: float
    xl_g: float
    m_eff_load: float  # h / Gamma_vL: the mass a force held on the load accelerates
    inv_pos_cl: float  # 1 / (m_eff_load + h fv_dir) in each direction
    inv_neg_cl: float
    pd_n: int  # knots of the friction profile l(x) (0: off)
    pd_x0: float
    pd_inv_step: float  # (n - 1) / L: knot intervals per metre
    pd_knots: tuple[float, ...]  # PD_MAX_KNOTS entries, those past pd_n unused
    cog_harmonics: bool  # a second or third harmonic of the cogging is on
    cog2_a: float
    cog2_b: float
    cog3_a: float
    cog3_b: float
    th_strain: float  # the thermal growth's strain, per metre from th_x0
    th_x0: float


def constants(p: np.ndarray) -> Plant:
    """Unpack plant row ``p`` into the constants the substep uses."""
    # rows are validated where they are built (Axis, the diagnosis's bounds); the guards below
    # only keep a degenerate row (a zero mass in an inverse-dynamics fit, a zero period) from
    # raising inside compiled code: it gives inf/NaN, which every driver checks for
    n_sub = max(int(p[NSUB]), 1)
    h = p[TS] / n_sub
    m = p[M]
    # compliance: the mass a held force accelerates over one substep, h / Gamma_v (the motor
    # side's for a soft spring, the whole mass M for a stiff one)
    comp = p[COMP_RATIO] > 0.0 and m != 0.0
    m_eff = m
    cc: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, h,
                             0.0, 0.0, 0.0)
    # the friction and B on the load instead (a belt's carriage): the load's constants
    load_fric = comp and p[COMP_LOAD] > 0.5
    cl: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    m_eff_load = inv_pos_cl = inv_neg_cl = 0.0
    if load_fric:
        full = compliance_load_constants(m, p[COMP_RATIO], p[COMP_FREQ], p[COMP_ZETA], h,
                                         p[B], p[COMP_B_MOTOR])
        cc = full[:16]
        cl = full[16:]
        m_eff = h / cc[9]
        # the load velocity v + d' answers a force held on the load with Gamma_v + Gamma_r
        m_eff_load = h / (cl[0] + cl[2])
        inv_pos_cl = 1.0 / (m_eff_load + h * max(p[FV] + 0.5 * p[DB], 0.0))
        inv_neg_cl = 1.0 / (m_eff_load + h * max(p[FV] - 0.5 * p[DB], 0.0))
    elif comp:
        cc = compliance_constants(m, p[COMP_RATIO], p[COMP_FREQ], p[COMP_ZETA], h, p[B])
        m_eff = h / cc[9]
    # the damping B of the implicit update (inside the exact map of a compliant axis)
    b_impl = 0.0 if comp else p[B]
    visc = b_impl + p[FV]
    # M_eff = M + h (B + fv_dir): the implicit update's effective mass in each direction
    # (divisions only where a term is on: the vector env unpacks a row at every step)
    meff_pos = m_eff + h * max(visc + 0.5 * p[DB], 0.0)
    inv_pos = 1.0 / meff_pos if meff_pos != 0.0 else math.inf
    inv_neg = inv_pos
    if p[DB] != 0.0:
        meff_neg = m_eff + h * max(visc - 0.5 * p[DB], 0.0)
        inv_neg = 1.0 / meff_neg if meff_neg != 0.0 else math.inf
    # no Stribeck hump (or vs <= 0): plain Coulomb, and the substep skips the exponential
    inv_vs = 1.0 / p[VS] if (p[VS] > 0.0 and p[FS_EXCESS] != 0.0) else 0.0
    cog_harmonics = (p[COG_H2_SIN] != 0.0 or p[COG_H2_COS] != 0.0 or p[COG_H3_SIN] != 0.0
                     or p[COG_H3_COS] != 0.0) and p[COG_PERIOD] != 0.0
    cog_on = ((p[COG_SIN] != 0.0 or p[COG_COS] != 0.0) and p[COG_PERIOD] != 0.0) or cog_harmonics
    cog_k = 2.0 * math.pi / p[COG_PERIOD] if cog_on else 0.0
    pd_on = (p[PD_SIN] != 0.0 or p[PD_COS] != 0.0) and p[PD_PERIOD] != 0.0
    pd_k = 2.0 * math.pi / p[PD_PERIOD] if pd_on else 0.0
    heat = p[TH_VHEAT] > 0.0
    inv_vheat = 1.0 / p[TH_VHEAT] if heat else 0.0
    th_gain = -math.expm1(-h / p[TH_TAU]) if heat else 0.0
    # two bodies across the gap: the damping B split as the mass is, the friction on the load
    two_body = p[BACKLASH] > 0.0 and p[BL_LOAD] > 0.0 and not comp and m != 0.0
    m_load = p[BL_LOAD] * m if two_body else 0.0
    b_load = p[BL_LOAD] * p[B] if two_body else 0.0
    inv_pos_load = inv_neg_load = 0.0
    if two_body:
        inv_pos_load = 1.0 / (m_load + h * max(b_load + p[FV] + 0.5 * p[DB], 0.0))
        inv_neg_load = 1.0 / (m_load + h * max(b_load + p[FV] - 0.5 * p[DB], 0.0))
    # the friction profile: a single knot (or a span of 0) is a constant change of level
    pd_n = min(max(int(p[PD_NKNOTS]), 0), PD_MAX_KNOTS)
    pd_inv_step = (pd_n - 1) / p[PD_SPAN] if (pd_n > 1 and p[PD_SPAN] > 0.0) else 0.0
    pd_knots = (p[PD_KNOT0], p[PD_KNOT0 + 1], p[PD_KNOT0 + 2], p[PD_KNOT0 + 3],
                p[PD_KNOT0 + 4], p[PD_KNOT0 + 5], p[PD_KNOT0 + 6], p[PD_KNOT0 + 7],
                p[PD_KNOT0 + 8], p[PD_KNOT0 + 9], p[PD_KNOT0 + 10], p[PD_KNOT0 + 11])
    return Plant(h, n_sub, m, b_impl, p[KT], p[IMAX], int(p[DELAY]), int(p[FKIND]), p[FC],
                 p[DFC], p[FS_EXCESS], p[VS], inv_vs, p[DELTA], p[FV], p[DB], inv_pos, inv_neg,
                 p[SIGMA0], p[SIGMA1], p[OFFSET], p[COG_SIN], p[COG_COS], cog_k, p[PD_GRAD],
                 p[PD_SIN], p[PD_COS], pd_k, p[PD_CENTER], p[BACKLASH], p[TH_AMP], p[TH_TAU],
                 p[QUANT], p[NOISE], p[MEAS_TABLE] > 0.5, m_eff, comp, cc[0], cc[1], cc[2],
                 cc[3], cc[4], cc[5], cc[6], cc[7], cc[8], cc[9], cc[10], cc[11], cc[12],
                 cc[13], cc[14], cc[15], p[LOG_MOTOR] > 0.5, heat, inv_vheat, th_gain,
                 two_body, m - m_load, p[B] - b_load, m_load, inv_pos_load, inv_neg_load,
                 b_load, load_fric, cl[0], cl[1], cl[2], cl[3], m_eff_load, inv_pos_cl,
                 inv_neg_cl, pd_n, p[PD_START], pd_inv_step, pd_knots, cog_harmonics,
                 p[COG_H2_SIN], p[COG_H2_COS], p[COG_H3_SIN], p[COG_H3_COS], p[TH_STRAIN],
                 p[TH_X0])


def friction_scale(c: Plant, x: float) -> float:
    """Position-dependent factor ``s(x)`` on the friction levels (never negative)."""
    # s(x) = 1 + g (x - x_c) + a sin(2 pi x / P) + b cos(2 pi x / P)
    s = 1.0 + c.pd_g * (x - c.pd_xc)
    if c.pd_a != 0.0 or c.pd_b != 0.0:
        ph = c.pd_k * x
        s += c.pd_a * math.sin(ph) + c.pd_b * math.cos(ph)
    if c.pd_n > 0:
        s += profile_level(c, x)
    return max(s, 0.0)


def profile_level(c: Plant, x: float) -> float:
    """The friction profile ``l(x)``: linear between equally spaced knots, held beyond them."""
    u = (x - c.pd_x0) * c.pd_inv_step
    last = c.pd_n - 1
    if u <= 0.0:
        return c.pd_knots[0]
    if not u < last:  # beyond the last knot (a NaN position too: never an index from it)
        return c.pd_knots[last]
    i = int(u)
    frac = u - i
    return c.pd_knots[i] + frac * (c.pd_knots[i + 1] - c.pd_knots[i])


def levels(c: Plant, x: float, sigma: float) -> tuple[float, float]:
    """Coulomb and static friction levels in direction ``sigma`` at position ``x``."""
    scale = friction_scale(c, x)
    fc_dir = max(c.fc + 0.5 * sigma * c.dfc, 0.0)
    return scale * fc_dir, scale * (fc_dir + c.fs_excess)


def position_force(c: Plant, x: float) -> float:
    """Force opposing the motor that depends on position only: offset and cogging."""
    f = c.offset
    if c.cog_a != 0.0 or c.cog_b != 0.0:
        # F_cog = A_s sin(2 pi x / lambda) + A_c cos(2 pi x / lambda)
        ph = c.cog_k * x
        f += c.cog_a * math.sin(ph) + c.cog_b * math.cos(ph)
    if c.cog_harmonics:
        # the harmonics h = 2, 3 on the same period (a separate branch: without them the
        # fundamental's sums stay the same bit for bit)
        ph = c.cog_k * x
        f += (c.cog2_a * math.sin(2.0 * ph) + c.cog2_b * math.cos(2.0 * ph)
              + c.cog3_a * math.sin(3.0 * ph) + c.cog3_b * math.cos(3.0 * ph))
    return f


def _mech(c: Plant, x: float, v: float, z: float, f_ext: float, m_eff: float,
          inv_pos: float, inv_neg: float, b: float) -> tuple[float, float, float]:
    """One substep of ``M dv/dt = f_ext - (B + fv) v - F_f`` for a body of mass ``m_eff``.

    ``inv_pos``, ``inv_neg``: ``1 / (M + h (B + fv_dir))`` in each direction; ``b`` the
    damping ``B`` of that body. Returns ``(v_new, z_new, F_f)``.
    """
    h = c.h
    if c.kind == KIND_STATIC:
        # Kikuuwe: v+ = v* - h sgn(v*) g(|v+|) / M_eff with v* = (M v + h f_ext) / M_eff,
        # M_eff = M + h (B + fv_dir); stick (v+ = 0) when |v*| <= h F_s / M_eff
        mom = m_eff * v + h * f_ext
        if mom > 0.0:
            sigma = 1.0
            inv_meff = inv_pos
        else:
            sigma = -1.0
            inv_meff = inv_neg
        h_inv_meff = h * inv_meff
        lo, hi = levels(c, x, sigma)
        v_star = mom * inv_meff
        speed = abs(v_star)
        if speed <= h_inv_meff * max(lo, hi):
            v_new = 0.0
        else:
            level, slope, curv = stribeck_level_taylor(speed, lo, hi, c.inv_vs, c.delta)
            v_new = v_star - sigma * (level * h_inv_meff)
            if v_new * sigma < 0.0:
                v_new = 0.0
            elif slope != 0.0:
                # one midpoint correction of the velocity-dependent level, 2nd-order accurate
                # in sliding where the Stribeck curve changes within a few substeps; the level
                # at the midpoint speed comes from its Taylor expansion about |v*| (one exp per
                # substep, not two; the midpoint is a fraction of vs away)
                v_mid = 0.5 * (abs(v_new) + (abs(v) if v * sigma > 0.0 else 0.0))
                dv = v_mid - speed
                level_mid = level + dv * (slope + 0.5 * curv * dv)
                level_mid = min(max(level_mid, min(lo, hi)), max(lo, hi))
                v_new = v_star - sigma * (level_mid * h_inv_meff)
                if v_new * sigma < 0.0:
                    v_new = 0.0
        # F_f = (M v + h f_ext - M v+) / h - B v+
        f_fric = m_eff * (v - v_new) * (1.0 / h) + f_ext - b * v_new
        return v_new, z, f_fric
    sigma_v = 1.0 if v >= 0.0 else -1.0
    visc = c.fv + 0.5 * sigma_v * c.db
    damping = max(b + visc, 0.0)
    s1 = c.sigma1 if c.kind == KIND_LUGRE else 0.0
    lo, hi = levels(c, x, sigma_v)
    g = lo if c.kind == KIND_DAHL else stribeck_level(abs(v), lo, hi, c.vs, c.delta)
    # dz/dt = v - sigma0 |v| z / g(v): exact for v frozen over the substep (stable for any h)
    if v != 0.0 and g > 0.0:
        z_ss = math.copysign(g / c.sigma0, v)
        z_new = z_ss + (z - z_ss) * math.exp(-c.sigma0 * abs(v) * h / g)
    else:
        z_new = z + v * h
    rate = (z_new - z) / h
    # F = sigma0 z + sigma1 dz/dt + fv v; the sigma1 v part of dz/dt is taken implicitly
    f_bristle = c.sigma0 * z_new + s1 * (rate - v)
    v_new = (m_eff * v + h * (f_ext - f_bristle)) / (m_eff + h * (damping + s1))
    return v_new, z_new, f_bristle + s1 * v_new + visc * v_new


def _mechanics(c: Plant, x: float, v: float, z: float,
               f_ext: float) -> tuple[float, float, float]:
    """One substep of ``M dv/dt = f_ext - (B + fv) v - F_f``: returns ``(v_new, z_new, F_f)``.

    ``M`` is the motor side's effective mass ``c.m_eff`` (the whole mass of a rigid axis).
    """
    return _mech(c, x, v, z, f_ext, c.m_eff, c.inv_pos, c.inv_neg, c.b)


def actuate(c: Plant, buf: np.ndarray, base: int, i_cmd: float) -> tuple[float, int]:
    """Delay and saturate the actuator command.

    ``buf[base:base + delay]`` holds the commands still in transit (newest first). Returns the
    applied command and the side it was clipped on (``+1``, ``-1``, or 0).
    """
    if c.delay > 0:
        i_app = buf[base + c.delay - 1]
        for j in range(c.delay - 1, 0, -1):
            buf[base + j] = buf[base + j - 1]
        buf[base] = i_cmd
    else:
        i_app = i_cmd
    if i_app > c.i_max:
        return c.i_max, 1
    if i_app < -c.i_max:
        return -c.i_max, -1
    return i_app, 0


def _compliant_substep(c: Plant, x: float, v: float, z: float, d: float, dv: float,
                       f_ext: float) -> tuple[float, float, float, float, float, float]:
    """One substep of the compliant axis: returns ``(x, v, z, d, dv, F_f)``.

    The free two-mass system's motor velocity after ``h``; the implicit update then gives the
    held motor force ``g`` (actuator, friction, cogging; not the spring, not ``B``) with the
    mass a held force accelerates, ``m_eff = h / Gamma_v``; then ``x``, ``d``, ``d'`` exactly
    for ``g`` held over the substep. (A function of its own, not inlined: the rigid substep's
    compiled code, and so its rounding, stays as it was.)
    """
    if c.load_fric:
        return _compliant_load_substep(c, x, v, z, d, dv, f_ext)
    v_in = c.p_vv * v + c.p_vd * d + c.p_vdv * dv
    v_new, z, f_fric = _mechanics(c, x, v_in, z, f_ext)
    g = c.m_eff * (v_new - v_in) * (1.0 / c.h)
    x_new = x + c.x_v * v + c.x_d * d + c.x_dv * dv + c.x_g * g
    d_new = c.p_dv * v + c.p_dd * d + c.p_ddv * dv + c.g_d * g
    dv_new = c.p_rv * v + c.p_rd * d + c.p_rdv * dv + c.g_r * g
    return x_new, v_new, z, d_new, dv_new, f_fric



def _compliant_load_substep(c: Plant, x: float, v: float, z: float, d: float, dv: float,
                            f_ext: float) -> tuple[float, float, float, float, float, float]:
    """One substep of the compliant axis with the friction on the load: ``(x, v, z, d, dv,
    F_f)``.

    The motor takes ``f_ext`` (actuator, offset, cogging) held over the substep. The load's
    velocity ``v_L = v + d'`` the free system would reach with it is the implicit update's
    ``v*``; the load's friction (at the load's position ``x + d``) follows from the mass a
    force held on the load accelerates, ``m_eff_load = h / Gamma_vL``, stiction and all, as the
    motor's does on a compliant axis with the friction on the motor; then ``x``, ``v``, ``d``,
    ``d'`` exactly for both forces held.
    """
    h = c.h
    # the rows of v and d' summed: the load's velocity
    vl_free = ((c.p_vv + c.p_rv) * v + (c.p_vd + c.p_rd) * d + (c.p_vdv + c.p_rdv) * dv
               + (c.g_v + c.g_r) * f_ext)
    vl_new, z, f_fric = _mech(c, x + d, vl_free, z, 0.0, c.m_eff_load, c.inv_pos_cl,
                              c.inv_neg_cl, 0.0)
    g_l = c.m_eff_load * (vl_new - vl_free) * (1.0 / h)
    x_new = x + c.x_v * v + c.x_d * d + c.x_dv * dv + c.x_g * f_ext + c.xl_g * g_l
    v_new = c.p_vv * v + c.p_vd * d + c.p_vdv * dv + c.g_v * f_ext + c.gl_v * g_l
    d_new = c.p_dv * v + c.p_dd * d + c.p_ddv * dv + c.g_d * f_ext + c.gl_d * g_l
    dv_new = c.p_rv * v + c.p_rd * d + c.p_rdv * dv + c.g_r * f_ext + c.gl_r * g_l
    return x_new, v_new, z, d_new, dv_new, f_fric


def _two_body_substep(c: Plant, x: float, v: float, z: float, d: float, dv: float,
                      f_ext: float) -> tuple[float, float, float, float, float, float]:
    """One substep of the two bodies across a backlash gap: returns ``(x, v, z, d, dv, F_f)``.

    ``x``, ``v``: the motor; ``d = x_L - x_M`` within ``[-b/2, b/2]`` and its rate. In contact
    (``d`` at a limit, not separating) the two move as one body, the rigid update of the whole
    axis with the load's friction, as long as the contact force that holds them together
    pushes (a contact cannot pull). Apart, the motor takes the actuator force alone and the
    load coasts against its friction (each with its share of ``B``); when the gap closes, the
    impact is perfectly inelastic: one velocity from the momentum, and the substep is taken
    together from the substep's start (so a vanishing gap gives the rigid axis).
    (A function of its own, not inlined: the rigid substep's compiled code stays as it was.)
    """
    h = c.h
    half = 0.5 * c.backlash
    x_l = x + d
    side = 1.0 if d <= -half else (-1.0 if d >= half else 0.0)
    if side != 0.0 and side * dv <= 0.0:
        # together: the whole mass, the load's friction (at the load's position)
        v_new, z_new, f_fric = _mech(c, x_l, v, z, f_ext, c.m, c.inv_pos, c.inv_neg, c.b)
        # the contact force on the load, from the motor's own balance
        f_c = f_ext - c.b_motor * v_new - c.m_motor * (v_new - v) * (1.0 / c.h)
        if side * f_c >= 0.0:
            return x + 0.5 * h * (v + v_new), v_new, z_new, d, 0.0, f_fric
    v_l = v + dv
    v_m = (c.m_motor * v + h * f_ext) / (c.m_motor + h * c.b_motor)
    v_l_new, z_new, f_fric = _mech(c, x_l, v_l, z, 0.0, c.m_load, c.inv_pos_load,
                                   c.inv_neg_load, c.b_load)
    x_new = x + 0.5 * h * (v + v_m)
    d_new = x_l + 0.5 * h * (v_l + v_l_new) - x_new
    if d_new < -half or d_new > half:
        # the gap closes within the substep: an inelastic impact (one velocity from the
        # momentum), and the substep taken together from there, so that a vanishing gap is the
        # rigid axis (stiction and all) and the centre of mass moves as the forces say
        d_c = -half if d_new < -half else half
        v_c = (c.m_motor * v + c.m_load * v_l) / c.m
        v_new, z_new, f_fric = _mech(c, x_l, v_c, z, f_ext, c.m, c.inv_pos, c.inv_neg, c.b)
        x_cm = x + c.m_load / c.m * d + 0.5 * h * (v_c + v_new)
        return x_cm - c.m_load / c.m * d_c, v_new, z_new, d_c, 0.0, f_fric
    return x_new, v_m, z_new, d_new, v_l_new - v_m, f_fric


def advance(c: Plant, x: float, v: float, z: float, x_play: float, d: float, dv: float,
            theta: float, f_motor: float
            ) -> tuple[float, float, float, float, float, float, float, float]:
    """Advance the mechanics over one sample (``n_sub`` substeps, zero-order hold on the force).

    Returns ``(x, v, z, x_play, d, dv, theta, F_f)``: motor position and velocity, bristle
    state, the position after the transmission's play, the compliant deflection ``x_L - x_M``
    and its rate (0 on a rigid axis), the normalised temperature of a motion-driven thermal
    drift (unchanged when the drift is time-driven), and the mean friction force over the
    sample.
    """
    h = c.h
    f_sum = 0.0
    for _ in range(c.n_sub):
        f_ext = f_motor - position_force(c, x)
        if c.comp:
            x, v_new, z, d, dv, f_fric = _compliant_substep(c, x, v, z, d, dv, f_ext)
        elif c.two_body:
            x, v_new, z, d, dv, f_fric = _two_body_substep(c, x, v, z, d, dv, f_ext)
        else:
            v_new, z, f_fric = _mechanics(c, x, v, z, f_ext)
            # trapezoidal position: exact when the velocity changes linearly over h
            x += 0.5 * h * (v + v_new)
        if c.heat:
            # tau dtheta/dt = |v| / v_heat - theta, exact for the mean speed held over h
            theta += (0.5 * (abs(v) + abs(v_new)) * c.inv_vheat - theta) * c.th_gain
        v = v_new
        f_sum += f_fric
        if c.backlash > 0.0 and not c.two_body:
            # play operator: the table follows only once the lost motion is taken up
            if x - x_play > 0.5 * c.backlash:
                x_play = x - 0.5 * c.backlash
            elif x - x_play < -0.5 * c.backlash:
                x_play = x + 0.5 * c.backlash
        else:
            x_play = x
    return x, v, z, x_play, d, dv, theta, f_sum / c.n_sub


def thermal_drift(c: Plant, theta: float, t: float, x: float) -> float:
    """Thermal growth of the table position ``x``: of the temperature ``theta``, or of time
    ``t``; an offset and, with a strain, a part proportional to the distance from ``th_x0``."""
    drift = 0.0
    if c.th_amp != 0.0 or c.th_strain != 0.0:
        # the growth at x: d_inf + strain (x - x0) (a screw grows from its fixed bearing)
        size = c.th_amp + c.th_strain * (x - c.th_x0)
        if c.heat:
            # d = size theta
            drift = size * theta
        else:
            # d(t) = size (1 - exp(-t / tau))
            drift = size * (1.0 - math.exp(-t / c.th_tau))
    return drift


def sense(c: Plant, x_motor: float, x_play: float, d: float, theta: float, t: float,
          noise: float) -> tuple[float, float]:
    """Feedback reading and logged reading at time ``t``; ``noise`` in position units.

    The table (load) side is ``x_play + d`` plus the thermal drift (of the temperature
    ``theta`` or of ``t``); the logged reading is the table's, or the motor's when the row logs
    the motor encoder (``log_motor``).
    """
    x_table = x_play + d + thermal_drift(c, theta, t, x_play + d)
    x_sensor = x_table if c.meas_table else x_motor
    x_log = x_motor if c.log_motor else x_table
    q = c.quant
    if q > 0.0:
        x_sensor = q * math.floor(x_sensor / q + 0.5)
        x_log = q * math.floor(x_log / q + 0.5)
    return x_sensor + noise, x_log + noise


def load_position(c: Plant, x_play: float, d: float, theta: float, t: float) -> float:
    """True (noise-free) table position at time ``t``: play, deflection and thermal drift."""
    return x_play + d + thermal_drift(c, theta, t, x_play + d)


def _sliding_force(p: np.ndarray, x: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    c = constants(p)
    for k in range(x.shape[0]):
        vk = v[k]
        f = position_force(c, x[k])
        if vk != 0.0:
            sigma = 1.0 if vk > 0.0 else -1.0
            # the row's B (c.b is the implicit update's: 0 on a compliant axis)
            damp = max(p[B] + c.fv + 0.5 * sigma * c.db, 0.0)
            lo, hi = levels(c, x[k], sigma)
            level = lo if c.inv_vs == 0.0 else stribeck_level(abs(vk), lo, hi, c.vs, c.delta)
            f += damp * vk + sigma * level
        out[k] = f


_coupling = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(_coupling)
_expm = numba.njit(cache=True, fastmath=FASTMATH)(_expm)
compliance_constants = numba.njit(cache=True, fastmath=FASTMATH)(compliance_constants)
compliance_load_constants = numba.njit(cache=True, fastmath=FASTMATH)(compliance_load_constants)
constants = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(constants)
profile_level = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(profile_level)
friction_scale = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(friction_scale)
levels = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(levels)
position_force = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(position_force)
_mech = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(_mech)
_mechanics = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(_mechanics)
actuate = numba.njit(cache=True, inline="always")(actuate)
_compliant_load_substep = numba.njit(cache=True, fastmath=FASTMATH)(_compliant_load_substep)
_compliant_substep = numba.njit(cache=True, fastmath=FASTMATH)(_compliant_substep)
_two_body_substep = numba.njit(cache=True, fastmath=FASTMATH)(_two_body_substep)
advance = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(advance)
thermal_drift = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(thermal_drift)
sense = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(sense)
load_position = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(load_position)
_sliding_force = numba.njit(cache=True)(_sliding_force)


def sliding_force(p: np.ndarray, x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Force of the plant opposing the motor, ``(B + fv) v + F_f + f0 + F_cog``, while sliding.

    The force law of :func:`advance` at a known motion (at ``v = 0`` only the position forces;
    friction then takes whatever value holds the axis, which an inverse model cannot know).
    Used by the inverse-dynamics effort model ``u = M a + sliding_force(x, v)``.

    Parameters
    ----------
    p : ndarray, shape (N_PLANT,)
        Plant row.
    x, v : ndarray, shape (K,)
        Position (m) and velocity (m/s).

    Returns
    -------
    ndarray, shape (K,)
    """
    out = np.empty(np.shape(x))
    _sliding_force(np.ascontiguousarray(p, dtype=float), np.ascontiguousarray(x, dtype=float),
                   np.ascontiguousarray(v, dtype=float), out)
    return out


__all__ = [
    "DELAY_MAX", "FASTMATH", "N_PLANT", "N_PLANT_COMPLIANT", "N_PLANT_RIGID", "N_PLANT_STATE",
    "PLANT_NAMES", "Plant",
    "actuate", "advance", "compliance_constants", "compliance_load_constants", "constants",
    "default_row", "friction_scale", "profile_level", "PD_MAX_KNOTS", "PD_LEVEL_RANGE",
    "PD_START", "PD_SPAN",
    "PD_NKNOTS", "PD_KNOT0", "N_PLANT_UNPROFILED", "COG_H2_SIN", "COG_H2_COS", "COG_H3_SIN",
    "COG_H3_COS", "N_PLANT_FUNDAMENTAL", "TH_STRAIN", "TH_X0", "N_PLANT_UNSTRAINED",
    "levels", "load_position", "pad_row", "position_force", "sense", "sliding_force",
    "thermal_drift",
    "TS", "NSUB", "M", "B", "KT", "IMAX", "DELAY", "FKIND", "FC", "DFC", "FS_EXCESS", "VS",
    "DELTA", "FV", "DB", "SIGMA0", "SIGMA1", "OFFSET", "COG_SIN", "COG_COS", "COG_PERIOD",
    "PD_GRAD", "PD_SIN", "PD_COS", "PD_PERIOD", "PD_CENTER", "BACKLASH", "TH_AMP", "TH_TAU",
    "QUANT", "NOISE", "MEAS_TABLE", "COMP_RATIO", "COMP_FREQ", "COMP_ZETA", "LOG_MOTOR",
    "TH_VHEAT", "BL_LOAD", "COMP_LOAD", "N_PLANT_HEATED", "N_PLANT_TWO_BODY", "S_X", "S_V",
    "S_XPLAY", "S_Z", "S_DEF", "S_DEFV",
    "S_HEAT", "KIND_STATIC",
    "KIND_LUGRE", "KIND_DAHL",
]

"""A second servo-axis simulator, written for the tests of ``fricbench diagnose``.

It shares no code with fricbench's axis kernel or the diagnosis's grey box: its own
integrator, controllers, friction, effects, reference generator and CSV writer, in plain
numpy and Python (nothing from :mod:`fricbench` is imported here). Runs drawn from it check
that the diagnosis holds on data it was not shaped on.

The loop
--------
A digital drive runs at 1 kHz (:data:`LOOP_TS`). At sample ``k`` it reads the motor-side
encoder, computes a command (a current in A, or a force when the force constant is 1),
clips it at the current limit and hands it to the power stage, which applies
``kt * command`` as a force from sample ``k + delay`` to ``k + delay + 1`` (zero-order
hold, a transport delay of ``delay`` loop periods). Two control laws:

* ``cascade``: position P with velocity feedforward, velocity PI on the backward-difference
  velocity (optionally low-pass filtered), acceleration feedforward, the current loop taken
  as ideal (a gain);
* ``pid``: a PID position loop (derivative of the error through a first-order filter,
  backward Euler) with optional velocity/acceleration feedforward of the reference
  (LinuxCNC's FF1/FF2), commanding the current directly.

Both integrate only while the command is not clipped in the integrator's direction
(conditional integration), as drives do against wind-up.

The mechanics
-------------
Semi-closed loop: the drive feeds back the motor-side position; the position written to the
log is the table's (a linear scale, or the load side of a rotary axis). Without backlash the
drive train is rigid and motor and table are one body. With backlash the axis is **two
bodies**, the motor (rotor, screw) and the table, coupled through a gap: no force while the
relative position is inside the gap, a stiff spring-damper contact (400..800 Hz) beyond it.
Two bodies rather than a play operator, because a play operator assumes the table stops the
instant the motor leaves it; here the table coasts until its friction stops it, and while the
gap is crossed the drive moves only the motor's inertia, so the loop's gain changes at each
reversal. That is what a real drive train does, and it is not the model the diagnosis fits
(a play operator on the output), which makes the check meaningful.

Forces on the table: Coulomb friction, optionally Stribeck (``fc + (fs - fc) exp(-(|v| /
vs)^shape)``, shape 1 or 2), viscous damping, the friction level optionally varying along
the stroke (a gradient and/or a sinusoidal wave). On the motor: the drive force, cogging
(``A sin(2 pi x / P + phi)`` in the motor position) and a share of the viscous damping.

Integrator
----------
Each loop period is cut into :data:`SUBSTEPS` (20: a 20 kHz internal step). Within a
substep every force except the viscous one is held constant and the body's motion
``m dv/dt = f - b v`` is integrated exactly (exponential solution). So without friction and
effects, a linear controller gives the exact sampled response of the continuous plant under a
zero-order hold: the same numbers as a ZOH discretisation (the tests check this against
python-control). Friction is a Karnopp-type stick/slip law without a velocity band: when
the friction force would reverse the velocity within a substep, the body is stopped at the
exact instant its velocity crosses zero (from the same exponential solution) and stays stuck
while the other forces on it are below the breakaway level; so it never chatters around zero
velocity. The two bodies' contact force is evaluated at the start of each substep (explicit
coupling; stable with a 20 kHz step for the contact frequencies and damping drawn here).

Thermal drift
-------------
Heating by motion: a normalised temperature ``theta`` follows ``tau dtheta/dt = |v_motor| /
v_heat - theta`` (``v_heat``: the run's mean reference speed, so ``theta`` is about 1 in
sustained motion and relaxes at rest), and the logged table position grows by ``G theta``
(screw expansion seen by the table-side sensor, not by the motor encoder). Not a function
of time alone: the diagnosis's ``d (1 - exp(-t / tau))`` is only an approximation of it.

Sensor and log
--------------
White noise, then quantisation to the encoder step (so every reading is a multiple of the
step) for both the feedback and the logged position, independently drawn. The log holds
every sample (1 kHz) or every 10th (100 Hz; the loop still runs at 1 kHz). The logged
effort is the clipped command: in A, in N (force command), or in % of the current limit.
Positions are written in m, mm or um (linear) or rad or deg (rotary). A "rounded export"
writes them with few decimals, so that the (coarse, not round) encoder step reads unevenly
(3.51, 3.52, ...).

Cases
-----
:func:`draw_case` draws one run of a kind (:data:`KINDS`) from a seed: the variant
(controller, delay, saturation, units, logging, effort, CSV layout) from ``[seed, 0]`` and
the physical parameters and reference from ``[seed, 1 + attempt]``. An effect whose
noise-free signature in the logged position is below twice the noise floor, or a cogging whose
period is longer than the run's travel, is redrawn (five tries, then the whole axis) so that
it can be seen at all. :func:`write_csv` writes the run the way a logger would,
:func:`cli_args` gives the ``fricbench diagnose`` options a user would type for it and
:meth:`Case.truth` what a right diagnosis says.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace

import numpy as np

__all__ = ["LOOP_TS", "SUBSTEPS", "KINDS", "EFFECT_NAME", "FRICTION_NAMES", "Plant",
           "Controller", "Sensor", "Variant", "Trace", "Case", "simulate", "loop_poles",
           "random_reference", "draw_variant", "draw_case", "write_csv", "cli_args",
           "UNIT_PER_SI"]

LOOP_TS = 1e-3
"""Period of the drive's control loop, s (1 kHz)."""

SUBSTEPS = 20
"""Integration substeps per loop period (a 20 kHz internal step)."""

KINDS = ("control", "backlash", "cogging", "thermal", "posdep", "stribeck")
"""Kinds of case: friction only, or friction and one undeclared effect."""

EFFECT_NAME = {"control": None, "backlash": "backlash", "cogging": "cogging",
               "thermal": "thermal_drift", "posdep": "position_dependent_friction",
               "stribeck": "stribeck_friction"}
"""The diagnosis's name of each kind's effect."""

FRICTION_NAMES = frozenset({"coulomb_friction", "stribeck_friction", "asymmetric_friction",
                            "force_offset"})
"""Effects that describe the friction every case has; naming them is never wrong."""

UNIT_PER_SI = {"m": 1.0, "mm": 1e3, "um": 1e6, "rad": 1.0, "deg": 180.0 / math.pi}
"""Logged position per SI unit (m or rad)."""

# scale of the linear reference case (a 30 mm stroke): other strokes and rotary axes scale
# every length-like range by stroke / _REF_STROKE so that the loop sees the same dynamics
_REF_STROKE = 0.03


# -- parameters -----------------------------------------------------------------------------
@dataclass(frozen=True)
class Plant:
    """Mechanics of the axis (SI; for a rotary axis read m as rad, N as N m, kg as kg m^2).

    Attributes
    ----------
    mass : float
        Total moving mass (or inertia), motor and table.
    damping : float
        Total viscous damping, N s/m; a fifth on the motor, the rest on the table.
    coulomb, breakaway : float
        Coulomb friction and breakaway (static) friction, N; ``breakaway > coulomb`` adds
        Stribeck friction.
    stribeck_velocity, stribeck_shape : float
        Stribeck velocity (m/s) and exponent (1 or 2).
    backlash : float
        Gap between motor and table, m (0: a rigid drive train, one body).
    motor_share : float
        Share of ``mass`` on the motor side (two bodies only).
    contact_hz, contact_zeta : float
        Natural frequency (Hz) and damping ratio of the contact once the gap is closed.
    cogging, cogging_period, cogging_phase : float
        Cogging force amplitude (N), period (m) and phase (rad), in the motor position.
    friction_ramp : float
        Change of the friction level across ``stroke`` (a fraction: 0.5 is +-25 % at the
        ends), about ``center``.
    friction_wave, friction_wave_period, friction_wave_phase : float
        Sinusoidal variation of the friction level along the stroke: amplitude (fraction),
        period (m), phase.
    center, stroke : float
        Centre and length of the stroke, m.
    thermal_growth, thermal_tau, heating_speed : float
        Thermal growth of the logged position at ``theta = 1`` (m), its time constant (s) and
        the motor speed that heats to ``theta = 1`` (m/s).
    """

    mass: float
    damping: float
    coulomb: float
    breakaway: float
    stribeck_velocity: float = 1e-3
    stribeck_shape: float = 2.0
    backlash: float = 0.0
    motor_share: float = 0.5
    contact_hz: float = 600.0
    contact_zeta: float = 0.3
    cogging: float = 0.0
    cogging_period: float = 1e-3
    cogging_phase: float = 0.0
    friction_ramp: float = 0.0
    friction_wave: float = 0.0
    friction_wave_period: float = 0.02
    friction_wave_phase: float = 0.0
    center: float = 0.0
    stroke: float = _REF_STROKE
    thermal_growth: float = 0.0
    thermal_tau: float = 10.0
    heating_speed: float = 0.01

    def friction_level(self, x: np.ndarray | float) -> np.ndarray | float:
        """Friction level along the stroke, relative to the nominal one (at least 0.1)."""
        lvl = (1.0 + self.friction_ramp * (x - self.center) / self.stroke
               + self.friction_wave * np.sin(2 * np.pi * x / self.friction_wave_period
                                             + self.friction_wave_phase))
        return np.maximum(lvl, 0.1)

    def without_friction(self) -> Plant:
        """The same plant with no friction (Coulomb, Stribeck, stroke variation) at all."""
        return replace(self, coulomb=0.0, breakaway=0.0, friction_ramp=0.0, friction_wave=0.0)


@dataclass(frozen=True)
class Controller:
    """The drive's control law and power stage.

    Attributes
    ----------
    law : str
        ``"cascade"`` or ``"pid"``.
    kt : float
        Force per unit command, N/A (1: the command is the force).
    kp, kv, ti, kvff, kaff, vel_pole : float
        Cascade: position gain (1/s), velocity gain (A s/m), integral time (s; inf: no
        integral), velocity feedforward fraction, acceleration feedforward (A s^2/m) and the
        pole of the first-order velocity filter (0: no filter; ``vf = p vf + (1 - p) v``).
    p, i, d, tf, ff1, ff2 : float
        PID: proportional (A/m), integral (A/(m s)), derivative (A s/m) gains, derivative
        filter time constant (s), velocity (A s/m) and acceleration (A s^2/m) feedforward.
    limit : float
        Clip level of the command, A (inf: none).
    delay : int
        Transport delay from command to force, loop periods.
    """

    law: str
    kt: float = 1.0
    kp: float = 0.0
    kv: float = 0.0
    ti: float = math.inf
    kvff: float = 0.0
    kaff: float = 0.0
    vel_pole: float = 0.0
    p: float = 0.0
    i: float = 0.0
    d: float = 0.0
    tf: float = 0.0
    ff1: float = 0.0
    ff2: float = 0.0
    limit: float = math.inf
    delay: int = 0

    def __post_init__(self) -> None:
        if self.law not in ("cascade", "pid"):
            raise ValueError(f"law={self.law!r}: expected 'cascade' or 'pid'")
        if self.delay < 0:
            raise ValueError(f"delay={self.delay}: expected >= 0 loop periods")


@dataclass(frozen=True)
class Sensor:
    """Position sensors (motor encoder and table scale alike).

    Attributes
    ----------
    quantum : float
        Encoder step, m (0: none).
    noise : float
        Standard deviation of the white noise before quantisation, m.
    """

    quantum: float = 0.0
    noise: float = 0.0


@dataclass(frozen=True)
class Variant:
    """How a case is controlled, logged and exported (drawn once per kind and seed).

    Attributes
    ----------
    law : str
        ``"cascade"`` or ``"pid"``.
    saturate : bool
        Whether the command is clipped at a current limit the run reaches.
    delay : int
        Transport delay, loop periods (0..3).
    vel_filter : bool
        A first-order filter on the cascade's velocity feedback.
    feedforward : bool
        Velocity and acceleration feedforward (cascade) or FF1/FF2 (PID).
    unit : str
        Position unit of the log: ``m``, ``mm``, ``um``, ``rad`` or ``deg``.
    log_every : int
        1 (a 1 kHz log) or 10 (100 Hz).
    effort : str or None
        The logged effort's unit (``"A"``, ``"N"``, ``"%"``), None when it is not logged.
    rounded : bool
        A coarse sensor and positions written with few decimals.
    time_column : bool
        Whether the file has a time column (else ``--sample-time``).
    sep : str
        ``","`` or ``";"``.
    header : str
        ``"names"`` (such as ``t,ref,pos,cmd``) or ``"channels"`` (``Channel 1..4``).
    """

    law: str = "cascade"
    saturate: bool = False
    delay: int = 0
    vel_filter: bool = False
    feedforward: bool = True
    unit: str = "m"
    log_every: int = 1
    effort: str | None = None  # None (not logged), "A", "N" or "%"
    rounded: bool = False
    time_column: bool = True
    sep: str = ","
    header: str = "names"  # "names" or "channels"

    @property
    def rotary(self) -> bool:
        """Whether the axis is rotary (positions in rad or deg)."""
        return self.unit in ("rad", "deg")

    def label(self) -> str:
        """A short description for tables."""
        parts = [self.law + (f"+d{self.delay}" if self.delay else "")
                 + ("+sat" if self.saturate else "") + ("+vf" if self.vel_filter else ""),
                 self.unit + ("~" if self.rounded else ""),
                 "100Hz" if self.log_every == 10 else "1kHz",
                 f"u[{self.effort}]" if self.effort else "no-u",
                 ("t" if self.time_column else "no-t") + self.sep
                 + ("ch" if self.header == "channels" else "")]
        return " ".join(parts)


# -- integrator ------------------------------------------------------------------------------
def _exact(x: float, v: float, f: float, m: float, b: float, h: float) -> tuple[float, float]:
    """State after ``h`` of ``m dv/dt = f - b v`` with ``f`` constant (exact solution)."""
    if b > 0.0:
        tau = m / b
        em1 = -math.expm1(-h / tau)  # 1 - exp(-h/tau), precise for h << tau
        vinf = f / b
        return x + vinf * h + (v - vinf) * tau * em1, v + (vinf - v) * em1
    a = f / m
    return x + v * h + 0.5 * a * h * h, v + a * h


def _stop(x: float, v: float, f: float, m: float, b: float) -> tuple[float, float]:
    """Time and position at which ``m dv/dt = f - b v`` (f opposing v) brings v to zero."""
    if b > 0.0:
        tau = m / b
        vinf = f / b
        t = tau * math.log1p(-v / vinf)
        return t, x + vinf * t + tau * v
    t = -v * m / f
    return t, x + 0.5 * v * t


def _advance(x: float, v: float, f: float, m: float, b: float, fc: float, fs: float,
             vs: float, shape: float, h: float) -> tuple[float, float]:
    """One substep of a body with viscous damping ``b`` and stick/slip friction.

    ``f`` is every other force on the body (held over the substep); ``fc``, ``fs`` the Coulomb
    and breakaway levels. A body at rest stays there while ``|f| <= fs``; a sliding body
    whose friction would reverse it is stopped at the zero crossing instead (no chatter).
    """
    if fs <= 0.0:
        return _exact(x, v, f, m, b, h)
    if v == 0.0:
        if abs(f) <= fs:
            return x, 0.0
        s = 1.0 if f > 0.0 else -1.0
        ff = s * fs  # breakaway: the friction at zero speed
    else:
        s = 1.0 if v > 0.0 else -1.0
        if fs > fc:
            ff = s * (fc + (fs - fc) * math.exp(-((abs(v) / vs) ** shape)))
        else:
            ff = s * fc
    x1, v1 = _exact(x, v, f - ff, m, b, h)
    if v1 * s >= 0.0:
        return x1, v1
    # the velocity crosses zero within the substep: stop there
    t_stop, x_stop = _stop(x, v, f - ff, m, b)
    if abs(f) <= fs:
        return x_stop, 0.0
    # pushed on through zero: slide the other way, from rest, for the rest of the substep
    return _exact(x_stop, 0.0, f + s * fs, m, b, h - t_stop)


# -- the loop --------------------------------------------------------------------------------
@dataclass
class Trace:
    """One simulated run at the loop rate (1 kHz), SI units.

    Attributes
    ----------
    t, x_ref : ndarray
        Time (s) and reference position.
    x_motor, x_table : ndarray
        True motor and table positions at the samples.
    y_feedback, y_log : ndarray
        Motor encoder reading the drive used, and the logged table position (thermal growth,
        noise and quantisation included).
    command : ndarray
        The clipped command (A; N when ``kt`` is 1): what the drive logs as its effort.
    force : ndarray
        The force applied from each sample to the next (after the delay).
    drift : ndarray
        Thermal growth included in ``y_log``.
    clipped : ndarray of bool
        Samples whose command was clipped.
    """

    t: np.ndarray
    x_ref: np.ndarray
    x_motor: np.ndarray
    x_table: np.ndarray
    y_feedback: np.ndarray
    y_log: np.ndarray
    command: np.ndarray
    force: np.ndarray
    drift: np.ndarray
    clipped: np.ndarray


def _quantise(y: float, q: float) -> float:
    return q * round(y / q) if q > 0.0 else y


def simulate(plant: Plant, ctrl: Controller, sensor: Sensor, x_ref: np.ndarray, *,
             seed: int | np.random.SeedSequence | None = 0, clean: bool = False,
             substeps: int = SUBSTEPS, x0: float = 0.0, v0: float = 0.0,
             drive: bool = True) -> Trace:
    """Run the loop on the reference ``x_ref`` (sampled at :data:`LOOP_TS`).

    Parameters
    ----------
    plant, ctrl, sensor : Plant, Controller, Sensor
    x_ref : ndarray
        Reference position at each loop sample, m.
    seed : int or SeedSequence, optional
        Seed of the sensor noise.
    clean : bool
        No noise and no quantisation (the run a perfect sensor would give).
    substeps : int
        Integration substeps per loop period.
    x0, v0 : float
        Initial position and velocity of motor and table (they start in the middle of the
        gap, at rest by default).
    drive : bool
        False: the controller's command is computed and logged but no force is applied (for
        free-motion checks of the mechanics).

    Returns
    -------
    Trace
    """
    ts = LOOP_TS
    h = ts / substeps
    xr = np.asarray(x_ref, dtype=float)
    n = xr.shape[0]
    if clean or sensor.noise <= 0.0:
        n_fb = n_log = np.zeros(n)
    else:
        rng = np.random.default_rng(seed)
        n_fb = rng.standard_normal(n) * sensor.noise
        n_log = rng.standard_normal(n) * sensor.noise
    q = 0.0 if clean else sensor.quantum
    # mechanics, as local floats (the inner loop is plain Python)
    two_body = plant.backlash > 0.0
    m_tot, b_tot = plant.mass, plant.damping
    if two_body:
        m_m, m_t = plant.motor_share * m_tot, (1.0 - plant.motor_share) * m_tot
        b_m, b_t = 0.2 * b_tot, 0.8 * b_tot
        mu = m_m * m_t / m_tot
        w_c = 2 * math.pi * plant.contact_hz
        k_c, c_c = mu * w_c**2, 2 * plant.contact_zeta * mu * w_c
        half_gap = 0.5 * plant.backlash
    else:
        m_m = m_t = m_tot
        b_m = b_t = b_tot
        k_c = c_c = half_gap = 0.0
    fc0, fs0 = plant.coulomb, max(plant.breakaway, plant.coulomb)
    vs, shape = plant.stribeck_velocity, plant.stribeck_shape
    varies = plant.friction_ramp != 0.0 or plant.friction_wave != 0.0
    fr_g = plant.friction_ramp / plant.stroke
    fr_c, fr_a = plant.center, plant.friction_wave
    fr_k, fr_p = 2 * math.pi / plant.friction_wave_period, plant.friction_wave_phase
    cog_a = plant.cogging
    cog_k = 2 * math.pi / plant.cogging_period
    cog_p = plant.cogging_phase
    th_g = plant.thermal_growth
    th_a = -math.expm1(-ts / plant.thermal_tau)
    th_v = plant.heating_speed
    # controller
    law = ctrl.law
    kt, lim = ctrl.kt, ctrl.limit
    ki_dt = ts / ctrl.ti if math.isfinite(ctrl.ti) else 0.0
    vp = ctrl.vel_pole
    d_a = ctrl.tf / (ctrl.tf + ts)
    d_b = ctrl.d / (ctrl.tf + ts)
    delay = ctrl.delay
    pending = [0.0] * delay  # commands on their way to the power stage
    integ = vf = dterm = 0.0
    xr_prev = xr[0]
    vr_prev = 0.0
    xm = xt = x0
    vm = vt = v0
    theta = 0.0
    y_prev = _quantise(xm + n_fb[0], q)
    e_prev = xr[0] - y_prev
    out = np.empty((9, n))
    for k in range(n):
        # -- sample
        drift = th_g * theta
        y_fb = _quantise(xm + n_fb[k], q)
        y_log = _quantise(xt + drift + n_log[k], q)
        # -- control law
        r = xr[k]
        vr = (r - xr_prev) / ts
        ar = (vr - vr_prev) / ts
        if law == "cascade":
            vmeas = (y_fb - y_prev) / ts
            vf = vp * vf + (1.0 - vp) * vmeas
            err = ctrl.kp * (r - y_fb) + ctrl.kvff * vr - vf
            raw = ctrl.kv * (err + integ) + ctrl.kaff * ar
        else:
            err = r - y_fb
            dterm = d_a * dterm + d_b * (err - e_prev)
            raw = ctrl.p * err + integ + dterm + ctrl.ff1 * vr + ctrl.ff2 * ar
            e_prev = err
        cmd = min(max(raw, -lim), lim)
        # conditional integration: hold the integral while clipped in its own direction
        if cmd == raw or (raw > 0.0) != (err > 0.0):
            integ += ki_dt * err if law == "cascade" else ctrl.i * ts * err
        y_prev = y_fb
        xr_prev, vr_prev = r, vr
        if delay:
            pending.append(cmd)
            force = kt * pending.pop(0)
        else:
            force = kt * cmd
        if not drive:
            force = 0.0
        out[0, k], out[1, k], out[2, k], out[3, k] = xm, xt, y_fb, y_log
        out[4, k], out[5, k], out[6, k], out[7, k] = cmd, force, drift, float(cmd != raw)
        # -- mechanics over one loop period
        xm_start = xm
        for _ in range(substeps):
            f_m = force
            if cog_a != 0.0:
                f_m += cog_a * math.sin(cog_k * xm + cog_p)
            if two_body:
                gap = xm - xt
                if gap > half_gap:
                    fk = k_c * (gap - half_gap) + c_c * (vm - vt)
                    fk = max(fk, 0.0)  # a contact only pushes
                elif gap < -half_gap:
                    fk = k_c * (gap + half_gap) + c_c * (vm - vt)
                    fk = min(fk, 0.0)
                else:
                    fk = 0.0
                lvl = (max(1.0 + fr_g * (xt - fr_c) + fr_a * math.sin(fr_k * xt + fr_p), 0.1)
                       if varies else 1.0)
                xm, vm = _exact(xm, vm, f_m - fk, m_m, b_m, h)
                xt, vt = _advance(xt, vt, fk, m_t, b_t, fc0 * lvl, fs0 * lvl, vs, shape, h)
            else:
                lvl = (max(1.0 + fr_g * (xm - fr_c) + fr_a * math.sin(fr_k * xm + fr_p), 0.1)
                       if varies else 1.0)
                xm, vm = _advance(xm, vm, f_m, m_m, b_m, fc0 * lvl, fs0 * lvl, vs, shape, h)
                xt, vt = xm, vm
        # heating by the motor's mean speed over the period
        theta += th_a * (abs(xm - xm_start) / (ts * th_v) - theta)
    t = np.arange(n) * ts
    return Trace(t=t, x_ref=xr.copy(), x_motor=out[0].copy(), x_table=out[1].copy(),
                 y_feedback=out[2].copy(), y_log=out[3].copy(), command=out[4].copy(),
                 force=out[5].copy(), drift=out[6].copy(), clipped=out[7] > 0.5)


# -- linear analysis (choosing stable gains) -------------------------------------------------
def loop_poles(mass: float, damping: float, ctrl: Controller) -> np.ndarray:
    """Poles (z plane) of the loop of ``ctrl`` around a rigid frictionless mass.

    The state is ``[x, v, c1, c2, c3, pending commands...]`` (controller states: the
    integral, the previous reading, the velocity filter or derivative state); the plant is
    its exact zero-order-hold discretisation. Used to draw gains whose loop is stable and
    damped, also when only the motor's inertia is driven (inside a backlash gap).
    """
    ts = LOOP_TS
    d = ctrl.delay
    n = 5 + d
    eye = np.eye(n)
    x, v, c1, c2, c3 = (eye[i] for i in range(5))
    if damping > 0.0:
        tau = mass / damping
        em1 = -math.expm1(-ts / tau)
        a_xv, a_vv = tau * em1, 1.0 - em1
        b_x, b_v = (ts - tau * em1) / damping, em1 / damping
    else:
        a_xv, a_vv = ts, 1.0
        b_x, b_v = ts * ts / (2 * mass), ts / mass
    rows = np.zeros((n, n))
    if ctrl.law == "cascade":
        ki_dt = ts / ctrl.ti if math.isfinite(ctrl.ti) else 0.0
        vf = ctrl.vel_pole * c3 + (1 - ctrl.vel_pole) * (x - c2) / ts
        err = -ctrl.kp * x - vf
        cmd = ctrl.kv * (err + c1)
        rows[2], rows[3], rows[4] = c1 + ki_dt * err, x, vf
    else:
        err = -x
        dterm = ctrl.tf / (ctrl.tf + ts) * c3 + ctrl.d / (ctrl.tf + ts) * (err - c2)
        cmd = ctrl.p * err + c1 + dterm
        rows[2], rows[3], rows[4] = c1 + ctrl.i * ts * err, err, dterm
    force = ctrl.kt * (eye[5] if d else cmd)
    for j in range(d):
        rows[5 + j] = eye[6 + j] if j + 1 < d else cmd
    rows[0] = x + a_xv * v + b_x * force
    rows[1] = a_vv * v + b_v * force
    return np.linalg.eigvals(rows)


def _damped(poles: np.ndarray, zeta_min: float = 0.2, radius_max: float = 0.9995) -> bool:
    """Whether every pole is inside ``radius_max`` and, unless very fast, damped by at least
    ``zeta_min``."""
    if np.max(np.abs(poles)) >= radius_max:
        return False
    for z in poles:
        if abs(z) < 0.05:
            continue
        s = np.log(complex(z)) / LOOP_TS
        if abs(s.imag) > 1e-9 and -s.real / abs(s) < zeta_min:
            return False
    return True


# -- reference -------------------------------------------------------------------------------
def _smoothstep(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def random_reference(rng: np.random.Generator, duration: float, stroke: float,
                     ts: float = LOOP_TS) -> np.ndarray:
    """A reference within ``+-stroke / 2``, starting at rest at 0.

    Pieces: minimum-jerk point-to-point moves, traverses at constant feed with smooth
    acceleration ramps, sine blocks faded in and out over a cycle, dwells; feeds from 7 %
    to 150 % of the stroke per second.
    """
    lim = 0.5 * stroke
    n = int(round(duration / ts))
    pieces = [np.zeros(int(rng.uniform(0.2, 0.5) / ts))]
    x = 0.0
    count = pieces[0].shape[0]
    while count < n:
        kind = rng.choice(["move", "move", "traverse", "sine", "dwell"])
        feed = stroke * math.exp(rng.uniform(math.log(0.07), math.log(1.5)))
        if kind in ("move", "traverse"):
            target = rng.uniform(-lim, lim)
            dist = target - x
            if abs(dist) < 0.02 * stroke:
                continue
            if kind == "move":
                m = max(int(1.875 * abs(dist) / feed / ts), 50)
                tau = np.arange(1, m + 1) / m
                seg = x + dist * tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
            else:
                t_acc = rng.uniform(0.05, 0.3)
                t_cruise = max(abs(dist) / feed - t_acc, 0.02)
                m_acc, m_cr = max(int(t_acc / ts), 2), max(int(t_cruise / ts), 1)
                ramp = _smoothstep(np.arange(1, m_acc + 1) / m_acc)
                vel = np.concatenate([ramp, np.ones(m_cr), ramp[::-1]])
                pos = np.cumsum(vel)
                seg = x + dist * pos / pos[-1]
            x = target
        elif kind == "sine":
            f = math.exp(rng.uniform(math.log(0.3), math.log(3.0)))
            amp = min(math.exp(rng.uniform(math.log(0.005 * stroke), math.log(lim / 2))),
                      feed / (2 * math.pi * f), lim - abs(x))
            cycles = int(rng.integers(2, 6))
            m = int(cycles / f / ts)
            tt = np.arange(1, m + 1) * ts
            env = _smoothstep(np.minimum(tt, tt[-1] - tt) * f)
            seg = x + amp * env * np.sin(2 * math.pi * f * tt)
        else:
            seg = np.full(int(rng.uniform(0.05, 0.6) / ts), x)
        pieces.append(seg)
        pieces.append(np.full(int(rng.uniform(0.0, 0.3) / ts), x))
        count += seg.shape[0] + pieces[-1].shape[0]
    # cut at the requested length, in the middle of a piece if so: loggers stop anywhere
    return np.concatenate(pieces)[:n]


# -- cases -----------------------------------------------------------------------------------
def draw_variant(rng: np.random.Generator) -> Variant:
    """A random controller, unit, logging and export layout."""
    law = "cascade" if rng.random() < 0.6 else "pid"
    rotary = rng.random() < 0.35
    unit = str(rng.choice(["rad", "deg"])) if rotary else str(rng.choice(["m", "mm", "um"]))
    effort = [None, "N", "A", "%"][int(rng.choice(4, p=[0.4, 0.2, 0.25, 0.15]))]
    return Variant(
        law=law,
        saturate=bool(rng.random() < 0.4),
        delay=int(rng.integers(1, 4)) if rng.random() < 0.5 else 0,
        vel_filter=law == "cascade" and bool(rng.random() < 0.3),
        feedforward=bool(rng.random() < (0.8 if law == "cascade" else 0.5)),
        unit=unit,
        log_every=10 if rng.random() < 0.3 else 1,
        effort=effort,
        rounded=bool(rng.random() < 0.25),
        time_column=bool(rng.random() < 0.6),
        sep=";" if rng.random() < 0.3 else ",",
        header="channels" if rng.random() < 0.4 else "names",
    )


def _count_jump(ctrl: Controller, quantum: float) -> float:
    """Force step one encoder count makes through the controller's derivative action."""
    if ctrl.law == "cascade":
        return ctrl.kt * ctrl.kv * ((1.0 - ctrl.vel_pole) / LOOP_TS + ctrl.kp) * quantum
    return ctrl.kt * (ctrl.p + ctrl.d / (ctrl.tf + LOOP_TS)) * quantum


def _design(rng: np.random.Generator, var: Variant, plant: Plant, kt: float,
            quantum: float, noise: float) -> Controller:
    """Gains for ``var``'s law on ``plant``: drawn, then lowered until the loop is stable and
    damped (with the whole mass, and with the motor's alone when there is a gap) and one
    encoder count (or twice the noise) moves the force by less than 30 % of the Coulomb
    friction (a drive tuned on a coarse encoder must be; otherwise it hunts between counts at
    its current limit)."""
    mass, damping = plant.mass, plant.damping
    delay = var.delay
    if var.law == "cascade":
        wv = rng.uniform(150.0, 400.0) / (1.0 + 0.6 * delay)
        kp_rel, ti_rel = rng.uniform(0.2, 0.4), rng.uniform(4.0, 10.0)
        kvff = rng.uniform(0.85, 1.0) if var.feedforward else 0.0
        kaff = rng.uniform(0.6, 1.0) * mass / kt if var.feedforward else 0.0
        pole = math.exp(-2 * math.pi * rng.uniform(150.0, 400.0) * LOOP_TS) \
            if var.vel_filter else 0.0
    else:
        w = rng.uniform(25.0, 70.0) / (1.0 + 0.3 * delay)
        kd_rel, ki_rel, n_filt = rng.uniform(0.8, 1.2), rng.uniform(0.5, 1.0), rng.uniform(5, 12)
        ff1 = rng.uniform(0.8, 1.0) * damping / kt if var.feedforward else 0.0
        ff2 = rng.uniform(0.7, 1.0) * mass / kt if var.feedforward else 0.0
    for _ in range(30):
        if var.law == "cascade":
            ctrl = Controller("cascade", kt=kt, kp=kp_rel * wv, kv=wv * mass / kt,
                              ti=ti_rel / wv, kvff=kvff, kaff=kaff, vel_pole=pole, delay=delay)
        else:
            ctrl = Controller("pid", kt=kt, p=3 * mass * w**2 / kt,
                              i=ki_rel * mass * w**3 / kt, d=kd_rel * 3 * mass * w / kt,
                              tf=max(1.0 / (n_filt * w), LOOP_TS), ff1=ff1, ff2=ff2,
                              delay=delay)
        ok = (_damped(loop_poles(mass, damping, ctrl))
              and _count_jump(ctrl, max(quantum, 2.0 * noise)) <= 0.3 * plant.coulomb)
        if ok and plant.backlash > 0.0:
            ok = _damped(loop_poles(plant.motor_share * mass, 0.2 * damping, ctrl),
                         zeta_min=0.1)
        if ok:
            return ctrl
        if var.law == "cascade":
            wv *= 0.85
        else:
            w *= 0.85
    raise RuntimeError(f"no stable gains for {var}")


def _base(rng: np.random.Generator, var: Variant) -> tuple[Plant, Sensor, float]:
    """Mechanics with Coulomb and viscous friction, the sensor and the force constant."""
    if var.rotary:
        stroke, mass, kt = rng.uniform(2.0, 6.0), rng.uniform(0.005, 0.05), rng.uniform(0.2, 2.0)
    else:
        stroke, mass, kt = rng.uniform(0.02, 0.05), rng.uniform(100.0, 600.0), \
            rng.uniform(50.0, 600.0)
    scale = stroke / _REF_STROKE
    fc = mass * rng.uniform(0.3, 1.0) * scale
    plant = Plant(mass=mass, damping=mass * rng.uniform(0.2, 1.5), coulomb=fc, breakaway=fc,
                  stroke=stroke)
    if var.rounded:
        # a coarse sensor whose step is not a round number in the log's unit
        q = (2 * math.pi / rng.integers(5000, 50000) if var.rotary
             else stroke * rng.uniform(1e-5, 1e-4))
        noise = q * rng.uniform(0.05, 0.3)
    else:
        q = (2 * math.pi / 2 ** int(rng.integers(18, 22)) if var.rotary
             else float(rng.choice([10e-9, 20e-9, 50e-9, 100e-9])))
        noise = q * rng.uniform(0.3, 1.5)
    return plant, Sensor(quantum=float(q), noise=float(noise)), float(kt)


def _add_effect(rng: np.random.Generator, kind: str, plant: Plant) -> Plant:
    """``plant`` with one effect of ``kind`` drawn at random."""
    scale = plant.stroke / _REF_STROKE
    fc = plant.coulomb
    if kind == "backlash":
        return replace(plant, backlash=rng.uniform(3e-6, 15e-6) * scale,
                       motor_share=rng.uniform(0.3, 0.6), contact_hz=rng.uniform(400, 800),
                       contact_zeta=rng.uniform(0.2, 0.4))
    if kind == "cogging":
        return replace(plant, cogging=rng.uniform(0.2, 0.8) * fc,
                       cogging_period=rng.uniform(2e-3, 8e-3) * scale,
                       cogging_phase=rng.uniform(0, 2 * math.pi))
    if kind == "thermal":
        return replace(plant, thermal_growth=rng.choice([-1.0, 1.0])
                       * rng.uniform(4e-6, 15e-6) * scale, thermal_tau=rng.uniform(3.0, 15.0))
    if kind == "posdep":
        shape = rng.choice(["ramp", "wave", "both"])
        ramp = rng.choice([-1.0, 1.0]) * rng.uniform(0.3, 0.8) if shape != "wave" else 0.0
        wave = rng.uniform(0.3, 0.8) if shape != "ramp" else 0.0
        if shape == "both":
            ramp, wave = 0.6 * ramp, 0.6 * wave
        return replace(plant, friction_ramp=ramp, friction_wave=wave,
                       friction_wave_period=rng.uniform(0.4, 1.0) * plant.stroke,
                       friction_wave_phase=rng.uniform(0, 2 * math.pi))
    if kind == "stribeck":
        return replace(plant, breakaway=fc * rng.uniform(1.2, 1.8),
                       stribeck_velocity=rng.uniform(1e-3, 4e-3) * scale,
                       stribeck_shape=2.0 if rng.random() < 0.7 else 1.0)
    if kind == "control":
        return plant
    raise ValueError(f"kind={kind!r}: expected one of {KINDS}")


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(e))))


@dataclass
class Case:
    """One drawn run and its truth.

    Attributes
    ----------
    kind, seed : str, int
    variant : Variant
    plant, ctrl, sensor : Plant, Controller, Sensor
        The axis (``plant`` with the effect).
    origin : float
        Axis coordinate of the stroke's centre, m or rad (logs rarely start at 0).
    trace, clean : Trace
        The logged run, and the same run with a perfect sensor.
    floor : float
        Noise floor of a free-run prediction: rms of the exported position minus the clean
        run's, at the logged samples, SI.
    signature : float or None
        Rms of the effect in the clean logged position (None for a control), SI.
    decimals : int or None
        Decimals of the positions in a rounded export.
    attempts : int
        Draws it took to make the effect visible.
    names : tuple of str
        Header names of time, reference, position, effort and the extra column.
    extra_column : bool
        Whether the file also holds the following error (a column to be ignored).
    """

    kind: str
    seed: int
    variant: Variant
    plant: Plant
    ctrl: Controller
    sensor: Sensor
    origin: float
    trace: Trace = field(repr=False)
    clean: Trace = field(repr=False)
    floor: float = 0.0
    signature: float | None = None
    decimals: int | None = None
    attempts: int = 1
    names: tuple[str, ...] = ()
    extra_column: bool = False

    @property
    def index(self) -> np.ndarray:
        """Loop samples that are logged."""
        return np.arange(0, self.trace.t.shape[0], self.variant.log_every)

    @property
    def log_ts(self) -> float:
        """Sample time of the log, s."""
        return LOOP_TS * self.variant.log_every

    def logged(self) -> dict[str, np.ndarray | None]:
        """The columns as exported: time (s), reference and position (in the log's unit,
        rounded in a rounded export) and the effort (in its unit, or None)."""
        idx = self.index
        k = UNIT_PER_SI[self.variant.unit]
        ref = self.trace.x_ref[idx] * k
        pos = self.trace.y_log[idx] * k
        if self.decimals is not None:
            ref, pos = np.round(ref, self.decimals), np.round(pos, self.decimals)
        cmd = self.trace.command[idx]
        eff = self.variant.effort
        if eff is None:
            effort = None
        elif eff == "N":
            effort = cmd * self.ctrl.kt
        elif eff == "A":
            effort = cmd.copy()
        else:
            effort = 100.0 * cmd / self._percent_base
        return {"t": self.trace.t[idx], "ref": ref, "pos": pos, "effort": effort}

    @property
    def _percent_base(self) -> float:
        lim = self.ctrl.limit
        return lim if math.isfinite(lim) else 1.25 * float(np.max(np.abs(self.trace.command)))

    def truth(self) -> dict[str, object]:
        """What a right diagnosis of this case says, and how the case was made."""
        effect = EFFECT_NAME[self.kind]
        unit = self.variant.unit
        return {
            "kind": self.kind, "seed": self.seed, "effect": effect,
            "allowed": sorted(FRICTION_NAMES | ({effect} if effect else set())),
            "floor_si": self.floor, "floor_logged": self.floor * UNIT_PER_SI[unit],
            "signature_si": self.signature,
            "position_unit": unit, "position_unit_si": "rad" if self.variant.rotary else "m",
            "variant": self.variant.label(), "log_ts_s": self.log_ts,
            "samples": int(self.index.shape[0]),
            "clipped_share": float(np.mean(self.trace.clipped)),
            "quantum_si": self.sensor.quantum, "noise_si": self.sensor.noise,
            "decimals": self.decimals, "attempts": self.attempts,
        }


def draw_case(kind: str, seed: int, *, duration: float | None = None,
              **overrides: object) -> Case:
    """Draw and simulate one case.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    seed : int
        Seed of everything (variant, parameters, reference, noise).
    duration : float, optional
        Run length, s (default: drawn in 8..16 s).
    **overrides
        Fields of :class:`Variant` to set instead of drawing them (``unit="deg"``, ...).

    Returns
    -------
    Case
        With the effect visible: its clean signature at least twice the noise floor.
    """
    if kind not in KINDS:
        raise ValueError(f"kind={kind!r}: expected one of {KINDS}")
    kid = KINDS.index(kind)
    vrng = np.random.default_rng([seed, kid, 0])
    var = replace(draw_variant(vrng), **overrides)  # type: ignore[arg-type]
    if var.law != "cascade":
        var = replace(var, vel_filter=False)
    dur = float(duration if duration is not None else vrng.uniform(8.0, 16.0))
    layout = _layout(vrng, var)
    for attempt in range(10):
        rng = np.random.default_rng([seed, kid, 1 + attempt])
        base, sensor, kt = _base(rng, var)
        origin = rng.uniform(-1.0, 1.0) * base.stroke
        base = replace(base, center=origin)
        xr = origin + random_reference(rng, dur, base.stroke)
        v_ref = np.abs(np.diff(xr)) / LOOP_TS
        base = replace(base, heating_speed=max(float(np.mean(v_ref)), 1e-3 * base.stroke))
        for tries in range(5):
            plant = _add_effect(rng, kind, base)
            ctrl = _design(rng, var, plant, kt, sensor.quantum, sensor.noise)
            if var.saturate:
                free = simulate(plant, ctrl, sensor, xr, x0=origin, clean=True)
                ctrl = replace(ctrl, limit=_clip_level(rng, plant, free.command, kt))
            noise_seed = np.random.SeedSequence([seed, kid, 99, attempt])
            clean = simulate(plant, ctrl, sensor, xr, x0=origin, clean=True)
            case = Case(kind, seed, var, plant, ctrl, sensor, origin, trace=clean, clean=clean,
                        attempts=attempt * 5 + tries + 1, names=layout[0],
                        extra_column=layout[1])
            if var.rounded:
                q_log = sensor.quantum * UNIT_PER_SI[var.unit]
                case.decimals = max(0, math.ceil(math.log10(10.0 / q_log)))
            if kind != "control":
                # the same gains on the axis without the effect: the signature is the
                # effect's alone
                ref_clean = simulate(_without_effect(kind, base, plant, clean), ctrl, sensor,
                                     xr, x0=origin, clean=True)
                case.signature = _rms((clean.y_log - ref_clean.y_log)[case.index])
            case.trace = simulate(plant, ctrl, sensor, xr, x0=origin, seed=noise_seed)
            pos_si = case.logged()["pos"] / UNIT_PER_SI[var.unit]  # type: ignore[operator]
            case.floor = _rms(pos_si - clean.y_log[case.index])
            if case.signature is None or (case.signature >= 2.0 * case.floor
                                          and _periodic_in_travel(kind, plant, clean)):
                return case
    raise RuntimeError(f"{kind} seed {seed}: no visible effect in 50 draws")


def _without_effect(kind: str, base: Plant, plant: Plant, clean: Trace) -> Plant:
    """The axis a case is compared with to measure its effect's signature.

    For friction that varies along the stroke it is the axis with the *mean* level over the
    positions the run slides through: a run that spans a small part of the stroke sees a
    nearly constant level, which is Coulomb friction of another size, not a position
    dependence, and must not count as a visible one."""
    if kind != "posdep":
        return base
    mean = float(np.mean(plant.friction_level(_sliding_positions(clean))))
    return replace(base, coulomb=base.coulomb * mean, breakaway=base.breakaway * mean)


def _periodic_in_travel(kind: str, plant: Plant, clean: Trace) -> bool:
    """Whether a periodic effect completes a period within the range the run slides through.

    A cogging whose period is longer than the travel is, over that travel, a friction level
    changing along the stroke, not a periodic term: the issue's rule rejects such a period as
    a fit artefact, so such a draw does not count as a visible cogging (as a friction level
    seen over a small part of its variation does not count as a position dependence)."""
    if kind != "cogging":
        return True
    x = _sliding_positions(clean)
    return float(np.max(x) - np.min(x)) >= plant.cogging_period


def _sliding_positions(clean: Trace) -> np.ndarray:
    """The table positions a noiseless run passes while moving (all of them if it never
    moves)."""
    moving = np.abs(np.gradient(clean.x_table)) > 0.0
    return clean.x_table[moving] if np.any(moving) else clean.x_table


def _clip_level(rng: np.random.Generator, plant: Plant, command: np.ndarray,
                kt: float) -> float:
    """A command limit that the run without one exceeds on 0.5..2 % of its samples (its
    hardest moves), but at least 1.3 times the largest static force (breakaway at the highest
    friction level along the stroke, plus cogging), which the drive must always overcome."""
    static = (max(plant.breakaway, plant.coulomb) * max(1.0 + 0.5 * abs(plant.friction_ramp)
                                                        + abs(plant.friction_wave), 1.0)
              + abs(plant.cogging)) / kt
    return max(float(np.quantile(np.abs(command), 1.0 - rng.uniform(0.005, 0.02))),
               1.3 * static)


_NAME_SETS = (("t", "ref", "pos", "cmd", "ferr"), ("time", "x_cmd", "x_act", "i_cmd", "lag"),
              ("Time [s]", "Reference", "Position", "Effort", "Following error"))


def _layout(rng: np.random.Generator, var: Variant) -> tuple[tuple[str, ...], bool]:
    """Header names (time, reference, position, effort, extra) and whether an extra
    column (the following error) is written."""
    if var.header == "channels":
        return ("Time", "Channel 1", "Channel 2", "Channel 3", "Channel 4"), True
    return _NAME_SETS[int(rng.integers(len(_NAME_SETS)))], bool(rng.random() < 0.5)


def _columns(case: Case) -> list[tuple[str, np.ndarray, str]]:
    """(header, values, format) of each exported column, in file order."""
    var = case.variant
    cols = case.logged()
    names = list(case.names)
    if var.header == "channels":
        # channels are numbered over the data columns only
        data_names = [f"Channel {i}" for i in range(1, 5)]
        names = [names[0]] + data_names
    pos_fmt = f".{case.decimals}f" if case.decimals is not None else ".10g"
    out: list[tuple[str, np.ndarray, str]] = []
    if var.time_column:
        out.append((names[0], cols["t"], ".6f"))  # type: ignore[arg-type]
    out.append((names[1], cols["ref"], pos_fmt))  # type: ignore[arg-type]
    out.append((names[2], cols["pos"], pos_fmt))  # type: ignore[arg-type]
    data = [names[3], names[4]]
    if cols["effort"] is not None:
        out.append((data.pop(0), cols["effort"], ".6g"))  # type: ignore[arg-type]
    if case.extra_column:
        out.append((data.pop(0), cols["ref"] - cols["pos"], pos_fmt))  # type: ignore[operator]
    return out


def write_csv(case: Case, path: str | os.PathLike[str]) -> None:
    """Write ``case`` as a logger would: one header row, one row per logged sample.

    With or without a time column, ``,`` or ``;`` separated (numbers always with a decimal
    point), named columns or ``Channel 1..4``, positions in the variant's unit.
    """
    cols = _columns(case)
    sep = case.variant.sep
    lines = [sep.join(name for name, _, _ in cols)]
    fmts = [f"{{:{fmt}}}" for _, _, fmt in cols]
    arrays = [values for _, values, _ in cols]
    for i in range(arrays[0].shape[0]):
        lines.append(sep.join(f.format(a[i]) for f, a in zip(fmts, arrays)))
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("\n".join(lines) + "\n")


def cli_args(case: Case, csv_path: str | os.PathLike[str]) -> list[str]:
    """The ``fricbench diagnose`` arguments a user would give for ``case``'s CSV: its
    columns (by 0-based index for ``Channel`` headers, by name otherwise), the position
    unit, ``--sample-time`` when there is no time column, the effort's column and unit."""
    var = case.variant
    cols = _columns(case)
    names = [c[0] for c in cols]

    def col(i: int) -> str:
        return str(i) if var.header == "channels" else names[i]

    first = 1 if var.time_column else 0
    args = [os.fspath(csv_path), "--reference", col(first), "--position", col(first + 1),
            "--position-unit", var.unit]
    if var.time_column:
        args += ["--time", col(0)]
    else:
        args += ["--sample-time", f"{case.log_ts:g}"]
    if var.effort is not None:
        args += ["--effort", col(first + 2), "--effort-unit", var.effort]
    return args

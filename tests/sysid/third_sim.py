"""A third servo-axis simulator for the tests of ``fricbench diagnose``: machines it has not met.

Written apart from fricbench's axis kernel and from ``second_sim.py`` (nothing of either is
imported or copied): its own integrator, stick-slip, controllers, reference and input
generators, sensors and log layouts, in plain numpy and Python. Where the second simulator draws
variants of one servo axis, this one draws *machines*: a PWM-driven DC motor, a vertical axis,
a linear motor, a belt drive, a velocity-loop drive, an open-loop test bench, ... (:data:`KINDS`,
each with its family's friction-only control).

Integrator
----------
Each control period ``T`` (1 kHz or 2 kHz) is cut into :data:`SUBSTEPS` sub-steps ``h``. Every
body moves by semi-implicit (symplectic) Euler: the new velocity from the forces at the start
of the sub-step, the viscous term taken implicitly (``v' = (v + h (F - Ff) / m) / (1 + h b /
m)``), then the position from the new velocity. Two bodies (a belt, a backlash gap) are coupled
explicitly through the force of their link at the start of the sub-step.

Friction
--------
* Karnopp stick-slip: a body at rest stays at rest while the other forces on it are at most its
  breakaway force ``Fs``; it breaks away in the direction of the net force. A sliding body feels
  ``Fc + (Fs - Fc) exp(-(v / vs)^2)`` against its motion; a step in which that force would
  reverse the velocity ends at rest (no chatter).
* LuGre (the presliding machine): bristle state ``z``, ``dz/dt = v - sigma0 |v| z / g(v)``,
  ``F = sigma0 z + sigma1 dz/dt + sigma2 v``; within a sub-step ``v`` is frozen and ``z``
  relaxes exactly (exponentially) to ``g(v) sign(v) / sigma0``.
* The friction level may vary along the stroke (once per turn of a rotary table, and a tight
  spot): ``level(x) = 1 + a sin(2 pi x / P + phi) + c exp(-((x - x_c) / w)^2 / 2)``.

Drives and controllers
----------------------
* ``current``: a PID position loop (derivative on the measurement through a first-order filter
  ``Td / N``, back-calculation anti-windup, optional velocity and acceleration feedforward)
  commands a current; the current loop is a first-order lag. One or zero periods of delay.
* ``pwm``: the same PID commands a PWM duty in ``[-1, 1]``; the armature follows
  ``L di/dt = d V_bus - R i - k_e omega`` (exact within a sub-step), torque ``k_t i``.
* ``velocity``: an analog velocity-command drive: an outer P position loop with velocity
  feedforward in the controller, a PI velocity loop in the drive at the sub-step rate on the
  filtered difference of the motor encoder.
* ``open``: a designed current (pulses and slow triangles of alternating sign), no loop.

Sensors and logs
----------------
Encoders quantise; an analog sensor adds white noise and mains hum (50 or 60 Hz and its third
harmonic) and is read through a 16-bit ADC; the loop feeds back what the sensor gives. The log
holds the reference, the table's position (a linear scale, a rotary table in degrees, ...), the
effort in its unit (A, N, % duty) and, for the belt, the load's encoder beside the motor's. A PC
logger's rows are taken at jittered instants (up to +-10 % of its period) and written with those
timestamps, tab-separated.

Cases
-----
:func:`draw_case` draws a machine of a kind from a seed (every random choice from
``numpy.random.default_rng([seed, kind index, attempt])``), simulates it twice (with and
without the sensor's noise) and, for a kind with an effect, a third time without the effect: the
effect must show in the logged position by at least twice the noise floor, else the machine is
redrawn. :meth:`Case.csv_text` is the log as written, :meth:`Case.cli_args` what a user types,
:meth:`Case.truth` what a right diagnosis says (judged by ``third_sim_check.py``).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace

import numpy as np

__all__ = ["KINDS", "FAMILY", "SUBSTEPS", "FRICTION_NAMES", "AXIS_EFFECTS", "Machine", "Trace",
           "Case", "simulate", "draw_case", "minimum_jerk_reference", "open_loop_current"]

SUBSTEPS = 8
"""Integration sub-steps per control period."""

KINDS = ("pwm_motor", "pwm_control", "vertical", "lugre", "linear_motor", "warming_screw",
         "hum", "jitter", "rotary_table", "servo_control", "velocity_drive", "velocity_control",
         "belt", "belt_control", "open_loop", "open_loop_control")
"""Machine kinds: each family's machines with their trait, and the family's friction-only
control (``*_control``)."""

FAMILY = {"pwm_motor": "pwm", "pwm_control": "pwm", "vertical": "servo", "lugre": "servo",
          "linear_motor": "servo", "warming_screw": "servo", "hum": "servo", "jitter": "servo",
          "rotary_table": "servo", "servo_control": "servo", "velocity_drive": "velocity",
          "velocity_control": "velocity", "belt": "belt", "belt_control": "belt",
          "open_loop": "open", "open_loop_control": "open"}
"""The drive family of each kind (the loop structure of the accuracy table)."""

FRICTION_NAMES = frozenset({"coulomb_friction", "stribeck_friction", "asymmetric_friction",
                            "force_offset"})
"""Names that describe the friction every machine has: naming them is never wrong."""

AXIS_EFFECTS = frozenset({"backlash", "cogging", "thermal_drift", "position_dependent_friction",
                          "compliance"})
"""Effects of the axis beyond its friction: named only where the machine has them."""

REQUIRED = {"pwm_motor": ("stribeck_friction",), "lugre": ("stribeck_friction",),
            "linear_motor": ("cogging",), "warming_screw": ("thermal_drift",),
            "rotary_table": ("position_dependent_friction",), "velocity_drive": ("backlash",),
            "belt": ("compliance",), "open_loop": ("stribeck_friction",)}
"""Effects a right diagnosis must name, per kind (others: none)."""

ONE_OF = {"vertical": ("force_offset", "asymmetric_friction")}
"""Kinds whose trait may be named in more than one way: at least one of these names."""

TRAITS = {"pwm_motor": "PWM duty in %, back-EMF, Stribeck friction",
          "pwm_control": "PWM duty in %, back-EMF, Coulomb friction only",
          "vertical": "gravity on a vertical axis (partly counterbalanced)",
          "lugre": "LuGre friction: presliding and Stribeck",
          "linear_motor": "linear motor cogging with 2nd and 3rd harmonics",
          "warming_screw": "ball screw warming up: thermal growth seen by the table's scale",
          "hum": "analog sensor with mains hum (fed back), friction only",
          "jitter": "PC logger with jittered timestamps, tab-separated, friction only",
          "rotary_table": "rotary table in degrees: friction once per turn and a tight spot",
          "servo_control": "PID current loop, Coulomb friction only",
          "velocity_drive": "velocity-loop drive, backlash, table scale logged",
          "velocity_control": "velocity-loop drive, rigid, friction only",
          "belt": "belt: compliance, friction on the load, both encoders logged",
          "belt_control": "stiff coupling, both encoders logged, friction only",
          "open_loop": "open-loop current runs, Stribeck friction",
          "open_loop_control": "open-loop current runs, Coulomb friction only"}
"""One line per kind: what the machine is."""

_G = 9.81
_DEG = 180.0 / math.pi


@dataclass(frozen=True)
class Machine:
    """One drawn machine: mechanics, friction, drive, controller and sensors (SI: m or rad).

    A rigid machine is one body of mass ``m_motor + m_load``; ``link`` ``"belt"`` couples the
    two bodies by a spring-damper, ``"gap"`` by a backlash gap with a stiff contact.
    """

    rotary: bool
    loop_ts: float
    m_motor: float
    m_load: float = 0.0
    link: str = "rigid"
    k_link: float = 0.0
    c_link: float = 0.0
    gap: float = 0.0
    # friction of the (load) body; the motor's own share in a two-body machine
    fc: float = 0.0
    fs: float = 0.0
    vs: float = 1.0
    visc: float = 0.0
    fc_motor: float = 0.0
    visc_motor: float = 0.0
    lugre: bool = False
    sigma0: float = 0.0
    sigma1: float = 0.0
    level_amp: float = 0.0
    level_period: float = 1.0
    level_phase: float = 0.0
    spot_height: float = 0.0
    spot_center: float = 0.0
    spot_width: float = 1.0
    gravity: float = 0.0
    cog: tuple[float, ...] = ()
    cog_phase: tuple[float, ...] = ()
    cog_period: float = 1.0
    growth: float = 0.0
    growth_tau: float = 1.0
    growth_speed: float = 1.0
    bearing: float = 0.0
    bearing_arm: float = 1.0
    # drive
    drive: str = "current"
    kt: float = 1.0
    tau_i: float = 1e-4
    i_max: float = math.inf
    v_bus: float = 24.0
    r_arm: float = 1.0
    l_arm: float = 1e-3
    # controller
    kp: float = 0.0
    ki: float = 0.0
    td: float = 0.0
    n_d: float = 8.0
    t_track: float = 1.0
    u_max: float = math.inf
    kff_v: float = 0.0
    kff_a: float = 0.0
    delay: int = 0
    kv: float = 0.0
    kiv: float = 0.0
    vel_filter_hz: float = 1000.0
    v_max: float = math.inf
    # sensors
    q_motor: float = 1e-6
    q_log: float = 1e-6
    q_load: float = 1e-6
    noise: float = 0.0
    hum: tuple[float, float, float, float, float] = (0.0, 50.0, 0.0, 0.0, 0.0)
    x0: float = 0.0

    def level(self, x: float) -> float:
        """Friction level along the stroke (1: nominal)."""
        lev = 1.0
        if self.level_amp:
            lev += self.level_amp * math.sin(2.0 * math.pi * x / self.level_period
                                             + self.level_phase)
        if self.spot_height:
            u = (x - self.spot_center) / self.spot_width
            lev += self.spot_height * math.exp(-0.5 * u * u)
        return lev

    def cogging(self, x: float) -> float:
        """Cogging force of the motor at position ``x``: a fundamental and its harmonics."""
        f = 0.0
        for k, (a, ph) in enumerate(zip(self.cog, self.cog_phase), start=1):
            f += a * math.sin(2.0 * math.pi * k * x / self.cog_period + ph)
        return f

    def hum_at(self, t: float) -> float:
        """Mains hum of the analog sensor at time ``t``: 50/60 Hz and its third harmonic."""
        a1, f, ph1, a3, ph3 = self.hum
        if not (a1 or a3):
            return 0.0
        return (a1 * math.sin(2.0 * math.pi * f * t + ph1)
                + a3 * math.sin(2.0 * math.pi * 3.0 * f * t + ph3))


@dataclass
class Trace:
    """One simulated run, at the control ticks (and the load's position at every sub-step).

    Attributes
    ----------
    t : ndarray
        Tick times, s.
    x_ref : ndarray
        Reference (the measured position's copy in open loop), m or rad.
    x_motor, x_load : ndarray
        True motor and load positions, m or rad.
    y_fb, y_log, y_load : ndarray
        The fed-back measurement, the logged table position (with thermal growth) and the
        load encoder (belt), as the sensors give them.
    command : ndarray
        The controller's output (A, duty fraction, m/s or rad/s for a velocity command).
    current : ndarray
        The motor's current, A (the drive's monitor).
    clipped : ndarray of bool
        Ticks where the command was at its limit.
    sub_t, sub_log : ndarray
        Sub-step times and the logged channel before the sensor (for a jittered logger).
    """

    t: np.ndarray
    x_ref: np.ndarray
    x_motor: np.ndarray
    x_load: np.ndarray
    y_fb: np.ndarray
    y_log: np.ndarray
    y_load: np.ndarray
    command: np.ndarray
    current: np.ndarray
    clipped: np.ndarray
    sub_t: np.ndarray = field(repr=False)
    sub_log: np.ndarray = field(repr=False)


def _quant(y: float, q: float) -> float:
    return q * math.floor(y / q + 0.5)


def _karnopp(v: float, f: float, mass: float, b: float, fc: float, fs: float, vs: float,
             h: float) -> float:
    """Velocity after one sub-step of a body with Karnopp stick-slip friction.

    ``f``: every force but friction and viscous damping. Stuck bodies stay stuck while
    ``|f| <= fs``; a step whose friction would reverse the motion ends at rest.
    """
    if v == 0.0:
        if abs(f) <= fs:
            return 0.0
        s = 1.0 if f > 0.0 else -1.0
        # v' = h (f - s Fs) / m, viscous implicit
        return h * (f - s * fs) / mass / (1.0 + h * b / mass)
    s = 1.0 if v > 0.0 else -1.0
    fk = fc + (fs - fc) * math.exp(-(v / vs) ** 2)
    vn = (v + h * (f - s * fk) / mass) / (1.0 + h * b / mass)
    return 0.0 if vn * s <= 0.0 else vn


def simulate(mc: Machine, x_ref: np.ndarray | None = None, i_open: np.ndarray | None = None,
             *, noise_seed: np.random.SeedSequence | None = None) -> Trace:
    """Simulate ``mc`` tracking ``x_ref`` (closed loop) or driven by ``i_open`` (A, open loop).

    ``noise_seed`` None: a perfect sensor (no quantisation, noise or hum), for the clean run.
    """
    if (x_ref is None) == (i_open is None):
        raise ValueError("give exactly one of x_ref (closed loop) and i_open (open loop)")
    n = int(x_ref.shape[0] if x_ref is not None else i_open.shape[0])  # type: ignore[union-attr]
    T = mc.loop_ts
    h = T / SUBSTEPS
    sensor = noise_seed is not None
    rng = np.random.default_rng(noise_seed) if sensor else None
    white = (rng.standard_normal((n, 2)) * mc.noise if rng is not None and mc.noise
             else np.zeros((n, 2)))
    two = mc.link != "rigid"
    m1 = mc.m_motor if two else mc.m_motor + mc.m_load
    m2 = mc.m_load
    xm = xl = mc.x0
    vm = vl = 0.0
    z = 0.0
    cur = 0.0
    theta = 0.0
    integ = 0.0
    dterm = 0.0
    iv = 0.0
    vfilt = 0.0
    enc_prev = mc.x0
    y_prev: float | None = None
    queue = [0.0] * (mc.delay + 1)
    a_cur = math.exp(-h / mc.tau_i)
    a_arm = math.exp(-h * mc.r_arm / mc.l_arm)
    a_vel = math.exp(-h * 2.0 * math.pi * mc.vel_filter_hz)
    out = {k: np.zeros(n) for k in ("x_ref", "xm", "xl", "y_fb", "y_log", "y_load", "cmd",
                                    "cur")}
    clipped = np.zeros(n, dtype=bool)
    # each record is the position after its sub-step: at the sub-step's end
    sub_t = (np.arange(n * SUBSTEPS) + 1) * h
    sub_log = np.zeros(n * SUBSTEPS)
    ref_prev = x_ref[0] if x_ref is not None else 0.0
    vref_prev = 0.0

    def logged_table(x: float) -> float:
        # screw growth seen by the table's scale: strain times the distance from the bearing
        if mc.growth:
            return x + theta * mc.growth * (x - mc.bearing) / mc.bearing_arm
        return x

    for k in range(n):
        t = k * T
        disturb = mc.hum_at(t) if sensor else 0.0
        x_fb_true = xm
        if sensor:
            q_fb = mc.q_log if mc.noise else mc.q_motor
            y = _quant(x_fb_true + white[k, 0] + disturb, q_fb)
        else:
            y = x_fb_true
        # -- controller, once per period
        if x_ref is not None:
            r = float(x_ref[k])
            vref = (r - ref_prev) / T
            aref = (vref - vref_prev) / T
            ref_prev, vref_prev = r, vref
            if mc.drive == "velocity":
                # outer P position loop with velocity feedforward: a speed command
                v_cmd = mc.kp * (r - y) + mc.kff_v * vref
                u = min(max(v_cmd, -mc.v_max), mc.v_max)
                clipped[k] = u != v_cmd
            else:
                e = r - y
                if y_prev is None:
                    y_prev = y
                # D = Td/(Td + N T) D - kp Td N/(Td + N T) (y - y_prev): derivative on y
                den = mc.td + mc.n_d * T
                dterm = mc.td / den * dterm - mc.kp * mc.td * mc.n_d / den * (y - y_prev)
                y_prev = y
                v_pid = mc.kp * e + integ + dterm + mc.kff_v * vref + mc.kff_a * aref
                u = min(max(v_pid, -mc.u_max), mc.u_max)
                clipped[k] = u != v_pid
                # back-calculation: I += ki T e + T / Tt (u - v)
                integ += mc.ki * T * e + T / mc.t_track * (u - v_pid)
        else:
            r = y
            u = float(i_open[k])  # type: ignore[index]
        queue.append(u)
        u_now = queue.pop(0)
        out["x_ref"][k] = r
        out["y_fb"][k] = y
        out["cmd"][k] = u
        out["xm"][k] = xm
        out["xl"][k] = xl if two else xm
        table = xl if two else xm
        if sensor:
            q_l = mc.q_log
            out["y_log"][k] = _quant(logged_table(table) + white[k, 1 if not mc.noise else 0]
                                     + disturb, q_l)
            out["y_load"][k] = _quant(xl if two else xm, mc.q_load)
        else:
            out["y_log"][k] = logged_table(table)
            out["y_load"][k] = xl if two else xm
        out["cur"][k] = cur
        # -- the sub-steps
        for j in range(SUBSTEPS):
            if mc.drive == "pwm":
                # L di/dt = d V - R i - ke w, exact with w frozen over the sub-step
                i_ss = (u_now * mc.v_bus - mc.kt * vm) / mc.r_arm
                cur = i_ss + (cur - i_ss) * a_arm
            elif mc.drive == "velocity":
                enc = _quant(xm, mc.q_motor) if sensor else xm
                vfilt = (enc - enc_prev) / h + (vfilt - (enc - enc_prev) / h) * a_vel
                enc_prev = enc
                ev = u_now - vfilt
                iv_new = iv + mc.kiv * h * ev
                i_cmd = mc.kv * ev + iv_new
                if abs(i_cmd) > mc.i_max:
                    i_cmd = math.copysign(mc.i_max, i_cmd)
                else:
                    iv = iv_new
                cur = i_cmd + (cur - i_cmd) * a_cur
            else:
                i_cmd = min(max(u_now, -mc.i_max), mc.i_max)
                cur = i_cmd + (cur - i_cmd) * a_cur
            f_drive = mc.kt * cur
            if mc.cog:
                f_drive += mc.cogging(xm)
            if two:
                d = xm - xl
                dv = vm - vl
                if mc.link == "belt":
                    f_link = mc.k_link * d + mc.c_link * dv
                elif d > mc.gap:
                    f_link = max(mc.k_link * (d - mc.gap) + mc.c_link * dv, 0.0)
                elif d < -mc.gap:
                    f_link = min(mc.k_link * (d + mc.gap) + mc.c_link * dv, 0.0)
                else:
                    f_link = 0.0
                vm = _karnopp(vm, f_drive - f_link, m1, mc.visc_motor, mc.fc_motor,
                              mc.fc_motor, 1.0, h)
                lev = mc.level(xl)
                vl = _karnopp(vl, f_link - mc.gravity, m2, mc.visc, mc.fc * lev, mc.fs * lev,
                              mc.vs, h)
                xm += h * vm
                xl += h * vl
            else:
                lev = mc.level(xm)
                f = f_drive - mc.gravity
                if mc.lugre:
                    g = lev * (mc.fc + (mc.fs - mc.fc) * math.exp(-(vm / mc.vs) ** 2))
                    z_old = z
                    if vm != 0.0:
                        # z relaxes to g sign(v) / sigma0 at the rate sigma0 |v| / g
                        z_ss = math.copysign(g / mc.sigma0, vm)
                        z = z_ss + (z - z_ss) * math.exp(-mc.sigma0 * abs(vm) * h / g)
                    f_fric = mc.sigma0 * z + mc.sigma1 * (z - z_old) / h
                    vm = (vm + h * (f - f_fric) / m1) / (1.0 + h * mc.visc / m1)
                else:
                    vm = _karnopp(vm, f, m1, mc.visc, mc.fc * lev, mc.fs * lev, mc.vs, h)
                xm += h * vm
                xl = xm
            if mc.growth:
                # tau dtheta/dt = |v| / v_heat - theta: heating by motion of the nut
                theta += h * (abs(vm) / mc.growth_speed - theta) / mc.growth_tau
            sub_log[k * SUBSTEPS + j] = logged_table(xl if two else xm)
    return Trace(t=np.arange(n) * T, x_ref=out["x_ref"], x_motor=out["xm"], x_load=out["xl"],
                 y_fb=out["y_fb"], y_log=out["y_log"], y_load=out["y_load"], command=out["cmd"],
                 current=out["cur"], clipped=clipped, sub_t=sub_t, sub_log=sub_log)


def minimum_jerk_reference(rng: np.random.Generator, duration: float, ts: float, center: float,
                           stroke: float, v_peak: float) -> np.ndarray:
    """Point-to-point moves between random targets, each a minimum-jerk profile
    ``x0 + D (10 s^3 - 15 s^4 + 6 s^5)``, with dwells between them. The first two moves go to
    the stroke's ends; a third of the others are short and slow (a tenth of the speed or
    less); three in four of the others cross the centre. No move lasts more than 1 s (a slow
    one 2 s), so a run reverses every few seconds."""
    n = int(round(duration / ts))
    x = np.empty(n)
    pos = center
    k = 0
    dwell0 = int(rng.uniform(0.2, 0.4) / ts)
    x[:dwell0] = pos
    k = dwell0
    targets = [center + 0.5 * stroke * s for s in (1.0, -1.0)]
    while k < n:
        slow = not targets and rng.random() < 1 / 3
        if targets:
            target = targets.pop(0)
        elif slow:
            # a slow move is a short one: a few percent of the stroke, back towards the centre
            step = stroke * rng.uniform(0.03, 0.12)
            target = pos - step if pos > center else pos + step
        elif rng.random() < 0.75:
            # mostly across the centre: back and forth, as a machine's test cycle goes
            target = center - math.copysign(stroke * rng.uniform(0.1, 0.5), pos - center)
        else:
            target = center + stroke * rng.uniform(-0.5, 0.5)
        dist = target - pos
        if abs(dist) < 0.02 * stroke:
            continue
        speed = v_peak * (rng.uniform(0.02, 0.1) if slow else rng.uniform(0.4, 1.0))
        # no move longer than 1 s (a slow one 2 s): a long stroke at a low speed would
        # otherwise fill the run with one move, and the run would never reverse
        speed = max(speed, 1.875 * abs(dist) / (2.0 if slow else 1.0))
        # peak speed of a minimum-jerk move is 1.875 D / T_move
        t_move = max(1.875 * abs(dist) / speed, 0.05)
        m = max(int(t_move / ts), 2)
        s = np.arange(1, m + 1) / m
        seg = pos + dist * (10 * s**3 - 15 * s**4 + 6 * s**5)
        stop = min(n, k + m)
        x[k:stop] = seg[:stop - k]
        k = stop
        pos = target
        dwell = int(rng.uniform(0.05, 0.4) / ts)
        stop = min(n, k + dwell)
        x[k:stop] = pos
        k = stop
    return x


def open_loop_current(rng: np.random.Generator, duration: float, ts: float,
                      i_break: float) -> np.ndarray:
    """A designed open-loop current: rests, pulses and slow triangles through the breakaway
    current ``i_break``, their signs alternating so that the axis goes back and forth."""
    n = int(round(duration / ts))
    i = np.zeros(n)
    k = int(rng.uniform(0.1, 0.3) / ts)
    sign = 1.0 if rng.random() < 0.5 else -1.0
    while k < n:
        if rng.random() < 0.5:
            m = int(rng.uniform(0.05, 0.25) / ts)
            seg = np.full(m, sign * i_break * rng.uniform(1.3, 2.5))
        else:
            m = int(rng.uniform(0.4, 1.0) / ts)
            peak = i_break * rng.uniform(1.1, 1.6)
            seg = sign * peak * (1.0 - np.abs(np.linspace(-1.0, 1.0, m)))
        stop = min(n, k + m)
        i[k:stop] = seg[:stop - k]
        k = stop + int(rng.uniform(0.1, 0.4) / ts)
        sign = -sign
    return i


@dataclass
class Case:
    """One drawn run of a kind and its truth.

    Attributes
    ----------
    kind, seed : str, int
    machine : Machine
    trace, clean : Trace
        The run as sensed, and the same run with a perfect sensor.
    floor : float
        Noise floor of a free-run prediction: rms of the logged position minus the clean run's
        at the logged rows, SI.
    signature : float or None
        Rms of the effect in the clean logged position, SI (None: no effect).
    unit : str
        Unit of the logged positions (``m``, ``mm``, ``um``, ``rad``, ``deg``).
    effort_unit : str or None
        Unit of the logged effort (``A``, ``N``, ``%``), None when none is logged.
    log_every : int
        Control ticks per log row (1, 2, or the jittered logger's period).
    jitter : float
        Largest timestamp jitter of the logger, share of its period (0: a regular log).
    sep : str
        Column separator.
    attempts : int
        Draws it took to make the effect visible.
    """

    kind: str
    seed: int
    machine: Machine
    trace: Trace = field(repr=False)
    clean: Trace = field(repr=False)
    floor: float
    signature: float | None
    unit: str
    effort_unit: str | None
    log_every: int
    jitter: float
    sep: str
    attempts: int
    rows: dict[str, np.ndarray] = field(repr=False, default_factory=dict)

    @property
    def family(self) -> str:
        """The drive family (``pwm``, ``servo``, ``velocity``, ``belt``, ``open``)."""
        return FAMILY[self.kind]

    @property
    def open_loop(self) -> bool:
        """Whether the run is an open-loop one (diagnosed with ``--open-loop``)."""
        return self.family == "open"

    @property
    def log_rate(self) -> str:
        """The log's nominal rate, e.g. ``1kHz``, ``500Hz``."""
        hz = 1.0 / (self.machine.loop_ts * self.log_every)
        return f"{hz / 1000:g}kHz" if hz >= 1000 else f"{hz:g}Hz"

    def truth(self) -> dict[str, object]:
        """What a right diagnosis of this run says, and how the run was made."""
        required = REQUIRED.get(self.kind, ())
        one_of = ONE_OF.get(self.kind, ())
        return {"kind": self.kind, "seed": self.seed, "family": self.family,
                "machine": TRAITS[self.kind], "required": list(required),
                "one_of": list(one_of),
                "allowed": sorted(FRICTION_NAMES | set(required) | set(one_of)),
                "forbidden": sorted(AXIS_EFFECTS - set(required)),
                "expect_warning": "resampled" if self.jitter else None,
                "no_resonance": self.kind == "hum",
                "floor_si": self.floor, "signature_si": self.signature,
                "position_unit": self.unit, "position_unit_si": "rad" if self.machine.rotary
                else "m", "effort_unit": self.effort_unit, "log_rate": self.log_rate,
                "samples": int(self.rows["t"].shape[0]), "attempts": self.attempts}

    def csv_text(self) -> str:
        """The log as the machine's logger writes it: a header row, one row per sample."""
        cols = self._columns()
        lines = [self.sep.join(name for name, _, _ in cols)]
        for i in range(cols[0][1].shape[0]):
            lines.append(self.sep.join(format(a[i], f) for _, a, f in cols))
        return "\n".join(lines) + "\n"

    def write_csv(self, path: str | os.PathLike[str]) -> None:
        """Write :meth:`csv_text` to ``path``."""
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(self.csv_text())

    def cli_args(self, csv_path: str | os.PathLike[str]) -> list[str]:
        """The ``fricbench diagnose`` arguments a user would give for this run's CSV."""
        names = _NAMES[self.family]
        args = [os.fspath(csv_path), "--time", names[0], "--position", names[2],
                "--position-unit", self.unit]
        if self.open_loop:
            args.append("--open-loop")
        else:
            args += ["--reference", names[1]]
        if self.effort_unit is not None:
            args += ["--effort", names[3], "--effort-unit", self.effort_unit]
        if "load" in self.rows:
            args += ["--load-position", names[4]]
        return args

    def _columns(self) -> list[tuple[str, np.ndarray, str]]:
        names = _NAMES[self.family]
        cols = [(names[0], self.rows["t"], ".6f")]
        if not self.open_loop:
            cols.append((names[1], self.rows["ref"], ".10g"))
        cols.append((names[2], self.rows["pos"], ".10g"))
        if "effort" in self.rows:
            cols.append((names[3], self.rows["effort"], ".6g"))
        if "load" in self.rows:
            cols.append((names[4], self.rows["load"], ".10g"))
        return cols


_NAMES = {"pwm": ("t", "setpoint", "angle", "duty", ""),
          "servo": ("time", "x_cmd", "x_meas", "effort", ""),
          "velocity": ("Time", "Command", "Scale", "Imon", ""),
          "belt": ("t_s", "ref_mm", "motor_mm", "force", "load_mm"),
          "open": ("time", "", "position", "current", "")}

_UNIT_SCALE = {"m": 1.0, "mm": 1e3, "um": 1e6, "rad": 1.0, "deg": _DEG}


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(a))))


def _pid_gains(rng: np.random.Generator, mass: float, gain: float, ts: float
               ) -> dict[str, float]:
    """PID gains placing the rigid loop's poles at ``(s + w)^3`` for a plant
    ``gain / (mass s^2)``, ``w`` well inside the sampling rate."""
    w = 2.0 * math.pi * rng.uniform(5.0, 12.0) * (1e-3 / ts) ** 0.5
    kp = 3.0 * mass * w * w / gain
    return {"kp": kp, "ki": mass * w**3 / gain, "td": 1.0 / w,
            "n_d": float(rng.uniform(6.0, 12.0)), "t_track": math.sqrt(3.0 / w / w)}


def _draw_machine(rng: np.random.Generator, kind: str, duration: float
                  ) -> tuple[Machine, np.ndarray | None, np.ndarray | None, dict[str, object]]:
    """A machine of ``kind``, its reference (or open-loop current) and its logging choices."""
    fam = FAMILY[kind]
    ts = float(rng.choice([1e-3, 5e-4]))
    log: dict[str, object] = {"unit": "mm", "effort_unit": "A",
                              "log_every": 1 if ts == 1e-3 else 2, "jitter": 0.0,
                              "sep": str(rng.choice([",", ";"]))}
    if fam == "pwm":
        # a small DC motor with an inertia disc, rotary, rad
        J = rng.uniform(2e-5, 2e-4)
        kt = rng.uniform(0.02, 0.08)
        R, L = rng.uniform(1.0, 5.0), rng.uniform(0.3e-3, 3e-3)
        vbus = float(rng.choice([12.0, 24.0, 48.0]))
        stall = kt * vbus / R
        fc = stall * rng.uniform(0.01, 0.04)
        fs = fc * (rng.uniform(1.4, 2.2) if kind == "pwm_motor" else 1.0)
        g = _pid_gains(rng, J, vbus * kt / R, ts)
        mc = Machine(rotary=True, loop_ts=ts, m_motor=J, fc=fc, fs=fs,
                     vs=rng.uniform(0.5, 3.0), visc=fc * rng.uniform(0.002, 0.01),
                     drive="pwm", kt=kt, v_bus=vbus, r_arm=R, l_arm=L, u_max=1.0,
                     delay=int(rng.integers(0, 2)), q_motor=2 * math.pi / (4 * float(
                         rng.choice([500, 1000, 2048]))), **g)
        mc = replace(mc, q_log=mc.q_motor)
        stroke, v_peak = rng.uniform(4.0, 20.0), rng.uniform(20.0, 80.0)
        log.update(unit="rad", effort_unit="%")
    elif fam in ("servo", "belt"):
        M = rng.uniform(3.0, 30.0)
        kt = rng.uniform(5.0, 40.0)
        fc = M * _G * rng.uniform(0.01, 0.05)
        stroke = rng.uniform(0.03, 0.2)
        v_peak = rng.uniform(0.03, 0.2)
        q = float(rng.choice([0.1e-6, 0.5e-6, 1e-6]))
        mc = Machine(rotary=False, loop_ts=ts, m_motor=M, fc=fc, fs=fc, vs=0.005,
                     visc=M * rng.uniform(1.0, 10.0), kt=kt, tau_i=rng.uniform(1e-4, 4e-4),
                     delay=int(rng.integers(0, 2)), q_motor=q, q_log=q, q_load=q)
        if fam == "belt":
            # motor (pulley, rotor) and carriage; friction mostly on the carriage
            share = rng.uniform(0.2, 0.5)
            mc = replace(mc, m_motor=M * share, m_load=M * (1 - share), link="belt",
                         fc_motor=0.1 * fc, visc_motor=0.2 * mc.visc, q_load=q * float(
                             rng.choice([1.0, 2.0, 5.0])))
            mu = mc.m_motor * mc.m_load / (mc.m_motor + mc.m_load)
            if kind == "belt":
                f_res = rng.uniform(15.0, 50.0)
                k_link = mu * (2 * math.pi * f_res) ** 2
                zeta = rng.uniform(0.03, 0.15)
                mc = replace(mc, k_link=k_link, c_link=2 * zeta * math.sqrt(k_link * mu))
            else:
                # the control: a coupling stiff enough to be rigid, both encoders still logged
                mc = replace(mc, link="rigid")
            log["effort_unit"] = "N"
        g = _pid_gains(rng, M, kt, ts)
        if kind == "belt":
            # a belt drive is tuned softer than its resonance
            f_res = math.sqrt(mc.k_link / mu) / (2 * math.pi)
            w = 2 * math.pi * min(rng.uniform(3.0, 6.0), f_res / 4)
            g.update(kp=3 * M * w * w / kt, ki=M * w**3 / kt, td=1 / w,
                     t_track=math.sqrt(3.0) / w)
        mc = replace(mc, **g)
        if rng.random() < 0.5:
            mc = replace(mc, kff_v=mc.visc / kt, kff_a=M / kt * rng.uniform(0.5, 1.0))
        if kind == "vertical":
            mc = replace(mc, gravity=M * _G * rng.uniform(0.3, 1.0))
        elif kind == "lugre":
            x_pre = rng.uniform(2e-6, 15e-6)
            sigma0 = fc / x_pre
            w_pre = math.sqrt(sigma0 / M)
            if w_pre * ts / SUBSTEPS > 0.4:
                sigma0 = M * (0.4 * SUBSTEPS / ts) ** 2
            mc = replace(mc, lugre=True, sigma0=sigma0, fs=fc * rng.uniform(1.4, 2.2),
                         vs=rng.uniform(0.5e-3, 5e-3),
                         sigma1=2 * rng.uniform(0.3, 1.0) * math.sqrt(sigma0 * M))
        elif kind == "linear_motor":
            period = rng.uniform(0.005, 0.02)
            stroke = max(stroke, 4 * period)
            a1 = fc * rng.uniform(0.3, 1.0)
            mc = replace(mc, cog=(a1, a1 * rng.uniform(0.3, 0.8), a1 * rng.uniform(0.0, 0.4)),
                         cog_phase=tuple(rng.uniform(0, 2 * math.pi, 3)), cog_period=period)
            log["effort_unit"] = "N"
        elif kind == "warming_screw":
            arm = rng.uniform(0.1, 0.5)
            mc = replace(mc, growth=rng.uniform(5e-6, 40e-6), growth_tau=rng.uniform(3.0, 30.0),
                         bearing_arm=arm)
            v_peak = max(v_peak, 0.1)
        elif kind == "hum":
            full = rng.uniform(0.05, 0.5)  # the sensor's range, m, read by a 16-bit ADC
            noise = rng.uniform(0.2e-6, 2e-6)
            a1 = noise * rng.uniform(2.0, 8.0)
            mc = replace(mc, noise=noise, q_log=full / 2**16,
                         hum=(a1, float(rng.choice([50.0, 60.0])) * rng.uniform(0.998, 1.002),
                              rng.uniform(0, 2 * math.pi), a1 * rng.uniform(0.2, 0.6),
                              rng.uniform(0, 2 * math.pi)))
            # the loop's derivative sees the hum: a heavier derivative filter
            mc = replace(mc, n_d=min(mc.n_d, 5.0))
        elif kind == "jitter":
            period = int(rng.integers(2, 6)) * (1 if ts == 1e-3 else 2)
            log.update(log_every=period, jitter=rng.uniform(0.05, 0.1), sep="\t")
        elif kind == "rotary_table":
            # a worm-driven table, degrees: friction once per turn and a tight spot
            J = M * 0.02
            fc_rot = J * rng.uniform(3.0, 15.0)
            q_rot = 2 * math.pi / 2 ** int(rng.integers(20, 24))
            mc = replace(mc, rotary=True, m_motor=J, kt=kt * 0.05, fc=fc_rot, fs=fc_rot,
                         visc=J * rng.uniform(0.5, 3.0), q_motor=q_rot, q_log=q_rot, vs=0.05,
                         kff_v=0.0, kff_a=0.0)
            stroke = math.radians(rng.uniform(120.0, 330.0))
            v_peak = math.radians(rng.uniform(30.0, 120.0))
            mc = replace(mc, level_amp=rng.uniform(0.2, 0.5), level_period=2 * math.pi,
                         level_phase=rng.uniform(0, 2 * math.pi),
                         spot_height=rng.uniform(0.3, 1.0), spot_width=stroke * rng.uniform(
                             0.03, 0.08), spot_center=stroke * rng.uniform(-0.3, 0.3))
            mc = replace(mc, **_pid_gains(rng, mc.m_motor, mc.kt, ts))
            log["unit"] = "deg"
        if kind in ("servo_control", "hum", "jitter", "lugre", "warming_screw"):
            # a current (A) or a force command (kt * i, N), or no effort at all
            log["effort_unit"] = str(rng.choice(["A", "N"])) if rng.random() < 0.7 else None
        if log["unit"] == "mm" and kind not in ("rotary_table", "belt", "belt_control"):
            log["unit"] = str(rng.choice(["mm", "um", "m"]))
        if fam == "belt":
            log["unit"] = "mm"
        # no saturation in these machines: a limit well above every force of the run
        mc = replace(mc, u_max=math.inf, i_max=math.inf)
    elif fam == "velocity":
        M = rng.uniform(5.0, 50.0)
        kt = rng.uniform(5.0, 40.0)
        fc = M * _G * rng.uniform(0.01, 0.05)
        stroke = rng.uniform(0.03, 0.2)
        v_peak = rng.uniform(0.03, 0.2)
        q = float(rng.choice([0.5e-6, 1e-6]))
        w_v = 2 * math.pi * rng.uniform(30.0, 80.0) * (1e-3 / ts) ** 0.5
        mc = Machine(rotary=False, loop_ts=ts, m_motor=M, fc=fc, fs=fc, vs=0.005,
                     visc=M * rng.uniform(1.0, 10.0), drive="velocity", kt=kt,
                     tau_i=rng.uniform(1e-4, 3e-4), kv=M * w_v / kt, kiv=M * w_v**2 / kt / 5,
                     vel_filter_hz=rng.uniform(500.0, 1500.0), kp=w_v / rng.uniform(6.0, 12.0),
                     kff_v=float(rng.choice([0.0, rng.uniform(0.5, 1.0)])),
                     delay=int(rng.integers(0, 2)), q_motor=q * 0.1, q_log=q)
        if kind == "velocity_drive":
            share = rng.uniform(0.2, 0.5)
            f_c = rng.uniform(300.0, 500.0)
            mu = M * share * (1 - share)
            k_link = mu * (2 * math.pi * f_c) ** 2
            mc = replace(mc, m_motor=M * share, m_load=M * (1 - share), link="gap",
                         gap=rng.uniform(3e-6, 25e-6), k_link=k_link,
                         c_link=2 * 0.2 * math.sqrt(k_link * mu), fc_motor=0.1 * fc,
                         visc_motor=0.3 * mc.visc)
        log["effort_unit"] = "A" if rng.random() < 0.5 else None
        log["unit"] = str(rng.choice(["mm", "m"]))
    else:  # open loop
        M = rng.uniform(3.0, 30.0)
        kt = rng.uniform(5.0, 40.0)
        fc = M * _G * rng.uniform(0.02, 0.06)
        fs = fc * (rng.uniform(1.4, 2.2) if kind == "open_loop" else 1.0)
        q = float(rng.choice([0.5e-6, 1e-6]))
        mc = Machine(rotary=False, loop_ts=ts, m_motor=M, fc=fc, fs=fs,
                     vs=rng.uniform(2e-3, 10e-3), visc=M * rng.uniform(1.0, 10.0), kt=kt,
                     tau_i=rng.uniform(1e-4, 3e-4), q_motor=q, q_log=q)
        i_in = open_loop_current(rng, duration, ts, max(fs, fc) / kt)
        log["unit"] = str(rng.choice(["mm", "m"]))
        return mc, None, i_in, log
    center = rng.uniform(-1.0, 1.0) * stroke
    mc = replace(mc, x0=center, bearing=center - mc.bearing_arm)
    if mc.growth:
        mc = replace(mc, growth_speed=0.3 * v_peak)
    ref = minimum_jerk_reference(rng, duration, ts, center, stroke, v_peak)
    return mc, ref, None, log


def _without_effect(kind: str, mc: Machine, clean: Trace) -> Machine:
    """The machine without its kind's trait, to measure the trait's signature."""
    if kind in ("pwm_motor", "lugre", "open_loop"):
        return replace(mc, fs=mc.fc)
    if kind == "vertical":
        return replace(mc, gravity=0.0)
    if kind == "linear_motor":
        return replace(mc, cog=())
    if kind == "warming_screw":
        return replace(mc, growth=0.0)
    if kind == "rotary_table":
        moving = np.abs(np.diff(clean.x_load)) > 0
        xs = clean.x_load[1:][moving] if np.any(moving) else clean.x_load
        mean = float(np.mean([mc.level(float(x)) for x in xs[::10]]))
        return replace(mc, level_amp=0.0, spot_height=0.0, fc=mc.fc * mean, fs=mc.fs * mean)
    if kind == "velocity_drive":
        return replace(mc, gap=0.0)
    if kind == "belt":
        return replace(mc, link="rigid", m_motor=mc.m_motor + mc.m_load, m_load=0.0,
                       fc=mc.fc + mc.fc_motor, fs=mc.fs + mc.fc_motor,
                       visc=mc.visc + mc.visc_motor)
    raise ValueError(f"kind={kind!r} has no trait to remove")


def _logged_rows(case_kind: str, mc: Machine, tr: Trace, log: dict[str, object],
                 rng: np.random.Generator) -> dict[str, np.ndarray]:
    """The rows the logger writes, in the log's units."""
    k = _UNIT_SCALE[str(log["unit"])]
    every = int(log["log_every"])  # type: ignore[call-overload]
    idx = np.arange(0, tr.t.shape[0], every)
    rows: dict[str, np.ndarray] = {"t": tr.t[idx].copy(), "ref": tr.x_ref[idx] * k,
                                   "pos": tr.y_log[idx] * k}
    if float(log["jitter"]):  # type: ignore[arg-type]
        # a PC logger: each row taken at a jittered instant, stamped with it, sampled from
        # the sub-step record (the sensor quantises it)
        period = every * mc.loop_ts
        tj = tr.t[idx] + period * float(log["jitter"]) * rng.uniform(  # type: ignore[arg-type]
            -1.0, 1.0, idx.shape[0])
        tj[0] = 0.0
        # read at its stamp: the sub-step record interpolated there (the nearest record, with
        # the records labelled a sub-step early, put a reading 0-190 us away from its stamp:
        # at the run's speeds microns, many times the sensor's noise, that no model removes)
        tick = np.clip(np.floor(tj / mc.loop_ts).astype(int), 0, tr.t.shape[0] - 1)
        rows["t"] = tj
        rows["ref"] = tr.x_ref[tick] * k
        rows["pos"] = np.array([_quant(v, mc.q_log)
                                for v in np.interp(tj, tr.sub_t, tr.sub_log)]) * k
    eu = log["effort_unit"]
    if eu == "A":
        rows["effort"] = (tr.current if mc.drive == "velocity" else tr.command)[idx].copy()
    elif eu == "N":
        rows["effort"] = tr.command[idx] * mc.kt
    elif eu == "%":
        rows["effort"] = 100.0 * tr.command[idx]
    if FAMILY[case_kind] == "belt":
        rows["pos"] = tr.y_fb[idx] * k  # the motor's encoder, the loop's feedback
        rows["load"] = tr.y_load[idx] * k
    if FAMILY[case_kind] == "open":
        rows.pop("ref")
    return rows


def draw_case(kind: str, seed: int, *, duration: float | None = None) -> Case:
    """Draw a machine of ``kind`` from ``seed`` and simulate its run.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    seed : int
        Seed of every random choice (machine, reference, sensor noise, logger jitter).
    duration : float, optional
        Run length, s (default drawn in 5..8 s).

    Returns
    -------
    Case
        With its trait visible: the trait's clean signature at least twice the noise floor.
    """
    if kind not in KINDS:
        raise ValueError(f"kind={kind!r}: expected one of {KINDS}")
    if duration is not None and not (1.0 <= duration <= 60.0):
        raise ValueError(f"duration={duration!r}: expected 1..60 s")
    kid = KINDS.index(kind)
    for attempt in range(30):
        rng = np.random.default_rng([seed, kid, attempt])
        dur = float(duration if duration is not None else rng.uniform(5.0, 8.0))
        mc, ref, i_in, log = _draw_machine(rng, kind, dur)
        clean = simulate(mc, ref, i_in)
        trace = simulate(mc, ref, i_in, noise_seed=np.random.SeedSequence([seed, kid, attempt,
                                                                           7]))
        if not _sane(mc, clean, trace, ref):
            continue
        rows = _logged_rows(kind, mc, trace, log, np.random.default_rng([seed, kid, attempt, 8]))
        every = int(log["log_every"])  # type: ignore[call-overload]
        idx = np.arange(0, trace.t.shape[0], every)
        chan = trace.y_fb if FAMILY[kind] == "belt" else trace.y_log
        chan_clean = clean.y_fb if FAMILY[kind] == "belt" else clean.y_log
        floor = _rms(chan[idx] - chan_clean[idx])
        signature = None
        if kind in REQUIRED or kind in ONE_OF:
            base = simulate(_without_effect(kind, mc, clean), ref, i_in)
            if kind == "belt":  # compliance shows between the two encoders, and in the motor
                diff = np.concatenate([(clean.x_load - base.x_load)[idx],
                                       (clean.x_motor - base.x_motor)[idx]])
            else:
                diff = (clean.y_log - base.y_log)[idx]
            signature = _rms(diff)
            if signature < 2.0 * max(floor, mc.q_log):
                continue
        return Case(kind=kind, seed=seed, machine=mc, trace=trace, clean=clean, floor=floor,
                    signature=signature, unit=str(log["unit"]),
                    effort_unit=log["effort_unit"],  # type: ignore[arg-type]
                    log_every=every, jitter=float(log["jitter"]),  # type: ignore[arg-type]
                    sep=str(log["sep"]), attempts=attempt + 1, rows=rows)
    raise RuntimeError(f"{kind} seed {seed}: no sane machine with a visible trait in 30 draws")


def _sane(mc: Machine, clean: Trace, trace: Trace, ref: np.ndarray | None) -> bool:
    """A run worth logging: finite, the loop tracking (error within a quarter of the stroke),
    the axis moving, an open-loop axis within a metre (or ten turns) of its start."""
    for tr in (clean, trace):
        if not np.all(np.isfinite(tr.y_log)):
            return False
        if ref is not None:
            stroke = float(np.ptp(ref))
            if float(np.max(np.abs(tr.x_load - ref))) > 0.25 * stroke:
                return False
        else:
            reach = 10 * 2 * math.pi if mc.rotary else 1.0
            if float(np.max(np.abs(tr.x_load - mc.x0))) > reach:
                return False
            if float(np.ptp(tr.x_load)) < 100 * mc.q_log:
                return False
    return True

"""The one batched physics step of the servo feed axis.

Everything that simulates an axis (the scalar env, the native vector env, ``simulate``, the
benchmark runner and the diagnosis) calls :func:`run_kernel`, which advances ``N`` independent
axes over ``K`` control samples. There is no second copy of these equations anywhere.

Per control sample ``k`` (period ``Ts``, zero-order hold on the current command):

1. the controller reads the measured position ``x_fb[k]`` (motor encoder or linear scale),
2. position P + velocity feedforward: ``v_cmd = Kp (x_r - x_fb) + kvff v_r``,
3. velocity PI on the backward-difference velocity ``(x_fb[k] - x_fb[k-1]) / Ts`` with
   clamping anti-windup, plus acceleration feedforward and the compensation force, gives the
   current command ``i = Kv (e_v + I) + (kaff M a_r + u_comp) / Kt`` (A),
4. optional pure delay of ``d`` samples, then current saturation ``|i| <= i_max``,
5. the mechanics ``M dv/dt = Kt i - B v - F_f - F_load - F_cog(x)`` are integrated over
   ``n_sub`` fixed substeps: implicit (Kikuuwe 2005) update for static friction laws, so that
   stiction holds exactly; exponential bristle update for LuGre/Dahl,
6. transmission backlash (play operator) and thermal drift give the table position; the sensor
   is quantised and noise is added.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from fricbench.friction.laws import KIND_DAHL, KIND_LUGRE, KIND_STATIC, stribeck_level

# -- parameter vector layout (columns of P, one row per axis) ------------------------------------
P_TS, P_NSUB, P_M, P_B, P_KT, P_IMAX, P_KP, P_KVFF, P_KAFF, P_KV, P_TI, P_FLOAD = range(12)
P_FKIND, P_FC, P_FS, P_VS, P_DELTA, P_FV, P_SIGMA0, P_SIGMA1 = range(12, 20)
(P_BACKLASH, P_MEAS_TABLE, P_COG_AMP, P_COG_PERIOD, P_COG_PHASE, P_PD_GRAD, P_PD_AMP,
 P_PD_PERIOD, P_PD_PHASE, P_TH_AMP, P_TH_TAU, P_QUANT, P_NOISE, P_DELAY) = range(20, 34)
N_PARAMS = 34

# -- state vector layout (columns of S) -----------------------------------------------------------
S_X, S_V, S_XPLAY, S_Z, S_I, S_XFB, S_XFB_PREV, S_T, S_XMEAS, S_OFF_PREV, S_IAPP = range(11)
DELAY_MAX = 16
S_DBUF = 11
N_STATE = S_DBUF + DELAY_MAX

# -- status codes ---------------------------------------------------------------------------------
STATUS_OK = 0
STATUS_NONFINITE = 1
STATUS_RUNAWAY = 2
RUNAWAY_VELOCITY = 100.0  # m/s: no feed axis moves this fast; the loop has gone unstable
RUNAWAY_POSITION = 1.0e3  # m


def _measure(p: np.ndarray, s: np.ndarray, noise: float) -> None:
    """Update the sensor readings of state ``s`` from the current mechanics."""
    t = s[S_T]
    drift = 0.0
    if p[P_TH_AMP] != 0.0:
        # d(t) = d_inf (1 - exp(-t / tau))
        drift = p[P_TH_AMP] * (1.0 - math.exp(-t / p[P_TH_TAU]))
    x_table = s[S_XPLAY] + drift
    q = p[P_QUANT]
    sig = p[P_NOISE] * noise
    if p[P_MEAS_TABLE] > 0.5:
        x_sensor = x_table
    else:
        x_sensor = s[S_X]
    if q > 0.0:
        x_sensor = q * math.floor(x_sensor / q + 0.5)
        x_table = q * math.floor(x_table / q + 0.5)
    s[S_XFB_PREV] = s[S_XFB]
    s[S_XFB] = x_sensor + sig
    s[S_XMEAS] = x_table + sig


def _friction_scale(p: np.ndarray, x: float) -> float:
    """Position-dependent friction factor ``1 + grad x + amp sin(2 pi x / period + phase)``."""
    scale = 1.0 + p[P_PD_GRAD] * x
    if p[P_PD_AMP] != 0.0:
        scale += p[P_PD_AMP] * math.sin(2.0 * math.pi * x / p[P_PD_PERIOD] + p[P_PD_PHASE])
    return scale


def _substep(p: np.ndarray, s: np.ndarray, force_motor: float, h: float) -> float:
    """Advance the mechanics of one axis by ``h``; return the friction force applied (N)."""
    m = p[P_M]
    x = s[S_X]
    v = s[S_V]
    kind = int(p[P_FKIND])
    scale = _friction_scale(p, x)
    fc = p[P_FC] * scale
    fs = p[P_FS] * scale
    f_ext = force_motor - p[P_FLOAD]
    if p[P_COG_AMP] != 0.0:
        # F_cog = A sin(2 pi x / lambda + phi)
        f_ext -= p[P_COG_AMP] * math.sin(2.0 * math.pi * x / p[P_COG_PERIOD] + p[P_COG_PHASE])
    damping = p[P_B] + p[P_FV]
    if kind == KIND_STATIC:
        # Kikuuwe: v+ = v* - h Sgn(v+) F_c / (M + h b); stick when |v*| <= h F_s / (M + h b)
        m_eff = m + h * damping
        v_star = (m * v + h * f_ext) / m_eff
        speed = abs(v_star)
        if speed * m_eff <= h * max(fs, fc):
            v_new = 0.0
        else:
            level = stribeck_level(speed, fc, fs, p[P_VS], p[P_DELTA])
            v_new = v_star - math.copysign(h * level / m_eff, v_star)
            if v_new * v_star < 0.0:
                v_new = 0.0
            elif p[P_VS] > 0.0:
                # one midpoint correction of the velocity-dependent level: 2nd-order accurate
                # in sliding, where the Stribeck curve changes within a few substeps
                v_mid = 0.5 * (abs(v_new) + (abs(v) if v * v_star > 0.0 else 0.0))
                level = stribeck_level(v_mid, fc, fs, p[P_VS], p[P_DELTA])
                v_new = v_star - math.copysign(h * level / m_eff, v_star)
                if v_new * v_star < 0.0:
                    v_new = 0.0
        f_fric = (m * v + h * f_ext - m * v_new) / h - p[P_B] * v_new
    else:
        sigma0 = p[P_SIGMA0]
        sigma1 = p[P_SIGMA1] if kind == KIND_LUGRE else 0.0
        if kind == KIND_DAHL:
            g = fc
        else:
            g = stribeck_level(abs(v), fc, fs, p[P_VS], p[P_DELTA])
        z = s[S_Z]
        # dz/dt = v - sigma0 |v| z / g(v): exact for v frozen over the substep (stable for any h)
        if v != 0.0 and g > 0.0:
            z_ss = math.copysign(g / sigma0, v)
            z_new = z_ss + (z - z_ss) * math.exp(-sigma0 * abs(v) * h / g)
        else:
            z_new = z + v * h
        rate = (z_new - z) / h
        # F = sigma0 z + sigma1 dz/dt + fv v; the sigma1 v part of dz/dt is taken implicitly
        f_bristle = sigma0 * z_new + sigma1 * (rate - v)
        v_new = (m * v + h * (f_ext - f_bristle)) / (m + h * (damping + sigma1))
        s[S_Z] = z_new
        f_fric = f_bristle + sigma1 * v_new + p[P_FV] * v_new
    # trapezoidal position: exact when the velocity changes linearly over the substep
    x_new = x + 0.5 * h * (v + v_new)
    s[S_X] = x_new
    s[S_V] = v_new
    b = p[P_BACKLASH]
    if b > 0.0:
        # play operator: the table follows the motor only after the lost motion b is taken up
        half = 0.5 * b
        if x_new - s[S_XPLAY] > half:
            s[S_XPLAY] = x_new - half
        elif x_new - s[S_XPLAY] < -half:
            s[S_XPLAY] = x_new + half
    else:
        s[S_XPLAY] = x_new
    return f_fric


def _control(p: np.ndarray, s: np.ndarray, xr: float, vr: float, ar: float, u_force: float,
             u_off: float) -> float:
    """Cascade controller of one axis at one sample; returns the applied current (A)."""
    ts = p[P_TS]
    xr_eff = xr + u_off
    vr_eff = vr + (u_off - s[S_OFF_PREV]) / ts
    s[S_OFF_PREV] = u_off
    # v_cmd = Kp (x_r - x_fb) + kvff v_r
    v_cmd = p[P_KP] * (xr_eff - s[S_XFB]) + p[P_KVFF] * vr_eff
    v_fb = (s[S_XFB] - s[S_XFB_PREV]) / ts
    e_v = v_cmd - v_fb
    kt = p[P_KT]
    # i = Kv (e_v + I) + (kaff M a_r + u) / Kt
    i_cmd = p[P_KV] * (e_v + s[S_I]) + (p[P_KAFF] * p[P_M] * ar + u_force) / kt
    d = int(p[P_DELAY])
    if d > 0:
        i_app = s[S_DBUF + d - 1]
        for j in range(d - 1, 0, -1):
            s[S_DBUF + j] = s[S_DBUF + j - 1]
        s[S_DBUF] = i_cmd
    else:
        i_app = i_cmd
    i_max = p[P_IMAX]
    saturated = False
    if i_app > i_max:
        i_app = i_max
        saturated = e_v > 0.0
    elif i_app < -i_max:
        i_app = -i_max
        saturated = e_v < 0.0
    # clamping anti-windup: freeze I while the output is saturated in the direction of e_v
    if p[P_TI] > 0.0 and not saturated:
        s[S_I] += ts / p[P_TI] * e_v
    s[S_IAPP] = i_app
    return i_app


def _run_impl(P: np.ndarray, S: np.ndarray, xr: np.ndarray, vr: np.ndarray, ar: np.ndarray,
              u_force: np.ndarray, u_off: np.ndarray, noise: np.ndarray, x_true: np.ndarray,
              x_meas: np.ndarray, force: np.ndarray, friction: np.ndarray,
              status: np.ndarray) -> None:
    n_axes, n_samples = xr.shape
    for n in numba.prange(n_axes):
        p = P[n]
        s = S[n]
        n_sub = int(p[P_NSUB])
        ts = p[P_TS]
        h = ts / n_sub
        for k in range(n_samples):
            x_true[n, k] = s[S_XPLAY]
            x_meas[n, k] = s[S_XMEAS]
            i_app = _control(p, s, xr[n, k], vr[n, k], ar[n, k], u_force[n, k], u_off[n, k])
            f_motor = p[P_KT] * i_app
            f_sum = 0.0
            for _ in range(n_sub):
                f_sum += _substep(p, s, f_motor, h)
            s[S_T] += ts
            force[n, k] = f_motor
            friction[n, k] = f_sum / n_sub
            vx = s[S_V]
            if not (math.isfinite(vx) and math.isfinite(s[S_X]) and math.isfinite(s[S_I])):
                status[n] = STATUS_NONFINITE
                break
            if abs(vx) > RUNAWAY_VELOCITY or abs(s[S_X]) > RUNAWAY_POSITION:
                status[n] = STATUS_RUNAWAY
                break
            _measure(p, s, noise[n, k])


_measure = numba.njit(cache=True, inline="always")(_measure)
_friction_scale = numba.njit(cache=True, inline="always")(_friction_scale)
_substep = numba.njit(cache=True)(_substep)
_control = numba.njit(cache=True)(_control)
_run_serial = numba.njit(cache=True)(_run_impl)
_run_parallel = numba.njit(cache=True, parallel=True)(_run_impl)

PARALLEL_MIN_AXES = 256


def run_kernel(P: np.ndarray, S: np.ndarray, xr: np.ndarray, vr: np.ndarray, ar: np.ndarray,
               u_force: np.ndarray, u_off: np.ndarray, noise: np.ndarray,
               out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
               status: np.ndarray) -> None:
    """Advance ``N`` axes over ``K`` samples in place.

    Parameters
    ----------
    P : ndarray, shape (N, N_PARAMS)
        Packed parameters, one row per axis (see :meth:`fricbench.axis.Axis.pack`).
    S : ndarray, shape (N, N_STATE)
        States, updated in place.
    xr, vr, ar : ndarray, shape (N, K)
        Reference position (m), velocity (m/s) and acceleration (m/s^2).
    u_force : ndarray, shape (N, K)
        Compensation force added to the velocity-loop output (N).
    u_off : ndarray, shape (N, K)
        Reference offset (pre-compensation) added to the position reference (m).
    noise : ndarray, shape (N, K)
        Standard normal draws for the measurement taken after each sample.
    out : tuple of 4 ndarrays, shape (N, K)
        Filled with the true table position at ``t_k`` (m), the logged measured position (m),
        the motor force over ``[t_k, t_k+1)`` (N) and the mean friction force (N).
    status : ndarray of int64, shape (N,)
        Set to a non-zero ``STATUS_*`` code for an axis whose state diverged; that axis stops.
    """
    run = _run_parallel if P.shape[0] >= PARALLEL_MIN_AXES else _run_serial
    run(P, S, xr, vr, ar, u_force, u_off, noise, out[0], out[1], out[2], out[3], status)


@numba.njit(cache=True)
def _initial_measure(P: np.ndarray, S: np.ndarray, noise: np.ndarray) -> None:
    for n in range(P.shape[0]):
        _measure(P[n], S[n], noise[n])
        S[n, S_XFB_PREV] = S[n, S_XFB]


def initial_state(P: np.ndarray, x0: np.ndarray, v0: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """States of ``N`` axes at rest-or-moving initial conditions, with a first measurement.

    The velocity filter starts settled (``x_fb[-1] = x_fb[0]``) and the integrator at zero.
    """
    n = P.shape[0]
    S = np.zeros((n, N_STATE))
    S[:, S_X] = x0
    S[:, S_V] = v0
    S[:, S_XPLAY] = x0
    _initial_measure(P, S, noise)
    return S


__all__ = [
    "run_kernel",
    "initial_state",
    "N_PARAMS",
    "N_STATE",
    "DELAY_MAX",
    "STATUS_OK",
    "STATUS_NONFINITE",
    "STATUS_RUNAWAY",
    "KIND_STATIC",
    "KIND_LUGRE",
    "KIND_DAHL",
]

"""The one batched physics step of the servo feed axis.

Everything that simulates an axis (the scalar env, the native vector env, ``simulate``, the
benchmark runner and the diagnosis) calls :func:`run_kernel`, which advances ``N`` independent
axes over ``K`` control samples; the native vector env's fused step
(:mod:`fricbench.gym.vector_step`) inlines the same per-axis body, :func:`advance_axis`. There is
no second copy of these equations anywhere.

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
import os

import numba
import numpy as np

from fricbench.friction.laws import (
    KIND_DAHL,
    KIND_LUGRE,
    KIND_STATIC,
    stribeck_level,
    stribeck_level_taylor,
)

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


def _sensor(x_motor: float, x_play: float, t: float, th_amp: float, th_tau: float,
            q: float, meas_table: bool, noise: float) -> tuple[float, float]:
    """Feedback reading and logged (table) reading of one axis at time ``t``."""
    drift = 0.0
    if th_amp != 0.0:
        # d(t) = d_inf (1 - exp(-t / tau))
        drift = th_amp * (1.0 - math.exp(-t / th_tau))
    x_table = x_play + drift
    x_sensor = x_table if meas_table else x_motor
    if q > 0.0:
        x_sensor = q * math.floor(x_sensor / q + 0.5)
        x_table = q * math.floor(x_table / q + 0.5)
    return x_sensor + noise, x_table + noise


def _measure(p: np.ndarray, s: np.ndarray, noise: float) -> None:
    """Take a new sensor reading into state ``s`` (used at reset)."""
    fb, logged = _sensor(s[S_X], s[S_XPLAY], s[S_T], p[P_TH_AMP], p[P_TH_TAU], p[P_QUANT],
                         p[P_MEAS_TABLE] > 0.5, p[P_NOISE] * noise)
    s[S_XFB_PREV] = s[S_XFB]
    s[S_XFB] = fb
    s[S_XMEAS] = logged


def _mechanics(x: float, v: float, z: float, f_ext: float, h: float, m: float, b: float,
               kind: int, fc: float, fs: float, vs: float, delta: float, fv: float,
               sigma0: float, sigma1: float) -> tuple[float, float, float]:
    """One substep of ``M dv/dt = f_ext - B v - F_f``: returns ``(v_new, z_new, F_f)``."""
    damping = b + fv
    if kind == KIND_STATIC:
        # Kikuuwe: v+ = v* - h Sgn(v+) F_c / (M + h b); stick when |v*| <= h F_s / (M + h b).
        # Reciprocals of the per-axis constants are loop-invariant once inlined: the substep
        # chain then has no division on its critical path.
        inv_m_eff = 1.0 / (m + h * damping)
        h_inv_m_eff = h * inv_m_eff
        inv_vs = 1.0 / vs if vs > 0.0 else 0.0
        v_star = (m * v + h * f_ext) * inv_m_eff
        speed = abs(v_star)
        if speed <= h_inv_m_eff * max(fs, fc):
            v_new = 0.0
        else:
            level, slope, curv = stribeck_level_taylor(speed, fc, fs, inv_vs, delta)
            v_new = v_star - math.copysign(level * h_inv_m_eff, v_star)
            if v_new * v_star < 0.0:
                v_new = 0.0
            elif slope != 0.0:
                # one midpoint correction of the velocity-dependent level, 2nd-order accurate
                # in sliding where the Stribeck curve changes within a few substeps; the level
                # at the midpoint speed comes from its Taylor expansion about |v*| (one exp per
                # substep, not two; the midpoint is a fraction of vs away)
                v_mid = 0.5 * (abs(v_new) + (abs(v) if v * v_star > 0.0 else 0.0))
                dv = v_mid - speed
                level_mid = level + dv * (slope + 0.5 * curv * dv)
                level_mid = min(max(level_mid, min(fc, fs)), max(fc, fs))
                v_new = v_star - math.copysign(level_mid * h_inv_m_eff, v_star)
                if v_new * v_star < 0.0:
                    v_new = 0.0
        # F_f = (M v + h f_ext - M v+) / h - b v+
        f_fric = m * (v - v_new) * (1.0 / h) + f_ext - b * v_new
        return v_new, z, f_fric
    s1 = sigma1 if kind == KIND_LUGRE else 0.0
    g = fc if kind == KIND_DAHL else stribeck_level(abs(v), fc, fs, vs, delta)
    # dz/dt = v - sigma0 |v| z / g(v): exact for v frozen over the substep (stable for any h)
    if v != 0.0 and g > 0.0:
        z_ss = math.copysign(g / sigma0, v)
        z_new = z_ss + (z - z_ss) * math.exp(-sigma0 * abs(v) * h / g)
    else:
        z_new = z + v * h
    rate = (z_new - z) / h
    # F = sigma0 z + sigma1 dz/dt + fv v; the sigma1 v part of dz/dt is taken implicitly
    f_bristle = sigma0 * z_new + s1 * (rate - v)
    v_new = (m * v + h * (f_ext - f_bristle)) / (m + h * (damping + s1))
    return v_new, z_new, f_bristle + s1 * v_new + fv * v_new


def advance_axis(n: int, P: np.ndarray, S: np.ndarray, xr: np.ndarray, vr: np.ndarray,
              ar: np.ndarray, u_force: np.ndarray, u_off: np.ndarray, noise: np.ndarray,
              x_true: np.ndarray, x_meas: np.ndarray, force: np.ndarray, friction: np.ndarray,
              status: np.ndarray) -> None:
    """Advance axis ``n`` over all samples of its rows of ``xr, ...`` (inputs and outputs as in
    :func:`run_kernel`).

    The body shared by the serial and parallel drivers and by the fused vector-env step; it is
    inlined into each caller.
    """
    n_samples = xr.shape[1]
    p = P[n]
    s = S[n]
    # parameters and state live in locals over the whole run: the inner loop touches no
    # arrays but the inputs and outputs
    ts = p[P_TS]
    n_sub = int(p[P_NSUB])
    h = ts / n_sub
    m, b, kt, i_max = p[P_M], p[P_B], p[P_KT], p[P_IMAX]
    kp, kvff, kaff, kv, ti, f_load = p[P_KP], p[P_KVFF], p[P_KAFF], p[P_KV], p[P_TI], \
        p[P_FLOAD]
    kind = int(p[P_FKIND])
    fc0, fs0, vs, delta, fv = p[P_FC], p[P_FS], p[P_VS], p[P_DELTA], p[P_FV]
    sigma0, sigma1 = p[P_SIGMA0], p[P_SIGMA1]
    backlash = p[P_BACKLASH]
    cog_amp, cog_k, cog_ph = p[P_COG_AMP], 2.0 * math.pi / p[P_COG_PERIOD], p[P_COG_PHASE]
    pd_grad, pd_amp = p[P_PD_GRAD], p[P_PD_AMP]
    pd_k, pd_ph = 2.0 * math.pi / p[P_PD_PERIOD], p[P_PD_PHASE]
    th_amp, th_tau, quant = p[P_TH_AMP], p[P_TH_TAU], p[P_QUANT]
    meas_table = p[P_MEAS_TABLE] > 0.5
    sig_noise = p[P_NOISE]
    delay = int(p[P_DELAY])
    ki = ts / ti if ti > 0.0 else 0.0
    x, v, x_play, z = s[S_X], s[S_V], s[S_XPLAY], s[S_Z]
    integ, x_fb, x_fb_prev, t = s[S_I], s[S_XFB], s[S_XFB_PREV], s[S_T]
    x_logged, off_prev, i_app = s[S_XMEAS], s[S_OFF_PREV], s[S_IAPP]
    for k in range(n_samples):
        x_true[n, k] = x_play
        x_meas[n, k] = x_logged
        # -- controller ----------------------------------------------------------------
        off = u_off[n, k]
        # v_cmd = Kp (x_r - x_fb) + kvff v_r   (the offset's rate enters the feedforward)
        v_cmd = kp * (xr[n, k] + off - x_fb) + kvff * (vr[n, k] + (off - off_prev) / ts)
        off_prev = off
        e_v = v_cmd - (x_fb - x_fb_prev) / ts
        # i = Kv (e_v + I) + (kaff M a_r + u) / Kt
        i_cmd = kv * (e_v + integ) + (kaff * m * ar[n, k] + u_force[n, k]) / kt
        if delay > 0:
            i_app = s[S_DBUF + delay - 1]
            for j in range(delay - 1, 0, -1):
                s[S_DBUF + j] = s[S_DBUF + j - 1]
            s[S_DBUF] = i_cmd
        else:
            i_app = i_cmd
        saturated = False
        if i_app > i_max:
            i_app = i_max
            saturated = e_v > 0.0
        elif i_app < -i_max:
            i_app = -i_max
            saturated = e_v < 0.0
        # clamping anti-windup: freeze I while the output saturates in the direction of e_v
        if not saturated:
            integ += ki * e_v
        f_motor = kt * i_app
        # -- mechanics over n_sub substeps (zero-order hold on the force) -----------------
        f_sum = 0.0
        for _ in range(n_sub):
            scale = 1.0 + pd_grad * x
            if pd_amp != 0.0:
                scale += pd_amp * math.sin(pd_k * x + pd_ph)
            f_ext = f_motor - f_load
            if cog_amp != 0.0:
                # F_cog = A sin(2 pi x / lambda + phi)
                f_ext -= cog_amp * math.sin(cog_k * x + cog_ph)
            v_new, z, f_fric = _mechanics(x, v, z, f_ext, h, m, b, kind, fc0 * scale,
                                          fs0 * scale, vs, delta, fv, sigma0, sigma1)
            # trapezoidal position: exact when the velocity changes linearly over h
            x += 0.5 * h * (v + v_new)
            v = v_new
            f_sum += f_fric
            if backlash > 0.0:
                # play operator: the table follows only once the lost motion is taken up
                if x - x_play > 0.5 * backlash:
                    x_play = x - 0.5 * backlash
                elif x - x_play < -0.5 * backlash:
                    x_play = x + 0.5 * backlash
            else:
                x_play = x
        t += ts
        force[n, k] = f_motor
        friction[n, k] = f_sum / n_sub
        if not (math.isfinite(v) and math.isfinite(x) and math.isfinite(integ)):
            status[n] = STATUS_NONFINITE
            break
        if abs(v) > RUNAWAY_VELOCITY or abs(x) > RUNAWAY_POSITION:
            status[n] = STATUS_RUNAWAY
            break
        # -- sensor reading for the next sample ------------------------------------------
        x_fb_prev = x_fb
        x_fb, x_logged = _sensor(x, x_play, t, th_amp, th_tau, quant, meas_table,
                                 sig_noise * noise[n, k])
    s[S_X], s[S_V], s[S_XPLAY], s[S_Z] = x, v, x_play, z
    s[S_I], s[S_XFB], s[S_XFB_PREV], s[S_T] = integ, x_fb, x_fb_prev, t
    s[S_XMEAS], s[S_OFF_PREV], s[S_IAPP] = x_logged, off_prev, i_app


# Fast-math without the no-NaN/no-inf assumptions, so that the divergence checks stay valid:
# reciprocals, fused multiply-add and reassociation change results by rounding only.
FASTMATH = {"arcp", "contract", "reassoc", "nsz", "afn"}
_sensor = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(_sensor)
_measure = numba.njit(cache=True)(_measure)
_mechanics = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(_mechanics)
advance_axis = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(advance_axis)


# Two drivers, two distinct functions: numba's on-disk cache is keyed by function, so one
# function compiled twice (serial and parallel) would share a cache entry and the serial
# dispatcher could load the threaded build, paying a thread wake-up on every env step.
@numba.njit(cache=True, fastmath=FASTMATH)
def _run_serial(P: np.ndarray, S: np.ndarray, xr: np.ndarray, vr: np.ndarray, ar: np.ndarray,
                u_force: np.ndarray, u_off: np.ndarray, noise: np.ndarray, x_true: np.ndarray,
                x_meas: np.ndarray, force: np.ndarray, friction: np.ndarray,
                status: np.ndarray) -> None:
    for n in range(xr.shape[0]):
        advance_axis(n, P, S, xr, vr, ar, u_force, u_off, noise, x_true, x_meas, force, friction,
                  status)


@numba.njit(cache=True, parallel=True, fastmath=FASTMATH)
def _run_parallel(P: np.ndarray, S: np.ndarray, xr: np.ndarray, vr: np.ndarray,
                  ar: np.ndarray, u_force: np.ndarray, u_off: np.ndarray, noise: np.ndarray,
                  x_true: np.ndarray, x_meas: np.ndarray, force: np.ndarray,
                  friction: np.ndarray, status: np.ndarray) -> None:
    for n in numba.prange(xr.shape[0]):
        advance_axis(n, P, S, xr, vr, ar, u_force, u_off, noise, x_true, x_meas, force, friction,
                  status)

# The threaded driver wins on an idle machine (8.1 M axis-steps/s at 4096 axes on 2 cores vs
# about 6 M serial) but collapses to 0.5 M when another process holds a core, because each
# parallel loop waits for its slowest thread. Shared machines are the norm here, so threads are
# opt-in: FRICBENCH_PARALLEL=1 uses them for batches of at least PARALLEL_MIN_AXES axes.
PARALLEL_MIN_AXES = 256 if os.environ.get("FRICBENCH_PARALLEL", "0") == "1" else 2**62


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
    "DELAY_MAX",
    "FASTMATH",
    "KIND_DAHL",
    "KIND_LUGRE",
    "KIND_STATIC",
    "N_PARAMS",
    "N_STATE",
    "STATUS_NONFINITE",
    "STATUS_OK",
    "STATUS_RUNAWAY",
    "advance_axis",
    "initial_state",
    "run_kernel",
]

"""The cascade controller driving the plant: the batched step of the environments.

:func:`run_kernel` advances ``N`` independent axes over ``K`` control samples; the scalar env,
the native vector env (whose fused step, :mod:`fricbench.gym.vector_step`, inlines the same
per-axis body :func:`advance_axis`), ``simulate`` and the benchmark runner call it. The
physics (actuator, mechanics, effects, sensor) is :mod:`fricbench.axis.plant`, which the
identified-law driver of the diagnosis (:mod:`fricbench.axis.linear_law`) calls too: there is
one copy of the plant's equations.

Per control sample ``k`` (period ``Ts``, zero-order hold on the current command):

1. the controller reads the measured position ``x_fb[k]`` (motor encoder or linear scale),
2. position P + velocity feedforward: ``v_cmd = Kp (x_r - x_fb) + kvff v_r``,
3. velocity PI on the backward-difference velocity ``(x_fb[k] - x_fb[k-1]) / Ts`` with
   clamping anti-windup, plus acceleration feedforward and the compensation force, gives the
   current command ``i = Kv (e_v + I) + (kaff M a_r + u_comp) / Kt`` (A),
4. the plant: optional pure delay of ``d`` samples, current saturation ``|i| <= i_max``, the
   mechanics over ``n_sub`` substeps, backlash, thermal drift and the sensor
   (:func:`fricbench.axis.plant.advance`, :func:`fricbench.axis.plant.sense`).

An axis whose controller is an identified linear law (``ControllerParams.law = "linear"``,
``P_LAW = 1``: the digital twin a diagnosis writes) replaces steps 2 and 3 by that law in its
reference form::

    u[k] = sum_i a_i u[k-i] + k_x x_r[k] + k_v v_r[k] + k_a a_r[k] + sum_m g_m x_r[k-m]
           + sum_j c_j x_fb[k-j]
    i = sat(u[k]) + u_comp / Kt

the same law :mod:`fricbench.axis.linear_law` runs for the diagnosis; its taps on the past
reference are kept as they are, those on the future reference (a planned trajectory's look-ahead)
are folded into the gains on the present position, velocity and acceleration.
"""

from __future__ import annotations

import math
import os
from typing import NamedTuple

import numba
import numpy as np

from fricbench.axis import plant as PL
from fricbench.axis.plant import (
    DELAY_MAX,
    FASTMATH,
    KIND_DAHL,
    KIND_LUGRE,
    KIND_STATIC,
    N_PLANT,
)

# -- parameter vector layout (columns of P, one row per axis) ------------------------------------
# the plant row of :mod:`fricbench.axis.plant` first, then the cascade's gains
P_TS, P_NSUB, P_M, P_B, P_KT, P_IMAX, P_DELAY = PL.TS, PL.NSUB, PL.M, PL.B, PL.KT, PL.IMAX, PL.DELAY
P_FKIND, P_FC, P_DFC, P_FS_EXCESS, P_VS, P_DELTA = PL.FKIND, PL.FC, PL.DFC, PL.FS_EXCESS, PL.VS, \
    PL.DELTA
P_FV, P_DB, P_SIGMA0, P_SIGMA1, P_FLOAD = PL.FV, PL.DB, PL.SIGMA0, PL.SIGMA1, PL.OFFSET
P_COG_SIN, P_COG_COS, P_COG_PERIOD = PL.COG_SIN, PL.COG_COS, PL.COG_PERIOD
P_PD_GRAD, P_PD_SIN, P_PD_COS, P_PD_PERIOD = PL.PD_GRAD, PL.PD_SIN, PL.PD_COS, PL.PD_PERIOD
P_BACKLASH, P_TH_AMP, P_TH_TAU, P_QUANT, P_NOISE, P_MEAS_TABLE = (
    PL.BACKLASH, PL.TH_AMP, PL.TH_TAU, PL.QUANT, PL.NOISE, PL.MEAS_TABLE)
P_COMP_RATIO, P_COMP_FREQ, P_COMP_ZETA, P_LOG_MOTOR = (PL.COMP_RATIO, PL.COMP_FREQ,
                                                       PL.COMP_ZETA, PL.LOG_MOTOR)
P_KP, P_KVFF, P_KAFF, P_KV, P_TI = range(N_PLANT, N_PLANT + 5)
# the identified linear law that replaces the cascade when P_LAW is 1:
# u[k] = sum_i a_i u[k-i] + k_x x_r[k] + k_v v_r[k] + k_a a_r[k] + sum_m g_m x_r[k-m]
#        + sum_j c_j y_fb[k-j]
LAW_NA_MAX = 4
"""Most recursion coefficients ``a_1 .. a_na`` of a linear law."""
LAW_NC_MAX = 8
"""Most position coefficients ``c_0 .. c_(nc-1)`` of a linear law."""
LAW_NR_MAX = 8
"""Most coefficients ``g_1 .. g_nr`` of a linear law on the past reference."""
(P_LAW, P_LAW_NA, P_LAW_NC, P_LAW_NR, P_LAW_KX, P_LAW_KV,
 P_LAW_KA) = range(N_PLANT + 5, N_PLANT + 12)
P_LAW_A = N_PLANT + 12
P_LAW_C = P_LAW_A + LAW_NA_MAX
P_LAW_G = P_LAW_C + LAW_NC_MAX
N_PARAMS = P_LAW_G + LAW_NR_MAX

# -- state vector layout (columns of S): the plant's state, then the cascade's ---------------------
S_X, S_V, S_XPLAY, S_Z, S_DEF, S_DEFV = PL.S_X, PL.S_V, PL.S_XPLAY, PL.S_Z, PL.S_DEF, PL.S_DEFV
S_HEAT = PL.S_HEAT
S_I, S_XFB, S_XFB_PREV, S_T, S_XMEAS, S_OFF_PREV, S_IAPP = range(PL.N_PLANT_STATE,
                                                                 PL.N_PLANT_STATE + 7)
S_DBUF = PL.N_PLANT_STATE + 7
# the linear law's histories: u[k-1] .. u[k-na] and y_fb[k-1] .. y_fb[k-nc+1]
# and x_r[k-1] .. x_r[k-nr], filled at the first sample (S_LAW_READY = 0 until then)
S_LAW_U = S_DBUF + DELAY_MAX
S_LAW_Y = S_LAW_U + LAW_NA_MAX
S_LAW_R = S_LAW_Y + LAW_NC_MAX
S_LAW_READY = S_LAW_R + LAW_NR_MAX
N_STATE = S_LAW_READY + 1

# -- status codes ---------------------------------------------------------------------------------
STATUS_OK = 0
STATUS_NONFINITE = 1
STATUS_RUNAWAY = 2
RUNAWAY_VELOCITY = 100.0  # m/s: no feed axis moves this fast; the loop has gone unstable
RUNAWAY_POSITION = 1.0e3  # m


def _measure(p: np.ndarray, s: np.ndarray, noise: float) -> None:
    """Take a new sensor reading into state ``s`` (used at reset)."""
    c = PL.constants(p)
    fb, logged = PL.sense(c, s[S_X], s[S_XPLAY], s[S_DEF], s[S_HEAT], s[S_T], c.noise * noise)
    s[S_XFB_PREV] = s[S_XFB]
    s[S_XFB] = fb
    s[S_XMEAS] = logged


class Gains(NamedTuple):
    """The cascade's gains and the linear law's sizes of a parameter row, unpacked once
    (:func:`gains`): scalars, not array loads, so that a caller stepping many axes that share
    one row reads them, and computes ``Ts / Ti`` and the reciprocals of ``Ts`` and ``Kt``,
    once per step instead of once per axis."""

    ts: float
    kp: float
    kvff: float
    kaff: float
    kv: float
    ti: float
    ki: float  # Ts / Ti (0 without an integrator)
    law: bool  # the identified linear law replaces the cascade
    na: int
    nc: int
    nr: int


def gains(p: np.ndarray) -> Gains:
    """Unpack the controller entries of parameter row ``p``."""
    ts, ti = p[P_TS], p[P_TI]
    return Gains(ts, p[P_KP], p[P_KVFF], p[P_KAFF], p[P_KV], ti, ts / ti if ti > 0.0 else 0.0,
                 p[P_LAW] > 0.5, int(p[P_LAW_NA]), int(p[P_LAW_NC]), int(p[P_LAW_NR]))


def advance_axis(n: int, P: np.ndarray, S: np.ndarray, xr: np.ndarray, vr: np.ndarray,
                 ar: np.ndarray, u_force: np.ndarray, u_off: np.ndarray, noise: np.ndarray,
                 x_true: np.ndarray, x_meas: np.ndarray, force: np.ndarray,
                 friction: np.ndarray, status: np.ndarray) -> None:
    """Advance axis ``n`` over all samples of its rows of ``xr, ...`` (inputs and outputs as in
    :func:`run_kernel`).

    The cascade controller around :mod:`fricbench.axis.plant`; the body shared by the serial
    and parallel drivers, inlined into each caller.
    """
    p = P[n]
    advance_axis_with(PL.constants(p), gains(p), p, n, n, S, xr, vr, ar, u_force, u_off,
                      noise, x_true, x_meas, force, friction, status)


def advance_axis_with(c: PL.Plant, g: Gains, p: np.ndarray, n: int, r: int, S: np.ndarray,
                      xr: np.ndarray, vr: np.ndarray, ar: np.ndarray, u_force: np.ndarray,
                      u_off: np.ndarray, noise: np.ndarray, x_true: np.ndarray,
                      x_meas: np.ndarray, force: np.ndarray, friction: np.ndarray,
                      status: np.ndarray) -> None:
    """:func:`advance_axis` with axis ``n``'s parameter row ``p`` (``P[n]``, or a row equal
    to it), its plant constants ``c`` (:func:`fricbench.axis.plant.constants`) and its gains
    ``g`` (:func:`gains`) already unpacked.

    The fused vector-env step advances each axis by one sample per call; unpacking its plant
    row (divisions, branches) at every call would cost a third of the sample, so it passes
    constants unpacked once per parameter change. When every axis holds the same row it passes
    that one row's constants and gains for all: they are then scalars the compiler keeps out
    of the loop over the axes (``Ts / Ti`` and the reciprocals of ``Ts`` and ``Kt`` computed
    once per step, no gain read from the row per axis), which array reads from the row, that
    the compiler cannot prove the state writes leave alone, are not. The row itself is read
    by the linear law only.
    """
    n_samples = xr.shape[1]
    s = S[n]
    # parameters and state live in locals over the whole run: the inner loop touches no
    # arrays but the inputs and outputs
    ts = g.ts
    m, kt = c.m, c.kt
    kp, kvff, kaff, kv = g.kp, g.kvff, g.kaff, g.kv
    ki = g.ki
    x, v, x_play, z, d, dv = s[S_X], s[S_V], s[S_XPLAY], s[S_Z], s[S_DEF], s[S_DEFV]
    theta = s[S_HEAT]
    integ, x_fb, x_fb_prev, t = s[S_I], s[S_XFB], s[S_XFB_PREV], s[S_T]
    x_logged, off_prev, i_app = s[S_XMEAS], s[S_OFF_PREV], s[S_IAPP]
    law = g.law
    na, nc, nr = g.na, g.nc, g.nr
    for k in range(n_samples):
        x_true[r, k] = x_play + d
        x_meas[r, k] = x_logged
        # -- controller ----------------------------------------------------------------
        off = u_off[r, k]
        if law:
            # the offset enters as a reference change, its rate as a reference velocity
            v_off = (off - off_prev) / ts
            off_prev = off
            x_ref = xr[r, k] + off
            v_ref = vr[r, k] + v_off
            if s[S_LAW_READY] == 0.0:
                # the reference before the first sample: extended at constant velocity
                for q in range(nr):
                    s[S_LAW_R + q] = x_ref - (q + 1) * ts * v_ref
                s[S_LAW_READY] = 1.0
            # u = sum_i a_i u[k-i] + k_x x_r + k_v v_r + k_a a_r + sum_m g_m x_r[k-m]
            #     + sum_j c_j y_fb[k-j]
            u_law = (p[P_LAW_KX] * x_ref + p[P_LAW_KV] * v_ref + p[P_LAW_KA] * ar[r, k]
                     + p[P_LAW_C] * x_fb)
            for q in range(nr):
                u_law += p[P_LAW_G + q] * s[S_LAW_R + q]
            for i in range(na):
                u_law += p[P_LAW_A + i] * s[S_LAW_U + i]
            for j in range(1, nc):
                u_law += p[P_LAW_C + j] * s[S_LAW_Y + j - 1]
            # the law recurses on its clipped output (a drive logs what it applies), so a
            # velocity-form law winds up no integrator
            u_law = min(max(u_law, -c.i_max), c.i_max)
            for i in range(na - 1, 0, -1):
                s[S_LAW_U + i] = s[S_LAW_U + i - 1]
            s[S_LAW_U] = u_law
            for j in range(nc - 2, 0, -1):
                s[S_LAW_Y + j] = s[S_LAW_Y + j - 1]
            s[S_LAW_Y] = x_fb
            for q in range(nr - 1, 0, -1):
                s[S_LAW_R + q] = s[S_LAW_R + q - 1]
            s[S_LAW_R] = x_ref
            i_cmd = u_law + u_force[r, k] / kt
            i_app, clipped = PL.actuate(c, s, S_DBUF, i_cmd)
        else:
            # v_cmd = Kp (x_r - x_fb) + kvff v_r   (the offset's rate enters the feedforward);
            # written as before the linear law existed: fast-math may reorder another form
            v_cmd = kp * (xr[r, k] + off - x_fb) + kvff * (vr[r, k] + (off - off_prev) / ts)
            off_prev = off
            e_v = v_cmd - (x_fb - x_fb_prev) / ts
            # i = Kv (e_v + I) + (kaff M a_r + u) / Kt
            i_cmd = kv * (e_v + integ) + (kaff * m * ar[r, k] + u_force[r, k]) / kt
            # -- plant: actuator --------------------------------------------------------
            i_app, clipped = PL.actuate(c, s, S_DBUF, i_cmd)
            # clamping anti-windup: freeze I while the output saturates in the direction of e_v
            if not (clipped * e_v > 0.0):
                integ += ki * e_v
        f_motor = kt * i_app
        # -- plant: mechanics over n_sub substeps ---------------------------------------
        x, v, z, x_play, d, dv, theta, f_fric = PL.advance(c, x, v, z, x_play, d, dv, theta,
                                                           f_motor)
        t += ts
        force[r, k] = f_motor
        friction[r, k] = f_fric
        if not (math.isfinite(v) and math.isfinite(x) and math.isfinite(integ)):
            status[n] = STATUS_NONFINITE
            break
        if abs(v) > RUNAWAY_VELOCITY or abs(x) > RUNAWAY_POSITION:
            status[n] = STATUS_RUNAWAY
            break
        # -- plant: sensor reading for the next sample -----------------------------------
        x_fb_prev = x_fb
        x_fb, x_logged = PL.sense(c, x, x_play, d, theta, t, c.noise * noise[r, k])
    s[S_X], s[S_V], s[S_XPLAY], s[S_Z], s[S_DEF], s[S_DEFV] = x, v, x_play, z, d, dv
    s[S_HEAT] = theta
    s[S_I], s[S_XFB], s[S_XFB_PREV], s[S_T] = integ, x_fb, x_fb_prev, t
    s[S_XMEAS], s[S_OFF_PREV], s[S_IAPP] = x_logged, off_prev, i_app


# fast-math as in the plant (FASTMATH): rounding-level changes only, divergence checks kept
_measure = numba.njit(cache=True)(_measure)
gains = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(gains)
advance_axis_with = numba.njit(cache=True, inline="always", fastmath=FASTMATH)(advance_axis_with)
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
        Filled with the true table position at ``t_k`` (m; after play and compliant
        deflection, without the thermal drift), the logged measured position (m),
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

    The cascade's velocity filter starts settled (``x_fb[-1] = x_fb[0]``) and its integrator
    at zero; a linear law's position history is the first reading extrapolated back at ``v0``
    (``y_fb[-j] = y_fb[0] - j v0 ts``), its output history zero.
    """
    n = P.shape[0]
    S = np.zeros((n, N_STATE))
    S[:, S_X] = x0
    S[:, S_V] = v0
    S[:, S_XPLAY] = x0
    _initial_measure(P, S, noise)
    back = np.arange(1, LAW_NC_MAX + 1)
    S[:, S_LAW_Y:S_LAW_Y + LAW_NC_MAX] = (S[:, S_XFB, None]
                                          - np.outer(np.asarray(v0) * P[:, P_TS], back))
    return S


__all__ = [
    "DELAY_MAX",
    "FASTMATH",
    "KIND_DAHL",
    "KIND_LUGRE",
    "KIND_STATIC",
    "LAW_NA_MAX",
    "LAW_NC_MAX",
    "LAW_NR_MAX",
    "N_PARAMS",
    "N_STATE",
    "STATUS_NONFINITE",
    "STATUS_OK",
    "STATUS_RUNAWAY",
    "advance_axis",
    "advance_axis_with",
    "Gains",
    "gains",
    "initial_state",
    "run_kernel",
]

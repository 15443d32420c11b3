"""Free-run simulation of the grey-box closed loop: identified controller + mass + effects.

The diagnosis predicts the measured position from the reference alone. Between them sits a
loop this module simulates sample by sample::

    u[k]   = sum_i a_i u[k-i] + r[k] + sum_j c_j y_fb[k-j] + w[k]      (linear controller, ARX)
    M dv/dt = u - B v - F_eff(x, v) ,  dx/dt = v                       (rigid mass, ZOH on u)
    y[k]   = play_b(x(t_k)) + d(t_k)                                  (logged position)

* the controller is any linear discrete law: ``r[k]`` is its precomputed reference part
  (position, velocity and acceleration feedforward), ``c_j`` its feedback on the position the
  controller sees (the motor side, ``x`` itself), ``a_i`` its own recursion (``a_1 = 1`` is an
  integrator); ``w`` an optional injected effort (test pulses);
* ``F_eff`` holds the force effects of the candidate library: Coulomb and Stribeck friction
  with true stiction (the implicit update of Kikuuwe et al. 2005, as in the axis kernel),
  direction-dependent Coulomb and viscous levels, a constant force, a position-periodic
  (cogging) force and position-dependent friction levels;
* backlash (a play operator) and thermal growth ``d(t) = d_inf (1 - exp(-t/tau))`` act between
  the motor and the logged position, outside the loop (motor-side feedback).

The friction level itself is :func:`fricbench.friction.laws.stribeck_level`, the one friction
law of the project. The axis kernel (:mod:`fricbench.axis.kernel`) is *not* reused: it
simulates one particular cascade controller, whereas the diagnosis must model loops it has not
seen (any linear controller identified from the data) and effects the kernel lacks
(direction-dependent friction).

Units: any consistent set. With a measured effort, forces are in the effort's unit (N when it is
a force) and ``M`` in that unit per m/s^2; without one the mass is normalised to 1 and every
force is an acceleration (m/s^2).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from fricbench.friction.laws import stribeck_level, stribeck_level_taylor

__all__ = ["N_PLANT", "PLANT_NAMES", "simulate_batch", "simulate_one", "default_plant",
           "sliding_force",
           "I_M", "I_B", "I_FC", "I_DFC", "I_DB", "I_FS", "I_VS", "I_OFF", "I_COGA", "I_COGB",
           "I_COGP", "I_PDG", "I_PDA", "I_PDB", "I_PDP", "I_XC", "I_BL", "I_THA", "I_THT"]

# -- plant/effect parameter layout ------------------------------------------------------------
(I_M, I_B, I_FC, I_DFC, I_DB, I_FS, I_VS, I_OFF, I_COGA, I_COGB, I_COGP, I_PDG, I_PDA, I_PDB,
 I_PDP, I_XC, I_BL, I_THA, I_THT) = range(19)
N_PLANT = 19
PLANT_NAMES = ("mass", "damping", "fc", "dfc", "dB", "fs_excess", "vs", "offset", "cog_sin",
               "cog_cos", "cog_period", "pd_gradient", "pd_sin", "pd_cos", "pd_period",
               "x_center", "backlash", "thermal_amplitude", "thermal_tau")


def default_plant(mass: float = 1.0, damping: float = 0.0) -> np.ndarray:
    """Plant row with every effect off (periods and time constants at harmless values)."""
    p = np.zeros(N_PLANT)
    p[I_M] = mass
    p[I_B] = damping
    p[I_VS] = 1.0e-3
    p[I_COGP] = 1.0
    p[I_PDP] = 1.0
    p[I_THT] = 1.0
    return p


@numba.njit(cache=True, inline="always")
def _scale(p: np.ndarray, x: float) -> float:
    # scale(x) = 1 + g (x - xc) + a sin(2 pi x / P) + b cos(2 pi x / P)
    s = 1.0 + p[I_PDG] * (x - p[I_XC])
    if p[I_PDA] != 0.0 or p[I_PDB] != 0.0:
        ph = 2.0 * math.pi * x / p[I_PDP]
        s += p[I_PDA] * math.sin(ph) + p[I_PDB] * math.cos(ph)
    return max(s, 0.0)


@numba.njit(cache=True, inline="always")
def _coulomb(p: np.ndarray, sigma: float) -> float:
    """Coulomb level in direction ``sigma`` (``fc +- dfc / 2``, never negative)."""
    return max(p[I_FC] + 0.5 * sigma * p[I_DFC], 0.0)


@numba.njit(cache=True, inline="always")
def _level(p: np.ndarray, speed: float, sigma: float, scale: float) -> float:
    """Sliding friction level (without viscous part) in direction ``sigma``, N."""
    fc = _coulomb(p, sigma)
    if p[I_FS] == 0.0:
        return scale * fc  # no Stribeck term: skip the exponential
    fs = fc + p[I_FS]
    return scale * stribeck_level(speed, fc, fs, p[I_VS], 2.0)


@numba.njit(cache=True, inline="always")
def _level_taylor(p: np.ndarray, speed: float, sigma: float,
                  scale: float) -> tuple[float, float, float]:
    """:func:`_level` with its first and second derivatives in ``speed`` (one ``exp``)."""
    fc = _coulomb(p, sigma)
    if p[I_FS] == 0.0 or p[I_VS] <= 0.0:
        return scale * fc, 0.0, 0.0
    g, dg, d2g = stribeck_level_taylor(speed, fc, fc + p[I_FS], 1.0 / p[I_VS], 2.0)
    return scale * g, scale * dg, scale * d2g


@numba.njit(cache=True)
def _sliding_force(p: np.ndarray, x: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    for k in range(x.shape[0]):
        vk = v[k]
        f = p[I_OFF]
        if p[I_COGA] != 0.0 or p[I_COGB] != 0.0:
            ph = 2.0 * math.pi * x[k] / p[I_COGP]
            f += p[I_COGA] * math.sin(ph) + p[I_COGB] * math.cos(ph)
        if vk != 0.0:
            sigma = 1.0 if vk > 0.0 else -1.0
            damp = p[I_B] + 0.5 * sigma * p[I_DB]
            if damp < 0.0:
                damp = 0.0
            f += damp * vk + sigma * _level(p, abs(vk), sigma, _scale(p, x[k]))
        out[k] = f


def sliding_force(p: np.ndarray, x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Force of the plant model opposing the motor, ``B v + F_eff(x, v)``, while sliding.

    The same force law as the simulator (at ``v = 0`` only the constant and cogging forces;
    the friction then takes whatever value holds the axis, which an inverse model cannot
    know). Used by the inverse-dynamics effort model ``u = M a + B v + F_eff``.

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


@numba.njit(cache=True, inline="always")
def _substep(p: np.ndarray, x: float, v: float, force: float, h: float, inv_pos: float,
             inv_neg: float) -> tuple[float, float]:
    """One implicit step of the mass; ``inv_pos``/``inv_neg`` are ``1 / (M + h B_dir)``."""
    m = p[I_M]
    f_ext = force - p[I_OFF]
    if p[I_COGA] != 0.0 or p[I_COGB] != 0.0:
        # F_cog = a sin(2 pi x / lambda) + b cos(2 pi x / lambda)
        ph = 2.0 * math.pi * x / p[I_COGP]
        f_ext -= p[I_COGA] * math.sin(ph) + p[I_COGB] * math.cos(ph)
    mom = m * v + h * f_ext
    sigma = 1.0 if mom > 0.0 else -1.0
    inv_meff = inv_pos if mom > 0.0 else inv_neg  # 1 / (M + h B_dir), precomputed
    scale = _scale(p, x)
    # Kikuuwe: stick when |M v + h F| <= h F_s, the level at rest g(0) = s(x) (fc + fs)
    fc_dir = _coulomb(p, sigma)
    if abs(mom) <= h * scale * (fc_dir + p[I_FS]):
        v_new = 0.0
    else:
        v_star = mom * inv_meff
        speed = abs(v_star)
        level, slope, curv = _level_taylor(p, speed, sigma, scale)
        v_new = v_star - sigma * h * level * inv_meff
        if v_new * sigma < 0.0:
            v_new = 0.0
        elif slope != 0.0:
            # midpoint correction of the velocity-dependent Stribeck level, from its Taylor
            # expansion about |v*| (as the axis kernel does)
            v_mid = 0.5 * (abs(v_new) + (abs(v) if v * sigma > 0.0 else 0.0))
            dv = v_mid - speed
            level_mid = level + dv * (slope + 0.5 * curv * dv)
            lo = scale * fc_dir
            level_mid = min(max(level_mid, lo), lo + scale * p[I_FS])
            v_new = v_star - sigma * h * level_mid * inv_meff
            if v_new * sigma < 0.0:
                v_new = 0.0
    # trapezoidal position update
    return x + 0.5 * h * (v + v_new), v_new


@numba.njit(cache=True)
def _run_one(p: np.ndarray, a: np.ndarray, c: np.ndarray, r: np.ndarray, w: np.ndarray,
             t: np.ndarray, ts: float, n_sub: int, x0: float, v0: float, u_init: np.ndarray,
             y_init: np.ndarray, noise: np.ndarray, quant: float, y_out: np.ndarray,
             u_out: np.ndarray) -> int:
    n = r.shape[0]
    na = a.shape[0]
    nc = c.shape[0]
    # histories: uh[i] = u[k-1-i], yh[j] = y_fb[k-j] (yh[0] is filled each sample)
    uh = u_init.copy()
    yh = np.empty(max(nc, 1))
    for j in range(nc):
        yh[j] = y_init[j] if j < y_init.shape[0] else y_init[-1]
    x = x0
    v = v0
    play = x0
    h = ts / n_sub
    b = p[I_BL]
    half = 0.5 * b
    # M_eff = M + h B_dir, B_dir = max(B +- dB / 2, 0)
    inv_pos = 1.0 / (p[I_M] + h * max(p[I_B] + 0.5 * p[I_DB], 0.0))
    inv_neg = 1.0 / (p[I_M] + h * max(p[I_B] - 0.5 * p[I_DB], 0.0))
    for k in range(n):
        # logged position: play operator (updated every substep) and thermal growth
        if b <= 0.0:
            play = x
        drift = 0.0
        if p[I_THA] != 0.0:
            # d(t) = d_inf (1 - exp(-t / tau))
            drift = p[I_THA] * (1.0 - math.exp(-t[k] / p[I_THT]))
        # sensors: optional quantisation and noise (to measure the noise floor of a run)
        y_k = play + drift
        x_fb = x
        if quant > 0.0:
            y_k = quant * math.floor(y_k / quant + 0.5)
            x_fb = quant * math.floor(x_fb / quant + 0.5)
        y_out[k] = y_k + noise[k]
        # controller (feedback on the motor-side position x)
        for j in range(nc - 1, 0, -1):
            yh[j] = yh[j - 1]
        if nc > 0:
            yh[0] = x_fb + noise[k]
        u = r[k] + w[k]
        for i in range(na):
            u += a[i] * uh[i]
        for j in range(nc):
            u += c[j] * yh[j]
        for i in range(na - 1, 0, -1):
            uh[i] = uh[i - 1]
        if na > 0:
            uh[0] = u
        u_out[k] = u
        for _ in range(n_sub):
            x, v = _substep(p, x, v, u, h, inv_pos, inv_neg)
            if b > 0.0:
                # play operator: the output follows only after the lost motion b is taken up
                if x - play > half:
                    play = x - half
                elif x - play < -half:
                    play = x + half
        if not (math.isfinite(x) and abs(v) < 1.0e6):
            for kk in range(k + 1, n):
                y_out[kk] = np.nan
                u_out[kk] = np.nan
            return 1
    return 0


@numba.njit(cache=True, parallel=True)
def _run_batch(P: np.ndarray, A: np.ndarray, C: np.ndarray, R: np.ndarray, w: np.ndarray,
               t: np.ndarray, ts: float, n_sub: int, x0: float, v0: float, U0: np.ndarray,
               y_init: np.ndarray, noise: np.ndarray, quant: float, Y: np.ndarray,
               U: np.ndarray, status: np.ndarray) -> None:
    for i in numba.prange(P.shape[0]):
        status[i] = _run_one(P[i], A[i], C[i], R[i], w, t, ts, n_sub, x0, v0, U0[i], y_init,
                             noise, quant, Y[i], U[i])


def simulate_batch(plant: np.ndarray, a: np.ndarray, c: np.ndarray, r: np.ndarray,
                   t: np.ndarray, ts: float, *, n_sub: int, x0: float, v0: float,
                   u_init: np.ndarray, y_init: np.ndarray, w: np.ndarray | None = None,
                   noise: np.ndarray | None = None, quant: float = 0.0,
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Simulate ``N`` parameter sets of the closed loop in parallel (one row each).

    Parameters
    ----------
    plant : ndarray, shape (N, N_PLANT)
        Plant and effect parameters (layout ``I_*``).
    a : ndarray, shape (N, na)
        Controller recursion coefficients on ``u[k-1] .. u[k-na]``.
    c : ndarray, shape (N, nc)
        Controller feedback coefficients on ``x[k] .. x[k-nc+1]``.
    r : ndarray, shape (N, K)
        Reference part of the controller output.
    t : ndarray, shape (K,)
        Sample times from the start of the run, s.
    ts : float
        Sample time, s.
    n_sub : int
        Plant substeps per sample.
    x0, v0 : float
        Initial motor position (m) and velocity (m/s).
    u_init : ndarray, shape (N, na)
        Controller output history ``u[-1] .. u[-na]``.
    y_init : ndarray, shape (nc,)
        Feedback history before the run, ``x[-1], x[-2], ...``, m.
    w : ndarray, shape (K,), optional
        Injected effort added to the controller output.
    noise : ndarray, shape (K,), optional
        Measurement noise added to the fed-back and the logged position, m.
    quant : float
        Quantisation step of both sensors, m (0: none).

    Returns
    -------
    y : ndarray, shape (N, K)
        Logged position, m (NaN after a divergence).
    u : ndarray, shape (N, K)
        Controller output (effort).
    status : ndarray of int64, shape (N,)
        0 when the row stayed finite, 1 when it diverged.
    """
    plant = np.ascontiguousarray(np.atleast_2d(plant), dtype=float)
    n_rows, n = plant.shape[0], r.shape[-1]
    A = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(a), (n_rows, np.shape(a)[-1])),
                             dtype=float)
    C = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(c), (n_rows, np.shape(c)[-1])),
                             dtype=float)
    R = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(r), (n_rows, n)), dtype=float)
    U0 = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(u_init),
                                              (n_rows, A.shape[1])), dtype=float)
    ww = np.zeros(n) if w is None else np.ascontiguousarray(w, dtype=float)
    nn = np.zeros(n) if noise is None else np.ascontiguousarray(noise, dtype=float)
    Y = np.empty((n_rows, n))
    U = np.empty((n_rows, n))
    status = np.zeros(n_rows, dtype=np.int64)
    _run_batch(plant, A, C, R, ww, np.ascontiguousarray(t, dtype=float), float(ts), int(n_sub),
               float(x0), float(v0), U0, np.ascontiguousarray(y_init, dtype=float), nn,
               float(quant), Y, U, status)
    return Y, U, status


def simulate_one(plant: np.ndarray, a: np.ndarray, c: np.ndarray, r: np.ndarray,
                 t: np.ndarray, ts: float, **kw: object) -> tuple[np.ndarray, np.ndarray]:
    """Single-row convenience wrapper of :func:`simulate_batch`; returns ``(y, u)``."""
    y, u, _ = simulate_batch(np.atleast_2d(plant), np.atleast_2d(a), np.atleast_2d(c),
                             np.atleast_2d(r), t, ts, **kw)  # type: ignore[arg-type]
    return y[0], u[0]

"""``ekf``: an extended Kalman filter whose state carries the friction level, fed back as force.

State ``s = [x, v, c, d]`` (position m, velocity m/s, Coulomb level ``F_c`` N, residual
disturbance N) with the nominal mass ``M`` and damping ``B`` of ``context.nominal_axis`` and
the *shape* of its nominal friction (the ratio ``rho = F_s / F_c``, the Stribeck velocity
``v_s``, the viscous coefficient ``f_v``; what commissioning identified)::

    dx/dt = v
    dv/dt = (F - F_f(v, c) - B v + d) / M          F: motor force (column ``motor_force``)
    dc/dt = w_c,   dd/dt = w_d                      random walks
    F_f(v, c) = c s(v) + f_v v
    s(v) = (1 + (rho - 1) exp(-(v / v_s)^2)) tanh(v / eps)

so ``F_f = (F_c + (F_s - F_c) exp(-(v/v_s)^2)) tanh(v/eps) + f_v v`` with ``F_s = rho c``: the
smooth Stribeck law of the estimated velocity, its level estimated online. The level is what
changes between machines and with temperature (the Stribeck shape much less); the residual
``d`` takes what the law misses (a shape or mass error, pre-sliding, cogging). The
compensation fed back at the velocity-loop output is ``u = F_f(v_hat, c_hat) - d_hat``.

Discretisation. Near ``v = 0`` the smooth law is stiff (``dF_f/dv = rho c / eps``, about
5e6 N s/m on the default axis: explicit Euler at 1 ms would explode), so the velocity takes a
linearly implicit (Rosenbrock-Euler) step in its dissipative part::

    a = (F - F_f - B v + d) / M,   g = min(da/dv, 0)
    dv = ts a / (1 - ts g),   v+ = v + dv,   x+ = x + ts v + ts dv / 2

which settles at the stick balance instead of oscillating. The Jacobian of this map is analytic
(:func:`ekf_transition`); the measurement is the encoder position ``z = x`` (``H = [1 0 0 0]``).

Tuning (not fitted on any run; the category is ``online``)
---------------------------------------------------------
* ``R``: ``q^2 / 12 + noise_std^2`` of the nominal axis, as ``kalman`` (encoder step ``q``).
* Force noise: the drive's reported force carries ``kt * current_noise_std`` (N) of
  white noise; held over a sample it enters ``Q`` through ``G = [ts^2/(2M), ts/M, 0, 0]``.
* ``d``: a zero-mean residual (first-order Gauss-Markov, correlation time ``residual_time``
  = 50 ms, the length of a breakaway transient) driven by the density of ``kalman``'s
  Butterworth rule for a bandwidth ``residual_bandwidth`` (``q_d = M^2 R ts omega^6``, Van Loan
  over ``ts``). Default 300 rad/s, below the loop's dominant pair (about 500 rad/s) and a third
  of ``kalman``'s 1000: the law carries the fast part of the friction (its step at a
  reversal), so the residual need only follow model error. Why it decays: while the axis
  slides one way, ``c s(v)`` and ``d`` are the same constant force and only their sum is
  observed; two random walks would split it at random (a level of -190 N beside a residual of
  -470 N was seen on an s-curve). Decaying, ``d`` hands any lasting force to the level.
* ``c``: prior std ``level_std * F_c`` (0.2: friction levels of one axis type differ by a few
  tens of percent between machines and operating states, Armstrong-Helouvry et al. 1994), and a
  random-walk density ``(level_std F_c)^2 / level_time`` so that the level may drift by that
  much in ``level_time = 1 s`` (a generous rate: temperature drifts over minutes; faster lets
  the level converge within the first reversals of an episode).
* The level is held (its gain set to zero, the Joseph-form covariance update stays exact for
  that gain) while the estimated speed is below ``3 eps``: sticking, any level balances the
  motor force, and the stiff law's linearisation would move it at random.
* ``eps = 1e-4 m/s``: the width of the sign's smooth crossing, below the encoder's one-sample
  velocity resolution ``q / ts`` (0.25 mm/s on the default axis) and the Stribeck velocity
  (2 mm/s), so that the law is the Stribeck law wherever the velocity is measurable.

Implementation
--------------
The filters of an episode's axes, and those of several episodes stepped together
(:meth:`ExtendedFrictionObserver.batch`), are the rows of one :class:`EKFBank`: states
(n, 4), covariances (n, 4, 4), one compiled call per sample for every row. It is filterpy's
``ExtendedKalmanFilter`` (predict ``P = F P F' + Q``, the Joseph-form update) written out for
this model, each row by the same scalar code, so that a row's numbers do not depend on the
other rows: the compensator's own act and a batch of episodes give the same bits.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import numba
import numpy as np

from fricbench._validation import check_positive
from fricbench.axis import Axis
from fricbench.compensators.base import Compensator, CompensatorBatch, EpisodeContext
from fricbench.compensators.dob import dob_model
from fricbench.compensators.kalman import ForceObserver

__all__ = ["EKFBank", "EKFModel", "ExtendedFrictionObserver", "ekf_model", "ekf_transition",
           "stribeck_shape"]


class EKFModel:
    """Constants of the EKF's model (SI units; built by :func:`ekf_model`).

    Attributes
    ----------
    mass, damping, ts : float
        Nominal mass (kg), damping (N s/m) and sample time (s).
    rho : float
        ``F_s / F_c`` of the nominal friction (1 without a Stribeck peak).
    vs : float
        Stribeck velocity, m/s (0: no Stribeck term).
    fv : float
        Viscous friction coefficient beyond ``damping``, N s/m.
    eps : float
        Velocity scale of the smooth sign ``tanh(v / eps)``, m/s.
    fc : float
        Nominal Coulomb level, N (the level's prior mean).
    decay : float
        ``exp(-ts / tau_d)``: the residual's decay over a sample (1: a random walk).
    """

    __slots__ = ("damping", "decay", "eps", "fc", "fv", "mass", "rho", "ts", "vs")

    def __init__(self, mass: float, damping: float, ts: float, rho: float, vs: float,
                 fv: float, eps: float, fc: float, decay: float = 1.0) -> None:
        self.mass, self.damping, self.ts = float(mass), float(damping), float(ts)
        self.rho, self.vs, self.fv = float(rho), float(vs), float(fv)
        self.eps, self.fc, self.decay = float(eps), float(fc), float(decay)


def ekf_model(axis: Axis, eps: float = 1.0e-4, residual_time: float | None = None) -> EKFModel:
    """The EKF's model from a nominal axis: mass, damping and the shape of its friction.

    Parameters
    ----------
    axis : Axis
        Nominal axis; its friction's ``kernel_params()`` give ``fc, fs, vs, fv`` (every law
        of :mod:`fricbench.friction` reports them; a LuGre law's steady state is this
        Stribeck law).
    eps : float
        Width of the smooth sign, m/s.
    residual_time : float or None
        Correlation time ``tau_d`` of the residual disturbance, s (``None``: a random walk).
    """
    check_positive("eps", eps, "m/s")
    ts = axis.controller.ts
    decay = 1.0 if residual_time is None else math.exp(
        -ts / check_positive("residual_time", residual_time, "s"))
    p = axis.friction.kernel_params()
    fc, fs = float(p.get("fc", 0.0)), float(p.get("fs", 0.0))
    rho = fs / fc if fc > 0.0 and fs > fc else 1.0
    return EKFModel(axis.mechanics.mass, axis.mechanics.damping, ts, rho,
                    float(p.get("vs", 0.0)), float(p.get("fv", 0.0)), eps, max(fc, 0.0), decay)


# -- the filters' kernels ------------------------------------------------------------------------
# Each row (one filter) is computed by the same scalar code, whatever the other rows and their
# number: a batch's row i is then bit for bit member i's own act. Compiled with numba (strict
# IEEE, no fast-math) because the step is ~150 scalar operations on 4-vectors and 4x4
# matrices: written as ~150 numpy calls on arrays of a few rows it took 157 us per act against
# filterpy's 58 us (one axis); compiled, the act takes ~30 us, most of it the act's checks.
# The 4x4 products are written out, summed in a fixed order (no BLAS, whose blocking would
# depend on the batch size).

# columns of a bank's parameter rows (EKFBank.prm)
(_TS, _INV_M, _DAMPING, _FV, _INV_EPS, _ON, _RHO_M1, _INV_VS2, _DECAY, _R,
 _V_ADAPT) = range(11)
_N_PRM = 11
# columns of an episode's per-row settings (_EpisodeRows.ep) and indices (_EpisodeRows.cols)
_E_SCALE, _F_SCALE, _GAIN, _LIMIT, _SCALE = range(5)
_OBS_ROW, _E_COL, _F_COL = range(3)


def _param_rows(models: Sequence[EKFModel], r: np.ndarray) -> np.ndarray:
    """The parameter rows (n, 11) of filters of ``models`` with position variances ``r``."""
    prm = np.zeros((len(models), _N_PRM))
    for i, m in enumerate(models):
        prm[i, _TS], prm[i, _INV_M], prm[i, _DAMPING] = m.ts, 1.0 / m.mass, m.damping
        prm[i, _FV], prm[i, _INV_EPS] = m.fv, 1.0 / m.eps
        # the Stribeck term is on only with a Stribeck velocity and a peak (rho != 1)
        on = m.vs > 0.0 and m.rho != 1.0
        prm[i, _ON], prm[i, _RHO_M1] = float(on), m.rho - 1.0
        prm[i, _INV_VS2] = 1.0 / (m.vs * m.vs) if on else 0.0
        prm[i, _DECAY], prm[i, _R] = m.decay, r[i]
        # below this estimated speed the level is held: 3 eps, where tanh(v / eps) > 0.995
        prm[i, _V_ADAPT] = 3.0 * m.eps
    return prm


def _shape_row(v: float, p: np.ndarray) -> tuple[float, float, float]:
    """``s(v)``, ``s'(v)``, ``s''(v)`` of the unit-level law, parameters ``p`` (one row)."""
    inv_eps = p[_INV_EPS]
    t = math.tanh(v * inv_eps)
    # tanh' = (1 - tanh^2) / eps,  tanh'' = -2 tanh (1 - tanh^2) / eps^2
    sech2 = 1.0 - t * t
    t1 = sech2 * inv_eps
    t2 = -2.0 * t * sech2 * inv_eps * inv_eps
    h, h1, h2 = 1.0, 0.0, 0.0
    if p[_ON] != 0.0:
        inv_vs2 = p[_INV_VS2]
        r2 = v * v * inv_vs2
        if r2 < 40.0:  # exp(-40) < 5e-18: beyond, h = 1 to float precision
            # h = 1 + (rho - 1) e,  e = exp(-v^2/vs^2),  e' = -2 v e / vs^2
            ex = p[_RHO_M1] * math.exp(-r2)
            h = 1.0 + ex
            h1 = -2.0 * v * inv_vs2 * ex
            h2 = ex * (4.0 * r2 - 2.0) * inv_vs2
    # s = h T,  s' = h' T + h T',  s'' = h'' T + 2 h' T' + h T''
    return h * t, h1 * t + h * t1, h2 * t + 2.0 * h1 * t1 + h * t2


def _transition_row(x: np.ndarray, force: float, p: np.ndarray, jac: np.ndarray) -> None:
    """``x`` (4,) <- its next state under ``force`` (N); rows 0 and 1 of ``jac`` (4, 4) <- the
    Jacobian ``d x+ / d x`` at the prior state (rows 2 and 3, ``diag(1, decay)``, are
    constant and left as they are)."""
    v, c, d = x[1], x[2], x[3]
    ts, inv_m = p[_TS], p[_INV_M]
    s, s1, s2 = _shape_row(v, p)
    # a = (F - c s(v) - (f_v + B) v + d) / M
    a = (force - c * s - (p[_FV] + p[_DAMPING]) * v + d) * inv_m
    # g = da/dv, implicit only where it damps (the stiff part)
    g = -(c * s1 + p[_FV] + p[_DAMPING]) * inv_m
    implicit = g < 0.0
    den = 1.0 - ts * g if implicit else 1.0
    dv = ts * a / den
    # d(dv)/dq = ts (da/dq) / den + ts^2 a (dg/dq) / den^2   (dg/dq only where implicit)
    k1 = ts / den
    k2 = ts * ts * a / (den * den) if implicit else 0.0
    ddv_dv = k1 * g + k2 * (-c * s2 * inv_m)
    ddv_dc = k1 * (-s * inv_m) + k2 * (-s1 * inv_m)
    ddv_dd = k1 * inv_m
    half = 0.5 * ts
    jac[0, 0] = 1.0
    jac[0, 1] = ts + half * ddv_dv
    jac[0, 2] = half * ddv_dc
    jac[0, 3] = half * ddv_dd
    jac[1, 0] = 0.0
    jac[1, 1] = 1.0 + ddv_dv
    jac[1, 2] = ddv_dc
    jac[1, 3] = ddv_dd
    # x+ = x + ts v + ts dv / 2,  v+ = v + dv,  c+ = c (random walk),
    # d+ = exp(-ts / tau_d) d (zero-mean residual)
    x[0] = x[0] + ts * v + half * dv
    x[1] = v + dv
    x[3] = p[_DECAY] * d


def _predict_row(x: np.ndarray, pc: np.ndarray, q: np.ndarray, f: np.ndarray, force: float,
                 p: np.ndarray, fp: np.ndarray) -> None:
    """One filter's prediction: ``x <- f(x, F)``, ``P <- F P F' + Q`` (``fp``: scratch 4x4)."""
    _transition_row(x, force, p, f)
    for i in range(4):
        for k in range(4):
            acc = f[i, 0] * pc[0, k]
            for j in range(1, 4):
                acc += f[i, j] * pc[j, k]
            fp[i, k] = acc
    for i in range(4):
        for m in range(4):
            acc = fp[i, 0] * f[m, 0]
            for j in range(1, 4):
                acc += fp[i, j] * f[m, j]
            pc[i, m] = acc + q[i, m]


def _update_row(x: np.ndarray, pc: np.ndarray, z: float, p: np.ndarray,
                k: np.ndarray) -> None:
    """One filter's Joseph-form update with the position ``z`` (``k``: scratch (4,))."""
    r = p[_R]
    # S = H P H' + R,  K = P H' / S
    s = pc[0, 0] + r
    for i in range(4):
        k[i] = pc[i, 0] / s
    if abs(x[1]) < p[_V_ADAPT]:
        # sticking: the level is not observable (any level balances the force), and the
        # stiff law's linearisation would move it at random; hold it (K_c = 0). The Joseph
        # form below keeps P right for this non-optimal gain.
        k[2] = 0.0
    # y = z - H x
    y = z - x[0]
    for i in range(4):
        x[i] += k[i] * y
    # P = (I - K H) P (I - K H)' + K R K'   (Joseph form, as filterpy), in three passes:
    # P - K P[0, :], then minus (the new) P[:, 0] K', plus R K K'
    p0 = pc[0].copy()
    for i in range(4):
        for j in range(4):
            pc[i, j] -= k[i] * p0[j]
    c0 = pc[:, 0].copy()
    for i in range(4):
        for j in range(4):
            pc[i, j] -= c0[i] * k[j]
    for i in range(4):
        for j in range(4):
            pc[i, j] += k[i] * k[j] * r


def _force_row(x: np.ndarray, p: np.ndarray) -> float:
    """``F_f(v_hat, c_hat) - d_hat`` of one filter, N."""
    v, c, d = x[1], x[2], x[3]
    return c * _shape_row(v, p)[0] + p[_FV] * v - d


def _bank_predict(x: np.ndarray, pc: np.ndarray, q: np.ndarray, f: np.ndarray,
                  prm: np.ndarray, force: np.ndarray) -> None:
    fp = np.empty((4, 4))
    for i in range(x.shape[0]):
        _predict_row(x[i], pc[i], q[i], f[i], force[i], prm[i], fp)


def _bank_update(x: np.ndarray, pc: np.ndarray, prm: np.ndarray, z: np.ndarray) -> None:
    k = np.empty(4)
    for i in range(x.shape[0]):
        _update_row(x[i], pc[i], z[i], prm[i], k)


def _bank_force(x: np.ndarray, prm: np.ndarray, out: np.ndarray) -> None:
    for i in range(x.shape[0]):
        out[i] = _force_row(x[i], prm[i])


def _episode_step(obs: np.ndarray, cols: np.ndarray, ep: np.ndarray, xref: np.ndarray,
                  k: int, x: np.ndarray, pc: np.ndarray, q: np.ndarray, f: np.ndarray,
                  prm: np.ndarray, out: np.ndarray) -> None:
    """Step ``k`` of every row: predict with the last motor force, update with the position,
    ``out`` <- the action (before the [-1, 1] clip)."""
    fp = np.empty((4, 4))
    kv = np.empty(4)
    kk = min(k, xref.shape[1] - 1)
    for i in range(x.shape[0]):
        o = cols[i, _OBS_ROW]
        if k > 0:
            # motor force of the last sample: it acted over [t_k-1, t_k)
            _predict_row(x[i], pc[i], q[i], f[i], obs[o, cols[i, _F_COL]] * ep[i, _F_SCALE],
                         prm[i], fp)
        # z = x_ref - e
        _update_row(x[i], pc[i], xref[i, kk] - obs[o, cols[i, _E_COL]] * ep[i, _E_SCALE],
                    prm[i], kv)
        # u = F_f(v_hat, c_hat) - d_hat: cancel the estimated friction and disturbance
        u = ep[i, _GAIN] * _force_row(x[i], prm[i])
        out[i] = min(max(u, -ep[i, _LIMIT]), ep[i, _LIMIT]) / ep[i, _SCALE]


_shape_row = numba.njit(cache=True, inline="always")(_shape_row)
_transition_row = numba.njit(cache=True, inline="always")(_transition_row)
_predict_row = numba.njit(cache=True, inline="always")(_predict_row)
_update_row = numba.njit(cache=True, inline="always")(_update_row)
_force_row = numba.njit(cache=True, inline="always")(_force_row)
_bank_predict = numba.njit(cache=True)(_bank_predict)
_bank_update = numba.njit(cache=True)(_bank_update)
_bank_force = numba.njit(cache=True)(_bank_force)
_episode_step = numba.njit(cache=True)(_episode_step)


def stribeck_shape(v: float, model: EKFModel) -> tuple[float, float, float]:
    """``s(v)``, ``s'(v)`` (s/m) and ``s''(v)`` (s^2/m^2) of the unit-level law.

    ``s(v) = h(v) tanh(v / eps)`` with ``h(v) = 1 + (rho - 1) exp(-(v / v_s)^2)``; the
    filters' own kernel.
    """
    s, s1, s2 = _shape_row(float(v), _param_rows([model], np.zeros(1))[0])
    return float(s), float(s1), float(s2)


def ekf_transition(state: np.ndarray, force: float, model: EKFModel,
                   jacobian: np.ndarray | None = None) -> np.ndarray:
    """One step of the EKF's model: the next state and (in place) its Jacobian.

    The filters' own kernel (:class:`EKFBank`).

    Parameters
    ----------
    state : ndarray, shape (4,) or (4, 1)
        ``[x, v, c, d]`` in m, m/s, N, N.
    force : float
        Motor force held over the step, N.
    model : EKFModel
        The model's constants.
    jacobian : ndarray, shape (4, 4), optional
        Written in place with ``d state+ / d state`` when given (its last two rows,
        ``diag(1, decay)``, are constant and left as they are: fill them once).

    Returns
    -------
    ndarray, shape (4, 1)
        The next state.
    """
    x = np.array(state, dtype=np.float64).reshape(4)
    jac = np.zeros((4, 4)) if jacobian is None else np.zeros((4, 4)) + jacobian
    _transition_row(x, float(force), _param_rows([model], np.zeros(1))[0], jac)
    if jacobian is not None:
        jacobian[:2] = jac[:2]
    return x.reshape(4, 1)


class EKFBank:
    """``n`` extended Kalman filters of the friction model, stepped together.

    Each row is the filter of the module docstring: the linearly implicit transition
    (:func:`ekf_transition`) with its analytic Jacobian, ``P = F P F' + Q``, and the Joseph-form
    update with the encoder position (``H = [1 0 0 0]``), the level held below ``3 eps``.
    filterpy's ``ExtendedKalmanFilter`` does the same for one filter at a time, at a Python
    and small-matrix overhead of tens of microseconds a step; here one compiled call steps
    every row, and a row's numbers do not depend on the other rows (the compensator's own
    act and a batch of episodes are the same code and the same bits).

    Parameters
    ----------
    models : sequence of EKFModel
        The model of each row.
    q : ndarray, shape (n, 4, 4)
        Process noise covariance per row.
    r : ndarray, shape (n,)
        Position measurement variance per row, m^2.
    x0 : ndarray, shape (n, 4)
        Initial states ``[x, v, c, d]``.
    p0 : ndarray, shape (n, 4, 4)
        Initial covariances.

    Attributes
    ----------
    x : ndarray, shape (n, 4)
        States (posterior after :meth:`update_position`).
    P : ndarray, shape (n, 4, 4)
        Covariances.
    Q : ndarray, shape (n, 4, 4)
        Process noise covariances.
    """

    _ARRAYS = ("x", "P", "Q", "prm", "_F")

    def __init__(self, models: Sequence[EKFModel], q: np.ndarray, r: np.ndarray,
                 x0: np.ndarray, p0: np.ndarray) -> None:
        n = len(models)
        self.x = np.array(x0, dtype=np.float64).reshape(n, 4)
        self.P = np.array(p0, dtype=np.float64).reshape(n, 4, 4)
        self.Q = np.array(q, dtype=np.float64).reshape(n, 4, 4)
        self.prm = _param_rows(models, np.asarray(r, dtype=np.float64).reshape(n))
        # the Jacobians; rows 2 and 3 are constant, diag(1, decay)
        self._F = np.zeros((n, 4, 4))
        self._F[:, 2, 2] = 1.0
        self._F[:, 3, 3] = self.prm[:, _DECAY]

    def __len__(self) -> int:
        return self.x.shape[0]

    @property
    def r(self) -> np.ndarray:
        """Position measurement variances (n,), m^2."""
        return self.prm[:, _R]

    def rows(self, sl: slice) -> EKFBank:
        """The filters of rows ``sl`` as a bank whose arrays are views of this one's: stepping
        either steps both."""
        out = object.__new__(EKFBank)
        for name in self._ARRAYS:
            setattr(out, name, getattr(self, name)[sl])
        return out

    @classmethod
    def concatenate(cls, banks: Sequence[EKFBank]) -> EKFBank:
        """One bank of the rows of ``banks`` (copies), in order."""
        out = object.__new__(cls)
        for name in cls._ARRAYS:
            setattr(out, name, np.concatenate([getattr(b, name) for b in banks]))
        return out

    def predict(self, force: np.ndarray) -> None:
        """Propagate every row over one sample with its motor force ``force`` (n,), N:
        ``x+ = f(x, F)``, ``P+ = F P F' + Q`` with ``F`` the Jacobian at the prior state."""
        _bank_predict(self.x, self.P, self.Q, self._F, self.prm,
                      np.asarray(force, dtype=np.float64).reshape(len(self)))

    def update_position(self, z: np.ndarray) -> None:
        """Update every row with its encoder position ``z`` (n,), m (Joseph form)."""
        _bank_update(self.x, self.P, self.prm, np.asarray(z, dtype=np.float64).reshape(len(self)))

    def friction_force(self) -> np.ndarray:
        """``F_f(v_hat, c_hat) - d_hat`` per row, N: the force the compensator cancels."""
        out = np.empty(len(self))
        _bank_force(self.x, self.prm, out)
        return out


class _EpisodeRows:
    """The filters of one or more episodes with what each row reads: which observation row
    and columns (``cols``), its scales, gain and clip (``ep``), its reference positions.

    One compensator's episode is D rows (one per axis, observation row 0); a batch of N
    episodes is their concatenation, N*D rows. :meth:`step` is the act of every row.
    """

    def __init__(self, bank: EKFBank, xref: np.ndarray, cols: np.ndarray,
                 ep: np.ndarray) -> None:
        self.bank, self.xref, self.cols, self.ep = bank, xref, cols, ep

    @classmethod
    def concatenate(cls, parts: Sequence[_EpisodeRows]) -> _EpisodeRows:
        """The rows of ``parts``, part ``i`` reading observation row ``i``; references of
        different lengths are padded with their last position (a row past its end reads its
        last sample, as a single episode does)."""
        k_max = max(p.xref.shape[1] for p in parts)
        xref = np.concatenate([np.pad(p.xref, ((0, 0), (0, k_max - p.xref.shape[1])),
                                      mode="edge") for p in parts])
        cols = np.concatenate([p.cols for p in parts])
        cols[:, _OBS_ROW] = np.concatenate([np.full(len(p.cols), i)
                                            for i, p in enumerate(parts)])
        return cls(EKFBank.concatenate([p.bank for p in parts]), xref, cols,
                   np.concatenate([p.ep for p in parts]))

    def step(self, observations: np.ndarray, k: int) -> np.ndarray:
        """Actions (before the [-1, 1] clip) of step ``k`` for ``observations`` (N, obs_dim)."""
        b = self.bank
        out = np.empty(len(b))
        _episode_step(np.ascontiguousarray(observations, dtype=np.float64), self.cols,
                      self.ep, self.xref, int(k), b.x, b.P, b.Q, b._F, b.prm, out)
        return out


class _FilterView:
    """Row ``i`` of a bank in filterpy's conventions (``x`` (4, 1), ``P`` (4, 4), ``R``
    (1, 1), ``update_position(z)``), to inspect one axis's filter; writes go to the bank."""

    def __init__(self, bank: EKFBank, i: int) -> None:
        self._bank = bank.rows(slice(i, i + 1))

    @property
    def x(self) -> np.ndarray:
        return self._bank.x.reshape(4, 1)

    @x.setter
    def x(self, value: np.ndarray) -> None:
        self._bank.x[0] = np.asarray(value, dtype=np.float64).reshape(4)

    @property
    def P(self) -> np.ndarray:  # noqa: N802 - filterpy's name
        return self._bank.P[0]

    @P.setter
    def P(self, value: np.ndarray) -> None:  # noqa: N802
        self._bank.P[0] = value

    @property
    def R(self) -> np.ndarray:  # noqa: N802
        return self._bank.r.reshape(1, 1)

    def update_position(self, z: float) -> None:
        self._bank.update_position(np.array([float(z)]))


class ExtendedFrictionObserver(ForceObserver):
    """EKF on ``[x, v, F_c, d]`` with a smooth Stribeck law; feeds back ``F_f_hat - d_hat``.

    One filter per axis, the rows of an :class:`EKFBank`; :meth:`batch` steps the episodes
    of several instances in one bank.

    Parameters
    ----------
    residual_bandwidth : float
        Bandwidth of the residual disturbance ``d``, rad/s (sets its random-walk density
        with ``kalman``'s rule; see the module docstring).
    residual_time : float
        Correlation time of the residual disturbance, s: it decays towards zero with this
        time constant, so that a lasting friction force is carried by the level.
    level_std : float
        Relative prior standard deviation of the Coulomb level (0.2 = 20 % of the nominal).
    level_time : float
        Time over which the level may drift by ``level_std`` (its random-walk density), s.
    eps : float
        Velocity scale of the smooth sign ``tanh(v / eps)``, m/s.
    gain : float
        Fraction of the estimated force fed back (1 = full cancellation).
    max_force : float or None
        Clip of the compensation force, N (``None``: the env's ``action_scale``).

    Attributes
    ----------
    level_ : list of float
        Estimated Coulomb level per axis after the last step, N.

    Notes
    -----
    Needs no training (``learns = False``, category ``online``): the model is the nominal axis
    of the episode context, as identified at commissioning, and the level adapts online.
    """

    id = "ekf"
    action_mode: ClassVar[str] = "force"
    learns: ClassVar[bool] = False
    category: ClassVar[str] = "online"

    def __init__(self, *, residual_bandwidth: float = 300.0, residual_time: float = 0.05,
                 level_std: float = 0.2,
                 level_time: float = 1.0, eps: float = 1.0e-4, gain: float = 1.0,
                 max_force: float | None = None) -> None:
        check_positive("residual_bandwidth", residual_bandwidth, "rad/s")
        check_positive("residual_time", residual_time, "s")
        check_positive("level_std", level_std)
        check_positive("level_time", level_time, "s")
        check_positive("eps", eps, "m/s")
        super().__init__(gain=gain, max_force=max_force)
        self.residual_bandwidth = residual_bandwidth
        self.residual_time = residual_time
        self.level_std = level_std
        self.level_time = level_time
        self.eps = eps
        self._k = 0

    def _covariances(self, axis: Axis, model: EKFModel) -> tuple[np.ndarray, np.ndarray]:
        """``Q`` (4x4) and ``R`` (1x1) of the nominal axis (module docstring)."""
        dob = dob_model(axis, self.residual_bandwidth)
        q = np.zeros((4, 4))
        idx = np.array([0, 1, 3])  # kalman's [x, v, d] block
        q[np.ix_(idx, idx)] = dob["Q"]
        # force noise of the reported current: G = [ts^2/(2M), ts/M, 0, 0]
        sigma_f = axis.controller.kt * axis.effects.current_noise_std
        g = np.array([0.5 * model.ts**2, model.ts, 0.0, 0.0]) / model.mass
        q += sigma_f**2 * np.outer(g, g)
        level_sd = self.level_std * max(model.fc, 1.0)
        # the level may drift by level_sd in level_time: q_c = level_sd^2 / level_time
        q[2, 2] = level_sd**2 / self.level_time * model.ts
        return q, dob["R"]

    def _reset(self, context: EpisodeContext, seed: int | None) -> None:
        axis = context.nominal_axis
        model = ekf_model(axis, self.eps, self.residual_time)
        q, r = self._covariances(axis, model)
        v0 = self._read_episode(context)
        level_sd = self.level_std * max(model.fc, 1.0)
        d = context.n_axes
        x0 = np.column_stack([self._xref[:, 0], v0, np.full(d, model.fc), np.zeros(d)])
        # start sure of x and v (at rest on the reference), unsure of the level by the
        # spread between machines, and of the residual by as much of the static level
        p0 = np.diag([r[0, 0], 1e-8, level_sd**2,
                      (self.level_std * model.rho * max(model.fc, 1.0))**2])
        bank = EKFBank([model] * d, np.broadcast_to(q, (d, 4, 4)), np.full(d, r[0, 0]), x0,
                       np.broadcast_to(p0, (d, 4, 4)))
        cols = np.zeros((d, 3), dtype=np.intp)  # observation row 0: the episode's own
        cols[:, _E_COL] = [c[0] for c in self._cols]
        cols[:, _F_COL] = [c[1] for c in self._cols]
        ep = np.empty((d, 5))
        ep[:, _E_SCALE], ep[:, _F_SCALE] = self._e_scale, self._f_scale
        ep[:, _GAIN], ep[:, _LIMIT], ep[:, _SCALE] = self.gain, self._limit, self._scale
        self._rows = _EpisodeRows(bank, np.array(self._xref, dtype=np.float64), cols, ep)
        self._k = 0

    @property
    def level_(self) -> list[float]:
        """Estimated Coulomb level per axis after the last step, N."""
        rows = getattr(self, "_rows", None)
        if rows is None:
            raise AttributeError("level_: no episode started (call reset())")
        return [float(c) for c in rows.bank.x[:, 2]]

    @property
    def _filters(self) -> list[_FilterView]:
        """Each axis's filter, viewed in filterpy's conventions (inspection, tests)."""
        return [_FilterView(self._rows.bank, i) for i in range(len(self._rows.bank))]

    def _act(self, observation: np.ndarray) -> np.ndarray:
        # the episode's D rows, through the same step as a batch of episodes
        out = self._rows.step(observation[None, :], self._k)
        self._k += 1
        return out

    @classmethod
    def batch(cls, members: Sequence[Compensator]) -> CompensatorBatch:
        """The members' filters in one bank, stepped by one call per sample (see
        :meth:`Compensator.batch`): row ``i`` gives member ``i``'s own actions, bit for bit."""
        return _EKFBatch(members)


class _EKFBatch(CompensatorBatch):
    """Episodes of ``ekf`` stepped together: the members' filters concatenated in one bank."""

    def __init__(self, members: Sequence[Compensator]) -> None:
        super().__init__(members)
        ekfs = [m for m in self.members if isinstance(m, ExtendedFrictionObserver)]
        if len(ekfs) != len(self.members):
            raise TypeError(f"members: instances of {type(self.members[0]).__name__}; "
                            "expected ExtendedFrictionObserver")
        stepped = [i for i, m in enumerate(ekfs) if m._k != 0]
        if stepped:
            raise ValueError(f"members: member {stepped[0]} has already acted "
                             f"{ekfs[stepped[0]]._k} times; expected members just reset")
        self._rows = _EpisodeRows.concatenate([m._rows for m in ekfs])
        # the members' filters become views of the bank: their level_ follows the batch
        d = self.n_axes
        for i, m in enumerate(ekfs):
            m._rows.bank = self._rows.bank.rows(slice(i * d, (i + 1) * d))
        self._k = 0

    def _act_rows(self, observations: np.ndarray) -> np.ndarray:
        out = self._rows.step(observations, self._k)
        self._k += 1
        return out.reshape(len(self.members), self.n_axes)

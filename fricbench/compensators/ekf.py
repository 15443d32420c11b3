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
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from fricbench._validation import check_nonneg, check_positive
from fricbench.axis import Axis
from fricbench.compensators.base import EpisodeContext
from fricbench.compensators.kalman import ForceObserver, dob_model

__all__ = ["EKFModel", "ExtendedFrictionObserver", "ekf_model", "ekf_transition",
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


def stribeck_shape(v: float, model: EKFModel) -> tuple[float, float, float]:
    """``s(v)``, ``s'(v)`` (s/m) and ``s''(v)`` (s^2/m^2) of the unit-level law.

    ``s(v) = h(v) tanh(v / eps)`` with ``h(v) = 1 + (rho - 1) exp(-(v / v_s)^2)``.
    """
    inv_eps = 1.0 / model.eps
    t = math.tanh(v * inv_eps)
    # tanh' = (1 - tanh^2) / eps,  tanh'' = -2 tanh (1 - tanh^2) / eps^2
    sech2 = 1.0 - t * t
    t1 = sech2 * inv_eps
    t2 = -2.0 * t * sech2 * inv_eps * inv_eps
    h, h1, h2 = 1.0, 0.0, 0.0
    if model.vs > 0.0 and model.rho != 1.0:
        inv_vs2 = 1.0 / (model.vs * model.vs)
        r2 = v * v * inv_vs2
        if r2 < 40.0:  # exp(-40) < 5e-18: beyond, h = 1 to float precision
            # h = 1 + (rho - 1) e,  e = exp(-v^2/vs^2),  e' = -2 v e / vs^2
            ex = (model.rho - 1.0) * math.exp(-r2)
            h = 1.0 + ex
            h1 = -2.0 * v * inv_vs2 * ex
            h2 = ex * (4.0 * r2 - 2.0) * inv_vs2
    # s = h T,  s' = h' T + h T',  s'' = h'' T + 2 h' T' + h T''
    return h * t, h1 * t + h * t1, h2 * t + 2.0 * h1 * t1 + h * t2


def ekf_transition(state: np.ndarray, force: float, model: EKFModel,
                   jacobian: np.ndarray | None = None) -> np.ndarray:
    """One step of the EKF's model: the next state and (in place) its Jacobian.

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
    x, v, c, d = (float(state[i, 0]) if state.ndim == 2 else float(state[i])
                  for i in range(4))
    m, ts = model.mass, model.ts
    s, s1, s2 = stribeck_shape(v, model)
    inv_m = 1.0 / m
    # a = (F - c s(v) - (f_v + B) v + d) / M
    a = (force - c * s - (model.fv + model.damping) * v + d) * inv_m
    # g = da/dv, implicit only where it damps (the stiff part)
    g = -(c * s1 + model.fv + model.damping) * inv_m
    implicit = g < 0.0
    den = 1.0 - ts * g if implicit else 1.0
    dv = ts * a / den
    # c+ = c (random walk), d+ = exp(-ts / tau_d) d (zero-mean residual)
    out = np.array([[x + ts * v + 0.5 * ts * dv], [v + dv], [c], [model.decay * d]])
    if jacobian is not None:
        # d(dv)/dq = ts (da/dq) / den + ts^2 a (dg/dq) / den^2   (dg/dq only where implicit)
        k1 = ts / den
        k2 = ts * ts * a / (den * den) if implicit else 0.0
        ddv_dv = k1 * g + k2 * (-c * s2 * inv_m)
        ddv_dc = k1 * (-s * inv_m) + k2 * (-s1 * inv_m)
        ddv_dd = k1 * inv_m
        half = 0.5 * ts
        jacobian[0, 0] = 1.0
        jacobian[0, 1] = ts + half * ddv_dv
        jacobian[0, 2] = half * ddv_dc
        jacobian[0, 3] = half * ddv_dd
        jacobian[1, 0] = 0.0
        jacobian[1, 1] = 1.0 + ddv_dv
        jacobian[1, 2] = ddv_dc
        jacobian[1, 3] = ddv_dd
    return out


class _FrictionEKF(ExtendedKalmanFilter):  # type: ignore[misc]
    """filterpy's EKF with the nonlinear prediction of :func:`ekf_transition`."""

    x: np.ndarray
    F: np.ndarray
    P: np.ndarray
    R: np.ndarray

    def __init__(self, model: EKFModel) -> None:
        super().__init__(dim_x=4, dim_z=1, dim_u=1)
        self.model = model
        self.F = np.diag([1.0, 1.0, 1.0, model.decay])
        # below this estimated speed the level is held: 3 eps, where tanh(v / eps) > 0.995
        self.v_adapt = 3.0 * model.eps
        self._gain = np.zeros((4, 1))
        self._buf = np.zeros((4, 4))

    def predict_x(self, u: float = 0.0) -> None:
        # filterpy then forms P = F P F' + Q with the Jacobian written here at the prior state
        self.x = ekf_transition(self.x, float(u), self.model, self.F)

    def update_position(self, z: float) -> None:
        """Update with the encoder position ``z`` (m): filterpy's ``update`` for ``H = [1 0 0 0]``.

        The same Joseph-form update as ``ExtendedKalmanFilter.update`` written for the scalar
        measurement, without its per-call matrix inverse, deep copies and history copies (it
        ran at a third of the step's time); ``x`` and ``P`` stay filterpy's attributes.
        """
        p, k, buf = self.P, self._gain, self._buf
        r = float(self.R[0, 0])
        # S = H P H' + R,  K = P H' / S
        s = p[0, 0] + r
        np.divide(p[:, :1], s, out=k)
        if abs(self.x[1, 0]) < self.v_adapt:
            # sticking: the level is not observable (any level balances the force), and the
            # stiff law's linearisation would move it at random; hold it (K_c = 0). The Joseph
            # form below keeps P right for this non-optimal gain.
            k[2, 0] = 0.0
        # y = z - H x
        y = z - self.x[0, 0]
        self.x += k * y
        # P = (I - K H) P (I - K H)' + K R K'   (Joseph form, as filterpy)
        np.multiply(k, p[:1, :], out=buf)
        p -= buf
        np.multiply(p[:, :1], k.T, out=buf)
        p -= buf
        np.multiply(k, k.T, out=buf)
        buf *= r
        p += buf


class ExtendedFrictionObserver(ForceObserver):
    """EKF on ``[x, v, F_c, d]`` with a smooth Stribeck law; feeds back ``F_f_hat - d_hat``.

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
        super().__init__()
        check_positive("residual_bandwidth", residual_bandwidth, "rad/s")
        check_positive("residual_time", residual_time, "s")
        check_positive("level_std", level_std)
        check_positive("level_time", level_time, "s")
        check_positive("eps", eps, "m/s")
        check_nonneg("gain", gain)
        if max_force is not None:
            check_positive("max_force", max_force, "N")
        self.residual_bandwidth = residual_bandwidth
        self.residual_time = residual_time
        self.level_std = level_std
        self.level_time = level_time
        self.eps = eps
        self.gain = gain
        self.max_force = max_force
        self._filters: list[_FrictionEKF] = []
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
        self._model = model
        self._filters = []
        for i in range(context.n_axes):
            kf = _FrictionEKF(model)
            kf.Q, kf.R = q.copy(), r.copy()
            kf.x = np.array([[self._xref[i, 0]], [v0[i]], [model.fc], [0.0]])
            # start sure of x and v (at rest on the reference), unsure of the level by the
            # spread between machines, and of the residual by as much of the static level
            kf.P = np.diag([r[0, 0], 1e-8, level_sd**2, (self.level_std * model.rho
                                                         * max(model.fc, 1.0))**2])
            self._filters.append(kf)
        self._k = 0
        self.level_ = [model.fc] * context.n_axes

    def _act(self, observation: np.ndarray) -> np.ndarray:
        k = min(self._k, self._xref.shape[1] - 1)
        out = np.empty(len(self._filters))
        model = self._model
        for i, kf in enumerate(self._filters):
            e_col, f_col = self._cols[i]
            if self._k > 0:
                # motor force of the last sample: it acted over [t_k-1, t_k)
                kf.predict(u=observation[f_col] * self._f_scale)
            # z = x_ref - e
            kf.update_position(self._xref[i, k] - observation[e_col] * self._e_scale)
            v, c, d = float(kf.x[1, 0]), float(kf.x[2, 0]), float(kf.x[3, 0])
            s = stribeck_shape(v, model)[0]
            self.level_[i] = c
            # u = F_f(v_hat, c_hat) - d_hat: cancel the estimated friction and disturbance
            u = self.gain * (c * s + model.fv * v - d)
            out[i] = min(max(u, -self._limit), self._limit) / self._scale
        self._k += 1
        return out

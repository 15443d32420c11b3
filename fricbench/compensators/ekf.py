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
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from fricbench._validation import check_nonneg, check_positive
from fricbench.axis import Axis
from fricbench.compensators.base import Compensator, CompensatorBatch, EpisodeContext
from fricbench.compensators.kalman import ForceObserver, dob_model

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


class _RowParams:
    """The model constants of ``n`` filters, one row each, as arrays of shape (n,).

    Every row may have its own :class:`EKFModel` (the members of a batch may be told different
    nominal axes); the kernels below read only these arrays, elementwise.
    """

    _FIELDS = ("ts", "half_ts", "inv_m", "damping", "fv", "inv_eps", "on", "rho_m1",
               "inv_vs2", "decay")
    __slots__ = _FIELDS

    ts: np.ndarray
    half_ts: np.ndarray
    inv_m: np.ndarray
    damping: np.ndarray
    fv: np.ndarray
    inv_eps: np.ndarray
    on: np.ndarray
    rho_m1: np.ndarray
    inv_vs2: np.ndarray
    decay: np.ndarray

    @classmethod
    def of(cls, models: Sequence[EKFModel]) -> _RowParams:
        """The rows of ``models``, in order."""
        out = cls()
        ts = np.array([m.ts for m in models])
        out.ts, out.half_ts = ts, 0.5 * ts
        out.inv_m = 1.0 / np.array([m.mass for m in models])
        out.damping = np.array([m.damping for m in models])
        out.fv = np.array([m.fv for m in models])
        out.inv_eps = 1.0 / np.array([m.eps for m in models])
        # the Stribeck term is on only with a Stribeck velocity and a peak (rho != 1)
        out.on = np.array([m.vs > 0.0 and m.rho != 1.0 for m in models])
        out.rho_m1 = np.array([m.rho - 1.0 for m in models])
        out.inv_vs2 = np.array([1.0 / (m.vs * m.vs) if m.vs > 0.0 else 0.0 for m in models])
        out.decay = np.array([m.decay for m in models])
        return out

    def rows(self, sl: slice) -> _RowParams:
        """Rows ``sl`` (views)."""
        out = _RowParams()
        for f in self._FIELDS:
            setattr(out, f, getattr(self, f)[sl])
        return out

    @classmethod
    def concatenate(cls, parts: Sequence[_RowParams]) -> _RowParams:
        """The rows of ``parts``, one after the other."""
        out = cls()
        for f in cls._FIELDS:
            setattr(out, f, np.concatenate([getattr(p, f) for p in parts]))
        return out


# Row independence. Each row's numbers must not depend on the other rows or on their number
# (a batch's row i is bit for bit member i's own act). Every kernel below is elementwise on
# arrays of shape (n,) (or (n, 4), (n, 4, 4) with the row first), sums written out term by
# term in a fixed order: no matmul, whose BLAS blocking changes with n, and no reductions.
# np.tanh and np.exp run SIMD code; they get fresh contiguous arrays, the path on which they
# give the same bits for an element whatever the length (tested for lengths 1..33).

def _shape(v: np.ndarray, prm: _RowParams, derivatives: bool = True
           ) -> tuple[np.ndarray, ...]:
    """``s(v)``, and with ``derivatives`` ``s'(v)``, ``s''(v)``, of the unit-level law, per row.

    ``s(v) = h(v) tanh(v / eps)`` with ``h(v) = 1 + (rho - 1) exp(-(v / v_s)^2)``.
    """
    t = np.tanh(v * prm.inv_eps)
    r2 = v * v * prm.inv_vs2
    # exp(-40) < 5e-18: beyond r2 = 40, h = 1 to float precision
    on = prm.on & (r2 < 40.0)
    # h = 1 + (rho - 1) e,  e = exp(-v^2/vs^2)
    ex = np.where(on, prm.rho_m1 * np.exp(-r2), 0.0)
    h = 1.0 + ex
    if not derivatives:
        return (h * t,)
    # tanh' = (1 - tanh^2) / eps,  tanh'' = -2 tanh (1 - tanh^2) / eps^2
    sech2 = 1.0 - t * t
    t1 = sech2 * prm.inv_eps
    t2 = -2.0 * t * sech2 * prm.inv_eps * prm.inv_eps
    # e' = -2 v e / vs^2,  h'' = (rho - 1) e (4 v^2/vs^2 - 2) / vs^2
    h1 = -2.0 * v * prm.inv_vs2 * ex
    h2 = ex * (4.0 * r2 - 2.0) * prm.inv_vs2
    # s = h T,  s' = h' T + h T',  s'' = h'' T + 2 h' T' + h T''
    return h * t, h1 * t + h * t1, h2 * t + 2.0 * h1 * t1 + h * t2


def _transition(x: np.ndarray, force: np.ndarray, prm: _RowParams,
                jacobian: np.ndarray | None) -> np.ndarray:
    """Next states (n, 4) of states ``x`` (n, 4) under ``force`` (n,), N; writes rows 0 and 1
    of each Jacobian ``d x+ / d x`` into ``jacobian`` (n, 4, 4) when given."""
    v, c, d = x[:, 1], x[:, 2], x[:, 3]
    s, s1, s2 = _shape(v, prm)
    ts, inv_m = prm.ts, prm.inv_m
    # a = (F - c s(v) - (f_v + B) v + d) / M
    a = (force - c * s - (prm.fv + prm.damping) * v + d) * inv_m
    # g = da/dv, implicit only where it damps (the stiff part)
    g = -(c * s1 + prm.fv + prm.damping) * inv_m
    implicit = g < 0.0
    den = np.where(implicit, 1.0 - ts * g, 1.0)
    dv = ts * a / den
    out = np.empty_like(x)
    out[:, 0] = x[:, 0] + ts * v + prm.half_ts * dv
    out[:, 1] = v + dv
    # c+ = c (random walk), d+ = exp(-ts / tau_d) d (zero-mean residual)
    out[:, 2] = c
    out[:, 3] = prm.decay * d
    if jacobian is not None:
        # d(dv)/dq = ts (da/dq) / den + ts^2 a (dg/dq) / den^2   (dg/dq only where implicit)
        k1 = ts / den
        k2 = np.where(implicit, ts * ts * a / (den * den), 0.0)
        ddv_dv = k1 * g + k2 * (-c * s2 * inv_m)
        ddv_dc = k1 * (-s * inv_m) + k2 * (-s1 * inv_m)
        ddv_dd = k1 * inv_m
        jacobian[:, 0, 0] = 1.0
        jacobian[:, 0, 1] = ts + prm.half_ts * ddv_dv
        jacobian[:, 0, 2] = prm.half_ts * ddv_dc
        jacobian[:, 0, 3] = prm.half_ts * ddv_dd
        jacobian[:, 1, 0] = 0.0
        jacobian[:, 1, 1] = 1.0 + ddv_dv
        jacobian[:, 1, 2] = ddv_dc
        jacobian[:, 1, 3] = ddv_dd
    return out


def stribeck_shape(v: float, model: EKFModel) -> tuple[float, float, float]:
    """``s(v)``, ``s'(v)`` (s/m) and ``s''(v)`` (s^2/m^2) of the unit-level law.

    ``s(v) = h(v) tanh(v / eps)`` with ``h(v) = 1 + (rho - 1) exp(-(v / v_s)^2)``; the
    filters' own kernel, on one row.
    """
    s, s1, s2 = _shape(np.array([float(v)]), _RowParams.of([model]))
    return float(s[0]), float(s1[0]), float(s2[0])


def ekf_transition(state: np.ndarray, force: float, model: EKFModel,
                   jacobian: np.ndarray | None = None) -> np.ndarray:
    """One step of the EKF's model: the next state and (in place) its Jacobian.

    The filters' own kernel (:class:`EKFBank`), on one row.

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
    x = np.asarray(state, dtype=np.float64).reshape(1, 4)
    jac = None if jacobian is None else jacobian[None, :, :]
    return _transition(x, np.array([float(force)]), _RowParams.of([model]), jac).reshape(4, 1)


class EKFBank:
    """``n`` extended Kalman filters of the friction model, stepped in one set of numpy calls.

    Each row is the filter of the module docstring: the linearly implicit transition
    (:func:`ekf_transition`) with its analytic Jacobian, ``P = F P F' + Q``, and the Joseph-form
    update with the encoder position (``H = [1 0 0 0]``), the level held below ``3 eps``.
    filterpy's ``ExtendedKalmanFilter`` does the same for one filter at a time, at a Python
    and small-matrix overhead of about 100 us a step; here one call steps every row, and a
    row's numbers do not depend on the other rows (elementwise arithmetic only, no matmul:
    the compensator's own act and a batch of episodes are then the same code and the same
    bits).

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
    """

    _ARRAYS = ("x", "P", "Q", "r", "v_adapt", "_F")

    def __init__(self, models: Sequence[EKFModel], q: np.ndarray, r: np.ndarray,
                 x0: np.ndarray, p0: np.ndarray) -> None:
        n = len(models)
        self.prm = _RowParams.of(models)
        self.x = np.array(x0, dtype=np.float64).reshape(n, 4)
        self.P = np.array(p0, dtype=np.float64).reshape(n, 4, 4)
        self.Q = np.array(q, dtype=np.float64).reshape(n, 4, 4)
        self.r = np.array(r, dtype=np.float64).reshape(n)
        # below this estimated speed the level is held: 3 eps, where tanh(v / eps) > 0.995
        self.v_adapt = np.array([3.0 * m.eps for m in models])
        # the Jacobians; rows 2 and 3 are constant, diag(1, decay)
        self._F = np.zeros((n, 4, 4))
        self._F[:, 2, 2] = 1.0
        self._F[:, 3, 3] = self.prm.decay

    def __len__(self) -> int:
        return self.x.shape[0]

    def rows(self, sl: slice) -> EKFBank:
        """The filters of rows ``sl`` as a bank whose arrays are views of this one's: stepping
        either steps both."""
        out = object.__new__(EKFBank)
        out.prm = self.prm.rows(sl)
        for name in self._ARRAYS:
            setattr(out, name, getattr(self, name)[sl])
        return out

    @classmethod
    def concatenate(cls, banks: Sequence[EKFBank]) -> EKFBank:
        """One bank of the rows of ``banks`` (copies), in order."""
        out = object.__new__(cls)
        out.prm = _RowParams.concatenate([b.prm for b in banks])
        for name in cls._ARRAYS:
            setattr(out, name, np.concatenate([getattr(b, name) for b in banks]))
        return out

    def predict(self, force: np.ndarray) -> None:
        """Propagate every row over one sample with its motor force ``force`` (n,), N."""
        f, p = self._F, self.P
        # the Jacobian at the prior state, then x+ = f(x, F)
        self.x[...] = _transition(self.x, force, self.prm, f)
        # P = F P F' + Q, the 4x4 products written out (row independent, see above)
        fp = f[:, :, 0, None] * p[:, None, 0, :]
        for j in range(1, 4):
            fp += f[:, :, j, None] * p[:, None, j, :]
        fpf = fp[:, :, 0, None] * f[:, None, :, 0]
        for j in range(1, 4):
            fpf += fp[:, :, j, None] * f[:, None, :, j]
        np.add(fpf, self.Q, out=p)

    def update_position(self, z: np.ndarray) -> None:
        """Update every row with its encoder position ``z`` (n,), m (Joseph form)."""
        p, x, r = self.P, self.x, self.r
        # S = H P H' + R,  K = P H' / S
        k = p[:, :, 0] / (p[:, 0, 0] + r)[:, None]
        # sticking: the level is not observable (any level balances the force), and the
        # stiff law's linearisation would move it at random; hold it (K_c = 0). The Joseph
        # form below keeps P right for this non-optimal gain.
        k[:, 2] = np.where(np.abs(x[:, 1]) < self.v_adapt, 0.0, k[:, 2])
        # y = z - H x
        y = z - x[:, 0]
        x += k * y[:, None]
        # P = (I - K H) P (I - K H)' + K R K'   (Joseph form, as filterpy): P - K P[0, :],
        # then minus (the new) P[:, 0] K', plus R K K'
        p -= k[:, :, None] * p[:, None, 0, :]
        p -= p[:, :, 0, None] * k[:, None, :]
        p += k[:, :, None] * k[:, None, :] * r[:, None, None]

    def friction_force(self) -> np.ndarray:
        """``F_f(v_hat, c_hat) - d_hat`` per row, N: the force the compensator cancels."""
        v, c, d = self.x[:, 1], self.x[:, 2], self.x[:, 3]
        s = _shape(v, self.prm, derivatives=False)[0]
        return c * s + self.prm.fv * v - d


class _EpisodeRows:
    """The filters of one or more episodes with what each row reads: which observation row,
    which columns and scales, its reference positions, its gain and clip.

    One compensator's episode is D rows (one per axis, observation row 0); a batch of N
    episodes is their concatenation, N*D rows. :meth:`step` is the act of every row.
    """

    def __init__(self, bank: EKFBank, xref: np.ndarray, obs_row: np.ndarray,
                 e_col: np.ndarray, f_col: np.ndarray, e_scale: np.ndarray,
                 f_scale: np.ndarray, gain: np.ndarray, limit: np.ndarray,
                 scale: np.ndarray) -> None:
        self.bank, self.xref, self.obs_row = bank, xref, obs_row
        self.e_col, self.f_col, self.e_scale, self.f_scale = e_col, f_col, e_scale, f_scale
        self.gain, self.limit, self.scale = gain, limit, scale

    @classmethod
    def concatenate(cls, parts: Sequence[_EpisodeRows]) -> _EpisodeRows:
        """The rows of ``parts``, part ``i`` reading observation row ``i``; references of
        different lengths are padded with their last position (a row past its end reads its
        last sample, as a single episode does)."""
        k_max = max(p.xref.shape[1] for p in parts)
        xref = np.concatenate([np.pad(p.xref, ((0, 0), (0, k_max - p.xref.shape[1])),
                                      mode="edge") for p in parts])
        obs_row = np.concatenate([np.full(len(p.obs_row), i) for i, p in enumerate(parts)])

        def cat(name: str) -> np.ndarray:
            return np.concatenate([getattr(p, name) for p in parts])

        return cls(EKFBank.concatenate([p.bank for p in parts]), xref, obs_row,
                   cat("e_col"), cat("f_col"), cat("e_scale"), cat("f_scale"), cat("gain"),
                   cat("limit"), cat("scale"))

    def step(self, observations: np.ndarray, k: int) -> np.ndarray:
        """Actions (before the [-1, 1] clip) of step ``k`` for ``observations`` (N, obs_dim)."""
        bank = self.bank
        if k > 0:
            # motor force of the last sample: it acted over [t_k-1, t_k)
            bank.predict(observations[self.obs_row, self.f_col] * self.f_scale)
        # z = x_ref - e
        z = (self.xref[:, min(k, self.xref.shape[1] - 1)]
             - observations[self.obs_row, self.e_col] * self.e_scale)
        bank.update_position(z)
        # u = F_f(v_hat, c_hat) - d_hat: cancel the estimated friction and disturbance
        u = self.gain * bank.friction_force()
        return np.minimum(np.maximum(u, -self.limit), self.limit) / self.scale


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
        cols = np.array(self._cols, dtype=np.intp).reshape(d, 2)

        def per_row(value: float) -> np.ndarray:
            return np.full(d, float(value))

        self._rows = _EpisodeRows(bank, np.array(self._xref, dtype=np.float64),
                                  np.zeros(d, dtype=np.intp), cols[:, 0], cols[:, 1],
                                  per_row(self._e_scale), per_row(self._f_scale),
                                  per_row(self.gain), per_row(self._limit),
                                  per_row(self._scale))
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

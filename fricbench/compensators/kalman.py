"""``kalman``: a Kalman-filter disturbance observer (DOB) on the nominal rigid-body model.

State ``s = [x, v, d]`` (position m, velocity m/s, disturbance force N) with the nominal mass
``M`` and damping ``B`` of ``context.nominal_axis``::

    dx/dt = v
    dv/dt = (F + d - B v) / M        F: motor force (observation column ``motor_force``)
    dd/dt = w                        w: white noise of spectral density q_d (random walk)

discretised with a zero-order hold at the control period ``ts`` (the drive holds the force
over a sample). The measurement is the encoder position ``z = x + n`` reconstructed from the
observation as ``x = x_ref - e``. Friction enters as ``d = -F_f``, so the compensation force
fed back at the velocity-loop output is ``u = -d_hat``.

Tuning (see ``docs/compensators.md``)
------------------------------------
* ``R``: variance of the position measurement, ``q^2 / 12`` for an encoder step ``q``
  (uniform quantisation error) plus ``noise_std^2``; floored at ``(1 nm)^2``.
* ``Q``: chosen for a wanted observer bandwidth ``omega_o``. With the continuous-equivalent
  measurement density ``R_c = R ts``, the steady-state filter of the chain
  ``d -> 1/(M s^2) -> x`` has its three poles on a Butterworth circle of radius
  ``omega_o = (q_d / (M^2 R_c))^(1/6)``, hence ``q_d = M^2 R ts omega_o^6`` (N^2/s). The
  discrete ``Q`` is the exact Van Loan integral of that density over ``ts``.
  :func:`observer_poles` returns the achieved discrete poles for checking.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, ClassVar

import numpy as np
from scipy import linalg

from fricbench._validation import check_nonneg, check_positive
from fricbench.axis import Axis
from fricbench.compensators.base import (
    Compensator,
    CompensatorBatch,
    EpisodeContext,
    feature_index,
)

if TYPE_CHECKING:
    from fricbench.compensators.residual_base import EpisodeObservers

__all__ = ["KalmanDisturbanceObserver", "dob_model", "observer_poles", "ForceObserver",
           "initial_covariance"]

_R_FLOOR = 1.0e-18  # m^2: (1 nm)^2, keeps the filter well posed for an ideal sensor


def dob_model(axis: Axis, bandwidth: float) -> dict[str, np.ndarray]:
    """Discrete model and noise covariances of the disturbance observer.

    Parameters
    ----------
    axis : Axis
        Nominal axis (mass, damping, sample time, encoder step and noise).
    bandwidth : float
        Wanted observer bandwidth ``omega_o``, rad/s.

    Returns
    -------
    dict
        ``F`` (3x3), ``B`` (3x1), ``H`` (1x3), ``Q`` (3x3), ``R`` (1x1), ``q_d`` (N^2/s).
    """
    check_positive("bandwidth", bandwidth, "rad/s")
    m, b, ts = axis.mechanics.mass, axis.mechanics.damping, axis.controller.ts
    q_step = axis.effects.quantization
    # R = q^2 / 12 + sigma_n^2 (uniform quantisation error plus sensor noise)
    r = max(q_step**2 / 12.0 + axis.effects.noise_std**2, _R_FLOOR)
    # q_d = M^2 R_c omega_o^6 with R_c = R ts: Butterworth poles of radius omega_o
    q_d = m**2 * r * ts * bandwidth**6
    a = np.array([[0.0, 1.0, 0.0], [0.0, -b / m, 1.0 / m], [0.0, 0.0, 0.0]])
    bu = np.array([[0.0], [1.0 / m], [0.0]])
    g = np.array([[0.0], [0.0], [1.0]])
    # ZOH: [Phi Gamma; 0 I] = expm([A B; 0 0] ts)
    big = np.zeros((4, 4))
    big[:3, :3], big[:3, 3:] = a, bu
    e = linalg.expm(big * ts)
    phi, gamma = e[:3, :3], e[:3, 3:]
    # Van Loan: Q = int_0^ts Phi(s) G q_d G' Phi(s)' ds
    vl = np.zeros((6, 6))
    vl[:3, :3], vl[:3, 3:], vl[3:, 3:] = -a, g @ g.T * q_d, a.T
    ev = linalg.expm(vl * ts)
    qd = ev[3:, 3:].T @ ev[:3, 3:]
    qd = 0.5 * (qd + qd.T)
    return {"F": phi, "B": gamma, "H": np.array([[1.0, 0.0, 0.0]]), "Q": qd,
            "R": np.array([[r]]), "q_d": np.array(q_d)}


def initial_covariance(axis: Axis, mdl: dict[str, np.ndarray]) -> np.ndarray:
    """``P_0`` of the observer: certain of position and velocity (at rest on the reference),
    unsure of ``d`` by the nominal breakaway force (``mdl``: :func:`dob_model`'s)."""
    fs = axis.friction.kernel_params()["fs"]
    return np.diag([mdl["R"][0, 0], 1e-8, fs**2 + 1.0])


def observer_poles(axis: Axis, bandwidth: float) -> np.ndarray:
    """Continuous-equivalent poles ``ln(z)/ts`` of the steady-state filter, rad/s.

    ``z`` are the eigenvalues of ``(I - K H) F`` with the steady-state gain ``K``.
    """
    mdl = dob_model(axis, bandwidth)
    f, h, q, r = mdl["F"], mdl["H"], mdl["Q"], mdl["R"]
    # P = F P F' - F P H'(H P H' + R)^-1 H P F' + Q  (prior covariance, DARE)
    p = linalg.solve_discrete_are(f.T, h.T, q, r)
    k = p @ h.T @ np.linalg.inv(h @ p @ h.T + r)
    z = np.linalg.eigvals((np.eye(3) - k @ h) @ f)
    return np.log(z.astype(complex)) / axis.controller.ts


class ForceObserver(Compensator):
    """Base of the observers fed back as a force (``kalman``, ``ekf``): the settings they
    share (``gain``, the fraction of the estimate fed back; ``max_force``, its clip in N or
    ``None`` for the env's ``action_scale``) and what they read from the episode."""

    max_force: float | None = None

    def __init__(self, *, gain: float, max_force: float | None) -> None:
        super().__init__()
        check_nonneg("gain", gain)
        if max_force is not None:
            check_positive("max_force", max_force, "N")
        self.gain = gain
        self.max_force = max_force
    _xref: np.ndarray
    _cols: list[tuple[int, int]]
    _e_scale: float
    _f_scale: float
    _scale: float
    _limit: float

    def _read_episode(self, context: EpisodeContext) -> np.ndarray:
        """Read the reference positions (``_xref``, one row per axis), each axis's error and
        motor-force columns and their scales, the force per unit action and the largest force
        fed back (``max_force``, else one unit action); return the start speeds."""
        ref = context.reference
        self._xref = np.atleast_2d(ref.x)
        cfg = context.task.observation
        self._cols = [(feature_index("error", i, cfg), feature_index("motor_force", i, cfg))
                      for i in range(context.n_axes)]
        self._e_scale, self._f_scale = cfg.error_scale, cfg.force_scale
        self._scale = context.task.action_scale
        self._limit = self._scale if self.max_force is None else self.max_force
        return np.atleast_2d(ref.v)[:, 0]


class KalmanDisturbanceObserver(ForceObserver):
    """Disturbance observer: a Kalman filter on ``[x, v, d]`` per axis, feeds back ``-d_hat``.

    The filter is filterpy's ``KalmanFilter`` recursion with its covariance precomputed as a
    gain schedule (:class:`~fricbench.compensators.residual_base.ObserverBank`, one row per
    axis; the covariance does not depend on the measurements), so that one episode and a
    batch of episodes (:meth:`batch`) run the same code.

    Parameters
    ----------
    bandwidth : float
        Observer bandwidth ``omega_o``, rad/s (sets ``Q``, see the module docstring).
    gain : float
        Fraction of the estimate fed back (1 = full cancellation).
    max_force : float or None
        Clip of the compensation force, N (``None``: the env's ``action_scale``).

    Attributes
    ----------
    d_hat_ : ndarray, shape (D,)
        Disturbance estimate of each axis after the last :meth:`act`, N.

    Notes
    -----
    Needs no training (``learns = False``): the model is the nominal axis of the episode
    context, as identified at commissioning.
    """

    id = "kalman"
    action_mode: ClassVar[str] = "force"
    learns: ClassVar[bool] = False
    category: ClassVar[str] = "online"

    def __init__(self, *, bandwidth: float = 1000.0, gain: float = 1.0,
                 max_force: float | None = None) -> None:
        check_positive("bandwidth", bandwidth, "rad/s")
        super().__init__(gain=gain, max_force=max_force)
        self.bandwidth = bandwidth

    @property
    def d_hat_(self) -> np.ndarray:
        """Disturbance estimate of each axis after the last act, N."""
        _ = self.context  # raises before the first episode
        return self._observers.bank.d_hat.copy()

    def _reset(self, context: EpisodeContext, seed: int | None) -> None:
        # imported here: the bank's module builds on this one's model
        from fricbench.compensators.residual_base import EpisodeObservers

        self._observers = EpisodeObservers(context, bandwidth=self.bandwidth, gain=self.gain,
                                           max_force=self.max_force)

    def _act(self, observation: np.ndarray) -> np.ndarray:
        return _observer_action(self._observers, observation[None])

    @classmethod
    def batch(cls, members: Sequence[Compensator]) -> CompensatorBatch:
        """One observer bank over every axis of every member's episode; members with other
        settings or nominal axes (another filter) act row by row (the default)."""
        from fricbench.compensators.residual_base import EpisodeObservers

        # checks the members: one class, each reset, one number of axes
        default = CompensatorBatch(members)
        try:
            stacked = EpisodeObservers.stack(
                [m._observers for m in members if isinstance(m, KalmanDisturbanceObserver)])
        except ValueError:
            return default
        return _KalmanBatch(members, stacked)


def _observer_action(observers: EpisodeObservers, observations: np.ndarray) -> np.ndarray:
    """Step ``observers`` on observations (N, obs_dim); actions ``u / action_scale`` (N * D,)
    with ``u = clip(-gain d_hat, +-max_force)``."""
    observers.step(observations)
    return observers.bank.force() / observers.action_scale


class _KalmanBatch(CompensatorBatch):
    """``kalman``'s episodes in one observer bank."""

    def __init__(self, members: Sequence[Compensator], observers: EpisodeObservers) -> None:
        super().__init__(members)
        self._observers = observers

    def _act_rows(self, observations: np.ndarray) -> np.ndarray:
        return _observer_action(self._observers, observations)

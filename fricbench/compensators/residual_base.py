"""The classical base of ``rl-residual``: the ``kalman`` disturbance observer over many axes.

:class:`ObserverBank` runs ``N`` copies of the Kalman disturbance observer of
:mod:`fricbench.compensators.kalman` side by side, as numpy over the rows: the same model
(:func:`~fricbench.compensators.kalman.dob_model`), the same initial state and covariance, the
same order of predict and update, the same output ``u = clip(-gain d_hat, +-limit)``. One bank
serves both sides of the residual policy: the training env
(:mod:`fricbench.compensators.residual_env`, thousands of rows stepped at once) and the
benchmark compensator (:class:`~fricbench.compensators.rl_residual.ResidualRLCompensator`,
one row per axis), so the base the policy learned on top of is the base it is scored on.

Why the filter can be vectorised cheaply: the covariance recursion of a linear Kalman filter
does not depend on the measurements. Every row starts from the same ``P_0`` and follows the
same ``P_k`` and gain ``K_k`` sequence, only shifted by when its episode started. The sequence
is computed once (:func:`gain_schedule`, the filterpy recursion with the Joseph-form update)
until the gain settles to its steady state; each row then needs only its state update.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fricbench._validation import check_int, check_nonneg, check_positive
from fricbench.axis import Axis
from fricbench.compensators.kalman import dob_model, initial_covariance

__all__ = ["ObserverBank", "gain_schedule"]

_MAX_SCHEDULE = 20_000
"""Longest gain schedule, samples (20 s at 1 kHz); the gain settles within a few hundred."""


def gain_schedule(axis: Axis, bandwidth: float, *, rtol: float = 1e-13) -> np.ndarray:
    """Kalman gains ``K_k`` of the disturbance observer from its first sample on, shape (n, 3).

    The recursion of filterpy's ``KalmanFilter`` (update first, then predict before each later
    update)::

        S = H P H' + R,  K = P H' / S,  P = (I - K H) P (I - K H)' + K R K'   (update)
        P = F P F' + Q                                                      (predict)

    stopped when ``K`` changes by less than ``rtol`` relative (then it stays at its steady
    state: row ``n - 1`` serves every later sample).

    Parameters
    ----------
    axis : Axis
        Nominal axis (as told to the compensator).
    bandwidth : float
        Observer bandwidth, rad/s.
    rtol : float
        Relative change of ``K`` below which the schedule ends.
    """
    mdl = dob_model(axis, bandwidth)
    f, h, q, r = mdl["F"], mdl["H"], mdl["Q"], mdl["R"]
    p = initial_covariance(axis, mdl)
    eye = np.eye(3)
    gains = []
    for _ in range(_MAX_SCHEDULE):
        # K = P H' (H P H' + R)^-1
        pht = p @ h.T
        k = pht @ np.linalg.inv(h @ pht + r)
        i_kh = eye - k @ h
        # Joseph form: P = (I - KH) P (I - KH)' + K R K'
        p = i_kh @ p @ i_kh.T + k @ r @ k.T
        # P = F P F' + Q
        p = f @ p @ f.T + q
        gains.append(k[:, 0])
        if len(gains) > 1 and np.max(np.abs(gains[-1] - gains[-2])) <= rtol * np.max(
                np.abs(gains[-1])):
            break
    return np.array(gains)


class ObserverBank:
    """``n`` Kalman disturbance observers (``kalman``'s filter) stepped together.

    Parameters
    ----------
    axis : Axis
        Nominal axis as told to the compensator (mass, damping, sample time, encoder step and
        noise, nominal static friction for ``P_0``).
    n : int
        Rows (observers).
    bandwidth : float
        Observer bandwidth ``omega_o``, rad/s (``kalman``'s ``bandwidth``).
    gain : float
        Fraction of the estimate fed back (``kalman``'s ``gain``).
    max_force : float
        Clip of the compensation force, N (``kalman`` clips at the env's ``action_scale``).

    Attributes
    ----------
    d_hat : ndarray, shape (n,)
        Disturbance estimate of each row after its last update, N.
    """

    def __init__(self, axis: Axis, n: int, *, bandwidth: float = 1000.0, gain: float = 1.0,
                 max_force: float = 600.0) -> None:
        if not isinstance(axis, Axis):
            raise TypeError(f"axis={axis!r}: expected an Axis")
        self.n = check_int("n", n, 1)
        self.bandwidth = check_positive("bandwidth", bandwidth, "rad/s")
        self.gain = check_nonneg("gain", gain)
        self.max_force = check_positive("max_force", max_force, "N")
        mdl = dob_model(axis, self.bandwidth)
        self._f, self._b = mdl["F"], mdl["B"][:, 0]
        self._gains = gain_schedule(axis, self.bandwidth)
        self._x = np.zeros((self.n, 3))
        self._k = np.zeros(self.n, dtype=np.int64)
        self.d_hat = np.zeros(self.n)

    @property
    def settings(self) -> dict[str, Any]:
        """The base's settings, as recorded with a policy trained on top of it."""
        return {"id": "kalman", "bandwidth": self.bandwidth, "gain": self.gain,
                "max_force": self.max_force}

    def reset(self, rows: np.ndarray, x0: np.ndarray, v0: np.ndarray) -> None:
        """Start the episodes of ``rows`` (int indices) at rest on the reference.

        ``x0``, ``v0``: reference position (m) and velocity (m/s) at their first sample.
        """
        self._x[rows, 0] = x0
        self._x[rows, 1] = v0
        self._x[rows, 2] = 0.0
        self._k[rows] = 0
        self.d_hat[rows] = 0.0

    def step(self, z: np.ndarray, force: np.ndarray, rows: np.ndarray | None = None) -> None:
        """One sample of ``rows`` (all by default): predict with the motor force of the last
        sample (not at an episode's first sample), then update with the position ``z``.

        Parameters
        ----------
        z : ndarray
            Measured position ``x_ref - e`` of each row, m.
        force : ndarray
            Motor force reported with this sample (it acted over the last one), N.
        rows : ndarray of int, optional
            Which rows; ``z`` and ``force`` hold one entry per row given.
        """
        idx = slice(None) if rows is None else rows
        x = self._x[idx]
        k = self._k[idx]
        later = (k > 0)[:, None]
        # predict: x = F x + B u (skipped at an episode's first sample)
        x = np.where(later, x @ self._f.T + np.asarray(force)[:, None] * self._b, x)
        gains = self._gains[np.minimum(k, len(self._gains) - 1)]
        # update: x = x + K (z - H x)
        x = x + gains * (np.asarray(z) - x[:, 0])[:, None]
        self._x[idx] = x
        self._k[idx] = k + 1
        self.d_hat[idx] = x[:, 2]

    def force(self, rows: np.ndarray | None = None) -> np.ndarray:
        """Compensation force of ``rows``, N: ``u = clip(-gain d_hat, +-max_force)``."""
        d = self.d_hat if rows is None else self.d_hat[rows]
        # u = -d_hat: cancel the estimated disturbance (friction enters as d = -F_f)
        return np.clip(-self.gain * d, -self.max_force, self.max_force)

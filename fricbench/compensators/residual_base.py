"""The ``kalman`` disturbance observer over many axes: ``kalman``'s filter, ``rl-residual``'s base.

:class:`ObserverBank` runs ``N`` copies of the Kalman disturbance observer of
:mod:`fricbench.compensators.kalman` side by side, as numpy over the rows: the same model
(:func:`~fricbench.compensators.dob.dob_model`), the same initial state and covariance, the
same order of predict and update as filterpy's ``KalmanFilter``, the same output
``u = clip(-gain d_hat, +-limit)``. A row's numbers never depend on the other rows. One bank
serves ``kalman`` itself and both sides of the residual policy: the training env
(:mod:`fricbench.compensators.residual_env`, thousands of rows stepped at once) and the
benchmark compensators (:class:`~fricbench.compensators.kalman.KalmanDisturbanceObserver`,
:class:`~fricbench.compensators.rl_residual.ResidualRLCompensator`: one row per axis of an
episode, or of every episode of a batch, :class:`EpisodeObservers`), so the base the policy
learned on top of is the base it is scored on.

Why the filter can be vectorised cheaply: the covariance recursion of a linear Kalman filter
does not depend on the measurements. Every row starts from the same ``P_0`` and follows the
same ``P_k`` and gain ``K_k`` sequence, only shifted by when its episode started. The sequence
is computed once (:func:`gain_schedule`, the filterpy recursion with the Joseph-form update)
until the gain settles to its steady state; each row then needs only its state update.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from fricbench._validation import check_int, check_nonneg, check_positive
from fricbench.axis import Axis
from fricbench.compensators.base import EpisodeContext, feature_index
from fricbench.compensators.dob import dob_model, initial_covariance

__all__ = ["EpisodeObservers", "ObserverBank", "gain_schedule"]

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
        x = np.where(later, self._predict(x, np.asarray(force, dtype=np.float64)), x)
        gains = self._gains[np.minimum(k, len(self._gains) - 1)]
        # update: x = x + K (z - H x)
        x = x + gains * (np.asarray(z) - x[:, 0])[:, None]
        self._x[idx] = x
        self._k[idx] = k + 1
        self.d_hat[idx] = x[:, 2]

    def _predict(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """``F x + B u`` of each row, column by column: a row's result never depends on the
        other rows (BLAS ``x @ F'`` blocks its sums by the number of rows), so a row steps
        the same alone, in a bank of one episode's axes or of many episodes."""
        f, b = self._f, self._b
        out = np.empty_like(x)
        for j in range(3):
            out[:, j] = f[j, 0] * x[:, 0] + f[j, 1] * x[:, 1] + f[j, 2] * x[:, 2] + b[j] * u
        return out

    def same_filter(self, other: ObserverBank) -> bool:
        """Whether ``other`` runs the same filter (model, gain schedule, gain and clip), so
        that their rows can be stepped in one bank (:meth:`stack`)."""
        return (isinstance(other, ObserverBank) and self.bandwidth == other.bandwidth
                and self.gain == other.gain
                and self.max_force == other.max_force and np.array_equal(self._f, other._f)
                and np.array_equal(self._b, other._b)
                and np.array_equal(self._gains, other._gains))

    @classmethod
    def stack(cls, banks: Sequence[ObserverBank]) -> ObserverBank:
        """One bank whose rows are the rows of ``banks`` in turn, in their current state.

        Each row then steps exactly, bit for bit, as it would in its own bank.

        Raises
        ------
        ValueError
            If ``banks`` is empty or its banks do not run the same filter
            (:meth:`same_filter`).
        """
        banks = list(banks)
        if not banks:
            raise ValueError("banks: expected at least one ObserverBank")
        first = banks[0]
        for i, other in enumerate(banks[1:], start=1):
            if not first.same_filter(other):
                raise ValueError(f"banks[{i}]: runs another filter than banks[0] (model, gain "
                                 "schedule, gain or max_force); expected the same")
        out = cls.__new__(cls)
        out.n = sum(b.n for b in banks)
        out.bandwidth, out.gain, out.max_force = first.bandwidth, first.gain, first.max_force
        out._f, out._b, out._gains = first._f, first._b, first._gains
        out._x = np.concatenate([b._x for b in banks])
        out._k = np.concatenate([b._k for b in banks])
        out.d_hat = np.concatenate([b.d_hat for b in banks])
        return out

    def force(self, rows: np.ndarray | None = None) -> np.ndarray:
        """Compensation force of ``rows``, N: ``u = clip(-gain d_hat, +-max_force)``."""
        d = self.d_hat if rows is None else self.d_hat[rows]
        # u = -d_hat: cancel the estimated disturbance (friction enters as d = -F_f)
        return np.clip(-self.gain * d, -self.max_force, self.max_force)


class EpisodeObservers:
    """An :class:`ObserverBank` fed by the observations of ``N`` episodes of ``D`` axes each.

    Row ``i * D + j`` of :attr:`bank` observes axis ``j`` of episode ``i``. ``kalman`` and
    ``rl-residual`` step one episode with it (``N = 1``) and a batch of episodes with the
    :meth:`stack` of their members' (one bank for every row): the same code, and each row's
    numbers do not depend on the others (:meth:`ObserverBank.step`).

    Parameters
    ----------
    context : EpisodeContext
        The episode (its reference, nominal axis, observation layout and action scale).
    bandwidth, gain : float
        The observer's settings (:class:`ObserverBank`).
    max_force : float or None
        Clip of the compensation force, N; ``None``: the env's ``action_scale``.

    Attributes
    ----------
    bank : ObserverBank
        The filters, ``N * D`` rows.
    n_episodes, n_axes : int
        ``N`` and ``D``.
    action_scale, force_scale : ndarray, shape (N * D,)
        Each row's force per unit action (N) and per unit of the observation's force (N).
    """

    def __init__(self, context: EpisodeContext, *, bandwidth: float, gain: float,
                 max_force: float | None = None) -> None:
        ref, cfg, d = context.reference, context.task.observation, context.n_axes
        scale = context.task.action_scale
        self.n_episodes, self.n_axes = 1, d
        self._e_cols = np.array([feature_index("error", j, cfg) for j in range(d)])
        self._f_cols = np.array([feature_index("motor_force", j, cfg) for j in range(d)])
        self._xref = np.atleast_2d(ref.x)[None]  # (N, D, K)
        self._e_scale = np.full(d, cfg.error_scale)
        self.force_scale = np.full(d, cfg.force_scale)
        self.action_scale = np.full(d, scale)
        self.bank = ObserverBank(context.nominal_axis, d, bandwidth=bandwidth, gain=gain,
                                 max_force=scale if max_force is None else max_force)
        self.bank.reset(np.arange(d), self._xref[0, :, 0], np.atleast_2d(ref.v)[:, 0])
        self._k = 0

    @classmethod
    def stack(cls, parts: Sequence[EpisodeObservers]) -> EpisodeObservers:
        """The episodes of ``parts`` in turn, in their current state, in one bank.

        Raises
        ------
        ValueError
            If ``parts`` is empty, its banks run different filters, its episodes have other
            observation layouts or numbers of axes, or they are at different samples.
        """
        parts = list(parts)
        if not parts:
            raise ValueError("parts: expected at least one EpisodeObservers")
        first = parts[0]
        for i, p in enumerate(parts[1:], start=1):
            if (p.n_axes != first.n_axes or p._k != first._k
                    or not np.array_equal(p._e_cols, first._e_cols)
                    or not np.array_equal(p._f_cols, first._f_cols)):
                raise ValueError(f"parts[{i}]: another number of axes, observation layout or "
                                 "sample than parts[0]; expected the same")
        out = cls.__new__(cls)
        out.n_episodes, out.n_axes = sum(p.n_episodes for p in parts), first.n_axes
        out._e_cols, out._f_cols, out._k = first._e_cols, first._f_cols, first._k
        # references of other lengths: each held at its last sample, as one episode is
        k_max = max(p._xref.shape[2] for p in parts)
        out._xref = np.concatenate([np.pad(p._xref, ((0, 0), (0, 0), (0, k_max - p._xref.shape[2])),
                                           mode="edge") for p in parts])
        out._e_scale = np.concatenate([p._e_scale for p in parts])
        out.force_scale = np.concatenate([p.force_scale for p in parts])
        out.action_scale = np.concatenate([p.action_scale for p in parts])
        out.bank = ObserverBank.stack([p.bank for p in parts])
        return out

    def step(self, observations: np.ndarray) -> None:
        """One sample of every episode, observations of shape (N, obs_dim)."""
        k = min(self._k, self._xref.shape[2] - 1)
        # z = x_ref - e; the motor force of the last sample drives the prediction
        z = self._xref[:, :, k].reshape(-1) - observations[:, self._e_cols].reshape(-1) \
            * self._e_scale
        self.bank.step(z, observations[:, self._f_cols].reshape(-1) * self.force_scale)
        self._k += 1

"""``kalman``: a Kalman-filter disturbance observer (DOB) on the nominal rigid-body model.

State ``s = [x, v, d]`` (position m, velocity m/s, disturbance force N) on the nominal mass and
damping of ``context.nominal_axis``; the compensation force fed back at the velocity-loop
output is ``u = -d_hat``. The model, its discretisation and its tuning (``Q`` from a wanted
observer bandwidth, ``R`` from the encoder) are :mod:`fricbench.compensators.dob`'s
(re-exported here); the filter runs as one row of
:class:`~fricbench.compensators.residual_base.ObserverBank`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from fricbench._validation import check_nonneg, check_positive
from fricbench.compensators.base import (
    Compensator,
    CompensatorBatch,
    EpisodeContext,
    feature_index,
)
from fricbench.compensators.dob import dob_model, initial_covariance, observer_poles
from fricbench.compensators.residual_base import EpisodeObservers

__all__ = ["KalmanDisturbanceObserver", "dob_model", "observer_poles", "ForceObserver",
           "initial_covariance"]


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
        self._observers = EpisodeObservers(context, bandwidth=self.bandwidth, gain=self.gain,
                                           max_force=self.max_force)

    def _act(self, observation: np.ndarray) -> np.ndarray:
        return _observer_action(self._observers, observation[None])

    @classmethod
    def batch(cls, members: Sequence[Compensator]) -> CompensatorBatch:
        """One observer bank over every axis of every member's episode; members with other
        settings or nominal axes (another filter) act row by row (the default)."""
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

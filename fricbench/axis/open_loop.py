"""The plant driven open loop: the measured effort is the input, the position the output.

The third driver of :mod:`fricbench.axis.plant` (after the cascade of :mod:`fricbench.axis.kernel`
and the linear law of :mod:`fricbench.axis.linear_law`). It adds no compiled code: a linear law
with no feedback and no recursion (``c = 0``, ``a = 0``) whose reference part is the effort,
``u[k] = r[k] = effort[k]``, is exactly the open-loop drive, so this module calls
:func:`fricbench.axis.linear_law.simulate_batch` with empty law coefficients. Per sample::

    u[k]    = effort[k]                                       (zero-order hold)
    M dv/dt = Kt u - (B + fv_dir) v - F_f(x, v) - f0 - F_cog(x)
    y[k]    = sense(x)

The free-run state starts from :func:`initial_state`, fitted on the first logged samples only.
"""

from __future__ import annotations

import numpy as np

from fricbench.axis.linear_law import simulate_batch

__all__ = ["simulate_open_loop", "initial_state"]


def initial_state(y: np.ndarray, ts: float, n_init: int) -> tuple[float, float]:
    """Position and velocity at the first sample, from the first ``n_init`` samples only.

    A quadratic least-squares fit ``y ~ x0 + v0 t + a t^2 / 2`` (a line for fewer than 4
    samples): the value and slope at ``t = 0``.

    Parameters
    ----------
    y : ndarray, shape (K,)
        Measured position, m (only ``y[:n_init]`` is read).
    ts : float
        Sample time, s.
    n_init : int
        Samples used (at least 2).

    Returns
    -------
    x0, v0 : float
        Position (m) and velocity (m/s) at sample 0.
    """
    if n_init < 2:
        raise ValueError(f"n_init={n_init!r}: at least 2 samples are needed for a velocity")
    yy = np.asarray(y, dtype=float)[:n_init]
    if yy.size < n_init or not np.all(np.isfinite(yy)):
        raise ValueError(f"y: expected {n_init} finite samples for the initial state, got "
                         f"{yy.size}")
    t = np.arange(n_init) * ts
    deg = 2 if n_init >= 4 else 1
    coef = np.polynomial.polynomial.polyfit(t, yy, deg)
    return float(coef[0]), float(coef[1])


def simulate_open_loop(plant: np.ndarray, effort: np.ndarray, ts: float, *, x0: float,
                       v0: float, n_sub: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Free-run positions of ``N`` plant rows driven by one effort record (rows in parallel).

    Parameters
    ----------
    plant : ndarray, shape (N, N_PLANT) or (N_PLANT,)
        Plant rows (:mod:`fricbench.axis.plant` layout); sample time and substeps are set here.
    effort : ndarray, shape (K,)
        Applied effort (force with ``Kt = 1``), held over each sample.
    ts : float
        Sample time, s.
    x0, v0 : float
        Initial position (m) and velocity (m/s).
    n_sub : int
        Mechanics substeps per sample.

    Returns
    -------
    y : ndarray, shape (N, K)
        Simulated logged position (NaN after a divergence).
    status : ndarray of int64, shape (N,)
        0 when a row stayed finite, 1 when it diverged.
    """
    P = np.atleast_2d(np.asarray(plant, dtype=float))
    r = np.ascontiguousarray(effort, dtype=float)
    if r.ndim != 1:
        raise ValueError(f"effort: expected a 1-D array, got shape {r.shape}")
    if not np.all(np.isfinite(r)):
        raise ValueError("effort: expected finite values")
    n_rows = P.shape[0]
    empty = np.zeros((n_rows, 0))
    y, _, status = simulate_batch(P, empty, empty, r, np.arange(r.size) * ts, ts,
                                  n_sub=n_sub, x0=x0, v0=v0, u_init=empty,
                                  y_init=np.zeros(0))
    return y, status

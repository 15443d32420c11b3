"""Least-squares solves of the diagnosis, on scipy's solvers.

* :func:`solve_ls`: the inverse-dynamics and screening regressions, tall and thin (thousands
  of rows, a dozen columns). They are reduced to their small Gram matrix first (one matrix
  product instead of a factorisation of the tall matrix: LAPACK's tall factorisations are slow
  when other processes load the machine), with columns scaled to unit norm so the conditioning
  is that of the correlations between regressors. Sign constraints are solved on the reduced
  problem by :func:`scipy.optimize.lsq_linear`.
* :func:`bounded_least_squares`: the output-error fits, by
  :func:`scipy.optimize.least_squares` (trust-region reflective, bounds) with a Jacobian from
  finite differences computed in one batched (parallel) simulation per iteration, its dense
  algebra on one BLAS thread (:mod:`fricbench._blas`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import optimize

from fricbench._blas import one_blas_thread

__all__ = ["solve_ls", "bounded_least_squares", "batched_jacobian", "sumsq", "matvec"]


# Vector products go through einsum rather than BLAS: after a parallel numba region the
# OpenMP worker threads keep spinning, and threaded BLAS level-1/2 calls then stall for
# milliseconds each (measured: a 25k-element dot product taking 12 ms instead of 6 us).
def sumsq(a: np.ndarray) -> float:
    """``sum(a**2)`` without BLAS."""
    return float(np.einsum("i,i->", a, a))


def matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A @ x`` for a matrix ``A`` without BLAS."""
    return np.einsum("ij,j->i", A, x)


def solve_ls(X: np.ndarray, y: np.ndarray, nonneg: np.ndarray | None = None,
             rcond: float = 1e-12) -> np.ndarray:
    """Least-squares coefficients of ``y ~ X c``, optionally with ``c[nonneg] >= 0``.

    Parameters
    ----------
    X : ndarray, shape (n, p)
    y : ndarray, shape (n,)
    nonneg : ndarray of bool, shape (p,), optional
        Coefficients constrained to be non-negative (solved by
        :func:`scipy.optimize.lsq_linear` on the reduced problem).
    rcond : float
        Directions of the scaled Gram matrix with eigenvalues below ``rcond`` times the largest
        are dropped (collinear regressors).

    Returns
    -------
    ndarray, shape (p,)
    """
    p = X.shape[1]
    if p == 0:
        return np.zeros(0)
    Xt = np.ascontiguousarray(X.T)
    norm = np.sqrt(np.einsum("ij,ij->i", Xt, Xt))
    norm = np.where(norm > 0, norm, 1.0)
    Xs = Xt / norm[:, None]
    # ||X c - y||^2 = ||R c - d||^2 + const with X'X = R'R: G = V diag(w) V', R = diag(sqrt w) V'
    w, V = np.linalg.eigh(Xs @ Xs.T)
    keep = w > rcond * max(float(w.max()), 1e-300)
    w, V = w[keep], V[:, keep]
    Vb = matvec(V.T, matvec(Xs, y))
    # minimum-norm solution in the kept directions: c = V diag(1/w) V' X'y
    c = matvec(V, Vb / w)
    if nonneg is not None and np.any(nonneg & (c < 0)):
        # same problem, square: ||X c - y||^2 = ||R c - d||^2 + const, R = diag(sqrt w) V'
        sw = np.sqrt(w)
        lo = np.where(nonneg, 0.0, -np.inf)
        c = optimize.lsq_linear(sw[:, None] * V.T, Vb / sw, bounds=(lo, np.inf),
                                method="bvls").x
    return c / norm


def batched_jacobian(residuals: Callable[[np.ndarray], np.ndarray], steps: np.ndarray,
                     hi: np.ndarray) -> tuple[Callable[[np.ndarray], np.ndarray],
                                              Callable[[np.ndarray], np.ndarray]]:
    """``fun`` and ``jac`` for :func:`scipy.optimize.least_squares` from a batched residual.

    Parameters
    ----------
    residuals : callable
        ``residuals(thetas)`` with ``thetas`` of shape (m, p) returns the residual vectors,
        shape (m, n) (evaluated in parallel by the caller).
    steps : ndarray, shape (p,)
        Forward-difference steps (a step that would pass ``hi`` is taken backwards).
    hi : ndarray, shape (p,)
        Upper bounds.

    Returns
    -------
    fun : callable
        ``fun(theta)``, shape (n,).
    jac : callable
        ``jac(theta)``, shape (n, p): one batch of ``p`` simulations (the residual at ``theta``
        is the one ``fun`` last returned when it was evaluated there).
    """
    last: dict[str, np.ndarray] = {}

    def fun(theta: np.ndarray) -> np.ndarray:
        r = residuals(theta[None, :])[0]
        last["theta"], last["r"] = theta.copy(), r
        return r

    def jac(theta: np.ndarray) -> np.ndarray:
        r = last["r"] if "theta" in last and np.array_equal(last["theta"], theta) else fun(theta)
        # J[:, j] = (r(theta + h_j e_j) - r(theta)) / h_j
        h = np.where(theta + steps <= hi, steps, -steps)
        rs = residuals(theta[None, :] + np.diag(h))
        return ((rs - r[None, :]) / h[:, None]).T

    return fun, jac


def _no_last_jacobian(fun: Callable[[np.ndarray], np.ndarray],
                      jac: Callable[[np.ndarray], np.ndarray], max_nfev: int,
                      skipped: list[bool]) -> tuple[Callable[[np.ndarray], np.ndarray],
                                                    Callable[[np.ndarray], np.ndarray]]:
    """``fun`` and ``jac`` with the Jacobian scipy asks for once its last evaluation is spent
    replaced by zeros (``skipped`` records it).

    :func:`scipy.optimize.least_squares` (``trf``) differentiates at every accepted point,
    the last one too, and then stops on ``max_nfev`` without stepping from it: that Jacobian
    (a batch of ``p`` free runs) only sets the returned ``jac``, ``grad`` and ``status``. The
    point, the cost and the residual returned are the same numbers without it."""
    calls = [0]
    size = [0]

    def f(theta: np.ndarray) -> np.ndarray:
        calls[0] += 1
        r = fun(theta)
        size[0] = r.shape[0]
        return r

    def j(theta: np.ndarray) -> np.ndarray:
        # the first Jacobian (the start's) is always taken: with max_nfev 1 it is the result
        if calls[0] >= max_nfev and calls[0] > 1:
            skipped.append(True)
            return np.zeros((size[0], theta.shape[0]))
        return jac(theta)

    return f, j


def bounded_least_squares(residuals: Callable[[np.ndarray], np.ndarray], theta0: np.ndarray,
                          lo: np.ndarray, hi: np.ndarray, steps: np.ndarray, *,
                          max_iter: int = 20, ftol: float = 1e-4,
                          final_jacobian: bool = True) -> optimize.OptimizeResult:
    """Bounded nonlinear least squares with batched finite differences.

    :func:`scipy.optimize.least_squares` (``method="trf"``, Jacobian scaling) with the
    Jacobian of :func:`batched_jacobian`.

    Parameters
    ----------
    residuals : callable
        ``residuals(thetas)`` with ``thetas`` of shape (m, p) returns the residual vectors,
        shape (m, n) (evaluated in parallel by the caller).
    theta0 : ndarray, shape (p,)
        Start (projected into the bounds).
    lo, hi : ndarray, shape (p,)
        Bounds.
    steps : ndarray, shape (p,)
        Finite-difference steps.
    max_iter : int
        Most trial steps (evaluations of ``residuals`` at one point, after the start); with
        ``max_iter=0`` only the Jacobian at the start is computed.
    ftol : float
        Stop when a step lowers the cost by less than this fraction.
    final_jacobian : bool
        Whether the Jacobian at the end point is wanted when the fit ends on ``max_iter``.
        Without it that batch of ``p`` free runs is not simulated (7 % of the simulations of
        ``diagnose_timing``'s run), ``jac`` is None then, and ``x``, ``cost`` and ``fun``
        are the same numbers (see :func:`_no_last_jacobian`).

    Returns
    -------
    scipy.optimize.OptimizeResult
        ``x``, ``cost``, ``fun`` (residual at ``x``), ``jac`` (shape (n, p), at ``x``; None
        when ``final_jacobian`` is False and it was not taken), ``nfev``, ``njev``, ...
    """
    theta0 = np.clip(np.asarray(theta0, dtype=float), lo, hi)
    fun, jac = batched_jacobian(residuals, steps, hi)
    skipped: list[bool] = []
    if not final_jacobian:
        fun, jac = _no_last_jacobian(fun, jac, max_iter + 1, skipped)
    with one_blas_thread():  # see fricbench._blas: an SVD of the Jacobian per step
        sol = optimize.least_squares(fun, theta0, jac=jac, bounds=(lo, hi), method="trf",
                                     x_scale="jac", ftol=ftol, max_nfev=max_iter + 1)
    if skipped:
        sol.jac = None
    return sol

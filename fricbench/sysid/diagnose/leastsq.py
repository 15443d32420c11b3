"""Small least-squares solvers tuned for the diagnosis.

The regressions here are tall and thin (thousands of rows, a dozen columns). They are solved
through the scaled normal equations and a pseudo-inverse of the small Gram matrix, which costs
one matrix product instead of a factorisation of the tall matrix (LAPACK's tall
factorisations are slow when other processes load the machine). Columns are scaled to unit
norm first, so the conditioning is that of the correlations between regressors.

:func:`levenberg_marquardt` minimises a simulation error whose Jacobian is obtained by
finite differences in one batched (parallel) simulation per iteration, and tries several
damping values at once in a second batch.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["solve_ls", "levenberg_marquardt", "LMResult", "sumsq", "matvec"]


# Vector products go through einsum rather than BLAS: after a parallel numba region the
# OpenMP worker threads keep spinning, and threaded BLAS level-1/2 calls then stall for
# milliseconds each (measured: a 25k-element dot product taking 12 ms instead of 6 us).
def sumsq(a: np.ndarray) -> float:
    """``sum(a**2)`` without BLAS."""
    return float(np.einsum("i,i->", a, a))


def matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A @ x`` for a matrix ``A`` without BLAS."""
    return np.einsum("ij,j->i", A, x)


def _pinv_solve(G: np.ndarray, b: np.ndarray, rcond: float = 1e-12) -> np.ndarray:
    w, V = np.linalg.eigh(G)
    keep = w > rcond * max(float(w.max()), 1e-300)
    return matvec(V[:, keep], matvec(V[:, keep].T, b) / w[keep])


def solve_ls(X: np.ndarray, y: np.ndarray, nonneg: np.ndarray | None = None,
             rcond: float = 1e-12) -> np.ndarray:
    """Least-squares coefficients of ``y ~ X c``, optionally with ``c[nonneg] >= 0``.

    Parameters
    ----------
    X : ndarray, shape (n, p)
    y : ndarray, shape (n,)
    nonneg : ndarray of bool, shape (p,), optional
        Coefficients constrained to be non-negative (active set: a coefficient that comes out
        negative is fixed at 0 and the rest re-solved).
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
    G = Xs @ Xs.T
    b = matvec(Xs, y)
    free = np.ones(p, dtype=bool)
    coef = np.zeros(p)
    for _ in range(p + 1):
        c = np.zeros(p)
        idx = np.flatnonzero(free)
        c[idx] = _pinv_solve(G[np.ix_(idx, idx)], b[idx], rcond)
        coef = c / norm
        if nonneg is None:
            break
        bad = free & nonneg & (coef < 0)
        if not bad.any():
            break
        free &= ~bad
    return coef


@dataclass
class LMResult:
    """Outcome of :func:`levenberg_marquardt`.

    Attributes
    ----------
    theta : ndarray
        Solution.
    residual : ndarray
        Residual at the solution.
    cost : float
        Half the squared norm of the residual.
    n_iter : int
        Iterations (one Jacobian each).
    jac_rows : ndarray or None
        Jacobian at the start of the last iteration, one row per parameter.
    """

    theta: np.ndarray
    residual: np.ndarray
    cost: float
    n_iter: int
    jac_rows: np.ndarray | None


def levenberg_marquardt(residuals: Callable[[np.ndarray], np.ndarray], theta0: np.ndarray,
                        lo: np.ndarray, hi: np.ndarray, steps: np.ndarray, *,
                        max_iter: int = 20, ftol: float = 1e-4, lam0: float = 1e-2
                        ) -> LMResult:
    """Bounded Levenberg-Marquardt with batched finite differences.

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
        Finite-difference steps (a step that would leave the bounds is taken backwards).
    max_iter : int
        Most iterations.
    ftol : float
        Stop when an iteration lowers the cost by less than this fraction.
    lam0 : float
        Initial damping, relative to the diagonal of the Gram matrix.

    Returns
    -------
    LMResult
    """
    theta = np.clip(np.asarray(theta0, dtype=float), lo, hi)
    r = residuals(theta[None, :])[0]
    cost = 0.5 * sumsq(r)
    lam = lam0
    jac_rows = None
    n_iter = 0
    for _ in range(max_iter):
        n_iter += 1
        h = np.where(theta + steps <= hi, steps, -steps)
        rs = residuals(theta[None, :] + np.diag(h))
        jac_rows = (rs - r[None, :]) / h[:, None]
        G = jac_rows @ jac_rows.T
        g = matvec(jac_rows, r)
        d = np.maximum(np.diag(G), 1e-12 * max(float(np.max(np.diag(G))), 1e-300))
        trials = []
        for lm in (lam * 0.1, lam, lam * 10.0):
            try:
                delta = -np.linalg.solve(G + lm * np.diag(d), g)
            except np.linalg.LinAlgError:
                delta = -_pinv_solve(G + lm * np.diag(d), g)
            trials.append(np.clip(theta + delta, lo, hi))
        rt = residuals(np.array(trials))
        costs = 0.5 * np.einsum("ij,ij->i", rt, rt)  # no BLAS (see sumsq)
        best = int(np.argmin(costs))
        if not np.isfinite(costs[best]) or costs[best] >= cost:
            lam *= 100.0
            if lam > 1e8:
                break
            continue
        improvement = (cost - costs[best]) / max(cost, 1e-300)
        theta, r, cost = trials[best], rt[best], float(costs[best])
        lam = (lam * 0.1, lam, lam * 10.0)[best]
        lam = min(max(lam, 1e-7), 1e8)
        if improvement < ftol:
            break
    return LMResult(theta, r, cost, n_iter, jac_rows)

"""Library solvers against the project's former hand-written ones, on diagnosis problems.

``python -m fricbench.bench.solver_benchmark [--emps DIR] [--samples 10000]``

The project keeps a numerical routine of its own only where it is more than 1.5 times
faster than the library's at equal accuracy, measured here in one process. Three pairs:

* **output-error fits**: the bounded Levenberg-Marquardt the diagnosis used (batched finite
  differences, three damping values tried in one parallel batch) against
  :func:`~fricbench.sysid.diagnose.leastsq.bounded_least_squares`
  (:func:`scipy.optimize.least_squares`, same batched Jacobian);
* **sign-constrained regressions**: the former active set (a negative coefficient is fixed at
  zero and the rest re-solved) against :func:`~fricbench.sysid.diagnose.leastsq.solve_ls`
  (:func:`scipy.optimize.lsq_linear` on the reduced problem);
* **first-order hold** of the transfer-function fit: a Taylor matrix exponential against
  :func:`scipy.signal.cont2discrete` (``method="foh"``, :func:`scipy.linalg.expm`).

The problems are the ones :func:`~fricbench.sysid.diagnose.diagnose` poses on a simulated run
of :func:`fricbench.axis.simulate` (position only, the case where every fit is output error)
and on the measured EMPS runs when their folder is given: each solver call of one diagnosis
is recorded, then solved again by both solvers in turn. Accuracy is the final cost of each
problem; time is wall clock (it depends on what else runs on the machine: the load average is
printed).

On the shared 2-core machine (load average 8 to 9), library time over own time: 1.14 and 0.73
for the fits (simulated run, EMPS; library cost 0.8 % and 0.01 % lower), 1.07 and 1.01 for the
regressions (same costs), 0.99 and 1.28 for ``fit_tf`` (same costs). No hand-written solver is
more than 1.5 times faster, so none is kept.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import linalg, signal

__all__ = ["Comparison", "compare_fits", "compare_regressions", "compare_holds", "main"]


# -- the former hand-written solvers (the reference of the comparison) -------------------------
def _own_levenberg_marquardt(residuals: Callable[[np.ndarray], np.ndarray], theta0: np.ndarray,
                             lo: np.ndarray, hi: np.ndarray, steps: np.ndarray, *,
                             max_iter: int = 20, ftol: float = 1e-4, lam0: float = 1e-2
                             ) -> tuple[np.ndarray, float]:
    """Bounded Levenberg-Marquardt with batched finite differences (the former solver)."""
    from fricbench.sysid.diagnose.leastsq import matvec, sumsq

    theta = np.clip(np.asarray(theta0, dtype=float), lo, hi)
    r = residuals(theta[None, :])[0]
    cost = 0.5 * sumsq(r)
    lam = lam0
    for _ in range(max_iter):
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
                delta = -_own_pinv_solve(G + lm * np.diag(d), g)
            trials.append(np.clip(theta + delta, lo, hi))
        rt = residuals(np.array(trials))
        costs = 0.5 * np.einsum("ij,ij->i", rt, rt)
        best = int(np.argmin(costs))
        if not np.isfinite(costs[best]) or costs[best] >= cost:
            lam *= 100.0
            if lam > 1e8:
                break
            continue
        improvement = (cost - costs[best]) / max(cost, 1e-300)
        theta, r, cost = trials[best], rt[best], float(costs[best])
        lam = min(max((lam * 0.1, lam, lam * 10.0)[best], 1e-7), 1e8)
        if improvement < ftol:
            break
    return theta, cost


def _own_pinv_solve(G: np.ndarray, b: np.ndarray, rcond: float = 1e-12) -> np.ndarray:
    w, V = np.linalg.eigh(G)
    keep = w > rcond * max(float(w.max()), 1e-300)
    return V[:, keep] @ ((V[:, keep].T @ b) / w[keep])


def _own_active_set_ls(X: np.ndarray, y: np.ndarray, nonneg: np.ndarray | None = None,
                       rcond: float = 1e-12) -> np.ndarray:
    """Sign-constrained least squares by the former active set (the former ``solve_ls``)."""
    p = X.shape[1]
    Xt = np.ascontiguousarray(X.T)
    norm = np.sqrt(np.einsum("ij,ij->i", Xt, Xt))
    norm = np.where(norm > 0, norm, 1.0)
    Xs = Xt / norm[:, None]
    G = Xs @ Xs.T
    b = np.einsum("ij,j->i", Xs, y)
    free = np.ones(p, dtype=bool)
    coef = np.zeros(p)
    for _ in range(p + 1):
        c = np.zeros(p)
        idx = np.flatnonzero(free)
        c[idx] = _own_pinv_solve(G[np.ix_(idx, idx)], b[idx], rcond)
        coef = c / norm
        if nonneg is None:
            break
        bad = free & nonneg & (coef < 0)
        if not bad.any():
            break
        free &= ~bad
    return coef


def _own_expm(m: np.ndarray) -> np.ndarray:
    """Matrix exponential: balancing, scaling and squaring, Taylor series (the former one)."""
    mb, (sc, _) = linalg.matrix_balance(m, permute=False, separate=True)
    nrm = float(np.max(np.sum(np.abs(mb), axis=1)))
    squarings = int(np.ceil(np.log2(nrm / 0.25))) if nrm > 0.25 else 0
    x = mb / 2.0**squarings
    out = np.eye(m.shape[0])
    term = np.eye(m.shape[0])
    for k in range(1, 16):  # ||x|| <= 1/4: the remainder is below 1e-21
        term = term @ x / k
        out = out + term
    for _ in range(squarings):
        out = out @ out
    return (out * sc[:, None]) / sc[None, :]


def _own_foh(num: np.ndarray, den: np.ndarray, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """First-order hold of ``num/den`` through :func:`_own_expm` (the former one)."""
    num = np.atleast_1d(np.asarray(num, dtype=float))
    den = np.atleast_1d(np.asarray(den, dtype=float))
    if len(den) == 1:
        return num / den[0], np.ones(1)
    a_c, b_c, c_c, d_c = signal.tf2ss(num, den)
    n = a_c.shape[0]
    blk = np.zeros((n + 2, n + 2))
    blk[:n, :n] = a_c * ts
    blk[:n, n:n + 1] = b_c * ts
    blk[n, n + 1] = 1.0
    e = _own_expm(blk)
    phi, g1, g2 = e[:n, :n], e[:n, n:n + 1], e[:n, n + 1:n + 2]
    numd, dend = signal.ss2tf(phi, phi @ g2 + g1 - g2, c_c, d_c + c_c @ g2)
    return np.ravel(numd), np.ravel(dend)


# -- recording and timing ---------------------------------------------------------------------
@dataclass(frozen=True)
class Comparison:
    """Both solvers on one set of problems.

    Attributes
    ----------
    what : str
        The problems.
    n_problems : int
    own_s, lib_s : float
        Wall time of the former solver and of the library's over all problems, s.
    own_cost, lib_cost : float
        Sum of the final costs over all problems (half squared residual norms).
    lib_worse, lib_better : int
        Problems where the library's final cost is more than 1 % above (below) the former's.
    """

    what: str
    n_problems: int
    own_s: float
    lib_s: float
    own_cost: float
    lib_cost: float
    lib_worse: int
    lib_better: int

    @property
    def speed_ratio(self) -> float:
        """Library time over own time (above 1: the former solver is faster)."""
        return self.lib_s / max(self.own_s, 1e-12)

    def lines(self) -> list[str]:
        """Printable summary."""
        return [
            f"{self.what}: {self.n_problems} problems",
            f"  own     {self.own_s:8.3f} s   sum of costs {self.own_cost:.6g}",
            f"  library {self.lib_s:8.3f} s   sum of costs {self.lib_cost:.6g}",
            f"  time library/own {self.speed_ratio:.2f}; cost library/own "
            f"{self.lib_cost / max(self.own_cost, 1e-300):.4f}; library >1 % worse on "
            f"{self.lib_worse}, >1 % better on {self.lib_better}",
        ]


@contextlib.contextmanager
def _recording(module: Any, name: str, calls: list) -> Iterator[None]:
    """Record the arguments of every call of ``module.name`` (and still make the call)."""
    original = getattr(module, name)

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        calls.append((args, kwargs))
        return original(*args, **kwargs)

    setattr(module, name, wrapper)
    try:
        yield
    finally:
        setattr(module, name, original)


def _compare(what: str, problems: Sequence[tuple[tuple, dict]],
             own: Callable[..., float], lib: Callable[..., float]) -> Comparison:
    own_s = lib_s = own_cost = lib_cost = 0.0
    worse = better = 0
    for k, (args, kwargs) in enumerate(problems):
        # alternate which solver goes first, so that a slow spell of the machine hits both
        order = ((own, lib) if k % 2 == 0 else (lib, own))
        out: dict[Callable[..., float], tuple[float, float]] = {}
        for f in order:
            t0 = time.perf_counter()
            cost = f(*args, **kwargs)
            out[f] = (time.perf_counter() - t0, cost)
        own_s += out[own][0]
        lib_s += out[lib][0]
        c_own, c_lib = out[own][1], out[lib][1]
        own_cost += c_own
        lib_cost += c_lib
        worse += int(c_lib > 1.01 * c_own)
        better += int(c_lib < c_own / 1.01)
    return Comparison(what, len(problems), own_s, lib_s, own_cost, lib_cost, worse, better)


def _record_diagnosis(run: Any, validate: Any = None) -> tuple[list, list]:
    """The output-error fits and sign-constrained regressions of one diagnosis."""
    from fricbench.sysid.diagnose import models
    from fricbench.sysid.diagnose.diagnosis import diagnose

    fits: list = []
    regressions: list = []
    with _recording(models, "bounded_least_squares", fits), \
            _recording(models, "solve_ls", regressions):
        diagnose(run, validate=validate)
    return fits, [c for c in regressions if len(c[0]) > 2 and c[0][2] is not None]


def compare_fits(problems: Sequence[tuple[tuple, dict]], what: str) -> Comparison:
    """Former Levenberg-Marquardt against ``bounded_least_squares`` on recorded fits."""
    from fricbench._blas import one_blas_thread
    from fricbench.sysid.diagnose.leastsq import bounded_least_squares

    def own(*args: Any, **kwargs: Any) -> float:
        with one_blas_thread():  # as the library solver runs
            return _own_levenberg_marquardt(*args, **kwargs)[1]

    def lib(*args: Any, **kwargs: Any) -> float:
        return float(bounded_least_squares(*args, **kwargs).cost)

    return _compare(what, problems, own, lib)


def compare_regressions(problems: Sequence[tuple[tuple, dict]], what: str,
                        repeat: int = 20) -> Comparison:
    """Former active set against ``solve_ls`` (lsq_linear) on recorded regressions.

    Each regression is solved ``repeat`` times per solver (one takes well under a millisecond).
    """
    from fricbench.sysid.diagnose.leastsq import solve_ls

    def cost(X: np.ndarray, y: np.ndarray, c: np.ndarray) -> float:
        r = y - X @ c
        return 0.5 * float(r @ r)

    def timed(solver: Callable[..., np.ndarray]) -> Callable[..., float]:
        def run(*args: Any, **kwargs: Any) -> float:
            for _ in range(repeat):
                c = solver(*args, **kwargs)
            return cost(args[0], args[1], c)
        return run

    return _compare(what, problems, timed(_own_active_set_ls), timed(solve_ls))


def compare_holds(x_ref: np.ndarray, x: np.ndarray, ts: float, what: str,
                  repeat: int = 2) -> Comparison:
    """``fit_tf`` with the former hold against ``fit_tf`` with ``cont2discrete``.

    The cost is half the sum of squared free-run errors of the fitted model (m^2).
    """
    from fricbench.sysid import tf_fit

    library_hold = tf_fit._foh

    def with_hold(hold: Callable[..., tuple[np.ndarray, np.ndarray]]) -> Callable[[], float]:
        def run() -> float:
            saved = tf_fit._foh
            tf_fit._foh = hold
            try:
                g = tf_fit.fit_tf(x_ref, x, ts)
            finally:
                tf_fit._foh = saved
            e = (x_ref - x) - tf_fit.tf_error_response(g, x_ref, ts)
            return 0.5 * float(e @ e)
        return run

    return _compare(what, [((), {})] * repeat, with_hold(_own_foh), with_hold(library_hold))


# -- the problems -------------------------------------------------------------------------------
def simulated_run(samples: int = 10_000, seed: int = 0) -> Any:
    """Position-only run of the default axis with Stribeck friction and a cogging ripple."""
    from fricbench.bench.diagnose_timing import benchmark_run

    return benchmark_run(samples, effort=False, seed=seed)


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: print both solvers' time and cost on each problem set, and the ratio."""
    ap = argparse.ArgumentParser(prog="python -m fricbench.bench.solver_benchmark",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=10_000,
                    help="length of the simulated run (default 10000)")
    ap.add_argument("--emps", default=None,
                    help="folder of emps_train.csv and emps_test_pulses.csv (optional)")
    args = ap.parse_args(argv)
    from fricbench.sysid.io import load_run

    sets: list[tuple[str, Any, Any]] = [
        (f"simulated run, {args.samples} samples, position only",
         simulated_run(args.samples), None)]
    if args.emps is not None:
        def emps(name: str) -> Any:
            return load_run(os.path.join(args.emps, name), time="t_s", reference="q_ref_m",
                            position="q_m", effort="force_N", effort_required=True)

        sets.append(("EMPS train (--validate pulses)", emps("emps_train.csv"),
                     emps("emps_test_pulses.csv")))
    # compile the numba kernels (or load them from their cache) before any timing
    _record_diagnosis(simulated_run(2000, seed=1))
    for label, run, validate in sets:
        fits, regressions = _record_diagnosis(run, validate)
        for cmp in (compare_fits(fits, f"{label}: output-error fits"),
                    compare_regressions(regressions, f"{label}: sign-constrained regressions")
                    if regressions else None,
                    compare_holds(run.x_ref, run.x, run.ts, f"{label}: fit_tf")):
            if cmp is not None:
                print("\n".join(cmp.lines()), flush=True)
    la = os.getloadavg()
    print(f"load average: {la[0]:.2f} {la[1]:.2f} {la[2]:.2f} on {os.cpu_count()} cpus")
    return 0


if __name__ == "__main__":
    sys.exit(main())

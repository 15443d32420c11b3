"""Continuous-time transfer-function identification of a position loop from sampled data.

The model is the paper's reference-to-position transfer function (its eq. 22 has two poles and
one zero)::

    G(s) = X(s) / X_ref(s) = (b_m s^m + ... + b_0) / (s^n + a_{n-1} s^{n-1} + ... + a_0)

fitted from the sampled reference ``x_ref`` and measured position ``x`` at sample time ``ts``.

Method (output-error, i.e. simulation-error, initialised from least squares)
--------------------------------------------------------------------------------
The fit works on the tracking error ``e = x_ref - x`` rather than on ``x``: the error path is
``E/X_ref = 1 - G = C(s)/D(s)`` with ``C = D - N``, which keeps the regressors well conditioned
(``x`` and ``x_ref`` differ by a few micrometres over metres of travel).

1. **Least squares (state-variable filter).** Both signals pass through
   ``lambda^n / (s + lambda)^n`` and its derivatives; ``D e = C x_ref`` is then linear in the
   coefficients and solved by least squares for a few filter bandwidths ``lambda``. This
   equation-error estimate is biased by output noise; it only provides starting points.
2. **Output error.** From each starting point, the coefficients are refined by
   Levenberg-Marquardt on the *simulation* error ``e - (C/D) x_ref`` (the model runs free on the
   reference, never on the measured output), which stays unbiased under white measurement noise
   and quantisation. The best refinement is returned.

Denominator coefficients are optimised as logarithms (positive, as every stable polynomial's
are) and the others scaled by powers of the loop's natural frequency, so the problem is well
scaled whatever the bandwidth. Simulations discretise the continuous model with a first-order
hold (:func:`scipy.signal.cont2discrete`; the reference is smooth, so the linear interpolation
between samples is accurate to ``O(ts^2)``) and start at rest in steady state at ``x_ref[0]``.

DC gain: free by default (``dc_gain=None``: ``b_0`` and ``a_0`` both fitted); ``dc_gain=1.0``
constrains ``b_0 = a_0``, which holds for any position loop with integral action or a type-1
plant (the paper's eq. 22 has DC gain 1). With enough motion the free fit returns a DC gain
within a few ppm of 1 anyway.
"""

from __future__ import annotations

from collections.abc import Sequence

import control
import numpy as np
from scipy import optimize, signal

from fricbench._blas import one_blas_thread
from fricbench._validation import check_int, check_positive, check_signal

__all__ = ["fit_tf", "fit_tf_multi", "simulate_tf", "tf_error_response", "TFFitError"]

_MIN_SAMPLES = 50


class TFFitError(ValueError):
    """The data cannot identify the requested transfer function (no motion, too short, ...)."""


# -- validation -------------------------------------------------------------------------------
def _check_pair(x_ref: object, x: object, label: str = "") -> tuple[np.ndarray, np.ndarray]:
    xr = check_signal(f"x_ref{label}", x_ref)
    xm = check_signal(f"x{label}", x)
    if xr.shape != xm.shape:
        raise ValueError(
            f"x_ref{label} has {xr.shape[0]} samples but x{label} has {xm.shape[0]}: "
            "reference and measured position must have the same length"
        )
    if xr.shape[0] < _MIN_SAMPLES:
        raise TFFitError(f"x_ref{label} has {xr.shape[0]} samples: need at least {_MIN_SAMPLES}")
    if np.ptp(xr) <= 0.0:
        raise TFFitError(f"x_ref{label} is constant: a run without motion identifies nothing")
    return xr, xm


def _check_orders(n_poles: int, n_zeros: int) -> tuple[int, int]:
    n = check_int("n_poles", n_poles, 1, 6)
    m = check_int("n_zeros", n_zeros, 0, 5)
    if m >= n:
        raise ValueError(f"n_zeros={n_zeros!r}: expected fewer zeros than poles (n_poles={n})")
    return n, m


# -- simulation -------------------------------------------------------------------------------
def _foh(num: np.ndarray, den: np.ndarray, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """First-order-hold discretisation of ``num/den`` (descending powers) as lfilter b, a.

    The input is taken as linear between samples (as ``control.forced_response`` does):
    :func:`scipy.signal.cont2discrete` with ``method="foh"``.
    """
    num = np.atleast_1d(np.asarray(num, dtype=float))
    den = np.atleast_1d(np.asarray(den, dtype=float))
    if len(den) == 1:
        return num / den[0], np.ones(1)
    numd, dend, _ = signal.cont2discrete((num, den), ts, method="foh")
    return np.ravel(numd), np.ravel(dend)


def _error_filter(c_asc: np.ndarray, a_asc: np.ndarray,
                  ts: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Discretised ``C/D`` (monic, ascending coefficients) and its DC gain."""
    num = np.concatenate([[1.0], c_asc[::-1]])
    den = np.concatenate([[1.0], a_asc[::-1]])
    b, a = _foh(num, den, ts)
    return b, a, float(c_asc[0] / a_asc[0])


def _error_response(filt: tuple[np.ndarray, np.ndarray, float], u: np.ndarray) -> np.ndarray:
    """``(C/D) u`` from rest in steady state at ``u[0]``."""
    b, a, dc = filt
    u0 = u[0]
    # e = (C/D)(u - u0) + C(0)/D(0) u0: the loop at rest at u0 before the run
    return signal.lfilter(b, a, u - u0) + dc * u0


def _tf_coeffs(tf: control.TransferFunction) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator of a SISO continuous ``tf`` as descending arrays, monic den."""
    if not isinstance(tf, control.TransferFunction):
        raise TypeError(f"tf={tf!r}: expected a control.TransferFunction")
    if tf.ninputs != 1 or tf.noutputs != 1:
        raise ValueError(f"tf has {tf.ninputs} inputs and {tf.noutputs} outputs: expected SISO")
    if not tf.isctime():
        raise ValueError("tf is discrete-time: expected a continuous-time transfer function")
    num = np.atleast_1d(np.asarray(tf.num[0][0], dtype=float))
    den = np.atleast_1d(np.asarray(tf.den[0][0], dtype=float))
    den = np.trim_zeros(den, "f")
    num = np.trim_zeros(num, "f") if np.any(num) else np.zeros(1)
    if len(num) > len(den):
        raise ValueError("tf is improper: expected no more zeros than poles")
    return num / den[0], den / den[0]


def tf_error_response(tf: control.TransferFunction, x_ref: np.ndarray, ts: float) -> np.ndarray:
    """Tracking error ``x_ref - G x_ref`` predicted by ``tf`` (free run), m.

    Computed on the error path ``1 - G`` directly, which avoids cancelling two large positions.

    Parameters
    ----------
    tf : control.TransferFunction
        Continuous-time SISO reference-to-position model.
    x_ref : ndarray, shape (K,)
        Reference position, m.
    ts : float
        Sample time, s.

    Returns
    -------
    ndarray, shape (K,)
        Predicted tracking error, m; the loop starts at rest in steady state at ``x_ref[0]``.
    """
    ts = check_positive("ts", ts, "s")
    u = check_signal("x_ref", x_ref)
    num, den = _tf_coeffs(tf)
    num_full = np.concatenate([np.zeros(len(den) - len(num)), num])
    # E/X_ref = 1 - G = C/D with C = D - N
    c_desc = np.trim_zeros(den - num_full, "f")
    if c_desc.size == 0:
        return np.zeros_like(u)
    with one_blas_thread():
        b, a = _foh(c_desc, den, ts)
    u0 = u[0]
    # from rest in steady state at u0: e = (C/D)(u - u0) + C(0)/D(0) u0
    return signal.lfilter(b, a, u - u0) + (c_desc[-1] / den[-1]) * u0


def simulate_tf(tf: control.TransferFunction, x_ref: np.ndarray, ts: float) -> np.ndarray:
    """Free-run simulation ``x_tf = G x_ref`` of a continuous-time model on a sampled reference.

    Parameters
    ----------
    tf : control.TransferFunction
        Continuous-time SISO model (e.g. from :func:`fit_tf`).
    x_ref : ndarray, shape (K,)
        Reference position, m, sampled at ``ts``.
    ts : float
        Sample time, s.

    Returns
    -------
    ndarray, shape (K,)
        Simulated position, m. First-order-hold discretisation; the loop starts at rest in
        steady state at ``x_ref[0]`` (as a servo axis does before a run).
    """
    u = check_signal("x_ref", x_ref)
    return u - tf_error_response(tf, u, ts)


# -- the fit ----------------------------------------------------------------------------------
class _Layout:
    """Parameter vector of the error path ``C/D`` for given orders and DC-gain constraint.

    ``theta`` holds ``log a_0 .. log a_{n-1}`` then the free ``c_i = a_i - b_i`` (``i <= m``,
    without ``c_0`` when the DC gain is fixed), each ``c_i`` scaled by ``w^(n-i)``.
    """

    def __init__(self, n: int, m: int, dc_gain: float | None) -> None:
        self.n, self.m, self.dc_gain = n, m, dc_gain
        self.c_free = [i for i in range(m + 1) if not (i == 0 and dc_gain is not None)]

    def coeffs(self, theta: np.ndarray, w: float) -> tuple[np.ndarray, np.ndarray]:
        """Ascending ``a`` (D without the leading 1) and ``c`` (C without its leading 1)."""
        a = np.exp(theta[: self.n])
        c = a.copy()  # b_i = 0 above the numerator degree: c_i = a_i there
        for k, i in enumerate(self.c_free):
            c[i] = theta[self.n + k] * w ** (self.n - i)
        if self.dc_gain is not None:
            # b_0 = k a_0  ->  c_0 = (1 - k) a_0
            c[0] = (1.0 - self.dc_gain) * a[0]
        return a, c

    def theta(self, a: np.ndarray, c: np.ndarray, w: float) -> np.ndarray:
        """Inverse of :meth:`coeffs` (``a`` must be positive)."""
        return np.concatenate([np.log(a), [c[i] / w ** (self.n - i) for i in self.c_free]])

    def tf(self, a: np.ndarray, c: np.ndarray) -> control.TransferFunction:
        b = a - c  # ascending numerator coefficients b_0..b_{n-1}
        b = b[: self.m + 1]
        return control.tf(b[::-1].tolist(), np.concatenate([[1.0], a[::-1]]).tolist())


def _svf_least_squares(runs: list[tuple[np.ndarray, np.ndarray]], sqrt_w: list[np.ndarray],
                       ts: float, lay: _Layout, lam: float
                       ) -> tuple[np.ndarray, np.ndarray] | None:
    """Equation-error estimate of ``(a, c)`` through the filter ``lam^n / (s + lam)^n``."""
    n = lay.n
    rows, rhs = [], []
    for (u, e), sw in zip(runs, sqrt_w, strict=True):
        ud, ed = u - u[0], e - e[0]
        fu, fe = [], []
        filt_den = np.poly(-lam * np.ones(n))
        for i in range(n + 1):
            num = np.zeros(i + 1)
            num[0] = lam**n  # lam^n s^i
            b, a = _foh(num, filt_den, ts)
            fu.append(signal.lfilter(b, a, ud))
            fe.append(signal.lfilter(b, a, ed))
        # D e = C u  ->  e^(n) - u^(n) = sum_i [-a_i e^(i) + c_i u^(i)], c_i = a_i above m
        cols = []
        for i in range(n):
            if i in lay.c_free or (i == 0 and lay.dc_gain is not None):
                col = -fe[i]
                if i == 0 and lay.dc_gain is not None:
                    col = col + (1.0 - lay.dc_gain) * fu[0]
            else:
                col = fu[i] - fe[i]
            cols.append(col)
        for i in lay.c_free:
            cols.append(fu[i])
        skip = 5 * n  # filter start-up transient
        rows.append((sw[:, None] * np.column_stack(cols))[skip:])
        rhs.append((sw * (fe[n] - fu[n]))[skip:])
    mat, vec = np.vstack(rows), np.concatenate(rhs)
    scale = np.linalg.norm(mat, axis=0)
    scale[scale == 0] = 1.0
    sol, *_ = np.linalg.lstsq(mat / scale, vec, rcond=None)
    sol = sol / scale
    a = sol[:n]
    c = a.copy()
    for k, i in enumerate(lay.c_free):
        c[i] = sol[n + k]
    if lay.dc_gain is not None:
        c[0] = (1.0 - lay.dc_gain) * a[0]
    # reflect unstable roots into the left half plane: a stable start for the output-error fit
    roots = np.roots(np.concatenate([[1.0], a[::-1]]))
    if not np.all(np.isfinite(roots)):
        return None
    roots = -np.abs(roots.real) + 1j * roots.imag
    roots = np.where(np.abs(roots.real) < 1e-3 * lam, -1e-3 * lam + 1j * roots.imag, roots)
    a_stable = np.real(np.poly(roots))[1:][::-1]
    if not np.all(a_stable > 0):
        return None
    if lay.dc_gain is not None:
        c[0] = (1.0 - lay.dc_gain) * a_stable[0]
    for i in range(n):
        if i not in lay.c_free and not (i == 0 and lay.dc_gain is not None):
            c[i] = a_stable[i]
    return a_stable, c


def fit_tf_multi(
    x_refs: Sequence[np.ndarray],
    xs: Sequence[np.ndarray],
    ts: float,
    n_poles: int = 2,
    n_zeros: int = 1,
    *,
    dc_gain: float | None = None,
    weights: Sequence[np.ndarray] | None = None,
    max_nfev: int = 200,
) -> control.TransferFunction:
    """Fit one transfer function to several runs (same axis, same ``ts``) jointly.

    Parameters are those of :func:`fit_tf`, with ``x_refs``, ``xs`` (and ``weights``)
    sequences of 1-D arrays, one per run; lengths may differ between runs.
    """
    ts = check_positive("ts", ts, "s")
    n, m = _check_orders(n_poles, n_zeros)
    if dc_gain is not None:
        dc_gain = check_positive("dc_gain", dc_gain)
    check_int("max_nfev", max_nfev, 1)
    if isinstance(x_refs, np.ndarray) or isinstance(xs, np.ndarray):
        raise TypeError("x_refs and xs: expected sequences of 1-D arrays (use fit_tf for one run)")
    if len(x_refs) != len(xs) or len(x_refs) == 0:
        raise ValueError(f"got {len(x_refs)} references and {len(xs)} positions: expected the "
                         "same non-zero number")
    if weights is not None and len(weights) != len(x_refs):
        raise ValueError(f"got {len(weights)} weight arrays for {len(x_refs)} runs")
    runs, sqrt_w = [], []
    for j, (xr, xm) in enumerate(zip(x_refs, xs, strict=True)):
        label = f"[{j}]" if len(x_refs) > 1 else ""
        u, x = _check_pair(xr, xm, label)
        runs.append((u, u - x))
        if weights is None:
            sqrt_w.append(np.ones_like(u))
        else:
            w_arr = check_signal(f"weights{label}", weights[j])
            if w_arr.shape != u.shape or np.any(w_arr < 0):
                raise ValueError(f"weights{label}: expected {u.shape[0]} non-negative values")
            sqrt_w.append(np.sqrt(w_arr))
    if sum(float(np.sum(w > 0)) for w in sqrt_w) < _MIN_SAMPLES:
        raise TFFitError(f"fewer than {_MIN_SAMPLES} samples have a non-zero weight")
    with one_blas_thread():  # see fricbench._blas: thousands of small matrix exponentials
        return _fit(runs, sqrt_w, ts, _Layout(n, m, dc_gain), max_nfev)


def _fit(runs: list[tuple[np.ndarray, np.ndarray]], sqrt_w: list[np.ndarray], ts: float,
         lay: _Layout, max_nfev: int) -> control.TransferFunction:
    """Output-error fit of validated runs ``(x_ref, e)`` (see :func:`fit_tf_multi`)."""
    n = lay.n
    e_all = np.concatenate([e - np.mean(e) for _, e in runs])
    e_scale = float(np.sqrt(np.mean(e_all**2))) or 1.0
    n_total = sum(len(u) for u, _ in runs)

    def residual(theta: np.ndarray, w: float) -> np.ndarray:
        a, c = lay.coeffs(theta, w)
        if n > 2 and np.any(np.roots(np.concatenate([[1.0], a[::-1]])).real >= 0):
            return np.full(n_total, 1e3)
        # simulation error: the model runs free on the reference, never on the measurement
        filt = _error_filter(c, a, ts)
        out = [sw * (e - _error_response(filt, u)) / e_scale
               for (u, e), sw in zip(runs, sqrt_w, strict=True)]
        res = np.concatenate(out)
        return res if np.all(np.isfinite(res)) else np.full(n_total, 1e3)

    starts = []
    for frac in (0.05, 0.1, 0.2, 0.4, 0.8):
        start = _svf_least_squares(runs, sqrt_w, ts, lay, frac / ts)
        if start is None:
            continue
        a0, c0 = start
        w0 = float(a0[0] ** (1.0 / n))
        theta0 = lay.theta(a0, c0, w0)
        starts.append((float(np.sum(residual(theta0, w0) ** 2)), theta0, w0))
    starts.sort(key=lambda item: item[0])
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    for _, theta0, w0 in starts[:2]:  # refine the two best least-squares starts
        try:
            sol = optimize.least_squares(residual, theta0, args=(w0,), method="lm",
                                         max_nfev=max_nfev * (len(theta0) + 1))
        except (ValueError, np.linalg.LinAlgError):
            continue
        cost = float(sol.cost)
        if np.isfinite(cost) and (best is None or cost < best[0]):
            a, c = lay.coeffs(sol.x, w0)
            best = (cost, a, c)
    if best is None:
        raise TFFitError("least squares found no stable starting point: the reference does not "
                         "excite the loop (too little or too slow motion?)")
    _, a, c = best
    return lay.tf(a, c)


def fit_tf(
    x_ref: np.ndarray,
    x: np.ndarray,
    ts: float,
    n_poles: int = 2,
    n_zeros: int = 1,
    *,
    dc_gain: float | None = None,
    weight: np.ndarray | None = None,
    max_nfev: int = 200,
) -> control.TransferFunction:
    """Identify a continuous-time reference-to-position transfer function.

    Output-error (simulation-error) fit initialised from state-variable-filter least squares;
    see the module docstring for the method.

    Parameters
    ----------
    x_ref : ndarray, shape (K,)
        Reference position, m.
    x : ndarray, shape (K,)
        Measured position, m (noise and quantisation allowed).
    ts : float
        Sample time, s.
    n_poles : int, optional
        Denominator order ``n`` (default 2, the paper's eq. 22).
    n_zeros : int, optional
        Numerator order ``m < n`` (default 1).
    dc_gain : float or None, optional
        ``None`` (default): DC gain free. A number ``k``: constrain ``b_0 = k a_0``
        (``1.0`` for a position loop with integral action).
    weight : ndarray, shape (K,), optional
        Non-negative weight of each sample in the cost (e.g. 0 inside the pre-sliding windows,
        so that friction transients do not bias the linear model). Default: all ones.
    max_nfev : int, optional
        Iteration budget of each Levenberg-Marquardt refinement (times the number of
        parameters plus one function evaluations).

    Returns
    -------
    control.TransferFunction
        Continuous-time ``G(s)`` with a monic denominator.

    Raises
    ------
    ValueError
        NaN/inf in the data, arrays of different lengths or not 1-D, bad orders.
    TFFitError
        No motion in ``x_ref``, fewer than 50 samples, or no stable fit.

    Examples
    --------
    >>> g = fit_tf(res.x_ref, res.x, 1e-3)          # doctest: +SKIP
    >>> g.num[0][0], g.den[0][0]                     # doctest: +SKIP
    """
    return fit_tf_multi([x_ref], [x], ts, n_poles, n_zeros, dc_gain=dc_gain,
                        weights=None if weight is None else [weight], max_nfev=max_nfev)

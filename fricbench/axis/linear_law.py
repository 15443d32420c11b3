"""A linear discrete control law driving the plant: the loop the diagnosis identifies.

The second controller driver of :mod:`fricbench.axis.plant` (the first is the cascade of
:mod:`fricbench.axis.kernel`). Per sample ``k``::

    y_fb[k], y[k] = sense(plant)                                       feedback and logged position
    u[k] = sum_i a_i u[k-i] + r[k] + sum_j c_j y_fb[k-j] + w[k]        linear law (ARX form)
    plant: actuator (delay, saturation), mechanics over n_sub substeps, with Kt u as the force

* ``r[k]`` is the law's precomputed reference part (position, velocity and acceleration
  feedforward), ``c_j`` its feedback on the position the controller sees, ``a_i`` its own
  recursion (``a_1 = 1`` is an integrator), ``w`` an optional injected effort (test pulses);
* any law of this form fits: a cascade rewritten as one difference equation, a PID, or a law
  identified from a logged effort by least squares.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numba
import numpy as np

from fricbench.axis import plant as PL
from fricbench.axis.plant import DELAY_MAX, FASTMATH, N_PLANT

__all__ = ["simulate_batch", "simulate_one", "DIVERGED_SPEED", "SimulationTally",
           "tally_simulations"]

# |v| above which a row has diverged. The diagnosis may run in any unit (m, rad, deg, a unit
# mass), so the bound is far above any real motion rather than the cascade's 100 m/s.
DIVERGED_SPEED = 1.0e6


def _run_one(p: np.ndarray, a: np.ndarray, c: np.ndarray, r: np.ndarray, w: np.ndarray,
             t: np.ndarray, x0: float, v0: float, u_init: np.ndarray, y_init: np.ndarray,
             noise: np.ndarray, y_out: np.ndarray, u_out: np.ndarray,
             y2_out: np.ndarray, positional: bool, a2: np.ndarray, c2: np.ndarray,
             r2: np.ndarray, g_init: np.ndarray, i_init: float) -> int:
    n = r.shape[0]
    na = a.shape[0]
    nc = c.shape[0]
    na2 = a2.shape[0]
    pc = PL.constants(p)
    # histories: uh[i] = u[k-1-i] (q[k-1-i] in positional form), gh[i] = g[k-1-i],
    # yh[j] = y_fb[k-j] (yh[0] is filled each sample)
    uh = u_init.copy()
    gh = g_init.copy()
    integ = i_init
    q = 0.0
    yh = np.empty(max(nc, 1))
    for j in range(nc):
        yh[j] = y_init[j] if j < y_init.shape[0] else y_init[-1]
    buf = np.zeros(DELAY_MAX)
    x = x0
    v = v0
    z = 0.0
    play = x0
    d = 0.0
    dv = 0.0
    theta = 0.0
    for k in range(n):
        y_fb, y_k = PL.sense(pc, x, play, d, theta, t[k], noise[k])
        y_out[k] = y_k
        # the other encoder: the motor's when the table is logged, else the table's
        if pc.log_motor:
            y2_out[k] = PL.load_position(pc, play, d, theta, t[k]) + noise[k]
        else:
            y2_out[k] = x + noise[k]
        for j in range(nc - 1, 0, -1):
            yh[j] = yh[j - 1]
        if nc > 0:
            yh[0] = y_fb
        # u[k] = sum_i a_i u[k-i] + r[k] + sum_j c_j y_fb[k-j] + w[k]
        u = r[k]
        for i in range(na):
            u += a[i] * uh[i]
        for j in range(nc):
            u += c[j] * yh[j]
        if positional:
            # u = q + I: the recursion runs on the proportional part q, the integral is a
            # state held while its increment pushes further into the limit (clamping)
            q = u
            g = r2[k]
            for i in range(na2):
                g += a2[i] * gh[i]
            for j in range(c2.shape[0]):
                g += c2[j] * yh[j]
            u = q + integ + w[k]
            if not ((u > pc.i_max and g > 0.0) or (u < -pc.i_max and g < 0.0)):
                integ += g
            for i in range(na2 - 1, 0, -1):
                gh[i] = gh[i - 1]
            if na2 > 0:
                gh[0] = g
        else:
            u += w[k]
        # a drive that clips its command logs the clipped value, and the law identified from
        # that log recurses on it (a velocity-form law, which winds up no integrator)
        if u > pc.i_max:
            u = pc.i_max
        elif u < -pc.i_max:
            u = -pc.i_max
        for i in range(na - 1, 0, -1):
            uh[i] = uh[i - 1]
        if na > 0:
            uh[0] = q if positional else u
        u_out[k] = u
        u_app, _ = PL.actuate(pc, buf, 0, u)
        x, v, z, play, d, dv, theta, _ = PL.advance(pc, x, v, z, play, d, dv, theta,
                                                    pc.kt * u_app)
        if not (math.isfinite(x) and math.isfinite(d) and abs(v) < DIVERGED_SPEED
                and math.isfinite(integ)):
            for kk in range(k + 1, n):
                y_out[kk] = np.nan
                y2_out[kk] = np.nan
                u_out[kk] = np.nan
            return 1
    return 0


_run_one = numba.njit(cache=True, fastmath=FASTMATH)(_run_one)


@dataclass(eq=False)
class SimulationTally:
    """What :func:`simulate_batch` simulated while the tally was open.

    Tallies compare by identity (two open ones may hold the same counts). A count of work,
    not of time: what a speed change does to the work shows here within a fraction of a per
    cent, where a wall time moves by tens of per cent with the machine's load. Not to the
    row: a caller that keeps runs it has simulated (the diagnosis's free-run cache) may
    simulate one twice when two threads ask for it at once, as their timing has it.

    Attributes
    ----------
    calls : int
        Calls of :func:`simulate_batch`.
    rows : int
        Rows simulated (a Jacobian's batch counts its rows).
    samples : int
        Samples simulated, over every row.
    substeps : int
        Plant integration steps, over every row (samples times substeps per sample).
    """

    calls: int = 0
    rows: int = 0
    samples: int = 0
    substeps: int = 0


_TALLIES: list[SimulationTally] = []
_TALLY_LOCK = threading.Lock()


@contextmanager
def tally_simulations() -> Iterator[SimulationTally]:
    """Count what :func:`simulate_batch` simulates inside the ``with`` block, on every thread.

    Examples
    --------
    >>> with tally_simulations() as work:
    ...     pass  # run a diagnosis here
    >>> work.rows
    0
    """
    tally = SimulationTally()
    with _TALLY_LOCK:
        _TALLIES.append(tally)
    try:
        yield tally
    finally:
        with _TALLY_LOCK:
            _TALLIES.remove(tally)


def _record(rows: int, samples: int, n_sub: int) -> None:
    with _TALLY_LOCK:
        for tally in _TALLIES:
            tally.calls += 1
            tally.rows += rows
            tally.samples += rows * samples
            tally.substeps += rows * samples * n_sub


# Row i runs law RI[i]: its reference parts R[RI[i]], R2[RI[i]] (the rows of a batch that share
# a law, a Jacobian's plant columns, share one copy of its K-sample arrays). Both drivers
# release the GIL: the diagnosis may run independent fits on threads of its own.
@numba.njit(cache=True, parallel=True, nogil=True)
def _run_batch(P: np.ndarray, A: np.ndarray, C: np.ndarray, R: np.ndarray, RI: np.ndarray,
               w: np.ndarray, t: np.ndarray, x0: float, v0: float, U0: np.ndarray,
               y_init: np.ndarray, noise: np.ndarray, Y: np.ndarray, U: np.ndarray,
               Y2: np.ndarray, status: np.ndarray, POS: np.ndarray, A2: np.ndarray,
               C2: np.ndarray, R2: np.ndarray, G0: np.ndarray, I0: np.ndarray) -> None:
    for i in numba.prange(P.shape[0]):
        j = RI[i]
        status[i] = _run_one(P[i], A[i], C[i], R[j], w, t, x0, v0, U0[i], y_init, noise, Y[i],
                             U[i], Y2[i], POS[i], A2[i], C2[i], R2[j], G0[i], I0[i])


@numba.njit(cache=True, nogil=True)
def _run_rows(P: np.ndarray, A: np.ndarray, C: np.ndarray, R: np.ndarray, RI: np.ndarray,
              w: np.ndarray, t: np.ndarray, x0: float, v0: float, U0: np.ndarray,
              y_init: np.ndarray, noise: np.ndarray, Y: np.ndarray, U: np.ndarray,
              Y2: np.ndarray, status: np.ndarray, POS: np.ndarray, A2: np.ndarray,
              C2: np.ndarray, R2: np.ndarray, G0: np.ndarray, I0: np.ndarray) -> None:
    """:func:`_run_batch` on the calling thread (no parallel region)."""
    for i in range(P.shape[0]):
        j = RI[i]
        status[i] = _run_one(P[i], A[i], C[i], R[j], w, t, x0, v0, U0[i], y_init, noise, Y[i],
                             U[i], Y2[i], POS[i], A2[i], C2[i], R2[j], G0[i], I0[i])


def simulate_batch(plant: np.ndarray, a: np.ndarray, c: np.ndarray, r: np.ndarray,
                   t: np.ndarray, ts: float, *, n_sub: int, x0: float, v0: float,
                   u_init: np.ndarray, y_init: np.ndarray, w: np.ndarray | None = None,
                   noise: np.ndarray | None = None, quant: float = 0.0,
                   other: np.ndarray | None = None, positional: np.ndarray | None = None,
                   a2: np.ndarray | None = None, c2: np.ndarray | None = None,
                   r2: np.ndarray | None = None, g_init: np.ndarray | None = None,
                   i_init: np.ndarray | None = None, law_index: np.ndarray | None = None,
                   parallel: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Simulate ``N`` parameter sets of the closed loop in parallel (one row each).

    Parameters
    ----------
    plant : ndarray, shape (N, N_PLANT)
        Plant rows (:mod:`fricbench.axis.plant` layout); their sample time, substeps and
        quantisation are set from ``ts``, ``n_sub`` and ``quant``.
    a : ndarray, shape (N, na)
        Law's recursion coefficients on ``u[k-1] .. u[k-na]``.
    c : ndarray, shape (N, nc)
        Law's feedback coefficients on ``y_fb[k] .. y_fb[k-nc+1]``.
    r : ndarray, shape (N, K)
        Reference part of the law's output (shape (L, K) with ``law_index``).
    t : ndarray, shape (K,)
        Sample times from the start of the run, s.
    ts : float
        Sample time, s.
    n_sub : int
        Plant substeps per sample.
    x0, v0 : float
        Initial motor position and velocity.
    u_init : ndarray, shape (N, na)
        Law's output history ``u[-1] .. u[-na]``.
    y_init : ndarray, shape (nc,)
        Feedback history before the run, ``y_fb[-1], y_fb[-2], ...``.
    w : ndarray, shape (K,), optional
        Injected effort added to the law's output.
    noise : ndarray, shape (K,), optional
        Measurement noise added to the fed-back and the logged position.
    quant : float
        Quantisation step of both sensors (0: none).
    other : ndarray, shape (N, K), optional
        Filled with the other encoder's reading (the motor's when the row logs the table, the
        table's when it logs the motor: ``log_motor``), with the same noise, unquantised.
    positional : ndarray of bool, shape (N,), optional
        Rows whose law is in positional form ``u = q + I`` (``a``, ``c``, ``r``, ``u_init``
        then give the proportional part ``q``): the integral ``I`` starts at ``i_init`` and
        grows by ``g[k] = sum_i a2_i g[k-i] + r2[k] + sum_j c2_j y_fb[k-j]`` (history
        ``g_init``) except while the command clips and ``g`` pushes further into the limit
        (clamping anti-windup). Other rows recurse on their clipped output (velocity form).
    a2, c2, r2, g_init, i_init : ndarray, optional
        Shapes (N, na2), (N, nc2 <= nc), (N, K), (N, na2), (N,); required with
        ``positional`` (``r2`` of shape (L, K) with ``law_index``).
    law_index : ndarray of int, shape (N,), optional
        Row ``i`` takes its reference parts from row ``law_index[i]`` of ``r`` and ``r2``
        (rows that share a law need not repeat its K-sample arrays). Default: row ``i``.
    parallel : bool
        Run the rows on numba's threads (False: one after the other on the calling thread,
        for a caller that runs batches on threads of its own). The rows' numbers are the same.

    Returns
    -------
    y : ndarray, shape (N, K)
        Logged position (NaN after a divergence).
    u : ndarray, shape (N, K)
        Law's output (effort).
    status : ndarray of int64, shape (N,)
        0 when the row stayed finite, 1 when it diverged.
    """
    P = np.array(np.atleast_2d(plant), dtype=float)
    if P.shape[1] != N_PLANT:
        raise ValueError(f"plant: expected rows of {N_PLANT} plant parameters, got shape "
                         f"{P.shape}")
    P[:, PL.TS] = ts
    P[:, PL.NSUB] = n_sub
    P[:, PL.QUANT] = quant
    n_rows, n = P.shape[0], r.shape[-1]
    A = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(a), (n_rows, np.shape(a)[-1])),
                             dtype=float)
    C = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(c), (n_rows, np.shape(c)[-1])),
                             dtype=float)
    if law_index is None:
        R = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(r), (n_rows, n)), dtype=float)
        RI = np.arange(n_rows, dtype=np.int64)
    else:
        R = np.ascontiguousarray(np.atleast_2d(r), dtype=float)
        RI = np.ascontiguousarray(law_index, dtype=np.int64).reshape(n_rows)
        if RI.size and (RI.min() < 0 or RI.max() >= R.shape[0]):
            raise ValueError(f"law_index: expected indices into the {R.shape[0]} rows of r")
    n_laws = R.shape[0]
    U0 = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(u_init),
                                              (n_rows, A.shape[1])), dtype=float)
    ww = np.zeros(n) if w is None else np.ascontiguousarray(w, dtype=float)
    nn = np.zeros(n) if noise is None else np.ascontiguousarray(noise, dtype=float)
    Y = np.empty((n_rows, n))
    U = np.empty((n_rows, n))
    if other is not None and (other.shape != (n_rows, n) or other.dtype != np.float64
                              or not other.flags.c_contiguous):
        raise ValueError(f"other: expected a C-contiguous float array of shape {(n_rows, n)}, "
                         f"got {other.dtype} {other.shape}")
    Y2 = np.empty((n_rows, n)) if other is None else other
    status = np.zeros(n_rows, dtype=np.int64)
    if positional is None or not np.any(positional):
        pos = np.zeros(n_rows, dtype=np.bool_)
        A2, C2, G0 = (np.zeros((n_rows, 0)),) * 3
        R2, I0 = np.zeros((n_laws, 1)), np.zeros(n_rows)
    else:
        pos = np.ascontiguousarray(positional, dtype=np.bool_).reshape(n_rows)
        if a2 is None or c2 is None or r2 is None or g_init is None or i_init is None:
            raise ValueError("positional rows need a2, c2, r2, g_init and i_init")
        A2 = np.ascontiguousarray(np.atleast_2d(a2), dtype=float)
        C2 = np.ascontiguousarray(np.atleast_2d(c2), dtype=float)
        R2 = np.ascontiguousarray(np.atleast_2d(r2), dtype=float)
        G0 = np.ascontiguousarray(np.atleast_2d(g_init), dtype=float)
        I0 = np.ascontiguousarray(i_init, dtype=float).reshape(n_rows)
        if (A2.shape != G0.shape or A2.shape[0] != n_rows or C2.shape[0] != n_rows
                or C2.shape[1] > C.shape[1] or R2.shape != (n_laws, n)):
            raise ValueError(f"a2, c2, r2, g_init: shapes {A2.shape}, {C2.shape}, {R2.shape}, "
                             f"{G0.shape} do not match {n_rows} rows of {n} samples with "
                             f"nc = {C.shape[1]}")
    # one row runs on this thread: a parallel region for it only waits for the idle workers
    # (on a loaded machine 11 ms against 5-9 ms for a 40,000-sample run); the row's code is
    # the same _run_one either way
    run = _run_rows if n_rows == 1 or not parallel else _run_batch
    if _TALLIES:
        _record(n_rows, n, int(n_sub))
    run(P, A, C, R, RI, ww, np.ascontiguousarray(t, dtype=float), float(x0), float(v0), U0,
        np.ascontiguousarray(y_init, dtype=float), nn, Y, U, Y2, status, pos, A2, C2, R2, G0, I0)
    return Y, U, status


def simulate_one(plant: np.ndarray, a: np.ndarray, c: np.ndarray, r: np.ndarray,
                 t: np.ndarray, ts: float, **kw: object) -> tuple[np.ndarray, np.ndarray]:
    """Single-row convenience wrapper of :func:`simulate_batch`; returns ``(y, u)``."""
    y, u, _ = simulate_batch(np.atleast_2d(plant), np.atleast_2d(a), np.atleast_2d(c),
                             np.atleast_2d(r), t, ts, **kw)  # type: ignore[arg-type]
    return y[0], u[0]

"""Transfer-function residual, break velocity and the nonlinear friction error (paper, Sec. 3.1).

Pipeline, for a run with reference ``x_ref`` and measured position ``x`` sampled at ``ts``:

1. :func:`tf_residual`: ``r = x - x_tf``, the free-run simulation of the identified transfer
   function subtracted from the measurement (the paper's "prediction error of the TF").
2. :func:`find_events`: starts, stops and reversals of the reference (the paper's three
   situations of three consecutive velocity samples; :func:`fricbench.run_events.motion_events`
   of the reference velocity).
3. :func:`identify_v_break`: the break velocity, from where the measured axis leaves its rest
   position after each start and reversal (procedure below).
4. :func:`presliding_mask` and :func:`extract_friction_error`: the pre-sliding windows around
   each event and the nonlinear friction error ``r`` inside them (0 outside).

Break-velocity procedure
------------------------
After a reversal or a start the reference accelerates away from its turning point while the
axis stays stuck until the drive force exceeds static friction; the reference speed at that
moment is the break velocity and its travel from the turning point the separation
displacement, related by ``v_break = sqrt(2 a0 x_break)`` (Yang, Yang & Ding 2018) with ``a0``
the acceleration at zero velocity. For each start and reversal:

* the measured displacement in the new direction of motion, ``d(t) = sgn (x(t) - x(t0))``, is
  taken from the turning point ``t0`` until it first exceeds ``fit_span`` (10 um by default),
* a *hinge* ``d(t) = c0 + c2 max(0, t - t_b)^2`` (at rest, then uniformly accelerating) is
  fitted by least squares, scanning ``t_b`` at ``ts / 10``; the fit uses every sample, so
  encoder quantisation and noise average out instead of biasing a threshold crossing,
* ``v_break_i = |v_ref(t_b)|`` and ``x_break_i = |x_ref(t_b) - x_ref(t0)|``.

The run's ``v_break`` and ``x_break`` are the medians over events (robust to the odd event
where the axis was still creeping), and ``a0 = v_break^2 / (2 x_break)`` is the equivalent
constant acceleration. On the simulated default axis the median agrees with the exact
breakaway read from the noise-free true position within about 10 % (``tests/sysid``).

Pre-sliding windows
-------------------
Around every event, the samples where ``|v_ref| < v_break`` (contiguous with the event), widened
by ``pre`` seconds before and ``post`` seconds after: the loop needs some time after breakaway
to recover the position lost while stuck, and that recovery is part of the friction error.
Outside the windows the residual is treated as not friction-related (paper, Sec. 3.1).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import control
import numpy as np

from fricbench._validation import check_int, check_nonneg, check_positive, check_signal
from fricbench.run_events import EVENT_KINDS, MotionEvent, motion_events
from fricbench.sysid.tf_fit import simulate_tf

__all__ = [
    "EVENT_KINDS",
    "MotionEvent",
    "Breakaway",
    "BreakVelocity",
    "FrictionError",
    "NoReversalError",
    "reference_velocity",
    "tf_residual",
    "find_events",
    "identify_v_break",
    "identify_v_break_multi",
    "presliding_mask",
    "extract_friction_error",
]

class NoReversalError(ValueError):
    """A run without the starts or reversals that friction identification needs."""


@dataclass(frozen=True)
class Breakaway:
    """Where the axis left its rest position after one start or reversal.

    Attributes
    ----------
    event : MotionEvent
    t_break : float
        Breakaway time, s.
    v_break : float
        Reference speed at breakaway, m/s.
    x_break : float
        Reference travel from the turning point to breakaway, m.
    """

    event: MotionEvent
    t_break: float
    v_break: float
    x_break: float


@dataclass(frozen=True)
class BreakVelocity:
    """Identified break velocity (medians over events).

    Attributes
    ----------
    v_break : float
        Break velocity, m/s.
    x_break : float
        Separation displacement, m.
    a0 : float
        Equivalent acceleration at zero velocity, ``v_break^2 / (2 x_break)``, m/s^2.
    breakaways : tuple of Breakaway
        The per-event estimates.
    """

    v_break: float
    x_break: float
    a0: float
    breakaways: tuple[Breakaway, ...] = field(repr=False)


@dataclass(frozen=True)
class FrictionError:
    """The friction-error decomposition of one run.

    Attributes
    ----------
    residual : ndarray
        TF residual ``r = x - x_tf``, m.
    mask : ndarray of bool
        Pre-sliding windows.
    friction_error : ndarray
        ``r`` inside the windows, 0 outside, m.
    events : tuple of MotionEvent
    """

    residual: np.ndarray
    mask: np.ndarray
    friction_error: np.ndarray
    events: tuple[MotionEvent, ...]


# -- signals ----------------------------------------------------------------------------------
def reference_velocity(x_ref: np.ndarray, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Reference velocity and acceleration by central differences (``np.gradient``), SI units.

    Every predictor derives its features this way from positions alone, in training and in
    prediction alike, so that they never depend on how a reference was generated.
    """
    ts = check_positive("ts", ts, "s")
    x_ref = check_signal("x_ref", x_ref)
    if x_ref.shape[0] < 3:
        raise ValueError(f"x_ref has {x_ref.shape[0]} samples: need at least 3")
    v = np.gradient(x_ref, ts)
    return v, np.gradient(v, ts)


def tf_residual(tf: control.TransferFunction, x_ref: np.ndarray, x: np.ndarray,
                ts: float) -> np.ndarray:
    """TF residual ``r = x - x_tf`` with ``x_tf`` the free-run simulation of ``tf``, m."""
    x_ref = check_signal("x_ref", x_ref)
    x = check_signal("x", x)
    if x.shape != x_ref.shape:
        raise ValueError(f"x_ref has {x_ref.shape[0]} samples but x has {x.shape[0]}")
    return x - simulate_tf(tf, x_ref, ts)


# -- events -----------------------------------------------------------------------------------
def find_events(x_ref: np.ndarray, ts: float, *, v_tol: float = 1e-6,
                max_gap: int = 2) -> list[MotionEvent]:
    """Starts, stops and reversals of a sampled reference.

    :func:`fricbench.run_events.motion_events` of the reference velocity
    (:func:`reference_velocity`): "zero" means ``|v| <= v_tol``, and a rest of at most
    ``max_gap`` samples between opposite motions is a direct reversal.

    Parameters
    ----------
    x_ref : ndarray, shape (K,)
        Reference position, m.
    ts : float
        Sample time, s.
    v_tol : float, optional
        Speed below which the reference counts as at rest, m/s.
    max_gap : int, optional
        Longest rest, in samples, still read as a direct reversal.

    Returns
    -------
    list of MotionEvent
        In time order.
    """
    v, _ = reference_velocity(x_ref, ts)
    v_tol = check_positive("v_tol", v_tol, "m/s")
    max_gap = check_int("max_gap", max_gap, 0)
    return motion_events(v, ts, rest_speed=v_tol, max_gap=max_gap)


# -- break velocity ---------------------------------------------------------------------------
def _hinge_break(t: np.ndarray, d: np.ndarray, step: float) -> float:
    """Least-squares ``t_b`` of ``d = c0 + c2 max(0, t - t_b)^2`` scanned at ``step``."""
    grid = np.arange(t[0], t[-1], step)
    h = np.clip(t[None, :] - grid[:, None], 0.0, None) ** 2  # (G, N)
    n = t.shape[0]
    # closed-form two-parameter least squares for every candidate t_b at once
    sh, shh = h.sum(axis=1), (h * h).sum(axis=1)
    sd, shd = d.sum(), h @ d
    det = n * shh - sh**2
    ok = det > 1e-30 * np.maximum(shh, 1e-300)
    c2 = np.where(ok, (n * shd - sh * sd) / np.where(ok, det, 1.0), 0.0)
    c0 = (sd - c2 * sh) / n
    sse = np.sum((c0[:, None] + c2[:, None] * h - d[None, :]) ** 2, axis=1)
    sse = np.where(ok & (c2 > 0), sse, np.inf)
    if not np.any(np.isfinite(sse)):
        return float("nan")
    return float(grid[int(np.argmin(sse))])


def _breakaways(x_ref: np.ndarray, x: np.ndarray, ts: float, fit_span: float,
                max_window: float, v_tol: float) -> list[Breakaway]:
    v, _ = reference_velocity(x_ref, ts)
    t = np.arange(x_ref.shape[0]) * ts
    out = []
    max_n = max(int(round(max_window / ts)), 4)
    for ev in find_events(x_ref, ts, v_tol=v_tol):
        if ev.kind == "stop":
            continue
        k0 = ev.index
        seg = ev.direction * (x[k0:k0 + max_n] - x[k0])
        beyond = np.flatnonzero(seg > fit_span)
        if beyond.size == 0 or beyond[0] < 4:
            continue  # never left the rest position in the window, or left at once
        k_end = k0 + int(beyond[0]) + 1
        tb = _hinge_break(t[k0:k_end], seg[: k_end - k0], ts / 10.0)
        if not np.isfinite(tb):
            continue
        vb = float(abs(np.interp(tb, t, v)))
        xb = float(abs(np.interp(tb, t, x_ref) - x_ref[k0]))
        out.append(Breakaway(ev, tb, vb, xb))
    return out


def identify_v_break_multi(
    x_refs: Sequence[np.ndarray],
    xs: Sequence[np.ndarray],
    ts: float,
    *,
    fit_span: float = 10e-6,
    max_window: float = 0.5,
    v_tol: float = 1e-6,
) -> BreakVelocity:
    """Break velocity from several runs (medians over all their starts and reversals).

    Parameters are those of :func:`identify_v_break`, with sequences of runs.
    """
    ts = check_positive("ts", ts, "s")
    fit_span = check_positive("fit_span", fit_span, "m")
    max_window = check_positive("max_window", max_window, "s")
    if len(x_refs) != len(xs) or len(x_refs) == 0:
        raise ValueError(f"got {len(x_refs)} references and {len(xs)} positions: expected the "
                         "same non-zero number")
    found: list[Breakaway] = []
    n_events = 0
    for j, (xr, xm) in enumerate(zip(x_refs, xs, strict=True)):
        label = f"[{j}]" if len(x_refs) > 1 else ""
        xr = check_signal(f"x_ref{label}", xr)
        xm = check_signal(f"x{label}", xm)
        if xr.shape != xm.shape:
            raise ValueError(f"x_ref{label} has {xr.shape[0]} samples but x{label} has "
                             f"{xm.shape[0]}")
        if np.ptp(xr) <= 0.0:
            raise NoReversalError(f"x_ref{label} is constant: a run without motion has no "
                                  "breakaway to identify v_break from")
        n_events += sum(e.kind != "stop" for e in find_events(xr, ts, v_tol=v_tol))
        found += _breakaways(xr, xm, ts, fit_span, max_window, v_tol)
    if n_events == 0:
        raise NoReversalError("the runs have no start or reversal: v_break needs the axis to "
                              "break away from rest at least once")
    if not found:
        raise NoReversalError(f"none of the {n_events} starts/reversals shows a breakaway (the "
                              f"axis never moved {fit_span * 1e6:g} um within {max_window:g} s)")
    vb = float(np.median([b.v_break for b in found]))
    xb = float(np.median([b.x_break for b in found]))
    # v_break = sqrt(2 a0 x_break)  ->  a0 = v_break^2 / (2 x_break)
    a0 = vb**2 / (2.0 * xb) if xb > 0 else float("inf")
    return BreakVelocity(vb, xb, a0, tuple(found))


def identify_v_break(
    x_ref: np.ndarray,
    x: np.ndarray,
    ts: float,
    *,
    fit_span: float = 10e-6,
    max_window: float = 0.5,
    v_tol: float = 1e-6,
) -> BreakVelocity:
    """Identify the break velocity ``v_break = sqrt(2 a0 x_break)`` from one run.

    See the module docstring for the procedure.

    Parameters
    ----------
    x_ref : ndarray, shape (K,)
        Reference position, m.
    x : ndarray, shape (K,)
        Measured position, m.
    ts : float
        Sample time, s.
    fit_span : float, optional
        Displacement after breakaway used by the hinge fit, m.
    max_window : float, optional
        Longest time searched for the breakaway after a turning point, s.
    v_tol : float, optional
        Rest threshold of :func:`find_events`, m/s.

    Returns
    -------
    BreakVelocity

    Raises
    ------
    NoReversalError
        No motion, no start or reversal, or no detectable breakaway.
    ValueError
        NaN, different lengths.
    """
    return identify_v_break_multi([x_ref], [x], ts, fit_span=fit_span, max_window=max_window,
                                  v_tol=v_tol)


# -- windows and the friction error -----------------------------------------------------------
def presliding_mask(x_ref: np.ndarray, ts: float, v_break: float, *, pre: float = 0.02,
                    post: float = 0.1, v_tol: float = 1e-6) -> np.ndarray:
    """Boolean mask of the pre-sliding windows around every start, stop and reversal.

    Each window is the stretch of samples with ``|v_ref| < v_break`` that contains the event
    (so a dwell at rest is inside), widened by ``pre`` s before and ``post`` s after.

    Parameters
    ----------
    x_ref : ndarray, shape (K,)
        Reference position, m.
    ts : float
        Sample time, s.
    v_break : float
        Break velocity, m/s.
    pre, post : float, optional
        Widening before and after, s.
    v_tol : float, optional
        Rest threshold of :func:`find_events`, m/s.
    """
    v_break = check_positive("v_break", v_break, "m/s")
    pre = check_nonneg("pre", pre, "s")
    post = check_nonneg("post", post, "s")
    v, _ = reference_velocity(x_ref, ts)
    k_total = v.shape[0]
    slow = np.abs(v) < v_break
    mask = np.zeros(k_total, dtype=bool)
    n_pre, n_post = int(round(pre / ts)), int(round(post / ts))
    for ev in find_events(x_ref, ts, v_tol=v_tol):
        lo = hi = ev.index
        while lo > 0 and slow[lo - 1]:
            lo -= 1
        while hi < k_total - 1 and slow[hi + 1]:
            hi += 1
        mask[max(lo - n_pre, 0): min(hi + n_post + 1, k_total)] = True
    return mask


def extract_friction_error(
    tf: control.TransferFunction,
    x_ref: np.ndarray,
    x: np.ndarray,
    ts: float,
    v_break: float,
    *,
    pre: float = 0.02,
    post: float = 0.1,
) -> FrictionError:
    """The nonlinear friction error of one run: the TF residual inside the pre-sliding windows.

    Parameters
    ----------
    tf : control.TransferFunction
        Identified reference-to-position model.
    x_ref, x : ndarray, shape (K,)
        Reference and measured position, m.
    ts : float
        Sample time, s.
    v_break : float
        Break velocity, m/s.
    pre, post : float, optional
        Window widening, s (see :func:`presliding_mask`).

    Returns
    -------
    FrictionError
    """
    r = tf_residual(tf, x_ref, x, ts)
    mask = presliding_mask(x_ref, ts, v_break, pre=pre, post=post)
    return FrictionError(r, mask, np.where(mask, r, 0.0), tuple(find_events(x_ref, ts)))

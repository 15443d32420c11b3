"""Building blocks of the reference trajectories: jerk-limited moves, rests, windowed sines.

A :class:`Segment` is a piece of a single-axis reference on its own local time axis
``tau`` in ``[0, duration]``, evaluated analytically (no numerical differentiation).
:func:`concatenate` lays segments end to end on one time line and samples it uniformly, so
segment durations need not be multiples of the sample time.

Point-to-point moves come from the `ruckig <https://github.com/pantor/ruckig>`_ library
(time-optimal under velocity, acceleration and jerk limits); they may start and end with a
non-zero acceleration, which is how a *direct* reversal (velocity crossing zero with finite
acceleration, no dwell) is built from two moves.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

from fricbench._validation import check_finite, check_nonneg, check_positive

__all__ = [
    "Segment",
    "check_positive_pair",
    "check_positive_sequence",
    "concatenate",
    "monotone_point_to_point",
    "point_to_point",
    "rest",
    "reversal_accel_limit",
    "smooth_window",
    "windowed_sines",
]

FloatArray = NDArray[np.float64]
State = tuple[float, float, float]
Evaluator = Callable[[FloatArray], tuple[FloatArray, FloatArray, FloatArray]]


@dataclass(frozen=True)
class Segment:
    """One piece of a single-axis reference.

    Attributes
    ----------
    duration : float
        Length, s (``>= 0``).
    evaluate : callable
        ``evaluate(tau) -> (x, v, a)`` for local times ``tau`` (s, array in
        ``[0, duration]``); position m, velocity m/s, acceleration m/s^2.
    start, end : tuple of float
        ``(x, v, a)`` at ``tau = 0`` and ``tau = duration``.
    bounds : tuple of float
        Lower and upper bound of ``x`` over the segment, m: exact for moves and rests,
        conservative (offset -/+ sum of amplitudes) for sine blocks.
    """

    duration: float
    evaluate: Evaluator
    start: State
    end: State
    bounds: tuple[float, float]


def _segment(duration: float, evaluate: Evaluator, bounds: tuple[float, float]) -> Segment:
    x, v, a = evaluate(np.array([0.0, duration]))
    return Segment(
        duration,
        evaluate,
        (float(x[0]), float(v[0]), float(a[0])),
        (float(x[1]), float(v[1]), float(a[1])),
        bounds,
    )


# -- point-to-point moves --------------------------------------------------------------------
def point_to_point(
    x0: float,
    x1: float,
    feed: float,
    accel: float,
    jerk: float,
    *,
    a0: float = 0.0,
    a1: float = 0.0,
) -> Segment:
    """Time-optimal jerk-limited move from ``x0`` to ``x1`` (ruckig), at rest at both ends.

    Parameters
    ----------
    x0, x1 : float
        Start and target position, m.
    feed : float
        Velocity limit, m/s (``> 0``).
    accel : float
        Acceleration limit, m/s^2 (``> 0``).
    jerk : float
        Jerk limit, m/s^3 (``> 0``).
    a0, a1 : float, optional
        Acceleration at the start and at the target, m/s^2, within ``accel`` and
        :func:`reversal_accel_limit` ``(feed, jerk)`` (beyond it the velocity limit would be
        broken); velocity is zero at both ends. A non-zero ``a1`` whose sign points back
        towards ``x0`` makes ``x1`` a direct reversal point when the next move starts with
        ``a0`` equal to it.

    Returns
    -------
    Segment
        The move; its ``bounds`` are ruckig's exact position extrema.

    Raises
    ------
    ValueError
        If a limit is not positive, ``a0`` or ``a1`` exceeds its limit, or ruckig rejects the
        input.
    """
    x0 = check_finite("x0", x0)
    x1 = check_finite("x1", x1)
    feed = check_positive("feed", feed, "m/s")
    accel = check_positive("accel", accel, "m/s^2")
    jerk = check_positive("jerk", jerk, "m/s^3")
    a0 = check_finite("a0", a0)
    a1 = check_finite("a1", a1)
    limit = min(accel, reversal_accel_limit(feed, jerk))
    for name, val in (("a0", a0), ("a1", a1)):
        if abs(val) > limit * (1.0 + 1e-9):
            raise ValueError(
                f"{name}={val!r}: expected |{name}| <= min(accel, sqrt(2 jerk feed)) = "
                f"{limit!r} m/s^2"
            )

    otg = Ruckig(1)
    inp = InputParameter(1)
    traj = Trajectory(1)
    inp.current_position = [x0]
    inp.current_velocity = [0.0]
    inp.current_acceleration = [a0]
    inp.target_position = [x1]
    inp.target_velocity = [0.0]
    inp.target_acceleration = [a1]
    inp.max_velocity = [feed]
    inp.max_acceleration = [accel]
    inp.max_jerk = [jerk]
    try:
        result = otg.calculate(inp, traj)
    except RuckigError as exc:
        raise ValueError(
            f"ruckig rejected the move x0={x0!r} -> x1={x1!r} (feed={feed!r}, accel={accel!r}, "
            f"jerk={jerk!r}, a0={a0!r}, a1={a1!r}): {exc}"
        ) from exc
    if result != Result.Working:
        raise ValueError(
            f"ruckig returned {result} for the move x0={x0!r} -> x1={x1!r} (feed={feed!r}, "
            f"accel={accel!r}, jerk={jerk!r}, a0={a0!r}, a1={a1!r}): expected Result.Working"
        )
    duration = float(traj.duration)
    ext = traj.position_extrema[0]

    def evaluate(tau: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        out = np.empty((3, tau.shape[0]))
        at_time = traj.at_time
        for k, tk in enumerate(np.clip(tau, 0.0, duration).tolist()):
            p, v, a = at_time(tk)
            out[0, k] = p[0]
            out[1, k] = v[0]
            out[2, k] = a[0]
        return out[0], out[1], out[2]

    return _segment(duration, evaluate, (float(ext.min), float(ext.max)))


def reversal_accel_limit(feed: float, jerk: float) -> float:
    """Largest acceleration a move may start or end with at zero velocity, m/s^2.

    Ramping the acceleration from ``a`` to 0 at ``jerk`` changes the velocity by
    ``a^2 / (2 jerk)``, which must stay within ``feed``: ``a_max = sqrt(2 jerk feed)``.
    """
    # a^2 / (2 j) <= feed
    return float(np.sqrt(2.0 * jerk * feed))


def _is_monotone(seg: Segment, x0: float, x1: float) -> bool:
    tol = 1e-12 + 1e-6 * abs(x1 - x0)
    return seg.bounds[0] >= min(x0, x1) - tol and seg.bounds[1] <= max(x0, x1) + tol


def monotone_point_to_point(
    x0: float,
    x1: float,
    feed: float,
    accel: float,
    jerk: float,
    *,
    a0: float = 0.0,
    a1: float = 0.0,
    tries: int = 8,
) -> Segment:
    """:func:`point_to_point` that never leaves ``[min(x0, x1), max(x0, x1)]``.

    ``a1`` is first clipped to :func:`reversal_accel_limit` ``(feed, jerk)`` and ``accel``. A
    short move asked to end with a large acceleration overshoots (ruckig first moves away to
    build it up): ``a1`` is then halved up to ``tries`` times, then set to zero, until the move
    stays between its end points (or ruckig accepts it). The returned segment's ``end[2]`` is
    the ``a1`` used.

    Raises
    ------
    ValueError
        If even ``a1 = 0`` overshoots (``a0`` too large for the distance); pass a smaller
        ``a0`` or a longer move.
    """
    cap = min(accel, reversal_accel_limit(feed, jerk))
    a1 = float(np.clip(a1, -cap, cap))
    for _ in range(tries):
        try:
            seg = point_to_point(x0, x1, feed, accel, jerk, a0=a0, a1=a1)
        except ValueError:  # ruckig found no profile ending with this a1
            a1 *= 0.5
            continue
        if _is_monotone(seg, x0, x1):
            return seg
        a1 *= 0.5
    seg = point_to_point(x0, x1, feed, accel, jerk, a0=a0, a1=0.0)
    if not _is_monotone(seg, x0, x1):
        raise ValueError(
            f"a0={a0!r}: the move x0={x0!r} -> x1={x1!r} overshoots with this start "
            f"acceleration (jerk={jerk!r}); expected a smaller |a0| or a longer move"
        )
    return seg


# -- rest --------------------------------------------------------------------------------------
def rest(x: float, duration: float) -> Segment:
    """Stand still at position ``x`` (m) for ``duration`` (s, ``>= 0``)."""
    x = check_finite("x", x)
    duration = check_nonneg("duration", duration, "s")

    def evaluate(tau: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        return np.full(tau.shape, x), np.zeros(tau.shape), np.zeros(tau.shape)

    return _segment(duration, evaluate, (x, x))


# -- windowed sines --------------------------------------------------------------------------
def smooth_window(
    tau: FloatArray, duration: float, ramp: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Window rising 0 -> 1 over ``ramp``, flat, falling 1 -> 0 over the last ``ramp`` seconds.

    The ramps are the septic smoothstep ``S(u) = 35u^4 - 84u^5 + 70u^6 - 20u^7`` whose first
    three derivatives vanish at ``u = 0`` and ``u = 1``, so a windowed signal is continuous up
    to jerk. Returns ``(w, dw/dtau, d2w/dtau2)``; requires ``0 < 2 ramp <= duration``.
    """
    w = np.ones(tau.shape)
    dw = np.zeros(tau.shape)
    ddw = np.zeros(tau.shape)
    for side in (1.0, -1.0):
        u = tau / ramp if side > 0 else (duration - tau) / ramp
        m = u < 1.0
        um = np.clip(u[m], 0.0, 1.0)
        # S = 35u^4 - 84u^5 + 70u^6 - 20u^7,  S' = 140 u^3 (1-u)^3,  S'' = 420 u^2 (1-u)^2 (1-2u)
        w[m] = um**4 * (35.0 - 84.0 * um + 70.0 * um**2 - 20.0 * um**3)
        dw[m] = side * 140.0 * um**3 * (1.0 - um) ** 3 / ramp
        ddw[m] = 420.0 * um**2 * (1.0 - um) ** 2 * (1.0 - 2.0 * um) / ramp**2
    return w, dw, ddw


def windowed_sines(
    amplitudes: Sequence[float],
    frequencies: Sequence[float],
    phases: Sequence[float],
    duration: float,
    ramp: float,
    offset: float = 0.0,
) -> Segment:
    """Sum of sinusoids under :func:`smooth_window`, around ``offset``.

    ``x(tau) = offset + w(tau) * sum_i A_i sin(2 pi f_i tau + phi_i)``, so the block starts and
    ends at rest at ``offset`` (x, v, a and jerk continuous with a rest there).

    Parameters
    ----------
    amplitudes : sequence of float
        ``A_i``, m.
    frequencies : sequence of float
        ``f_i``, Hz.
    phases : sequence of float
        ``phi_i``, rad.
    duration : float
        Block length, s.
    ramp : float
        Window ramp time at each end, s; ``0 < 2 ramp <= duration``.
    offset : float, optional
        Centre position, m.
    """
    amp = np.asarray(amplitudes, dtype=float)[:, None]
    omega = 2.0 * np.pi * np.asarray(frequencies, dtype=float)[:, None]
    phi = np.asarray(phases, dtype=float)[:, None]
    if not amp.shape == omega.shape == phi.shape:
        raise ValueError(
            f"amplitudes, frequencies, phases have lengths {amp.shape[0]}, {omega.shape[0]}, "
            f"{phi.shape[0]}: expected equal lengths"
        )
    duration = check_positive("duration", duration, "s")
    ramp = check_positive("ramp", ramp, "s")
    if 2.0 * ramp > duration * (1.0 + 1e-12):
        raise ValueError(f"ramp={ramp!r}: expected 2 * ramp <= duration={duration!r} s")
    offset = check_finite("offset", offset)

    def evaluate(tau: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        tau = np.clip(tau, 0.0, duration)
        arg = omega * tau[None, :] + phi
        sn, cs = np.sin(arg), np.cos(arg)
        s = np.sum(amp * sn, axis=0)
        ds = np.sum(amp * omega * cs, axis=0)
        dds = -np.sum(amp * omega**2 * sn, axis=0)
        w, dw, ddw = smooth_window(tau, duration, ramp)
        # x = o + w s,  v = w' s + w s',  a = w'' s + 2 w' s' + w s''
        return offset + w * s, dw * s + w * ds, ddw * s + 2.0 * dw * ds + w * dds

    span = float(np.sum(np.abs(amp)))
    return _segment(duration, evaluate, (offset - span, offset + span))


# -- sampling --------------------------------------------------------------------------------
def concatenate(
    segments: Sequence[Segment], ts: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Lay ``segments`` end to end and sample the result every ``ts`` seconds from ``t = 0``.

    The time line is the sum of the segment durations ``T``; there are ``ceil(T / ts) + 1``
    samples, the last one holding the final state of the last segment.

    Returns
    -------
    t, x, v, a : ndarray, shape (K,)
        Time (s), position (m), velocity (m/s), acceleration (m/s^2).

    Raises
    ------
    ValueError
        If ``segments`` is empty, ``ts`` is not positive, or a segment does not start where the
        previous one ended (position, velocity and acceleration must match).
    """
    ts = check_positive("ts", ts, "s")
    if len(segments) == 0:
        raise ValueError("segments=[]: expected at least one segment")
    for i in range(1, len(segments)):
        prev, cur = segments[i - 1].end, segments[i].start
        for j, (nm, scale) in enumerate((("x", 1e-3), ("v", 1e-3), ("a", 1e-1))):
            if abs(prev[j] - cur[j]) > 1e-9 * (scale + abs(prev[j])):
                raise ValueError(
                    f"segments[{i}] starts at {nm}={cur[j]!r} but segments[{i - 1}] ends at "
                    f"{nm}={prev[j]!r}: expected a contiguous sequence"
                )
    durations = np.array([s.duration for s in segments], dtype=float)
    starts = np.concatenate(([0.0], np.cumsum(durations)[:-1]))
    total = float(np.sum(durations))
    k = int(np.ceil(total / ts - 1e-9)) + 1
    t = np.arange(k, dtype=float) * ts
    # sample -> segment: a sample on a boundary belongs to the later segment
    idx = np.minimum(np.searchsorted(starts[1:], t, side="right"), len(segments) - 1)
    x = np.empty(k)
    v = np.empty(k)
    a = np.empty(k)
    for i in np.unique(idx).tolist():
        m = idx == i
        tau = np.clip(t[m] - starts[i], 0.0, durations[i])
        x[m], v[m], a[m] = segments[i].evaluate(tau)
    return t, x, v, a


# -- argument checks for sequences -----------------------------------------------------------
def check_positive_sequence(name: str, value: Any, unit: str = "") -> tuple[float, ...]:
    """A non-empty sequence of finite numbers ``> 0``, returned as a tuple of float."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence | np.ndarray):
        raise TypeError(f"{name}={value!r}: expected a sequence of numbers")
    if len(value) == 0:
        raise ValueError(f"{name}={value!r}: expected at least one value")
    return tuple(check_positive(f"{name}[{i}]", v, unit) for i, v in enumerate(value))


def check_positive_pair(name: str, value: Any, unit: str = "") -> tuple[float, float]:
    """A ``(low, high)`` range with ``0 < low <= high``."""
    pair = check_positive_sequence(name, value, unit)
    if len(pair) != 2 or pair[0] > pair[1]:
        raise ValueError(f"{name}={value!r}: expected (low, high) with 0 < low <= high")
    return pair[0], pair[1]

"""Starts, stops and reversals of a run: the one event finder of fricbench.

Every part that looks for where an axis starts, stops or turns round (the friction-error
windows and the predictors' features, the loader's reversal count, the diagnosis report, the
benchmark's reversal peaks) reads the motion through two functions of this module:

* :func:`motion_sign`: the direction of motion of each sample, ``+1``, ``-1`` or ``0`` at rest
  (``|v| <= rest_speed``); :func:`hysteresis_sign` gives the same from a position whose noise
  would make a speed threshold chatter (a turn counts once the position came back by ``tol``);
* :func:`motion_events`: the start, stop and reversal events of a velocity (the paper's rule on
  three consecutive samples, a short rest between opposite motions read as a direct
  reversal), with the turning-point sample, the first sample of the new motion, the direction
  and the acceleration; :func:`sign_reversals` the first samples of the reversals alone.

The thresholds and windows differ between callers (a reference at rest below 1 um/s, a log's
reversals beyond 0.1 % of its stroke) and stay arguments at the call sites.
:meth:`fricbench.run.Run.events` applies :func:`motion_events` to a run's reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fricbench._validation import check_int, check_nonneg, check_positive, check_signal

__all__ = ["EVENT_KINDS", "MotionEvent", "hysteresis_sign", "motion_events", "motion_sign",
           "sign_reversals"]

EVENT_KINDS = ("start", "stop", "reversal")


@dataclass(frozen=True)
class MotionEvent:
    """One start, stop or reversal.

    Attributes
    ----------
    kind : {"start", "stop", "reversal"}
    index : int
        Sample of the turning point: last rest sample before a start, first rest sample of a
        stop, the sample of smallest ``|v|`` at a reversal.
    direction : int
        ``+1`` or ``-1``: direction of motion after a start or reversal, before a stop.
    accel : float
        ``|a|`` at ``index``, m/s^2 (``a0`` of the paper for a reference).
    onset : int
        First moving sample of the new motion after a start or reversal; the first rest
        sample (``index``) of a stop.
    """

    kind: str
    index: int
    direction: int
    accel: float
    onset: int


def motion_sign(v: np.ndarray, rest_speed: float = 1e-6) -> np.ndarray:
    """Direction of motion of each sample: ``sign(v)`` where ``|v| > rest_speed``, else 0.

    Parameters
    ----------
    v : array_like, shape (K,)
        Velocity, m/s (or rad/s).
    rest_speed : float, optional
        Speed at or below which a sample is at rest, same unit; 0 reads only ``v == 0`` as
        rest.

    Returns
    -------
    ndarray of float, shape (K,)
        ``-1.0``, ``0.0`` or ``+1.0``.

    Raises
    ------
    ValueError
        ``v`` not 1-D or not finite, ``rest_speed`` negative or not finite.
    """
    v = check_signal("v", v)
    rest_speed = check_nonneg("rest_speed", rest_speed, "m/s")
    return np.where(np.abs(v) > rest_speed, np.sign(v), 0.0)


def hysteresis_sign(x: np.ndarray, tol: float) -> np.ndarray:
    """Direction of the last move of ``x`` by more than ``tol``, for each sample.

    A position hysteresis (a play operator of width ``tol``): the direction becomes ``+1`` once
    ``x`` rose by more than ``tol`` from the start, ``-1`` once it fell by more than ``tol``
    from its highest value so far, and changes again each time ``x`` comes back by more than
    ``tol`` from its extreme in the current direction. Noise and excursions smaller than
    ``tol`` never turn it; it is 0 until the first such move.

    Parameters
    ----------
    x : array_like, shape (K,)
        Position, m (or rad).
    tol : float
        Smallest turn that counts, same unit, > 0.

    Returns
    -------
    ndarray of float, shape (K,)
        ``-1.0``, ``0.0`` (before the first move) or ``+1.0``.
    """
    x = check_signal("x", x)
    tol = check_positive("tol", tol, "m")
    out = np.zeros(x.shape[0])
    if x.shape[0] == 0:
        return out
    direction = 0
    extreme = x[0]
    for k, value in enumerate(x):
        if direction >= 0:
            if value > extreme:
                extreme = value
                if direction == 0 and value - x[0] > tol:
                    direction = 1
            elif extreme - value > tol:
                direction = -1
                extreme = value
        elif value < extreme:
            extreme = value
        elif value - extreme > tol:
            direction = 1
            extreme = value
        out[k] = direction
    return out


def sign_reversals(sign: np.ndarray) -> np.ndarray:
    """First sample of each motion opposite to the motion before it (rests in between allowed).

    The reversals of :func:`motion_events` with ``max_gap=None``, placed at their ``onset``.

    Parameters
    ----------
    sign : array_like, shape (K,)
        Direction of each sample (``-1``, ``0``, ``+1``), from :func:`motion_sign` or
        :func:`hysteresis_sign`.

    Returns
    -------
    ndarray of int64
        Increasing sample indices.
    """
    s = check_signal("sign", sign)
    if np.any((s != -1.0) & (s != 0.0) & (s != 1.0)):
        raise ValueError("sign has values other than -1, 0 and +1: expected the output of "
                         "motion_sign or hysteresis_sign")
    nz = np.flatnonzero(s)
    if nz.size < 2:
        return np.zeros(0, dtype=np.int64)
    return nz[1:][s[nz[1:]] != s[nz[:-1]]].astype(np.int64)


def motion_events(v: np.ndarray, ts: float, *, rest_speed: float = 1e-6,
                  max_gap: int | None = 2) -> list[MotionEvent]:
    """Starts, stops and reversals of a sampled velocity.

    The paper's rule on three consecutive samples ``v1, v2, v3`` (start: ``0, 0, !=0``; stop:
    ``!=0, 0, 0``; reversal: ``!=0, 0, !=0``) with "zero" meaning ``|v| <= rest_speed``, and a
    rest of at most ``max_gap`` samples between opposite motions counted as a direct reversal
    (a smooth zero crossing may leave one or two samples at rest); a rest that short between
    motions of one direction is no event. Motion from the first sample is a start (the axis
    rested before the run).

    Parameters
    ----------
    v : array_like, shape (K,)
        Velocity, m/s.
    ts : float
        Sample time, s (for the acceleration ``np.gradient(v, ts)``).
    rest_speed : float, optional
        Speed at or below which a sample is at rest, m/s (0: only ``v == 0``).
    max_gap : int or None, optional
        Longest rest, in samples, still read as a direct reversal; None: any rest.

    Returns
    -------
    list of MotionEvent
        In time order.

    Raises
    ------
    ValueError
        ``v`` not 1-D or not finite, ``ts`` not > 0, ``rest_speed`` < 0, ``max_gap`` < 0.
    TypeError
        ``max_gap`` not an integer or None.
    """
    v = check_signal("v", v)
    ts = check_positive("ts", ts, "s")
    sgn = motion_sign(v, rest_speed).astype(int)
    gap_max = np.inf if max_gap is None else check_int("max_gap", max_gap, 0)
    if v.shape[0] == 0:
        return []
    a = np.gradient(v, ts) if v.shape[0] >= 2 else np.zeros_like(v)
    # maximal runs of equal sign
    change = np.flatnonzero(np.diff(sgn)) + 1
    bounds = np.concatenate([[0], change, [len(sgn)]])
    runs = [(int(bounds[i]), int(bounds[i + 1]), int(sgn[bounds[i]]))
            for i in range(len(bounds) - 1)]
    events: list[MotionEvent] = []
    for i, (lo, hi, s) in enumerate(runs):
        if s == 0:
            continue
        prev = runs[i - 1] if i > 0 else None
        if prev is not None and prev[2] != 0 and prev[2] != s:
            # sign change between two samples: the turning point is the smaller |v|
            k = lo if abs(v[lo]) < abs(v[lo - 1]) else lo - 1
            events.append(MotionEvent("reversal", k, s, float(abs(a[k])), lo))
        elif prev is None or prev[2] == 0:
            before = runs[i - 2] if i >= 2 else None
            gap = prev[1] - prev[0] if prev is not None else 0
            if prev is not None and before is not None and before[2] == -s and gap <= gap_max:
                k = prev[0] + int(np.argmin(np.abs(v[prev[0]:prev[1]])))
                events.append(MotionEvent("reversal", k, s, float(abs(a[k])), lo))
            elif prev is not None and before is not None and before[2] == s and gap <= gap_max:
                continue  # momentary rest without a change of direction
            else:
                k = max(lo - 1, 0)
                events.append(MotionEvent("start", k, s, float(abs(a[k])), lo))
        nxt = runs[i + 1] if i + 1 < len(runs) else None
        if nxt is not None and nxt[2] == 0:
            after = runs[i + 2] if i + 2 < len(runs) else None
            if after is not None and nxt[1] - nxt[0] <= gap_max:
                continue  # handled as a reversal (or ignored) by the next motion run
            events.append(MotionEvent("stop", hi, s, float(abs(a[min(hi, len(a) - 1)])), hi))
    return events

"""Jerk-limited point-to-point move ("S-curve" velocity profile), optionally and back."""

from __future__ import annotations

from fricbench._validation import check_finite, check_nonneg, check_positive, check_range
from fricbench.trajectories.base import Reference
from fricbench.trajectories.segments import concatenate, point_to_point, rest

__all__ = ["s_curve"]


def s_curve(
    *,
    distance: float = 0.05,
    feed: float = 0.05,
    accel: float = 1.0,
    jerk: float = 50.0,
    dwell: float = 0.2,
    back: bool = True,
    ts: float = 1e-3,
) -> Reference:
    """Time-optimal jerk-limited move ``0 -> distance``, a dwell, then back to 0 if ``back``.

    Geometry: ``0 -> distance`` (ruckig, at rest at both ends), dwell; with ``back`` also
    ``distance -> 0``, dwell. With the defaults the move reaches the feed (50 mm over
    50 mm/s: about 1.07 s per move) and the whole reference lasts about 2.5 s.

    Parameters
    ----------
    distance : float, optional
        Signed travel, m (non-zero; negative moves the axis in the negative direction).
    feed : float, optional
        Velocity limit, m/s.
    accel : float, optional
        Acceleration limit, m/s^2.
    jerk : float, optional
        Jerk limit, m/s^3.
    dwell : float, optional
        Rest after each move, s (``>= 0``).
    back : bool, optional
        Return to 0 after the first dwell.
    ts : float, optional
        Sample time, s, in ``(0, 0.1]``.

    Returns
    -------
    Reference
        Single-axis reference named ``"s_curve"``, starting and ending at rest.
    """
    distance = check_finite("distance", distance)
    if distance == 0.0:
        raise ValueError(f"distance={distance!r}: expected a non-zero travel in m")
    feed = check_positive("feed", feed, "m/s")
    accel = check_positive("accel", accel, "m/s^2")
    jerk = check_positive("jerk", jerk, "m/s^3")
    dwell_s = check_nonneg("dwell", dwell, "s")
    if not isinstance(back, bool):
        raise TypeError(f"back={back!r}: expected a bool")
    ts = check_positive("ts", ts, "s")
    ts = check_range("ts", ts, 0.0, 0.1, "s")

    segs = [point_to_point(0.0, distance, feed, accel, jerk), rest(distance, dwell_s)]
    if back:
        segs += [point_to_point(distance, 0.0, feed, accel, jerk), rest(0.0, dwell_s)]
    t, x, v, a = concatenate(segs, ts)
    params = dict(distance=distance, feed=feed, accel=accel, jerk=jerk, dwell=dwell_s,
                  back=back, ts=ts)
    return Reference(t, x, v, a, name="s_curve", params=params)

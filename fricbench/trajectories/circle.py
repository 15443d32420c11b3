"""Two-axis circular test (ISO 230-4 style): X and Y interpolate a circle, quadrant reversals."""

from __future__ import annotations

import numpy as np

from fricbench._validation import check_choice, check_nonneg, check_positive, check_range
from fricbench.trajectories.base import Reference
from fricbench.trajectories.segments import Segment, concatenate, point_to_point, rest

__all__ = ["circle"]

DIRECTIONS = ("ccw", "cw", "both")


def circle(
    *,
    radius: float = 0.01,
    feed: float = 0.02,
    accel: float = 0.5,
    jerk: float = 20.0,
    direction: str = "both",
    revolutions: float = 1.0,
    dwell: float = 0.2,
    ts: float = 1e-3,
) -> Reference:
    """Circle of ``radius`` traversed at tangential ``feed``, counter-clockwise and/or clockwise.

    Geometry: centre at ``(-radius, 0)``, so both axes start at 0 and the circle starts at the
    origin, which is the +X quadrant point. The arc length ``s(t)`` is a time-optimal
    jerk-limited move (ruckig; limits ``feed``, ``accel``, ``jerk`` on the tangential motion)
    from 0 to ``L = 2 pi radius revolutions``; the angle is ``theta = s / radius`` and::

        x = radius (cos theta - 1)                       y = radius sin theta
        vx = -radius sin theta * w                       vy = radius cos theta * w
        ax = -radius (cos theta w^2 + sin theta dw)      ay = radius (cos theta dw - sin theta w^2)

    with ``w = ds/dt / radius`` and ``dw = d2s/dt2 / radius`` (analytic, no finite
    differences). ``direction="ccw"``: ``s`` from 0 to ``L`` then ``dwell``; ``"cw"``: 0 to
    ``-L`` then ``dwell``; ``"both"``: 0 to ``L``, ``dwell``, back from ``L`` to 0 along the
    same circle (clockwise), ``dwell``. An axis reverses where the other crosses a quadrant
    point: Y at theta = pi/2 and 3 pi/2, X at theta = pi (and at the start point). Besides the
    tangential limits there is the centripetal acceleration ``feed^2 / radius`` (0.04 m/s^2
    with the defaults). Defaults: 10 mm radius at 20 mm/s, one revolution each way, about
    7 s.

    Parameters
    ----------
    radius : float, optional
        Circle radius, m.
    feed : float, optional
        Tangential velocity limit, m/s.
    accel : float, optional
        Tangential acceleration limit, m/s^2.
    jerk : float, optional
        Tangential jerk limit, m/s^3.
    direction : {"ccw", "cw", "both"}, optional
        Sense of rotation; ``"both"`` is counter-clockwise then clockwise back.
    revolutions : float, optional
        Turns per direction (``> 0``; fractions allowed).
    dwell : float, optional
        Rest after each traversal, s (``>= 0``).
    ts : float, optional
        Sample time, s, in ``(0, 0.1]``.

    Returns
    -------
    Reference
        Two-axis reference named ``"circle"``; ``x``, ``v``, ``a`` have shape ``(2, K)``,
        rows X and Y.
    """
    radius = check_positive("radius", radius, "m")
    feed = check_positive("feed", feed, "m/s")
    accel = check_positive("accel", accel, "m/s^2")
    jerk = check_positive("jerk", jerk, "m/s^3")
    direction = check_choice("direction", direction, DIRECTIONS)
    revolutions = check_positive("revolutions", revolutions)
    dwell = check_nonneg("dwell", dwell, "s")
    ts = check_positive("ts", ts, "s")
    ts = check_range("ts", ts, 0.0, 0.1, "s")

    length = 2.0 * np.pi * radius * revolutions
    end = -length if direction == "cw" else length
    segs: list[Segment] = [point_to_point(0.0, end, feed, accel, jerk), rest(end, dwell)]
    if direction == "both":
        segs += [point_to_point(end, 0.0, feed, accel, jerk), rest(0.0, dwell)]
    t, s, ds, dds = concatenate(segs, ts)

    theta, w, dw = s / radius, ds / radius, dds / radius
    cos, sin = np.cos(theta), np.sin(theta)
    x = radius * np.stack((cos - 1.0, sin))
    v = radius * np.stack((-sin * w, cos * w))
    # ax = d/dt(-sin(theta) w) = -(cos(theta) w^2 + sin(theta) dw)
    # ay = d/dt(cos(theta) w) = cos(theta) dw - sin(theta) w^2
    a = radius * np.stack((-(cos * w**2 + sin * dw), cos * dw - sin * w**2))
    params = dict(radius=radius, feed=feed, accel=accel, jerk=jerk, direction=direction,
                  revolutions=revolutions, dwell=dwell, ts=ts)
    return Reference(t, x, v, a, name="circle", params=params)

"""The "M-serial" linear trajectory: single-axis position traces shaped like the letter M."""

from __future__ import annotations

from fricbench._validation import check_nonneg, check_positive, check_range
from fricbench.trajectories.base import Reference
from fricbench.trajectories.segments import (
    Segment,
    check_positive_sequence,
    concatenate,
    monotone_point_to_point,
    rest,
    reversal_accel_limit,
)

__all__ = ["m_serial"]

# One letter M, in units of the letter's stroke S and feed F:
# (target / S, feed / F, what happens at the target, reversal acceleration / accel)
_LETTER: tuple[tuple[float, float, str, float], ...] = (
    (0.5, 1.0, "stop", 0.0),  # rise to mid-height, stop and dwell (no reversal)
    (1.0, 0.5, "stop", 0.0),  # rise to the top at half feed, stop, dwell, then reverse
    (0.5, 1.0, "direct", 1.0),  # fall to the middle valley, direct reversal at +accel
    (1.0, 0.75, "direct", 0.5),  # rise to the top, direct reversal at -accel / 2
    (0.0, 0.5, "stop", 0.0),  # fall back to 0 at half feed, stop and dwell
)


def m_serial(
    *,
    stroke: float = 0.02,
    feed: float = 0.02,
    accel: float = 0.5,
    jerk: float = 20.0,
    dwell: float = 0.2,
    stroke_scales: tuple[float, ...] = (1.0, 0.6, 0.3),
    feed_scales: tuple[float, ...] = (1.0, 0.5, 0.25),
    ts: float = 1e-3,
) -> Reference:
    """The paper's "M-serial" linear test: letters M drawn one after another on one axis.

    Geometry: letter ``i`` has stroke ``S = stroke * stroke_scales[i]`` and feed
    ``F = feed * feed_scales[i]``; its position trace is the letter M::

        0 -> S/2   at F,      stop, dwell             (start and stop, no reversal)
        S/2 -> S   at F/2,    stop, dwell             (reversal after a dwell)
        S -> S/2   at F,      direct reversal, a = +accel      (velocity crosses zero)
        S/2 -> S   at 3F/4,   direct reversal, a = -accel / 2
        S -> 0     at F/2,    stop, dwell

    Every move is time-optimal under ``(feed, accel, jerk)`` limits (ruckig). A direct reversal
    passes the target with zero velocity and the given acceleration, so the velocity changes
    sign without a stop; that acceleration is capped at ``0.9 sqrt(2 jerk F_min)`` (the feeds
    of the two moves must not be exceeded while it builds up) and halved further on a stroke
    too short for it. With the defaults (three letters: S = 20, 12, 6 mm; F = 20, 10, 5 mm/s)
    the trace lasts about 18.2 s, segment feeds range over 2.5..20 mm/s, and there are
    11 reversals (6 direct at 0.25..0.5 m/s^2, 5 after a dwell, counting the turn between
    letters) and 9 dwells at rest. Starts and ends at rest at 0.

    Parameters
    ----------
    stroke : float, optional
        Height of the first letter, m.
    feed : float, optional
        Feed of the first letter, m/s.
    accel : float, optional
        Acceleration limit, m/s^2.
    jerk : float, optional
        Jerk limit, m/s^3.
    dwell : float, optional
        Rest at every stop, s (``>= 0``).
    stroke_scales, feed_scales : tuple of float, optional
        One entry per letter (equal lengths, each ``> 0``): stroke and feed relative to
        ``stroke`` and ``feed``.
    ts : float, optional
        Sample time, s, in ``(0, 0.1]``.

    Returns
    -------
    Reference
        Single-axis reference named ``"m_serial"``.
    """
    stroke = check_positive("stroke", stroke, "m")
    feed = check_positive("feed", feed, "m/s")
    accel = check_positive("accel", accel, "m/s^2")
    jerk = check_positive("jerk", jerk, "m/s^3")
    dwell = check_nonneg("dwell", dwell, "s")
    stroke_scales = check_positive_sequence("stroke_scales", stroke_scales)
    feed_scales = check_positive_sequence("feed_scales", feed_scales)
    if len(stroke_scales) != len(feed_scales):
        raise ValueError(
            f"feed_scales={feed_scales!r}: expected {len(stroke_scales)} entries, one per "
            f"entry of stroke_scales"
        )
    ts = check_positive("ts", ts, "s")
    ts = check_range("ts", ts, 0.0, 0.1, "s")

    # the moves of all letters: (target m, feed m/s, kind, reversal acceleration m/s^2)
    plan = [
        (frac * stroke * s_scale, f_rel * feed * f_scale, kind, a_rel * accel)
        for s_scale, f_scale in zip(stroke_scales, feed_scales, strict=True)
        for frac, f_rel, kind, a_rel in _LETTER
    ]
    segs: list[Segment] = []
    pos, acc = 0.0, 0.0
    for i, (target, f, kind, a_rev) in enumerate(plan):
        a_end = 0.0
        if kind == "direct":
            # the next move starts with this acceleration: keep it within its feed too
            a_rev = min(a_rev, 0.9 * reversal_accel_limit(min(f, plan[i + 1][1]), jerk))
            # at a direct reversal the acceleration points back to where the move came from
            a_end = a_rev if target < pos else -a_rev
        move = monotone_point_to_point(pos, target, f, accel, jerk, a0=acc, a1=a_end)
        segs.append(move)
        pos, acc = target, move.end[2]
        if kind == "stop":
            segs.append(rest(pos, dwell))
    t, x, v, a = concatenate(segs, ts)
    params = dict(stroke=stroke, feed=feed, accel=accel, jerk=jerk, dwell=dwell,
                  stroke_scales=stroke_scales, feed_scales=feed_scales, ts=ts)
    return Reference(t, x, v, a, name="m_serial", params=params)

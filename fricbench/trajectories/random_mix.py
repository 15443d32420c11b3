"""Seeded random training mixture of jerk-limited moves, direct reversals and sine blocks."""

from __future__ import annotations

import math

import numpy as np

from fricbench._validation import check_int, check_positive, check_range
from fricbench.trajectories.base import Reference
from fricbench.trajectories.segments import (
    Segment,
    check_positive_pair,
    concatenate,
    monotone_point_to_point,
    point_to_point,
    rest,
    reversal_accel_limit,
    windowed_sines,
)

__all__ = ["random_mixture"]

_P_MOVE, _P_REVERSAL = 0.35, 0.35  # block probabilities; sine blocks take the rest
_P_NO_DWELL = 0.3  # probability that a block is followed by no dwell at all
_DWELL_RANGE = (0.02, 0.5)  # s, log-uniform otherwise
_FREQ_RANGE = (0.2, 5.0)  # Hz, log-uniform, for the first sine component
_SINE_V_FACTOR = 1.5  # sine blocks may reach 1.5 x the highest move feed
_MAX_REJECTS = 5  # consecutive blocks that do not fit before the mixture is closed


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return lo if lo == hi else float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def random_mixture(
    *,
    seed: int = 0,
    duration: float = 20.0,
    length_range: tuple[float, float] = (5e-5, 0.02),
    feed_range: tuple[float, float] = (1e-3, 0.05),
    accel_range: tuple[float, float] = (0.05, 2.0),
    jerk_range: tuple[float, float] = (10.0, 200.0),
    x_limit: float = 0.03,
    ts: float = 1e-3,
) -> Reference:
    """A random sequence of motion blocks for training, reproducible from ``seed``.

    Geometry: blocks are drawn with ``np.random.default_rng(seed)`` and appended while they
    (and a move back to 0 after them) fit in ``duration``; then the axis moves back to 0 and
    rests until exactly ``duration``. Positions stay within ``[-x_limit, x_limit]``. Each
    block is, with probability 0.35 / 0.35 / 0.30:

    * a **move**: jerk-limited point-to-point (ruckig) over a log-uniform length in
      ``length_range``, in a random direction, with log-uniform feed, acceleration and jerk
      from ``feed_range``, ``accel_range``, ``jerk_range``;
    * a **direct reversal**: two such moves in opposite directions joined at zero velocity
      with a random non-zero acceleration (up to the acceleration limit and
      ``0.9 sqrt(2 jerk feed)``), so the velocity crosses zero without a stop;
    * a **sine block**: one or two sinusoids (first frequency log-uniform in 0.2..5 Hz,
      amplitude log-uniform from ``length_range[0]`` to half of ``length_range[1]``), 1..4
      full cycles between half-cycle smooth ramps, around the current position; the peak
      velocity is capped at 1.5 x ``feed_range[1]`` and the peak acceleration at
      ``accel_range[1]``.

    Each block is followed by a dwell at rest (none with probability 0.3, else log-uniform in
    0.02..0.5 s). The defaults cover the velocities (up to 50 mm/s for moves, 75 mm/s for
    sines), accelerations (up to 2 m/s^2; a sine block's smooth ramps may exceed its cap a
    little), jerks and sub-100-um strokes of the evaluation set
    (``m_serial``, ``curve``, ``reversal_sine``, ``s_curve``) while staying disjoint from it:
    every length, feed, limit, frequency and phase is drawn from a continuous distribution, so
    no seed reproduces an evaluation sequence (that has probability zero), and the block
    structure (random order, random dwells) differs from the fixed evaluation patterns.

    Parameters
    ----------
    seed : int, optional
        Seed of ``np.random.default_rng`` (``>= 0``); same seed, same arrays bit for bit.
    duration : float, optional
        Length, s (the last sample is at ``ceil(duration / ts) * ts``).
    length_range : (float, float), optional
        Move lengths, m (``0 < low <= high <= x_limit``).
    feed_range : (float, float), optional
        Move feeds, m/s.
    accel_range : (float, float), optional
        Acceleration limits, m/s^2.
    jerk_range : (float, float), optional
        Jerk limits, m/s^3.
    x_limit : float, optional
        Half-width of the allowed position range, m.
    ts : float, optional
        Sample time, s, in ``(0, 0.1]``.

    Returns
    -------
    Reference
        Single-axis reference named ``"random"``, starting and ending at rest at 0.
    """
    seed = check_int("seed", seed, 0)
    duration = check_positive("duration", duration, "s")
    length_range = check_positive_pair("length_range", length_range, "m")
    feed_range = check_positive_pair("feed_range", feed_range, "m/s")
    accel_range = check_positive_pair("accel_range", accel_range, "m/s^2")
    jerk_range = check_positive_pair("jerk_range", jerk_range, "m/s^3")
    x_limit = check_positive("x_limit", x_limit, "m")
    if length_range[1] > x_limit:
        raise ValueError(
            f"length_range={length_range!r}: expected the longest move <= x_limit={x_limit!r} m"
        )
    ts = check_positive("ts", ts, "s")
    ts = check_range("ts", ts, 0.0, 0.1, "s")

    rng = np.random.default_rng(seed)

    def limits() -> tuple[float, float, float]:
        return (_loguniform(rng, *feed_range), _loguniform(rng, *accel_range),
                _loguniform(rng, *jerk_range))

    def target(pos: float, length: float, sign: float) -> float:
        # move ``length`` in direction ``sign`` unless that leaves [-x_limit, x_limit]
        end = pos + sign * length
        return end if abs(end) <= x_limit else pos - sign * length

    def dwell_after(pos: float) -> Segment:
        d = 0.0 if rng.random() < _P_NO_DWELL else _loguniform(rng, *_DWELL_RANGE)
        return rest(pos, d)

    def move_block(pos: float) -> list[Segment]:
        length = _loguniform(rng, *length_range)
        end = target(pos, length, 1.0 if rng.random() < 0.5 else -1.0)
        return [point_to_point(pos, end, *limits()), dwell_after(end)]

    def reversal_block(pos: float) -> list[Segment]:
        l1, l2 = _loguniform(rng, *length_range), _loguniform(rng, *length_range)
        b = target(pos, l1, 1.0 if rng.random() < 0.5 else -1.0)
        sign = 1.0 if b > pos else -1.0
        # second leg back towards ``pos``, shortened if it would leave the allowed range
        c = float(np.clip(b - sign * l2, -x_limit, x_limit))
        f1, f2 = _loguniform(rng, *feed_range), _loguniform(rng, *feed_range)
        acc, jerk = _loguniform(rng, *accel_range), _loguniform(rng, *jerk_range)
        cap = min(acc, 0.9 * reversal_accel_limit(min(f1, f2), jerk))
        a_rev = rng.uniform(0.3, 1.0) * cap
        for _ in range(6):  # halve the reversal acceleration until both legs stay monotone
            try:
                m1 = monotone_point_to_point(pos, b, f1, acc, jerk, a1=-sign * a_rev)
                m2 = monotone_point_to_point(b, c, f2, acc, jerk, a0=m1.end[2])
                break
            except ValueError:
                a_rev *= 0.5
        else:
            m1 = point_to_point(pos, b, f1, acc, jerk)
            m2 = point_to_point(b, c, f2, acc, jerk)
        return [m1, m2, dwell_after(c)]

    def sine_block(pos: float) -> list[Segment] | None:
        n = int(rng.integers(1, 3))
        amp0 = _loguniform(rng, length_range[0], max(length_range[0], 0.5 * length_range[1]))
        f0 = _loguniform(rng, *_FREQ_RANGE)
        amps = [amp0] + [amp0 * rng.uniform(0.1, 0.5) for _ in range(n - 1)]
        freqs = [f0] + [f0 * rng.uniform(1.5, 3.5) for _ in range(n - 1)]
        phases = [float(rng.uniform(0.0, 2.0 * np.pi)) for _ in range(n)]
        cycles = int(rng.integers(1, 5))
        amp_arr, omega = np.array(amps), 2.0 * np.pi * np.array(freqs)
        # scale amplitudes so that sum(w A) <= 1.5 feed_max and sum(w^2 A) <= accel_max
        scale = min(1.0, _SINE_V_FACTOR * feed_range[1] / float(np.sum(omega * amp_arr)),
                    accel_range[1] / float(np.sum(omega**2 * amp_arr)),
                    (x_limit - abs(pos)) / float(np.sum(amp_arr)))
        if scale * amp0 < length_range[0]:
            return None  # too close to the position limit for a useful block
        seg = windowed_sines(tuple(scale * amp_arr), tuple(freqs), tuple(phases),
                             (cycles + 1.0) / f0, 0.5 / f0, offset=pos)
        return [seg, dwell_after(pos)]

    segs: list[Segment] = []
    pos, elapsed = 0.0, 0.0
    home: Segment | None = None  # the move back to 0 from ``pos``
    rejects = 0
    while rejects < _MAX_REJECTS:
        u = rng.random()
        if u < _P_MOVE:
            block = move_block(pos)
        elif u < _P_MOVE + _P_REVERSAL:
            block = reversal_block(pos)
        else:
            block = sine_block(pos) or move_block(pos)
        new_pos = block[-1].end[0]
        new_home = point_to_point(new_pos, 0.0, *limits()) if new_pos != 0.0 else None
        need = sum(s.duration for s in block) + (new_home.duration if new_home else 0.0)
        if elapsed + need > duration:
            rejects += 1
            continue
        rejects = 0
        segs += block
        elapsed += sum(s.duration for s in block)
        pos, home = new_pos, new_home
    if home is not None:
        segs.append(home)
        elapsed += home.duration
    segs.append(rest(0.0, max(0.0, duration - elapsed)))
    t, x, v, a = concatenate(segs, ts)
    params = dict(seed=seed, duration=duration, length_range=length_range,
                  feed_range=feed_range, accel_range=accel_range, jerk_range=jerk_range,
                  x_limit=x_limit, ts=ts)
    return Reference(t, x, v, a, name="random", params=params)

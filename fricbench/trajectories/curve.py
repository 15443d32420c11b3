"""A smooth free-form single-axis curve with many reversals (the paper's second test)."""

from __future__ import annotations

from fricbench._validation import check_finite, check_positive, check_range
from fricbench.trajectories.base import Reference
from fricbench.trajectories.segments import check_positive_sequence, concatenate, windowed_sines

__all__ = ["curve"]


def curve(
    *,
    amplitudes: tuple[float, ...] = (0.010, 0.004, 0.0015),
    frequencies: tuple[float, ...] = (0.15, 0.4, 1.1),
    phases: tuple[float, ...] = (0.0, 1.0, 2.0),
    duration: float = 15.0,
    ramp: float = 2.0,
    ts: float = 1e-3,
) -> Reference:
    """Sum of incommensurate sinusoids under a jerk-continuous start/end window.

    Geometry: ``x(t) = w(t) * sum_i A_i sin(2 pi f_i t + phi_i)``, where ``w`` rises from 0 to
    1 over ``ramp`` seconds with the septic smoothstep (zero first, second and third
    derivative at both ends of the ramp), stays at 1 and falls back to 0 over the last
    ``ramp`` seconds. The curve therefore starts and ends at rest at 0 with continuous jerk,
    and ``v``, ``a`` are the exact derivatives (product rule), not finite differences. Because
    the frequencies are not harmonics of each other, the velocity crosses zero many times with
    a different acceleration at each crossing. With the defaults (A = 10, 4, 1.5 mm;
    f = 0.15, 0.4, 1.1 Hz; 15 s with 2 s ramps): peak |x| about 14.8 mm, peak |v| about
    29 mm/s, peak |a| about 0.10 m/s^2, and 23 velocity reversals with |a| between about
    0.02 and 0.10 m/s^2 at the crossings.

    Parameters
    ----------
    amplitudes : tuple of float, optional
        ``A_i``, m (each ``> 0``).
    frequencies : tuple of float, optional
        ``f_i``, Hz (each ``> 0``; same length as ``amplitudes``).
    phases : tuple of float, optional
        ``phi_i``, rad (same length as ``amplitudes``).
    duration : float, optional
        Length, s.
    ramp : float, optional
        Window ramp time at each end, s (``0 < 2 ramp <= duration``).
    ts : float, optional
        Sample time, s, in ``(0, 0.1]``.

    Returns
    -------
    Reference
        Single-axis reference named ``"curve"``.
    """
    amplitudes = check_positive_sequence("amplitudes", amplitudes, "m")
    frequencies = check_positive_sequence("frequencies", frequencies, "Hz")
    if isinstance(phases, (str, bytes)) or not hasattr(phases, "__len__"):
        raise TypeError(f"phases={phases!r}: expected a sequence of numbers")
    phases = tuple(check_finite(f"phases[{i}]", p) for i, p in enumerate(phases))
    for name, seq in (("frequencies", frequencies), ("phases", phases)):
        if len(seq) != len(amplitudes):
            raise ValueError(
                f"{name}={seq!r}: expected {len(amplitudes)} entries, one per amplitude"
            )
    duration = check_positive("duration", duration, "s")
    ramp = check_positive("ramp", ramp, "s")
    if 2.0 * ramp > duration:
        raise ValueError(f"ramp={ramp!r}: expected 2 * ramp <= duration={duration!r} s")
    ts = check_positive("ts", ts, "s")
    ts = check_range("ts", ts, 0.0, 0.1, "s")

    seg = windowed_sines(amplitudes, frequencies, phases, duration, ramp)
    t, x, v, a = concatenate([seg], ts)
    params = dict(amplitudes=amplitudes, frequencies=frequencies, phases=phases,
                  duration=duration, ramp=ramp, ts=ts)
    return Reference(t, x, v, a, name="curve", params=params)

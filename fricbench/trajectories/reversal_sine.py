"""Sine sweeps over amplitudes and frequencies: reversals from sub-100-um to mm strokes."""

from __future__ import annotations

from fricbench._validation import check_int, check_nonneg, check_positive, check_range
from fricbench.trajectories.base import Reference
from fricbench.trajectories.segments import (
    Segment,
    check_positive_sequence,
    concatenate,
    rest,
    windowed_sines,
)

__all__ = ["reversal_sine"]


def reversal_sine(
    *,
    amplitudes: tuple[float, ...] = (5e-5, 2e-4, 1e-3, 5e-3),
    frequencies: tuple[float, ...] = (0.5, 2.0),
    cycles: int = 3,
    ramp_cycles: float = 0.5,
    dwell: float = 0.2,
    ts: float = 1e-3,
) -> Reference:
    """Blocks of sinusoidal motion, one per (frequency, amplitude), separated by dwells.

    Geometry: for each frequency ``f`` in order, for each amplitude ``A`` in order, one block
    ``x = A w(tau) sin(2 pi f tau)`` of length ``(cycles + 2 ramp_cycles) / f`` whose window
    ``w`` (septic smoothstep, jerk-continuous) rises over the first ``ramp_cycles / f`` seconds
    and falls over the last, leaving ``cycles`` full-amplitude cycles in between; then
    ``dwell`` seconds at rest at 0. Each block starts and ends at rest at 0; derivatives are
    analytic. The peak velocity of a block is ``2 pi f A`` and the acceleration at its
    reversals ``(2 pi f)^2 A``. With the defaults (A = 50 um, 200 um, 1 mm, 5 mm;
    f = 0.5, 2 Hz; 3 cycles) there are 8 blocks and 41.6 s; peak |v| is 63 mm/s, reversal
    accelerations in the full-amplitude cycles range from 0.5 mm/s^2 to 0.79 m/s^2 (the
    half-cycle ramps reach up to 1.4 m/s^2); the 50 um blocks probe pre-sliding
    (sub-100-um) reversals.

    Parameters
    ----------
    amplitudes : tuple of float, optional
        Sine amplitudes, m (each ``> 0``).
    frequencies : tuple of float, optional
        Sine frequencies, Hz (each ``> 0``).
    cycles : int, optional
        Full-amplitude cycles per block (``>= 1``).
    ramp_cycles : float, optional
        Length of each window ramp in cycles of the block's frequency (``> 0``).
    dwell : float, optional
        Rest after each block, s (``>= 0``).
    ts : float, optional
        Sample time, s, in ``(0, 0.1]``.

    Returns
    -------
    Reference
        Single-axis reference named ``"reversal_sine"``.
    """
    amplitudes = check_positive_sequence("amplitudes", amplitudes, "m")
    frequencies = check_positive_sequence("frequencies", frequencies, "Hz")
    cycles = check_int("cycles", cycles, 1)
    ramp_cycles = check_positive("ramp_cycles", ramp_cycles)
    dwell = check_nonneg("dwell", dwell, "s")
    ts = check_positive("ts", ts, "s")
    ts = check_range("ts", ts, 0.0, 0.1, "s")

    segs: list[Segment] = []
    for f in frequencies:
        for amp in amplitudes:
            length = (cycles + 2.0 * ramp_cycles) / f
            segs.append(windowed_sines((amp,), (f,), (0.0,), length, ramp_cycles / f))
            segs.append(rest(0.0, dwell))
    t, x, v, a = concatenate(segs, ts)
    params = dict(amplitudes=amplitudes, frequencies=frequencies, cycles=cycles,
                  ramp_cycles=ramp_cycles, dwell=dwell, ts=ts)
    return Reference(t, x, v, a, name="reversal_sine", params=params)

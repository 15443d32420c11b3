"""The loop ticks at which a PC logger's readings of a drive were latched.

A PC logger polls a drive and stamps each row with its own clock when the row is read; a value
the drive computes in its loop (the reference above all) is the one of the drive's last loop
tick, latched up to a loop period before the stamp. On a log slower than the loop, with
stamps that jitter, that age varies from row to row over a whole loop period: interpolated at
its stamps, a reference moving at ``v`` is off by ``v`` times the age (rms ``v T / sqrt 12``
about the half-period delay it adds on average), scatter that a model of the loop follows as
it follows the reference, and that no effect explains. A planned reference has no noise of
its own, so the scatter shows the ticks: each reading's age is measured against a smooth
curve through the readings, and the latch instants (stamp minus age) sit on a lattice
``phase + k T`` of the PC's clock. :func:`tick_lattice` finds that lattice; a column is read
at its ticks (:func:`latched_times`, the last tick at or before each stamp) only where its
readings lie more smoothly on them than on their stamps (:func:`roughness`), so a column
sampled at its stamps, or a log with no such latch, is left as it was.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import make_smoothing_spline
from scipy.signal import zoom_fft

__all__ = ["TickLattice", "tick_lattice", "latched_times", "roughness"]


@dataclass(frozen=True)
class TickLattice:
    """A drive's loop ticks in the logger's clock: ``phase + k period``, s."""

    period: float
    phase: float


def latched_times(t: np.ndarray, lattice: TickLattice) -> np.ndarray:
    """The last tick of ``lattice`` at or before each stamp of ``t``: the instant a reading of
    a value the drive latched at its ticks belongs to."""
    T, ph = lattice.period, lattice.phase
    return ph + T * np.floor((np.asarray(t, dtype=float) - ph) / T)


def roughness(t: np.ndarray, y: np.ndarray) -> float:
    """How far each sample of ``y`` is from the cubic through its two neighbours on each side
    at times ``t`` (sum of squares; inf when ``t`` is not increasing): a smooth signal at its
    true instants leaves its noise and a fourth derivative's share, a reading placed at a wrong
    instant its speed times the error."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.size < 5 or np.any(np.diff(t) <= 0.0):
        return math.inf
    i = np.arange(2, t.size - 2)
    nb = (i - 2, i - 1, i + 1, i + 2)
    x = t[i]
    est = np.zeros(i.size)
    for a in range(4):
        weight = np.ones(i.size)
        for b in range(4):
            if a != b:
                weight *= (x - t[nb[b]]) / (t[nb[a]] - t[nb[b]])
        est += weight * y[nb[a]]
    e = y[i] - est
    return float(np.dot(e, e))


def _spectrum(times: np.ndarray, weights: np.ndarray, f_lo: float, f_hi: float, n_f: int,
              bin_width: float) -> tuple[np.ndarray, np.ndarray]:
    """``|sum w exp(-2 pi i f t)|`` on ``n_f`` frequencies of ``[f_lo, f_hi]``: the times binned
    (phase error at most ``pi f_hi bin_width``), the sum a zoomed DFT of the bins."""
    t0 = float(np.min(times))
    idx = np.floor((times - t0) / bin_width).astype(np.int64)
    hist = np.bincount(idx, weights=weights).astype(float)
    fs = 1.0 / bin_width
    spec = zoom_fft(hist, [f_lo, f_hi], m=n_f, fs=fs, endpoint=True)
    return np.linspace(f_lo, f_hi, n_f), np.abs(spec)


def tick_lattice(t: np.ndarray, y: np.ndarray) -> TickLattice | None:
    """The lattice of loop ticks at which the readings ``y`` (stamped ``t``) were latched, or
    None when the readings show none.

    Each reading's age is its distance below a smoothing spline of the readings (smoothing
    chosen by generalised cross-validation), over the spline's slope: ``a = (s(t) - y) / s'(t)``,
    weighted by ``s'^2`` (a reading at rest tells nothing of its age). The latch instants
    ``t - a`` are then ``k T`` apart: the spans between consecutive ones give the period
    roughly (the strongest line of their spectrum between 2 and 256 ticks per row: a drive
    latches at least twice per row for its age to vary from row to row, and a search bound: a
    25 kHz loop logged at 100 Hz), the instants over the whole run give it finely (their
    spectrum's peak), and period and phase are settled where the readings, each at the
    last tick before its stamp, are the smoothest (:func:`roughness`). Nothing here is a
    decision: the caller keeps the lattice only where it makes a column smoother.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    n = t.size
    if n < 16 or np.any(np.diff(t) <= 0.0) or float(np.ptp(y)) <= 0.0:
        return None
    step = float(np.median(np.diff(t)))
    span = float(t[-1] - t[0])
    try:
        spline = make_smoothing_spline(t, y)
    except (ValueError, np.linalg.LinAlgError):
        return None
    slope = spline.derivative()(t)
    moving = slope != 0.0
    age = np.zeros(n)
    age[moving] = (spline(t[moving]) - y[moving]) / slope[moving]
    w = slope * slope
    latch = t - age
    # coarse: the spans between consecutive latch instants are whole ticks
    d = np.diff(latch)
    wd = np.minimum(w[1:], w[:-1])
    keep = (d > 0.0) & (d < 3.0 * step) & (wd > 0.0)
    if np.count_nonzero(keep) < 8:
        return None
    f_lo, f_hi = 2.0 / step, 256.0 / step
    # frequency spacing a twelfth of a cycle over the longest span kept (3 rows), bins fine
    # enough that the binning turns a phase by at most 1/32 of a cycle at f_hi
    n_f = int(math.ceil((f_hi - f_lo) * 36.0 * step)) + 1
    f, spec = _spectrum(d[keep], wd[keep], f_lo, f_hi, n_f, 1.0 / (32.0 * f_hi))
    f0 = float(f[int(np.argmax(spec))])
    # fine: one lattice over the whole run, searched over the coarse line's main lobe (half a
    # cycle per row off it: +-1/(2 step)) at a quarter of a cycle over the run
    good = w > 0.0
    lo, hi = max(f0 - 0.5 / step, 0.5 * f0), f0 + 0.5 / step
    n_fine = int(math.ceil((hi - lo) * 4.0 * span)) + 1
    # bins of 1/16 tick (the binning turns a phase by at most 1/32 of a cycle); a memory
    # budget of 2^22 bins (262144 ticks: 131 s of a 2 kHz loop) beyond which the run is left
    # at its stamps
    lgood = latch[good]
    if (float(np.ptp(lgood)) + 3.0 * step) * 16.0 * hi > 2.0**22:
        return None
    f, spec = _spectrum(lgood, w[good], lo, hi, n_fine, 1.0 / (16.0 * hi))
    period = 1.0 / float(f[int(np.argmax(spec))])
    # the period to within a drift of 1/8 tick over the run; a reading's latch instant is
    # only estimated (the spline's own lag varies with the motion), so period and phase are
    # settled on what matters, the smoothness of the readings at their ticks: periods drifting
    # by up to 1/8 tick over the run in steps of 1/64, phases on a grid of 64 about the run's
    # middle (where a period's error moves no tick)
    mid = 0.5 * (t[0] + t[-1])
    best = (math.inf, period, 0.0)
    for drift in np.arange(-8, 9) / 64.0:
        per = period * (1.0 + drift * period / span)
        for p in mid + per * np.arange(64) / 64.0:
            r = roughness(latched_times(t, TickLattice(per, p)), y)
            if r < best[0]:
                best = (r, per, p)
    rough, period, phase = best
    # a pattern search from there: period (as drift over the run) and phase in steps halved
    # until a 4096th of a tick, the readings' smoothness deciding each move
    dd, dp = 1.0 / 64.0, period / 64.0
    while dd >= 1.0 / 4096.0:
        moved = False
        for i in (-1, 0, 1):
            for j in (-1, 0, 1):
                if i == 0 and j == 0:
                    continue
                per = period * (1.0 + i * dd * period / span)
                p = phase + j * dp
                r = roughness(latched_times(t, TickLattice(per, p)), y)
                if r < rough:
                    rough, cand = r, (per, p)
                    moved = True
        if moved:
            period, phase = cand
        else:
            dd, dp = 0.5 * dd, 0.5 * dp
    if not math.isfinite(rough):
        return None
    return TickLattice(period=period, phase=float(np.mod(phase, period)))

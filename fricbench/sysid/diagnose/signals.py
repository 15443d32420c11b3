"""Signal processing of the diagnosis: filtered derivatives, parallel decimation, the noise
floor, held-out folds and the search for spatial periods.

Derivatives follow the IDIM-LS recipe of Gautier and Janot (used for the EMPS reference
results): positions pass a zero-phase Butterworth low-pass filter, velocity and acceleration are
central differences of the filtered position, and every column of the regression (and the
effort) is then decimated *in parallel* with the same anti-aliasing filter, so that the
filtering does not bias a model that is linear in its parameters.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, signal

from fricbench.sysid.diagnose.settings import DiagnoseSettings, defaults

__all__ = ["filtered_derivatives", "decimate_columns", "NoiseFloor", "noise_floor",
           "SensorLine", "sensor_lines", "disturbance_warning", "rest_segments", "mains_visible",
           "remove_lines",
           "block_folds", "fold_blocks", "period_candidates",
           "choose_filter", "Saturation", "detect_saturation"]


def filtered_derivatives(x: np.ndarray, ts: float, cutoff_hz: float,
                         order: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zero-phase low-pass ``x`` and differentiate it twice.

    Parameters
    ----------
    x : ndarray, shape (K,)
        Position, m.
    ts : float
        Sample time, s.
    cutoff_hz : float
        Butterworth cut-off frequency, Hz (below the Nyquist frequency ``0.5 / ts``).
    order : int
        Butterworth order (applied forward and backward: twice the order in magnitude).

    Returns
    -------
    xf, v, a : ndarray, shape (K,)
        Filtered position (m), velocity (m/s) and acceleration (m/s^2) by central differences.
    """
    nyq = 0.5 / ts
    if not 0.0 < cutoff_hz < nyq:
        raise ValueError(f"cutoff_hz={cutoff_hz!r}: expected a value in (0, {nyq:g}) Hz")
    b, a = signal.butter(order, cutoff_hz / nyq)
    xf = signal.filtfilt(b, a, x, padlen=min(3 * max(len(a), len(b)), x.shape[0] - 1))
    v = np.gradient(xf, ts)
    acc = np.gradient(v, ts)
    return xf, v, acc


def decimate_columns(cols: np.ndarray, factor: int) -> np.ndarray:
    """Low-pass (zero-phase FIR) and keep every ``factor``-th row of each column.

    Parameters
    ----------
    cols : ndarray, shape (K,) or (K, P)
        Columns sampled at the original rate.
    factor : int
        Decimation factor (1: unchanged).

    Returns
    -------
    ndarray, shape (ceil(K / factor),) or (ceil(K / factor), P)
    """
    if factor <= 1:
        return np.asarray(cols, dtype=float)
    return signal.decimate(np.asarray(cols, dtype=float), factor, ftype="fir", axis=0)


class NoiseFloor:
    """Measurement noise, quantisation and periodic disturbances of a position signal.

    Attributes
    ----------
    sigma : float
        Standard deviation of the white part, m (from third differences).
    quantum : float
        Detected quantisation step, m (0 when the values are not on a grid).
    lines : tuple of SensorLine
        Periodic components of the measurement that are no motion (mains hum,
        :func:`sensor_lines`); empty when none was found.
    sensor_rms : float
        The sensor's own floor: ``max(sigma, quantum / sqrt(12))``, m; never zero (see
        :func:`noise_floor` for the fallbacks).
    disturbance_rms : float
        Rms of the lines, ``sqrt(sum(amplitude**2) / 2)``, m (0 without lines).
    rms : float
        The floor a free-run prediction cannot beat: the sensor's floor and the lines' power
        added, ``sqrt(sensor_rms**2 + disturbance_rms**2)``, m.
    source : str
        Where the floor comes from: ``"quantum"`` (detected), ``"stated quantum"``,
        ``"noise"`` (third differences), or a fallback (``"noise, non-robust"``,
        ``"resolution of the values"``).
    """

    def __init__(self, sigma: float, quantum: float, source: str = "noise",
                 lines: tuple[SensorLine, ...] = ()) -> None:
        self.sigma = float(sigma)
        self.quantum = float(quantum)
        self.source = source
        self.lines = tuple(lines)
        self.sensor_rms = float(max(self.sigma, self.quantum / np.sqrt(12.0)))
        self.disturbance_rms = float(np.sqrt(sum(ln.variance for ln in self.lines)))
        self.rms = float(np.hypot(self.sensor_rms, self.disturbance_rms))

    def with_lines(self, lines: tuple[SensorLine, ...] | list[SensorLine]) -> NoiseFloor:
        """The same sensor floor with ``lines`` as its periodic disturbances."""
        return NoiseFloor(self.sigma, self.quantum, self.source, tuple(lines))

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form (``sensor_disturbance_rms_m`` only when lines were found)."""
        out: dict[str, object] = {"sigma_m": self.sigma, "quantum_m": self.quantum,
                                  "rms_m": self.rms, "source": self.source}
        if self.lines:
            out["sensor_rms_m"] = self.sensor_rms
            out["sensor_disturbance_rms_m"] = self.disturbance_rms
        return out


@dataclass(frozen=True)
class SensorLine:
    """A periodic component of the measurement that is no motion of the axis (mains hum).

    Attributes
    ----------
    frequency_hz : float
        Its frequency, Hz (refined by least squares).
    amplitude : float
        Amplitude of the least-squares sinusoid at that frequency, in the signal's SI unit.
    harmonic : int
        Which harmonic of ``mains_hz`` it is (1: the fundamental).
    mains_hz : float
        The mains fundamental it belongs to, Hz.
    ratio : float
        Its periodogram ordinate over the median of its local band (the detection's statistic).
    where : str
        Where it was found: ``"rests"``, ``"residual"`` or ``"rests and residual"``.
    """

    frequency_hz: float
    amplitude: float
    harmonic: int
    mains_hz: float
    ratio: float
    where: str

    @property
    def variance(self) -> float:
        """Its power, ``amplitude**2 / 2``."""
        return 0.5 * self.amplitude**2

    def to_dict(self, to_si: float = 1.0, unit: str = "m") -> dict[str, object]:
        """JSON-ready form: the amplitude in SI (``amplitude_m``) and in the log's own unit
        ``unit`` (``to_si`` SI units each)."""
        return {"frequency_hz": self.frequency_hz, "amplitude": self.amplitude / to_si,
                "unit": unit, "amplitude_m": self.amplitude, "harmonic": self.harmonic,
                "mains_hz": self.mains_hz, "where": self.where,
                "ratio_to_local_level": self.ratio}


def disturbance_warning(lines: Sequence[SensorLine], unit: str = "m", to_si: float = 1.0
                        ) -> str:
    """The warning of a sensor disturbance (both loops' reports), amplitudes in the log's
    ``unit`` (``to_si`` SI units each)."""
    each = ", ".join(f"{ln.frequency_hz:.4g} Hz ({ln.amplitude / to_si:.3g} {unit} amplitude, "
                     f"in the {ln.where})" for ln in lines)
    rms = math.sqrt(sum(ln.variance for ln in lines)) / to_si
    return (f"sensor disturbance: the measured position carries lines of the "
            f"{lines[0].mains_hz:g} Hz mains ({each}): hum on the position sensor, no motion of "
            f"the axis and no resonance; their power ({rms:.3g} {unit} rms) joins the noise "
            "floor")


def _quantum(x: np.ndarray) -> float:
    """Encoder step of ``x`` (m), or 0 when the values do not lie on a grid.

    The smallest step between samples that occurs repeatedly (within 2 %, so that the steps of
    a rounded export, 3.51 and 3.52, count as one) is a first guess; the step and the offset of
    the grid ``x = x0 + n q`` are then fitted by least squares to the distinct values, so that
    the rounding of single steps averages out. The values must lie on that grid within
    ``settings.quantum_grid_tolerance``.
    """
    d = np.abs(np.diff(x))
    scale = max(float(np.max(np.abs(x))), 1e-12)
    d = np.sort(d[d > 1e-9 * scale])
    if d.size < 20:
        return 0.0
    # the smallest step that occurs repeatedly
    q = 0.0
    for cand in d[: min(d.size, 200)]:
        if np.count_nonzero(np.abs(d[:2000] - cand) <= 0.02 * cand) >= 5:
            q = float(cand)
            break
    if q <= 0.0:
        return 0.0
    # the mean of the steps around it: a rounded export's 3.5, 3.6 and 3.7 for a 3.601 step
    q = float(np.mean(d[np.abs(d - q) <= 0.05 * q][:2000]))
    levels = np.unique(x)
    if levels.size < 3:
        return q
    # levels = x0 + n q: slope and intercept by least squares over the distinct values, over
    # a span of levels widened 8-fold at a time, so that the step known to a few per cent from
    # single steps numbers no level wrong when the values span thousands of steps
    span = 8.0
    while True:
        sel = levels[levels <= levels[0] + span * q]
        n = np.round((sel - sel[0]) / q)
        if np.ptp(n) <= 0:
            return 0.0
        q_new, x0 = np.polyfit(n, sel, 1)
        if not (np.isfinite(q_new) and q_new > 0.0):
            return 0.0
        q = float(q_new)
        if sel.size == levels.size:
            break
        span *= 8.0
    for _ in range(2):
        n = np.round((levels - levels[0]) / q)
        q_new, x0 = np.polyfit(n, levels, 1)
        if not (np.isfinite(q_new) and q_new > 0.0):
            return 0.0
        q = float(q_new)
    frac = (x - x0) / q
    frac = frac - np.round(frac)
    return q if float(np.percentile(np.abs(frac), 99)) < defaults().quantum_grid_tolerance else 0.0


def noise_floor(x: np.ndarray, x_ref: np.ndarray, quantum: float | None = None) -> NoiseFloor:
    """Estimate the measurement noise and quantisation of ``x``.

    The third difference of the tracking error ``x - x_ref`` removes the smooth motion; for
    white noise its variance is ``20 sigma^2``. A robust scale (median absolute deviation)
    ignores the short transients at starts and reversals. The sensor step is detected by
    :func:`_quantum` (rounded exports tolerated) unless ``quantum`` states it.

    The floor is never zero. When the values are on no grid and the median absolute deviation
    is 0 (a coarse sensor at rest most of the time, or the reference equal to the measurement
    at most samples), ``sigma`` falls back to the rms of the third difference (non-robust);
    when that is 0 too, to the resolution of the values: the smallest nonzero difference
    between two distinct values over ``sqrt(12)``, or ``1e-9`` of their magnitude.

    Parameters
    ----------
    x, x_ref : ndarray, shape (K,)
        Measured and reference position, m.
    quantum : float, optional
        The sensor's step, m, when known (``fricbench diagnose --quantum``); > 0.

    Returns
    -------
    NoiseFloor

    Raises
    ------
    ValueError
        ``quantum`` not a positive finite number.
    """
    xx = np.asarray(x, dtype=float)
    e = xx - np.asarray(x_ref, dtype=float)
    d3 = np.diff(e, 3)
    mad = float(np.median(np.abs(d3 - np.median(d3)))) if d3.size else 0.0
    sigma = 1.4826 * mad / np.sqrt(20.0)
    source = "noise"
    if quantum is not None:
        if not (np.isfinite(quantum) and quantum > 0.0):
            raise ValueError(f"quantum={quantum!r}: expected a positive sensor step, m")
        q, q_source = float(quantum), "stated quantum"
    else:
        q, q_source = _quantum(xx), "quantum"
    if q / np.sqrt(12.0) >= sigma and q > 0.0:
        source = q_source
    if sigma <= 0.0 and q <= 0.0:
        sigma = float(np.sqrt(np.mean(d3**2)) / np.sqrt(20.0)) if d3.size else 0.0
        source = "noise, non-robust"
        if not sigma > 0.0:
            levels = np.unique(xx)
            steps = np.diff(levels)
            steps = steps[steps > 0.0]
            res = float(np.min(steps)) if steps.size else 0.0
            sigma = max(res / np.sqrt(12.0), 1e-9 * float(np.max(np.abs(xx), initial=0.0)),
                        1e-300)
            source = "resolution of the values"
    return NoiseFloor(sigma, q, source)


def rest_segments(x_ref: np.ndarray, ts: float,
                  settings: DiagnoseSettings | None = None) -> list[tuple[int, int]]:
    """Sample ranges ``(start, stop)`` where the reference is still, each after its transient.

    A rest is a run of samples whose reference does not change (within ``1e-12`` of its
    magnitude: an exported reference repeats its value). Its first ``settings.rest_settle_share``
    is the axis settling and is left out; what remains must hold
    ``settings.sensor_line_min_periods`` periods of the lowest mains fundamental.
    """
    st = defaults() if settings is None else settings
    xr = np.asarray(x_ref, dtype=float)
    if xr.size < 4:
        return []
    scale = max(float(np.max(np.abs(xr))), 1e-300)
    still = np.abs(np.diff(xr)) <= 1e-12 * scale
    at = np.zeros(xr.size, dtype=bool)
    at[1:] |= still
    at[:-1] |= still
    edges = np.flatnonzero(np.diff(np.r_[0, at.astype(np.int8), 0]))
    min_len = st.sensor_line_min_periods / (min(st.mains_hz) * ts)
    out = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        a = int(a + np.ceil(st.rest_settle_share * (b - a)))
        if b - a >= max(min_len, 8):
            out.append((a, int(b)))
    return out


def mains_visible(ts: float, settings: DiagnoseSettings | None = None) -> bool:
    """Whether a log sampled every ``ts`` s can show the lowest mains fundamental below its
    Nyquist frequency (with the local band the test compares it with)."""
    st = defaults() if settings is None else settings
    f0 = min(st.mains_hz)
    return f0 * (1.0 + st.mains_tolerance) + 0.5 * f0 < 0.5 / ts


class _Segments:
    """Sample ranges of a signal, each with the orthonormal basis of a quadratic in time over
    it (so that a segment's offset and settling can be removed from any column)."""

    def __init__(self, segments: list[tuple[int, int]], n: int) -> None:
        self.ranges = segments
        self.n = n
        self.bases = []
        for a, b in segments:
            u = np.linspace(-1.0, 1.0, b - a)
            self.bases.append(np.linalg.qr(np.column_stack([np.ones_like(u), u, u * u]))[0])
        self.used = np.zeros(n, dtype=bool)
        for a, b in segments:
            self.used[a:b] = True

    def detrend(self, cols: np.ndarray) -> np.ndarray:
        """``cols`` (K,) or (K, P) less each segment's quadratic, zero outside the segments."""
        out = np.zeros((self.n,) + cols.shape[1:])
        for (a, b), q in zip(self.ranges, self.bases, strict=True):
            seg = cols[a:b]
            out[a:b] = seg - q @ (q.T @ seg)
        return out

    def fit(self, d: np.ndarray, freqs: list[float], t: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
        """Least-squares sinusoids at ``freqs`` in the detrended signal ``d``, each segment's
        quadratic fitted with them (the columns detrended the same way). Returns their
        amplitudes and each one's fitted signal (a column per frequency, zero outside the
        segments)."""
        ph = 2.0 * np.pi * np.outer(t, np.asarray(freqs, dtype=float))
        k = len(freqs)
        cols = self.detrend(np.column_stack([np.sin(ph), np.cos(ph)]))
        coef, *_ = np.linalg.lstsq(cols[self.used], d[self.used], rcond=None)
        parts = cols[:, :k] * coef[:k] + cols[:, k:] * coef[k:]
        return np.hypot(coef[:k], coef[k:]), parts


def sensor_lines(s: np.ndarray, ts: float, segments: list[tuple[int, int]], where: str,
                 settings: DiagnoseSettings | None = None,
                 floor: float = 0.0) -> list[SensorLine]:
    """Lines of the mains (50/60 Hz and harmonics) in the signal ``s`` over ``segments``.

    ``s`` is a measurement with the motion left out: the position in the rests of the
    reference (:func:`rest_segments`), or a free-run residual (one segment, the whole run).
    Each segment loses a quadratic in time (its offset and settling); the segments keep their
    place in time, so that a line keeps its phase across them (the mains' is continuous).

    For every harmonic ``h f0`` of ``settings.mains_hz`` up to ``settings.mains_max_harmonic``
    and below the Nyquist frequency (less half a fundamental, the local band's width):

    1. the candidate is the highest ordinate of the zero-padded (4-fold) periodogram within
       ``settings.mains_tolerance`` of ``h f0`` (plus a grid step), its frequency refined by a
       parabola through the log ordinates around it;
    2. every candidate's sinusoid is fitted (jointly, by least squares) and removed; the local
       level of a candidate is the median ordinate of what remains over its band (half a
       fundamental on either side, wider when the segments hold too few independent ordinates
       in it: ``settings.sensor_line_band_bins``), so that neither a line nor its leakage
       through the gaps between the rests raises it;
    3. a candidate is a line when its ordinate, every other candidate removed, stands at least
       ``settings.sensor_line_ratio`` times above its local level, and its amplitude reaches
       the sensor's own floor ``floor``. A line below that floor adds less than half the
       sensor's variance to it, carries at most a third of a residual that holds the
       sensor's noise (so is never what a residual is named after), and on a digital encoder
       is motion rather than the sensor's (EMPS's residual has a 100 Hz line of a quarter of
       its encoder's step: a drive's ripple moves the axis; an encoder's count has no hum).

    Each fundamental is searched on its own (its harmonics a fundamental apart can be fitted
    together; 240 and 250 Hz may not); the lines' amplitudes are then fitted jointly by least
    squares, and one grid feeds a site: only the fundamental whose lines carry the more power
    is kept. A log whose Nyquist
    frequency is at or below a harmonic cannot see it (a 100 Hz log cannot see 50 Hz: what
    aliases there is not told from motion): see :func:`mains_visible`.

    Parameters
    ----------
    s : ndarray, shape (K,)
        The signal (SI unit).
    ts : float
        Sample time, s.
    segments : list of (int, int)
        Sample ranges searched.
    where : str
        What ``s`` is, recorded in each line (``"rests"``, ``"residual"``).
    settings : DiagnoseSettings, optional
    floor : float
        The sensor's own floor (:attr:`NoiseFloor.sensor_rms`), SI: a line's amplitude must
        reach it (0: any line that stands out counts).

    Returns
    -------
    list of SensorLine
        Sorted by frequency; empty when no line stands out, or the segments are too short.
    """
    st = defaults() if settings is None else settings
    s = np.asarray(s, dtype=float)
    n = s.size
    segments = [(int(a), int(b)) for a, b in segments if b - a >= 8 and b <= n]
    if not segments or not np.all(np.isfinite(s)):
        return []
    nyq = 0.5 / ts
    t = np.arange(n) * ts
    segs = _Segments(segments, n)
    d = segs.detrend(s)
    used = sum(b - a for a, b in segments)
    scale = max(float(np.max(np.abs(s[segments[0][0]:segments[-1][1]]))), 1e-300)
    # a still sensor (every segment constant up to rounding) has no spectrum to test
    if not float(np.sqrt(np.sum(d * d) / used)) > 1e-12 * scale:
        return []
    span = segments[-1][1] - segments[0][0]
    nfft = 1 << int(np.ceil(np.log2(4 * max(span, 16))))
    lo = segments[0][0]
    grid = np.fft.rfftfreq(nfft, ts)
    step = float(grid[1])
    power = np.abs(np.fft.rfft(d[lo:], nfft)) ** 2

    def ordinate(sig: np.ndarray, f: float) -> float:
        return float(np.abs(np.dot(sig, np.exp(-2j * np.pi * f * t))) ** 2)

    best: list[SensorLine] = []
    for f0 in st.mains_hz:
        # each grid on its own: harmonics of one fundamental lie a fundamental apart, those
        # of two (250 and 240 Hz) may be too close to fit together
        cands: list[tuple[float, int]] = []  # (frequency, harmonic)
        for h in range(1, st.mains_max_harmonic + 1):
            fh = h * f0
            half = st.mains_tolerance * fh + step
            if fh + half + 0.5 * f0 >= nyq:
                break
            win = np.flatnonzero(np.abs(grid - fh) <= half)
            if win.size == 0:
                continue
            k = int(win[np.argmax(power[win])])
            f_best = float(grid[k])
            if 0 < k < power.size - 1 and np.all(power[k - 1:k + 2] > 0.0):
                # the peak between the grid's points: a parabola through the log ordinates
                # (exact for a Gaussian-shaped peak, within a few % of a step otherwise)
                y0, y1, y2 = np.log(power[k - 1:k + 2])
                den = y0 - 2.0 * y1 + y2
                if den < 0.0:
                    f_best += step * float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5))
            cands.append((f_best, h))
        if not cands:
            continue
        _, parts = segs.fit(d, [c[0] for c in cands], t)
        clean = d - np.sum(parts, axis=1)
        clean_power = np.abs(np.fft.rfft(clean[lo:], nfft)) ** 2
        # the band holds at least settings.sensor_line_band_bins independent ordinates (1 / T
        # apart, T the time the segments hold): a short log's band is wider than the fundamental
        half_band = max(0.5 * f0, 0.5 * st.sensor_line_band_bins / (used * ts))
        found: list[tuple[float, int, float]] = []
        for i, (f, h) in enumerate(cands):
            band = (np.abs(grid - h * f0) <= half_band) & (grid > 0.0) & (grid < nyq)
            level = float(np.median(clean_power[band])) if np.any(band) else 0.0
            # the candidate's ordinate with every other candidate removed: the leakage of a
            # strong line through the gaps between the rests is no line of its own
            ratio = ordinate(clean + parts[:, i], f) / level if level > 0.0 else 0.0
            if ratio >= st.sensor_line_ratio:
                found.append((f, h, ratio))
        if not found:
            continue
        amps, _ = segs.fit(d, [f for f, *_ in found], t)
        lines = [SensorLine(float(f), float(a), int(h), float(f0), float(r), where)
                 for (f, h, r), a in zip(found, amps, strict=True) if a >= floor]
        # one grid feeds a site: the fundamental whose lines carry the more power
        if sum(ln.variance for ln in lines) > sum(ln.variance for ln in best):
            best = lines
    return sorted(best, key=lambda ln: ln.frequency_hz)


def remove_lines(r: np.ndarray, ts: float, freqs: list[float]) -> np.ndarray:
    """``r`` less its least-squares sinusoids at ``freqs`` (with a quadratic in time beside
    them, which stays in)."""
    r = np.asarray(r, dtype=float)
    if not freqs or r.size < 8:
        return r
    segs = _Segments([(0, r.size)], r.size)
    _, parts = segs.fit(segs.detrend(r), list(freqs), np.arange(r.size) * ts)
    return r - np.sum(parts, axis=1)


def choose_filter(x: np.ndarray, ts: float, noise: NoiseFloor) -> tuple[float, int, str]:
    """Derivative filter cut-off (Hz) and decimation chosen from the sensor and the motion.

    The IDIM-LS recipe of the EMPS reference (a cut-off at a tenth of the sampling rate,
    decimation by 10) assumes a fine sensor. A coarse one (a potentiometer on a 10-bit ADC, a
    low-count encoder) is differentiated twice into noise with that filter. The resolution
    ``res = sqrt(12) * noise.sensor_rms`` (the quantum, or the white noise's equivalent; a hum's
    lines are no resolution) against the
    mean speed ``v`` of the measured motion (its path length through a play of one
    resolution, which ignores dithering by a step at rest, over the duration) gives the
    cut-off ``v / (settings.steps_per_filter_period * res)`` when that is lower than the
    recipe's; the decimation keeps the decimated Nyquist frequency near the cut-off
    (``fs / fc``), with at least 400 decimated rows and never less than the recipe's 10.

    Parameters
    ----------
    x : ndarray, shape (K,)
        Measured position (m or rad).
    ts : float
        Sample time, s.
    noise : NoiseFloor
        The position's noise floor (:func:`noise_floor`).

    Returns
    -------
    cutoff_hz : float
    decim : int
    source : str
        ``"default"`` (the recipe) or ``"sensor resolution"``.
    """
    fs = 1.0 / ts
    n = int(x.shape[0])
    fc_recipe, decim_recipe = 0.1 * fs, 10
    res = float(np.sqrt(12.0) * noise.sensor_rms)
    duration = n * ts
    if not (res > 0.0 and n > 10 and duration > 0.0):
        return fc_recipe, decim_recipe, "default"
    # path length through a play operator one resolution wide: a step back and forth at rest
    # does not count as motion
    y = float(x[0])
    path = 0.0
    half = 0.5 * res
    for xk in np.asarray(x, dtype=float)[:: max(1, n // 20000)]:
        if xk > y + half:
            path += xk - half - y
            y = xk - half
        elif xk < y - half:
            path += y - (xk + half)
            y = xk + half
    v_mean = path / duration
    fc = v_mean / (defaults().steps_per_filter_period * res)
    fc_min = max(5.0 / duration, 0.002 * fs)
    if not np.isfinite(fc) or fc >= fc_recipe or v_mean <= 0.0:
        return fc_recipe, decim_recipe, "default"
    fc = max(fc, fc_min)
    decim = int(max(decim_recipe, min(round(fs / fc), n // 400)))
    return float(fc), decim, "sensor resolution"


@dataclass(frozen=True)
class Saturation:
    """Where the logged effort sits at the drive's limit.

    Attributes
    ----------
    high, low : float or None
        Clip levels detected on each side (None: that side never clips).
    level : float
        The symmetric limit given to the simulated actuator: the larger detected magnitude.
    mask : ndarray of bool
        Samples at a clip level.
    """

    high: float | None
    low: float | None
    level: float
    mask: np.ndarray = field(repr=False)

    @property
    def share(self) -> float:
        """Fraction of the samples at a clip level."""
        return float(np.mean(self.mask))

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form (levels in the effort's unit)."""
        out: dict[str, object] = {"level": self.level, "samples": int(np.count_nonzero(
            self.mask)), "share_pct": 100.0 * self.share}
        if self.high is not None:
            out["high"] = self.high
        if self.low is not None:
            out["low"] = self.low
        return out


def _clip_side(u: np.ndarray, top: float, tol: float, sign: float) -> np.ndarray | None:
    """Mask of samples at ``top`` when the effort piles up there (a clip), else None.

    A clipped signal piles samples onto one level; the peak of an unclipped (even coarsely
    quantised) signal visits its top level about as often as the level below it. Where the
    values near the top repeat anyway (a rounded or coarse log: the level below the top is
    visited more than once), equal peaks are what rounding makes of a repeated move's crest,
    each touched once: there a clip must also hold its level, a plateau of two samples in a
    row at least. Where they do not repeat, three samples on one value are a clip.
    """
    at = sign * (u - top) >= -tol
    n_top = int(np.count_nonzero(at))
    if n_top < 3:
        return None
    below = u[~at]
    if below.size == 0:
        return None
    nxt = below[np.argmax(sign * below)]
    n_next = int(np.count_nonzero(np.abs(u - nxt) <= tol))
    if n_next > 1 and not np.any(at[1:] & at[:-1]):
        return None
    return at if n_top > 2 * n_next else None


def detect_saturation(u: np.ndarray) -> Saturation | None:
    """The clip level of an effort that saturates (a current or force command at its limit).

    Parameters
    ----------
    u : ndarray, shape (K,)
        Logged effort.

    Returns
    -------
    Saturation or None
        None when neither extreme is a clip level.
    """
    u = np.asarray(u, dtype=float)
    scale = float(np.max(np.abs(u), initial=0.0))
    if not scale > 0.0:
        return None
    # a clip writes one and the same value: only (nearly) bit-equal samples are at it
    tol = 1e-12 * scale
    hi_mask = _clip_side(u, float(np.max(u)), tol, 1.0) if np.max(u) > 0 else None
    lo_mask = _clip_side(u, float(np.min(u)), tol, -1.0) if np.min(u) < 0 else None
    if hi_mask is None and lo_mask is None:
        return None
    mask = np.zeros(u.shape[0], dtype=bool)
    levels = []
    high = low = None
    if hi_mask is not None:
        mask |= hi_mask
        high = float(np.max(u))
        levels.append(abs(high))
    if lo_mask is not None:
        mask |= lo_mask
        low = float(np.min(u))
        levels.append(abs(low))
    return Saturation(high, low, max(levels), mask)


def block_folds(n: int, n_blocks: int = 20, n_folds: int = 2) -> np.ndarray:
    """Fold label of each sample: contiguous time blocks assigned to folds in turn.

    Contiguous blocks keep the autocorrelated residual of one block out of the other fold;
    interleaving them (block ``i`` goes to fold ``i % n_folds``) lets every fold see every part
    of the run (both directions of motion, all speeds).

    Parameters
    ----------
    n : int
        Number of samples.
    n_blocks : int
        Number of blocks.
    n_folds : int
        Number of folds.

    Returns
    -------
    ndarray of int, shape (n,)
    """
    n_blocks = max(n_folds, min(n_blocks, n // 50))
    block = (np.arange(n) * n_blocks) // n
    return (block % n_folds).astype(np.int64)


def fold_blocks(folds: np.ndarray) -> list[tuple[int, int]]:
    """The held-out blocks of :func:`block_folds` labels as sample ranges ``(start, stop)``:
    the contiguous runs of one fold, fold 0's first, each fold's in time order (the order in
    which the diagnosis judges its two fold fits)."""
    edges = np.flatnonzero(np.diff(folds)) + 1
    ranges = list(zip(np.r_[0, edges].tolist(), np.r_[edges, folds.size].tolist(),
                      strict=True))
    return [r for k in (0, 1) for r in ranges if folds[r[0]] == k]


def period_candidates(x: np.ndarray, r: np.ndarray, moving: np.ndarray, p_min: float,
                      p_max: float, n_best: int = 3) -> list[float]:
    """Spatial periods (m) at which the residual ``r`` varies with the position ``x``.

    The residual of the moving samples is averaged in position bins a quarter of ``p_min``
    wide; the periodogram of that position series (zero-padded FFT) gives the periods of the
    ``n_best`` highest separated peaks between ``p_min`` and ``p_max``, each refined
    continuously between the FFT's grid points, then by a least-squares sinusoid beside a line
    within one spectral resolution (:func:`_refine_ls`: the peak of a stroke holding few periods
    is biased by a slope of the residual). The fits then refine them further.
    """
    xs, rs = x[moving], r[moving]
    if xs.size < 50 or p_max <= p_min:
        return []
    width = 0.25 * p_min
    lo = float(np.min(xs))
    n_bins = int(np.ceil((float(np.max(xs)) - lo) / width)) + 1
    if n_bins < 8:
        return []
    idx = np.minimum(((xs - lo) / width).astype(np.int64), n_bins - 1)
    sums = np.bincount(idx, weights=rs - rs.mean(), minlength=n_bins)
    counts = np.bincount(idx, minlength=n_bins)
    series = np.where(counts > 0, sums / np.maximum(counts, 1), 0.0)
    n_fft = 1 << int(np.ceil(np.log2(8 * n_bins)))
    power = np.abs(np.fft.rfft(series, n_fft)) ** 2
    freqs = np.fft.rfftfreq(n_fft, width)  # cycles per metre
    band = (freqs >= 1.0 / p_max) & (freqs <= 1.0 / p_min)
    if not np.any(band):
        return []
    cand = np.flatnonzero(band)
    # local maxima only
    peaks = [i for i in cand if 0 < i < power.size - 1 and power[i] >= power[i - 1]
             and power[i] >= power[i + 1]]
    peaks.sort(key=lambda i: -power[i])
    picked: list[float] = []
    df = 2.0 / (n_bins * width)
    step = freqs[1] - freqs[0]
    centres = (np.arange(n_bins) + 0.5) * width
    filled = counts > 0
    for i in peaks:
        f = _refine_peak(series, centres, freqs[i], step)
        f = _refine_ls(series[filled], centres[filled], f, 0.5 * df)
        if all(abs(f - 1.0 / p) > df for p in picked):
            picked.append(1.0 / f)
        if len(picked) >= n_best:
            break
    return picked


def _refine_ls(series: np.ndarray, centres: np.ndarray, f0: float, half: float) -> float:
    """Frequency (1/m) within ``half`` of ``f0`` of the sinusoid that, with a straight line,
    explains most of ``series`` by least squares (a grid of 17, then a bounded scalar search
    around its best point).

    The periodogram's peak is biased when the stroke holds few periods and the residual has a
    slope along it (a friction level changing along the stroke): leakage from the line moves
    the peak by up to a resolution (10 to 19 % with 3 to 4 periods and a slope of 5 to 10
    ripple amplitudes over the stroke), beyond the 2 % a fit may move a period. The line in the
    regression takes the slope out, and the sum runs over the filled bins only.
    """
    design0 = np.column_stack([np.ones_like(centres), centres - centres.mean()])

    def unexplained(f: float) -> float:
        ph = 2.0 * np.pi * f * centres
        a = np.column_stack([design0, np.sin(ph), np.cos(ph)])
        coef, *_ = np.linalg.lstsq(a, series, rcond=None)
        return float(np.sum((series - a @ coef) ** 2))

    lo, hi = max(f0 - half, 0.5 * f0), f0 + half
    grid = np.linspace(lo, hi, 17)
    vals = [unexplained(f) for f in grid]
    k = int(np.argmin(vals))
    a_, b_ = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    res = optimize.minimize_scalar(unexplained, bounds=(a_, b_), method="bounded",
                                   options={"xatol": 1e-4 * (hi - lo)})
    return float(res.x) if res.fun <= vals[k] else float(grid[k])


def _refine_peak(series: np.ndarray, centres: np.ndarray, f0: float, step: float) -> float:
    """Frequency (1/m) of the periodogram's maximum within one FFT step of ``f0``.

    The zero-padded FFT samples the periodogram on a grid; between its points the power
    ``|sum_j s_j exp(-2 pi i f c_j)|^2`` is maximised continuously (golden section).
    """
    def neg_power(f: float) -> float:
        return -float(np.abs(np.dot(series, np.exp(-2j * np.pi * f * centres))) ** 2)

    res = optimize.minimize_scalar(neg_power, bounds=(f0 - step, f0 + step), method="bounded",
                                   options={"xatol": 1e-4 * step})
    return float(res.x) if res.fun <= neg_power(f0) else float(f0)


def open_loop_motion(effort: np.ndarray, y: np.ndarray, ts: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The open loop's inverse-dynamics signals: the position and the effort filtered forward
    and backward (4th-order Butterworth at a fifth of the sampling rate, 100 Hz at most), and
    the velocity and acceleration by central differences of the filtered position.

    Returns
    -------
    yf, uf, v, acc : ndarray
    """
    b, a = signal.butter(4, min(100.0, 0.2 / ts) * 2.0 * ts)
    yf = signal.filtfilt(b, a, y)
    uf = signal.filtfilt(b, a, effort)
    v = np.gradient(yf, ts)
    return yf, uf, v, np.gradient(v, ts)

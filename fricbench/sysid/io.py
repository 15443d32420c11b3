"""Loading and validating measured (or simulated) runs from CSV files.

A run file is a CSV with a one-line header and one row per uniformly spaced sample: time (s),
reference position (m), measured position (m) and, optionally, the actuator effort (force in N,
or a current or voltage: any consistent unit). ``fricbench simulate`` writes this format; the
EMPS files of ``data/emps`` use other column names, chosen with the keyword arguments of
:func:`load_run`. Logs as they come are read too: columns chosen by name or by 0-based index,
``,``, ``;`` or tab separators (a decimal comma is refused: numbers must use the C-locale
point), no time column (a given sample time), positions in mm, um, rad or deg (converted to
m or rad on reading, see :mod:`fricbench.units`).

Every problem with the file raises :class:`DataError` with a message that says what is wrong
and where (line and column); problems that still allow an analysis become warnings on the
returned :class:`RunData`. The file is only ever read, line by line and within fixed bounds
(:data:`MAX_FILE_BYTES`, :data:`MAX_ROWS`, :data:`MAX_LINE_BYTES`), so a huge or endless input
is refused early; a pipe (FIFO, ``/dev/stdin``) is read the same way as a file. A quoted cell
must end on its own line.

Times and positions (after conversion to SI: m, or rad for a rotary axis) must be on the
scale of a servo axis (:data:`SAMPLE_TIME_RANGE`,
:data:`POSITION_LIMIT`, :data:`MIN_STROKE`) and the effort within :data:`EFFORT_RANGE`; anything
else is refused before a fit, with the column, the value and the expected range.
"""

from __future__ import annotations

import csv
import math
import os
import re
import stat
from array import array
from collections.abc import Callable, Iterator
from typing import Any, BinaryIO

import numpy as np
from scipy.interpolate import PchipInterpolator

from fricbench.run import Run, validate_run_arrays
from fricbench.run_events import hysteresis_sign, motion_events, sign_reversals
from fricbench.sysid.ticks import latched_times, roughness, tick_lattice
from fricbench.units import position_unit as _position_unit

__all__ = ["DataError", "RunData", "load_run", "validate_arrays", "MIN_SAMPLES",
           "TIME_JITTER_TOLERANCE", "RESAMPLE_MAX_JITTER", "MAX_FILE_BYTES", "MAX_ROWS",
           "MAX_LINE_BYTES",
           "SAMPLE_TIME_RANGE", "POSITION_LIMIT", "MIN_STROKE", "EFFORT_RANGE", "MIN_STARTS",
           "REST_S"]

MIN_SAMPLES = 200
"""Fewest samples a run may have (0.2 s at 1 kHz)."""

TIME_JITTER_TOLERANCE = 0.01
"""Largest relative deviation of a time step from the median step taken as uniform sampling."""

RESAMPLE_MAX_JITTER = 0.5
"""Largest relative deviation of a time step from the median step that is resampled (a PC
logger's timestamps, jittered by its scheduler): a step more than 1.5 times the median, or
less than half of it, is a dropped or a doubled sample, not jitter, and the run is refused."""

MAX_FILE_BYTES = 256 * 2**20
"""Largest run file read, bytes (256 MiB); a larger file is refused before it is opened, a pipe
once that much has been read."""

MAX_ROWS = 1_000_000
"""Most data rows of a run file (1000 s at 1 kHz); reading stops at the next one."""

MAX_LINE_BYTES = 100_000
"""Longest line of a run file, bytes; a longer one is refused without reading it whole."""

SAMPLE_TIME_RANGE = (1e-6, 0.1)
"""Sample times of a servo-axis log, s: 1 MHz to 10 Hz (time in ms or us falls outside)."""

POSITION_LIMIT = 1e3
"""Largest position magnitude, m. No servo axis is longer; files in millimetres up to 1 m pass
(with a warning that they look like millimetres), larger numbers are refused."""

MIN_STROKE = 1e-8
"""Smallest range of motion, m: ten steps of a 1 nm encoder, the finest resolution in use."""

EFFORT_RANGE = (1e-9, 1e12)
"""Range of the largest effort magnitude in any unit (N, A, V, % or DAC counts); an effort
outside it, or constant, is degenerate: refused when required, else dropped with a warning."""

MIN_STARTS = 2
"""Starts from rest that let a run whose reference never reverses show its friction level:
at rest friction holds the axis, where a constant force would push it (one start, at the
edge of a run, is too little to tell)."""

REST_S = 0.01
"""Shortest rest of the reference that counts, s: shorter pauses between moves of one
direction are the motion's own."""

_MM_SUSPECT_RANGE = 2.0  # m: a feed-axis stroke longer than this is more likely in mm
_CONSTANT_REL = 1e-9  # a column varying by less than this share of its magnitude is constant
_DECIMAL_COMMA = re.compile(r"^[-+]?\d+,\d+([eE][-+]?\d+)?$")


class DataError(ValueError):
    """The run file cannot be analysed; the message says why and where."""


RunData = Run
"""The run type the loader returns: :class:`fricbench.run.Run` (kept as a name for old code)."""


# -- helpers ------------------------------------------------------------------------------------
def _effort_problem(u: np.ndarray, name: str | None, where: Callable[[int], str]) -> str | None:
    """Why the effort column ``u`` is degenerate, or None when it is usable."""
    lo, hi = EFFORT_RANGE
    i = int(np.argmax(np.abs(u)))
    peak = abs(float(u[i]))
    if peak > hi:
        return (f"column {name!r}: effort {u[i]:.6g} at {where(i)} is beyond +-{hi:g}, more "
                "than any effort unit (N, A, V, % or DAC counts) reaches")
    # ptp of values below 1e12 cannot overflow
    if float(np.ptp(u)) <= _CONSTANT_REL * peak:
        return (f"column {name!r} is constant ({u[0]:.6g}): it carries no information on the "
                "forces")
    if peak < lo:
        return (f"column {name!r}: the effort never exceeds {peak:.3g} in magnitude, below the "
                f"{lo:g} any effort unit resolves")
    return None


def _latch_instants(t: np.ndarray, columns: dict[str, object | None]
                    ) -> tuple[dict[str, np.ndarray], str]:
    """The instants each position column of a jittered log belongs to, and the words that say
    so (empty when every column stays at its stamps).

    A PC logger reading a drive gets the values the drive latched at its last loop tick: the
    reference, a planned trajectory without noise of its own, shows that lattice of ticks
    (:func:`fricbench.sysid.ticks.tick_lattice`). A column is read at its ticks (the last one at
    or before each stamp) when its readings lie on them more smoothly than on their stamps
    (:func:`fricbench.sysid.ticks.roughness`): the reference first, then each position, which a
    logger may read from the drive (latched) or from the sensor at the stamp. The effort stays
    at its stamps: its own noise leaves no such comparison. Interpolated at the stamps, a
    latched reference is off by its speed times a reading's age, uniform over a loop period:
    scatter the model's loop follows as the drive's never did."""
    times: dict[str, np.ndarray] = {}
    ref = columns.get("x_ref")
    if ref is None:
        return times, ""
    r = np.asarray(ref, dtype=float)
    if r.shape != t.shape or not np.all(np.isfinite(r)):
        return times, ""
    lattice = tick_lattice(t, r)
    if lattice is None:
        return times, ""
    tau = latched_times(t, lattice)
    at_stamps, at_ticks = roughness(t, r), roughness(tau, r)
    if not at_ticks < at_stamps:
        return times, ""
    times["x_ref"] = tau
    moved = ["reference"]
    for key, name in (("x", "position"), ("x_load", "load position")):
        col = columns.get(key)
        if col is None:
            continue
        a = np.asarray(col, dtype=float)
        if a.shape == t.shape and np.all(np.isfinite(a)) and roughness(tau, a) < roughness(t, a):
            times[key] = tau
            moved.append(name)
    kept = [name for key, name in (("x", "position"), ("x_load", "load position"))
            if columns.get(key) is not None and key not in times]
    smoother = at_stamps / at_ticks if at_ticks > 0.0 else math.inf
    note = (f"; the {' and '.join(moved)} as the drive latched {'them' if len(moved) > 1 else 'it'}"
            f" at its loop ticks, a lattice of {1e6 * lattice.period:.4g} us found in the "
            f"reference's readings (on it they lie {smoother:.3g} times more smoothly, in squared "
            "error, than on their stamps): each reading placed at the last tick before its "
            "stamp")
    if kept:
        note += f"; the {' and '.join(kept)} at {'their' if len(kept) > 1 else 'its'} stamps"
    return times, note


def _resample_jitter(t: object, x_ref: object, x: object, u: object | None,
                     x_load: object | None, line_numbers: np.ndarray | None, t_name: str,
                     source: str) -> tuple[Any, Any, Any, Any, Any, np.ndarray | None, str]:
    """Arrays on a uniform grid when the time steps jitter by more than
    :data:`TIME_JITTER_TOLERANCE` and at most :data:`RESAMPLE_MAX_JITTER` of their median:
    interpolation at ``t0 + k ts`` (positions by a monotone cubic, the effort linearly), ``ts``
    the median step, and the warning that says so (empty when nothing was resampled). Anything
    else goes on to the checks unchanged (a larger deviation is refused there, with its
    figure)."""
    tt = np.asarray(t, dtype=float)
    if tt.ndim != 1 or tt.size < 3 or not np.all(np.isfinite(tt)):
        return t, x_ref, x, u, x_load, line_numbers, ""
    dt = np.diff(tt)
    if np.any(dt <= 0.0):
        return t, x_ref, x, u, x_load, line_numbers, ""
    ts = float(np.median(dt))
    dev = float(np.max(np.abs(dt - ts))) / ts
    if not TIME_JITTER_TOLERANCE < dev <= RESAMPLE_MAX_JITTER:
        if dev > RESAMPLE_MAX_JITTER:
            i = int(np.argmax(np.abs(dt - ts)))
            where = (f"line {int(line_numbers[i + 1])}" if line_numbers is not None
                     else f"sample {i + 1}")
            raise DataError(
                f"{source}: column {t_name!r}: irregular sampling beyond what is resampled: the "
                f"step to {where} is {dt[i]:.6g} s against the median {ts:.6g} s "
                f"({100 * dev:.3g} % off; up to {100 * RESAMPLE_MAX_JITTER:g} % is resampled): "
                "a dropped or doubled sample; cut the run there or resample it first")
        return t, x_ref, x, u, x_load, line_numbers, ""
    grid = tt[0] + ts * np.arange(int(np.floor((tt[-1] - tt[0]) / ts + 1e-9)) + 1)
    times, ticks_note = _latch_instants(tt, {"x_ref": x_ref, "x": x, "x_load": x_load})

    def on_grid(a: object | None, key: str | None = None) -> np.ndarray | None:
        if a is None:
            return None
        arr = np.asarray(a, dtype=float)
        if arr.shape != tt.shape:  # the checks name the length mismatch
            return arr
        at = times.get(key, tt) if key else tt
        if key is None or not np.all(np.isfinite(arr)) or not np.all(np.diff(at) > 0.0):
            return np.interp(grid, at, arr)
        # a position between jittered readings: linear interpolation is off by half the
        # acceleration times the offset from one reading times that to the next (at 4 ms
        # steps and 10 % jitter, 0.5 um on a third-simulator run whose noise floor is
        # 0.035 um); a monotone cubic (Fritsch-Carlson, scipy's PCHIP) follows the curvature
        # and, unlike a spline, invents no motion at a rest or past a stop
        return PchipInterpolator(at, arr, extrapolate=True)(grid)

    n_jit = int(np.sum(np.abs(dt - ts) / ts > TIME_JITTER_TOLERANCE))
    why = (f"{source + ': ' if source else ''}column {t_name!r}: the time steps jitter by up to "
           f"{100 * dev:.3g} % of their median {ts:.6g} s ({n_jit} of {dt.size} steps beyond "
           f"{100 * TIME_JITTER_TOLERANCE:g} %): the run was resampled to that step (positions by "
           f"monotone cubic interpolation, the effort linearly; {tt.size} -> {grid.size} "
           f"samples){ticks_note}")
    return (grid, on_grid(x_ref, "x_ref"), on_grid(x, "x"), on_grid(u),
            on_grid(x_load, "x_load"), None, why)


def validate_arrays(t: np.ndarray, x_ref: np.ndarray, x: np.ndarray, u: np.ndarray | None = None,
                    *, source: str = "<arrays>", names: dict[str, str | None] | None = None,
                    line_numbers: np.ndarray | None = None,
                    effort_required: bool = True, position_unit: str = "m",
                    open_loop: bool = False, x_load: np.ndarray | None = None,
                    effort_unit: str | None = None) -> RunData:
    """Check arrays of one run and wrap them in a :class:`RunData`.

    Parameters
    ----------
    t, x_ref, x : array_like, shape (K,)
        Time (s), reference position and measured position, in SI: m, or rad when
        ``position_unit`` is rotary.
    u : array_like, shape (K,), optional
        Effort.
    source : str
        Label used in messages.
    names : dict, optional
        Column names for messages (keys ``t``, ``x_ref``, ``x``, ``u``).
    line_numbers : ndarray of int, optional
        File line of each sample (for messages); samples are numbered from 0 without it.
    effort_required : bool
        A degenerate effort (constant, or its magnitude outside :data:`EFFORT_RANGE`) raises;
        when False it is dropped with a warning and the run has no effort.
    position_unit : str
        The unit the positions were logged in (``m``, ``mm``, ``um``, ``rad``, ``deg``); the
        arrays are already converted to its SI unit. It is recorded in ``RunData.units``
        (``"position"``: the SI unit, ``"position_logged"``: this one); a rotary unit turns off
        the "looks like millimetres" warning.
    open_loop : bool
        An open-loop run without a reference (``x_ref`` is the measured position): the check
        that reference and position differ is skipped.
    x_load : array_like, shape (K,), optional
        A second, load-side position (a linear scale beside the motor encoder ``x``), in the
        same unit as ``x``.
    effort_unit : str, optional
        The effort's unit as the source states it (``"N"``, ``"A"``): recorded as
        ``RunData.units["effort"]`` with ``units["effort_stated"] = "yes"``. None: the unit is
        not known and ``"N"`` is assumed (no ``"effort_stated"``).

    Returns
    -------
    RunData

    Raises
    ------
    DataError
        NaN or inf, time not increasing or irregular, too short, no motion, values off the
        scale of a servo axis (:data:`SAMPLE_TIME_RANGE`, :data:`POSITION_LIMIT`,
        :data:`MIN_STROKE`), the measured position equal to the reference, a degenerate
        effort that is required.
    """
    unit = _position_unit(position_unit)
    si = unit.si
    if names is None:
        names = {"t": "t", "x_ref": "x_ref", "x": "x"}
        if u is not None:
            names["u"] = "u"
    names = dict(names)

    def where(i: int) -> str:
        return f"line {int(line_numbers[i])}" if line_numbers is not None else f"sample {i}"

    units = {"time": "s", "position": si, "position_logged": unit.name,
             "effort": effort_unit or "N"}
    if effort_unit is not None and u is not None:
        units["effort_stated"] = "yes"  # by the source, not assumed
    if x_load is not None:
        names.setdefault("x_load", "x_load")
    t, x_ref, x, u, x_load, line_numbers, resampled = _resample_jitter(
        t, x_ref, x, u, x_load, line_numbers, names["t"] or "t", source)
    clean, ts = validate_run_arrays(
        t, x_ref, x, u, source=source, where=where, min_samples=MIN_SAMPLES,
        labels={key: f"column {name!r}" for key, name in names.items()},
        too_short_why=" (the diagnosis fits a dynamic model and holds part of the run out)",
        max_jitter=TIME_JITTER_TOLERANCE, units=units, error=DataError,
        extra=None if x_load is None else {"x_load": x_load})
    ts_lo, ts_hi = SAMPLE_TIME_RANGE
    if not ts_lo <= ts <= ts_hi:
        raise DataError(f"{source}: column {names['t']!r}: sample time {ts:.6g} s (the median "
                        f"step) is outside [{ts_lo:g}, {ts_hi:g}] s, the sample times of a "
                        "servo-axis log (1 MHz to 10 Hz); is the column in seconds?")
    xr, xm = clean["x_ref"], clean["x"]
    xl = clean.get("x_load")
    for key, arr in (("x_ref", xr), ("x", xm)) + ((("x_load", xl),) if xl is not None else ()):
        i = int(np.argmax(np.abs(arr)))
        if abs(arr[i]) > POSITION_LIMIT:
            raise DataError(f"{source}: {where(i)}, column {names[key]!r}: position {arr[i]:.6g} "
                            f"is outside +-{POSITION_LIMIT:g} {si} (after conversion from "
                            f"{unit.name}), the positions a servo axis can have; is the column "
                            f"in {unit.name} (--position-unit)?")
    warnings: list[str] = [resampled] if resampled else []
    # positions within +-POSITION_LIMIT: spans and differences cannot overflow
    span_ref = float(np.ptp(xr))
    span_x = float(np.ptp(xm))
    if span_ref <= 0.0:
        raise DataError(f"{source}: column {names['x_ref']!r} is constant: a run without motion; "
                        "no analysis is possible (neither the loop dynamics nor any effect "
                        "can be identified)")
    if span_ref < MIN_STROKE:
        raise DataError(f"{source}: column {names['x_ref']!r} moves by {span_ref:.3g} {si}, "
                        f"less than the {MIN_STROKE:g} {si} a diagnosis needs (ten steps of a "
                        f"1 nm encoder): no resolvable motion; is the column in {unit.name} "
                        "(--position-unit)?")
    if span_x <= 0.0:
        raise DataError(f"{source}: column {names['x']!r} is constant while the reference moves "
                        f"by {span_ref:.6g}: the measured position did not follow; check the "
                        "column choice")
    if span_x < MIN_STROKE:
        raise DataError(f"{source}: column {names['x']!r} moves by {span_x:.3g} {si} while "
                        f"the reference moves by {span_ref:.6g} {si}: less than the "
                        f"{MIN_STROKE:g} {si} a diagnosis needs (ten steps of a 1 nm encoder); "
                        "check the column choice and unit")
    peak = max(float(np.max(np.abs(xr))), float(np.max(np.abs(xm))))
    gap = float(np.max(np.abs(xr - xm)))
    if gap <= _CONSTANT_REL * peak and not open_loop:
        raise DataError(f"{source}: the reference {names['x_ref']!r} and the measured position "
                        f"{names['x']!r} are equal at every sample (largest difference "
                        f"{gap:.3g} {si}): there is no tracking error to explain; the reference "
                        "is the commanded position (--reference), the measurement the "
                        "sensor's (--position)")
    uu = clean.get("u")
    if uu is not None:
        problem = _effort_problem(uu, names.get("u"), where)
        if problem is not None and effort_required:
            raise DataError(f"{source}: {problem}; choose another column (--effort) or "
                            "diagnose from the positions only (--no-effort)")
        if problem is not None:
            warnings.append(f"the effort is not used: {problem}; the diagnosis uses the "
                            "positions only")
            uu = None
            names.pop("u", None)
    if not unit.rotary and max(span_ref, span_x, float(np.max(np.abs(xr)))) > _MM_SUSPECT_RANGE:
        warnings.append(
            f"positions span {span_ref:.6g} (reference) and {span_x:.6g} (measured) m: these "
            "look like millimetres or encoder counts, not metres; the reported parameters "
            "assume metres (give --position-unit mm, um, rad or deg if they are not)"
        )
    err_rms = float(np.sqrt(np.mean((xr - xm) ** 2)))
    if err_rms > 0.2 * span_ref:
        warnings.append(
            f"{source}: the measured position (column {names['x']!r}) differs from the "
            f"reference (column {names['x_ref']!r}) by {err_rms / unit.to_si:.4g} {unit.name} "
            f"rms, {100 * err_rms / span_ref:.0f} % of the stroke: are both columns in the "
            "same unit and the right ones? (a step reference leaves such an error after each "
            "step)"
        )
    # a reversal: the reference turns back by more than 0.1 % of its stroke (a hysteresis on
    # the position read at 1 kHz, deaf to noise and dither)
    step = max(1, int(round(1e-3 / ts)))
    n_rev = int(sign_reversals(hysteresis_sign(xr[::step], max(1e-3 * span_ref, 1e-9))).size)
    # a start from a rest of the reference (the rest seen in the run, at least REST_S long):
    # where the axis rests, friction holds it and a constant force would push it
    vr_k = np.gradient(xr[::step], step * ts)
    rest_gap = max(1, int(round(REST_S / (step * ts))))
    n_starts = sum(1 for e in motion_events(vr_k, step * ts,
                                            rest_speed=0.01 * float(np.max(np.abs(vr_k))),
                                            max_gap=rest_gap)
                   if e.kind == "start" and e.index > 0)
    if n_rev == 0 and n_starts >= MIN_STARTS:
        warnings.append(
            "the reference never reverses: direction-dependent effects, friction varying "
            "along the stroke and backlash cannot be separated from a constant force "
            "(asymmetric_friction, position_dependent_friction and backlash are not tried); "
            f"coulomb_friction and stribeck_friction are judged on its {n_starts} starts from "
            "rest, where friction holds the axis and a constant force would not"
        )
    elif n_rev == 0:
        warnings.append(
            "the reference never reverses: friction levels, direction-dependent effects and "
            "backlash cannot be separated from a constant force; coulomb_friction, "
            "stribeck_friction, asymmetric_friction and backlash are not tried"
        )
    if xl is not None and float(np.ptp(xl)) < MIN_STROKE:
        raise DataError(f"{source}: column {names['x_load']!r} (the load position) moves by "
                        f"{float(np.ptp(xl)):.3g} {si}: less than the {MIN_STROKE:g} {si} a "
                        "diagnosis needs; check the column choice (--load-position) and unit")
    return RunData(t=clean["t"], x_ref=xr, x=xm, u=uu, ts=ts, source=source,
                   columns=names, warnings=tuple(warnings), n_reversals=n_rev,
                   n_starts=n_starts, units=units,
                   x_load=xl)


# -- reading ------------------------------------------------------------------------------------
def _lines(fh: BinaryIO, path: str) -> Iterator[tuple[int, str, bool]]:
    """Yield ``(line number, text without line end, complete)`` of a byte stream.

    At most :data:`MAX_LINE_BYTES` of a line are read (``complete`` is False when it is
    longer) and :data:`MAX_FILE_BYTES` in all; NUL bytes and text that is not UTF-8 raise
    :class:`DataError` naming the line.
    """
    total = 0
    line_no = 0
    while True:
        raw = fh.readline(MAX_LINE_BYTES + 1)
        if not raw:
            return
        line_no += 1
        total += len(raw)
        if total > MAX_FILE_BYTES:
            raise DataError(f"{path}: line {line_no}: more than MAX_FILE_BYTES = "
                            f"{MAX_FILE_BYTES} bytes read ({MAX_FILE_BYTES // 2**20} MiB, the "
                            "largest run file read); cut the run into shorter files")
        body = raw.rstrip(b"\r\n")
        complete = len(body) <= MAX_LINE_BYTES
        if line_no == 1 and body.startswith(b"\xef\xbb\xbf"):
            body = body[3:]
        nul = body.find(b"\x00")
        if nul >= 0:
            raise DataError(f"{path}: line {line_no}, byte {nul + 1}: NUL bytes: looks like a "
                            "binary file, expected a text CSV")
        if not complete:  # refused by the caller; decoded only to name the column
            yield line_no, body.decode("utf-8", errors="replace"), False
            return
        try:
            text = body.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise DataError(f"{path}: line {line_no}, byte {exc.start + 1}: not UTF-8 text: "
                            "expected a text CSV; is it a binary (.mat, .xlsx) file?") from None
        yield line_no, text, True


def _field_at(text: str, delimiter: str, pos: int | None = None) -> int:
    """Index of the field of ``text`` holding character ``pos`` (default: the field an
    unterminated quote opens, else the last one), quotes respected."""
    field_no, quoted, opened = 0, False, 0
    for k, ch in enumerate(text):
        if pos is not None and k >= pos:
            return field_no
        if ch == '"':
            quoted = not quoted
            if quoted:
                opened = field_no
        elif ch == delimiter and not quoted:
            field_no += 1
    return opened if quoted and pos is None else field_no


def _split(text: str, delimiter: str) -> list[str]:
    """Fields of one line; raise csv.Error for bad quoting (quotes must close on the line)."""
    if '"' not in text:
        return text.split(delimiter)
    return next(csv.reader((text,), delimiter=delimiter, strict=True))


def _open(path: str) -> BinaryIO:
    """Open ``path`` for reading bytes after the checks that need no reading."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise DataError(f"{path}: no such file") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read: {exc.strerror}") from None
    if stat.S_ISDIR(st.st_mode):
        raise DataError(f"{path}: is a directory, expected a CSV file")
    if stat.S_ISREG(st.st_mode):
        if st.st_size == 0:
            raise DataError(f"{path}: the file is empty")
        if st.st_size > MAX_FILE_BYTES:
            raise DataError(f"{path}: {st.st_size} bytes, more than MAX_FILE_BYTES = "
                            f"{MAX_FILE_BYTES} ({MAX_FILE_BYTES // 2**20} MiB, the largest run "
                            "file read); cut the run into shorter files")
    try:
        return open(path, "rb")
    except OSError as exc:
        raise DataError(f"{path}: cannot read: {exc.strerror}") from None


Column = str | int
"""A column of a run file: its header name, or its 0-based index (an int, or a string of
digits that is not a header name)."""


def load_run(path: str | os.PathLike[str], *, time: Column | None = "t",
             reference: Column | None = "x_ref", position: Column = "x",
             effort: Column | None = "u", effort_required: bool = False,
             sample_time: float | None = None, position_unit: str = "m",
             load_position: Column | None = None) -> RunData:
    """Read a run from a CSV file and validate it.

    The file (or a pipe) is read line by line: at most :data:`MAX_FILE_BYTES` bytes,
    :data:`MAX_ROWS` data rows and :data:`MAX_LINE_BYTES` bytes per line; a regular file larger
    than :data:`MAX_FILE_BYTES` is refused before it is opened.

    Parameters
    ----------
    path : str or PathLike
        CSV file with a header row (comma, semicolon or tab separated, whichever the header
        holds most; ``#`` comment lines before the header are skipped). Numbers use a decimal
        point (C locale); a decimal comma is refused. A quoted cell must end on its line.
    time, reference, position : str or int
        Columns of time (s), reference position and measured position (in
        ``position_unit``): a header name, or a 0-based index (an int, or a string of digits
        that is not a header name: ``"0"`` is the first column). A header may state a
        column's unit in brackets, ``x [mm]``: the name alone (``x``) selects it, a time
        column must then be in s and a position column in ``position_unit``, and the effort's
        unit is read from it (``u [N]``, as ``fricbench simulate`` writes). ``time`` None: no
        time column (then ``sample_time`` is required). ``reference`` None: an open-loop run with
        no reference; ``x_ref`` is then the measured position (nothing tracks it).
    effort : str, int or None
        Column of the effort (name or 0-based index). When the column is missing the run has
        no effort, unless ``effort_required`` (then it is an error); None never reads an
        effort.
    effort_required : bool
        Raise when the ``effort`` column is missing or degenerate (set when the user named it);
        otherwise a degenerate effort (constant, or off the scale of :data:`EFFORT_RANGE`) is
        dropped with a warning.
    sample_time : float, optional
        For a log without a time column: the sample time Ts (s); sample k is at ``t = k Ts``.
        It is an error to give it for a file that has the ``time`` column.
    position_unit : str
        Unit of the position columns: ``m``, ``mm``, ``um`` (linear axis) or ``rad``, ``deg``
        (rotary axis). Positions are converted to m or rad on reading; the scale checks of
        :func:`validate_arrays` apply to the converted values.
    load_position : str or int, optional
        Column of a second, load-side position (a linear scale, or the load's encoder behind
        a coupling), in ``position_unit``; ``position`` is then the motor encoder. Required
        when given (a missing column is an error).

    Returns
    -------
    RunData

    Raises
    ------
    DataError
        Missing, empty, binary or too large file, missing columns (the message lists those
        found), both or neither of a time column and ``sample_time``, a decimal comma, bad
        quoting, overlong lines, non-numeric cells (line and column), NaN or inf,
        time not increasing or irregular beyond 1 %, too few samples, no motion, values off
        the scale of a servo axis (see :func:`validate_arrays`).
    """
    path = os.fspath(path)
    unit = _position_unit(position_unit)  # ValueError for an unknown unit, before reading
    if sample_time is not None and not (math.isfinite(sample_time) and sample_time > 0.0):
        raise ValueError(f"sample_time={sample_time!r}: expected a positive time step, s")
    with _open(path) as fh:
        return _parse(_lines(fh, path), path, time=time, reference=reference,
                      position=position, effort=effort, effort_required=effort_required,
                      sample_time=sample_time, to_si=unit.to_si, position_unit=unit.name,
                      load_position=load_position)


_UNIT_IN_NAME = re.compile(r"^(.*?)\s*\[([^\[\]]+)\]$")


def _name_and_unit(header_name: str) -> tuple[str, str | None]:
    """``("u", "N")`` for a header ``"u [N]"``; ``(name, None)`` without a bracketed unit."""
    m = _UNIT_IN_NAME.match(header_name)
    return (m.group(1), m.group(2).strip()) if m and m.group(1) else (header_name, None)


def _column_index(spec: Column, header: list[str]) -> int | None:
    """Index of column ``spec`` (a header name, else a 0-based index) in ``header``, or
    None when there is no such column."""
    if isinstance(spec, str):
        if spec in header:
            return header.index(spec)
        named = [j for j, h in enumerate(header) if _name_and_unit(h)[0] == spec]
        if len(named) == 1:  # "u" selects "u [N]"
            return named[0]
        if not spec.strip().isdigit():
            return None
        spec = int(spec)
    if isinstance(spec, bool) or not isinstance(spec, int):
        raise TypeError(f"column {spec!r}: expected a header name (str) or a 0-based index "
                        "(int)")
    return spec if 0 <= spec < len(header) else None


def _number(cell: str, path: str, line_no: int, name: str, delimiter: str) -> float:
    """The value of one numeric cell; DataError naming the line and column otherwise."""
    try:
        value = float(cell)
    except ValueError:
        if _DECIMAL_COMMA.match(cell):
            sep = {";": "semicolon", "\t": "tab"}.get(delimiter, repr(delimiter))
            raise DataError(f"{path}: line {line_no}, column {name!r}: {cell[:40]!r} has a "
                            f"decimal comma ({sep}-separated file); numbers must use a decimal "
                            "point (C locale): export again with the C or English locale, or "
                            "replace the commas by points") from None
        raise DataError(f"{path}: line {line_no}, column {name!r}: {cell[:40]!r} "
                        "is not a number") from None
    if not math.isfinite(value):
        raise DataError(f"{path}: line {line_no}, column {name!r}: {cell!r} is not "
                        "finite (NaN or inf); remove or fill such rows")
    return value


def _stated_units(wanted: dict[str, str], path: str, position_unit: str) -> str | None:
    """Check the units the chosen columns state in their names (``"x [mm]"``) against the
    options; return the effort's stated unit, or None.

    Raises
    ------
    DataError
        A time column not in s, a position column in a unit other than ``position_unit``.
    """
    for key, name in wanted.items():
        unit = _name_and_unit(name)[1]
        if unit is None or key == "u":
            continue
        if key == "t" and unit != "s":
            raise DataError(f"{path}: column {name!r} states {unit}; expected a time in s (give "
                            "the time in seconds, or --sample-time without a time column)")
        if key != "t" and unit != position_unit:
            raise DataError(f"{path}: column {name!r} states {unit} but the positions are read "
                            f"in {position_unit} (--position-unit); expected the same unit, "
                            f"such as --position-unit {unit}")
    return _name_and_unit(wanted["u"])[1] if "u" in wanted else None


def _parse(lines: Iterator[tuple[int, str, bool]], path: str, *, time: Column | None,
           reference: Column | None, position: Column, effort: Column | None,
           effort_required: bool, sample_time: float | None = None, to_si: float = 1.0,
           position_unit: str = "m", load_position: Column | None = None) -> RunData:
    """Header, columns and numbers of the lines of a run file (see :func:`load_run`)."""
    seen_text = seen_line = False
    for line_no, text, complete in lines:
        seen_line = True
        if not complete:
            raise DataError(f"{path}: line {line_no} is longer than MAX_LINE_BYTES = "
                            f"{MAX_LINE_BYTES} bytes before the header; expected a CSV header")
        if not text.strip():
            continue
        seen_text = True
        if text.lstrip().startswith("#"):
            continue
        break
    else:
        if not seen_line:
            raise DataError(f"{path}: the file is empty")
        if not seen_text:
            raise DataError(f"{path}: the file holds only whitespace")
        raise DataError(f"{path}: no header row found (only comments)")
    header_no, header_line = line_no, text
    delimiter = max((",", ";", "\t"), key=header_line.count)
    if header_line.count(delimiter) == 0:
        delimiter = ","
    try:
        header = [h.strip() for h in _split(header_line, delimiter)]
    except csv.Error as exc:
        j = _field_at(header_line, delimiter)
        raise DataError(f"{path}: line {header_no} (the header), field {j + 1}: bad quoting "
                        f"({exc}); a quoted name must close on its line") from None
    specs: dict[str, Column] = {"x": position}
    if reference is not None:
        specs["x_ref"] = reference
    if load_position is not None:
        specs["x_load"] = load_position
    t_idx = _column_index(time, header) if time is not None else None
    if sample_time is not None and t_idx is not None:
        raise DataError(f"{path}: the file has a time column {header[t_idx]!r} and a sample "
                        f"time {sample_time:g} s was given (--sample-time): give one of them "
                        "(a log without a time column needs --sample-time)")
    if sample_time is None:
        if time is None:
            raise DataError(f"{path}: no time column and no sample time: give the time column "
                            "(--time) or the sample time of the log (--sample-time)")
        specs = {"t": time, **specs}
    idx: dict[str, int] = {}
    missing: list[Column] = []
    for key, spec in specs.items():
        found = _column_index(spec, header)
        if found is None:
            missing.append(spec)
        else:
            idx[key] = found
    j_u = _column_index(effort, header) if effort is not None else None
    if effort is not None and effort_required and j_u is None:
        missing.append(effort)
    if missing:
        hint = ("; or give the sample time of a log without one, --sample-time"
                if "t" in specs and _column_index(specs["t"], header) is None else "")
        if reference is not None and reference in missing:
            hint += ("; a run without a reference (effort-driven, open loop): --open-loop "
                     "with an effort column")
        raise DataError(f"{path}: missing column(s) {', '.join(map(repr, missing))}; the file "
                        f"has {', '.join(map(repr, header))} (choose with --time, --reference, "
                        f"--position, --load-position, --effort: a name or a 0-based "
                        f"index{hint})")
    if len(set(header)) != len(header):
        dup = sorted({h for h in header if header.count(h) > 1})
        raise DataError(f"{path}: duplicate column name(s) {dup} in the header")
    if j_u is not None:
        idx["u"] = j_u
    wanted = {key: header[j] for key, j in idx.items()}
    effort_unit = _stated_units(wanted, path, position_unit)
    ncol = len(header)

    def column(j: int) -> str:
        return f"column {header[j]!r}" if j < ncol else f"field {j + 1} (beyond the header)"

    data = {key: array("d") for key in wanted}
    line_numbers = array("q")
    for line_no, text, complete in lines:
        if not complete:
            j = _field_at(text, delimiter, MAX_LINE_BYTES)
            raise DataError(f"{path}: line {line_no}, {column(j)}: the line is longer than "
                            f"MAX_LINE_BYTES = {MAX_LINE_BYTES} bytes; expected short numeric "
                            "cells (an unterminated quote or a corrupt line?)")
        if not text.strip() or text.lstrip().startswith("#"):
            continue
        try:
            row = _split(text, delimiter)
        except csv.Error as exc:
            j = _field_at(text, delimiter)
            raise DataError(f"{path}: line {line_no}, {column(j)}: bad quoting ({exc}); a "
                            "quoted cell must close on its line") from None
        if len(row) != ncol:
            detail = (f"{column(ncol)} holds {row[ncol].strip()[:40]!r}" if len(row) > ncol
                      else f"{column(len(row))} and after are missing")
            raise DataError(f"{path}: line {line_no} has {len(row)} fields, the header has "
                            f"{ncol}: {detail}")
        if len(line_numbers) >= MAX_ROWS:
            raise DataError(f"{path}: line {line_no}: more than MAX_ROWS = {MAX_ROWS} data "
                            "rows (the most samples a run may have); cut the run into shorter "
                            "files")
        for key, j in idx.items():
            data[key].append(_number(row[j].strip(), path, line_no, header[j], delimiter))
        line_numbers.append(line_no)
    if not line_numbers:
        raise DataError(f"{path}: the header has no data rows below it")
    names: dict[str, str | None] = dict(wanted)
    if sample_time is not None:
        # t_k = k Ts
        t = np.arange(len(line_numbers), dtype=float) * sample_time
        names["t"] = f"k * {sample_time:g} s (--sample-time)"
    else:
        t = np.asarray(data["t"])
    # open loop (no reference column): the measured position stands in for x_ref
    x_ref = data["x_ref"] if "x_ref" in data else data["x"]
    if "x_ref" not in data:
        names["x_ref"] = names["x"]
    return validate_arrays(t, to_si * np.asarray(x_ref), to_si * np.asarray(data["x"]),
                           np.asarray(data["u"]) if "u" in data else None,
                           source=path, names=names, line_numbers=np.asarray(line_numbers),
                           effort_required=effort_required, position_unit=position_unit,
                           open_loop="x_ref" not in data, effort_unit=effort_unit,
                           x_load=(to_si * np.asarray(data["x_load"]) if "x_load" in data
                                   else None))

"""Loading and validating measured (or simulated) runs from CSV files.

A run file is a CSV with a one-line header and one row per uniformly spaced sample: time (s),
reference position (m), measured position (m) and, optionally, the actuator effort (force in N,
or a current or voltage: any consistent unit). ``fricbench simulate`` writes this format; the
EMPS files of ``data/emps`` use other column names, chosen with the keyword arguments of
:func:`load_run`.

Every problem with the file raises :class:`DataError` with a message that says what is wrong
and where (row and column); problems that still allow an analysis become warnings on the
returned :class:`RunData`. The file is only ever read.
"""

from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass, field

import numpy as np

__all__ = ["DataError", "RunData", "load_run", "validate_arrays", "MIN_SAMPLES",
           "TIME_JITTER_TOLERANCE"]

MIN_SAMPLES = 200
"""Fewest samples a run may have (0.2 s at 1 kHz)."""

TIME_JITTER_TOLERANCE = 0.01
"""Largest allowed relative deviation of a time step from the median step."""

_MM_SUSPECT_RANGE = 2.0  # m: a feed-axis stroke longer than this is more likely in mm
_MAX_BYTES_SNIFF = 8192


class DataError(ValueError):
    """The run file cannot be analysed; the message says why and where."""


@dataclass(frozen=True)
class RunData:
    """One validated run: uniformly sampled reference, measured position and optional effort.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Sample times as read, s.
    x_ref : ndarray, shape (K,)
        Reference position, m.
    x : ndarray, shape (K,)
        Measured position, m.
    u : ndarray or None, shape (K,)
        Actuator effort (any consistent unit), or None when the file has none.
    ts : float
        Sample time, s (median time step).
    source : str
        Where the data came from (file path or a label).
    columns : dict
        The column names used for ``t``, ``x_ref``, ``x`` and ``u``.
    warnings : tuple of str
        Problems that do not prevent an analysis (positions that look like mm, no reversals).
    n_reversals : int
        Velocity reversals of the reference.
    """

    t: np.ndarray
    x_ref: np.ndarray
    x: np.ndarray
    u: np.ndarray | None
    ts: float
    source: str = "<arrays>"
    columns: dict[str, str | None] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    n_reversals: int = 0

    @property
    def n_samples(self) -> int:
        """Number of samples K."""
        return int(self.t.shape[0])

    @property
    def duration(self) -> float:
        """Length of the run, s."""
        return float(self.t[-1] - self.t[0])

    @property
    def has_effort(self) -> bool:
        """Whether an effort column was given."""
        return self.u is not None


# -- helpers ------------------------------------------------------------------------------------
def _count_reversals(x: np.ndarray, ts: float, tol: float) -> int:
    """Direction changes of ``x`` ignoring excursions smaller than ``tol`` (m)."""
    # hysteresis on the position: a reversal is a turn by more than tol after a move
    direction = 0
    extreme = x[0]
    count = 0
    for value in x[:: max(1, int(round(1e-3 / ts)))]:
        if direction >= 0:
            if value > extreme:
                extreme = value
                if direction == 0 and value - x[0] > tol:
                    direction = 1
            elif extreme - value > tol:
                if direction == 1:
                    count += 1
                direction = -1
                extreme = value
        else:
            if value < extreme:
                extreme = value
            elif value - extreme > tol:
                count += 1
                direction = 1
                extreme = value
    return count


def validate_arrays(t: np.ndarray, x_ref: np.ndarray, x: np.ndarray, u: np.ndarray | None = None,
                    *, source: str = "<arrays>", names: dict[str, str | None] | None = None,
                    line_numbers: np.ndarray | None = None) -> RunData:
    """Check arrays of one run and wrap them in a :class:`RunData`.

    Parameters
    ----------
    t, x_ref, x : array_like, shape (K,)
        Time (s), reference position (m), measured position (m).
    u : array_like, shape (K,), optional
        Effort.
    source : str
        Label used in messages.
    names : dict, optional
        Column names for messages (keys ``t``, ``x_ref``, ``x``, ``u``).
    line_numbers : ndarray of int, optional
        File line of each sample (for messages); samples are numbered from 0 without it.

    Returns
    -------
    RunData

    Raises
    ------
    DataError
        NaN or inf, time not increasing or irregular, too short, or no motion.
    """
    names = dict(names or {"t": "t", "x_ref": "x_ref", "x": "x", "u": "u"})

    def where(i: int) -> str:
        return f"line {int(line_numbers[i])}" if line_numbers is not None else f"sample {i}"

    arrays = {"t": t, "x_ref": x_ref, "x": x}
    if u is not None:
        arrays["u"] = u
    clean: dict[str, np.ndarray] = {}
    length = None
    for key, value in arrays.items():
        arr = np.asarray(value, dtype=float)
        if arr.ndim != 1:
            raise DataError(f"{source}: column {names.get(key)!r} has shape {arr.shape}: "
                            "expected one value per row")
        if length is not None and arr.shape[0] != length:
            raise DataError(f"{source}: column {names.get(key)!r} has {arr.shape[0]} values, "
                            f"expected {length}")
        length = arr.shape[0]
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            i = int(bad[0])
            raise DataError(f"{source}: {where(i)}, column {names.get(key)!r}: "
                            f"value {arr[i]!r} is not finite ({bad.size} such rows); "
                            "remove or fill them")
        clean[key] = arr
    n = int(length or 0)
    if n < MIN_SAMPLES:
        raise DataError(f"{source}: {n} samples: too short, need at least {MIN_SAMPLES} "
                        "(the diagnosis fits a dynamic model and holds part of the run out)")
    tt = clean["t"]
    dt = np.diff(tt)
    if np.any(dt <= 0.0):
        i = int(np.flatnonzero(dt <= 0.0)[0])
        raise DataError(f"{source}: column {names['t']!r} does not increase at {where(i + 1)} "
                        f"({tt[i]!r} then {tt[i + 1]!r}); expected strictly increasing time")
    ts = float(np.median(dt))
    dev = np.abs(dt - ts) / ts
    if np.max(dev) > TIME_JITTER_TOLERANCE:
        i = int(np.argmax(dev))
        raise DataError(
            f"{source}: irregular sampling: the step to {where(i + 1)} is "
            f"{dt[i]:.6g} s against the median {ts:.6g} s ({100 * dev[i]:.1f} % off, "
            f"{int(np.sum(dev > TIME_JITTER_TOLERANCE))} steps beyond "
            f"{100 * TIME_JITTER_TOLERANCE:g} %); resample the run to a uniform step first"
        )
    xr, xm = clean["x_ref"], clean["x"]
    warnings: list[str] = []
    span_ref = float(np.ptp(xr))
    span_x = float(np.ptp(xm))
    if span_ref <= 0.0:
        raise DataError(f"{source}: column {names['x_ref']!r} is constant: a run without motion; "
                        "no analysis is possible (neither the loop dynamics nor any effect "
                        "can be identified)")
    if span_x <= 0.0:
        raise DataError(f"{source}: column {names['x']!r} is constant while the reference moves "
                        f"by {span_ref:.6g}: the measured position did not follow; check the "
                        "column choice")
    if max(span_ref, span_x, float(np.max(np.abs(xr)))) > _MM_SUSPECT_RANGE:
        warnings.append(
            f"positions span {span_ref:.6g} (reference) and {span_x:.6g} (measured): these look "
            "like millimetres or encoder counts, not metres; the reported parameters assume "
            "metres (convert the columns if they are not)"
        )
    err_rms = float(np.sqrt(np.mean((xr - xm) ** 2)))
    if err_rms > 0.2 * span_ref:
        warnings.append(
            f"the measured position differs from the reference by {err_rms:.6g} rms, "
            f"{100 * err_rms / span_ref:.0f} % of the stroke: are both columns in the same unit "
            "and the right ones?"
        )
    n_rev = _count_reversals(xr, ts, max(1e-3 * span_ref, 1e-9))
    if n_rev == 0:
        warnings.append(
            "the reference never reverses: friction levels, direction-dependent effects and "
            "backlash cannot be separated from a constant force; coulomb_friction, "
            "stribeck_friction, asymmetric_friction and backlash are not tried"
        )
    return RunData(t=tt, x_ref=xr, x=xm, u=clean.get("u"), ts=ts, source=source,
                   columns=names, warnings=tuple(warnings), n_reversals=n_rev)


def _sniff(path: str) -> str:
    """Return the text of ``path``; raise DataError for a missing, empty or binary file."""
    if not os.path.exists(path):
        raise DataError(f"{path}: no such file")
    if os.path.isdir(path):
        raise DataError(f"{path}: is a directory, expected a CSV file")
    if os.path.getsize(path) == 0:
        raise DataError(f"{path}: the file is empty")
    with open(path, "rb") as fh:
        raw = fh.read()
    head = raw[:_MAX_BYTES_SNIFF]
    if b"\x00" in head:
        raise DataError(f"{path}: looks like a binary file (NUL bytes), expected a text CSV")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not UTF-8 text (byte {exc.start}): expected a text CSV; "
                        "is it a binary (.mat, .xlsx) file?") from None
    if not text.strip():
        raise DataError(f"{path}: the file holds only whitespace")
    return text


def load_run(path: str | os.PathLike[str], *, time: str = "t", reference: str = "x_ref",
             position: str = "x", effort: str | None = "u",
             effort_required: bool = False) -> RunData:
    """Read a run from a CSV file and validate it.

    Parameters
    ----------
    path : str or PathLike
        CSV file with a header row (comma, semicolon or tab separated; ``#`` comment lines
        before the header are skipped).
    time, reference, position : str
        Column names of time (s), reference position (m) and measured position (m).
    effort : str or None
        Column name of the effort. When the column is missing the run has no effort, unless
        ``effort_required`` (then it is an error); None never reads an effort.
    effort_required : bool
        Raise when the ``effort`` column is missing (set when the user named it).

    Returns
    -------
    RunData

    Raises
    ------
    DataError
        Missing, empty or binary file, missing columns (the message lists those found),
        non-numeric cells (row and column), NaN or inf, time not increasing or irregular
        beyond 1 %, too few samples, no motion.
    """
    path = os.fspath(path)
    text = _sniff(path)
    lines = text.splitlines()
    start = 0
    while start < len(lines) and (not lines[start].strip() or lines[start].lstrip()
                                  .startswith("#")):
        start += 1
    if start >= len(lines):
        raise DataError(f"{path}: no header row found (only comments)")
    header_line = lines[start]
    delimiter = max((",", ";", "\t"), key=header_line.count)
    if header_line.count(delimiter) == 0:
        delimiter = ","
    reader = csv.reader(io.StringIO("\n".join(lines[start:])), delimiter=delimiter)
    header = [h.strip() for h in next(reader)]
    wanted = {"t": time, "x_ref": reference, "x": position}
    missing = [name for name in wanted.values() if name not in header]
    if effort is not None and effort_required and effort not in header:
        missing.append(effort)
    if missing:
        raise DataError(f"{path}: missing column(s) {', '.join(map(repr, missing))}; the file "
                        f"has {', '.join(map(repr, header))} (choose with --time, --reference, "
                        "--position, --effort)")
    if len(set(header)) != len(header):
        dup = sorted({h for h in header if header.count(h) > 1})
        raise DataError(f"{path}: duplicate column name(s) {dup} in the header")
    if effort is not None and effort in header:
        wanted["u"] = effort
    idx = {key: header.index(name) for key, name in wanted.items()}
    ncol = len(header)
    data: dict[str, list[float]] = {key: [] for key in wanted}
    line_numbers: list[int] = []
    first_row = start + 2  # 1-based file line of the first data row
    for offset, row in enumerate(reader):
        line_no = first_row + offset
        if not row or all(not c.strip() for c in row):
            continue
        if row[0].lstrip().startswith("#"):
            continue
        if len(row) != ncol:
            raise DataError(f"{path}: line {line_no} has {len(row)} fields, the header has "
                            f"{ncol}")
        for key, j in idx.items():
            cell = row[j].strip()
            try:
                value = float(cell)
            except ValueError:
                raise DataError(f"{path}: line {line_no}, column {header[j]!r}: {cell!r} is not "
                                "a number") from None
            if not math.isfinite(value):
                raise DataError(f"{path}: line {line_no}, column {header[j]!r}: {cell!r} is not "
                                "finite (NaN or inf); remove or fill such rows")
            data[key].append(value)
        line_numbers.append(line_no)
    if not data["t"]:
        raise DataError(f"{path}: the header has no data rows below it")
    names = {k: wanted.get(k) for k in ("t", "x_ref", "x", "u")}
    return validate_arrays(np.array(data["t"]), np.array(data["x_ref"]), np.array(data["x"]),
                           np.array(data["u"]) if "u" in data else None, source=path,
                           names=names, line_numbers=np.array(line_numbers))

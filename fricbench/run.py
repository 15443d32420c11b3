"""The one run type: a logged or simulated run of one axis, as every part of fricbench reads it.

A :class:`Run` holds the uniformly sampled time, reference and measured position and, when
the log has one, the actuator effort, with the units and metadata of its source. Every path
that builds one checks its arrays with :func:`validate_run_arrays` (one value per sample,
equal lengths, finite, strictly increasing and uniformly sampled time, SI units): the CSV
loader and its validator (:func:`fricbench.sysid.io.load_run`,
:func:`fricbench.sysid.io.validate_arrays`) from a file or arrays,
:meth:`fricbench.axis.SimulationResult.as_run` from a simulation, the predictors' ``fit``
(:func:`fricbench.predictors.as_runs`) from whatever run-like objects they are given. The
predictors, the diagnosis and the benchmark take it; :meth:`Run.events` gives its starts, stops
and reversals (:mod:`fricbench.run_events`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fricbench.run_events import MotionEvent, motion_events
from fricbench.units import POSITION_UNITS, PositionUnit

__all__ = ["Run", "RUN_UNITS", "validate_run_arrays"]

RUN_UNITS = {"time": ("s",), "position": ("m", "rad")}
"""The units a run's arrays are held in (SI: the loader converts on reading)."""


def _sample(i: int) -> str:
    return f"sample {i}"


def validate_run_arrays(
    t: object,
    x_ref: object,
    x: object,
    u: object | None = None,
    *,
    source: str = "",
    labels: Mapping[str, str | None] | None = None,
    where: Callable[[int], str] = _sample,
    min_samples: int = 1,
    too_short_why: str = "",
    max_jitter: float = 1e-6,
    units: Mapping[str, str] | None = None,
    error: type[ValueError] = ValueError,
    extra: Mapping[str, Any] | None = None,
) -> tuple[dict[str, np.ndarray], float]:
    """Check the arrays of one run: the one validator of every path that builds a :class:`Run`.

    Parameters
    ----------
    t, x_ref, x : array_like, shape (K,)
        Time (s), reference and measured position (m, or rad).
    u : array_like, shape (K,), optional
        Effort.
    source : str, optional
        Prefix of every message (a file name); none when empty.
    labels : mapping, optional
        How messages name each array (keys ``t``, ``x_ref``, ``x``, ``u``): ``"column 'q_m'"``
        for a file, ``"runs[2].x"`` for an argument; the key itself by default.
    where : callable, optional
        ``where(i)`` names sample ``i`` in messages (``"line 12"`` for a file).
    min_samples : int, optional
        Fewest samples accepted.
    too_short_why : str, optional
        Why ``min_samples`` are needed, appended to that message.
    max_jitter : float, optional
        Largest relative deviation of a time step from the median step.
    units : mapping, optional
        The run's units: ``"time"`` and ``"position"`` must be SI (:data:`RUN_UNITS`).
    error : type, optional
        The ``ValueError`` subclass raised (the loader's ``DataError``).
    extra : mapping, optional
        Further per-sample arrays checked alike (a load encoder's position, ``x_load``),
        named in messages by ``labels`` (the key by default).

    Returns
    -------
    arrays : dict of ndarray
        ``t``, ``x_ref``, ``x`` (and ``u`` and the ``extra`` arrays when given) as float
        arrays.
    ts : float
        The median time step, s (NaN with fewer than two samples).

    Raises
    ------
    ValueError (or ``error``)
        An array not 1-D, of another length, with NaN or inf, too few samples, time not
        strictly increasing or not uniformly sampled, a unit that is not SI.
    """
    prefix = f"{source}: " if source else ""
    names = {"t": "t", "x_ref": "x_ref", "x": "x", "u": "u",
             **{key: key for key in (extra or {})}, **(labels or {})}
    for key, allowed in RUN_UNITS.items():
        if units is not None and units.get(key) not in allowed:
            raise error(f"{prefix}units[{key!r}]={units.get(key)!r}: expected "
                        f"{' or '.join(map(repr, allowed))} (a run holds SI units)")
    arrays = {"t": t, "x_ref": x_ref, "x": x}
    if u is not None:
        arrays["u"] = u
    arrays.update(extra or {})
    clean: dict[str, np.ndarray] = {}
    for key, value in arrays.items():
        arr = np.asarray(value, dtype=float)
        if arr.ndim != 1:
            raise error(f"{prefix}{names[key]} has shape {arr.shape}: expected a 1-D array, one "
                        "value per sample (a single-axis run)")
        if clean and arr.shape[0] != clean["t"].shape[0]:
            raise error(f"{prefix}{names[key]} has {arr.shape[0]} samples but {names['t']} has "
                        f"{clean['t'].shape[0]}: every array must have the same length")
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            i = int(bad[0])
            raise error(f"{prefix}{where(i)}, {names[key]} contains NaN or inf: value "
                        f"{float(arr[i])!r} is not finite ({bad.size} such samples); remove or "
                        "fill them")
        clean[key] = arr
    tt = clean["t"]
    n = tt.shape[0]
    if n < min_samples:
        raise error(f"{prefix}{names['t']} has {n} samples: too short, need at least "
                    f"{min_samples}{too_short_why}")
    if n < 2:
        return clean, float("nan")
    dt = np.diff(tt)
    if np.any(dt <= 0.0):
        i = int(np.flatnonzero(dt <= 0.0)[0])
        raise error(f"{prefix}{names['t']} does not increase at {where(i + 1)} "
                    f"({float(tt[i])!r} then {float(tt[i + 1])!r}); expected strictly "
                    "increasing time")
    ts = float(np.median(dt))
    dev = np.abs(dt - ts) / ts
    if np.max(dev) > max_jitter:
        i = int(np.argmax(dev))
        raise error(
            f"{prefix}irregular sampling: the step to {where(i + 1)} is {dt[i]:.6g} s against "
            f"the median {ts:.6g} s ({100 * dev[i]:.3g} % off, "
            f"{int(np.sum(dev > max_jitter))} steps beyond {100 * max_jitter:g} %); resample "
            "the run to a uniform step first"
        )
    return clean, ts


@dataclass(frozen=True)
class Run:
    """One run of one axis: reference, measured position and optional effort.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Sample times, s.
    x_ref : ndarray, shape (K,)
        Reference position (m, or rad for a rotary axis; see ``units``).
    x : ndarray, shape (K,)
        Measured position, same unit.
    u : ndarray or None, shape (K,)
        Actuator effort (force, current or a raw command; see ``units``), or None.
    ts : float
        Sample time, s. When not given: the first time step (the median step for a run read
        from a file, where the loader sets it).
    source : str
        Where the data came from (file path or a label).
    columns : dict
        The column names used for ``t``, ``x_ref``, ``x`` and ``u``.
    warnings : tuple of str
        Problems that do not prevent an analysis.
    n_reversals : int
        Direction changes of the reference (set by the loader).
    n_starts : int
        Starts of the reference from a rest seen in the run (set by the loader).
    units : dict
        Units of ``"time"``, ``"position"`` and ``"effort"``.
    x_load : ndarray or None, shape (K,)
        A second measured position on the load side (a linear scale beside the motor encoder
        that ``x`` then holds), same unit, or None.
    """

    t: np.ndarray
    x_ref: np.ndarray
    x: np.ndarray
    u: np.ndarray | None = None
    ts: float = 0.0
    source: str = "<arrays>"
    columns: dict[str, str | None] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    n_reversals: int = 0
    n_starts: int = 0
    units: dict[str, str] = field(
        default_factory=lambda: {"time": "s", "position": "m", "effort": "N"})
    x_load: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not self.ts and np.shape(self.t)[0] >= 2:
            object.__setattr__(self, "ts", float(self.t[1] - self.t[0]))

    @property
    def n_samples(self) -> int:
        """Number of samples K."""
        return int(self.t.shape[0])

    @property
    def duration(self) -> float:
        """Length of the run, s."""
        return float(self.t[-1] - self.t[0])

    @property
    def logged_unit(self) -> PositionUnit:
        """The position unit the log was in (``units["position_logged"]``, else the SI unit):
        the unit figures are shown in (deg stays deg, mm is shown in um)."""
        name = self.units.get("position_logged", self.units.get("position", "m"))
        if name not in POSITION_UNITS:
            name = "rad" if self.units.get("position") == "rad" else "m"
        return POSITION_UNITS[name]

    @property
    def has_effort(self) -> bool:
        """Whether the run has an effort."""
        return self.u is not None

    def events(self, rest_speed: float = 1e-6, max_gap: int | None = 2) -> list[MotionEvent]:
        """Starts, stops and reversals of the reference.

        :func:`fricbench.run_events.motion_events` of the reference velocity by central
        differences (``np.gradient(x_ref, ts)``).

        Parameters
        ----------
        rest_speed : float, optional
            Speed at or below which the reference is at rest, m/s (rad/s).
        max_gap : int or None, optional
            Longest rest, in samples, still read as a direct reversal; None: any rest.

        Returns
        -------
        list of MotionEvent
        """
        return motion_events(np.gradient(self.x_ref, self.ts), self.ts, rest_speed=rest_speed,
                             max_gap=max_gap)

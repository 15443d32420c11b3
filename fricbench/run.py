"""The one run type: a logged or simulated run of one axis, as every part of fricbench reads it.

A :class:`Run` holds the uniformly sampled time, reference and measured position and, when
the log has one, the actuator effort, with the units and metadata of its source. The CSV
loader and its validator (:func:`fricbench.sysid.io.load_run`,
:func:`fricbench.sysid.io.validate_arrays`) build it from a file or arrays;
:meth:`fricbench.axis.SimulationResult.as_run` from a simulation. The predictors, the
diagnosis and the benchmark take it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Run"]


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
    units : dict
        Units of ``"time"``, ``"position"`` and ``"effort"``.
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
    units: dict[str, str] = field(
        default_factory=lambda: {"time": "s", "position": "m", "effort": "N"})

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
    def has_effort(self) -> bool:
        """Whether the run has an effort."""
        return self.u is not None

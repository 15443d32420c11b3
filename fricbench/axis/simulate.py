"""Full-trajectory simulation of one or many axes on a reference."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from fricbench.axis.batch import AxisBatch
from fricbench.axis.params import Axis
from fricbench.run import Run, validate_run_arrays
from fricbench.trajectories.base import Reference

__all__ = ["SimulationResult", "simulate", "simulate_many"]


@dataclass(frozen=True)
class SimulationResult:
    """One simulated run (python-control's ``TimeResponseData`` in spirit).

    Arrays have shape (K,) for a single axis and (D, K) for a multi-axis reference.

    Attributes
    ----------
    t : ndarray
        Time, s.
    x_ref : ndarray
        Reference position, m (the nominal one, before any pre-compensation offset).
    x : ndarray
        Measured table position, m (with quantisation and noise when enabled).
    x_true : ndarray
        True table position, m.
    u : ndarray
        Motor force as the drive reports it (``kt`` times the current, with the
        current-measurement noise ``effects.current_noise_std`` when enabled), N.
    friction : ndarray
        Mean friction force over each sample, N.
    """

    t: np.ndarray
    x_ref: np.ndarray
    x: np.ndarray
    x_true: np.ndarray
    u: np.ndarray
    friction: np.ndarray
    reference: Reference = field(repr=False)
    axes: tuple[Axis, ...] = field(repr=False, default=())
    seed: int | None = None

    @property
    def error(self) -> np.ndarray:
        """Actual tracking error ``x_ref - x_true``, m."""
        return self.x_ref - self.x_true

    @property
    def measured_error(self) -> np.ndarray:
        """Tracking error as measured, ``x_ref - x``, m."""
        return self.x_ref - self.x

    @property
    def max_error(self) -> float:
        """Max |actual tracking error|, m."""
        return float(np.max(np.abs(self.error)))

    @property
    def rms_error(self) -> float:
        """RMS actual tracking error, m."""
        return float(np.sqrt(np.mean(self.error**2)))

    def as_run(self, axis: int | None = None) -> Run:
        """The run as a log would hold it: time, reference, measured position, motor force.

        Parameters
        ----------
        axis : int, optional
            Which coordinate of a multi-axis result (required there; a run is one axis).

        Returns
        -------
        Run
        """
        x_ref, x, u = (np.atleast_2d(a) for a in (self.x_ref, self.x, self.u))
        d = x_ref.shape[0]
        if axis is None:
            if d != 1:
                raise ValueError(f"axis=None: this result has {d} axes; expected an index "
                                 f"0..{d - 1}")
            axis = 0
        if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)) or not 0 <= axis < d:
            raise ValueError(f"axis={axis!r}: expected an integer in 0..{d - 1}")
        ts = self.axes[0].controller.ts if self.axes else 0.0
        arrs, _ = validate_run_arrays(self.t, x_ref[axis], x[axis], u[axis],
                                      source="fricbench.simulate")
        return Run(arrs["t"], arrs["x_ref"], arrs["x"], arrs["u"], ts=ts,
                   source="fricbench.simulate",
                   columns={"t": "t", "x_ref": "x_ref", "x": "x", "u": "u"})


def _as_rows(arr: np.ndarray | None, d: int, k: int, name: str) -> np.ndarray | None:
    if arr is None:
        return None
    a = np.asarray(arr, dtype=float)
    if a.ndim == 1:
        a = a[None, :]
    if a.shape != (d, k):
        raise ValueError(f"{name} has shape {np.shape(arr)}: expected ({k},) or ({d}, {k})")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or inf")
    return np.ascontiguousarray(a)


def simulate(
    axis: Axis | Sequence[Axis],
    reference: Reference,
    *,
    seed: int | None = 0,
    u_force: np.ndarray | None = None,
    u_offset: np.ndarray | None = None,
    x0: float | None = None,
    v0: float | None = None,
) -> SimulationResult:
    """Simulate the axis (or one axis per coordinate) on ``reference``.

    Parameters
    ----------
    axis : Axis or sequence of Axis
        One axis for every coordinate, or one per coordinate of a multi-axis reference.
    reference : Reference
        Sampled at the controller's ``ts``.
    seed : int or None
        Seed of the measurement noise (only drawn when ``noise_std > 0``; the current noise,
        when ``current_noise_std > 0``, is drawn after it from the same generator).
    u_force : ndarray, optional
        Compensation force added at the velocity-loop output, N, shape (K,) or (D, K).
    u_offset : ndarray, optional
        Reference offset (pre-compensation), m, shape (K,) or (D, K).
    x0, v0 : float, optional
        Initial position (m) and velocity (m/s) of every coordinate (default: the reference's
        first sample, plus the offset's, and the reference's velocity).

    Returns
    -------
    SimulationResult
    """
    if not isinstance(reference, Reference):
        raise TypeError(f"reference={reference!r}: expected a Reference")
    d, k = reference.n_axes, reference.n_samples
    axes = [axis] * d if isinstance(axis, Axis) else list(axis)
    if len(axes) != d:
        raise ValueError(f"got {len(axes)} axes for a {d}-axis reference")
    for a in axes:
        if abs(a.controller.ts - reference.ts) > 1e-9 * max(1.0, reference.ts) and k > 1:
            raise ValueError(
                f"reference sampled at ts={reference.ts:g} s but the axis controller runs at "
                f"ts={a.controller.ts:g} s: generate the reference with ts={a.controller.ts:g}"
            )
    rows = (lambda z: np.ascontiguousarray(np.atleast_2d(z), dtype=float))
    xr, vr, ar = rows(reference.x), rows(reference.v), rows(reference.a)
    uf = _as_rows(u_force, d, k, "u_force")
    uo = _as_rows(u_offset, d, k, "u_offset")
    batch = AxisBatch(axes)
    rng = np.random.default_rng(seed)
    if any(a.needs_noise for a in axes):
        noise = rng.standard_normal((d, k + 1))
    else:
        noise = np.zeros((d, k + 1))
    start = xr[:, 0] + (0.0 if uo is None else uo[:, 0])
    speed = vr[:, 0]
    for name, value in (("x0", x0), ("v0", v0)):
        if value is not None and not (isinstance(value, (int, float, np.floating))
                                      and math.isfinite(value)):
            raise ValueError(f"{name}={value!r}: expected a finite number (m, m/s)")
    if x0 is not None:
        start = np.full(d, float(x0))
    if v0 is not None:
        speed = np.full(d, float(v0))
    batch.reset(start, speed, noise[:, 0])
    x_true, x_meas, force, fric = batch.run(xr, vr, ar, uf, uo,
                                            np.ascontiguousarray(noise[:, 1:]))
    i_noise = np.array([a.effects.current_noise_std for a in axes])
    if np.any(i_noise > 0.0):
        kt = np.array([a.controller.kt for a in axes])
        # F_meas = kt (i + n_i), n_i ~ N(0, current_noise_std^2)
        force = force + (kt * i_noise)[:, None] * rng.standard_normal(force.shape)
    squeeze = (lambda z: z[0] if d == 1 else z)
    return SimulationResult(
        t=reference.t, x_ref=squeeze(xr), x=squeeze(x_meas), x_true=squeeze(x_true),
        u=squeeze(force), friction=squeeze(fric), reference=reference, axes=tuple(axes),
        seed=seed,
    )


def simulate_many(axes: Sequence[Axis], references: Sequence[Reference], *,
                  seeds: Sequence[int | None] | None = None) -> list[SimulationResult]:
    """Simulate several single-axis runs (one axis and reference each)."""
    if len(axes) != len(references):
        raise ValueError(f"got {len(axes)} axes and {len(references)} references")
    seeds = list(seeds) if seeds is not None else [0] * len(axes)
    return [simulate(a, r, seed=s) for a, r, s in zip(axes, references, seeds, strict=True)]

"""``AxisBatch``: N axes advanced together by the one kernel; the object every simulator holds."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fricbench.axis import kernel as K
from fricbench.axis.params import Axis

__all__ = ["AxisBatch", "SimulationDivergedError"]


class SimulationDivergedError(FloatingPointError):
    """The simulated state became non-finite or ran away: the loop is unstable."""


def _stability_hint(axis: Axis) -> str:
    c, m = axis.controller, axis.mechanics
    if c.law == "linear":
        return (f"likely cause: the identified linear law does not hold this plant (mass = "
                f"{m.mass:g} kg, kt = {c.kt:g} N/A, ts = {c.ts:g} s; friction: "
                f"{axis.friction.to_dict()})")
    wv = c.kv * c.kt / m.mass
    return (
        f"likely cause: an unstable loop for these parameters (velocity-loop bandwidth "
        f"kv*kt/mass = {wv:.0f} rad/s at ts = {c.ts:g} s gives wv*ts = {wv * c.ts:.2f}; "
        f"keep it below about 0.6, and kp well below the velocity bandwidth, kp = {c.kp:g} 1/s; "
        f"friction: {axis.friction.to_dict()})"
    )


class AxisBatch:
    """``N`` servo axes with their states, stepped by :func:`fricbench.axis.kernel.run_kernel`.

    Parameters
    ----------
    axes : Axis or sequence of Axis
        One axis (replicated ``n`` times) or one per row.
    n : int, optional
        Number of copies when ``axes`` is a single axis (default 1).
    """

    def __init__(self, axes: Axis | Sequence[Axis], n: int | None = None) -> None:
        if isinstance(axes, Axis):
            count = 1 if n is None else int(n)
            if count < 1:
                raise ValueError(f"n={n!r}: expected >= 1")
            self.axes: list[Axis] = [axes] * count
            self.P = np.tile(axes.pack(), (count, 1))
        else:
            self.axes = list(axes)
            if not self.axes or not all(isinstance(a, Axis) for a in self.axes):
                raise TypeError(f"axes={axes!r}: expected an Axis or a non-empty list of Axis")
            if n is not None and n != len(self.axes):
                raise ValueError(f"n={n!r}: does not match len(axes)={len(self.axes)}")
            self.P = np.stack([a.pack() for a in self.axes])
        self.n = self.P.shape[0]
        # every row the same plant row: a stepper may then unpack it once for all rows
        self.uniform = bool(np.all(self.P == self.P[0]))
        self.S = np.zeros((self.n, K.N_STATE))
        self.status = np.zeros(self.n, dtype=np.int64)
        self._out1 = tuple(np.empty((self.n, 1)) for _ in range(4))

    def set_params(self, i: int, axis: Axis) -> None:
        """Replace the parameters of row ``i`` (e.g. friction randomised per episode).

        Rows are changed through this method only (it keeps :attr:`uniform` true).
        """
        self.axes[i] = axis
        self.P[i] = axis.pack()
        if i == 0 or i == -self.n:
            self.uniform = bool(np.all(self.P == self.P[0]))
        else:
            self.uniform = self.uniform and bool(np.array_equal(self.P[i], self.P[0]))

    def reset(self, x0: np.ndarray | float, v0: np.ndarray | float = 0.0,
              noise: np.ndarray | None = None, rows: np.ndarray | None = None) -> None:
        """Put axes (all, or the boolean/int ``rows``) at position ``x0`` and velocity ``v0``."""
        idx = np.arange(self.n) if rows is None else np.flatnonzero(
            np.asarray(rows)) if np.asarray(rows).dtype == bool else np.asarray(rows)
        cnt = idx.shape[0]
        if cnt == 0:
            return
        nz = np.zeros(cnt) if noise is None else np.broadcast_to(noise, (cnt,))
        x0a = np.broadcast_to(np.asarray(x0, dtype=float), (cnt,))
        v0a = np.broadcast_to(np.asarray(v0, dtype=float), (cnt,))
        self.S[idx] = K.initial_state(np.ascontiguousarray(self.P[idx]), x0a, v0a,
                                      np.ascontiguousarray(nz, dtype=float))
        self.status[idx] = K.STATUS_OK

    def run(self, xr: np.ndarray, vr: np.ndarray, ar: np.ndarray,
            u_force: np.ndarray | None = None, u_off: np.ndarray | None = None,
            noise: np.ndarray | None = None,
            out: tuple[np.ndarray, ...] | None = None) -> tuple[np.ndarray, ...]:
        """Advance all axes over ``K`` samples; inputs have shape (N, K).

        Returns
        -------
        x_true, x_meas, force, friction : ndarray, shape (N, K)
            True table position and measured position at each ``t_k`` (m), motor force and mean
            friction force over ``[t_k, t_k+1)`` (N).

        Raises
        ------
        SimulationDivergedError
            At the first non-finite or runaway state, naming the axis, time and likely cause.
        """
        shape = xr.shape
        zeros = np.zeros(shape) if u_force is None or u_off is None or noise is None \
            else xr[:0]
        if out is None:
            out = (np.empty(shape), np.empty(shape), np.empty(shape), np.empty(shape))
        K.run_kernel(self.P, self.S, xr, vr, ar,
                     zeros if u_force is None else u_force,
                     zeros if u_off is None else u_off,
                     zeros if noise is None else noise,
                     (out[0], out[1], out[2], out[3]), self.status)
        if self.status.any():
            bad = int(np.flatnonzero(self.status)[0])
            what = "non-finite" if self.status[bad] == K.STATUS_NONFINITE else "runaway"
            raise SimulationDivergedError(
                f"axis {bad}: {what} state at t = {self.S[bad, K.S_T]:.4f} s "
                f"(x = {self.S[bad, K.S_X]:.3g} m, v = {self.S[bad, K.S_V]:.3g} m/s); "
                + _stability_hint(self.axes[bad])
            )
        return out

    def step(self, xr: np.ndarray, vr: np.ndarray, ar: np.ndarray, u_force: np.ndarray,
             u_off: np.ndarray, noise: np.ndarray) -> tuple[np.ndarray, ...]:
        """One control sample for all axes; inputs have shape (N,), outputs shape (N, 1)."""
        col = (lambda a: a.reshape(self.n, 1))
        return self.run(col(xr), col(vr), col(ar), col(u_force), col(u_off), col(noise),
                        out=self._out1)

    # -- readings of the current state --------------------------------------------------------
    @property
    def position(self) -> np.ndarray:
        """Logged (measured, table) position at the current sample, m, shape (N,)."""
        return self.S[:, K.S_XMEAS]

    @property
    def feedback_position(self) -> np.ndarray:
        """Position the controller reads, m, shape (N,)."""
        return self.S[:, K.S_XFB]

    @property
    def measured_velocity(self) -> np.ndarray:
        """Backward-difference velocity the controller uses, m/s, shape (N,)."""
        return (self.S[:, K.S_XFB] - self.S[:, K.S_XFB_PREV]) / self.P[:, K.P_TS]

    @property
    def true_position(self) -> np.ndarray:
        """True table position (before sensor: play and compliant deflection), m, shape (N,)."""
        return self.S[:, K.S_XPLAY] + self.S[:, K.S_DEF]

    @property
    def velocity(self) -> np.ndarray:
        """True motor-side velocity, m/s, shape (N,)."""
        return self.S[:, K.S_V]

    @property
    def current(self) -> np.ndarray:
        """Applied current of the last sample, A, shape (N,)."""
        return self.S[:, K.S_IAPP]

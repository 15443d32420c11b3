"""A simulated run written out: the CSV ``fricbench diagnose`` reads, its picture, and for a
circle run the ballbar (polar) plot of the radial error."""

from __future__ import annotations

import io
import os
from typing import TYPE_CHECKING

import numpy as np

from fricbench._atomic import atomic_write
from fricbench.axis.ballbar import ballbar_figure as runs_ballbar_figure
from fricbench.axis.ballbar import circle_run
from fricbench.axis.simulate import SimulationResult

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["ballbar_figure", "plot_ballbar", "plot_run", "radial_deviation", "run_figure",
           "write_csv"]


def write_csv(res: SimulationResult, path: str | os.PathLike[str]) -> list[str]:
    """Write ``t,x_ref,x,u [N]`` (s, m, m, N; more axes as ``x_ref_1,x_1,u_1 [N],...``)
    atomically.

    The effort's unit is stated in its column's name, where :func:`fricbench.sysid.io.load_run`
    reads it (the name ``u`` still selects the column); time and positions are in s and m,
    the loader's defaults.

    Returns the column names.
    """
    x_ref, x, u = (np.atleast_2d(a) for a in (res.x_ref, res.x, res.u))
    cols = ["t", "x_ref", "x", "u [N]"]
    data = [res.t, x_ref[0], x[0], u[0]]
    for i in range(1, x_ref.shape[0]):
        cols += [f"x_ref_{i}", f"x_{i}", f"u_{i} [N]"]
        data += [x_ref[i], x[i], u[i]]
    lines = [",".join(cols)]
    lines += [",".join(f"{v:.12g}" for v in row) for row in np.column_stack(data)]
    atomic_write(path, "\n".join(lines) + "\n")
    return cols


def run_figure(res: SimulationResult, title: str) -> Figure:
    """Reference and measured position (mm) above the tracking error (um).

    The measured position is a wide, pale line under the reference, which is a thin black dashed
    line on top: where the axis tracks well, the reference stays visible inside the measured
    trace instead of under it.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 6), dpi=100)
    FigureCanvasAgg(fig)
    a1, a2 = fig.subplots(2, 1, sharex=True)
    x_ref, x, err = (np.atleast_2d(a) for a in (res.x_ref, res.x, res.error))
    for i in range(x_ref.shape[0]):
        color = f"C{i}"
        a1.plot(res.t, x[i] * 1e3, color=color, lw=3.0, alpha=0.45, zorder=2,
                label=f"measured x, axis {i}")
        a1.plot(res.t, x_ref[i] * 1e3, color="k", linestyle=(0, (4, 2)), lw=1.0, zorder=3,
                label="reference x_ref (dashed)" if i == 0 else None)
        # the legend states the maximum of the very curve it names
        a2.plot(res.t, err[i] * 1e6, color=color, lw=1,
                label=f"axis {i} (max |e| {np.abs(err[i]).max() * 1e6:.2f} um)")
    a1.set_ylabel("position [mm]")
    a1.legend(fontsize=8)
    a1.set_title(title)
    a2.set_ylabel("tracking error x_ref - x_true [um]")
    a2.set_xlabel("time [s]")
    a2.legend(fontsize=8)
    a2.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def plot_run(res: SimulationResult, title: str, path: str | os.PathLike[str]) -> None:
    """Write :func:`run_figure` as a PNG (atomically)."""
    _save_png(run_figure(res, title), path)


def _save_png(fig: Figure, path: str | os.PathLike[str]) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    atomic_write(path, buf.getvalue())


def radial_deviation(res: SimulationResult) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What a ballbar reads on a ``circle`` run: angle, radial deviation and sense of rotation.

    The circle is the one :func:`fricbench.trajectories.circle` defines (centre
    ``(-radius, 0)``); the position is the true table position. See
    :func:`fricbench.axis.ballbar.circle_run`, which this unpacks.

    Returns
    -------
    theta : ndarray, shape (K,)
        Angle of the actual position about the centre, rad.
    dr : ndarray, shape (K,)
        Radial deviation ``r - radius``, m (positive: outside the circle).
    sense : ndarray of int, shape (K,)
        +1 counter-clockwise, -1 clockwise (from the reference's angular velocity), 0 at rest.
    """
    run = circle_run(res.reference, np.atleast_2d(res.x_true))
    return run.theta, run.deviation, run.sense


def ballbar_figure(res: SimulationResult, title: str) -> tuple[Figure, float]:
    """The ballbar picture of a circle run: a polar plot of ``R + k (r - R)``.

    The radial deviation is magnified ``k`` times (a 1-2-5 number that brings the largest
    deviation to about 30 % of the radius) so that the quadrant glitches at the axis reversals
    (X at 0 and 180 degrees, Y at 90 and 270) stand out; the scale and the ring spacing in um
    are written on the plot (:func:`fricbench.axis.ballbar.ballbar_figure`). Returns the
    figure and ``k``.
    """
    run = circle_run(res.reference, np.atleast_2d(res.x_true))
    return runs_ballbar_figure({"run": run}, title)


def plot_ballbar(res: SimulationResult, title: str, path: str | os.PathLike[str]) -> float:
    """Write :func:`ballbar_figure` as a PNG; return the magnification ``k``."""
    fig, k = ballbar_figure(res, title)
    _save_png(fig, path)
    return k

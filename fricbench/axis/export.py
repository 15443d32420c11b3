"""A simulated run written out: the CSV ``fricbench diagnose`` reads, and its picture."""

from __future__ import annotations

import io
import os

import numpy as np

from fricbench._atomic import atomic_write
from fricbench.axis.simulate import SimulationResult

__all__ = ["write_csv", "plot_run"]


def write_csv(res: SimulationResult, path: str | os.PathLike[str]) -> list[str]:
    """Write ``t,x_ref,x,u`` (s, m, m, N; more axes as ``x_ref_1,x_1,u_1,...``) atomically.

    Returns the column names.
    """
    x_ref, x, u = (np.atleast_2d(a) for a in (res.x_ref, res.x, res.u))
    cols = ["t", "x_ref", "x", "u"]
    data = [res.t, x_ref[0], x[0], u[0]]
    for i in range(1, x_ref.shape[0]):
        cols += [f"x_ref_{i}", f"x_{i}", f"u_{i}"]
        data += [x_ref[i], x[i], u[i]]
    lines = [",".join(cols)]
    lines += [",".join(f"{v:.12g}" for v in row) for row in np.column_stack(data)]
    atomic_write(path, "\n".join(lines) + "\n")
    return cols


def plot_run(res: SimulationResult, title: str, path: str | os.PathLike[str]) -> None:
    """Reference and measured position (mm) above the tracking error (um), as a PNG."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 6), dpi=100)
    FigureCanvasAgg(fig)
    a1, a2 = fig.subplots(2, 1, sharex=True)
    x_ref, x, err = (np.atleast_2d(a) for a in (res.x_ref, res.x, res.error))
    for i in range(x_ref.shape[0]):
        a1.plot(res.t, x_ref[i] * 1e3, "k--", lw=1, label="reference" if i == 0 else None)
        a1.plot(res.t, x[i] * 1e3, lw=1, label=f"measured axis {i}")
        a2.plot(res.t, err[i] * 1e6, lw=1, label=f"axis {i}")
    a1.set_ylabel("position [mm]")
    a1.legend(fontsize=8)
    a1.set_title(title)
    a2.set_ylabel("tracking error [um]")
    a2.set_xlabel("time [s]")
    a2.grid(alpha=0.3)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    atomic_write(path, buf.getvalue())

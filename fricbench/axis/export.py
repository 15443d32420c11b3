"""A simulated run written out: the CSV ``fricbench diagnose`` reads, its picture, and for a
circle run the ballbar (polar) plot of the radial error."""

from __future__ import annotations

import io
import os
from typing import TYPE_CHECKING, Any

import numpy as np

from fricbench._atomic import atomic_write
from fricbench.axis.simulate import SimulationResult

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["ballbar_figure", "plot_ballbar", "plot_run", "radial_deviation", "write_csv"]


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
        # the legend states the maximum of the very curve it names
        a2.plot(res.t, err[i] * 1e6, lw=1,
                label=f"axis {i} (max |e| {np.abs(err[i]).max() * 1e6:.2f} um)")
    a1.set_ylabel("position [mm]")
    a1.legend(fontsize=8)
    a1.set_title(title)
    a2.set_ylabel("tracking error x_ref - x_true [um]")
    a2.set_xlabel("time [s]")
    a2.legend(fontsize=8)
    a2.grid(alpha=0.3)
    fig.tight_layout()
    _save_png(fig, path)


def _save_png(fig: Figure, path: str | os.PathLike[str]) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    atomic_write(path, buf.getvalue())


def radial_deviation(res: SimulationResult) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What a ballbar reads on a ``circle`` run: angle, radial deviation and sense of rotation.

    The circle is the one :func:`fricbench.trajectories.circle` defines: centre
    ``(-radius, 0)``, nominal radius ``radius`` (from ``res.reference.params``). The position is
    the true table position (a ballbar is its own sensor, it does not read the axis encoders).

    Returns
    -------
    theta : ndarray, shape (K,)
        Angle of the actual position about the centre, rad.
    dr : ndarray, shape (K,)
        Radial deviation ``r - radius``, m (positive: outside the circle).
    sense : ndarray of int, shape (K,)
        +1 counter-clockwise, -1 clockwise (from the reference's angular velocity), 0 at rest.
    """
    ref = res.reference
    if ref.name != "circle" or np.ndim(res.x_true) != 2 or "radius" not in ref.params:
        raise ValueError(f"reference {ref.name!r}: the ballbar plot needs a 'circle' run "
                         "(two axes X, Y)")
    radius = float(ref.params["radius"])
    cx, cy = -radius, 0.0
    x, y = res.x_true[0] - cx, res.x_true[1] - cy
    # dr = |p - c| - R
    dr = np.hypot(x, y) - radius
    theta = np.arctan2(y, x)
    xr, yr = ref.x[0] - cx, ref.x[1] - cy
    # w R^2 = (p_ref - c) x v_ref: the reference's angular velocity times R^2
    w = (xr * ref.v[1] - yr * ref.v[0]) / radius**2
    moving = np.hypot(ref.v[0], ref.v[1]) > 1e-6
    sense = np.where(moving, np.sign(w), 0.0).astype(int)
    return theta, dr, sense


def _nice(x: float) -> float:
    """Largest 1, 2 or 5 times a power of ten not above ``x > 0``."""
    e = np.floor(np.log10(x))
    m = x / 10.0**e
    return float((5.0 if m >= 5.0 else 2.0 if m >= 2.0 else 1.0) * 10.0**e)


def ballbar_figure(res: SimulationResult, title: str) -> tuple[Figure, float]:
    """The ballbar picture of a circle run: a polar plot of ``R + k (r - R)``.

    The radial deviation is magnified ``k`` times (a 1-2-5 number that brings the largest
    deviation to about 30 % of the radius) so that the quadrant glitches at the axis reversals
    (X at 0 and 180 degrees, Y at 90 and 270) stand out; the scale and the ring spacing in um
    are written on the plot. Returns the figure and ``k``.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    theta, dr, sense = radial_deviation(res)
    radius = float(res.reference.params["radius"])
    moving = sense != 0
    dev_max = float(np.abs(dr[moving]).max()) if moving.any() else 0.0
    k = _nice(0.3 * radius / dev_max) if dev_max > 0 else 1.0
    fig = Figure(figsize=(7, 7.4), dpi=100)
    FigureCanvasAgg(fig)
    ax: Any = fig.add_subplot(1, 1, 1, projection="polar")
    ring = np.linspace(0.0, 2.0 * np.pi, 721)
    r_mm = radius * 1e3
    ax.plot(ring, np.full_like(ring, r_mm), "k--", lw=0.8, label=f"nominal R = {r_mm:g} mm")
    for s, name, color in ((1, "counter-clockwise", "tab:blue"), (-1, "clockwise", "tab:red")):
        m = sense == s
        if not m.any():
            continue
        # plotted radius = R + k (r - R)
        ax.plot(theta[m], (radius + k * dr[m]) * 1e3, color=color, lw=1.1,
                label=f"{name}: r - R from {dr[m].min() * 1e6:+.2f} to "
                      f"{dr[m].max() * 1e6:+.2f} um")
    step = _nice(dev_max) if dev_max > 0 else 1e-6
    ticks = np.arange(-2, 3) * step
    ticks = ticks[np.abs(k * ticks) < 0.9 * radius]
    ax.set_rticks((radius + k * ticks) * 1e3)
    ax.set_yticklabels([f"{t * 1e6:+g} um" if t else "0" for t in ticks], fontsize=7)
    ax.set_rlim(0.0, (radius + k * max(2.2 * step, 1.2 * dev_max)) * 1e3)
    ax.set_rlabel_position(45.0)
    ax.set_xticks(np.deg2rad([0, 90, 180, 270]))
    ax.set_xticklabels(["0°\nX reverses", "90°\nY reverses", "180°\nX reverses",
                        "270°\nY reverses"], fontsize=8)
    ax.set_title(title, fontsize=10, pad=18)
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, -0.2), fontsize=8)
    fig.text(0.5, 0.015, f"radial error magnified x{k:g}: plotted radius = R + {k:g} (r - R); "
             f"rings every {step * 1e6:g} um of r - R", ha="center", fontsize=9)
    fig.subplots_adjust(top=0.88, bottom=0.2)
    return fig, k


def plot_ballbar(res: SimulationResult, title: str, path: str | os.PathLike[str]) -> float:
    """Write :func:`ballbar_figure` as a PNG; return the magnification ``k``."""
    fig, k = ballbar_figure(res, title)
    _save_png(fig, path)
    return k

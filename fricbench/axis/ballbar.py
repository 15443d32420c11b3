"""The ballbar test of a circular contour (ISO 230-4; the Renishaw QC20 picture).

A ballbar is a length gauge between a pivot at the circle's centre and the tool: it reads the
radius of the actual path against the angle. Its picture is a polar plot of
``R + k (r - R)``: the nominal circle of radius ``R`` with the radial deviation magnified
``k`` times, so that micrometres show on a circle of millimetres and the quadrant glitches (an
axis reversing where the other crosses a quadrant point: 0, 90, 180 and 270 degrees) stand out.

:func:`radial_deviation` computes what the gauge reads from X-Y positions, :func:`circle_run`
the same for a run of the ``circle`` trajectory with its sense of rotation, and
:func:`ballbar_figure` / :func:`plot_ballbar` draw one run or several side by side (small
multiples at one magnification, so the panels compare by eye).
"""

from __future__ import annotations

import io
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from fricbench._atomic import atomic_write

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from fricbench.trajectories import Reference

__all__ = [
    "BALLBAR_FILL",
    "CircleRun",
    "ballbar_figure",
    "ballbar_magnification",
    "circle_run",
    "plot_ballbar",
    "radial_deviation",
]

BALLBAR_FILL = 0.3
"""The largest radial deviation is magnified to about this fraction of the radius."""

RING_LABEL_ANGLE = 45.0
"""Angle of the ring labels, degrees: midway between the quadrant points, where the path is
calm."""

REST_SPEED = 1e-6
"""Reference path speed below which a sample is at rest (no sense of rotation), m/s."""


def _vector(name: str, value: object) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{name}={value!r}: expected a 1-D array of positions in m") from None
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} has shape {arr.shape}: expected a non-empty 1-D array of "
                         "positions in m")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf: expected finite positions in m")
    return arr


def _positive(name: str, value: object, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name}={value!r}: expected a number, {unit}")
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{name}={value!r}: expected a finite number > 0, {unit}")
    return v


def radial_deviation(x: np.ndarray, y: np.ndarray, center: Sequence[float],
                     radius: float) -> tuple[np.ndarray, np.ndarray]:
    """What a ballbar reads: the angle and the radial deviation of a path about a circle.

    Parameters
    ----------
    x, y : array_like, shape (K,)
        Actual positions of the X and Y axes, m.
    center : sequence of two floats
        Centre of the nominal circle (the ballbar's pivot), ``(cx, cy)`` in m.
    radius : float
        Nominal radius ``R``, m, > 0.

    Returns
    -------
    theta : ndarray, shape (K,)
        Angle of each position about ``center``, rad, in ``(-pi, pi]`` (0 along +X).
    deviation : ndarray, shape (K,)
        ``r - R``, m: positive outside the nominal circle. The centre is the one given (no
        least-squares centring is removed, unlike a ballbar's circularity report).

    Raises
    ------
    ValueError
        ``x`` or ``y`` not a non-empty 1-D finite array, of different lengths; ``center`` not
        two finite numbers; ``radius`` not finite and > 0.
    TypeError
        A value that is not numeric.
    """
    xs, ys = _vector("x", x), _vector("y", y)
    if xs.shape != ys.shape:
        raise ValueError(f"x has {xs.size} samples and y {ys.size}: expected the same number")
    try:
        c = np.asarray(center, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"center={center!r}: expected two numbers (cx, cy) in m") from None
    if c.shape != (2,) or not np.all(np.isfinite(c)):
        raise ValueError(f"center={center!r}: expected two finite numbers (cx, cy) in m")
    r_nom = _positive("radius", radius, "m")
    dx, dy = xs - c[0], ys - c[1]
    # dr = |p - c| - R
    return np.arctan2(dy, dx), np.hypot(dx, dy) - r_nom


@dataclass(frozen=True)
class CircleRun:
    """A circle run as a ballbar reads it (SI units).

    Attributes
    ----------
    theta : ndarray, shape (K,)
        Angle of the actual position about the centre, rad.
    deviation : ndarray, shape (K,)
        Radial deviation ``r - radius``, m (positive: outside the circle).
    sense : ndarray of int, shape (K,)
        +1 counter-clockwise, -1 clockwise (the reference's), 0 where the reference rests.
    radius : float
        Nominal radius, m.
    center : tuple of float
        Centre of the nominal circle, m.
    """

    theta: np.ndarray
    deviation: np.ndarray
    sense: np.ndarray
    radius: float
    center: tuple[float, float]

    @property
    def moving(self) -> np.ndarray:
        """Samples where the reference moves (the ones a ballbar test records)."""
        return self.sense != 0

    @property
    def max_deviation(self) -> float:
        """Largest ``|r - R|`` while moving, m (0 for a run that never moves)."""
        m = self.moving
        return float(np.abs(self.deviation[m]).max()) if m.any() else 0.0


def circle_run(reference: Reference, position: np.ndarray) -> CircleRun:
    """The ballbar reading of a run of the ``circle`` trajectory.

    The nominal circle is the one :func:`fricbench.trajectories.circle` draws: centre
    ``(-radius, 0)``, radius ``reference.params["radius"]``. ``position`` is the actual
    position, shape (2, K), rows X and Y, m: the true table position (a ballbar is its own
    sensor, it does not read the axis encoders).

    Raises
    ------
    ValueError
        ``reference`` not a two-axis ``circle`` with its radius, or ``position`` not of the
        reference's shape.
    """
    if getattr(reference, "name", None) != "circle" or np.ndim(reference.x) != 2 \
            or "radius" not in reference.params:
        raise ValueError(f"reference {getattr(reference, 'name', reference)!r}: the ballbar "
                         "plot needs a 'circle' run (two axes X, Y)")
    pos = np.asarray(position, dtype=float)
    if pos.shape != reference.x.shape:
        raise ValueError(f"position has shape {pos.shape}: expected {reference.x.shape}, the "
                         "reference's (rows X and Y)")
    radius = float(reference.params["radius"])
    cx, cy = -radius, 0.0
    theta, dr = radial_deviation(pos[0], pos[1], (cx, cy), radius)
    xr, yr = reference.x[0] - cx, reference.x[1] - cy
    vx, vy = reference.v[0], reference.v[1]
    # w R^2 = (p_ref - c) x v_ref: the reference's angular velocity times R^2
    w = xr * vy - yr * vx
    sense = np.where(np.hypot(vx, vy) > REST_SPEED, np.sign(w), 0.0).astype(int)
    return CircleRun(theta, dr, sense, radius, (cx, cy))


def _nice(x: float) -> float:
    """Largest 1, 2 or 5 times a power of ten not above ``x > 0``."""
    e = math.floor(math.log10(x))
    m = x / 10.0**e
    return float((5.0 if m >= 5.0 else 2.0 if m >= 2.0 else 1.0) * 10.0**e)


def ballbar_magnification(max_deviation: float, radius: float,
                          fill: float = BALLBAR_FILL) -> float:
    """The magnification ``k`` of a ballbar plot: a 1-2-5 number that brings the largest radial
    deviation to at most ``fill`` of the radius (and not less than 40 % of that).

    ``max_deviation`` (m, >= 0; 0 gives ``k = 1``), ``radius`` (m, > 0), ``fill`` in (0, 1].
    """
    if isinstance(max_deviation, bool) or not isinstance(
            max_deviation, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(float(max_deviation)) and max_deviation >= 0.0):
        raise ValueError(f"max_deviation={max_deviation!r}: expected a finite number >= 0, m")
    r_nom = _positive("radius", radius, "m")
    f = _positive("fill", fill, "a fraction of the radius")
    if f > 1.0:
        raise ValueError(f"fill={fill!r}: expected a fraction of the radius in (0, 1]")
    return _nice(f * r_nom / float(max_deviation)) if max_deviation > 0 else 1.0


_SENSES = ((1, "counter-clockwise", "tab:blue"), (-1, "clockwise", "tab:red"))


def _panel(ax: Any, run: CircleRun, k: float, step: float, span: float, title: str,
           baseline: tuple[str, CircleRun] | None, legend: bool) -> None:
    """One polar panel: nominal circle, the baseline in grey, the run by sense."""
    ring = np.linspace(0.0, 2.0 * np.pi, 721)
    r_mm = run.radius * 1e3
    ax.plot(ring, np.full_like(ring, r_mm), "k--", lw=0.7, label=f"nominal R = {r_mm:g} mm")
    if baseline is not None:
        name, base = baseline
        m = base.moving
        ax.plot(base.theta[m], (base.radius + k * base.deviation[m]) * 1e3, color="0.7",
                lw=0.8, label=f"{name} (both senses)")
    for s, name, color in _SENSES:
        m = run.sense == s
        if not m.any():
            continue
        # plotted radius = R + k (r - R)
        ax.plot(run.theta[m], (run.radius + k * run.deviation[m]) * 1e3, color=color, lw=1.0,
                label=f"{name}: r - R from {run.deviation[m].min() * 1e6:+.2f} to "
                      f"{run.deviation[m].max() * 1e6:+.2f} um")
    n_ticks = np.arange(-2, 3)
    ticks = n_ticks * step
    keep = np.abs(k * ticks) < 0.9 * run.radius
    n_ticks, ticks = n_ticks[keep], ticks[keep]
    ax.set_rticks((run.radius + k * ticks) * 1e3)
    ax.set_rlim(0.0, (run.radius + k * span) * 1e3)
    # the ring labels are texts of their own, not tick labels (each ring is drawn after the
    # previous ring's label and struck it out): centred on their ring at 45 degrees, between
    # the quadrant glitches, on an opaque patch above the rings and the traces. A small panel
    # labels every other ring: the labels would overlap
    ax.set_yticklabels([])
    for n, t in zip(n_ticks, ticks, strict=True):
        if legend or n % 2 == 0:
            ax.text(np.deg2rad(RING_LABEL_ANGLE), (run.radius + k * t) * 1e3,
                    "0" if not t else f"{t * 1e6:+g} um", fontsize=7, ha="center",
                    va="center", zorder=6.0, gid="ring-label",
                    bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.9, "pad": 0.8})
    ax.set_xticks(np.deg2rad([0, 90, 180, 270]))
    if legend:
        ax.set_xticklabels(["0°\nX reverses", "90°\nY reverses", "180°\nX reverses",
                            "270°\nY reverses"], fontsize=8)
    else:
        ax.set_xticklabels(["0°", "90°", "180°", "270°"], fontsize=7)
    ax.set_title(title, fontsize=9 if legend else 8, pad=14 if legend else 8)


def ballbar_figure(runs: Mapping[str, CircleRun], title: str, *,
                   baseline: str | None = None,
                   magnification: float | None = None) -> tuple[Figure, float]:
    """The ballbar picture: a polar plot of ``R + k (r - R)`` per run, at one magnification.

    One run is drawn alone with a legend per sense of rotation; several are small multiples,
    one panel each with its range of ``r - R`` in its title. ``k`` (a 1-2-5 number, see
    :func:`ballbar_magnification`, unless ``magnification`` is given) brings the largest
    deviation of all runs to about 30 % of the radius; it and the ring spacing in um are
    written on the figure.

    Parameters
    ----------
    runs : mapping of str to CircleRun
        Label -> run (insertion order is panel order); at least one, with the same radius.
    title : str
        Figure title.
    baseline : str, optional
        Label of a run drawn in grey behind each other panel, for comparison (``"none"``).
    magnification : float, optional
        ``k`` to use instead of the one chosen from the data (> 0).

    Returns
    -------
    fig : matplotlib.figure.Figure
    k : float
        The magnification used.

    Raises
    ------
    ValueError
        No run, runs of different radii, a ``baseline`` that is not a label of ``runs``, or a
        ``magnification`` that is not finite and > 0.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if not runs:
        raise ValueError("runs={}: expected at least one circle run")
    for label, run in runs.items():
        if not isinstance(run, CircleRun):
            raise TypeError(f"runs[{label!r}]={type(run).__name__}: expected a CircleRun "
                            "(fricbench.axis.ballbar.circle_run)")
    radii = {run.radius for run in runs.values()}
    if len(radii) > 1:
        raise ValueError(f"runs have radii {sorted(radii)} m: expected one nominal circle")
    radius = radii.pop()
    if baseline is not None and baseline not in runs:
        raise ValueError(f"baseline={baseline!r}: not one of the runs ({', '.join(runs)})")
    dev_max = max(run.max_deviation for run in runs.values())
    k = (ballbar_magnification(dev_max, radius) if magnification is None
         else _positive("magnification", magnification, "a factor"))
    step = _nice(dev_max) if dev_max > 0 else 1e-6
    span = max(2.2 * step, 1.2 * dev_max)
    n = len(runs)
    height = 7.4
    if n == 1:
        fig = Figure(figsize=(7, height), dpi=100)
        FigureCanvasAgg(fig)
        ((label, run),) = runs.items()
        ax: Any = fig.add_subplot(1, 1, 1, projection="polar")
        _panel(ax, run, k, step, span, title, None, legend=True)
        ax.legend(loc="lower center", bbox_to_anchor=(0.5, -0.2), fontsize=8)
        fig.subplots_adjust(top=0.88, bottom=0.2)
    else:
        cols = math.ceil(math.sqrt(n))
        rows = math.ceil(n / cols)
        height = 3.4 * rows + 1.1
        fig = Figure(figsize=(max(3.4 * cols, 9.0), height), dpi=100)
        FigureCanvasAgg(fig)
        base = (baseline, runs[baseline]) if baseline is not None else None
        for i, (label, run) in enumerate(runs.items()):
            ax = fig.add_subplot(rows, cols, i + 1, projection="polar")
            m = run.moving
            lo, hi = ((run.deviation[m].min(), run.deviation[m].max()) if m.any()
                      else (0.0, 0.0))
            _panel(ax, run, k, step, span,
                   f"{label}\nr - R {lo * 1e6:+.1f} .. {hi * 1e6:+.1f} um",
                   base if base is not None and label != base[0] else None, legend=False)
        fig.suptitle(title, fontsize=10, y=1.0 - 0.12 / height)
        senses = "blue counter-clockwise, red clockwise"
        grey = f"; grey: {baseline}" if baseline is not None else ""
        fig.text(0.5, 0.3 / height, f"{senses}{grey}; dashed: nominal circle R = "
                 f"{radius * 1e3:g} mm; X reverses at 0° and 180°, Y at 90° and 270°",
                 ha="center", fontsize=8)
        fig.subplots_adjust(top=1.0 - 1.0 / height, bottom=0.75 / height, hspace=0.5,
                            wspace=0.3, left=0.04, right=0.96)
    fig.text(0.5, 0.08 / (height if n > 1 else 7.4),
             f"radial deviation magnified x{k:g}: plotted radius = R + {k:g} (r - R); scale: "
             f"rings every {step * 1e6:g} um of r - R", ha="center", fontsize=9)
    return fig, k


def plot_ballbar(runs: Mapping[str, CircleRun], title: str, path: str | os.PathLike[str], *,
                 baseline: str | None = None, magnification: float | None = None) -> float:
    """Write :func:`ballbar_figure` as a PNG (atomically); return the magnification ``k``."""
    fig, k = ballbar_figure(runs, title, baseline=baseline, magnification=magnification)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    atomic_write(path, buf.getvalue())
    return k

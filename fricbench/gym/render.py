"""Matplotlib frames for ``ServoAxisEnv.render()``: what a student needs to see of an episode.

Four panels: reference and actual position, tracking error, reference and actual velocity (all
against time, with a time cursor), and the friction force against velocity: the friction
model's steady-state curve ``F(v)`` (the Stribeck curve) drawn once per episode, with the axis's
operating point (velocity, mean friction force of the last sample) moving on it.

Speed: one figure per env, reused. Everything that does not change during an episode (axes,
reference traces, the friction curve) is drawn once into a background; a frame restores that
background and draws only the moving artists (blitting), then reads the Agg buffer. A full
redraw happens only when the error leaves its current y-range (the range grows by half) or the
figure is resized. ``python -m fricbench.gym.render_benchmark`` measures the ms per frame.
"""

from __future__ import annotations

import os
import sys
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from fricbench.friction import FrictionModel

__all__ = ["AxisFigure", "EpisodeTrace", "display_available", "HEADLESS_HUMAN_WARNING"]

HEADLESS_HUMAN_WARNING = (
    "render_mode='human' on a machine without a display (no DISPLAY / WAYLAND_DISPLAY, or "
    "a non-interactive matplotlib backend; backend: {backend}): nothing will be shown, the frames "
    "are drawn off-screen and dropped. Use render_mode='rgb_array' and keep the frames "
    "env.render() returns (for instance with gymnasium.wrappers.RecordVideo), or run where "
    "a display is available."
)

# Trail of the operating point on the friction curve, s of simulated time.
TRAIL_S = 0.2


@dataclass
class EpisodeTrace:
    """What an episode has done so far, sample by sample (arrays preallocated at reset).

    Attributes
    ----------
    t : ndarray, shape (K,)
        Sample times, s.
    x_ref, v_ref : ndarray, shape (D, K)
        Reference position (m) and velocity (m/s) of the whole episode.
    x : ndarray, shape (D, K)
        Measured position, m.
    error : ndarray, shape (D, K)
        True tracking error ``x_ref - x_true``, m.
    v : ndarray, shape (D, K)
        True axis velocity, m/s.
    friction : ndarray, shape (D, K)
        Mean friction force over the sample that ended at ``t_k``, N (0 at ``k = 0``).
    friction_model : FrictionModel
        The episode's friction law (the curve drawn under the operating point).
    k : int
        Index of the last recorded sample.
    """

    t: np.ndarray
    x_ref: np.ndarray
    v_ref: np.ndarray
    x: np.ndarray
    error: np.ndarray
    v: np.ndarray
    friction: np.ndarray
    friction_model: FrictionModel
    k: int = -1

    @classmethod
    def start(cls, t: np.ndarray, x_ref: np.ndarray, v_ref: np.ndarray,
              friction_model: FrictionModel) -> EpisodeTrace:
        """Empty trace of an episode with reference ``x_ref``, ``v_ref`` of shape (D, K)."""
        shape = x_ref.shape
        return cls(t, x_ref, v_ref, np.zeros(shape), np.zeros(shape), np.zeros(shape),
                   np.zeros(shape), friction_model)

    def record(self, k: int, x: np.ndarray, error: np.ndarray, v: np.ndarray,
               friction: np.ndarray) -> None:
        """Store sample ``k`` (each argument of shape (D,), SI units)."""
        self.x[:, k] = x
        self.error[:, k] = error
        self.v[:, k] = v
        self.friction[:, k] = friction
        self.k = k


def display_available() -> tuple[bool, str]:
    """Whether a matplotlib window can be shown here, and the backend's name.

    False without ``DISPLAY`` / ``WAYLAND_DISPLAY`` on Linux and the BSDs (pyplot is then not
    imported, so no GUI toolkit is touched), or when matplotlib's backend is non-interactive.
    """
    if sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")) and not (
            os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return False, "none: no DISPLAY or WAYLAND_DISPLAY"
    import matplotlib.pyplot as plt
    from matplotlib.backends import BackendFilter, backend_registry

    backend = str(plt.get_backend())
    interactive = backend.lower() in {
        b.lower() for b in backend_registry.list_builtin(BackendFilter.INTERACTIVE)}
    return interactive, backend


class AxisFigure:
    """One reusable figure that draws :class:`EpisodeTrace` frames.

    Parameters
    ----------
    window : bool
        Draw into a pyplot window (``render_mode="human"`` with a display); otherwise into an
        off-screen Agg canvas.
    blit : bool
        Redraw only the moving artists over a saved background (default). ``False`` redraws the
        whole figure every frame (the slow path, kept for the benchmark).
    """

    def __init__(self, *, window: bool = False, blit: bool = True) -> None:
        self.window = window
        self.blit = blit
        self.frames_drawn = 0
        self.full_redraws = 0
        if window:
            import matplotlib.pyplot as plt

            self.fig = plt.figure(figsize=(8, 5.6), dpi=80)
            plt.show(block=False)
        else:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            self.fig = Figure(figsize=(8, 5.6), dpi=80)
            FigureCanvasAgg(self.fig)
        self._trace: EpisodeTrace | None = None
        self._bg: Any = None
        self._moving: list[Any] = []
        self.fig.canvas.mpl_connect("draw_event", self._on_draw)

    # -- episode setup --------------------------------------------------------------------------
    def _setup(self, tr: EpisodeTrace) -> None:
        """Lay out the axes and draw what stays fixed during the episode."""
        from matplotlib.ticker import FuncFormatter

        fig = self.fig
        fig.clf()
        self._trace = tr
        d = tr.x_ref.shape[0]
        colors = ["tab:blue", "tab:orange", "tab:green", "tab:red"]
        ax_x, ax_v, ax_e, ax_f = (fig.add_subplot(2, 2, i) for i in (1, 2, 3, 4))
        ax_v.sharex(ax_x)
        ax_e.sharex(ax_x)
        t_end = float(tr.t[-1]) if tr.t.size > 1 else 1.0
        ax_x.set_xlim(0.0, t_end)
        self.lines_x, self.lines_e, self.lines_v, self.points, self.trails = [], [], [], [], []
        self.cursors = []
        for j in range(d):
            c = colors[j % len(colors)]
            name = "XYZW"[j] if d > 1 else "axis"
            ax_x.plot(tr.t, tr.x_ref[j] * 1e3, "k--", lw=0.8,
                      label="reference" if j == 0 else None)
            ax_v.plot(tr.t, tr.v_ref[j] * 1e3, "k--", lw=0.8)
            self.lines_x.append(ax_x.plot([], [], color=c, lw=1.2, animated=True,
                                          label=f"actual {name}")[0])
            self.lines_v.append(ax_v.plot([], [], color=c, lw=1.0, animated=True)[0])
            self.lines_e.append(ax_e.plot([], [], color=c, lw=1.0, animated=True,
                                          label=name)[0])
            self.trails.append(ax_f.plot([], [], color=c, lw=0.8, alpha=0.6,
                                         animated=True)[0])
            self.points.append(ax_f.plot([], [], "o", color=c, ms=7, animated=True,
                                         label=f"operating point {name}" if d > 1 else
                                         "operating point")[0])
        for ax in (ax_x, ax_v, ax_e):
            self.cursors.append(ax.axvline(0.0, color="tab:red", lw=0.8, animated=True))
            ax.grid(alpha=0.3)
        pad = (lambda lo, hi: (lo - 0.08 * (hi - lo + 1e-9), hi + 0.08 * (hi - lo + 1e-9)))
        ax_x.set_ylim(*pad(tr.x_ref.min() * 1e3, tr.x_ref.max() * 1e3))
        ax_v.set_ylim(*pad(tr.v_ref.min() * 1e3, tr.v_ref.max() * 1e3))
        ax_x.set_ylabel("position [mm]")
        ax_x.set_xlabel("time [s]")
        ax_x.legend(loc="best", fontsize=7)
        ax_v.set_ylabel("velocity [mm/s]")
        ax_v.set_title("velocity (dashed: reference)", fontsize=9)
        ax_e.set_ylabel("tracking error [um]")
        ax_e.set_xlabel("time [s]")
        ax_v.set_xlabel("time [s]")
        self._err_lim = 5.0
        ax_e.set_ylim(-self._err_lim, self._err_lim)
        # the friction law, once: F(v) over the reference's speed range, symlog in v so the
        # Stribeck dip (|v| of a few vs) and the cruising speed are both readable
        kp = tr.friction_model.kernel_params()
        v_max = max(float(np.abs(tr.v_ref).max()) * 1.3, 1e-4)
        lin = kp["vs"] if kp["vs"] > 0 else 0.02 * v_max
        lin = min(lin, 0.5 * v_max)
        v = np.concatenate([-np.geomspace(v_max, lin * 1e-2, 200), [0.0],
                            np.geomspace(lin * 1e-2, v_max, 200)])
        f = tr.friction_model.force(v)
        (self.curve,) = ax_f.plot(v * 1e3, f, color="0.3", lw=1.5,
                                  label=f"{tr.friction_model.id} law F(v), steady state")
        ax_f.set_xscale("symlog", linthresh=lin * 1e3, linscale=0.5)
        ax_f.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
        ax_f.set_xlim(-v_max * 1e3, v_max * 1e3)
        f_abs = max(float(np.abs(f).max()), tr.friction_model.breakaway_force, 1.0)
        ax_f.set_ylim(-1.5 * f_abs, 1.5 * f_abs)
        ax_f.axhline(0.0, color="0.7", lw=0.5)
        ax_f.axvline(0.0, color="0.7", lw=0.5)
        ax_f.set_xlabel("velocity [mm/s] (symlog)")
        ax_f.set_ylabel("friction force [N]")
        ax_f.set_title("friction vs velocity (Stribeck curve)", fontsize=9)
        ax_f.legend(loc="upper left", fontsize=7)
        ax_f.grid(alpha=0.3)
        # the time is read off the red cursor: a changing text label would cost ~7 ms a frame
        fig.tight_layout()
        self.ax_e = ax_e
        self._moving = [*self.lines_x, *self.lines_v, *self.lines_e, *self.trails,
                        *self.points, *self.cursors]
        for a in self._moving:
            a.set_animated(self.blit)
        ts = float(tr.t[1] - tr.t[0]) if tr.t.size > 1 else 1.0
        self._trail_n = max(2, int(round(TRAIL_S / ts)))
        self._bg = None

    # -- frames ----------------------------------------------------------------------------------
    def _on_draw(self, event: Any) -> None:
        """After a full draw (ours, a resize, a zoom): save the background for blitting."""
        if self.blit and self._moving:
            canvas: Any = self.fig.canvas
            self._bg = canvas.copy_from_bbox(self.fig.bbox)
            self._draw_moving()

    def _draw_moving(self) -> None:
        for a in self._moving:
            self.fig.draw_artist(a)

    def _update(self, tr: EpisodeTrace) -> bool:
        """Move the artists to sample ``tr.k``; True when the error's y-range had to grow."""
        k = tr.k
        n = k + 1
        t = tr.t[:n]
        for j in range(tr.x.shape[0]):
            self.lines_x[j].set_data(t, tr.x[j, :n] * 1e3)
            self.lines_v[j].set_data(t, tr.v[j, :n] * 1e3)
            self.lines_e[j].set_data(t, tr.error[j, :n] * 1e6)
            lo = max(0, n - self._trail_n)
            self.trails[j].set_data(tr.v[j, lo:n] * 1e3, tr.friction[j, lo:n])
            self.points[j].set_data([tr.v[j, k] * 1e3], [tr.friction[j, k]])
        tk = float(tr.t[k])
        for c in self.cursors:
            c.set_xdata([tk, tk])
        e_max = float(np.abs(tr.error[:, :n]).max()) * 1e6
        if e_max > self._err_lim:
            self._err_lim = 1.5 * e_max
            self.ax_e.set_ylim(-self._err_lim, self._err_lim)
            return True
        return False

    def draw(self, tr: EpisodeTrace) -> np.ndarray | None:
        """Draw sample ``tr.k`` of ``tr``; the RGB frame (H, W, 3) uint8, or None in a window."""
        if tr is not self._trace:
            self._setup(tr)
        rescaled = self._update(tr)
        canvas: Any = self.fig.canvas
        if not self.blit or self._bg is None or rescaled:
            # blit: the draw_event saves the background and draws the moving artists over it
            canvas.draw()
            self.full_redraws += 1
        else:
            canvas.restore_region(self._bg)
            self._draw_moving()
            if self.window:
                canvas.blit(self.fig.bbox)
        self.frames_drawn += 1
        if self.window:
            canvas.flush_events()
            return None
        rgba = np.asarray(canvas.buffer_rgba())
        frame = np.empty(rgba.shape[:2] + (3,), dtype=np.uint8)
        # one channel at a time: about 10x faster than rgba[..., :3].copy() (5 ms at 640x448)
        for c in range(3):
            frame[..., c] = rgba[..., c]
        return frame

    def close(self) -> None:
        """Close the window (if any) and drop the figure."""
        if self.window:
            import matplotlib.pyplot as plt

            plt.close(self.fig)
        self._trace = None
        self._bg = None


def warn_headless(backend: str) -> None:
    """The one warning for ``render_mode="human"`` without a display."""
    warnings.warn(HEADLESS_HUMAN_WARNING.format(backend=backend), UserWarning, stacklevel=4)

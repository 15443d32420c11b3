"""Matplotlib frames for ``render()``: reference vs actual position and the error trace."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["draw_episode"]


def draw_episode(history: dict[str, list[np.ndarray]], fig: Any,
                 human: bool) -> tuple[np.ndarray | None, Any]:
    """Draw the episode so far; return an RGB frame (rgb_array) or None (human) and the figure."""
    if human:
        import matplotlib.pyplot as plt

        if fig is None:
            plt.ion()
            fig = plt.figure(figsize=(7, 5))
    elif fig is None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(figsize=(7, 5), dpi=80)
        FigureCanvasAgg(fig)
    fig.clf()
    ax_pos, ax_err = fig.subplots(2, 1, sharex=True)
    t = np.asarray(history["t"])
    xr = np.asarray(history["x_ref"]) * 1e3
    x = np.asarray(history["x"]) * 1e3
    err = np.asarray(history["error"]) * 1e6
    for j in range(xr.shape[1] if xr.ndim == 2 else 0):
        ax_pos.plot(t, xr[:, j], "k--", lw=1, label="reference" if j == 0 else None)
        ax_pos.plot(t, x[:, j], lw=1.2, label=f"actual axis {j}")
        ax_err.plot(t, err[:, j], lw=1, label=f"axis {j}")
    ax_pos.set_ylabel("position [mm]")
    ax_pos.legend(loc="upper right", fontsize=8)
    ax_err.set_ylabel("tracking error [um]")
    ax_err.set_xlabel("time [s]")
    ax_err.grid(alpha=0.3)
    fig.tight_layout()
    if human:
        import matplotlib.pyplot as plt

        plt.pause(0.001)
        return None, fig
    fig.canvas.draw()
    frame = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    return frame, fig

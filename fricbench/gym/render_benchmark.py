"""Milliseconds per ``render()`` frame, against references measured in the same run.

Run ``python -m fricbench.gym.render_benchmark [--frames N] [--env ID] [--trajectory ID]``.
One episode is stepped with zero action; a frame is drawn every ``1 / render_fps`` s of
simulated time (as human mode does) until ``N`` frames, by three drawers on the same trace:

* ``blit``: ``env.render()`` as shipped (reused figure, background restored, moving artists
  drawn; a full redraw only when the error range grows);
* ``full redraw, same picture``: the same figure with blitting off (``canvas.draw()`` a frame);
* ``old full redraw``: the renderer before this module (``fig.clf()`` and every axis rebuilt
  each frame, two panels), kept here only as the reference.

Speed is measured here, not in timed tests (timings depend on the machine's load; the ratio
of the lines is what carries over).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["main", "old_full_redraw"]


def old_full_redraw(t: np.ndarray, x_ref: np.ndarray, x: np.ndarray, err: np.ndarray,
                    fig: Any) -> tuple[np.ndarray, Any]:
    """The frame of the renderer this one replaced (reference only): rebuild and draw all."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if fig is None:
        fig = Figure(figsize=(7, 5), dpi=80)
        FigureCanvasAgg(fig)
    fig.clf()
    ax_pos, ax_err = fig.subplots(2, 1, sharex=True)
    for j in range(x_ref.shape[0]):
        ax_pos.plot(t, x_ref[j] * 1e3, "k--", lw=1, label="reference" if j == 0 else None)
        ax_pos.plot(t, x[j] * 1e3, lw=1.2, label=f"actual axis {j}")
        ax_err.plot(t, err[j] * 1e6, lw=1, label=f"axis {j}")
    ax_pos.set_ylabel("position [mm]")
    ax_pos.legend(loc="upper right", fontsize=8)
    ax_err.set_ylabel("tracking error [um]")
    ax_err.set_xlabel("time [s]")
    ax_err.grid(alpha=0.3)
    fig.tight_layout()
    canvas: Any = fig.canvas
    canvas.draw()
    frame = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    return frame, fig


def _time(draw: Callable[[int], object], ks: list[int],
          step_to: Callable[[int], None]) -> np.ndarray:
    out = []
    for k in ks:
        step_to(k)
        t0 = time.perf_counter()
        draw(k)
        out.append(time.perf_counter() - t0)
    return np.asarray(out) * 1e3


def main(argv: list[str] | None = None) -> int:
    """Print ms per frame of the shipped renderer and of the two full-redraw references."""
    p = argparse.ArgumentParser(prog="python -m fricbench.gym.render_benchmark",
                                description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--env", default="fricbench/PaperAxis-v0")
    p.add_argument("--trajectory", default="s_curve")
    p.add_argument("--frames", type=int, default=40, help="frames per drawer (default 40)")
    args = p.parse_args(argv)
    if args.frames < 1:
        p.error(f"--frames={args.frames}: expected >= 1")

    import gymnasium as gym

    import fricbench.gym  # noqa: F401  (registers the envs)
    from fricbench.gym.render import AxisFigure

    env = gym.make(args.env, render_mode="rgb_array")
    base: Any = env.unwrapped
    env.reset(seed=0, options={"trajectory": args.trajectory})
    n = base.reference.n_samples
    every = max(1, int(round(1.0 / (base.metadata["render_fps"] * base.ts))))
    ks = [min(i * every, n - 1) for i in range(args.frames)]
    zero = np.zeros(base.n_axes, dtype=np.float32)

    def step_to(k: int) -> None:
        while base._k < k:
            env.step(zero)

    env.render()  # first frame: layout and background, not counted
    ms_blit = _time(lambda k: env.render(), ks, step_to)
    tr = base._trace
    slow = AxisFigure(blit=False)
    slow.draw(tr)
    ms_full = _time(lambda k: slow.draw(tr), ks, lambda k: None)
    fig: Any = None

    def old(k: int) -> None:
        nonlocal fig
        sl = slice(0, k + 1)
        _, fig = old_full_redraw(tr.t[sl], tr.x_ref[:, sl], tr.x[:, sl], tr.error[:, sl], fig)

    old(ks[0])
    ms_old = _time(old, ks, lambda k: None)
    h, w, _ = base.render().shape
    print(f"render() frame time, {args.env} on {args.trajectory}: {args.frames} frames, one "
          f"every {every * base.ts * 1e3:.0f} ms of simulated time (render_fps "
          f"{base.metadata['render_fps']}), {w}x{h} px, Agg")
    for name, ms in (("blit (shipped)", ms_blit), ("full redraw, same picture", ms_full),
                     ("old full redraw (reference)", ms_old)):
        print(f"  {name:<28s} median {np.median(ms):7.2f} ms/frame   mean {ms.mean():7.2f}   "
              f"x{np.median(ms_old) / np.median(ms):5.1f} vs old")
    print(f"  full redraws inside the blit run: {base._fig.full_redraws - 1} (error range grew)")
    env.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The quadrant glitch: an ISO 230-4 circle test on two axes with and without friction,
radial deviation magnified. Writes docs/img/quadrant_glitch.png."""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from fricbench.axis import Axis, simulate
from fricbench.trajectories import make_trajectory


def main(out: str = "docs/img/quadrant_glitch.png") -> None:
    ref = make_trajectory("circle", direction="ccw")
    centre = 0.5 * (ref.x.max(axis=1) + ref.x.min(axis=1))
    radius = 0.5 * (ref.x[0].max() - ref.x[0].min())
    gain = 200.0  # radial magnification of the plot
    fig = plt.figure(figsize=(6.5, 6.5))
    ax = fig.add_subplot(1, 1, 1)
    th = np.linspace(0, 2 * np.pi, 400)
    ax.plot(np.cos(th), np.sin(th), "k--", lw=0.8, label="reference")
    for label, axis in (("with Stribeck friction", Axis()),
                        ("without friction", Axis().without_friction())):
        res = simulate(axis, ref)
        dx, dy = res.x_true[0] - centre[0], res.x_true[1] - centre[1]
        r = np.hypot(dx, dy)
        ang = np.arctan2(dy, dx)
        moving = np.hypot(*ref.v) > 1e-6
        rr = 1.0 + gain * (r - radius) / radius
        ax.plot((rr * np.cos(ang))[moving], (rr * np.sin(ang))[moving], lw=1.2,
                label=f"{label} (dev. {np.ptp((r - radius)[moving]) * 1e6:.1f} um)")
    ax.set_aspect("equal")
    ax.set_title(f"Circle R = {radius * 1e3:.0f} mm: radial deviation x{gain:.0f}\n"
                 "spikes where an axis reverses (quadrant glitches)")
    ax.legend(loc="lower left", fontsize=8)
    ax.axis("off")
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])

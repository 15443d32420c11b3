"""Stick-slip at low velocity: the paper axis with a softened velocity loop follows a slow ramp.
Below the Stribeck velocity friction falls as speed rises, so the axis sticks, breaks away,
overshoots and sticks again. Writes docs/img/stick_slip.png."""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from fricbench.axis import Axis, simulate
from fricbench.trajectories import Reference


def main(out: str = "docs/img/stick_slip.png") -> None:
    t = np.arange(0.0, 3.0, 1e-3)
    speed = 0.2e-3  # m/s, well below the Stribeck velocity of 2 mm/s
    ref = Reference.from_positions(t, speed * t, "ramp")
    # a soft, integral-heavy velocity loop, as on a badly tuned or heavy axis
    soft = Axis().with_controller(kp=20.0, kv=30.0, ti=0.2)
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    for label, axis in (("Stribeck (fs > fc): stick-slip", soft),
                        ("Coulomb only (fs = fc)", soft.with_friction("coulomb", fc=350.0)),
                        ("no friction", soft.without_friction())):
        res = simulate(axis, ref)
        a1.plot(t, res.x_true * 1e6, label=label)
        a2.plot(t[1:], np.diff(res.x_true) / 1e-3 * 1e3, label=label)
    a1.plot(t, ref.x * 1e6, "k--", lw=1, label="reference")
    a1.set_ylabel("position [um]")
    a1.legend(fontsize=8)
    a1.set_title("Slow ramp at 0.2 mm/s")
    a2.set_ylabel("velocity [mm/s]")
    a2.set_xlabel("time [s]")
    for a in (a1, a2):
        a.grid(alpha=0.3)
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])

"""Draw the friction laws: steady-state force against velocity, and the LuGre/Dahl pre-sliding
hysteresis at a reversal. Writes docs/img/stribeck_curve.png."""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from fricbench.axis import Axis, simulate
from fricbench.friction import make_friction
from fricbench.trajectories import Reference


def main(out: str = "docs/img/stribeck_curve.png") -> None:
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    v = np.linspace(-0.02, 0.02, 2001)
    for fid in ("coulomb", "stribeck", "lugre"):
        a1.plot(v * 1e3, make_friction(fid).force(v), label=fid)
    a1.plot(v * 1e3, make_friction("stribeck", fv=3000.0).force(v), "--",
            label="stribeck + viscous")
    a1.set_xlabel("velocity [mm/s]")
    a1.set_ylabel("friction force [N]")
    a1.set_title("Steady-state friction: the Stribeck dip near zero velocity")
    a1.grid(alpha=0.3)
    a1.legend()
    # pre-sliding: drive the open-loop axis back and forth by a few um with a slow force
    t = np.arange(0.0, 2.0, 1e-3)
    z = np.zeros_like(t)
    ref = Reference(t, z, z, z, "still")
    for fid in ("lugre", "dahl"):
        axis = Axis(friction=make_friction(fid)).with_controller(kp=0.0, kvff=0.0, kv=0.0,
                                                                  ti=0.0)
        force = 300.0 * np.sin(2 * np.pi * 1.0 * t)  # below the 350 N Coulomb level
        res = simulate(axis, ref, u_force=force)
        a2.plot(res.x_true * 1e6, res.friction, label=fid)
    a2.set_xlabel("displacement [um]")
    a2.set_ylabel("friction force [N]")
    a2.set_title("Pre-sliding hysteresis (force below breakaway)")
    a2.grid(alpha=0.3)
    a2.legend()
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])

"""The default axis beside the paper's identified axis (eq. 22): frequency response, step,
and the M-serial tracking error. Writes docs/img/paper_vs_default_axis.png and prints the
figures quoted in docs/default_axis.md."""

from __future__ import annotations

import sys
from pathlib import Path

import control
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from fricbench.axis import closed_loop, simulate
from fricbench.gym import get_spec
from fricbench.trajectories import make_trajectory

PAPER = control.tf([1351.0, 4.952e5], [1.0, 1109.0, 4.952e5])


def main(out: str = "docs/img/paper_vs_default_axis.png") -> None:
    axis = get_spec("fricbench/PaperAxis-v0").axis
    ts = axis.controller.ts
    cl = closed_loop(axis)
    w = np.logspace(0, np.log10(0.9 * np.pi / ts), 400)
    z = np.exp(1j * w * ts)
    # x_ref drives v_ref = s x_ref and a_ref = s^2 x_ref, as the trajectories do
    ours = np.array([cl(zi)[0, 0] + cl(zi)[0, 1] * 1j * wi + cl(zi)[0, 2] * (1j * wi) ** 2
                     for zi, wi in zip(z, w, strict=True)])
    paper = np.array([PAPER(1j * wi) for wi in w])
    poles = np.log(control.poles(cl).astype(complex)) / ts
    print("sampled-loop poles [rad/s]:", np.round(poles, 1))
    print("|pole| [rad/s]:", np.round(np.abs(poles), 1), " damping:",
          np.round(-poles.real / np.abs(poles), 3))
    bw = w[np.argmax(np.abs(ours) < 10 ** (-3 / 20))] if np.any(np.abs(ours) < 0.707) else np.nan
    bwp = w[np.argmax(np.abs(paper) < 0.707)]
    print(f"-3 dB bandwidth: ours {bw:.0f} rad/s, paper {bwp:.0f} rad/s")
    fig, axs = plt.subplots(2, 2, figsize=(12, 7.5))
    axs[0, 0].semilogx(w, 20 * np.log10(np.abs(paper)), label="paper eq. (22)")
    axs[0, 0].semilogx(w, 20 * np.log10(np.abs(ours)), "--", label="default axis (sampled)")
    axs[0, 0].set_ylabel("|X/X_ref| [dB]")
    axs[0, 0].set_title("Reference-to-position response")
    axs[0, 0].legend()
    axs[1, 0].semilogx(w, np.degrees(np.angle(paper)), label="paper")
    axs[1, 0].semilogx(w, np.degrees(np.angle(ours)), "--", label="default axis")
    axs[1, 0].set_ylabel("phase [deg]")
    axs[1, 0].set_xlabel("frequency [rad/s]")
    for a in axs[:, 0]:
        a.grid(alpha=0.3, which="both")
    ref = make_trajectory("m_serial")
    res = simulate(axis, ref)
    lin = simulate(axis.without_friction(), ref)
    tf_err = ref.x - control.forced_response(PAPER, T=ref.t, U=ref.x).outputs
    print(f"M-serial: max |e| {res.max_error * 1e6:.1f} um, linear part "
          f"{lin.max_error * 1e6:.1f} um, friction spike "
          f"{np.max(np.abs(res.x_true - lin.x_true)) * 1e6:.1f} um; "
          f"paper's eq. 22 on our M-serial: {np.max(np.abs(tf_err)) * 1e6:.1f} um")
    cur = make_trajectory("curve")
    rc = simulate(axis, cur)
    print(f"curve: max |e| {rc.max_error * 1e6:.1f} um")
    axs[0, 1].plot(ref.t, ref.x * 1e3, "k")
    axs[0, 1].set_ylabel("reference [mm]")
    axs[0, 1].set_title("M-serial run (cf. the paper's Fig. 11)")
    axs[1, 1].plot(ref.t, res.error * 1e6, label="tracking error, default axis")
    axs[1, 1].plot(ref.t, (lin.x_true - res.x_true) * 1e6, lw=0.8,
                   label="friction part (vs friction-free run)")
    axs[1, 1].set_ylabel("error [um]")
    axs[1, 1].set_xlabel("time [s]")
    axs[1, 1].legend(fontsize=8)
    for a in axs[:, 1]:
        a.grid(alpha=0.3)
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])

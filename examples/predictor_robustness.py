"""Predictors on axes with an effect the grey box does not model.

For the default axis and five variants with one thing changed, every predictor is fitted on
the two training runs of ``fricbench reproduce`` (M-serial and curve, 0.1 um noise, seeds 1
and 2) and scored on the held-out runs (0.05 um, seeds 101 and 102) by the max prediction
error against the true position. Prints the table quoted in docs/reproduction.md and writes
docs/img/predictor_robustness.png. About 8 minutes on 2 cores (the LSTMs).
"""

from __future__ import annotations

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import FuncFormatter
from tqdm import tqdm

from fricbench.axis import Axis, simulate
from fricbench.predictors import make_predictor
from fricbench.trajectories import make_trajectory

PREDICTORS = ("tf", "tf+lstm", "tf+lstm-phys", "greybox", "greybox+lstm")
TRAJECTORIES = ("m_serial", "curve")


def cases() -> dict[str, Axis]:
    """The default axis and one-effect variants (SI units)."""
    a = Axis()
    return {
        "default": a,
        "LuGre friction (sigma0 1.75e8 N/m)": a.with_friction(
            "lugre", fc=350.0, fs=500.0, vs=2e-3, sigma0=1.75e8, sigma1=3e4
        ).with_controller(n_substeps=10),
        "backlash 3 um": a.with_effects(backlash=3e-6),
        "cogging 40 N, 5 mm": a.with_effects(cogging_amplitude=40.0, cogging_period=5e-3),
        "viscous 2000 N s/m": a.with_friction("stribeck", fc=350.0, fs=500.0, vs=2e-3,
                                              fv=2000.0),
        "thermal drift 5 um, 60 s": a.with_effects(thermal_drift=5e-6,
                                                   thermal_time_constant=60.0),
    }


def measure() -> dict[str, dict[str, tuple[float, float]]]:
    """Max held-out prediction error (m) per case, predictor and trajectory."""
    refs = {n: make_trajectory(n) for n in TRAJECTORIES}
    out: dict[str, dict[str, tuple[float, float]]] = {}
    jobs = [(c, p) for c in cases() for p in PREDICTORS]
    axes = cases()
    data: dict[str, tuple[list, dict]] = {}
    for case, pid in tqdm(jobs, desc="fit", unit="fit"):
        if case not in data:
            ax = axes[case]
            tr = ax.with_effects(quantization=0.25e-6, noise_std=0.10e-6)
            te = ax.with_effects(quantization=0.25e-6, noise_std=0.05e-6)
            data[case] = ([simulate(tr, refs[n], seed=1 + i) for i, n in enumerate(TRAJECTORIES)],
                          {n: simulate(te, refs[n], seed=101 + i)
                           for i, n in enumerate(TRAJECTORIES)})
        train, test = data[case]
        kwargs = {"verbose": 0} if pid != "tf" else {}
        pred = make_predictor(pid, **kwargs).fit(train)
        errs = tuple(float(np.max(np.abs(test[n].x_true - pred.predict(refs[n]))))
                     for n in TRAJECTORIES)
        out.setdefault(case, {})[pid] = errs  # type: ignore[assignment]
    return out


def table(res: dict[str, dict[str, tuple[float, float]]]) -> str:
    head = "| axis | " + " | ".join(f"`{p}`" for p in PREDICTORS) + " |"
    lines = [head, "|---" * (len(PREDICTORS) + 1) + "|"]
    for case, row in res.items():
        tf = row["tf"]
        cells = [f"{tf[0] * 1e6:.2f} / {tf[1] * 1e6:.2f}"]
        for p in PREDICTORS[1:]:
            e = row[p]
            cells.append(f"{e[0] * 1e6:.2f} / {e[1] * 1e6:.2f} "
                         f"({tf[0] / e[0]:.1f}x / {tf[1] / e[1]:.1f}x)")
        lines.append(f"| {case} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(res: dict[str, dict[str, tuple[float, float]]], path: str) -> None:
    fig, axs = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    names = list(res)
    x = np.arange(len(names))
    width = 0.8 / (len(PREDICTORS) - 1)
    for k, traj in enumerate(TRAJECTORIES):
        ax = axs[k]
        for j, p in enumerate(PREDICTORS[1:]):
            ratio = [res[c]["tf"][k] / res[c][p][k] for c in names]
            ax.bar(x + (j - (len(PREDICTORS) - 2) / 2) * width, ratio, width, label=p)
        ax.axhline(10.0, color="k", lw=0.8, ls="--")
        ax.set_xticks(x, [n.split(" (")[0] for n in names], rotation=30, ha="right",
                      fontsize=8)
        ax.set_title(f"{traj}: TF-only max error / predictor's (held-out)")
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}x"))
        ax.yaxis.set_minor_formatter(FuncFormatter(
            lambda v, _: f"{v:g}x" if v in (2.0, 3.0, 5.0, 20.0, 30.0) else ""))
    axs[0].set_ylabel("TF-only / predictor (dashed: 10x)")
    axs[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(out: str = "docs/img/predictor_robustness.png") -> None:
    res = measure()
    print("max held-out prediction error [um], M-serial / curve (ratio to `tf`)")
    print(table(res))
    plot(res, out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])

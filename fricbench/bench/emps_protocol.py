"""EMPS on its official protocol (nonlinear_benchmarks): position simulated from the force.

Trained on ``emps_train.csv``; the position of ``emps_test_pulses.csv`` is simulated free-run
from its measured force alone, the initial state taken from its first 20 samples only, and the
error is the RMSE on ``y[20:]`` in mm (nothing detrended). The test run is evaluated once, at
the end: the effect search judges on held-out blocks of the training run
(:func:`fricbench.sysid.diagnose.open_loop.search_open_loop`).

Run ``python -m fricbench.bench.emps_protocol [--data DIR] [--json OUT.json]``.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fricbench._atomic import atomic_write
from fricbench.axis import plant as PL
from fricbench.sysid.diagnose.open_loop import (
    OpenLoopFit,
    free_run_errors,
    search_open_loop,
    simulate_model,
)

__all__ = ["ProtocolResult", "run_protocol", "idim_ls_row", "REFERENCES", "main"]

N_INIT = 20
"""Samples of the test run the protocol lets a model use for its initial state."""

TRAIN_FILE = "emps_train.csv"
TEST_FILE = "emps_test_pulses.csv"

IDIM_LS = {"M_kg": 95.1089, "Fv_N_s_per_m": 203.5034, "Fc_N": 20.3935, "offset_N": -3.1648}
"""Published symmetric IDIM-LS parameters (Janot, Gautier, Brunot 2019, EMPS_Description §3.4)."""

REFERENCES: tuple[tuple[str, str], ...] = (
    ("IDIM-LS, Janot et al. 2019 (inverse dynamics), simulated here the same way",
     "measured by this command (row above)"),
    ("Forgione & Piga 2021, Eur. J. Control 59 (neural state space, decimated x5)",
     "R^2 > 0.99 on both runs"),
    ("Forgione & Piga 2021, IJACSP (dynoNet)", "fit 96.8 %, RMSE 2.64e-3 (m: see PROVENANCE)"),
    ("Champneys et al. 2024, arXiv:2405.10779 (ten baselines: LTI SS, ARX/NARX, GP, RNN)",
     "table not retrieved here (no web access): see the paper"),
)


@dataclass
class ProtocolResult:
    """Figures of one protocol run (positions in m, errors in m unless named ``_mm``)."""

    fit: OpenLoopFit
    train: dict[str, float]
    test: dict[str, float]
    idim_train: dict[str, float]
    idim_test: dict[str, float]
    elapsed_s: float
    traces: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    def to_json(self) -> dict[str, object]:
        """The JSON report: model, errors in mm and R^2, references."""
        def mm(d: dict[str, float]) -> dict[str, float]:
            return {"rmse_mm": 1e3 * d["rms"], "max_mm": 1e3 * d["max"],
                    "final_mm": 1e3 * d["final"], "r2": d["r2"]}
        return {"protocol": {"train": TRAIN_FILE, "test": TEST_FILE, "input": "force_N",
                             "output": "q_m", "n_init": N_INIT, "metric": "RMSE of y[20:], mm"},
                "model": {"effects": list(self.fit.model.effects),
                          "parameters": self.fit.model.describe("N"),
                          "parameter_sd": self.fit.uncertainty("N"),
                          "not_detected": self.fit.not_detected},
                "search": {"heldout_rmse_mm": {k: 1e3 * v for k, v in self.fit.heldout.items()},
                           "steps": self.fit.steps},
                "train": mm(self.train), "test": mm(self.test),
                "idim_ls": {"train": mm(self.idim_train), "test": mm(self.idim_test)},
                "references": [{"model": a, "figure": b} for a, b in REFERENCES],
                "elapsed_s": self.elapsed_s}


def _load(path: Path) -> tuple[np.ndarray, np.ndarray]:
    data = np.genfromtxt(path, delimiter=",", names=True)
    return np.asarray(data["force_N"], dtype=float), np.asarray(data["q_m"], dtype=float)


def idim_ls_row(ts: float = 1e-3) -> np.ndarray:
    """Plant row of the published symmetric IDIM-LS model (forces in N)."""
    p = PL.default_row(IDIM_LS["M_kg"], IDIM_LS["Fv_N_s_per_m"], ts)
    p[PL.FC] = IDIM_LS["Fc_N"]
    p[PL.OFFSET] = IDIM_LS["offset_N"]
    return p


def default_data_dir() -> Path:
    """``$FRICBENCH_EMPS_DIR`` or the shared data folder next to the repository."""
    env = os.environ.get("FRICBENCH_EMPS_DIR")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[3] / "shared" / "data" / "emps"


def run_protocol(data_dir: str | os.PathLike[str] | None = None, *, folds: int = 2,
                 log: bool = False) -> ProtocolResult:
    """Fit on the training run, simulate the test run from its force, return the figures."""
    d = Path(data_dir) if data_dir is not None else default_data_dir()
    for name in (TRAIN_FILE, TEST_FILE):
        if not (d / name).is_file():
            raise FileNotFoundError(f"data_dir={str(d)!r}: {name} not found (set "
                                    "FRICBENCH_EMPS_DIR or pass --data)")
    ts = 1e-3
    t0 = time.perf_counter()
    f_tr, q_tr = _load(d / TRAIN_FILE)
    f_te, q_te = _load(d / TEST_FILE)
    fit = search_open_loop(f_tr, q_tr, ts, n_init=N_INIT, folds=folds,
                           log=print if log else None)
    # the test run, once: its force and its first N_INIT positions only
    y_tr = simulate_model(fit.model.plant, f_tr, q_tr, ts, N_INIT)[0]
    y_te = simulate_model(fit.model.plant, f_te, q_te[:N_INIT], ts, N_INIT)[0]
    idim = idim_ls_row(ts)
    yi_tr = simulate_model(idim, f_tr, q_tr, ts, N_INIT)[0]
    yi_te = simulate_model(idim, f_te, q_te[:N_INIT], ts, N_INIT)[0]
    return ProtocolResult(fit, free_run_errors(y_tr, q_tr, N_INIT),
                          free_run_errors(y_te, q_te, N_INIT),
                          free_run_errors(yi_tr, q_tr, N_INIT),
                          free_run_errors(yi_te, q_te, N_INIT), time.perf_counter() - t0,
                          {"t": ts * np.arange(q_te.shape[0]), "q_test": q_te,
                           "y_test": y_te, "y_idim_test": yi_te})


def plot_test_run(res: ProtocolResult, path: str | os.PathLike[str]) -> None:
    """The test run simulated from its force: measured and simulated position (mm) and the
    error of the model and of the published IDIM-LS model, as a PNG."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    tr = res.traces
    t, q = tr["t"], tr["q_test"]
    fig = Figure(figsize=(9, 6), dpi=100)
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2)
    ax1.plot(t, 1e3 * q, "k", lw=1.2, label="measured q")
    ax1.plot(t, 1e3 * tr["y_test"], "tab:blue", lw=1.0,
             label=f"model, free run from the force (RMSE {1e3 * res.test['rms']:.2f} mm)")
    ax1.plot(t, 1e3 * tr["y_idim_test"], "tab:red", lw=0.8, ls="--",
             label=f"IDIM-LS, published (RMSE {1e3 * res.idim_test['rms']:.2f} mm)")
    ax1.set_ylabel("position [mm]")
    ax1.set_title(f"EMPS official protocol: {TEST_FILE} simulated from its force "
                  f"(initial state from its first {N_INIT} samples)", fontsize=10)
    ax1.legend(fontsize=8)
    ax2.plot(t, 1e3 * (q - tr["y_test"]), "tab:blue", lw=1.0, label="model")
    ax2.plot(t, 1e3 * (q - tr["y_idim_test"]), "tab:red", lw=0.8, ls="--", label="IDIM-LS")
    ax2.axhline(0.0, color="k", lw=0.5)
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("measured - simulated [mm]")
    ax2.legend(fontsize=8)
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    atomic_write(path, buf.getvalue())


def format_table(res: ProtocolResult) -> str:
    """The protocol's figures as a markdown table, references below."""
    lines = ["| model | train sim RMSE, mm | test RMSE, mm | test R^2 |", "|---|---|---|---|"]
    m = res.fit.model
    lines.append(f"| rigid, open-loop output error ({', '.join(m.effects)}) | "
                 f"{1e3 * res.train['rms']:.2f} | {1e3 * res.test['rms']:.2f} | "
                 f"{res.test['r2']:.4f} |")
    lines.append(f"| IDIM-LS, Janot et al. 2019 (published parameters) | "
                 f"{1e3 * res.idim_train['rms']:.2f} | {1e3 * res.idim_test['rms']:.2f} | "
                 f"{res.idim_test['r2']:.4f} |")
    lines.append("")
    lines.append("References (not run here):")
    for a, b in REFERENCES[1:]:
        lines.append(f"- {a}: {b}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: print the protocol's table, optionally write the JSON."""
    ap = argparse.ArgumentParser(prog="python -m fricbench.bench.emps_protocol",
                                 description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("--data", default=None, help="folder of emps_train.csv and "
                    "emps_test_pulses.csv (default: $FRICBENCH_EMPS_DIR or ../shared/data/emps)")
    ap.add_argument("--folds", type=int, default=2, help="held-out blocks of the training run")
    ap.add_argument("--json", metavar="OUT.json", default=None, help="write the JSON here")
    ap.add_argument("--quiet", action="store_true", help="no progress lines")
    ap.add_argument("--plot", metavar="OUT.png", default=None,
                    help="draw the test run: measured, simulated, and the error (mm)")
    args = ap.parse_args(argv)
    res = run_protocol(args.data, folds=args.folds, log=not args.quiet)
    print(format_table(res))
    print(f"\nmodel parameters: {json.dumps(res.fit.model.describe('N'))}")
    print(f"their standard deviations: {json.dumps(res.fit.uncertainty('N'))}")
    print(f"elapsed {res.elapsed_s:.1f} s")
    if args.json:
        atomic_write(args.json, json.dumps(res.to_json(), indent=2) + "\n")
    if args.plot:
        plot_test_run(res, args.plot)
        print(f"plot: {args.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
